//! Stage 4 — splatting the oriented samples into the vector field V (§4.2, §4.5).
//!
//! V = Σ_s m_s n_s Σ_o α_o(s) F̃_o, where m_s is the sample's mass at a depth (its area times its
//! confidence times its share of that depth, see [`crate::density`]), F̃_o = B_o/h³ the
//! unit-integral node function and α_o(s) the splatting weights, which sum to one over o: the
//! node functions' own values b(t) over the 3×3×3 nodes around the sample's cell (B-spline), or
//! the paper's trilinear weights over the eight nearest node centres. Both are products of one
//! weight per axis, and both reach at most one node beyond the sample's cell on each axis.
//!
//! The sum is gathered rather than scattered: every core node adds up what the samples in the
//! 27 cells around it give it (degree 1: the 8 cells that share its corner), with those samples
//! in a fixed order, so nodes are independent (parallel, no atomics) and the result is the same
//! for any number of threads.
//!
//! With Neumann or Dirichlet boundaries a weight that would go to a node just outside the cube
//! goes to the node it mirrors inside: along each axis, the first and last node also collect the
//! weight of their reflection. The fold keeps each sample's whole mass inside the cube and has no
//! sign (the same for both kinds): V's values beyond the faces then follow from the inside ones
//! with the boundary's signs ([`fill_mirrors_field`]).

use crate::bspline::Degree;
use crate::density::DepthSample;
use crate::grid::cell_of;
use crate::memory::zeroed;
use crate::octree::{brick_local, fill_mirrors_field, BrickCursor, Level};
use crate::parallel::{scatter_by_chunk, stop_requested};
use crate::points::Samples;
use crate::{Params, Result, Splatting};
use glam::DVec3;
use rayon::prelude::*;

/// The coefficients of V at one depth on K_d, mirror nodes filled (see
/// [`fill_mirrors_field`]), for the samples `at_depth` with the parameters' splatting weights and
/// boundary.
pub(crate) fn splat_level(
    level: &Level,
    samples: &Samples,
    at_depth: &[DepthSample],
    params: &Params,
) -> Result<[Vec<f64>; 3]> {
    let mut v = splat_depth(
        level,
        &samples.positions,
        &samples.normals,
        at_depth,
        params.splatting,
        params.boundary.mirror_sign().is_some(),
    )?;
    fill_mirrors_field(level, &mut v);
    Ok(v)
}

/// The coefficients of V at one depth (x, y and z, one value per node of the level; zero
/// outside the core), for the samples `at_depth` (any order).
fn splat_depth(
    level: &Level,
    positions: &[DVec3],
    normals: &[[f32; 3]],
    at_depth: &[DepthSample],
    splatting: Splatting,
    fold: bool,
) -> Result<[Vec<f64>; 3]> {
    let inv_h = (level.depth as f64).exp2();
    let n = 1i32 << level.depth;
    let linear = level.degree == Degree::One;
    // Samples grouped by the level index of their cell, in sample order within a cell.
    let mut by_cell: Vec<(u32, DepthSample)> = at_depth
        .par_iter()
        .filter(|s| s.mass != 0.0)
        .map(|s| {
            let cell = cell_of(positions[s.sample as usize], inv_h);
            let index = level
                .find(cell)
                .expect("the octree holds the cell of every splatted sample");
            (index, *s)
        })
        .collect();
    by_cell.par_sort_unstable_by_key(|(cell, s)| (*cell, s.sample));
    // The cells holding samples, each with its range of by_cell, and the cells of brick b as
    // cells[brick_start[b]..brick_start[b + 1]] (cells in index order are in brick order): a
    // table per brick, not per node.
    let mut cells: Vec<(u32, u32, u32)> = Vec::new();
    for (k, &(cell, _)) in by_cell.iter().enumerate() {
        match cells.last_mut() {
            Some((last, _, end)) if *last == cell => *end = k as u32 + 1,
            _ => cells.push((cell, k as u32, k as u32 + 1)),
        }
    }
    let brick_start = level.brick_starts(cells.iter().map(|&(cell, _, _)| cell));
    let samples = SampleCells {
        level,
        cells: &cells,
        brick_start: &brick_start,
    };

    // Each core node's sum goes straight into the field: no per-node list of sums beside it.
    let mut field = [
        zeroed(level.len(), "the splatted normals (V)")?,
        zeroed(level.len(), "the splatted normals (V)")?,
        zeroed(level.len(), "the splatted normals (V)")?,
    ];
    // The cells around a node (slot = dx + 3dy + 9dz for the cell at offset (dx, dy, dz) − 1)
    // whose samples give it weight: all 27 for degree 2; for degree 1 the 8 that share the
    // corner, a corner's hat being zero over the cells beyond it (t − o ≥ 1). Leaving out
    // exact zeros changes no sum.
    const ALL_CELLS: [u8; 27] = {
        let mut slots = [0u8; 27];
        let mut k = 0;
        while k < 27 {
            slots[k] = k as u8;
            k += 1;
        }
        slots
    };
    const CORNER_CELLS: [u8; 8] = [0, 1, 3, 4, 9, 10, 12, 13];
    let cell_slots: &[u8] = if linear { &CORNER_CELLS } else { &ALL_CELLS };
    let [fx, fy, fz] = &mut field;
    scatter_by_chunk(&level.core, [fx, fy, fz], &mut [], |_, writer, _| {
        // (A cancelled splat skips its remaining chunks; see `stop_requested`.)
        if stop_requested() {
            return;
        }
        let mut cursor = BrickCursor::default();
        let mut window = SampleWindow::default();
        // Along each axis, the weight node c − 1 + k receives from a sample in cell c: the
        // degree's function of the sample's position and the node only, so computed once per
        // sample and window instead of once per node the sample reaches (27 at degree 2).
        let axis_weights = |sample: &DepthSample| -> [[f64; 3]; 3] {
            let t = positions[sample.sample as usize] * inv_h;
            let c = cell_of(positions[sample.sample as usize], inv_h);
            std::array::from_fn(|axis| {
                std::array::from_fn(|k| {
                    let o = c[axis] - 1 + k as i32;
                    if linear {
                        // Degree 1: the hats of the cell's corners (trilinear weights).
                        crate::bspline::hat(t[axis] - o as f64)
                    } else {
                        axis_weight(splatting, t[axis], c[axis], o, n, fold)
                    }
                })
            })
        };
        for (k, &node) in writer.indices().iter().enumerate() {
            let mut sum = DVec3::ZERO;
            let at = level.locate(&mut cursor, node);
            if window.slot != at.slot {
                samples.fill(&mut window, at.slot, &by_cell, normals, &axis_weights);
            }
            let l = at.local.map(|v| v as usize);
            for &slot in cell_slots {
                let slot = slot as usize;
                let (dx, dy, dz) = (slot % 3, slot / 3 % 3, slot / 9);
                let (start, end) =
                    window.ranges[(l[0] + dx) + 10 * ((l[1] + dy) + 10 * (l[2] + dz))];
                // The node is c + 1 − d along each axis for a sample in cell c at offset d − 1.
                let (kx, ky, kz) = (2 - dx, 2 - dy, 2 - dz);
                for sample in &window.samples[start as usize..end as usize] {
                    let mut weight = 1.0;
                    weight *= sample.weights[0][kx];
                    weight *= sample.weights[1][ky];
                    weight *= sample.weights[2][kz];
                    sum += sample.normal * (sample.mass * weight);
                }
            }
            for (component, value) in writer.at(k).into_iter().zip(sum.to_array()) {
                *component = value;
            }
        }
    });
    Ok(field)
}

/// The cells holding samples at one depth (cell index, range of its samples), grouped by brick.
struct SampleCells<'a> {
    level: &'a Level,
    cells: &'a [(u32, u32, u32)],
    brick_start: &'a [u32],
}

/// The samples of the cells within one node of one brick, each with its normal, mass and axis
/// weights, and their ranges per cell: a 10×10×10 table (window coordinate = brick-local
/// coordinate + 1, x fastest) of ranges of `samples`, empty where a cell has no samples.
struct SampleWindow {
    slot: usize,
    ranges: Box<[(u32, u32); 1000]>,
    samples: Vec<WindowSample>,
}

/// A sample of a [`SampleWindow`]: its normal, its mass at the depth, and along each axis the
/// weight node c − 1 + k receives from it (c its cell), k = 0, 1, 2.
struct WindowSample {
    normal: DVec3,
    mass: f64,
    weights: [[f64; 3]; 3],
}

impl Default for SampleWindow {
    fn default() -> Self {
        SampleWindow {
            slot: usize::MAX,
            ranges: Box::new([(0, 0); 1000]),
            samples: Vec::new(),
        }
    }
}

impl SampleCells<'_> {
    /// Fills `window` for brick slot `b` from the cells of the 27 bricks around it: their
    /// samples (`by_cell`'s ranges, in order) with their normals and `axis_weights`.
    fn fill(
        &self,
        window: &mut SampleWindow,
        b: usize,
        by_cell: &[(u32, DepthSample)],
        normals: &[[f32; 3]],
        axis_weights: &impl Fn(&DepthSample) -> [[f64; 3]; 3],
    ) {
        window.slot = b;
        window.ranges.fill((0, 0));
        window.samples.clear();
        let around = self.level.bricks().bricks_around27(b);
        for (slot, brick) in around.iter().enumerate() {
            let Some(brick) = *brick else { continue };
            let offset = [slot % 3, slot / 3 % 3, slot / 9];
            let range = self.brick_start[brick] as usize..self.brick_start[brick + 1] as usize;
            for &(cell, start, end) in &self.cells[range] {
                let l = brick_local((self.level.keys[cell as usize] & 511) as usize);
                // Window coordinate: local + 8·(offset − 1) + 1.
                let w: [i32; 3] = std::array::from_fn(|a| (l[a] + 8 * offset[a]) as i32 - 7);
                if w.iter().all(|v| (0..10).contains(v)) {
                    let w = w.map(|v| v as usize);
                    let first = window.samples.len() as u32;
                    window
                        .samples
                        .extend(by_cell[start as usize..end as usize].iter().map(|(_, s)| {
                            WindowSample {
                                normal: DVec3::from_array(
                                    normals[s.sample as usize].map(f64::from),
                                ),
                                mass: s.mass,
                                weights: axis_weights(s),
                            }
                        }));
                    window.ranges[w[0] + 10 * (w[1] + 10 * w[2])] =
                        (first, window.samples.len() as u32);
                }
            }
        }
    }
}

/// Along one axis: the weight node `i` receives from a sample at `t` (in node widths) in cell
/// `c`, folding in the weight of its mirror image when `fold` (mirrored boundaries) and `i` is
/// the first or last of the `n` nodes inside the cube.
#[inline]
fn axis_weight(splatting: Splatting, t: f64, c: i32, i: i32, n: i32, fold: bool) -> f64 {
    let direct = node_weight(splatting, t, c, i);
    if !fold {
        direct
    } else if i == 0 {
        direct + node_weight(splatting, t, c, -1)
    } else if i == n - 1 {
        direct + node_weight(splatting, t, c, n)
    } else {
        direct
    }
}

/// The weight node `i` (centre i + ½) receives from a sample at `t` in cell `c` (zero beyond one
/// node of the cell).
#[inline]
fn node_weight(splatting: Splatting, t: f64, c: i32, i: i32) -> f64 {
    if (i - c).abs() > 1 {
        return 0.0;
    }
    let offset = t - (i as f64 + 0.5);
    match splatting {
        Splatting::BSpline => crate::bspline::value(offset),
        Splatting::Trilinear => (1.0 - offset.abs()).max(0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_along_an_axis_sum_to_one_and_fold_at_the_faces() {
        let n = 8;
        for splatting in [Splatting::BSpline, Splatting::Trilinear] {
            for k in 0..=80 {
                let t = k as f64 / 10.0 * 0.999; // inside [0, 8)
                let c = t.floor() as i32;
                // Inside the cube with mirror folding, or over all nodes without.
                let folded: f64 = (0..n)
                    .map(|i| axis_weight(splatting, t, c, i, n, true))
                    .sum();
                let free: f64 = (-1..=n)
                    .map(|i| axis_weight(splatting, t, c, i, n, false))
                    .sum();
                assert!(
                    (folded - 1.0).abs() < 1e-12,
                    "{splatting:?} t {t}: {folded}"
                );
                assert!((free - 1.0).abs() < 1e-12, "{splatting:?} t {t}: {free}");
            }
        }
    }

    #[test]
    fn trilinear_weights_are_the_eight_nearest_centres() {
        // t = 3.3: centres 2.5 and 3.5 get 0.2 and 0.8; centre 4.5 gets nothing.
        let w = |i| node_weight(Splatting::Trilinear, 3.3, 3, i);
        assert!((w(2) - 0.2).abs() < 1e-12 && (w(3) - 0.8).abs() < 1e-12 && w(4) == 0.0);
    }
}

//! Stage 4 — splatting the oriented samples into the vector field V (§4.2, §4.5).
//!
//! V = Σ_s m_s n_s Σ_o α_o(s) F̃_o, where m_s is the sample's mass at a depth (its area times its
//! confidence times its share of that depth, see [`crate::density`]), F̃_o = B_o/h³ the
//! unit-integral node function and α_o(s) the splatting weights, which sum to one over o: the
//! node functions' own values b(t) over the 3×3×3 nodes around the sample's cell (B-spline), or
//! the paper's trilinear weights over the eight nearest node centres. Both are products of one
//! weight per axis, and both reach at most one node beyond the sample's cell on each axis.
//!
//! Every core node adds up what the samples in the 27 cells around it give it (degree 1: the 8
//! cells that share its corner), offset by offset and within a cell in sample order, so the sum
//! is the same for any number of threads. The work goes brick by brick (a brick's nodes are
//! consecutive, so bricks are independent: parallel, no atomics): the samples of the cells
//! within one node of the brick are gathered once, then scattered to the brick's nodes one
//! offset at a time, which adds each node's terms in that same order.
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
use crate::octree::{brick_local, fill_mirrors_field, Level, CORE};
use crate::parallel::stop_requested;
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

    // Each brick's sums go straight into the field: no per-node list of sums beside it.
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
    // A task per brick (its nodes are consecutive in K_d, so it owns its part of each
    // component): the samples of its window scattered to its positions ([`BrickSums::scatter`],
    // in the order a per-node gather adds them), then its core nodes take their sums.
    let index = level.bricks();
    index
        .parts(field.each_mut().map(|component| &mut component[..]))
        .into_par_iter()
        .enumerate()
        .with_min_len(16)
        .for_each_init(
            || (SampleWindow::default(), BrickSums::default()),
            |(window, sums), (b, mut out)| {
                // (A cancelled splat skips its remaining bricks; see `stop_requested`.)
                if stop_requested() {
                    return;
                }
                let (first, occupied) = index.brick(b);
                let first = first as usize;
                let has_core =
                    (first..first + out[0].len()).any(|node| level.flags[node] & CORE != 0);
                if !has_core {
                    return;
                }
                samples.fill(window, b, &by_cell, normals, &axis_weights);
                sums.scatter(window, cell_slots);
                // The core nodes take their sums; the other nodes of K_d keep zero.
                let mut node = first;
                for (word, &occ) in occupied.iter().enumerate() {
                    let mut bits = occ;
                    while bits != 0 {
                        let bit = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        if level.flags[node] & CORE != 0 {
                            let l = brick_local(word * 64 + bit);
                            let sum = sums.at[l[0] + 8 * (l[1] + 8 * l[2])];
                            for (component, value) in out.iter_mut().zip(sum.to_array()) {
                                component[node - first] = value;
                            }
                        }
                        node += 1;
                    }
                }
            },
        );
    Ok(field)
}

/// The cells holding samples at one depth (cell index, range of its samples), grouped by brick.
struct SampleCells<'a> {
    level: &'a Level,
    cells: &'a [(u32, u32, u32)],
    brick_start: &'a [u32],
}

/// The samples of the cells within one node of one brick, each with its normal, mass and axis
/// weights, by cell: the window coordinates of the cells that have samples (brick-local
/// coordinate + 1 per axis, 0..10) with their ranges of `samples`, in the order `fill` meets
/// them.
#[derive(Default)]
struct SampleWindow {
    cells: Vec<([u8; 3], u32, u32)>,
    samples: Vec<WindowSample>,
}

/// One brick's sums of V at its 8×8×8 positions (index x + 8y + 64z), before they go to its
/// core nodes.
struct BrickSums {
    at: Box<[DVec3; 512]>,
}

impl Default for BrickSums {
    fn default() -> Self {
        BrickSums {
            at: Box::new([DVec3::ZERO; 512]),
        }
    }
}

impl BrickSums {
    /// Every position's sum over the window's samples that weigh on it: for each offset
    /// `cell_slots` lists in turn (slot = dx + 3dy + 9dz, the cell at offset (dx, dy, dz) − 1
    /// from the node), the samples of that cell in order. Each position thus adds its terms in
    /// the order a gather over the slots would, starting from zero.
    fn scatter(&mut self, window: &SampleWindow, cell_slots: &[u8]) {
        self.at.fill(DVec3::ZERO);
        for &slot in cell_slots {
            let slot = slot as usize;
            let d = [slot % 3, slot / 3 % 3, slot / 9];
            // The node is c + 1 − d along each axis for a sample in cell c at offset d − 1:
            // at window coordinate w of the cell, brick-local w − d; its weight index 2 − d.
            let k = d.map(|d| 2 - d);
            for &(w, start, end) in &window.cells {
                let l: [usize; 3] = std::array::from_fn(|a| (w[a] as usize).wrapping_sub(d[a]));
                if l.iter().any(|&v| v >= 8) {
                    continue;
                }
                let sum = &mut self.at[l[0] + 8 * (l[1] + 8 * l[2])];
                for sample in &window.samples[start as usize..end as usize] {
                    let mut weight = 1.0;
                    weight *= sample.weights[0][k[0]];
                    weight *= sample.weights[1][k[1]];
                    weight *= sample.weights[2][k[2]];
                    *sum += sample.normal * (sample.mass * weight);
                }
            }
        }
    }
}

/// A sample of a [`SampleWindow`]: its normal, its mass at the depth, and along each axis the
/// weight node c − 1 + k receives from it (c its cell), k = 0, 1, 2.
struct WindowSample {
    normal: DVec3,
    mass: f64,
    weights: [[f64; 3]; 3],
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
        window.cells.clear();
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
                    window
                        .cells
                        .push((w.map(|v| v as u8), first, window.samples.len() as u32));
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
    use crate::octree::Octree;
    use crate::Boundary;

    /// Proves: the brick-by-brick splat gives every core node Σ_s m_s n_s Π_a w_a(s, o) over
    /// the samples s whose cell is within one node of it (w_a the degree's weight along axis a,
    /// folded at the faces with mirrors), zero elsewhere, the same bit for bit at 1, 2 and 3
    /// threads; for both degrees, with and without mirrored faces, with samples packed into
    /// a few cells (many per cell) and spread over many bricks.
    #[test]
    fn the_splat_is_the_direct_sum_over_the_samples_at_every_node() {
        let depth = 5u32;
        let n = 1i32 << depth;
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut positions = Vec::new();
        for k in 0..1500 {
            // Half anywhere in the cube (faces included), half in a few cells.
            let p = if k % 2 == 0 {
                DVec3::new(uniform(), uniform(), uniform()) * 0.999
            } else {
                DVec3::new(0.5, 0.25, 0.75) + DVec3::new(uniform(), uniform(), uniform()) * 0.05
            };
            positions.push(p);
        }
        let normals: Vec<[f32; 3]> = (0..positions.len())
            .map(|k| {
                [
                    (k % 7) as f32 - 3.0,
                    (k % 5) as f32 * 0.5,
                    1.0 - (k % 3) as f32,
                ]
            })
            .collect();
        let at_depth: Vec<DepthSample> = (0..positions.len() as u32)
            .map(|sample| DepthSample {
                sample,
                mass: 0.25 + (sample % 11) as f64 * 0.1,
            })
            .collect();
        let inv_h = n as f64;
        for (degree, boundary) in [
            (Degree::Two, Boundary::Free),
            (Degree::Two, Boundary::Neumann),
            (Degree::One, Boundary::Neumann),
        ] {
            let fold = boundary.mirror_sign().is_some();
            let mut cells = vec![Vec::new(); depth as usize + 1];
            cells[depth as usize] = positions.iter().map(|&p| cell_of(p, inv_h)).collect();
            let tree = Octree::build_for(cells, 2, boundary, degree);
            let level = &tree.levels[depth as usize];
            let splat_with = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| {
                        splat_depth(
                            level,
                            &positions,
                            &normals,
                            &at_depth,
                            Splatting::BSpline,
                            fold,
                        )
                        .unwrap()
                    })
            };
            let v = splat_with(1);
            for threads in [2, 3] {
                assert!(
                    (0..3).all(|a| v[a]
                        .iter()
                        .zip(&splat_with(threads)[a])
                        .all(|(x, y)| x.to_bits() == y.to_bits())),
                    "{degree:?} {boundary:?}: {threads} threads"
                );
            }
            let weight = |t: f64, c: i32, o: i32| match degree {
                Degree::One => crate::bspline::hat(t - o as f64),
                Degree::Two => axis_weight(Splatting::BSpline, t, c, o, n, fold),
            };
            let mut reached = 0;
            for node in 0..level.len() as u32 {
                let o = level.coord(node);
                let mut want = DVec3::ZERO;
                if level.flags[node as usize] & CORE != 0 {
                    for s in &at_depth {
                        let p = positions[s.sample as usize];
                        let c = cell_of(p, inv_h);
                        if (0..3).any(|a| (o[a] - c[a]).abs() > 1) {
                            continue;
                        }
                        let t = p * inv_h;
                        let w: f64 = (0..3).map(|a| weight(t[a], c[a], o[a])).product();
                        let normal = DVec3::from_array(normals[s.sample as usize].map(f64::from));
                        want += normal * (s.mass * w);
                    }
                }
                let got = DVec3::new(
                    v[0][node as usize],
                    v[1][node as usize],
                    v[2][node as usize],
                );
                assert!(
                    (got - want).length() <= 1e-12 * (1.0 + want.length()),
                    "{degree:?} {boundary:?}: node {o:?} has {got} instead of {want}"
                );
                reached += (want != DVec3::ZERO) as usize;
            }
            assert!(
                reached > 1000,
                "{degree:?} {boundary:?}: {reached} nodes reached"
            );
        }
    }

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

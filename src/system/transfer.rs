//! Grid transfer between consecutive depths by the two-scale relation
//! ([`crate::bspline::REFINE`]): coarser coefficients prolonged exactly into a finer halo
//! (node by node, brick by brick, or inside a brick window), and the transpose, restriction.

use super::bricks::{BrickNodes, BrickScratch, CoreBricks, WINDOW};
use crate::bspline::{Degree, REFINE};
use crate::error::Result;
use crate::memory::zeroed;
use crate::octree::{axis_interval_masks, brick_local, AxisStep, Level, NONE};
use crate::parallel::{split_parts, stop_requested};
use rayon::prelude::*;
use std::ops::Range;

/// A coarser vector field prolonged to a finer halo, evaluated where it is read instead of
/// stored (node by node with [`ProlongedField::at`], brick by brick by
/// [`divergence_of_prolonged`](super::rhs::divergence_of_prolonged) and [`ProlongedField::add_to`]): the value at a
/// fine node is what [`prolong`] of each component followed by [`fill_mirrors_field`](crate::octree::fill_mirrors_field) would
/// hold there. Reading it where needed saves three halo-sized vectors.
pub struct ProlongedField<'a> {
    pub coarse: &'a Level,
    pub fine: &'a Level,
    pub field: [&'a [f64]; 3],
    pub scale: f64,
}

impl ProlongedField<'_> {
    /// The three components at fine node `i`.
    #[inline]
    pub fn at(&self, i: u32) -> [f64; 3] {
        let scales = [self.scale; 3];
        if !self.fine.mirrors.is_empty() {
            // Neumann or Dirichlet: a node outside the cube mirrors its reflection inside, if in
            // K_d, with the signs of [`fill_mirrors_field`](crate::octree::fill_mirrors_field).
            let c = self.fine.coord(i);
            if let Some((inside, flips)) = self.fine.reflect(c) {
                if let Some(j) = self.fine.find(inside) {
                    let v = prolonged_at(self.coarse, self.fine, self.field, scales, j);
                    let scalar = self.fine.mirror_sign(flips);
                    return std::array::from_fn(|axis| {
                        if flips & (1 << axis) != 0 {
                            -scalar * v[axis]
                        } else {
                            scalar * v[axis]
                        }
                    });
                }
            } else if self.fine.degree == Degree::One {
                // A node on a face is its own image: the components the reflection would
                // negate are 0 (as `fill_mirrors_field` leaves them).
                let n = 1i32 << self.fine.depth;
                let on = (0..3).fold(0u8, |f, a| f | ((c[a] == 0 || c[a] == n) as u8) << a);
                if on != 0 {
                    let v = prolonged_at(self.coarse, self.fine, self.field, scales, i);
                    let scalar = self.fine.mirror_sign(on);
                    return std::array::from_fn(|axis| {
                        let sign = if on & (1 << axis) != 0 {
                            -scalar
                        } else {
                            scalar
                        };
                        if sign < 0.0 {
                            0.0
                        } else {
                            v[axis]
                        }
                    });
                }
            }
        }
        prolonged_at(self.coarse, self.fine, self.field, scales, i)
    }

    /// `v[axis][i] +=` the prolonged field at every fine node i (brick by brick).
    pub fn add_to(&self, v: &mut [Vec<f64>; 3]) {
        let [vx, vy, vz] = v;
        let at_mirror = |node: u32| self.at(node);
        let at_mirror: Option<&(dyn Fn(u32) -> [f64; 3] + Sync)> = if self.fine.mirrors.is_empty() {
            None
        } else {
            Some(&at_mirror)
        };
        prolong_by_brick(
            self.coarse,
            self.fine,
            self.field,
            self.scale,
            at_mirror,
            [vx, vy, vz],
            |x, p| p + x,
        );
    }
}

/// Prolongs coarse coefficients (on K_{d−1}) to the fine halo K_d, exactly: the fine
/// combination represents the same function wherever the coarse one is complete.
pub fn prolong(coarse: &Level, fine: &Level, x: &[f64], scale: f64) -> Result<Vec<f64>> {
    let mut out = zeroed(fine.len(), "the coefficients")?;
    prolong_by_brick(coarse, fine, [x], scale, None, [&mut out], |_, v| v);
    Ok(out)
}

impl CoreBricks {
    /// The window of core brick `cb` for `field` (a coarser field prolonged to this depth),
    /// with the values [`ProlongedField::at`] gives at each node of the window (zero where the
    /// fine depth has no node). The fine window covers fine coordinates origin − 2 .. origin + 10
    /// per axis; their refinement parents (m = ⌊f/2⌋ and its partner m ± 1) lie in the coarse
    /// coordinates origin/2 − 2 .. origin/2 + 6, gathered once into an 8×8×8 array from the
    /// eight coarse bricks that cover them, and prolonged to the whole window one axis at a
    /// time ([`prolong_window`], with the weights of [`refinement_parents`]). Nodes beyond the
    /// cube (mirrors, with Neumann or Dirichlet boundaries) take the node-by-node path.
    pub(super) fn gather_prolonged(
        &self,
        field: &ProlongedField<'_>,
        cb: usize,
        windows: &mut [Vec<[f64; WINDOW]>; 3],
        scratch: &mut BrickScratch,
    ) {
        let (fine, coarse) = (field.fine, field.coarse);
        let origin = fine.bricks().origin(self.around[cb][13] as usize);
        let coarse_origin: [i32; 3] = std::array::from_fn(|a| origin[a] / 2 - 2);

        coarse_window(coarse, coarse_origin, field.field, &mut scratch.coarse);
        for c in 0..3 {
            let [along_x, _] = &mut scratch.y;
            let [along_y, _, _] = &mut scratch.z;
            prolong_window(
                fine.degree,
                &scratch.coarse[c],
                along_x,
                along_y,
                &mut scratch.prolonged[c],
                field.scale,
            );
        }

        // The fine window: the prolongation where K_d has a node, zero elsewhere (beyond the
        // cube, with mirrors, a node's value is its mirror image's, signed).
        let mut present = [0u16; WINDOW * WINDOW];
        self.for_each_window_group(fine, cb, |_, corners, [x, y, z]| {
            for (k, row) in [
                z * WINDOW + y,
                z * WINDOW + y + 1,
                (z + 1) * WINDOW + y,
                (z + 1) * WINDOW + y + 1,
            ]
            .into_iter()
            .enumerate()
            {
                present[row] |= ((corners >> (2 * k) & 3) as u16) << x;
            }
        });
        for (window, prolonged) in windows.iter_mut().zip(&scratch.prolonged) {
            for ((w, p), &bits) in window.iter_mut().zip(prolonged).zip(&present) {
                *w = std::array::from_fn(|x| if bits >> x & 1 == 1 { p[x] } else { 0.0 });
            }
        }
        let n = 1i32 << fine.depth;
        let at_face = (0..3).any(|a| origin[a] - 2 < 0 || origin[a] + 10 > n);
        if !fine.mirrors.is_empty() && at_face {
            self.for_each_window_group(fine, cb, |mut node, corners, [x, y, z]| {
                for c in (0..8).filter(|c| corners >> c & 1 == 1) {
                    let w = [x + (c & 1), y + (c >> 1 & 1), z + (c >> 2)];
                    let f: [i32; 3] = std::array::from_fn(|a| origin[a] - 2 + w[a] as i32);
                    if fine.follows_mirror_rule(f) {
                        for (window, v) in windows.iter_mut().zip(field.at(node as u32)) {
                            window[w[2] * WINDOW + w[1]][w[0]] = v;
                        }
                    }
                    node += 1;
                }
            });
        }
    }
}

/// The prolongation (times `scale`) of a coarse 8×8×8 window (`coarse`, index x + 8y + 64z,
/// as [`coarse_window`] fills it for a fine brick's window) at every position of the fine
/// 12×12×12 window, one axis at a time: along each axis fine position w takes ¾ of coarse
/// position ⌊w/2⌋ + 1 and ¼ of ⌊w/2⌋ (w even) or ⌊w/2⌋ + 2 (w odd), the two-scale relation
/// ([`refinement_parents`]; degree 1: all of ⌊w/2⌋ + 1 for even w, half of each for odd). `along_x` (8·8 rows) and `along_y` (8·12 rows) are scratch space.
fn prolong_window(
    degree: Degree,
    coarse: &[f64],
    along_x: &mut [[f64; WINDOW]],
    along_y: &mut [[f64; WINDOW]],
    out: &mut [[f64; WINDOW]],
    scale: f64,
) {
    // [own, partner] weights by the fine position's parity (a window position has the parity
    // of its fine coordinate: the window starts at a brick origin − 2).
    let weights = [degree.refine(0), degree.refine(1)];
    let partner = |w: usize| if w & 1 == 0 { w >> 1 } else { (w >> 1) + 2 };
    for (r, row) in along_x[..64].iter_mut().enumerate() {
        let line = &coarse[8 * r..8 * r + 8];
        *row = std::array::from_fn(|w| {
            let [own, other] = weights[w & 1];
            own * line[(w >> 1) + 1] + other * line[partner(w)]
        });
    }
    for z in 0..8 {
        for w in 0..WINDOW {
            let [own_w, other_w] = weights[w & 1];
            let (own, other) = (&along_x[8 * z + (w >> 1) + 1], &along_x[8 * z + partner(w)]);
            along_y[WINDOW * z + w] = std::array::from_fn(|x| own_w * own[x] + other_w * other[x]);
        }
    }
    for w in 0..WINDOW {
        let [own_w, other_w] = weights[w & 1];
        for y in 0..WINDOW {
            let (own, other) = (
                &along_y[WINDOW * ((w >> 1) + 1) + y],
                &along_y[WINDOW * partner(w) + y],
            );
            out[WINDOW * w + y] =
                std::array::from_fn(|x| (own_w * own[x] + other_w * other[x]) * scale);
        }
    }
}

/// Fills `window` (per component, 8×8×8, index x + 8y + 64z) with `fields` at the coarse nodes
/// of coordinates `origin` .. `origin` + 8 per axis (zero where `coarse` has no node), from the
/// eight coarse bricks that cover them (`origin` ≡ 2 mod 4: the window of a fine brick whose
/// origin is O starts at O/2 − 2, and spans two bricks per axis).
fn coarse_window<const C: usize>(
    coarse: &Level,
    origin: [i32; 3],
    fields: [&[f64]; C],
    window: &mut [Vec<f64>; C],
) {
    for component in window.iter_mut() {
        component.fill(0.0);
    }
    let index = coarse.bricks();
    for k in 0..8 {
        let brick_origin: [i32; 3] =
            std::array::from_fn(|a| origin[a].div_euclid(8) * 8 + 8 * ((k >> a) & 1));
        let Some(slot) = coarse.brick_containing(brick_origin) else {
            continue;
        };
        // The part of this brick inside the window, per axis, in its local coordinates.
        let mut region = [u64::MAX; 8];
        for a in 0..3 {
            let lo = (origin[a] - brick_origin[a]).max(0) as usize;
            let hi = (origin[a] + 8 - brick_origin[a]).min(8) as usize;
            for (r, m) in region.iter_mut().zip(&axis_interval_masks()[a][lo][hi]) {
                *r &= m;
            }
        }
        // The window's bounds are even in the brick, so it takes whole 2×2×2 groups (a byte of
        // an occupancy word, nodes in corner order x + 2y + 4z), placed group by group.
        let (mut node, occupied) = index.brick(slot);
        for (word, (&occ, &region)) in occupied.iter().zip(&region).enumerate() {
            let mut bits = occ & region;
            while bits != 0 {
                let byte = bits.trailing_zeros() / 8;
                bits &= !(0xff << (8 * byte));
                let mut n = (node + (occ & ((1u64 << (8 * byte)) - 1)).count_ones()) as usize;
                let l = brick_local(word * 64 + 8 * byte as usize);
                let u: [usize; 3] =
                    std::array::from_fn(|a| (brick_origin[a] + l[a] as i32 - origin[a]) as usize);
                let base = u[2] * 64 + u[1] * 8 + u[0];
                let mut corners = (occ >> (8 * byte)) as u8;
                while corners != 0 {
                    let c = corners.trailing_zeros() as usize;
                    corners &= corners - 1;
                    let at = base + (c & 1) + 8 * (c >> 1 & 1) + 64 * (c >> 2);
                    for (w, values) in window.iter_mut().zip(&fields) {
                        w[at] = values[n];
                    }
                    n += 1;
                }
            }
            node += occ.count_ones();
        }
    }
}

/// The prolongation (times `scale`) of a coarse 8×8×8 window (`coarse`, index x + 8y + 64z,
/// as [`coarse_window`] fills it for the fine brick at `origin`, from origin/2 − 2) at the
/// brick's 8×8×8 positions (`out`, index x + 8y + 64z), one axis at a time with the weights and
/// in the order of [`prolong_window`], so a node takes the value it has in a brick window's
/// prolongation. Along each axis, brick position l takes `own` of window position ⌊l/2⌋ + 2
/// and `partner` of ⌊l/2⌋ + 1 (l even) or ⌊l/2⌋ + 3 (l odd), so the window's rows 1..7 are
/// read. `along_x` (6·6 rows) and `along_y` (6·8 rows) are scratch space.
fn prolong_brick(
    degree: Degree,
    coarse: &[f64],
    along_x: &mut [[f64; 8]; 36],
    along_y: &mut [[f64; 8]; 48],
    out: &mut [f64],
    scale: f64,
) {
    let weights = [degree.refine(0), degree.refine(1)];
    let own_at = |l: usize| (l >> 1) + 2;
    let partner_at = |l: usize| {
        if l & 1 == 0 {
            (l >> 1) + 1
        } else {
            (l >> 1) + 3
        }
    };
    // Window rows (y, z) in 1..7, stored at (y − 1) + 6 (z − 1).
    for (r, row) in along_x.iter_mut().enumerate() {
        let (y, z) = (r % 6 + 1, r / 6 + 1);
        let line = &coarse[8 * y + 64 * z..8 * y + 64 * z + 8];
        *row = std::array::from_fn(|x| {
            let [own_w, other_w] = weights[x & 1];
            own_w * line[own_at(x)] + other_w * line[partner_at(x)]
        });
    }
    // Window planes z in 1..7 and brick rows y, stored at y + 8 (z − 1).
    for z in 0..6 {
        for y in 0..8 {
            let [own_w, other_w] = weights[y & 1];
            let (own, other) = (
                &along_x[(own_at(y) - 1) + 6 * z],
                &along_x[(partner_at(y) - 1) + 6 * z],
            );
            along_y[y + 8 * z] = std::array::from_fn(|x| own_w * own[x] + other_w * other[x]);
        }
    }
    for z in 0..8 {
        let [own_w, other_w] = weights[z & 1];
        for y in 0..8 {
            let (own, other) = (
                &along_y[y + 8 * (own_at(z) - 1)],
                &along_y[y + 8 * (partner_at(z) - 1)],
            );
            let row = &mut out[8 * y + 64 * z..8 * y + 64 * z + 8];
            for (x, o) in row.iter_mut().enumerate() {
                *o = (own_w * own[x] + other_w * other[x]) * scale;
            }
        }
    }
}

/// A task's scratch space for [`prolong_by_brick`]: the coarse window of each field, its
/// prolongation at the brick's positions, and [`prolong_brick`]'s passes.
struct BrickProlongation<const C: usize> {
    window: [Vec<f64>; C],
    prolonged: [Vec<f64>; C],
    along_x: [[f64; 8]; 36],
    along_y: [[f64; 8]; 48],
}

impl<const C: usize> BrickProlongation<C> {
    fn new() -> Self {
        BrickProlongation {
            window: std::array::from_fn(|_| vec![0.0; 512]),
            prolonged: std::array::from_fn(|_| vec![0.0; 512]),
            along_x: [[0.0; 8]; 36],
            along_y: [[0.0; 8]; 48],
        }
    }
}

/// `outputs[c][node] = combine(outputs[c][node], value[c])` for every node of `fine`, with
/// `value` the prolongation of `fields` (times `scale`) there, brick by brick in parallel: each
/// fine brick gathers the coarse nodes under it once ([`coarse_window`]) and prolongs them to
/// all its positions one axis at a time ([`prolong_brick`]). With `at_mirror`,
/// nodes beyond the cube take `at_mirror(node)` instead. A brick's nodes are consecutive, so
/// each task owns its brick's part of every output.
fn prolong_by_brick<const C: usize>(
    coarse: &Level,
    fine: &Level,
    fields: [&[f64]; C],
    scale: f64,
    at_mirror: Option<&(dyn Fn(u32) -> [f64; C] + Sync)>,
    outputs: [&mut [f64]; C],
    combine: impl Fn(f64, f64) -> f64 + Sync,
) {
    let index = fine.bricks();
    index
        .parts(outputs)
        .into_par_iter()
        .enumerate()
        .with_min_len(16)
        .for_each_init(BrickProlongation::<C>::new, |scratch, (b, mut out)| {
            // (A cancelled solve skips the remaining bricks; see `stop_requested`.)
            if stop_requested() {
                return;
            }
            let origin = fine.bricks().origin(b);
            let coarse_origin: [i32; 3] = std::array::from_fn(|a| origin[a] / 2 - 2);
            coarse_window(coarse, coarse_origin, fields, &mut scratch.window);
            for (window, prolonged) in scratch.window.iter().zip(&mut scratch.prolonged) {
                prolong_brick(
                    fine.degree,
                    window,
                    &mut scratch.along_x,
                    &mut scratch.along_y,
                    prolonged,
                    scale,
                );
            }
            let (first, occupied) = index.brick(b);
            let mut node = first;
            for (word, &occ) in occupied.iter().enumerate() {
                let mut bits = occ;
                while bits != 0 {
                    let bit = bits.trailing_zeros();
                    bits &= bits - 1;
                    let l = brick_local(word * 64 + bit as usize);
                    let f: [i32; 3] = std::array::from_fn(|a| origin[a] + l[a] as i32);
                    let value = match at_mirror {
                        Some(at) if fine.follows_mirror_rule(f) => at(node),
                        _ => {
                            let at = l[0] + 8 * l[1] + 64 * l[2];
                            std::array::from_fn(|c| scratch.prolonged[c][at])
                        }
                    };
                    let k = (node - first) as usize;
                    for (out, v) in out.iter_mut().zip(value) {
                        out[k] = combine(out[k], v);
                    }
                    node += 1;
                }
            }
        });
}

/// The two-scale weight of parent k of a fine node (bit a of k set: the partner along axis a,
/// weight ¼; clear: the node's own parent's column, weight ¾), the same for every node.
pub(super) const PARENT_WEIGHTS: [f64; 8] = {
    let mut w = [1.0; 8];
    let mut k = 0;
    while k < 8 {
        let mut axis = 0;
        while axis < 3 {
            w[k] *= if (k >> axis) & 1 == 1 {
                REFINE[0]
            } else {
                REFINE[1]
            };
            axis += 1;
        }
        k += 1;
    }
    w
};

/// The two-scale weights of the eight parents of a fine node whose coordinates have these
/// parities, in the order of [`PARENT_WEIGHTS`] (which degree 2 gives whatever the parities; a
/// degree-1 node on an even coordinate takes nothing from its partner along that axis).
#[inline]
pub(super) fn parent_weights(degree: Degree, parity: [usize; 3]) -> [f64; 8] {
    match degree {
        Degree::Two => PARENT_WEIGHTS,
        Degree::One => {
            let axis = parity.map(|p| degree.refine(p));
            std::array::from_fn(|k| axis[0][k & 1] * axis[1][(k >> 1) & 1] * axis[2][(k >> 2) & 1])
        }
    }
}

/// The eight parents of fine node `i` whose refinement covers it, with their two-scale weights:
/// per axis, child 2m = ¾·parent m + ¼·parent m−1 and child 2m+1 = ¾·parent m + ¼·parent m+1.
#[inline]
pub(super) fn refinement_parents(coarse: &Level, fine: &Level, i: u32) -> [(u32, f64); 8] {
    let mut out = [(NONE, 0.0); 8];
    let Some((p, at)) = fine.parent_in(coarse, i) else {
        return out;
    };
    // The parity of each coordinate is the key's bit of that axis (the key's offset is even).
    let key = fine.keys[i as usize];
    let weights = parent_weights(
        fine.degree,
        std::array::from_fn(|a| (key >> a) as usize & 1),
    );
    let steps: [[AxisStep; 2]; 3] = std::array::from_fn(|axis| {
        let partner = if (key >> axis) & 1 == 0 { -1 } else { 1 };
        [0, partner].map(|delta| AxisStep::new(at.local[axis], delta, axis))
    });
    for k in 0..8 {
        // Parent k is parent (k without its highest axis bit) stepped along that axis: each
        // parent reached along x, then y, then z, and missing when the one it steps from is.
        let node = if k == 0 {
            p
        } else {
            let axis = 7 - (k as u8).leading_zeros() as usize;
            if out[k & !(1 << axis)].0 == NONE {
                NONE
            } else {
                let step = steps[0][k & 1]
                    .join(steps[1][k >> 1 & 1])
                    .join(steps[2][k >> 2 & 1]);
                coarse.node_after(at, step)
            }
        };
        out[k] = (node, weights[k]);
    }
    out
}

/// The prolongation of `inputs` (each times its scale) at fine node `i`.
#[inline]
pub(super) fn prolonged_at<const N: usize>(
    coarse: &Level,
    fine: &Level,
    inputs: [&[f64]; N],
    scales: [f64; N],
    i: u32,
) -> [f64; N] {
    let parents = refinement_parents(coarse, fine, i);
    std::array::from_fn(|k| {
        parents
            .iter()
            .filter(|(n, _)| *n != NONE)
            .map(|&(n, w)| w * inputs[k][n as usize])
            .sum::<f64>()
            * scales[k]
    })
}

/// The transpose of [`prolong`]: adds Σ_children w · `fine[child]` to every coarse node.
///
/// Fine brick by fine brick: the coarse nodes its nodes refine from (a 6×6×6 block) are looked
/// up once per brick, then every fine node adds to its eight parents, in node order and with
/// the parents `refinement_parents` gives (so sums come out the same as node by node). The
/// coarse nodes are cut into one run of whole coarse bricks per thread; each thread walks the
/// fine bricks that reach its run, in the same order, and adds only to its own nodes, so every
/// coarse node receives the same terms in the same order at any thread count.
pub fn restrict_into(coarse: &Level, fine: &Level, fine_values: &[f64], coarse_out: &mut [f64]) {
    let coarse_index = coarse.bricks();
    let bricks = coarse_index.brick_count();
    let parts = rayon::current_num_threads().clamp(1, bricks.max(1));
    let brick_bounds: Vec<usize> = (0..=parts).map(|p| p * bricks / parts).collect();
    let first_node = |b: usize| {
        if b < bricks {
            coarse_index.brick(b).0 as usize
        } else {
            coarse.len()
        }
    };
    let node_ranges = brick_bounds
        .windows(2)
        .map(|w| first_node(w[0])..first_node(w[1]));
    let outputs = split_parts(coarse_out, node_ranges);
    outputs
        .into_par_iter()
        .zip(brick_bounds.par_windows(2))
        .for_each(|(out, w)| {
            restrict_part(coarse, fine, fine_values, w[0]..w[1], first_node(w[0]), out)
        });
}

/// [`restrict_into`]'s work for the coarse bricks `coarse_bricks` (slots), whose nodes start at
/// `first` and are `out`.
fn restrict_part(
    coarse: &Level,
    fine: &Level,
    fine_values: &[f64],
    coarse_bricks: Range<usize>,
    first: usize,
    out: &mut [f64],
) {
    const SIDE: usize = 6;
    let fine_index = fine.bricks();
    let coarse_index = coarse.bricks();
    let mut window = [NONE; SIDE * SIDE * SIDE];
    for b in 0..fine_index.brick_count() {
        // (Every thread walks every fine brick: a cancelled solve skips the rest; see
        // `stop_requested`.)
        if b % 64 == 0 && stop_requested() {
            return;
        }
        let fine_origin = fine_index.origin(b);
        // Window coordinate w along an axis is coarse coordinate origin + w; it spans the two
        // coarse bricks from `coarse_brick`.
        let origin = fine_origin.map(|o| o.div_euclid(2) - 1);
        let coarse_brick = origin.map(|o| o.div_euclid(8) * 8);
        let slots: [Option<usize>; 8] = std::array::from_fn(|k| {
            coarse.brick_containing(std::array::from_fn(|a| {
                coarse_brick[a] + 8 * ((k >> a) & 1) as i32
            }))
        });
        if !slots
            .iter()
            .any(|s| s.is_some_and(|s| coarse_bricks.contains(&s)))
        {
            continue;
        }
        let walk = BrickNodes::new(fine_index, b);
        if walk
            .clone()
            .all(|(node, _)| fine_values[node as usize] == 0.0)
        {
            continue;
        }
        for (w, entry) in window.iter_mut().enumerate() {
            let w = [w % SIDE, w / SIDE % SIDE, w / (SIDE * SIDE)];
            // The coordinate relative to the first coarse brick of each axis (0..16).
            let c: [i32; 3] = std::array::from_fn(|a| origin[a] + w[a] as i32 - coarse_brick[a]);
            let k = (0..3).fold(0, |k, a| k | ((c[a] >= 8) as usize) << a);
            *entry = slots[k].map_or(NONE, |slot| {
                coarse_index.node_in(slot, c.map(|v| (v & 7) as usize))
            });
        }
        for (node, l) in walk {
            let v = fine_values[node as usize];
            if v == 0.0 {
                continue;
            }
            let weights = parent_weights(fine.degree, l.map(|c| c & 1));
            // Parent at window coordinate l/2 + 1, partners one step towards the node's side.
            let at = |k: usize| {
                let c: [usize; 3] = std::array::from_fn(|a| {
                    let partner = if (k >> a) & 1 == 0 {
                        0
                    } else if l[a] & 1 == 0 {
                        -1
                    } else {
                        1
                    };
                    (l[a] as i32 / 2 + 1 + partner) as usize
                });
                window[c[0] + SIDE * (c[1] + SIDE * c[2])]
            };
            let mut parents = [NONE; 8];
            for k in 0..8 {
                // Reached as refinement_parents reaches it: missing when the one it steps
                // from (k without its highest axis bit) is.
                parents[k] = if k == 0 {
                    at(0)
                } else {
                    let axis = 7 - (k as u8).leading_zeros() as usize;
                    if parents[k & !(1 << axis)] == NONE {
                        NONE
                    } else {
                        at(k)
                    }
                };
                // Only this part's nodes (NONE, u32::MAX, is past every part).
                if let Some(sum) = (parents[k] as usize)
                    .checked_sub(first)
                    .and_then(|i| out.get_mut(i))
                {
                    *sum += weights[k] * v;
                }
            }
        }
    }
}

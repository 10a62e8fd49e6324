//! Brick windows: the operators' 1-D passes on dense 12³ windows gathered brick by brick.
//!
//! A brick is an 8×8×8 block of the Morton index ([`crate::octree::BrickIndex`]). The stencils
//! of a brick's nodes read the input within two nodes of it: a window of [`WINDOW`]³ positions
//! gathered from the 27 bricks around, in which the tensor-product operators run as three 1-D
//! passes (5 taps each; 3 at degree 1, whose outer taps are zero) on a dense local array instead
//! of 125-entry rows. Every output comes from its own brick, so bricks run in parallel with no
//! halo-sized buffer. The AVX-512 and POPCNT variants of the passes and gathers live in
//! [`super::simd`].

use super::screening::{Proxies, ScreeningCells, PADDED};
use crate::bspline::{Degree, Tables};
use crate::octree::{brick_local, BrickIndex, Level};
use crate::parallel::{split_parts, stop_requested};
use rayon::prelude::*;

/// The nodes of one brick in key order, as (node index, brick-local coordinates): a node's
/// index is one more than the previous one's, not searched or counted.
#[derive(Clone)]
pub(super) struct BrickNodes<'a> {
    occupied: &'a [u64; 8],
    word: usize,
    bits: u64,
    node: u32,
}

impl<'a> BrickNodes<'a> {
    #[inline(always)]
    pub(super) fn new(index: &'a BrickIndex, b: usize) -> Self {
        let (node, occupied) = index.brick(b);
        BrickNodes {
            occupied,
            word: 0,
            bits: occupied[0],
            node,
        }
    }
}

impl Iterator for BrickNodes<'_> {
    type Item = (u32, [usize; 3]);

    #[inline(always)]
    fn next(&mut self) -> Option<(u32, [usize; 3])> {
        while self.bits == 0 {
            self.word += 1;
            if self.word == 8 {
                return None;
            }
            self.bits = self.occupied[self.word];
        }
        let bit = self.bits.trailing_zeros() as usize;
        self.bits &= self.bits - 1;
        let node = self.node;
        self.node += 1;
        let l = BRICK_LOCAL[self.word * 64 + bit];
        Some((node, [l[0] as usize, l[1] as usize, l[2] as usize]))
    }
}

/// [`brick_local`] of every position, looked up rather than computed in the bit walks.
static BRICK_LOCAL: [[u8; 3]; 512] = {
    let mut table = [[0u8; 3]; 512];
    let mut p = 0;
    while p < 512 {
        let mut axis = 0;
        while axis < 3 {
            let q = p >> axis;
            table[p][axis] = ((q & 1) | (q >> 2 & 2) | (q >> 4 & 4)) as u8;
            axis += 1;
        }
        p += 1;
    }
    table
};

/// Nodes across a brick's window: the brick's 8 and two on each side.
pub(super) const WINDOW: usize = 12;

/// The bricks (8×8×8 blocks of the Morton index, see [`crate::octree::BrickIndex`]) that hold
/// core nodes. The Laplacian at a brick's core nodes reads the input within two nodes of the
/// brick: a 12×12×12 window gathered from the 27 bricks around, in which the three 1-D passes
/// run on a dense local array. Every core node's output comes from its own brick, so no
/// halo-sized buffer is needed and bricks run in parallel.
pub(super) struct CoreBricks {
    /// Slots of the 27 bricks around each core brick (index (dx+1) + 3(dy+1) + 9(dz+1);
    /// `u32::MAX` where no node lies).
    pub(super) around: Vec<[u32; 27]>,
    /// Position in the level's core list of each core brick's first core node.
    pub(super) first_core: Vec<u32>,
    /// Which positions of each core brick hold core nodes.
    pub(super) core_mask: Vec<[u64; 8]>,
}

/// For each of the 27 bricks around a brick, the positions whose window coordinates (local
/// coordinate + 8·offset + 2) all lie in 0..12.
pub(super) fn window_regions() -> &'static [[u64; 8]; 27] {
    static REGIONS: std::sync::OnceLock<[[u64; 8]; 27]> = std::sync::OnceLock::new();
    REGIONS.get_or_init(|| {
        std::array::from_fn(|slot| {
            let offset = [slot % 3, slot / 3 % 3, slot / 9].map(|o| o as i64 - 1);
            let mut mask = [0u64; 8];
            for p in 0..512 {
                let l = brick_local(p);
                if (0..3).all(|a| (0..WINDOW as i64).contains(&(l[a] as i64 + 8 * offset[a] + 2))) {
                    mask[p >> 6] |= 1 << (p & 63);
                }
            }
            mask
        })
    })
}

/// Scratch space of one task: the z-pass values (up to three arrays) and the y-pass values
/// (two), rows of [`WINDOW`] along x.
pub(super) struct BrickScratch {
    pub(super) z: [Vec<[f64; WINDOW]>; 3],
    pub(super) y: [Vec<[f64; WINDOW]>; 2],
    /// A coarser depth's field on the 8×8×8 coarse nodes whose refinement covers the window
    /// (index x + 8y + 64z), when the window is a prolongation
    /// ([`CoreBricks::gather_prolonged`]).
    pub(super) coarse: [Vec<f64>; 3],
    /// The prolongation of `coarse` at every position of the window, node or not.
    pub(super) prolonged: [Vec<[f64; WINDOW]>; 3],
    /// The screening term at the brick's positions and two nodes around them (index
    /// [`padded`](super::screening::padded)`(x, y, z)` for brick-local x, y, z in −2..10).
    pub(super) screened: Box<[f64; PADDED]>,
}

impl BrickScratch {
    #[inline(always)]
    pub(super) fn laplacian_passes_portable<const REACH: usize>(
        &mut self,
        w: &[[f64; WINDOW]],
        t: &Tables,
    ) {
        for zl in 0..8 {
            for yw in 0..WINDOW {
                let at = zl * WINDOW + yw;
                let rows = rows5(w, at, WINDOW);
                self.z[0][at] = row_sum::<REACH>(&t.mass, rows);
                self.z[1][at] = row_sum::<REACH>(&t.stiffness, rows);
            }
        }
        for zl in 0..8 {
            for yl in 0..8 {
                let (at, z) = (zl * WINDOW + yl, &self.z);
                let (a, b) = (rows5(&z[0], at, 1), rows5(&z[1], at, 1));
                let mass_a = row_sum::<REACH>(&t.mass, a);
                let mixed = add_rows(
                    row_sum::<REACH>(&t.stiffness, a),
                    row_sum::<REACH>(&t.mass, b),
                );
                self.y[0][zl * 8 + yl] = mass_a;
                self.y[1][zl * 8 + yl] = mixed;
            }
        }
    }

    /// The x-pass at the core nodes: `scale·(Σ taps[0]·y₀ + Σ taps[1]·y₁)` along x.
    pub(super) fn x_pass<const REACH: usize>(
        &self,
        core_nodes: CoreNodes<'_>,
        taps: [&[f64; 5]; 2],
        scale: f64,
    ) {
        core_nodes.for_each(|o, [x, y, z]| {
            let a: [f64; 5] = self.y[0][z * 8 + y][x..x + 5].try_into().unwrap();
            let b: [f64; 5] = self.y[1][z * 8 + y][x..x + 5].try_into().unwrap();
            *o = scale * (window_sum::<REACH>(taps[0], &a) + window_sum::<REACH>(taps[1], &b));
        });
    }
}

/// The core nodes of one brick, each with its output element (the brick's part of the output,
/// in core order) and its coordinates in the brick, for a kernel of
/// [`CoreBricks::for_each_brick`]. A concrete type rather than a `dyn Iterator`, so that the
/// kernels' per-node loops are inlined: the dynamic call per node was about half the time of
/// the Laplacian's x-pass.
pub(super) struct CoreNodes<'a> {
    out: &'a mut [f64],
    mask: &'a [u64; 8],
}

impl CoreNodes<'_> {
    /// `f(output element, [x, y, z] in the brick)` for every core node, in core order.
    #[inline(always)]
    pub(super) fn for_each(self, mut f: impl FnMut(&mut f64, [usize; 3])) {
        let mut outputs = self.out.iter_mut();
        for (word, &bits) in self.mask.iter().enumerate() {
            let mut bits = bits;
            while bits != 0 {
                let p = word * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let l = BRICK_LOCAL[p];
                let o = outputs.next().expect("one output per core node");
                f(o, [l[0] as usize, l[1] as usize, l[2] as usize]);
            }
        }
    }
}

/// Element-wise a + b.
#[inline]
pub(super) fn add_rows(a: [f64; WINDOW], b: [f64; WINDOW]) -> [f64; WINDOW] {
    std::array::from_fn(|x| a[x] + b[x])
}

/// The five rows `rows[start + k·stride]`, k = 0..5.
#[inline]
pub(super) fn rows5(rows: &[[f64; WINDOW]], start: usize, stride: usize) -> [&[f64; WINDOW]; 5] {
    std::array::from_fn(|k| &rows[start + k * stride])
}

/// row-wise Σ_δ taps[δ+2]·rows[δ+2] over |δ| ≤ `REACH` (each element summed in the order of
/// [`window_sum`]).
#[inline(always)]
pub(super) fn row_sum<const REACH: usize>(
    taps: &[f64; 5],
    rows: [&[f64; WINDOW]; 5],
) -> [f64; WINDOW] {
    std::array::from_fn(|x| {
        if REACH == 1 {
            taps[2] * rows[2][x] + taps[1] * rows[1][x] + taps[3] * rows[3][x]
        } else {
            taps[2] * rows[2][x]
                + taps[1] * rows[1][x]
                + taps[0] * rows[0][x]
                + taps[3] * rows[3][x]
                + taps[4] * rows[4][x]
        }
    })
}

/// Σ_δ taps[δ+2] · window[δ+2] over |δ| ≤ `REACH`, in the order centre, −1, −2, +1, +2.
///
/// `REACH` is the tables' reach ([`Degree::table_reach`]): degree 1's taps at δ = ±2 are zero, and leaving
/// out a product that is exactly zero changes no sum (at most the sign of a zero), so the
/// 3-tap sums give the 5-tap sums' values with 40 % fewer operations.
#[inline(always)]
fn window_sum<const REACH: usize>(taps: &[f64; 5], window: &[f64; 5]) -> f64 {
    if REACH == 1 {
        taps[2] * window[2] + taps[1] * window[1] + taps[3] * window[3]
    } else {
        taps[2] * window[2]
            + taps[1] * window[1]
            + taps[0] * window[0]
            + taps[3] * window[3]
            + taps[4] * window[4]
    }
}

impl CoreBricks {
    pub(super) fn new(level: &Level) -> CoreBricks {
        let index = level.bricks();
        // Per brick holding core nodes: its 27 bricks around, its first core position, its mask.
        type Found = Option<([u32; 27], u32, [u64; 8])>;
        let found: Vec<Found> = (0..index.brick_count())
            .into_par_iter()
            .map(|b| {
                let nodes = index.nodes(b);
                let first = nodes.start as u32;
                let mut mask = [0u64; 8];
                for i in nodes {
                    if level.flags[i] & crate::octree::CORE != 0 {
                        let p = (level.keys[i] & 511) as usize;
                        mask[p >> 6] |= 1 << (p & 63);
                    }
                }
                if mask == [0; 8] {
                    return None;
                }
                let first_core = level.core.partition_point(|&c| c < first) as u32;
                let around = index
                    .bricks_around27(b)
                    .map(|s| s.map_or(u32::MAX, |s| s as u32));
                Some((around, first_core, mask))
            })
            .collect();
        let mut bricks = CoreBricks {
            around: Vec::new(),
            first_core: Vec::new(),
            core_mask: Vec::new(),
        };
        for (around, first_core, mask) in found.into_iter().flatten() {
            bricks.around.push(around);
            bricks.first_core.push(first_core);
            bricks.core_mask.push(mask);
        }
        bricks
    }

    /// Every brick of K_d with all its nodes as the "core": the passes of [`CoreBricks`] then
    /// give their values at every node of K_d, in K_d's order.
    pub(super) fn whole_level(level: &Level) -> CoreBricks {
        let index = level.bricks();
        let count = index.brick_count();
        CoreBricks {
            around: (0..count)
                .map(|b| {
                    index
                        .bricks_around27(b)
                        .map(|s| s.map_or(u32::MAX, |s| s as u32))
                })
                .collect(),
            first_core: (0..count).map(|b| index.brick(b).0).collect(),
            core_mask: (0..count).map(|b| *index.brick(b).1).collect(),
        }
    }

    /// `out[c]` = h·(D⊗M⊗M + M⊗D⊗M + M⊗M⊗D)·input at every core node c (in core order), plus,
    /// with `weighted_chi` = (cells, proxies, W_q χ(q) by slot), W_q χ(q) at every proxy in a core
    /// brick's window for χ = input (the screening term's first half, see `DepthOperator::apply`).
    pub(super) fn laplacian(
        &self,
        level: &Level,
        input: &[f64],
        h: f64,
        weighted_chi: Option<(&ScreeningCells, &Proxies, &mut [f64])>,
        out: &mut [f64],
    ) {
        match level.degree.table_reach() {
            1 => self.laplacian_reaching::<1>(level, input, h, weighted_chi, out),
            _ => self.laplacian_reaching::<2>(level, input, h, weighted_chi, out),
        }
    }

    /// [`CoreBricks::laplacian`] with passes of `REACH` nodes each side
    /// ([`Degree::table_reach`]).
    fn laplacian_reaching<const REACH: usize>(
        &self,
        level: &Level,
        input: &[f64],
        h: f64,
        weighted_chi: Option<(&ScreeningCells, &Proxies, &mut [f64])>,
        out: &mut [f64],
    ) {
        let t = level.degree.tables();
        let (screening, chi_parts): (_, Vec<&mut [f64]>) = match weighted_chi {
            Some((cells, proxies, chi)) => {
                let bricks =
                    (0..self.len()).map(|cb| cells.slots_in_brick(self.around[cb][13] as usize));
                (Some((cells, proxies)), split_parts(chi, bricks))
            }
            None => (None, (0..self.len()).map(|_| Default::default()).collect()),
        };
        self.for_each_brick(
            |cb, [window], _| self.gather_values(level, cb, input, window),
            out,
            chi_parts,
            |[w], scratch, cb, core_nodes, chi| {
                if let Some((cells, proxies)) = screening {
                    // W_q·χ(q) at the proxies of the cells in this brick, from the window.
                    cells.weigh_in_window(self.around[cb][13] as usize, proxies, w, chi);
                }
                scratch.laplacian_passes::<REACH>(w, t);
                scratch.x_pass::<REACH>(core_nodes, [&t.stiffness, &t.mass], h);
            },
        );
    }

    /// `out[c]` = ⟨∇B_c, V⟩ = (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)) at every
    /// core node c, for V's coefficients `v(n)` on K_d, with the 1-D tables `t` of the level's
    /// degree.
    pub(super) fn divergence(
        &self,
        fill: impl Fn(usize, &mut [Vec<[f64; WINDOW]>; 3], &mut BrickScratch) + Sync,
        degree: Degree,
        inv_h: f64,
        out: &mut [f64],
    ) {
        let t = degree.tables();
        match degree.table_reach() {
            1 => self.divergence_reaching::<1>(fill, t, inv_h, out),
            _ => self.divergence_reaching::<2>(fill, t, inv_h, out),
        }
    }

    /// [`CoreBricks::divergence`] with passes of `REACH` nodes each side
    /// ([`Degree::table_reach`]).
    fn divergence_reaching<const REACH: usize>(
        &self,
        fill: impl Fn(usize, &mut [Vec<[f64; WINDOW]>; 3], &mut BrickScratch) + Sync,
        t: &Tables,
        inv_h: f64,
        out: &mut [f64],
    ) {
        self.for_each_brick(
            fill,
            out,
            vec![(); self.len()],
            |[wx, wy, wz], scratch, _, core_nodes, ()| {
                for zl in 0..8 {
                    for yw in 0..WINDOW {
                        let at = zl * WINDOW + yw;
                        scratch.z[0][at] = row_sum::<REACH>(&t.mass, rows5(wx, at, WINDOW));
                        scratch.z[1][at] = row_sum::<REACH>(&t.mass, rows5(wy, at, WINDOW));
                        scratch.z[2][at] = row_sum::<REACH>(&t.advection, rows5(wz, at, WINDOW));
                    }
                }
                for zl in 0..8 {
                    for yl in 0..8 {
                        let (at, z) = (zl * WINDOW + yl, &scratch.z);
                        let mixed = add_rows(
                            row_sum::<REACH>(&t.advection, rows5(&z[1], at, 1)),
                            row_sum::<REACH>(&t.mass, rows5(&z[2], at, 1)),
                        );
                        let mass_x = row_sum::<REACH>(&t.mass, rows5(&z[0], at, 1));
                        scratch.y[0][zl * 8 + yl] = mass_x;
                        scratch.y[1][zl * 8 + yl] = mixed;
                    }
                }
                scratch.x_pass::<REACH>(core_nodes, [&t.advection, &t.mass], inv_h);
            },
        );
    }

    /// For every core brick `cb` (in parallel): `fill(cb, windows, scratch)` fills the window of
    /// each of the C components, then `kernel(windows, scratch, cb, core nodes, part)` runs,
    /// where the core nodes come as (their output element, their coordinates in the brick) and
    /// `part` is the brick's own entry of `parts` (one per core brick: state that only this
    /// brick's task touches). Each task owns its brick's part of `out` (the brick's core nodes
    /// are consecutive in core order), so no two tasks share an element.
    pub(super) fn for_each_brick<const C: usize, P: Send>(
        &self,
        fill: impl Fn(usize, &mut [Vec<[f64; WINDOW]>; C], &mut BrickScratch) + Sync,
        out: &mut [f64],
        parts: Vec<P>,
        kernel: impl Fn(&[Vec<[f64; WINDOW]>; C], &mut BrickScratch, usize, CoreNodes<'_>, P) + Sync,
    ) {
        const BRICKS_PER_TASK: usize = 16;
        assert_eq!(parts.len(), self.len());
        let outs = split_parts(
            out,
            (0..self.len()).map(|cb| {
                let first = self.first_core[cb] as usize;
                first..first + self.core_count(cb)
            }),
        );
        outs.into_par_iter()
            .zip(parts)
            .enumerate()
            .with_min_len(BRICKS_PER_TASK)
            .for_each_init(
                || {
                    (
                        std::array::from_fn::<_, C, _>(|_| vec![[0.0; WINDOW]; WINDOW * WINDOW]),
                        BrickScratch {
                            z: std::array::from_fn(|_| vec![[0.0; WINDOW]; 8 * WINDOW]),
                            y: std::array::from_fn(|_| vec![[0.0; WINDOW]; 8 * 8]),
                            coarse: std::array::from_fn(|_| vec![0.0; 8 * 8 * 8]),
                            prolonged: std::array::from_fn(|_| {
                                vec![[0.0; WINDOW]; WINDOW * WINDOW]
                            }),
                            screened: Box::new([0.0; PADDED]),
                        },
                    )
                },
                |(windows, scratch), (cb, (out, part))| {
                    // (A cancelled solve skips the remaining bricks; see `stop_requested`.)
                    if stop_requested() {
                        return;
                    }
                    fill(cb, windows, scratch);
                    let core_nodes = CoreNodes {
                        out,
                        mask: &self.core_mask[cb],
                    };
                    kernel(windows, scratch, cb, core_nodes, part);
                },
            );
    }

    /// The number of core bricks.
    pub(super) fn len(&self) -> usize {
        self.around.len()
    }

    /// The number of core nodes in core brick `cb`.
    pub(super) fn core_count(&self, cb: usize) -> usize {
        self.core_mask[cb]
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    #[inline(always)]
    pub(super) fn gather_portable<const C: usize>(
        &self,
        level: &Level,
        cb: usize,
        read: &(impl Fn(usize) -> [f64; C] + Sync),
        windows: &mut [Vec<[f64; WINDOW]>; C],
    ) {
        for w in windows.iter_mut() {
            w.fill([0.0; WINDOW]);
        }
        self.for_each_window_group(level, cb, |mut node, present, [x, y, z]| {
            let mut corners = present;
            while corners != 0 {
                let c = corners.trailing_zeros() as usize;
                corners &= corners - 1;
                let row = (z + (c >> 2)) * WINDOW + y + (c >> 1 & 1);
                for (w, v) in windows.iter_mut().zip(read(node)) {
                    w[row][x + (c & 1)] = v;
                }
                node += 1;
            }
        });
    }

    /// Calls `group(first node, corners present, window coordinate of corner 0)` for every
    /// 2×2×2 group of nodes of K_d in the window of core brick `cb` that holds any: a group is
    /// one byte of a brick's occupancy word (corner c = x + 2y + 4z at bit c), and its nodes
    /// are consecutive in K_d's order. The window's parts of the bricks around are unions of
    /// whole groups (their bounds are even), see `window_regions`.
    #[inline(always)]
    pub(super) fn for_each_window_group(
        &self,
        level: &Level,
        cb: usize,
        mut group: impl FnMut(usize, u8, [usize; 3]),
    ) {
        self.for_each_window_word(level, cb, |slot, word, before, occ, wanted| {
            let offset = [slot % 3, slot / 3 % 3, slot / 9].map(|o| 8 * o);
            let mut bits = wanted;
            while bits != 0 {
                let byte = bits.trailing_zeros() as usize / 8;
                bits &= !(0xff << (8 * byte));
                let node = before + (occ & ((1u64 << (8 * byte)) - 1)).count_ones() as usize;
                // Window coordinate: local + 8·(offset − 1) + 2 = local + 8·offset − 6.
                let l = brick_local(word * 64 + byte * 8);
                group(
                    node,
                    (occ >> (8 * byte)) as u8,
                    [0, 1, 2].map(|a| l[a] + offset[a] - 6),
                );
            }
        });
    }

    /// Calls `word(slot, word index, its first node, occupancy, the occupancy in the window)`
    /// for every occupancy word of the 27 bricks around core brick `cb` (slots as in
    /// `around`) that has a node in the window; the word's nodes are consecutive in K_d's
    /// order from its first.
    #[inline(always)]
    pub(super) fn for_each_window_word(
        &self,
        level: &Level,
        cb: usize,
        mut word: impl FnMut(usize, usize, usize, u64, u64),
    ) {
        let index = level.bricks();
        let regions = window_regions();
        for (slot, &b) in self.around[cb].iter().enumerate() {
            if b == u32::MAX {
                continue;
            }
            let (first, occupied) = index.brick(b as usize);
            let mut before = first as usize;
            for (w, (&occ, &region)) in occupied.iter().zip(&regions[slot]).enumerate() {
                let wanted = occ & region;
                if wanted != 0 {
                    word(slot, w, before, occ, wanted);
                }
                before += occ.count_ones() as usize;
            }
        }
    }
}

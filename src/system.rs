//! Stage 5 — the linear system (§4.3), applied matrix-free.
//!
//! At depth d the unknowns are the coefficients x_o of the core nodes. The system is
//!
//! ```text
//!   Σ_o′ ( ⟨∇B_o, ∇B_o′⟩ + α·2^d·Σ_q W_q B_o(q) B_o′(q) ) x_o′ = ⟨∇B_o, V⟩ − (same operator)(χ_coarser)
//! ```
//!
//! the Laplacian (the paper's L up to sign: ⟨ΔF, F′⟩ = −⟨∇F, ∇F′⟩) plus the screening term of
//! Kazhdan & Hoppe 2013 over "proxy" samples q (the weighted mean of the samples in each node,
//! with their summed weight W_q). The 2^d factor keeps the balance between the two terms the same
//! at every depth (the Laplacian's entries scale with the node width, the screening's with its
//! square). α = 0 is the 2006 method.
//!
//! Same-depth stencils are tensor products of the 1-D tables of [`crate::bspline`], so they are
//! applied as three 1-D passes (5 taps each) instead of 125-entry rows:
//! `⟨∇B_o, ∇B_o′⟩ = h (D⊗M⊗M + M⊗D⊗M + M⊗M⊗D)` and `⟨∇B_o, F̃_o′⟩·v = (1/h)(G⊗M⊗M vx + …)`.
//! The passes run brick by brick on dense 12³ windows gathered from the halo (`CoreBricks`):
//! over the bricks holding core nodes for the operator in the solve, over every brick of K_d
//! for the right-hand side's divergence on the whole halo (restricted to coarser depths).
//! The screening term runs on the same core windows (`ScreeningCells`). Both are exact wherever
//! the input is supported on K_d (see [`crate::octree`]): every node a core node's stencil
//! reaches is in the halo.
//!
//! Cross-depth terms use the two-scale relation ([`crate::bspline::REFINE`]) instead of
//! cross-depth tables: coarser coefficients are prolonged into the current depth's halo, and the
//! divergence of finer vector-field coefficients is restricted to coarser nodes. Both are exact.

use crate::bspline::{tables, Tables, REFINE};
use crate::octree::{axis_interval_masks, brick_local, AxisStep, BrickIndex, Level, NONE};
use glam::DVec3;
use rayon::prelude::*;

/// Rows per parallel task: fixed, so results never depend on the thread count.
pub const CHUNK: usize = 4096;

/// The nodes of one brick in key order, as (node index, brick-local coordinates): a node's
/// index is one more than the previous one's, not searched or counted.
#[derive(Clone)]
struct BrickNodes<'a> {
    occupied: &'a [u64; 8],
    word: usize,
    bits: u64,
    node: u32,
}

impl<'a> BrickNodes<'a> {
    #[inline(always)]
    fn new(index: &'a BrickIndex, b: usize) -> Self {
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

/// Neumann boundaries: sets every mirror node outside the cube to the value of the inside node it
/// reflects, so free-space stencils act as the folded (even) basis (no-op with free boundaries).
pub fn fill_mirrors(level: &Level, x: &mut [f64]) {
    for m in &level.mirrors {
        x[m.outside as usize] = x[m.inside as usize];
    }
}

/// [`fill_mirrors`] for a vector field: a component normal to a reflecting face changes sign.
pub fn fill_mirrors_field(level: &Level, v: &mut [Vec<f64>; 3]) {
    for m in &level.mirrors {
        for (axis, comp) in v.iter_mut().enumerate() {
            let sign = if m.flips & (1 << axis) != 0 {
                -1.0
            } else {
                1.0
            };
            comp[m.outside as usize] = sign * comp[m.inside as usize];
        }
    }
}

/// Sets x[core node i] = f(i, x[core node i]) for every core position i (in parallel, in fixed
/// chunks), then refills the mirror nodes: how a vector that lives on the core is kept on K_d.
pub fn update_on_core(level: &Level, x: &mut [f64], f: impl Fn(usize, f64) -> f64 + Sync) {
    for_each_core_node(level, x, |i, _, v| *v = f(i, *v));
    fill_mirrors(level, x);
}

/// `f(core position, node, &mut x[node])` for every core node, in parallel chunks.
fn for_each_core_node(level: &Level, x: &mut [f64], f: impl Fn(usize, usize, &mut f64) + Sync) {
    let shared = SharedSlice::new(x);
    level
        .core
        .par_chunks(CHUNK)
        .enumerate()
        .for_each(|(c, nodes)| {
            for (j, &n) in nodes.iter().enumerate() {
                // SAFETY: core indices are distinct, so each element has one writer.
                f(c * CHUNK + j, n as usize, unsafe {
                    shared.get_mut(n as usize)
                });
            }
        });
}

/// The screening samples of one depth: the samples grouped by node cell at a finer "proxy
/// depth" (weighted mean position, summed weight), kept when their cell at this depth lies
/// within one node of the core (farther ones touch no core node function). Grouping at a finer
/// depth than the level's own keeps the proxies on the surface: the mean of the samples in a
/// large cell lies inside a convex surface by about width²/(8·radius).
#[derive(Debug, Default)]
pub struct Proxies {
    /// K_d index of the cell (at this depth) holding each proxy; proxies of one cell are
    /// consecutive.
    pub cell: Vec<u32>,
    /// Summed screening weight of the samples of each proxy.
    pub weight: Vec<f64>,
    /// The proxy's position in its cell, in cell widths (each coordinate in [0, 1]): 12 bytes
    /// a proxy, where its stencil would take 72 (see [`Proxies::stencil`]).
    pub offset: Vec<[f32; 3]>,
}

impl Proxies {
    /// Groups samples (`positions` sorted by Morton key at a depth ≥ `proxy_depth`, so that the
    /// samples of a cell are consecutive) into proxies at `proxy_depth` ≥ the level's depth. In
    /// parallel over pieces cut between groups (a fixed number of samples apart), appended in
    /// order.
    pub fn build(level: &Level, positions: &[DVec3], weights: &[f64], proxy_depth: u32) -> Proxies {
        const SAMPLES_PER_PIECE: usize = 1 << 14;
        let inv_proxy_h = (proxy_depth as f64).exp2();
        let group_of = |s: usize| cell_of(positions[s], inv_proxy_h);
        let n = positions.len();
        let mut cuts = vec![0];
        while let Some(&last) = cuts.last() {
            let mut cut = last + SAMPLES_PER_PIECE;
            if cut >= n {
                break;
            }
            while cut < n && group_of(cut) == group_of(cut - 1) {
                cut += 1;
            }
            cuts.push(cut);
        }
        cuts.push(n);
        let pieces: Vec<Proxies> = cuts
            .par_windows(2)
            .map(|piece| {
                let range = piece[0]..piece[1];
                Self::build_piece(
                    level,
                    &positions[range.clone()],
                    &weights[range],
                    proxy_depth,
                )
            })
            .collect();
        let mut proxies = Proxies::default();
        for piece in pieces {
            proxies.cell.extend(piece.cell);
            proxies.weight.extend(piece.weight);
            proxies.offset.extend(piece.offset);
        }
        proxies
    }

    /// [`Proxies::build`] on a run of samples that starts and ends between groups.
    fn build_piece(
        level: &Level,
        positions: &[DVec3],
        weights: &[f64],
        proxy_depth: u32,
    ) -> Proxies {
        let inv_h = (level.depth as f64).exp2();
        let inv_proxy_h = (proxy_depth as f64).exp2();
        let mut proxies = Proxies::default();
        let mut s = 0;
        while s < positions.len() {
            let group = cell_of(positions[s], inv_proxy_h);
            let mut sum_w = 0.0;
            let mut sum_p = DVec3::ZERO;
            while s < positions.len() && cell_of(positions[s], inv_proxy_h) == group {
                sum_w += weights[s];
                sum_p += positions[s] * weights[s];
                s += 1;
            }
            if sum_w <= 0.0 {
                continue;
            }
            let shift = proxy_depth - level.depth;
            let cell = [group[0] >> shift, group[1] >> shift, group[2] >> shift];
            let Some(idx) = level.find(cell) else {
                continue;
            };
            if level.flags[idx as usize] & crate::octree::NEAR == 0 {
                continue;
            }
            let t = sum_p / sum_w * inv_h;
            let offset = [t.x, t.y, t.z].map(|v| (v - v.floor()).clamp(0.0, 1.0) as f32);
            proxies.cell.push(idx);
            proxies.weight.push(sum_w);
            proxies.offset.push(offset);
        }
        proxies
    }

    pub fn len(&self) -> usize {
        self.cell.len()
    }

    /// b(t − centre) for the three nodes per axis around proxy `q`'s cell (cell − 1, cell,
    /// cell + 1), at the proxy: with f its offset in the cell, the degree-2 B-spline gives
    /// ½(1 − f)², ¾ − (f − ½)² and ½f².
    #[inline]
    pub fn stencil(&self, q: usize) -> [[f64; 3]; 3] {
        self.offset[q].map(|f| {
            let f = f as f64;
            let g = 1.0 - f;
            [0.5 * g * g, 0.75 - (f - 0.5) * (f - 0.5), 0.5 * f * f]
        })
    }

    pub fn is_empty(&self) -> bool {
        self.cell.is_empty()
    }
}

/// The node cell containing `p` at the depth of inverse width `inv_h`.
#[inline]
pub fn cell_of(p: DVec3, inv_h: f64) -> [i32; 3] {
    let t = (p * inv_h).floor();
    [t.x as i32, t.y as i32, t.z as i32]
}

/// Nodes across a brick's window: the brick's 8 and two on each side.
const WINDOW: usize = 12;

/// The bricks (8×8×8 blocks of the Morton index, see [`crate::octree::BrickIndex`]) that hold
/// core nodes. The Laplacian at a brick's core nodes reads the input within two nodes of the
/// brick: a 12×12×12 window gathered from the 27 bricks around, in which the three 1-D passes
/// run on a dense local array. Every core node's output comes from its own brick, so no
/// halo-sized buffer is needed and bricks run in parallel.
struct CoreBricks {
    /// Slots of the 27 bricks around each core brick (index (dx+1) + 3(dy+1) + 9(dz+1);
    /// `u32::MAX` where no node lies).
    around: Vec<[u32; 27]>,
    /// Position in the level's core list of each core brick's first core node.
    first_core: Vec<u32>,
    /// Which positions of each core brick hold core nodes.
    core_mask: Vec<[u64; 8]>,
}

/// For each of the 27 bricks around a brick, the positions whose window coordinates (local
/// coordinate + 8·offset + 2) all lie in 0..12.
fn window_regions() -> &'static [[u64; 8]; 27] {
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
struct BrickScratch {
    z: [Vec<[f64; WINDOW]>; 3],
    y: [Vec<[f64; WINDOW]>; 2],
    /// A coarser depth's field on the 8×8×8 coarse nodes whose refinement covers the window
    /// (index x + 8y + 64z), when the window is a prolongation
    /// ([`CoreBricks::gather_prolonged`]).
    coarse: [Vec<f64>; 3],
    /// The prolongation of `coarse` at every position of the window, node or not.
    prolonged: [Vec<[f64; WINDOW]>; 3],
    /// The screening term at the brick's positions and two nodes around them (index
    /// [`padded`]`(x, y, z)` for brick-local x, y, z in −2..10).
    screened: Box<[f64; PADDED]>,
}

impl BrickScratch {
    /// The Laplacian's z-pass (every row of the window at the brick's 8 depths: M and D
    /// along z) and y-pass (the brick's 8 × 8 rows: M_y M_z and D_y M_z + M_y D_z), leaving
    /// the x-pass's two inputs in `y`. The same code compiled for AVX-512 where the CPU has it
    /// (checked at run time): its 12-wide rows take 2 vector operations instead of SSE2's 6
    /// (0.090 -> 0.060 s per application at depth 10 on the Happy Buddha; AVX2 0.069 s). No
    /// fused multiply-adds and no reordering, so the values are the same bit for bit.
    fn laplacian_passes(&mut self, w: &[[f64; WINDOW]], t: &Tables) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has the feature the function is compiled for.
            unsafe { self.laplacian_passes_avx512(w, t) };
            return;
        }
        self.laplacian_passes_portable(w, t);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn laplacian_passes_avx512(&mut self, w: &[[f64; WINDOW]], t: &Tables) {
        self.laplacian_passes_portable(w, t);
    }

    #[inline(always)]
    fn laplacian_passes_portable(&mut self, w: &[[f64; WINDOW]], t: &Tables) {
        for zl in 0..8 {
            for yw in 0..WINDOW {
                let at = zl * WINDOW + yw;
                let rows = rows5(w, at, WINDOW);
                self.z[0][at] = row_sum(&t.mass, rows);
                self.z[1][at] = row_sum(&t.stiffness, rows);
            }
        }
        for zl in 0..8 {
            for yl in 0..8 {
                let (at, z) = (zl * WINDOW + yl, &self.z);
                let (a, b) = (rows5(&z[0], at, 1), rows5(&z[1], at, 1));
                let mass_a = row_sum(&t.mass, a);
                let mixed = add_rows(row_sum(&t.stiffness, a), row_sum(&t.mass, b));
                self.y[0][zl * 8 + yl] = mass_a;
                self.y[1][zl * 8 + yl] = mixed;
            }
        }
    }

    /// The x-pass at the core nodes: scale·(Σ taps[0]·y₀ + Σ taps[1]·y₁) along x.
    fn x_pass(
        &self,
        core_nodes: &mut dyn Iterator<Item = (&mut f64, [usize; 3])>,
        taps: [&[f64; 5]; 2],
        scale: f64,
    ) {
        for (o, [x, y, z]) in core_nodes {
            let a: [f64; 5] = self.y[0][z * 8 + y][x..x + 5].try_into().unwrap();
            let b: [f64; 5] = self.y[1][z * 8 + y][x..x + 5].try_into().unwrap();
            *o = scale * (window_sum(taps[0], &a) + window_sum(taps[1], &b));
        }
    }
}

/// Element-wise a + b.
#[inline]
fn add_rows(a: [f64; WINDOW], b: [f64; WINDOW]) -> [f64; WINDOW] {
    std::array::from_fn(|x| a[x] + b[x])
}

/// The five rows `rows[start + k·stride]`, k = 0..5.
#[inline]
fn rows5(rows: &[[f64; WINDOW]], start: usize, stride: usize) -> [&[f64; WINDOW]; 5] {
    std::array::from_fn(|k| &rows[start + k * stride])
}

/// row-wise Σ_δ taps[δ+2]·rows[δ+2] (each element summed in the order of [`window_sum`]).
#[inline]
fn row_sum(taps: &[f64; 5], rows: [&[f64; WINDOW]; 5]) -> [f64; WINDOW] {
    std::array::from_fn(|x| {
        taps[2] * rows[2][x]
            + taps[1] * rows[1][x]
            + taps[0] * rows[0][x]
            + taps[3] * rows[3][x]
            + taps[4] * rows[4][x]
    })
}

impl CoreBricks {
    fn new(level: &Level) -> CoreBricks {
        let index = level.bricks();
        let found: Vec<Option<([u32; 27], u32, [u64; 8])>> = (0..index.brick_count())
            .into_par_iter()
            .map(|b| {
                let (first, occupied) = index.brick(b);
                let count: u32 = occupied.iter().map(|w| w.count_ones()).sum();
                let mut mask = [0u64; 8];
                for i in first..first + count {
                    if level.flags[i as usize] & crate::octree::CORE != 0 {
                        let p = (level.keys[i as usize] & 511) as usize;
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
    fn whole_level(level: &Level) -> CoreBricks {
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

    /// out[c] = h·(D⊗M⊗M + M⊗D⊗M + M⊗M⊗D)·input at every core node c (in core order), plus,
    /// with `screening` = (cells, proxies, weight α), α·Σ_q W_q B_c(q) χ(q) for χ = input.
    fn laplacian(
        &self,
        level: &Level,
        input: &[f64],
        h: f64,
        weighted_chi: Option<(&ScreeningCells, &Proxies, &mut [f64])>,
        out: &mut [f64],
    ) {
        let t = tables();
        let weighted_chi =
            weighted_chi.map(|(cells, proxies, chi)| (cells, proxies, SharedSlice::new(chi)));
        self.for_each_brick(
            |cb, [window], _| self.gather_values(level, cb, input, window),
            out,
            |[w], scratch, cb, core_nodes| {
                if let Some((cells, proxies, chi)) = &weighted_chi {
                    // W_q·χ(q) at the proxies of the cells in this brick, from the window.
                    for cell in cells.in_brick(self.around[cb][13] as usize) {
                        let c = brick_local(cell.position as usize).map(|v| v + 2);
                        let mut x = [0.0; 27];
                        for (k, x) in x.chunks_exact_mut(3).enumerate() {
                            let row = &w[(c[2] + k / 3 - 1) * WINDOW + c[1] + k % 3 - 1];
                            x.copy_from_slice(&row[c[0] - 1..c[0] + 2]);
                        }
                        for q in cell.proxies.0 as usize..cell.proxies.1 as usize {
                            let value =
                                proxies.weight[q] * tensor_contract(&proxies.stencil(q), &x);
                            // SAFETY: each cell lies in one brick, handled by one task.
                            unsafe { *chi.get_mut(q) = value };
                        }
                    }
                }
                scratch.laplacian_passes(w, t);
                scratch.x_pass(core_nodes, [&t.stiffness, &t.mass], h);
            },
        );
    }

    /// out[c] = ⟨∇B_c, V⟩ = (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)) at every
    /// core node c, for V's coefficients `v(n)` on K_d.
    fn divergence(
        &self,
        fill: impl Fn(usize, &mut [Vec<[f64; WINDOW]>; 3], &mut BrickScratch) + Sync,
        inv_h: f64,
        out: &mut [f64],
    ) {
        let t = tables();
        self.for_each_brick(fill, out, |[wx, wy, wz], scratch, _, core_nodes| {
            for zl in 0..8 {
                for yw in 0..WINDOW {
                    let at = zl * WINDOW + yw;
                    scratch.z[0][at] = row_sum(&t.mass, rows5(wx, at, WINDOW));
                    scratch.z[1][at] = row_sum(&t.mass, rows5(wy, at, WINDOW));
                    scratch.z[2][at] = row_sum(&t.advection, rows5(wz, at, WINDOW));
                }
            }
            for zl in 0..8 {
                for yl in 0..8 {
                    let (at, z) = (zl * WINDOW + yl, &scratch.z);
                    let mixed = add_rows(
                        row_sum(&t.advection, rows5(&z[1], at, 1)),
                        row_sum(&t.mass, rows5(&z[2], at, 1)),
                    );
                    let mass_x = row_sum(&t.mass, rows5(&z[0], at, 1));
                    scratch.y[0][zl * 8 + yl] = mass_x;
                    scratch.y[1][zl * 8 + yl] = mixed;
                }
            }
            scratch.x_pass(core_nodes, [&t.advection, &t.mass], inv_h);
        });
    }

    /// For every core brick `cb` (in parallel): `fill(cb, windows, scratch)` fills the window of
    /// each of the C components, then `kernel(windows, scratch, cb, core nodes)` runs, where the
    /// core nodes come as (their output element, their coordinates in the brick).
    fn for_each_brick<const C: usize>(
        &self,
        fill: impl Fn(usize, &mut [Vec<[f64; WINDOW]>; C], &mut BrickScratch) + Sync,
        out: &mut [f64],
        kernel: impl Fn(
                &[Vec<[f64; WINDOW]>; C],
                &mut BrickScratch,
                usize,
                &mut dyn Iterator<Item = (&mut f64, [usize; 3])>,
            ) + Sync,
    ) {
        const BRICKS_PER_TASK: usize = 16;
        let out = SharedSlice::new(out);
        (0..self.around.len())
            .into_par_iter()
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
                |(windows, scratch), cb| {
                    fill(cb, windows, scratch);
                    let mask = &self.core_mask[cb];
                    let first = self.first_core[cb] as usize;
                    let out = &out;
                    let mut core_nodes = mask
                        .iter()
                        .enumerate()
                        .flat_map(|(word, &bits)| {
                            let mut bits = bits;
                            std::iter::from_fn(move || {
                                (bits != 0).then(|| {
                                    let p = word * 64 + bits.trailing_zeros() as usize;
                                    bits &= bits - 1;
                                    p
                                })
                            })
                        })
                        .enumerate()
                        // SAFETY: every core node lies in one brick, handled by one task.
                        .map(|(k, p)| (unsafe { out.get_mut(first + k) }, brick_local(p)));
                    kernel(windows, scratch, cb, &mut core_nodes);
                },
            );
    }

    /// The components on the window of core brick `cb` (zero where K_d has no node), node by
    /// node. Counting a group's rank in its brick is a population count: with the POPCNT
    /// instruction (checked at run time on x86-64) it is one instruction instead of a dozen.
    fn gather<const C: usize>(
        &self,
        level: &Level,
        cb: usize,
        read: &(impl Fn(usize) -> [f64; C] + Sync),
        windows: &mut [Vec<[f64; WINDOW]>; C],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU has the feature the function is compiled for.
            unsafe { self.gather_popcnt(level, cb, read, windows) };
            return;
        }
        self.gather_portable(level, cb, read, windows);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "popcnt")]
    unsafe fn gather_popcnt<const C: usize>(
        &self,
        level: &Level,
        cb: usize,
        read: &(impl Fn(usize) -> [f64; C] + Sync),
        windows: &mut [Vec<[f64; WINDOW]>; C],
    ) {
        self.gather_portable(level, cb, read, windows);
    }

    #[inline(always)]
    fn gather_portable<const C: usize>(
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

    /// [`CoreBricks::gather`] of one vector: on x86-64 CPUs with AVX-512 each 2×2×2 group is
    /// one expanding load (its nodes are consecutive in `input`) and four stores, half the
    /// time of the node-by-node walk on the Laplacian's windows; the same values either way.
    fn gather_values(
        &self,
        level: &Level,
        cb: usize,
        input: &[f64],
        window: &mut Vec<[f64; WINDOW]>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            // SAFETY: the CPU has the features the function is compiled for.
            unsafe { self.gather_values_avx512(level, cb, input, window) };
            return;
        }
        self.gather(level, cb, &|n| [input[n]], std::array::from_mut(window));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,popcnt")]
    unsafe fn gather_values_avx512(
        &self,
        level: &Level,
        cb: usize,
        input: &[f64],
        window: &mut [[f64; WINDOW]],
    ) {
        use std::arch::x86_64::*;
        window.fill([0.0; WINDOW]);
        let rows = window.len();
        let out = window.as_mut_ptr() as *mut f64;
        self.for_each_window_group(level, cb, |node, present, [x, y, z]| {
            // Corner c of the group (x + 2y + 4z) is lane c; lanes 2k, 2k + 1 are a pair of x
            // neighbours in window row (z + k/2, y + k%2).
            assert!(node + present.count_ones() as usize <= input.len());
            assert!((z + 1) * WINDOW + y + 1 < rows && x + 1 < WINDOW);
            // SAFETY: the load reads one element per set bit of `present` from `node` on, and
            // the stores write two elements at x in rows of the window (both checked above).
            unsafe {
                let v = _mm512_maskz_expandloadu_pd(present, input.as_ptr().add(node));
                let (low, high) = (
                    _mm512_extractf64x4_pd::<0>(v),
                    _mm512_extractf64x4_pd::<1>(v),
                );
                let at = |row: usize| out.add(row * WINDOW + x);
                _mm_storeu_pd(at(z * WINDOW + y), _mm256_castpd256_pd128(low));
                _mm_storeu_pd(at(z * WINDOW + y + 1), _mm256_extractf128_pd::<1>(low));
                _mm_storeu_pd(at((z + 1) * WINDOW + y), _mm256_castpd256_pd128(high));
                _mm_storeu_pd(
                    at((z + 1) * WINDOW + y + 1),
                    _mm256_extractf128_pd::<1>(high),
                );
            }
        });
    }

    /// Calls `group(first node, corners present, window coordinate of corner 0)` for every
    /// 2×2×2 group of nodes of K_d in the window of core brick `cb` that holds any: a group is
    /// one byte of a brick's occupancy word (corner c = x + 2y + 4z at bit c), and its nodes
    /// are consecutive in K_d's order. The window's parts of the bricks around are unions of
    /// whole groups (their bounds are even), see `window_regions`.
    #[inline(always)]
    fn for_each_window_group(
        &self,
        level: &Level,
        cb: usize,
        mut group: impl FnMut(usize, u8, [usize; 3]),
    ) {
        let index = level.bricks();
        let regions = window_regions();
        for (slot, &b) in self.around[cb].iter().enumerate() {
            if b == u32::MAX {
                continue;
            }
            let offset = [slot % 3, slot / 3 % 3, slot / 9].map(|o| 8 * o);
            let (first, occupied) = index.brick(b as usize);
            let mut before = first as usize;
            for (word, (&occ, &region)) in occupied.iter().zip(&regions[slot]).enumerate() {
                let mut bits = occ & region;
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
                before += occ.count_ones() as usize;
            }
        }
    }
}

impl CoreBricks {
    /// The window of core brick `cb` for `field` (a coarser field prolonged to this depth),
    /// with the values [`ProlongedField::at`] gives at each node of the window (zero where the
    /// fine depth has no node). The fine window covers fine coordinates origin − 2 .. origin + 10
    /// per axis; their refinement parents (m = ⌊f/2⌋ and its partner m ± 1) lie in the coarse
    /// coordinates origin/2 − 2 .. origin/2 + 6, gathered once into an 8×8×8 array from the
    /// eight coarse bricks that cover them. Each window node then sums its eight parents in
    /// the order and with the weights of [`refinement_parents`]. Nodes beyond the cube (mirrors,
    /// with Neumann boundaries) take the node-by-node path.
    fn gather_prolonged(
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
                &scratch.coarse[c],
                along_x,
                along_y,
                &mut scratch.prolonged[c],
                field.scale,
            );
        }

        // The fine window: the prolongation where K_d has a node, zero elsewhere (beyond the
        // cube, with Neumann mirrors, a node's value is its mirror image's).
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
                    if f.iter().any(|&v| v < 0 || v >= n) {
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
/// ([`refinement_parents`]). `along_x` (8·8 rows) and `along_y` (8·12 rows) are scratch space.
fn prolong_window(
    coarse: &[f64],
    along_x: &mut [[f64; WINDOW]],
    along_y: &mut [[f64; WINDOW]],
    out: &mut [[f64; WINDOW]],
    scale: f64,
) {
    let [quarter, three_quarters] = [REFINE[0], REFINE[1]];
    let partner = |w: usize| if w & 1 == 0 { w >> 1 } else { (w >> 1) + 2 };
    for (r, row) in along_x[..64].iter_mut().enumerate() {
        let line = &coarse[8 * r..8 * r + 8];
        *row = std::array::from_fn(|w| {
            three_quarters * line[(w >> 1) + 1] + quarter * line[partner(w)]
        });
    }
    for z in 0..8 {
        for w in 0..WINDOW {
            let (own, other) = (&along_x[8 * z + (w >> 1) + 1], &along_x[8 * z + partner(w)]);
            along_y[WINDOW * z + w] =
                std::array::from_fn(|x| three_quarters * own[x] + quarter * other[x]);
        }
    }
    for w in 0..WINDOW {
        for y in 0..WINDOW {
            let (own, other) = (
                &along_y[WINDOW * ((w >> 1) + 1) + y],
                &along_y[WINDOW * partner(w) + y],
            );
            out[WINDOW * w + y] =
                std::array::from_fn(|x| (three_quarters * own[x] + quarter * other[x]) * scale);
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
            std::array::from_fn(|a| origin[a].div_euclid(8) * 8 + 8 * ((k >> a) & 1) as i32);
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
        let (mut node, occupied) = index.brick(slot);
        for (word, (&occ, &region)) in occupied.iter().zip(&region).enumerate() {
            let mut bits = occ & region;
            while bits != 0 {
                let bit = bits.trailing_zeros();
                bits &= bits - 1;
                let n = node + (occ & ((1u64 << bit) - 1)).count_ones();
                let l = brick_local(word * 64 + bit as usize);
                let u: [usize; 3] =
                    std::array::from_fn(|a| (brick_origin[a] + l[a] as i32 - origin[a]) as usize);
                for (w, values) in window.iter_mut().zip(&fields) {
                    w[u[2] * 64 + u[1] * 8 + u[0]] = values[n as usize];
                }
            }
            node += occ.count_ones();
        }
    }
}

/// The prolongation (times `scale`) at fine coordinate `f` of the coarse values in `window`
/// (from [`coarse_window`] at `origin`): its eight refinement parents summed in the order and
/// with the weights of [`refinement_parents`].
#[inline]
fn prolonged_from_window<const C: usize>(
    window: &[Vec<f64>; C],
    origin: [i32; 3],
    f: [i32; 3],
    scale: f64,
) -> [f64; C] {
    // Per axis: the parent's and its partner's place in the window (as flat-index terms), then
    // parent k's place: bit a of k picks the partner along axis a.
    let place: [[usize; 2]; 3] = std::array::from_fn(|a| {
        let own = ((f[a] >> 1) - origin[a]) as usize;
        let partner = if f[a] & 1 == 1 { own + 1 } else { own - 1 };
        [own << (3 * a), partner << (3 * a)]
    });
    let parents: [usize; 8] =
        std::array::from_fn(|k| place[0][k & 1] + place[1][(k >> 1) & 1] + place[2][(k >> 2) & 1]);
    std::array::from_fn(|component| {
        let values = &window[component][..512];
        (0..8)
            .map(|k| PARENT_WEIGHTS[k] * values[parents[k]])
            .sum::<f64>()
            * scale
    })
}

/// `write(node, value)` for every node of `fine` with the prolongation of `fields` (times
/// `scale`) there, brick by brick in parallel: each fine brick gathers the coarse nodes under
/// it once ([`coarse_window`]). With `at_mirror`, nodes beyond the cube take `at_mirror(node)`
/// instead. Each node is written once, by the task of its brick.
fn prolong_by_brick<const C: usize>(
    coarse: &Level,
    fine: &Level,
    fields: [&[f64]; C],
    scale: f64,
    at_mirror: Option<&(dyn Fn(u32) -> [f64; C] + Sync)>,
    write: impl Fn(u32, [f64; C]) + Sync,
) {
    let n = 1i32 << fine.depth;
    let index = fine.bricks();
    (0..index.brick_count())
        .into_par_iter()
        .with_min_len(16)
        .for_each_init(
            || std::array::from_fn::<_, C, _>(|_| vec![0.0; 512]),
            |window, b| {
                let origin = fine.bricks().origin(b);
                let coarse_origin: [i32; 3] = std::array::from_fn(|a| origin[a] / 2 - 2);
                coarse_window(coarse, coarse_origin, fields, window);
                let (mut node, occupied) = index.brick(b);
                for (word, &occ) in occupied.iter().enumerate() {
                    let mut bits = occ;
                    while bits != 0 {
                        let bit = bits.trailing_zeros();
                        bits &= bits - 1;
                        let l = brick_local(word * 64 + bit as usize);
                        let f: [i32; 3] = std::array::from_fn(|a| origin[a] + l[a] as i32);
                        let value = match at_mirror {
                            Some(at) if f.iter().any(|&v| v < 0 || v >= n) => at(node),
                            _ => prolonged_from_window(window, coarse_origin, f, scale),
                        };
                        write(node, value);
                        node += 1;
                    }
                }
            },
        );
}

/// Σ_δ taps[δ+2] · window[δ+2], in the order centre, −1, −2, +1, +2.
#[inline]
fn window_sum(taps: &[f64; 5], window: &[f64; 5]) -> f64 {
    taps[2] * window[2]
        + taps[1] * window[1]
        + taps[0] * window[0]
        + taps[3] * window[3]
        + taps[4] * window[4]
}

/// The operator A_d = L_d + S_d of one depth, with its scratch space.
pub struct DepthOperator<'a> {
    pub level: &'a Level,
    pub proxies: &'a Proxies,
    /// Weight of the screening term.
    pub screening: f64,
    /// The bricks holding core nodes: the Laplacian is applied brick by brick.
    bricks: CoreBricks,
    /// The cells whose proxies screen this depth, by brick (`None` without screening).
    screening_cells: Option<ScreeningCells>,
    /// W_q χ(q) at every proxy during a product (empty without screening).
    weighted_chi: Vec<f64>,
}

impl<'a> DepthOperator<'a> {
    /// `screening` is the weight α_d of the screening term at this depth.
    pub fn new(level: &'a Level, proxies: &'a Proxies, screening: f64) -> Self {
        let screens = screening > 0.0 && !proxies.is_empty();
        let bricks = CoreBricks::new(level);
        let screening_cells = screens.then(|| ScreeningCells::new(level, proxies, &bricks));
        DepthOperator {
            level,
            proxies,
            screening,
            bricks,
            screening_cells,
            weighted_chi: if screens {
                vec![0.0; proxies.len()]
            } else {
                Vec::new()
            },
        }
    }

    /// `out[c]` = (A · input)(core node c), for `input` given on all of K_d with its mirror
    /// nodes filled (see [`fill_mirrors`]): the prolonged coarser solution, or a
    /// conjugate-gradient direction (zero beyond the core but at the mirrors, see
    /// [`update_on_core`]).
    ///
    /// The Laplacian h·(D⊗M⊗M + M⊗D⊗M + M⊗M⊗D) is applied brick by brick (see `CoreBricks`);
    /// the screening term α·Σ_q W_q B_o(q) χ(q) in two sweeps over the bricks (see
    /// `ScreeningCells`): W_q χ(q) at every proxy, read from the Laplacian's input window of the
    /// proxy's brick, then each core brick collects from the proxies within one node of it.
    pub fn apply(&mut self, input: &[f64], out: &mut [f64]) {
        let level = self.level;
        let proxies = self.proxies;
        let bricks = &self.bricks;
        let Some(cells) = &self.screening_cells else {
            bricks.laplacian(level, input, level.width(), None, out);
            return;
        };
        let chi = &mut self.weighted_chi;
        bricks.laplacian(
            level,
            input,
            level.width(),
            Some((cells, proxies, chi)),
            out,
        );
        cells.weigh_outside_core_bricks(level, proxies, input, chi);
        let chi = &*chi;
        let scale = self.screening;
        bricks.for_each_brick::<0>(
            |_, _, _| {},
            out,
            |_, scratch, cb, core_nodes| {
                let acc = &mut scratch.screened;
                acc.fill(0.0);
                cells.accumulate(level, cb, &bricks.around[cb], acc, |range, contribution| {
                    for q in range {
                        tensor_accumulate(&proxies.stencil(q), chi[q], contribution);
                    }
                });
                for (o, [x, y, z]) in core_nodes {
                    *o += scale * acc[padded(x, y, z)];
                }
            },
        );
    }

    /// ⟨∇B_o, V⟩ at every core node (in core order) for a field V whose coefficients on K_d
    /// (x, y, z at node n) `v(n)` gives: [`divergence`] restricted to the core, computed brick
    /// by brick as (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)). `v` is called
    /// once per node for every brick window it lies in (about 3.4 times on average). The
    /// pipeline uses [`divergence_of_prolonged`]; this is the node-by-node
    /// reference the tests check it and [`divergence`] against.
    #[cfg(test)]
    pub fn divergence_on_core(&mut self, v: impl Fn(usize) -> [f64; 3] + Sync) -> Vec<f64> {
        let level = self.level;
        let bricks = &self.bricks;
        let mut out = vec![0.0; level.core.len()];
        bricks.divergence(
            |cb, windows, _| bricks.gather(level, cb, &v, windows),
            1.0 / level.width(),
            &mut out,
        );
        out
    }

    /// The diagonal of A on the core (for Jacobi preconditioning).
    pub fn diagonal(&mut self) -> Vec<f64> {
        let level = self.level;
        let t = tables();
        let lap = level.width() * 3.0 * t.stiffness[2] * t.mass[2] * t.mass[2];
        let mut out = vec![lap; level.core.len()];
        let Some(cells) = &self.screening_cells else {
            return out;
        };
        let proxies = self.proxies;
        let scale = self.screening;
        self.bricks.for_each_brick::<0>(
            |_, _, _| {},
            &mut out,
            |_, scratch, cb, core_nodes| {
                let acc = &mut scratch.screened;
                acc.fill(0.0);
                cells.accumulate(
                    level,
                    cb,
                    &self.bricks.around[cb],
                    acc,
                    |range, contribution| {
                        for q in range {
                            let squared = proxies.stencil(q).map(|axis| axis.map(|b| b * b));
                            tensor_accumulate(&squared, proxies.weight[q], contribution);
                        }
                    },
                );
                for (o, [x, y, z]) in core_nodes {
                    *o = lap + scale * acc[padded(x, y, z)];
                }
            },
        );
        out
    }
}

/// Σ_slot x[slot] · st[0][slot % 3] · st[1][slot / 3 % 3] · st[2][slot / 9] (x fastest), one
/// axis at a time (39 multiplications instead of 81).
#[inline]
fn tensor_contract(st: &[[f64; 3]; 3], x: &[f64; 27]) -> f64 {
    let mut sum = 0.0;
    for (z, plane) in x.chunks_exact(9).enumerate() {
        let mut plane_sum = 0.0;
        for (y, row) in plane.chunks_exact(3).enumerate() {
            plane_sum += st[1][y] * (st[0][0] * row[0] + st[0][1] * row[1] + st[0][2] * row[2]);
        }
        sum += st[2][z] * plane_sum;
    }
    sum
}

/// out[slot] += w · st[0][slot % 3] · st[1][slot / 3 % 3] · st[2][slot / 9] (the transpose of
/// [`tensor_contract`]).
#[inline]
fn tensor_accumulate(st: &[[f64; 3]; 3], w: f64, out: &mut [f64; 27]) {
    for z in 0..3 {
        let wz = w * st[2][z];
        for y in 0..3 {
            let wzy = wz * st[1][y];
            for x in 0..3 {
                out[9 * z + 3 * y + x] += wzy * st[0][x];
            }
        }
    }
}

/// A brick's positions with two nodes of padding on each side, [`WINDOW`]³ of them.
const PADDED: usize = WINDOW * WINDOW * WINDOW;

/// The index of brick-local position (x, y, z) (each in −2..10, shifted by 2) in a padded
/// brick array.
#[inline]
fn padded(x: usize, y: usize, z: usize) -> usize {
    (x + 2) + WINDOW * ((y + 2) + WINDOW * (z + 2))
}

/// The cells of K_d holding proxies, grouped by brick, for the screening term
/// Σ_q W_q B_o(q) χ(q) at a core node o: a core brick's nodes collect from the cells within one
/// node of the brick (in its own and the 26 bricks around), each reading χ at its proxies from
/// the 3×3×3 nodes around it in the brick's input window, which the Laplacian gathered anyway.
/// No halo-sized sum, no random gather or scatter; a cell near a brick's edge is visited by
/// each brick it touches (about twice on average).
struct ScreeningCells {
    /// Per brick slot of K_d, the range of `cells` in it.
    brick_start: Vec<u32>,
    cells: Vec<ScreeningCell>,
    /// Per core brick (in `CoreBricks` order), the range of `near`.
    near_start: Vec<u32>,
    /// The cells within one node of each core brick, with their window coordinates there.
    near: Vec<NearCell>,
    /// The cells (node index and index in `cells`) in bricks without core nodes, whose
    /// proxies no core brick's window covers: found node by node (few, at the core's edge).
    outside_core_bricks: Vec<(u32, u32)>,
}

/// A cell within one node of a core brick: its index in `ScreeningCells::cells` and its
/// coordinates in the brick's window (local + 2, so 1..=10).
#[derive(Debug, Clone, Copy)]
struct NearCell {
    cell: u32,
    window: [u8; 3],
}

#[derive(Debug, Clone, Copy)]
struct ScreeningCell {
    /// The cell's position in its brick (its key's low nine bits).
    position: u16,
    /// The range of its proxies.
    proxies: (u32, u32),
}

impl ScreeningCells {
    /// Adds a cell's block contribution (cell at window coordinates `w`) to the brick at
    /// `origin`, a block node beyond the cube going to the inside node it mirrors.
    fn add_reflected(
        origin: [i32; 3],
        n: i32,
        w: [usize; 3],
        contribution: &[f64; 27],
        acc: &mut [f64; PADDED],
    ) {
        for (k, c) in contribution.iter().enumerate() {
            // The block node's brick-local coordinates.
            let mut node = [k % 3, k / 3 % 3, k / 9].map(|d| d as i32);
            for a in 0..3 {
                node[a] += w[a] as i32 - 3;
                let g = origin[a] + node[a];
                if g < 0 {
                    node[a] = -1 - g - origin[a];
                } else if g >= n {
                    node[a] = 2 * n - 1 - g - origin[a];
                }
            }
            if node.iter().all(|&v| (0..8).contains(&v)) {
                acc[padded(node[0] as usize, node[1] as usize, node[2] as usize)] += *c;
            }
        }
    }

    fn new(level: &Level, proxies: &Proxies, core_bricks: &CoreBricks) -> ScreeningCells {
        // Each cell with its run of proxies (the proxies of one cell are consecutive; were they
        // not, a cell would just appear twice).
        let mut runs: Vec<(u32, (u32, u32))> = Vec::new();
        for (q, &cell) in proxies.cell.iter().enumerate() {
            match runs.last_mut() {
                Some((last, range)) if *last == cell => range.1 = q as u32 + 1,
                _ => runs.push((cell, (q as u32, q as u32 + 1))),
            }
        }
        runs.par_sort_unstable();
        let brick_start = level.brick_starts(runs.iter().map(|&(cell, _)| cell));
        let cells = runs
            .iter()
            .map(|&(cell, proxies)| ScreeningCell {
                position: (level.keys[cell as usize] & 511) as u16,
                proxies,
            })
            .collect();
        let mut has_core = vec![false; level.bricks().brick_count()];
        for around in &core_bricks.around {
            has_core[around[13] as usize] = true;
        }
        let outside_core_bricks = (0..has_core.len())
            .filter(|&b| !has_core[b])
            .flat_map(|b| brick_start[b]..brick_start[b + 1])
            .map(|k| (runs[k as usize].0, k))
            .collect();
        let mut cells = ScreeningCells {
            brick_start,
            cells,
            near_start: Vec::new(),
            near: Vec::new(),
            outside_core_bricks,
        };
        let per_brick: Vec<Vec<NearCell>> = core_bricks
            .around
            .par_iter()
            .map(|around| cells.near_cells(around))
            .collect();
        cells.near_start = std::iter::once(0)
            .chain(per_brick.iter().scan(0u32, |total, near| {
                *total += near.len() as u32;
                Some(*total)
            }))
            .collect();
        cells.near = per_brick.into_iter().flatten().collect();
        cells
    }

    /// The cells within one node of the brick whose 27 surrounding brick slots are `around`.
    fn near_cells(&self, around: &[u32; 27]) -> Vec<NearCell> {
        let mut near = Vec::new();
        for (slot, &b) in around.iter().enumerate() {
            if b == u32::MAX {
                continue;
            }
            let offset = [slot % 3, slot / 3 % 3, slot / 9];
            let range = self.brick_start[b as usize]..self.brick_start[b as usize + 1];
            for k in range {
                let l = brick_local(self.cells[k as usize].position as usize);
                // Window coordinate: local + 8·(offset − 1) + 2; the cell's block meets the
                // brick (window 2..10) when the cell is at 1..=10.
                let w: [i32; 3] = std::array::from_fn(|a| (l[a] + 8 * offset[a]) as i32 - 6);
                if w.iter().all(|v| (1..=10).contains(v)) {
                    near.push(NearCell {
                        cell: k,
                        window: w.map(|v| v as u8),
                    });
                }
            }
        }
        near
    }

    /// The cells in brick slot `b`.
    fn in_brick(&self, b: usize) -> &[ScreeningCell] {
        &self.cells[self.brick_start[b] as usize..self.brick_start[b + 1] as usize]
    }

    /// `chi[q]` = W_q χ(q) at the proxies of the cells outside every core brick.
    fn weigh_outside_core_bricks(
        &self,
        level: &Level,
        proxies: &Proxies,
        input: &[f64],
        chi: &mut [f64],
    ) {
        for &(node, k) in &self.outside_core_bricks {
            let x = level
                .block27(node)
                .map(|n| if n == NONE { 0.0 } else { input[n as usize] });
            let cell = &self.cells[k as usize];
            for q in cell.proxies.0 as usize..cell.proxies.1 as usize {
                chi[q] = proxies.weight[q] * tensor_contract(&proxies.stencil(q), &x);
            }
        }
    }

    /// For every cell within one node of the brick whose 27 surrounding brick slots are
    /// `around`, `contribute(range of its proxies, contribution)` adds the values of the cell's
    /// 3×3×3 node block (x fastest) to `contribution`, which is added to `acc` (the brick's
    /// positions padded by two nodes, see [`padded`]): whole blocks, without bounds to test per
    /// cell; the padding takes the block nodes beyond the brick, which other bricks compute.
    /// With Neumann boundaries a block node beyond the cube is the mirror image of one inside,
    /// whose folded function collects it instead.
    fn accumulate(
        &self,
        level: &Level,
        cb: usize,
        around: &[u32; 27],
        acc: &mut [f64; PADDED],
        mut contribute: impl FnMut(std::ops::Range<usize>, &mut [f64; 27]),
    ) {
        let origin = level.bricks().origin(around[13] as usize);
        let n = 1i32 << level.depth;
        let reflects =
            !level.mirrors.is_empty() && (0..3).any(|a| origin[a] == 0 || origin[a] + 8 >= n);
        let entries = self.near_start[cb] as usize..self.near_start[cb + 1] as usize;
        for near in &self.near[entries] {
            let cell = &self.cells[near.cell as usize];
            let w = near.window.map(usize::from);
            let mut contribution = [0.0; 27];
            contribute(
                cell.proxies.0 as usize..cell.proxies.1 as usize,
                &mut contribution,
            );
            if reflects {
                Self::add_reflected(origin, n, w, &contribution, acc);
                continue;
            }
            // Block node d of a cell at window coordinate w (local + 2) is at local w − 3 + d,
            // padded index w − 1 + d.
            for (dz, plane) in contribution.chunks_exact(9).enumerate() {
                for (dy, row) in plane.chunks_exact(3).enumerate() {
                    let at = w[0] - 1 + WINDOW * ((w[1] - 1 + dy) + WINDOW * (w[2] - 1 + dz));
                    for (a, c) in acc[at..at + 3].iter_mut().zip(row) {
                        *a += c;
                    }
                }
            }
        }
    }
}

/// A slice written from several threads at indices known to be disjoint between threads.
pub(crate) struct SharedSlice<'a, T> {
    start: *mut T,
    len: usize,
    _slice: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: elements are only reached through `get_mut`, whose callers guarantee that no two
// threads use the same index at the same time; T: Send lets them move between threads.
unsafe impl<T: Send> Sync for SharedSlice<'_, T> {}

impl<'a, T> SharedSlice<'a, T> {
    pub(crate) fn new(slice: &'a mut [T]) -> Self {
        SharedSlice {
            start: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: std::marker::PhantomData,
        }
    }

    /// Element `i` (bounds-checked).
    ///
    /// # Safety
    /// No other thread may access element `i` while the returned reference lives.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn get_mut(&self, i: usize) -> &mut T {
        assert!(i < self.len);
        &mut *self.start.add(i)
    }
}

/// ⟨∇B_o, V_d⟩ for every node of K_d, where V_d = Σ v_o′ B_o′/h³ (unit-integral node
/// functions, §4.1) has coefficients `v` (x, y, z components) on K_d, which is dropped when it
/// returns; [`divergence_of`] for a field that is kept.
pub fn divergence(level: &Level, v: [Vec<f64>; 3]) -> Vec<f64> {
    divergence_of(level, &v)
}

/// [`divergence`] of a field that is kept. Brick by brick over every brick of K_d, on 12³
/// windows of the three components gathered from the 27 bricks around (values beyond K_d are
/// zero), as (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)): one sweep and no
/// halo-sized scratch, where nine axis passes over the whole halo read and wrote it 18 times.
pub fn divergence_of(level: &Level, v: &[Vec<f64>; 3]) -> Vec<f64> {
    let bricks = CoreBricks::whole_level(level);
    let mut out = vec![0.0; level.len()];
    bricks.divergence(
        |cb, windows, _| {
            for (window, component) in windows.iter_mut().zip(v) {
                bricks.gather_values(level, cb, component, window);
            }
        },
        1.0 / level.width(),
        &mut out,
    );
    out
}

/// The two-scale weight of parent k of a fine node (bit a of k set: the partner along axis a,
/// weight ¼; clear: the node's own parent's column, weight ¾), the same for every node.
const PARENT_WEIGHTS: [f64; 8] = {
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

/// The eight parents of fine node `i` whose refinement covers it, with their two-scale weights:
/// per axis, child 2m = ¾·parent m + ¼·parent m−1 and child 2m+1 = ¾·parent m + ¼·parent m+1.
#[inline]
fn refinement_parents(coarse: &Level, fine: &Level, i: u32) -> [(u32, f64); 8] {
    let mut out = [(NONE, 0.0); 8];
    let Some((p, at)) = fine.parent_in(coarse, i) else {
        return out;
    };
    // The parity of each coordinate is the key's bit of that axis (the key's offset is even).
    let key = fine.keys[i as usize];
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
        out[k] = (node, PARENT_WEIGHTS[k]);
    }
    out
}

/// Prolongs coarse coefficients (on K_{d−1}) to the fine halo K_d, exactly: the fine
/// combination represents the same function wherever the coarse one is complete.
pub fn prolong(coarse: &Level, fine: &Level, x: &[f64], scale: f64) -> Vec<f64> {
    let mut out = vec![0.0; fine.len()];
    let shared = SharedSlice::new(&mut out);
    prolong_by_brick(coarse, fine, [x], scale, None, |node, [v]| {
        // SAFETY: every node is written once, by the task of its brick.
        unsafe { *shared.get_mut(node as usize) = v };
    });
    out
}

/// The prolongation of `inputs` (each times its scale) at fine node `i`.
#[inline]
fn prolonged_at<const N: usize>(
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

/// ⟨∇B_o, V⟩ at every core node of `field.fine` (in core order) for V a coarser field prolonged
/// to that depth ([`divergence`] restricted to the core, brick by brick): each core brick's
/// window computes the prolongation from the coarse nodes under it, instead of every window
/// node finding its eight parents (every node lies in about 3.4 windows).
pub fn divergence_of_prolonged(field: &ProlongedField<'_>) -> Vec<f64> {
    let level = field.fine;
    let bricks = CoreBricks::new(level);
    let mut out = vec![0.0; level.core.len()];
    bricks.divergence(
        |cb, windows, scratch| bricks.gather_prolonged(field, cb, windows, scratch),
        1.0 / level.width(),
        &mut out,
    );
    out
}

/// A coarser vector field prolonged to a finer halo, evaluated where it is read instead of
/// stored (node by node with [`ProlongedField::at`], brick by brick by
/// [`divergence_of_prolonged`] and [`ProlongedField::add_to`]): the value at a
/// fine node is what [`prolong`] of each component followed by [`fill_mirrors_field`] would
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
            // Neumann: a node outside the cube mirrors its reflection inside, if in K_d.
            let n = 1i32 << self.fine.depth;
            if let Some((inside, flips)) = crate::octree::reflect(self.fine.coord(i), n) {
                if let Some(j) = self.fine.find(inside) {
                    let v = prolonged_at(self.coarse, self.fine, self.field, scales, j);
                    return std::array::from_fn(|axis| {
                        if flips & (1 << axis) != 0 {
                            -v[axis]
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
        let shared = [vx, vy, vz].map(|component| SharedSlice::new(component));
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
            |node, p| {
                for (component, p) in shared.iter().zip(p) {
                    // SAFETY: every node is written once, by the task of its brick.
                    let x = unsafe { component.get_mut(node as usize) };
                    *x = p + *x;
                }
            },
        );
    }
}

/// The transpose of [`prolong`]: adds Σ_children w · `fine[child]` to every coarse node.
///
/// Fine brick by fine brick: the coarse nodes its nodes refine from (a 6×6×6 block) are looked
/// up once per brick, then every fine node adds to its eight parents, in node order and with
/// the parents `refinement_parents` gives (so sums come out the same as node by node).
pub fn restrict_into(coarse: &Level, fine: &Level, fine_values: &[f64], coarse_out: &mut [f64]) {
    const SIDE: usize = 6;
    let fine_index = fine.bricks();
    let coarse_index = coarse.bricks();
    let mut window = [NONE; SIDE * SIDE * SIDE];
    for b in 0..fine_index.brick_count() {
        let walk = BrickNodes::new(fine_index, b);
        if walk
            .clone()
            .all(|(node, _)| fine_values[node as usize] == 0.0)
        {
            continue;
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
                if parents[k] != NONE {
                    coarse_out[parents[k] as usize] += PARENT_WEIGHTS[k] * v;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::octree::Octree;

    /// A complete 16³ grid with free boundaries: its halo reaches two nodes beyond the cube, so
    /// every core node sees its whole 5³ neighbourhood.
    fn grid() -> Octree {
        Octree::build(vec![Vec::new(); 5], 4, false)
    }

    /// Coefficients on K of the polynomial f in node units (t = p/h = i + ½ at node centres).
    /// Quadratic B-splines reproduce quadratics: Σ_i b(t − t_i)·(t_i² − ¼) = t², Σ_i b(t − t_i)·t_i = t.
    fn coefficients(level: &Level, f: impl Fn([f64; 3]) -> f64) -> Vec<f64> {
        (0..level.len() as u32)
            .map(|i| f(level.coord(i).map(|c| c as f64 + 0.5)))
            .collect()
    }

    #[test]
    fn laplacian_of_quadratics_matches_integration_by_parts() {
        let tree = grid();
        let level = &tree.levels[4];
        let h = level.width();
        let proxies = Proxies::default();
        let mut op = DepthOperator::new(level, &proxies, 0.0);
        let mut out = vec![0.0; level.core.len()];
        // f = x² (unit coordinates) = h²(t² ): coefficients h²(t_i² − ¼). ⟨∇B_o, ∇f⟩ = −∫B_o Δf = −2h³.
        let x = coefficients(level, |t| h * h * (t[0] * t[0] - 0.25));
        op.apply(&x, &mut out);
        for v in &out {
            assert!(
                (v + 2.0 * h * h * h).abs() < 1e-12,
                "{v} vs {}",
                -2.0 * h * h * h
            );
        }
        // f = x² + y² − 2z² + 3xy is harmonic: ⟨∇B_o, ∇f⟩ = 0.
        let x = coefficients(level, |t| {
            h * h
                * ((t[0] * t[0] - 0.25) + (t[1] * t[1] - 0.25) - 2.0 * (t[2] * t[2] - 0.25)
                    + 3.0 * t[0] * t[1])
        });
        op.apply(&x, &mut out);
        assert!(out.iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn divergence_of_a_linear_field_is_its_constant_divergence() {
        let tree = grid();
        let level = &tree.levels[4];
        let h = level.width();
        // V = (x, 2y, −z): coefficients of the unit-integral F̃_o = B_o/h³ are h³·V(t_i·h).
        let v = [
            coefficients(level, |t| h * h * h * (h * t[0])),
            coefficients(level, |t| h * h * h * (2.0 * h * t[1])),
            coefficients(level, |t| h * h * h * (-h * t[2])),
        ];
        let div = divergence(level, v);
        // ⟨∇B_o, V⟩ = −∫B_o ∇·V = −(1 + 2 − 1)·h³ at every core node.
        for &c in &level.core {
            let got = div[c as usize];
            assert!((got + 2.0 * h * h * h).abs() < 1e-12, "{got}");
        }
    }

    /// A complete 16³ tree and a sparse one (only part of the cube refined, down to depth 5),
    /// with Neumann or free boundaries.
    fn complete_and_sparse_trees(neumann: bool) -> [Octree; 2] {
        let sparse: Vec<Vec<[i32; 3]>> = (0..=5)
            .map(|d| {
                let n = 1 << d;
                (0..n)
                    .flat_map(|i| [[i, i / 2, n / 3], [n - 1 - i, i, i / 3], [0, i, n - 1]])
                    .collect()
            })
            .collect();
        [
            Octree::build(vec![Vec::new(); 5], 4, neumann),
            Octree::build(sparse, 2, neumann),
        ]
    }

    /// The brick-by-brick prolongations (of the coefficients, of V added to a field, and inside
    /// the coarse divergence's windows), the restriction and the separable passes give the
    /// node-by-node values bit for bit, with free and
    /// with Neumann boundaries (mirror nodes beyond the cube), on sparse levels (only part of
    /// the cube refined) as well as complete ones.
    #[test]
    fn brick_prolongations_match_node_by_node_prolongation() {
        for neumann in [false, true] {
            for tree in complete_and_sparse_trees(neumann) {
                for d in 1..tree.levels.len() {
                    let (coarse, fine) = (&tree.levels[d - 1], &tree.levels[d]);
                    let field: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        (0..coarse.len())
                            .map(|i| ((i * (a + 5) + 3) % 13) as f64 - 6.5)
                            .collect()
                    });
                    let prolonged = ProlongedField {
                        coarse,
                        fine,
                        field: [&field[0], &field[1], &field[2]],
                        scale: 0.125,
                    };
                    let proxies = Proxies::default();
                    let mut op = DepthOperator::new(fine, &proxies, 0.0);
                    let by_node = op.divergence_on_core(|n| prolonged.at(n as u32));
                    let by_brick = divergence_of_prolonged(&prolonged);
                    assert!(!by_node.is_empty());
                    let same = |a: &[f64], b: &[f64], what: &str| {
                        assert_eq!(a.len(), b.len());
                        for (a, b) in a.iter().zip(b) {
                            assert_eq!(
                                a.to_bits(),
                                b.to_bits(),
                                "{what}, depth {d}, neumann {neumann}: {a} vs {b}"
                            );
                        }
                    };
                    same(&by_node, &by_brick, "divergence");
                    let by_node: Vec<f64> = (0..fine.len() as u32)
                        .map(|i| prolonged_at(coarse, fine, [&field[0]], [2.0], i)[0])
                        .collect();
                    same(&by_node, &prolong(coarse, fine, &field[0], 2.0), "prolong");
                    let base: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        (0..fine.len()).map(|i| (i % (a + 2)) as f64).collect()
                    });
                    let mut added = base.clone();
                    prolonged.add_to(&mut added);
                    let want: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        (0..fine.len())
                            .map(|i| prolonged.at(i as u32)[a] + base[a][i])
                            .collect()
                    });
                    for a in 0..3 {
                        same(&want[a], &added[a], "add_to");
                    }
                    // Restriction (the transpose) brick by brick against node by node, with
                    // zeros among the fine values as the pipeline's have.
                    let fine_values: Vec<f64> = (0..fine.len())
                        .map(|i| {
                            if i % 5 == 0 {
                                0.0
                            } else {
                                (i % 9) as f64 - 4.0
                            }
                        })
                        .collect();
                    let mut by_node = vec![0.5; coarse.len()];
                    for i in 0..fine.len() as u32 {
                        for (n, w) in refinement_parents(coarse, fine, i) {
                            if n != NONE && fine_values[i as usize] != 0.0 {
                                by_node[n as usize] += w * fine_values[i as usize];
                            }
                        }
                    }
                    let mut by_brick = vec![0.5; coarse.len()];
                    restrict_into(coarse, fine, &fine_values, &mut by_brick);
                    same(&by_node, &by_brick, "restrict");
                    // The divergence brick by brick against the 125-node sum node by node.
                    let field: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        (0..fine.len())
                            .map(|i| ((i * (a + 2) + 1) % 11) as f64 * 0.37 - 1.7)
                            .collect()
                    });
                    let got = divergence_of(fine, &field);
                    let t = tables();
                    for i in 0..fine.len() as u32 {
                        let o = fine.coord(i);
                        let mut want = 0.0;
                        for k in 0..125 {
                            let d = [k % 5, k / 5 % 5, k / 25];
                            let Some(j) =
                                fine.find(std::array::from_fn(|a| o[a] + d[a] as i32 - 2))
                            else {
                                continue;
                            };
                            let (m, g) = (t.mass, t.advection);
                            let v = field.each_ref().map(|c| c[j as usize]);
                            want += g[d[0]] * m[d[1]] * m[d[2]] * v[0]
                                + m[d[0]] * g[d[1]] * m[d[2]] * v[1]
                                + m[d[0]] * m[d[1]] * g[d[2]] * v[2];
                        }
                        want /= fine.width();
                        let err = (got[i as usize] - want).abs();
                        assert!(
                            err < 1e-9 * (1.0 + want.abs()),
                            "node {i}: {} vs {want}",
                            got[i as usize]
                        );
                    }
                }
            }
        }
    }

    /// The window of every core brick gathered group by group from a vector (AVX-512's
    /// expanding loads where the CPU has them) equals the node-by-node gather, with and without
    /// mirror nodes, on sparse and complete levels; the windows' parts of the bricks around are
    /// whole 2×2×2 groups, which the group walk relies on.
    #[test]
    fn vector_windows_match_the_node_by_node_gather() {
        for region in window_regions() {
            for word in region {
                assert!(word.to_le_bytes().iter().all(|&b| b == 0 || b == 0xff));
            }
        }
        #[cfg(target_arch = "x86_64")]
        if !std::arch::is_x86_feature_detected!("avx512f") {
            eprintln!("no AVX-512 on this CPU: checking the portable gather against itself");
        }
        for neumann in [false, true] {
            for tree in complete_and_sparse_trees(neumann) {
                for level in &tree.levels {
                    let input: Vec<f64> = (0..level.len()).map(|i| (i % 97) as f64 + 0.5).collect();
                    let bricks = CoreBricks::new(level);
                    let mut fast = [vec![[f64::NAN; WINDOW]; WINDOW * WINDOW]];
                    let mut slow = fast.clone();
                    for cb in 0..bricks.around.len() {
                        bricks.gather_values(level, cb, &input, &mut fast[0]);
                        bricks.gather(level, cb, &|n| [input[n]], &mut slow);
                        assert_eq!(fast, slow, "depth {} brick {cb}", level.depth);
                    }
                }
            }
        }
    }

    #[test]
    fn divergence_on_core_matches_the_full_divergence() {
        let tree = grid();
        let level = &tree.levels[4];
        let v: [Vec<f64>; 3] = std::array::from_fn(|a| {
            (0..level.len())
                .map(|i| ((i * (a + 3)) % 11) as f64 - 5.0)
                .collect()
        });
        let full = divergence(level, v.clone());
        let kept = divergence_of(level, &v);
        assert!(full
            .iter()
            .zip(&kept)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let proxies = Proxies::default();
        let mut op = DepthOperator::new(level, &proxies, 0.0);
        let on_core = op.divergence_on_core(|n| [v[0][n], v[1][n], v[2][n]]);
        for (&c, got) in level.core.iter().zip(&on_core) {
            let want = full[c as usize];
            assert!(
                (got - want).abs() < 1e-12 * want.abs().max(1.0),
                "{got} vs {want}"
            );
        }
    }

    #[test]
    fn prolongation_reproduces_coarse_quadratics_and_restriction_is_its_transpose() {
        let tree = grid();
        let (coarse, fine) = (&tree.levels[3], &tree.levels[4]);
        let f = |p: [f64; 3]| p[0] * p[0] + 0.5 * p[1] * p[2] - p[2];
        // Coefficients of f in each depth's basis (unit coordinates p = t·h).
        let at = |level: &Level| {
            let h = level.width();
            coefficients(level, |t| {
                let p = t.map(|v| v * h);
                f(p) - 0.25 * h * h // the −¼ correction of the x² term
            })
        };
        let got = prolong(coarse, fine, &at(coarse), 1.0);
        let want = at(fine);
        for &c in &fine.core {
            assert!((got[c as usize] - want[c as usize]).abs() < 1e-12);
        }
        // ⟨R u, v⟩ = ⟨u, P v⟩ on vectors supported on the cores.
        let u: Vec<f64> = (0..fine.len())
            .map(|i| {
                if fine.flags[i] & crate::octree::CORE != 0 {
                    (i % 7) as f64
                } else {
                    0.0
                }
            })
            .collect();
        let v: Vec<f64> = (0..coarse.len())
            .map(|i| {
                if coarse.flags[i] & crate::octree::CORE != 0 {
                    (i % 5) as f64 - 2.0
                } else {
                    0.0
                }
            })
            .collect();
        let mut ru = vec![0.0; coarse.len()];
        restrict_into(coarse, fine, &u, &mut ru);
        let pv = prolong(coarse, fine, &v, 1.0);
        let lhs: f64 = ru.iter().zip(&v).map(|(a, b)| a * b).sum();
        let rhs: f64 = u.iter().zip(&pv).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-9 * lhs.abs().max(1.0));
    }

    /// A proxy's stencil is the B-spline's values at the three nodes around its cell, as
    /// [`crate::density::stencil27`] evaluates them at the proxy's position.
    #[test]
    fn proxy_stencil_is_the_bspline_at_the_proxy() {
        let inv_h = 16.0;
        for p in [
            DVec3::new(0.3, 0.51, 0.77),
            DVec3::new(0.0, 0.999, 0.5),
            DVec3::new(0.0625, 0.125, 0.9),
        ] {
            let t = p * inv_h;
            let proxies = Proxies {
                cell: vec![0],
                weight: vec![1.0],
                offset: vec![[t.x, t.y, t.z].map(|v| (v - v.floor()) as f32)],
            };
            let (_, want) = crate::density::stencil27(p, inv_h);
            let got = proxies.stencil(0);
            for a in 0..3 {
                for k in 0..3 {
                    assert!(
                        (got[a][k] - want[a][k]).abs() < 1e-6,
                        "{p} axis {a} node {k}"
                    );
                }
                assert!((got[a].iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
        }
    }

    /// The screening term applied brick by brick (and the diagonal) against a node-by-node
    /// reference: every proxy reads χ from the 3×3×3 nodes around its cell and gives back to
    /// them, mirror nodes folding into the inside nodes they reflect; free and Neumann
    /// boundaries, proxies in the middle, at the faces, corners and across brick edges.
    #[test]
    fn brick_screening_matches_the_node_by_node_sum() {
        for neumann in [false, true] {
            for tree in complete_and_sparse_trees(neumann) {
                let level = &tree.levels[tree.levels.len() - 1];
                let n = 1i32 << level.depth;
                // Proxies in cells inside the cube within one node of the core (as the pipeline
                // keeps them), one to three per cell; some of those cells lie in bricks without
                // core nodes.
                let mut proxies = Proxies::default();
                let near: Vec<u32> = (0..level.len() as u32)
                    .filter(|&i| level.flags[i as usize] & crate::octree::NEAR != 0)
                    .collect();
                for (k, &c) in near.iter().enumerate() {
                    let coord = level.coord(c);
                    if coord.iter().any(|&v| v < 0 || v >= n) || k % 3 == 1 {
                        continue;
                    }
                    for j in 0..1 + k % 3 {
                        let f = |a: usize| ((k * 7 + j * 5 + a * 3) % 10) as f32 / 10.0 + 0.05;
                        proxies.cell.push(c);
                        proxies.weight.push(0.5 + (k % 5) as f64);
                        proxies.offset.push([f(0), f(1), f(2)]);
                    }
                }
                assert!(!proxies.is_empty());
                let bricks = CoreBricks::new(level);
                let cells = ScreeningCells::new(level, &proxies, &bricks);
                if level.core.len() < level.len() / 2 {
                    assert!(
                        !cells.outside_core_bricks.is_empty(),
                        "the sparse tree has proxy cells in bricks without core nodes"
                    );
                }
                let x: Vec<f64> = (0..level.len())
                    .map(|i| ((i * 13) % 17) as f64 / 17.0 - 0.4)
                    .collect();
                let mut x = x;
                fill_mirrors(level, &mut x);
                let alpha = 3.5;
                let mut got = vec![0.0; level.core.len()];
                DepthOperator::new(level, &proxies, alpha).apply(&x, &mut got);
                let mut laplacian = vec![0.0; level.core.len()];
                DepthOperator::new(level, &proxies, 0.0).apply(&x, &mut laplacian);
                let mut screened = vec![0.0; level.len()];
                let mut squares = vec![0.0; level.len()];
                for q in 0..proxies.len() {
                    let block = level.block27(proxies.cell[q]);
                    let st = &proxies.stencil(q);
                    let b = |slot: usize| st[0][slot % 3] * st[1][slot / 3 % 3] * st[2][slot / 9];
                    let chi: f64 = (0..27)
                        .filter(|&s| block[s] != NONE)
                        .map(|s| x[block[s] as usize] * b(s))
                        .sum();
                    for s in 0..27 {
                        if block[s] != NONE {
                            screened[block[s] as usize] += proxies.weight[q] * chi * b(s);
                            squares[block[s] as usize] += proxies.weight[q] * b(s) * b(s);
                        }
                    }
                }
                for m in &level.mirrors {
                    screened[m.inside as usize] += screened[m.outside as usize];
                    squares[m.inside as usize] += squares[m.outside as usize];
                }
                let mut op = DepthOperator::new(level, &proxies, alpha);
                let diagonal = op.diagonal();
                let lap_diagonal = DepthOperator::new(level, &proxies, 0.0).diagonal();
                for (k, &c) in level.core.iter().enumerate() {
                    let want = laplacian[k] + alpha * screened[c as usize];
                    assert!(
                        (got[k] - want).abs() < 1e-12 * want.abs().max(1.0),
                        "neumann {neumann}, node {:?}: {} vs {want}",
                        level.coord(c),
                        got[k]
                    );
                    let want = lap_diagonal[k] + alpha * squares[c as usize];
                    assert!((diagonal[k] - want).abs() < 1e-12 * want.abs().max(1.0));
                }
            }
        }
    }

    #[test]
    fn neumann_mirrors_make_constants_harmonic_up_to_the_faces() {
        // With reflected (even) node functions the constant 1 is in the space and has zero
        // gradient everywhere in the cube, so L·1 vanishes at every node, the face nodes too;
        // with free boundaries the node functions simply stop and the face nodes feel it.
        for neumann in [true, false] {
            let tree = Octree::build(vec![Vec::new(); 4], 3, neumann);
            let level = &tree.levels[3];
            let proxies = Proxies::default();
            let mut op = DepthOperator::new(level, &proxies, 0.0);
            let mut x: Vec<f64> = (0..level.len())
                .map(|i| {
                    if level.flags[i] & crate::octree::CORE != 0 {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect();
            fill_mirrors(level, &mut x);
            let mut out = vec![0.0; level.core.len()];
            op.apply(&x, &mut out);
            let worst = out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if neumann {
                assert!(worst < 1e-14, "{worst}");
            } else {
                assert!(worst > 1e-3);
            }
        }
    }
}

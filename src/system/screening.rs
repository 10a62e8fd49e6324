//! The screening term of Kazhdan & Hoppe (2013): α·Σ_q W_q B_o(q) χ(q) at every core node o,
//! over "proxy" samples q (the weighted mean of the samples in a small cell, with their summed
//! weight W_q), applied brick by brick on the Laplacian's windows.

use super::bricks::{CoreBricks, WINDOW};
use crate::bspline::Degree;
use crate::grid::{cell_runs, cuts_between_cells, morton_nested};
use crate::octree::{brick_local, Level, NEAR, NONE};
use crate::parallel::stop_requested;
use glam::DVec3;
use rayon::prelude::*;

/// Each sample's screening weight: SPSR's α·Area/Σw·Σ_s w_s χ(s)², with the area the density
/// estimate's (`areas`) and w the confidence: confidence × total area / total confidence.
pub(crate) fn sample_weights(areas: &[f64], confidence: &[f64]) -> Vec<f64> {
    let total_area: f64 = areas.iter().zip(confidence).map(|(a, c)| a * c).sum();
    let total_confidence: f64 = confidence.iter().sum();
    sample_weights_from_totals(confidence, total_area, total_confidence)
}

/// [`sample_weights`] from the totals over all the samples (Σ area × confidence, Σ
/// confidence), for samples that are part of them (the out-of-core path's slabs).
pub(crate) fn sample_weights_from_totals(
    confidence: &[f64],
    total_area: f64,
    total_confidence: f64,
) -> Vec<f64> {
    confidence
        .iter()
        .map(|c| c * total_area / total_confidence)
        .collect()
}

/// How many times the samples' noise σ the cells of the finest depth the screening is scaled
/// to are wide ([`screening_depth`]). Set on noisy synthetic shapes against their true
/// surfaces and on the shared laser scans by the distance to samples held out of the
/// reconstruction (docs/benchmarks.md, issue 16): 20 was the closest on the synthetic noise and
/// the bunny but rounded off the Buddha's thin parts (a larger RMS distance than the default's),
/// 5 kept more of the noise, and 10 came within 1.3 % of the best on the scans and took 28–59 %
/// off the noisy shapes' distance to the truth at depths 10–11. Measured again with the
/// per-depth weights of [`ScreeningWeights`] (2026-12-06): the same trade (20 closer on the
/// bunny and the noisy sphere, farther on the Buddha by mean and RMS), so 10 stays.
pub(crate) const NOISE_CELLS: f64 = 10.0;

/// The noise's depth s, which [`ScreeningWeights`] reads: the requested depth, or, when the
/// samples scatter σ > 0 across the surface (unit cube units), no finer than the depth whose
/// cells are [`NOISE_CELLS`] σ wide. The screening pulls χ onto the samples; at depths finer
/// than that the full pull goes into following the noise (measured: the distance to the true
/// surface grows with depth at 2^D and stays flat with the finer depths' pull at 2^s).
pub(crate) fn screening_depth(requested_depth: u32, sigma: f64) -> f64 {
    let requested = requested_depth as f64;
    if sigma > 0.0 {
        requested.min(-(NOISE_CELLS * sigma).log2())
    } else {
        requested
    }
}

/// The screening term's weight α_d at each depth d of the cascade.
///
/// α·2^D, D the requested depth — the finest depth's balance between the Laplacian and the
/// screening term (SPSR), kept at coarser depths, where it is then relatively stronger. The
/// cascade never revisits a coarse depth, so a coarse solution that ignores the samples would
/// leave an offset the thin finer bands cannot take out. (When the tree stops short of D,
/// keeping D's weight was measured to avoid a 76-vertex bubble beside the oni's horn that the
/// finest used depth's weight produced.)
///
/// When the screening follows the samples' noise, the depths finer than the noise's depth s
/// ([`screening_depth`]: their cells narrower than [`NOISE_CELLS`] σ) are pulled by α·2^s
/// instead, the balance of a reconstruction at depth s: there the full pull would fit the
/// surface to the noise. The depths up to ⌊s⌋ keep α·2^D: their cells are wide against the
/// noise (the screening's proxies average it away), and their pull is what keeps a small
/// detached part of the scan on the isosurface (measured, docs/benchmarks.md, issue 16: with
/// α·2^s at every depth the Happy Buddha's 474-sample fragment dissolved at depth 11, and the
/// Buddha's held-out distance was 0.2–0.6 % larger at depths 9–11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScreeningWeights {
    /// α·2^D.
    full: f64,
    /// α·2^s.
    noise: f64,
    /// ⌊s⌋: the finest depth pulled by `full`.
    last_full: usize,
    /// s itself (at most D), as [`crate::Stats::screening_depth`] reports it.
    pub(crate) noise_depth: f64,
}

impl ScreeningWeights {
    /// The weights for point weight α, requested depth D and the noise's depth s (D when the
    /// samples read no noise or the screening does not follow it: then α·2^D at every depth).
    pub(crate) fn new(point_weight: f32, requested_depth: u32, noise_depth: f64) -> Self {
        let alpha = point_weight as f64;
        let noise_depth = noise_depth.min(requested_depth as f64);
        ScreeningWeights {
            full: alpha * (requested_depth as f64).exp2(),
            noise: alpha * noise_depth.exp2(),
            last_full: noise_depth.floor().max(0.0) as usize,
            noise_depth,
        }
    }

    /// α·2^D at every depth (the noise not followed, or not yet estimated).
    pub(crate) fn full_at_every_depth(point_weight: f32, requested_depth: u32) -> Self {
        Self::new(point_weight, requested_depth, requested_depth as f64)
    }

    /// α_d at depth `depth`.
    pub(crate) fn at(&self, depth: usize) -> f64 {
        if depth <= self.last_full {
            self.full
        } else {
            self.noise
        }
    }
}

/// The depth at which the screening samples of depth d are grouped: two depths finer (16× less
/// sag of a proxy below a curved surface than grouping at d). On a 40k-point sphere at depth 7
/// grouping at d, at d + 2 or not at all (every sample) measured within 1% of each other; d + 2
/// keeps the proxies on the surface where samples are sparse and coarse cells large.
pub(crate) fn proxy_depth(d: u32, max_depth: u32) -> u32 {
    (d + 2).min(max_depth)
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
    /// The degree of the level's node functions (see [`Proxies::stencil`]).
    pub degree: Degree,
}

impl Proxies {
    /// Groups samples (`positions` sorted by Morton key at a depth ≥ `proxy_depth`, so that the
    /// samples of a cell are consecutive) into proxies at `proxy_depth` ≥ the level's depth. In
    /// parallel over pieces cut between groups (a fixed number of samples apart), appended in
    /// order.
    pub fn build(level: &Level, positions: &[DVec3], weights: &[f64], proxy_depth: u32) -> Proxies {
        let cuts = cuts_between_cells(positions, proxy_depth, 1 << 14);
        let pieces: Vec<Proxies> = cuts
            .par_windows(2)
            .map(|piece| {
                // (A cancelled solve skips the remaining pieces, leaving fewer proxies: a
                // valid set nothing reads; see `stop_requested`.)
                if stop_requested() {
                    return Proxies::default();
                }
                let range = piece[0]..piece[1];
                Self::build_piece(
                    level,
                    &positions[range.clone()],
                    &weights[range],
                    proxy_depth,
                )
            })
            .collect();
        let mut proxies = Proxies {
            degree: level.degree,
            ..Proxies::default()
        };
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
        let mut proxies = Proxies::default();
        for_each_group(positions, weights, proxy_depth, |group, sum_p, sum_w| {
            proxies.push_group(level, group, sum_p, sum_w, proxy_depth)
        });
        proxies
    }

    /// The proxies of one depth from samples already grouped by cell at `proxy_depth`
    /// (`groups`: the cell, Σ w·p and Σ w of its samples, in Morton order of the cells, each
    /// cell once), as [`Proxies::build`] makes them from the samples: the out-of-core base sums
    /// its slabs' groups, since a group is additive over the samples in it.
    pub(crate) fn from_groups(
        level: &Level,
        groups: &[([i32; 3], DVec3, f64)],
        proxy_depth: u32,
    ) -> Proxies {
        let mut proxies = Proxies {
            degree: level.degree,
            ..Proxies::default()
        };
        for &(cell, sum_p, sum_w) in groups {
            proxies.push_group(level, cell, sum_p, sum_w, proxy_depth);
        }
        proxies
    }

    /// Adds the proxy of the samples of cell `group` of `proxy_depth` (their Σ w·p and Σ w),
    /// unless they weigh nothing or lie beyond the nodes near the level's core.
    fn push_group(
        &mut self,
        level: &Level,
        group: [i32; 3],
        sum_p: DVec3,
        sum_w: f64,
        proxy_depth: u32,
    ) {
        if sum_w <= 0.0 {
            return;
        }
        let shift = proxy_depth - level.depth;
        let cell = [group[0] >> shift, group[1] >> shift, group[2] >> shift];
        let Some(idx) = level.find(cell) else {
            return;
        };
        if level.flags[idx as usize] & NEAR == 0 {
            return;
        }
        let inv_h = (level.depth as f64).exp2();
        let t = sum_p / sum_w * inv_h;
        let offset = [t.x, t.y, t.z].map(|v| (v - crate::grid::floor(v)).clamp(0.0, 1.0) as f32);
        self.cell.push(idx);
        self.weight.push(sum_w);
        self.offset.push(offset);
    }

    pub fn len(&self) -> usize {
        self.cell.len()
    }

    /// b(t − centre) for the three nodes per axis around proxy `q`'s cell (cell − 1, cell,
    /// cell + 1), at the proxy: with f its offset in the cell, the degree-2 B-spline gives
    /// ½(1 − f)², ¾ − (f − ½)² and ½f²; degree 1's hats on the cell's corners 0, 1 − f and f.
    #[inline]
    pub fn stencil(&self, q: usize) -> [[f64; 3]; 3] {
        if self.degree == Degree::One {
            return self.offset[q].map(|f| {
                let f = f as f64;
                [0.0, 1.0 - f, f]
            });
        }
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

/// Calls `f(cell, Σ w·p, Σ w)` for the samples of each cell of `proxy_depth` in turn: the
/// samples (`positions`, with `weights`) must be in Morton order at a depth ≥ `proxy_depth`,
/// so that a cell's samples are consecutive.
fn for_each_group(
    positions: &[DVec3],
    weights: &[f64],
    proxy_depth: u32,
    mut f: impl FnMut([i32; 3], DVec3, f64),
) {
    let mut previous_group = None;
    for (group, run) in cell_runs(positions, proxy_depth) {
        // Each group's samples must be consecutive (Morton order at a depth ≥ the proxy
        // depth), or a cell would get several proxies with part of its weight each.
        let key = morton_nested(group.map(|v| v.max(0) as u32));
        debug_assert!(previous_group < Some(key), "samples not in Morton order");
        previous_group = Some(key);
        let mut sum_w = 0.0;
        let mut sum_p = DVec3::ZERO;
        for s in run {
            sum_w += weights[s];
            sum_p += positions[s] * weights[s];
        }
        f(group, sum_p, sum_w);
    }
}

/// The samples grouped by cell of `proxy_depth` (the cell, Σ w·p, Σ w), in Morton order of
/// the cells, for [`Proxies::from_groups`]; the samples in Morton order as for
/// [`Proxies::build`].
pub(crate) fn sample_groups(
    positions: &[DVec3],
    weights: &[f64],
    proxy_depth: u32,
) -> Vec<([i32; 3], DVec3, f64)> {
    let mut groups = Vec::new();
    for_each_group(positions, weights, proxy_depth, |cell, sum_p, sum_w| {
        groups.push((cell, sum_p, sum_w))
    });
    groups
}

/// `Σ_slot x[slot] · st[0][slot % 3] · st[1][slot / 3 % 3] · st[2][slot / 9]` (x fastest), one
/// axis at a time (39 multiplications instead of 81), over the block nodes from `first` on
/// along every axis ([`Degree::first_node`] of the stencil's degree: at degree 1 the 2×2×2
/// block, 14 multiplications; what it leaves out is exactly zero).
#[inline]
pub(super) fn tensor_contract(st: &[[f64; 3]; 3], x: &[f64; 27], first: usize) -> f64 {
    if first == 1 {
        tensor_contract_from::<1>(st, x)
    } else {
        tensor_contract_from::<0>(st, x)
    }
}

#[inline(always)]
fn tensor_contract_from<const FIRST: usize>(st: &[[f64; 3]; 3], x: &[f64; 27]) -> f64 {
    let mut sum = 0.0;
    for z in FIRST..3 {
        let mut plane_sum = 0.0;
        for y in FIRST..3 {
            let row = &x[9 * z + 3 * y..9 * z + 3 * y + 3];
            let row_sum = if FIRST == 1 {
                st[0][1] * row[1] + st[0][2] * row[2]
            } else {
                st[0][0] * row[0] + st[0][1] * row[1] + st[0][2] * row[2]
            };
            plane_sum += st[1][y] * row_sum;
        }
        sum += st[2][z] * plane_sum;
    }
    sum
}

/// `out[slot] += w · st[0][slot % 3] · st[1][slot / 3 % 3] · st[2][slot / 9]` (the transpose of
/// [`tensor_contract`]) from block node `FIRST` on along every axis.
#[inline(always)]
fn tensor_accumulate<const FIRST: usize>(st: &[[f64; 3]; 3], w: f64, out: &mut [f64; 27]) {
    for z in FIRST..3 {
        let wz = w * st[2][z];
        for y in FIRST..3 {
            let wzy = wz * st[1][y];
            for x in FIRST..3 {
                out[9 * z + 3 * y + x] += wzy * st[0][x];
            }
        }
    }
}

/// A brick's positions with two nodes of padding on each side, [`WINDOW`]³ of them.
pub(super) const PADDED: usize = WINDOW * WINDOW * WINDOW;

/// The index of brick-local position (x, y, z) (each in −2..10, shifted by 2) in a padded
/// brick array.
#[inline]
pub(super) fn padded(x: usize, y: usize, z: usize) -> usize {
    (x + 2) + WINDOW * ((y + 2) + WINDOW * (z + 2))
}

/// The cells of K_d holding proxies, grouped by brick, for the screening term
/// Σ_q W_q B_o(q) χ(q) at a core node o: a core brick's nodes collect from the cells within one
/// node of the brick (in its own and the 26 bricks around), each reading χ at its proxies from
/// the 3×3×3 nodes around it in the brick's input window, which the Laplacian gathered anyway.
/// No halo-sized sum, no random gather or scatter; a cell near a brick's edge is visited by
/// each brick it touches (about twice on average).
///
/// W_q χ(q) is kept by *slot*: the proxies numbered cell by cell in the cells' order, so that
/// the proxies of one brick's cells are consecutive and each brick's task owns its range.
pub(super) struct ScreeningCells {
    /// Per brick slot of K_d, the range of `cells` in it.
    brick_start: Vec<u32>,
    cells: Vec<ScreeningCell>,
    /// Per core brick (in `CoreBricks` order), the range of `near`.
    near_start: Vec<u32>,
    /// The cells within one node of each core brick, with their window coordinates there.
    near: Vec<NearCell>,
    /// The cells (node index and index in `cells`) in bricks without core nodes, whose
    /// proxies no core brick's window covers: found node by node (few, at the core's edge).
    pub(super) outside_core_bricks: Vec<(u32, u32)>,
    /// The number of proxies (slots).
    slots: usize,
}

/// A cell within one node of a core brick: its index in `ScreeningCells::cells` and its
/// coordinates in the brick's window (local + 2, so 1..=10).
#[derive(Debug, Clone, Copy)]
struct NearCell {
    cell: u32,
    window: [u8; 3],
}

#[derive(Debug, Clone, Copy)]
pub(super) struct ScreeningCell {
    /// The cell's position in its brick (its key's low nine bits).
    position: u16,
    /// The range of its proxies.
    proxies: (u32, u32),
    /// The slot of its first proxy (its others follow).
    first_slot: u32,
}

impl ScreeningCells {
    /// Adds a cell's block contribution (cell at window coordinates `w`) to the brick at
    /// `origin`, a block node beyond the cube going to the inside node it mirrors, times
    /// `face_sign` per face crossed (the transpose of [`fill_mirrors`](super::fill_mirrors)).
    fn add_reflected(
        degree: Degree,
        origin: [i32; 3],
        n: i32,
        face_sign: f64,
        w: [usize; 3],
        contribution: &[f64; 27],
        acc: &mut [f64; PADDED],
    ) {
        for (k, c) in contribution.iter().enumerate() {
            // The block node's brick-local coordinates.
            let mut node = [k % 3, k / 3 % 3, k / 9].map(|d| d as i32);
            let mut sign = 1.0;
            for a in 0..3 {
                node[a] += w[a] as i32 - 3;
                let g = origin[a] + node[a];
                // Degree 1's nodes sit on corners: −g mirrors g, and the faces' own nodes
                // (0 and n) are inside.
                let (near, far) = match degree {
                    Degree::Two => (-1, 2 * n - 1),
                    Degree::One => (0, 2 * n),
                };
                if g < 0 {
                    node[a] = near - g - origin[a];
                    sign *= face_sign;
                } else if g > far - n {
                    node[a] = far - g - origin[a];
                    sign *= face_sign;
                }
            }
            if node.iter().all(|&v| (0..8).contains(&v)) {
                acc[padded(node[0] as usize, node[1] as usize, node[2] as usize)] += sign * *c;
            }
        }
    }

    pub(super) fn new(
        level: &Level,
        proxies: &Proxies,
        core_bricks: &CoreBricks,
    ) -> ScreeningCells {
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
        let mut slots = 0;
        let cells = runs
            .iter()
            .map(|&(cell, proxies)| {
                let first_slot = slots;
                slots += proxies.1 - proxies.0;
                ScreeningCell {
                    position: (level.keys[cell as usize] & 511) as u16,
                    proxies,
                    first_slot,
                }
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
            slots: slots as usize,
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
    pub(super) fn in_brick(&self, b: usize) -> &[ScreeningCell] {
        &self.cells[self.brick_start[b] as usize..self.brick_start[b + 1] as usize]
    }

    /// `chi[slot of q]` = W_q χ(q) at the proxies of the cells outside every core brick.
    pub(super) fn weigh_outside_core_bricks(
        &self,
        level: &Level,
        proxies: &Proxies,
        input: &[f64],
        chi: &mut [f64],
    ) {
        let first_node = proxies.degree.first_node();
        for &(node, k) in &self.outside_core_bricks {
            let x = level
                .block27(node)
                .map(|n| if n == NONE { 0.0 } else { input[n as usize] });
            let cell = &self.cells[k as usize];
            for (slot, q) in cell.slots().zip(cell.proxy_range()) {
                chi[slot] =
                    proxies.weight[q] * tensor_contract(&proxies.stencil(q), &x, first_node);
            }
        }
    }

    /// For every cell within one node of the brick whose 27 surrounding brick slots are
    /// `around`, adds the tensor-product blocks `w · st[0] ⊗ st[1] ⊗ st[2]` of its proxies over the
    /// cell's 3×3×3 node block, `(st, w) = proxy(slot, q)` for each proxy q (with its slot), to
    /// `acc` (the brick's positions padded by two nodes, see [`padded`]): whole blocks, without
    /// bounds to test per cell; the padding takes the block nodes beyond the brick, which other
    /// bricks compute. A cell's proxies are summed into its block first, then the block into
    /// `acc`; a cell with one proxy (nearly all) goes straight into `acc`, which adds the same
    /// values in the same order.
    /// With Neumann or Dirichlet boundaries a block node beyond the cube is the mirror image of
    /// one inside, whose folded function collects it instead, times `face_sign` per face
    /// crossed: [`Level::face_sign`] for the operator (Pᵀ S P, P the signed extension, so the
    /// system stays symmetric), 1 for the diagonal's sums of squares (the Jacobi
    /// preconditioner only needs a positive approximation of the diagonal; Neumann's is the
    /// same).
    pub(super) fn accumulate(
        &self,
        level: &Level,
        cb: usize,
        around: &[u32; 27],
        face_sign: f64,
        acc: &mut [f64; PADDED],
        proxy: impl Fn(usize, usize) -> ([[f64; 3]; 3], f64),
    ) {
        // The block nodes from `FIRST` on along every axis: degree 1 gives nothing to the
        // first (`Degree::first_node`), and its zeros are not added.
        if level.degree.first_node() == 1 {
            self.accumulate_from::<1>(level, cb, around, face_sign, acc, proxy)
        } else {
            self.accumulate_from::<0>(level, cb, around, face_sign, acc, proxy)
        }
    }

    /// [`ScreeningCells::accumulate`] for node functions that are zero on block nodes before
    /// `FIRST` along each axis.
    fn accumulate_from<const FIRST: usize>(
        &self,
        level: &Level,
        cb: usize,
        around: &[u32; 27],
        face_sign: f64,
        acc: &mut [f64; PADDED],
        proxy: impl Fn(usize, usize) -> ([[f64; 3]; 3], f64),
    ) {
        let origin = level.bricks().origin(around[13] as usize);
        let n = 1i32 << level.depth;
        let reflects =
            !level.mirrors.is_empty() && (0..3).any(|a| origin[a] == 0 || origin[a] + 8 >= n);
        let entries = self.near_start[cb] as usize..self.near_start[cb + 1] as usize;
        for near in &self.near[entries] {
            let cell = &self.cells[near.cell as usize];
            let w = near.window.map(usize::from);
            if !reflects && cell.proxies.1 - cell.proxies.0 == 1 {
                let (st, weight) = proxy(cell.first_slot as usize, cell.proxies.0 as usize);
                add_tensor::<FIRST>(&st, weight, w, acc);
                continue;
            }
            let mut contribution = [0.0; 27];
            for (slot, q) in cell.slots().zip(cell.proxy_range()) {
                let (st, weight) = proxy(slot, q);
                tensor_accumulate::<FIRST>(&st, weight, &mut contribution);
            }
            if reflects {
                Self::add_reflected(level.degree, origin, n, face_sign, w, &contribution, acc);
            } else {
                add_block::<FIRST>(&contribution, w, acc);
            }
        }
    }

    /// The slots of the proxies of the cells in brick slot `b` (consecutive).
    pub(super) fn slots_in_brick(&self, b: usize) -> std::ops::Range<usize> {
        let slot_of = |k: u32| {
            self.cells
                .get(k as usize)
                .map_or(self.slots, |cell| cell.first_slot as usize)
        };
        slot_of(self.brick_start[b])..slot_of(self.brick_start[b + 1])
    }

    /// `chi[slot − first slot of the brick]` = W_q χ(q) at the proxies of the cells in brick
    /// slot `b`, with χ read from the brick's input window `w` (the Laplacian's).
    pub(super) fn weigh_in_window(
        &self,
        b: usize,
        proxies: &Proxies,
        w: &[[f64; WINDOW]],
        chi: &mut [f64],
    ) {
        let first = self.slots_in_brick(b).start;
        let first_node = proxies.degree.first_node();
        for cell in self.in_brick(b) {
            let c = brick_local(cell.position as usize).map(|v| v + 2);
            let mut x = [0.0; 27];
            for (k, x) in x.chunks_exact_mut(3).enumerate() {
                let row = &w[(c[2] + k / 3 - 1) * WINDOW + c[1] + k % 3 - 1];
                x.copy_from_slice(&row[c[0] - 1..c[0] + 2]);
            }
            for (slot, q) in cell.slots().zip(cell.proxy_range()) {
                chi[slot - first] =
                    proxies.weight[q] * tensor_contract(&proxies.stencil(q), &x, first_node);
            }
        }
    }
}

/// `acc` += `weight · st[0] ⊗ st[1] ⊗ st[2]` over a cell's block from block node `FIRST` of
/// every axis on, the cell at window coordinate `w` (local + 2): [`tensor_accumulate`] into a
/// zeroed block and then [`add_block`], fused; each element gets the same product, added once.
#[inline(always)]
fn add_tensor<const FIRST: usize>(
    st: &[[f64; 3]; 3],
    weight: f64,
    w: [usize; 3],
    acc: &mut [f64; PADDED],
) {
    for dz in FIRST..3 {
        let wz = weight * st[2][dz];
        for dy in FIRST..3 {
            let wzy = wz * st[1][dy];
            let at = w[0] - 1 + WINDOW * ((w[1] - 1 + dy) + WINDOW * (w[2] - 1 + dz));
            for x in FIRST..3 {
                acc[at + x] += wzy * st[0][x];
            }
        }
    }
}

/// `acc` += a cell's block `contribution` (3×3×3, x fastest) from block node `FIRST` of every
/// axis on, the cell at window coordinate `w` (local + 2): block node d at padded index
/// w − 1 + d.
#[inline(always)]
fn add_block<const FIRST: usize>(contribution: &[f64; 27], w: [usize; 3], acc: &mut [f64; PADDED]) {
    for dz in FIRST..3 {
        for dy in FIRST..3 {
            let at = w[0] - 1 + WINDOW * ((w[1] - 1 + dy) + WINDOW * (w[2] - 1 + dz));
            let row = &contribution[9 * dz + 3 * dy..9 * dz + 3 * dy + 3];
            for x in FIRST..3 {
                acc[at + x] += row[x];
            }
        }
    }
}

impl ScreeningCell {
    /// Its proxies' indices in [`Proxies`].
    pub(super) fn proxy_range(&self) -> std::ops::Range<usize> {
        self.proxies.0 as usize..self.proxies.1 as usize
    }

    /// Its proxies' slots.
    pub(super) fn slots(&self) -> std::ops::Range<usize> {
        let first = self.first_slot as usize;
        first..first + (self.proxies.1 - self.proxies.0) as usize
    }
}

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
//! applied as three 1-D passes along the neighbour links (5 taps each) instead of 125-entry rows:
//! `⟨∇B_o, ∇B_o′⟩ = h (D⊗M⊗M + M⊗D⊗M + M⊗M⊗D)` and `⟨∇B_o, F̃_o′⟩·v = (1/h)(G⊗M⊗M vx + …)`.
//! A pass over the halo K_d is exact wherever its input is supported on K_d (see
//! [`crate::octree`]), so no node ever reads a neighbour that should exist but does not.
//!
//! Cross-depth terms use the two-scale relation ([`crate::bspline::REFINE`]) instead of
//! cross-depth tables: coarser coefficients are prolonged into the current depth's halo, and the
//! divergence of finer vector-field coefficients is restricted to coarser nodes. Both are exact.

use crate::bspline::{tables, REFINE};
use crate::octree::{Level, NONE};
use glam::DVec3;
use rayon::prelude::*;

/// Rows per parallel task: fixed, so results never depend on the thread count.
pub const CHUNK: usize = 4096;

/// out[i] = Σ_δ taps[δ+2] · input[node i shifted by δ along `axis`], for every node of K_d.
pub fn pass(level: &Level, axis: usize, taps: &[f64; 5], input: &[f64], out: &mut [f64]) {
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            for (j, o) in chunk.iter_mut().enumerate() {
                *o = tap_sum(level, axis, taps, input, (c * CHUNK + j) as u32);
            }
        });
}

#[inline]
fn tap_sum(level: &Level, axis: usize, taps: &[f64; 5], input: &[f64], i: u32) -> f64 {
    let (minus, plus) = (2 * axis, 2 * axis + 1);
    let mut sum = taps[2] * input[i as usize];
    let m1 = level.neighbor(i, minus);
    if m1 != NONE {
        sum += taps[1] * input[m1 as usize];
        let m2 = level.neighbor(m1, minus);
        if m2 != NONE {
            sum += taps[0] * input[m2 as usize];
        }
    }
    let p1 = level.neighbor(i, plus);
    if p1 != NONE {
        sum += taps[3] * input[p1 as usize];
        let p2 = level.neighbor(p1, plus);
        if p2 != NONE {
            sum += taps[4] * input[p2 as usize];
        }
    }
    sum
}

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
    let shared = SharedSlice::new(x);
    level
        .core
        .par_chunks(CHUNK)
        .enumerate()
        .for_each(|(c, nodes)| {
            for (j, &n) in nodes.iter().enumerate() {
                // SAFETY: core indices are distinct, so each element has one writer.
                let v = unsafe { shared.get_mut(n as usize) };
                *v = f(c * CHUNK + j, *v);
            }
        });
    fill_mirrors(level, x);
}

/// x[core node] += alpha · p[core node] for every core node (in parallel; mirrors untouched).
pub fn add_on_core(level: &Level, x: &mut [f64], alpha: f64, p: &[f64]) {
    let shared = SharedSlice::new(x);
    level.core.par_chunks(CHUNK).for_each(|nodes| {
        for &n in nodes {
            // SAFETY: core indices are distinct, so each element has one writer.
            unsafe { *shared.get_mut(n as usize) += alpha * p[n as usize] };
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
    /// b(t − centre) for the three nodes per axis around the proxy's cell (cell − 1, cell,
    /// cell + 1), evaluated at the proxy.
    pub stencil: Vec<[[f64; 3]; 3]>,
}

impl Proxies {
    /// Groups samples (in `order`, sorted by Morton key at a depth ≥ `proxy_depth`) into
    /// proxies at `proxy_depth` ≥ the level's depth. In parallel over pieces of `order` cut
    /// between groups (a fixed number of samples apart), appended in order.
    pub fn build(
        level: &Level,
        positions: &[DVec3],
        weights: &[f64],
        order: &[u32],
        proxy_depth: u32,
    ) -> Proxies {
        const SAMPLES_PER_PIECE: usize = 1 << 14;
        let inv_proxy_h = (proxy_depth as f64).exp2();
        let group_of = |s: usize| cell_of(positions[order[s] as usize], inv_proxy_h);
        let mut cuts = vec![0];
        while let Some(&last) = cuts.last() {
            let mut cut = last + SAMPLES_PER_PIECE;
            if cut >= order.len() {
                break;
            }
            while cut < order.len() && group_of(cut) == group_of(cut - 1) {
                cut += 1;
            }
            cuts.push(cut);
        }
        cuts.push(order.len());
        let pieces: Vec<Proxies> = cuts
            .par_windows(2)
            .map(|piece| {
                Self::build_piece(
                    level,
                    positions,
                    weights,
                    &order[piece[0]..piece[1]],
                    proxy_depth,
                )
            })
            .collect();
        let mut proxies = Proxies::default();
        for piece in pieces {
            proxies.cell.extend(piece.cell);
            proxies.weight.extend(piece.weight);
            proxies.stencil.extend(piece.stencil);
        }
        proxies
    }

    /// [`Proxies::build`] on a run of `order` that starts and ends between groups.
    fn build_piece(
        level: &Level,
        positions: &[DVec3],
        weights: &[f64],
        order: &[u32],
        proxy_depth: u32,
    ) -> Proxies {
        let inv_h = (level.depth as f64).exp2();
        let inv_proxy_h = (proxy_depth as f64).exp2();
        let mut proxies = Proxies::default();
        let mut s = 0;
        while s < order.len() {
            let group = cell_of(positions[order[s] as usize], inv_proxy_h);
            let mut sum_w = 0.0;
            let mut sum_p = DVec3::ZERO;
            while s < order.len() && cell_of(positions[order[s] as usize], inv_proxy_h) == group {
                let k = order[s] as usize;
                sum_w += weights[k];
                sum_p += positions[k] * weights[k];
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
            let q = sum_p / sum_w;
            let (_, stencil) = crate::density::stencil27(q, inv_h);
            proxies.cell.push(idx);
            proxies.weight.push(sum_w);
            proxies.stencil.push(stencil);
        }
        proxies
    }

    pub fn len(&self) -> usize {
        self.cell.len()
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

/// Where the input of [`DepthOperator::apply_on`] can be non-zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Support {
    /// Anywhere on K_d (e.g. the prolonged coarser solution).
    Halo,
    /// Only on the core C_d (the conjugate-gradient directions): the z-pass then only has to run
    /// within two nodes (along z) of the core, everything else it would produce is zero.
    Core,
}

/// The nodes one 1-D pass visits, line by line along its axis: every maximal run of K_d nodes
/// within two nodes (along the axis) of a node whose value a later pass reads. Walking a line
/// with a sliding window reads each input once and needs no neighbour links (chasing two links
/// per tap, mostly to far-away Morton indices, was the cost of the passes).
struct PassLines {
    /// Node indices, line after line, each line followed by [`LINE_END`]; a node whose value is
    /// read later carries [`NEEDED`], and [`NEEDED_FOR_CORE_INPUT`] if that value can be non-zero
    /// when the input lives on the core.
    entries: Vec<u32>,
    /// Task c walks `entries[task_start[c]..task_start[c + 1]]` (whole lines, a fixed split).
    task_start: Vec<usize>,
}

const LINE_END: u32 = u32::MAX;
const NEEDED: u32 = 1 << 31;
const NEEDED_FOR_CORE_INPUT: u32 = 1 << 30;
const NODE_BITS: u32 = NEEDED_FOR_CORE_INPUT - 1;
/// Lines per parallel task of a pass.
const LINES_PER_TASK: usize = 512;

impl PassLines {
    /// `needed[i]`: the flags of node i (0 when no later pass reads it).
    fn new(level: &Level, axis: usize, needed: &[u32]) -> PassLines {
        assert!(
            level.len() <= NODE_BITS as usize,
            "too many nodes for the pass lines"
        );
        let in_span: Vec<bool> = (0..level.len() as u32)
            .into_par_iter()
            .map(|i| {
                line5(level, axis, i)
                    .iter()
                    .any(|&n| n != NONE && needed[n as usize] != 0)
            })
            .collect();
        let (minus, plus) = (2 * axis, 2 * axis + 1);
        let starts: Vec<u32> = (0..level.len() as u32)
            .into_par_iter()
            .filter(|&i| {
                let before = level.neighbor(i, minus);
                in_span[i as usize] && (before == NONE || !in_span[before as usize])
            })
            .collect();
        let tasks: Vec<Vec<u32>> = starts
            .par_chunks(LINES_PER_TASK)
            .map(|starts| {
                let mut entries = Vec::new();
                for &start in starts {
                    let mut n = start;
                    while n != NONE && in_span[n as usize] {
                        entries.push(n | needed[n as usize]);
                        n = level.neighbor(n, plus);
                    }
                    entries.push(LINE_END);
                }
                entries
            })
            .collect();
        let mut task_start = vec![0];
        for task in &tasks {
            task_start.push(task_start.last().unwrap() + task.len());
        }
        PassLines {
            entries: tasks.concat(),
            task_start,
        }
    }

    /// For every node the pass must produce, `update(window, &mut out[node])` with the input
    /// values at offsets −2..=2 along the line (zero where K_d has no node). With
    /// `core_input`, nodes only needed for inputs beyond the core get an all-zero window.
    fn run<V, T>(
        &self,
        core_input: bool,
        out: &mut [T],
        read: impl Fn(usize) -> V + Sync,
        update: impl Fn([V; 5], &mut T) + Sync,
    ) where
        V: Copy + Default,
        T: Send,
    {
        let out = SharedSlice::new(out);
        // SAFETY: every node lies on one line of this pass only, and one task walks each line.
        self.walk(core_input, read, |n, window| {
            update(window, unsafe { out.get_mut(n) })
        });
    }

    /// [`run`](Self::run) with the input in the output's own elements (`read` picks it from
    /// one): a line's inputs are all read before its outputs are written, and lines share no
    /// node, so the pass needs no second buffer.
    fn run_in_place<V, T>(
        &self,
        values: &mut [T],
        read: impl Fn(&T) -> V + Sync,
        update: impl Fn([V; 5], &mut T) + Sync,
    ) where
        V: Copy + Default,
        T: Send,
    {
        let values = SharedSlice::new(values);
        // SAFETY: as in `run`; a node is only read by the task of its line, before that task
        // writes it.
        self.walk(
            false,
            |n| read(unsafe { values.get_mut(n) }),
            |n, window| update(window, unsafe { values.get_mut(n) }),
        );
    }

    /// Walks every line (tasks in parallel): reads its nodes' inputs, then calls
    /// `write(node, window)` for every node the pass must produce.
    fn walk<V>(
        &self,
        core_input: bool,
        read: impl Fn(usize) -> V + Sync,
        write: impl Fn(usize, [V; 5]) + Sync,
    ) where
        V: Copy + Default,
    {
        let computed = if core_input {
            NEEDED_FOR_CORE_INPUT
        } else {
            NEEDED
        };
        self.task_start.par_windows(2).for_each(|task| {
            let mut values: Vec<V> = Vec::new();
            for line in self.entries[task[0]..task[1]].split(|&e| e == LINE_END) {
                if line.is_empty() {
                    continue;
                }
                values.clear();
                values.extend([V::default(); 2]);
                values.extend(line.iter().map(|&e| read((e & NODE_BITS) as usize)));
                values.extend([V::default(); 2]);
                for (k, &e) in line.iter().enumerate() {
                    if e & NEEDED == 0 {
                        continue;
                    }
                    let window = if e & computed != 0 {
                        [
                            values[k],
                            values[k + 1],
                            values[k + 2],
                            values[k + 3],
                            values[k + 4],
                        ]
                    } else {
                        [V::default(); 5]
                    };
                    write((e & NODE_BITS) as usize, window);
                }
            }
        });
    }
}

/// The lines of the z and y passes of one depth.
struct PassPlan {
    /// z-pass: the nodes the y-pass reads (the core widened by two along x, then two along y);
    /// with a core input only those within two nodes along z of the core can be non-zero.
    z: PassLines,
    /// y-pass: the nodes the x-pass reads (the core widened by two along x).
    y: PassLines,
}

impl PassPlan {
    fn new(level: &Level) -> PassPlan {
        let line_has = |axis: usize, i: u32, marked: &dyn Fn(u32) -> bool| {
            line5(level, axis, i)
                .iter()
                .any(|&n| n != NONE && marked(n))
        };
        let is_core = |n: u32| level.flags[n as usize] & crate::octree::CORE != 0;
        let nodes = 0..level.len() as u32;
        let y_needed: Vec<u32> = nodes
            .clone()
            .into_par_iter()
            .map(|i| {
                if line_has(0, i, &is_core) {
                    NEEDED | NEEDED_FOR_CORE_INPUT
                } else {
                    0
                }
            })
            .collect();
        let z_needed: Vec<u32> = nodes
            .into_par_iter()
            .map(|i| {
                if !line_has(1, i, &|n| y_needed[n as usize] != 0) {
                    0
                } else if line_has(2, i, &is_core) {
                    NEEDED | NEEDED_FOR_CORE_INPUT
                } else {
                    NEEDED
                }
            })
            .collect();
        PassPlan {
            z: PassLines::new(level, 2, &z_needed),
            y: PassLines::new(level, 1, &y_needed),
        }
    }
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

/// The five nodes on the line through node `i` along `axis`, at offsets −2..=2 (`NONE` where
/// outside K_d).
#[inline]
fn line5(level: &Level, axis: usize, i: u32) -> [u32; 5] {
    let step = |n: u32, dir: usize| {
        if n == NONE {
            NONE
        } else {
            level.neighbor(n, dir)
        }
    };
    let m1 = step(i, 2 * axis);
    let p1 = step(i, 2 * axis + 1);
    [step(m1, 2 * axis), m1, i, p1, step(p1, 2 * axis + 1)]
}

/// Σ_δ taps[δ+2] · value(node at δ) along the line (summed in the order of [`tap_sum`]).
#[inline]
fn line_sum(line: &[u32; 5], taps: &[f64; 5], value: impl Fn(usize) -> f64) -> f64 {
    let mut sum = taps[2] * value(line[2] as usize);
    for slot in [1, 0, 3, 4] {
        if line[slot] != NONE {
            sum += taps[slot] * value(line[slot] as usize);
        }
    }
    sum
}

/// The operator A_d = L_d + S_d of one depth, with its scratch space.
pub struct DepthOperator<'a> {
    pub level: &'a Level,
    pub proxies: &'a Proxies,
    /// Weight of the screening term.
    pub screening: f64,
    plan: PassPlan,
    /// The passes' values on K_d: the z-pass writes (M_z·input, D_z·input), the y-pass
    /// replaces them, line by line, with (M_y M_z·input, (D_y M_z + M_y D_z)·input).
    passes: Vec<[f64; 2]>,
    /// The cells whose proxies screen this depth (`None` without screening).
    screening_cells: Option<ScreeningCells>,
}

impl<'a> DepthOperator<'a> {
    /// `screening` is the weight α_d of the screening term at this depth.
    pub fn new(level: &'a Level, proxies: &'a Proxies, screening: f64) -> Self {
        let n = level.len();
        let screens = screening > 0.0 && !proxies.is_empty();
        let screening_cells = screens.then(|| ScreeningCells::new(level, proxies));
        DepthOperator {
            level,
            proxies,
            screening,
            plan: PassPlan::new(level),
            passes: vec![[0.0; 2]; n],
            screening_cells,
        }
    }

    /// out[c] = (A · input)(core node c), for `input` given on all of K_d (with its mirror
    /// nodes filled, see [`fill_mirrors`]), e.g. the prolonged coarser solution.
    pub fn apply(&mut self, input: &[f64], out: &mut [f64]) {
        self.apply_on(input, Support::Halo, out);
    }

    /// out = A·x for `x` on K_d that is non-zero only on the core (e.g. a conjugate-gradient
    /// direction, see [`update_on_core`]) and, with Neumann boundaries, on the mirror nodes
    /// outside the cube, which carry the values they reflect as in every vector A acts on (the
    /// folded basis). Without mirrors the passes are restricted to the core's neighbourhood;
    /// the mirrors lie beyond it, so with them they are not.
    pub fn apply_core(&mut self, x: &[f64], out: &mut [f64]) {
        let support = if self.level.mirrors.is_empty() {
            Support::Core
        } else {
            Support::Halo
        };
        self.apply_on(x, support, out);
    }

    /// out[c] = (A · input)(core node c), for `input` given on all of K_d and non-zero only
    /// where `support` says.
    ///
    /// The Laplacian h·(D⊗M⊗M + M⊗D⊗M + M⊗M⊗D) is applied as three fused 1-D passes, z then
    /// y then x, each computed only where the next one reads it (see [`PassPlan`]).
    fn apply_on(&mut self, input: &[f64], support: Support, out: &mut [f64]) {
        let level = self.level;
        let t = tables();
        let h = level.width();
        self.plan.z.run(
            support == Support::Core,
            &mut self.passes,
            |n| input[n],
            |w, o| *o = [window_sum(&t.mass, &w), window_sum(&t.stiffness, &w)],
        );
        self.plan.y.run_in_place(
            &mut self.passes,
            |&v| v,
            |w, o| {
                let (a, b) = (w.map(|v| v[0]), w.map(|v| v[1]));
                *o = [
                    window_sum(&t.mass, &a),
                    window_sum(&t.stiffness, &a) + window_sum(&t.mass, &b),
                ];
            },
        );
        let core = &level.core;
        let y_pass = &self.passes;
        out.par_chunks_mut(CHUNK)
            .zip(core.par_chunks(CHUNK))
            .for_each(|(o, nodes)| {
                for (o, &n) in o.iter_mut().zip(nodes) {
                    let line = line5(level, 0, n);
                    *o = h
                        * (line_sum(&line, &t.stiffness, |n| y_pass[n][0])
                            + line_sum(&line, &t.mass, |n| y_pass[n][1]));
                }
            });
        if let Some(cells) = &self.screening_cells {
            let scale = self.screening;
            let proxies = self.proxies;
            // Σ_q W_q B_o(q) χ(q) on K_d, in the first half of the pass buffer (free again
            // once the x-pass has read it).
            let screened = &mut self.passes.as_flattened_mut()[..level.len()];
            screened.par_iter_mut().for_each(|v| *v = 0.0);
            cells.scatter(screened, |block, range, contribution| {
                let mut x = [0.0; 27];
                for (x, &n) in x.iter_mut().zip(block) {
                    if n != NONE {
                        *x = input[n as usize];
                    }
                }
                for q in range {
                    let st = &proxies.stencil[q];
                    let chi = tensor_contract(st, &x);
                    tensor_accumulate(st, proxies.weight[q] * chi, contribution);
                }
            });
            let screened = &*screened;
            out.par_chunks_mut(CHUNK)
                .zip(core.par_chunks(CHUNK))
                .for_each(|(o, nodes)| {
                    for (o, &n) in o.iter_mut().zip(nodes) {
                        *o += scale * screened[n as usize];
                    }
                });
            // Neumann: an inside node's function is folded with its reflections, so it also
            // collects what the proxies give its mirror images.
            for m in &level.mirrors {
                if let Ok(pos) = core.binary_search(&m.inside) {
                    out[pos] += scale * screened[m.outside as usize];
                }
            }
        }
    }

    /// ⟨∇B_o, V⟩ at every core node (in core order) for a field V whose coefficients on K_d
    /// (x, y, z at node n) `v(n)` gives: [`divergence`] restricted to the core, computed with
    /// the fused passes as (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)). `v` is
    /// called twice per node the passes visit.
    pub fn divergence_on_core(&mut self, v: impl Fn(usize) -> [f64; 3] + Sync) -> Vec<f64> {
        let level = self.level;
        let t = tables();
        let inv_h = 1.0 / level.width();
        let plan = &self.plan;
        // After the y-pass, passes[·][1] = G_y M_z v_y + M_y G_z v_z ...
        plan.z.run(
            false,
            &mut self.passes,
            |n| {
                let v = v(n);
                [v[1], v[2]]
            },
            |w, o| {
                let (a, b) = (w.map(|v| v[0]), w.map(|v| v[1]));
                *o = [window_sum(&t.mass, &a), window_sum(&t.advection, &b)];
            },
        );
        plan.y.run_in_place(
            &mut self.passes,
            |&v| v,
            |w, o| {
                let (a, b) = (w.map(|v| v[0]), w.map(|v| v[1]));
                o[1] = window_sum(&t.advection, &a) + window_sum(&t.mass, &b);
            },
        );
        // ... and then passes[·][0] = M_y M_z v_x (the z-pass writes only [0], which keeps the
        // [1] the y-pass wrote at the nodes the x-pass reads).
        plan.z.run(
            false,
            &mut self.passes,
            |n| v(n)[0],
            |w, o| o[0] = window_sum(&t.mass, &w),
        );
        plan.y.run_in_place(
            &mut self.passes,
            |v| v[0],
            |w, o| o[0] = window_sum(&t.mass, &w),
        );
        let y_pass = &self.passes;
        level
            .core
            .par_iter()
            .with_min_len(CHUNK)
            .map(|&n| {
                let line = line5(level, 0, n);
                inv_h
                    * (line_sum(&line, &t.advection, |n| y_pass[n][0])
                        + line_sum(&line, &t.mass, |n| y_pass[n][1]))
            })
            .collect()
    }

    /// The diagonal of A on the core (for Jacobi preconditioning).
    pub fn diagonal(&mut self) -> Vec<f64> {
        let level = self.level;
        let t = tables();
        let lap = level.width() * 3.0 * t.stiffness[2] * t.mass[2] * t.mass[2];
        let Some(cells) = &self.screening_cells else {
            return vec![lap; level.core.len()];
        };
        let proxies = self.proxies;
        let scale = self.screening;
        let screened = &mut self.passes.as_flattened_mut()[..level.len()];
        screened.par_iter_mut().for_each(|v| *v = 0.0);
        cells.scatter(screened, |_, range, contribution| {
            for q in range {
                let st = &proxies.stencil[q];
                let w = proxies.weight[q];
                for (slot, c) in contribution.iter_mut().enumerate() {
                    let b = st[0][slot % 3] * st[1][(slot / 3) % 3] * st[2][slot / 9];
                    *c += w * b * b;
                }
            }
        });
        let screened = &*screened;
        level
            .core
            .par_iter()
            .map(|&n| lap + scale * screened[n as usize])
            .collect()
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

/// out[slot] += w · st[0][slot % 3] · st[1][slot / 3 % 3] · st[2][slot / 9], the transpose of
/// [`tensor_contract`].
#[inline]
fn tensor_accumulate(st: &[[f64; 3]; 3], w: f64, out: &mut [f64; 27]) {
    for (z, plane) in out.chunks_exact_mut(9).enumerate() {
        let wz = w * st[2][z];
        for (y, row) in plane.chunks_exact_mut(3).enumerate() {
            let wzy = wz * st[1][y];
            for (o, sx) in row.iter_mut().zip(&st[0]) {
                *o += wzy * sx;
            }
        }
    }
}

/// The cells of K_d holding proxies, in slabs of [`SLAB`] cells along z, each slab in Morton
/// order. The 3×3×3 node blocks around the cells of two even (or two odd) slabs never overlap,
/// so all even slabs, then all odd ones, scatter into node values in parallel without races,
/// one task per slab; every node then sums its contributions in an order that does not depend
/// on the thread count. Within a slab, consecutive cells touch nearby nodes (cache reuse).
///
/// This replaces gathering, per core node, from the 27 cells around it (a random look-up per
/// cell, most of them empty): only cells that hold proxies are visited, once per product.
struct ScreeningCells {
    /// The 3×3×3 node block around each cell holding proxies (x fastest, `NONE` outside K_d),
    /// slab by slab: looked up once per depth rather than by chasing links in every product.
    blocks: Vec<[u32; 27]>,
    /// The range of each cell's proxies.
    proxies: Vec<(u32, u32)>,
    /// The ranges of `blocks` of the even slabs, then of the odd ones.
    slabs: [Vec<std::ops::Range<usize>>; 2],
}

/// Slab thickness in cells (≥ 2 keeps the blocks of same-parity slabs apart).
const SLAB: i32 = 4;

impl ScreeningCells {
    fn new(level: &Level, proxies: &Proxies) -> ScreeningCells {
        let slab_of = |cell: u32| level.coord(cell)[2].div_euclid(SLAB);
        // Each cell with its run of proxies (the proxies of one cell are consecutive; were they
        // not, a cell would just appear twice in its slab).
        let mut cells: Vec<(u32, (u32, u32))> = Vec::new();
        for (q, &cell) in proxies.cell.iter().enumerate() {
            match cells.last_mut() {
                Some((last, range)) if *last == cell => range.1 = q as u32 + 1,
                _ => cells.push((cell, (q as u32, q as u32 + 1))),
            }
        }
        cells.par_sort_unstable_by_key(|&(cell, _)| (slab_of(cell), cell));
        let mut slabs: [Vec<std::ops::Range<usize>>; 2] = [Vec::new(), Vec::new()];
        let mut start = 0;
        while start < cells.len() {
            let slab = slab_of(cells[start].0);
            let end = start + cells[start..].partition_point(|&(c, _)| slab_of(c) == slab);
            slabs[slab.rem_euclid(2) as usize].push(start..end);
            start = end;
        }
        ScreeningCells {
            blocks: cells
                .par_iter()
                .map(|&(cell, _)| level.block27(cell))
                .collect(),
            proxies: cells.iter().map(|&(_, range)| range).collect(),
            slabs,
        }
    }

    /// For every cell, `contribute(node block, range of the cell's proxies, contribution)` fills
    /// 27 values (x fastest) that are then added to `values` at the cell's 3×3×3 node block.
    fn scatter(
        &self,
        values: &mut [f64],
        contribute: impl Fn(&[u32; 27], std::ops::Range<usize>, &mut [f64; 27]) + Sync,
    ) {
        let shared = SharedSlice::new(values);
        for parity in &self.slabs {
            parity.par_iter().for_each(|slab| {
                let blocks = &self.blocks[slab.clone()];
                let proxies = &self.proxies[slab.clone()];
                for (block, &(start, end)) in blocks.iter().zip(proxies) {
                    let mut contribution = [0.0; 27];
                    contribute(block, start as usize..end as usize, &mut contribution);
                    for (&n, c) in block.iter().zip(&contribution) {
                        if n != NONE {
                            // SAFETY: the blocks of the slabs of one parity are disjoint, so no
                            // other thread touches node n while this parity runs.
                            unsafe { *shared.get_mut(n as usize) += *c };
                        }
                    }
                }
            });
        }
    }
}

/// A slice written from several threads at indices known to be disjoint between threads.
struct SharedSlice<'a, T> {
    start: *mut T,
    len: usize,
    _slice: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: elements are only reached through `get_mut`, whose callers guarantee that no two
// threads use the same index at the same time; T: Send lets them move between threads.
unsafe impl<T: Send> Sync for SharedSlice<'_, T> {}

impl<'a, T> SharedSlice<'a, T> {
    fn new(slice: &'a mut [T]) -> Self {
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
    unsafe fn get_mut(&self, i: usize) -> &mut T {
        assert!(i < self.len);
        &mut *self.start.add(i)
    }
}

/// Σ over the 27 nodes around `cell` of x · (tensor stencil weight).
#[inline]
pub fn evaluate_block(level: &Level, cell: u32, st: &[[f64; 3]; 3], x: &[f64]) -> f64 {
    let block = level.block27(cell);
    let mut sum = 0.0;
    for (slot, &n) in block.iter().enumerate() {
        if n != NONE {
            sum += x[n as usize] * st[0][slot % 3] * st[1][(slot / 3) % 3] * st[2][slot / 9];
        }
    }
    sum
}

/// ⟨∇B_o, V_d⟩ for every node of K_d, where V_d = Σ v_o′ B_o′/h³ (unit-integral node
/// functions, §4.1) has coefficients `v` (x, y, z components) on K_d.
pub fn divergence(level: &Level, v: &[Vec<f64>; 3]) -> Vec<f64> {
    let t = tables();
    let n = level.len();
    let inv_h = 1.0 / level.width();
    let mut a = vec![0.0; n];
    let mut b = vec![0.0; n];
    let mut out = vec![0.0; n];
    // x component: G_x M_y M_z
    pass(level, 2, &t.mass, &v[0], &mut a);
    pass(level, 1, &t.mass, &a, &mut b);
    pass(level, 0, &t.advection, &b, &mut out);
    // y component: M_x G_y M_z
    pass(level, 2, &t.mass, &v[1], &mut a);
    pass(level, 1, &t.advection, &a, &mut b);
    pass(level, 0, &t.mass, &b, &mut a);
    add_into(&mut out, &a);
    // z component: M_x M_y G_z
    pass(level, 2, &t.advection, &v[2], &mut a);
    pass(level, 1, &t.mass, &a, &mut b);
    pass(level, 0, &t.mass, &b, &mut a);
    add_into(&mut out, &a);
    out.par_iter_mut().for_each(|o| *o *= inv_h);
    out
}

fn add_into(out: &mut [f64], x: &[f64]) {
    out.par_chunks_mut(CHUNK)
        .zip(x.par_chunks(CHUNK))
        .for_each(|(o, x)| {
            for (o, x) in o.iter_mut().zip(x) {
                *o += x;
            }
        });
}

/// The eight parents of fine node `i` whose refinement covers it, with their two-scale weights:
/// per axis, child 2m = ¾·parent m + ¼·parent m−1 and child 2m+1 = ¾·parent m + ¼·parent m+1.
#[inline]
fn refinement_parents(coarse: &Level, fine: &Level, i: u32) -> [(u32, f64); 8] {
    let mut out = [(NONE, 0.0); 8];
    let p = fine.parent[i as usize];
    if p == NONE {
        return out;
    }
    // The parity of each coordinate is the key's bit of that axis (the key's offset is even).
    let key = fine.keys[i as usize];
    let partner_dir = [0, 1, 2].map(|axis| 2 * axis + ((key >> axis) & 1) as usize);
    for k in 0..8 {
        // Parent k is parent (k without its highest axis bit) stepped along that axis: seven
        // links in all, each parent reached along x, then y, then z.
        let node = if k == 0 {
            p
        } else {
            let axis = 7 - (k as u8).leading_zeros() as usize;
            let from = out[k & !(1 << axis)].0;
            if from == NONE {
                NONE
            } else {
                coarse.neighbor(from, partner_dir[axis])
            }
        };
        let mut w = 1.0;
        for axis in 0..3 {
            w *= if (k >> axis) & 1 == 1 {
                REFINE[0]
            } else {
                REFINE[1]
            };
        }
        out[k] = (node, w);
    }
    out
}

/// Prolongs coarse coefficients (on K_{d−1}) to the fine halo K_d, exactly: the fine
/// combination represents the same function wherever the coarse one is complete.
pub fn prolong(coarse: &Level, fine: &Level, x: &[f64], scale: f64) -> Vec<f64> {
    let [out] = prolong_many(coarse, fine, [x], [scale]);
    out
}

/// [`prolong`] of several coefficient vectors (each with its scale) in one sweep, so the parents
/// of every fine node are looked up once.
pub fn prolong_many<const N: usize>(
    coarse: &Level,
    fine: &Level,
    inputs: [&[f64]; N],
    scales: [f64; N],
) -> [Vec<f64>; N] {
    let mut out: [Vec<f64>; N] = std::array::from_fn(|_| vec![0.0; fine.len()]);
    let mut columns = out.each_mut().map(|o| o.chunks_mut(CHUNK));
    let chunks: Vec<[&mut [f64]; N]> = (0..fine.len().div_ceil(CHUNK))
        .map(|_| {
            columns
                .each_mut()
                .map(|c| c.next().expect("one chunk per column"))
        })
        .collect();
    chunks
        .into_par_iter()
        .enumerate()
        .for_each(|(c, mut outs)| {
            for j in 0..outs[0].len() {
                let values = prolonged_at(coarse, fine, inputs, scales, (c * CHUNK + j) as u32);
                for (o, v) in outs.iter_mut().zip(values) {
                    o[j] = v;
                }
            }
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

/// A coarser vector field prolonged to a finer halo, evaluated node by node instead of stored:
/// the value at a fine node is what [`prolong_many`] followed by [`fill_mirrors_field`] would
/// hold there. Reading it once per node (as a pass does) costs one prolongation sweep and saves
/// three halo-sized vectors.
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

    /// v[axis][i] += the prolonged field at every fine node i.
    pub fn add_to(&self, v: &mut [Vec<f64>; 3]) {
        let [vx, vy, vz] = v;
        vx.par_chunks_mut(CHUNK)
            .zip(vy.par_chunks_mut(CHUNK).zip(vz.par_chunks_mut(CHUNK)))
            .enumerate()
            .for_each(|(c, (x, (y, z)))| {
                for j in 0..x.len() {
                    let p = self.at((c * CHUNK + j) as u32);
                    x[j] = p[0] + x[j];
                    y[j] = p[1] + y[j];
                    z[j] = p[2] + z[j];
                }
            });
    }
}

/// The transpose of [`prolong`]: adds Σ_children w · fine[child] to every coarse node.
pub fn restrict_into(coarse: &Level, fine: &Level, fine_values: &[f64], coarse_out: &mut [f64]) {
    for i in 0..fine.len() as u32 {
        let v = fine_values[i as usize];
        if v == 0.0 {
            continue;
        }
        for (n, w) in refinement_parents(coarse, fine, i) {
            if n != NONE {
                coarse_out[n as usize] += w * v;
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
        let div = divergence(level, &v);
        // ⟨∇B_o, V⟩ = −∫B_o ∇·V = −(1 + 2 − 1)·h³ at every core node.
        for &c in &level.core {
            let got = div[c as usize];
            assert!((got + 2.0 * h * h * h).abs() < 1e-12, "{got}");
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
        let full = divergence(level, &v);
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

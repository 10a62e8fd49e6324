//! Stage 2 — kernel density estimation (§4.5).
//!
//! Every sample splats a unit weight onto the eight depth-D̂ nodes nearest to it with trilinear
//! weights; the density at a point is W(q) = Σ_o count_o · B_o(q), which for a surface sampled
//! with ρ samples per unit area is about ρ·h²·B₄(0) (B₄ the quartic B-spline, 115/192: the
//! trilinear hat convolved with b, integrated across the surface).
//!
//! From W each sample gets
//! * an **area** A_s = (115/192)·h_D̂² / W(s): the patch of surface it stands for (§4.5 weights
//!   its contribution by 1/W; the constant makes V the gradient of a unit-jump indicator, which
//!   the screening term needs);
//! * a **depth** Depth(s) = min(D, D̂ + log₄(W(s)/n)), where n is the target number of samples per
//!   node: W(s)·4^(D̂−d) samples fall in a depth-d node around s, so this is the depth at which
//!   that count is n. It is the paper's min(D, D + log₄(W/W̄)) with the reference density tied to
//!   a sample count (PoissonRecon's `samplesPerNode`) instead of the mean, so uniformly dense
//!   scans keep their full depth.
//!
//! Where W(s) < n the kernel depth is finer than the sampling, and W there is mostly the
//! sample's own splat (≈ 0.2–0.4 at any depth), which would put every sample, however sparse or
//! isolated, within about a level of D̂. So the counts are also kept at every coarser depth
//! (each restricted from the next finer one), and such a sample's density is read at coarser
//! and coarser depths d until W_d(s) ≥ n; its depth lies between d and d + 1 by the counts seen
//! at the two (d + ln(W_d/n) / ln(W_d/W_{d+1})), and its area is (115/192)·h_d²/W_d. This is
//! what PoissonRecon does too. It keeps the tree, the splat and the screening from following a
//! requested depth beyond what the samples resolve (issue 16's "bumps": exact samples of a box
//! came out less accurate at depth 12 than unscreened), and gives stray samples a coarse depth.
//!
//! Where the surface bends under the kernel (the samples' unit normals, summed with the same
//! weights as the counts, cancel by more than [`BENT_SPREAD`]), the count is read as
//! PoissonRecon reads it (against n·B₄(0)), which puts the sample's splat up to a third of a
//! depth finer, though never past the next whole depth the plain count gives: the bend's sag
//! under a coarse splat is then the larger error, while on a flat or gently curved surface the
//! finer splat would only follow the sampling's chance fluctuations (see [`estimate`]).

use crate::bspline::stencil27;
use crate::error::Result;
use crate::grid::{morton, unmorton, Coord, KeyMap, OFFSET};
use crate::octree::NONE;
use crate::parallel::{map_in_blocks, Watch};
use glam::{DVec3, DVec4};
use rayon::prelude::*;
use std::sync::Arc;

/// B₄(0): the quartic B-spline's peak, the plane integral of the splatting kernel.
const PLANE_KERNEL_PEAK: f64 = 115.0 / 192.0;

/// The eight nodes nearest to `p` at a depth of width `h` and their trilinear weights.
#[inline]
fn trilinear(p: DVec3, inv_h: f64) -> [([i32; 3], f64); 8] {
    let t = p * inv_h - DVec3::splat(0.5);
    let base = crate::grid::floor3(t);
    let f = t - base;
    let b = [base.x as i32, base.y as i32, base.z as i32];
    let mut out = [([0; 3], 0.0); 8];
    for (corner, slot) in out.iter_mut().enumerate() {
        let (dx, dy, dz) = (corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
        let wx = if dx == 1 { f.x } else { 1.0 - f.x };
        let wy = if dy == 1 { f.y } else { 1.0 - f.y };
        let wz = if dz == 1 { f.z } else { 1.0 - f.z };
        *slot = (
            [b[0] + dx as i32, b[1] + dy as i32, b[2] + dz as i32],
            wx * wy * wz,
        );
    }
    out
}

/// The splatted sample counts at the kernel depth and at every coarser depth.
pub struct DensityField {
    pub depth: u32,
    /// `levels[d]`: the counts at depth d, for d in 0..=depth (shared: the out-of-core path's
    /// slabs each hold their own finer depths over one set of the coarse ones,
    /// [`DensityField::with_finer`]).
    levels: Vec<Arc<BrickCounts>>,
}

impl DensityField {
    /// Splats a unit weight per sample (times its confidence, when given) at `depth`, and
    /// restricts the counts to every coarser depth. (The pipeline takes the same counts from
    /// its [`NormalSums`], see [`NormalSums::kernel_counts`].)
    #[cfg(test)]
    pub fn splat(positions: &[DVec3], confidence: Option<&[f64]>, depth: u32) -> Self {
        let mut counts = KernelCounts::new(depth);
        counts.add(positions, confidence);
        counts.into_field()
    }

    /// The node slots of its bricks, all depths: what the memory budget counts for it.
    pub(crate) fn slots(&self) -> usize {
        self.levels.iter().map(|level| level.slots()).sum()
    }

    /// A field of depths 0..=`self.depth` + `finer.len()`: this one's depths (shared, not
    /// copied), then `finer[i]`'s nodes as the counts of depth `self.depth` + 1 + i. What it
    /// gives is the field of all the samples wherever `finer` holds every node the evaluation
    /// reads (the out-of-core path's slabs, `outofcore/field.rs`).
    pub(crate) fn with_finer(&self, finer: Vec<Vec<(u64, f64)>>) -> DensityField {
        let mut levels = self.levels.clone();
        for nodes in finer {
            let mut level = BrickCounts::default();
            level.insert(nodes);
            levels.push(Arc::new(level));
        }
        DensityField {
            depth: levels.len() as u32 - 1,
            levels,
        }
    }

    /// The node slots of the kernel depth's bricks alone (those of [`NormalSums`] over the same
    /// samples).
    pub(crate) fn kernel_slots(&self) -> usize {
        self.levels[self.depth as usize].slots()
    }

    /// W(q) = Σ_o count_o B_o(q) at the kernel depth.
    pub fn evaluate(&self, q: DVec3) -> f64 {
        self.evaluate_at(self.depth, q)
    }

    /// W_d(q) = Σ_o count_o B_o(q) over the depth-d counts, d ≤ the kernel depth.
    pub fn evaluate_at(&self, depth: u32, q: DVec3) -> f64 {
        self.levels[depth as usize].evaluate(depth, q)
    }
}

/// Values of one depth's nodes (counts, or sums of normals), by bricks of 4×4×4 nodes (the
/// nodes whose Morton keys agree but in their low six bits): per brick its 64 values and which
/// of its nodes were given one. The 27 nodes a density reads lie in at most 8 bricks (3.4 on
/// average) and the 8 a sample splats onto in at most 8 (about 2), so each costs a few
/// look-ups in a table of bricks, instead of one per node in a table of nodes too large for
/// the caches (where half of the density stage's time went). The values of a node are summed
/// in the same order either way.
struct Bricks<T> {
    /// Brick key (node key >> [`BRICK_SHIFT`]) → index in `bricks`.
    slot: KeyMap<u32>,
    bricks: Vec<Brick<T>>,
}

impl<T> Default for Bricks<T> {
    fn default() -> Self {
        Bricks {
            slot: KeyMap::default(),
            bricks: Vec::new(),
        }
    }
}

/// The sample counts of one depth.
type BrickCounts = Bricks<f64>;

/// Bits of a node's key that place it in its brick: two per axis.
const BRICK_SHIFT: u32 = 6;
/// Nodes along each axis of a brick.
pub(crate) const BRICK_SIDE: u32 = 1 << (BRICK_SHIFT / 3);

#[derive(Clone)]
struct Brick<T> {
    key: u64,
    /// Bit `l` set when node `l` (its key's low six bits) has a value.
    touched: u64,
    values: [T; 64],
}

impl<T: Copy> Brick<T> {
    /// Its nodes with a value, as (key, value), in key order.
    fn nodes(&self) -> impl Iterator<Item = (u64, T)> + '_ {
        let mut bits = self.touched;
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let local = bits.trailing_zeros();
                bits &= bits - 1;
                (
                    self.key << BRICK_SHIFT | local as u64,
                    self.values[local as usize],
                )
            })
        })
    }
}

/// Where the bricks of a block of nodes at most four wide on every axis (from `low` on) are,
/// each looked up once: at most two bricks per axis, eight in all.
struct BricksAround {
    /// The brick coordinates of `low`.
    first: [i32; 3],
    /// Per brick (x + 2y + 4z, 1 for the second brick of an axis): its index in the counts,
    /// [`BricksAround::UNKNOWN`] before it is looked up, `NONE` when it has no nodes.
    slots: [u32; 8],
}

impl BricksAround {
    const UNKNOWN: u32 = u32::MAX - 1;

    fn new(low: Coord) -> Self {
        BricksAround {
            first: low.map(|v| (v + OFFSET) >> 2),
            slots: [Self::UNKNOWN; 8],
        }
    }

    /// The index in `slots` of the brick of `node` (within the block).
    #[inline]
    fn which(&self, node: Coord) -> usize {
        let step = |a: usize| (((node[a] + OFFSET) >> 2) - self.first[a]) as usize;
        debug_assert!(
            (0..3).all(|a| step(a) <= 1),
            "the block is at most four wide"
        );
        step(0) | step(1) << 1 | step(2) << 2
    }
}

/// A node's place in its brick: its key's low six bits (the low two bits of each coordinate,
/// interleaved; [`OFFSET`] is a multiple of 4, so they are the coordinates' own), without
/// computing the whole key: only a brick not yet found needs that.
#[inline]
fn brick_local(node: Coord) -> usize {
    // Bits 0 and 1 of v to bits 0 and 3.
    let spread = |v: i32| ((v & 1) | (v & 2) << 2) as usize;
    spread(node[0]) | spread(node[1]) << 1 | spread(node[2]) << 2
}

impl<T: Copy + Default> Bricks<T> {
    /// The value of `node`, if it has one (its brick found through `around`).
    #[inline]
    fn get(&self, around: &mut BricksAround, node: Coord) -> Option<T> {
        let which = around.which(node);
        if around.slots[which] == BricksAround::UNKNOWN {
            around.slots[which] = self
                .slot
                .get(&(morton(node) >> BRICK_SHIFT))
                .copied()
                .unwrap_or(NONE);
        }
        let b = around.slots[which];
        if b == NONE {
            return None;
        }
        let brick = &self.bricks[b as usize];
        let local = brick_local(node);
        (brick.touched >> local & 1 == 1).then(|| brick.values[local])
    }

    /// The value of `node`, made 0 first if it had none (its brick found or made through
    /// `around`).
    #[inline]
    fn value_mut(&mut self, around: &mut BricksAround, node: Coord) -> &mut T {
        let which = around.which(node);
        if around.slots[which] == BricksAround::UNKNOWN {
            let key = morton(node) >> BRICK_SHIFT;
            let next = self.bricks.len() as u32;
            let b = *self.slot.entry(key).or_insert(next);
            if b == next {
                self.bricks.push(Brick {
                    key,
                    touched: 0,
                    values: [T::default(); 64],
                });
            }
            around.slots[which] = b;
        }
        let brick = &mut self.bricks[around.slots[which] as usize];
        let local = brick_local(node);
        brick.touched |= 1 << local;
        &mut brick.values[local]
    }

    /// Σ_o value_o B_o(q) over its nodes, which are of depth `depth`: the 27 whose functions
    /// reach q.
    fn evaluate(&self, depth: u32, q: DVec3) -> T
    where
        T: std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>,
    {
        let (c, w) = stencil27(q, (depth as f64).exp2());
        let low = [c[0] - 1, c[1] - 1, c[2] - 1];
        let mut bricks = BricksAround::new(low);
        let mut sum = T::default();
        for (k, wz) in w[2].iter().enumerate() {
            for (j, wy) in w[1].iter().enumerate() {
                for (i, wx) in w[0].iter().enumerate() {
                    let node = [low[0] + i as i32, low[1] + j as i32, low[2] + k as i32];
                    if let Some(n) = self.get(&mut bricks, node) {
                        sum = sum + n * *wx * *wy * *wz;
                    }
                }
            }
        }
        sum
    }

    /// Splats `value(s)` of every sample s at `positions` onto the eight nodes of `depth` nearest
    /// to it, with their trilinear weights times its confidence (1 when not given).
    fn splat(
        &mut self,
        depth: u32,
        positions: &[DVec3],
        confidence: Option<&[f64]>,
        value: impl Fn(usize) -> T,
    ) where
        T: std::ops::AddAssign + std::ops::Mul<f64, Output = T>,
    {
        let inv_h = (depth as f64).exp2();
        for (s, &p) in positions.iter().enumerate() {
            let c = confidence.map_or(1.0, |w| w[s]);
            let v = value(s);
            let nodes = trilinear(p, inv_h);
            let mut bricks = BricksAround::new(nodes[0].0);
            for (node, w) in nodes {
                *self.value_mut(&mut bricks, node) += v * (w * c);
            }
        }
    }

    /// Its nodes, which are of depth `depth`, whose centre's x `keep` accepts, with their
    /// values, sorted by key.
    fn sorted_nodes_where(&self, depth: u32, keep: impl Fn(f64) -> bool) -> Vec<(u64, T)> {
        let mut nodes = self.sorted_nodes();
        nodes.retain(|&(key, _)| keep(node_centre_x(key, depth)));
        nodes
    }

    /// Values made elsewhere, set (a node given twice keeps the second).
    fn insert(&mut self, nodes: impl IntoIterator<Item = (u64, T)>) {
        for (key, value) in nodes {
            let node = unmorton(key);
            *self.value_mut(&mut BricksAround::new(node), node) = value;
        }
    }

    /// Every node with a value, as (key, value): in key order within a brick, bricks in the
    /// order they were made.
    fn nodes(&self) -> impl Iterator<Item = (u64, T)> + '_ {
        self.bricks.iter().flat_map(Brick::nodes)
    }

    /// Its bricks in key order (so their nodes, each brick's in key order, are too).
    fn sorted_bricks(&self) -> Vec<&Brick<T>> {
        let mut order: Vec<&Brick<T>> = self.bricks.iter().collect();
        order.sort_unstable_by_key(|brick| brick.key);
        order
    }

    /// Every node with a value, as (key, value), in key order.
    fn sorted_nodes(&self) -> Vec<(u64, T)> {
        self.sorted_bricks()
            .into_iter()
            .flat_map(Brick::nodes)
            .collect()
    }

    /// The node slots its bricks hold (64 a brick, touched or not).
    fn slots(&self) -> usize {
        self.bricks.capacity() * 64
    }

    /// `f` of every value, in the same bricks and slots (and the same room for bricks).
    fn map<U: Copy>(&self, f: impl Fn(T) -> U) -> Bricks<U> {
        let mut bricks = Vec::with_capacity(self.bricks.capacity());
        bricks.extend(self.bricks.iter().map(|brick| Brick {
            key: brick.key,
            touched: brick.touched,
            values: brick.values.map(&f),
        }));
        Bricks {
            slot: self.slot.clone(),
            bricks,
        }
    }
}

/// The samples' counts at the kernel depth, gathered in any number of parts (the out-of-core
/// path reads its points in chunks): [`KernelCounts::add`] of each part, then
/// [`KernelCounts::into_field`], gives the field of all the points (the counts summed in
/// another order when the parts are not the points in order: equal to rounding).
pub(crate) struct KernelCounts {
    depth: u32,
    counts: BrickCounts,
}

impl KernelCounts {
    pub(crate) fn new(depth: u32) -> Self {
        KernelCounts {
            depth,
            counts: BrickCounts::default(),
        }
    }

    /// Splats a unit weight per sample (times its confidence, when given) at the kernel depth.
    #[cfg(test)]
    pub(crate) fn add(&mut self, positions: &[DVec3], confidence: Option<&[f64]>) {
        self.counts
            .splat(self.depth, positions, confidence, |_| 1.0);
    }

    /// The nodes touched so far, as sorted distinct keys.
    #[cfg(test)]
    pub(crate) fn into_sorted_keys(self) -> Vec<u64> {
        self.counts
            .sorted_nodes()
            .into_iter()
            .map(|(key, _)| key)
            .collect()
    }

    /// Counts of the same depth made elsewhere (each node's once: a node given twice keeps
    /// the second count).
    pub(crate) fn insert(&mut self, nodes: impl IntoIterator<Item = (u64, f64)>) {
        self.counts.insert(nodes);
    }

    /// The field: the counts, restricted to every coarser depth.
    pub(crate) fn into_field(self) -> DensityField {
        let depth = self.depth;
        let mut levels = vec![Arc::new(self.counts)];
        for _ in 0..depth {
            let coarser = restrict(levels.last().expect("the kernel depth's counts"));
            levels.push(Arc::new(coarser));
        }
        levels.reverse();
        DensityField { depth, levels }
    }

    /// The counts restricted depth by depth from the kernel's down to `coarsest`: `visit(d,
    /// nodes)` gets, for each depth d below the kernel's, from the finest, its nodes whose
    /// centre's x `keep` accepts, with their counts, sorted by key. (The depths of
    /// [`KernelCounts::into_field`] from `coarsest` up, without making the coarser ones or
    /// holding more than two depths at once.)
    pub(crate) fn restrict_down_to(
        self,
        coarsest: u32,
        keep: impl Fn(f64) -> bool,
        mut visit: impl FnMut(u32, Vec<(u64, f64)>),
    ) {
        let mut level = self.counts;
        for d in (coarsest..self.depth).rev() {
            level = restrict(&level);
            visit(d, level.sorted_nodes_where(d, &keep));
        }
    }
}

/// The x of the centre of the node of depth `depth` with key `key`, in the unit cube.
pub(crate) fn node_centre_x(key: u64, depth: u32) -> f64 {
    (f64::from(unmorton(key)[0]) + 0.5) * (-f64::from(depth)).exp2()
}

/// The nodes of the kernel depth the samples' splats touch, without their counts: what the
/// out-of-core path's planner measures the surface and the field by, gathered in any number of
/// parts (each part's nodes, [`KernelNodes::into_sorted_keys`], [`KernelNodes::insert`]ed in
/// any order). Its bricks are those of the field of the same samples, so it gives that field's
/// node slots at every depth ([`KernelNodes::slots_by_depth`]), at 16 bytes a brick of 64
/// slots instead of 528.
pub(crate) struct KernelNodes {
    depth: u32,
    nodes: Bricks<()>,
}

impl KernelNodes {
    pub(crate) fn new(depth: u32) -> Self {
        KernelNodes {
            depth,
            nodes: Bricks::default(),
        }
    }

    /// The nodes the splats of samples at `positions` touch (those [`KernelCounts::add`] would
    /// give a count).
    pub(crate) fn add(&mut self, positions: &[DVec3]) {
        let inv_h = (self.depth as f64).exp2();
        for &p in positions {
            let nodes = trilinear(p, inv_h);
            let mut bricks = BricksAround::new(nodes[0].0);
            for (node, _) in nodes {
                self.nodes.value_mut(&mut bricks, node);
            }
        }
    }

    /// Nodes found elsewhere (a node given twice is one node).
    pub(crate) fn insert(&mut self, keys: impl IntoIterator<Item = u64>) {
        self.nodes.insert(keys.into_iter().map(|key| (key, ())));
    }

    /// The nodes, as sorted distinct keys.
    pub(crate) fn into_sorted_keys(self) -> Vec<u64> {
        self.nodes
            .sorted_nodes()
            .into_iter()
            .map(|(key, _)| key)
            .collect()
    }

    /// The x index of every node (one entry a node, in no particular order): where the samples'
    /// surface lies across x, at the kernel depth's resolution.
    pub(crate) fn node_x(&self) -> impl Iterator<Item = i32> + '_ {
        self.nodes.nodes().map(|(key, _)| unmorton(key)[0])
    }

    /// The node slots of the bricks of each depth, 0 to the kernel depth, of the density field
    /// of the same samples (its counts inserted as these nodes were, then restricted).
    pub(crate) fn slots_by_depth(&self) -> Vec<usize> {
        let mut slots = vec![self.nodes.slots()];
        let mut level: Option<Bricks<()>> = None;
        for _ in 0..self.depth {
            let coarser = restrict_with(level.as_ref().unwrap_or(&self.nodes), |_, _, _| {});
            slots.push(coarser.slots());
            level = Some(coarser);
        }
        slots.reverse();
        slots
    }
}

/// The samples' counts and unit normals summed together at the kernel depth, with the weights
/// the counts are splatted with (trilinear, times the confidence): per node (count, N_x, N_y,
/// N_z), so that one evaluation gives W(q) (bit for bit the field's: the same additions in the
/// same order) and N(q) = Σ_o N_o B_o(q). |N(q)| ≤ W(q), equal where every sample near q faces
/// the same way, and 1 − |N|/W measures how far the normals under the kernel turn
/// ([`BENT_SPREAD`]). Needed only while the samples' depths are read ([`estimate`]), then
/// dropped: a transient of the density stage, checked against the memory budget once the
/// field's slots are known (`memory::Footprint::reading_density`). Gathered in parts like
/// [`KernelCounts`], for the out-of-core path.
pub(crate) struct NormalSums {
    depth: u32,
    sums: Bricks<DVec4>,
}

impl NormalSums {
    pub(crate) fn new(depth: u32) -> Self {
        NormalSums {
            depth,
            sums: Bricks::default(),
        }
    }

    /// The sums of `normals` (unit, one per position) splatted at `depth` from `positions`.
    pub(crate) fn splat(
        positions: &[DVec3],
        confidence: Option<&[f64]>,
        normals: &[[f32; 3]],
        depth: u32,
    ) -> Self {
        let mut sums = NormalSums::new(depth);
        sums.add(positions, confidence, normals);
        sums
    }

    /// Adds samples with their unit normals, one per position, counted as
    /// [`KernelCounts::add`] counts them.
    pub(crate) fn add(
        &mut self,
        positions: &[DVec3],
        confidence: Option<&[f64]>,
        normals: &[[f32; 3]],
    ) {
        self.sums.splat(self.depth, positions, confidence, |s| {
            let [x, y, z] = normals[s];
            DVec4::new(1.0, x as f64, y as f64, z as f64)
        });
    }

    /// The counts alone, as [`KernelCounts::add`] over the same samples makes them, bit for bit
    /// (each the same additions in the same order: the weights times 1): the in-memory
    /// pipeline splats its samples once for both.
    pub(crate) fn kernel_counts(&self) -> KernelCounts {
        KernelCounts {
            depth: self.depth,
            counts: self.sums.map(|sum| sum.x),
        }
    }

    /// The nodes whose centre's x `keep` accepts, with their (count, N), sorted by key.
    pub(crate) fn sorted_nodes_where(&self, keep: impl Fn(f64) -> bool) -> Vec<(u64, DVec4)> {
        self.sums.sorted_nodes_where(self.depth, keep)
    }

    /// Sums of the same depth made elsewhere (a node given twice keeps the second).
    pub(crate) fn insert(&mut self, nodes: impl IntoIterator<Item = (u64, DVec4)>) {
        self.sums.insert(nodes);
    }

    /// W(q) and 1 − |N(q)| / W(q) (0 where W(q) ≤ 0).
    pub(crate) fn density_and_spread(&self, q: DVec3) -> (f64, f64) {
        let sum = self.sums.evaluate(self.depth, q);
        let w = sum.x;
        let spread = if w > 0.0 {
            1.0 - DVec3::new(sum.y, sum.z, sum.w).length() / w
        } else {
            0.0
        };
        (w, spread)
    }
}

/// The counts of one depth coarser: each node's count, as a mass at its centre, splatted
/// trilinearly onto the coarser nodes. A centre lies a quarter of a coarse width from the
/// nearest coarse centre on each axis, so it gives ¾ to that node and ¼ to the next one away
/// (total mass kept). Nodes are visited in key order (bricks by key, nodes by key within
/// each), so the sums do not depend on the map's layout. The coarse nodes a fine brick's
/// nodes reach lie within four of each other on every axis, so each fine brick looks up its
/// coarse bricks once, not each node.
fn restrict(fine: &BrickCounts) -> BrickCounts {
    restrict_with(fine, |sum, count, [wx, wy, wz]| {
        *sum += count * wx * wy * wz
    })
}

/// [`restrict`] of any values: `add(coarse, fine, weights)` adds a fine node's value with its
/// weight on each axis to a coarse node's (for the nodes alone, without values, adds nothing:
/// the coarse nodes and bricks are those of the counts).
fn restrict_with<T: Copy + Default>(
    fine: &Bricks<T>,
    add: impl Fn(&mut T, T, [f64; 3]),
) -> Bricks<T> {
    let mut coarse = Bricks::<T>::default();
    coarse.bricks.reserve(fine.bricks.len() / 2);
    for brick in fine.sorted_bricks() {
        // Its node of local index 0; its nodes are 4b..4b + 3 per axis, so the coarse nodes
        // they reach are 2b − 1..2b + 2.
        let origin = unmorton(brick.key << BRICK_SHIFT);
        let mut bricks = BricksAround::new(origin.map(|o| o.div_euclid(2) - 1));
        let mut bits = brick.touched;
        while bits != 0 {
            let local = bits.trailing_zeros() as i32;
            bits &= bits - 1;
            let count = brick.values[local as usize];
            // The inverse of `brick_local`: bits a and a + 3 are axis a's low two bits.
            let node: Coord =
                std::array::from_fn(|a| origin[a] + (local >> a & 1) + (local >> (a + 3) & 1) * 2);
            let axis = node.map(|j| {
                let i = j.div_euclid(2);
                [(i, 0.75), (if j % 2 == 0 { i - 1 } else { i + 1 }, 0.25)]
            });
            for (x, wx) in axis[0] {
                for (y, wy) in axis[1] {
                    for (z, wz) in axis[2] {
                        add(
                            coarse.value_mut(&mut bricks, [x, y, z]),
                            count,
                            [wx, wy, wz],
                        );
                    }
                }
            }
        }
    }
    coarse
}

/// Per-sample results of the density stage (from W(s), the density at each sample, which is
/// kept only as its distribution).
pub struct SampleDensity {
    /// A_s, the surface area each sample stands for (unit-cube units).
    pub area: Vec<f64>,
    /// Depth(s), fractional, in [0, D].
    pub depth: Vec<f64>,
    /// The distribution of W(s) over the samples: entry k is the density below which k / 1000
    /// of the samples lie (see [`quantiles`]). Kept in the mesh's figures as the scale the
    /// densities at its vertices are compared with when trimming.
    pub quantiles: Vec<f32>,
}

/// How many steps [`quantiles`] divides the samples' density distribution into.
pub const QUANTILE_STEPS: usize = 1000;

/// The `QUANTILE_STEPS + 1` quantiles of `values` (entry k: the value of rank
/// ⌊k·(n − 1) / QUANTILE_STEPS⌋ in ascending order, so entry 0 is the minimum and the last
/// the maximum); empty when `values` is. Sorting gives the same order at any thread count.
pub fn quantiles(values: &[f64]) -> Vec<f32> {
    if values.is_empty() {
        return Vec::new();
    }
    let mut sorted = values.to_vec();
    sorted.par_sort_unstable_by(f64::total_cmp);
    let n = sorted.len();
    (0..=QUANTILE_STEPS)
        .map(|k| sorted[k * (n - 1) / QUANTILE_STEPS] as f32)
        .collect()
}

/// Where the samples' normals under the density's kernel turn by more than this, the kernel
/// spans a bend, and a sample's count is read as PoissonRecon reads it (finer; see
/// [`estimate`]). The measure is 1 − |N(s)| / W(s) ([`NormalSums`]): 0 where every sample near
/// s faces one way, 1 − sin θ / θ for normals spread evenly over an arc of ±θ, so 0.02 is a
/// bend of about ±20° under the kernel (its B-spline weights fall off within about a node of
/// the sample). Measured (docs/benchmarks.md, issue 16, 2026-12-05), with 0.01, 0.02, 0.05
/// and 0.1: 0.02 and 0.01 bring the sparse shared clouds closest to their held-out points at
/// depths 6–7 and the exact cube to its truth, 0.05 and 0.1 less; at 0.02 the exact spheres
/// and tori keep every figure at depths 8–12 and the noisy ones move by less than 0.1 % (their
/// normals turn less than that under the kernel), the bunny and the Buddha by as little; with
/// no threshold at all (every sample read finer) the noisy sphere and torus lose 2–6 % at
/// depth 8, so the bend, not the count, decides.
pub(crate) const BENT_SPREAD: f64 = 0.02;

/// Evaluates W at every sample and derives its area and depth.
///
/// Where the kernel depth sees at least `samples_per_node` samples around a sample, its depth
/// is D̂ + log₄(W/n) and its area (115/192)·h²/W as in the module documentation. Where it sees
/// fewer (sparse sampling, a stray sample, the edge of a scan), W at the kernel depth says
/// little: a sample's own splat alone gives W ≈ 0.2–0.4 at any depth, so every sample, however
/// isolated, would get a depth within about one level of D̂ and an area of a few kernel cells.
/// Instead the density is read at coarser and coarser depths until a node's neighbourhood
/// holds n samples, and the depth is placed between the last two depths by the counts actually
/// seen there (rather than assuming ×4 a depth, which holds only on a well-sampled surface):
/// d + ln(W_d/n) / ln(W_d/W_{d+1}), and the area is read at depth d. A sample whose
/// neighbourhood never holds n samples gets depth 0.
///
/// With the samples' `normals` summed at the kernel depth, a sample whose kernel spans a bend
/// (1 − |N|/W > [`BENT_SPREAD`]) has its count read against n·B₄(0) instead of n, as
/// PoissonRecon counts (its density is normalised so that a plane with n samples per node
/// reads n; psr's reads B₄(0)·n ≈ 0.6 n): its splat about a third of a depth finer, but no
/// finer than the next whole depth above the one n gives, so that a bend never opens a depth
/// the sampling's count does not reach (the tree, and the time, stay those of the count).
/// Where the surface bends under the kernel, the coarser splat's sag across the bend is the
/// larger error; where it is flat, the finer splat only follows the chance fluctuations of
/// the samples (the bumps of issue 16). Measured: the exact cube's distance to its truth and
/// its normals improve at depths 8–11; the kitten at depths 6–9 comes closer to its held-out
/// points than Open3D, and the oni on one draw of the held-out points at depths 6–9, within
/// 6 % of it on two others at depths 6–7 (it was 18–35 % behind); the bunny's and the
/// Buddha's trees are unchanged.
pub fn estimate(
    field: &DensityField,
    normals: Option<&NormalSums>,
    positions: &[DVec3],
    max_depth: u32,
    samples_per_node: f64,
    watch: &Watch,
) -> Result<SampleDensity> {
    let per_sample: Vec<(f64, f64, f64)> = map_in_blocks(
        positions,
        |&p| {
            // With the normals, W comes with N from one evaluation (the same bits as the
            // field's).
            let (w, spread) = match normals {
                Some(sums) => sums.density_and_spread(p),
                None => (field.evaluate(p), 0.0),
            };
            debug_assert_eq!(w.to_bits(), field.evaluate(p).to_bits());
            let (area, depth) = area_and_depth(field, p, w, max_depth, samples_per_node);
            if spread > BENT_SPREAD {
                let finer = samples_per_node * PLANE_KERNEL_PEAK;
                let (area, bent) = area_and_depth(field, p, w, max_depth, finer);
                (w, area, bent.min(depth.ceil()))
            } else {
                (w, area, depth)
            }
        },
        watch,
        0.5,
        0.95,
    )?;
    Ok(SampleDensity {
        area: per_sample.iter().map(|s| s.1).collect(),
        depth: per_sample.iter().map(|s| s.2).collect(),
        quantiles: quantiles(&per_sample.iter().map(|s| s.0).collect::<Vec<_>>()),
    })
}

/// The area and depth of a sample at `p` whose density at the kernel depth is `w`, for `n`
/// samples per node (see [`estimate`]).
fn area_and_depth(field: &DensityField, p: DVec3, w: f64, max_depth: u32, n: f64) -> (f64, f64) {
    let kernel_depth = field.depth;
    if w <= 0.0 {
        // A sample always lies within the support of its own splat, so W(s) > 0 unless its
        // confidence is 0: such samples get no area and the coarsest depth.
        return (0.0, 0.0);
    }
    if w >= n {
        let depth = kernel_depth as f64 + (w / n).log2() * 0.5;
        let area = PLANE_KERNEL_PEAK * (-2.0 * kernel_depth as f64).exp2() / w;
        return (area, depth.min(max_depth as f64));
    }
    let mut finer = w;
    let mut d = kernel_depth;
    while d > 0 {
        d -= 1;
        let coarser = field.evaluate_at(d, p);
        if coarser >= n {
            let area = PLANE_KERNEL_PEAK * (-2.0 * d as f64).exp2() / coarser;
            let step = if coarser > finer {
                ((coarser / n).ln() / (coarser / finer).ln()).min(1.0)
            } else {
                0.0
            };
            return (area, (d as f64 + step).min(max_depth as f64));
        }
        finer = coarser;
    }
    (PLANE_KERNEL_PEAK / finer, 0.0)
}

/// One sample's contribution at one depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DepthSample {
    /// The sample's index (the position and normal it refers to).
    pub(crate) sample: u32,
    /// Its mass at this depth: its area × its confidence × its share of this depth.
    pub(crate) mass: f64,
}

/// The samples splatted at each depth (§4.5): a sample of fractional depth δ goes to ⌊δ⌋ with
/// weight 1 − frac(δ) and to ⌊δ⌋ + 1 with frac(δ), times its area and confidence; δ is first
/// raised to `coarsest` (`Octree::coarsest_depth`: a depth with no node inside the cube cannot
/// take a splat). Consumes the depths (spent here; the areas stay for the isovalue).
///
/// Index d of the result holds depth d's samples, up to the finest depth that has any but not
/// above `full_depth`: when the density puts no sample at the deepest depths (sparse scans at a
/// high depth), those would hold no unknowns and only multiply the extraction grid, so the
/// tree, the screening scale and the extraction stop at the finest depth that has samples.
pub(crate) fn samples_by_depth(
    density: &mut SampleDensity,
    confidence: &[f64],
    max_depth: u32,
    full_depth: u32,
    coarsest: u32,
) -> Vec<Vec<DepthSample>> {
    let mut at_depth: Vec<Vec<DepthSample>> = vec![Vec::new(); max_depth as usize + 1];
    for (s, &depth) in density.depth.iter().enumerate() {
        let mass = density.area[s] * confidence[s];
        for (d, w) in depth_split(depth.max(coarsest as f64)) {
            if w > 0.0 {
                at_depth[d as usize].push(DepthSample {
                    sample: s as u32,
                    mass: w * mass,
                });
            }
        }
    }
    density.depth = Vec::new();
    let finest = (0..=max_depth as usize)
        .rev()
        .find(|&d| !at_depth[d].is_empty())
        .unwrap_or(0)
        .max(full_depth as usize);
    at_depth.truncate(finest + 1);
    at_depth
}

/// A fractional depth δ splats into ⌊δ⌋ with weight 1 − frac(δ) and ⌊δ⌋ + 1 with frac(δ).
fn depth_split(depth: f64) -> [(u32, f64); 2] {
    let base = depth.floor();
    let frac = depth - base;
    [(base as u32, 1.0 - frac), (base as u32 + 1, frac)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves the samples' density distribution is kept as 1001 quantiles, from the minimum to
    /// the maximum, each the value of its rank.
    #[test]
    fn quantiles_run_from_the_minimum_to_the_maximum_by_rank() {
        let values: Vec<f64> = (0..2001).rev().map(|i| i as f64 * 0.5).collect();
        let q = quantiles(&values);
        assert_eq!(q.len(), QUANTILE_STEPS + 1);
        assert_eq!((q[0], q[1], q[500], q[1000]), (0.0, 1.0, 500.0, 1000.0));
        assert!(q.windows(2).all(|w| w[0] <= w[1]));
        assert!(quantiles(&[]).is_empty());
        assert_eq!(quantiles(&[3.0]), vec![3.0f32; QUANTILE_STEPS + 1]);
    }

    /// Proves the nodes alone, found in parts and joined, are the nodes the counts touch, and
    /// give the node slots of the field of those counts at every depth.
    #[test]
    fn the_kernel_nodes_alone_give_the_fields_nodes_and_slots() {
        let positions: Vec<DVec3> = (0..20_000)
            .map(|i| {
                let t = i as f64 * 2.399_963;
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 20_000.0;
                let r = (1.0 - z * z).sqrt();
                DVec3::splat(0.5) + 0.3 * DVec3::new(r * t.cos(), r * t.sin(), z)
            })
            .collect();
        let depth = 6;
        let mut counts = KernelCounts::new(depth);
        counts.add(&positions, None);
        let keys = counts.into_sorted_keys();
        let mut joined = KernelNodes::new(depth);
        for part in positions.chunks(7_000) {
            let mut nodes = KernelNodes::new(depth);
            nodes.add(part);
            joined.insert(nodes.into_sorted_keys());
        }
        assert_eq!(joined.node_x().count(), keys.len());
        let mut inserted = KernelCounts::new(depth);
        inserted.insert(keys.iter().map(|&key| (key, 1.0)));
        let field = inserted.into_field();
        let slots = joined.slots_by_depth();
        assert_eq!(slots.len(), depth as usize + 1);
        assert_eq!(slots[depth as usize], field.kernel_slots());
        assert_eq!(slots.iter().sum::<usize>(), field.slots());
        assert_eq!(joined.into_sorted_keys(), keys);
    }

    /// A node's place in its brick is its key's low six bits, halo coordinates included.
    #[test]
    fn brick_local_is_the_keys_low_bits() {
        for x in -8..12 {
            for y in [-3, 0, 5, 6] {
                for z in [-1, 2, 7] {
                    assert_eq!(brick_local([x, y, z]) as u64, morton([x, y, z]) & 63);
                }
            }
        }
    }

    #[test]
    fn trilinear_weights_sum_to_one_and_reproduce_the_position() {
        let p = DVec3::new(0.3, 0.71, 0.055);
        let inv_h = 16.0;
        let nodes = trilinear(p, inv_h);
        let total: f64 = nodes.iter().map(|n| n.1).sum();
        assert!((total - 1.0).abs() < 1e-12);
        let mean = nodes.iter().fold(DVec3::ZERO, |acc, (c, w)| {
            acc + DVec3::new(c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5) / inv_h * *w
        });
        assert!((mean - p).length() < 1e-12);
    }

    #[test]
    fn uniform_plane_sampling_gives_its_density_and_area() {
        // A plane z = const sampled on a regular grid of spacing s has ρ = 1/s², so the area per
        // sample is s². The estimate depends on where the plane cuts the kernel-depth nodes
        // (0.5 of B₄(0)'s mean when midway between node centres, 0.75 on them), so average over
        // eight plane offsets, as a surface's many orientations and positions do.
        let s = 1.0 / 512.0;
        let depth = 5;
        let h = 1.0 / 32.0;
        let mut mean_area = 0.0;
        for k in 0..8 {
            let z = 0.5 + (k as f64 + 0.5) / 8.0 * h;
            let mut pts = Vec::new();
            for i in 0..512 {
                for j in 0..512 {
                    pts.push(DVec3::new((i as f64 + 0.37) * s, (j as f64 + 0.61) * s, z));
                }
            }
            let field = DensityField::splat(&pts, None, depth);
            let est = estimate(
                &field,
                None,
                &[DVec3::new(0.5, 0.5, z), DVec3::new(0.31, 0.62, z)],
                8,
                1.5,
                &Watch::new(),
            )
            .unwrap();
            assert!((est.area[0] - est.area[1]).abs() < 1e-3 * est.area[0]);
            mean_area += est.area[0] / 8.0;
            // (512/32)² = 256 samples per depth-5 node: log₄(W/1.5) ≈ 3.7 depths finer, so
            // the depth is clamped at D = 8.
            assert_eq!(est.depth[0], 8.0);
        }
        assert!(
            (mean_area / (s * s) - 1.0).abs() < 0.02,
            "mean area {mean_area} vs {}",
            s * s
        );
    }

    /// Proves that a sampling sparser than the kernel depth's nodes gets the depth and area its
    /// spacing implies, not those its own splat suggests: a plane sampled every 1/64 (16 kernel
    /// nodes of depth 8 per sample) has n = 1.5 samples per node of width h where
    /// (115/192)·(h·64)² = 1.5, h = 1/40.4, depth 5.34; the area per sample is (1/64)².
    /// Read at the kernel depth alone, W ≈ 0.3 (mostly the sample's own splat) would give depth
    /// 8 + log₄(0.3/1.5) ≈ 6.8 and an area of 2 kernel cells, an eighth of the true one.
    #[test]
    fn sparse_sampling_is_read_at_the_depth_where_a_node_holds_enough_samples() {
        let s = 1.0 / 64.0;
        let z = 0.5 + 0.3 / 256.0;
        let mut pts = Vec::new();
        for i in 8..56 {
            for j in 8..56 {
                pts.push(DVec3::new((i as f64 + 0.37) * s, (j as f64 + 0.61) * s, z));
            }
        }
        let field = DensityField::splat(&pts, None, 8);
        let centre = pts.len() / 2 + 24;
        let est = estimate(
            &field,
            None,
            &pts[centre..centre + 1],
            10,
            1.5,
            &Watch::new(),
        )
        .unwrap();
        let expected_depth = (64.0 * (115.0f64 / 192.0 / 1.5).sqrt()).log2();
        assert!(
            (est.depth[0] - expected_depth).abs() < 0.35,
            "depth {} vs {expected_depth}",
            est.depth[0]
        );
        assert!(
            (est.area[0] / (s * s) - 1.0).abs() < 0.25,
            "area {} vs {}",
            est.area[0],
            s * s
        );
    }

    /// Proves that a stray sample, alone in its neighbourhood, is splatted coarse (a node must
    /// reach the nearby surface's samples to hold n of them) instead of within a level of the
    /// kernel depth as its own splat alone would suggest (W ≈ 0.3: depth ≈ 6.8 at kernel
    /// depth 8).
    #[test]
    fn a_stray_sample_is_splatted_coarse() {
        let mut pts = Vec::new();
        for i in 0..256 {
            for j in 0..256 {
                pts.push(DVec3::new(
                    (i as f64 + 0.5) / 256.0,
                    (j as f64 + 0.5) / 256.0,
                    0.3,
                ));
            }
        }
        let stray = DVec3::new(0.5, 0.5, 0.3 + 24.0 / 256.0);
        pts.push(stray);
        let field = DensityField::splat(&pts, None, 8);
        let est = estimate(&field, None, &[stray, pts[100]], 10, 1.5, &Watch::new()).unwrap();
        assert!(est.depth[0] <= 5.0, "stray sample's depth {}", est.depth[0]);
        // The plane's spacing is a kernel node's width: n = 1.5 samples per node at depth
        // 8 − log₂(√(1.5·192/115)) = 7.34.
        assert!(
            est.depth[1] >= 7.0,
            "surface sample's depth {}",
            est.depth[1]
        );
    }

    /// Proves that §4.5's adaptive depth is used: with a sampling density varying 10× from the
    /// south pole (sparse) to the north pole (dense) of a sphere, the sparsest tenth of the
    /// samples (lowest z) gets a median depth at least one level coarser than the densest tenth.
    ///
    /// Why one level: Depth(s) = D̂ + log₄(W(s)/n), so a density contrast c gives log₄ c levels.
    /// The two tenths' median samples sit near z ≈ −0.72 and z ≈ 0.96, whose densities differ by
    /// 10^((0.96 + 0.72)/2) ≈ 6.9×, i.e. 1.39 levels. Neither is clamped at D = 8: 1.44 samples
    /// per depth-8 node area at z = 0.96, times the kernel's plane integral 115/192, over
    /// n = 1.5, predicts depth 7.60 there, and 6.20 at z = −0.72. Measured: 7.583 (dense) vs
    /// 6.312 (sparse), 1.27 levels. With a single depth for all samples the difference would
    /// be 0. (tests/reconstruction.rs checks the reconstruction of the same sphere.)
    /// Points `spacing` apart on the two faces of a box's convex edge along y at x = z = 0.5:
    /// the top (z = 0.5, x from 0.2 to 0.5, normal +z) and the side (x = 0.5, z from 0.2 to
    /// 0.5, normal +x), y from 0.2 to 0.8.
    fn box_edge(spacing: f64) -> (Vec<DVec3>, Vec<[f32; 3]>) {
        let steps = (0.3 / spacing).round() as usize;
        let (mut positions, mut normals) = (Vec::new(), Vec::new());
        for j in 0..=2 * steps {
            let y = 0.2 + j as f64 * spacing;
            for i in 0..steps {
                let t = 0.2 + i as f64 * spacing;
                positions.push(DVec3::new(t, y, 0.5));
                normals.push([0.0, 0.0, 1.0]);
                positions.push(DVec3::new(0.5, y, t));
                normals.push([1.0, 0.0, 0.0]);
            }
        }
        (positions, normals)
    }

    #[test]
    fn counts_taken_from_the_normal_sums_are_the_splatted_counts() {
        let (positions, normals) = box_edge(0.004);
        let kernel_depth = 6;
        let splatted = DensityField::splat(&positions, None, kernel_depth);
        let taken = NormalSums::splat(&positions, None, &normals, kernel_depth)
            .kernel_counts()
            .into_field();
        assert_eq!(taken.slots(), splatted.slots());
        assert_eq!(taken.kernel_slots(), splatted.kernel_slots());
        for depth in 0..=kernel_depth {
            for p in positions.iter().step_by(7) {
                let (a, b) = (
                    taken.evaluate_at(depth, *p),
                    splatted.evaluate_at(depth, *p),
                );
                assert_eq!(a.to_bits(), b.to_bits(), "depth {depth}, {p}");
            }
        }
    }

    #[test]
    fn the_normals_spread_is_zero_on_a_flat_face_and_large_across_an_edge() {
        let (positions, normals) = box_edge(0.004);
        let kernel_depth = 6;
        let field = DensityField::splat(&positions, None, kernel_depth);
        let sums = NormalSums::splat(&positions, None, &normals, kernel_depth);
        let spread = |p: DVec3| {
            let (w, spread) = sums.density_and_spread(p);
            assert_eq!(w.to_bits(), field.evaluate(p).to_bits(), "{p}");
            spread
        };
        // Far from the edge every sample faces one way: N is W along the normal, exactly.
        assert_eq!(spread(DVec3::new(0.3, 0.5, 0.5)), 0.0);
        assert_eq!(spread(DVec3::new(0.5, 0.5, 0.3)), 0.0);
        // At the edge the two faces' normals, at right angles, weigh about the same:
        // |N| / W ≈ cos 45°.
        let at_edge = spread(DVec3::new(0.5, 0.5, 0.5));
        assert!((at_edge - (1.0 - 0.5f64.sqrt())).abs() < 0.02, "{at_edge}");
        assert!(at_edge > BENT_SPREAD);
        // A sphere of radius 0.3 (a curve the kernel resolves) stays below the bend.
        let mut sphere = Vec::new();
        let mut sphere_normals = Vec::new();
        let n = 200;
        for i in 0..n {
            let z = -1.0 + (2 * i + 1) as f64 / n as f64;
            for j in 0..2 * n {
                let phi = std::f64::consts::PI * j as f64 / n as f64 + i as f64;
                let r = (1.0 - z * z).sqrt();
                let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                sphere.push(DVec3::splat(0.5) + 0.3 * d);
                sphere_normals.push([d.x as f32, d.y as f32, d.z as f32]);
            }
        }
        let sums = NormalSums::splat(&sphere, None, &sphere_normals, kernel_depth);
        let worst = sphere
            .iter()
            .map(|&p| sums.density_and_spread(p).1)
            .fold(0.0, f64::max);
        assert!(worst < 0.02, "{worst}");
    }

    #[test]
    fn samples_at_a_bend_read_a_finer_depth_but_not_past_the_next_whole_depth() {
        let (positions, normals) = box_edge(0.004);
        let (depth, kernel_depth, samples_per_node) = (9, 6, 1.5);
        let field = DensityField::splat(&positions, None, kernel_depth);
        let sums = NormalSums::splat(&positions, None, &normals, kernel_depth);
        let watch = Watch::new();
        let counted = estimate(&field, None, &positions, depth, samples_per_node, &watch).unwrap();
        let bent = estimate(
            &field,
            Some(&sums),
            &positions,
            depth,
            samples_per_node,
            &watch,
        )
        .unwrap();
        let mut finer = 0;
        for (s, p) in positions.iter().enumerate() {
            let (was, is) = (counted.depth[s], bent.depth[s]);
            let from_edge = (0.5 - p.x).max(0.5 - p.z);
            if from_edge > 0.05 {
                // Out of the kernel's reach of the edge: the count alone decides.
                assert_eq!(is.to_bits(), was.to_bits(), "{p}");
                assert_eq!(bent.area[s].to_bits(), counted.area[s].to_bits());
            }
            assert!(is >= was && is <= was.ceil(), "{p}: {was} → {is}");
            if is > was {
                finer += 1;
                assert!(from_edge < 0.03, "{p} read finer {from_edge} from the edge");
            }
        }
        // The samples within about a kernel cell of the edge (a tenth of them) read finer.
        assert!(
            finer * 20 > positions.len(),
            "{finer} of {}",
            positions.len()
        );
    }

    #[test]
    fn nonuniform_sampling_gets_coarser_depths_where_sparse() {
        // 100k points on the unit sphere, accepted with probability 10^((z + 1)/2) / 10, mapped
        // into the unit cube as the pipeline maps them (bounding cube × 1.1).
        let mut state = 3u64;
        let mut next = move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let ratio: f64 = 10.0;
        let mut on_sphere = Vec::new();
        while on_sphere.len() < 100_000 {
            let z = 2.0 * next() - 1.0;
            let phi = std::f64::consts::TAU * next();
            let s = (1.0 - z * z).sqrt();
            if next() * ratio < ratio.powf((z + 1.0) / 2.0) {
                on_sphere.push(DVec3::new(s * phi.cos(), s * phi.sin(), z));
            }
        }
        let unit: Vec<DVec3> = on_sphere
            .iter()
            .map(|p| *p / 2.2 + DVec3::splat(0.5))
            .collect();
        let (depth, kernel_depth, samples_per_node) = (8, 6, 1.5);
        let field = DensityField::splat(&unit, None, kernel_depth);
        let estimate =
            estimate(&field, None, &unit, depth, samples_per_node, &Watch::new()).unwrap();
        assert!(estimate.depth.iter().all(|d| (0.0..=8.0).contains(d)));
        let mut by_z: Vec<(f64, f64)> = on_sphere
            .iter()
            .zip(&estimate.depth)
            .map(|(p, &d)| (p.z, d))
            .collect();
        by_z.sort_by(|a, b| a.0.total_cmp(&b.0));
        let tenth = by_z.len() / 10;
        let median = |slice: &[(f64, f64)]| {
            let mut d: Vec<f64> = slice.iter().map(|s| s.1).collect();
            d.sort_by(f64::total_cmp);
            d[d.len() / 2]
        };
        let sparse = median(&by_z[..tenth]);
        let dense = median(&by_z[by_z.len() - tenth..]);
        eprintln!("median sample depth: sparsest tenth {sparse:.3}, densest tenth {dense:.3}");
        assert!(
            dense - sparse >= 1.0,
            "sparse samples must be splatted markedly coarser: {sparse} vs {dense}"
        );
    }
}

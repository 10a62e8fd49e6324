//! Stage 3 — the octree (§4.1), stored linearly one depth at a time.
//!
//! At each depth d the tree keeps two nested node sets:
//!
//! * the **core** C_d: the nodes that carry unknowns. It holds every node whose function covers
//!   a cell holding a sample splatted at depth d (§4.2; the 27 nodes around the cell at degree
//!   2, its eight corners at degree 1: [`Degree::nodes_over_a_cell`]), the parent of every core
//!   node of depth d + 1 (so the tree is a proper octree), all of that widened by one node (see
//!   [`Octree::build`]), and every node when d ≤ full depth;
//! * the **halo** K_d ⊇ C_d: every node within two nodes (Chebyshev distance) of the core. The
//!   node functions of C_d overlap exactly the nodes of K_d, so every stencil, the prolongation of
//!   the coarser solution and the evaluation of χ near the core read only nodes of K_d.
//!
//! Nodes of one depth are sorted by Morton key; a [`BrickIndex`] finds a node from its key, and
//! finds its neighbours and parent from its position in its 8×8×8 brick and the bricks around
//! (kept per brick, not per node: a node costs its key and flags only), so hot loops count bits
//! in occupancy masks instead of hashing keys. Node indices can lie just outside [0, 2^d): a
//! node function near the cube's face reaches beyond it, and with free boundaries (the
//! paper's) that is where its neighbours live.

use crate::bspline::Degree;
use crate::density::DepthSample;
use crate::error::Result;
use crate::grid::{cell_of, compact, morton, spread, unmorton, Coord, KeyMap, BITS, OFFSET};
use crate::parallel::{split_parts, stop_requested, DistinctIndices, Watch};
use crate::Boundary;
use glam::DVec3;
use rayon::prelude::*;

/// Marks a missing neighbour or parent.
pub const NONE: u32 = u32::MAX;

/// Flag bits per node.
pub const CORE: u8 = 1;
/// Within one node of the core: the node functions of the core cover (part of) this cell.
pub const NEAR: u8 = 2;
/// A node with at least one core child: in the leaf partition the isosurface is extracted on,
/// its eight children replace it. Usually a core node; with degree 1 and Dirichlet boundaries
/// also a face node (outside the core) above core nodes next to the face. Every split node's
/// parent is split too, so the leaves tile the cube.
pub const SPLIT: u8 = 4;

/// The nodes of one depth.
#[derive(Debug, Default)]
pub struct Level {
    pub depth: u32,
    /// Morton keys of K_d, sorted.
    pub keys: Vec<u64>,
    /// `CORE` / `NEAR` / `SPLIT` bits per node.
    pub flags: Vec<u8>,
    /// Indices of the core nodes, ascending (so distinct: the per-node loops write at them in
    /// parallel).
    pub core: DistinctIndices,
    /// With Neumann or Dirichlet boundaries: every halo node outside the cube, the node it
    /// mirrors (its reflection across the cube's faces, inside the cube) and a bit per reflected
    /// axis.
    pub mirrors: Vec<Mirror>,
    /// Degree 1 with Neumann or Dirichlet boundaries: the halo nodes on the cube's faces
    /// (`inside` = `outside`, `flips` the axes whose face they lie on), which are their own
    /// mirror images: an even extension keeps their value (and scales their rows, see
    /// [`Level::face_scale`]), an odd one makes it 0. Empty otherwise.
    pub faces: Vec<Mirror>,
    /// The sign a value takes across one face: +1 (Neumann, and free, which has no mirrors),
    /// −1 (Dirichlet). See [`Level::mirror_sign`].
    pub face_sign: f64,
    /// The degree of the node functions (which also decides where a node's function is
    /// centred, see [`crate::bspline`]): every stage reads it from here.
    pub degree: Degree,
    index: BrickIndex,
}

impl Level {
    /// The factor from an inside node's value to its mirror node's, for a mirror reflected
    /// across the faces of the axes set in `flips`: [`Level::face_sign`] once per face (+1 for
    /// Neumann; for Dirichlet −1 across one or three faces, +1 across two, the odd extension).
    #[inline]
    pub fn mirror_sign(&self, flips: u8) -> f64 {
        if flips.count_ones() % 2 == 1 {
            self.face_sign
        } else {
            1.0
        }
    }

    /// Reflects a node coordinate into the cube across its faces ([`reflect`] for degree 2,
    /// [`reflect_corner`] for degree 1), `None` if it is inside.
    #[inline]
    pub fn reflect(&self, c: Coord) -> Option<(Coord, u8)> {
        let n = 1i32 << self.depth;
        match self.degree {
            Degree::Two => reflect(c, n),
            Degree::One => reflect_corner(c, n),
        }
    }

    /// Whether a node at `c` takes its value from the mirrors' rule rather than from its own
    /// coefficient: beyond the cube, or (degree 1) on one of its faces.
    #[inline]
    pub fn follows_mirror_rule(&self, c: Coord) -> bool {
        let n = 1i32 << self.depth;
        match self.degree {
            Degree::Two => c.iter().any(|&v| v < 0 || v >= n),
            Degree::One => c.iter().any(|&v| v <= 0 || v >= n),
        }
    }

    /// The factor by which a face node's row of the Laplacian and of the right-hand side is
    /// scaled (degree 1 with mirrors): ½ per face the node lies on. The free-space stencils
    /// integrate its function over both sides of the face, twice the cube's part (the even
    /// extension is symmetric); the screening sums only over the cube, and so must the rest
    /// of the row, for the system to be the Galerkin system of the folded basis on the cube
    /// (and symmetric).
    #[inline]
    pub fn face_scale(flips: u8) -> f64 {
        0.5f64.powi(flips.count_ones() as i32)
    }

    /// The brick index of K_d (for brick-by-brick traversals).
    pub fn bricks(&self) -> &BrickIndex {
        &self.index
    }

    /// The slot in [`Level::bricks`] of the brick holding coordinate `c`, if it has nodes.
    pub fn brick_containing(&self, c: Coord) -> Option<usize> {
        self.index.slot_of(morton(c) >> BrickIndex::BRICK_BITS)
    }

    /// Number of nodes in K_d.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Index of the node with this coordinate, if it is in K_d.
    #[inline]
    pub fn find(&self, c: Coord) -> Option<u32> {
        self.index.get(morton(c))
    }

    /// The node with this coordinate and where it lies, if it is in K_d.
    #[inline]
    pub fn find_place(&self, c: Coord) -> Option<(u32, NodePlace)> {
        let key = morton(c);
        let slot = self.index.slot_of(key >> BrickIndex::BRICK_BITS)?;
        let position = (key & 511) as usize;
        let i = self.index.in_brick(slot, position)?;
        let local = brick_local(position).map(|v| v as i32);
        Some((i, NodePlace { slot, local }))
    }

    /// For nodes given in ascending order (repeats allowed), where each brick's run starts:
    /// the nodes of brick slot b are positions `starts[b]..starts[b + 1]` of the sequence.
    pub fn brick_starts(&self, nodes: impl IntoIterator<Item = u32>) -> Vec<u32> {
        let mut starts = vec![0u32; self.index.brick_count() + 1];
        let mut cursor = BrickCursor::default();
        let mut previous = None;
        for node in nodes {
            debug_assert!(previous <= Some(node), "brick_starts needs nodes in order");
            previous = Some(node);
            starts[self.locate(&mut cursor, node).slot + 1] += 1;
        }
        for b in 0..self.index.brick_count() {
            starts[b + 1] += starts[b];
        }
        starts
    }

    /// The parent of node `i` (the node of `coarse`, the level above, containing it) and
    /// where it lies, if it is in K_{d−1}.
    #[inline]
    pub fn parent_in(&self, coarse: &Level, i: u32) -> Option<(u32, NodePlace)> {
        coarse.find_place(self.coord(i).map(|v| v.div_euclid(2)))
    }

    /// The coordinate of node `i`.
    #[inline]
    pub fn coord(&self, i: u32) -> Coord {
        unmorton(self.keys[i as usize])
    }

    /// Node width h = 2^−d.
    pub fn width(&self) -> f64 {
        (-(self.depth as f64)).exp2()
    }

    /// The face neighbour of node `i` in direction `dir` (−x, +x, −y, +y, −z, +z), `NONE` when
    /// outside K_d (the node-by-node reference the brick walks are tested against).
    #[cfg(test)]
    pub fn neighbor(&self, i: u32, dir: usize) -> u32 {
        let mut offset = [0; 3];
        offset[dir / 2] = if dir.is_multiple_of(2) { -1 } else { 1 };
        let at = self.locate(&mut BrickCursor::default(), i);
        self.node_near(at, offset)
    }

    /// Where node `i` lies: its brick's slot (found from `cursor`, which remembers the last
    /// brick so that a walk over ascending nodes searches once per brick) and its coordinates
    /// within the brick.
    #[inline]
    pub fn locate(&self, cursor: &mut BrickCursor, i: u32) -> NodePlace {
        let position = (self.keys[i as usize] & 511) as usize;
        NodePlace {
            slot: self.index.slot_of_node_from(cursor, i),
            local: brick_local(position).map(|v| v as i32),
        }
    }

    /// The node a move from the node at `at` lands on, `NONE` if outside K_d.
    #[inline(always)]
    pub fn node_after(&self, at: NodePlace, step: AxisStep) -> u32 {
        self.index.node_at(at.slot, step)
    }

    /// The node `offset` (each component in −8..=8) away from the node at `at`, `NONE` if
    /// outside K_d.
    #[cfg(test)]
    pub fn node_near(&self, at: NodePlace, offset: [i32; 3]) -> u32 {
        let steps: [AxisStep; 3] =
            std::array::from_fn(|axis| AxisStep::new(at.local[axis], offset[axis], axis));
        self.index
            .node_at(at.slot, steps[0].join(steps[1]).join(steps[2]))
    }

    /// The 3×3×3 block of nodes around node `i` (x fastest); entries outside K_d are `NONE`.
    #[inline]
    pub fn block27(&self, i: u32) -> [u32; 27] {
        let at = self.locate(&mut BrickCursor::default(), i);
        self.block27_at(i, at)
    }

    /// [`Level::block27`] of node `i` at `at`. Reached as by stepping from neighbour to
    /// neighbour along z, then y, then x: a node whose row (or plane) centre is missing from
    /// K_d is `NONE` too.
    #[inline]
    pub fn block27_at(&self, i: u32, at: NodePlace) -> [u32; 27] {
        self.block_from::<0>(i, at)
    }

    /// [`Level::block27_at`]'s entries at offsets 0 and +1 on every axis (slots 13, 14, 16, 17,
    /// 22, 23, 25, 26, the same nodes), `NONE` elsewhere: the nodes on the corners of node `i`'s
    /// cell, all that a degree-1 function needs there (see [`crate::bspline::Degree::stencil27`]),
    /// for 8 of the 27 look-ups.
    #[inline]
    pub fn corner_block_at(&self, i: u32, at: NodePlace) -> [u32; 27] {
        self.block_from::<1>(i, at)
    }

    /// The block of node `i`: its entries whose offsets are at least `FIRST − 1` on every axis.
    #[inline(always)]
    fn block_from<const FIRST: usize>(&self, i: u32, at: NodePlace) -> [u32; 27] {
        let steps: [[AxisStep; 3]; 3] = std::array::from_fn(|axis| {
            std::array::from_fn(|d| AxisStep::new(at.local[axis], d as i32 - 1, axis))
        });
        let node = |x: usize, y: usize, z: usize| {
            self.index
                .node_at(at.slot, steps[0][x].join(steps[1][y]).join(steps[2][z]))
        };
        let mut out = [NONE; 27];
        for z in FIRST..3 {
            let zn = if z == 1 { i } else { node(1, 1, z) };
            if zn == NONE {
                continue;
            }
            for y in FIRST..3 {
                let yn = if y == 1 { zn } else { node(1, y, z) };
                if yn == NONE {
                    continue;
                }
                let row = z * 9 + y * 3;
                if FIRST == 0 {
                    out[row] = node(0, y, z);
                }
                out[row + 1] = yn;
                out[row + 2] = node(2, y, z);
            }
        }
        out
    }
}

/// A move from a node along some axes, as the brick it lands in (its offset in the 27-brick
/// table from the node's own brick, 0 for the same brick) and the key bits of its position
/// there. Moves along different axes combine with [`AxisStep::join`].
#[derive(Debug, Clone, Copy)]
pub struct AxisStep {
    brick: i32,
    bits: usize,
}

impl AxisStep {
    /// `delta` (−8..=8) along `axis` from brick-local coordinate `local`.
    #[inline(always)]
    pub fn new(local: i32, delta: i32, axis: usize) -> AxisStep {
        let v = local + delta;
        let stride = 3i32.pow(axis as u32);
        let (brick, v) = if v < 0 {
            (-stride, v + 8)
        } else if v >= 8 {
            (stride, v - 8)
        } else {
            (0, v)
        };
        AxisStep {
            brick,
            bits: spread3(v as usize) << axis,
        }
    }

    #[inline(always)]
    pub fn join(self, other: AxisStep) -> AxisStep {
        AxisStep {
            brick: self.brick + other.brick,
            bits: self.bits | other.bits,
        }
    }
}

/// A node's brick slot and its position (key bits and coordinates 0..8) within the brick.
#[derive(Debug, Clone, Copy)]
pub struct NodePlace {
    pub slot: usize,
    pub local: [i32; 3],
}

/// The brick of the last node located: the range of node indices it holds and its slot.
#[derive(Debug, Clone, Copy, Default)]
pub struct BrickCursor {
    start: u32,
    end: u32,
    slot: usize,
}

/// A halo node outside the cube that stands for the reflection of an inside node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mirror {
    pub outside: u32,
    pub inside: u32,
    /// Bit a set: reflected across a face normal to axis a.
    pub flips: u8,
}

/// Reflects a node index into [0, n) across the faces of the cube (node centres at i + ½, so
/// index −1 − i mirrors i and 2n − 1 − i mirrors i from the far face); `None` if inside.
#[inline]
pub fn reflect(c: Coord, n: i32) -> Option<(Coord, u8)> {
    let mut out = c;
    let mut flips = 0u8;
    for a in 0..3 {
        if c[a] < 0 {
            out[a] = -1 - c[a];
            flips |= 1 << a;
        } else if c[a] >= n {
            out[a] = 2 * n - 1 - c[a];
            flips |= 1 << a;
        }
    }
    (flips != 0).then_some((out, flips))
}

/// [`reflect`] for degree-1 nodes, which sit on cell corners: the faces are at nodes 0 and n, so
/// node −i mirrors node i and n + i mirrors n − i; nodes on a face are their own images (inside).
#[inline]
pub fn reflect_corner(c: Coord, n: i32) -> Option<(Coord, u8)> {
    let mut out = c;
    let mut flips = 0u8;
    for a in 0..3 {
        if c[a] < 0 {
            out[a] = -c[a];
            flips |= 1 << a;
        } else if c[a] > n {
            out[a] = 2 * n - c[a];
            flips |= 1 << a;
        }
    }
    (flips != 0).then_some((out, flips))
}

/// Neumann and Dirichlet boundaries: sets every mirror node outside the cube to the value of
/// the inside node it reflects times [`Level::mirror_sign`], so free-space stencils act as the
/// folded basis, even (Neumann) or odd (Dirichlet); no-op with free boundaries.
///
/// Node centres sit at i + ½ and faces at 0 and 2^d, so node −1 − i is node i's reflection:
/// B_i − B_{−1−i} is odd about the face and χ built from odd-folded functions is 0 on it.
/// Scalars on the nodes, whether coefficients or tested quantities ⟨∇B_o, V⟩, all extend so.
pub fn fill_mirrors(level: &Level, x: &mut [f64]) {
    for m in &level.mirrors {
        x[m.outside as usize] = level.mirror_sign(m.flips) * x[m.inside as usize];
    }
    for f in &level.faces {
        if level.mirror_sign(f.flips) < 0.0 {
            x[f.outside as usize] = 0.0;
        }
    }
}

/// [`fill_mirrors`] for a vector field, which extends as the gradient of such a χ does: a
/// component normal to a reflecting face changes sign relative to the scalar's sign (with
/// Neumann the normal components flip; with Dirichlet the tangential ones).
pub fn fill_mirrors_field(level: &Level, v: &mut [Vec<f64>; 3]) {
    for m in &level.mirrors {
        let scalar = level.mirror_sign(m.flips);
        for (axis, comp) in v.iter_mut().enumerate() {
            let sign = if m.flips & (1 << axis) != 0 {
                -scalar
            } else {
                scalar
            };
            comp[m.outside as usize] = sign * comp[m.inside as usize];
        }
    }
    // A degree-1 node on a face is its own image: a component the reflection would negate is 0.
    for f in &level.faces {
        let scalar = level.mirror_sign(f.flips);
        for (axis, comp) in v.iter_mut().enumerate() {
            let sign = if f.flips & (1 << axis) != 0 {
                -scalar
            } else {
                scalar
            };
            if sign < 0.0 {
                comp[f.outside as usize] = 0.0;
            }
        }
    }
}

/// The whole tree: one [`Level`] per depth 0..=max depth.
#[derive(Debug, Default)]
pub struct Octree {
    pub levels: Vec<Level>,
}

impl Octree {
    /// Builds the tree from the cells that hold samples splatted at each depth
    /// (`sample_cells[d]`, any order, duplicates allowed).
    ///
    /// The core of depth d is every node whose function covers such a cell (the cell's 3×3×3
    /// block at degree 2, its 2×2×2 corners at degree 1) plus the parent of every core node of
    /// depth d + 1, widened by one node on every side; down to `full_depth` it is the complete
    /// grid. Then the halo is added.
    ///
    /// At degree 1 the node below the cell on each axis (c − 1, whose hat is zero over the cell)
    /// is not counted as covering it: counted, it gave the samples a second layer of unknowns on
    /// their low side only, a fifth of the finest depth's unknowns on the bunny and the Happy
    /// Buddha scans, and the held-out samples were no closer for it (`docs/benchmarks.md`,
    /// 2026-12-07).
    ///
    /// The widening: a depth's unknowns correct what the coarser depths could not resolve, and
    /// that correction decays over a few node widths away from the samples; a core that ends
    /// right at the splatted nodes cuts it off and leaves a ripple on the surface (PoissonRecon's
    /// graded octree gives the same room). Measured on a 40k-point sphere at depth 7: mesh to
    /// sphere mean distance −27% (unscreened −60%); bunny scans at depth 8: reference → mesh mean
    /// 4.70e-5 → 4.45e-5 m; for about 1.7× the unknowns.
    ///
    /// With Neumann or Dirichlet boundaries the core stays inside the cube (a splat beyond a
    /// face lands on the mirrored node inside), and every halo node outside it is linked to the
    /// inside node it mirrors; with free boundaries the core may reach one node beyond the
    /// cube, where functions still overlap it.
    /// (The pipeline builds through [`Octree::around_samples`]; tests call this directly.)
    #[cfg(test)]
    pub fn build(sample_cells: Vec<Vec<Coord>>, full_depth: u32, boundary: Boundary) -> Octree {
        Self::build_for(sample_cells, full_depth, boundary, Degree::Two)
    }

    /// [`Octree::build`] for node functions of `degree`.
    #[cfg(test)]
    pub fn build_for(
        sample_cells: Vec<Vec<Coord>>,
        full_depth: u32,
        boundary: Boundary,
        degree: Degree,
    ) -> Octree {
        let unwatched = Watch::new();
        let unlimited = |_: &[u64]| Ok(());
        match Octree::build_watched(
            sample_cells,
            full_depth,
            boundary,
            degree,
            &unwatched,
            &unlimited,
        ) {
            Ok(tree) => tree,
            Err(e) => unreachable!("a watch nobody cancels stopped the build: {e}"),
        }
    }

    /// [`Octree::build_for`], reporting its progress to `watch` and stopping (with
    /// `Error::Cancelled`) between depths when it is cancelled. Degree 1's nodes sit on cell
    /// corners, so with mirrors the nodes inside the cube are 0..=n per axis (n = 2^d): with
    /// Neumann the core reaches the far face's nodes n, with Dirichlet it leaves out both faces'
    /// nodes (χ is 0 there), and every face node is listed in [`Level::faces`].
    ///
    /// `budget` is called with every depth's core node count (0 for the depths not yet built)
    /// after each depth's core set is built, finest first, and so before the halos (most of
    /// the tree's memory); it may refuse with [`crate::Error::OutOfMemory`].
    fn build_watched(
        sample_cells: Vec<Vec<Coord>>,
        full_depth: u32,
        boundary: Boundary,
        degree: Degree,
        watch: &Watch,
        budget: &(dyn Fn(&[u64]) -> Result<()> + Sync),
    ) -> Result<Octree> {
        let cores = Self::core_sets(sample_cells, full_depth, boundary, degree, watch, budget)?;
        Self::from_cores(cores, boundary, degree, watch)
    }

    /// The core set of every depth (sorted packed keys) from the cells holding samples splatted
    /// at each depth: the first half of [`Octree::build_watched`], reporting up to half of the
    /// progress.
    ///
    /// Every step (the 3×3×3 blocks, the parents, the widening, the clip to the core's range)
    /// maps a union of inputs to the union of their images, and the complete depths are the
    /// same for any input, so the core sets of the union of two sets of cells are the unions of
    /// their core sets, depth by depth: the out-of-core path builds the whole cloud's coarse
    /// depths from its slabs' (see `crate::outofcore`).
    pub(crate) fn core_sets(
        sample_cells: Vec<Vec<Coord>>,
        full_depth: u32,
        boundary: Boundary,
        degree: Degree,
        watch: &Watch,
        budget: &(dyn Fn(&[u64]) -> Result<()> + Sync),
    ) -> Result<Vec<Vec<u64>>> {
        let mirror_sign = boundary.mirror_sign();
        let max_depth = sample_cells.len() as u32 - 1;
        // Core sets as sorted packed keys, finest first so parents can be added on the way up.
        let mut cores: Vec<Vec<u64>> = vec![Vec::new(); sample_cells.len()];
        for d in (0..=max_depth).rev() {
            let n = 1i32 << d;
            let (lo, hi) = core_range(d, boundary, degree);
            let clip = |keys: Vec<u64>| -> Vec<u64> {
                keys.into_iter()
                    .filter(|&k| unpack(k).iter().all(|v| (lo..=hi).contains(v)))
                    .collect()
            };
            let mut cells: Vec<u64> = sample_cells[d as usize]
                .par_iter()
                .map(|&c| pack(c))
                .collect();
            cells.par_sort_unstable();
            cells.dedup();
            // Cancel points between the finest depths' sorts and dilations, each a fraction of
            // a second on a million samples.
            watch.check()?;
            let over_cells = shifted_by(&cells, degree.nodes_over_a_cell());
            let mut keys = clip(match (mirror_sign, degree) {
                (Some(_), Degree::One) => with_corner_images(over_cells, n),
                _ => over_cells,
            });
            watch.check()?;
            if d < max_depth {
                keys = merge_unique(&keys, &parents_of(&cores[d as usize + 1]));
            }
            if d <= full_depth {
                let mut grid =
                    crate::memory::with_capacity((n as usize).pow(3), "a complete octree depth")?;
                // Every node inside the cube: the cells (degree 2) or the corners in the core's
                // range (degree 1 with mirrors).
                let range = match (mirror_sign, degree) {
                    (Some(_), Degree::One) => lo..hi + 1,
                    _ => 0..n,
                };
                for z in range.clone() {
                    for y in range.clone() {
                        for x in range.clone() {
                            grid.push(pack([x, y, z]));
                        }
                    }
                }
                keys = merge_unique(&keys, &grid);
                if degree == Degree::One {
                    // A parent of a degree-1 core node can be a face node (⌊1/2⌋ = 0), which
                    // Dirichlet leaves out of the core.
                    keys = clip(keys);
                }
            } else {
                keys = clip(dilate(&keys, 1));
            }
            cores[d as usize] = keys;
            // The budget sees each depth's core as soon as it exists (the finest, usually the
            // largest, first), the depths not yet built counted as empty.
            budget(&cores.iter().map(|c| c.len() as u64).collect::<Vec<_>>())?;
            // The finest depths are most of the work: count them as such.
            let done = (max_depth - d + 1) as usize;
            watch.step(done, max_depth as usize + 1, 0.0, 0.5)?;
        }
        Ok(cores)
    }

    /// The tree from its core sets ([`Octree::core_sets`]): each depth's halo, mirrors and
    /// brick index, then the split flags; the second half of the progress.
    pub(crate) fn from_cores(
        cores: Vec<Vec<u64>>,
        boundary: Boundary,
        degree: Degree,
        watch: &Watch,
    ) -> Result<Octree> {
        let mirror_sign = boundary.mirror_sign();
        // The levels are independent: built side by side (the widening of one level's bricks
        // is serial).
        let mut levels: Vec<Level> = cores
            .into_par_iter()
            .enumerate()
            .map(|(d, core)| {
                // (A cancelled build skips the levels not yet started, and stops those under
                // way between their steps: see `stop_requested`.)
                if watch.is_cancelled() {
                    return Ok(None);
                }
                Level::with_halo(d as u32, &core, mirror_sign, degree)
            })
            .collect::<Result<Vec<Option<Level>>>>()?
            .into_iter()
            .collect::<Option<Vec<Level>>>()
            .ok_or(crate::Error::Cancelled)?;
        for d in 1..levels.len() {
            watch.step(d, levels.len(), 0.8, 1.0)?;
            let (coarse, fine) = levels.split_at_mut(d);
            let (coarse, fine) = (&mut coarse[d - 1], &fine[0]);
            // The core of depth d − 1 holds the parents of the core of depth d, but for degree
            // 1 with Dirichlet boundaries: a core node next to a face (index 1) has a face node
            // (index 0) for its parent, which that boundary keeps out of the core. It is in the
            // halo and split all the same; its own parent is split too, since the core node
            // beside it (index 1, the parents' core widened by one) is one of that parent's
            // children.
            let core_keys: Vec<u64> = fine
                .core
                .par_iter()
                .map(|&i| fine.keys[i as usize])
                .collect();
            let mut parents = vec![NONE; core_keys.len()];
            coarse_parents(coarse, &core_keys, &mut parents);
            // (Every parent is there but a degree-1 Dirichlet face node's at depth 0, which
            // has no nodes then: the extraction splits the root whenever there is a depth 1.)
            for p in parents.into_iter().filter(|&p| p != NONE) {
                coarse.flags[p as usize] |= SPLIT;
            }
        }
        Ok(Octree { levels })
    }

    /// The coarsest depth whose core can hold a node: 1 for degree 1 with Dirichlet boundaries
    /// (depth 0's nodes are the cube's corners, all on its faces, where χ is 0), else 0. No
    /// sample may be splatted coarser (see `density::samples_by_depth`): its cell would have
    /// no node to find.
    pub(crate) fn coarsest_depth(boundary: Boundary, degree: Degree) -> u32 {
        (0..)
            .find(|&d| {
                let (lo, hi) = core_range(d, boundary, degree);
                lo <= hi
            })
            .expect("depth 1 has an interior node whatever the basis")
    }

    /// The tree around the samples splatted at each depth (`at_depth[d]`, see
    /// [`crate::density::samples_by_depth`]), at `positions` in the unit cube; cancelled
    /// through `watch` (see [`Octree::build`]).
    pub(crate) fn around_samples(
        at_depth: &[Vec<DepthSample>],
        positions: &[DVec3],
        full_depth: u32,
        boundary: Boundary,
        degree: Degree,
        watch: &Watch,
        budget: &(dyn Fn(&[u64]) -> Result<()> + Sync),
    ) -> Result<Octree> {
        Octree::build_watched(
            sample_cells(at_depth, positions),
            full_depth,
            boundary,
            degree,
            watch,
            budget,
        )
    }

    pub fn max_depth(&self) -> u32 {
        self.levels.len() as u32 - 1
    }
}

/// The cell of each sample splatted at each depth (`at_depth[d]`, at `positions` in the unit
/// cube), what [`Octree::core_sets`] builds the cores from.
pub(crate) fn sample_cells(at_depth: &[Vec<DepthSample>], positions: &[DVec3]) -> Vec<Vec<Coord>> {
    at_depth
        .iter()
        .enumerate()
        .map(|(d, at)| {
            let inv_h = (d as f64).exp2();
            at.iter()
                .map(|s| cell_of(positions[s.sample as usize], inv_h))
                .collect()
        })
        .collect()
}

/// Degree-1 nodes (sorted packed keys) with mirrors: each node beyond the cube replaced by the
/// inside node it mirrors ([`reflect_corner`]), which carries its function's weight. A sample
/// on the cube's far face lies in cell n, whose corners are n and n + 1: with Dirichlet n is
/// no unknown (χ is 0 there) and n + 1 is n − 1's image, so the sample's cell stays in reach
/// of the core only through the image. At degree 2 the 3×3×3 block over a cell already holds
/// the images of its nodes beyond the cube.
fn with_corner_images(keys: Vec<u64>, n: i32) -> Vec<u64> {
    let image = |k: u64| reflect_corner(unpack(k), n).map(|(c, _)| pack(c));
    let mut images: Vec<u64> = keys.par_iter().filter_map(|&k| image(k)).collect();
    if images.is_empty() {
        return keys;
    }
    images.sort_unstable();
    images.dedup();
    let inside: Vec<u64> = keys.into_iter().filter(|&k| image(k).is_none()).collect();
    merge_unique(&inside, &images)
}

/// The node coordinates (per axis, inclusive) a core at depth `d` may hold: one node beyond the
/// cube on each side with free boundaries (their functions still overlap it); with mirrors,
/// the cells inside the cube (degree 2) or the corners in it (degree 1), less the faces' under
/// Dirichlet (χ is 0 there) and including them under Neumann.
fn core_range(d: u32, boundary: Boundary, degree: Degree) -> (i32, i32) {
    let n = 1i32 << d;
    match (boundary.mirror_sign(), degree) {
        (None, _) => (-1, n),
        (Some(_), Degree::Two) => (0, n - 1),
        (Some(sign), Degree::One) if sign > 0.0 => (0, n),
        (Some(_), Degree::One) => (1, n - 1),
    }
}

/// `out[i]` = the index in `coarse` of the parent of the node with key `keys[i]` (`NONE` if
/// absent), in parallel chunks, hashing a coarse brick only when the parents' brick changes.
fn coarse_parents(coarse: &Level, keys: &[u64], out: &mut [u32]) {
    const NODES_PER_TASK: usize = 4096;
    let index = &coarse.index;
    out.par_chunks_mut(NODES_PER_TASK)
        .zip(keys.par_chunks(NODES_PER_TASK))
        .for_each(|(out, keys)| {
            let mut cached: Option<(u64, Option<usize>)> = None;
            for (o, &k) in out.iter_mut().zip(keys) {
                let pk = parent_key(k);
                let brick = pk >> BrickIndex::BRICK_BITS;
                let slot = match cached {
                    Some((b, slot)) if b == brick => slot,
                    _ => {
                        let slot = index.slot_of(brick);
                        cached = Some((brick, slot));
                        slot
                    }
                };
                *o = slot
                    .and_then(|b| index.in_brick(b, (pk & 511) as usize))
                    .unwrap_or(NONE);
            }
        });
}

/// The number of nodes a brick's 512-bit occupancy holds.
fn ones(mask: &[u64; 8]) -> usize {
    mask.iter().map(|w| w.count_ones() as usize).sum()
}

/// Key of the parent of the node with key `k`.
#[inline]
pub fn parent_key(k: u64) -> u64 {
    let c = unmorton(k);
    morton([c[0].div_euclid(2), c[1].div_euclid(2), c[2].div_euclid(2)])
}

impl Level {
    /// The level whose core is `core` (packed keys, sorted, unique): K_d is the core widened by two
    /// nodes, NEAR the core widened by one. The widening runs on bit rows of 8×8×8 bricks
    /// ([`BrickRows`]), and the bricks sorted by key list the nodes in Morton order (a brick's
    /// positions are its keys' low nine bits): no per-node sort and no per-node look-up.
    fn with_halo(
        depth: u32,
        core: &[u64],
        mirror_sign: Option<f64>,
        degree: Degree,
    ) -> Result<Option<Level>> {
        // Ok(None) as soon as the watched job that builds the level is cancelled: between the
        // steps below, and in the listing (each brick skips its work once it is).
        let core_rows = BrickRows::from_packed(core);
        if stop_requested() {
            return Ok(None);
        }
        let near_rows = core_rows.widened();
        if stop_requested() {
            return Ok(None);
        }
        let halo_rows = near_rows.widened();
        if stop_requested() {
            return Ok(None);
        }
        let mut bricks: Vec<(u64, u64)> = halo_rows
            .rows
            .keys()
            .map(|&b| (BrickRows::morton_of(b), b))
            .collect();
        bricks.par_sort_unstable();
        if stop_requested() {
            return Ok(None);
        }
        // Per brick, in key order: the occupancy of K_d, NEAR and the core (Morton positions).
        let masks: Vec<[[u64; 8]; 3]> = bricks
            .par_iter()
            .map(|&(_, b)| {
                [&halo_rows, &near_rows, &core_rows]
                    .map(|set| set.rows.get(&b).map_or([0; 8], BrickRows::morton_masks))
            })
            .collect();
        drop((core_rows, near_rows, halo_rows));

        // Per brick: where its nodes and its core nodes start (prefix sums of the masks' bit
        // counts), so that bricks list their nodes side by side in parallel, each into its own
        // part of the arrays, in the same order as one after another.
        let counts: Vec<(usize, usize)> = masks
            .par_iter()
            .map(|[halo, _, in_core]| (ones(halo), ones(in_core)))
            .collect();
        let (mut total, mut total_core) = (0usize, 0usize);
        let starts: Vec<(usize, usize)> = counts
            .iter()
            .map(|&(nodes, core)| {
                let at = (total, total_core);
                (total, total_core) = (total + nodes, total_core + core);
                at
            })
            .collect();
        if total > NONE as usize {
            return Err(crate::Error::TooLarge {
                what: "octree nodes at one depth",
                count: total,
                limit: NONE as usize,
            });
        }
        // The level's largest arrays (a node each): a refusal is an out-of-memory error.
        let mut keys: Vec<u64> = crate::memory::zeroed(total, "an octree level's node keys")?;
        let mut flags: Vec<u8> = crate::memory::zeroed(total, "an octree level's node flags")?;
        let mut core: Vec<u32> = crate::memory::zeroed(total_core, "an octree level's core")?;
        let node_ranges: Vec<std::ops::Range<usize>> = starts
            .iter()
            .zip(&counts)
            .map(|(s, c)| s.0..s.0 + c.0)
            .collect();
        let node_parts = split_parts(&mut keys, node_ranges.iter().cloned());
        let flag_parts = split_parts(&mut flags, node_ranges);
        let core_parts = split_parts(
            &mut core,
            starts.iter().zip(&counts).map(|(s, c)| s.1..s.1 + c.1),
        );
        let n = 1i32 << depth;
        // Per brick, its mirrors (outside node, inside key, flips) and degree-1 face nodes.
        type BrickMirrors = (Vec<(u32, u64, u8)>, Vec<Mirror>);
        let listed: Vec<BrickMirrors> = node_parts
            .into_par_iter()
            .zip(flag_parts)
            .zip(core_parts)
            .zip(bricks.par_iter().zip(&masks).zip(&starts))
            .map(
                |(((keys, flags), core), ((&(brick, _), [halo, near, in_core]), &(first, _)))| {
                    if stop_requested() {
                        return (Vec::new(), Vec::new());
                    }
                    let (mut at, mut at_core) = (0, 0);
                    for word in 0..8 {
                        let mut bits = halo[word];
                        while bits != 0 {
                            let bit = bits.trailing_zeros();
                            bits &= bits - 1;
                            keys[at] =
                                brick << BrickIndex::BRICK_BITS | (word as u64 * 64 + bit as u64);
                            let mut flag = 0;
                            if near[word] >> bit & 1 == 1 {
                                flag |= NEAR;
                            }
                            if in_core[word] >> bit & 1 == 1 {
                                flag |= CORE;
                                core[at_core] = (first + at) as u32;
                                at_core += 1;
                            }
                            flags[at] = flag;
                            at += 1;
                        }
                    }
                    let (mut mirrors, mut faces) = (Vec::new(), Vec::new());
                    if mirror_sign.is_some() {
                        // A brick's nodes outside the cube mirror nodes inside; in the same
                        // halo, since the reflection of a halo node is within two nodes of the
                        // same core nodes.
                        for (j, &key) in keys.iter().enumerate() {
                            let i = (first + j) as u32;
                            let c = unmorton(key);
                            let reflected = match degree {
                                Degree::Two => reflect(c, n),
                                Degree::One => reflect_corner(c, n),
                            };
                            if let Some((inside, flips)) = reflected {
                                mirrors.push((i, morton(inside), flips));
                            } else if degree == Degree::One {
                                let on = (0..3)
                                    .fold(0u8, |f, a| f | ((c[a] == 0 || c[a] == n) as u8) << a);
                                if on != 0 {
                                    faces.push(Mirror {
                                        outside: i,
                                        inside: i,
                                        flips: on,
                                    });
                                }
                            }
                        }
                    }
                    (mirrors, faces)
                },
            )
            .collect();
        if stop_requested() {
            return Ok(None);
        }
        let mut mirrors = Vec::new();
        let mut faces = Vec::new();
        for (m, f) in listed {
            mirrors.extend(m);
            faces.extend(f);
        }
        let index = BrickIndex::from_bricks(
            bricks.iter().map(|&(b, _)| b).collect(),
            masks.iter().map(|m| m[0]).collect(),
        );
        let mirrors = mirrors
            .into_iter()
            .filter_map(|(outside, inside, flips)| {
                Some(Mirror {
                    outside,
                    inside: index.get(inside)?,
                    flips,
                })
            })
            .collect();
        Ok(Some(Level {
            depth,
            keys,
            flags,
            core: DistinctIndices::new(core),
            mirrors,
            faces,
            face_sign: mirror_sign.unwrap_or(1.0),
            degree,
            index,
        }))
    }
}

/// A set of nodes of one depth as bit rows of 8×8×8 bricks: per brick (keyed by its packed
/// coordinates, the nodes' offset coordinates divided by 8), row y + 8z holds bit x. Widening
/// the set by one node is then two shifts and ORs per row and axis, with the bits that cross a
/// brick face carried into the brick beside.
struct BrickRows {
    rows: KeyMap<[u8; 64]>,
}

impl BrickRows {
    /// The set of the nodes with these packed keys.
    fn from_packed(keys: &[u64]) -> BrickRows {
        let mut rows: KeyMap<[u8; 64]> = KeyMap::default();
        for &k in keys {
            let c = [0, 1, 2].map(|a| (k >> (a as u32 * BITS)) & ((1 << BITS) - 1));
            let brick = c[0] >> 3 | (c[1] >> 3) << BITS | (c[2] >> 3) << (2 * BITS);
            rows.entry(brick).or_insert([0; 64])[(c[1] & 7 | (c[2] & 7) << 3) as usize] |=
                1 << (c[0] & 7);
        }
        BrickRows { rows }
    }

    /// The Morton key of a brick (the Morton keys of its nodes without their low nine bits).
    fn morton_of(brick: u64) -> u64 {
        let mask = (1 << BITS) - 1;
        spread(brick & mask) | spread(brick >> BITS & mask) << 1 | spread(brick >> (2 * BITS)) << 2
    }

    /// The brick's occupancy by Morton position (x, y, z bits interleaved from bit 0), row by
    /// row: a position's bits 6–8 (the coordinates' high bits) pick its word, and a row's four
    /// nodes with the same high x bit land in one word at bits 0, 1, 8 and 9 (x's low bits are
    /// position bits 0 and 3) shifted by the row's y and z low bits (position bits 1, 4 and 2,
    /// 5). Position by position this took 7.7 % of the density and octree stages' time on the
    /// Happy Buddha at depth 10 (degree 1, one thread).
    fn morton_masks(rows: &[u8; 64]) -> [u64; 8] {
        let mut mask = [0u64; 8];
        for (row, &bits) in rows.iter().enumerate() {
            if bits == 0 {
                continue;
            }
            let (y, z) = (row & 7, row >> 3);
            let word = (y >> 2) << 1 | (z >> 2) << 2;
            let shift = (y & 1) << 1 | (z & 1) << 2 | (y >> 1 & 1) << 4 | (z >> 1 & 1) << 5;
            for (high_x, nibble) in [(0, bits & 15), (1, bits >> 4)] {
                let nibble = u64::from(nibble);
                mask[word | high_x] |= ((nibble & 3) | (nibble >> 2) << 8) << shift;
            }
        }
        mask
    }

    /// The nodes within Chebyshev distance one of the set.
    fn widened(&self) -> BrickRows {
        self.widened_along(0).widened_along(1).widened_along(2)
    }

    /// The set widened by one node along `axis`.
    fn widened_along(&self, axis: usize) -> BrickRows {
        let or_into = |rows: &mut [u8; 64], more: &[u8; 64]| {
            for (r, m) in rows.iter_mut().zip(more) {
                *r |= m;
            }
        };
        let mut out = self.rows.clone();
        let step = 1u64 << (axis as u32 * BITS);
        for (&brick, rows) in &self.rows {
            // The rows moved one node towards +axis and −axis within the brick, and the bits
            // that leave it on each side, as rows of the brick beside.
            let mut moved = [0u8; 64];
            let (mut carry_up, mut carry_down) = ([0u8; 64], [0u8; 64]);
            for r in 0..64 {
                let (y, z) = (r & 7, r >> 3);
                match axis {
                    0 => {
                        moved[r] |= rows[r] << 1 | rows[r] >> 1;
                        carry_up[r] = rows[r] >> 7;
                        carry_down[r] = rows[r] << 7;
                    }
                    1 => {
                        if y < 7 {
                            moved[r + 1] |= rows[r];
                        } else {
                            carry_up[r - 7] = rows[r];
                        }
                        if y > 0 {
                            moved[r - 1] |= rows[r];
                        } else {
                            carry_down[r + 7] = rows[r];
                        }
                    }
                    _ => {
                        if z < 7 {
                            moved[r + 8] |= rows[r];
                        } else {
                            carry_up[y] = rows[r];
                        }
                        if z > 0 {
                            moved[r - 8] |= rows[r];
                        } else {
                            carry_down[y + 56] = rows[r];
                        }
                    }
                }
            }
            or_into(out.get_mut(&brick).expect("a copy of the input"), &moved);
            if carry_up.iter().any(|&r| r != 0) {
                or_into(out.entry(brick + step).or_insert([0; 64]), &carry_up);
            }
            if carry_down.iter().any(|&r| r != 0) {
                // Halo coordinates stay above −OFFSET (a brick of offset coordinate 0).
                assert!(
                    (brick / step) & ((1 << BITS) - 1) > 0,
                    "node coordinate below -OFFSET"
                );
                or_into(out.entry(brick - step).or_insert([0; 64]), &carry_down);
            }
        }
        BrickRows { rows: out }
    }
}

/// Finds a node's index from its Morton key without a per-node hash table.
///
/// The eight-bit-aligned blocks of Morton keys are 8×8×8 "bricks", and since the nodes of a
/// depth are sorted by key, each brick's nodes are contiguous. The index keeps, per brick that
/// has nodes, the index of its first node and a 512-bit occupancy mask; a node's index is that
/// first index plus the number of occupied positions before it. The brick table is small
/// (about a hundredth of the nodes near a surface), so lookups stay in cache, and building it
/// is one pass over the sorted keys.
#[derive(Debug, Default)]
pub struct BrickIndex {
    slot: KeyMap<u32>,
    /// Per brick, in key order: its key (the node keys' bits above the brick's own nine), the
    /// index of its first node and its occupancy.
    bricks: Vec<u64>,
    first: Vec<u32>,
    occupied: Vec<[u64; 8]>,
    /// Per brick, the index of the first node of each 64-position word of its occupancy (so a
    /// node's index is one count of bits below it in its word away).
    word_first: Vec<[u32; 8]>,
    /// Per brick, the slots of the 27 bricks around it (index (dx+1) + 3(dy+1) + 9(dz+1), the
    /// brick itself in the middle), `NONE` where no node lies: a neighbour across a brick face
    /// costs a table read, not a hash.
    around: Vec<[u32; 27]>,
}

impl BrickIndex {
    const BRICK_BITS: u32 = 9;

    /// `keys` sorted ascending, unique.
    #[cfg(test)]
    fn new(keys: &[u64]) -> BrickIndex {
        let (mut bricks, mut occupied): (Vec<u64>, Vec<[u64; 8]>) = (Vec::new(), Vec::new());
        for &k in keys {
            let brick = k >> Self::BRICK_BITS;
            if bricks.last() != Some(&brick) {
                bricks.push(brick);
                occupied.push([0; 8]);
            }
            let position = (k & 511) as usize;
            occupied.last_mut().expect("pushed above")[position >> 6] |= 1 << (position & 63);
        }
        Self::from_bricks(bricks, occupied)
    }

    /// The index of the nodes in these bricks (keys ascending, each with its occupancy by
    /// position), numbered in that order.
    fn from_bricks(bricks: Vec<u64>, occupied: Vec<[u64; 8]>) -> BrickIndex {
        let mut index = BrickIndex::default();
        let mut next = 0u32;
        for (b, (&brick, occupancy)) in bricks.iter().zip(&occupied).enumerate() {
            index.slot.insert(brick, b as u32);
            index.first.push(next);
            next += occupancy.iter().map(|w| w.count_ones()).sum::<u32>();
        }
        index.bricks = bricks;
        index.occupied = occupied;
        index.word_first = index
            .first
            .iter()
            .zip(&index.occupied)
            .map(|(&first, occupied)| {
                let mut next = first;
                occupied.map(|word| {
                    let start = next;
                    next += word.count_ones();
                    start
                })
            })
            .collect();
        index.around = (0..index.bricks.len())
            .into_par_iter()
            .map(|b| {
                std::array::from_fn(|slot| {
                    let offset = [slot % 3, slot / 3 % 3, slot / 9].map(|o| o as i64 - 1);
                    index.brick_beside(b, offset).map_or(NONE, |s| s as u32)
                })
            })
            .collect();
        index
    }

    /// The index of the node with Morton key `k`, if present.
    #[inline]
    pub fn get(&self, k: u64) -> Option<u32> {
        let b = self.slot_of(k >> Self::BRICK_BITS)?;
        self.in_brick(b, (k & 511) as usize)
    }

    /// The slot of the brick with key `brick`, if it has nodes.
    #[inline]
    fn slot_of(&self, brick: u64) -> Option<usize> {
        self.slot.get(&brick).map(|&b| b as usize)
    }

    /// The index of the node at `position` (its key's low nine bits) in brick slot `b`.
    #[inline]
    fn in_brick(&self, b: usize, position: usize) -> Option<u32> {
        let (word, bit) = (position >> 6, position & 63);
        let mask = self.occupied[b][word];
        if mask >> bit & 1 == 0 {
            return None;
        }
        Some(self.word_first[b][word] + (mask & ((1u64 << bit) - 1)).count_ones())
    }

    /// The slot of the brick holding node `i`, searching only when `i` is outside the cursor's
    /// brick.
    #[inline]
    fn slot_of_node_from(&self, cursor: &mut BrickCursor, i: u32) -> usize {
        if !(cursor.start..cursor.end).contains(&i) {
            let slot = self.first.partition_point(|&f| f <= i) - 1;
            *cursor = BrickCursor {
                start: self.first[slot],
                end: self.first.get(slot + 1).copied().unwrap_or(u32::MAX),
                slot,
            };
        }
        cursor.slot
    }

    /// The node at brick-local coordinates `local` of brick slot `b`, `NONE` if absent.
    #[inline]
    pub fn node_in(&self, b: usize, local: [usize; 3]) -> u32 {
        self.in_brick(b, brick_position(local)).unwrap_or(NONE)
    }

    /// The node a move from a node of brick slot `b` lands on, `NONE` if absent.
    #[inline(always)]
    fn node_at(&self, b: usize, step: AxisStep) -> u32 {
        let slot = self.around[b][(13 + step.brick) as usize];
        if slot == NONE {
            return NONE;
        }
        self.in_brick(slot as usize, step.bits).unwrap_or(NONE)
    }

    /// The coordinates of the node at local (0, 0, 0) of brick slot `b`.
    pub fn origin(&self, b: usize) -> Coord {
        unmorton(self.bricks[b] << Self::BRICK_BITS)
    }

    /// Number of bricks that hold nodes.
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// The index of brick `b`'s first node and its 512-bit occupancy (bit p: the node whose key
    /// ends in the nine bits p, x y z interleaved from bit 0).
    #[inline]
    pub fn brick(&self, b: usize) -> (u32, &[u64; 8]) {
        (self.first[b], &self.occupied[b])
    }

    /// The indices of brick `b`'s nodes, consecutive in the level.
    #[inline]
    pub fn nodes(&self, b: usize) -> std::ops::Range<usize> {
        let count: u32 = self.occupied[b].iter().map(|w| w.count_ones()).sum();
        self.first[b] as usize..(self.first[b] + count) as usize
    }

    /// Each brick's part (its nodes') of each of `outputs` (vectors with one element per node
    /// of the level), in brick order: for tasks that each own a brick's nodes.
    pub fn parts<'a, T, const C: usize>(&self, outputs: [&'a mut [T]; C]) -> Vec<[&'a mut [T]; C]> {
        let mut parts = outputs.map(|output| {
            crate::parallel::split_parts(output, (0..self.brick_count()).map(|b| self.nodes(b)))
                .into_iter()
        });
        (0..self.brick_count())
            .map(|_| std::array::from_fn(|c| parts[c].next().expect("one part per brick")))
            .collect()
    }

    /// The slots of the 27 bricks around brick `b` (index (dx+1) + 3(dy+1) + 9(dz+1); brick b
    /// itself in the middle), `None` where no node lies.
    pub fn bricks_around27(&self, b: usize) -> [Option<usize>; 27] {
        self.around[b].map(|s| (s != NONE).then_some(s as usize))
    }

    /// The slot of the brick `offset` bricks away from brick slot `b`, if it has nodes.
    fn brick_beside(&self, b: usize, offset: [i64; 3]) -> Option<usize> {
        let brick = self.bricks[b];
        let mut key = 0;
        for (axis, o) in offset.into_iter().enumerate() {
            let c = compact(brick >> axis) as i64 + o;
            if c < 0 {
                return None;
            }
            key |= spread(c as u64) << axis;
        }
        self.slot_of(key)
    }
}

/// A coordinate of a position within a brick (nine bits, x y z interleaved from bit 0).
#[inline]
fn local_coord(position: usize, axis: usize) -> usize {
    let p = position >> axis;
    (p & 1) | (p >> 2 & 2) | (p >> 4 & 4)
}

/// The three coordinates (0..8) of a position within a brick.
#[inline]
pub fn brick_local(position: usize) -> [usize; 3] {
    [0, 1, 2].map(|axis| local_coord(position, axis))
}

/// Brick occupancy masks per axis and local interval, see [`axis_interval_masks`].
pub type IntervalMasks = [[[[u64; 8]; 9]; 9]; 3];

/// Per axis a and local interval lo..hi (0 ≤ lo ≤ hi ≤ 8), the brick positions whose local
/// coordinate along a lies in it.
pub fn axis_interval_masks() -> &'static IntervalMasks {
    static MASKS: std::sync::OnceLock<Box<IntervalMasks>> = std::sync::OnceLock::new();
    MASKS.get_or_init(|| {
        let mut masks = Box::new([[[[0u64; 8]; 9]; 9]; 3]);
        for (a, per_axis) in masks.iter_mut().enumerate() {
            for (lo, from_lo) in per_axis.iter_mut().enumerate() {
                for (hi, mask) in from_lo.iter_mut().enumerate().skip(lo) {
                    for p in 0..512 {
                        if (lo..hi).contains(&brick_local(p)[a]) {
                            mask[p >> 6] |= 1 << (p & 63);
                        }
                    }
                }
            }
        }
        masks
    })
}

/// The position (key's low nine bits) of brick-local coordinates, the inverse of
/// [`brick_local`].
#[inline]
pub fn brick_position(local: [usize; 3]) -> usize {
    spread3(local[0]) | spread3(local[1]) << 1 | spread3(local[2]) << 2
}

/// The three bits of a brick-local coordinate (0..8) spread to every third bit, as in a key.
#[inline]
fn spread3(v: usize) -> usize {
    (v & 1) | (v & 2) << 2 | (v & 4) << 4
}

/// Packs a node coordinate with z most significant, then y, then x (21 bits each after the
/// offset), so that sorting packed keys sorts coordinates by (z, y, x) and a shift along one
/// axis is an addition that keeps any sorted list sorted.
#[inline]
pub fn pack(c: Coord) -> u64 {
    ((c[2] + OFFSET) as u64) << (2 * BITS)
        | ((c[1] + OFFSET) as u64) << BITS
        | (c[0] + OFFSET) as u64
}

/// Inverse of [`pack`].
#[inline]
pub fn unpack(k: u64) -> Coord {
    let mask = (1u64 << BITS) - 1;
    [
        (k & mask) as i32 - OFFSET,
        ((k >> BITS) & mask) as i32 - OFFSET,
        (k >> (2 * BITS)) as i32 - OFFSET,
    ]
}

/// The parents (coordinates halved, rounding down) of sorted unique packed keys, sorted and
/// unique, without sorting: among the keys whose y and z have given parities the map to parents
/// keeps the (z, y, x) order (z = 2Z + parity fixes Z's order, likewise y; x only repeats), so
/// the parents are four sorted runs, each deduplicated as it is made, merged. (A parallel sort
/// of them was 1.4 % of a one-thread run on the Happy Buddha at depth 10.)
fn parents_of(children: &[u64]) -> Vec<u64> {
    let mut by_parity: [Vec<u64>; 4] = Default::default();
    for &key in children {
        let c = unpack(key);
        let parent = pack(c.map(|v| v.div_euclid(2)));
        let run = &mut by_parity[((c[1] & 1) | (c[2] & 1) << 1) as usize];
        if run.last() != Some(&parent) {
            run.push(parent);
        }
    }
    let [a, b, c, d] = by_parity;
    merge_unique(&merge_unique(&a, &b), &merge_unique(&c, &d))
}

/// The sorted union of two sorted, unique key lists.
fn merge_unique(a: &[u64], b: &[u64]) -> Vec<u64> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        let (x, y) = (a[i], b[j]);
        out.push(x.min(y));
        i += (x <= y) as usize;
        j += (y <= x) as usize;
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// All keys within Chebyshev distance `r` of the given packed keys (sorted, unique), sorted and
/// unique: [`shifted_by`] with the offsets −r..=r.
pub fn dilate(keys: &[u64], r: i32) -> Vec<u64> {
    shifted_by(keys, -r..=r)
}

/// ∪ (keys + (i, j, k)) over every offset i, j, k in `offsets`, for sorted unique packed keys;
/// sorted and unique. One axis at a time, never sorting: along x the sorted keys form runs that
/// are widened and merged in one pass; along y and z the union of the shifted lists is a merge
/// of sorted lists (a shift along an axis keeps a (z, y, x)-sorted list sorted). No coordinate
/// may leave −OFFSET..2^21 − OFFSET.
///
/// Inside a cancelled watched job ([`stop_requested`]) the result is incomplete: the job stops
/// at its next cancel point and nothing reads it.
fn shifted_by(keys: &[u64], offsets: std::ops::RangeInclusive<i32>) -> Vec<u64> {
    let (below, above) = (-*offsets.start() as i64, *offsets.end() as i64);
    assert!(below + above >= 0, "an empty range of offsets");
    let mut along_x = Vec::with_capacity(keys.len() * 2);
    let row_of = |k: u64| k >> BITS;
    let low = |k: u64| (k as i64 - below) as u64;
    let high = |k: u64| (k as i64 + above) as u64;
    let mut i = 0;
    while i < keys.len() {
        let row = row_of(keys[i]);
        let mut lo = low(keys[i]);
        let mut hi = high(keys[i]);
        i += 1;
        while i < keys.len() && row_of(keys[i]) == row {
            let k = keys[i];
            if low(k) > hi + 1 {
                along_x.extend(lo..=hi);
                lo = low(k);
            }
            hi = high(k);
            i += 1;
        }
        along_x.extend(lo..=hi);
    }
    if stop_requested() {
        return Vec::new();
    }
    let along_y = union_of_shifts(&along_x, 1 << BITS, offsets.clone());
    drop(along_x);
    union_of_shifts(&along_y, 1 << (2 * BITS), offsets)
}

/// ∪_{k ∈ offsets} (keys + k·step), for sorted unique keys.
///
/// In parallel: the output is cut at key values taken from `keys` (how many pieces depends only
/// on the length, so the result does not depend on the thread count), and each piece merges,
/// from every shifted copy, the keys that land in it, all copies at once into the piece's one
/// list (merging them two at a time made a list per copy and per merge: a tenth of a degree-1
/// run's page faults on the Happy Buddha at depth 10).
fn union_of_shifts(keys: &[u64], step: u64, offsets: std::ops::RangeInclusive<i32>) -> Vec<u64> {
    let shifts: Vec<i64> = offsets.map(|k| k as i64 * step as i64).collect();
    let pieces = (keys.len() >> 15).clamp(1, 256);
    let bounds: Vec<i64> = (1..pieces)
        .map(|p| keys[p * keys.len() / pieces] as i64)
        .collect();
    let merged: Vec<Vec<u64>> = (0..pieces)
        .into_par_iter()
        .map(|p| {
            if stop_requested() {
                return Vec::new();
            }
            // Per shifted copy, the keys whose shifted value lies in [bounds[p − 1], bounds[p]).
            let copies: Vec<(&[u64], i64)> = shifts
                .iter()
                .map(|&s| {
                    let start = match p {
                        0 => 0,
                        _ => keys.partition_point(|&v| v as i64 + s < bounds[p - 1]),
                    };
                    let end = match bounds.get(p) {
                        Some(&hi) => keys.partition_point(|&v| v as i64 + s < hi),
                        None => keys.len(),
                    };
                    (&keys[start..end], s)
                })
                .collect();
            merge_shifted(&copies)
        })
        .collect();
    concat_in_parallel(&merged)
}

/// The pieces one after another, copied in parallel (`concat` copies them on one thread).
fn concat_in_parallel(pieces: &[Vec<u64>]) -> Vec<u64> {
    let mut out = vec![0u64; pieces.iter().map(Vec::len).sum()];
    let mut at = 0;
    let ranges: Vec<std::ops::Range<usize>> = pieces
        .iter()
        .map(|piece| {
            at += piece.len();
            at - piece.len()..at
        })
        .collect();
    split_parts(&mut out, ranges)
        .into_par_iter()
        .zip(pieces)
        .for_each(|(to, piece)| to.copy_from_slice(piece));
    out
}

/// The sorted union of sorted unique key lists, each shifted by its offset (which keeps it
/// sorted), in one pass: each step takes the least head and advances every list that holds
/// it. Packed keys stay below 2^63, so `u64::MAX` marks a list that is used up.
fn merge_shifted(copies: &[(&[u64], i64)]) -> Vec<u64> {
    let mut out = Vec::with_capacity(copies.iter().map(|(keys, _)| keys.len()).sum());
    let mut at = vec![0usize; copies.len()];
    let head = |k: usize, at: &[usize]| {
        let (keys, shift) = copies[k];
        keys.get(at[k])
            .map_or(u64::MAX, |&v| (v as i64 + shift) as u64)
    };
    loop {
        let least = (0..copies.len())
            .map(|k| head(k, &at))
            .min()
            .unwrap_or(u64::MAX);
        if least == u64::MAX {
            return out;
        }
        out.push(least);
        for k in 0..copies.len() {
            at[k] += (head(k, &at) == least) as usize;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bricks_morton_masks_hold_each_row_node_at_its_position() {
        // Position by position against the rows, on random rows, single nodes and full rows.
        let mut state = 11u64;
        let mut cases: Vec<[u8; 64]> = (0..200)
            .map(|_| std::array::from_fn(|_| lcg_byte(&mut state)))
            .collect();
        cases.push([0xff; 64]);
        for row in 0..64 {
            for x in 0..8 {
                let mut rows = [0u8; 64];
                rows[row] = 1 << x;
                cases.push(rows);
            }
        }
        for rows in cases {
            let mask = BrickRows::morton_masks(&rows);
            for p in 0..512 {
                let [x, y, z] = brick_local(p);
                assert_eq!(
                    mask[p >> 6] >> (p & 63) & 1,
                    u64::from(rows[y + 8 * z] >> x & 1)
                );
            }
        }
    }

    fn lcg_byte(state: &mut u64) -> u8 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 56) as u8
    }

    #[test]
    fn morton_order_keeps_a_parents_children_contiguous() {
        let p = morton([3, 5, 6]);
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    assert_eq!(parent_key(morton([6 + dx, 10 + dy, 12 + dz])), p);
                }
            }
        }
    }

    #[test]
    fn dilation_matches_brute_force() {
        let pts = vec![
            [0, 0, 0],
            [5, 0, 0],
            [2, 3, 1],
            [9, 9, 9],
            [6, 0, 0],
            [-1, 4, 4],
        ];
        let mut keys: Vec<u64> = pts.iter().map(|&c| pack(c)).collect();
        keys.sort_unstable();
        // Chebyshev balls, and the one-sided ranges of degree 1's corners and beyond.
        let ranges = [(-1, 1), (-2, 2), (0, 1), (0, 0), (1, 3), (-3, -1)];
        for (lo, hi) in ranges {
            let got = if lo == -hi {
                dilate(&keys, hi)
            } else {
                shifted_by(&keys, lo..=hi)
            };
            let mut want = Vec::new();
            for p in &pts {
                for dz in lo..=hi {
                    for dy in lo..=hi {
                        for dx in lo..=hi {
                            want.push(pack([p[0] + dx, p[1] + dy, p[2] + dz]));
                        }
                    }
                }
            }
            want.sort_unstable();
            want.dedup();
            assert_eq!(got, want, "offsets {lo}..={hi}");
        }
    }

    #[test]
    fn a_samples_core_is_the_nodes_over_its_cell_widened_by_one() {
        // One sample cell at depth 5, far from the faces, nothing complete below depth 1:
        // degree 2's nodes over the cell are c − 1..=c + 1 per axis, degree 1's its corners
        // c..=c + 1; widened by one node, the core of depth 5 is a box of 5 or 4 nodes a side,
        // the same about the cell's centre on both sides.
        let c = [12, 17, 9];
        for (degree, lo, hi) in [(Degree::Two, -2, 2), (Degree::One, -1, 2)] {
            let mut sample_cells = vec![Vec::new(); 6];
            sample_cells[5] = vec![c];
            let tree = Octree::build_for(sample_cells, 1, Boundary::Neumann, degree);
            let finest = &tree.levels[5];
            let mut core: Vec<Coord> = finest.core.iter().map(|&i| finest.coord(i)).collect();
            core.sort_unstable();
            let mut want = Vec::new();
            for x in lo..=hi {
                for y in lo..=hi {
                    for z in lo..=hi {
                        want.push([c[0] + x, c[1] + y, c[2] + z]);
                    }
                }
            }
            want.sort_unstable();
            assert_eq!(core, want, "{degree:?}");
        }
    }

    #[test]
    fn parents_without_sorting_match_sorting() {
        // Keys of a band of nodes, some in the halo below 0, sorted and unique.
        let mut keys: Vec<u64> = (0..60_000i64)
            .map(|i| {
                let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 44;
                pack([
                    (h % 41) as i32 - 4,
                    ((h / 41) % 37) as i32 - 3,
                    (i % 29) as i32 - 2,
                ])
            })
            .collect();
        keys.sort_unstable();
        keys.dedup();
        let mut want: Vec<u64> = keys
            .iter()
            .map(|&k| pack(unpack(k).map(|v| v.div_euclid(2))))
            .collect();
        want.sort_unstable();
        want.dedup();
        assert_eq!(parents_of(&keys), want);
        assert!(parents_of(&[]).is_empty());
    }

    #[test]
    fn union_of_shifts_in_pieces_matches_sorting() {
        // Enough keys for many pieces; a sparse pseudo-random band of coordinates.
        let mut keys: Vec<u64> = (0..200_000u64)
            .map(|i| {
                let h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                pack([(h % 300) as i32, ((h / 300) % 300) as i32, (i % 97) as i32])
            })
            .collect();
        keys.sort_unstable();
        keys.dedup();
        for (step, r) in [(1u64 << BITS, 1), (1u64 << (2 * BITS), 2)] {
            let mut want: Vec<u64> = (-r..=r)
                .flat_map(|k| {
                    keys.iter()
                        .map(move |&v| (v as i64 + k as i64 * step as i64) as u64)
                })
                .collect();
            want.sort_unstable();
            want.dedup();
            assert_eq!(union_of_shifts(&keys, step, -r..=r), want);
        }
    }

    #[test]
    fn pack_round_trips_and_sorts_by_z_then_y_then_x() {
        for c in [[0, 0, 0], [-2, 5, 7], [65537, -8, 3], [123, 456, 789]] {
            assert_eq!(unpack(pack(c)), c);
        }
        assert!(pack([9, 9, 0]) < pack([0, 0, 1]));
        assert!(pack([9, 0, 1]) < pack([0, 1, 1]));
        assert_eq!(pack([3, 4, 5]) + (1 << BITS), pack([3, 5, 5]));
    }

    #[test]
    fn brick_index_finds_exactly_the_stored_keys() {
        let coords: Vec<Coord> = (0..2000)
            .map(|i| [(i * 7) % 37 - 3, (i * 13) % 29, (i * 5) % 41 - 2])
            .collect();
        let mut keys: Vec<u64> = coords.iter().map(|&c| morton(c)).collect();
        keys.sort_unstable();
        keys.dedup();
        let index = BrickIndex::new(&keys);
        for (i, &k) in keys.iter().enumerate() {
            assert_eq!(index.get(k), Some(i as u32));
        }
        for c in [[100, 0, 0], [-5, -5, -5], [36, 30, 0]] {
            assert_eq!(index.get(morton(c)), None);
        }
    }

    /// K_d, NEAR and the mirrors that the brick rows give are the core widened by two and by
    /// one node as [`dilate`] widens packed keys, with each node outside the cube mirrored, on
    /// sparse trees whose cores reach the cube's faces, with and without mirrors.
    #[test]
    fn brick_row_widening_matches_packed_dilation() {
        for boundary in [Boundary::Free, Boundary::Neumann, Boundary::Dirichlet] {
            let sample_cells: Vec<Vec<Coord>> = (0..=6)
                .map(|d| {
                    let n = 1 << d;
                    (0..n)
                        .flat_map(|i| [[i, (i * 5) % n, n - 1 - i], [0, i, (i * 3) % n]])
                        .collect()
                })
                .collect();
            let tree = Octree::build(sample_cells, 2, boundary);
            for level in &tree.levels {
                let mut core: Vec<u64> = level.core.iter().map(|&i| pack(level.coord(i))).collect();
                core.sort_unstable();
                let near = dilate(&core, 1);
                let halo = dilate(&near, 1);
                let morton_sorted = |packed: &[u64]| {
                    let mut keys: Vec<u64> = packed.iter().map(|&k| morton(unpack(k))).collect();
                    keys.sort_unstable();
                    keys
                };
                assert_eq!(level.keys, morton_sorted(&halo), "depth {}", level.depth);
                let flagged = |flag: u8| {
                    let keys: Vec<u64> = (0..level.len())
                        .filter(|&i| level.flags[i] & flag != 0)
                        .map(|i| level.keys[i])
                        .collect();
                    keys
                };
                assert_eq!(flagged(NEAR), morton_sorted(&near));
                assert_eq!(flagged(CORE), morton_sorted(&core));
                let n = 1 << level.depth;
                let mirrored: Vec<u32> = (0..level.len() as u32)
                    .filter(|&i| reflect(level.coord(i), n).is_some())
                    .collect();
                if let Some(sign) = boundary.mirror_sign() {
                    assert_eq!(level.face_sign, sign);
                    let outside: Vec<u32> = level.mirrors.iter().map(|m| m.outside).collect();
                    assert_eq!(outside, mirrored);
                    for m in &level.mirrors {
                        let (inside, flips) = reflect(level.coord(m.outside), n).unwrap();
                        assert_eq!((level.coord(m.inside), m.flips), (inside, flips));
                    }
                } else {
                    assert!(level.mirrors.is_empty());
                }
            }
        }
    }

    /// Degree 1 with Dirichlet boundaries keeps the face corners out of the core, so the
    /// parent of a core node next to a face is a face node: it is split all the same, and so
    /// are its ancestors. Every split node's parent is split, every core node's parent is
    /// split, and a node is split exactly when it has a core or split child.
    #[test]
    fn degree_one_dirichlet_splits_the_face_nodes_above_core_nodes() {
        // Sample cells along the x = 0 face at depth 4, with nothing deeper than depth 1
        // complete: the core reaches index 1 there, whose parents have index 0.
        let cells: Vec<Coord> = (0..16).flat_map(|y| [[0, y, 3], [0, y, 12]]).collect();
        let mut sample_cells = vec![Vec::new(); 5];
        sample_cells[4] = cells;
        let tree = Octree::build_for(sample_cells, 0, Boundary::Dirichlet, Degree::One);
        let mut face_nodes_split = 0;
        for d in 0..tree.levels.len() - 1 {
            let (level, finer) = (&tree.levels[d], &tree.levels[d + 1]);
            for j in 0..level.len() as u32 {
                let c = level.coord(j);
                let split_or_core_child = (0..8).any(|k| {
                    let child = [0, 1, 2].map(|a| 2 * c[a] + (k >> a & 1));
                    finer
                        .find(child)
                        .is_some_and(|n| finer.flags[n as usize] & (CORE | SPLIT) != 0)
                });
                let flags = level.flags[j as usize];
                assert_eq!(
                    flags & SPLIT != 0,
                    split_or_core_child,
                    "depth {d} node {c:?}"
                );
                if flags & (SPLIT | CORE) == SPLIT {
                    face_nodes_split += 1;
                }
            }
            for j in 0..finer.len() as u32 {
                if finer.flags[j as usize] & (CORE | SPLIT) == 0 {
                    continue;
                }
                // Depth 0 holds no node with these boundaries: the root stands for itself.
                if let Some((p, _)) = finer.parent_in(level, j) {
                    assert!(level.flags[p as usize] & SPLIT != 0, "depth {d}");
                } else {
                    assert_eq!(d, 0, "the parent of {:?} is missing", finer.coord(j));
                }
            }
        }
        assert!(
            face_nodes_split > 0,
            "the case this test is about did not arise"
        );
    }

    #[test]
    fn tree_is_proper_with_halo_and_links() {
        let sample_cells = vec![vec![], vec![], vec![], vec![[5, 2, 7]]];
        let tree = Octree::build(sample_cells, 1, Boundary::Neumann);
        let finest = &tree.levels[3];
        // The nodes covering cell (5, 2, 7) are [4, 6] × [1, 3] × [6, 8]; widened by one and
        // clipped to the 8³ cube the core is [3, 7] × [0, 4] × [5, 7]; the halo is that box
        // widened by two.
        assert_eq!(finest.core.len(), 5 * 5 * 3);
        assert_eq!(finest.len(), 9 * 9 * 7);
        let i = finest.find([5, 2, 7]).unwrap();
        assert_eq!(finest.flags[i as usize], CORE | NEAR);
        // Split: the parents of core nodes, and only they.
        for d in 0..3 {
            let level = &tree.levels[d];
            let finer = &tree.levels[d + 1];
            for (j, &flags) in level.flags.iter().enumerate() {
                let has_core_child = (0..8).any(|k| {
                    let c = level.coord(j as u32);
                    let child = [0, 1, 2].map(|a| 2 * c[a] + (k >> a & 1));
                    finer
                        .find(child)
                        .is_some_and(|n| finer.flags[n as usize] & CORE != 0)
                });
                assert_eq!(flags & SPLIT != 0, has_core_child, "depth {d} node {j}");
            }
        }
        assert_eq!(finest.flags.iter().filter(|&&f| f & SPLIT != 0).count(), 0);
        let corner = finest.find([3, 0, 5]).unwrap();
        assert_eq!(finest.flags[corner as usize], CORE | NEAR);
        assert_eq!(
            finest.flags[finest.find([5, 2, 8]).unwrap() as usize] & CORE,
            0
        );
        assert_eq!(
            finest.flags[finest.find([5, 2, 8]).unwrap() as usize] & NEAR,
            NEAR
        );
        assert_eq!(finest.coord(finest.neighbor(i, 1)), [6, 2, 7]);
        let (p, _) = finest.parent_in(&tree.levels[2], i).unwrap();
        assert_eq!(tree.levels[2].coord(p), [2, 1, 3]);
        assert!(tree.levels[2].flags[p as usize] & CORE != 0);
        // Complete to the full depth.
        assert_eq!(tree.levels[1].core.len(), 8);
        let block = finest.block27(i);
        assert!(block.iter().all(|&n| n != NONE));
        assert_eq!(finest.coord(block[0]), [4, 1, 6]);
        assert_eq!(finest.coord(block[26]), [6, 3, 8]);
        // Neumann mirrors: (5, 2, 7) is far from the faces of the 8³ grid except z (8 → 7).
        let outside = finest.find([5, 2, 8]).unwrap();
        let m = finest
            .mirrors
            .iter()
            .find(|m| m.outside == outside)
            .unwrap();
        assert_eq!((finest.coord(m.inside), m.flips), ([5, 2, 7], 4));
    }

    #[test]
    fn neighbours_found_through_bricks_are_the_nodes_beside() {
        // A 64³ grid plus its halo, and a sparse tree whose halo is ragged: neighbours within a
        // brick, across brick faces, edges and corners, and missing ones.
        let mut shell = Vec::new();
        for z in 0..64 {
            for y in 0..64 {
                for x in 0..64 {
                    let r2 = (x - 32) * (x - 32) + (y - 32) * (y - 32) + (z - 32) * (z - 32);
                    if (r2 - 400i32).abs() < 40 {
                        shell.push([x, y, z]);
                    }
                }
            }
        }
        let grid = Octree::build(vec![Vec::new(); 7], 6, Boundary::Free);
        let mut cells = vec![Vec::new(); 7];
        cells[6] = shell;
        let sparse = Octree::build(cells, 2, Boundary::Neumann);
        for level in [&grid.levels[6], &sparse.levels[6]] {
            let mut cursor = BrickCursor::default();
            let mut missing = 0;
            for i in 0..level.len() as u32 {
                let c = level.coord(i);
                let at_offset = |o: [i32; 3]| {
                    level
                        .find([c[0] + o[0], c[1] + o[1], c[2] + o[2]])
                        .unwrap_or(NONE)
                };
                for dir in 0..6 {
                    let mut o = [0; 3];
                    o[dir / 2] = if dir % 2 == 0 { -1 } else { 1 };
                    assert_eq!(level.neighbor(i, dir), at_offset(o), "node {c:?} dir {dir}");
                }
                let at = level.locate(&mut cursor, i);
                let block = level.block27_at(i, at);
                assert_eq!(block, level.block27(i));
                // The corner block: the same nodes at offsets 0 and +1, nothing elsewhere.
                let corners = level.corner_block_at(i, at);
                for (slot, (&corner, &full)) in corners.iter().zip(&block).enumerate() {
                    let on_corner = slot % 3 > 0 && slot / 3 % 3 > 0 && slot / 9 > 0;
                    assert_eq!(corner, if on_corner { full } else { NONE }, "slot {slot}");
                }
                for (slot, &n) in block.iter().enumerate() {
                    let o = [slot % 3, slot / 3 % 3, slot / 9].map(|v| v as i32 - 1);
                    let reached =
                        at_offset([0, 0, o[2]]) != NONE && at_offset([0, o[1], o[2]]) != NONE;
                    let want = if reached { at_offset(o) } else { NONE };
                    assert_eq!(n, want, "node {c:?} slot {slot}");
                    missing += (n == NONE) as usize;
                }
            }
            assert!(missing > 0, "the halo's edge has missing neighbours");
        }
    }
}

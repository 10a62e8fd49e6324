//! Stage 8 — isosurface extraction (§4.4): a watertight, manifold mesh of {χ = γ} on the leaves
//! of the octree.
//!
//! **Leaves.** A node with a core child is *split* ([`SPLIT`]: a core node, or with degree 1
//! and Dirichlet boundaries a face node above core nodes next to the face): its eight
//! children replace it (a child outside the core is a leaf too). Every other core node is a
//! leaf. χ is evaluated exactly through the whole tree, so a coarse leaf is one where χ is
//! smooth at that scale, and the mesh is as fine as the samples there: triangles shrink where
//! samples are dense and grow where they are sparse, as in the paper, instead of cutting the
//! whole surface at the finest depth any sample reaches (at depth 11 on the bunny scans that was
//! 4× the triangles for the same χ).
//!
//! **The tree is 2:1 balanced.** The core of depth d contains the parents of the core of depth
//! d + 1 widened by one node ([`crate::octree::Octree::build`]), so every depth-d neighbour
//! (across a face, an edge or a corner) of a split node is in the core; a leaf of depth d − 1
//! touching it would have a core child, i.e. be split. Hence leaves that touch differ by at most
//! one depth, and:
//! * a leaf's face is either one face of a same-size or coarser neighbour, or four faces of
//!   finer neighbours;
//! * a leaf's edge is either whole or cut once at its midpoint (when a finer leaf touches it).
//!
//! **Faces.** The surface is traced on *minimal faces*: a leaf's face, or its four quarters when
//! the neighbour across is finer. A minimal face's boundary runs through its four corners and the
//! midpoints of its cut edges; each sign change along it is a vertex on a *minimal edge* (an edge
//! or half-edge not cut further), shared by every leaf around that edge. On each face the
//! crossings are joined in pairs without crossing: each run of inside points along the boundary
//! is cut off (the outside is joined across the face) or each run of outside points is. With two
//! crossings both are the same. With more, a plain face (four points) decides by the asymptotic
//! decider on its corner values; a face with cut edges by the sign of χ at its centre. Both
//! cells beside a face see the same boundary points, values and decision, so they produce the
//! same segments, traversed in opposite directions: the mesh is closed.
//!
//! **Cells.** A leaf's segments, collected over its minimal faces, form disjoint loops: each
//! minimal edge on its boundary lies on exactly two of its minimal faces, which traverse it in
//! opposite directions. Loops are triangulated so that no diagonal joins two vertices on one
//! face of the leaf (a neighbour could produce the same diagonal); when no such fan exists a
//! centre vertex is added. Every mesh edge is then in exactly two triangles and every vertex has
//! a single fan: a 2-manifold. The surface is followed from the leaves that hold samples, leaf
//! to leaf through the leaves around every crossed edge. A leaf of the finest depth reads χ at
//! its corners off its own 27 nodes; every other corner and edge midpoint is evaluated once and
//! kept (and the centre of a rare ambiguous face with cut edges where it is needed). χ at a
//! point is a pure function of the point, so the leaves sharing it see the same value either
//! way.
//!
//! **Vertices.** Each crossed minimal edge's vertex is the root of χ − γ on it; then, unless the
//! caller asks for vertices on the level set, [`fit_to_surface`] moves every vertex along the
//! normal by the (smoothed) mean sag of its chords, so that the flat triangles straddle the
//! surface.
//!
//! Corners are classed "outside" when χ ≥ γ. Triangles are oriented so that their normals point
//! towards larger χ, which is outside (V points along the outward normals). Beyond the cube
//! everything is outside, and one layer of cells mirroring the leaves inside takes part, so
//! where the surface meets the cube (sparse or open scans) it is closed by a cap lying on the
//! cube's face: the mesh is always closed. With Dirichlet boundaries χ = 0 > γ on the faces
//! (see [`crate::Boundary::Dirichlet`]): they are outside, the surface does not meet them and
//! there is no cap.

use crate::bspline::Degree;
use crate::error::{Error, Result};
use crate::evaluate::Indicator;
use crate::grid::{cell_of, morton, KeyMap};
use crate::key_table::KeyTable;
use crate::octree::{Level, Octree, CORE, NONE, SPLIT};
use crate::parallel::Watch;
use glam::DVec3;
use rayon::prelude::*;
use std::ops::Range;

/// A triangle mesh in unit-cube coordinates.
#[derive(Debug, Default)]
pub struct RawMesh {
    pub vertices: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// When asked for: the unit normal ∇χ/|∇χ| at each vertex, zero where there is none (the
    /// cap on the cube's faces, where χ is not defined beyond the face).
    pub normals: Vec<DVec3>,
}

/// A grid point of the finest depth D (integer coordinates, 2^D across the cube).
type Point = [i64; 3];

/// Corner index = x + 2y + 4z. Edge index = 4·axis + (bits of the other two axes, in cyclic
/// order after `axis`).
fn edge_corners(edge: usize) -> (usize, usize) {
    let axis = edge / 4;
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let bits = edge % 4;
    let base = ((bits & 1) << u) | (((bits >> 1) & 1) << v);
    (base, base | (1 << axis))
}

fn edge_between(a: usize, b: usize) -> usize {
    let diff = a ^ b;
    let axis = diff.trailing_zeros() as usize;
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let lo = a & !diff;
    4 * axis + ((lo >> u) & 1) + 2 * ((lo >> v) & 1)
}

/// The four corners of each face (face 2·axis + side), counter-clockwise seen from outside the
/// cube.
fn face_cycles() -> [[usize; 4]; 6] {
    let mut faces = [[0; 4]; 6];
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in 0..2 {
            let at = |du: usize, dv: usize| (side << axis) | (du << u) | (dv << v);
            let ccw = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
            faces[axis * 2 + side] = if side == 1 {
                ccw
            } else {
                [ccw[0], ccw[3], ccw[2], ccw[1]]
            };
        }
    }
    faces
}

/// Keys pack three coordinates of 20 bits each after this offset: finest-grid points (at most
/// 2^16 + 1 across plus one cell of the coarsest depth beyond the cube on each side), and
/// doubled points (edge midpoints, cell centres).
const KEY_OFFSET: i64 = 1 << 19;

#[inline]
fn pack(p: Point) -> u64 {
    let [x, y, z] = p.map(|v| (v + KEY_OFFSET) as u64);
    x | y << 20 | z << 40
}

/// Inverse of [`pack`].
#[inline]
fn unpack(k: u64) -> Point {
    [k & 0xF_FFFF, (k >> 20) & 0xF_FFFF, (k >> 40) & 0xF_FFFF].map(|v| v as i64 - KEY_OFFSET)
}

/// The key of the minimal edge between finest-grid points `a` and `b`: its doubled midpoint and
/// its axis (an aligned edge's midpoint also fixes its length).
#[inline]
fn edge_key(a: Point, b: Point) -> u64 {
    let axis = (0..3).find(|&i| a[i] != b[i]).unwrap_or(0) as u64;
    pack([a[0] + b[0], a[1] + b[1], a[2] + b[2]]) | axis << 60
}

/// Where a cell of some depth stands in the leaf partition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Status {
    /// Inside a coarser leaf.
    Coarser,
    Leaf,
    /// Replaced by its children.
    Split,
}

/// A leaf: its depth and its cell coordinates at that depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Leaf {
    depth: u32,
    cell: Point,
}

/// The status of node `i` of `level` (`coarser`: the level above, if any). A split node (see
/// [`SPLIT`]) is split; any other core node is a leaf; any other node is a leaf exactly when
/// its parent is split. The root is split whenever there is a depth 1 (its node may be
/// missing: degree 1 with Dirichlet boundaries has no node at depth 0).
fn node_status(level: &Level, coarser: Option<&Level>, i: u32) -> Status {
    let flags = level.flags[i as usize];
    if flags & SPLIT != 0 {
        return Status::Split;
    }
    if flags & CORE != 0 {
        return Status::Leaf;
    }
    let parent_split = coarser
        .is_some_and(|c| parent_is_split(c, || level.parent_in(c, i).map(|(parent, _)| parent)));
    if parent_split {
        Status::Leaf
    } else {
        Status::Coarser
    }
}

/// Whether the parent of a node, in `coarser` (found by `parent` when it is there), is split:
/// its flag says so, but for the root, split whenever there is a depth 1 (its node may be
/// missing: degree 1 with Dirichlet boundaries has no node at depth 0).
fn parent_is_split(coarser: &Level, parent: impl FnOnce() -> Option<u32>) -> bool {
    coarser.depth == 0 || parent().is_some_and(|p| coarser.flags[p as usize] & SPLIT != 0)
}

/// The leaf partition of the tree, with one layer of cells beyond the cube mirroring the leaves
/// inside.
struct Leaves<'t> {
    tree: &'t Octree,
    finest: u32,
}

impl Leaves<'_> {
    fn status(&self, depth: u32, cell: Point) -> Status {
        let n = 1i64 << depth;
        let mirrored = cell.map(|v| {
            let m = if v < 0 {
                -1 - v
            } else if v >= n {
                2 * n - 1 - v
            } else {
                v
            };
            m.clamp(0, n - 1) as i32
        });
        let level = &self.tree.levels[depth as usize];
        let coarser = depth.checked_sub(1).map(|d| &self.tree.levels[d as usize]);
        if let Some(i) = level.find(mirrored) {
            return node_status(level, coarser, i);
        }
        // Not even in the halo: a leaf only if its parent is split; the root (without a node
        // of its own here) is split whenever there is a depth 1.
        match coarser {
            None if self.tree.levels.len() > 1 => Status::Split,
            None => Status::Leaf,
            Some(c) if parent_is_split(c, || c.find(mirrored.map(|v| v >> 1))) => Status::Leaf,
            Some(_) => Status::Coarser,
        }
    }

    /// The leaf containing the depth-`depth` cell `cell`, if that cell is not split and lies
    /// within one cell of the cube.
    fn containing(&self, mut depth: u32, mut cell: Point) -> Option<Leaf> {
        loop {
            match self.status(depth, cell) {
                Status::Leaf => break,
                Status::Coarser if depth > 0 => {
                    depth -= 1;
                    cell = cell.map(|v| v.div_euclid(2));
                }
                _ => return None,
            }
        }
        let n = 1i64 << depth;
        cell.iter()
            .all(|v| (-1..=n).contains(v))
            .then_some(Leaf { depth, cell })
    }

    /// The statuses of the cells of a leaf's depth around it. Away from the cube's faces they
    /// come from the tree's neighbour and parent look-ups (every neighbour of a leaf is in the halo),
    /// with those 27 nodes; next to them, the mirrored lookups of [`Leaves::status`].
    fn block(&self, leaf: &Leaf) -> (Block, Option<[u32; 27]>) {
        let n = 1i64 << leaf.depth;
        let level = &self.tree.levels[leaf.depth as usize];
        let interior = leaf.cell.iter().all(|&x| x >= 1 && x <= n - 2);
        let node = if interior {
            level.find_place(leaf.cell.map(|x| x as i32))
        } else {
            None
        };
        match node {
            Some((i, at)) => {
                let coarser = leaf
                    .depth
                    .checked_sub(1)
                    .map(|d| &self.tree.levels[d as usize]);
                let nodes = level.block27_at(i, at);
                let block = nodes.map(|j| {
                    if j == NONE {
                        Status::Coarser
                    } else {
                        node_status(level, coarser, j)
                    }
                });
                (block, Some(nodes))
            }
            None => (
                std::array::from_fn(|i| {
                    let offset = [i as i64 % 3 - 1, (i as i64 / 3) % 3 - 1, i as i64 / 9 - 1];
                    if offset == [0, 0, 0] {
                        return Status::Leaf;
                    }
                    self.status(
                        leaf.depth,
                        std::array::from_fn(|a| leaf.cell[a] + offset[a]),
                    )
                }),
                None,
            ),
        }
    }

    /// A leaf's key: its doubled centre on the finest grid (which also fixes its size).
    fn key(&self, leaf: &Leaf) -> u64 {
        let size = 1i64 << (self.finest - leaf.depth);
        pack(leaf.cell.map(|v| 2 * v * size + size))
    }
}

/// The statuses of the 3×3×3 cells of a leaf's depth around it (index (dx+1) + 3(dy+1) + 9(dz+1)).
type Block = [Status; 27];

/// A leaf planned for tracing: its neighbours' statuses, the slots it uses (its points:
/// [`LeafPoints`]), χ − γ at them, and the slots whose values come from the table of evaluated points.
type Plan = (Block, u32, [f64; SLOTS], u32);

const fn block_index(offset: [i64; 3]) -> usize {
    ((offset[0] + 1) + 3 * (offset[1] + 1) + 9 * (offset[2] + 1)) as usize
}

/// The slots of a leaf's block (see [`block_index`]) whose cells are split, as a bit mask.
fn split_slots(block: &Block) -> u32 {
    (0..27)
        .filter(|&s| block[s] == Status::Split)
        .fold(0, |mask, s| mask | 1 << s)
}

/// Per edge of a leaf (numbered as in [`edge_corners`]): the slots of its block of the four
/// cells of the leaf's depth around the edge, the leaf's own among them.
const EDGE_CELLS: [u32; 12] = {
    let mut masks = [0u32; 12];
    let mut e = 0;
    while e < 12 {
        let axis = e / 4;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        // The edge's position across u and v: 0 on the leaf's low side, 1 on its high side.
        let (eu, ev) = (((e % 4) & 1) as i64, ((e % 4) >> 1) as i64);
        let mut k = 0;
        while k < 4 {
            // A cell beside the edge lies at offset eu − 1 or eu along u, ev − 1 or ev along v.
            let mut offset = [0i64; 3];
            offset[u] = eu - 1 + (k & 1);
            offset[v] = ev - 1 + (k >> 1);
            masks[e] |= 1 << block_index(offset);
            k += 1;
        }
        e += 1;
    }
    masks
};

/// Whether a leaf's edge `e` is cut: some cell of the leaf's depth around it is split (`split`:
/// [`split_slots`] of the leaf's block).
fn edge_is_cut(split: u32, e: usize) -> bool {
    split & EDGE_CELLS[e] != 0
}

/// Whether the cell across a leaf's face `face` (2·axis + side) is split.
fn face_is_split(split: u32, face: usize) -> bool {
    let mut across = [0i64; 3];
    across[face / 2] = 2 * (face % 2) as i64 - 1;
    split >> block_index(across) & 1 == 1
}

/// Slots of a leaf's points: corner k at k, the midpoint of edge e at 8 + e, the centre of
/// face f at 20 + f.
const SLOTS: usize = 26;
const fn edge_slot(e: usize) -> u8 {
    8 + e as u8
}
const fn centre_slot(f: usize) -> u8 {
    20 + f as u8
}

/// A leaf's points on the finest grid, by slot ([`edge_slot`], [`centre_slot`]): its corners,
/// the midpoints of its edges and the centres of its faces, computed where they are read
/// rather than stored (26 points are 624 bytes, most of a plan).
#[derive(Debug, Clone, Copy)]
struct LeafPoints {
    /// Corner 0 on the finest grid.
    origin: Point,
    /// The leaf's width on the finest grid.
    size: i64,
}

impl LeafPoints {
    fn new(leaf: &Leaf, finest: u32) -> Self {
        let size = 1i64 << (finest - leaf.depth);
        LeafPoints {
            origin: leaf.cell.map(|c| c * size),
            size,
        }
    }

    /// The point of `slot`.
    #[inline]
    fn at(&self, slot: usize) -> Point {
        let (size, half) = (self.size, self.size / 2);
        let corner = |k: usize| -> Point {
            std::array::from_fn(|a| self.origin[a] + ((k >> a) & 1) as i64 * size)
        };
        match slot {
            0..8 => corner(slot),
            8..20 => {
                let e = slot - 8;
                let mut m = corner(edge_corners(e).0);
                m[e / 4] += half;
                m
            }
            _ => {
                let (axis, side) = ((slot - 20) / 2, (slot - 20) % 2);
                std::array::from_fn(|a| {
                    self.origin[a] + if a == axis { side as i64 * size } else { half }
                })
            }
        }
    }
}

/// The slots a leaf uses: its corners, the midpoints of its cut edges and the centres of its
/// faces towards finer leaves (`split`: [`split_slots`] of the leaf's block).
fn used_slots(split: u32) -> u32 {
    let mut used = 0xFF;
    for e in 0..12 {
        if edge_is_cut(split, e) {
            used |= 1 << edge_slot(e);
        }
    }
    for f in 0..6 {
        if face_is_split(split, f) {
            used |= 1 << centre_slot(f);
        }
    }
    used
}

/// One minimal face: its boundary points (slots of the leaf's points), counter-clockwise seen
/// from outside the leaf; `len` is 4 plus the number of cut edges.
#[derive(Debug, Clone, Copy, Default)]
struct MinimalFace {
    slots: [u8; 8],
    len: u8,
    /// Which face of the leaf (2·axis + side) it lies on.
    face: u8,
}

/// The minimal faces of a leaf (at most 24: four quarters on each face), and their number,
/// from the slots its points use (see [`used_slots`]): a cut edge has its midpoint, a face
/// towards finer leaves its centre.
fn minimal_faces(used: u32, cycles: &[[usize; 4]; 6]) -> ([MinimalFace; 24], usize) {
    let in_use = |slot: u8| used >> slot & 1 == 1;
    let mut out = [MinimalFace::default(); 24];
    let mut count = 0;
    for (face, cycle) in cycles.iter().enumerate() {
        let p = cycle.map(|k| k as u8);
        let m: [u8; 4] =
            std::array::from_fn(|k| edge_slot(edge_between(cycle[k], cycle[(k + 1) % 4])));
        if in_use(centre_slot(face)) {
            // Four quarter faces, each in the same rotational order; their edges are not cut
            // further (the finer leaves across touch this leaf, so nothing finer touches them).
            let centre = centre_slot(face);
            for quarter in [
                [p[0], m[0], centre, m[3]],
                [m[0], p[1], m[1], centre],
                [centre, m[1], p[2], m[2]],
                [m[3], centre, m[2], p[3]],
            ] {
                let mut slots = [0u8; 8];
                slots[..4].copy_from_slice(&quarter);
                out[count] = MinimalFace {
                    slots,
                    len: 4,
                    face: face as u8,
                };
                count += 1;
            }
        } else {
            let mut f = MinimalFace {
                face: face as u8,
                ..MinimalFace::default()
            };
            for k in 0..4 {
                f.slots[f.len as usize] = p[k];
                f.len += 1;
                if in_use(m[k]) {
                    f.slots[f.len as usize] = m[k];
                    f.len += 1;
                }
            }
            out[count] = f;
            count += 1;
        }
    }
    (out, count)
}

/// A crossed minimal edge as one leaf sees it.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    key: u64,
    /// The edge's ends and the values there (χ − γ, of opposite signs; ∞ beyond the cube).
    a: Point,
    b: Point,
    va: f64,
    vb: f64,
    /// Bit per face of the leaf the edge lies on.
    faces: u8,
}

/// The surface loops of consecutive leaves, flattened so that tracing allocates per run of
/// leaves rather than per leaf and per loop: every crossing in order, where each loop ends in
/// `crossings`, and where each leaf's loops end in `loop_ends`.
#[derive(Debug, Default)]
struct Loops {
    crossings: Vec<Crossing>,
    loop_ends: Vec<u32>,
    leaf_ends: Vec<u32>,
}

impl Loops {
    /// Closes the loops of the next leaf (none if it was not crossed).
    fn end_leaf(&mut self) {
        self.leaf_ends.push(self.loop_ends.len() as u32);
    }

    /// The number of leaves whose loops are here.
    fn leaves(&self) -> usize {
        self.leaf_ends.len()
    }

    /// The range in `loop_ends` of leaf `k`'s loops.
    fn loops_of(&self, k: usize) -> Range<usize> {
        let start = k.checked_sub(1).map_or(0, |j| self.leaf_ends[j] as usize);
        start..self.leaf_ends[k] as usize
    }

    /// Where loop `l`'s crossings start in `crossings` (where loop `l − 1` ends).
    fn loop_start(&self, l: usize) -> usize {
        l.checked_sub(1).map_or(0, |j| self.loop_ends[j] as usize)
    }

    /// The range in `crossings` of loop `l`.
    fn crossings_of(&self, l: usize) -> Range<usize> {
        self.loop_start(l)..self.loop_ends[l] as usize
    }

    /// Leaf `k`'s crossings, loop after loop.
    fn crossings_of_leaf(&self, k: usize) -> &[Crossing] {
        let loops = self.loops_of(k);
        &self.crossings[self.loop_start(loops.start)..self.loop_start(loops.end)]
    }

    /// Leaf `k`'s loops, each a slice of crossings.
    #[cfg(test)]
    fn of_leaf(&self, k: usize) -> impl Iterator<Item = &[Crossing]> {
        self.loops_of(k)
            .map(move |l| &self.crossings[self.crossings_of(l)])
    }
}

/// The surface loops of one leaf, each a list of crossings in order (counter-clockwise about the
/// normal pointing to larger values), from its minimal faces, its points and their values
/// (χ − γ), appended to `out` (the caller closes the leaf). `centre_value` gives χ − γ at the
/// centre of a face with cut edges, needed only when such a face has more than two crossings.
fn leaf_loops(
    faces: &[MinimalFace],
    points: &LeafPoints,
    values: &[f64; SLOTS],
    centre_value: &impl Fn(Point) -> f64,
    out: &mut Loops,
) {
    // Segments, as pairs of minimal edges (slot pairs), from a crossing where the boundary walk
    // enters the inside to one where it leaves; with the face each lies on.
    const MAX_SEGMENTS: usize = MAX_LOOP;
    let mut segments = [((0u8, 0u8), (0u8, 0u8), 0u8); MAX_SEGMENTS];
    let mut count = 0;
    for f in faces {
        let len = f.len as usize;
        let slot = |k: usize| f.slots[k % len];
        let outside = |k: usize| values[slot(k) as usize] >= 0.0;
        let mut crossings = [(0u8, false); 8];
        let mut m = 0;
        for k in 0..len {
            if outside(k) != outside(k + 1) {
                crossings[m] = (k as u8, outside(k));
                m += 1;
            }
        }
        if m == 0 {
            continue;
        }
        let outside_joined = m > 2
            && if len == 4 {
                // Asymptotic decider: the bilinear interpolant's saddle is outside exactly when
                // the product of the outside pair exceeds that of the inside pair.
                let v = |k: usize| values[slot(k) as usize];
                let (p, q) = (v(0) * v(2), v(1) * v(3));
                if outside(0) {
                    p >= q
                } else {
                    q >= p
                }
            } else {
                let corners: Vec<Point> = (0..len).map(|k| points.at(slot(k) as usize)).collect();
                centre_value(face_centre(&corners)) >= 0.0
            };
        let edge = |i: usize| {
            let k = crossings[i % m].0 as usize;
            (slot(k), slot(k + 1))
        };
        for (i, &(_, outside_before)) in crossings[..m].iter().enumerate() {
            if !outside_before {
                continue;
            }
            // Outside joined: cut off the inside run that starts here (to the next crossing);
            // inside joined: cut off the outside run that ends here (from the previous one).
            let to = if outside_joined { i + 1 } else { i + m - 1 };
            segments[count] = (edge(i), edge(to), f.face);
            count += 1;
        }
    }
    let segments = &segments[..count];
    let same = |x: (u8, u8), y: (u8, u8)| x == y || x == (y.1, y.0);
    let crossing = |(i, j): (u8, u8), faces: u8| {
        let (a, b) = (points.at(i as usize), points.at(j as usize));
        Crossing {
            key: edge_key(a, b),
            a,
            b,
            va: values[i as usize],
            vb: values[j as usize],
            faces,
        }
    };
    let mut used = [false; MAX_SEGMENTS];
    for start in 0..count {
        if used[start] {
            continue;
        }
        used[start] = true;
        let first = out.crossings.len();
        let mut s = start;
        loop {
            let next = (0..count).find(|&t| !used[t] && same(segments[t].0, segments[s].1));
            // Each crossing starts one segment and ends the previous one: it lies on both faces.
            let after = next.unwrap_or(start);
            out.crossings.push(crossing(
                segments[after].0,
                1 << segments[after].2 | 1 << segments[s].2,
            ));
            match next {
                Some(t) => {
                    used[t] = true;
                    s = t;
                }
                None => break,
            }
        }
        // The loop was built from its second crossing: rotate so it starts at the first.
        out.crossings[first..].rotate_right(1);
        out.loop_ends.push(out.crossings.len() as u32);
    }
}

/// The centre of a square face from its boundary points.
fn face_centre(points: &[Point]) -> Point {
    std::array::from_fn(|a| {
        let lo = points
            .iter()
            .map(|p| p[a])
            .min()
            .expect("a face has points");
        let hi = points
            .iter()
            .map(|p| p[a])
            .max()
            .expect("a face has points");
        (lo + hi) / 2
    })
}

/// Stage 8: the mesh of {χ = γ} (unit-cube coordinates), traced from the finest-depth cells of
/// the samples at `positions`, its vertices fitted to the surface ([`fit_to_surface`]) unless
/// `on_isosurface`; with the normals at the vertices when fitted or `with_normals`. Reports
/// its progress to `watch` (up to 0.9: the caller's last step is the rest) and stops with
/// `Error::Cancelled` at the cancel point after each batch of leaves when it is cancelled.
pub(crate) fn extract_around_samples(
    chi: &Indicator,
    isovalue: f64,
    positions: &[DVec3],
    on_isosurface: bool,
    with_normals: bool,
    watch: &Watch,
) -> Result<RawMesh> {
    let inv_h = (chi.tree.max_depth() as f64).exp2();
    let seeds: Vec<[i64; 3]> = positions
        .iter()
        .map(|&p| cell_of(p, inv_h).map(i64::from))
        .collect();
    let mut mesh = extract(chi, isovalue, seeds, !on_isosurface || with_normals, watch)?;
    if !on_isosurface {
        fit_to_surface(&mut mesh, watch)?;
    }
    Ok(mesh)
}

/// Leaves planned and traced together (fixed, so the mesh does not depend on the thread count).
///
/// A batch's plans are written once and read by four passes (the points to evaluate, their
/// values, the loops, the numbering), so the batch is sized for them to stay in cache between
/// the passes. When a plan held its 26 points (870 bytes a leaf), 4096 leaves were 3.5 MB and
/// 16,384 (14 MB) had every pass read them from memory: on the Happy Buddha at depth 10
/// (degree 1) the extraction took 3.42 → 2.81 s on one thread and 2.00 → 1.65 s on two
/// (medians of five), the bunny's 1.25 → 1.02 s; 2048 leaves did about as well as 4096. The
/// points are now computed where read ([`LeafPoints`]): 248 bytes a leaf, 1 MB a batch.
/// The mesh is the same but for the order of its vertices, which are numbered batch by batch.
const WAVE_BATCH: usize = 4096;

/// Leaves whose loops are found and triangulated together, into one [`Loops`] and one [`Fans`]
/// (the work is split by runs; the order of the results is the leaves' whatever the split).
const LOOP_RUN: usize = 256;

/// How many look-ups ahead the numbering announces a key to its table: enough look-ups to cover
/// a cache miss's wait, few enough that the announced lines are still cached when used.
const LOOK_AHEAD: usize = 16;

/// The most crossings a leaf's loop can have: one per segment of its minimal faces.
const MAX_LOOP: usize = 48;

/// The triangles of a run of leaves (centres as `ADDED_CENTRE` | their index in `centres`,
/// counted from the run's first), and per leaf the ends of its triangles and centres.
#[derive(Debug, Default)]
struct Fans {
    triangles: Vec<[u32; 3]>,
    centres: Vec<DVec3>,
    leaf_ends: Vec<(usize, usize)>,
}

/// What the out-of-core slabs (`crate::outofcore::seams`) ask of the trace besides the mesh.
/// The default asks for nothing: the in-memory extraction.
#[derive(Debug, Clone, Default)]
pub(crate) struct Tracing {
    /// Trace only the leaves whose x extent (finest-grid units, half-open) overlaps this
    /// range; the surface is not followed into the others (vertices on their boundary with
    /// traced leaves are still made).
    pub(crate) window: Option<Range<i64>>,
    /// Record every vertex's key and every triangle's leaf ([`Keyed`]).
    pub(crate) keyed: bool,
}

/// Besides the mesh, when [`Tracing::keyed`]: what places its parts in the whole surface,
/// whatever the trace order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Keyed {
    /// Per vertex: the key of the minimal edge it lies on ([`edge_key`]: bits 60–61 the axis,
    /// 62–63 clear), or for a leaf's added centre vertex [`CENTRE_KEY`] | (its rank among that
    /// leaf's centres) << 60 | the leaf's key.
    pub(crate) vertex: Vec<u64>,
    /// Per triangle: the lower x corner of its leaf, in finest-grid units.
    pub(crate) leaf_x: Vec<i64>,
}

/// The bit that tells a centre vertex's key from an edge's (edge keys leave it clear).
pub(crate) const CENTRE_KEY: u64 = 1 << 63;

/// Whether a leaf's x extent (finest-grid units) overlaps `window`.
fn in_window(leaf: &Leaf, finest: u32, window: &Option<Range<i64>>) -> bool {
    window.as_ref().is_none_or(|w| {
        let size = 1i64 << (finest - leaf.depth);
        let lo = leaf.cell[0] * size;
        lo < w.end && lo + size > w.start
    })
}

/// Extracts {χ = γ} on the leaves of `chi`'s tree, following the surface from the leaves
/// containing the finest-depth cells in `seeds` (any order, duplicates allowed). Fails with
/// [`Error::TooLarge`] when the mesh would need vertex ids past 2³¹, and with
/// `Error::Cancelled` at a cancel point (three per batch of leaves) once `watch` is cancelled;
/// its progress, the leaves traced over the leaves found so far, goes to `watch` (0 to 0.8).
pub fn extract(
    chi: &Indicator,
    isovalue: f64,
    seeds: Vec<[i64; 3]>,
    with_normals: bool,
    watch: &Watch,
) -> Result<RawMesh> {
    let tracing = Tracing::default();
    extract_traced(chi, isovalue, seeds, with_normals, &tracing, watch).map(|(mesh, _)| mesh)
}

/// [`extract`], limited to the leaves in `tracing.window` when there is one, and with the
/// [`Keyed`] parts when `tracing.keyed` (empty otherwise). The mesh over the traced leaves is
/// the same as [`extract`]'s there: the same vertices bit for bit (each a pure function of its
/// edge, or of its leaf for a centre) and the same triangles per leaf, in another order.
/// Without a window or keys the extra work is one test per leaf found and one per batch.
pub(crate) fn extract_traced(
    chi: &Indicator,
    isovalue: f64,
    seeds: Vec<[i64; 3]>,
    with_normals: bool,
    tracing: &Tracing,
    watch: &Watch,
) -> Result<(RawMesh, Keyed)> {
    let window = &tracing.window;
    let mut keyed = Keyed::default();
    let finest = chi.tree.max_depth();
    let leaves = Leaves {
        tree: &chi.tree,
        finest,
    };
    let n = 1i64 << finest;
    let h = 1.0 / n as f64;
    let cycles = face_cycles();
    let evaluate = |p: Point| -> f64 {
        if p.iter().all(|v| (0..=n).contains(v)) {
            chi.value(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * h) - isovalue
        } else {
            // Beyond the cube everything is outside: the surface is closed along the cube's
            // faces where it meets them (vertices on such edges land on the face).
            f64::INFINITY
        }
    };
    let mut values: KeyMap<f64> = KeyMap::default();
    let mut mesh = RawMesh::default();

    // In Morton order, so that the leaves of a batch lie close together, as the nodes and
    // coefficients their plans read do (lexicographic order walked the cube in columns:
    // the Buddha's extraction at depth 10, degree 1, one thread, 2.97 → 2.78 s).
    let mut seeds = seeds;
    seeds.par_sort_unstable_by_key(|c| morton(c.map(|v| v as i32)));
    seeds.dedup();
    let mut frontier: Vec<Leaf> = seeds
        .par_iter()
        .filter_map(|&c| leaves.containing(finest, c))
        .filter(|leaf| in_window(leaf, finest, window))
        .collect();
    // The leaves with samples are most of those the trace visits, and about as many as the
    // edges it crosses (the Happy Buddha at depth 10: 0.87, 1.58 and 1.36 million): reserved for,
    // the tables grow once or not at all.
    let mut visited: KeyTable<()> = KeyTable::with_capacity(frontier.len());
    let mut vertex_of_edge: KeyTable<u32> = KeyTable::with_capacity(frontier.len());
    frontier.retain(|leaf| visited.insert_new(leaves.key(leaf), ()));
    watch.check()?;
    let mut traced = 0usize;

    // Where each leaf of the wave stands among its neighbours, its points and χ − γ there.
    // The corners of a leaf away from the cube's faces come from the leaf's own 27 nodes,
    // which its block looked up anyway, wherever χ there is its depth's (its corner node is
    // NEAR, and no split node beside the corner lets a finer depth reach it): a pure function
    // of the position, so the leaves sharing a corner get the same value. Every other point
    // (`looked_up`) is evaluated once and kept in `values`: it costs a look-up from the finest
    // depth down. Into a buffer kept from batch to batch (see `WAVE_BATCH`): a fresh buffer
    // each time faulted in fresh pages (with batches of 16,384 leaves, a quarter of a degree-1
    // run's page faults on the bunny at depth 10).
    let plan_batch = |batch: &[Leaf], plans: &mut Vec<Plan>| {
        batch
            .par_iter()
            .map(|leaf| {
                let (block, nodes) = leaves.block(leaf);
                let split = split_slots(&block);
                let used = used_slots(split);
                let corners = match &nodes {
                    Some(nodes) => chi.corner_values(leaf.depth, nodes, split),
                    None => [None; 8],
                };
                let mut values = [0.0; SLOTS];
                let mut looked_up = 0u32;
                for i in (0..SLOTS).filter(|&i| used >> i & 1 == 1) {
                    match corners.get(i) {
                        Some(Some(v)) => values[i] = v - isovalue,
                        _ => looked_up |= 1 << i,
                    }
                }
                (block, used, values, looked_up)
            })
            .collect_into_vec(plans);
    };

    // Wave by wave, each in batches of a fixed size: the first wave holds every leaf with a
    // sample, and planning it at once held ~0.6 KB per leaf (bunny depth 10: 400 MB).
    let mut next_frontier = Vec::new();
    let mut done = 0;
    // This batch's plans, and the next batch's, planned while this one's vertices are numbered.
    let (mut plans, mut next_plans): (Vec<Plan>, Vec<Plan>) = (Vec::new(), Vec::new());
    let mut planned = false;
    while done < frontier.len() {
        let batch = &frontier[done..(done + WAVE_BATCH).min(frontier.len())];
        done += batch.len();
        if !planned {
            plan_batch(batch, &mut plans);
        }
        let mut needed: Vec<u64> = plans
            .par_iter()
            .zip(batch)
            .flat_map_iter(|(&(_, _, _, looked_up), leaf)| {
                let points = LeafPoints::new(leaf, finest);
                (0..SLOTS)
                    .filter(move |&i| looked_up >> i & 1 == 1)
                    .map(move |i| pack(points.at(i)))
            })
            .filter(|k| !values.contains_key(k))
            .collect();
        needed.par_sort_unstable();
        needed.dedup();
        let fresh: Vec<f64> = needed.par_iter().map(|&k| evaluate(unpack(k))).collect();
        values.extend(needed.into_iter().zip(fresh));
        watch.check()?;
        plans
            .par_iter_mut()
            .zip(batch)
            .for_each(|((_, _, vals, looked_up), leaf)| {
                let points = LeafPoints::new(leaf, finest);
                for i in (0..SLOTS).filter(|&i| *looked_up >> i & 1 == 1) {
                    vals[i] = values[&pack(points.at(i))];
                }
            });

        // The surface's loops in each leaf of the wave (independent: in parallel, by runs of
        // leaves). Face centres, needed only by rare ambiguous faces, are evaluated where they
        // are needed.
        let crossed: Vec<Loops> = plans
            .par_chunks(LOOP_RUN)
            .zip(batch.par_chunks(LOOP_RUN))
            .map(|(run, leaves)| {
                let mut out = Loops::default();
                for ((_, used, vals, _), leaf) in run.iter().zip(leaves) {
                    let used = *used;
                    // The points' signs as a mask (one pass, no branch per point), then
                    // whether the used ones have both.
                    let non_negative = vals
                        .iter()
                        .enumerate()
                        .fold(0u32, |m, (i, &v)| m | ((v >= 0.0) as u32) << i);
                    let (outside, inside) = (non_negative & used != 0, !non_negative & used != 0);
                    if outside && inside {
                        let (faces, count) = minimal_faces(used, &cycles);
                        let points = LeafPoints::new(leaf, finest);
                        leaf_loops(&faces[..count], &points, vals, &evaluate, &mut out);
                    }
                    out.end_leaf();
                }
                out
            })
            .collect();
        watch.check()?;

        // Every crossing of this batch may make a vertex and every loop a centre vertex: their
        // ids must stay below ADDED_CENTRE (and so fit in u32), checked here once for the
        // batch so that the loops below convert with `as` (debug-asserted) at no cost.
        let new_at_most: usize = crossed
            .iter()
            .map(|run| run.crossings.len() + run.loop_ends.len())
            .sum();
        let ids_needed = mesh.vertices.len() + new_at_most;
        if ids_needed > ADDED_CENTRE as usize {
            return Err(Error::TooLarge {
                what: "mesh vertices",
                count: ids_needed,
                limit: ADDED_CENTRE as usize,
            });
        }

        // Number the vertices of newly crossed edges in trace order, and visit the leaves
        // around each of those edges. Every crossing's vertex id is kept, in the same order,
        // for the triangulation. This is one thread's work: the next batch of the wave (which
        // neither reads nor changes these tables) is planned meanwhile.
        let following = &frontier[done..(done + WAVE_BATCH).min(frontier.len())];
        let number = || {
            // Every crossing's key, in order, so that each look-up is announced
            // `LOOK_AHEAD` crossings before it is made (see `KeyTable`).
            let keys: Vec<u64> = crossed
                .iter()
                .flat_map(|run| run.crossings.iter().map(|c| c.key))
                .collect();
            let mut new_edges: Vec<Crossing> = Vec::new();
            let mut crossing_ids: Vec<u32> = Vec::with_capacity(keys.len());
            // The leaves around each leaf's new edges, each once and in the order first met,
            // but for the leaf itself (adjacent edges share their neighbours, so the table of
            // visited leaves is asked once per leaf found, not per edge), and in the window.
            let mut found: Vec<Leaf> = Vec::new();
            let mut around_leaf: Vec<Leaf> = Vec::new();
            let leaf_crossings = crossed
                .iter()
                .flat_map(|run| (0..run.leaves()).map(move |k| run.crossings_of_leaf(k)));
            for ((leaf, (block, _, _, _)), crossings) in
                batch.iter().zip(&plans).zip(leaf_crossings)
            {
                around_leaf.clear();
                for c in crossings {
                    let j = crossing_ids.len();
                    if let Some(&ahead) = keys.get(j + LOOK_AHEAD) {
                        vertex_of_edge.prefetch(ahead);
                    }
                    let next_id = mesh.vertices.len() + new_edges.len();
                    debug_assert!(next_id < ADDED_CENTRE as usize, "checked for the batch");
                    let (id, created) = vertex_of_edge.get_or_insert(c.key, next_id as u32);
                    crossing_ids.push(id);
                    if !created {
                        continue;
                    }
                    new_edges.push(*c);
                    for around in leaves_around(leaf, block, c, finest).into_iter().flatten() {
                        if around != *leaf && !around_leaf.contains(&around) {
                            around_leaf.push(around);
                        }
                    }
                }
                found.extend(
                    around_leaf
                        .drain(..)
                        .filter(|around| in_window(around, finest, window)),
                );
            }
            // Then the leaves found, in the same order (numbering the edges never reads the
            // visited leaves, so this is the order of checking each leaf after its edges).
            let found_keys: Vec<u64> = found.iter().map(|around| leaves.key(around)).collect();
            for (i, (around, &key)) in found.iter().zip(&found_keys).enumerate() {
                if let Some(&ahead) = found_keys.get(i + LOOK_AHEAD) {
                    visited.prefetch(ahead);
                }
                if visited.insert_new(key, ()) {
                    next_frontier.push(*around);
                }
            }
            (new_edges, crossing_ids)
        };
        let ((new_edges, crossing_ids), next_planned) = rayon::join(number, || {
            let planning = !following.is_empty();
            if planning {
                plan_batch(following, &mut next_plans);
            }
            planning
        });
        planned = next_planned;
        std::mem::swap(&mut plans, &mut next_plans);
        // Place the new vertices (independent of each other: in parallel), then triangulate.
        let placed: Vec<(DVec3, DVec3)> = new_edges
            .par_iter()
            .map(|c| edge_vertex(chi, isovalue, h, c, with_normals))
            .collect();
        mesh.vertices.extend(placed.iter().map(|&(v, _)| v));
        if tracing.keyed {
            keyed.vertex.extend(new_edges.iter().map(|c| c.key));
        }
        if with_normals {
            mesh.normals.extend(placed.iter().map(|&(_, n)| n));
        }
        // Triangulate each run's loops (in parallel), then append in wave order, numbering the
        // centre vertices some loops add after this wave's edge vertices, leaf after leaf.
        let vertices = &mesh.vertices;
        let mut first_id = Vec::with_capacity(crossed.len());
        let mut count = 0;
        for run in &crossed {
            first_id.push(count);
            count += run.crossings.len();
        }
        let fans: Vec<Fans> = crossed
            .par_iter()
            .zip(&first_id)
            .map(|(run, &first)| {
                let mut fans = Fans::default();
                for k in 0..run.leaves() {
                    for l in run.loops_of(k) {
                        let at = run.crossings_of(l);
                        let ids = &crossing_ids[first + at.start..first + at.end];
                        let mut on_faces = [0u8; MAX_LOOP];
                        for (f, c) in on_faces.iter_mut().zip(&run.crossings[at]) {
                            *f = c.faces;
                        }
                        let on_faces = &on_faces[..ids.len()];
                        triangulate(
                            ids,
                            on_faces,
                            vertices,
                            &mut fans.triangles,
                            &mut fans.centres,
                        );
                    }
                    fans.leaf_ends
                        .push((fans.triangles.len(), fans.centres.len()));
                }
                fans
            })
            .collect();
        let mut leaves_in_batch = batch.iter();
        for fans in fans {
            debug_assert!(mesh.vertices.len() + fans.centres.len() <= ADDED_CENTRE as usize);
            // The run's centres are numbered from its first: the same ids as leaf by leaf, as
            // nothing else is appended between the leaves of a run.
            let base = mesh.vertices.len() as u32;
            if tracing.keyed {
                let (mut triangles_before, mut centres_before) = (0, 0);
                for &(triangles_end, centres_end) in &fans.leaf_ends {
                    let leaf = leaves_in_batch
                        .next()
                        .expect("a run's leaves are in the batch");
                    let centres = centres_end - centres_before;
                    if centres > 8 {
                        return Err(Error::Internal(format!(
                            "a leaf added {centres} centre vertices, more than its keys can number"
                        )));
                    }
                    let leaf_key = leaves.key(leaf);
                    keyed
                        .vertex
                        .extend((0..centres as u64).map(|k| CENTRE_KEY | k << 60 | leaf_key));
                    let size = 1i64 << (finest - leaf.depth);
                    keyed.leaf_x.extend(std::iter::repeat_n(
                        leaf.cell[0] * size,
                        triangles_end - triangles_before,
                    ));
                    (triangles_before, centres_before) = (triangles_end, centres_end);
                }
            }
            if with_normals {
                let inside = |v: &DVec3| v.cmpge(DVec3::ZERO).all() && v.cmple(DVec3::ONE).all();
                mesh.normals.extend(fans.centres.iter().map(|v| {
                    if inside(v) {
                        chi.gradient(*v).normalize_or_zero()
                    } else {
                        DVec3::ZERO
                    }
                }));
            }
            mesh.vertices.extend(fans.centres);
            mesh.triangles.extend(fans.triangles.into_iter().map(|t| {
                t.map(|i| {
                    if i & ADDED_CENTRE != 0 {
                        base + (i & !ADDED_CENTRE)
                    } else {
                        i
                    }
                })
            }));
        }
        // Every leaf found is traced once: the fraction of those found so far that are traced
        // reaches 1 at the end (finding leaves lowers it meanwhile: the watch keeps the largest).
        traced += batch.len();
        watch.step(traced, visited.len(), 0.0, 0.8)?;
        if done == frontier.len() {
            frontier = std::mem::take(&mut next_frontier);
            done = 0;
        }
    }
    Ok((mesh, keyed))
}

/// Moves every vertex along the surface normal so that the flat triangles straddle {χ = γ}
/// instead of lying on its concave side.
///
/// Extraction puts every vertex on the surface exactly, so each triangle is a chord of it: on a
/// convex patch the whole triangle is inside, on a concave one outside. With vertices on a
/// surface z = ½ xᵀ II x, the linear interpolant's error at barycentric coordinates λ is
/// ½ Σ_{i<j} λ_i λ_j e_ijᵀ II e_ij, whose mean over the triangle is the mean of its three edges'
/// midpoint sags eᵀ II e / 8. The normal curvature along an edge a→b follows from the unit
/// normals at its ends, eᵀ II e ≈ (n_b − n_a)·(b − a), and the normals are ∇χ/|∇χ| (degree-2
/// B-splines have a continuous gradient, so they are smooth across cells). A vertex's sag is
/// the mean over its edges; moving every vertex out by it makes each triangle's mean signed
/// distance to the surface about zero. Per edge the term is at most |b − a|/4, so no vertex
/// moves further than a quarter of the longest edge within two edges of it, whatever the
/// normals.
///
/// The sags are then averaged with their neighbours' twice (each pass: half the vertex's own,
/// half its neighbours' mean). Where the samples are noisy, χ's level set has wiggles a few
/// cells wide whose sag is noise too, and restoring it would copy the noise into the mesh;
/// the curvature of the shape itself spans more cells and passes through. Measured against the
/// exact surfaces (Chamfer, thousandths of the diagonal), without → with smoothing: torus at
/// depth 7 0.030 → 0.030 (0.043 on the isosurface), a noisy sphere at depth 8 0.089 → 0.087
/// (0.083), a 100k-point sphere at depth 8 0.0158 → 0.0153 (0.0153); and from the input
/// points, CGAL's kitten 0.29 → 0.30 (0.41) and oni 1.29 → 1.36 (1.66).
///
/// Vertices of the cap on the cube's faces (outside the unit cube by construction) stay on the
/// face, and their edges do not count: χ is not defined beyond the cube.
///
/// Connectivity is untouched, so the mesh stays closed and manifold. The few triangles whose
/// orientation the move reverses are slivers from edge roots next to a corner: on the bunny
/// scans at depth 10, 337 of 1.08M triangles, 2e-3 of the mean area each before the move,
/// 5e-6 of the total area after; Happy Buddha 728 of 2.7M, 3e-6 of the area.
///
/// Stops with `Error::Cancelled` between its passes once `watch` is cancelled (the mesh is then
/// half moved: the caller drops it).
pub fn fit_to_surface(mesh: &mut RawMesh, watch: &Watch) -> Result<()> {
    const SMOOTHING_PASSES: usize = 2;
    assert_eq!(
        mesh.normals.len(),
        mesh.vertices.len(),
        "fitting needs the normals: extract with_normals"
    );
    let (vertices, normals) = (&mesh.vertices, &mesh.normals);
    let valid: Vec<bool> = normals.iter().map(|n| *n != DVec3::ZERO).collect();
    let mut edges = EdgeMeans::new(&mesh.triangles, &valid);
    let mut sag = vec![0.0; vertices.len()];
    edges.mean_into(
        |a, b| (normals[b] - normals[a]).dot(vertices[b] - vertices[a]) / 8.0,
        &mut sag,
    );
    let mut around = vec![0.0; vertices.len()];
    for pass in 0..SMOOTHING_PASSES {
        watch.step(pass, SMOOTHING_PASSES + 1, 0.8, 0.9)?;
        edges.mean_into(|_, b| sag[b], &mut around);
        sag.par_iter_mut()
            .zip(&around)
            .for_each(|(s, a)| *s = 0.5 * (*s + a));
    }
    drop(edges);
    mesh.vertices
        .par_iter_mut()
        .zip(mesh.normals.par_iter().zip(sag.par_iter()))
        .for_each(|(v, (n, &s))| *v += *n * s);
    watch.set(0.9);
    Ok(())
}

/// The fixed-point unit of the sums in [`EdgeMeans`]: 2⁻¹¹⁰. A term is at most a quarter
/// of an edge (|term| < 1, see [`fit_to_surface`]) and a vertex has a few dozen edges at most,
/// so its sum stays far below 2¹²⁷; a term is read to within 2⁻¹¹⁰ ≈ 8e-34, far below the
/// spacing of the f64 coordinates it moves (2⁻⁵³ near 1, 2⁻⁶⁹ at the finest cell of depth 16).
const SUM_UNIT: f64 = 1.0 / (1u128 << 110) as f64;

/// For every vertex of a closed mesh, the mean of a term over its edges whose two ends are
/// `valid` (0 with none), pass after pass. Each triangle's directed edges a→b visit every edge
/// once from each end.
///
/// The sums are exact integers of [`SUM_UNIT`]s, so a vertex's mean does not depend on the order
/// of its triangles: a slab of the out-of-core mode, which traces the surface in another order,
/// fits its vertices bit for bit as the whole mesh does (`crate::outofcore::seams`). (Summed
/// in f64, one vertex in a few differed in its last bits.) For the same reason the vertices
/// are shared between the threads in ranges, each scanning every triangle for the edges that
/// start in its range: no sum is split, none is held twice. The counts and the sums are kept
/// from pass to pass (the sums' pages, 16 bytes a vertex, were faulted in afresh every pass,
/// the most of this step's time).
struct EdgeMeans<'m> {
    triangles: &'m [[u32; 3]],
    valid: &'m [bool],
    /// Vertices per range (the last may be shorter).
    per_range: usize,
    /// Per vertex, its edges with both ends valid.
    count: Vec<u32>,
    /// Per vertex, the sum of the pass's terms.
    sum: Vec<i128>,
}

impl<'m> EdgeMeans<'m> {
    fn new(triangles: &'m [[u32; 3]], valid: &'m [bool]) -> Self {
        let per_range = valid.len().div_ceil(rayon::current_num_threads()).max(1);
        let mut count = vec![0u32; valid.len()];
        count
            .par_chunks_mut(per_range)
            .enumerate()
            .for_each(|(range, count)| {
                for_each_edge_from(triangles, range * per_range, count.len(), |i, a, b| {
                    if valid[a] && valid[b] {
                        count[i] += 1;
                    }
                });
            });
        EdgeMeans {
            triangles,
            valid,
            per_range,
            count,
            sum: vec![0; valid.len()],
        }
    }

    /// `means[v]` = the mean of `term(v, w)` over the edges v→w with both ends valid, 0 when
    /// v has none.
    fn mean_into(&mut self, term: impl Fn(usize, usize) -> f64 + Sync, means: &mut [f64]) {
        let (triangles, valid, per_range) = (self.triangles, self.valid, self.per_range);
        self.sum
            .par_chunks_mut(per_range)
            .zip(means.par_chunks_mut(per_range))
            .zip(self.count.par_chunks(per_range))
            .enumerate()
            .for_each(|(range, ((sum, means), count))| {
                sum.fill(0);
                for_each_edge_from(triangles, range * per_range, sum.len(), |i, a, b| {
                    if valid[a] && valid[b] {
                        sum[i] += in_sum_units(term(a, b));
                    }
                });
                for ((mean, &s), &c) in means.iter_mut().zip(sum.iter()).zip(count) {
                    *mean = if c > 0 {
                        s as f64 * SUM_UNIT / c as f64
                    } else {
                        0.0
                    };
                }
            });
    }
}

/// Calls `edge(i, a, b)` for every directed edge a→b of `triangles`, in their order, that
/// starts at vertex a = `first` + i with i < `len`.
#[inline]
fn for_each_edge_from(
    triangles: &[[u32; 3]],
    first: usize,
    len: usize,
    mut edge: impl FnMut(usize, usize, usize),
) {
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if let Some(i) = a.checked_sub(first).filter(|&i| i < len) {
                edge(i, a, b);
            }
        }
    }
}

/// `term` in [`SUM_UNIT`]s, truncated towards zero: `(term / SUM_UNIT) as i128`, from two
/// conversions to i64 (the one to i128 is a library call). With s = term·2⁵⁵ (exact), its
/// whole part h and its fraction f = s − h (exact, of the sign of s):
/// trunc(s·2⁵⁵) = h·2⁵⁵ + trunc(f·2⁵⁵), since h·2⁵⁵ is a whole number of f's sign.
#[inline]
fn in_sum_units(term: f64) -> i128 {
    const HALF: f64 = (1u64 << 55) as f64;
    debug_assert!(term.abs() < 1.0, "a term is less than one (see `SUM_UNIT`)");
    let scaled = term * HALF;
    // `as` truncates towards zero (`f64::trunc` would be a library call without SSE4.1), and
    // h goes back to f64 exactly: below 2⁵³, or s was whole already.
    let whole = scaled as i64;
    let fraction = ((scaled - whole as f64) * HALF) as i64;
    ((whole as i128) << 55) + fraction as i128
}

/// The leaves around a crossed minimal edge on the boundary of `leaf` (whose neighbourhood is
/// `block`), found from the block alone: the edge is either one of the leaf's depth, with the
/// four cells of that depth around it each a leaf or inside a coarser one, or half of one
/// (on a cut edge, or inside a face towards finer leaves), with the four cells of the next depth
/// around it each a leaf or inside one of the leaf's depth (2:1 balance).
fn leaves_around(leaf: &Leaf, block: &Block, c: &Crossing, finest: u32) -> [Option<Leaf>; 4] {
    let axis = (0..3)
        .find(|&i| c.a[i] != c.b[i])
        .expect("an edge has length");
    let length = (c.b[axis] - c.a[axis]).abs();
    let depth = finest - length.trailing_zeros();
    let start: Point = std::array::from_fn(|i| c.a[i].min(c.b[i]).div_euclid(length));
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut out = [None; 4];
    for (slot, (du, dv)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
        let mut cell = start;
        cell[u] -= du;
        cell[v] -= dv;
        // The cell of the leaf's depth containing this one, as an offset in the block.
        let shift = depth - leaf.depth;
        let at_leaf_depth: Point = cell.map(|x| x >> shift);
        let offset: Point = std::array::from_fn(|a| at_leaf_depth[a] - leaf.cell[a]);
        let found = match block[block_index(offset)] {
            Status::Leaf => Leaf {
                depth: leaf.depth,
                cell: at_leaf_depth,
            },
            Status::Coarser => Leaf {
                depth: leaf.depth - 1,
                cell: at_leaf_depth.map(|x| x >> 1),
            },
            Status::Split => Leaf {
                depth: leaf.depth + 1,
                cell,
            },
        };
        let n = 1i64 << found.depth;
        if found.cell.iter().all(|x| (-1..=n).contains(x)) && !out.contains(&Some(found)) {
            out[slot] = Some(found);
        }
    }
    out
}

/// The vertex on a crossed minimal edge.
///
/// Along an edge of the finest grid χ is a single quadratic in the edge parameter t: every
/// node function's breakpoints lie on grid corners of its own depth, which are corners of the
/// finest grid too. One more value, at the midpoint, fixes that quadratic, and its root in (0, 1)
/// is where χ = γ exactly. On a coarser leaf's edge the same holds wherever χ is resolved at the
/// leaf's depth, which is what makes the leaf coarse. (Linear interpolation of the end values
/// misplaces vertices by up to a few percent of a cell, in a pattern that follows the grid:
/// measured on a 40k-point sphere at depth 7, exact roots cut the mean mesh-to-sphere distance by
/// 17%.)
///
/// With `with_normal`, also the unit normal ∇χ/|∇χ| there (zero on the cap). On an edge of the
/// finest grid the vertex and the midpoint share their cell at every depth, so χ at both comes
/// from the same nodes, found once.
fn edge_vertex(
    chi: &Indicator,
    isovalue: f64,
    h: f64,
    c: &Crossing,
    with_normal: bool,
) -> (DVec3, DVec3) {
    let start = DVec3::new(c.a[0] as f64, c.a[1] as f64, c.a[2] as f64);
    let end = DVec3::new(c.b[0] as f64, c.b[1] as f64, c.b[2] as f64);
    // Kept off the corners so that no two vertices coincide.
    let at = |t: f64| (start + (end - start) * t.clamp(1e-3, 1.0 - 1e-3)) * h;
    if c.va.is_infinite() {
        return (at(1.0), DVec3::ZERO); // the cap: on the face, at the far end
    }
    if c.vb.is_infinite() {
        return (at(0.0), DVec3::ZERO); // the cap: on the face, at the near end
    }
    let finest_edge = (0..3).map(|i| (c.b[i] - c.a[i]).abs()).sum::<i64>() == 1;
    let midpoint = (start + end) * 0.5 * h;
    // At degree 1 χ is trilinear in each cell of the finest depth, so linear along a finest
    // edge: its root is the linear one, which the quadratic through the midpoint's value gives
    // there too (its curvature term is zero but for rounding, within `quadratic_root`'s
    // margin), without looking that value up (the look-up was a tenth of a degree-1
    // extraction; on the bunny, the Happy Buddha, the kitten and the oni at depth 10 the root
    // was the linear one for every one of their 1.83 million finest edges).
    let linear_edge =
        finest_edge && (chi.tree.levels.last()).is_some_and(|level| level.degree == Degree::One);
    let block = (!linear_edge || with_normal)
        .then(|| chi.block(midpoint))
        .flatten();
    let t = if linear_edge {
        c.va / (c.va - c.vb)
    } else {
        let vm = block.as_ref().map_or(0.0, |b| chi.value_in(b, midpoint)) - isovalue;
        quadratic_root(c.va, vm, c.vb)
    };
    let vertex = at(t);
    if !with_normal {
        return (vertex, DVec3::ZERO);
    }
    let gradient = match &block {
        Some(b) if finest_edge => chi.gradient_in(b, vertex),
        _ => chi.gradient(vertex),
    };
    (vertex, gradient.normalize_or_zero())
}

/// The root in [0, 1] of the quadratic through (0, `v0`), (½, `vm`), (1, `v1`), where `v0` and
/// `v1` have opposite signs (so there is exactly one).
fn quadratic_root(v0: f64, vm: f64, v1: f64) -> f64 {
    let linear = v0 / (v0 - v1);
    // q(t) = v0 + b t + c t².
    let c = 2.0 * (v0 + v1) - 4.0 * vm;
    let b = v1 - v0 - c;
    if c.abs() <= 1e-12 * (v0.abs() + v1.abs()) {
        return linear;
    }
    let disc = (b * b - 4.0 * c * v0).max(0.0);
    // Stable pair of roots: q/c and v0/q.
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let candidates = [q / c, if q != 0.0 { v0 / q } else { f64::NAN }];
    candidates
        .into_iter()
        .filter(|t| (-1e-9..=1.0 + 1e-9).contains(t))
        .min_by(|a, b| (a - linear).abs().total_cmp(&(b - linear).abs()))
        .unwrap_or(linear)
}

/// Marks, in a leaf's triangles before they join the mesh, the k-th centre vertex that leaf
/// adds (as `ADDED_CENTRE | k`); real vertex ids stay below it: extraction checks, once per
/// batch of leaves, that the batch's new vertices keep them there, and otherwise fails with
/// [`Error::TooLarge`] (a mesh of 2^31 vertices needs about 200 GB here).
const ADDED_CENTRE: u32 = 1 << 31;

/// Two fans of one loop whose smallest triangles differ by less than this fraction of the
/// larger are a tie, and the earlier apex in the loop's order keeps it (loop order comes from
/// the leaf's topology, not from coordinates). Without the margin the choice was decided by
/// rounding: the same two triangles listed from either end of their diagonal, or the fans of a
/// near-parallelogram, have smallest areas equal but for the last bits, and the same cloud
/// moved 10⁶ away in `f64` (its vertices then differ by about 10⁻¹⁰ of the cube) picked the
/// other fan for about 1 % of its triangles. A vertex moved by δ of the cube changes the areas
/// of a depth-d leaf's triangles by about 2δ·2^d of themselves, so this margin holds such
/// ties to depth 18 for δ = 10⁻¹⁰, while no fan is worse than the best by more than 0.01 %.
const FAN_TIE: f64 = 1e-4;

/// Triangulates one loop (vertex ids `ids`, each with the bit mask of the leaf's faces it lies
/// on) as a fan from a vertex none of whose diagonals joins two vertices on a common face of the
/// leaf, choosing among those the fan whose smallest triangle is largest; with no such vertex,
/// as a fan around an added centre vertex, which is pushed to `centres` and referred to as
/// `ADDED_CENTRE | index in centres`.
fn triangulate(
    ids: &[u32],
    on_faces: &[u8],
    vertices: &[DVec3],
    triangles: &mut Vec<[u32; 3]>,
    centres: &mut Vec<DVec3>,
) {
    let m = ids.len();
    if m < 3 {
        // Two crossings joined on two faces of the leaf (around the midpoint of a cut edge that
        // is alone on its side): the neighbours across those faces close the surface there.
        return;
    }
    if m == 3 {
        triangles.push([ids[0], ids[1], ids[2]]);
        return;
    }
    let pos = |k: usize| vertices[ids[k % m] as usize];
    let mut best: Option<(f64, usize)> = None;
    for apex in 0..m {
        let safe = (2..m - 1).all(|j| on_faces[apex] & on_faces[(apex + j) % m] == 0);
        if !safe {
            continue;
        }
        let smallest = (1..m - 1)
            .map(|j| {
                (pos(apex + j) - pos(apex))
                    .cross(pos(apex + j + 1) - pos(apex))
                    .length()
            })
            .fold(f64::INFINITY, f64::min);
        if best.is_none_or(|(s, _)| smallest > s + FAN_TIE * s.max(smallest)) {
            best = Some((smallest, apex));
        }
    }
    match best {
        Some((_, apex)) => {
            for j in 1..m - 1 {
                triangles.push([ids[apex], ids[(apex + j) % m], ids[(apex + j + 1) % m]]);
            }
        }
        None => {
            let centre = ids.iter().map(|&i| vertices[i as usize]).sum::<DVec3>() / m as f64;
            // A leaf's loops add a few centres at most; the batch's check bounds them anyway.
            debug_assert!(centres.len() < ADDED_CENTRE as usize);
            let c = ADDED_CENTRE | centres.len() as u32;
            centres.push(centre);
            for k in 0..m {
                triangles.push([c, ids[k], ids[(k + 1) % m]]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_root_is_exact_on_quadratics_and_lines() {
        // q(t) = (t − r)(t + 2) for several r in [0, 1]: values at 0, ½, 1.
        for k in 0..=20 {
            let r = k as f64 / 20.0;
            let q = |t: f64| (t - r) * (t + 2.0);
            if q(0.0) == 0.0 || q(1.0) == 0.0 {
                continue;
            }
            let got = quadratic_root(q(0.0), q(0.5), q(1.0));
            assert!((got - r).abs() < 1e-12, "r {r} got {got}");
        }
        // A line: the linear root.
        assert!((quadratic_root(-1.0, 0.5, 2.0) - 1.0 / 3.0).abs() < 1e-12);
        // Strongly curved, root near the start: q(t) = 3(t − 0.1)(t − 1.7).
        let q = |t: f64| 3.0 * (t - 0.1) * (t - 1.7);
        assert!((quadratic_root(q(0.0), q(0.5), q(1.0)) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn cube_topology_is_consistent() {
        for e in 0..12 {
            let (a, b) = edge_corners(e);
            assert_eq!(edge_between(a, b), e);
        }
        // Every edge lies on exactly two faces, traversed once each way.
        let cycles = face_cycles();
        let mut directed = [[0; 8]; 8];
        for cycle in &cycles {
            for k in 0..4 {
                directed[cycle[k]][cycle[(k + 1) % 4]] += 1;
            }
        }
        for e in 0..12 {
            let (a, b) = edge_corners(e);
            assert_eq!((directed[a][b], directed[b][a]), (1, 1), "edge {e}");
        }
    }

    /// A small deterministic generator for the property tests.
    fn lcg(state: &mut u64) -> u64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        *state >> 33
    }

    /// Proves: a loop's fans whose smallest triangles differ only by rounding are a tie kept by
    /// the first apex, however the vertices are moved by 10⁻¹² (so the same cloud moved in `f64`
    /// gives the same triangles; before [`FAN_TIE`] the choice followed the rounding), while a
    /// fan that is really better (by 30 % here) is still chosen.
    #[test]
    fn near_equal_fans_are_a_tie_kept_by_the_first_apex() {
        let fan = |vertices: &[DVec3]| {
            let (mut triangles, mut centres) = (Vec::new(), Vec::new());
            triangulate(
                &[0, 1, 2, 3],
                &[0; 4],
                vertices,
                &mut triangles,
                &mut centres,
            );
            assert!(centres.is_empty());
            triangles
        };
        let h = 1.0 / 128.0;
        let corner = DVec3::new(0.25, 0.5, 0.75);
        let square = [
            corner,
            corner + DVec3::new(h, 0.0, 0.0),
            corner + DVec3::new(h, h, 0.0),
            corner + DVec3::new(0.0, h, 0.0),
        ];
        let want = vec![[0, 1, 2], [0, 2, 3]];
        assert_eq!(fan(&square), want);
        let mut state = 11;
        for _ in 0..2000 {
            let mut jitter = || (lcg(&mut state) as f64 / (1u64 << 31) as f64 - 0.5) * 2e-12;
            let moved: Vec<DVec3> = square
                .iter()
                .map(|&p| p + DVec3::new(jitter(), jitter(), jitter()))
                .collect();
            assert_eq!(fan(&moved), want, "{moved:?}");
        }
        // Vertex 1 moved out along its diagonal: the diagonal 1–3 makes the larger smallest
        // triangle, and its fan is chosen.
        let mut kite = square;
        kite[1] += DVec3::new(0.3 * h, -0.3 * h, 0.0);
        assert_eq!(fan(&kite), vec![[1, 2, 3], [1, 3, 0]]);
    }

    /// Checks that a leaf's loops pass through every crossed minimal edge exactly once, that
    /// every loop has at least two crossings, and that each crossing lies on one or two faces
    /// of the leaf.
    fn assert_loops_cover_crossed_edges(
        used: u32,
        points: &LeafPoints,
        vals: &[f64; SLOTS],
        centre_value: &impl Fn(Point) -> f64,
    ) -> Vec<Vec<Crossing>> {
        let (faces, count) = minimal_faces(used, &face_cycles());
        let faces = &faces[..count];
        let mut run = Loops::default();
        leaf_loops(faces, points, vals, centre_value, &mut run);
        run.end_leaf();
        assert_eq!(run.leaves(), 1);
        let loops: Vec<Vec<Crossing>> = run.of_leaf(0).map(<[Crossing]>::to_vec).collect();
        let mut expected: Vec<u64> = Vec::new();
        for f in faces {
            let len = f.len as usize;
            for k in 0..len {
                let (i, j) = (f.slots[k] as usize, f.slots[(k + 1) % len] as usize);
                if (vals[i] >= 0.0) != (vals[j] >= 0.0) {
                    expected.push(edge_key(points.at(i), points.at(j)));
                }
            }
        }
        expected.sort_unstable();
        // Each crossed minimal edge is on two minimal faces.
        assert_eq!(expected.len() % 2, 0);
        expected.dedup();
        let mut seen: Vec<u64> = loops.iter().flatten().map(|c| c.key).collect();
        seen.sort_unstable();
        assert_eq!(seen, expected);
        for lp in &loops {
            // Two crossings joined on two faces: a pinch where an outside (or inside) point is
            // cut off on two faces of the leaf and no triangle is needed inside it.
            assert!(lp.len() >= 2, "a loop of {}", lp.len());
            for c in lp {
                assert!((1..=2).contains(&c.faces.count_ones()));
            }
        }
        loops
    }

    /// Proves: a leaf's points by slot are its corners (corner k at offset k's bits × its
    /// width), the midpoints of its edges and the centres of its faces, at several depths
    /// below the finest and places in the cube.
    #[test]
    fn a_leafs_points_are_its_corners_edge_midpoints_and_face_centres() {
        let cycles = face_cycles();
        for (depth, cell) in [(0, [0, 0, 0]), (2, [1, 3, 0]), (4, [7, 2, 15])] {
            let leaf = Leaf { depth, cell };
            let points = LeafPoints::new(&leaf, 5);
            let size = 1i64 << (5 - depth);
            for k in 0..8 {
                let want: Point = std::array::from_fn(|a| (cell[a] + (k >> a & 1) as i64) * size);
                assert_eq!(points.at(k), want, "corner {k}");
            }
            let mean = |corners: &[usize]| -> Point {
                std::array::from_fn(|a| {
                    corners.iter().map(|&k| points.at(k)[a]).sum::<i64>() / corners.len() as i64
                })
            };
            for e in 0..12 {
                let (a, b) = edge_corners(e);
                assert_eq!(points.at(edge_slot(e) as usize), mean(&[a, b]), "edge {e}");
            }
            for (f, cycle) in cycles.iter().enumerate() {
                assert_eq!(points.at(centre_slot(f) as usize), mean(cycle), "face {f}");
            }
        }
    }

    /// The unit cube as a leaf among same-size leaves: its eight corners only.
    fn unit_leaf() -> (u32, LeafPoints) {
        let leaf = Leaf {
            depth: 0,
            cell: [0, 0, 0],
        };
        let (points, used) = (LeafPoints::new(&leaf, 0), used_slots(0));
        assert_eq!(used, 0xFF);
        (used, points)
    }

    #[test]
    fn every_sign_pattern_gives_closed_loops_over_its_crossed_edges() {
        let (used, points) = unit_leaf();
        for case in 0..256usize {
            for saddle_bias in [0.3, 3.0] {
                let mut vals = [0.0; SLOTS];
                for (c, v) in vals.iter_mut().enumerate().take(8) {
                    let mag = if c % 2 == 0 { saddle_bias } else { 1.0 };
                    *v = if (case >> c) & 1 == 1 { mag } else { -mag };
                }
                let no_centres = |_: Point| -> f64 { unreachable!("plain faces") };
                assert_loops_cover_crossed_edges(used, &points, &vals, &no_centres);
            }
        }
    }

    #[test]
    fn an_edges_cells_are_the_cells_of_the_leafs_depth_that_hold_it() {
        // In units of the leaf's cell: the leaf is [0, 1]³, the block's cell at offset o is
        // [o, o + 1]³, and an edge lies on a cell when both its ends do.
        for (e, &cells) in EDGE_CELLS.iter().enumerate() {
            let (a, b) = edge_corners(e);
            let corner = |c: usize| [c & 1, c >> 1 & 1, c >> 2 & 1].map(|v| v as i64);
            let holding: u32 = (0..27)
                .filter(|&s| {
                    let offset = [s as i64 % 3 - 1, s as i64 / 3 % 3 - 1, s as i64 / 9 - 1];
                    [corner(a), corner(b)]
                        .iter()
                        .all(|p| (0..3).all(|i| (offset[i]..=offset[i] + 1).contains(&p[i])))
                })
                .fold(0, |mask, s| mask | 1 << s);
            assert_eq!(holding.count_ones(), 4, "edge {e}");
            assert_eq!(cells, holding, "edge {e}");
            // A lone split cell beside the edge cuts it; one elsewhere does not.
            for s in 0..27 {
                assert_eq!(edge_is_cut(1 << s, e), holding >> s & 1 == 1);
            }
        }
        for f in 0..6 {
            let (axis, side) = (f / 2, f % 2);
            let across = (0..27)
                .filter(|&s| face_is_split(1 << s, f))
                .collect::<Vec<_>>();
            let mut offset = [0i64; 3];
            offset[axis] = 2 * side as i64 - 1;
            assert_eq!(across, vec![block_index(offset)], "face {f}");
        }
    }

    #[test]
    fn cut_edges_and_split_neighbours_give_closed_loops() {
        // A depth-1 leaf at (1, 1, 1) of a depth-3 grid, random neighbour statuses (cut edges and
        // split faces in every combination) and random values at every point.
        let leaf = Leaf {
            depth: 1,
            cell: [1, 1, 1],
        };
        let mut state = 7u64;
        let mut split_faces = 0;
        for _ in 0..2000 {
            let block: Block = std::array::from_fn(|i| match lcg(&mut state) % 4 {
                0 if i != 13 => Status::Split,
                1 => Status::Coarser,
                _ => Status::Leaf,
            });
            let split = split_slots(&block);
            split_faces += (0..6).filter(|&f| face_is_split(split, f)).count();
            let (points, used) = (LeafPoints::new(&leaf, 3), used_slots(split));
            let seed = lcg(&mut state);
            let random = |p: Point| {
                let h = pack(p).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed;
                (h >> 40) as f64 - (1u64 << 23) as f64 + 0.5
            };
            let mut vals = [0.0; SLOTS];
            for i in (0..SLOTS).filter(|&i| used >> i & 1 == 1) {
                vals[i] = random(points.at(i));
            }
            assert_loops_cover_crossed_edges(used, &points, &vals, &random);
        }
        assert!(split_faces > 1000, "the cases cover split faces");
    }

    #[test]
    fn single_outside_corner_is_cut_off_facing_outwards() {
        let (used, points) = unit_leaf();
        let mut vals = [-1.0; SLOTS];
        vals[0] = 1.0;
        let loops = assert_loops_cover_crossed_edges(used, &points, &vals, &|_| -1.0);
        assert_eq!(loops.len(), 1);
        let lp = &loops[0];
        let point = |c: &Crossing| {
            let mid: [f64; 3] = std::array::from_fn(|a| (c.a[a] + c.b[a]) as f64 / 2.0);
            DVec3::from(mid)
        };
        let normal = (point(&lp[1]) - point(&lp[0])).cross(point(&lp[2]) - point(&lp[0]));
        // Outside (larger values) is towards corner 0, i.e. −(1,1,1).
        assert!(normal.dot(DVec3::ONE) < 0.0);
    }

    /// Proves: the fixed-point terms of `EdgeMeans` come out as the direct conversion to
    /// i128 gives them, for terms of either sign and every magnitude below 1 (down to those
    /// that truncate to 0), and a mesh's means do not depend on how many threads sum them.
    #[test]
    fn fixed_point_terms_match_the_direct_conversion_and_means_any_thread_count() {
        let check = |t: f64| assert_eq!(in_sum_units(t), (t / SUM_UNIT) as i128, "term {t:e}");
        let mut state = 7u64;
        for _ in 0..200_000 {
            let mantissa = (lcg(&mut state) as f64 + 0.5) / (1u64 << 31) as f64;
            let exponent = -((lcg(&mut state) % 120) as i32);
            let sign = if lcg(&mut state) & 1 == 0 { 1.0 } else { -1.0 };
            check(sign * mantissa * 2f64.powi(exponent) * 0.999);
        }
        for term in [
            0.0,
            -0.0,
            0.999_999_999_999,
            -0.999_999_999_999,
            SUM_UNIT,
            -SUM_UNIT,
        ] {
            check(term);
        }
        // A strip of triangles over 1,000 vertices, some invalid; terms of both signs.
        let triangles: Vec<[u32; 3]> = (0..998u32).map(|i| [i, i + 1, i + 2]).collect();
        let valid: Vec<bool> = (0..1000).map(|i| i % 17 != 3).collect();
        let term = |a: usize, b: usize| ((a * 31 + b * 7) % 101) as f64 / 404.0 - 0.12;
        let means: Vec<Vec<f64>> = [1, 2, 3, 7]
            .iter()
            .map(|&threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| {
                        let mut means = vec![f64::NAN; valid.len()];
                        EdgeMeans::new(&triangles, &valid).mean_into(term, &mut means);
                        means
                    })
            })
            .collect();
        assert!(means.iter().all(|m| m == &means[0]));
        assert!(means[0].iter().any(|&m| m < 0.0) && means[0].iter().any(|&m| m > 0.0));
        assert_eq!(means[0][3], 0.0, "an invalid vertex has no edges");
    }

    #[test]
    fn keys_round_trip_and_tell_edge_lengths_apart() {
        for p in [[0, 0, 0], [-65536, 3, 131072], [5, -1, 7]] {
            assert_eq!(unpack(pack(p)), p);
        }
        // Same start and axis, different lengths: different edges.
        assert_ne!(
            edge_key([0, 0, 0], [1, 0, 0]),
            edge_key([0, 0, 0], [2, 0, 0])
        );
        // Same doubled midpoint, different axes.
        assert_ne!(
            edge_key([0, 2, 0], [4, 2, 0]),
            edge_key([2, 0, 0], [2, 4, 0])
        );
        assert_eq!(
            edge_key([4, 2, 0], [0, 2, 0]),
            edge_key([0, 2, 0], [4, 2, 0])
        );
    }
}

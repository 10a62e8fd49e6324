//! The mesh across the slabs' walls (`docs/out-of-core.md`, "The extraction across walls"):
//! each slab's part of the in-memory mesh, and the parts welded into one mesh.
//!
//! **A slab's part.** The slab traces {χ = γ} with the in-memory extraction
//! ([`crate::extract::extract_traced`]) over the leaves overlapping its owned x range widened by a
//! margin ([`margin`]), fits the vertices as the in-memory pipeline does, and keeps the triangles
//! of the leaves it *owns* (lower x corner in its range). Every vertex is a pure function of its
//! minimal edge (or, for a centre vertex, of its leaf), and its fitted position a pure function
//! of its 3-ring (the fit's sag reads the vertex's edges, and each of the two smoothing passes
//! one ring more; its sums are exact, so the triangles' order does not count,
//! [`crate::extract::fit_to_surface`]). So wherever the traced mesh holds a vertex's whole
//! 3-ring, the slab's vertex is the in-memory one bit for bit; [`slab_part`] checks that it does
//! for every vertex it keeps (the margin guarantees it, the check keeps a wrong window from
//! passing silently).
//!
//! **Keys.** A vertex is named by its minimal edge's key (a centre vertex by its leaf's): the
//! same in every slab that makes it. A vertex on a wall (used by leaves of two slabs) is in both
//! slabs' parts, marked [`SHARED_BELOW`] or [`SHARED_ABOVE`]; [`weld`] keeps the lower slab's
//! and checks the other is the same bit for bit.
//!
//! **Margin.** Let S be the size of the coarsest leaf near the wall (finest-grid units). A kept
//! vertex v lies on an owned leaf, so within [x0, x1 − 1 + S] (an owned leaf starts before x1
//! and may reach S − 1 beyond it). Every mesh edge lies in one leaf, so the vertices u within two
//! edges of v lie within 2S of v, and the leaves holding u's triangles within S more. A leaf is
//! traced when its x extent overlaps the window; the leaves around u do when the window reaches
//! from x0 − 2S (exclusive) to x1 − 1 + 3S, i.e. a margin of 3S on each side. Vertices on the
//! level set (`on_isosurface`) need only their own triangles (to tell which are on a wall): S.
//! S is found in the tree ([`margin`]): the coarsest depth d with a leaf overlapping the
//! range widened by 3 cells of depth d (coarser leaves farther away cannot be reached from
//! the owned leaves through finer ones within that band).
//!
//! **Seeds.** The trace follows the surface from the seeds' leaves, within the window: a piece
//! of surface in the window reached in memory only through leaves beyond it, or from samples
//! the slab does not hold, is missing; the check above then fails for the kept vertices next
//! to it, or (a piece wholly inside) it is missing from the part. The seeds' exchange between
//! neighbours (the doc's "Seeds") is the caller's.

use crate::error::{Error, Result};
use crate::evaluate::Indicator;
use crate::extract::{extract_traced, fit_to_surface, Keyed, RawMesh, Tracing};
use crate::grid::KeyMap;
use crate::octree::{Octree, SPLIT};
use crate::parallel::Watch;
use glam::DVec3;
use std::ops::Range;

/// In [`SlabPart::shared`]: the vertex is also used by a leaf of a slab below (lower x).
pub(crate) const SHARED_BELOW: u8 = 1;
/// In [`SlabPart::shared`]: the vertex is also used by a leaf of a slab above (higher x).
pub(crate) const SHARED_ABOVE: u8 = 2;

/// One slab's part of the mesh: the triangles of the leaves it owns and the vertices they use.
#[derive(Debug, Default)]
pub(crate) struct SlabPart {
    /// Unit-cube positions, in the order the owned triangles first use them.
    pub(crate) vertices: Vec<DVec3>,
    /// The unit normals at the vertices when fitted or asked for (as [`RawMesh::normals`]).
    pub(crate) normals: Vec<DVec3>,
    /// Per vertex, its key in the whole mesh ([`Keyed::vertex`]).
    pub(crate) keys: Vec<u64>,
    /// Into `vertices`, in trace order.
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Per vertex, [`SHARED_BELOW`] and [`SHARED_ABOVE`] bits: which neighbours' parts hold it too.
    pub(crate) shared: Vec<u8>,
}

/// The margin (finest-grid units) to add on each side of `owned` (finest-grid x, half-open) for
/// the traced window: 3S when the vertices are fitted, S on the level set, S being the size of
/// the coarsest leaf within reach (see the module documentation). Reads the flags of the
/// tree's levels from the root down to the first depth with a leaf in the band.
pub(crate) fn margin(tree: &Octree, owned: &Range<i64>, fitted: bool) -> i64 {
    let finest = tree.max_depth();
    let rings = if fitted { 3 } else { 1 };
    for level in tree.levels.iter().skip(1) {
        let size = 1i64 << (finest - level.depth);
        let reach = rings * size;
        let band = owned.start - reach..owned.end + reach;
        // Any node in the cube not split is a leaf or lies in one (found here or at a coarser
        // depth); the leaves are all nodes of the tree (every child of a split node is in its
        // halo), and those beyond the cube mirror leaves inside (its halo nodes there are not
        // read by the extraction).
        let n = 1i32 << level.depth;
        let leaf_in_band = (0..level.len() as u32).any(|i| {
            let c = level.coord(i);
            let lo = c[0] as i64 * size;
            level.flags[i as usize] & SPLIT == 0
                && c.iter().all(|v| (0..n).contains(v))
                && lo < band.end
                && lo + size > band.start
        });
        if leaf_in_band {
            return reach;
        }
    }
    rings
}

/// Slab `owned`'s part of the mesh of {χ = `isovalue`} that [`crate::extract::extract`] (then
/// [`fit_to_surface`] unless `on_isosurface`) makes of the whole `chi` from the same seeds, traced
/// over the leaves overlapping `traced` (which must hold `owned` widened by [`margin`]) from the
/// leaves of `seeds` (finest-depth cells, those of the slab's padded samples). `owned` and
/// `traced` are finest-grid x ranges. Fails with [`Error::Internal`] when the traced mesh does
/// not hold the whole 3-ring (1-ring on the level set) of a kept vertex: `traced` is too
/// narrow, or a piece of surface next to the slab was not reached from its seeds.
#[allow(clippy::too_many_arguments)]
pub(crate) fn slab_part(
    chi: &Indicator,
    isovalue: f64,
    seeds: Vec<[i64; 3]>,
    owned: Range<i64>,
    traced: Range<i64>,
    on_isosurface: bool,
    with_normals: bool,
    watch: &Watch,
) -> Result<SlabPart> {
    let (mesh, keyed) = traced_mesh(
        chi,
        isovalue,
        seeds,
        traced,
        on_isosurface,
        with_normals,
        watch,
    )?;
    owned_part(&mesh, &keyed, owned, if on_isosurface { 0 } else { 2 })
}

/// The mesh over the leaves overlapping `traced`, fitted unless `on_isosurface`, with its keys.
fn traced_mesh(
    chi: &Indicator,
    isovalue: f64,
    seeds: Vec<[i64; 3]>,
    traced: Range<i64>,
    on_isosurface: bool,
    with_normals: bool,
    watch: &Watch,
) -> Result<(RawMesh, Keyed)> {
    let tracing = Tracing {
        window: Some(traced),
        keyed: true,
    };
    let normals = !on_isosurface || with_normals;
    let (mut mesh, keyed) = extract_traced(chi, isovalue, seeds, normals, &tracing, watch)?;
    if !on_isosurface {
        fit_to_surface(&mut mesh, watch)?;
    }
    Ok((mesh, keyed))
}

/// The part of the traced `mesh` that the leaves in `owned` make, checking that no kept vertex
/// is within `clearance` edges of a vertex whose triangles are not all traced.
fn owned_part(
    mesh: &RawMesh,
    keyed: &Keyed,
    owned: Range<i64>,
    clearance: usize,
) -> Result<SlabPart> {
    let vertex_count = mesh.vertices.len();
    // Incomplete vertices: the ends of edges with one triangle only (the mesh over every leaf
    // is closed, so its edges have two), then spread `clearance` edges.
    let mut edges: KeyMap<u32> = KeyMap::default();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges
                .entry(u64::from(a.min(b)) << 32 | u64::from(a.max(b)))
                .or_default() += 1;
        }
    }
    let mut tainted = vec![false; vertex_count];
    for (&edge, &count) in &edges {
        if count != 2 {
            tainted[(edge >> 32) as usize] = true;
            tainted[(edge & 0xFFFF_FFFF) as usize] = true;
        }
    }
    for _ in 0..clearance {
        let mut spread = tainted.clone();
        for t in &mesh.triangles {
            if t.iter().any(|&v| tainted[v as usize]) {
                for &v in t {
                    spread[v as usize] = true;
                }
            }
        }
        tainted = spread;
    }

    let mut used_by = vec![0u8; vertex_count];
    for (t, &x) in mesh.triangles.iter().zip(&keyed.leaf_x) {
        let side = if x < owned.start {
            SHARED_BELOW
        } else if x >= owned.end {
            SHARED_ABOVE
        } else {
            continue;
        };
        for &v in t {
            used_by[v as usize] |= side;
        }
    }

    let mut part = SlabPart::default();
    let mut renumbered = vec![u32::MAX; vertex_count];
    for (t, &x) in mesh.triangles.iter().zip(&keyed.leaf_x) {
        if !owned.contains(&x) {
            continue;
        }
        let mut kept = [0u32; 3];
        for (k, &v) in t.iter().enumerate() {
            let v = v as usize;
            if renumbered[v] == u32::MAX {
                if tainted[v] {
                    return Err(Error::Internal(format!(
                        "slab {owned:?}: the traced window does not hold the neighbourhood of \
                         the vertex at {:?} (window too narrow, or surface not reached from \
                         the seeds)",
                        mesh.vertices[v]
                    )));
                }
                renumbered[v] = part.vertices.len() as u32;
                part.vertices.push(mesh.vertices[v]);
                if !mesh.normals.is_empty() {
                    part.normals.push(mesh.normals[v]);
                }
                part.keys.push(keyed.vertex[v]);
                part.shared.push(used_by[v]);
            }
            kept[k] = renumbered[v];
        }
        part.triangles.push(kept);
    }
    Ok(part)
}

/// The slabs' parts, in slab order, as one mesh: a vertex in several parts (same key) is the
/// first part's, and the others' triangles refer to it. Fails with [`Error::Internal`] when
/// two parts disagree on a shared vertex's position or normal (they are computed from the same
/// χ by the same code: a bug, or χ not the same on both sides of a wall).
#[cfg(test)]
pub(crate) fn weld(parts: &[SlabPart]) -> Result<RawMesh> {
    let mut mesh = RawMesh::default();
    let mut index: KeyMap<u32> = KeyMap::default();
    for (k, part) in parts.iter().enumerate() {
        let mut global = Vec::with_capacity(part.vertices.len());
        for (v, (&key, &position)) in part.keys.iter().zip(&part.vertices).enumerate() {
            let normal = part.normals.get(v).copied();
            let id = match index.get(&key) {
                Some(&id) => {
                    let same = |a: DVec3, b: DVec3| {
                        a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits)
                    };
                    let agrees = same(mesh.vertices[id as usize], position)
                        && normal.is_none_or(|n| same(mesh.normals[id as usize], n));
                    if !agrees {
                        return Err(Error::Internal(format!(
                            "slab {k}'s wall vertex {key:#x} at {position:?} is at {:?} in the \
                             slab below",
                            mesh.vertices[id as usize]
                        )));
                    }
                    id
                }
                None => {
                    let id = u32::try_from(mesh.vertices.len()).map_err(|_| Error::TooLarge {
                        what: "mesh vertices",
                        count: mesh.vertices.len() + 1,
                        limit: u32::MAX as usize,
                    })?;
                    index.insert(key, id);
                    mesh.vertices.push(position);
                    if let Some(n) = normal {
                        mesh.normals.push(n);
                    }
                    id
                }
            };
            global.push(id);
        }
        mesh.triangles
            .extend(part.triangles.iter().map(|t| t.map(|v| global[v as usize])));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::extract_around_samples;
    use crate::grid::cell_of;
    use crate::outofcore::tests::bumpy_sphere_chi;
    use std::collections::HashMap;
    use std::sync::OnceLock;

    /// The bumpy sphere's χ at depth 7, its isovalue and samples (built once for the tests).
    fn sphere() -> &'static (Indicator, f64, Vec<DVec3>) {
        static SPHERE: OnceLock<(Indicator, f64, Vec<DVec3>)> = OnceLock::new();
        SPHERE.get_or_init(|| bumpy_sphere_chi(&crate::Params::default().with_depth(7)))
    }

    /// The cells of every `stride`-th sample, those with x in `x`.
    fn seeds(chi: &Indicator, positions: &[DVec3], stride: usize, x: &Range<i64>) -> Vec<[i64; 3]> {
        let inv_h = (chi.tree.max_depth() as f64).exp2();
        positions
            .iter()
            .step_by(stride)
            .map(|&p| cell_of(p, inv_h).map(i64::from))
            .filter(|c| x.contains(&c[0]))
            .collect()
    }

    fn bits(v: DVec3) -> [u64; 3] {
        v.to_array().map(f64::to_bits)
    }

    /// A mesh up to the numbering of its vertices: its vertices (position and normal, as
    /// bits) sorted, and its triangles as their corners' positions, each rotated to start at
    /// its least corner (keeping its orientation), sorted.
    type Canonical = (Vec<([u64; 3], [u64; 3])>, Vec<[[u64; 3]; 3]>);
    fn canonical(mesh: &RawMesh) -> Canonical {
        let normal = |v: usize| mesh.normals.get(v).copied().map_or([0; 3], bits);
        let mut vertices: Vec<_> = (0..mesh.vertices.len())
            .map(|v| (bits(mesh.vertices[v]), normal(v)))
            .collect();
        vertices.sort_unstable();
        let mut triangles: Vec<[[u64; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let mut corners = t.map(|v| bits(mesh.vertices[v as usize]));
                let least = (0..3).min_by_key(|&k| corners[k]).expect("three corners");
                corners.rotate_left(least);
                corners
            })
            .collect();
        triangles.sort_unstable();
        (vertices, triangles)
    }

    /// Every directed edge is in one triangle and its reverse in another: each edge in exactly
    /// two triangles, consistently oriented; no vertex is used twice by a triangle or unused.
    fn assert_closed_and_manifold(mesh: &RawMesh) {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        let mut used = vec![false; mesh.vertices.len()];
        for t in &mesh.triangles {
            assert!(
                t[0] != t[1] && t[1] != t[2] && t[2] != t[0],
                "degenerate {t:?}"
            );
            for k in 0..3 {
                used[t[k] as usize] = true;
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &count) in &directed {
            assert_eq!(count, 1, "edge {a}→{b} in {count} triangles");
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}–{b} open");
        }
        assert!(used.iter().all(|&u| u), "unused vertices");
    }

    /// The slabs between `walls` (finest-grid x; the first and last beyond the cube), each
    /// traced from its own (every `stride`-th) samples' cells within its window, welded.
    fn welded(walls: &[i64], stride: usize, on_isosurface: bool) -> (RawMesh, Vec<SlabPart>) {
        let (chi, isovalue, positions) = sphere();
        let parts: Vec<SlabPart> = walls
            .windows(2)
            .map(|w| {
                let owned = w[0]..w[1];
                let m = margin(&chi.tree, &owned, !on_isosurface);
                let traced = owned.start - m..owned.end + m;
                let seeds = seeds(chi, positions, stride, &traced);
                slab_part(
                    chi,
                    *isovalue,
                    seeds,
                    owned,
                    traced,
                    on_isosurface,
                    false,
                    &Watch::new(),
                )
                .expect("the window holds the kept vertices' rings")
            })
            .collect();
        (weld(&parts).expect("the parts agree on their walls"), parts)
    }

    /// The in-memory mesh traced from every `stride`-th sample's cell: the pipeline's
    /// [`extract_around_samples`] for every sample, [`crate::extract::extract`] then
    /// [`fit_to_surface`] as it does for the others.
    fn in_memory(stride: usize, on_isosurface: bool) -> RawMesh {
        let (chi, isovalue, positions) = sphere();
        let watch = Watch::new();
        if stride == 1 {
            return extract_around_samples(chi, *isovalue, positions, on_isosurface, false, &watch)
                .expect("extracted");
        }
        let n = 1i64 << chi.tree.max_depth();
        let seeds = seeds(chi, positions, stride, &(-n..2 * n));
        let mut mesh = crate::extract::extract(chi, *isovalue, seeds, !on_isosurface, &watch)
            .expect("extracted");
        if !on_isosurface {
            fit_to_surface(&mut mesh, &watch).expect("not cancelled");
        }
        mesh
    }

    /// Proves the slabs' parts welded are the in-memory mesh exactly: the same vertices and
    /// normals bit for bit, the same triangles, closed and manifold, for 1, 3 and 5 slabs
    /// with walls through the middle, at odd places, and where the surface is nearly tangent
    /// to the wall's plane (just inside its least and greatest x), fitted and on the level set;
    /// and that the wall vertices, and only they, are in two parts and marked so. From every
    /// sample's cell (nearly every leaf of the surface holds one: the trace order is the seeds'
    /// order in memory and in the slabs alike) and from every 997th (most leaves are reached
    /// leaf to leaf, in an order that differs between the slabs and the whole: with the fit's
    /// sums in f64 the vertices differed in their last bits there).
    #[test]
    fn the_slabs_parts_welded_are_the_in_memory_mesh() {
        let (chi, _, _) = sphere();
        let n = 1i64 << chi.tree.max_depth();
        for (stride, on_isosurface) in [(1, false), (1, true), (997, false), (997, true)] {
            let whole = in_memory(stride, on_isosurface);
            assert_closed_and_manifold(&whole);
            let xs = whole.vertices.iter().map(|v| v.x * n as f64);
            let least = xs.clone().fold(f64::INFINITY, f64::min);
            let greatest = xs.fold(f64::NEG_INFINITY, f64::max);
            // Tangent-ish: the first grid plane inside the surface's extent at each end.
            let (low, high) = (least.floor() as i64 + 1, greatest.ceil() as i64 - 1);
            let reference = canonical(&whole);
            for walls in [
                vec![-n, 2 * n],
                vec![-n, low, n / 2 + 3, 2 * n],
                vec![-n, low, n / 2 - 11, n / 2, n / 2 + 17, high, 2 * n],
            ] {
                let (mesh, parts) = welded(&walls, stride, on_isosurface);
                let what = format!(
                    "walls {walls:?}, every {stride}th sample, on the level set {on_isosurface}"
                );
                assert_eq!(mesh.vertices.len(), whole.vertices.len(), "{what}");
                assert_eq!(mesh.triangles.len(), whole.triangles.len(), "{what}");
                assert!(canonical(&mesh) == reference, "{what}: the meshes differ");
                assert_closed_and_manifold(&mesh);
                // A key in two parts is marked on both sides, and only such keys are marked.
                let mut holders: HashMap<u64, Vec<usize>> = HashMap::new();
                for (k, part) in parts.iter().enumerate() {
                    for &key in &part.keys {
                        holders.entry(key).or_default().push(k);
                    }
                }
                let mut on_walls = 0;
                for (k, part) in parts.iter().enumerate() {
                    for (&key, &shared) in part.keys.iter().zip(&part.shared) {
                        let slabs = &holders[&key];
                        let below = slabs.iter().any(|&j| j < k);
                        let above = slabs.iter().any(|&j| j > k);
                        let expected = if below { SHARED_BELOW } else { 0 }
                            | if above { SHARED_ABOVE } else { 0 };
                        assert_eq!(shared, expected, "{what}: slab {k}, key {key:#x}");
                        on_walls += usize::from(shared != 0);
                    }
                }
                assert_eq!(on_walls > 0, walls.len() > 2, "{what}: wall vertices");
            }
        }
    }

    /// Proves the margin is needed: traced over its owned range only, a slab fits some of its
    /// vertices next to its walls differently from the whole mesh (and `slab_part` refuses
    /// that window), while with the margin every vertex is the whole mesh's.
    #[test]
    fn without_the_margin_the_fit_differs_next_to_the_walls() {
        let (chi, isovalue, positions) = sphere();
        let n = 1i64 << chi.tree.max_depth();
        let all = seeds(chi, positions, 1, &(-n..2 * n));
        let (whole, whole_keys) =
            traced_mesh(chi, *isovalue, all, -n..2 * n, false, false, &Watch::new())
                .expect("extracted");
        let by_key: HashMap<u64, DVec3> = whole_keys
            .vertex
            .iter()
            .copied()
            .zip(whole.vertices.iter().copied())
            .collect();
        let walls = [-n, n / 2 - 11, n / 2 + 17, 2 * n];
        let mut differ = std::collections::HashSet::new();
        for w in walls.windows(2) {
            let owned = w[0]..w[1];
            let narrow = seeds(chi, positions, 1, &owned);
            let (mesh, keyed) = traced_mesh(
                chi,
                *isovalue,
                narrow.clone(),
                owned.clone(),
                false,
                false,
                &Watch::new(),
            )
            .expect("extracted");
            // The vertices of the owned leaves' triangles, unchecked.
            for (t, &x) in mesh.triangles.iter().zip(&keyed.leaf_x) {
                if owned.contains(&x) {
                    for &v in t {
                        let v = v as usize;
                        if by_key[&keyed.vertex[v]] != mesh.vertices[v] {
                            differ.insert(keyed.vertex[v]);
                        }
                    }
                }
            }
            let refused = slab_part(
                chi,
                *isovalue,
                narrow,
                owned.clone(),
                owned.clone(),
                false,
                false,
                &Watch::new(),
            );
            assert!(
                matches!(refused, Err(Error::Internal(_))),
                "slab {owned:?} without margin"
            );
        }

        assert!(!differ.is_empty(), "some vertices next to the walls move");
    }

    /// Proves a slab's part does not depend on the thread count: the same vertices (bits),
    /// keys, triangles and wall marks with one thread and with three.
    #[test]
    fn a_slabs_part_is_the_same_on_any_number_of_threads() {
        let (chi, isovalue, positions) = sphere();
        let n = 1i64 << chi.tree.max_depth();
        let owned = n / 2 - 11..n / 2 + 17;
        let m = margin(&chi.tree, &owned, true);
        let traced = owned.start - m..owned.end + m;
        let part = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            pool.install(|| {
                let seeds = seeds(chi, positions, 997, &traced);
                let part = slab_part(
                    chi,
                    *isovalue,
                    seeds,
                    owned.clone(),
                    traced.clone(),
                    false,
                    true,
                    &Watch::new(),
                )
                .expect("extracted");
                let vertices: Vec<_> = part.vertices.iter().map(|&v| bits(v)).collect();
                let normals: Vec<_> = part.normals.iter().map(|&v| bits(v)).collect();
                (vertices, normals, part.keys, part.triangles, part.shared)
            })
        };
        let one = part(1);
        assert!(!one.3.is_empty());
        assert!(one == part(3));
    }
}

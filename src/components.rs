//! Between stages 8 and 9 — the surface's pieces that the samples support.
//!
//! {χ = γ} may have, besides the surface the samples describe, a few tiny closed pieces
//! ("bubbles") beside it: a level set of a smooth function crosses γ wherever the function
//! wiggles around it, and χ wiggles near stray samples (a sample off the surface splats its
//! normal and is screened towards γ) and where overlapping scans disagree by a few cells. The
//! density stage already reads sparse and stray samples at the coarser depth where they have
//! neighbours, which removes most of them (and the bumps) at the cause; what remains on the
//! shared scans are pieces of 8 to a few hundred triangles around zero to a dozen samples
//! (Happy Buddha depth 11: nine, bunny depth 11: one, with none of its own samples).
//!
//! A piece of surface is *supported* by the samples within one cell of its vertices, the cell
//! being the surface's own resolution there: the finest cell, or the piece's mean edge length
//! where it was traced in coarser leaves (sparse samples are read at a coarser depth, and the
//! surface there has coarser triangles, whose vertices lie farther from the samples). Every
//! connected component of the mesh but the largest is kept only when at least
//! [`crate::Params::min_component_samples`] samples support it (default 8): the density
//! estimate calls a node sampled when it holds `samples_per_node` (1.5) samples, and the
//! smallest closed surface extraction makes, around one grid corner, crosses the 2 × 2 × 2 cells
//! at that corner, about 8 nodes' worth of surface; fewer samples cannot define a closed surface
//! by the estimate's own measure. The rule is on samples, not on size: a small real part of
//! the scan (a detached fragment, a pebble) carries its own samples and stays whatever its
//! size, and a large piece that no sample supports goes (Happy Buddha at depth 11: a
//! 574-triangle piece 10 cells off the body with edges 4.8 cells long has 77 samples within
//! that distance, 3.3 cells apart, with normals agreeing with its own: it stays). The largest
//! component always stays, so the output is never emptied. Components are whole closed
//! surfaces, so removing some keeps the mesh closed and manifold.
//!
//! Cost: a union-find over the triangles (bunny depth 10, one component: 0.06 s of a 23 s
//! run); when there are other components, their vertices (at most 64 of each at first: a
//! large one, another object of the scene, is rarely short of support) in a hash grid and one
//! probe per sample (Happy Buddha depth 10, three components: 0.37 s of 55 s; both on a loaded
//! 2-core machine, `docs/benchmarks.md`).

use crate::error::Result;
use crate::extract::RawMesh;
use crate::grid::KeyMap;
use crate::parallel::Watch;
use glam::DVec3;
use rayon::prelude::*;

/// What [`drop_unsupported`] removed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Removed {
    /// Connected components removed.
    pub components: usize,
    /// Their triangles.
    pub triangles: usize,
}

/// Removes from `mesh` (unit-cube coordinates, extracted on a tree of depth `finest_depth`)
/// every connected component but the largest that fewer than `min_samples` of the `samples`
/// (unit-cube coordinates) support, as the module documentation defines it. `min_samples` 0
/// keeps all.
pub(crate) fn drop_unsupported(
    mesh: &mut RawMesh,
    finest_depth: u32,
    samples: &[DVec3],
    min_samples: u32,
    watch: &Watch,
) -> Result<Removed> {
    if min_samples == 0 || mesh.triangles.is_empty() {
        return Ok(Removed::default());
    }
    // Cancel points (`watch`) between the passes, each at most a few tenths of a second on
    // millions of triangles.
    let component = vertex_components(mesh.vertices.len(), &mesh.triangles);
    watch.check()?;
    // Triangles per component (indexed by the component's root vertex).
    let mut triangles_of = vec![0usize; mesh.vertices.len()];
    for t in &mesh.triangles {
        triangles_of[component[t[0] as usize] as usize] += 1;
    }
    // The largest; among equals the one with the lowest root, so the choice is deterministic.
    let largest = (0..triangles_of.len())
        .max_by_key(|&r| (triangles_of[r], std::cmp::Reverse(r)))
        .expect("a mesh with triangles has vertices") as u32;
    if triangles_of[largest as usize] == mesh.triangles.len() {
        return Ok(Removed::default());
    }
    watch.check()?;

    // Each other component's radius: one cell at the surface's own resolution there, the
    // finest cell or, where the component was traced in coarser leaves (sparse samples are
    // read at a coarser depth), its mean edge length.
    let finest_cell = (-(finest_depth as f64)).exp2();
    let mut edge_sum: KeyMap<f64> = KeyMap::default();
    for t in &mesh.triangles {
        let root = component[t[0] as usize];
        if root != largest {
            let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
            *edge_sum.entry(root as u64).or_default() +=
                a.distance(b) + b.distance(c) + c.distance(a);
        }
    }
    let radius: KeyMap<f64> = edge_sum
        .iter()
        .map(|(&root, &sum)| {
            let mean_edge = sum / (3 * triangles_of[root as usize]) as f64;
            (root, finest_cell.max(mean_edge))
        })
        .collect();

    // The samples within that radius of each other component's vertices. A large component
    // (another object of the scene) is first probed through an even subset of its vertices:
    // the samples near them are a lower bound of its support, and usually enough, so its
    // whole vertex list is never bucketed; only components still short of `min_samples` are
    // probed again with every vertex.
    let mut vertices_of: KeyMap<Vec<u32>> = KeyMap::default();
    for (v, &root) in component.iter().enumerate() {
        if root != largest && triangles_of[root as usize] > 0 {
            vertices_of.entry(root as u64).or_default().push(v as u32);
        }
    }
    let mut probe: Vec<u32> = vertices_of
        .values()
        .flat_map(|list| {
            let step = list.len().div_ceil(PROBE_VERTICES);
            list.iter().step_by(step).copied()
        })
        .collect();
    probe.sort_unstable();
    watch.check()?;
    let mut support = samples_near(&probe, &component, &radius, mesh, samples, finest_cell);
    watch.check()?;
    let mut again: Vec<u32> = vertices_of
        .iter()
        .filter(|(root, list)| {
            list.len() > PROBE_VERTICES
                && support.get(root).copied().unwrap_or(0) < min_samples as u64
        })
        .flat_map(|(_, list)| list.iter().copied())
        .collect();
    if !again.is_empty() {
        again.sort_unstable();
        support.extend(samples_near(
            &again,
            &component,
            &radius,
            mesh,
            samples,
            finest_cell,
        ));
        watch.check()?;
    }

    // The verdict.
    let keep_root = |root: u32| {
        root == largest || support.get(&(root as u64)).copied().unwrap_or(0) >= min_samples as u64
    };
    let mut removed = Removed::default();
    for (root, &count) in triangles_of.iter().enumerate() {
        if count > 0 && !keep_root(root as u32) {
            removed.components += 1;
            removed.triangles += count;
        }
    }
    if removed.components == 0 {
        return Ok(removed);
    }

    // The kept vertices, renumbered in their order (a new index is never above the old one).
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    let mut next = 0u32;
    for (v, slot) in new_index.iter_mut().enumerate() {
        if keep_root(component[v]) {
            *slot = next;
            next += 1;
        }
    }
    let kept = |v: &usize| new_index[*v] != u32::MAX;
    let vertices = (0..mesh.vertices.len())
        .filter(kept)
        .map(|v| mesh.vertices[v])
        .collect();
    let normals = if mesh.normals.is_empty() {
        Vec::new()
    } else {
        (0..mesh.normals.len())
            .filter(kept)
            .map(|v| mesh.normals[v])
            .collect()
    };
    mesh.triangles
        .retain(|t| new_index[t[0] as usize] != u32::MAX);
    for t in &mut mesh.triangles {
        *t = t.map(|v| new_index[v as usize]);
    }
    mesh.vertices = vertices;
    mesh.normals = normals;
    Ok(removed)
}

/// Vertices of a component probed in a first pass (see [`drop_unsupported`]).
const PROBE_VERTICES: usize = 64;

/// For the components of the `vertices` listed, the number of `samples` within their radius of
/// one of those vertices (per component root). The vertices go into a grid of buckets as wide
/// as the largest radius, each listed in the 27 buckets around its own: a sample then looks in
/// its own bucket only, and finds every listed vertex within that radius of it.
fn samples_near(
    vertices: &[u32],
    component: &[u32],
    radius: &KeyMap<f64>,
    mesh: &RawMesh,
    samples: &[DVec3],
    finest_cell: f64,
) -> KeyMap<u64> {
    let radius_of = |v: u32| radius[&(component[v as usize] as u64)];
    let bucket = vertices
        .iter()
        .fold(finest_cell, |a, &v| a.max(radius_of(v)));
    let bucket_of = |p: DVec3| -> [i64; 3] {
        let c = (p / bucket).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    };
    // Buckets are at least a finest cell wide and the points within a cell of the unit cube:
    // coordinates from -2 to 2^16 + 1, 21 bits per axis after the offset.
    let key = |c: [i64; 3]| -> u64 {
        let packed = c.map(|v| (v + 4) as u64 & 0x1f_ffff);
        packed[0] << 42 | packed[1] << 21 | packed[2]
    };
    let mut near: KeyMap<Vec<u32>> = KeyMap::default();
    for &v in vertices {
        let c = bucket_of(mesh.vertices[v as usize]);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    near.entry(key([c[0] + dx, c[1] + dy, c[2] + dz]))
                        .or_default()
                        .push(v);
                }
            }
        }
    }
    let near = &near;
    let supports: Vec<u32> = samples
        .par_iter()
        .flat_map_iter(|&p| {
            let mut roots: Vec<u32> = Vec::new();
            if let Some(listed) = near.get(&key(bucket_of(p))) {
                for &v in listed {
                    let r = radius_of(v);
                    if p.distance_squared(mesh.vertices[v as usize]) <= r * r {
                        roots.push(component[v as usize]);
                    }
                }
                roots.sort_unstable();
                roots.dedup();
            }
            roots
        })
        .collect();
    let mut support: KeyMap<u64> = KeyMap::default();
    for root in supports {
        *support.entry(root as u64).or_default() += 1;
    }
    support
}

/// The connected components of a mesh by shared vertices: for each vertex, the lowest vertex
/// index of its component (a union-find that always links the higher root under the lower).
/// Also [`crate::trim`]'s pieces.
pub(crate) fn vertex_components(vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    for t in triangles {
        for &b in &t[1..] {
            let (ra, rb) = (root(&mut parent, t[0]), root(&mut parent, b));
            if ra != rb {
                let (low, high) = (ra.min(rb), ra.max(rb));
                parent[high as usize] = low;
            }
        }
    }
    (0..vertex_count as u32)
        .map(|v| root(&mut parent, v))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_are_labelled_by_their_lowest_vertex() {
        // Two triangles sharing an edge, a lone triangle, and a vertex in no triangle.
        let triangles = [[3, 1, 2], [2, 1, 0], [6, 5, 4]];
        assert_eq!(
            vertex_components(8, &triangles),
            vec![0, 0, 0, 0, 4, 4, 4, 7]
        );
    }
}

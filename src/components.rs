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
//! A piece of surface is *supported* by the samples that lie in the octree leaves it crosses:
//! the leaves are the extraction's own cells, as fine as the samples there, so the rule means
//! "samples within a cell of the piece" at the resolution the surface has at that place. Every
//! connected component of the mesh but the largest is kept only when at least
//! [`crate::Params::min_component_samples`] samples support it (default 8): the density
//! estimate calls a node sampled when it holds `samples_per_node` (1.5) samples, and the
//! smallest closed surface extraction makes, around one grid corner, crosses the 2 × 2 × 2 cells
//! at that corner, about 8 nodes' worth of surface; fewer samples cannot define a closed surface
//! by the estimate's own measure. The rule is on samples, not on size: a small real part of
//! the scan (a detached fragment, a pebble) carries its own samples and stays whatever its
//! size, and a large piece that no sample supports goes. The largest component always stays,
//! so the output is never emptied. Components are whole closed surfaces, so removing some
//! keeps the mesh closed and manifold.
//!
//! Cost: a union-find over the triangles; only when the mesh has more than one component, a
//! leaf look-up per triangle of the smaller ones and one hash probe per sample and leaf depth.

use crate::extract::{leaf_at, RawMesh};
use crate::grid::KeyMap;
use crate::octree::Octree;
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

/// Removes from `mesh` (unit-cube coordinates, extracted on `tree`'s leaves) every connected
/// component but the largest that fewer than `min_samples` of the `samples` (unit-cube
/// coordinates) support, as the module documentation defines it. `min_samples` 0 keeps all.
pub(crate) fn drop_unsupported(
    mesh: &mut RawMesh,
    tree: &Octree,
    samples: &[DVec3],
    min_samples: u32,
) -> Removed {
    if min_samples == 0 || mesh.triangles.is_empty() {
        return Removed::default();
    }
    let component = vertex_components(mesh.vertices.len(), &mesh.triangles);
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
        return Removed::default();
    }

    // The leaves the other components cross: the leaf of each triangle's centroid (a triangle
    // lies in the leaf that traced it; fitting moves its vertices by a fraction of an edge).
    let mut crossed: Vec<(u32, [i64; 3], u32)> = mesh
        .triangles
        .par_iter()
        .filter_map(|t| {
            let root = component[t[0] as usize];
            if root == largest {
                return None;
            }
            let centroid = t.iter().map(|&v| mesh.vertices[v as usize]).sum::<DVec3>() / 3.0;
            leaf_at(tree, centroid).map(|(depth, cell)| (depth, cell, root))
        })
        .collect();
    crossed.par_sort_unstable();
    crossed.dedup();

    // The samples in those leaves: a sample lies in the leaf of depth d whose cell is its own
    // cell at depth d, so one probe per depth among the crossed leaves' depths finds it.
    let finest = tree.max_depth();
    let depths: Vec<u32> = {
        let mut d: Vec<u32> = crossed.iter().map(|&(d, _, _)| d).collect();
        d.dedup();
        d
    };
    let key = |depth: u32, cell: [i64; 3]| -> u64 {
        // A leaf's cell is within -1..=2^depth and depth ≤ 16 (MAX_DEPTH): 19 bits per axis
        // and 5 for the depth.
        let packed = cell.map(|v| (v + 1) as u64 & 0x7_ffff);
        (depth as u64) << 57 | packed[0] << 38 | packed[1] << 19 | packed[2]
    };
    let wanted: KeyMap<()> = crossed.iter().map(|&(d, c, _)| (key(d, c), ())).collect();
    // The finest cells those leaves cover, as a box: samples outside it are skipped at once.
    let (mut low, mut high) = ([i64::MAX; 3], [i64::MIN; 3]);
    for &(d, c, _) in &crossed {
        let shift = finest - d;
        for a in 0..3 {
            low[a] = low[a].min(c[a] << shift);
            high[a] = high[a].max(((c[a] + 1) << shift) - 1);
        }
    }
    let inv_h = (finest as f64).exp2();
    let (depths, wanted) = (&depths, &wanted);
    let found: Vec<u64> = samples
        .par_iter()
        .flat_map_iter(|&p| {
            let cell = (p * inv_h).floor();
            let cell = [cell.x as i64, cell.y as i64, cell.z as i64];
            let inside = (0..3).all(|a| (low[a]..=high[a]).contains(&cell[a]));
            depths.iter().filter(move |_| inside).filter_map(move |&d| {
                let k = key(d, cell.map(|v| v >> (finest - d)));
                wanted.contains_key(&k).then_some(k)
            })
        })
        .collect();
    let mut samples_in: KeyMap<u32> = KeyMap::default();
    for k in found {
        *samples_in.entry(k).or_default() += 1;
    }

    // Each component's support, and the verdict.
    let mut support: KeyMap<u64> = KeyMap::default();
    for &(d, c, root) in &crossed {
        let n = samples_in.get(&key(d, c)).copied().unwrap_or(0);
        *support.entry(root as u64).or_default() += n as u64;
    }
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
        return removed;
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
    removed
}

/// The connected components of a mesh by shared vertices: for each vertex, the lowest vertex
/// index of its component (a union-find that always links the higher root under the lower).
fn vertex_components(vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
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

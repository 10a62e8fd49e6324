//! Combinatorial and volumetric facts about a triangle mesh.

use crate::point::v3;
use std::fmt;

/// Combinatorial facts about a triangle mesh; build with [`MeshTopology::of`].
///
/// Triangles with an index out of range or a repeated index are not simplices: they are counted
/// in `invalid_triangles` and left out of everything else (edges, vertices, components, Euler).
/// Edges are undirected vertex pairs; a triangle (a, b, c) uses a→b, b→c, c→a.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeshTopology {
    /// Vertices referenced by at least one valid triangle (V of the Euler characteristic).
    pub vertices: usize,
    /// Vertices of the positions array no valid triangle uses.
    pub unreferenced_vertices: usize,
    /// Distinct undirected edges (E).
    pub edges: usize,
    /// Valid triangles (F).
    pub faces: usize,
    /// Triangles with an out-of-range or repeated index.
    pub invalid_triangles: usize,
    /// Edges used by exactly one triangle.
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Edges used by exactly two triangles in the same direction (neighbours with opposite
    /// orientation).
    pub misoriented_edges: usize,
    /// Vertices whose incident triangles form more than one fan (edge-connected group around the
    /// vertex), e.g. two cones touching at their apex.
    pub non_manifold_vertices: usize,
    /// Connected components, triangles joined by shared vertices.
    pub components: usize,
    /// Triangles per component, largest first.
    pub component_faces: Vec<usize>,
    /// Euler characteristic V − E + F over referenced vertices and valid triangles.
    pub euler: i64,
    /// Vertices whose position is bitwise equal to an earlier vertex's (over all vertices):
    /// vertex count minus distinct positions.
    pub duplicate_vertices: usize,
    /// Valid triangles whose area (computed in f64) is exactly zero.
    pub degenerate_triangles: usize,
}

/// Union–find with path halving; roots are the smallest index of their set.
struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }
}

/// The connected component of each of `vertex_count` vertices, joined by the triangles' edges:
/// the smallest vertex index of its component (a vertex no triangle uses is its own).
pub fn vertex_components(vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut sets = UnionFind::new(vertex_count);
    for t in triangles {
        sets.union(t[0], t[1]);
        sets.union(t[0], t[2]);
    }
    (0..vertex_count as u32).map(|v| sets.find(v)).collect()
}

impl MeshTopology {
    /// Analyses the mesh given by `positions` and `triangles`.
    pub fn of(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let nv = positions.len();
        let valid: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .filter(|t| {
                t.iter().all(|&i| (i as usize) < nv) && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
            })
            .collect();
        let invalid_triangles = triangles.len() - valid.len();

        let mut referenced = vec![false; nv];
        for t in &valid {
            for &i in t {
                referenced[i as usize] = true;
            }
        }
        let vertices = referenced.iter().filter(|&&r| r).count();

        // Edges: sort (undirected key, direction) pairs and read off each edge's uses.
        let mut half_edges: Vec<(u64, bool)> = Vec::with_capacity(3 * valid.len());
        for t in &valid {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (lo, hi, forward) = if a < b { (a, b, true) } else { (b, a, false) };
                half_edges.push((((lo as u64) << 32) | hi as u64, forward));
            }
        }
        half_edges.sort_unstable();
        let (mut edges, mut boundary_edges, mut non_manifold_edges, mut misoriented_edges) =
            (0, 0, 0, 0);
        let mut i = 0;
        while i < half_edges.len() {
            let key = half_edges[i].0;
            let mut j = i;
            let mut forward = 0;
            while j < half_edges.len() && half_edges[j].0 == key {
                forward += half_edges[j].1 as usize;
                j += 1;
            }
            let uses = j - i;
            edges += 1;
            match uses {
                1 => boundary_edges += 1,
                2 if forward != 1 => misoriented_edges += 1,
                2 => {}
                _ => non_manifold_edges += 1,
            }
            i = j;
        }

        // Fans: per vertex, join incident triangles that share a spoke (an edge at the vertex).
        let mut start = vec![0usize; nv + 1];
        for t in &valid {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..nv {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        // For each corner: the two other vertices of its triangle.
        let mut corners = vec![[0u32; 2]; 3 * valid.len()];
        for t in &valid {
            for k in 0..3 {
                let v = t[k] as usize;
                corners[fill[v]] = [t[(k + 1) % 3], t[(k + 2) % 3]];
                fill[v] += 1;
            }
        }
        let mut non_manifold_vertices = 0;
        let mut spokes: Vec<(u32, u32)> = Vec::new();
        let mut local = UnionFind::new(0);
        for v in 0..nv {
            let around = &corners[start[v]..start[v + 1]];
            if around.len() < 2 {
                continue;
            }
            spokes.clear();
            for (c, others) in around.iter().enumerate() {
                spokes.push((others[0], c as u32));
                spokes.push((others[1], c as u32));
            }
            spokes.sort_unstable();
            local.parent.clear();
            local.parent.extend(0..around.len() as u32);
            for pair in spokes.windows(2) {
                if pair[0].0 == pair[1].0 {
                    local.union(pair[0].1, pair[1].1);
                }
            }
            let fans = (0..around.len() as u32)
                .filter(|&c| local.find(c) == c)
                .count();
            if fans > 1 {
                non_manifold_vertices += 1;
            }
        }

        // Components by shared vertices.
        let mut uf = UnionFind::new(nv);
        for t in &valid {
            uf.union(t[0], t[1]);
            uf.union(t[1], t[2]);
        }
        let mut faces_at_root = vec![0usize; nv];
        for t in &valid {
            let r = uf.find(t[0]);
            faces_at_root[r as usize] += 1;
        }
        let mut component_faces: Vec<usize> =
            faces_at_root.into_iter().filter(|&f| f > 0).collect();
        component_faces.sort_unstable_by(|a, b| b.cmp(a));

        let mut keys: Vec<[u32; 3]> = positions.iter().map(|p| p.map(f32::to_bits)).collect();
        keys.sort_unstable();
        keys.dedup();
        let duplicate_vertices = nv - keys.len();

        let degenerate_triangles = valid
            .iter()
            .filter(|t| {
                triangle_area(
                    positions[t[0] as usize],
                    positions[t[1] as usize],
                    positions[t[2] as usize],
                ) == 0.0
            })
            .count();

        MeshTopology {
            vertices,
            unreferenced_vertices: nv - vertices,
            edges,
            faces: valid.len(),
            invalid_triangles,
            boundary_edges,
            non_manifold_edges,
            misoriented_edges,
            non_manifold_vertices,
            components: component_faces.len(),
            component_faces,
            euler: vertices as i64 - edges as i64 + valid.len() as i64,
            duplicate_vertices,
            degenerate_triangles,
        }
    }

    /// A closed 2-manifold: at least one triangle, no invalid triangles, every edge used by
    /// exactly two triangles, every vertex a single fan. Says nothing about orientation (see
    /// [`Self::is_consistently_oriented`]) or geometry (degenerate triangles, duplicates).
    pub fn is_closed_manifold(&self) -> bool {
        self.faces > 0
            && self.invalid_triangles == 0
            && self.boundary_edges == 0
            && self.non_manifold_edges == 0
            && self.non_manifold_vertices == 0
    }

    /// Every edge shared by two triangles is traversed once in each direction.
    pub fn is_consistently_oriented(&self) -> bool {
        self.misoriented_edges == 0
    }

    /// For a connected, closed, orientable mesh: the genus (2 − χ) / 2 (sphere 0, torus 1).
    pub fn genus(&self) -> Option<i64> {
        let ok =
            self.components == 1 && self.is_closed_manifold() && self.is_consistently_oriented();
        (ok && (2 - self.euler) % 2 == 0).then(|| (2 - self.euler) / 2)
    }
}

impl fmt::Display for MeshTopology {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "V={} E={} F={} χ={} components={} boundary_edges={} non_manifold_edges={} \
             non_manifold_vertices={} misoriented_edges={} invalid_triangles={} \
             degenerate_triangles={} duplicate_vertices={} unreferenced_vertices={}",
            self.vertices,
            self.edges,
            self.faces,
            self.euler,
            self.components,
            self.boundary_edges,
            self.non_manifold_edges,
            self.non_manifold_vertices,
            self.misoriented_edges,
            self.invalid_triangles,
            self.degenerate_triangles,
            self.duplicate_vertices,
            self.unreferenced_vertices
        )
    }
}

/// Area of the triangle (a, b, c), in f64.
fn triangle_area(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f64 {
    let (a, b, c) = (v3(a), v3(b), v3(c));
    0.5 * (b - a).cross(c - a).length()
}

/// Signed volume enclosed by the mesh, Σ a·(b×c) / 6 over its triangles: positive when a closed
/// mesh's triangles are counter-clockwise seen from outside. Triangles with out-of-range indices
/// are skipped.
pub fn signed_volume(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    let get = |i: u32| positions.get(i as usize).copied().map(v3);
    triangles
        .iter()
        .filter_map(|t| Some(get(t[0])?.dot(get(t[1])?.cross(get(t[2])?))))
        .sum::<f64>()
        / 6.0
}

/// Total area of the mesh's triangles (out-of-range triangles skipped).
pub fn surface_area(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    let get = |i: u32| positions.get(i as usize).copied();
    triangles
        .iter()
        .filter_map(|t| Some(triangle_area(get(t[0])?, get(t[1])?, get(t[2])?)))
        .sum()
}

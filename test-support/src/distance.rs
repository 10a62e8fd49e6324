//! Distances to a triangle mesh: exact point–triangle distances, a BVH, mesh sampling, the
//! Chamfer distance to a known surface and one-sided distance statistics.

use crate::point::{v3, AsPoint};
use crate::Rng;
use glam::DVec3;
use rayon::prelude::*;
use std::fmt;

// ---------------------------------------------------------------------------------------------
// Exact point–triangle distance and a BVH over a mesh
// ---------------------------------------------------------------------------------------------

fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let n = (b - a).cross(c - a);
    let n2 = n.length_squared();
    let scale = (b - a).length_squared() * (c - a).length_squared();
    if n2 > 1e-24 * scale {
        // The projection of p lies inside the triangle iff p is on the inner side of the three
        // planes through the edges that contain n (the sign of ((e × (p − start)) · n)).
        let inside = (b - a).cross(p - a).dot(n) >= 0.0
            && (c - b).cross(p - b).dot(n) >= 0.0
            && (a - c).cross(p - c).dot(n) >= 0.0;
        if inside {
            return p - n * ((p - a).dot(n) / n2);
        }
    }
    // Otherwise the nearest point is on the boundary (also for needle and point triangles).
    let candidates = [
        closest_on_segment(p, a, b),
        closest_on_segment(p, b, c),
        closest_on_segment(p, c, a),
    ];
    let mut best = candidates[0];
    for q in &candidates[1..] {
        if (*q - p).length_squared() < (best - p).length_squared() {
            best = *q;
        }
    }
    best
}

/// The point of the (closed, solid) triangle (a, b, c) nearest to `p`. Exact up to rounding;
/// degenerate triangles (segments, points) are handled.
pub fn closest_point_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let f = DVec3::from_array;
    closest_on_triangle(f(p), f(a), f(b), f(c)).to_array()
}

/// Euclidean distance from `p` to the triangle (a, b, c).
pub fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let q = closest_point_on_triangle(p, a, b, c);
    (DVec3::from_array(q) - DVec3::from_array(p)).length()
}

/// The answer to a closest-point query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Distance to the mesh (∞ for a mesh without triangles).
    pub distance: f64,
    /// The nearest point on the mesh.
    pub point: [f64; 3],
    /// Index (into the input triangles) of a triangle containing `point`.
    pub triangle: usize,
}

#[derive(Debug, Clone, Copy)]
struct BvhNode {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first index into `order`; inner: index of the left child (right = left + 1).
    first: u32,
    /// Leaf: number of triangles (> 0); inner: 0.
    count: u32,
}

const BVH_LEAF: usize = 4;

fn box_distance2(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

/// Exact closest-point queries against a triangle mesh, accelerated by a bounding-volume
/// hierarchy (median split of triangle centroids along the longest axis, 4 triangles per leaf,
/// branch-and-bound search nearest box first). Triangles with out-of-range indices are ignored.
pub struct MeshDistance {
    triangles: Vec<[DVec3; 3]>,
    /// Input index of each stored triangle.
    source: Vec<usize>,
    order: Vec<u32>,
    nodes: Vec<BvhNode>,
}

impl MeshDistance {
    pub fn new(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let mut tris = Vec::with_capacity(triangles.len());
        let mut source = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            if t.iter().all(|&k| (k as usize) < positions.len()) {
                tris.push(t.map(|k| v3(positions[k as usize])));
                source.push(i);
            }
        }
        let mut bvh = MeshDistance {
            order: (0..tris.len() as u32).collect(),
            triangles: tris,
            source,
            nodes: Vec::new(),
        };
        if !bvh.triangles.is_empty() {
            let centroids: Vec<DVec3> = bvh
                .triangles
                .iter()
                .map(|t| (t[0] + t[1] + t[2]) / 3.0)
                .collect();
            bvh.nodes.push(BvhNode {
                lo: DVec3::ZERO,
                hi: DVec3::ZERO,
                first: 0,
                count: 0,
            });
            bvh.build(0, 0, bvh.triangles.len(), &centroids);
        }
        bvh
    }

    fn build(&mut self, node: usize, start: usize, end: usize, centroids: &[DVec3]) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut clo = lo;
        let mut chi = hi;
        for &t in &self.order[start..end] {
            for v in self.triangles[t as usize] {
                lo = lo.min(v);
                hi = hi.max(v);
            }
            clo = clo.min(centroids[t as usize]);
            chi = chi.max(centroids[t as usize]);
        }
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        if end - start <= BVH_LEAF {
            self.nodes[node].first = start as u32;
            self.nodes[node].count = (end - start) as u32;
            return;
        }
        let extent = chi - clo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = (start + end) / 2;
        self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centroids[a as usize][axis]
                .total_cmp(&centroids[b as usize][axis])
                .then(a.cmp(&b))
        });
        let left = self.nodes.len();
        let blank = BvhNode {
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
            first: 0,
            count: 0,
        };
        self.nodes.push(blank);
        self.nodes.push(blank);
        self.nodes[node].first = left as u32;
        self.nodes[node].count = 0;
        self.build(left, start, mid, centroids);
        self.build(left + 1, mid, end, centroids);
    }

    /// Number of triangles indexed.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when there is no triangle to measure against.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The nearest point of the mesh to `p`.
    pub fn closest(&self, p: [f64; 3]) -> Closest {
        let p = DVec3::from_array(p);
        let mut best = Closest {
            distance: f64::INFINITY,
            point: [f64::NAN; 3],
            triangle: usize::MAX,
        };
        if self.nodes.is_empty() {
            return best;
        }
        let mut best2 = f64::INFINITY;
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, box_distance2(p, self.nodes[0].lo, self.nodes[0].hi)));
        while let Some((index, bound)) = stack.pop() {
            if bound >= best2 {
                continue;
            }
            let node = self.nodes[index as usize];
            if node.count > 0 {
                for &t in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    let [a, b, c] = self.triangles[t as usize];
                    let q = closest_on_triangle(p, a, b, c);
                    let d2 = (q - p).length_squared();
                    if d2 < best2 {
                        best2 = d2;
                        best.point = q.to_array();
                        best.triangle = self.source[t as usize];
                    }
                }
            } else {
                let (l, r) = (node.first, node.first + 1);
                let dl = box_distance2(p, self.nodes[l as usize].lo, self.nodes[l as usize].hi);
                let dr = box_distance2(p, self.nodes[r as usize].lo, self.nodes[r as usize].hi);
                // Push the farther child first so the nearer one is searched first.
                let (near, far) = if dl <= dr {
                    ((l, dl), (r, dr))
                } else {
                    ((r, dr), (l, dl))
                };
                if far.1 < best2 {
                    stack.push(far);
                }
                if near.1 < best2 {
                    stack.push(near);
                }
            }
        }
        best.distance = best2.sqrt();
        best
    }

    /// Distance from `p` to the mesh.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        self.closest(p).distance
    }

    /// Distances from many points to the mesh (in parallel; the result is in input order and
    /// does not depend on the thread count).
    pub fn distances<P: AsPoint + Sync>(&self, points: &[P]) -> Vec<f64> {
        points
            .par_iter()
            .map(|p| self.distance(p.point().to_array()))
            .collect()
    }
}

/// `n` points area-uniform on the mesh, reproducibly from `seed`: a triangle is picked with
/// probability proportional to its area, then a point uniform on it (r1, r2 uniform,
/// s = √r1, p = (1 − s) a + s (1 − r2) b + s r2 c). Returns nothing for a mesh of zero area.
pub fn sample_mesh(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    n: usize,
    seed: u64,
) -> Vec<[f64; 3]> {
    let tris: Vec<[DVec3; 3]> = triangles
        .iter()
        .filter(|t| t.iter().all(|&k| (k as usize) < positions.len()))
        .map(|t| t.map(|k| v3(positions[k as usize])))
        .collect();
    let mut cumulative = Vec::with_capacity(tris.len());
    let mut total = 0.0;
    for [a, b, c] in &tris {
        total += 0.5 * (*b - *a).cross(*c - *a).length();
        cumulative.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let u = rng.next_f64() * total;
            let i = cumulative.partition_point(|&c| c <= u).min(tris.len() - 1);
            let [a, b, c] = tris[i];
            let s = rng.next_f64().sqrt();
            let r2 = rng.next_f64();
            ((1.0 - s) * a + (s * (1.0 - r2)) * b + (s * r2) * c).to_array()
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Chamfer and one-sided distances
// ---------------------------------------------------------------------------------------------

/// The seed [`chamfer_to_surface`] samples the mesh with.
const CHAMFER_MESH_SEED: u64 = 0x00C4_A3F0;

/// Symmetric Chamfer distance between a mesh and a known surface; see [`chamfer_to_surface`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chamfer {
    /// Mean over area-uniform mesh samples of the exact distance to the true surface.
    pub mesh_to_true: f64,
    /// Mean over the true-surface samples of the exact distance to the mesh.
    pub true_to_mesh: f64,
    /// Largest mesh → true distance seen (a one-sided Hausdorff estimate).
    pub mesh_to_true_max: f64,
    /// Largest true → mesh distance seen.
    pub true_to_mesh_max: f64,
    /// `mesh_to_true + true_to_mesh`, in input units.
    pub symmetric: f64,
    /// The normaliser: bounding-box diagonal of the true shape.
    pub diagonal: f64,
    /// `symmetric / diagonal`.
    pub relative: f64,
    /// `(mesh_to_true + true_to_mesh) / 2 / diagonal`: the same with the two means averaged
    /// instead of added (half of `relative`), the other common Chamfer convention.
    pub relative_average: f64,
}

impl fmt::Display for Chamfer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "chamfer/diag = {:.3e} (averaged {:.3e}; mesh→true mean {:.3e} max {:.3e}, \
             true→mesh mean {:.3e} max {:.3e}; diag {:.4})",
            self.relative,
            self.relative_average,
            self.mesh_to_true,
            self.mesh_to_true_max,
            self.true_to_mesh,
            self.true_to_mesh_max,
            self.diagonal
        )
    }
}

/// Symmetric Chamfer distance from a mesh to a known surface S, relative to S's size:
///
/// ```text
/// chamfer = mean_{m ∈ M} d(m, S)  +  mean_{s ∈ T} d(s, mesh)
/// relative = chamfer / diagonal
/// ```
///
/// * M: `n_mesh_samples` points area-uniform on the mesh ([`sample_mesh`], seed
///   `CHAMFER_MESH_SEED`); d(m, S) = `exact_distance(m)`, the exact unsigned distance to S
///   (e.g. [`sphere_distance`], [`torus_distance`]).
/// * T: `true_samples`, points area-uniform on S (use a different seed from the reconstruction's
///   input so the test does not reward fitting exactly the input points); d(s, mesh) is the
///   exact point-to-triangle-mesh distance ([`MeshDistance`]).
/// * `true_bbox_diagonal`: the diagonal of S's bounding box ([`sphere_bbox_diagonal`],
///   [`torus_bbox_diagonal`]).
///
/// Distances are plain (not squared) Euclidean distances and the two means are added, not
/// averaged; `relative_average` is the averaged convention (half as large). Calibration: Open3D
/// 0.20 (depth 8, its defaults) on `sample_sphere(100_000, 1.0, [0.0; 3], 1)` gives
/// `relative` = 3.47e-5 and `relative_average` = 1.73e-5 (true samples: seed 1001, 200k mesh
/// samples); the issue's "incumbents reach 1.3e-5–2.0e-5" matches the averaged convention.
/// An empty mesh gives infinite distances.
///
/// [`sphere_distance`]: crate::sphere_distance
/// [`torus_distance`]: crate::torus_distance
/// [`sphere_bbox_diagonal`]: crate::sphere_bbox_diagonal
/// [`torus_bbox_diagonal`]: crate::torus_bbox_diagonal
pub fn chamfer_to_surface<F>(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    exact_distance: F,
    true_samples: &[[f32; 3]],
    n_mesh_samples: usize,
    true_bbox_diagonal: f64,
) -> Chamfer
where
    F: Fn([f64; 3]) -> f64 + Sync,
{
    let mesh_samples = sample_mesh(positions, triangles, n_mesh_samples, CHAMFER_MESH_SEED);
    let to_true: Vec<f64> = mesh_samples
        .par_iter()
        .map(|&p| exact_distance(p))
        .collect();
    let to_mesh = MeshDistance::new(positions, triangles).distances(true_samples);
    let mean = |d: &[f64]| {
        if d.is_empty() {
            f64::INFINITY
        } else {
            d.iter().sum::<f64>() / d.len() as f64
        }
    };
    let max = |d: &[f64]| {
        if d.is_empty() {
            f64::INFINITY
        } else {
            d.iter().copied().fold(0.0, f64::max)
        }
    };
    let (mesh_to_true, true_to_mesh) = (mean(&to_true), mean(&to_mesh));
    let symmetric = mesh_to_true + true_to_mesh;
    Chamfer {
        mesh_to_true,
        true_to_mesh,
        mesh_to_true_max: max(&to_true),
        true_to_mesh_max: max(&to_mesh),
        symmetric,
        diagonal: true_bbox_diagonal,
        relative: symmetric / true_bbox_diagonal,
        relative_average: 0.5 * symmetric / true_bbox_diagonal,
    }
}

/// Summary of a set of distances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistanceStats {
    pub count: usize,
    pub mean: f64,
    /// Middle value (mean of the two middle values for an even count).
    pub median: f64,
    /// 95th percentile, nearest-rank: the ⌈0.95 n⌉-th smallest value.
    pub p95: f64,
    pub max: f64,
    pub rms: f64,
}

impl DistanceStats {
    /// Statistics of `distances` (NaN fields when empty).
    pub fn of(mut distances: Vec<f64>) -> Self {
        let n = distances.len();
        if n == 0 {
            return DistanceStats {
                count: 0,
                mean: f64::NAN,
                median: f64::NAN,
                p95: f64::NAN,
                max: f64::NAN,
                rms: f64::NAN,
            };
        }
        let mean = distances.iter().sum::<f64>() / n as f64;
        let rms = (distances.iter().map(|d| d * d).sum::<f64>() / n as f64).sqrt();
        distances.sort_unstable_by(f64::total_cmp);
        let median = if n % 2 == 1 {
            distances[n / 2]
        } else {
            0.5 * (distances[n / 2 - 1] + distances[n / 2])
        };
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
        DistanceStats {
            count: n,
            mean,
            median,
            p95: distances[rank - 1],
            max: distances[n - 1],
            rms,
        }
    }
}

impl fmt::Display for DistanceStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "n={} mean={:.4e} median={:.4e} p95={:.4e} max={:.4e} rms={:.4e}",
            self.count, self.mean, self.median, self.p95, self.max, self.rms
        )
    }
}

/// Distances from `points` to the mesh (exact point-to-triangle, via [`MeshDistance`]),
/// summarised. E.g. reference-mesh vertices (or [`sample_mesh`] samples of the reference) →
/// reconstructed mesh for the bunny test.
pub fn one_sided_mesh_distance<P: AsPoint + Sync>(
    points: &[P],
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> DistanceStats {
    DistanceStats::of(MeshDistance::new(positions, triangles).distances(points))
}

/// Distances from each of `queries` to the nearest of `points` (exact, in parallel, in query
/// order): a [`MeshDistance`] over the points as one-point triangles.
pub fn nearest_point_distances<P: AsPoint + Sync>(queries: &[P], points: &[[f32; 3]]) -> Vec<f64> {
    let singletons: Vec<[u32; 3]> = (0..points.len() as u32).map(|i| [i, i, i]).collect();
    MeshDistance::new(points, &singletons).distances(queries)
}

/// Distances from the surface of a mesh to a point set: `n_samples` points area-uniform on the
/// mesh ([`sample_mesh`], from `seed`), each measured to its nearest point of `points`,
/// summarised. High where the mesh has surface far from every point, such as the lid a
/// reconstruction puts over a scan's missing side.
pub fn mesh_to_points_distance(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    points: &[[f32; 3]],
    n_samples: usize,
    seed: u64,
) -> DistanceStats {
    let samples = sample_mesh(positions, triangles, n_samples, seed);
    DistanceStats::of(nearest_point_distances(&samples, points))
}

//! End-to-end reconstruction tests: what issue 2 ("What must be shown") asks of the whole
//! pipeline, on analytic shapes whose exact distance function is known, on a real scan with a
//! reference mesh, and for determinism and invariance.
//!
//! Conventions:
//! * Accuracy is the symmetric Chamfer distance of `psr_test_support::chamfer_to_surface` in its
//!   averaged form `relative_average` = (mean mesh→true + mean true→mesh) / 2 / bbox diagonal,
//!   the convention under which PoissonRecon, Open3D and PCL reach 1.3e-5–2.0e-5 on the
//!   100k-point unit sphere at depth 8 (Open3D 0.20: 1.73e-5 on exactly the points of
//!   `sphere_is_a_closed_sphere_and_converges_with_depth`).
//! * The true-surface samples use a different seed from the reconstruction's input, so the
//!   Chamfer distance does not reward passing exactly through the input points.
//! * Every bound states where it comes from. Bounds that could not be set from the issue or from
//!   exact geometry were set by measurement (psr at the time of writing, printed by the test
//!   with `--nocapture`) plus a stated margin.

use psr::{reconstruct, Mesh, Params, PointSet, VertexPlacement};
use psr_test_support::{
    bbox_diagonal, chamfer_to_surface, data_or_skip, jitter_positions, one_sided_mesh_distance,
    perturb_normals_gaussian, sample_box, sample_mesh, sample_sphere, sample_sphere_nonuniform,
    sample_torus, signed_volume, sphere_bbox_diagonal, sphere_distance, surface_area,
    torus_bbox_diagonal, torus_distance, torus_signed_distance, MeshTopology, Rng,
};
use std::f64::consts::PI;
use std::time::Instant;

/// Area-uniform mesh samples for the mesh → true half of the Chamfer distance (as in the Open3D
/// calibration of `chamfer_to_surface`).
const CHAMFER_MESH_SAMPLES: usize = 200_000;
/// True-surface samples for the true → mesh half.
const CHAMFER_TRUE_SAMPLES: usize = 100_000;

/// Reconstructs, panicking with the error's message on failure, and logs size and time.
fn run(points: &PointSet, params: &Params, label: &str) -> Mesh {
    let started = Instant::now();
    let mesh =
        reconstruct(points, params).unwrap_or_else(|e| panic!("{label}: reconstruct failed: {e}"));
    eprintln!(
        "{label}: {} points -> {} vertices, {} triangles, {} nodes in {:.2} s",
        points.len(),
        mesh.positions.len(),
        mesh.triangles.len(),
        mesh.stats.total_nodes(),
        started.elapsed().as_secs_f64()
    );
    mesh
}

/// The checks every reconstruction of a well-sampled closed surface must pass: a closed,
/// consistently oriented 2-manifold (every edge in exactly two triangles traversed once each
/// way, every vertex a single fan) with no invalid or degenerate (zero-area) triangles, no two
/// vertices at
/// the same position (the extraction shares every vertex between the cells that cut the same
/// edge, so a duplicate would be an unshared seam) and no unused vertices; one density per
/// vertex; positive signed volume (triangles counter-clockwise seen from outside, as `Mesh`
/// documents).
fn assert_watertight(mesh: &Mesh, label: &str) -> MeshTopology {
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    eprintln!("{label}: {topo}");
    assert!(
        topo.is_closed_manifold(),
        "{label}: not a closed 2-manifold: {topo}"
    );
    assert!(
        topo.is_consistently_oriented(),
        "{label}: inconsistently oriented: {topo}"
    );
    assert_eq!(topo.invalid_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.degenerate_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.duplicate_vertices, 0, "{label}: {topo}");
    assert_eq!(topo.unreferenced_vertices, 0, "{label}: {topo}");
    assert_eq!(
        mesh.densities.len(),
        mesh.positions.len(),
        "{label}: one density per vertex"
    );
    assert!(
        mesh.positions.iter().flatten().all(|c| c.is_finite()),
        "{label}: non-finite vertex position"
    );
    let volume = signed_volume(&mesh.positions, &mesh.triangles);
    assert!(
        volume > 0.0,
        "{label}: signed volume {volume} is not positive (faces point inwards)"
    );
    topo
}

/// Numbers in scientific notation, for messages.
fn sci(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.4e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn point_set(positions: &[[f32; 3]], normals: &[[f32; 3]]) -> PointSet {
    PointSet::from_slices(positions, normals).expect("test input is valid")
}

/// Mean and largest distance between two meshes, symmetrised: `n` area-uniform samples of each
/// measured against the other, the two means averaged. For comparing two reconstructions of the
/// same surface.
fn mesh_to_mesh(a: &Mesh, b: &Mesh, n: usize) -> (f64, f64) {
    let on_a = sample_mesh(&a.positions, &a.triangles, n, 17);
    let on_b = sample_mesh(&b.positions, &b.triangles, n, 18);
    let ab = one_sided_mesh_distance(&on_a, &b.positions, &b.triangles);
    let ba = one_sided_mesh_distance(&on_b, &a.positions, &a.triangles);
    (0.5 * (ab.mean + ba.mean), ab.max.max(ba.max))
}

// ---------------------------------------------------------------------------------------------
// Sphere
// ---------------------------------------------------------------------------------------------

/// Proves: on 100k area-uniform samples of the unit sphere with exact normals, default
/// parameters at depths 6, 7 and 8 give a closed, consistently oriented 2-manifold with one
/// component and Euler characteristic 2 (a topological sphere), whose volume and area match the
/// sphere's, and whose Chamfer distance to the true sphere falls strictly with every depth and
/// meets the bound at depth 8.
///
/// Bounds:
/// * volume and area: within 0.2 % of 4π/3 and 4π at every depth. (A closed surface at mean
///   radial offset ε from the unit sphere has volume error ≈ 3ε and area error ≈ 2ε; with a
///   depth-6 cell 0.034 of the radius, anything beyond a few per mille would mean a systematic
///   shrink or bulge.) Measured: depth 6 volume −8.3e-5, area +1.4e-4; depth 7 −6.3e-6,
///   +1.4e-4; depth 8 +7.1e-6, +1.0e-4: the bound has a 14× margin.
/// * Chamfer at depth 8: see `SPHERE_DEPTH8_CHAMFER_BOUND`.
#[test]
fn sphere_is_a_closed_sphere_and_converges_with_depth() {
    let (positions, normals) = sample_sphere(100_000, 1.0, [0.0; 3], 1);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_sphere(CHAMFER_TRUE_SAMPLES, 1.0, [0.0; 3], 1001);
    let exact_volume = 4.0 / 3.0 * PI;
    let exact_area = 4.0 * PI;

    let mut chamfers = Vec::new();
    for depth in [6, 7, 8] {
        let label = format!("sphere depth {depth}");
        let mesh = run(&points, &Params::default().with_depth(depth), &label);
        let topo = assert_watertight(&mesh, &label);
        assert_eq!(topo.components, 1, "{label}: {topo}");
        assert_eq!(topo.euler, 2, "{label}: {topo}");
        assert_eq!(topo.genus(), Some(0), "{label}: {topo}");

        let volume = signed_volume(&mesh.positions, &mesh.triangles);
        let area = surface_area(&mesh.positions, &mesh.triangles);
        let volume_error = (volume - exact_volume) / exact_volume;
        let area_error = (area - exact_area) / exact_area;
        let chamfer = chamfer_to_surface(
            &mesh.positions,
            &mesh.triangles,
            sphere_distance([0.0; 3], 1.0),
            &truth,
            CHAMFER_MESH_SAMPLES,
            sphere_bbox_diagonal(1.0),
        );
        eprintln!(
            "{label}: volume error {volume_error:+.3e}, area error {area_error:+.3e}, {chamfer}"
        );
        assert!(
            volume_error.abs() < 2e-3,
            "{label}: volume {volume} vs exact {exact_volume}"
        );
        assert!(
            area_error.abs() < 2e-3,
            "{label}: area {area} vs exact {exact_area}"
        );
        chamfers.push(chamfer.relative_average);
    }
    eprintln!(
        "sphere Chamfer (relative_average) at depths 6, 7, 8: {}",
        sci(&chamfers)
    );
    assert!(
        chamfers[0] > chamfers[1] && chamfers[1] > chamfers[2],
        "Chamfer distance must fall strictly with depth 6 -> 7 -> 8: {}",
        sci(&chamfers)
    );
    assert!(
        chamfers[2] <= SPHERE_DEPTH8_CHAMFER_BOUND,
        "sphere depth 8: Chamfer {:.4e} above {SPHERE_DEPTH8_CHAMFER_BOUND:e}",
        chamfers[2]
    );
}

/// Depth-8 Chamfer bound (averaged convention) for the 100k-point unit sphere.
///
/// The bound (the incumbents reach 1.3e-5–2.0e-5; Open3D 0.20 gives 1.73e-5 on these
/// very points). psr measures 1.5444e-5 (depth 6: 3.9023e-5, depth 7: 1.9736e-5), and 1.5337e-5
/// with its vertices on the isosurface (depth 6: 6.3146e-5, depth 7: 2.2685e-5): at depth 8
/// the sphere's chords barely sag. Earlier builds measured 2.1920e-5 with B-spline splatting
/// and 3.4457e-5 with the paper's trilinear splatting.
const SPHERE_DEPTH8_CHAMFER_BOUND: f64 = 3.0e-5;

/// Proves issue 16's "no bumps" on a faceted solid sampled exactly: on 100k area-uniform samples
/// of a box (half extents 0.8, sharp edges and corners) the Chamfer distance to the true box at
/// depths 8, 10 and 12 falls or stays flat (within 2 %) as the requested depth grows past the
/// sampling's, and at each depth is no larger than the unscreened (point weight 0) run's.
///
/// Why it could fail: 100k samples put about 0.3 samples in a depth-8 node, so the density
/// depth of every sample lies near 6.5 whatever depth is asked for. When the density was read
/// at the kernel depth (depth − 2) alone, a sample's own splat made it look dense enough for
/// depth ≈ kernel depth − 1, so the tree, the splat and the screening followed the requested
/// depth down to where the samples are several cells apart, and the surface got bumps at the
/// sample spacing: measured then, Chamfer (sum of the means, input units) 1.58e-4, 2.10e-4 and
/// 2.46e-4 at depths 8, 10, 11 against 5.49e-4, 3.00e-4, 1.89e-4 unscreened (worse than
/// unscreened at depth 11). Reading the density at coarser depths until a node holds the target
/// count (`density::estimate`) measures 1.58e-4, 1.07e-4, 9.5e-5 at depths 8, 10, 11, and
/// reading it as PoissonRecon does where the normals bend under the kernel (its edges;
/// `density::BENT_SPREAD`) 1.47e-4, 1.06e-4, 9.5e-5 (`bench/bumps.py`'s cube).
#[test]
fn faceted_solid_does_not_get_bumps_as_depth_grows_past_its_sampling() {
    let half = [0.8; 3];
    let (positions, normals) = sample_box(100_000, half, 3);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_box(CHAMFER_TRUE_SAMPLES, half, 1003);
    let box_distance = |p: [f64; 3]| {
        let q: Vec<f64> = (0..3).map(|a| p[a].abs() - half[a]).collect();
        let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
        let inside = q.iter().cloned().fold(f64::MIN, f64::max).min(0.0);
        (outside + inside).abs()
    };
    let diagonal = 2.0 * 0.8 * 3f64.sqrt();
    let chamfer = |params: &Params, label: &str| {
        let mesh = run(&points, params, label);
        let topo = assert_watertight(&mesh, label);
        assert_eq!(topo.components, 1, "{label}: {topo}");
        let c = chamfer_to_surface(
            &mesh.positions,
            &mesh.triangles,
            box_distance,
            &truth,
            CHAMFER_MESH_SAMPLES,
            diagonal,
        );
        eprintln!("{label}: {c}");
        c.relative_average
    };
    let mut screened = Vec::new();
    for depth in [8, 10, 12] {
        let default = chamfer(
            &Params::default().with_depth(depth),
            &format!("box depth {depth}"),
        );
        let unscreened = chamfer(
            &Params::default().with_depth(depth).with_point_weight(0.0),
            &format!("box depth {depth}, point weight 0"),
        );
        assert!(
            default <= unscreened,
            "depth {depth}: screened Chamfer {default:.4e} above unscreened {unscreened:.4e}"
        );
        screened.push(default);
    }
    eprintln!("box Chamfer at depths 8, 10, 12: {}", sci(&screened));
    assert!(
        screened.windows(2).all(|w| w[1] <= 1.02 * w[0]),
        "the Chamfer distance must fall or stay flat as the depth grows: {}",
        sci(&screened)
    );
}

// ---------------------------------------------------------------------------------------------
// Torus
// ---------------------------------------------------------------------------------------------

const TORUS_MAJOR: f64 = 1.0;
const TORUS_MINOR: f64 = 0.35;

/// Proves: on 100k area-uniform samples of a ring torus (R = 1, r = 0.35) with exact normals,
/// depths 7 and 8 give a closed, oriented 2-manifold with one component and Euler
/// characteristic 0 (genus 1: the hole is kept, not filled), the Chamfer distance falls from
/// depth 7 to 8 and is within `TORUS_DEPTH8_CHAMFER_BOUND` at depth 8.
#[test]
fn torus_keeps_its_hole_and_converges_with_depth() {
    let (positions, normals) = sample_torus(100_000, TORUS_MAJOR, TORUS_MINOR, 2);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_torus(CHAMFER_TRUE_SAMPLES, TORUS_MAJOR, TORUS_MINOR, 1002);

    let mut chamfers = Vec::new();
    for depth in [7, 8] {
        let label = format!("torus depth {depth}");
        let mesh = run(&points, &Params::default().with_depth(depth), &label);
        let topo = assert_watertight(&mesh, &label);
        assert_eq!(topo.components, 1, "{label}: {topo}");
        assert_eq!(topo.euler, 0, "{label}: {topo}");
        assert_eq!(topo.genus(), Some(1), "{label}: {topo}");
        let chamfer = chamfer_to_surface(
            &mesh.positions,
            &mesh.triangles,
            torus_distance(TORUS_MAJOR, TORUS_MINOR),
            &truth,
            CHAMFER_MESH_SAMPLES,
            torus_bbox_diagonal(TORUS_MAJOR, TORUS_MINOR),
        );
        eprintln!("{label}: {chamfer}");
        chamfers.push(chamfer.relative_average);
    }
    eprintln!(
        "torus Chamfer (relative_average) at depths 7, 8: {}",
        sci(&chamfers)
    );
    assert!(
        chamfers[0] > chamfers[1],
        "torus Chamfer must fall from depth 7 to 8: {}",
        sci(&chamfers)
    );
    assert!(
        chamfers[1] <= TORUS_DEPTH8_CHAMFER_BOUND,
        "torus depth 8: Chamfer {:.4e} above {TORUS_DEPTH8_CHAMFER_BOUND:e}",
        chamfers[1]
    );
}

/// Depth-8 torus Chamfer bound (averaged convention). There is no incumbent figure for this
/// torus; psr measured 1.3157e-5 (depth 7: 2.9216e-5), and the bound is that × 1.15. With its
/// vertices on the isosurface it measured 1.4539e-5 (depth 7: 4.3068e-5): the thin tube, 0.35
/// of the major radius, makes the chords sag (see the test below).
const TORUS_DEPTH8_CHAMFER_BOUND: f64 = 1.52e-5;

/// Proves: fitted vertices (the default) bring the mesh closer to a curved surface than vertices
/// on the isosurface. On 40k samples of the torus at depth 7, with vertices on the isosurface
/// the mesh's triangles are chords of the tube, so its area-uniform samples lie inside the
/// torus on average (measured: mean signed distance −0.034 thousandths of the diagonal, vertices
/// +0.001); fitting moves the vertices out by the chords' mean sag so that the triangles
/// straddle the surface (samples −0.004, vertices +0.031) and the Chamfer distance to the exact
/// torus falls by 29% (measured 0.71×). Both meshes share their triangles, and both are
/// closed: fitting moves vertices, never connectivity.
#[test]
fn fitted_vertices_straddle_a_curved_surface_instead_of_cutting_inside_it() {
    let (positions, normals) = sample_torus(40_000, TORUS_MAJOR, TORUS_MINOR, 2);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_torus(CHAMFER_TRUE_SAMPLES, TORUS_MAJOR, TORUS_MINOR, 1002);
    let diagonal = torus_bbox_diagonal(TORUS_MAJOR, TORUS_MINOR);
    let signed = torus_signed_distance(TORUS_MAJOR, TORUS_MINOR);
    let mean_signed = |samples: &[[f64; 3]]| {
        samples.iter().map(|&p| signed(p)).sum::<f64>() / samples.len() as f64 / diagonal
    };

    let mut meshes = Vec::new();
    for placement in [VertexPlacement::OnIsosurface, VertexPlacement::Fitted] {
        let label = format!("torus depth 7, {placement:?} vertices");
        let params = Params::default()
            .with_depth(7)
            .with_vertex_placement(placement);
        let mesh = run(&points, &params, &label);
        assert_watertight(&mesh, &label);
        let chamfer = chamfer_to_surface(
            &mesh.positions,
            &mesh.triangles,
            torus_distance(TORUS_MAJOR, TORUS_MINOR),
            &truth,
            CHAMFER_MESH_SAMPLES,
            diagonal,
        );
        let vertices: Vec<[f64; 3]> = mesh.positions.iter().map(|p| p.map(f64::from)).collect();
        let samples = sample_mesh(&mesh.positions, &mesh.triangles, CHAMFER_MESH_SAMPLES, 7);
        let (on_vertices, on_triangles) = (mean_signed(&vertices), mean_signed(&samples));
        eprintln!(
            "{label}: {chamfer}; mean signed distance / diagonal: vertices {on_vertices:+.3e}, \
             triangles {on_triangles:+.3e}"
        );
        meshes.push((mesh, chamfer.relative_average, on_vertices, on_triangles));
    }
    let (on_surface, fitted) = (&meshes[0], &meshes[1]);
    assert_eq!(on_surface.0.triangles, fitted.0.triangles);
    // On the isosurface: vertices unbiased (within a tenth of the sag), triangles inside.
    assert!(
        on_surface.2.abs() < 0.1 * on_surface.3.abs(),
        "{:+.3e} {:+.3e}",
        on_surface.2,
        on_surface.3
    );
    assert!(
        on_surface.3 < -2e-5,
        "chords should sag inside: {:+.3e}",
        on_surface.3
    );
    // Fitted: vertices outside, triangles straddling (a fifth of the sag left at most).
    assert!(
        fitted.2 > 2e-5,
        "fitted vertices should move out: {:+.3e}",
        fitted.2
    );
    assert!(
        fitted.3.abs() < 0.2 * on_surface.3.abs(),
        "{:+.3e} {:+.3e}",
        fitted.3,
        on_surface.3
    );
    assert!(
        fitted.1 < 0.85 * on_surface.1,
        "fitted Chamfer {:.4e} should be well below on-isosurface {:.4e}",
        fitted.1,
        on_surface.1
    );
}

// ---------------------------------------------------------------------------------------------
// Non-uniform sampling
// ---------------------------------------------------------------------------------------------

/// Proves: with a sampling density varying 10× from the south pole (sparse) to the north pole
/// (dense) of the unit sphere, the reconstruction is still a closed topological sphere within
/// `NONUNIFORM_CHAMFER_BOUND` of the truth, and the sparse cap stays accurate. That the
/// density-adaptive depth of §4.5 is really used on this sphere (the sparsest tenth of the
/// samples at least one level coarser than the densest) is the density stage's unit test
/// `nonuniform_sampling_gets_coarser_depths_where_sparse`.
#[test]
fn nonuniform_sampling_uses_adaptive_depth_and_stays_accurate() {
    let ratio = 10.0;
    let (positions, normals) = sample_sphere_nonuniform(100_000, 3, ratio);
    let params = Params::default();

    let points = point_set(&positions, &normals);
    let mesh = run(&points, &params, "nonuniform sphere");
    let topo = assert_watertight(&mesh, "nonuniform sphere");
    assert_eq!(topo.components, 1, "{topo}");
    assert_eq!(topo.euler, 2, "{topo}");

    let (truth, _) = sample_sphere(CHAMFER_TRUE_SAMPLES, 1.0, [0.0; 3], 1003);
    let diagonal = sphere_bbox_diagonal(1.0);
    let chamfer = chamfer_to_surface(
        &mesh.positions,
        &mesh.triangles,
        sphere_distance([0.0; 3], 1.0),
        &truth,
        CHAMFER_MESH_SAMPLES,
        diagonal,
    );
    eprintln!("nonuniform sphere: {chamfer}");
    assert!(
        chamfer.relative_average <= NONUNIFORM_CHAMFER_BOUND,
        "nonuniform sphere: Chamfer {:.4e} above {NONUNIFORM_CHAMFER_BOUND:e}",
        chamfer.relative_average
    );

    // Accuracy on each polar cap z < −0.8 / z > 0.8 (each a tenth of the sphere's area): the
    // same averaged Chamfer restricted to the cap, mesh samples and true samples alike.
    let cap = |south: bool| {
        let inside = |z: f64| if south { z < -0.8 } else { z > 0.8 };
        let on_mesh: Vec<[f64; 3]> =
            sample_mesh(&mesh.positions, &mesh.triangles, CHAMFER_MESH_SAMPLES, 5)
                .into_iter()
                .filter(|p| inside(p[2]))
                .collect();
        let exact = sphere_distance([0.0; 3], 1.0);
        let to_true = on_mesh.iter().map(|&p| exact(p)).sum::<f64>() / on_mesh.len() as f64;
        let on_truth: Vec<[f32; 3]> = truth
            .iter()
            .copied()
            .filter(|p| inside(p[2] as f64))
            .collect();
        let to_mesh = one_sided_mesh_distance(&on_truth, &mesh.positions, &mesh.triangles).mean;
        0.5 * (to_true + to_mesh) / diagonal
    };
    let (sparse_cap, dense_cap) = (cap(true), cap(false));
    eprintln!(
        "nonuniform sphere: cap Chamfer sparse (z < -0.8) {sparse_cap:.4e}, \
         dense (z > 0.8) {dense_cap:.4e}"
    );
    assert!(
        sparse_cap <= NONUNIFORM_SPARSE_CAP_BOUND,
        "nonuniform sphere: sparse cap Chamfer {sparse_cap:.4e} above {NONUNIFORM_SPARSE_CAP_BOUND:e}"
    );

    // The mesh follows the tree: extracted on its leaves, its triangles are larger where the
    // samples are sparse. Mean edge length on each cap (triangles whose centroid is there).
    let cap_edge = |south: bool| {
        let (mut sum, mut count) = (0.0, 0usize);
        for t in &mesh.triangles {
            let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
            let z = (p[0][2] + p[1][2] + p[2][2]) / 3.0;
            if (south && z < -0.8) || (!south && z > 0.8) {
                for k in 0..3 {
                    let (a, b) = (p[k], p[(k + 1) % 3]);
                    sum += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                        .sqrt();
                    count += 1;
                }
            }
        }
        sum / count as f64
    };
    let (sparse_edge, dense_edge) = (cap_edge(true), cap_edge(false));
    eprintln!(
        "nonuniform sphere: mean edge length sparse cap {sparse_edge:.4e}, dense cap \
         {dense_edge:.4e}"
    );
    // One depth coarser doubles the edge length; the sparse cap's samples sit about a depth
    // and a half below the dense cap's (median 6.3 vs 7.6, printed above).
    assert!(
        sparse_edge >= 1.5 * dense_edge,
        "nonuniform sphere: the sparse cap's triangles ({sparse_edge:.4e}) are not coarser than \
         the dense cap's ({dense_edge:.4e})"
    );
}

/// Whole-sphere Chamfer bound for the 10×-non-uniform sphere at depth 8: measured 3.075e-5 by
/// an earlier build, × 1.15; now 1.624e-5 (1.728e-5 with vertices on the isosurface).
/// (Between the uniform sphere's depth-8 1.5e-5 and depth-7 2.0e-5, as expected for samples
/// splatted at depths 6.3–7.6.)
const NONUNIFORM_CHAMFER_BOUND: f64 = 3.54e-5;
/// Chamfer bound on the sparse cap z < −0.8 (0.15–0.19 samples per depth-8 node area there):
/// measured 6.1857e-5 by an earlier build, × 1.15; now 3.5668e-5 (dense cap z > 0.8:
/// 8.8723e-6). That is near the uniform sphere's depth-6 figure (3.9e-5), matching the ≈ 6.3
/// depth its samples are splatted at: coarser, as §4.5 intends, but no hole and no blow-up.
const NONUNIFORM_SPARSE_CAP_BOUND: f64 = 7.12e-5;

// ---------------------------------------------------------------------------------------------
// Sparse sampling
// ---------------------------------------------------------------------------------------------

/// Proves: a sparsely but evenly sampled sphere, 200 points (about 7 depth-6 cells apart),
/// still gives a closed topological sphere of one component with the default parameters, at
/// depth 6 and at depth 8, where the samples are about 28 cells apart. (An early build failed
/// here, with χ near the bounding cube close to the isovalue and extra open sheets running into
/// the cube's faces; the test is not ignored and passes.)
#[test]
fn sparse_sphere_is_closed() {
    let (positions, normals) = sample_sphere(200, 1.0, [0.0; 3], 9);
    let points = point_set(&positions, &normals);
    for depth in [6, 8] {
        let label = format!("200-point sphere depth {depth}");
        let mesh = run(&points, &Params::default().with_depth(depth), &label);
        let topo = assert_watertight(&mesh, &label);
        assert_eq!(topo.components, 1, "{label}: {topo}");
        assert_eq!(topo.euler, 2, "{label}: {topo}");
    }
}

// ---------------------------------------------------------------------------------------------
// Noise
// ---------------------------------------------------------------------------------------------

/// Proves: with normals rotated by a half-normal angle of σ = 15° (RMS angular error 15°, mean
/// 12°) and positions jittered by an isotropic Gaussian of σ = 0.001 per axis (about an eighth
/// of a depth-8 cell), the unit-sphere reconstruction at depth 8 is still a closed topological
/// sphere with one component, within `NOISY_CHAMFER_BOUND` of the true sphere.
#[test]
fn noisy_normals_and_positions_still_give_a_closed_accurate_sphere() {
    let (positions, normals) = sample_sphere(100_000, 1.0, [0.0; 3], 4);
    let normals = perturb_normals_gaussian(&normals, 15f64.to_radians(), 40);
    let positions = jitter_positions(&positions, 1e-3, 41);
    let points = point_set(&positions, &normals);
    let mesh = run(&points, &Params::default(), "noisy sphere");
    let topo = assert_watertight(&mesh, "noisy sphere");
    assert_eq!(topo.components, 1, "{topo}");
    assert_eq!(topo.euler, 2, "{topo}");

    let (truth, _) = sample_sphere(CHAMFER_TRUE_SAMPLES, 1.0, [0.0; 3], 1004);
    let chamfer = chamfer_to_surface(
        &mesh.positions,
        &mesh.triangles,
        sphere_distance([0.0; 3], 1.0),
        &truth,
        CHAMFER_MESH_SAMPLES,
        sphere_bbox_diagonal(1.0),
    );
    eprintln!("noisy sphere: {chamfer}");
    assert!(
        chamfer.relative_average <= NOISY_CHAMFER_BOUND,
        "noisy sphere: Chamfer {:.4e} above {NOISY_CHAMFER_BOUND:e}",
        chamfer.relative_average
    );
}

/// Chamfer bound for the noisy sphere at depth 8: measured 8.255e-5, × 1.15; now 8.633e-5
/// (8.287e-5 with vertices on the isosurface: fitting the mesh to χ's level set keeps a little
/// more of the wiggles the noise puts in it, see `extract::fit_to_surface`). For scale: the
/// jitter alone puts the input points a mean σ·√(2/π) = 8.0e-4 off the sphere, 2.3e-4 of the
/// diagonal, and the mesh is 2.8× closer than that; the noise-free sphere measures 2.2e-5.
const NOISY_CHAMFER_BOUND: f64 = 9.5e-5;

// ---------------------------------------------------------------------------------------------
// Real scan
// ---------------------------------------------------------------------------------------------

/// Proves: the merged raw Stanford bunny scans (362k points, estimated normals, stray points,
/// misregistration, a sparsely covered underside) at depth 8 give a closed, oriented 2-manifold
/// that lies close to the Stanford zipper reconstruction: the distance from area-uniform samples
/// of the reference surface (not its vertices: the file has unreferenced vertices) to the mesh
/// has mean and 95th percentile within `BUNNY_MEAN_BOUND` and `BUNNY_P95_BOUND`.
#[test]
fn bunny_scans_give_a_closed_mesh_near_the_reference() {
    let test = "bunny_scans_give_a_closed_mesh_near_the_reference";
    let Some(scans) = data_or_skip("bunny_scans.ply", test) else {
        return;
    };
    let Some(reference) = data_or_skip("bunny_scans.reference.ply", test) else {
        return;
    };
    let cloud = psr::ply::read_point_cloud(&scans).unwrap_or_else(|e| panic!("{e}"));
    let points = point_set(&cloud.positions, &cloud.normals);
    let mesh = run(&points, &Params::default(), "bunny depth 8");
    let topo = assert_watertight(&mesh, "bunny depth 8");
    eprintln!(
        "bunny depth 8: component sizes (triangles) {:?}",
        &topo.component_faces[..topo.components.min(10)]
    );
    // Stray points may legitimately give small islands, so one component is not required (psr
    // measured exactly one, Euler characteristic 2); but the bunny itself must be one piece
    // holding nearly all of the surface.
    assert!(
        topo.component_faces[0] as f64 >= 0.99 * topo.faces as f64,
        "bunny: the largest component has only {} of {} triangles",
        topo.component_faces[0],
        topo.faces
    );

    let (reference_positions, reference_triangles) =
        psr::ply::read_mesh(&reference).unwrap_or_else(|e| panic!("{e}"));
    let on_reference = sample_mesh(&reference_positions, &reference_triangles, 200_000, 7);
    let d = one_sided_mesh_distance(&on_reference, &mesh.positions, &mesh.triangles);
    eprintln!("bunny depth 8: reference -> mesh {d} (m)");
    assert!(
        d.mean <= BUNNY_MEAN_BOUND,
        "bunny: mean reference->mesh {:.4e} m above {BUNNY_MEAN_BOUND:e}",
        d.mean
    );
    assert!(
        d.p95 <= BUNNY_P95_BOUND,
        "bunny: p95 reference->mesh {:.4e} m above {BUNNY_P95_BOUND:e}",
        d.p95
    );
}

/// Mean reference → mesh distance bound for the bunny at depth 8, in metres (the points'
/// bounding box, stray points included, is 0.175 m across, so a depth-8 cell is
/// 0.175 × 1.1 / 256 ≈ 0.75 mm): psr measured 4.864e-5 m
/// (Open3D 0.20: 4.71e-5 m on the same data); bound = measured × 1.15. Now 4.729e-5 m, and
/// 4.420e-5 m with vertices on the isosurface: the reference lies inside the scans (input
/// points are a mean 2.4e-5 m, median 1.2e-5 m, outside it), and fitted vertices move the mesh
/// towards the scans (the input points' mean signed distance to the mesh, 0.34e-5 m on the
/// isosurface, 0.12e-5 m fitted), so away from the reference.
const BUNNY_MEAN_BOUND: f64 = 5.59e-5;
/// 95th-percentile reference → mesh distance bound, metres: psr measured 1.3585e-4 m (Open3D
/// 1.36e-4 m); bound = measured × 1.15. Now 1.3645e-4 m (1.2882e-4 m on the isosurface).
const BUNNY_P95_BOUND: f64 = 1.56e-4;

// ---------------------------------------------------------------------------------------------
// Determinism and invariance
// ---------------------------------------------------------------------------------------------

fn kitten() -> PointSet {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/kitten_cgal.ply");
    let cloud = psr::ply::read_point_cloud(&path).unwrap_or_else(|e| panic!("{e}"));
    point_set(&cloud.positions, &cloud.normals)
}

/// Asserts two meshes are the same bit for bit: positions, triangles, densities, and the
/// isovalue, node counts and solver figures (everything but the timings).
fn assert_bit_identical(a: &Mesh, b: &Mesh, label: &str) {
    let bits = |m: &Mesh| {
        m.positions
            .iter()
            .map(|p| p.map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        a.positions.len(),
        b.positions.len(),
        "{label}: vertex counts differ"
    );
    assert_eq!(
        a.triangles.len(),
        b.triangles.len(),
        "{label}: triangle counts differ"
    );
    assert!(bits(a) == bits(b), "{label}: vertex positions differ");
    assert!(a.triangles == b.triangles, "{label}: triangles differ");
    let dbits = |m: &Mesh| m.densities.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert!(dbits(a) == dbits(b), "{label}: densities differ");
    assert_eq!(
        a.stats.isovalue.to_bits(),
        b.stats.isovalue.to_bits(),
        "{label}: isovalues differ"
    );
    assert_eq!(a.stats.nodes_per_depth, b.stats.nodes_per_depth, "{label}");
    let solves = |m: &Mesh| {
        m.stats
            .solves
            .iter()
            .map(|s| {
                (
                    s.depth,
                    s.unknowns,
                    s.iterations,
                    s.relative_residual.to_bits(),
                )
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(
        solves(a),
        solves(b),
        "{label}: solver iterations or residuals differ"
    );
}

/// Proves: a width (PoissonRecon's `--width`) chooses the smallest depth whose finest cells,
/// the bounding cube's side over 2^depth, are no wider, overriding `depth`, and gives the mesh
/// of that depth asked for directly, bit for bit; `Stats` reports the depth used and the
/// octree's finest depth, which sparse samples keep below it.
#[test]
fn a_width_chooses_the_depth_and_stats_report_it() {
    let (positions, normals) = sample_sphere(20_000, 1.0, [0.0; 3], 17);
    let points = point_set(&positions, &normals);
    // The cube side as the pipeline computes it: the longest side of the bounding box × scale.
    let extent = (0..3)
        .map(|a| {
            let (lo, hi) = positions.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                (lo.min(p[a] as f64), hi.max(p[a] as f64))
            });
            hi - lo
        })
        .fold(0.0, f64::max);
    let side = extent * Params::default().scale as f64;
    for (width, depth) in [(side / 128.0, 7), (side / 128.0 * 0.99, 8)] {
        let label = format!("width {width} (depth {depth})");
        let by_width = run(
            &points,
            &Params::default().with_depth(3).with_width(Some(width)),
            &label,
        );
        assert_eq!(by_width.stats.depth, depth, "{label}");
        assert!(by_width.stats.finest_depth() <= depth, "{label}");
        let by_depth = run(&points, &Params::default().with_depth(depth), &label);
        assert_eq!(by_depth.stats.depth, depth, "{label}");
        assert_eq!(by_width.stats.finest_depth(), by_depth.stats.finest_depth());
        assert_bit_identical(&by_width, &by_depth, &label);
    }
    // 200 points at depth 10: the density stops the tree above depth 10.
    let (positions, normals) = sample_sphere(200, 1.0, [0.0; 3], 9);
    let sparse = run(
        &point_set(&positions, &normals),
        &Params::default().with_depth(10),
        "sparse",
    );
    eprintln!(
        "sparse: depth {}, finest {}",
        sparse.stats.depth,
        sparse.stats.finest_depth()
    );
    assert_eq!(sparse.stats.depth, 10);
    assert!(sparse.stats.finest_depth() < 10, "{:?}", sparse.stats);
    assert_eq!(
        sparse.stats.nodes_per_depth.len(),
        sparse.stats.finest_depth() as usize + 1
    );
}

/// Proves: the thread count does not change the result, not even in the last bit (Params
/// documents "The result does not depend on it"): a 20k-point sphere and the kitten scan at
/// depth 7, and the kitten at the default depth 8, with 1 and with 2 threads.
#[test]
fn one_and_two_threads_give_the_same_mesh_bit_for_bit() {
    let (positions, normals) = sample_sphere(20_000, 1.0, [0.0; 3], 6);
    let cases = [
        ("sphere 20k depth 7", point_set(&positions, &normals), 7),
        ("kitten depth 7", kitten(), 7),
        ("kitten depth 8", kitten(), 8),
    ];
    for (label, points, depth) in cases {
        let one = run(
            &points,
            &Params::default().with_depth(depth).with_threads(1),
            &format!("{label}, 1 thread"),
        );
        let two = run(
            &points,
            &Params::default().with_depth(depth).with_threads(2),
            &format!("{label}, 2 threads"),
        );
        assert!(!one.triangles.is_empty(), "{label}: empty mesh");
        assert_bit_identical(&one, &two, label);
    }
}

/// Proves: the order of the input points does not matter beyond floating-point rounding. The
/// pipeline sums per-sample contributions in input order, so a shuffled input may round
/// differently and is not required to be bit-identical; but the mesh must be the same surface:
/// vertex counts within 1 %, and the symmetric mean distance between the two meshes below
/// 1e-6 of the bounding-box diagonal (a depth-8 cell is about 1/256 of it; rounding differences
/// move vertices by orders of magnitude less: measured 1.4e-8 of the diagonal and the same vertex
/// count; on a 100k-point sphere 4.6e-9). Checked on the kitten scan at depth 8.
#[test]
fn shuffled_input_gives_the_same_surface() {
    let kitten = kitten();
    let (positions, normals) = (kitten.positions(), kitten.normals());
    let mut order: Vec<usize> = (0..positions.len()).collect();
    let mut rng = Rng::new(80);
    for i in (1..order.len()).rev() {
        order.swap(i, rng.below(i as u64 + 1) as usize);
    }
    let shuffled_positions: Vec<_> = order.iter().map(|&i| positions[i]).collect();
    let shuffled_normals: Vec<_> = order.iter().map(|&i| normals[i]).collect();
    let a = run(&kitten, &Params::default(), "kitten in order");
    let b = run(
        &point_set(&shuffled_positions, &shuffled_normals),
        &Params::default(),
        "kitten shuffled",
    );
    assert_watertight(&b, "kitten shuffled");
    let (na, nb) = (a.positions.len() as f64, b.positions.len() as f64);
    let (mean, max) = mesh_to_mesh(&a, &b, 100_000);
    let diagonal = bbox_diagonal(positions);
    eprintln!(
        "shuffle: vertices {na} vs {nb}; mesh-to-mesh mean {:.3e}, max {:.3e} of the diagonal",
        mean / diagonal,
        max / diagonal
    );
    assert!(
        (na - nb).abs() <= 0.01 * na,
        "vertex counts {na} vs {nb} differ by more than 1%"
    );
    assert!(
        mean / diagonal < 1e-6,
        "shuffled input moved the surface by {:.3e} of the diagonal",
        mean / diagonal
    );
}

/// Proves: the reconstruction commutes with similarities of the input. The points are mapped
/// into the unit cube by their own bounding box, so scaling the input by s and translating it
/// by t must give the original mesh scaled by s and translated by t, up to the rounding of the
/// transformed f32 inputs: coordinates up to 22 round by up to 9.5e-7, 2e-7 of the transformed
/// kitten's diagonal (3.5 × 1.33). Checked on the kitten at depth 8: after mapping the
/// transformed mesh back, vertex counts agree within 1 % and the symmetric mean distance between
/// the meshes is below 1e-6 of the diagonal, 5× that rounding (measured: the same vertex count,
/// 9.5e-8).
#[test]
fn translated_and_scaled_input_translates_and_scales_the_mesh() {
    let points = kitten();
    let (s, t) = (3.5f64, [20.0f64, -17.0, 9.0]);
    let moved: Vec<[f32; 3]> = points
        .positions()
        .iter()
        .map(|p| [0, 1, 2].map(|k| (p[k] as f64 * s + t[k]) as f32))
        .collect();
    let a = run(&points, &Params::default(), "kitten");
    let b = run(
        &point_set(&moved, points.normals()),
        &Params::default(),
        "kitten scaled and moved",
    );
    assert_watertight(&b, "kitten scaled and moved");
    let mut back = b.clone();
    back.positions = b
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|k| ((p[k] as f64 - t[k]) / s) as f32))
        .collect();
    let diagonal = bbox_diagonal(points.positions());
    let (na, nb) = (a.positions.len() as f64, b.positions.len() as f64);
    let (mean, max) = mesh_to_mesh(&a, &back, 100_000);
    eprintln!(
        "similarity: vertices {na} vs {nb}; mesh-to-mesh mean {:.3e}, max {:.3e} of the diagonal",
        mean / diagonal,
        max / diagonal
    );
    assert!(
        (na - nb).abs() <= 0.01 * na,
        "vertex counts {na} vs {nb} differ by more than 1%"
    );
    assert!(
        mean / diagonal < 1e-6,
        "the transformed mesh is {:.3e} of the diagonal off",
        mean / diagonal
    );
}

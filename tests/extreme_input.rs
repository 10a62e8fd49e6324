//! Extreme but valid input (issue 19): every case gives a closed mesh of what was sampled or a
//! clear error, in the time and memory a user would accept (each case here runs in seconds;
//! their figures are printed). The cases: coordinates near the top of f32's range and near its
//! smallest normal numbers, a cloud spanning 10⁶ with a part 10⁻³ across, a million
//! duplicates, a depth far beyond the sampling, normals all one way, and a few thousand points
//! at the deepest depth (16).

use psr::{reconstruct, Error, Mesh, Params, PointSet};
use psr_test_support::{sample_sphere, MeshTopology};
use std::time::Instant;

/// Reconstructs, printing the outcome and the time.
fn run(
    label: &str,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    params: &Params,
) -> Result<Mesh, Error> {
    let points = PointSet::from_slices(positions, normals).expect("valid points");
    let started = Instant::now();
    let outcome = reconstruct(&points, params);
    let seconds = started.elapsed().as_secs_f64();
    match &outcome {
        Ok(mesh) => eprintln!(
            "{label}: {} points, depth {} (finest {}): {} vertices, {} triangles in {seconds:.2} s",
            positions.len(),
            mesh.stats.depth,
            mesh.stats.nodes_per_depth.len().saturating_sub(1),
            mesh.positions.len(),
            mesh.triangles.len()
        ),
        Err(e) => eprintln!(
            "{label}: {} points: error in {seconds:.2} s: {e}",
            positions.len()
        ),
    }
    if let Err(Error::Internal(message)) = &outcome {
        panic!("{label}: internal error (a bug): {message}");
    }
    outcome
}

/// Asserts `mesh` is one closed sphere of radius `radius` around `center` (every vertex within
/// `tolerance` × radius of it), with finite vertices.
fn assert_sphere(label: &str, mesh: &Mesh, center: [f64; 3], radius: f64, tolerance: f64) {
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    assert!(
        topo.is_closed_manifold() && topo.components == 1 && topo.euler == 2,
        "{label}: not one closed sphere: {topo}"
    );
    let worst = mesh
        .positions
        .iter()
        .map(|p| {
            let d: f64 = (0..3).map(|a| (f64::from(p[a]) - center[a]).powi(2)).sum();
            (d.sqrt() - radius).abs() / radius
        })
        .fold(0.0, f64::max);
    assert!(
        worst <= tolerance,
        "{label}: a vertex is {worst:.3e} radii off the sphere (allowed {tolerance})"
    );
}

/// Proves: a sphere whose coordinates reach 3·10³⁸ (f32's largest is 3.4·10³⁸; the bounding
/// cube's side, 1.1 × 6·10³⁸, is past it) and one of radius 10⁻³⁷ (ten times f32's smallest
/// normal number, so the samples' coordinates keep about 24 bits) both come out as closed
/// spheres, their vertices finite and on the sphere.
#[test]
fn coordinates_near_the_ends_of_f32s_range() {
    for (label, radius) in [("radius 3e38", 3e38), ("radius 1e-37", 1e-37)] {
        let (p, n) = sample_sphere(4000, radius, [0.0; 3], 31);
        let mesh = run(label, &p, &n, &Params::default().with_depth(7)).expect("a mesh");
        assert!(
            mesh.positions.iter().flatten().all(|c| c.is_finite()),
            "{label}: a non-finite vertex"
        );
        assert_sphere(label, &mesh, [0.0; 3], radius, 0.02);
    }
}

/// Proves: a cloud spanning 10⁶ (a unit sphere at the origin and one 10⁶ away) with a part
/// 10⁻³ across (a sphere of radius 5·10⁻⁴ beside the first) gives a closed mesh with finite
/// vertices at depth 12, and with a width of 10⁻⁴ too: that width would need depth 34, past the
/// deepest (16), so the depth is 16 (as `Params::width` documents, PoissonRecon's rule) and the
/// mesh reports it. At either depth the cells (270 and 17 units) are wider than the spheres, so
/// what is left of them are blobs of a few cells or nothing: the octree's 16 levels bound the
/// detail one reconstruction resolves to 1.1 × span / 2¹⁶.
#[test]
fn a_cloud_spanning_a_million_with_detail_at_a_thousandth() {
    let (mut p, mut n) = sample_sphere(3000, 1.0, [0.0; 3], 32);
    let (far_p, far_n) = sample_sphere(3000, 1.0, [1e6, 0.0, 0.0], 33);
    let (tiny_p, tiny_n) = sample_sphere(3000, 5e-4, [0.0, 3.0, 0.0], 34);
    p.extend(far_p);
    n.extend(far_n);
    p.extend(tiny_p);
    n.extend(tiny_n);
    for (label, params) in [
        ("span 1e6, depth 12", Params::default().with_depth(12)),
        (
            "span 1e6, width 1e-4",
            Params::default().with_width(Some(1e-4)),
        ),
    ] {
        let mesh = run(label, &p, &n, &params).expect("a mesh");
        let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
        assert!(topo.is_closed_manifold(), "{label}: {topo}");
        assert!(
            mesh.positions.iter().flatten().all(|c| c.is_finite()),
            "{label}"
        );
        let expected_depth = if params.width.is_some() { 16 } else { 12 };
        assert_eq!(mesh.stats.depth, expected_depth, "{label}: the depth used");
    }
}

/// Proves: a million points that are 2,000 copies of each of 500 samples of a sphere give the
/// same closed sphere as the 500 samples once, within a small fraction of the radius (the
/// duplicates weigh each sample alike, so the surface is the same; only the density estimate
/// sees 2,000 times the samples and puts them deeper).
#[test]
fn a_million_duplicates() {
    let (p, n) = sample_sphere(500, 1.0, [0.0; 3], 35);
    let params = Params::default().with_depth(7);
    let once = run("500 samples once", &p, &n, &params).expect("a mesh");
    assert_sphere("500 samples once", &once, [0.0; 3], 1.0, 0.08);
    let copies: Vec<[f32; 3]> = (0..1_000_000).map(|i| p[i % 500]).collect();
    let copies_n: Vec<[f32; 3]> = (0..1_000_000).map(|i| n[i % 500]).collect();
    let many = run("500 samples x 2000", &copies, &copies_n, &params).expect("a mesh");
    assert_sphere("500 samples x 2000", &many, [0.0; 3], 1.0, 0.08);
}

/// Proves: 2,000 samples of a sphere at depth 16 (the deepest), far beyond their spacing (about
/// 2⁻⁵ of the sphere), give a closed sphere in seconds: the octree stops where the samples stop
/// defining the surface instead of refining 2¹⁶ cells across; the same at depth 12.
#[test]
fn a_few_thousand_points_at_the_deepest_depth() {
    let (p, n) = sample_sphere(2000, 1.0, [0.0; 3], 36);
    for depth in [12, 16] {
        let label = format!("2000 samples at depth {depth}");
        let mesh = run(&label, &p, &n, &Params::default().with_depth(depth)).expect("a mesh");
        assert_sphere(&label, &mesh, [0.0; 3], 1.0, 0.05);
    }
}

/// Proves: samples of a sphere whose normals all point one way (+z: half of them inward) give
/// an oriented manifold mesh with finite vertices or a clear error, never a panic (the field
/// such normals splat has no inside to enclose: what comes out is cut off by the cube).
#[test]
fn normals_all_one_way() {
    let (p, _) = sample_sphere(3000, 1.0, [0.0; 3], 37);
    let up = vec![[0.0f32, 0.0, 1.0]; p.len()];
    if let Ok(mesh) = run("normals all +z", &p, &up, &Params::default().with_depth(7)) {
        let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
        assert_eq!(topo.non_manifold_edges, 0, "normals all +z: {topo}");
        assert!(topo.is_consistently_oriented(), "normals all +z: {topo}");
        assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
    }
}

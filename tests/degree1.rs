//! Degree-1 node functions (issue 17): piecewise-linear hats on the cell corners, PoissonRecon's
//! and Open3D's default, beside psr's default degree 2. On the analytic shapes of
//! `reconstruction.rs` (the same points, the same Chamfer convention: the mean of the two
//! one-sided mean distances over the bounding-box diagonal, see that file's module doc), with
//! `Params::default().with_degree(1)` (point weight 2, PoissonRecon's default for degree 1),
//! the mesh is a closed, oriented 2-manifold of the right genus whose Chamfer distance falls
//! with depth and stays within a bound set from a measurement (stated at each bound), for every
//! boundary kind; the result does not depend on the thread count; a degree other than 1 or 2
//! is an error naming the parameter.

use psr::{reconstruct, Boundary, Error, Mesh, Params, PointSet};
use psr_test_support::{
    chamfer_to_surface, sample_box, sample_sphere, sample_torus, signed_volume,
    sphere_bbox_diagonal, sphere_distance, torus_bbox_diagonal, torus_distance, MeshTopology, Rng,
};

const CHAMFER_MESH_SAMPLES: usize = 200_000;
const CHAMFER_TRUE_SAMPLES: usize = 100_000;
const TORUS_MAJOR: f64 = 1.0;
const TORUS_MINOR: f64 = 0.35;

fn point_set(positions: &[[f32; 3]], normals: &[[f32; 3]]) -> PointSet {
    PointSet::from_slices(positions, normals).expect("valid samples")
}

fn run(points: &PointSet, params: &Params, label: &str) -> Mesh {
    let mesh = reconstruct(points, params).unwrap_or_else(|e| panic!("{label}: {e}"));
    eprintln!(
        "{label}: {} vertices, {} triangles, {} nodes",
        mesh.positions.len(),
        mesh.triangles.len(),
        mesh.stats.total_nodes()
    );
    mesh
}

/// Closed, oriented, manifold, one component, the given Euler characteristic.
fn assert_closed(mesh: &Mesh, euler: i64, label: &str) {
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    eprintln!("{label}: {topo}");
    assert!(topo.is_closed_manifold(), "{label}: {topo}");
    assert!(topo.is_consistently_oriented(), "{label}: {topo}");
    assert_eq!(topo.invalid_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.degenerate_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.duplicate_vertices, 0, "{label}: {topo}");
    assert!(
        signed_volume(&mesh.positions, &mesh.triangles) > 0.0,
        "{label}: faces point inwards"
    );
    assert_eq!(topo.components, 1, "{label}: {topo}");
    assert_eq!(topo.euler, euler, "{label}: {topo}");
}

/// Proves: degree 1 on the 100k-point unit sphere of `reconstruction.rs` gives a closed
/// topological sphere at depths 6, 7 and 8 whose Chamfer distance falls with every depth and
/// is within `SPHERE_DEPTH8_CHAMFER_BOUND` at depth 8.
#[test]
fn degree_one_sphere_is_closed_and_converges_with_depth() {
    let (positions, normals) = sample_sphere(100_000, 1.0, [0.0; 3], 1);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_sphere(CHAMFER_TRUE_SAMPLES, 1.0, [0.0; 3], 1001);
    let mut chamfers = Vec::new();
    for depth in [6, 7, 8] {
        let label = format!("degree-1 sphere depth {depth}");
        let params = Params::default().with_depth(depth).with_degree(1);
        let mesh = run(&points, &params, &label);
        assert_closed(&mesh, 2, &label);
        let chamfer = chamfer_to_surface(
            &mesh.positions,
            &mesh.triangles,
            sphere_distance([0.0; 3], 1.0),
            &truth,
            CHAMFER_MESH_SAMPLES,
            sphere_bbox_diagonal(1.0),
        );
        eprintln!("{label}: {chamfer}");
        chamfers.push(chamfer.relative_average);
    }
    eprintln!("degree-1 sphere Chamfer at depths 6, 7, 8: {chamfers:?}");
    assert!(
        chamfers[0] > chamfers[1] && chamfers[1] > chamfers[2],
        "{chamfers:?}"
    );
    assert!(
        chamfers[2] <= SPHERE_DEPTH8_CHAMFER_BOUND,
        "degree-1 sphere depth 8: {:.4e} above {SPHERE_DEPTH8_CHAMFER_BOUND:e}",
        chamfers[2]
    );
}

/// Depth-8 degree-1 sphere Chamfer bound: psr measured 4.1436e-5 (depth 6: 7.6775e-5, depth 7:
/// 4.9922e-5); bound = that × 1.15. Degree 2 measures 1.5444e-5 on the same points and Open3D
/// 0.20 (PoissonRecon's degree 1) 1.73e-5 (`reconstruction.rs`): psr's degree 1 is 2.4× less
/// accurate than Open3D's here, a gap this bound records rather than hides. Neither the vertex
/// placement (on the isosurface: 3.991e-5) nor the point weight (4: 3.486e-5) explains it.
const SPHERE_DEPTH8_CHAMFER_BOUND: f64 = 4.77e-5;

/// Proves: degree 1 on the 100k-point torus (R = 1, r = 0.35) of `reconstruction.rs` keeps its
/// hole (Euler characteristic 0) at depths 7 and 8, and its Chamfer distance falls from depth
/// 7 to 8 to within `TORUS_DEPTH8_CHAMFER_BOUND`.
#[test]
fn degree_one_torus_keeps_its_hole_and_converges_with_depth() {
    let (positions, normals) = sample_torus(100_000, TORUS_MAJOR, TORUS_MINOR, 2);
    let points = point_set(&positions, &normals);
    let (truth, _) = sample_torus(CHAMFER_TRUE_SAMPLES, TORUS_MAJOR, TORUS_MINOR, 1002);
    let mut chamfers = Vec::new();
    for depth in [7, 8] {
        let label = format!("degree-1 torus depth {depth}");
        let params = Params::default().with_depth(depth).with_degree(1);
        let mesh = run(&points, &params, &label);
        assert_closed(&mesh, 0, &label);
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
    eprintln!("degree-1 torus Chamfer at depths 7, 8: {chamfers:?}");
    assert!(chamfers[0] > chamfers[1], "{chamfers:?}");
    assert!(
        chamfers[1] <= TORUS_DEPTH8_CHAMFER_BOUND,
        "degree-1 torus depth 8: {:.4e} above {TORUS_DEPTH8_CHAMFER_BOUND:e}",
        chamfers[1]
    );
}

/// Depth-8 degree-1 torus Chamfer bound: psr measured 3.5521e-5 (depth 7: 6.2627e-5); bound =
/// that × 1.15. Degree 2 measures 1.3157e-5 on the same points.
const TORUS_DEPTH8_CHAMFER_BOUND: f64 = 4.09e-5;

/// Proves: at degree 1 every boundary kind gives a closed sphere of one component at depth 7
/// (their face nodes are handled differently: see `octree::Octree::build_for`; Dirichlet once
/// gave 160 components here, from face nodes left in the coarse depths' cores), and one and
/// two threads give the same mesh bit for bit.
#[test]
fn degree_one_is_closed_for_every_boundary_and_independent_of_threads() {
    let (positions, normals) = sample_sphere(20_000, 1.0, [0.0; 3], 5);
    let points = point_set(&positions, &normals);
    for boundary in [Boundary::Neumann, Boundary::Free, Boundary::Dirichlet] {
        let label = format!("degree-1 sphere {boundary:?}");
        let params = Params::default()
            .with_depth(7)
            .with_degree(1)
            .with_boundary(boundary);
        let one = run(&points, &params.clone().with_threads(1), &label);
        assert_closed(&one, 2, &label);
        let two = run(&points, &params.with_threads(2), &label);
        assert_eq!(one.positions, two.positions, "{label}");
        assert_eq!(one.triangles, two.triangles, "{label}");
    }
}

/// Proves: a degree other than 1 or 2 is refused with an error naming the parameter (not a
/// panic), and `with_degree` sets the point weight to 2 × degree unless it is set after.
#[test]
fn bad_degrees_are_refused_and_the_point_weight_follows_the_degree() {
    let (positions, normals) = sample_sphere(2_000, 1.0, [0.0; 3], 3);
    let points = point_set(&positions, &normals);
    for degree in [0u8, 3, 7, 255] {
        let params = Params::default().with_depth(5).with_degree(degree);
        match reconstruct(&points, &params) {
            Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "degree"),
            other => panic!("degree {degree}: {other:?}"),
        }
    }
    assert_eq!(Params::default().point_weight, 4.0);
    assert_eq!(Params::default().with_degree(1).point_weight, 2.0);
    assert_eq!(Params::default().with_degree(2).point_weight, 4.0);
    let p = Params::default().with_degree(1).with_point_weight(4.0);
    assert_eq!((p.degree, p.point_weight), (1, 4.0));
}

/// Proves: samples so sparse that the density puts them at depth 0 reconstruct with degree 1
/// and Dirichlet boundaries, whose depth 0 has no node inside the cube (its corners are all on
/// the faces): they are splatted at depth 1 instead. Found by the `reconstruct` fuzz target
/// (`fuzz/regressions/reconstruct/`): the splat looked for a node depth 0 does not have and
/// panicked. With mirrors (Dirichlet, Neumann) both degrees give a closed mesh on the same cloud.
#[test]
fn samples_too_sparse_for_any_depth_reconstruct_with_degree_one_and_dirichlet() {
    // 24 points of the unit sphere, with the cube hugging them (scale 1): every sample's
    // density is below samples_per_node down to depth 0.
    let (positions, normals) = sample_sphere(24, 1.0, [0.0; 3], 17);
    let points = point_set(&positions, &normals);
    for degree in [1, 2] {
        for boundary in [Boundary::Dirichlet, Boundary::Neumann] {
            let params = Params::default()
                .with_degree(degree)
                .with_boundary(boundary)
                .with_depth(3)
                .with_scale(1.0)
                .with_threads(1);
            let label = format!("sparse sphere, degree {degree}, {boundary:?}");
            let mesh = run(&points, &params, &label);
            let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
            assert!(topo.is_closed_manifold(), "{label}: {topo}");
        }
    }
}

/// Proves: with degree 1 and Dirichlet boundaries, the leaves the mesh is extracted on tile the
/// cube when samples lie next to its faces, so the mesh is a closed, consistently oriented
/// 2-manifold. Degree-1 nodes sit on cell corners and Dirichlet keeps the face corners out of
/// the core, so a core node next to a face (index 1) has a face node for its parent; the
/// extraction read that parent's split flag as a core node's only, and the coarser leaf around
/// it overlapped the core node's cell:
/// edges in three triangles and in one (found by the `reconstruct` fuzz target,
/// `fuzz/regressions/reconstruct/degree1_dirichlet_scale1_folded_edges`: 67 points, depth 5).
/// Here the samples cover a box's faces and the cube is their bounding box (scale 1), at
/// depths 3 to 7, with the tree complete to depth 0 (adaptive from the root) and to the
/// default full depth, and a cloud with normals of random lengths and signs; and, at the
/// default scale 1.1, a sphere whose samples are read coarse (20 per node), so that the core
/// of the coarse depths reaches the faces (found by `scripts/topology_sweep.py`).
#[test]
fn degree_one_dirichlet_leaves_tile_the_cube_when_samples_touch_its_faces() {
    let (positions, normals) = sample_box(4_000, [1.0, 0.8, 0.6], 5);
    let mut rng = Rng::new(11);
    let random_normals: Vec<[f32; 3]> = (0..positions.len())
        .map(|_| std::array::from_fn(|_| rng.uniform(-3.0, 3.0) as f32))
        .collect();
    for (cloud, normals) in [("box", &normals), ("random normals", &random_normals)] {
        let points = point_set(&positions, normals);
        for depth in 3..=7 {
            for full_depth in [0, 5] {
                let params = Params::default()
                    .with_degree(1)
                    .with_boundary(Boundary::Dirichlet)
                    .with_scale(1.0)
                    .with_depth(depth)
                    .with_full_depth(full_depth)
                    .with_min_component_samples(0);
                let label = format!("{cloud}, depth {depth}, full depth {full_depth}");
                let mesh = run(&points, &params, &label);
                let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
                assert!(topo.is_closed_manifold(), "{label}: {topo}");
                assert!(topo.is_consistently_oriented(), "{label}: {topo}");
            }
        }
    }
    let (positions, normals) = sample_sphere(20_000, 1.0, [0.0; 3], 3);
    let points = point_set(&positions, &normals);
    let params = Params::default()
        .with_degree(1)
        .with_boundary(Boundary::Dirichlet)
        .with_depth(7)
        .with_full_depth(0)
        .with_kernel_depth(Some(5))
        .with_samples_per_node(20.0)
        .with_min_component_samples(0);
    let label = "sphere read coarse, scale 1.1";
    let mesh = run(&points, &params, label);
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    assert!(topo.is_closed_manifold(), "{label}: {topo}");
    assert!(topo.is_consistently_oriented(), "{label}: {topo}");
}

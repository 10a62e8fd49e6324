//! Tests of the shared test utilities (the `psr-test-support` crate in `test-support/`)
//! themselves: the samplers, the topology checks and the distances must be right before they can
//! judge a reconstruction. None of these needs the reconstruction core.

use psr_test_support::*;

fn tetrahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    // Counter-clockwise seen from outside.
    let triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    (positions, triangles)
}

fn unit_cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    for i in 0..8u32 {
        positions.push([(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]);
    }
    // Each face as a quad, counter-clockwise from outside; vertex index = x + 2y + 4z.
    let quads = [
        [0, 2, 3, 1], // z = 0, normal −z
        [4, 5, 7, 6], // z = 1, normal +z
        [0, 1, 5, 4], // y = 0, normal −y
        [2, 6, 7, 3], // y = 1, normal +y
        [0, 4, 6, 2], // x = 0, normal −x
        [1, 3, 7, 5], // x = 1, normal +x
    ];
    let mut triangles = Vec::new();
    for [a, b, c, d] in quads {
        triangles.push([a, b, c]);
        triangles.push([a, c, d]);
    }
    (positions, triangles)
}

fn shifted(
    mesh: &(Vec<[f32; 3]>, Vec<[u32; 3]>),
    by: [f32; 3],
    first_index: u32,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let positions = mesh
        .0
        .iter()
        .map(|p| [p[0] + by[0], p[1] + by[1], p[2] + by[2]])
        .collect();
    let triangles = mesh.1.iter().map(|t| t.map(|i| i + first_index)).collect();
    (positions, triangles)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

// --- PRNG ---------------------------------------------------------------------------------------

#[test]
fn rng_is_deterministic_and_uniform() {
    let a: Vec<u64> = {
        let mut r = Rng::new(42);
        (0..5).map(|_| r.next_u64()).collect()
    };
    let b: Vec<u64> = {
        let mut r = Rng::new(42);
        (0..5).map(|_| r.next_u64()).collect()
    };
    assert_eq!(a, b);
    assert_ne!(a, {
        let mut r = Rng::new(43);
        (0..5).map(|_| r.next_u64()).collect::<Vec<_>>()
    });
    // SplitMix64's published first output for seed 0.
    assert_eq!(Rng::new(0).next_u64(), 0xE220_A839_7B1D_CDAF);

    let mut r = Rng::new(7);
    let n = 200_000;
    let xs: Vec<f64> = (0..n).map(|_| r.next_f64()).collect();
    assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
    let mean = xs.iter().sum::<f64>() / n as f64;
    assert!(close(mean, 0.5, 0.005), "mean {mean}");
    let gs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
    let gmean = gs.iter().sum::<f64>() / n as f64;
    let gvar = gs.iter().map(|g| (g - gmean) * (g - gmean)).sum::<f64>() / n as f64;
    assert!(
        close(gmean, 0.0, 0.01) && close(gvar, 1.0, 0.02),
        "normal mean {gmean} var {gvar}"
    );
    let mut counts = [0usize; 7];
    for _ in 0..70_000 {
        counts[r.below(7) as usize] += 1;
    }
    assert!(
        counts.iter().all(|&c| (9_500..10_500).contains(&c)),
        "{counts:?}"
    );
}

// --- samplers -----------------------------------------------------------------------------------

#[test]
fn sphere_samples_lie_on_the_sphere_with_outward_normals_and_uniform_area() {
    let (radius, center) = (2.5, [1.0, -2.0, 0.5]);
    let (p, n) = sample_sphere(100_000, radius, center, 1);
    assert_eq!((p.len(), n.len()), (100_000, 100_000));
    let dist = sphere_distance(center, radius);
    let mut dot_sum = 0.0;
    let mut cap = 0;
    for (p, n) in p.iter().zip(&n) {
        let q = [p[0] as f64, p[1] as f64, p[2] as f64];
        assert!(dist(q) < 1e-5, "off the sphere by {}", dist(q));
        let nl = (n[0] as f64).hypot(n[1] as f64).hypot(n[2] as f64);
        assert!(close(nl, 1.0, 1e-6));
        let rel = [q[0] - center[0], q[1] - center[1], q[2] - center[2]];
        let d = (rel[0] * n[0] as f64 + rel[1] * n[1] as f64 + rel[2] * n[2] as f64) / radius;
        assert!(d > 0.999_999, "normal not radial: {d}");
        dot_sum += d;
        if rel[2] / radius > 0.5 {
            cap += 1;
        }
    }
    assert!(dot_sum / 100_000.0 > 0.0);
    // The cap z > r/2 has a quarter of the sphere's area (Archimedes).
    let frac = cap as f64 / 100_000.0;
    assert!(close(frac, 0.25, 0.005), "cap fraction {frac}");
    // Same seed, same points; other seed, other points.
    assert_eq!(sample_sphere(10, radius, center, 1).0, p[..10].to_vec());
    assert_ne!(sample_sphere(10, radius, center, 2).0, p[..10].to_vec());
    // A unit sphere at the origin: |p| = r.
    let (p, _) = sample_sphere(1000, 1.0, [0.0; 3], 3);
    assert!(p.iter().all(|p| close(
        (p[0] as f64).hypot(p[1] as f64).hypot(p[2] as f64),
        1.0,
        1e-6
    )));
}

#[test]
fn torus_samples_lie_on_the_torus_and_are_area_uniform() {
    let (big, small) = (1.0, 0.3);
    let n = 200_000;
    let (p, nrm) = sample_torus(n, big, small, 5);
    assert_eq!(p.len(), n);
    let dist = torus_distance(big, small);
    let mut outer = 0;
    for (p, nv) in p.iter().zip(&nrm) {
        let q = [p[0] as f64, p[1] as f64, p[2] as f64];
        assert!(dist(q) < 1e-6);
        // Outward: along p minus the nearest point of the core circle.
        let rho = q[0].hypot(q[1]);
        let core = [big * q[0] / rho, big * q[1] / rho, 0.0];
        let rel = [
            (q[0] - core[0]) / small,
            (q[1] - core[1]) / small,
            q[2] / small,
        ];
        let d = rel[0] * nv[0] as f64 + rel[1] * nv[1] as f64 + rel[2] * nv[2] as f64;
        assert!(d > 0.999_99, "normal not outward: {d}");
        if rho > big {
            outer += 1;
        }
    }
    // Area of the outer half (cos v > 0) over the total: (πR + 2r) / (2πR).
    let expected = 0.5 + small / (std::f64::consts::PI * big);
    let frac = outer as f64 / n as f64;
    assert!(
        close(frac, expected, 0.004),
        "outer fraction {frac}, expected {expected}"
    );
}

#[test]
fn nonuniform_sphere_density_varies_by_the_ratio() {
    let ratio = 10.0;
    let n = 200_000;
    let (p, nrm) = sample_sphere_nonuniform(n, 9, ratio);
    assert_eq!(p.len(), n);
    assert!(p.iter().zip(&nrm).all(|(p, n)| p == n));
    assert!(p.iter().all(|p| close(
        (p[0] as f64).hypot(p[1] as f64).hypot(p[2] as f64),
        1.0,
        1e-6
    )));
    // Caps of equal area (height 0.1) at each pole: their count ratio is the ratio of the
    // density integrated over z ∈ [0.9, 1] and z ∈ [−1, −0.9].
    let north = p.iter().filter(|p| p[2] > 0.9).count() as f64;
    let south = p.iter().filter(|p| p[2] < -0.9).count() as f64;
    let integral = |a: f64, b: f64| {
        let k = ratio.ln() / 2.0;
        (nonuniform_sphere_density(b, ratio) - nonuniform_sphere_density(a, ratio)) / k
    };
    let expected = integral(0.9, 1.0) / integral(-1.0, -0.9);
    assert!(expected > 8.5 && expected < 10.0);
    assert!(
        close(north / south, expected, 0.06 * expected),
        "north/south {} expected {expected}",
        north / south
    );
}

#[test]
fn normal_perturbations_have_the_requested_angles() {
    let (_, normals) = sample_sphere(20_000, 1.0, [0.0; 3], 11);
    let angle = 20f64.to_radians();
    let fixed = perturb_normals(&normals, angle, 12);
    for (a, b) in normals.iter().zip(&fixed) {
        assert!(close(angle_between(*a, *b), angle, 1e-5));
        let len = (b[0] as f64).hypot(b[1] as f64).hypot(b[2] as f64);
        assert!(close(len, 1.0, 1e-6));
    }
    // The azimuth is random: the perturbed normals' mean offset from the originals is ~0.
    let mut mean = [0.0f64; 3];
    for (a, b) in normals.iter().zip(&fixed) {
        for k in 0..3 {
            mean[k] += (b[k] - a[k]) as f64 / normals.len() as f64;
        }
    }
    let radial = mean.iter().map(|m| m * m).sum::<f64>().sqrt();
    // Only the component along the normal survives: 1 − cos θ ≈ 0.06 of length.
    assert!(radial < 0.07, "{mean:?}");

    let sigma = 10f64.to_radians();
    let noisy = perturb_normals_gaussian(&normals, sigma, 13);
    let angles: Vec<f64> = normals
        .iter()
        .zip(&noisy)
        .map(|(a, b)| angle_between(*a, *b))
        .collect();
    let mean_angle = angles.iter().sum::<f64>() / angles.len() as f64;
    let rms = (angles.iter().map(|a| a * a).sum::<f64>() / angles.len() as f64).sqrt();
    let expected_mean = sigma * (2.0 / std::f64::consts::PI).sqrt();
    assert!(
        close(mean_angle, expected_mean, 0.02 * expected_mean),
        "mean {mean_angle} vs {expected_mean}"
    );
    assert!(close(rms, sigma, 0.02 * sigma), "rms {rms} vs {sigma}");

    let (p, _) = sample_sphere(20_000, 1.0, [0.0; 3], 11);
    let jittered = jitter_positions(&p, 0.01, 14);
    let var = p
        .iter()
        .zip(&jittered)
        .map(|(a, b)| (0..3).map(|k| ((b[k] - a[k]) as f64).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (3.0 * p.len() as f64);
    assert!(
        close(var.sqrt(), 0.01, 0.0003),
        "jitter sigma {}",
        var.sqrt()
    );
}

// --- topology -----------------------------------------------------------------------------------

#[test]
fn tetrahedron_and_cube_are_closed_with_euler_two() {
    let (p, t) = tetrahedron();
    let topo = MeshTopology::of(&p, &t);
    assert!(
        topo.is_closed_manifold() && topo.is_consistently_oriented(),
        "{topo}"
    );
    assert_eq!(
        (topo.vertices, topo.edges, topo.faces, topo.euler),
        (4, 6, 4, 2)
    );
    assert_eq!((topo.components, topo.genus()), (1, Some(0)));
    assert!(close(signed_volume(&p, &t), 1.0 / 6.0, 1e-12));
    assert!(close(surface_area(&p, &t), 1.5 + 3f64.sqrt() / 2.0, 1e-12));

    let (p, t) = unit_cube();
    let topo = MeshTopology::of(&p, &t);
    assert!(
        topo.is_closed_manifold() && topo.is_consistently_oriented(),
        "{topo}"
    );
    assert_eq!(
        (topo.vertices, topo.edges, topo.faces, topo.euler),
        (8, 18, 12, 2)
    );
    assert_eq!(
        topo.duplicate_vertices + topo.degenerate_triangles + topo.unreferenced_vertices,
        0
    );
    assert!(close(signed_volume(&p, &t), 1.0, 1e-12));
    assert!(close(surface_area(&p, &t), 6.0, 1e-12));
    // Reversing every triangle flips the sign of the volume, not the topology.
    let flipped: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    assert!(close(signed_volume(&p, &flipped), -1.0, 1e-12));
    assert!(MeshTopology::of(&p, &flipped).is_consistently_oriented());
}

#[test]
fn open_square_has_four_boundary_edges() {
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let t = vec![[0, 1, 2], [0, 2, 3]];
    let topo = MeshTopology::of(&p, &t);
    assert_eq!(topo.boundary_edges, 4);
    assert_eq!((topo.edges, topo.euler, topo.components), (5, 1, 1));
    assert!(!topo.is_closed_manifold());
    assert_eq!(topo.genus(), None);
    // A tetrahedron with one face removed: 3 boundary edges.
    let (p, mut t) = tetrahedron();
    t.pop();
    let topo = MeshTopology::of(&p, &t);
    assert_eq!((topo.boundary_edges, topo.euler), (3, 1));
}

#[test]
fn non_manifold_edges_vertices_and_orientation_are_found() {
    // Three triangles on one edge.
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let t = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]];
    let topo = MeshTopology::of(&p, &t);
    assert_eq!(topo.non_manifold_edges, 1);
    assert_eq!(topo.boundary_edges, 6);
    assert!(!topo.is_closed_manifold());

    // Two tetrahedra touching at one vertex (a bow tie of solids): every edge is fine, the
    // shared vertex has two fans.
    let tet = tetrahedron();
    // The mirror image −p of the tetrahedron (triangles reversed to stay outward), glued at
    // the origin: its copy of vertex 0 (index 4) is replaced by vertex 0 and left unused.
    let other_positions: Vec<[f32; 3]> = tet.0.iter().map(|p| [-p[0], -p[1], -p[2]]).collect();
    let other_triangles: Vec<[u32; 3]> = tet
        .1
        .iter()
        .map(|t| [t[0] + 4, t[2] + 4, t[1] + 4])
        .collect();
    let mut p = tet.0.clone();
    p.extend(&other_positions);
    let mut t = tet.1.clone();
    t.extend(
        other_triangles
            .iter()
            .map(|t| t.map(|i| if i == 4 { 0 } else { i })),
    );
    let topo = MeshTopology::of(&p, &t);
    assert_eq!(
        (
            topo.non_manifold_vertices,
            topo.non_manifold_edges,
            topo.boundary_edges
        ),
        (1, 0, 0),
        "{topo}"
    );
    assert_eq!(
        (topo.vertices, topo.unreferenced_vertices, topo.components),
        (7, 1, 1)
    );
    assert_eq!(topo.euler, 7 - 12 + 8);
    assert!(!topo.is_closed_manifold());
    assert!(topo.is_consistently_oriented());
    assert!(close(signed_volume(&p, &t), 2.0 / 6.0, 1e-12));

    // One face of a tetrahedron flipped: its three edges are traversed twice the same way.
    let (p, mut t) = tetrahedron();
    t[3].swap(1, 2);
    let topo = MeshTopology::of(&p, &t);
    assert!(topo.is_closed_manifold());
    assert_eq!(topo.misoriented_edges, 3);
    assert!(!topo.is_consistently_oriented());
    assert_eq!(topo.genus(), None);
}

#[test]
fn components_duplicates_degenerates_and_invalid_triangles_are_counted() {
    let tet = tetrahedron();
    let far = shifted(&tet, [5.0, 0.0, 0.0], 4);
    let p: Vec<[f32; 3]> = tet.0.iter().chain(&far.0).copied().collect();
    let t: Vec<[u32; 3]> = tet.1.iter().chain(&far.1).copied().collect();
    let topo = MeshTopology::of(&p, &t);
    assert!(topo.is_closed_manifold());
    assert_eq!(
        (topo.components, topo.euler, topo.component_faces.clone()),
        (2, 4, vec![4, 4])
    );
    assert_eq!(topo.genus(), None);

    // An unshared copy of vertex 0 (same bits), a zero-area triangle and two invalid ones.
    let mut p = tet.0.clone();
    p.push(p[0]);
    p.push([0.5, 0.0, 0.0]); // on the edge 0–1
    let mut t = tet.1.clone();
    t.push([0, 1, 5]); // collinear: zero area
    t.push([0, 0, 1]); // repeated index
    t.push([0, 1, 99]); // out of range
    let topo = MeshTopology::of(&p, &t);
    assert_eq!(topo.duplicate_vertices, 1);
    assert_eq!(topo.degenerate_triangles, 1);
    assert_eq!(topo.invalid_triangles, 2);
    assert_eq!(topo.faces, 5);
    assert_eq!(topo.unreferenced_vertices, 1);
    assert!(!topo.is_closed_manifold());
    // −0.0 and 0.0 differ bitwise, so they are not duplicates.
    let topo = MeshTopology::of(&[[0.0, 0.0, 0.0], [-0.0, 0.0, 0.0]], &[]);
    assert_eq!(topo.duplicate_vertices, 0);
}

#[test]
fn reference_meshes_have_the_right_topology() {
    let (p, t) = octahedron();
    let topo = MeshTopology::of(&p, &t);
    assert!(topo.is_closed_manifold() && topo.is_consistently_oriented());
    assert_eq!(
        (topo.vertices, topo.edges, topo.faces, topo.genus()),
        (6, 12, 8, Some(0))
    );
    // Volume of the octahedron |x|+|y|+|z| ≤ 1: 4/3.
    assert!(close(signed_volume(&p, &t), 4.0 / 3.0, 1e-9));

    for k in 0..4 {
        let (p, t) = icosphere(k);
        let topo = MeshTopology::of(&p, &t);
        assert!(
            topo.is_closed_manifold() && topo.is_consistently_oriented(),
            "{topo}"
        );
        assert_eq!(
            (topo.faces, topo.euler, topo.components),
            (20 * 4usize.pow(k), 2, 1)
        );
        assert_eq!(topo.duplicate_vertices, 0);
        assert!(signed_volume(&p, &t) > 0.0);
    }
    let (p, t) = icosphere(5);
    let volume = signed_volume(&p, &t);
    assert!(
        close(volume, 4.0 / 3.0 * std::f64::consts::PI, 0.01),
        "{volume}"
    );

    let (p, t) = torus_mesh(1.0, 0.3, 64, 24);
    let topo = MeshTopology::of(&p, &t);
    assert!(
        topo.is_closed_manifold() && topo.is_consistently_oriented(),
        "{topo}"
    );
    assert_eq!((topo.euler, topo.genus()), (0, Some(1)));
    // Torus volume 2π²Rr² and area 4π²Rr, approached from below by the inscribed grid.
    let pi2 = std::f64::consts::PI.powi(2);
    let (volume, area) = (signed_volume(&p, &t), surface_area(&p, &t));
    assert!(
        volume < 2.0 * pi2 * 0.09 && volume > 0.98 * 2.0 * pi2 * 0.09,
        "{volume}"
    );
    assert!(
        area < 4.0 * pi2 * 0.3 && area > 0.98 * 4.0 * pi2 * 0.3,
        "{area}"
    );
}

// --- distances ----------------------------------------------------------------------------------

#[test]
fn point_triangle_distances_match_hand_values() {
    let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let d = |p: [f64; 3]| point_triangle_distance(p, a, b, c);
    // Above the interior: the height.
    assert!(close(d([0.2, 0.3, 5.0]), 5.0, 1e-12));
    assert!(close(d([0.2, 0.3, -0.5]), 0.5, 1e-12));
    // In the plane, inside: zero.
    assert_eq!(d([0.25, 0.25, 0.0]), 0.0);
    // Nearest a vertex.
    assert!(close(d([-1.0, -1.0, 0.0]), 2f64.sqrt(), 1e-12));
    assert!(close(d([2.0, -1.0, 1.0]), 3f64.sqrt(), 1e-12));
    // Nearest an edge: the hypotenuse x + y = 1 from (1, 1, 0) is √2/2; from (0.5, −2, 2), the
    // edge y = 0 at (0.5, 0, 0) is √8.
    assert!(close(d([1.0, 1.0, 0.0]), 0.5f64.sqrt(), 1e-12));
    assert!(close(d([0.5, -2.0, 2.0]), 8f64.sqrt(), 1e-12));
    let q = closest_point_on_triangle([1.0, 1.0, 3.0], a, b, c);
    assert!(close(q[0], 0.5, 1e-12) && close(q[1], 0.5, 1e-12) && close(q[2], 0.0, 1e-12));
    // Degenerate triangles: a segment and a point.
    assert!(close(
        point_triangle_distance([0.5, 1.0, 0.0], a, b, b),
        1.0,
        1e-12
    ));
    assert!(close(
        point_triangle_distance([0.0, 3.0, 4.0], a, a, a),
        5.0,
        1e-12
    ));
}

#[test]
fn bvh_queries_equal_brute_force() {
    let (p, t) = icosphere(3);
    let bvh = MeshDistance::new(&p, &t);
    assert_eq!(bvh.len(), t.len());
    let f = |i: u32| p[i as usize].map(|c| c as f64);
    let mut rng = Rng::new(21);
    for _ in 0..2000 {
        let r = rng.uniform(0.0, 3.0);
        let d = rng.unit_vector();
        let q = [d[0] * r, d[1] * r, d[2] * r];
        let brute = t
            .iter()
            .map(|tri| point_triangle_distance(q, f(tri[0]), f(tri[1]), f(tri[2])))
            .fold(f64::INFINITY, f64::min);
        let found = bvh.closest(q);
        assert!(
            close(found.distance, brute, 1e-12),
            "{} vs {brute}",
            found.distance
        );
        let tri = t[found.triangle];
        let again = point_triangle_distance(q, f(tri[0]), f(tri[1]), f(tri[2]));
        assert!(close(again, found.distance, 1e-12));
    }
    // Far away points, and an empty mesh.
    assert!(close(bvh.distance([100.0, 0.0, 0.0]), 99.0, 1e-6));
    assert_eq!(MeshDistance::new(&p, &[]).distance([0.0; 3]), f64::INFINITY);
}

#[test]
fn mesh_sampling_is_area_uniform_and_on_the_mesh() {
    // Two triangles with areas 1 and 3.
    let p = vec![
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 5.0],
        [3.0, 0.0, 5.0],
        [0.0, 2.0, 5.0],
    ];
    let t = vec![[0, 1, 2], [3, 4, 5]];
    let s = sample_mesh(&p, &t, 100_000, 3);
    assert_eq!(s.len(), 100_000);
    let upper = s.iter().filter(|q| q[2] > 2.5).count() as f64 / s.len() as f64;
    assert!(close(upper, 0.75, 0.006), "{upper}");
    let bvh = MeshDistance::new(&p, &t);
    assert!(s.iter().all(|q| bvh.distance(*q) < 1e-12));
    // Uniform within a triangle: a quarter of the lower triangle's samples fall in the corner
    // sub-triangle x/2 + y < 1/2 at the origin (half the size, so a quarter of the area).
    let lower: Vec<_> = s.iter().filter(|q| q[2] < 2.5).collect();
    let corner =
        lower.iter().filter(|q| q[0] / 2.0 + q[1] < 0.5).count() as f64 / lower.len() as f64;
    assert!(close(corner, 0.25, 0.01), "{corner}");
    assert_eq!(sample_mesh(&p, &t, 10, 3), s[..10].to_vec());
}

#[test]
fn octahedron_chamfer_to_the_unit_sphere_matches_quadrature() {
    // Reference values by independent quadrature (numpy, midpoint rules, converged to 7 digits):
    //  * mesh → sphere: the mean of 1 − |p| over the face x + y + z = 1 (x, y, z ≥ 0), which
    //    is 0 at the vertices and 1 − 1/√3 ≈ 0.423 at the centroid: 0.2982912;
    //  * sphere → mesh: the mean over the unit sphere of the distance to the face of the
    //    point's octant, (x + y + z − 1)/√3 where the projection falls inside the face (61 % of
    //    the sphere) and the distance to the nearest edge elsewhere: 0.2940433.
    let (m2t, t2m) = (0.298_291_2, 0.294_043_3);
    let (p, t) = octahedron();
    let (truth, _) = sample_sphere(400_000, 1.0, [0.0; 3], 31);
    let chamfer = chamfer_to_surface(
        &p,
        &t,
        sphere_distance([0.0; 3], 1.0),
        &truth,
        400_000,
        sphere_bbox_diagonal(1.0),
    );
    println!("{chamfer}");
    assert!(close(chamfer.mesh_to_true, m2t, 0.003 * m2t), "{chamfer}");
    assert!(close(chamfer.true_to_mesh, t2m, 0.003 * t2m), "{chamfer}");
    assert!(close(chamfer.symmetric, m2t + t2m, 0.003 * (m2t + t2m)));
    assert!(close(
        chamfer.relative,
        (m2t + t2m) / (2.0 * 3f64.sqrt()),
        0.003 * 0.171
    ));
    // Largest distances: the face centroid (1 − 1/√3) and the sphere point (1,1,1)/√3.
    assert!(close(
        chamfer.mesh_to_true_max,
        1.0 - 1.0 / 3f64.sqrt(),
        0.003
    ));
    assert!(close(
        chamfer.true_to_mesh_max,
        1.0 - 1.0 / 3f64.sqrt(),
        0.003
    ));
}

#[test]
fn chamfer_falls_as_an_icosphere_is_refined() {
    let (truth, _) = sample_sphere(50_000, 1.0, [0.0; 3], 41);
    let mut last = f64::INFINITY;
    for k in 1..6 {
        let (p, t) = icosphere(k);
        let c = chamfer_to_surface(
            &p,
            &t,
            sphere_distance([0.0; 3], 1.0),
            &truth,
            50_000,
            sphere_bbox_diagonal(1.0),
        );
        // Chord error: each refinement halves the edges, so the error falls about 4×.
        assert!(c.relative < last / 3.0, "level {k}: {c}");
        last = c.relative;
    }
    // A torus grid against the exact torus: small and symmetric-ish.
    let (p, t) = torus_mesh(1.0, 0.3, 256, 96);
    let (truth, _) = sample_torus(50_000, 1.0, 0.3, 42);
    let c = chamfer_to_surface(
        &p,
        &t,
        torus_distance(1.0, 0.3),
        &truth,
        50_000,
        torus_bbox_diagonal(1.0, 0.3),
    );
    assert!(c.relative < 1e-4, "{c}");
    assert!(close(
        torus_bbox_diagonal(1.0, 0.3),
        (2.6f64 * 2.6 * 2.0 + 0.36).sqrt(),
        1e-12
    ));
}

#[test]
fn one_sided_distance_statistics() {
    // A unit square at z = 0; points at heights 1, 2, ..., 100 above its interior.
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let t = vec![[0, 1, 2], [0, 2, 3]];
    let points: Vec<[f32; 3]> = (1..=100).map(|h| [0.3, 0.6, h as f32]).collect();
    let s = one_sided_mesh_distance(&points, &p, &t);
    assert_eq!(s.count, 100);
    assert!(close(s.mean, 50.5, 1e-9));
    assert!(close(s.median, 50.5, 1e-9));
    assert!(close(s.p95, 95.0, 1e-9));
    assert!(close(s.max, 100.0, 1e-9));
    let odd = DistanceStats::of(vec![3.0, 1.0, 2.0]);
    assert_eq!((odd.median, odd.p95, odd.max), (2.0, 3.0, 3.0));
}

// --- data ---------------------------------------------------------------------------------------

#[test]
fn shared_data_reads_and_the_reference_bunny_is_open() {
    let test = "shared_data_reads_and_the_reference_bunny_is_open";
    if let Some(path) = data_or_skip("kitten_cgal.ply", test) {
        let kitten = psr::ply::read_point_cloud(&path).unwrap();
        assert_eq!(kitten.positions.len(), 5210);
        assert_eq!(kitten.normals.len(), 5210);
    }
    if let Some(path) = data_or_skip("bunny_scans.reference.ply", test) {
        let (positions, triangles) = psr::ply::read_mesh(&path).unwrap();
        assert_eq!((positions.len(), triangles.len()), (35_947, 69_451));
        let topo = MeshTopology::of(&positions, &triangles);
        println!(
            "bunny reference: {topo}, volume {:.4e}",
            signed_volume(&positions, &triangles)
        );
        // The zippered reference has holes in the bottom.
        assert!(topo.boundary_edges > 0);
        assert!(signed_volume(&positions, &triangles) > 0.0);
    }
}

/// The real scans through `psr::ply`: sizes, unit normals, and colours where the file has them.
/// (Moved here from a unit test in src/ply.rs, which skipped silently without the data.)
#[test]
fn shared_scans_read_with_their_normals_and_colours() {
    let test = "shared_scans_read_with_their_normals_and_colours";
    if let Some(path) = data_or_skip("bunny_scans.ply", test) {
        let points = psr::ply::read_point_cloud(&path).unwrap();
        assert_eq!(points.len(), 362_272);
        assert!(points.colors.is_none() && points.confidence.is_none());
        let n = points.normals[1000];
        assert!(((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-4);
    }
    if let Some(path) = data_or_skip("lion_takanawa_rgb.ply", test) {
        let points = psr::ply::read_point_cloud(&path).unwrap();
        assert_eq!(points.colors.as_ref().map(|c| c.len()), Some(341_989));
        assert_eq!(points.color_type, psr::ply::ColorType::U8);
        assert!(
            points.channels.is_empty(),
            "x y z nx ny nz red green blue only"
        );
    }
}

// --- Scans with missing regions, boundaries, shapes of triangles --------------------------------

#[test]
fn captures_keep_the_side_facing_the_camera_and_the_plane() {
    let (p, n) = sample_sphere(20_000, 1.0, [0.0; 3], 3);
    let (seen, seen_normals) = capture_from(&p, &n, [0.0, 0.0, 10.0]);
    // A camera 10 radii away sees the cap above z = 1/10: (1 − 0.1) / 2 of the sphere.
    let share = seen.len() as f64 / p.len() as f64;
    assert!((share - 0.45).abs() < 0.02, "{share}");
    assert!(seen.iter().zip(&seen_normals).all(|(q, m)| {
        let to_camera = [-q[0], -q[1], 10.0 - q[2]];
        (0..3).map(|i| to_camera[i] * m[i]).sum::<f32>() > 0.0
    }));
    let (upper, _) = keep_above_plane(&p, &n, [0.0, 0.0, 1.0], 0.0);
    assert!(upper.iter().all(|q| q[2] >= 0.0));
    assert!((upper.len() as f64 / p.len() as f64 - 0.5).abs() < 0.02);
}

#[test]
fn boundary_loops_of_an_open_square_and_a_closed_cube() {
    // A 2 × 2 grid of squares, 8 triangles: one loop of the 8 outer vertices, counter-clockwise.
    let id = |i: u32, j: u32| j * 3 + i;
    let mut positions = Vec::new();
    for j in 0..3 {
        for i in 0..3 {
            positions.push([i as f32, j as f32, 0.0]);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..2 {
        for i in 0..2 {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    let loops = boundary_loops(&triangles).expect("one simple loop");
    assert_eq!(loops, vec![vec![0, 1, 2, 5, 8, 7, 6, 3]]);
    assert!(close(loop_length(&positions, &loops[0]), 8.0, 1e-12));
    // A closed mesh has none; a bowtie (two triangles sharing one vertex) is not simple.
    assert_eq!(boundary_loops(&unit_cube().1), Some(vec![]));
    assert_eq!(boundary_loops(&[[0, 1, 2], [0, 3, 4]]), None);
}

#[test]
fn excess_length_is_one_for_a_circle_and_more_for_a_sawtooth() {
    let n = 400;
    let ring = |bump: f64| -> Vec<[f32; 3]> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let r = 1.0 + if k % 2 == 0 { bump } else { -bump };
                [(r * a.cos()) as f32, (r * a.sin()) as f32, 0.0]
            })
            .collect()
    };
    let lp: Vec<u32> = (0..n as u32).collect();
    let edge = std::f64::consts::TAU / n as f64;
    let smooth = loop_excess_length(&ring(0.0), &lp, 2.0 * edge);
    assert!((smooth - 1.0).abs() < 1e-3, "{smooth}");
    // Teeth half an edge high: each edge becomes about √(1 + 1) times longer.
    let teeth = loop_excess_length(&ring(0.5 * edge), &lp, 2.0 * edge);
    assert!(teeth > 1.3, "{teeth}");
}

#[test]
fn triangle_quality_is_one_for_equilateral_and_small_for_slivers() {
    let h = 3f32.sqrt() / 2.0;
    assert!(close(
        triangle_quality([0.0; 3], [1.0, 0.0, 0.0], [0.5, h, 0.0]),
        1.0,
        1e-6
    ));
    assert!(triangle_quality([0.0; 3], [1.0, 0.0, 0.0], [0.5, 0.01, 0.0]) < 0.03);
    assert_eq!(
        triangle_quality([0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]),
        0.0
    );
}

#[test]
fn nearest_point_and_mesh_to_points_distances() {
    let points = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
    let d = nearest_point_distances(
        &[[0.1f32, 0.0, 0.0], [0.0, 1.5, 0.0], [3.0, 0.0, 0.0]],
        &points,
    );
    assert!(
        close(d[0], 0.1, 1e-6) && close(d[1], 0.5, 1e-6) && close(d[2], 2.0, 1e-6),
        "{d:?}"
    );
    // A unit square 1 above a point at its corner's foot: distances from √1 to √3.
    let (square, tris) = (
        vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let stats = mesh_to_points_distance(&square, &tris, &[[0.0, 0.0, 0.0]], 20_000, 1);
    assert!(
        stats.max <= 3f64.sqrt() + 1e-6 && stats.median > 1.0,
        "{stats}"
    );
    // Mean of √(1 + x² + y²) over the unit square: 1.2808.
    assert!(close(stats.mean, 1.2808, 0.01), "{stats}");
}

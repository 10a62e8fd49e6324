//! The implicit function as a product (issue 17): χ kept after a reconstruction, evaluated at
//! points, differentiated, and sampled on a grid.
//!
//! What is shown, on a sphere of radius 1 off the origin:
//! * the grid is point evaluation: every grid value is `value` at its `grid_point`, rounded to
//!   f32, bit for bit, and the batch functions agree with the single-point ones; the same
//!   whatever the thread count; the layout is z fastest (NumPy C order for `[x][y][z]`);
//! * χ − γ is negative inside and positive outside, and ∇χ/|∇χ| is the outward normal: within
//!   a few degrees of the true sphere's, and of the mesh's vertex normals;
//! * the zero crossing of χ − γ along rays from the centre lies within one finest cell of the
//!   true sphere, and the gradient in input units matches a finite difference;
//! * keeping χ does not change the mesh;
//! * outside the cube, NaN queries, bad resolutions and boxes: defined values or clear errors,
//!   never a panic.

use psr::{
    reconstruct, reconstruct_with_implicit, Error, ImplicitFunction, Mesh, Params, PointSet,
    MAX_GRID_RESOLUTION,
};
use psr_test_support::{sample_sphere, Rng};

const CENTER: [f64; 3] = [0.25, -0.5, 1.0];
const DEPTH: u32 = 6;

fn sphere(threads: usize) -> (Mesh, ImplicitFunction) {
    let (positions, normals) = sample_sphere(20_000, 1.0, CENTER, 17);
    let points = PointSet::from_slices(&positions, &normals).unwrap();
    let params = Params::default()
        .with_depth(DEPTH)
        .with_threads(threads)
        .with_vertex_normals(true);
    reconstruct_with_implicit(&points, &params).unwrap()
}

fn add(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    a.map(|c| c / n)
}

#[test]
fn the_grid_is_point_evaluation_at_its_cell_centres() {
    let (_, chi) = sphere(0);
    let n = 24;
    let grid = chi.sample_grid(n).unwrap();
    assert_eq!(grid.len(), n * n * n);
    let (origin, size) = chi.cube();
    let max = origin.map(|o| o + size);
    let mut f32_points = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let p = ImplicitFunction::grid_point(origin, max, n, [i, j, k]);
                // z fastest: NumPy C order for an [x][y][z] array.
                let at = (i * n + j) * n + k;
                assert_eq!(
                    grid[at].to_bits(),
                    (chi.value(p) as f32).to_bits(),
                    "cell {i} {j} {k}"
                );
                // The documented cell centres.
                for a in 0..3 {
                    let index = [i, j, k][a] as f64;
                    let expected = origin[a] + (index + 0.5) * size / n as f64;
                    assert!((p[a] - expected).abs() <= 1e-12 * size, "{p:?}");
                }
                f32_points.push(p.map(|c| c as f32));
            }
        }
    }
    // The batch functions (parallel for this many points) agree with the single-point ones.
    let values = chi.values(&f32_points).unwrap();
    let gradients = chi.gradients(&f32_points).unwrap();
    for (at, p) in f32_points.iter().enumerate() {
        let p = p.map(f64::from);
        assert_eq!(values[at].to_bits(), (chi.value(p) as f32).to_bits());
        assert_eq!(gradients[at], chi.gradient(p).map(|g| g as f32));
    }
    // A box of the user's over part of the cube: the same rule.
    let lo = [CENTER[0] - 0.3, CENTER[1], CENTER[2] - 1.2];
    let hi = [CENTER[0] + 0.1, CENTER[1] + 0.5, CENTER[2] + 1.2];
    let boxed = chi.sample_box(lo, hi, 7).unwrap();
    for i in 0..7 {
        for j in 0..7 {
            for k in 0..7 {
                let p = ImplicitFunction::grid_point(lo, hi, 7, [i, j, k]);
                assert_eq!(boxed[(i * 7 + j) * 7 + k], chi.value(p) as f32);
            }
        }
    }
}

#[test]
fn the_grid_does_not_depend_on_the_thread_count() {
    let (_, one) = sphere(1);
    let (_, two) = sphere(2);
    assert_eq!(one.isovalue().to_bits(), two.isovalue().to_bits());
    let a = one.sample_grid(40).unwrap();
    let b = two.sample_grid(40).unwrap();
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}

#[test]
fn keeping_chi_does_not_change_the_mesh() {
    let (positions, normals) = sample_sphere(20_000, 1.0, CENTER, 17);
    let points = PointSet::from_slices(&positions, &normals).unwrap();
    let params = Params::default()
        .with_depth(DEPTH)
        .with_vertex_normals(true);
    let plain = reconstruct(&points, &params).unwrap();
    let (kept, chi) = sphere(0);
    assert_eq!(plain.positions, kept.positions);
    assert_eq!(plain.triangles, kept.triangles);
    assert_eq!(chi.isovalue(), kept.stats.isovalue);
    assert_eq!(chi.depth(), kept.stats.finest_depth());
}

#[test]
fn chi_minus_gamma_is_negative_inside_and_its_gradient_points_outward() {
    let (mesh, chi) = sphere(0);
    let gamma = chi.isovalue();
    let (origin, size) = chi.cube();
    let mut rng = Rng::new(5);
    let mut worst_angle: f64 = 0.0;
    for _ in 0..2000 {
        let d = rng.unit_vector();
        for r in [0.0, 0.3, 0.6, 0.85] {
            let p = add(CENTER, d, r);
            assert!(chi.value(p) < gamma, "inside at r = {r}: {}", chi.value(p));
        }
        for r in [1.15, 1.3] {
            let p = add(CENTER, d, r);
            if (0..3).all(|a| p[a] > origin[a] && p[a] < origin[a] + size) {
                assert!(chi.value(p) > gamma, "outside at r = {r}: {}", chi.value(p));
            }
        }
        // On the sphere, ∇χ is along the outward normal d.
        let g = chi.gradient(add(CENTER, d, 1.0));
        let cos = dot(unit(g), d);
        worst_angle = worst_angle.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
    }
    println!("worst angle between grad chi and the sphere's normal: {worst_angle:.2} degrees");
    assert!(worst_angle < 5.0, "{worst_angle}");
    // The mesh's vertex normals (outward) are ∇χ/|∇χ| at the vertices.
    let mut worst_mesh: f64 = 0.0;
    for (v, n) in mesh.positions.iter().zip(&mesh.normals) {
        let g = chi.gradient(v.map(f64::from));
        let cos = dot(unit(g), n.map(f64::from));
        worst_mesh = worst_mesh.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
    }
    println!("worst angle between grad chi and the mesh's vertex normals: {worst_mesh:.3} degrees");
    assert!(worst_mesh < 1.0, "{worst_mesh}");
}

#[test]
fn the_zero_crossing_lies_within_a_cell_of_the_sphere() {
    let (_, chi) = sphere(0);
    let gamma = chi.isovalue();
    let (_, size) = chi.cube();
    let cell = size / f64::from(1u32 << chi.depth());
    let mut rng = Rng::new(9);
    let mut worst: f64 = 0.0;
    for _ in 0..500 {
        let d = rng.unit_vector();
        let f = |r: f64| chi.value(add(CENTER, d, r)) - gamma;
        let (mut lo, mut hi) = (0.5, 1.05);
        assert!(f(lo) < 0.0 && f(hi) > 0.0, "{} {}", f(lo), f(hi));
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        worst = worst.max((lo - 1.0).abs());
    }
    println!("worst |radius of the zero crossing - 1|: {worst:.5} (cell {cell:.5})");
    assert!(worst < cell, "{worst} >= {cell}");
}

#[test]
fn the_gradient_is_the_derivative_in_input_units() {
    let (_, chi) = sphere(0);
    let mut rng = Rng::new(3);
    let h = 1e-5;
    for _ in 0..200 {
        let p = add(CENTER, rng.unit_vector(), rng.uniform(0.2, 1.1));
        let g = chi.gradient(p);
        let scale = dot(g, g).sqrt().max(1e-3);
        for a in 0..3 {
            let mut e = [0.0; 3];
            e[a] = 1.0;
            let fd = (chi.value(add(p, e, h)) - chi.value(add(p, e, -h))) / (2.0 * h);
            assert!(
                (fd - g[a]).abs() < 1e-3 * scale,
                "{p:?} axis {a}: {fd} vs {}",
                g[a]
            );
        }
    }
}

#[test]
fn outside_the_cube_chi_is_continued_constantly() {
    let (_, chi) = sphere(0);
    let (origin, size) = chi.cube();
    let inside = [origin[0] + 0.3 * size, origin[1] + 0.6 * size, origin[2]];
    let far = [inside[0], inside[1], origin[2] - 5.0 * size];
    assert_eq!(chi.value(far), chi.value(inside));
    let g_in = chi.gradient(inside);
    let g_far = chi.gradient(far);
    assert_eq!([g_far[0], g_far[1], g_far[2]], [g_in[0], g_in[1], 0.0]);
    for p in [[1e300, 0.0, 0.0], [-1e300, -1e300, 1e300], [f64::MAX; 3]] {
        assert!(chi.value(p).is_finite());
        assert!(chi.gradient(p).iter().all(|g| g.is_finite()));
    }
    // A box reaching far outside the cube samples without trouble.
    let grid = chi
        .sample_box(origin.map(|o| o - size), origin.map(|o| o + 2.0 * size), 9)
        .unwrap();
    assert!(grid.iter().all(|v| v.is_finite()));
}

#[test]
fn bad_queries_and_resolutions_are_clear_errors() {
    let (_, chi) = sphere(0);
    assert!(chi.value([f64::NAN, 0.0, 0.0]).is_nan());
    assert!(chi.value([0.0, f64::INFINITY, 0.0]).is_nan());
    assert!(chi
        .gradient([0.0, 0.0, f64::NAN])
        .iter()
        .all(|g| g.is_nan()));
    let points = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [0.0, f32::NAN, 0.0]];
    assert_eq!(
        chi.values(&points),
        Err(Error::NonFinitePosition { index: 2 })
    );
    assert_eq!(
        chi.gradients(&points[1..]).unwrap_err(),
        Error::NonFinitePosition { index: 1 }
    );
    assert_eq!(chi.values(&[]).unwrap(), Vec::<f32>::new());
    for resolution in [0, MAX_GRID_RESOLUTION + 1, 1 << 22, usize::MAX] {
        match chi.sample_grid(resolution) {
            Err(
                e @ Error::InvalidParameter {
                    name: "resolution", ..
                },
            ) => {
                let message = e.to_string();
                assert!(message.contains(&resolution.to_string()), "{message}");
            }
            other => panic!("resolution {resolution}: {other:?}"),
        }
    }
    let (origin, size) = chi.cube();
    let max = origin.map(|o| o + size);
    for (lo, hi) in [
        (max, origin),
        ([f64::NAN, 0.0, 0.0], max),
        (origin, [f64::INFINITY, 0.0, 0.0]),
    ] {
        assert!(
            matches!(
                chi.sample_box(lo, hi, 4),
                Err(Error::InvalidParameter { name: "box", .. })
            ),
            "{lo:?} {hi:?}"
        );
    }
    // A flat box is a valid slice.
    let slice = chi
        .sample_box(origin, [max[0], max[1], origin[2]], 5)
        .unwrap();
    assert_eq!(slice.len(), 125);
}

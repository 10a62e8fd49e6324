//! Bad and degenerate input through the Rust API: every one returns an `Err` whose message says
//! what is wrong and where (the index, the field), or, for inputs that are unusual but valid,
//! a closed mesh; nothing panics (a panic fails the test).

use psr::{reconstruct, reconstruct_with_progress, Error, Params, PointSet, Stage};
use psr_test_support::{sample_sphere, MeshTopology, Rng};

const UP: [f32; 3] = [0.0, 0.0, 1.0];

/// A small valid point set: 200 points of the unit sphere with outward normals.
fn sphere() -> PointSet {
    let (p, n) = sample_sphere(200, 1.0, [0.0; 3], 5);
    PointSet::from_slices(&p, &n).unwrap()
}

/// Asserts `message` contains every one of `parts`.
fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "error message {message:?} does not mention {part:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Points
// ---------------------------------------------------------------------------------------------

/// Proves: reconstructing no points is `Error::EmptyInput` (for a fresh set, one built from empty
/// slices, and one emptied by `clear`), with a message that says what to do.
#[test]
fn empty_input_is_an_error() {
    let empty = PointSet::from_slices(&[], &[]).unwrap();
    let mut cleared = sphere();
    cleared.clear();
    for points in [PointSet::new(), empty, cleared] {
        let err = reconstruct(&points, &Params::default()).unwrap_err();
        assert_eq!(err, Error::EmptyInput);
        assert_mentions(&err.to_string(), &["no input points"]);
    }
}

/// Proves: a NaN or infinite coordinate is rejected by `PointSet::from_slices` with
/// `NonFinitePosition` naming the first bad index, and the message names it too.
#[test]
fn non_finite_positions_are_rejected_with_their_index() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for axis in 0..3 {
            let mut positions = vec![[0.5f32, 0.25, 0.125]; 10];
            positions[7][axis] = bad;
            positions[9][axis] = bad; // only the first bad index is reported
            let err = PointSet::from_slices(&positions, &[UP; 10]).unwrap_err();
            assert_eq!(
                err,
                Error::NonFinitePosition { index: 7 },
                "{bad} on axis {axis}"
            );
            assert_mentions(&err.to_string(), &["point 7", "NaN or infinite"]);
        }
    }
}

/// Proves: a NaN or infinite normal component is `NonFiniteNormal` with its index.
#[test]
fn non_finite_normals_are_rejected_with_their_index() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut normals = vec![UP; 6];
        normals[4] = [1.0, bad, 0.0];
        let err = PointSet::from_slices(&[[0.0; 3]; 6], &normals).unwrap_err();
        assert_eq!(err, Error::NonFiniteNormal { index: 4 }, "{bad}");
        assert_mentions(&err.to_string(), &["normal 4", "NaN or infinite"]);
    }
    // A position error comes first when both are bad at the same index.
    let err = PointSet::from_slices(&[[f32::NAN; 3]], &[[f32::NAN; 3]]).unwrap_err();
    assert_eq!(err, Error::NonFinitePosition { index: 0 });
}

/// Proves: a zero-length normal (or one too short to normalise, 1e-30, below the 1e-20 cut)
/// is `ZeroNormal` with its index, while a short but usable normal is accepted and normalised.
#[test]
fn zero_normals_are_rejected_with_their_index() {
    for bad in [[0.0f32; 3], [-0.0, 0.0, -0.0], [1e-30, 0.0, 0.0]] {
        let mut normals = vec![UP; 5];
        normals[2] = bad;
        let err = PointSet::from_slices(&[[1.0; 3]; 5], &normals).unwrap_err();
        assert_eq!(err, Error::ZeroNormal { index: 2 }, "{bad:?}");
        assert_mentions(&err.to_string(), &["normal 2", "zero length"]);
    }
    let short = PointSet::from_slices(&[[1.0; 3]], &[[0.0, 3e-10, 0.0]]).unwrap();
    assert_eq!(short.normals()[0], [0.0, 1.0, 0.0]);
}

/// Proves: normals (or weights) of a different length than the positions are `LengthMismatch`,
/// the message giving both lengths and which array is wrong; a failed batch appends nothing.
#[test]
fn mismatched_lengths_are_rejected() {
    let err = PointSet::from_slices(&[[0.0; 3]; 3], &[UP; 2]).unwrap_err();
    assert_eq!(
        err,
        Error::LengthMismatch {
            what: "normals",
            positions: 3,
            other: 2
        }
    );
    assert_mentions(
        &err.to_string(),
        &["normals", "2 entries", "positions has 3"],
    );

    let mut points = sphere();
    let err = points
        .extend_weighted(&[[0.0; 3]; 4], &[UP; 4], Some(&[1.0; 5]))
        .unwrap_err();
    assert_eq!(
        err,
        Error::LengthMismatch {
            what: "weights",
            positions: 4,
            other: 5
        }
    );
    assert_mentions(
        &err.to_string(),
        &["weights", "5 entries", "positions has 4"],
    );
    assert_eq!(points.len(), 200, "a failed batch must append nothing");
}

/// Proves: confidence weights must be finite and ≥ 0 (`InvalidWeight` with the index), and a
/// set whose weights are all zero, which carries no information, is an error at reconstruction
/// rather than a meaningless mesh; some zero weights among positive ones are fine.
#[test]
fn invalid_and_all_zero_weights_are_errors() {
    let (p, n) = sample_sphere(100, 1.0, [0.0; 3], 9);
    for bad in [-1.0f32, f32::NAN, f32::INFINITY] {
        let mut w = vec![1.0f32; 100];
        w[42] = bad;
        let mut points = PointSet::new();
        let err = points.extend_weighted(&p, &n, Some(&w)).unwrap_err();
        assert_eq!(err, Error::InvalidWeight { index: 42 }, "{bad}");
        assert_mentions(&err.to_string(), &["weight 42", "finite and >= 0"]);
    }

    let mut zero = PointSet::new();
    zero.extend_weighted(&p, &n, Some(&[0.0; 100])).unwrap();
    let err = reconstruct(&zero, &Params::default().with_depth(5)).unwrap_err();
    eprintln!("all-zero weights: {err}");
    assert_eq!(err, Error::NoPositiveWeight);
    assert_mentions(&err.to_string(), &["every confidence weight is 0"]);

    // Half the points at zero weight: those points are simply ignored (2000 points, so the 1000
    // that count still sample the sphere densely enough for a closed mesh at depth 6).
    let (p, n) = sample_sphere(2000, 1.0, [0.0; 3], 10);
    let mut some_zero = PointSet::new();
    let w: Vec<f32> = (0..2000)
        .map(|i| if i % 2 == 0 { 0.0 } else { 1.0 })
        .collect();
    some_zero.extend_weighted(&p, &n, Some(&w)).unwrap();
    let mesh = reconstruct(&some_zero, &Params::default().with_depth(6)).unwrap();
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    assert!(topo.is_closed_manifold() && topo.euler == 2, "{topo}");
}

// ---------------------------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------------------------

/// Proves: every `Params` field out of its documented range is `Error::InvalidParameter` naming
/// that field (in the error and in its message, with the offending value), from `validate` and
/// from `reconstruct` alike, before any work is done; the range ends themselves are accepted.
#[test]
fn out_of_range_parameters_name_the_field() {
    let d = Params::default;
    let cases: Vec<(&str, Params, &str)> = vec![
        ("depth", d().with_depth(0), "0"),
        ("depth", d().with_depth(17), "17"),
        ("full_depth", d().with_full_depth(17), "17"),
        (
            "kernel_depth",
            d().with_depth(8).with_kernel_depth(Some(9)),
            "9",
        ),
        ("samples_per_node", d().with_samples_per_node(0.0), "0"),
        ("samples_per_node", d().with_samples_per_node(0.5), "0.5"),
        (
            "samples_per_node",
            d().with_samples_per_node(f32::NAN),
            "NaN",
        ),
        (
            "samples_per_node",
            d().with_samples_per_node(f32::INFINITY),
            "inf",
        ),
        ("scale", d().with_scale(0.5), "0.5"),
        ("scale", d().with_scale(f32::INFINITY), "inf"),
        ("scale", d().with_scale(f32::NAN), "NaN"),
        ("point_weight", d().with_point_weight(-1.0), "-1"),
        ("point_weight", d().with_point_weight(f32::NAN), "NaN"),
        ("point_weight", d().with_point_weight(f32::INFINITY), "inf"),
        ("threads", d().with_threads(5000), "5000"),
        ("solver_tolerance", d().with_solver_tolerance(0.0), "0"),
        ("solver_tolerance", d().with_solver_tolerance(1.0), "1"),
        (
            "solver_tolerance",
            d().with_solver_tolerance(f64::NAN),
            "NaN",
        ),
        (
            "max_solver_iterations",
            d().with_max_solver_iterations(0),
            "0",
        ),
        (
            "max_solver_iterations",
            d().with_max_solver_iterations(10_001),
            "10001",
        ),
    ];
    let points = sphere();
    for (field, params, value) in cases {
        let from_validate = params.validate().unwrap_err();
        let from_reconstruct = reconstruct(&points, &params).unwrap_err();
        assert_eq!(from_validate, from_reconstruct, "{field}");
        match &from_reconstruct {
            Error::InvalidParameter {
                name, value: shown, ..
            } => {
                assert_eq!(*name, field, "{params:?}");
                assert_eq!(shown, value, "{field}");
            }
            other => panic!("{field}: expected InvalidParameter, got {other:?}"),
        }
        let message = from_reconstruct.to_string();
        assert_mentions(
            &message,
            &[
                &format!("parameter {field} = {value}"),
                "out of range",
                "expected",
            ],
        );
        // The empty-input check must not hide a bad parameter (or the other way round).
        assert!(matches!(
            reconstruct(&PointSet::new(), &params),
            Err(Error::InvalidParameter { .. })
        ));
    }

    let ok = [
        Params::default(),
        d().with_depth(1),
        d().with_depth(16),
        d().with_full_depth(0),
        d().with_kernel_depth(Some(0)),
        d().with_kernel_depth(Some(8)),
        d().with_samples_per_node(1.0),
        d().with_scale(1.0),
        d().with_scale(100.0),
        d().with_point_weight(0.0),
        d().with_solver_tolerance(1e-12),
        d().with_max_solver_iterations(1),
        d().with_max_solver_iterations(10_000),
    ];
    for params in ok {
        assert_eq!(params.validate(), Ok(()), "{params:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Degenerate but valid input
// ---------------------------------------------------------------------------------------------

/// Reconstructs a degenerate input and accepts either a clear error (anything but
/// `Error::Internal`, which marks a bug) or a mesh that is a consistently oriented 2-manifold,
/// closed everywhere except where it meets the bounding cube. Returns a one-line description.
///
/// Why not require a closed mesh: for a plane, a line or a point the Poisson solution's
/// isosurface is itself unbounded (for a disc with one normal it is the disc's plane, by
/// symmetry of the double layer), so the correct result is a surface cut off by the cube, as
/// PoissonRecon also gives. What must hold is that every boundary edge lies on the cube's faces:
/// a hole anywhere else would be an extraction bug.
fn closed_in_cube_or_clear_error(
    label: &str,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    depth: u32,
) -> String {
    let points = PointSet::from_slices(positions, normals).unwrap();
    let params = Params::default().with_depth(depth);
    let outcome = match reconstruct(&points, &params) {
        Ok(mesh) => {
            let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
            assert!(
                mesh.positions.iter().flatten().all(|c| c.is_finite()),
                "{label}: non-finite vertex"
            );
            assert_eq!(topo.invalid_triangles, 0, "{label}: {topo}");
            assert_eq!(topo.non_manifold_edges, 0, "{label}: {topo}");
            assert_eq!(topo.non_manifold_vertices, 0, "{label}: {topo}");
            assert!(topo.is_consistently_oriented(), "{label}: {topo}");
            assert_eq!(mesh.densities.len(), mesh.positions.len(), "{label}");
            // Boundary edges: only on the cube's faces (within a quarter of a finest cell, which
            // also covers the f32 rounding of the vertex positions).
            let (origin, size) = bounding_cube(positions, params.scale as f64);
            let tolerance = 0.25 * (-(depth as f64)).exp2();
            let on_face = |v: u32| {
                let p = mesh.positions[v as usize];
                let q: [f64; 3] = std::array::from_fn(|a| (p[a] as f64 - origin[a]) / size);
                q.iter().any(|&c| c <= tolerance || c >= 1.0 - tolerance)
            };
            let mut uses = std::collections::HashMap::new();
            for t in &mesh.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                }
            }
            let inner_holes = uses
                .iter()
                .filter(|&(&(a, b), &n)| n == 1 && !(on_face(a) && on_face(b)))
                .count();
            assert_eq!(
                inner_holes, 0,
                "{label}: {inner_holes} boundary edges away from the cube faces: {topo}"
            );
            format!("{label}: Ok, {topo}")
        }
        Err(Error::Internal(message)) => panic!("{label}: internal error (a bug): {message}"),
        Err(err) => {
            assert!(!err.to_string().is_empty());
            format!("{label}: Err({err})")
        }
    };
    eprintln!("{outcome}");
    outcome
}

/// The cube psr reconstructs in, as `Params::scale` documents it: centred on the points' bounding
/// box, with edge `scale` × the box's longest side (> 0 for every input that gives a mesh).
/// Returns its lowest corner and its edge.
fn bounding_cube(positions: &[[f32; 3]], scale: f64) -> ([f64; 3], f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    let size = scale * (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    (
        std::array::from_fn(|a| (lo[a] + hi[a]) / 2.0 - size / 2.0),
        size,
    )
}

/// Proves: inputs with no volume to enclose, or far fewer distinct points than samples, do not
/// panic and give either a clear error or a mesh that is closed inside the bounding cube (see
/// `closed_in_cube_or_clear_error`): 10k copies each of 3 points, 1000 identical points, a
/// single point (at the origin and elsewhere), 1000 collinear points, a disc of coplanar points
/// with one normal, and spheres at extreme but finite scales and offsets.
#[test]
fn coincident_points_are_a_clear_error() {
    for n in [1usize, 1000] {
        let points = PointSet::from_slices(&vec![[2.0, -3.0, 4.0]; n], &vec![UP; n]).unwrap();
        let err = reconstruct(&points, &Params::default().with_depth(6)).unwrap_err();
        assert_eq!(err, Error::DegenerateInput { points: n });
        assert_mentions(&err.to_string(), &["coincide"]);
    }
}

#[test]
fn degenerate_inputs_do_not_panic() {
    let three = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let three_normals = [[-1.0f32, -1.0, 1.0], [1.0, 0.0, 0.2], [0.0, 1.0, 0.2]];
    let copies: Vec<[f32; 3]> = (0..30_000).map(|i| three[i % 3]).collect();
    let copies_n: Vec<[f32; 3]> = (0..30_000).map(|i| three_normals[i % 3]).collect();
    closed_in_cube_or_clear_error("10k copies of 3 points", &copies, &copies_n, 8);

    closed_in_cube_or_clear_error(
        "1000 identical points",
        &[[2.0, -3.0, 4.0]; 1000],
        &[UP; 1000],
        8,
    );
    closed_in_cube_or_clear_error("one point", &[[2.0, -3.0, 4.0]], &[UP], 8);
    closed_in_cube_or_clear_error("one point at the origin", &[[0.0; 3]], &[UP], 8);

    let line: Vec<[f32; 3]> = (0..1000)
        .map(|i| [i as f32 * 1e-3, 2.0 * i as f32 * 1e-3, 0.5])
        .collect();
    closed_in_cube_or_clear_error("1000 collinear points", &line, &[UP; 1000], 8);

    let mut disc = Vec::new();
    let mut rng = Rng::new(12);
    while disc.len() < 5000 {
        let (x, y) = (rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
        if x * x + y * y <= 1.0 {
            disc.push([x as f32, y as f32, 0.25]);
        }
    }
    closed_in_cube_or_clear_error(
        "5000 coplanar points (a disc)",
        &disc,
        &vec![UP; disc.len()],
        8,
    );

    // Extreme scales and offsets (f32 keeps 24 bits, so at an offset of 1e4 the unit sphere's
    // points are still resolved to 1e-3 of its radius).
    for (label, radius, center) in [
        ("sphere of radius 1e30", 1e30, [0.0; 3]),
        ("sphere of radius 1e-30", 1e-30, [0.0; 3]),
        ("unit sphere at 1e4", 1.0, [1e4, -1e4, 1e4]),
    ] {
        let (p, n) = sample_sphere(2000, radius, center, 13);
        let outcome = closed_in_cube_or_clear_error(label, &p, &n, 6);
        // A well-sampled sphere is not degenerate: whatever its scale or offset, it must come
        // out as a closed sphere.
        let mesh = reconstruct(
            &PointSet::from_slices(&p, &n).unwrap(),
            &Params::default().with_depth(6),
        )
        .unwrap();
        let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
        assert!(
            topo.is_closed_manifold() && topo.euler == 2 && topo.components == 1,
            "{outcome}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Cancellation
// ---------------------------------------------------------------------------------------------

/// Proves: a progress callback that returns `false` stops the reconstruction with
/// `Error::Cancelled`, whether it does so at the first report or in the middle of the solve, and
/// it is not called again after it said stop.
#[test]
fn progress_callback_can_cancel() {
    let points = sphere();
    for stop_at in [Stage::Points, Stage::Octree, Stage::Solve, Stage::Extract] {
        let mut calls_after_stop = 0;
        let mut stopped = false;
        let mut callback = |stage: Stage, _fraction: f32| {
            if stopped {
                calls_after_stop += 1;
            }
            if stage == stop_at {
                stopped = true;
            }
            !stopped
        };
        let err =
            reconstruct_with_progress(&points, &Params::default().with_depth(6), &mut callback)
                .unwrap_err();
        assert_eq!(err, Error::Cancelled, "stop at {stop_at:?}");
        assert_mentions(&err.to_string(), &["cancelled"]);
        assert!(stopped, "{stop_at:?} was never reported");
        assert_eq!(
            calls_after_stop, 0,
            "called again after stop at {stop_at:?}"
        );
    }
    // A callback that always continues sees every stage and gets a mesh.
    let mut seen = Vec::new();
    let mesh = reconstruct_with_progress(
        &points,
        &Params::default().with_depth(6),
        &mut |stage, fraction| {
            assert!((0.0..=1.0).contains(&fraction), "fraction {fraction}");
            if seen.last() != Some(&stage) {
                seen.push(stage);
            }
            true
        },
    )
    .unwrap();
    assert!(!mesh.triangles.is_empty());
    eprintln!("stages reported: {seen:?}");
}

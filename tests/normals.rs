//! Normal estimation and orientation (issue 15): agreement of the estimated normals with the
//! true outward normals on analytic shapes (smooth, sharp-edged, thin, nearly touching; clean,
//! noisy, unevenly sampled), determinism across thread counts, bad input, and reconstructions
//! from estimated normals against reconstructions from the true ones.
//!
//! Agreement is the fraction of points whose estimated normal has a positive dot product with
//! the true outward normal: it measures orientation (a wrong sign is a flipped point), not the
//! angular accuracy of the fit.

use psr::{
    estimate_normals, orient_normals, reconstruct, Error, NormalEstimation, Orientation, Params,
    PointSet,
};
use psr_test_support::{
    chamfer_to_surface, data_or_skip, jitter_positions, perturb_normals, sample_box,
    sample_hollow_ball, sample_sphere, sample_sphere_nonuniform, sample_torus, sample_two_boxes,
    sample_two_tori, sphere_bbox_diagonal, sphere_distance, thin_unevenly, torus_bbox_diagonal,
    torus_distance, MeshTopology,
};
use std::time::Instant;

/// The fraction of points whose estimated normal agrees in sign with the true one.
fn agreement(estimated: &[[f32; 3]], truth: &[[f32; 3]]) -> f64 {
    assert_eq!(estimated.len(), truth.len());
    let agree = estimated
        .iter()
        .zip(truth)
        .filter(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0.0)
        .count();
    agree as f64 / truth.len() as f64
}

/// Estimates with default options, checks the normals are unit and finite, and returns the
/// agreement with `truth`.
fn measure(label: &str, positions: &[[f32; 3]], truth: &[[f32; 3]]) -> f64 {
    let started = Instant::now();
    let normals = estimate_normals(positions, &NormalEstimation::default())
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let seconds = started.elapsed().as_secs_f64();
    for n in &normals {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!(
            (length - 1.0).abs() < 1e-5,
            "{label}: normal {n:?} is not unit"
        );
    }
    let fraction = agreement(&normals, truth);
    eprintln!(
        "{label}: {} points, agreement {:.4} % ({} flipped) in {seconds:.2} s",
        positions.len(),
        100.0 * fraction,
        ((1.0 - fraction) * positions.len() as f64).round()
    );
    fraction
}

/// The bar: at least 99.9 % of the normals point outward.
const REQUIRED_AGREEMENT: f64 = 0.999;

/// A shape three ways: clean, with positions jittered by `noise` (per axis), and thinned to a
/// 10× density contrast along x. Returns the three agreements.
fn three_ways(label: &str, positions: &[[f32; 3]], truth: &[[f32; 3]], noise: f64) -> [f64; 3] {
    let clean = measure(&format!("{label} clean"), positions, truth);
    let jittered = jitter_positions(positions, noise, 99);
    let noisy = measure(&format!("{label} noise {noise}"), &jittered, truth);
    let (thin_p, thin_n) = thin_unevenly(positions, truth, 10.0, 98);
    let uneven = measure(&format!("{label} uneven 10x"), &thin_p, &thin_n);
    [clean, noisy, uneven]
}

fn assert_agreement(label: &str, fractions: [f64; 3]) {
    for (how, f) in ["clean", "noisy", "uneven"].iter().zip(fractions) {
        assert!(
            f >= REQUIRED_AGREEMENT,
            "{label} {how}: only {:.4} % of the normals point outward",
            100.0 * f
        );
    }
}

/// Proves: on a unit sphere (60k points), clean, with positions jittered by σ = 0.003 and
/// unevenly sampled, at least 99.9 % of the estimated normals point outward.
#[test]
fn sphere_normals_point_outward() {
    let (p, n) = sample_sphere(60_000, 1.0, [0.0; 3], 1);
    assert_agreement("sphere", three_ways("sphere", &p, &n, 0.003));
    let (p, n) = sample_sphere_nonuniform(60_000, 3, 10.0);
    let f = measure("sphere 10x pole to pole", &p, &n);
    assert!(f >= REQUIRED_AGREEMENT, "non-uniform sphere: {f}");
}

/// Proves: on a ring torus (R = 1, r = 0.35, 60k points) at least 99.9 % point outward, clean,
/// noisy (σ = 0.003) and unevenly sampled.
#[test]
fn torus_normals_point_outward() {
    let (p, n) = sample_torus(60_000, 1.0, 0.35, 2);
    assert_agreement("torus", three_ways("torus", &p, &n, 0.003));
}

/// Proves: on a cube with sharp edges and corners (half side 1, 60k points) at least 99.9 %
/// point outward (along the edges the fitted plane is tilted, but still on the outward side).
#[test]
fn box_normals_point_outward() {
    let (p, n) = sample_box(60_000, [1.0, 1.0, 1.0], 3);
    assert_agreement("box", three_ways("box", &p, &n, 0.003));
}

/// Two tori whose outer walls are 0.1 apart (a few sample spacings).
#[test]
fn two_nearly_touching_tori_normals_point_outward() {
    let (p, n) = sample_two_tori(80_000, 1.0, 0.35, 0.1, 4);
    assert_agreement("two tori", three_ways("two tori", &p, &n, 0.003));
}

/// A thin plate: 2 × 2 × 0.08 (two faces 4 sample spacings apart).
#[test]
fn thin_plate_normals_point_outward() {
    let (p, n) = sample_box(60_000, [1.0, 1.0, 0.04], 5);
    assert_agreement("thin plate", three_ways("thin plate", &p, &n, 0.002));
}

/// The median distance from a point to its `k`-th nearest neighbour (the radius of the
/// neighbourhoods the estimation uses), over every 300th point, by brute force.
fn neighbourhood_radius(positions: &[[f32; 3]], k: usize) -> f64 {
    let mut radii: Vec<f64> = positions
        .iter()
        .step_by(300)
        .map(|p| {
            let mut d: Vec<f64> = positions
                .iter()
                .map(|q| {
                    (0..3)
                        .map(|a| (p[a] as f64 - q[a] as f64).powi(2))
                        .sum::<f64>()
                })
                .collect();
            d.select_nth_unstable_by(k, f64::total_cmp);
            d[k].sqrt()
        })
        .collect();
    radii.sort_by(f64::total_cmp);
    radii[radii.len() / 2]
}

/// Proves: two sheets closer than a neighbourhood keep their own orientations. A hollow ball (60k
/// points: a unit sphere, and inside it the cavity's wall, a sphere of radius 0.98 with its
/// normals towards the centre), whose wall is 0.02 thick: half the radius of a 20-neighbourhood
/// here (0.039, both spheres counted), one sample spacing. Every neighbourhood holds both
/// spheres; the points' neighbours on the other sphere are found by the two-sheet split
/// (`sheets.rs`), kept out of the spanning trees, and the two spheres are joined by the votes
/// across them (adjacent sheets of a closed surface face opposite ways). Before that, one sphere
/// came out with the other's orientation (51 % agreement). Clean and with noise σ = 0.001; see
/// `two_sheets_unevenly_sampled` for the uneven sampling.
#[test]
fn hollow_ball_with_a_wall_thinner_than_a_neighbourhood() {
    let (p, n) = sample_hollow_ball(60_000, 0.02, 7);
    let radius = neighbourhood_radius(&p, 20);
    eprintln!("hollow ball: wall 0.02, 20-neighbourhood radius {radius:.4}");
    assert!(
        0.02 < 0.6 * radius,
        "the wall is thinner than a neighbourhood"
    );
    let clean = measure("hollow ball, wall 0.02", &p, &n);
    let noisy = measure(
        "hollow ball, wall 0.02, noise 0.001",
        &jitter_positions(&p, 0.001, 99),
        &n,
    );
    // The true lines with every third sign flipped, re-oriented.
    let scrambled: Vec<[f32; 3]> = n
        .iter()
        .enumerate()
        .map(|(i, m)| if i % 3 == 0 { m.map(|c| -c) } else { *m })
        .collect();
    let fixed = orient_normals(&p, &scrambled, &NormalEstimation::default()).unwrap();
    let reoriented = agreement(&fixed, &n);
    eprintln!(
        "hollow ball, true lines re-oriented: agreement {:.4} %",
        100.0 * reoriented
    );
    for (how, f) in [
        ("clean", clean),
        ("noisy", noisy),
        ("re-oriented", reoriented),
    ] {
        assert!(
            f >= REQUIRED_AGREEMENT,
            "hollow ball {how}: only {:.4} % of the normals point outward",
            100.0 * f
        );
    }
}

/// Proves: two bodies a gap narrower than a neighbourhood apart keep their own orientations:
/// two boxes 2 × 2 × 0.5 (80k points), one on top of the other with a gap of 0.04 between the
/// faces that face each other, 0.9 of a 20-neighbourhood's radius. Before the two-sheet split,
/// 0.51 % of the normals were flipped (99.49 % agreement), at the gap 0.02 16 % (one box's
/// gap face and what the tree reached from it). Clean and with noise σ = 0.001.
#[test]
fn two_boxes_a_gap_narrower_than_a_neighbourhood_apart() {
    let (p, n) = sample_two_boxes(80_000, [1.0, 1.0, 0.25], 0.04, 6);
    let radius = neighbourhood_radius(&p, 20);
    eprintln!("two boxes: gap 0.04, 20-neighbourhood radius {radius:.4}");
    assert!(0.04 < radius, "the gap is narrower than a neighbourhood");
    let clean = measure("two boxes, gap 0.04", &p, &n);
    let noisy = measure(
        "two boxes, gap 0.04, noise 0.001",
        &jitter_positions(&p, 0.001, 99),
        &n,
    );
    for (how, f) in [("clean", clean), ("noisy", noisy)] {
        assert!(
            f >= REQUIRED_AGREEMENT,
            "two boxes {how}: only {:.4} % of the normals point outward",
            100.0 * f
        );
    }
}

/// Proves, and records a known shortfall: the same two shapes thinned to a 10× density contrast
/// along x keep at least 99 % of their normals outward, but not the 99.9 %: where the
/// sampling is sparse a neighbourhood is wider than the wall or the gap by more, fewer of the
/// neighbourhoods split cleanly, and the edges missed as crossing between sheets carry signs
/// across (measured with this test: hollow ball 99.31 %, two boxes 99.80 %).
#[test]
fn two_sheets_unevenly_sampled() {
    let (p, n) = sample_hollow_ball(60_000, 0.02, 7);
    let (p, n) = thin_unevenly(&p, &n, 10.0, 98);
    let ball = measure("hollow ball, wall 0.02, uneven 10x", &p, &n);
    let (p, n) = sample_two_boxes(80_000, [1.0, 1.0, 0.25], 0.04, 6);
    let (p, n) = thin_unevenly(&p, &n, 10.0, 98);
    let boxes = measure("two boxes, gap 0.04, uneven 10x", &p, &n);
    for (shape, f) in [("hollow ball", ball), ("two boxes", boxes)] {
        assert!(
            f >= 0.99,
            "{shape}, uneven: only {:.4} % of the normals point outward",
            100.0 * f
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Determinism, other orientations, bad input
// ---------------------------------------------------------------------------------------------

/// Proves: 1, 2 and 3 threads give the same normals bit for bit (propagation, noisy torus, a
/// cloud with exact duplicates and lattice ties, and a hollow ball whose wall is thinner than a
/// neighbourhood, so that the two-sheet split and the votes across sheets are exercised), and
/// so does re-orientation of given normals.
#[test]
fn one_and_two_threads_give_the_same_normals_bit_for_bit() {
    let (p, _) = sample_torus(40_000, 1.0, 0.35, 6);
    let mut p = jitter_positions(&p, 0.003, 7);
    p.extend_from_within(..500);
    for x in 0..20 {
        for y in 0..20 {
            p.push([3.0 + 0.01 * x as f32, 0.01 * y as f32, 0.0]);
        }
    }
    let (ball, ball_normals) = sample_hollow_ball(30_000, 0.03, 8);
    let ball = jitter_positions(&ball, 0.001, 9);
    let bits = |normals: Vec<[f32; 3]>| -> Vec<[u32; 3]> {
        normals.iter().map(|n| n.map(f32::to_bits)).collect()
    };
    for (label, cloud) in [("torus and lattice", &p), ("hollow ball", &ball)] {
        let with = |threads: usize| {
            let options = NormalEstimation::default().with_threads(threads);
            bits(estimate_normals(cloud, &options).unwrap())
        };
        let one = with(1);
        assert!(one == with(2), "{label}: 1 and 2 threads differ");
        assert!(one == with(3), "{label}: 1 and 3 threads differ");
    }
    let scrambled: Vec<[f32; 3]> = ball_normals
        .iter()
        .enumerate()
        .map(|(i, n)| if i % 3 == 0 { n.map(|c| -c) } else { *n })
        .collect();
    let with = |threads: usize| {
        let options = NormalEstimation::default().with_threads(threads);
        bits(orient_normals(&ball, &scrambled, &options).unwrap())
    };
    assert!(with(1) == with(2), "re-orientation: 1 and 2 threads differ");
}

/// Proves: estimation and re-orientation report `Stage::Normals` on the calling thread with
/// fractions rising from 0 to 1, many times over a cloud of several batches (so that a host can
/// cancel mid-way), and a stop at any report (in the neighbour search, the fits or the
/// orientation) ends the work with `Error::Cancelled` and no further call.
#[test]
fn progress_is_reported_throughout_and_a_stop_cancels() {
    let (p, truth) = sample_torus(60_000, 1.0, 0.35, 3);
    let options = NormalEstimation::default().with_threads(2);
    let me = std::thread::current().id();
    let mut fractions = Vec::new();
    let normals = psr::estimate_normals_with_progress(&p, &options, &mut |stage, fraction| {
        assert_eq!(stage, psr::Stage::Normals);
        assert_eq!(
            std::thread::current().id(),
            me,
            "called on the calling thread"
        );
        fractions.push(fraction);
        true
    })
    .unwrap();
    assert!(normals == estimate_normals(&p, &options).unwrap());
    assert_eq!(fractions.first(), Some(&0.0));
    assert_eq!(fractions.last(), Some(&1.0));
    assert!(
        fractions.windows(2).all(|w| w[0] <= w[1]),
        "fractions rise: {fractions:?}"
    );
    assert!(fractions.len() >= 8, "reported often: {fractions:?}");
    for stop_at in [1, 2, fractions.len() / 2, fractions.len() - 1] {
        let mut calls = 0;
        let result = psr::estimate_normals_with_progress(&p, &options, &mut |_, _| {
            calls += 1;
            calls < stop_at
        });
        assert!(
            matches!(result, Err(Error::Cancelled)),
            "stop at call {stop_at}"
        );
        assert_eq!(calls, stop_at, "no call after the stop");
    }
    let mut calls = 0;
    let result = psr::orient_normals_with_progress(&p, &truth, &options, &mut |stage, _| {
        assert_eq!(stage, psr::Stage::Normals);
        calls += 1;
        calls < 3
    });
    assert!(matches!(result, Err(Error::Cancelled)));
    assert_eq!(calls, 3);
}

/// Proves: a viewpoint orients every normal towards it; orient_normals repairs randomly
/// flipped (and slightly perturbed) normals on a sphere to point outward everywhere.
#[test]
fn viewpoint_and_consistent_signs() {
    let (p, n) = sample_sphere(20_000, 1.0, [0.0; 3], 8);
    let inward = estimate_normals(
        &p,
        &NormalEstimation::default().with_orientation(Orientation::Viewpoint([0.0; 3])),
    )
    .unwrap();
    assert_eq!(agreement(&inward, &n), 0.0, "all normals face the centre");

    let mut scrambled = perturb_normals(&n, 0.1, 9);
    for (i, m) in scrambled.iter_mut().enumerate() {
        if i % 3 == 0 {
            *m = m.map(|c| -c);
        }
    }
    let fixed = orient_normals(&p, &scrambled, &NormalEstimation::default()).unwrap();
    assert_eq!(agreement(&fixed, &n), 1.0);
    for (a, b) in fixed.iter().zip(&scrambled) {
        let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        assert!(
            (dot.abs() - 1.0).abs() < 1e-5,
            "orient_normals keeps each line"
        );
    }
}

/// Proves: bad input gives errors that name the problem, never NaN normals.
#[test]
fn bad_input_is_reported_and_duplicates_give_no_nan() {
    let options = NormalEstimation::default();
    assert_eq!(estimate_normals(&[], &options), Err(Error::EmptyInput));
    let (mut p, _) = sample_sphere(100, 1.0, [0.0; 3], 10);
    p[17][1] = f32::NAN;
    assert_eq!(
        estimate_normals(&p, &options),
        Err(Error::NonFinitePosition { index: 17 })
    );
    let few = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(
        estimate_normals(&few, &options),
        Err(Error::TooFewPoints {
            points: 3,
            neighbors: 20
        })
    );
    let same = vec![[1.0, 2.0, 3.0]; 50];
    assert_eq!(
        estimate_normals(&same, &options),
        Err(Error::DegenerateInput { points: 50 })
    );
    let line: Vec<[f32; 3]> = (0..50).map(|i| [i as f32, 2.0 * i as f32, 0.5]).collect();
    assert_eq!(
        estimate_normals(&line, &options),
        Err(Error::NoPlaneDefined { points: 50 })
    );
    assert!(matches!(
        estimate_normals(&line, &options.clone().with_neighbors(0)),
        Err(Error::InvalidParameter {
            name: "neighbors",
            ..
        })
    ));
    let e = Error::TooFewPoints {
        points: 3,
        neighbors: 20,
    };
    assert!(e.to_string().contains("at least 21 points"), "{e}");

    // A sphere where 30 points are stacked 25 deep (their neighbourhoods are single points):
    // they borrow their neighbours' normals, finite and outward.
    let (mut p, mut n) = sample_sphere(5_000, 1.0, [0.0; 3], 11);
    for i in 0..30 {
        for _ in 0..24 {
            p.push(p[i]);
            n.push(n[i]);
        }
    }
    let got = estimate_normals(&p, &options).unwrap();
    assert!(got.iter().flatten().all(|c| c.is_finite()));
    assert_eq!(agreement(&got, &n), 1.0);
}

// ---------------------------------------------------------------------------------------------
// Reconstruction from estimated normals
// ---------------------------------------------------------------------------------------------

/// Reconstructs at depth 8 from `normals`, checks a closed manifold, returns the Chamfer
/// distance (relative, averaged) to the true surface.
fn chamfer_from(
    label: &str,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    distance: impl Fn([f64; 3]) -> f64 + Sync,
    truth: &[[f32; 3]],
    diagonal: f64,
) -> f64 {
    let points = PointSet::from_slices(positions, normals).unwrap();
    let mesh = reconstruct(&points, &Params::default()).unwrap();
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    assert!(topo.is_closed_manifold(), "{label}: {topo}");
    let chamfer = chamfer_to_surface(
        &mesh.positions,
        &mesh.triangles,
        distance,
        truth,
        200_000,
        diagonal,
    );
    eprintln!("{label}: {topo}; {chamfer}");
    chamfer.relative_average
}

/// Proves: on 100k points of a sphere and of a torus, reconstructions from the estimated normals
/// are closed and within 1.2× the Chamfer distance of reconstructions from the true normals.
#[test]
fn reconstruction_from_estimated_normals_is_as_accurate() {
    let (p, n) = sample_sphere(100_000, 1.0, [0.0; 3], 1);
    let (truth, _) = sample_sphere(100_000, 1.0, [0.0; 3], 1001);
    let estimated = estimate_normals(&p, &NormalEstimation::default()).unwrap();
    let d = sphere_distance([0.0; 3], 1.0);
    let diag = sphere_bbox_diagonal(1.0);
    let exact = chamfer_from("sphere, true normals", &p, &n, d, &truth, diag);
    let ours = chamfer_from("sphere, estimated normals", &p, &estimated, d, &truth, diag);
    eprintln!(
        "sphere: Chamfer ratio estimated / true = {:.4}",
        ours / exact
    );
    assert!(ours <= 1.2 * exact, "sphere: {ours:.4e} vs {exact:.4e}");

    let (p, n) = sample_torus(100_000, 1.0, 0.35, 2);
    let (truth, _) = sample_torus(100_000, 1.0, 0.35, 1002);
    let estimated = estimate_normals(&p, &NormalEstimation::default()).unwrap();
    let d = torus_distance(1.0, 0.35);
    let diag = torus_bbox_diagonal(1.0, 0.35);
    let exact = chamfer_from("torus, true normals", &p, &n, d, &truth, diag);
    let ours = chamfer_from("torus, estimated normals", &p, &estimated, d, &truth, diag);
    eprintln!(
        "torus: Chamfer ratio estimated / true = {:.4}",
        ours / exact
    );
    assert!(ours <= 1.2 * exact, "torus: {ours:.4e} vs {exact:.4e}");
}

// ---------------------------------------------------------------------------------------------
// Real scans (timing; run with --ignored --nocapture)
// ---------------------------------------------------------------------------------------------

/// Prints the time of estimate + orient at 1 and 2 threads on the bunny and Buddha scans, and
/// the agreement with the normals stored in the files. Not a pass/fail test of speed.
#[test]
#[ignore = "timing on the shared data; run with --ignored --nocapture"]
fn time_real_scans() {
    for name in ["bunny_scans.ply", "happy_buddha_scans.ply"] {
        let Some(path) = data_or_skip(name, "time_real_scans") else {
            continue;
        };
        let cloud = psr::ply::read_point_cloud(&path).unwrap();
        let mut first: Option<Vec<[f32; 3]>> = None;
        for threads in [1, 2] {
            let started = Instant::now();
            let normals = estimate_normals(
                &cloud.positions,
                &NormalEstimation::default().with_threads(threads),
            )
            .unwrap();
            let seconds = started.elapsed().as_secs_f64();
            eprintln!(
                "{name}: {} points, {threads} thread(s): {seconds:.2} s, agreement with the file's normals {:.4} %",
                cloud.len(),
                100.0 * agreement(&normals, &cloud.normals)
            );
            match &first {
                None => first = Some(normals),
                Some(f) => assert!(f == &normals, "{name}: 1 and 2 threads differ"),
            }
        }
    }
}

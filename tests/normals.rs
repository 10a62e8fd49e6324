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
    chamfer_to_surface, data_or_skip, jitter_positions, perturb_normals, sample_box, sample_sphere,
    sample_sphere_nonuniform, sample_torus, sample_two_tori, sphere_bbox_diagonal, sphere_distance,
    thin_unevenly, torus_bbox_diagonal, torus_distance, MeshTopology,
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

//! Normals read off the reconstruction itself (`Orientation::Reconstruction`, issue 15): the
//! orientation that does not propagate signs along a neighbour graph but repeats
//! reconstructions from an arbitrary start (`src/normals/reconstruction.rs`). Agreement with
//! the true outward normals on analytic shapes (clean, noisy, unevenly sampled, thin, nearly
//! touching), re-orientation of given lines, determinism across thread counts, progress and
//! cancel, and its option's range. The scans are in `normals_on_scans.rs`.

use psr::{
    estimate_normals, estimate_normals_with_progress, orient_normals, Error, NormalEstimation,
    Orientation, Stage,
};
use psr_test_support::{
    jitter_positions, sample_box, sample_sphere, sample_torus, sample_two_tori, thin_unevenly,
};

/// The bar: at least 99.9 % of the normals point outward.
const REQUIRED_AGREEMENT: f64 = 0.999;

fn options() -> NormalEstimation {
    NormalEstimation::default().with_orientation(Orientation::Reconstruction)
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Estimates with `Orientation::Reconstruction`, checks the normals are unit, prints and
/// returns the fraction agreeing with `truth` in sign and the median |n·truth|.
fn measure(label: &str, positions: &[[f32; 3]], truth: &[[f32; 3]]) -> (f64, f32) {
    let normals =
        estimate_normals(positions, &options()).unwrap_or_else(|e| panic!("{label}: {e}"));
    for n in &normals {
        assert!(
            (dot(*n, *n).sqrt() - 1.0).abs() < 1e-5,
            "{label}: {n:?} not unit"
        );
    }
    let agree = normals
        .iter()
        .zip(truth)
        .filter(|(a, b)| dot(**a, **b) > 0.0)
        .count();
    let mut alignment: Vec<f32> = normals
        .iter()
        .zip(truth)
        .map(|(a, b)| dot(*a, *b).abs())
        .collect();
    alignment.sort_by(f32::total_cmp);
    let median = alignment[alignment.len() / 2];
    let fraction = agree as f64 / truth.len() as f64;
    eprintln!(
        "{label}: {} points, agreement {:.4} % ({} flipped), median |n·truth| {median:.5}",
        positions.len(),
        100.0 * fraction,
        truth.len() - agree
    );
    (fraction, median)
}

fn assert_outward(label: &str, positions: &[[f32; 3]], truth: &[[f32; 3]]) {
    let (fraction, median) = measure(label, positions, truth);
    assert!(
        fraction >= REQUIRED_AGREEMENT,
        "{label}: only {:.4} % of the normals point outward",
        100.0 * fraction
    );
    assert!(
        median > 0.99,
        "{label}: the lines are off: median |n·truth| {median}"
    );
}

/// Proves: on a sphere, clean, noisy (σ = 0.003) and thinned to a 10× density contrast, at
/// least 99.9 % of the normals point outward and their lines follow the surface.
#[test]
fn sphere_by_reconstruction() {
    let (p, n) = sample_sphere(12_000, 1.0, [0.0; 3], 1);
    assert_outward("sphere clean", &p, &n);
    assert_outward("sphere noisy", &jitter_positions(&p, 0.003, 2), &n);
    let (tp, tn) = thin_unevenly(&p, &n, 10.0, 3);
    assert_outward("sphere uneven 10x", &tp, &tn);
}

/// Proves: the same on a ring torus (R = 1, r = 0.35).
#[test]
fn torus_by_reconstruction() {
    let (p, n) = sample_torus(12_000, 1.0, 0.35, 4);
    assert_outward("torus clean", &p, &n);
    assert_outward("torus noisy", &jitter_positions(&p, 0.003, 5), &n);
}

/// Proves: the same on a cube with sharp edges and corners, and on a thin plate (2 × 2 × 0.08).
#[test]
fn box_and_thin_plate_by_reconstruction() {
    let (p, n) = sample_box(12_000, [1.0, 1.0, 1.0], 6);
    assert_outward("box", &p, &n);
    let (p, n) = sample_box(12_000, [1.0, 1.0, 0.04], 7);
    assert_outward("thin plate", &p, &n);
}

/// Proves: two tori whose outer walls are 0.1 apart both come out outward.
#[test]
fn two_nearly_touching_tori_by_reconstruction() {
    let (p, n) = sample_two_tori(16_000, 1.0, 0.35, 0.1, 8);
    assert_outward("two tori", &p, &n);
}

/// Proves: orient_normals with `Orientation::Reconstruction` keeps the given lines bit for bit
/// up to sign and makes every sign outward, from signs scrambled one in three.
#[test]
fn reorientation_keeps_the_lines_and_fixes_the_signs() {
    let (p, n) = sample_torus(8_000, 1.0, 0.35, 9);
    let scrambled: Vec<[f32; 3]> = n
        .iter()
        .enumerate()
        .map(|(i, n)| if i % 3 == 0 { n.map(|c| -c) } else { *n })
        .collect();
    let fixed = orient_normals(&p, &scrambled, &options()).unwrap();
    for ((f, s), t) in fixed.iter().zip(&scrambled).zip(&n) {
        assert!(
            (dot(*f, *s).abs() - 1.0).abs() < 1e-6,
            "line changed: {f:?} from {s:?}"
        );
        assert!(dot(*f, *t) > 0.0, "not outward: {f:?}, truth {t:?}");
    }
}

/// Proves: one, two and three threads give the same normals bit for bit.
#[test]
fn threads_give_the_same_normals_bit_for_bit() {
    let (p, _) = sample_torus(6_000, 1.0, 0.35, 10);
    let p = jitter_positions(&p, 0.003, 11);
    let bits = |threads: usize| -> Vec<[u32; 3]> {
        estimate_normals(
            &p,
            &options()
                .with_reconstruction_iterations(4)
                .with_threads(threads),
        )
        .unwrap()
        .iter()
        .map(|n| n.map(f32::to_bits))
        .collect()
    };
    let one = bits(1);
    assert!(one == bits(2), "1 and 2 threads differ");
    assert!(one == bits(3), "1 and 3 threads differ");
}

/// Proves: progress rises from 0 to 1 on the calling thread through every reconstruction, and
/// a stop in the propagation, in either start's rounds or at the end ends the work with
/// `Error::Cancelled` and no further call.
#[test]
fn progress_rises_and_a_stop_cancels() {
    let (p, _) = sample_sphere(4_000, 1.0, [0.0; 3], 12);
    let options = options().with_reconstruction_iterations(3);
    let mut fractions = Vec::new();
    estimate_normals_with_progress(&p, &options, &mut |stage, f| {
        assert_eq!(stage, Stage::Normals);
        fractions.push(f);
        true
    })
    .unwrap();
    assert_eq!(fractions.first(), Some(&0.0));
    assert_eq!(fractions.last(), Some(&1.0));
    assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");
    assert!(
        fractions.len() >= 4 * 9,
        "every stage of every reconstruction: {fractions:?}"
    );
    // How many reports a reconstruction makes depends on its timing, so the stops are set by
    // the fraction reached, not by a call count.
    for stop_from in [0.0, 0.03, 0.15, 0.5, 0.97] {
        let (mut stopped, mut after) = (false, 0);
        let result = estimate_normals_with_progress(&p, &options, &mut |_, f| {
            if stopped {
                after += 1;
            }
            stopped = stopped || f >= stop_from;
            !stopped
        });
        assert!(
            matches!(result, Err(Error::Cancelled)),
            "stop from {stop_from}: {result:?}"
        );
        assert_eq!(after, 0, "no call after the stop");
    }
}

/// Proves: an iteration count outside 1..=1000 is refused by name, and bad points get the same
/// errors as with propagation.
#[test]
fn bad_iterations_and_points_are_refused() {
    let (p, _) = sample_sphere(500, 1.0, [0.0; 3], 13);
    for bad in [0, 1001] {
        match estimate_normals(&p, &options().with_reconstruction_iterations(bad)) {
            Err(Error::InvalidParameter { name, .. }) => {
                assert_eq!(name, "reconstruction_iterations")
            }
            other => panic!("{bad} iterations: {other:?}"),
        }
    }
    let mut nan = p.clone();
    nan[7][1] = f32::NAN;
    assert!(matches!(
        estimate_normals(&nan, &options()),
        Err(Error::NonFinitePosition { index: 7 })
    ));
    assert!(matches!(
        estimate_normals(&[], &options()),
        Err(Error::EmptyInput)
    ));
    assert!(matches!(
        estimate_normals(&vec![[1.0, 2.0, 3.0]; 50], &options()),
        Err(Error::DegenerateInput { .. })
    ));
}

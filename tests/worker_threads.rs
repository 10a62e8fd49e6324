//! A reconstruction leaves no thread behind even when it unwinds: a panic inside it (here from
//! the progress callback) still ends its worker pool and joins every worker before the panic
//! reaches the caller, as a normal return does. A trim leaves none either (not even rayon's
//! global pool). In a test binary of its own, since other tests' reconstructions would run
//! workers meanwhile.

use psr::{reconstruct_with_progress, Params, PointSet, Stage, Threshold, Trimming};
#[cfg(target_os = "linux")]
use psr_test_support::running_threads_named;

#[test]
#[cfg(target_os = "linux")]
fn a_panic_inside_a_reconstruction_still_joins_its_workers() {
    let n = 1000;
    let points: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let ring = (1.0 - y * y).sqrt();
            let phi = 2.399963229728653 * i as f64;
            [ring * phi.cos(), y, ring * phi.sin()].map(|c| c as f32)
        })
        .collect();
    let cloud = PointSet::from_slices(&points, &points).unwrap();
    for stage in [Stage::Splat, Stage::Solve, Stage::Extract] {
        let params = Params::default().with_depth(5).with_threads(3);
        let outcome = std::panic::catch_unwind(|| {
            reconstruct_with_progress(&cloud, &params, &mut |at, _| {
                if at == stage {
                    panic!("the host's callback fails during {}", at.name());
                }
                true
            })
        });
        assert!(outcome.is_err(), "the panic reaches the caller");
        // Checked at once: no grace period.
        let left = running_threads_named("psr-worker");
        assert!(
            left.is_empty(),
            "workers alive after a panic in {stage:?}: {left:?}"
        );
    }
    let mesh =
        reconstruct_with_progress(&cloud, &Params::default().with_depth(5), &mut |_, _| true)
            .expect("a reconstruction");

    // A trim, successful or refused, leaves the process with the threads it had.
    let before = running_threads_named("");
    for threshold in [Threshold::Automatic, Threshold::Density(f32::NAN)] {
        let _ = psr::trim(&mesh, &Trimming::default().with_threshold(threshold));
        let mut bad = mesh.clone();
        bad.triangles.push([0, 1, u32::MAX]);
        let _ = psr::trim(&bad, &Trimming::default().with_threshold(threshold));
        let after = running_threads_named("");
        assert_eq!(
            before.len(),
            after.len(),
            "threads before a trim: {before:?}, after: {after:?}"
        );
    }
}

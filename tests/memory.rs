//! The memory budget (issue 19): `Params::max_memory`, `estimate_memory`, and
//! `Error::OutOfMemory` when the limit or the system says no, with nothing kept.

use psr::{estimate_memory, estimate_memory_for, reconstruct, Error, Params, PointSet};
use psr_test_support::{data_or_skip, sample_sphere};
use std::time::Instant;

fn sphere() -> PointSet {
    let (p, n) = sample_sphere(20_000, 1.0, [0.0; 3], 7);
    PointSet::from_slices(&p, &n).unwrap()
}

/// Proves: a limit below what the points alone need fails with `OutOfMemory` naming the limit
/// and a larger figure that would do; the same points then give, with no limit or a limit of
/// the estimate, the mesh bit for bit that a reconstruction that never failed gives.
#[test]
fn a_small_limit_fails_typed_and_nothing_is_kept() {
    let points = sphere();
    let params = Params::default().with_depth(7).with_threads(2);
    let expected = reconstruct(&points, &params).unwrap();

    let err = reconstruct(&points, &params.clone().with_max_memory(Some(1 << 20))).unwrap_err();
    let Error::OutOfMemory {
        needed,
        limit,
        enough,
        ..
    } = err.clone()
    else {
        panic!("expected OutOfMemory, got {err:?}");
    };
    assert_eq!(limit, Some(1 << 20));
    assert!(needed > 1 << 20, "{err}");
    assert!(enough.unwrap() >= needed, "{err}");
    let message = err.to_string();
    assert!(
        message.contains("1.00 MiB") && message.contains("allow at least"),
        "{message}"
    );

    let estimate = estimate_memory(&points, &params).unwrap();
    for retry in [None, Some(estimate)] {
        let mesh = reconstruct(&points, &params.clone().with_max_memory(retry)).unwrap();
        assert_eq!(mesh.positions, expected.positions, "{retry:?}");
        assert_eq!(mesh.triangles, expected.triangles, "{retry:?}");
        assert_eq!(mesh.densities, expected.densities, "{retry:?}");
    }
}

/// Proves: a limit between what the points need and what the octree then needs is refused
/// once the octree's node counts are known (the precise check), not before and not after the
/// system is built: the figure reported is the accounting's from the node counts.
#[test]
fn the_precise_check_uses_the_octrees_node_counts() {
    let points = sphere();
    let params = Params::default().with_depth(8).with_threads(2);
    let mesh = reconstruct(&points, &params).unwrap();
    let needed = mesh.stats.estimated_memory;
    assert!(needed > 0);
    // Just under the figure: refused, and the figure is the one reported.
    let err = reconstruct(&points, &params.clone().with_max_memory(Some(needed - 1)));
    match err {
        Err(Error::OutOfMemory {
            what,
            needed: reported,
            ..
        }) => {
            assert!(what.contains("octree"), "{what}");
            assert_eq!(reported, needed);
        }
        other => panic!("expected OutOfMemory, got {other:?}"),
    }
    // At the figure: accepted, the same mesh.
    let again = reconstruct(&points, &params.clone().with_max_memory(Some(needed))).unwrap();
    assert_eq!(again.positions, mesh.positions);
}

/// Proves: the estimate grows with the depth and the points and is refused for a width
/// without points; `max_memory = Some(0)` is an invalid parameter.
#[test]
fn the_estimate_for_a_count_and_depth() {
    let at = |n, d| estimate_memory_for(n, &Params::default().with_depth(d)).unwrap();
    assert!(at(1_000_000, 9) < at(1_000_000, 10));
    assert!(at(100_000, 10) < at(1_000_000, 10));
    assert!(matches!(
        estimate_memory_for(10, &Params::default().with_width(Some(0.1))),
        Err(Error::InvalidParameter { name: "width", .. })
    ));
    assert!(matches!(
        reconstruct(&sphere(), &Params::default().with_max_memory(Some(0))),
        Err(Error::InvalidParameter {
            name: "max_memory",
            ..
        })
    ));
}

/// Proves: a complete octree far beyond any machine (full depth 12: 2^36 nodes) is refused up
/// front by a limit, before anything is allocated.
#[test]
fn an_absurd_request_is_refused_by_the_limit_up_front() {
    let params = Params::default()
        .with_depth(12)
        .with_full_depth(12)
        .with_max_memory(Some(8 << 30));
    let started = Instant::now();
    let err = reconstruct(&sphere(), &params).unwrap_err();
    assert!(
        matches!(err, Error::OutOfMemory { what, limit: Some(_), .. } if what.contains("complete")),
        "{err:?}"
    );
    eprintln!(
        "refused up front in {:.3} s: {err}",
        started.elapsed().as_secs_f64()
    );
}

const CHILD: &str = "PSR_MEMORY_TEST_CHILD";

/// Proves: when the system refuses one of the big allocations (here, with no limit set, the
/// 512 GiB complete grid of full depth 12, in a child process whose address space is capped at
/// 8 GB so the refusal does not depend on the machine's overcommit policy), the reconstruction
/// returns `OutOfMemory` with no limit, not an abort; and the same process then reconstructs
/// normally. The child is this test binary run again under `ulimit -v`; an abort there fails
/// the test.
#[test]
fn a_refusal_by_the_system_is_typed_not_an_abort() {
    if std::env::var_os(CHILD).is_some() {
        let points = sphere();
        let absurd = Params::default().with_depth(12).with_full_depth(12);
        let err = reconstruct(&points, &absurd).unwrap_err();
        assert!(
            matches!(
                err,
                Error::OutOfMemory {
                    limit: None,
                    enough: None,
                    ..
                }
            ),
            "{err:?}"
        );
        println!("child: {err}");
        let mesh = reconstruct(&points, &Params::default().with_depth(6)).unwrap();
        assert!(!mesh.triangles.is_empty());
        println!("child: recovered");
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let output = std::process::Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 8000000 && exec \"$0\" \"$@\"")
        .arg(&exe)
        .args([
            "--exact",
            "a_refusal_by_the_system_is_typed_not_an_abort",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success() && stdout.contains("child: recovered"),
        "child failed ({:?}):\n{stdout}\n{stderr}",
        output.status
    );
    // (libtest prints the child's first line after the test's name.)
    let refusal = stdout
        .find("child: out of memory: the system refused")
        .map(|at| stdout[at..].lines().next().unwrap_or_default());
    assert!(
        refusal.is_some(),
        "the child never met the refusal:\n{stdout}"
    );
    eprintln!("{}", refusal.unwrap_or_default());
}

/// Proves, on the Happy Buddha at depth 12 with a limit far too small (64 MiB; it needs about
/// 1 GB): the typed error, naming the limit; and the same points and parameters with a smaller
/// depth then reconstruct as on a handle that never failed. Prints the time to the error
/// (measured figures in docs/benchmarks.md, issue 19).
#[test]
fn the_buddha_at_depth_12_with_a_far_too_small_limit() {
    let name = "happy_buddha_scans.ply";
    let Some(path) = data_or_skip(name, "the_buddha_at_depth_12_with_a_far_too_small_limit") else {
        return;
    };
    let cloud = psr::ply::read_point_cloud(&path).unwrap();
    let points = PointSet::from_slices(&cloud.positions, &cloud.normals).unwrap();
    let params = Params::default().with_depth(12).with_threads(2);
    let small = params.clone().with_max_memory(Some(64 << 20));
    let started = Instant::now();
    let err = reconstruct(&points, &small).unwrap_err();
    let seconds = started.elapsed().as_secs_f64();
    assert!(
        matches!(err, Error::OutOfMemory { limit: Some(l), .. } if l == 64 << 20),
        "{err:?}"
    );
    let estimate = estimate_memory(&points, &params).unwrap();
    eprintln!(
        "{name}: {} points, depth 12, limit 64 MiB: {err} after {seconds:.3} s; estimate {estimate} bytes",
        points.len()
    );
    // Reusable: a smaller depth, the same mesh as without the failure before it.
    let lower = small.clone().with_depth(6).with_max_memory(None);
    let after = reconstruct(&points, &lower).unwrap();
    let fresh = reconstruct(&points, &params.clone().with_depth(6)).unwrap();
    assert_eq!(after.positions, fresh.positions);
    assert_eq!(after.triangles, fresh.triangles);
}

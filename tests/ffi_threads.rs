//! psr_reconstructor_solve must leave no thread behind: its worker threads are joined before it
//! returns, so a host can unload libpsr right after (plugins) and leak checkers see no live
//! threads. In a test binary of its own, since other tests' solves would run workers meanwhile.

use psr::ffi::*;
#[cfg(target_os = "linux")]
use psr_test_support::running_threads_named;
use std::ptr;

#[test]
#[cfg(target_os = "linux")]
fn solve_returns_only_after_its_worker_threads_have_exited() {
    let n = 1000;
    let (mut p, mut nrm) = (Vec::new(), Vec::new());
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let ring = (1.0 - y * y).sqrt();
        let phi = 2.399963229728653 * i as f64;
        let d = [ring * phi.cos(), y, ring * phi.sin()];
        p.extend(d.map(|c| c as f32));
        nrm.extend(d.map(|c| c as f32));
    }
    let before = running_threads_named("").len();
    for threads in [2u32, 4] {
        unsafe {
            let mut r = ptr::null_mut();
            assert_eq!(psr_reconstructor_new(&mut r), psr_status::Ok);
            assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
            assert_eq!(psr_reconstructor_set_threads(r, threads), psr_status::Ok);
            assert_eq!(
                psr_reconstructor_add_points(r, p.as_ptr(), 0, nrm.as_ptr(), 0, n),
                psr_status::Ok
            );
            let mut m = ptr::null_mut();
            assert_eq!(psr_reconstructor_solve(r, &mut m), psr_status::Ok);
            // Checked at once: no grace period (threads already in the kernel's exit path, after
            // their join, are not counted: see running_threads_named).
            let names = running_threads_named("");
            let workers = running_threads_named("psr-worker");
            assert!(
                workers.is_empty(),
                "worker threads still alive after solve returned: {workers:?}"
            );
            assert_eq!(
                names.len(),
                before,
                "thread count changed across solve: {names:?}"
            );
            psr_mesh_free(m);
            psr_reconstructor_free(r);
        }
    }
}

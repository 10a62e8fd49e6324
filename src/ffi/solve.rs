//! Solving: psr_reconstructor_set_progress_callback, psr_reconstructor_solve, and the test hooks
//! that force a panic inside the next solve.

use super::mesh::psr_mesh;
use super::panic_boundary::{guard, handle_mut, require_out, write_out};
use super::reconstructor::{psr_reconstructor, UserPointer};
use super::stage::psr_progress_fn;
use super::status::{psr_status, Failure};
use crate::{ImplicitFunction, Mesh, Stage};
use std::ffi::c_void;

/// Sets (or, with callback NULL, removes) the progress callback of r. See psr_progress_fn for
/// when and on which thread it is called. user is passed back to it untouched and may be NULL.
///
/// r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `callback`, if set, is safe to call with `user` until it is
/// replaced or r is freed.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_progress_callback(
    r: *mut psr_reconstructor,
    callback: psr_progress_fn,
    user: *mut c_void,
) -> psr_status {
    const F: &str = "psr_reconstructor_set_progress_callback";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        handle.progress = callback;
        handle.user = UserPointer(user);
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Reconstructs a watertight mesh from r's points and parameters and writes a new mesh to
/// *out; free it with psr_mesh_free. r keeps its points and parameters and may be solved again.
/// Runs on the calling thread, using the number of worker threads set with
/// psr_reconstructor_set_threads; the progress callback, if any, is called on the calling thread,
/// during every stage at least every 20 ms (see psr_progress_fn).
///
/// r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_EMPTY_INPUT (no points), PSR_STATUS_INVALID_PARAMETER (kernel_depth > depth),
/// PSR_STATUS_CANCELLED (the callback returned false), PSR_STATUS_HANDLE_POISONED,
/// PSR_STATUS_INVALID_ARGUMENT (called from r's own progress callback, all points coincide, the
/// points added without normals cannot be given normals: fewer of them than the neighbour
/// count + 1, or all on a line, or PSR_ORIENTATION_SENSORS while some of them have no sensor,
/// or they meet points with colours or channels), PSR_STATUS_INVALID_WEIGHT (every confidence
/// weight is 0),
/// PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR (a bug; if it was a panic, r is
/// now poisoned). On failure *out is left untouched. Points added without normals get them (estimated and oriented, see
/// psr_reconstructor_add_positions) before the reconstruction starts.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_solve(
    r: *mut psr_reconstructor,
    out: *mut *mut psr_mesh,
) -> psr_status {
    const F: &str = "psr_reconstructor_solve";
    let body = || {
        require_out(F, "out", out)?;
        // SAFETY: `r` is NULL or a live handle (this function's contract), used by no other
        // call meanwhile (guard runs the body only then and holds no reference to r).
        let (mesh, _) = unsafe { solve_on(F, r, false) }?;
        let mesh = Box::into_raw(Box::new(psr_mesh::new(mesh)));
        // SAFETY: `out` is not NULL (checked first) and valid for writing one pointer (this
        // function's contract).
        unsafe { write_out(F, "out", out, mesh) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// psr_reconstructor_solve's work, for it and psr_reconstructor_solve_implicit (`function`,
/// named in the messages): the mesh, and χ when `keep_implicit`.
///
/// # Safety
/// `r` is NULL or a live handle that no other call is using, and this runs inside `guard`
/// (which clears `busy` whichever way it ends).
pub(super) unsafe fn solve_on(
    function: &'static str,
    r: *mut psr_reconstructor,
    keep_implicit: bool,
) -> Result<(Mesh, Option<ImplicitFunction>), Failure> {
    let (params, callback, user, panic_now) = {
        // SAFETY: `r` is NULL or a live handle no other call is using (this function's
        // contract).
        let handle = unsafe { handle_mut(function, r) }?;
        let panic_now = std::mem::take(&mut handle.panic_next_solve);
        (
            handle.params.clone(),
            handle.progress,
            handle.user,
            panic_now,
        )
    };
    if panic_now {
        panic!("forced by the test hook psr_reconstructor_debug_panic_next_solve");
    }
    // SAFETY: `r` is a live handle (handle_mut above found it not NULL), and the mutable
    // reference from handle_mut has ended. No mutable reference to *r is made while this
    // shared one lives: a call the callback makes on r sees `busy` through its own shared
    // reference and is refused, which does not touch the points borrowed here.
    let handle: &psr_reconstructor = unsafe { &*r };
    handle.busy.set(true);
    let mut progress = |stage: Stage, fraction: f32| match callback {
        // SAFETY: whoever set the callback promised it is safe to call with `user` until it
        // is replaced or r is freed (psr_reconstructor_set_progress_callback's contract),
        // and neither can happen during the solve: calls on r from the callback are
        // refused, and psr_reconstructor_free does nothing then.
        Some(f) => unsafe { f(user.0, stage.into(), fraction) },
        None => true,
    };
    let with_estimated_normals;
    let points = if handle.positions_without_normals.is_empty() {
        &handle.points
    } else {
        // The points added without normals get theirs here and join the others (a copy of
        // the oriented points while the solve runs). They carry no colours or channels, so
        // they cannot join points that do.
        if handle.points.colors().is_some() || !handle.points.channels().is_empty() {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{function}: r holds points with colours or channels \
                     (psr_reconstructor_add_point_arrays) and points without normals \
                     (psr_reconstructor_add_positions), which carry none: give every point \
                     the same attributes, or clear the points and add them again"
                ),
            ));
        }
        let options = super::normals::estimation_for_solve(function, handle, params.threads)?;
        let unoriented = &handle.positions_without_normals;
        // (guard clears `busy` whichever way the body ends.)
        let estimated = crate::estimate_normals_with_progress(unoriented, &options, &mut progress)
            .map_err(|e| Failure::from_error(function, e))?;
        let mut all = handle.points.clone();
        all.extend(unoriented, &estimated)
            .map_err(|e| Failure::from_error(function, e))?;
        with_estimated_normals = all;
        &with_estimated_normals
    };
    let result = if keep_implicit {
        crate::reconstruct_with_implicit_and_progress(points, &params, &mut progress)
            .map(|(mesh, implicit)| (mesh, Some(implicit)))
    } else {
        crate::reconstruct_with_progress(points, &params, &mut progress).map(|m| (m, None))
    };
    handle.busy.set(false);
    result.map_err(|e| Failure::from_error(function, e))
}

/// Test hook for psr's own Rust tests, not API (neither Rust nor C): makes the next solve on `r`
/// panic inside the panic boundary, to prove that the panic becomes `InternalError` and poisons
/// the handle.
///
/// # Safety
/// `r` is NULL (nothing happens) or a live handle from psr_reconstructor_new that no other call
/// is using.
#[doc(hidden)]
pub unsafe fn debug_panic_next_solve(r: *mut psr_reconstructor) {
    // SAFETY: `r` is NULL or a live handle no other call is using (this function's contract).
    if let Some(handle) = unsafe { r.as_mut() } {
        handle.panic_next_solve = true;
    }
}

/// Test hook, compiled only with the cargo feature "test-panic" (CMake: -DPSR_TEST_PANIC=ON):
/// makes the next psr_reconstructor_solve on r panic inside the library, which must come back
/// as PSR_STATUS_INTERNAL_ERROR and poison r. Never use it in applications.
///
/// r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INVALID_ARGUMENT.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[cfg(feature = "test-panic")]
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_debug_panic_next_solve(
    r: *mut psr_reconstructor,
) -> psr_status {
    const F: &str = "psr_reconstructor_debug_panic_next_solve";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        unsafe { handle_mut(F, r) }?.panic_next_solve = true;
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

//! The `psr_reconstructor` handle: what it holds, and psr_reconstructor_new, _free and
//! _last_error.

use super::panic_boundary::{guard_no_handle, guard_value, require_out, write_out};
use super::stage::psr_progress_fn;
use super::status::psr_status;
use crate::{NormalEstimation, Params, PointSet};
use std::cell::{Cell, RefCell};
use std::ffi::{c_char, c_void, CString};
use std::ptr;

/// The caller's opaque user pointer. psr never dereferences it; it only hands it back to the
/// callback on the thread that called solve, so moving it between threads with the handle is the
/// caller's business (documented in the header's threading section).
#[derive(Clone, Copy)]
pub(super) struct UserPointer(pub(super) *mut c_void);
// SAFETY: psr never dereferences the pointer, see above.
unsafe impl Send for UserPointer {}

/// A reusable reconstruction: parameters, accumulated points, an optional progress callback and
/// the message of the last failed call. Created by psr_reconstructor_new, destroyed by
/// psr_reconstructor_free. Opaque to C.
pub struct psr_reconstructor {
    pub(super) params: Params,
    pub(super) points: PointSet,
    /// Points added without normals (psr_reconstructor_add_positions); the solve estimates
    /// their normals.
    pub(super) positions_without_normals: Vec<[f32; 3]>,
    /// The sensor position of each point without normals, in step with
    /// `positions_without_normals` ([`super::normals::NO_SENSOR`] for a point added without
    /// one), or empty while no point has one (psr_reconstructor_add_positions_seen_from and
    /// _with_sensors).
    pub(super) sensors: Vec<[f32; 3]>,
    /// How those normals are estimated and oriented. `Orientation::Sensors` is kept with an
    /// empty list here (the selection only); the solve fills it from `sensors`.
    pub(super) normal_estimation: NormalEstimation,
    /// The last viewpoint set, for PSR_ORIENTATION_VIEWPOINT.
    pub(super) viewpoint: Option<[f64; 3]>,
    pub(super) progress: psr_progress_fn,
    pub(super) user: UserPointer,
    /// The last failed call's message, returned by psr_reconstructor_last_error. Interior
    /// mutability because calls taking `const psr_reconstructor *` report failures too; a handle
    /// is never used from two threads at once, which `RefCell` (Send, not Sync) expresses.
    pub(super) last_error: RefCell<Option<CString>>,
    /// Set when a call on this handle panicked; then every call but last_error and free is
    /// refused.
    pub(super) poisoned: Cell<bool>,
    /// Set while psr_reconstructor_solve runs, to refuse calls from inside the progress callback.
    pub(super) busy: Cell<bool>,
    /// What the last psr_reconstructor_solve_file_out_of_core measured of the samples' noise,
    /// `None` before one succeeds (psr_reconstructor_out_of_core_noise).
    pub(super) last_out_of_core_noise: Cell<Option<super::outofcore::psr_out_of_core_noise>>,
    /// Test hook: the next solve panics (see `debug_panic_next_solve` in solve.rs).
    pub(super) panic_next_solve: bool,
}

impl psr_reconstructor {
    fn new() -> Self {
        psr_reconstructor {
            params: Params::default(),
            points: PointSet::new(),
            positions_without_normals: Vec::new(),
            sensors: Vec::new(),
            normal_estimation: NormalEstimation::default(),
            viewpoint: None,
            progress: None,
            user: UserPointer(ptr::null_mut()),
            last_error: RefCell::new(None),
            poisoned: Cell::new(false),
            busy: Cell::new(false),
            last_out_of_core_noise: Cell::new(None),
            panic_next_solve: false,
        }
    }

    pub(super) fn set_message(&self, message: String) {
        // Interior NULs would truncate the C string; replace them rather than lose the message.
        *self.last_error.borrow_mut() = Some(super::c_string(&message));
    }
}

/// Creates a reconstructor with every parameter at its default and no points, and writes it to
/// *out. Free it with psr_reconstructor_free.
///
/// out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT (out is NULL) or
/// PSR_STATUS_INTERNAL_ERROR. On failure *out is left untouched.
///
/// # Safety
/// `out` is NULL or valid for writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_new(out: *mut *mut psr_reconstructor) -> psr_status {
    const F: &str = "psr_reconstructor_new";
    guard_no_handle(F, || {
        require_out(F, "out", out)?;
        let handle = Box::into_raw(Box::new(psr_reconstructor::new()));
        // SAFETY: `out` is NULL or valid for writing one pointer (this function's contract).
        unsafe { write_out(F, "out", out, handle) }
    })
}

/// Destroys a reconstructor, its points and its last message. Meshes it produced stay valid.
/// r may be NULL (nothing happens); poisoned handles are freed like any other. Calling it from
/// inside r's own progress callback does nothing.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new, not used again afterwards.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_free(r: *mut psr_reconstructor) {
    guard_value("psr_reconstructor_free", (), || {
        if r.is_null() {
            return;
        }
        // SAFETY: `r` is a live handle (this function's contract). The reference is shared: a
        // solve running on r (this is then a call from its callback) holds a shared one too.
        if unsafe { &*r }.busy.get() {
            return;
        }
        // SAFETY: `r` came from Box::into_raw in psr_reconstructor_new and is not used again
        // (this function's contract), and no call on it is running (it is not busy), so this
        // is the only reference to it.
        drop(unsafe { Box::from_raw(r) });
    })
}

/// The message of the last failed call on r, naming the bad argument, index or parameter, or
/// "" when the last call on r succeeded. The string belongs to r: it stays valid until the next
/// call on r (any psr_reconstructor_* function but this one) and must not be freed. Works on
/// poisoned handles. If r is NULL, returns a static message saying so. Never NULL.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_last_error(
    r: *const psr_reconstructor,
) -> *const c_char {
    static NULL_HANDLE: &str = "psr_reconstructor_last_error: r is NULL\0";
    static EMPTY: &str = "\0";
    guard_value(
        "psr_reconstructor_last_error",
        NULL_HANDLE.as_ptr().cast(),
        // SAFETY: `r` is NULL or a live handle (this function's contract); no call that could
        // change it runs meanwhile, as a handle is used from one thread at a time.
        || match unsafe { r.as_ref() } {
            None => NULL_HANDLE.as_ptr().cast(),
            Some(handle) => match handle.last_error.borrow().as_ref() {
                // The CString's heap buffer does not move when the RefCell guard is dropped; it
                // lives until the next call replaces or clears the message.
                Some(message) => message.as_ptr(),
                None => EMPTY.as_ptr().cast(),
            },
        },
    )
}

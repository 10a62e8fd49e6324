//! The panic boundary: `guard`, the one `catch_unwind` every exported function runs its body
//! through, which also refuses poisoned and busy handles and records the last message; and the
//! helpers that turn C pointers into references and write out-parameters.

use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure, Outcome};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

/// The one panic boundary. Every exported function runs its body through here.
///
/// `r` is the reconstructor the call is on, or NULL for calls on no reconstructor (mesh
/// functions, free, last_error, version and status functions) or when the caller passed NULL
/// (the body then reports it). On a reconstructor, `guard` refuses poisoned handles and calls
/// from inside the handle's own progress callback, clears the last message, and records the
/// outcome: the failure's message, or on a panic, the poisoned flag and the panic's message.
///
/// The body must not hold a reference to `*r` when it returns or unwinds: `guard` reads the
/// handle through its own shared reference before and after the body, never during it.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new, and `body` holds no reference to
/// `*r` when it returns or unwinds.
pub(super) unsafe fn guard(
    function: &str,
    r: *const psr_reconstructor,
    body: impl FnOnce() -> Outcome,
) -> psr_status {
    // SAFETY: a non-NULL `r` is a live handle (this function's contract); the reference is
    // shared and dropped before the body runs.
    if let Some(handle) = unsafe { r.as_ref() } {
        if handle.busy.get() {
            handle.set_message(format!(
                "{function}: called from inside this reconstructor's own progress callback; the \
                 callback may only return true or false (use another handle for other work)"
            ));
            return psr_status::InvalidArgument;
        }
        if handle.poisoned.get() {
            let previous = handle
                .last_error
                .borrow()
                .as_ref()
                .map(|m| m.to_string_lossy().into_owned());
            let original = previous
                .as_deref()
                .map(original_panic_message)
                .unwrap_or_default();
            handle.set_message(format!(
                "{function}: refused: this psr_reconstructor hit an internal error earlier and can \
                 only be freed; create a new one. Original error: {original}"
            ));
            return psr_status::HandlePoisoned;
        }
        *handle.last_error.borrow_mut() = None;
    }
    // AssertUnwindSafe: whatever state a panic leaves half-updated is behind the poisoned flag,
    // which stops every later use of it.
    let outcome = catch_unwind(AssertUnwindSafe(body));
    let (status, message, poison) = match outcome {
        Ok(Ok(())) => return psr_status::Ok,
        Ok(Err(failure)) => (failure.status, failure.message, false),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic with a non-string payload".to_string());
            let message = format!(
                "{function}: {PANIC_PREFIX}{what}. This is a bug in psr; please report it with \
                 the input that triggered it. The handle is now unusable: free it."
            );
            (psr_status::InternalError, message, true)
        }
    };
    // SAFETY: as above; the body has returned or unwound, so no reference it made is live.
    if let Some(handle) = unsafe { r.as_ref() } {
        handle.busy.set(false);
        if poison {
            handle.poisoned.set(true);
        }
        handle.set_message(message);
    }
    status
}

const PANIC_PREFIX: &str = "internal error (panic): ";

/// The first panic's message, kept through later refusals of a poisoned handle.
fn original_panic_message(previous: &str) -> String {
    match previous.find("Original error: ") {
        Some(at) => previous[at + "Original error: ".len()..].to_string(),
        None => previous.to_string(),
    }
}

/// [`guard`] for calls on no reconstructor (psr_reconstructor_new, the mesh functions): a
/// failure's status is returned and its message dropped, as there is no handle to keep it.
pub(super) fn guard_no_handle(function: &str, body: impl FnOnce() -> Outcome) -> psr_status {
    // SAFETY: a NULL reconstructor is never dereferenced.
    unsafe { guard(function, ptr::null(), body) }
}

/// [`guard`] for functions that return a value rather than a status: `fallback` is returned if
/// the body panics.
pub(super) fn guard_value<T>(function: &str, fallback: T, body: impl FnOnce() -> T) -> T {
    let mut value = None;
    guard_no_handle(function, || {
        value = Some(body());
        Ok(())
    });
    value.unwrap_or(fallback)
}

/// The reconstructor behind `r` for a call that changes it.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new, and no other reference to it is
/// live while the returned one is used.
pub(super) unsafe fn handle_mut<'a>(
    function: &str,
    r: *mut psr_reconstructor,
) -> Result<&'a mut psr_reconstructor, Failure> {
    // SAFETY: `r` is NULL (then `as_mut` gives None) or a live handle with no other reference
    // to it live (this function's contract).
    unsafe { r.as_mut() }.ok_or_else(|| Failure::null(function, "r"))
}

/// The reconstructor behind `r` for a call that only reads it.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new, and no mutable reference to it is
/// live while the returned one is used.
pub(super) unsafe fn handle_ref<'a>(
    function: &str,
    r: *const psr_reconstructor,
) -> Result<&'a psr_reconstructor, Failure> {
    // SAFETY: `r` is NULL (then `as_ref` gives None) or a live handle with no mutable
    // reference to it live (this function's contract).
    unsafe { r.as_ref() }.ok_or_else(|| Failure::null(function, "r"))
}

/// Writes an out-parameter (the last step of a successful call).
///
/// # Safety
/// `out` is NULL or valid for writes of `T`.
pub(super) unsafe fn write_out<T>(function: &str, name: &str, out: *mut T, value: T) -> Outcome {
    if out.is_null() {
        return Err(Failure::null(function, name));
    }
    // SAFETY: `out` is not NULL (checked above), so it is valid for writes of `T` (this
    // function's contract). `write` does not read or drop the old value, which C may have left
    // uninitialised.
    unsafe { out.write(value) };
    Ok(())
}

/// Fails early when an out-parameter is NULL, before any work is done.
pub(super) fn require_out<T>(function: &str, name: &str, out: *mut T) -> Outcome {
    if out.is_null() {
        Err(Failure::null(function, name))
    } else {
        Ok(())
    }
}

//! The C API: opaque handles over [`crate::Params`], [`crate::PointSet`] and [`crate::Mesh`].
//!
//! This module only checks arguments, converts between C and Rust representations and forwards
//! to [`crate::reconstruct_with_progress`]; it holds no reconstruction logic. `include/psr.h` is
//! generated from it by cbindgen (see `cbindgen.toml` and `scripts/gen_header.sh`), so the doc
//! comments below are the C documentation: they speak C.
//!
//! Invariants the code below keeps:
//! - No panic crosses the boundary: every exported function runs its body through `guard`,
//!   the one `catch_unwind` of this module. A panic in a call on a reconstructor poisons it.
//! - Out-parameters are written only on success, as the very last step.
//! - No global state: each handle carries its parameters, points, callback and last message, and
//!   each solve builds its own worker pool, so different handles may run on different threads.
//! - `unsafe` is confined to turning C pointers into references and slices, each behind a NULL,
//!   length and overflow check.

#![allow(non_camel_case_types)]

use crate::{Error, Mesh, Params, PointSet, Stage};
use std::cell::{Cell, RefCell};
use std::ffi::{c_char, c_int, c_void, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

// ---------------------------------------------------------------------------------------------
// Versions
// ---------------------------------------------------------------------------------------------

/// Major version of the header you compiled against (the crate version's first number).
/// Compare with psr_version_major() to detect a header/library mismatch.
pub const PSR_VERSION_MAJOR: u32 = 0;
/// Minor version of the header you compiled against.
pub const PSR_VERSION_MINOR: u32 = 1;
/// Patch version of the header you compiled against.
pub const PSR_VERSION_PATCH: u32 = 0;

/// Parses a decimal version component at compile time.
const fn parse_version_component(s: &str) -> u32 {
    let bytes = s.as_bytes();
    let mut value = 0u32;
    let mut i = 0;
    while i < bytes.len() {
        assert!(
            bytes[i].is_ascii_digit(),
            "version component is not a decimal number"
        );
        value = value * 10 + (bytes[i] - b'0') as u32;
        i += 1;
    }
    value
}

// One version source: the crate version. cbindgen can only copy literals into the header, so the
// literals above are checked against Cargo.toml here; bumping the crate version without them
// fails the build.
const _: () = assert!(
    PSR_VERSION_MAJOR == parse_version_component(env!("CARGO_PKG_VERSION_MAJOR")),
    "PSR_VERSION_MAJOR in src/ffi.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);
const _: () = assert!(
    PSR_VERSION_MINOR == parse_version_component(env!("CARGO_PKG_VERSION_MINOR")),
    "PSR_VERSION_MINOR in src/ffi.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);
const _: () = assert!(
    PSR_VERSION_PATCH == parse_version_component(env!("CARGO_PKG_VERSION_PATCH")),
    "PSR_VERSION_PATCH in src/ffi.rs disagrees with Cargo.toml: update it and regenerate include/psr.h"
);

static VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");

// ---------------------------------------------------------------------------------------------
// Plain types
// ---------------------------------------------------------------------------------------------

/// What a fallible psr function reports. 0 is success; the numbers are stable and never reused:
/// new statuses get new numbers. Functions that receive a status from you (psr_status_string)
/// take it as an int, so any value is safe to pass.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum psr_status {
    /// Success.
    Ok = 0,
    /// A required pointer argument was NULL (the message names it).
    NullArgument = 1,
    /// An argument is malformed: a stride smaller than 3 floats, a count whose byte length
    /// overflows, a call from inside the handle's own progress callback (the message says which).
    InvalidArgument = 2,
    /// psr_reconstructor_solve was called on a reconstructor holding no points.
    EmptyInput = 3,
    /// A position has a NaN or infinite coordinate (the message gives its index in the batch).
    NonFinitePosition = 4,
    /// A normal has a NaN or infinite component (the message gives its index in the batch).
    NonFiniteNormal = 5,
    /// A normal has zero length (the message gives its index in the batch).
    ZeroNormal = 6,
    /// A parameter is outside its documented range (the message names it, its value and the
    /// range), or two parameters disagree at solve time (kernel_depth > depth).
    InvalidParameter = 7,
    /// The progress callback returned false.
    Cancelled = 8,
    /// A copy-out buffer is smaller than the data; nothing was written.
    BufferTooSmall = 9,
    /// An earlier call on this reconstructor hit an internal error (a bug); the handle refuses
    /// everything but psr_reconstructor_last_error and psr_reconstructor_free.
    HandlePoisoned = 10,
    /// A bug in psr. If it came from a panic, the handle is now poisoned. Please report it with
    /// the message and the input that triggered it.
    InternalError = 11,
    /// The operating system refused to start the solve's worker threads (a thread or process
    /// limit, or no memory for their stacks). Nothing was computed and the handle stays usable:
    /// set fewer threads (psr_reconstructor_set_threads) or free resources and try again.
    ThreadsUnavailable = 12,
}

/// The pipeline stages reported to the progress callback, in order.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum psr_stage {
    /// Copying the points and mapping them into the unit cube.
    Points = 0,
    /// Estimating the sampling density (it decides the depths the octree needs).
    Density = 1,
    /// Building the octree.
    Octree = 2,
    /// Splatting the normals into the vector field.
    Splat = 3,
    /// Assembling the linear system.
    System = 4,
    /// Solving it, depth by depth.
    Solve = 5,
    /// Computing the isovalue.
    Isovalue = 6,
    /// Extracting the isosurface.
    Extract = 7,
    /// Assembling the output mesh.
    Mesh = 8,
}

impl From<Stage> for psr_stage {
    fn from(stage: Stage) -> Self {
        match stage {
            Stage::Points => psr_stage::Points,
            Stage::Octree => psr_stage::Octree,
            Stage::Density => psr_stage::Density,
            Stage::Splat => psr_stage::Splat,
            Stage::System => psr_stage::System,
            Stage::Solve => psr_stage::Solve,
            Stage::Isovalue => psr_stage::Isovalue,
            Stage::Extract => psr_stage::Extract,
            Stage::Mesh => psr_stage::Mesh,
        }
    }
}

/// A progress callback: receives your user pointer, the current stage and the fraction of that
/// stage done (0 to 1, not necessarily reaching 1), and returns true to go on or false to cancel
/// (psr_reconstructor_solve then returns PSR_STATUS_CANCELLED and no mesh).
///
/// It is called only from inside psr_reconstructor_solve, on the thread that called it, never
/// concurrently with itself. It must not call any function on the reconstructor being solved
/// (such calls are refused with PSR_STATUS_INVALID_ARGUMENT, and psr_reconstructor_free does
/// nothing); it may use other handles, psr_status_string and the version functions. It must not
/// unwind (no C++ exception or longjmp out of it).
pub type psr_progress_fn =
    Option<unsafe extern "C" fn(user: *mut c_void, stage: psr_stage, fraction: f32) -> bool>;

// ---------------------------------------------------------------------------------------------
// Handles
// ---------------------------------------------------------------------------------------------

/// The caller's opaque user pointer. psr never dereferences it; it only hands it back to the
/// callback on the thread that called solve, so moving it between threads with the handle is the
/// caller's business (documented in the header's threading section).
#[derive(Clone, Copy)]
struct UserPointer(*mut c_void);
// SAFETY: psr never dereferences the pointer, see above.
unsafe impl Send for UserPointer {}

/// A reusable reconstruction: parameters, accumulated points, an optional progress callback and
/// the message of the last failed call. Created by psr_reconstructor_new, destroyed by
/// psr_reconstructor_free. Opaque to C.
pub struct psr_reconstructor {
    params: Params,
    points: PointSet,
    progress: psr_progress_fn,
    user: UserPointer,
    /// The last failed call's message, returned by psr_reconstructor_last_error. Interior
    /// mutability because calls taking `const psr_reconstructor *` report failures too; a handle
    /// is never used from two threads at once, which `RefCell` (Send, not Sync) expresses.
    last_error: RefCell<Option<CString>>,
    /// Set when a call on this handle panicked; then every call but last_error and free is
    /// refused.
    poisoned: Cell<bool>,
    /// Set while psr_reconstructor_solve runs, to refuse calls from inside the progress callback.
    busy: Cell<bool>,
    /// Test hook: the next solve panics (see [`debug_panic_next_solve`]).
    panic_next_solve: bool,
}

/// A reconstructed triangle mesh. Created by psr_reconstructor_solve, destroyed by
/// psr_mesh_free; independent of the reconstructor that made it. Opaque to C.
pub struct psr_mesh {
    mesh: Mesh,
}

impl psr_reconstructor {
    fn new() -> Self {
        psr_reconstructor {
            params: Params::default(),
            points: PointSet::new(),
            progress: None,
            user: UserPointer(ptr::null_mut()),
            last_error: RefCell::new(None),
            poisoned: Cell::new(false),
            busy: Cell::new(false),
            panic_next_solve: false,
        }
    }

    fn set_message(&self, message: String) {
        // Interior NULs would truncate the C string; replace them rather than lose the message.
        let message = CString::new(message.replace('\0', "\u{FFFD}")).unwrap_or_default();
        *self.last_error.borrow_mut() = Some(message);
    }
}

// ---------------------------------------------------------------------------------------------
// The panic boundary
// ---------------------------------------------------------------------------------------------

/// Why a call failed: the status returned to C and the message kept on the handle.
struct Failure {
    status: psr_status,
    message: String,
}

impl Failure {
    fn new(status: psr_status, message: impl Into<String>) -> Self {
        Failure {
            status,
            message: message.into(),
        }
    }

    fn null(function: &str, argument: &str) -> Self {
        Failure::new(
            psr_status::NullArgument,
            format!("{function}: {argument} is NULL"),
        )
    }

    /// A Rust API error, prefixed with the C function that met it.
    fn from_error(function: &str, error: Error) -> Self {
        let status = match &error {
            Error::EmptyInput => psr_status::EmptyInput,
            Error::LengthMismatch { .. } => psr_status::InvalidArgument,
            Error::NonFinitePosition { .. } => psr_status::NonFinitePosition,
            Error::NonFiniteNormal { .. } => psr_status::NonFiniteNormal,
            Error::ZeroNormal { .. } => psr_status::ZeroNormal,
            // Weights are not exposed to C yet; when they are, this gets a status of its own.
            Error::InvalidWeight { .. } => psr_status::InvalidArgument,
            Error::NoPositiveWeight => psr_status::InvalidArgument,
            Error::DegenerateInput { .. } => psr_status::InvalidArgument,
            Error::InvalidParameter { .. } => psr_status::InvalidParameter,
            Error::Cancelled => psr_status::Cancelled,
            Error::ThreadsUnavailable { .. } => psr_status::ThreadsUnavailable,
            Error::Internal(_) => psr_status::InternalError,
        };
        Failure::new(status, format!("{function}: {error}"))
    }
}

type Outcome = Result<(), Failure>;

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
fn guard(
    function: &str,
    r: *const psr_reconstructor,
    body: impl FnOnce() -> Outcome,
) -> psr_status {
    // SAFETY: a non-NULL `r` came from psr_reconstructor_new (the caller's contract), and no
    // other reference to it is live here (see above).
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
    // SAFETY: as above; the body has returned, so no reference it made is live.
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

/// [`guard`] for functions that return a value rather than a status: `fallback` is returned if
/// the body panics.
fn guard_value<T>(function: &str, fallback: T, body: impl FnOnce() -> T) -> T {
    let mut value = None;
    guard(function, ptr::null(), || {
        value = Some(body());
        Ok(())
    });
    value.unwrap_or(fallback)
}

/// The reconstructor behind `r` for a call that changes it.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new, with no other reference to it live.
unsafe fn handle_mut<'a>(
    function: &str,
    r: *mut psr_reconstructor,
) -> Result<&'a mut psr_reconstructor, Failure> {
    r.as_mut().ok_or_else(|| Failure::null(function, "r"))
}

/// The reconstructor behind `r` for a call that only reads it.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
unsafe fn handle_ref<'a>(
    function: &str,
    r: *const psr_reconstructor,
) -> Result<&'a psr_reconstructor, Failure> {
    r.as_ref().ok_or_else(|| Failure::null(function, "r"))
}

/// Writes an out-parameter (the last step of a successful call).
///
/// # Safety
/// `out` is NULL or valid for writes of `T`.
unsafe fn write_out<T>(function: &str, name: &str, out: *mut T, value: T) -> Outcome {
    if out.is_null() {
        return Err(Failure::null(function, name));
    }
    out.write(value);
    Ok(())
}

/// Fails early when an out-parameter is NULL, before any work is done.
fn require_out<T>(function: &str, name: &str, out: *mut T) -> Outcome {
    if out.is_null() {
        Err(Failure::null(function, name))
    } else {
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Status and version
// ---------------------------------------------------------------------------------------------

/// The name of a status, e.g. "PSR_STATUS_ZERO_NORMAL", as a static NUL-terminated string
/// (never free it). Any int is accepted: unknown values give "PSR_STATUS_UNKNOWN". Never NULL.
#[no_mangle]
pub extern "C" fn psr_status_string(status: c_int) -> *const c_char {
    let name: &'static str = match status {
        0 => "PSR_STATUS_OK\0",
        1 => "PSR_STATUS_NULL_ARGUMENT\0",
        2 => "PSR_STATUS_INVALID_ARGUMENT\0",
        3 => "PSR_STATUS_EMPTY_INPUT\0",
        4 => "PSR_STATUS_NON_FINITE_POSITION\0",
        5 => "PSR_STATUS_NON_FINITE_NORMAL\0",
        6 => "PSR_STATUS_ZERO_NORMAL\0",
        7 => "PSR_STATUS_INVALID_PARAMETER\0",
        8 => "PSR_STATUS_CANCELLED\0",
        9 => "PSR_STATUS_BUFFER_TOO_SMALL\0",
        10 => "PSR_STATUS_HANDLE_POISONED\0",
        11 => "PSR_STATUS_INTERNAL_ERROR\0",
        12 => "PSR_STATUS_THREADS_UNAVAILABLE\0",
        _ => "PSR_STATUS_UNKNOWN\0",
    };
    name.as_ptr().cast()
}

/// The library's version, "MAJOR.MINOR.PATCH", as a static NUL-terminated string (never free
/// it). Never NULL.
#[no_mangle]
pub extern "C" fn psr_version() -> *const c_char {
    VERSION.as_ptr().cast()
}

/// The library's major version. A program compiled against PSR_VERSION_MAJOR.PSR_VERSION_MINOR
/// can check at run time that the library it loaded is ABI-compatible: for 0.x versions the
/// major and minor must both match; from 1.0 on the major must match and the minor be at least
/// the header's.
#[no_mangle]
pub extern "C" fn psr_version_major() -> u32 {
    PSR_VERSION_MAJOR
}

/// The library's minor version (see psr_version_major).
#[no_mangle]
pub extern "C" fn psr_version_minor() -> u32 {
    PSR_VERSION_MINOR
}

/// The library's patch version (see psr_version_major).
#[no_mangle]
pub extern "C" fn psr_version_patch() -> u32 {
    PSR_VERSION_PATCH
}

// ---------------------------------------------------------------------------------------------
// Reconstructor lifetime and errors
// ---------------------------------------------------------------------------------------------

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
    guard(F, ptr::null(), || {
        require_out(F, "out", out)?;
        let handle = Box::into_raw(Box::new(psr_reconstructor::new()));
        write_out(F, "out", out, handle)
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
        if r.is_null() || (*r).busy.get() {
            return;
        }
        drop(Box::from_raw(r));
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
        || match r.as_ref() {
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

// ---------------------------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------------------------

/// Applies one parameter after checking it alone against its documented range, so that
/// setters can be called in any order. Cross-parameter rules (kernel_depth <= depth) are checked
/// by psr_reconstructor_solve.
///
/// # Safety
/// As for [`handle_mut`].
unsafe fn set_param(
    function: &'static str,
    r: *mut psr_reconstructor,
    apply: impl Fn(&mut Params),
) -> psr_status {
    guard(function, r, || {
        let handle = handle_mut(function, r)?;
        // Check the value against the widest range its parameter may take on its own.
        let mut probe = Params {
            depth: crate::params::MAX_DEPTH,
            ..Params::default()
        };
        apply(&mut probe);
        probe
            .validate()
            .map_err(|e| Failure::from_error(function, e))?;
        apply(&mut handle.params);
        Ok(())
    })
}

/// Reads one parameter into an out-parameter.
///
/// # Safety
/// As for [`handle_ref`] and [`write_out`].
unsafe fn get_param<T>(
    function: &'static str,
    r: *const psr_reconstructor,
    out: *mut T,
    read: impl FnOnce(&Params) -> T,
) -> psr_status {
    guard(function, r, || {
        let handle = handle_ref(function, r)?;
        require_out(function, "out", out)?;
        let value = read(&handle.params);
        write_out(function, "out", out, value)
    })
}

/// Sets the maximum octree depth D: the finest cells are 2^-D of the bounding cube, so each
/// extra level gives about 4x the triangles. Default 8, range 1 to 16.
/// PoissonRecon --depth, PCL setDepth, Open3D depth.
///
/// r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_PARAMETER (value out of range; the parameter keeps its value),
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_depth(
    r: *mut psr_reconstructor,
    depth: u32,
) -> psr_status {
    set_param("psr_reconstructor_set_depth", r, |p| p.depth = depth)
}

/// Writes the maximum octree depth to *out. r and out must not be NULL. Returns PSR_STATUS_OK,
/// PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called
/// from r's progress callback) or PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_depth(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    get_param("psr_reconstructor_get_depth", r, out, |p| p.depth)
}

/// Sets the depth down to which the octree is complete, so the coarse solution is defined
/// everywhere. Default 5, range 0 to 16 (values above depth act as depth).
/// PoissonRecon --fullDepth, PCL setMinDepth.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_full_depth(
    r: *mut psr_reconstructor,
    full_depth: u32,
) -> psr_status {
    set_param("psr_reconstructor_set_full_depth", r, |p| {
        p.full_depth = full_depth
    })
}

/// Writes the full depth to *out. r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_full_depth(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    get_param("psr_reconstructor_get_full_depth", r, out, |p| p.full_depth)
}

/// Sets the depth at which the sampling density is estimated. A negative value (the default,
/// -1) means automatic: depth - 2, at least 0. Range: negative, or 0 to 16; it must not exceed
/// depth, which psr_reconstructor_solve checks (PSR_STATUS_INVALID_PARAMETER), so setters may
/// come in any order. PoissonRecon --kernelDepth.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_kernel_depth(
    r: *mut psr_reconstructor,
    kernel_depth: i32,
) -> psr_status {
    let value = u32::try_from(kernel_depth).ok();
    set_param("psr_reconstructor_set_kernel_depth", r, |p| {
        p.kernel_depth = value
    })
}

/// Writes the kernel depth to *out: -1 when automatic, else the depth that was set (not the
/// resolved automatic value). r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_kernel_depth(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    // Set values are at most MAX_DEPTH (16), so the conversion cannot fail.
    get_param("psr_reconstructor_get_kernel_depth", r, out, |p| {
        p.kernel_depth
            .map_or(-1, |k| i32::try_from(k).unwrap_or(i32::MAX))
    })
}

/// Sets the target number of samples per octree node: sparser samples are splatted at coarser
/// depths, which smooths noisy input. Default 1.5, range 1 to 1e6.
/// PoissonRecon --samplesPerNode, PCL setSamplesPerNode.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth (NaN and infinities
/// give PSR_STATUS_INVALID_PARAMETER).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_samples_per_node(
    r: *mut psr_reconstructor,
    samples_per_node: f32,
) -> psr_status {
    set_param("psr_reconstructor_set_samples_per_node", r, |p| {
        p.samples_per_node = samples_per_node
    })
}

/// Writes the samples per node to *out. r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_samples_per_node(
    r: *const psr_reconstructor,
    out: *mut f32,
) -> psr_status {
    get_param("psr_reconstructor_get_samples_per_node", r, out, |p| {
        p.samples_per_node
    })
}

/// Sets the ratio between the reconstruction cube and the points' bounding box. Default 1.1,
/// range 1 to 100. PoissonRecon --scale, PCL setScale, Open3D scale.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_scale(
    r: *mut psr_reconstructor,
    scale: f32,
) -> psr_status {
    set_param("psr_reconstructor_set_scale", r, |p| p.scale = scale)
}

/// Writes the scale to *out. r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_scale(
    r: *const psr_reconstructor,
    out: *mut f32,
) -> psr_status {
    get_param("psr_reconstructor_get_scale", r, out, |p| p.scale)
}

/// Sets the screening weight alpha (Kazhdan & Hoppe 2013): how strongly the surface is pulled
/// onto the samples; 0 gives the unscreened 2006 method. Default 4, range 0 to 1e6.
/// PoissonRecon --pointWeight, PCL setPointWeight.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_point_weight(
    r: *mut psr_reconstructor,
    point_weight: f32,
) -> psr_status {
    set_param("psr_reconstructor_set_point_weight", r, |p| {
        p.point_weight = point_weight
    })
}

/// Writes the screening weight to *out. r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_point_weight(
    r: *const psr_reconstructor,
    out: *mut f32,
) -> psr_status {
    get_param("psr_reconstructor_get_point_weight", r, out, |p| {
        p.point_weight
    })
}

/// Sets the number of worker threads psr_reconstructor_solve uses; 0 (the default) means one
/// per core. Each solve starts and stops its own workers: psr never uses a global or
/// host-provided thread pool, and the mesh does not depend on this count. Range 0 to 4096.
/// Open3D n_threads, PCL setThreads.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_threads(
    r: *mut psr_reconstructor,
    threads: u32,
) -> psr_status {
    let threads = usize::try_from(threads).unwrap_or(usize::MAX);
    set_param("psr_reconstructor_set_threads", r, |p| p.threads = threads)
}

/// Writes the thread count to *out (0 = one per core). r and out must not be NULL. Returns the
/// statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_threads(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    // Set values are at most 4096, so the conversion cannot fail.
    get_param("psr_reconstructor_get_threads", r, out, |p| {
        u32::try_from(p.threads).unwrap_or(u32::MAX)
    })
}

/// Sets the most conjugate-gradient iterations per depth. Default 60, range 1 to 10000.
/// PoissonRecon --iters (counts Gauss-Seidel sweeps, not the same unit).
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_max_solver_iterations(
    r: *mut psr_reconstructor,
    iterations: u32,
) -> psr_status {
    set_param("psr_reconstructor_set_max_solver_iterations", r, |p| {
        p.max_solver_iterations = iterations
    })
}

/// Writes the most solver iterations per depth to *out. r and out must not be NULL. Returns
/// the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_max_solver_iterations(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    get_param("psr_reconstructor_get_max_solver_iterations", r, out, |p| {
        p.max_solver_iterations
    })
}

/// Sets the relative residual |b - Ax| / |b| at which a depth's solve stops. Default 1e-2,
/// range 1e-12 (inclusive) to 1 (exclusive). PoissonRecon --cgAccuracy (coarsest level only).
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_solver_tolerance(
    r: *mut psr_reconstructor,
    tolerance: f64,
) -> psr_status {
    set_param("psr_reconstructor_set_solver_tolerance", r, |p| {
        p.solver_tolerance = tolerance
    })
}

/// Writes the solver tolerance to *out. r and out must not be NULL. Returns the statuses of
/// psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_solver_tolerance(
    r: *const psr_reconstructor,
    out: *mut f64,
) -> psr_status {
    get_param("psr_reconstructor_get_solver_tolerance", r, out, |p| {
        p.solver_tolerance
    })
}

/// Boundary conditions at the bounding cube, for psr_reconstructor_set_boundary.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_boundary {
    /// Zero normal derivative on the cube's faces (the default; PoissonRecon --bType 3, Open3D).
    Neumann = 0,
    /// The 2006 paper: node functions simply end beyond the cube (PoissonRecon --bType 1).
    Free = 1,
}

/// Splatting weights, for psr_reconstructor_set_splatting.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_splatting {
    /// The node functions' own B-spline weights over 3x3x3 nodes (the default; smoother and
    /// more accurate, about 1.6x the time).
    Bspline = 0,
    /// The 2006 paper's trilinear weights over the 8 nearest nodes.
    Trilinear = 1,
}

/// Where the mesh's vertices go, for psr_reconstructor_set_vertex_placement.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_vertex_placement {
    /// Found on the isosurface, then moved along the normal by the mean sag of the chords they
    /// end, so that the flat triangles straddle the curved surface (the default; closer to the
    /// surface and to the input points).
    Fitted = 0,
    /// Exactly on the isosurface {chi = isovalue}, as PoissonRecon places them.
    OnIsosurface = 1,
}

/// Sets a parameter that takes one of a few named values, given as an integer (never trusted
/// as a Rust enum).
///
/// # Safety
/// As for [`handle_mut`].
unsafe fn set_choice<T: Copy>(
    function: &'static str,
    r: *mut psr_reconstructor,
    name: &'static str,
    expected: &'static str,
    value: i32,
    choices: &[T],
    apply: impl Fn(&mut Params, T),
) -> psr_status {
    guard(function, r, || {
        let handle = handle_mut(function, r)?;
        let choice = usize::try_from(value)
            .ok()
            .and_then(|i| choices.get(i).copied())
            .ok_or_else(|| {
                Failure::from_error(
                    function,
                    Error::InvalidParameter {
                        name,
                        value: value.to_string(),
                        expected,
                    },
                )
            })?;
        apply(&mut handle.params, choice);
        Ok(())
    })
}

/// Sets the boundary condition: PSR_BOUNDARY_NEUMANN (0, the default) or PSR_BOUNDARY_FREE (1).
/// PoissonRecon --bType.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for any other value).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_boundary(
    r: *mut psr_reconstructor,
    boundary: i32,
) -> psr_status {
    set_choice(
        "psr_reconstructor_set_boundary",
        r,
        "boundary",
        "PSR_BOUNDARY_NEUMANN (0) or PSR_BOUNDARY_FREE (1)",
        boundary,
        &[crate::Boundary::Neumann, crate::Boundary::Free],
        |p, b| p.boundary = b,
    )
}

/// Writes the boundary condition (a psr_boundary value) to *out. r and out must not be NULL.
/// Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_boundary(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    get_param("psr_reconstructor_get_boundary", r, out, |p| {
        match p.boundary {
            crate::Boundary::Neumann => psr_boundary::Neumann as i32,
            crate::Boundary::Free => psr_boundary::Free as i32,
        }
    })
}

/// Sets the splatting weights: PSR_SPLATTING_BSPLINE (0, the default) or
/// PSR_SPLATTING_TRILINEAR (1, the 2006 paper's).
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for any other value).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_splatting(
    r: *mut psr_reconstructor,
    splatting: i32,
) -> psr_status {
    set_choice(
        "psr_reconstructor_set_splatting",
        r,
        "splatting",
        "PSR_SPLATTING_BSPLINE (0) or PSR_SPLATTING_TRILINEAR (1)",
        splatting,
        &[crate::Splatting::BSpline, crate::Splatting::Trilinear],
        |p, v| p.splatting = v,
    )
}

/// Writes the splatting weights (a psr_splatting value) to *out. r and out must not be NULL.
/// Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_splatting(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    get_param("psr_reconstructor_get_splatting", r, out, |p| {
        match p.splatting {
            crate::Splatting::BSpline => psr_splatting::Bspline as i32,
            crate::Splatting::Trilinear => psr_splatting::Trilinear as i32,
        }
    })
}

/// Sets where the mesh's vertices go: PSR_VERTEX_PLACEMENT_FITTED (0, the default: moved off the
/// isosurface by the mean sag of their chords, so that the triangles straddle it) or
/// PSR_VERTEX_PLACEMENT_ON_ISOSURFACE (1: exactly on it, as PoissonRecon places them).
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for any other value).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_vertex_placement(
    r: *mut psr_reconstructor,
    placement: i32,
) -> psr_status {
    set_choice(
        "psr_reconstructor_set_vertex_placement",
        r,
        "vertex_placement",
        "PSR_VERTEX_PLACEMENT_FITTED (0) or PSR_VERTEX_PLACEMENT_ON_ISOSURFACE (1)",
        placement,
        &[
            crate::VertexPlacement::Fitted,
            crate::VertexPlacement::OnIsosurface,
        ],
        |p, v| p.vertex_placement = v,
    )
}

/// Writes where the vertices go (a psr_vertex_placement value) to *out. r and out must not be
/// NULL. Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_vertex_placement(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    get_param(
        "psr_reconstructor_get_vertex_placement",
        r,
        out,
        |p| match p.vertex_placement {
            crate::VertexPlacement::Fitted => psr_vertex_placement::Fitted as i32,
            crate::VertexPlacement::OnIsosurface => psr_vertex_placement::OnIsosurface as i32,
        },
    )
}

// ---------------------------------------------------------------------------------------------
// Points
// ---------------------------------------------------------------------------------------------

/// Size of one position or normal: 3 floats.
const VEC3_BYTES: usize = 3 * std::mem::size_of::<f32>();

/// Copies `count` 3-float vectors starting `stride` bytes apart (0 = packed). The caller has
/// checked that `base` is non-NULL, `stride` is 0 or at least 12 and the span does not overflow.
///
/// # Safety
/// `base` is valid for reads of the whole span.
unsafe fn gather_vec3(base: *const f32, stride: usize, count: usize) -> Vec<[f32; 3]> {
    let stride = if stride == 0 { VEC3_BYTES } else { stride };
    let bytes = base.cast::<u8>();
    (0..count)
        // Unaligned reads: interleaved vertex formats with odd strides are accepted.
        .map(|i| bytes.add(i * stride).cast::<[f32; 3]>().read_unaligned())
        .collect()
}

/// Checks one strided array argument; `stride` 0 means packed.
fn check_array(
    function: &str,
    name: &str,
    stride_name: &str,
    base: *const f32,
    stride: usize,
    count: usize,
) -> Outcome {
    if base.is_null() {
        return Err(Failure::null(
            function,
            &format!("{name} (with count {count})"),
        ));
    }
    let stride = if stride == 0 { VEC3_BYTES } else { stride };
    if stride < VEC3_BYTES {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!("{function}: {stride_name} is {stride} bytes, less than one element (3 floats = 12 bytes); use 0 for packed arrays"),
        ));
    }
    // The last element ends at (count - 1) * stride + 12, which must fit in isize.
    let span = (count - 1)
        .checked_mul(stride)
        .and_then(|s| s.checked_add(VEC3_BYTES));
    match span {
        Some(span) if span <= isize::MAX as usize => Ok(()),
        _ => Err(Failure::new(
            psr_status::InvalidArgument,
            format!("{function}: {count} points with a {stride}-byte {stride_name} span more bytes than memory can hold"),
        )),
    }
}

/// Appends `count` oriented points to r. Position i is the 3 floats at
/// `(const char *)positions + i * position_stride_bytes`, normal i likewise; a stride of 0 means
/// tightly packed (12 bytes), otherwise it must be at least 12 (interleaved vertex structs are
/// fine; no alignment is required). Normals need not be unit length; they are normalised.
///
/// The points are copied: the arrays may be freed as soon as this returns. Calls append, so a
/// cloud can be added in batches. The batch is checked whole first: if any position is NaN or
/// infinite, or any normal is NaN, infinite or zero, nothing from this batch is appended, points
/// from earlier batches stay, and the message names the first bad index within this batch.
///
/// Extensions (per-point confidence weights, colours) will come as new functions, e.g.
/// psr_reconstructor_add_points_ex taking a struct that begins with its own size, never by
/// changing this signature.
///
/// r must not be NULL; positions and normals may be NULL only when count is 0 (then nothing
/// happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
/// stride below 12, or count * stride overflowing), PSR_STATUS_NON_FINITE_POSITION,
/// PSR_STATUS_NON_FINITE_NORMAL, PSR_STATUS_ZERO_NORMAL, PSR_STATUS_HANDLE_POISONED or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
/// strided spans described above.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_points(
    r: *mut psr_reconstructor,
    positions: *const f32,
    position_stride_bytes: usize,
    normals: *const f32,
    normal_stride_bytes: usize,
    count: usize,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_points";
    guard(F, r, || {
        let handle = handle_mut(F, r)?;
        if count == 0 {
            return Ok(());
        }
        check_array(
            F,
            "positions",
            "position_stride_bytes",
            positions,
            position_stride_bytes,
            count,
        )?;
        check_array(
            F,
            "normals",
            "normal_stride_bytes",
            normals,
            normal_stride_bytes,
            count,
        )?;
        let p = gather_vec3(positions, position_stride_bytes, count);
        let n = gather_vec3(normals, normal_stride_bytes, count);
        handle.points.extend(&p, &n).map_err(|e| {
            let mut failure = Failure::from_error(F, e);
            failure
                .message
                .push_str(" (index within this batch; nothing from this batch was added)");
            failure
        })
    })
}

/// Writes the number of points r holds to *out. r and out must not be NULL. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_HANDLE_POISONED,
/// PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback) or PSR_STATUS_INTERNAL_ERROR;
/// *out is written only on success.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_point_count(
    r: *const psr_reconstructor,
    out: *mut usize,
) -> psr_status {
    const F: &str = "psr_reconstructor_point_count";
    guard(F, r, || {
        let handle = handle_ref(F, r)?;
        write_out(F, "out", out, handle.points.len())
    })
}

/// Removes every point from r (parameters and callback stay), so the handle can be reused for
/// another cloud. r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_clear_points(r: *mut psr_reconstructor) -> psr_status {
    const F: &str = "psr_reconstructor_clear_points";
    guard(F, r, || {
        handle_mut(F, r)?.points.clear();
        Ok(())
    })
}

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
    guard(F, r, || {
        let handle = handle_mut(F, r)?;
        handle.progress = callback;
        handle.user = UserPointer(user);
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------------
// Solve
// ---------------------------------------------------------------------------------------------

/// Reconstructs a watertight mesh from r's points and parameters and writes a new mesh to
/// *out; free it with psr_mesh_free. r keeps its points and parameters and may be solved again.
/// Runs on the calling thread, using the number of worker threads set with
/// psr_reconstructor_set_threads; the progress callback, if any, is called on the calling thread.
///
/// r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_EMPTY_INPUT (no points), PSR_STATUS_INVALID_PARAMETER (kernel_depth > depth),
/// PSR_STATUS_CANCELLED (the callback returned false), PSR_STATUS_HANDLE_POISONED,
/// PSR_STATUS_INVALID_ARGUMENT (called from r's own progress callback, or all points coincide)
/// or PSR_STATUS_INTERNAL_ERROR (a bug; if it was a panic, r is now poisoned). On failure *out is
/// left untouched.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_solve(
    r: *mut psr_reconstructor,
    out: *mut *mut psr_mesh,
) -> psr_status {
    const F: &str = "psr_reconstructor_solve";
    guard(F, r, || {
        require_out(F, "out", out)?;
        let (params, callback, user, panic_now) = {
            let handle = handle_mut(F, r)?;
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
        // No reference to *r is held while the callback runs: a call it makes on r sees `busy`
        // through its own shared reference and is refused. The points are borrowed through a
        // shared reference, which those refused calls do not conflict with.
        let handle: &psr_reconstructor = &*r;
        handle.busy.set(true);
        let mut progress = |stage: Stage, fraction: f32| match callback {
            Some(f) => f(user.0, stage.into(), fraction),
            None => true,
        };
        let result = crate::reconstruct_with_progress(&handle.points, &params, &mut progress);
        handle.busy.set(false);
        let mesh = result.map_err(|e| Failure::from_error(F, e))?;
        let mesh = Box::into_raw(Box::new(psr_mesh { mesh }));
        write_out(F, "out", out, mesh)
    })
}

/// Test hook: makes the next solve on `r` panic inside the panic boundary, to prove that the
/// panic becomes `InternalError` and poisons the handle. Not part of the C API.
///
/// # Safety
/// `r` is a live handle from psr_reconstructor_new.
#[doc(hidden)]
pub unsafe fn debug_panic_next_solve(r: *mut psr_reconstructor) {
    if let Some(handle) = r.as_mut() {
        handle.panic_next_solve = true;
    }
}

/// Test hook: wraps a mesh built in Rust as a C handle (free it with psr_mesh_free), so the
/// mesh functions can be tested on known data. Not part of the C API.
#[doc(hidden)]
pub fn debug_mesh_new(mesh: Mesh) -> *mut psr_mesh {
    Box::into_raw(Box::new(psr_mesh { mesh }))
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
    guard(F, r, || {
        handle_mut(F, r)?.panic_next_solve = true;
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------------
// Mesh
// ---------------------------------------------------------------------------------------------

/// Number of vertices of m; 0 if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_vertex_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_vertex_count", 0, || {
        m.as_ref().map_or(0, |m| m.mesh.positions.len())
    })
}

/// Number of triangles of m; 0 if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_triangle_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_triangle_count", 0, || {
        m.as_ref().map_or(0, |m| m.mesh.triangles.len())
    })
}

/// The vertex positions of m, 3 floats (x, y, z) per vertex, in the input's coordinates, owned
/// by m: valid until psr_mesh_free(m), never to be freed or written. NULL if m is NULL or has no
/// vertices.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_positions(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_positions", ptr::null(), || match m.as_ref() {
        Some(m) if !m.mesh.positions.is_empty() => m.mesh.positions.as_ptr().cast(),
        _ => ptr::null(),
    })
}

/// The triangles of m, 3 zero-based vertex indices per triangle, counter-clockwise seen from
/// outside (so face normals point out of the solid), owned by m: valid until psr_mesh_free(m).
/// NULL if m is NULL or has no triangles.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_triangles(m: *const psr_mesh) -> *const u32 {
    guard_value("psr_mesh_triangles", ptr::null(), || match m.as_ref() {
        Some(m) if !m.mesh.triangles.is_empty() => m.mesh.triangles.as_ptr().cast(),
        _ => ptr::null(),
    })
}

/// The sampling density estimate at each vertex (one float per vertex), owned by m: valid until
/// psr_mesh_free(m). Low values mark surface invented far from any sample; drop triangles whose
/// vertices fall below a threshold to trim it (like PoissonRecon's SurfaceTrimmer). NULL if m is
/// NULL or has no vertices.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_densities(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_densities", ptr::null(), || match m.as_ref() {
        Some(m) if !m.mesh.densities.is_empty() => m.mesh.densities.as_ptr(),
        _ => ptr::null(),
    })
}

/// The isovalue the surface was extracted at (the indicator function's mean over the samples,
/// paper section 4.4). NaN if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_isovalue(m: *const psr_mesh) -> f64 {
    guard_value("psr_mesh_isovalue", f64::NAN, || {
        m.as_ref().map_or(f64::NAN, |m| m.mesh.stats.isovalue)
    })
}

/// Copies `src` into `dst` (capacity in elements) after the checks shared by the copy-outs.
///
/// # Safety
/// `dst` is NULL or valid for writes of `capacity` elements.
unsafe fn copy_out<T: Copy>(
    m: *const psr_mesh,
    src: impl FnOnce(&Mesh) -> &[T],
    dst: *mut T,
    capacity: usize,
) -> psr_status {
    guard("psr_mesh_copy", ptr::null(), || {
        let m = m
            .as_ref()
            .ok_or_else(|| Failure::null("psr_mesh_copy", "m"))?;
        let src = src(&m.mesh);
        if src.is_empty() {
            return Ok(());
        }
        if dst.is_null() {
            return Err(Failure::null("psr_mesh_copy", "dst"));
        }
        if capacity < src.len() {
            return Err(Failure::new(psr_status::BufferTooSmall, ""));
        }
        ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len());
        Ok(())
    })
}

/// Copies the vertex positions of m into dst: 3 * psr_mesh_vertex_count(m) floats.
/// capacity_floats is the number of floats dst can hold.
///
/// m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_positions(
    m: *const psr_mesh,
    dst: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    copy_out(
        m,
        |mesh| mesh.positions.as_flattened(),
        dst,
        capacity_floats,
    )
}

/// Copies the triangles of m into dst: 3 * psr_mesh_triangle_count(m) vertex indices.
/// capacity_indices is the number of uint32_t dst can hold.
///
/// m must not be NULL; dst may be NULL only when the mesh has no triangles. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_indices` values.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_triangles(
    m: *const psr_mesh,
    dst: *mut u32,
    capacity_indices: usize,
) -> psr_status {
    copy_out(
        m,
        |mesh| mesh.triangles.as_flattened(),
        dst,
        capacity_indices,
    )
}

/// Copies the per-vertex densities of m into dst: psr_mesh_vertex_count(m) floats.
/// capacity_floats is the number of floats dst can hold.
///
/// m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_densities(
    m: *const psr_mesh,
    dst: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    copy_out(m, |mesh| &mesh.densities, dst, capacity_floats)
}

/// Destroys a mesh and its arrays; pointers from psr_mesh_positions and the like become invalid.
/// m may be NULL (nothing happens).
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve, not used again afterwards.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_free(m: *mut psr_mesh) {
    guard_value("psr_mesh_free", (), || {
        if !m.is_null() {
            drop(Box::from_raw(m));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    fn assert_send<T: Send>() {}

    #[test]
    fn handles_are_send() {
        assert_send::<psr_reconstructor>();
        assert_send::<psr_mesh>();
    }

    #[test]
    fn status_names_match_the_enum() {
        let all = [
            (psr_status::Ok, "PSR_STATUS_OK"),
            (psr_status::NullArgument, "PSR_STATUS_NULL_ARGUMENT"),
            (psr_status::InvalidArgument, "PSR_STATUS_INVALID_ARGUMENT"),
            (psr_status::EmptyInput, "PSR_STATUS_EMPTY_INPUT"),
            (
                psr_status::NonFinitePosition,
                "PSR_STATUS_NON_FINITE_POSITION",
            ),
            (psr_status::NonFiniteNormal, "PSR_STATUS_NON_FINITE_NORMAL"),
            (psr_status::ZeroNormal, "PSR_STATUS_ZERO_NORMAL"),
            (psr_status::InvalidParameter, "PSR_STATUS_INVALID_PARAMETER"),
            (psr_status::Cancelled, "PSR_STATUS_CANCELLED"),
            (psr_status::BufferTooSmall, "PSR_STATUS_BUFFER_TOO_SMALL"),
            (psr_status::HandlePoisoned, "PSR_STATUS_HANDLE_POISONED"),
            (psr_status::InternalError, "PSR_STATUS_INTERNAL_ERROR"),
            (
                psr_status::ThreadsUnavailable,
                "PSR_STATUS_THREADS_UNAVAILABLE",
            ),
        ];
        for (status, name) in all {
            let got = unsafe { CStr::from_ptr(psr_status_string(status as c_int)) };
            assert_eq!(got.to_str().unwrap(), name);
        }
        for unknown in [-1, 13, c_int::MAX, c_int::MIN] {
            let got = unsafe { CStr::from_ptr(psr_status_string(unknown)) };
            assert_eq!(got.to_str().unwrap(), "PSR_STATUS_UNKNOWN");
        }
    }

    #[test]
    fn version_parts_match_the_crate_version() {
        let text = unsafe { CStr::from_ptr(psr_version()) }.to_str().unwrap();
        assert_eq!(text, env!("CARGO_PKG_VERSION"));
        assert_eq!(
            format!(
                "{}.{}.{}",
                psr_version_major(),
                psr_version_minor(),
                psr_version_patch()
            ),
            text
        );
    }

    #[test]
    fn stages_keep_their_numbers() {
        for stage in Stage::ALL {
            assert_eq!(psr_stage::from(stage) as u32, stage as u32);
        }
    }
}

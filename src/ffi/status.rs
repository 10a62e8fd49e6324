//! Statuses: `psr_status`, `psr_status_string`, and `Failure`, a failed call's status and
//! message, with the mapping from the Rust [`crate::Error`] to a status.

use crate::Error;
use std::ffi::{c_char, c_int};

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
    /// A position, of a point or of a sensor, has a NaN or infinite coordinate (the message says
    /// which and gives its index in the batch).
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
    /// A colour component or channel value given with a point is NaN or infinite (the message
    /// names the colours or the channel and gives the point's index in the batch).
    NonFiniteAttribute = 13,
    /// A confidence weight is negative, NaN or infinite (the message gives its index in the
    /// batch), or, at solve, every weight is 0.
    InvalidWeight = 14,
    /// A transform given with points (psr_reconstructor_add_points_transformed) has a NaN or
    /// infinite entry, is not affine (last row not 0 0 0 1) or is singular (the message says
    /// which).
    InvalidTransform = 15,
    /// The mesh would have more vertices, or the input more points, than 32-bit indices can
    /// name (the message gives the count): reconstruct at a lower depth or in pieces.
    TooLarge = 16,
    /// The solve needs more memory than psr_reconstructor_set_max_memory allows (checked
    /// before the memory is allocated: from the point count, then from the octree's node
    /// counts), or the system refused an allocation. The message names what was being
    /// allocated, the bytes needed, the limit and, when known, the smallest limit that would
    /// do. Nothing was kept and the handle stays usable: raise the limit, lower the depth or
    /// free memory, and solve again (the same mesh as a handle that never failed).
    OutOfMemory = 17,
    /// A file could not be opened, read, created or written (psr_ply_read, psr_mesh_write_ply):
    /// the message has the path and the system's reason (no such file, permission denied, disk
    /// full).
    IoError = 18,
    /// A file was read but is not what it should be (psr_ply_read): not PLY, a malformed header
    /// or value, a truncated body, no vertex element or no x y z, a face index out of range. The
    /// message says where (line, element, entry).
    InvalidFile = 19,
}

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
        13 => "PSR_STATUS_NON_FINITE_ATTRIBUTE\0",
        14 => "PSR_STATUS_INVALID_WEIGHT\0",
        15 => "PSR_STATUS_INVALID_TRANSFORM\0",
        16 => "PSR_STATUS_TOO_LARGE\0",
        17 => "PSR_STATUS_OUT_OF_MEMORY\0",
        18 => "PSR_STATUS_IO_ERROR\0",
        19 => "PSR_STATUS_INVALID_FILE\0",
        _ => "PSR_STATUS_UNKNOWN\0",
    };
    name.as_ptr().cast()
}

/// Why a call failed: the status returned to C and the message kept on the handle.
pub(super) struct Failure {
    pub(super) status: psr_status,
    pub(super) message: String,
}

impl Failure {
    pub(super) fn new(status: psr_status, message: impl Into<String>) -> Self {
        Failure {
            status,
            message: message.into(),
        }
    }

    pub(super) fn null(function: &str, argument: &str) -> Self {
        Failure::new(
            psr_status::NullArgument,
            format!("{function}: {argument} is NULL"),
        )
    }

    /// A Rust API error, prefixed with the C function that met it.
    pub(super) fn from_error(function: &str, error: Error) -> Self {
        let status = match &error {
            Error::EmptyInput => psr_status::EmptyInput,
            Error::LengthMismatch { .. } => psr_status::InvalidArgument,
            Error::NonFinitePosition { .. } => psr_status::NonFinitePosition,
            Error::NonFiniteNormal { .. } => psr_status::NonFiniteNormal,
            Error::ZeroNormal { .. } => psr_status::ZeroNormal,
            Error::InvalidWeight { .. } => psr_status::InvalidWeight,
            Error::NoPositiveWeight => psr_status::InvalidWeight,
            Error::DegenerateInput { .. } => psr_status::InvalidArgument,
            // Normal estimation is not exposed to C yet; these get statuses when it is.
            Error::TooFewPoints { .. } => psr_status::InvalidArgument,
            Error::NoPlaneDefined { .. } => psr_status::InvalidArgument,
            Error::InvalidParameter { .. } => psr_status::InvalidParameter,
            // A psr_mesh is always consistent (psr made it), so C never meets this.
            Error::InvalidMesh(_) => psr_status::InvalidArgument,
            Error::Cancelled => psr_status::Cancelled,
            Error::ThreadsUnavailable { .. } => psr_status::ThreadsUnavailable,
            Error::NonFiniteAttribute { .. } => psr_status::NonFiniteAttribute,
            // Mismatched lengths, batches with other attributes than the points before them and
            // bad channel names are malformed arguments.
            Error::AttributeLength { .. } => psr_status::InvalidArgument,
            Error::AttributesDiffer { .. } => psr_status::InvalidArgument,
            Error::InvalidChannelName { .. } => psr_status::InvalidArgument,
            Error::InvalidTransform { .. } => psr_status::InvalidTransform,
            Error::TooLarge { .. } => psr_status::TooLarge,
            Error::OutOfMemory { .. } => psr_status::OutOfMemory,
            Error::Internal(_) => psr_status::InternalError,
        };
        Failure::new(status, format!("{function}: {error}"))
    }
}

pub(super) type Outcome = Result<(), Failure>;

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

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
            (
                psr_status::NonFiniteAttribute,
                "PSR_STATUS_NON_FINITE_ATTRIBUTE",
            ),
            (psr_status::InvalidWeight, "PSR_STATUS_INVALID_WEIGHT"),
            (psr_status::InvalidTransform, "PSR_STATUS_INVALID_TRANSFORM"),
            (psr_status::TooLarge, "PSR_STATUS_TOO_LARGE"),
            (psr_status::OutOfMemory, "PSR_STATUS_OUT_OF_MEMORY"),
            (psr_status::IoError, "PSR_STATUS_IO_ERROR"),
            (psr_status::InvalidFile, "PSR_STATUS_INVALID_FILE"),
        ];
        for (status, name) in all {
            // SAFETY: psr_status_string returns a static NUL-terminated string, never NULL.
            let got = unsafe { CStr::from_ptr(psr_status_string(status as c_int)) };
            assert_eq!(got.to_str().unwrap(), name);
        }
        for unknown in [-1, 20, c_int::MAX, c_int::MIN] {
            // SAFETY: as above.
            let got = unsafe { CStr::from_ptr(psr_status_string(unknown)) };
            assert_eq!(got.to_str().unwrap(), "PSR_STATUS_UNKNOWN");
        }
    }
}

//! Points: psr_reconstructor_add_points (strided, checked whole before anything is appended),
//! its double-precision and transformed forms (psr_reconstructor_add_points_f64,
//! psr_reconstructor_add_points_transformed), psr_reconstructor_point_count and
//! psr_reconstructor_clear_points.

use super::panic_boundary::{guard, handle_mut, handle_ref, write_out};
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure, Outcome};

/// Copies `count` 3-float vectors starting `stride` bytes apart (0 = packed).
///
/// # Safety
/// As for [`gather_vec3_of`].
pub(super) unsafe fn gather_vec3(base: *const f32, stride: usize, count: usize) -> Vec<[f32; 3]> {
    // SAFETY: forwarded from this function's contract.
    unsafe { gather_vec3_of(base, stride, count) }
}

/// Copies `count` vectors of 3 `T` (float or double) starting `stride` bytes apart (0 =
/// packed).
///
/// # Safety
/// `base`, `stride` and `count` have passed [`check_array_of`] (so `base` is not NULL and the
/// span fits in `isize`), and `base` is valid for reads of that whole span: `count` vectors of
/// 3 `T`, `stride` bytes apart.
pub(super) unsafe fn gather_vec3_of<T: Copy>(
    base: *const T,
    stride: usize,
    count: usize,
) -> Vec<[T; 3]> {
    let element = 3 * std::mem::size_of::<T>();
    let stride = if stride == 0 { element } else { stride };
    let bytes = base.cast::<u8>();
    (0..count)
        .map(|i| {
            // SAFETY: i < count, so the vector at base + i * stride lies inside the span,
            // which is readable and fits in isize (this function's contract); the reads are
            // unaligned, so interleaved vertex formats with odd strides are accepted.
            unsafe { bytes.add(i * stride).cast::<[T; 3]>().read_unaligned() }
        })
        .collect()
}

/// A rejected batch's failure: the error's message says that its index counts within the batch
/// and that nothing from the batch was added.
pub(super) fn batch_failure(function: &str, error: crate::Error) -> Failure {
    let mut failure = Failure::from_error(function, error);
    failure
        .message
        .push_str(" (index within this batch; nothing from this batch was added)");
    failure
}

/// Checks one strided array argument of 3-float vectors; `stride` 0 means packed.
pub(super) fn check_array(
    function: &str,
    name: &str,
    stride_name: &str,
    base: *const f32,
    stride: usize,
    count: usize,
) -> Outcome {
    check_array_of(function, name, stride_name, base, stride, count)
}

/// Checks one strided array argument of vectors of 3 `T` (float or double); `stride` 0 means
/// packed.
pub(super) fn check_array_of<T>(
    function: &str,
    name: &str,
    stride_name: &str,
    base: *const T,
    stride: usize,
    count: usize,
) -> Outcome {
    let element = 3 * std::mem::size_of::<T>();
    let scalar = if std::mem::size_of::<T>() == 8 {
        "doubles"
    } else {
        "floats"
    };
    if base.is_null() {
        return Err(Failure::null(
            function,
            &format!("{name} (with count {count})"),
        ));
    }
    let stride = if stride == 0 { element } else { stride };
    if stride < element {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!("{function}: {stride_name} is {stride} bytes, less than one element (3 {scalar} = {element} bytes); use 0 for packed arrays"),
        ));
    }
    // The last element ends at (count - 1) * stride + element, which must fit in isize.
    let span = (count - 1)
        .checked_mul(stride)
        .and_then(|s| s.checked_add(element));
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
/// Per-point confidence weights, colours and channels come through
/// psr_reconstructor_add_point_arrays, whose struct begins with its own size; this signature
/// never changes.
///
/// r must not be NULL; positions and normals may be NULL only when count is 0 (then nothing
/// happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
/// stride below 12, count * stride overflowing, or points before in r carry colours or
/// channels, which these would lack), PSR_STATUS_NON_FINITE_POSITION,
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
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
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
        // SAFETY: both arrays passed check_array above, and are readable over their spans
        // (this function's contract).
        let (p, n) = unsafe {
            (
                gather_vec3(positions, position_stride_bytes, count),
                gather_vec3(normals, normal_stride_bytes, count),
            )
        };
        handle
            .points
            .extend(&p, &n)
            .map_err(|e| batch_failure(F, e))
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// One batch's double positions and float normals.
type F64Batch = (Vec<[f64; 3]>, Vec<[f32; 3]>);

/// Reads the strided double positions and float normals of one batch, after checking them as
/// psr_reconstructor_add_points checks its arrays.
///
/// # Safety
/// `positions` and `normals` are NULL or valid for reads of their strided spans (`count`
/// vectors of 3 doubles, resp. 3 floats).
unsafe fn gather_f64_batch(
    function: &str,
    positions: *const f64,
    position_stride_bytes: usize,
    normals: *const f32,
    normal_stride_bytes: usize,
    count: usize,
) -> Result<F64Batch, Failure> {
    check_array_of(
        function,
        "positions",
        "position_stride_bytes",
        positions,
        position_stride_bytes,
        count,
    )?;
    check_array(
        function,
        "normals",
        "normal_stride_bytes",
        normals,
        normal_stride_bytes,
        count,
    )?;
    // SAFETY: both arrays passed their checks above, and are readable over their spans (this
    // function's contract).
    Ok(unsafe {
        (
            gather_vec3_of(positions, position_stride_bytes, count),
            gather_vec3(normals, normal_stride_bytes, count),
        )
    })
}

/// psr_reconstructor_add_points with positions in double precision: 3 doubles per position
/// (position_stride_bytes 0 = packed, 24 bytes, else at least 24), normals in float as there.
/// The reconstructor keeps the doubles, fits the bounding cube to them and returns a mesh whose
/// float positions are relative to a round origin near the points (psr_mesh_origin;
/// psr_mesh_copy_positions_f64 gives the vertices in double, in the input's coordinates), so
/// coordinates far from 0, such as georeferenced scans 10^6 m away, keep the precision of the
/// object's own size. Coordinates must also be within float range (|c| < 3.4e38). Costs 24
/// more bytes per point held, for every point of r, once any batch came in double.
///
/// r must not be NULL; positions and normals may be NULL only when count is 0. Returns the
/// statuses of psr_reconstructor_add_points (a stride below 24 for positions is
/// PSR_STATUS_INVALID_ARGUMENT).
///
/// # Safety
/// `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
/// strided spans described above.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_points_f64(
    r: *mut psr_reconstructor,
    positions: *const f64,
    position_stride_bytes: usize,
    normals: *const f32,
    normal_stride_bytes: usize,
    count: usize,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_points_f64";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        if count == 0 {
            return Ok(());
        }
        // SAFETY: the arrays are NULL or readable over their spans (this function's contract).
        let (p, n) = unsafe {
            gather_f64_batch(
                F,
                positions,
                position_stride_bytes,
                normals,
                normal_stride_bytes,
                count,
            )
        }?;
        handle
            .points
            .extend_f64(&p, &n)
            .map_err(|e| batch_failure(F, e))
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// psr_reconstructor_add_points_f64 with an affine transform applied to the batch first:
/// transform is 16 doubles, a 4x4 matrix in row-major order (element 4 * row + column), so
/// position p becomes M p + t with M the upper-left 3x3 block and t its last column (elements
/// 3, 7 and 11); the last row (elements 12 to 15) must be exactly 0 0 0 1. Normals are transformed
/// by M's inverse transpose and renormalised (they stay perpendicular to the surface under
/// non-uniform scales and shears, and outward under reflections). For registering scans, each
/// with its pose, and placing local coordinates in a georeferenced frame; PoissonRecon's
/// --xForm (a file of the same 16 numbers, row-major).
///
/// r must not be NULL; transform must not be NULL, even when count is 0 (it is checked then
/// too); positions and normals may be NULL only when count is 0. Returns the statuses of
/// psr_reconstructor_add_points_f64, and PSR_STATUS_INVALID_TRANSFORM for a NaN or infinite
/// entry, a last row other than 0 0 0 1, or a singular M (nothing from the batch is added).
///
/// # Safety
/// `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
/// strided spans described above; `transform` is NULL or valid for reads of 16 doubles.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_points_transformed(
    r: *mut psr_reconstructor,
    positions: *const f64,
    position_stride_bytes: usize,
    normals: *const f32,
    normal_stride_bytes: usize,
    count: usize,
    transform: *const f64,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_points_transformed";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        if transform.is_null() {
            return Err(Failure::null(F, "transform"));
        }
        // SAFETY: `transform` is not NULL, so valid for reads of 16 doubles (this function's
        // contract); read unaligned, as C does not promise more than double's alignment.
        let flat = unsafe { transform.cast::<[f64; 16]>().read_unaligned() };
        let matrix: [[f64; 4]; 4] = [0, 1, 2, 3].map(|r| [0, 1, 2, 3].map(|c| flat[4 * r + c]));
        // An empty batch still has its transform checked, so a bad one is reported at once.
        let (p, n) = if count == 0 {
            (Vec::new(), Vec::new())
        } else {
            // SAFETY: the arrays are NULL or readable over their spans (this function's
            // contract).
            unsafe {
                gather_f64_batch(
                    F,
                    positions,
                    position_stride_bytes,
                    normals,
                    normal_stride_bytes,
                    count,
                )
            }?
        };
        handle
            .points
            .extend_transformed(&p, &n, &matrix)
            .map_err(|e| batch_failure(F, e))
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Writes the number of points r holds to *out (with and without normals). r and out must not
/// be NULL. Returns
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
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way.
        let handle = unsafe { handle_ref(F, r) }?;
        let count = handle.points.len() + handle.positions_without_normals.len();
        // SAFETY: `out` is NULL or valid for writes (this function's contract).
        unsafe { write_out(F, "out", out, count) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Removes every point from r, with and without normals, and their sensors (parameters, the
/// orientation among them, and the callback stay), so the handle can be reused for another
/// cloud. r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_clear_points(r: *mut psr_reconstructor) -> psr_status {
    const F: &str = "psr_reconstructor_clear_points";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        handle.points.clear();
        handle.positions_without_normals = Vec::new();
        handle.sensors = Vec::new();
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

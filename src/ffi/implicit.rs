//! The `psr_implicit` handle: the solved indicator function χ kept after a solve
//! (psr_reconstructor_solve_implicit), evaluated at points (psr_implicit_evaluate), with its
//! gradient (psr_implicit_gradient), sampled on a grid over its bounding cube
//! (psr_implicit_sample_grid) or over any box (psr_implicit_sample_box); its isovalue and
//! bounding cube; psr_implicit_free. The Rust API's [`crate::ImplicitFunction`].
//!
//! Like a mesh function, a psr_implicit function has no reconstructor to keep a failure's
//! message on, so C sees the status alone; the messages are still built (naming the C function
//! and the argument) for the Rust tests.

use super::mesh::psr_mesh;
use super::panic_boundary::{guard, guard_no_handle, guard_value, require_out, write_out};
use super::reconstructor::psr_reconstructor;
use super::solve::solve_on;
use super::status::{psr_status, Failure};
use crate::implicit::grid_size;
use crate::ImplicitFunction;
use std::ptr;

/// The solved indicator function χ of one reconstruction, with its isovalue and bounding cube.
/// Created by psr_reconstructor_solve_implicit, destroyed by psr_implicit_free; independent of
/// the reconstructor and the mesh. Never modified: its functions may be called from several
/// threads at once. Opaque to C.
pub struct psr_implicit {
    pub(super) implicit: ImplicitFunction,
}

/// psr_reconstructor_solve, also keeping the solved indicator function χ: writes a new
/// psr_implicit to *out_implicit (free it with psr_implicit_free) and, unless out_mesh is NULL,
/// the mesh to *out_mesh (free it with psr_mesh_free; the same mesh psr_reconstructor_solve
/// gives). The psr_implicit keeps the octree and its coefficients: about the octree's memory
/// until it is freed.
///
/// r and out_implicit must not be NULL; out_mesh may be. Returns the statuses of
/// psr_reconstructor_solve. On failure neither out-parameter is written.
///
/// # Safety
/// `r` is NULL or a live handle; `out_mesh` is NULL or valid for writing one pointer, and so is
/// `out_implicit`.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_solve_implicit(
    r: *mut psr_reconstructor,
    out_mesh: *mut *mut psr_mesh,
    out_implicit: *mut *mut psr_implicit,
) -> psr_status {
    const F: &str = "psr_reconstructor_solve_implicit";
    let body = || {
        require_out(F, "out_implicit", out_implicit)?;
        // SAFETY: `r` is NULL or a live handle (this function's contract), used by no other
        // call meanwhile (guard runs the body only then and holds no reference to r).
        let (mesh, implicit) = unsafe { solve_on(F, r, true) }?;
        let implicit = implicit.ok_or_else(|| {
            Failure::new(psr_status::InternalError, format!("{F}: χ was not kept"))
        })?;
        let implicit = Box::into_raw(Box::new(psr_implicit { implicit }));
        if !out_mesh.is_null() {
            let mesh = Box::into_raw(Box::new(psr_mesh::new(mesh)));
            // SAFETY: `out_mesh` is not NULL, so valid for writing one pointer (this function's
            // contract).
            unsafe { out_mesh.write(mesh) };
        }
        // SAFETY: `out_implicit` is not NULL (checked first) and valid for writing one pointer
        // (this function's contract).
        unsafe { write_out(F, "out_implicit", out_implicit, implicit) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Destroys an implicit function. f may be NULL (nothing happens).
///
/// # Safety
/// `f` is NULL or a live psr_implicit, not used again afterwards (by any thread).
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_free(f: *mut psr_implicit) {
    guard_value("psr_implicit_free", (), || {
        if !f.is_null() {
            // SAFETY: `f` came from Box::into_raw in psr_reconstructor_solve_implicit and is not
            // used again (this function's contract).
            drop(unsafe { Box::from_raw(f) });
        }
    })
}

/// The live implicit function behind `f`, or the failure naming `function`'s NULL f.
///
/// # Safety
/// `f` is NULL or a live psr_implicit.
unsafe fn implicit_of<'a>(
    function: &str,
    f: *const psr_implicit,
) -> Result<&'a ImplicitFunction, Failure> {
    // SAFETY: `f` is NULL or a live psr_implicit (this function's contract); it never changes,
    // so a shared reference is sound even with other threads reading it.
    unsafe { f.as_ref() }
        .map(|f| &f.implicit)
        .ok_or_else(|| Failure::null(function, "f"))
}

/// The isovalue γ the mesh was extracted at (psr_mesh_isovalue of the mesh from the same
/// solve): the surface is where χ = γ. NaN if f is NULL.
///
/// # Safety
/// `f` is NULL or a live psr_implicit.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_isovalue(f: *const psr_implicit) -> f64 {
    guard_value("psr_implicit_isovalue", f64::NAN, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        unsafe { implicit_of("psr_implicit_isovalue", f) }.map_or(f64::NAN, |f| f.isovalue())
    })
}

/// Writes the bounding cube χ was solved in, in input coordinates: its minimum corner to
/// origin[0..3] and its edge length to *size (the points' bounding box enlarged by
/// psr_reconstructor_set_scale's factor). psr_implicit_sample_grid samples this cube.
///
/// f, origin and size must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
/// PSR_STATUS_INTERNAL_ERROR; nothing is written on failure.
///
/// # Safety
/// `f` is NULL or a live psr_implicit; `origin` is NULL or valid for writes of 3 doubles;
/// `size` is NULL or valid for writes of one.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_cube(
    f: *const psr_implicit,
    origin: *mut f64,
    size: *mut f64,
) -> psr_status {
    const F: &str = "psr_implicit_cube";
    guard_no_handle(F, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        let implicit = unsafe { implicit_of(F, f) }?;
        require_out(F, "origin", origin)?;
        require_out(F, "size", size)?;
        let (corner, edge) = implicit.cube();
        // SAFETY: `origin` is not NULL, so valid for writes of 3 doubles (this function's
        // contract).
        unsafe { ptr::copy_nonoverlapping(corner.as_ptr(), origin, 3) };
        // SAFETY: `size` is NULL or valid for writes of one double (this function's contract).
        unsafe { write_out(F, "size", size, edge) }
    })
}

/// The `count` points at `points` (3 floats each) as a slice, after the checks the evaluating
/// functions share: f not NULL, points and `out` not NULL unless count is 0, 3 × count (floats
/// of `per_point` × count, for the output) within memory.
///
/// # Safety
/// `points` is NULL or valid for reads of 3 × count floats.
unsafe fn points_of<'a, T>(
    function: &str,
    points: *const f32,
    count: usize,
    out: *mut T,
    per_point: usize,
) -> Result<&'a [[f32; 3]], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if points.is_null() {
        return Err(Failure::null(
            function,
            &format!("points (with count {count})"),
        ));
    }
    if out.is_null() {
        return Err(Failure::null(
            function,
            &format!("the output (with count {count})"),
        ));
    }
    let fits = |n: usize, size: usize| {
        count
            .checked_mul(n)
            .and_then(|v| v.checked_mul(size))
            .is_some_and(|bytes| bytes <= isize::MAX as usize)
    };
    if !fits(3, size_of::<f32>()) || !fits(per_point, size_of::<T>()) {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!("{function}: count {count} overflows the size of the arrays"),
        ));
    }
    // SAFETY: `points` is not NULL, so valid for reads of 3 × count floats (this function's
    // contract), whose byte size fits in isize (checked above); [f32; 3] has f32's alignment.
    Ok(unsafe { std::slice::from_raw_parts(points.cast::<[f32; 3]>(), count) })
}

/// Evaluates χ at count points: points holds 3 floats (x, y, z) per point in the input's
/// coordinates, values receives one float per point. The surface is where χ equals
/// psr_implicit_isovalue(f); χ − isovalue is negative inside and positive outside. Outside the
/// bounding cube (psr_implicit_cube) χ is continued constantly along the cube's normals (the
/// value at the nearest point of the cube). Large batches run on worker threads started for the
/// call (as many as psr_reconstructor_set_threads gave the solve); the values do not depend on
/// their number.
///
/// f must not be NULL; points and values may be NULL only when count is 0. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (3 × count floats
/// overflow), PSR_STATUS_NON_FINITE_POSITION (a NaN or infinite coordinate; nothing is written),
/// PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR. values is written only on
/// success.
///
/// # Safety
/// `f` is NULL or a live psr_implicit; `points` is NULL or valid for reads of 3 × count floats;
/// `values` is NULL or valid for writes of count floats and does not overlap `points`.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_evaluate(
    f: *const psr_implicit,
    points: *const f32,
    count: usize,
    values: *mut f32,
) -> psr_status {
    const F: &str = "psr_implicit_evaluate";
    guard_no_handle(F, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        let implicit = unsafe { implicit_of(F, f) }?;
        // SAFETY: `points` is NULL or valid for reads of 3 × count floats (this function's
        // contract).
        let points = unsafe { points_of(F, points, count, values, 1) }?;
        let result = implicit
            .values(points)
            .map_err(|e| Failure::from_error(F, e))?;
        // SAFETY: when count > 0, `values` is not NULL (points_of checked), so valid for writes
        // of count floats not overlapping `points` (this function's contract).
        unsafe { copy_to(&result, values) };
        Ok(())
    })
}

/// Evaluates ∇χ at count points (see psr_implicit_evaluate): gradients receives 3 floats per
/// point, the derivatives per input unit along x, y, z. ∇χ points outward (the mesh's vertex
/// normals are ∇χ/|∇χ|); outside the bounding cube its components along the axes on which the
/// point lies outside are 0.
///
/// f must not be NULL; points and gradients may be NULL only when count is 0. Returns the
/// statuses of psr_implicit_evaluate; gradients is written only on success.
///
/// # Safety
/// `f` is NULL or a live psr_implicit; `points` is NULL or valid for reads of 3 × count floats;
/// `gradients` is NULL or valid for writes of 3 × count floats and does not overlap `points`.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_gradient(
    f: *const psr_implicit,
    points: *const f32,
    count: usize,
    gradients: *mut f32,
) -> psr_status {
    const F: &str = "psr_implicit_gradient";
    guard_no_handle(F, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        let implicit = unsafe { implicit_of(F, f) }?;
        // SAFETY: `points` is NULL or valid for reads of 3 × count floats (this function's
        // contract).
        let points = unsafe { points_of(F, points, count, gradients, 3) }?;
        let result = implicit
            .gradients(points)
            .map_err(|e| Failure::from_error(F, e))?;
        // SAFETY: when count > 0, `gradients` is not NULL (points_of checked), so valid for
        // writes of 3 × count floats not overlapping `points` (this function's contract).
        unsafe { copy_to(result.as_flattened(), gradients) };
        Ok(())
    })
}

/// Samples χ on a resolution³ grid over the bounding cube (psr_implicit_cube), at the centres
/// of its cells, as PoissonRecon's --grid does: the value of cell (i, j, k) (x, y, z indices)
/// is χ at origin + (i + 0.5, j + 0.5, k + 0.5) × size / resolution and goes to
/// out[(i * resolution + j) * resolution + k]: z fastest, NumPy's C order for an array of
/// shape (resolution, resolution, resolution) indexed (i, j, k). Each value is what psr_implicit_evaluate gives at that point (computed in double
/// precision, rounded to float once). capacity_floats is the number of floats out can hold:
/// at least resolution³. Runs on worker threads started for the call, like
/// psr_implicit_evaluate.
///
/// f must not be NULL, nor out. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_PARAMETER (resolution 0 or above 4096, or resolution³ floats too many for
/// the address space), PSR_STATUS_BUFFER_TOO_SMALL (nothing is written),
/// PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR. out is written only on
/// success.
///
/// # Safety
/// `f` is NULL or a live psr_implicit; `out` is NULL or valid for writes of capacity_floats
/// floats.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_sample_grid(
    f: *const psr_implicit,
    resolution: usize,
    out: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    const F: &str = "psr_implicit_sample_grid";
    guard_no_handle(F, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        let implicit = unsafe { implicit_of(F, f) }?;
        let (origin, size) = implicit.cube();
        let max = origin.map(|o| o + size);
        // SAFETY: `out` is NULL or valid for writes of capacity_floats floats (this function's
        // contract).
        unsafe { sample_into(F, implicit, (origin, max), resolution, out, capacity_floats) }
    })
}

/// Samples χ on a resolution³ grid over the box from min to max (3 doubles each, input
/// coordinates; a side may have zero length, and the box may reach outside the bounding cube),
/// at the centres of its cells: the value of cell (i, j, k) (x, y, z indices) is χ at
/// min + (i + 0.5, j + 0.5, k + 0.5) × (max − min) / resolution and goes to
/// out[(i * resolution + j) * resolution + k], the order of psr_implicit_sample_grid (which is
/// this function over the bounding cube). For a region of interest finer than the cube's grid,
/// or a grid aligned with the object rather than with the cube. capacity_floats is the number
/// of floats out can hold: at least resolution³.
///
/// f, min, max and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_PARAMETER (a corner with a NaN or infinite coordinate, min above max on
/// an axis, resolution 0 or above 4096, or resolution³ floats too many for the address space),
/// PSR_STATUS_BUFFER_TOO_SMALL (nothing is written), PSR_STATUS_THREADS_UNAVAILABLE or
/// PSR_STATUS_INTERNAL_ERROR. out is written only on success.
///
/// # Safety
/// `f` is NULL or a live psr_implicit; `min` and `max` are NULL or valid for reads of 3
/// doubles; `out` is NULL or valid for writes of capacity_floats floats.
#[no_mangle]
pub unsafe extern "C" fn psr_implicit_sample_box(
    f: *const psr_implicit,
    min: *const f64,
    max: *const f64,
    resolution: usize,
    out: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    const F: &str = "psr_implicit_sample_box";
    guard_no_handle(F, || {
        // SAFETY: `f` is NULL or a live psr_implicit (this function's contract).
        let implicit = unsafe { implicit_of(F, f) }?;
        let mut corners = [[0.0f64; 3]; 2];
        for (corner, (name, p)) in corners.iter_mut().zip([("min", min), ("max", max)]) {
            if p.is_null() {
                return Err(Failure::null(F, name));
            }
            // SAFETY: `p` is not NULL, so valid for reads of 3 doubles (this function's
            // contract).
            *corner = unsafe { [*p, *p.add(1), *p.add(2)] };
        }
        // SAFETY: `out` is NULL or valid for writes of capacity_floats floats (this function's
        // contract).
        unsafe {
            sample_into(
                F,
                implicit,
                (corners[0], corners[1]),
                resolution,
                out,
                capacity_floats,
            )
        }
    })
}

/// χ on a resolution³ grid over `corners` (min, max) into `out`, for the two sampling
/// functions: the box and resolution are checked, then `out` and its capacity, before anything
/// is written.
///
/// # Safety
/// `out` is NULL or valid for writes of `capacity_floats` floats that C does not touch during
/// the call.
unsafe fn sample_into(
    function: &'static str,
    implicit: &ImplicitFunction,
    (min, max): ([f64; 3], [f64; 3]),
    resolution: usize,
    out: *mut f32,
    capacity_floats: usize,
) -> Result<(), Failure> {
    let count = grid_size(min, max, resolution).map_err(|e| Failure::from_error(function, e))?;
    require_out(function, "out", out)?;
    if capacity_floats < count {
        return Err(Failure::new(
            psr_status::BufferTooSmall,
            format!(
                "{function}: capacity_floats is {capacity_floats}, less than the {count} values \
                 of a {resolution}³ grid; nothing was written"
            ),
        ));
    }
    // SAFETY: `out` is not NULL, so valid for writes of capacity_floats >= count floats (this
    // function's contract), and C does not touch them during the call.
    let out = unsafe { std::slice::from_raw_parts_mut(out, count) };
    implicit
        .fill_box(min, max, resolution, out)
        .map_err(|e| Failure::from_error(function, e))
}

/// Copies `src` to `dst`.
///
/// # Safety
/// `src` is empty, or `dst` is valid for writes of src.len() elements and does not overlap it.
unsafe fn copy_to<T: Copy>(src: &[T], dst: *mut T) {
    if !src.is_empty() {
        // SAFETY: `dst` is valid for writes of src.len() elements, not overlapping `src` (this
        // function's contract).
        unsafe { ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send_sync<T: Send + Sync>() {}

    #[test]
    fn the_handle_may_be_shared_between_threads() {
        assert_send_sync::<psr_implicit>();
    }

    #[test]
    fn null_handles_and_arrays_are_refused_by_name() {
        let mut values = [0.0f32; 2];
        let points = [0.0f32; 6];
        let null: *const psr_implicit = ptr::null();
        // SAFETY: a NULL handle is never dereferenced; the arrays are valid.
        unsafe {
            let e = implicit_of("psr_implicit_evaluate", null).unwrap_err();
            assert_eq!(e.status, psr_status::NullArgument);
            assert_eq!(e.message, "psr_implicit_evaluate: f is NULL");
            let e = points_of("g", ptr::null(), 2, values.as_mut_ptr(), 1).unwrap_err();
            assert_eq!(e.message, "g: points (with count 2) is NULL");
            let e = points_of::<f32>("g", points.as_ptr(), 2, ptr::null_mut(), 1).unwrap_err();
            assert_eq!(e.message, "g: the output (with count 2) is NULL");
            let e = points_of("g", points.as_ptr(), usize::MAX / 4, values.as_mut_ptr(), 3)
                .unwrap_err();
            assert_eq!(e.status, psr_status::InvalidArgument);
            let empty = points_of::<f32>("g", ptr::null(), 0, ptr::null_mut(), 1);
            assert!(matches!(empty, Ok(p) if p.is_empty()));
        }
    }
}

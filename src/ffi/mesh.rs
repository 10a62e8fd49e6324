//! The `psr_mesh` handle: counts, borrowed views, copy-outs into the caller's buffers, and
//! psr_mesh_free.
//!
//! A mesh function has no reconstructor to keep a failure's message on (the header's
//! psr_reconstructor_last_error explains calls on a reconstructor only), so C sees just the
//! status. The copy-outs still build their messages, naming the real C function and the
//! argument at fault, so that they are right wherever they are reported; the tests below check
//! them.

use super::panic_boundary::{guard_no_handle, guard_value};
use super::status::{psr_status, Failure, Outcome};
use crate::Mesh;
use std::ffi::CString;
use std::ptr;

/// A reconstructed triangle mesh. Created by psr_reconstructor_solve (or psr_mesh_trim, from
/// another mesh), destroyed by psr_mesh_free; independent of the reconstructor or mesh that
/// made it. Opaque to C.
pub struct psr_mesh {
    pub(super) mesh: Mesh,
    /// The names of the mesh's channels as C strings, for psr_mesh_channel_name (made once, so
    /// the pointers it returns live as long as the mesh).
    pub(super) channel_names: Vec<CString>,
}

impl psr_mesh {
    /// The C handle of `mesh` (every psr_mesh is made here).
    pub(super) fn new(mesh: Mesh) -> psr_mesh {
        // Channel names hold no NUL (PointSet refuses control characters in them).
        let channel_names = super::channel_names(&mesh.channels);
        psr_mesh {
            mesh,
            channel_names,
        }
    }
}

/// Test hook for psr's own Rust tests, not API (neither Rust nor C): wraps a mesh built in Rust
/// as a C handle (free it with psr_mesh_free), so the mesh functions can be tested on known
/// data.
#[doc(hidden)]
pub fn debug_mesh_new(mesh: Mesh) -> *mut psr_mesh {
    Box::into_raw(Box::new(psr_mesh::new(mesh)))
}

/// Number of vertices of m; 0 if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_vertex_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_vertex_count", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        unsafe { m.as_ref() }.map_or(0, |m| m.mesh.positions.len())
    })
}

/// Number of triangles of m; 0 if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_triangle_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_triangle_count", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        unsafe { m.as_ref() }.map_or(0, |m| m.mesh.triangles.len())
    })
}

/// The vertex positions of m, 3 floats (x, y, z) per vertex, in the input's coordinates less
/// psr_mesh_origin(m), which is (0, 0, 0) unless points were added in double
/// (psr_reconstructor_add_points_f64, psr_reconstructor_add_points_transformed); owned by m:
/// valid until psr_mesh_free(m), never to be freed or written. NULL if m is NULL or has no
/// vertices.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_positions(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_positions", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        match unsafe { m.as_ref() } {
            Some(m) if !m.mesh.positions.is_empty() => m.mesh.positions.as_ptr().cast(),
            _ => ptr::null(),
        }
    })
}

/// The triangles of m, 3 zero-based vertex indices per triangle, counter-clockwise seen from
/// outside (so face normals point out of the solid), owned by m: valid until psr_mesh_free(m).
/// NULL if m is NULL or has no triangles.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_triangles(m: *const psr_mesh) -> *const u32 {
    guard_value("psr_mesh_triangles", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        match unsafe { m.as_ref() } {
            Some(m) if !m.mesh.triangles.is_empty() => m.mesh.triangles.as_ptr().cast(),
            _ => ptr::null(),
        }
    })
}

/// The sampling density estimate at each vertex (one float per vertex), owned by m: valid until
/// psr_mesh_free(m). Low values mark surface invented far from any sample; psr_mesh_trim cuts
/// the surface back along a threshold of it (like PoissonRecon's SurfaceTrimmer). NULL if m is
/// NULL or has no vertices.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_densities(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_densities", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        match unsafe { m.as_ref() } {
            Some(m) if !m.mesh.densities.is_empty() => m.mesh.densities.as_ptr(),
            _ => ptr::null(),
        }
    })
}

/// The isovalue the surface was extracted at (the indicator function's mean over the samples,
/// paper section 4.4). NaN if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_isovalue(m: *const psr_mesh) -> f64 {
    guard_value("psr_mesh_isovalue", f64::NAN, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        unsafe { m.as_ref() }.map_or(f64::NAN, |m| m.mesh.stats.isovalue)
    })
}

/// What tells the three copy-outs apart: the C function and its capacity argument, which the
/// failure messages name, and the array copied.
struct CopyOut<T: 'static> {
    function: &'static str,
    capacity: &'static str,
    array: fn(&Mesh) -> &[T],
}

/// psr_mesh_copy_positions.
const POSITIONS: CopyOut<f32> = CopyOut {
    function: "psr_mesh_copy_positions",
    capacity: "capacity_floats",
    array: |mesh| mesh.positions.as_flattened(),
};

/// psr_mesh_copy_triangles.
const TRIANGLES: CopyOut<u32> = CopyOut {
    function: "psr_mesh_copy_triangles",
    capacity: "capacity_indices",
    array: |mesh| mesh.triangles.as_flattened(),
};

/// psr_mesh_copy_densities.
const DENSITIES: CopyOut<f32> = CopyOut {
    function: "psr_mesh_copy_densities",
    capacity: "capacity_floats",
    array: |mesh| &mesh.densities,
};

/// A copy-out behind the panic boundary: its status. A mesh function has no handle to keep
/// the failure's message in, so only the status reaches C (see [`try_copy_out`]).
///
/// # Safety
/// As for [`try_copy_out`].
unsafe fn copy_out<T: Copy>(
    what: &CopyOut<T>,
    m: *const psr_mesh,
    dst: *mut T,
    capacity: usize,
) -> psr_status {
    guard_no_handle(what.function, || {
        // SAFETY: forwarded from this function's contract, which is try_copy_out's.
        unsafe { try_copy_out(what, m, dst, capacity) }
    })
}

/// Copies the array `what` names from `m` into `dst` (room for `capacity` elements), after the
/// checks shared by the copy-outs; on failure nothing is written. The failure names the C
/// function and the argument at fault, as a message on a reconstructor would.
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim); `dst` is NULL or valid for writes
/// of `capacity` elements.
unsafe fn try_copy_out<T: Copy>(
    what: &CopyOut<T>,
    m: *const psr_mesh,
    dst: *mut T,
    capacity: usize,
) -> Outcome {
    let function = what.function;
    // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so a
    // shared reference is sound even with other threads reading it.
    let m = unsafe { m.as_ref() }.ok_or_else(|| Failure::null(function, "m"))?;
    let src = (what.array)(&m.mesh);
    if src.is_empty() {
        return Ok(());
    }
    if dst.is_null() {
        let dst = format!("dst (with {} values to copy)", src.len());
        return Err(Failure::null(function, &dst));
    }
    if capacity < src.len() {
        return Err(Failure::new(
            psr_status::BufferTooSmall,
            format!(
                "{function}: {} is {capacity}, less than the {} values to copy; nothing was \
                 written",
                what.capacity,
                src.len()
            ),
        ));
    }
    // SAFETY: `dst` is not NULL, so it is valid for writes of `capacity` >= src.len() elements
    // (this function's contract). It does not overlap `src`, the mesh's own array, which C only
    // ever gets as a pointer to const and must never write.
    unsafe { ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
    Ok(())
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
    // SAFETY: `m` is NULL or a live mesh and `dst` is NULL or valid for writes of the given
    // capacity (this function's contract).
    unsafe { copy_out(&POSITIONS, m, dst, capacity_floats) }
}

/// Writes to out[0..3] the point m's positions are relative to, in the input's coordinates:
/// (0, 0, 0) unless points were added in double, else the centre of the reconstruction's
/// bounding cube rounded to a multiple of the smallest power of two at least the cube's side
/// (so a round number, and 0 for a cube near 0). A vertex is at origin + position; in float,
/// positions relative to it keep float's relative precision (6e-8) of the object's size
/// however far the object is from 0.
///
/// m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
/// PSR_STATUS_INTERNAL_ERROR; out is written only on success.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes of 3 doubles.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_origin(m: *const psr_mesh, out: *mut f64) -> psr_status {
    const F: &str = "psr_mesh_origin";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        let m = unsafe { m.as_ref() }.ok_or_else(|| Failure::null(F, "m"))?;
        if out.is_null() {
            return Err(Failure::null(F, "out"));
        }
        // SAFETY: `out` is not NULL, so valid for writes of 3 doubles (this function's
        // contract); written unaligned, as C promises no more than double's alignment.
        unsafe { out.cast::<[f64; 3]>().write_unaligned(m.mesh.origin) };
        Ok(())
    })
}

/// Copies the vertex positions of m into dst in double, in the input's coordinates
/// (psr_mesh_origin(m) + each float position, added in double): 3 * psr_mesh_vertex_count(m)
/// doubles. capacity_doubles is the number of doubles dst can hold. For points added in double,
/// the vertices as accurate as the reconstruction (not float's 6 cm steps at 10^6 m).
///
/// m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_doubles` doubles.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_positions_f64(
    m: *const psr_mesh,
    dst: *mut f64,
    capacity_doubles: usize,
) -> psr_status {
    const F: &str = "psr_mesh_copy_positions_f64";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so
        // a shared reference is sound even with other threads reading it.
        let m = unsafe { m.as_ref() }.ok_or_else(|| Failure::null(F, "m"))?;
        let values = 3 * m.mesh.positions.len();
        if values == 0 {
            return Ok(());
        }
        if dst.is_null() {
            return Err(Failure::null(
                F,
                &format!("dst (with {values} values to copy)"),
            ));
        }
        if capacity_doubles < values {
            return Err(Failure::new(
                psr_status::BufferTooSmall,
                format!(
                    "{F}: capacity_doubles is {capacity_doubles}, less than the {values} values \
                     to copy; nothing was written"
                ),
            ));
        }
        let exact = m.mesh.positions_f64();
        // SAFETY: `dst` is not NULL, so valid for writes of capacity_doubles >= values doubles
        // (this function's contract); `exact` is this call's own vector.
        unsafe { ptr::copy_nonoverlapping(exact.as_flattened().as_ptr(), dst, values) };
        Ok(())
    })
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
    // SAFETY: `m` is NULL or a live mesh and `dst` is NULL or valid for writes of the given
    // capacity (this function's contract).
    unsafe { copy_out(&TRIANGLES, m, dst, capacity_indices) }
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
    // SAFETY: `m` is NULL or a live mesh and `dst` is NULL or valid for writes of the given
    // capacity (this function's contract).
    unsafe { copy_out(&DENSITIES, m, dst, capacity_floats) }
}

/// Destroys a mesh and its arrays; pointers from psr_mesh_positions and the like become invalid.
/// m may be NULL (nothing happens).
///
/// # Safety
/// `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim), not used
/// again afterwards.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_free(m: *mut psr_mesh) {
    guard_value("psr_mesh_free", (), || {
        if !m.is_null() {
            // SAFETY: `m` came from Box::into_raw in psr_reconstructor_solve, psr_mesh_trim (or
            // debug_mesh_new) and is not used again (this function's contract).
            drop(unsafe { Box::from_raw(m) });
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mesh with 2 vertices and 1 triangle.
    fn small_mesh() -> psr_mesh {
        psr_mesh::new(Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            triangles: vec![[0, 1, 1]],
            densities: vec![1.0, 2.0],
            ..Mesh::default()
        })
    }

    /// Runs `what` on `m` with a `capacity`-element buffer, or NULL if `null_dst`, and returns
    /// its status and message.
    fn run<T: Copy + Default>(
        what: &CopyOut<T>,
        m: *const psr_mesh,
        null_dst: bool,
        capacity: usize,
    ) -> (psr_status, String) {
        let mut buffer = vec![T::default(); capacity];
        let dst = if null_dst {
            ptr::null_mut()
        } else {
            buffer.as_mut_ptr()
        };
        // SAFETY: `m` is NULL or points to a live mesh of the caller's; `dst` is NULL or
        // `buffer`, which holds `capacity` elements.
        match unsafe { try_copy_out(what, m, dst, capacity) } {
            Ok(()) => (psr_status::Ok, String::new()),
            Err(failure) => (failure.status, failure.message),
        }
    }

    /// Checks the failures of `what`, which must be the C function `function` with the
    /// capacity argument `capacity`, on a mesh where it has `needed` values to copy.
    fn check<T: Copy + Default>(what: &CopyOut<T>, function: &str, capacity: &str, needed: usize) {
        let mesh = small_mesh();
        let m: *const psr_mesh = &mesh;
        assert_eq!((what.function, what.capacity), (function, capacity));
        assert_eq!(
            run(what, ptr::null(), false, needed),
            (psr_status::NullArgument, format!("{function}: m is NULL"))
        );
        assert_eq!(
            run(what, m, true, needed),
            (
                psr_status::NullArgument,
                format!("{function}: dst (with {needed} values to copy) is NULL")
            )
        );
        assert_eq!(
            run(what, m, false, needed - 1),
            (
                psr_status::BufferTooSmall,
                format!(
                    "{function}: {capacity} is {}, less than the {needed} values to copy; \
                     nothing was written",
                    needed - 1
                )
            )
        );
        assert_eq!(run(what, m, false, needed), (psr_status::Ok, String::new()));
    }

    /// Proves: each copy-out's failures name that C function (not the psr_mesh_copy that does
    /// not exist) and the argument at fault (m, dst, or its capacity argument as the header
    /// spells it, with the sizes), with the documented status.
    #[test]
    fn copy_out_failures_name_the_function_and_the_argument() {
        check(&POSITIONS, "psr_mesh_copy_positions", "capacity_floats", 6);
        check(&TRIANGLES, "psr_mesh_copy_triangles", "capacity_indices", 3);
        check(&DENSITIES, "psr_mesh_copy_densities", "capacity_floats", 2);
    }
}

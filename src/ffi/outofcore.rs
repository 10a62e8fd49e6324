//! Reconstruction out of core: psr_reconstructor_solve_file_out_of_core, its report and the
//! noise it measured.

use super::panic_boundary::{guard, handle_mut, handle_ref, require_out, write_out};
use super::ply::path_argument;
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure};
use crate::{OutOfCore, OutOfCoreError, Stage};
use std::ffi::c_char;

/// What psr_reconstructor_solve_file_out_of_core did.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct psr_out_of_core_report {
    /// Points read from the input file.
    pub points: u64,
    /// Vertices written to the output file.
    pub vertices: u64,
    /// Triangles written to the output file.
    pub triangles: u64,
    /// Slabs the cloud was cut into.
    pub slabs: u64,
    /// The depth used (from the width when one is set).
    pub depth: u32,
    /// 1 when the points had colours or other properties, which this path does not carry.
    pub attributes_dropped: u32,
    /// Closed pieces left out for want of supporting samples (psr_reconstructor_set_min_component_samples).
    pub unsupported_components: u64,
    /// The isovalue.
    pub isovalue: f64,
    /// Seconds the run took.
    pub seconds: f64,
}

/// The samples' noise as a reconstruction out of core measured it
/// (psr_reconstructor_out_of_core_noise): what psr_mesh_sample_noise and
/// psr_mesh_screening_depth tell of an in-memory mesh, which psr_out_of_core_report (a fixed
/// struct) has no room for.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct psr_out_of_core_noise {
    /// The samples' positional noise sigma in input units (0 for exact samples of a smooth
    /// surface), or NaN when the screening did not follow it
    /// (psr_reconstructor_set_screening_follows_noise was false). The in-memory estimate of the
    /// same cloud, bit for bit, when cells_beyond_padding is 0.
    pub sample_noise: f64,
    /// The noise's depth s of the screening weight, as psr_mesh_screening_depth: the depth
    /// used when the samples read no noise or the screening did not follow it.
    pub screening_depth: f64,
    /// Cells of the estimate wider than their slab's padding, fitted from the samples within
    /// it (0 unless the median sample lies about three depths coarser than the slabs' walls).
    pub cells_beyond_padding: u64,
}

/// Reconstructs the oriented points of the PLY file input_path into the mesh output_path
/// (binary PLY: vertex x y z, float or, for double input, double; value, the sampling density;
/// face vertex_indices as int) without holding the whole cloud, its octree or its mesh in
/// memory at once (docs/out-of-core.md): the cloud is read in chunks and binned across x into
/// slabs in a temporary directory made under temp_dir (NULL: the system's) and removed however
/// the call ends; the coarse depths are solved once for the whole cloud and the finer ones slab
/// by slab; the mesh is written slab by slab, closed across the slabs' walls, each wall vertex
/// once. r's points are not used: its parameters, threads and progress callback are (the passes
/// report as the stages they correspond to: reading PSR_STAGE_POINTS, the base PSR_STAGE_SYSTEM,
/// the slabs PSR_STAGE_SOLVE, seams and isovalue PSR_STAGE_ISOVALUE, the slabs' meshes
/// PSR_STAGE_EXTRACT, the file PSR_STAGE_MESH). slabs 0 chooses the fewest slabs whose largest
/// fits r's memory limit (psr_reconstructor_set_max_memory; then one must be set), and with
/// them the depth up to which the whole cloud is solved at once (a finer one for a limit that
/// cuts the cloud thin, so that each slab's padding is thinner: docs/out-of-core.md); a limit
/// no cut fits is refused with PSR_STATUS_OUT_OF_MEMORY before the slabs are solved, the
/// message giving the smallest workable limit. use_confidence non-zero weighs the points by their
/// confidence (or value) property. The mesh is the in-memory psr_reconstructor_solve's to within
/// the solver's tolerance, not bit for bit; colours and channels are not carried and vertex
/// normals are refused (PSR_STATUS_INVALID_PARAMETER). report may be NULL.
///
/// r, input_path and output_path must not be NULL. Returns PSR_STATUS_OK,
/// PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty path, a call from r's own
/// progress callback), PSR_STATUS_IO_ERROR (the input cannot be read, the output or a temporary
/// file cannot be written: the message has the path and the system's reason),
/// PSR_STATUS_INVALID_FILE (the input is not a PLY of oriented points), the statuses of
/// psr_reconstructor_solve for the points and parameters (their indices are the file's),
/// PSR_STATUS_OUT_OF_MEMORY, PSR_STATUS_CANCELLED, PSR_STATUS_HANDLE_POISONED or
/// PSR_STATUS_INTERNAL_ERROR. On failure *report is left untouched and no file is left at
/// output_path by this call (the mesh is written there last, and removed if that fails).
///
/// # Safety
/// `r` is NULL or a live handle; the paths are NULL or NUL-terminated strings; `report` is NULL
/// or valid for writing one psr_out_of_core_report.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_solve_file_out_of_core(
    r: *mut psr_reconstructor,
    input_path: *const c_char,
    output_path: *const c_char,
    temp_dir: *const c_char,
    slabs: usize,
    use_confidence: i32,
    report: *mut psr_out_of_core_report,
) -> psr_status {
    const F: &str = "psr_reconstructor_solve_file_out_of_core";
    let body = || {
        // SAFETY: the paths are NULL or NUL-terminated strings (this function's contract).
        let input = unsafe { path_argument(F, input_path) }?;
        // SAFETY: as above.
        let output = unsafe { path_argument(F, output_path) }?;
        let temp_dir = if temp_dir.is_null() {
            None
        } else {
            // SAFETY: as above.
            Some(unsafe { path_argument(F, temp_dir) }?)
        };
        let (params, callback, user) = {
            // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the
            // body only when no other call on r is under way.
            let handle = unsafe { handle_mut(F, r) }?;
            (handle.params.clone(), handle.progress, handle.user)
        };
        // SAFETY: `r` is a live handle (handle_mut found it not NULL) and its mutable
        // reference has ended; calls the callback makes on r see `busy` and are refused.
        let handle: &psr_reconstructor = unsafe { &*r };
        handle.last_out_of_core_noise.set(None);
        handle.busy.set(true);
        let mut progress = |stage: Stage, fraction: f32| match callback {
            // SAFETY: whoever set the callback promised it is safe to call with `user` until it
            // is replaced or r is freed, and neither can happen meanwhile (calls on r from the
            // callback are refused).
            Some(f) => unsafe { f(user.0, stage.into(), fraction) },
            None => true,
        };
        let options = OutOfCore::default()
            .with_slabs((slabs > 0).then_some(slabs))
            .with_temp_dir(temp_dir)
            .with_confidence(use_confidence != 0);
        let result = crate::reconstruct_out_of_core_with_progress(
            &input,
            &output,
            &params,
            &options,
            &mut progress,
        );
        handle.busy.set(false);
        let done = result.map_err(|e| match e {
            OutOfCoreError::Reconstruction(e) => Failure::from_error(F, e),
            OutOfCoreError::Input(e) => {
                let status = match e.kind() {
                    crate::ply::PlyErrorKind::Io { .. } => psr_status::IoError,
                    _ => psr_status::InvalidFile,
                };
                Failure::new(status, format!("{F}: {e}"))
            }
            e @ (OutOfCoreError::Scratch { .. } | OutOfCoreError::Output { .. }) => {
                Failure::new(psr_status::IoError, format!("{F}: {e}"))
            }
            // (A run from C is a team of one: no other member to fail.)
            e @ OutOfCoreError::Member { .. } => {
                Failure::new(psr_status::InternalError, format!("{F}: {e}"))
            }
        })?;
        handle
            .last_out_of_core_noise
            .set(Some(psr_out_of_core_noise {
                sample_noise: done.sample_noise.unwrap_or(f64::NAN),
                screening_depth: done.screening_depth,
                cells_beyond_padding: done.noise_cells_beyond_padding,
            }));
        if !report.is_null() {
            let out = psr_out_of_core_report {
                points: done.points,
                vertices: done.vertices,
                triangles: done.triangles,
                slabs: done.slabs as u64,
                depth: done.depth,
                attributes_dropped: done.attributes_dropped as u32,
                unsupported_components: done.unsupported_components as u64,
                isovalue: done.isovalue,
                seconds: done.seconds,
            };
            // SAFETY: `report` is not NULL and valid for one report (this function's contract).
            unsafe { report.write(out) };
        }
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Writes to *out the samples' noise as the last psr_reconstructor_solve_file_out_of_core on r
/// measured it (see psr_out_of_core_noise).
///
/// r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_ARGUMENT (no reconstruction out of core on r yet, or the last one failed;
/// or called from r's progress callback), PSR_STATUS_HANDLE_POISONED or
/// PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_out_of_core_noise(
    r: *const psr_reconstructor,
    out: *mut psr_out_of_core_noise,
) -> psr_status {
    const F: &str = "psr_reconstructor_out_of_core_noise";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way.
        let handle = unsafe { handle_ref(F, r) }?;
        require_out(F, "out", out)?;
        let noise = handle.last_out_of_core_noise.get().ok_or_else(|| {
            Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{F}: no reconstruction out of core on this handle to read (none was made, \
                     or the last psr_reconstructor_solve_file_out_of_core failed)"
                ),
            )
        })?;
        // SAFETY: `out` is not NULL and valid for writes (this function's contract).
        unsafe { write_out(F, "out", out, noise) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

//! The memory budget: psr_reconstructor_set_max_memory / _get_max_memory, the estimates
//! psr_reconstructor_estimate_memory and psr_estimate_memory (Rust's `Params::max_memory`,
//! `estimate_memory` and `estimate_memory_for`).

use super::panic_boundary::{guard, guard_no_handle, handle_ref, require_out, write_out};
use super::params::{get_param, set_param};
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure};
use crate::memory::Footprint;
use crate::Params;

/// Sets the most memory a solve on r may use, in bytes; 0 (the default) means no limit. psr
/// counts the big arrays of a reconstruction (the points, the octree, the system, the solver,
/// the extraction and the mesh; see psr_reconstructor_estimate_memory) and checks the count
/// against the limit before allocating them: first from the point count, before anything is
/// copied (a limit far too small fails within milliseconds), then from the octree's node
/// counts, before the system is built. A solve that would need more returns
/// PSR_STATUS_OUT_OF_MEMORY, naming what needed how much, the limit and the smallest limit that
/// would do, and keeps nothing; the handle stays usable. Any value is accepted (0 or 1 to
/// 2^64 - 1). The limit covers psr's own big arrays, not the memory the host holds, the
/// thread stacks or the allocator's overhead. Without a limit, the system's refusal of one of
/// the big allocations is PSR_STATUS_OUT_OF_MEMORY too. No PoissonRecon, PCL or Open3D
/// equivalent.
///
/// r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_max_memory(
    r: *mut psr_reconstructor,
    bytes: u64,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_max_memory", r, |p| {
            p.max_memory = (bytes != 0).then_some(bytes)
        })
    }
}

/// Writes the memory limit in bytes (0: no limit, the default) to *out. r and out must not be
/// NULL. Returns the statuses of psr_reconstructor_get_depth; *out is written only on success.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_max_memory(
    r: *const psr_reconstructor,
    out: *mut u64,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_max_memory", r, out, |p| {
            p.max_memory.unwrap_or(0)
        })
    }
}

/// Writes to *out the memory, in bytes, a solve of r's points with r's parameters is estimated
/// to need at its peak, before solving: computed from the point count and the depth (the depth
/// psr_reconstructor_set_width picks is found from the points' bounding box) in well under a
/// second. It counts the points r holds, the octree, the system, the solver, the extraction
/// and the mesh; not the host's own memory, the mesh after the solve returns, nor, for points
/// without normals, the normal estimation. Meant as an upper bound for scanned surfaces:
/// measured on the bunny and the Happy Buddha scans at depths 9 to 12 it is 1.8 to 2.5 times
/// the peak resident memory of the whole process (docs/benchmarks.md, issue 19). A limit set to
/// it with psr_reconstructor_set_max_memory lets that solve through, since the solve checks
/// the finer count from its octree. With no points the estimate is that of the smallest
/// reconstruction (the complete octree down to the full depth).
///
/// r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_PARAMETER (two parameters disagree, as psr_reconstructor_solve would
/// report), PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress
/// callback) or PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_estimate_memory(
    r: *const psr_reconstructor,
    out: *mut u64,
) -> psr_status {
    const F: &str = "psr_reconstructor_estimate_memory";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way.
        let handle = unsafe { handle_ref(F, r) }?;
        require_out(F, "out", out)?;
        let params = &handle.params;
        params.validate().map_err(|e| Failure::from_error(F, e))?;
        let depth = match params.width {
            None => params.depth,
            Some(_) => {
                // The bounding box of every point r holds, with or without normals.
                let all = handle
                    .points
                    .positions()
                    .iter()
                    .chain(&handle.positions_without_normals);
                let mut low = [f64::INFINITY; 3];
                let mut high = [f64::NEG_INFINITY; 3];
                for p in all {
                    for k in 0..3 {
                        low[k] = low[k].min(p[k] as f64);
                        high[k] = high[k].max(p[k] as f64);
                    }
                }
                let side = (0..3).map(|k| high[k] - low[k]).fold(0.0, f64::max);
                params.depth_for_cube(side * params.scale as f64)
            }
        };
        let count = handle.points.len() + handle.positions_without_normals.len();
        let estimate = Footprint::predicted(
            count as u64,
            handle.points.attributes().width() as u64,
            depth,
            params.full_depth.min(depth),
            params
                .kernel_depth
                .unwrap_or(depth.saturating_sub(2))
                .min(depth),
        )
        .peak();
        // SAFETY: `out` is NULL or valid for writes (this function's contract).
        unsafe { write_out(F, "out", out, estimate) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Writes to *out the memory, in bytes, a reconstruction of point_count points (position and
/// normal) at depth is estimated to need at its peak, every other parameter at its default:
/// the estimate of psr_reconstructor_estimate_memory, for a host that has no reconstructor
/// yet (e.g. to choose the depth for the memory it has). depth must be 1 to 16.
///
/// out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_PARAMETER (depth out of range; *out untouched) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_estimate_memory(
    depth: u32,
    point_count: u64,
    out: *mut u64,
) -> psr_status {
    const F: &str = "psr_estimate_memory";
    guard_no_handle(F, || {
        require_out(F, "out", out)?;
        let count = usize::try_from(point_count).unwrap_or(usize::MAX);
        let estimate = crate::estimate_memory_for(count, &Params::default().with_depth(depth))
            .map_err(|e| Failure::from_error(F, e))?;
        // SAFETY: `out` is NULL or valid for writes (this function's contract).
        unsafe { write_out(F, "out", out, estimate) }
    })
}

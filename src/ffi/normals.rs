//! Points without normals: psr_reconstructor_add_positions, whose normals psr_reconstructor_solve
//! estimates and orients (crate::estimate_normals), and the estimation's settings.

use super::panic_boundary::{guard, handle_mut, handle_ref, require_out, write_out};
use super::points::{batch_failure, check_array, gather_vec3};
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure};
use crate::{Error, NormalEstimation, Orientation};

/// How the normals psr estimates get their signs (psr_reconstructor_set_normal_orientation).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_orientation {
    /// Consistent over each connected part of the cloud by propagation along a minimum spanning
    /// tree (Hoppe et al. 1992), outward where a part encloses volume. The default. Open3D
    /// orient_normals_consistent_tangent_plane.
    Propagate = 0,
    /// Facing the point set with psr_reconstructor_set_viewpoint (a single scan's scanner).
    /// Open3D orient_normals_towards_camera_location, PCL setViewPoint.
    Viewpoint = 1,
}

/// Appends `count` points without normals to r: position i is the 3 floats at
/// `(const char *)positions + i * position_stride_bytes` (0 = packed). psr_reconstructor_solve
/// estimates their normals from these positions (a plane through each point and its nearest
/// neighbours, see psr_reconstructor_set_normal_neighbors), orients them (see
/// psr_reconstructor_set_normal_orientation) and reconstructs them together with the points added
/// with normals. Use it for a scanner's or photogrammetry's x y z export; add all of one cloud's
/// unoriented points before solving, since the neighbourhoods are found among them.
///
/// The positions are copied; the batch is checked whole first (a NaN or infinite coordinate
/// appends nothing and the message names its index in this batch). psr_reconstructor_point_count
/// counts these points too and psr_reconstructor_clear_points removes them. The estimation is
/// reported to the progress callback as PSR_STAGE_NORMALS (before PSR_STAGE_POINTS) and may be
/// cancelled there like any stage; it takes about 2 s per million points per core.
///
/// r must not be NULL; positions may be NULL only when count is 0. Returns PSR_STATUS_OK,
/// PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a stride below 12, or count * stride
/// overflowing), PSR_STATUS_NON_FINITE_POSITION, PSR_STATUS_HANDLE_POISONED or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `positions` is NULL or valid for reads of the strided span
/// described above.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_positions(
    r: *mut psr_reconstructor,
    positions: *const f32,
    position_stride_bytes: usize,
    count: usize,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_positions";
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
        // SAFETY: the array passed check_array above and is readable over its span (this
        // function's contract).
        let batch = unsafe { gather_vec3(positions, position_stride_bytes, count) };
        if let Some(index) = batch.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(batch_failure(F, Error::NonFinitePosition { index }));
        }
        handle.positions_without_normals.extend(batch);
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Changes r's normal estimation by `apply` after checking the result.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
unsafe fn set_estimation(
    function: &'static str,
    r: *mut psr_reconstructor,
    apply: impl FnOnce(&mut NormalEstimation),
) -> psr_status {
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(function, r) }?;
        let mut changed = handle.normal_estimation.clone();
        apply(&mut changed);
        changed
            .validate()
            .map_err(|e| Failure::from_error(function, e))?;
        handle.normal_estimation = changed;
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(function, r, body) }
}

/// Reads one setting of r's normal estimation into *out.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes of `T`.
unsafe fn get_estimation<T>(
    function: &'static str,
    r: *const psr_reconstructor,
    out: *mut T,
    read: impl FnOnce(&NormalEstimation) -> T,
) -> psr_status {
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way.
        let handle = unsafe { handle_ref(function, r) }?;
        require_out(function, "out", out)?;
        let value = read(&handle.normal_estimation);
        // SAFETY: `out` is NULL or valid for writes of `T` (this function's contract).
        unsafe { write_out(function, "out", out, value) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(function, r, body) }
}

/// Sets how many nearest neighbours (besides the point itself) fit each estimated normal's plane
/// and link the points for orientation. Default 20, range 1 to 1000 (10 to 30 is usual; at
/// least 3 for a plane): more smooths noise and bridges uneven sampling, fewer keeps sharp edges
/// and thin parts apart. Open3D KDTreeSearchParamKNN (which counts the point itself), PCL
/// setKSearch.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_normal_neighbors(
    r: *mut psr_reconstructor,
    neighbors: u32,
) -> psr_status {
    let neighbors = usize::try_from(neighbors).unwrap_or(usize::MAX);
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_estimation("psr_reconstructor_set_normal_neighbors", r, |e| {
            e.neighbors = neighbors
        })
    }
}

/// Writes the neighbour count of normal estimation to *out. r and out must not be NULL. Returns
/// the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_normal_neighbors(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_estimation("psr_reconstructor_get_normal_neighbors", r, out, |e| {
            u32::try_from(e.neighbors).unwrap_or(u32::MAX)
        })
    }
}

/// Sets how estimated normals get their signs: PSR_ORIENTATION_PROPAGATE (0, the default) or
/// PSR_ORIENTATION_VIEWPOINT (1, facing the point given to psr_reconstructor_set_viewpoint,
/// which must be called first).
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for any other value, or for VIEWPOINT before a viewpoint).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_normal_orientation(
    r: *mut psr_reconstructor,
    orientation: i32,
) -> psr_status {
    const F: &str = "psr_reconstructor_set_normal_orientation";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        let refused = |expected: &'static str| {
            Failure::from_error(
                F,
                Error::InvalidParameter {
                    name: "orientation",
                    value: orientation.to_string(),
                    expected,
                },
            )
        };
        handle.normal_estimation.orientation = match orientation {
            0 => Orientation::Propagate,
            1 => Orientation::Viewpoint(handle.viewpoint.ok_or_else(|| {
                refused("PSR_ORIENTATION_VIEWPOINT after psr_reconstructor_set_viewpoint")
            })?),
            _ => {
                return Err(refused(
                    "PSR_ORIENTATION_PROPAGATE (0) or PSR_ORIENTATION_VIEWPOINT (1)",
                ))
            }
        };
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Writes the orientation of estimated normals (a psr_orientation value) to *out. r and out must
/// not be NULL. Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_normal_orientation(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_estimation(
            "psr_reconstructor_get_normal_orientation",
            r,
            out,
            |e| match e.orientation {
                Orientation::Viewpoint(_) => psr_orientation::Viewpoint as i32,
                _ => psr_orientation::Propagate as i32,
            },
        )
    }
}

/// Sets the viewpoint (x, y, z, in the points' coordinates, e.g. the scanner's position) that
/// estimated normals face, and selects PSR_ORIENTATION_VIEWPOINT. The coordinates must be
/// finite. Open3D orient_normals_towards_camera_location, PCL setViewPoint.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for a NaN or infinite coordinate).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_viewpoint(
    r: *mut psr_reconstructor,
    x: f64,
    y: f64,
    z: f64,
) -> psr_status {
    const F: &str = "psr_reconstructor_set_viewpoint";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        let point = [x, y, z];
        if !point.iter().all(|c| c.is_finite()) {
            return Err(Failure::from_error(
                F,
                Error::InvalidParameter {
                    name: "viewpoint",
                    value: format!("({x}, {y}, {z})"),
                    expected: "three finite coordinates",
                },
            ));
        }
        handle.viewpoint = Some(point);
        handle.normal_estimation.orientation = Orientation::Viewpoint(point);
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

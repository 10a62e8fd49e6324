//! Points without normals: psr_reconstructor_add_positions, and with the position of the sensor
//! that saw them psr_reconstructor_add_positions_seen_from (one per batch) and
//! psr_reconstructor_add_positions_with_sensors (one per point); psr_reconstructor_solve
//! estimates and orients their normals (crate::estimate_normals) with the settings here.

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
    /// Each normal facing its own point's sensor, the scanner position given with the point by
    /// psr_reconstructor_add_positions_seen_from (one per batch, e.g. per scan of a registered
    /// multi-scan cloud) or psr_reconstructor_add_positions_with_sensors (one per point, e.g.
    /// a mobile scanner's trajectory); those functions select it. Every point added without
    /// normals must then have a sensor (psr_reconstructor_solve checks). PCL
    /// flipNormalTowardsViewpoint with each point's vp_x vp_y vp_z; Open3D has none.
    Sensors = 2,
    /// Read off the reconstruction itself, repeated (iterative Poisson reconstruction, Hou et
    /// al. 2022): in rounds, coarse to fine, the points are reconstructed with their current
    /// normals and each takes the normal of the mesh's triangles nearest it, from two starts
    /// (propagation's normals and an arbitrary one), keeping the one whose mesh fits the points
    /// better. Holds where propagation fails (folds and lips a few sample spacings thick, sparse
    /// clouds) and gives the normal's line too, at the cost of a few reconstructions per depth
    /// up to the depth of the points' spacing (at most 10): a second for thousands of points,
    /// minutes for a million. psr_reconstructor_set_normal_reconstruction_iterations bounds the
    /// rounds per depth. Open3D, PCL, PoissonRecon: none.
    Reconstruction = 3,
}

/// Marks, in the handle's `sensors`, a point added without a sensor; real sensors are finite.
pub(super) const NO_SENSOR: [f32; 3] = [f32::NAN; 3];

/// The sensors of one batch of points without normals.
enum BatchSensors {
    /// psr_reconstructor_add_positions: none.
    None,
    /// psr_reconstructor_add_positions_seen_from: one for the whole batch.
    One([f32; 3]),
    /// psr_reconstructor_add_positions_with_sensors: one per point.
    PerPoint(Vec<[f32; 3]>),
}

/// Copies and checks one batch of positions without normals (see
/// psr_reconstructor_add_positions); `count` is not 0.
///
/// # Safety
/// `positions` is NULL or valid for reads of `count` strided 3-float vectors.
unsafe fn checked_positions(
    function: &str,
    positions: *const f32,
    position_stride_bytes: usize,
    count: usize,
) -> Result<Vec<[f32; 3]>, Failure> {
    check_array(
        function,
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
        return Err(batch_failure(function, Error::NonFinitePosition { index }));
    }
    Ok(batch)
}

/// A sensor with a NaN or infinite coordinate: `which` names it ("sensor 3", "sensor").
fn non_finite_sensor(function: &str, which: &str, sensor: [f32; 3]) -> Failure {
    Failure::new(
        psr_status::NonFinitePosition,
        format!(
            "{function}: {which} = ({}, {}, {}) has a NaN or infinite coordinate: remove or fix it \
             (nothing from this batch was added)",
            sensor[0], sensor[1], sensor[2]
        ),
    )
}

/// Appends a checked batch of points without normals, and their sensors, to r. A batch with
/// sensors selects PSR_ORIENTATION_SENSORS.
fn append_unoriented(handle: &mut psr_reconstructor, batch: Vec<[f32; 3]>, sensors: BatchSensors) {
    let before = handle.positions_without_normals.len();
    handle.positions_without_normals.extend(batch);
    let after = handle.positions_without_normals.len();
    match sensors {
        BatchSensors::None => {
            if !handle.sensors.is_empty() {
                handle.sensors.resize(after, NO_SENSOR);
            }
            return;
        }
        BatchSensors::One(sensor) => {
            handle.sensors.resize(before, NO_SENSOR);
            handle.sensors.resize(after, sensor);
        }
        BatchSensors::PerPoint(sensors) => {
            handle.sensors.resize(before, NO_SENSOR);
            handle.sensors.extend(sensors);
        }
    }
    handle.normal_estimation.orientation = Orientation::Sensors(Vec::new());
}

/// Appends `count` points without normals to r: position i is the 3 floats at
/// `(const char *)positions + i * position_stride_bytes` (0 = packed). psr_reconstructor_solve
/// estimates their normals from these positions (a plane through each point and its nearest
/// neighbours, see psr_reconstructor_set_normal_neighbors), orients them (see
/// psr_reconstructor_set_normal_orientation) and reconstructs them together with the points added
/// with normals. Use it for a scanner's or photogrammetry's x y z export; add all of one cloud's
/// unoriented points before solving, since the neighbourhoods are found among them. When the
/// scanner's position is known, add the points with psr_reconstructor_add_positions_seen_from
/// or psr_reconstructor_add_positions_with_sensors instead.
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
        // SAFETY: `positions` is NULL or readable over its strided span (this function's
        // contract).
        let batch = unsafe { checked_positions(F, positions, position_stride_bytes, count) }?;
        append_unoriented(handle, batch, BatchSensors::None);
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Appends `count` points without normals that one sensor saw, e.g. one scan of a registered
/// multi-scan cloud: like psr_reconstructor_add_positions, and `sensor` points to the 3 floats
/// x, y, z of the scanner's origin in the points' coordinates. psr_reconstructor_solve turns
/// each estimated normal to face its point's sensor (n · (sensor − p) ≥ 0), which is right
/// wherever the sensor could see the point, thin walls and parts that touch included, where
/// propagation can fail. Call it once per scan.
///
/// Selects PSR_ORIENTATION_SENSORS, which needs a sensor for every point added without normals:
/// psr_reconstructor_solve refuses a mix with points from psr_reconstructor_add_positions
/// (PSR_STATUS_INVALID_ARGUMENT, naming the first point without a sensor). Choosing another
/// orientation afterwards (psr_reconstructor_set_normal_orientation,
/// psr_reconstructor_set_viewpoint) keeps the sensors but does not use them.
///
/// The positions and the sensor are copied; the batch is checked whole first (nothing is
/// appended and the orientation is unchanged if a position or the sensor has a NaN or infinite
/// coordinate; the message says which). psr_reconstructor_clear_points removes the points and
/// their sensors.
///
/// r must not be NULL; positions and sensor may be NULL only when count is 0 (then nothing
/// happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
/// stride below 12, or count * stride overflowing), PSR_STATUS_NON_FINITE_POSITION (a point's
/// or the sensor's coordinate), PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `positions` is NULL or valid for reads of the strided span
/// described above; `sensor` is NULL or valid for reads of 3 floats.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_positions_seen_from(
    r: *mut psr_reconstructor,
    positions: *const f32,
    position_stride_bytes: usize,
    count: usize,
    sensor: *const f32,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_positions_seen_from";
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
        if sensor.is_null() {
            return Err(Failure::null(F, &format!("sensor (with count {count})")));
        }
        // SAFETY: `positions` is NULL or readable over its strided span (this function's
        // contract).
        let batch = unsafe { checked_positions(F, positions, position_stride_bytes, count) }?;
        // SAFETY: `sensor` is not NULL (checked above) and readable for 3 floats (this
        // function's contract); the read is unaligned, so any float array will do.
        let sensor = unsafe { sensor.cast::<[f32; 3]>().read_unaligned() };
        if !sensor.iter().all(|c| c.is_finite()) {
            return Err(non_finite_sensor(F, "sensor", sensor));
        }
        append_unoriented(handle, batch, BatchSensors::One(sensor));
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Appends `count` points without normals, each with the position of the sensor that saw it,
/// e.g. a mobile scanner's trajectory sampled at each shot: like
/// psr_reconstructor_add_positions_seen_from, but sensor i is the 3 floats at
/// `(const char *)sensors + i * sensor_stride_bytes` (0 = packed; interleaved x y z sx sy sz
/// records work with both strides 24). When a batch of points shares one sensor,
/// psr_reconstructor_add_positions_seen_from says so without repeating it.
///
/// Selects PSR_ORIENTATION_SENSORS, with the same rule for points without sensors as
/// psr_reconstructor_add_positions_seen_from. The arrays are copied and checked whole first
/// (a NaN or infinite coordinate in either appends nothing, and the message names its index in
/// this batch).
///
/// r must not be NULL; positions and sensors may be NULL only when count is 0 (then nothing
/// happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
/// stride below 12, or count * stride overflowing), PSR_STATUS_NON_FINITE_POSITION (a point's
/// or a sensor's coordinate), PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `positions` and `sensors` are NULL or valid for reads of the
/// strided spans described above.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_positions_with_sensors(
    r: *mut psr_reconstructor,
    positions: *const f32,
    position_stride_bytes: usize,
    sensors: *const f32,
    sensor_stride_bytes: usize,
    count: usize,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_positions_with_sensors";
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
            "sensors",
            "sensor_stride_bytes",
            sensors,
            sensor_stride_bytes,
            count,
        )?;
        // SAFETY: `positions` is NULL or readable over its strided span (this function's
        // contract).
        let batch = unsafe { checked_positions(F, positions, position_stride_bytes, count) }?;
        // SAFETY: the array passed check_array above and is readable over its span (this
        // function's contract).
        let per_point = unsafe { gather_vec3(sensors, sensor_stride_bytes, count) };
        if let Some(index) = per_point
            .iter()
            .position(|s| !s.iter().all(|c| c.is_finite()))
        {
            return Err(non_finite_sensor(
                F,
                &format!("sensor {index} (index within this batch)"),
                per_point[index],
            ));
        }
        append_unoriented(handle, batch, BatchSensors::PerPoint(per_point));
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// The options psr_reconstructor_solve estimates r's normals with: r's settings, `threads`
/// worker threads, and for PSR_ORIENTATION_SENSORS the points' sensors, refused unless every
/// point without normals has one.
pub(super) fn estimation_for_solve(
    function: &str,
    handle: &psr_reconstructor,
    threads: usize,
) -> Result<NormalEstimation, Failure> {
    let mut options = handle.normal_estimation.clone().with_threads(threads);
    if let Orientation::Sensors(sensors) = &mut options.orientation {
        let unoriented = handle.positions_without_normals.len();
        if handle.sensors.is_empty() {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{function}: the orientation is PSR_ORIENTATION_SENSORS but none of the \
                     {unoriented} points without normals has a sensor: add them with \
                     psr_reconstructor_add_positions_seen_from or \
                     psr_reconstructor_add_positions_with_sensors, or choose another orientation"
                ),
            ));
        }
        let missing = handle.sensors.iter().filter(|s| s[0].is_nan()).count();
        if let Some(first) = handle.sensors.iter().position(|s| s[0].is_nan()) {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{function}: the orientation is PSR_ORIENTATION_SENSORS but {missing} of the \
                     {unoriented} points without normals have no sensor (the first is point \
                     {first} of them in the order added, from psr_reconstructor_add_positions): \
                     add every one with a sensor, or choose another orientation"
                ),
            ));
        }
        sensors.clone_from(&handle.sensors);
    }
    Ok(options)
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

/// Sets how estimated normals get their signs: PSR_ORIENTATION_PROPAGATE (0, the default),
/// PSR_ORIENTATION_VIEWPOINT (1, facing the point given to psr_reconstructor_set_viewpoint,
/// which must be called first), PSR_ORIENTATION_SENSORS (2, each facing its point's sensor;
/// adding points with a sensor selects it, and psr_reconstructor_solve refuses it unless every
/// point added without normals has a sensor) or PSR_ORIENTATION_RECONSTRUCTION (3, read off
/// the reconstruction itself, repeated; see psr_orientation).
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
            2 => Orientation::Sensors(Vec::new()),
            3 => Orientation::Reconstruction,
            _ => {
                return Err(refused(
                    "PSR_ORIENTATION_PROPAGATE (0), PSR_ORIENTATION_VIEWPOINT (1), \
                     PSR_ORIENTATION_SENSORS (2) or PSR_ORIENTATION_RECONSTRUCTION (3)",
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
                Orientation::Propagate => psr_orientation::Propagate as i32,
                Orientation::Viewpoint(_) => psr_orientation::Viewpoint as i32,
                Orientation::Sensors(_) => psr_orientation::Sensors as i32,
                Orientation::Reconstruction => psr_orientation::Reconstruction as i32,
            },
        )
    }
}

/// Sets the most rounds PSR_ORIENTATION_RECONSTRUCTION runs at each depth (a depth ends sooner
/// once fewer than 0.01 % of the signs change in a round). Default 10, range 1 to 1000; each
/// round costs about a reconstruction at that depth. Ignored by the other orientations.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_normal_reconstruction_iterations(
    r: *mut psr_reconstructor,
    iterations: u32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_estimation(
            "psr_reconstructor_set_normal_reconstruction_iterations",
            r,
            |e| e.reconstruction_iterations = iterations,
        )
    }
}

/// Writes the most rounds per depth of PSR_ORIENTATION_RECONSTRUCTION to *out. r and out must
/// not be NULL. Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_normal_reconstruction_iterations(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_estimation(
            "psr_reconstructor_get_normal_reconstruction_iterations",
            r,
            out,
            |e| e.reconstruction_iterations,
        )
    }
}

/// Sets the viewpoint (x, y, z, in the points' coordinates, e.g. the scanner's position) that
/// estimated normals face, and selects PSR_ORIENTATION_VIEWPOINT (points' sensors, if any, are
/// kept but not used). The coordinates must be finite. For several scans, give each its own
/// sensor with psr_reconstructor_add_positions_seen_from instead. Open3D
/// orient_normals_towards_camera_location, PCL setViewPoint.
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

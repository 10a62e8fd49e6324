//! Parameters: the psr_reconstructor_set_* / _get_* pairs, each checking its value alone, and
//! the named choices `psr_boundary`, `psr_splatting` and `psr_vertex_placement`.

use super::panic_boundary::{guard, handle_mut, handle_ref, require_out, write_out};
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure};
use crate::{Error, Params};

/// Applies one parameter after checking it alone against its documented range, so that
/// setters can be called in any order. Cross-parameter rules (kernel_depth <= depth) are checked
/// by psr_reconstructor_solve.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
pub(super) unsafe fn set_param(
    function: &'static str,
    r: *mut psr_reconstructor,
    apply: impl Fn(&mut Params),
) -> psr_status {
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(function, r) }?;
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
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(function, r, body) }
}

/// Reads one parameter into an out-parameter.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new; `out` is NULL or valid for writes
/// of `T`.
pub(super) unsafe fn get_param<T>(
    function: &'static str,
    r: *const psr_reconstructor,
    out: *mut T,
    read: impl FnOnce(&Params) -> T,
) -> psr_status {
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way.
        let handle = unsafe { handle_ref(function, r) }?;
        require_out(function, "out", out)?;
        let value = read(&handle.params);
        // SAFETY: `out` is NULL or valid for writes of `T` (this function's contract).
        unsafe { write_out(function, "out", out, value) }
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(function, r, body) }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe { set_param("psr_reconstructor_set_depth", r, |p| p.depth = depth) }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe { get_param("psr_reconstructor_get_depth", r, out, |p| p.depth) }
}

/// Sets the target width of the finest cells, in input units, which then chooses the depth
/// instead of psr_reconstructor_set_depth: the smallest depth from 1 to 16 whose cells (the
/// bounding cube's side, the points' bounding box's longest side times the scale, over 2^depth)
/// are at most width wide; 16 when even those are wider. psr_mesh_depth reports the depth
/// used. 0 turns it off (the default: the depth decides); otherwise finite and > 0.
/// PoissonRecon --width (which, when > 0, likewise overrides --depth), Open3D's width argument
/// of create_from_point_cloud_poisson (ignored there when depth is given); PCL has none.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth (negative, NaN or
/// infinite: PSR_STATUS_INVALID_PARAMETER).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_width(
    r: *mut psr_reconstructor,
    width: f64,
) -> psr_status {
    let width = (width != 0.0).then_some(width);
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe { set_param("psr_reconstructor_set_width", r, |p| p.width = width) }
}

/// Writes the target width of the finest cells to *out, 0 when it is off (the depth decides).
/// r and out must not be NULL. Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_width(
    r: *const psr_reconstructor,
    out: *mut f64,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_width", r, out, |p| {
            p.width.unwrap_or(0.0)
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_full_depth", r, |p| {
            p.full_depth = full_depth
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe { get_param("psr_reconstructor_get_full_depth", r, out, |p| p.full_depth) }
}

/// Sets the depth at which the sampling density is estimated. A negative value (the default,
/// -1) means automatic: depth - 2, at least 0. Range: negative, or 0 to 16; it must not exceed
/// depth, which psr_reconstructor_solve checks (PSR_STATUS_INVALID_PARAMETER), so setters may
/// come in any order; with a width set (psr_reconstructor_set_width) a larger value acts as
/// the depth the width chooses. PoissonRecon --kernelDepth.
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_kernel_depth", r, |p| {
            p.kernel_depth = value
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_kernel_depth", r, out, |p| {
            p.kernel_depth
                .map_or(-1, |k| i32::try_from(k).unwrap_or(i32::MAX))
        })
    }
}

/// Sets the target number of samples per octree node: sparser samples are splatted at coarser
/// depths, which smooths noisy input. Default 1.5, range 1 to 1e6.
/// PoissonRecon --samplesPerNode, PCL setSamplesPerNode (psr's count reads about 0.6 of
/// PoissonRecon's, so the same value is about a third of a depth coarser, except where the
/// surface bends under the density's kernel: there psr reads it as PoissonRecon does).
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_samples_per_node", r, |p| {
            p.samples_per_node = samples_per_node
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_samples_per_node", r, out, |p| {
            p.samples_per_node
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe { set_param("psr_reconstructor_set_scale", r, |p| p.scale = scale) }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe { get_param("psr_reconstructor_get_scale", r, out, |p| p.scale) }
}

/// Sets the screening weight alpha (Kazhdan & Hoppe 2013): how strongly the surface is pulled
/// onto the samples; 0 gives the unscreened 2006 method. Default 4 (2 x the default degree 2;
/// psr_reconstructor_set_degree sets it to 2 x the degree), range 0 to 1e6. The pull is
/// scaled by 2^depth, and at the depths finer than the samples' noise supports by that
/// depth's 2^s (psr_reconstructor_set_screening_follows_noise, on by default). PoissonRecon
/// --pointWeight, PCL setPointWeight.
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_point_weight", r, |p| {
            p.point_weight = point_weight
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_point_weight", r, out, |p| {
            p.point_weight
        })
    }
}

/// Sets whether the screening follows the samples' noise: the reconstruction estimates how far
/// the samples scatter across the surface (sigma, psr_mesh_sample_noise) and pulls the depths
/// finer than the one whose cells are 10 sigma wide (s, psr_mesh_screening_depth) with alpha
/// 2^s instead of alpha 2^depth, so that a high depth does not pull the surface onto the
/// noise (the coarser depths keep alpha 2^depth, which keeps small detached parts of a scan);
/// exact samples keep 2^depth; so do clouds too sparse for the estimate to resolve the surface
/// (it reads no noise there). Out of core (psr_reconstructor_solve_file_out_of_core) the slabs
/// estimate the same sigma from their parts (psr_reconstructor_out_of_core_noise). Default true
/// (it was false before the 2026-12-06 build).
/// false keeps 2^depth at any noise, the scale of SPSR and PoissonRecon: on noisy clouds the
/// surface then follows the noise more with every depth past the samples' own (farther from
/// the true surface and from samples held out of the reconstruction, closer to the points it
/// was fitted to; psr's docs/benchmarks.md, issue 16). No PoissonRecon, Open3D or PCL
/// equivalent.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_vertex_normals.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_screening_follows_noise(
    r: *mut psr_reconstructor,
    follows: bool,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_screening_follows_noise", r, |p| {
            p.screening_follows_noise = follows
        })
    }
}

/// Writes whether the screening follows the samples' noise to *out. r and out must not be
/// NULL. Returns the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_screening_follows_noise(
    r: *const psr_reconstructor,
    out: *mut bool,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param(
            "psr_reconstructor_get_screening_follows_noise",
            r,
            out,
            |p| p.screening_follows_noise,
        )
    }
}

/// Sets the degree of the B-spline node functions: 2 (the default; a smooth gradient) or 1
/// (piecewise-linear, PoissonRecon's and Open3D's default; cheaper per unknown). Also sets the
/// screening weight to 2 x degree (PoissonRecon's default for that degree): call
/// psr_reconstructor_set_point_weight after this for another weight. PoissonRecon --degree,
/// PCL setDegree.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
/// (PSR_STATUS_INVALID_PARAMETER for any value but 1 and 2, leaving the degree and the
/// screening weight as they were).
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_degree(
    r: *mut psr_reconstructor,
    degree: i32,
) -> psr_status {
    const FUNCTION: &str = "psr_reconstructor_set_degree";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(FUNCTION, r) }?;
        let degree = u8::try_from(degree)
            .ok()
            .filter(|d| (1..=2).contains(d))
            .ok_or_else(|| {
                Failure::from_error(
                    FUNCTION,
                    Error::InvalidParameter {
                        name: "degree",
                        value: degree.to_string(),
                        expected: "1 or 2",
                    },
                )
            })?;
        handle.params = handle.params.clone().with_degree(degree);
        Ok(())
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(FUNCTION, r, body) }
}

/// Writes the B-spline degree (1 or 2) to *out. r and out must not be NULL. Returns the
/// statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_degree(
    r: *const psr_reconstructor,
    out: *mut i32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe { get_param("psr_reconstructor_get_degree", r, out, |p| p.degree as i32) }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe { set_param("psr_reconstructor_set_threads", r, |p| p.threads = threads) }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_threads", r, out, |p| {
            u32::try_from(p.threads).unwrap_or(u32::MAX)
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_max_solver_iterations", r, |p| {
            p.max_solver_iterations = iterations
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_max_solver_iterations", r, out, |p| {
            p.max_solver_iterations
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_solver_tolerance", r, |p| {
            p.solver_tolerance = tolerance
        })
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_solver_tolerance", r, out, |p| {
            p.solver_tolerance
        })
    }
}

/// Boundary conditions at the bounding cube, for psr_reconstructor_set_boundary.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_boundary {
    /// Zero normal derivative on the cube's faces (the default; PoissonRecon --bType 3, Open3D).
    Neumann = 0,
    /// The 2006 paper: node functions simply end beyond the cube (PoissonRecon --bType 1).
    Free = 1,
    /// chi = 0 on the cube's faces, which are then outside the surface: an open scan (terrain,
    /// room, tunnel) closes on itself inside the cube instead of running out to the faces and
    /// being capped there as with Neumann (PoissonRecon --bType 2; no Open3D or PCL
    /// equivalent). Costs the same as Neumann.
    Dirichlet = 2,
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
/// `r` is NULL or a live handle from psr_reconstructor_new.
unsafe fn set_choice<T: Copy>(
    function: &'static str,
    r: *mut psr_reconstructor,
    name: &'static str,
    expected: &'static str,
    value: i32,
    choices: &[T],
    apply: impl Fn(&mut Params, T),
) -> psr_status {
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(function, r) }?;
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
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(function, r, body) }
}

/// Sets the boundary condition: PSR_BOUNDARY_NEUMANN (0, the default), PSR_BOUNDARY_FREE (1)
/// or PSR_BOUNDARY_DIRICHLET (2, for open scans). PoissonRecon --bType (3, 1 and 2).
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_choice(
            "psr_reconstructor_set_boundary",
            r,
            "boundary",
            "PSR_BOUNDARY_NEUMANN (0), PSR_BOUNDARY_FREE (1) or PSR_BOUNDARY_DIRICHLET (2)",
            boundary,
            &[
                crate::Boundary::Neumann,
                crate::Boundary::Free,
                crate::Boundary::Dirichlet,
            ],
            |p, b| p.boundary = b,
        )
    }
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_boundary", r, out, |p| {
            match p.boundary {
                crate::Boundary::Neumann => psr_boundary::Neumann as i32,
                crate::Boundary::Free => psr_boundary::Free as i32,
                crate::Boundary::Dirichlet => psr_boundary::Dirichlet as i32,
            }
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_splatting", r, out, |p| {
            match p.splatting {
                crate::Splatting::BSpline => psr_splatting::Bspline as i32,
                crate::Splatting::Trilinear => psr_splatting::Trilinear as i32,
            }
        })
    }
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
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
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
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
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
}

/// Sets the fewest input samples that must lie within one cell of a closed component of the
/// surface (the finest cell, or its mean edge length where it was meshed coarser) for it to stay
/// in the mesh (the largest component always stays): the level
/// set's tiny "bubbles" beside the surface, around a few stray samples, are left out, while a
/// real part of the scan, however small, carries its own samples. Default 8; 0 keeps every
/// component. psr_mesh_unsupported_components tells how many were left out. No PoissonRecon
/// equivalent.
///
/// r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_min_component_samples(
    r: *mut psr_reconstructor,
    samples: u32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_min_component_samples", r, |p| {
            p.min_component_samples = samples
        })
    }
}

/// Writes the fewest samples a closed component needs to stay (see
/// psr_reconstructor_set_min_component_samples) to *out. r and out must not be NULL. Returns
/// the statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_min_component_samples(
    r: *const psr_reconstructor,
    out: *mut u32,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_min_component_samples", r, out, |p| {
            p.min_component_samples
        })
    }
}

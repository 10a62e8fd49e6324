//! Trimming a mesh: `psr_trim_options` (an options struct that begins with its own size, so it
//! can grow), psr_trim_options_init, psr_mesh_trim, and the threshold a trimmed mesh was cut
//! at.
//!
//! The options are read field by field at their offsets, never through a reference to the whole
//! struct: a program built with an older header passes a smaller struct, whose missing fields
//! take their defaults, and a program built with a newer header passes a larger one, accepted
//! when every field this library does not know is zero (their "not set"). The struct has no
//! padding, so every field added at its end changes its size.

use super::mesh::psr_mesh;
use super::panic_boundary::{guard_no_handle, guard_value, require_out, write_out};
use super::stage::{psr_progress_fn, psr_stage};
use super::status::{psr_status, Failure, Outcome};
use super::MAX_STRUCT_SIZE;
use crate::{Error, Stage, Threshold, Trimming};
use std::ffi::c_void;
use std::mem::{offset_of, size_of};
use std::ptr;

/// What psr_trim_options.threshold_value means (psr_trim_options.threshold).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum psr_trim_threshold {
    /// Half the density below which 0.1 % of the input samples lie: the surface is cut a little
    /// beyond the edges of the sparsest sampled regions, and at most about 0.1 % of the samples
    /// lose the surface around them. threshold_value is ignored. The default.
    Automatic = 0,
    /// threshold_value is a density (the unit of psr_mesh_densities: samples per kernel-depth
    /// node), finite and >= 0; 0 keeps everything.
    Density = 1,
    /// threshold_value is a fraction q in [0, 1] of the mesh's area: the cut is at the lowest
    /// density below which at least that much of the area lies (more goes where a whole region
    /// shares one density, such as a lid far from every sample, at 0).
    Quantile = 2,
    /// threshold_value is PoissonRecon's depth-like value d in [0, 32] (its --density output
    /// and SurfaceTrimmer --trim): the density 4^(d - kernel depth).
    Depth = 3,
}

/// Options of psr_mesh_trim. Fill it with psr_trim_options_init(&opts, sizeof opts), which
/// writes the defaults and struct_size, then change the fields you need. Fields are only ever
/// added at the end: a program built with this header keeps working with later libraries, and
/// a later program with this library as long as it leaves the fields this header lacks at
/// their defaults (zero).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct psr_trim_options {
    /// The size of this struct as your header defines it (sizeof(psr_trim_options)); set by
    /// psr_trim_options_init. It tells the library which fields you have.
    pub struct_size: usize,
    /// A psr_trim_threshold: how threshold_value is read. Default PSR_TRIM_THRESHOLD_AUTOMATIC.
    pub threshold: i32,
    /// Worker threads for the trim; 0 = one per core. Default 0. The result does not depend on
    /// it.
    pub threads: u32,
    /// The threshold, in the unit psr_trim_threshold gives it; ignored for
    /// PSR_TRIM_THRESHOLD_AUTOMATIC. Default 0.
    pub threshold_value: f64,
    /// Pieces left by the cut with less than this fraction of the cut surface's area are
    /// dropped; range [0, 1]. Default 0 (every piece kept: pieces left near samples are small
    /// sampled parts). PoissonRecon's SurfaceTrimmer --aRatio (default 0.001 there).
    pub min_piece_area: f32,
    /// Pieces of fewer triangles than this are dropped too. Default 0.
    pub min_piece_triangles: u32,
    /// A progress callback for the trim, or NULL (the default) for none: called as for
    /// psr_reconstructor_solve (see psr_progress_fn) with PSR_STAGE_TRIM, on the thread that
    /// called psr_mesh_trim, at least every 20 ms while the cut runs, then with 1; returning
    /// false cancels (psr_mesh_trim returns PSR_STATUS_CANCELLED and no mesh, within a step of
    /// the cut: 9 steps, each a parallel pass over the mesh). A struct from a header without
    /// this field ends before it: then no callback is called.
    pub progress: psr_progress_fn,
    /// Passed as the callback's first argument; the library never reads it. Default NULL.
    pub progress_user_data: *mut c_void,
}

/// The default options, as psr_trim_options_init writes them (the Rust API's defaults).
fn defaults() -> psr_trim_options {
    let d = Trimming::default();
    psr_trim_options {
        struct_size: size_of::<psr_trim_options>(),
        threshold: psr_trim_threshold::Automatic as i32,
        threads: u32::try_from(d.threads).unwrap_or(0),
        threshold_value: 0.0,
        min_piece_area: d.min_piece_area,
        min_piece_triangles: d.min_piece_triangles,
        progress: None,
        progress_user_data: ptr::null_mut(),
    }
}

/// The progress callback psr_trim_options carries, with its user pointer.
#[derive(Clone, Copy)]
struct TrimProgress {
    callback: psr_progress_fn,
    user: *mut c_void,
}

/// Checks a struct_size given by C.
fn check_size(function: &str, struct_size: usize) -> Outcome {
    if (size_of::<usize>()..=MAX_STRUCT_SIZE).contains(&struct_size) {
        Ok(())
    } else {
        Err(Failure::new(
            psr_status::InvalidArgument,
            format!(
                "{function}: struct_size is {struct_size}, not the size of a psr_trim_options \
                 ({} to {MAX_STRUCT_SIZE} bytes): fill the struct with \
                 psr_trim_options_init(&opts, sizeof opts)",
                size_of::<usize>()
            ),
        ))
    }
}

/// Fills *opts (struct_size bytes, sizeof(psr_trim_options) as the caller's header defines it)
/// with the default options: every field it knows set to its default, any later field zeroed,
/// and opts->struct_size = struct_size. Pass sizeof of your struct, so that a newer library
/// never writes beyond it.
///
/// opts must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_ARGUMENT (struct_size below sizeof(size_t) or above 4096; nothing is
/// written) or PSR_STATUS_INTERNAL_ERROR. Thread-safe.
///
/// # Safety
/// `opts` is NULL or valid for writing `struct_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn psr_trim_options_init(
    opts: *mut psr_trim_options,
    struct_size: usize,
) -> psr_status {
    const F: &str = "psr_trim_options_init";
    guard_no_handle(F, || {
        require_out(F, "opts", opts)?;
        check_size(F, struct_size)?;
        let base = opts.cast::<u8>();
        // SAFETY: `opts` is not NULL, so it is valid for writing `struct_size` bytes (this
        // function's contract).
        unsafe { ptr::write_bytes(base, 0, struct_size) };
        let defaults = defaults();
        let known = size_of::<psr_trim_options>().min(struct_size);
        // SAFETY: both spans are `known` <= struct_size bytes: the defaults are a whole struct,
        // the destination valid for struct_size bytes (this function's contract). They are
        // different objects.
        unsafe { ptr::copy_nonoverlapping(ptr::from_ref(&defaults).cast::<u8>(), base, known) };
        // SAFETY: struct_size >= size_of::<usize>() (checked), so the first field is writable;
        // unaligned, since an older or newer caller's struct is only known to be bytes.
        unsafe { base.cast::<usize>().write_unaligned(struct_size) };
        Ok(())
    })
}

/// Reads a field of type `T` at `offset` of the caller's struct of `size` bytes, or `None` when
/// the struct ends before the field does (an older header's struct).
///
/// # Safety
/// `base` is valid for reading `size` bytes.
unsafe fn field<T: Copy>(base: *const u8, size: usize, offset: usize) -> Option<T> {
    // SAFETY: the field lies within the `size` readable bytes (checked); unaligned, since the
    // caller's struct is only known to be bytes.
    (offset + size_of::<T>() <= size)
        .then(|| unsafe { base.add(offset).cast::<T>().read_unaligned() })
}

/// The Rust options C's `options` stand for (the defaults for NULL).
///
/// # Safety
/// `options` is NULL or points to `options->struct_size` readable bytes.
unsafe fn read_options(
    function: &str,
    options: *const psr_trim_options,
) -> Result<(Trimming, TrimProgress), Failure> {
    let mut trimming = Trimming::default();
    let mut progress = TrimProgress {
        callback: None,
        user: ptr::null_mut(),
    };
    if options.is_null() {
        return Ok((trimming, progress));
    }
    let base = options.cast::<u8>();
    // SAFETY: a non-NULL `options` starts with its struct_size (this function's contract).
    let size = unsafe { base.cast::<usize>().read_unaligned() };
    check_size(function, size)?;
    let known = size_of::<psr_trim_options>();
    if size > known {
        // SAFETY: the caller's struct has `size` readable bytes (this function's contract).
        let later = unsafe { std::slice::from_raw_parts(base.add(known), size - known) };
        if let Some(at) = later.iter().position(|&b| b != 0) {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{function}: the psr_trim_options passed ({size} bytes) sets a field this \
                     library does not know (byte {} is not zero; this library's struct has \
                     {known} bytes): leave later fields at their defaults or use a newer psr",
                    known + at
                ),
            ));
        }
    }
    // SAFETY: `base` has `size` readable bytes (this function's contract).
    let kind: i32 = unsafe { field(base, size, offset_of!(psr_trim_options, threshold)) }
        .unwrap_or(psr_trim_threshold::Automatic as i32);
    // SAFETY: as above.
    let value: f64 =
        unsafe { field(base, size, offset_of!(psr_trim_options, threshold_value)) }.unwrap_or(0.0);
    // A double beyond f32's range becomes infinite, which the Rust options refuse.
    let value = value as f32;
    trimming.threshold = match kind {
        0 => Threshold::Automatic,
        1 => Threshold::Density(value),
        2 => Threshold::Quantile(value),
        3 => Threshold::Depth(value),
        _ => {
            return Err(Failure::from_error(
                function,
                Error::InvalidParameter {
                    name: "threshold",
                    value: kind.to_string(),
                    expected: "PSR_TRIM_THRESHOLD_AUTOMATIC (0), _DENSITY (1), _QUANTILE (2) or \
                               _DEPTH (3)",
                },
            ))
        }
    };
    // SAFETY: as above.
    let threads: Option<u32> = unsafe { field(base, size, offset_of!(psr_trim_options, threads)) };
    if let Some(threads) = threads {
        trimming.threads = usize::try_from(threads).unwrap_or(usize::MAX);
    }
    // SAFETY: as above.
    let area: Option<f32> =
        unsafe { field(base, size, offset_of!(psr_trim_options, min_piece_area)) };
    if let Some(area) = area {
        trimming.min_piece_area = area;
    }
    let triangles = offset_of!(psr_trim_options, min_piece_triangles);
    // SAFETY: as above.
    let count: Option<u32> = unsafe { field(base, size, triangles) };
    if let Some(count) = count {
        trimming.min_piece_triangles = count;
    }
    // SAFETY: as above; a function pointer's bits, NULL (None) or a function the caller gave.
    let callback: Option<psr_progress_fn> =
        unsafe { field(base, size, offset_of!(psr_trim_options, progress)) };
    if let Some(callback) = callback {
        progress.callback = callback;
    }
    // SAFETY: as above.
    let user: Option<*mut c_void> =
        unsafe { field(base, size, offset_of!(psr_trim_options, progress_user_data)) };
    if let Some(user) = user {
        progress.user = user;
    }
    Ok((trimming, progress))
}

/// psr_mesh_trim's body, returning its failure's message (which C does not see; the tests
/// check it).
///
/// # Safety
/// As for psr_mesh_trim.
unsafe fn try_trim(
    m: *const psr_mesh,
    options: *const psr_trim_options,
    out: *mut *mut psr_mesh,
) -> Outcome {
    const F: &str = "psr_mesh_trim";
    // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so a
    // shared reference is sound even with other threads reading it.
    let mesh = unsafe { m.as_ref() }.ok_or_else(|| Failure::null(F, "m"))?;
    require_out(F, "out", out)?;
    // SAFETY: `options` is NULL or points to its struct_size readable bytes (this function's
    // contract).
    let (trimming, progress) = unsafe { read_options(F, options) }?;
    let mut report = |stage: Stage, fraction: f32| match progress.callback {
        // SAFETY: the caller promised the callback is safe to call with its user pointer
        // during psr_mesh_trim (this function's contract); it is called on this thread only.
        Some(callback) => unsafe { callback(progress.user, psr_stage::from(stage), fraction) },
        None => true,
    };
    let trimmed = crate::trim_with_progress(&mesh.mesh, &trimming, &mut report)
        .map_err(|e| Failure::from_error(F, e))?;
    let trimmed = Box::into_raw(Box::new(psr_mesh::new(trimmed)));
    // SAFETY: `out` is not NULL (checked) and valid for writing one pointer (this function's
    // contract).
    unsafe { write_out(F, "out", out, trimmed) }
}

/// Cuts m back to where its sampling density is at least a threshold (psr_trim_options) and
/// writes the result to *out as a new mesh (free it with psr_mesh_free); m itself is left as
/// it is, so the untrimmed surface stays available. The cut follows the density's contour
/// across triangles; the result is a mesh with boundary: every edge in one or two triangles,
/// every vertex a single fan, oriented like m, with one density per vertex (interpolated on
/// the cut). Cutting everything away gives a mesh with no vertices, not an error.
/// psr_mesh_trim_density and psr_mesh_trim_depth give the threshold it was cut at. The Rust
/// API's psr::trim; PoissonRecon's SurfaceTrimmer.
///
/// m and out must not be NULL; options may be NULL for the defaults (the automatic threshold,
/// every piece kept). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_ARGUMENT (options->struct_size not set by psr_trim_options_init, or a
/// field this library does not know set to non-zero), PSR_STATUS_INVALID_PARAMETER (an unknown
/// threshold kind, or a value out of the range its field documents), PSR_STATUS_CANCELLED
/// (options->progress returned false), PSR_STATUS_THREADS_UNAVAILABLE or
/// PSR_STATUS_INTERNAL_ERROR. A mesh function keeps no message (there is no reconstructor to
/// keep it on). On failure *out is left untouched.
///
/// Runs on the calling thread with its own worker threads (options->threads). m is only read:
/// several threads may trim (or read) the same mesh at once.
///
/// # Safety
/// `m` is NULL or a live mesh; `options` is NULL or points to a psr_trim_options of
/// `options->struct_size` readable bytes, whose progress, if set, is safe to call with its
/// progress_user_data during the call; `out` is NULL or valid for writing one pointer.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_trim(
    m: *const psr_mesh,
    options: *const psr_trim_options,
    out: *mut *mut psr_mesh,
) -> psr_status {
    guard_no_handle("psr_mesh_trim", || {
        // SAFETY: forwarded from this function's contract, which is try_trim's.
        unsafe { try_trim(m, options, out) }
    })
}

/// The density m was cut at by psr_mesh_trim (whatever psr_trim_threshold asked for, resolved to
/// a density); NaN if m is NULL or was not made by psr_mesh_trim.
///
/// # Safety
/// `m` is NULL or a live mesh.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_trim_density(m: *const psr_mesh) -> f64 {
    guard_value("psr_mesh_trim_density", f64::NAN, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change.
        unsafe { m.as_ref() }
            .and_then(|m| m.mesh.stats.trim.as_ref())
            .map_or(f64::NAN, |r| r.density)
    })
}

/// The same threshold as PoissonRecon's depth-like value, kernel depth + log4(density)
/// (-infinity for a density of 0); NaN if m is NULL or was not made by psr_mesh_trim.
///
/// # Safety
/// `m` is NULL or a live mesh.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_trim_depth(m: *const psr_mesh) -> f64 {
    guard_value("psr_mesh_trim_depth", f64::NAN, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change.
        unsafe { m.as_ref() }
            .and_then(|m| m.mesh.stats.trim.as_ref())
            .map_or(f64::NAN, |r| r.depth)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Mesh;

    /// The struct has no padding: its size is the sum of its fields', so any field added at
    /// the end changes it.
    #[test]
    fn options_have_no_padding() {
        let pointer = size_of::<usize>();
        let fields = pointer + 4 + 4 + 8 + 4 + 4 + pointer + pointer;
        assert_eq!(size_of::<psr_trim_options>(), fields);
        assert_eq!(
            offset_of!(psr_trim_options, progress_user_data) + pointer,
            size_of::<psr_trim_options>()
        );
    }

    fn failure(m: &psr_mesh, options: *const psr_trim_options) -> (psr_status, String) {
        let mut out = ptr::null_mut();
        // SAFETY: `m` is a live mesh, options NULL or a struct of its struct_size, out valid.
        match unsafe { try_trim(m, options, &mut out) } {
            Ok(()) => {
                // SAFETY: `out` was just written with a new mesh.
                unsafe { super::super::mesh::psr_mesh_free(out) };
                (psr_status::Ok, String::new())
            }
            Err(f) => (f.status, f.message),
        }
    }

    /// Proves each refusal names psr_mesh_trim, what is wrong and what to do.
    #[test]
    fn failures_say_what_is_wrong() {
        let mut mesh = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            densities: vec![1.0, 2.0, 3.0],
            ..Mesh::default()
        };
        mesh.stats.sample_density_quantiles = vec![1.0; 1001];
        let m = psr_mesh::new(mesh);
        let mut opts = defaults();
        assert_eq!(failure(&m, &opts).0, psr_status::Ok);
        opts.struct_size = 3;
        let (status, message) = failure(&m, &opts);
        assert_eq!(status, psr_status::InvalidArgument);
        assert!(
            message.starts_with("psr_mesh_trim: struct_size is 3"),
            "{message}"
        );
        assert!(message.contains("psr_trim_options_init"), "{message}");
        opts = defaults();
        opts.threshold = 9;
        let (status, message) = failure(&m, &opts);
        assert_eq!(status, psr_status::InvalidParameter);
        assert!(
            message.contains("threshold = 9") && message.contains("_DEPTH (3)"),
            "{message}"
        );
        opts = defaults();
        opts.threshold = psr_trim_threshold::Quantile as i32;
        opts.threshold_value = 2.0;
        let (status, message) = failure(&m, &opts);
        assert_eq!(status, psr_status::InvalidParameter);
        assert!(
            message.contains("Quantile(2)") && message.contains("[0, 1]"),
            "{message}"
        );
        // A newer caller's larger struct with a later field set.
        let mut newer = [0u64; 8];
        // SAFETY: `newer` has 64 writable bytes.
        unsafe { psr_trim_options_init(newer.as_mut_ptr().cast(), 64) };
        newer[7] = 1;
        let (status, message) = failure(&m, newer.as_ptr().cast());
        assert_eq!(status, psr_status::InvalidArgument);
        assert!(message.contains("byte 56 is not zero"), "{message}");
    }
}

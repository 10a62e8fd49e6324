//! A mesh's figures for hosts: the depth used, the octree's finest depth, the nodes per depth,
//! and how each depth's solve ended (`psr_depth_solve`, an out-struct that begins with its own
//! size). The Rust API's `Stats` and `DepthSolve`.
//!
//! `psr_depth_solve` is written field by field at its offsets, never through a reference to a
//! caller's struct of another size: a program built with a newer header passes a larger struct,
//! whose fields this library does not know are zeroed (0 = not reported). Fields are only added
//! at the end; the struct has no padding, so every addition changes its size.

use super::mesh::psr_mesh;
use super::panic_boundary::{guard_no_handle, guard_value, write_out};
use super::status::{psr_status, Failure, Outcome};
use super::MAX_STRUCT_SIZE;
use crate::mesh::Stats;
use std::mem::{offset_of, size_of};
use std::ptr;

/// How one depth's linear solve ended (psr_mesh_solve_stats). Set struct_size to
/// sizeof(psr_depth_solve) before the call: it tells the library how much it may write.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct psr_depth_solve {
    /// The size of this struct as your header defines it (sizeof(psr_depth_solve)); set it
    /// before calling psr_mesh_solve_stats, which leaves it as it is.
    pub struct_size: usize,
    /// The octree depth of this solve.
    pub depth: u32,
    /// Conjugate-gradient iterations run.
    pub iterations: u32,
    /// Unknowns (octree nodes) at this depth.
    pub unknowns: u64,
    /// |b - Ax| / |b| at the end (0 when b = 0).
    pub relative_residual: f64,
    /// Wall seconds for this depth (right-hand side, operator set-up and iterations).
    pub seconds: f64,
}

/// The figures of a live mesh, or the failure naming `function`'s NULL m.
///
/// # Safety
/// `m` is NULL or a live mesh.
unsafe fn stats_of<'a>(function: &str, m: *const psr_mesh) -> Result<&'a Stats, Failure> {
    // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so a
    // shared reference is sound even with other threads reading it.
    unsafe { m.as_ref() }
        .map(|m| &m.mesh.stats)
        .ok_or_else(|| Failure::null(function, "m"))
}

/// Writes to *out the maximum octree depth the reconstruction of m used: the depth set with
/// psr_reconstructor_set_depth, or the one psr_reconstructor_set_width chose. 0 for a mesh no
/// reconstruction made. A trimmed mesh reports the figures of the mesh it was cut from (so do
/// the other functions here).
///
/// m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
/// PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_depth(m: *const psr_mesh, out: *mut u32) -> psr_status {
    const F: &str = "psr_mesh_depth";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh and `out` is NULL or valid for writes (this
        // function's contract).
        unsafe { write_out(F, "out", out, stats_of(F, m)?.depth) }
    })
}

/// Writes to *out the octree's finest depth: psr_mesh_depth's, or less when the sampling
/// density put no sample that deep (sparse points at a high depth), where the tree and the
/// surface stop (never above the full depth). psr_mesh_node_counts has this + 1 entries.
///
/// m and out must not be NULL. Returns the statuses of psr_mesh_depth.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_finest_depth(m: *const psr_mesh, out: *mut u32) -> psr_status {
    const F: &str = "psr_mesh_finest_depth";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh and `out` is NULL or valid for writes (this
        // function's contract).
        unsafe { write_out(F, "out", out, stats_of(F, m)?.finest_depth()) }
    })
}

/// Writes to *out the noise's depth s of the screening weight: the depths finer than s were
/// pulled with alpha 2^s instead of alpha 2^depth (those up to floor(s) keep alpha 2^depth).
/// psr_mesh_depth's when the samples read no noise or the screening did not follow it
/// (psr_reconstructor_set_screening_follows_noise); less (fractional) when the noise set it.
/// 0 for a mesh no reconstruction made.
///
/// m and out must not be NULL. Returns the statuses of psr_mesh_depth.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_screening_depth(m: *const psr_mesh, out: *mut f64) -> psr_status {
    const F: &str = "psr_mesh_screening_depth";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh and `out` is NULL or valid for writes (this
        // function's contract).
        unsafe { write_out(F, "out", out, stats_of(F, m)?.screening_depth) }
    })
}

/// Writes to *out the samples' positional noise sigma in input units (their RMS scatter across
/// the surface; 0 for exact samples of a smooth surface) as the reconstruction of m estimated
/// it, or NaN when it did not (psr_reconstructor_set_screening_follows_noise was false).
///
/// m and out must not be NULL. Returns the statuses of psr_mesh_depth.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_sample_noise(m: *const psr_mesh, out: *mut f64) -> psr_status {
    const F: &str = "psr_mesh_sample_noise";
    guard_no_handle(F, || {
        // SAFETY: `m` is NULL or a live mesh and `out` is NULL or valid for writes (this
        // function's contract).
        unsafe {
            write_out(
                F,
                "out",
                out,
                stats_of(F, m)?.sample_noise.unwrap_or(f64::NAN),
            )
        }
    })
}

/// Copies the octree's node (unknown) counts per depth into out, index = depth, from 0 to
/// psr_mesh_finest_depth; capacity is the number of uint64_t out can hold, and *count gets
/// the number written. To ask for the count alone, pass out = NULL and capacity = 0: *count
/// gets the number of entries there are. A mesh no reconstruction made has none.
///
/// m and count must not be NULL; out may be NULL only with capacity 0. Returns PSR_STATUS_OK,
/// PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (capacity > 0 but less than the
/// entries; nothing is written, *count neither) or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or valid for writes of `capacity` values; `count`
/// is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_node_counts(
    m: *const psr_mesh,
    out: *mut u64,
    capacity: usize,
    count: *mut usize,
) -> psr_status {
    guard_no_handle("psr_mesh_node_counts", || {
        // SAFETY: forwarded from this function's contract, which is try_node_counts'.
        unsafe { try_node_counts(m, out, capacity, count) }
    })
}

/// psr_mesh_node_counts.
///
/// # Safety
/// As for psr_mesh_node_counts.
unsafe fn try_node_counts(
    m: *const psr_mesh,
    out: *mut u64,
    capacity: usize,
    count: *mut usize,
) -> Outcome {
    const F: &str = "psr_mesh_node_counts";
    // SAFETY: `m` is NULL or a live mesh (this function's contract).
    let nodes = &unsafe { stats_of(F, m) }?.nodes_per_depth;
    if count.is_null() {
        return Err(Failure::null(F, "count"));
    }
    if out.is_null() {
        if capacity > 0 {
            return Err(Failure::null(F, "out (with capacity > 0)"));
        }
        // SAFETY: `count` is not NULL, so valid for writes (this function's contract).
        return unsafe { write_out(F, "count", count, nodes.len()) };
    }
    if capacity < nodes.len() {
        return Err(Failure::new(
            psr_status::BufferTooSmall,
            format!(
                "{F}: capacity is {capacity}, less than the {} depths; nothing was written",
                nodes.len()
            ),
        ));
    }
    for (d, &n) in nodes.iter().enumerate() {
        // SAFETY: `out` is not NULL, so valid for writes of `capacity` > d values (this
        // function's contract).
        unsafe { out.add(d).write(n as u64) };
    }
    // SAFETY: `count` is not NULL, so valid for writes (this function's contract).
    unsafe { write_out(F, "count", count, nodes.len()) }
}

/// Number of closed components of the level set that the reconstruction left out of m because
/// too few samples support them (psr_reconstructor_set_min_component_samples); 0 if m is NULL
/// or no reconstruction made it.
///
/// # Safety
/// `m` is NULL or a live mesh.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_unsupported_components(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_unsupported_components", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change.
        unsafe { m.as_ref() }.map_or(0, |m| m.mesh.stats.unsupported_components)
    })
}

/// Number of per-depth solves of m, coarse to fine (psr_mesh_solve_stats' indices); 0 if m is
/// NULL or no reconstruction made it.
///
/// # Safety
/// `m` is NULL or a live mesh.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_solve_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_solve_count", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change.
        unsafe { m.as_ref() }.map_or(0, |m| m.mesh.stats.solves.len())
    })
}

/// Writes how the solve at index (0 = the coarsest, up to psr_mesh_solve_count(m) - 1) ended
/// into *out: its depth, unknowns, iterations, final relative residual and seconds. Set
/// out->struct_size = sizeof(psr_depth_solve) first: the library writes the fields it knows
/// that fit in that size, and sets the rest of a larger (newer) struct to zero.
///
/// m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_ARGUMENT (index out of range, or out->struct_size smaller than this
/// header's first psr_depth_solve or implausibly large: not set) or PSR_STATUS_INTERNAL_ERROR;
/// *out is written only on success.
///
/// # Safety
/// `m` is NULL or a live mesh; `out` is NULL or points to a psr_depth_solve whose struct_size
/// bytes are writable.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_solve_stats(
    m: *const psr_mesh,
    index: usize,
    out: *mut psr_depth_solve,
) -> psr_status {
    guard_no_handle("psr_mesh_solve_stats", || {
        // SAFETY: forwarded from this function's contract, which is try_solve_stats'.
        unsafe { try_solve_stats(m, index, out) }
    })
}

/// psr_mesh_solve_stats.
///
/// # Safety
/// As for psr_mesh_solve_stats.
unsafe fn try_solve_stats(m: *const psr_mesh, index: usize, out: *mut psr_depth_solve) -> Outcome {
    const F: &str = "psr_mesh_solve_stats";
    // SAFETY: `m` is NULL or a live mesh (this function's contract).
    let solves = &unsafe { stats_of(F, m) }?.solves;
    if out.is_null() {
        return Err(Failure::null(F, "out"));
    }
    // SAFETY: `out` is not NULL, so it points to a struct that begins with its size (this
    // function's contract); read as that field alone, without assuming alignment.
    let size = unsafe { ptr::read_unaligned(out.cast::<usize>()) };
    let ours = size_of::<psr_depth_solve>();
    if !(ours..=MAX_STRUCT_SIZE).contains(&size) {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!(
                "{F}: out->struct_size is {size}; set it to sizeof(psr_depth_solve) ({ours} in \
                 this library's header) before the call"
            ),
        ));
    }
    let Some(solve) = solves.get(index) else {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!(
                "{F}: index {index} is not below the {} solves",
                solves.len()
            ),
        ));
    };
    let figures = psr_depth_solve {
        struct_size: size,
        depth: solve.depth,
        iterations: solve.iterations,
        unknowns: solve.unknowns as u64,
        relative_residual: solve.relative_residual,
        seconds: solve.seconds,
    };
    let bytes = out.cast::<u8>();
    // SAFETY: `out` holds `size` >= size_of::<psr_depth_solve>() writable bytes (checked above,
    // and this function's contract), so the whole struct fits, and the bytes from its end to
    // `size` are the caller's, for fields this library does not know: zero means not reported.
    // The struct_size field is written with the value read from it.
    unsafe {
        ptr::write_unaligned(out, figures);
        ptr::write_bytes(bytes.add(ours), 0, size - ours);
    }
    debug_assert_eq!(
        offset_of!(psr_depth_solve, seconds) + 8,
        ours,
        "no tail padding"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DepthSolve, Mesh};

    /// Proves: psr_depth_solve has no padding (every field added later changes its size), and
    /// its fields sit where the header's C struct puts them on 64-bit targets.
    #[test]
    fn the_out_struct_has_no_padding() {
        let fields = size_of::<usize>() + 4 + 4 + 8 + 8 + 8;
        assert_eq!(size_of::<psr_depth_solve>(), fields);
        assert_eq!(offset_of!(psr_depth_solve, depth), size_of::<usize>());
    }

    /// Proves: the figures written are the mesh's, a newer (larger) struct gets zeros past the
    /// fields this library knows, and a size that was not set is refused without a write.
    #[test]
    fn solve_figures_are_written_and_a_larger_struct_gets_zeros() {
        let stats = Stats {
            solves: vec![DepthSolve {
                depth: 7,
                unknowns: 1234,
                iterations: 9,
                relative_residual: 0.004,
                seconds: 0.5,
            }],
            ..Stats::default()
        };
        let mesh = psr_mesh::new(Mesh {
            stats,
            ..Mesh::default()
        });
        let ours = size_of::<psr_depth_solve>();
        // A newer header's struct: this one and two more u64 fields, set to garbage.
        let mut newer = [0xABu8; 64];
        newer[..size_of::<usize>()].copy_from_slice(&(ours + 16).to_ne_bytes());
        let out = newer.as_mut_ptr().cast::<psr_depth_solve>();
        // SAFETY: `newer` holds ours + 16 writable bytes; the mesh is live.
        assert!(unsafe { try_solve_stats(&mesh, 0, out) }.is_ok());
        // SAFETY: `newer` holds a whole psr_depth_solve.
        let got = unsafe { ptr::read_unaligned(out) };
        assert_eq!(
            (got.struct_size, got.depth, got.unknowns, got.iterations),
            (ours + 16, 7, 1234, 9)
        );
        assert_eq!((got.relative_residual, got.seconds), (0.004, 0.5));
        assert!(newer[ours..ours + 16].iter().all(|&b| b == 0));
        assert!(
            newer[ours + 16..].iter().all(|&b| b == 0xAB),
            "past its size"
        );

        for size in [0, ours - 1, MAX_STRUCT_SIZE + 1] {
            let mut s = [0xCDu8; 64];
            s[..size_of::<usize>()].copy_from_slice(&size.to_ne_bytes());
            let out = s.as_mut_ptr().cast::<psr_depth_solve>();
            // SAFETY: as above; the call must refuse before writing.
            let failure = unsafe { try_solve_stats(&mesh, 0, out) }.unwrap_err();
            assert_eq!(failure.status, psr_status::InvalidArgument, "{size}");
            assert!(s[size_of::<usize>()..].iter().all(|&b| b == 0xCD));
        }
    }
}

//! The C API: opaque handles over [`crate::Params`], [`crate::PointSet`] and [`crate::Mesh`].
//!
//! This module only checks arguments, converts between C and Rust representations and forwards
//! to [`crate::reconstruct_with_progress`]; it holds no reconstruction logic. `include/psr.h` is
//! generated from it by cbindgen (see `cbindgen.toml` and `scripts/gen_header.sh`), so the doc
//! comments below are the C documentation: they speak C.
//!
//! Invariants the code below keeps:
//! - No panic crosses the boundary: every exported function runs its body through `guard`,
//!   the one `catch_unwind` of this module. A panic in a call on a reconstructor poisons it.
//! - Out-parameters are written only on success, as the very last step.
//! - No global state: each handle carries its parameters, points, callback and last message, and
//!   each solve builds its own worker pool, so different handles may run on different threads.
//!   (The one static filled at run time, psr_stage_string's table of names, is written once
//!   and never changes.)
//! - `unsafe` is confined to turning C pointers into references, reading and writing through
//!   them (each behind a NULL, length and overflow check) and calling the C progress callback.
//!   Every `unsafe fn` says what its caller must guarantee (`# Safety`), every `unsafe {}` block
//!   why that holds there (`// SAFETY:`); the crate's lints (`src/lib.rs`) make the blocks
//!   explicit, also inside `unsafe fn`, and require their comments.
//!
//! One file per concept of the C API, as rustls-ffi does; everything C sees is re-exported here,
//! so `psr::ffi::*` is the whole C API:
//! - `panic_boundary.rs`: `guard` (the one `catch_unwind`, poisoning, the refusal of calls from
//!   inside a handle's own callback, the last message) and the helpers that turn C pointers into
//!   references and write out-parameters.
//! - `status.rs`: `psr_status`, `psr_status_string`, and `Failure`, a failed call's status and
//!   message, with the mapping from [`crate::Error`] to a status.
//! - `version.rs`: `PSR_VERSION_*` and `psr_version*`.
//! - `stage.rs`: `psr_stage`, `psr_stage_string` and `psr_progress_fn`.
//! - `reconstructor.rs`: the `psr_reconstructor` handle; psr_reconstructor_new, _free and
//!   _last_error.
//! - `params.rs`: the parameter setters and getters; `psr_boundary`, `psr_splatting`,
//!   `psr_vertex_placement`.
//! - `points.rs`: psr_reconstructor_add_points (and its _f64 and _transformed forms), _point_count
//!   and _clear_points.
//! - `solve.rs`: psr_reconstructor_set_progress_callback, psr_reconstructor_solve and the
//!   panic test hooks.
//! - `mesh.rs`: the `psr_mesh` handle: counts, borrowed views, copy-outs, psr_mesh_free.
//! - `normals.rs`: psr_reconstructor_add_positions (points without normals, estimated at solve),
//!   _seen_from and _with_sensors (with their sensors' positions), the estimation's settings;
//!   `psr_orientation`.
//! - `trim.rs`: psr_mesh_trim and its options, `psr_trim_options` (the first options struct:
//!   it begins with its own size so it can grow) and `psr_trim_threshold`;
//!   psr_mesh_trim_density and _depth.
//! - `attributes.rs`: `psr_point_arrays` (a struct that begins with its own size),
//!   psr_point_arrays_init and psr_reconstructor_add_point_arrays (confidence, colours,
//!   channels); psr_reconstructor_set_vertex_normals; the mesh's normals, colours and channels.
//! - `stats.rs`: the mesh's figures (the Rust `Stats`): psr_mesh_depth, _finest_depth,
//!   _node_counts, _solve_count and _solve_stats with `psr_depth_solve` (an out-struct that
//!   begins with its own size), _unsupported_components.
//! - `implicit.rs`: the `psr_implicit` handle, the solved χ kept by
//!   psr_reconstructor_solve_implicit: psr_implicit_evaluate, _gradient, _sample_grid,
//!   _sample_box, _isovalue, _cube and _free.
//! - `memory.rs`: the memory limit (psr_reconstructor_set_max_memory, _get_max_memory) and
//!   the estimates before a solve (psr_reconstructor_estimate_memory, psr_estimate_memory).

// The C names (psr_status, psr_mesh, ...) are the header's, not Rust's.
#![allow(non_camel_case_types)]

// The files in the header's order (cbindgen writes functions in the order it reads them; these
// comments also keep rustfmt from sorting the lines).
// No C functions: the one catch_unwind and the pointer helpers.
/// The largest struct_size accepted in a size-prefixed struct (psr_trim_options,
/// psr_depth_solve): far above any foreseeable version of one, low enough that an unset or
/// uninitialised size is refused rather than read as a huge struct.
const MAX_STRUCT_SIZE: usize = 4096;

/// `text` as a C string, each NUL byte (which would end it early) replaced by U+FFFD: for the
/// names and messages psr hands to C.
fn c_string(text: &str) -> std::ffi::CString {
    std::ffi::CString::new(text.replace('\0', "\u{FFFD}")).unwrap_or_default()
}

/// The names of `channels` as C strings (see [`c_string`]), for the handles that lend them.
fn channel_names(channels: &[crate::Channel]) -> Vec<std::ffi::CString> {
    channels.iter().map(|c| c_string(&c.name)).collect()
}

mod panic_boundary;
// psr_status_string.
mod status;
// Stage names and the progress callback's type.
mod stage;
// psr_version and its parts.
mod version;
// psr_reconstructor_new, _free, _last_error.
mod reconstructor;
// The parameter setters and getters.
mod params;
// psr_reconstructor_add_points, _point_count, _clear_points.
mod points;
// psr_reconstructor_set_progress_callback, psr_reconstructor_solve.
mod solve;
// psr_mesh_*.
mod mesh;
// Points without normals and the estimation of their normals.
mod normals;
// Trimming a mesh by its sampling density.
mod trim;
// Points with confidence, colours and channels; the mesh's normals, colours and channels.
mod attributes;
// The mesh's figures: depths, nodes per depth, the solves (psr_depth_solve).
mod stats;
// The solved implicit function χ: evaluated, differentiated, sampled on a grid.
mod implicit;
// The memory limit and the estimates.
mod memory;
mod ply;
// Reconstruction out of core, from file to file.
mod outofcore;

pub use self::attributes::{
    psr_mesh_channel, psr_mesh_channel_count, psr_mesh_channel_name, psr_mesh_color_components,
    psr_mesh_colors, psr_mesh_copy_channel, psr_mesh_copy_colors, psr_mesh_copy_normals,
    psr_mesh_normals, psr_point_arrays, psr_point_arrays_init, psr_reconstructor_add_point_arrays,
    psr_reconstructor_get_vertex_normals, psr_reconstructor_set_vertex_normals,
};
pub use self::implicit::{
    psr_implicit, psr_implicit_cube, psr_implicit_evaluate, psr_implicit_free,
    psr_implicit_gradient, psr_implicit_isovalue, psr_implicit_sample_box,
    psr_implicit_sample_grid, psr_reconstructor_solve_implicit,
};
pub use self::memory::{
    psr_estimate_memory, psr_reconstructor_estimate_memory, psr_reconstructor_get_max_memory,
    psr_reconstructor_set_max_memory,
};
pub use self::mesh::{
    psr_mesh, psr_mesh_copy_densities, psr_mesh_copy_positions, psr_mesh_copy_positions_f64,
    psr_mesh_copy_triangles, psr_mesh_densities, psr_mesh_free, psr_mesh_isovalue, psr_mesh_origin,
    psr_mesh_positions, psr_mesh_triangle_count, psr_mesh_triangles, psr_mesh_vertex_count,
};
pub use self::normals::{
    psr_orientation, psr_reconstructor_add_positions, psr_reconstructor_add_positions_seen_from,
    psr_reconstructor_add_positions_with_sensors, psr_reconstructor_get_normal_neighbors,
    psr_reconstructor_get_normal_orientation,
    psr_reconstructor_get_normal_reconstruction_iterations, psr_reconstructor_set_normal_neighbors,
    psr_reconstructor_set_normal_orientation,
    psr_reconstructor_set_normal_reconstruction_iterations, psr_reconstructor_set_viewpoint,
};
pub use self::outofcore::{
    psr_out_of_core_noise, psr_out_of_core_report, psr_reconstructor_out_of_core_noise,
    psr_reconstructor_solve_file_out_of_core,
};
pub use self::params::{
    psr_boundary, psr_reconstructor_get_boundary, psr_reconstructor_get_degree,
    psr_reconstructor_get_depth, psr_reconstructor_get_full_depth,
    psr_reconstructor_get_kernel_depth, psr_reconstructor_get_max_solver_iterations,
    psr_reconstructor_get_min_component_samples, psr_reconstructor_get_point_weight,
    psr_reconstructor_get_samples_per_node, psr_reconstructor_get_scale,
    psr_reconstructor_get_screening_follows_noise, psr_reconstructor_get_solver_tolerance,
    psr_reconstructor_get_splatting, psr_reconstructor_get_threads,
    psr_reconstructor_get_vertex_placement, psr_reconstructor_get_width,
    psr_reconstructor_set_boundary, psr_reconstructor_set_degree, psr_reconstructor_set_depth,
    psr_reconstructor_set_full_depth, psr_reconstructor_set_kernel_depth,
    psr_reconstructor_set_max_solver_iterations, psr_reconstructor_set_min_component_samples,
    psr_reconstructor_set_point_weight, psr_reconstructor_set_samples_per_node,
    psr_reconstructor_set_scale, psr_reconstructor_set_screening_follows_noise,
    psr_reconstructor_set_solver_tolerance, psr_reconstructor_set_splatting,
    psr_reconstructor_set_threads, psr_reconstructor_set_vertex_placement,
    psr_reconstructor_set_width, psr_splatting, psr_vertex_placement,
};
pub use self::ply::{
    psr_mesh_write_ply, psr_ply, psr_ply_channel, psr_ply_channel_count, psr_ply_channel_name,
    psr_ply_color_components, psr_ply_colors, psr_ply_confidence, psr_ply_free, psr_ply_normals,
    psr_ply_positions, psr_ply_positions_f64, psr_ply_read, psr_ply_sensors,
    psr_ply_triangle_count, psr_ply_triangles, psr_ply_vertex_count, PSR_PLY_ASCII,
    PSR_PLY_BIG_ENDIAN, PSR_PLY_DOUBLE_POSITIONS,
};
pub use self::points::{
    psr_reconstructor_add_points, psr_reconstructor_add_points_f64,
    psr_reconstructor_add_points_transformed, psr_reconstructor_clear_points,
    psr_reconstructor_point_count,
};
pub use self::reconstructor::{
    psr_reconstructor, psr_reconstructor_free, psr_reconstructor_last_error, psr_reconstructor_new,
};
#[cfg(feature = "test-panic")]
pub use self::solve::psr_reconstructor_debug_panic_next_solve;
pub use self::solve::{psr_reconstructor_set_progress_callback, psr_reconstructor_solve};
pub use self::stage::{psr_progress_fn, psr_stage, psr_stage_string};
pub use self::stats::{
    psr_depth_solve, psr_mesh_depth, psr_mesh_finest_depth, psr_mesh_node_counts,
    psr_mesh_sample_noise, psr_mesh_screening_depth, psr_mesh_solve_count, psr_mesh_solve_stats,
    psr_mesh_unsupported_components,
};
pub use self::status::{psr_status, psr_status_string};
pub use self::trim::{
    psr_mesh_trim, psr_mesh_trim_density, psr_mesh_trim_depth, psr_trim_options,
    psr_trim_options_init, psr_trim_threshold,
};
pub use self::version::{
    psr_version, psr_version_major, psr_version_minor, psr_version_patch, PSR_VERSION_MAJOR,
    PSR_VERSION_MINOR, PSR_VERSION_PATCH,
};

// Test hooks for the Rust tests, not part of the C API.
#[doc(hidden)]
pub use self::mesh::debug_mesh_new;
#[doc(hidden)]
pub use self::solve::debug_panic_next_solve;

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn handles_are_send() {
        assert_send::<psr_reconstructor>();
        assert_send::<psr_mesh>();
        assert_send::<psr_implicit>();
        assert_send::<psr_ply>();
    }
}

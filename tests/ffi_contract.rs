//! Contract tests of the C API, calling the exported functions directly as a C program would.
//!
//! Tests that need the reconstruction core to produce meshes go through [`solve_or_skip`]: while
//! `src/pipeline.rs` is still the placeholder that answers "pipeline being written", they print
//! a visible SKIP line instead of failing. Once the core lands the placeholder text is gone and
//! they run in full.

use psr::ffi::*;
use std::ffi::{c_void, CStr};
use std::ptr;

// ------------------------------------------------------------------------------------------------
// Helpers
// ------------------------------------------------------------------------------------------------

/// A dangling but non-NULL, aligned pointer for arguments that must never be read.
fn sentinel_ptr<T>() -> *mut T {
    ptr::NonNull::dangling().as_ptr()
}

fn new_handle() -> *mut psr_reconstructor {
    let mut r = ptr::null_mut();
    assert_eq!(unsafe { psr_reconstructor_new(&mut r) }, psr_status::Ok);
    assert!(!r.is_null());
    r
}

fn last_error(r: *const psr_reconstructor) -> String {
    let p = unsafe { psr_reconstructor_last_error(r) };
    assert!(!p.is_null(), "last_error never returns NULL");
    unsafe { CStr::from_ptr(p) }.to_str().unwrap().to_owned()
}

fn point_count(r: *const psr_reconstructor) -> usize {
    let mut n = usize::MAX;
    assert_eq!(
        unsafe { psr_reconstructor_point_count(r, &mut n) },
        psr_status::Ok
    );
    n
}

/// `n` points on a sphere (Fibonacci lattice) with outward unit normals, flattened.
fn sphere(n: usize, centre: [f32; 3], radius: f32) -> (Vec<f32>, Vec<f32>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (mut p, mut nrm) = (Vec::with_capacity(3 * n), Vec::with_capacity(3 * n));
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let ring = (1.0 - y * y).sqrt();
        let phi = golden * i as f64;
        let d = [ring * phi.cos(), y, ring * phi.sin()];
        for k in 0..3 {
            p.push(centre[k] + radius * d[k] as f32);
            nrm.push(d[k] as f32);
        }
    }
    (p, nrm)
}

fn add_sphere(r: *mut psr_reconstructor, n: usize) {
    let (p, nrm) = sphere(n, [0.1, -0.2, 0.3], 1.0);
    assert_eq!(
        unsafe { psr_reconstructor_add_points(r, p.as_ptr(), 0, nrm.as_ptr(), 0, n) },
        psr_status::Ok,
        "{}",
        last_error(r)
    );
}

/// Message of the placeholder pipeline that stands in until the core lands.
const PLACEHOLDER: &str = "pipeline being written";

/// Solves `r`; `None` (after a visible SKIP line) while the core is the placeholder.
fn solve_or_skip(r: *mut psr_reconstructor, test: &str) -> Option<*mut psr_mesh> {
    let mut mesh = ptr::null_mut();
    let status = unsafe { psr_reconstructor_solve(r, &mut mesh) };
    if status == psr_status::InternalError && last_error(r).contains(PLACEHOLDER) {
        eprintln!("SKIP {test}: the reconstruction core is not in yet ({PLACEHOLDER})");
        return None;
    }
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(!mesh.is_null());
    Some(mesh)
}

/// A small known mesh (a tetrahedron) wrapped as a C handle, for the mesh functions.
fn tetrahedron() -> *mut psr_mesh {
    let mut mesh = psr::Mesh::default();
    mesh.positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    mesh.triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    mesh.densities = vec![1.0, 2.0, 3.0, 4.0];
    mesh.stats.isovalue = 0.5;
    debug_mesh_new(mesh)
}

// ------------------------------------------------------------------------------------------------
// Arguments, NULL and lifetimes
// ------------------------------------------------------------------------------------------------

#[test]
fn free_null_is_a_no_op() {
    unsafe {
        psr_reconstructor_free(ptr::null_mut());
        psr_mesh_free(ptr::null_mut());
    }
}

#[test]
fn null_for_every_pointer_argument() {
    use psr_status::NullArgument as NULL;
    let null_r: *mut psr_reconstructor = ptr::null_mut();
    let null_m: *mut psr_mesh = ptr::null_mut();
    let r = new_handle();
    let p = [0.0f32; 3];
    let n = [0.0f32, 0.0, 1.0];
    unsafe {
        assert_eq!(psr_reconstructor_new(ptr::null_mut()), NULL);

        // Setters with a NULL handle.
        assert_eq!(psr_reconstructor_set_depth(null_r, 6), NULL);
        assert_eq!(psr_reconstructor_set_width(null_r, 0.5), NULL);
        assert_eq!(psr_reconstructor_set_full_depth(null_r, 3), NULL);
        assert_eq!(psr_reconstructor_set_min_component_samples(null_r, 3), NULL);
        assert_eq!(psr_reconstructor_set_kernel_depth(null_r, 3), NULL);
        assert_eq!(psr_reconstructor_set_samples_per_node(null_r, 2.0), NULL);
        assert_eq!(psr_reconstructor_set_scale(null_r, 1.2), NULL);
        assert_eq!(psr_reconstructor_set_point_weight(null_r, 2.0), NULL);
        assert_eq!(psr_reconstructor_set_degree(null_r, 1), NULL);
        assert_eq!(psr_reconstructor_set_threads(null_r, 1), NULL);
        assert_eq!(
            psr_reconstructor_set_max_solver_iterations(null_r, 10),
            NULL
        );
        assert_eq!(psr_reconstructor_set_solver_tolerance(null_r, 1e-4), NULL);

        // Getters: NULL handle, then NULL out; out-params untouched either way.
        let mut u = 77u32;
        let mut i = 77i32;
        let mut f = 77.0f32;
        let mut d = 77.0f64;
        let mut z = 77usize;
        assert_eq!(psr_reconstructor_get_depth(null_r, &mut u), NULL);
        assert_eq!(psr_reconstructor_get_width(null_r, &mut d), NULL);
        assert_eq!(psr_reconstructor_get_full_depth(null_r, &mut u), NULL);
        assert_eq!(
            psr_reconstructor_get_min_component_samples(null_r, &mut u),
            NULL
        );
        assert_eq!(psr_reconstructor_get_kernel_depth(null_r, &mut i), NULL);
        assert_eq!(psr_reconstructor_get_samples_per_node(null_r, &mut f), NULL);
        assert_eq!(psr_reconstructor_get_scale(null_r, &mut f), NULL);
        assert_eq!(psr_reconstructor_get_point_weight(null_r, &mut f), NULL);
        assert_eq!(psr_reconstructor_get_degree(null_r, &mut 0), NULL);
        assert_eq!(psr_reconstructor_get_threads(null_r, &mut u), NULL);
        assert_eq!(
            psr_reconstructor_get_max_solver_iterations(null_r, &mut u),
            NULL
        );
        assert_eq!(psr_reconstructor_get_solver_tolerance(null_r, &mut d), NULL);
        assert_eq!(psr_reconstructor_point_count(null_r, &mut z), NULL);
        assert_eq!((u, i, f, d, z), (77, 77, 77.0, 77.0, 77));

        assert_eq!(psr_reconstructor_get_depth(r, ptr::null_mut()), NULL);
        assert!(last_error(r).contains("out is NULL"), "{}", last_error(r));
        assert_eq!(psr_reconstructor_get_width(r, ptr::null_mut()), NULL);
        assert_eq!(psr_reconstructor_get_full_depth(r, ptr::null_mut()), NULL);
        assert_eq!(
            psr_reconstructor_get_min_component_samples(r, ptr::null_mut()),
            NULL
        );
        assert_eq!(psr_reconstructor_get_kernel_depth(r, ptr::null_mut()), NULL);
        assert_eq!(
            psr_reconstructor_get_samples_per_node(r, ptr::null_mut()),
            NULL
        );
        assert_eq!(psr_reconstructor_get_scale(r, ptr::null_mut()), NULL);
        assert_eq!(psr_reconstructor_get_point_weight(r, ptr::null_mut()), NULL);
        assert_eq!(psr_reconstructor_get_degree(r, ptr::null_mut()), NULL);
        assert_eq!(psr_reconstructor_get_threads(r, ptr::null_mut()), NULL);
        assert_eq!(
            psr_reconstructor_get_max_solver_iterations(r, ptr::null_mut()),
            NULL
        );
        assert_eq!(
            psr_reconstructor_get_solver_tolerance(r, ptr::null_mut()),
            NULL
        );
        assert_eq!(psr_reconstructor_point_count(r, ptr::null_mut()), NULL);

        // Points.
        assert_eq!(
            psr_reconstructor_add_points(null_r, p.as_ptr(), 0, n.as_ptr(), 0, 1),
            NULL
        );
        assert_eq!(
            psr_reconstructor_add_points(r, ptr::null(), 0, n.as_ptr(), 0, 1),
            NULL
        );
        assert!(last_error(r).contains("positions"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, ptr::null(), 0, 1),
            NULL
        );
        assert!(last_error(r).contains("normals"), "{}", last_error(r));
        // NULL arrays are fine with a zero count.
        assert_eq!(
            psr_reconstructor_add_points(r, ptr::null(), 0, ptr::null(), 0, 0),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 0);
        assert_eq!(psr_reconstructor_clear_points(null_r), NULL);

        // Points without normals, with and without sensors, and the estimation's settings.
        let s = [0.0f32, 0.0, 10.0];
        assert_eq!(
            psr_reconstructor_add_positions(null_r, p.as_ptr(), 0, 1),
            NULL
        );
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(null_r, p.as_ptr(), 0, 1, s.as_ptr()),
            NULL
        );
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(r, ptr::null(), 0, 1, s.as_ptr()),
            NULL
        );
        assert!(last_error(r).contains("positions"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(r, p.as_ptr(), 0, 1, ptr::null()),
            NULL
        );
        assert!(last_error(r).contains("sensor"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(null_r, p.as_ptr(), 0, s.as_ptr(), 0, 1),
            NULL
        );
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(r, ptr::null(), 0, s.as_ptr(), 0, 1),
            NULL
        );
        assert!(last_error(r).contains("positions"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(r, p.as_ptr(), 0, ptr::null(), 0, 1),
            NULL
        );
        assert!(last_error(r).contains("sensors"), "{}", last_error(r));
        // NULL arrays are fine with a zero count, and then nothing happens at all.
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(r, ptr::null(), 0, 0, ptr::null()),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(r, ptr::null(), 0, ptr::null(), 0, 0),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 0);
        let mut o = -1i32;
        assert_eq!(
            psr_reconstructor_get_normal_orientation(r, &mut o),
            psr_status::Ok
        );
        assert_eq!(
            o,
            psr_orientation::Propagate as i32,
            "count 0 selects nothing"
        );
        assert_eq!(psr_reconstructor_set_normal_neighbors(null_r, 5), NULL);
        assert_eq!(psr_reconstructor_get_normal_neighbors(null_r, &mut u), NULL);
        assert_eq!(psr_reconstructor_set_normal_orientation(null_r, 0), NULL);
        assert_eq!(
            psr_reconstructor_get_normal_orientation(null_r, &mut i),
            NULL
        );
        assert_eq!(psr_reconstructor_set_viewpoint(null_r, 0.0, 0.0, 1.0), NULL);
        assert_eq!((u, i), (77, 77), "out-parameters untouched on failure");
        assert_eq!(
            psr_reconstructor_get_normal_neighbors(r, ptr::null_mut()),
            NULL
        );
        assert_eq!(
            psr_reconstructor_set_progress_callback(null_r, None, ptr::null_mut()),
            NULL
        );

        // Solve.
        let mut mesh = sentinel_ptr::<psr_mesh>();
        assert_eq!(psr_reconstructor_solve(null_r, &mut mesh), NULL);
        assert_eq!(mesh, sentinel_ptr());
        assert_eq!(psr_reconstructor_solve(r, ptr::null_mut()), NULL);
        assert!(last_error(r).contains("out is NULL"), "{}", last_error(r));

        // last_error on NULL is a static message, never NULL.
        assert!(last_error(null_r).contains("NULL"));

        // Mesh functions on NULL.
        assert_eq!(psr_mesh_vertex_count(null_m), 0);
        assert_eq!(psr_mesh_triangle_count(null_m), 0);
        assert!(psr_mesh_positions(null_m).is_null());
        assert!(psr_mesh_triangles(null_m).is_null());
        assert!(psr_mesh_densities(null_m).is_null());
        assert!(psr_mesh_isovalue(null_m).is_nan());
        let mut fbuf = [0.0f32; 16];
        let mut ubuf = [0u32; 16];
        assert_eq!(psr_mesh_copy_positions(null_m, fbuf.as_mut_ptr(), 16), NULL);
        assert_eq!(psr_mesh_copy_triangles(null_m, ubuf.as_mut_ptr(), 16), NULL);
        assert_eq!(psr_mesh_copy_densities(null_m, fbuf.as_mut_ptr(), 16), NULL);
        let mut nodes = [0u64; 4];
        let mut solve = psr_depth_solve {
            struct_size: std::mem::size_of::<psr_depth_solve>(),
            depth: 77,
            iterations: 77,
            unknowns: 77,
            relative_residual: 77.0,
            seconds: 77.0,
        };
        assert_eq!(psr_mesh_depth(null_m, &mut u), NULL);
        assert_eq!(psr_mesh_finest_depth(null_m, &mut u), NULL);
        assert_eq!(
            psr_mesh_node_counts(null_m, nodes.as_mut_ptr(), 4, &mut z),
            NULL
        );
        assert_eq!(psr_mesh_solve_count(null_m), 0);
        assert_eq!(psr_mesh_unsupported_components(null_m), 0);
        assert_eq!(psr_mesh_solve_stats(null_m, 0, &mut solve), NULL);
        assert_eq!((u, z, solve.depth), (77, 77, 77));
        let m = tetrahedron();
        assert_eq!(psr_mesh_copy_positions(m, ptr::null_mut(), 16), NULL);
        assert_eq!(psr_mesh_copy_triangles(m, ptr::null_mut(), 16), NULL);
        assert_eq!(psr_mesh_copy_densities(m, ptr::null_mut(), 16), NULL);
        assert_eq!(psr_mesh_depth(m, ptr::null_mut()), NULL);
        assert_eq!(psr_mesh_finest_depth(m, ptr::null_mut()), NULL);
        assert_eq!(
            psr_mesh_node_counts(m, nodes.as_mut_ptr(), 4, ptr::null_mut()),
            NULL
        );
        assert_eq!(psr_mesh_node_counts(m, ptr::null_mut(), 4, &mut z), NULL);
        assert_eq!(psr_mesh_solve_stats(m, 0, ptr::null_mut()), NULL);
        assert_eq!(z, 77);
        psr_mesh_free(m);

        psr_reconstructor_free(r);
    }
}

#[test]
fn new_handle_has_the_documented_defaults() {
    let r = new_handle();
    let defaults = psr::Params::default();
    unsafe {
        let (mut u, mut i, mut f, mut d) = (0u32, 0i32, 0f32, 0f64);
        assert_eq!(psr_reconstructor_get_depth(r, &mut u), psr_status::Ok);
        assert_eq!(u, defaults.depth);
        assert_eq!(psr_reconstructor_get_full_depth(r, &mut u), psr_status::Ok);
        assert_eq!(u, defaults.full_depth);
        assert_eq!(
            psr_reconstructor_get_min_component_samples(r, &mut u),
            psr_status::Ok
        );
        assert_eq!(u, defaults.min_component_samples);
        assert_eq!(
            psr_reconstructor_get_kernel_depth(r, &mut i),
            psr_status::Ok
        );
        assert_eq!(i, -1);
        assert_eq!(
            psr_reconstructor_get_samples_per_node(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(f, defaults.samples_per_node);
        assert_eq!(psr_reconstructor_get_scale(r, &mut f), psr_status::Ok);
        assert_eq!(f, defaults.scale);
        assert_eq!(
            psr_reconstructor_get_point_weight(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(f, defaults.point_weight);
        assert_eq!(psr_reconstructor_get_threads(r, &mut u), psr_status::Ok);
        assert_eq!(u as usize, defaults.threads);
        assert_eq!(
            psr_reconstructor_get_max_solver_iterations(r, &mut u),
            psr_status::Ok
        );
        assert_eq!(u, defaults.max_solver_iterations);
        assert_eq!(
            psr_reconstructor_get_solver_tolerance(r, &mut d),
            psr_status::Ok
        );
        assert_eq!(d, defaults.solver_tolerance);
        assert_eq!(psr_reconstructor_get_width(r, &mut d), psr_status::Ok);
        assert_eq!(
            (d, defaults.width),
            (0.0, None),
            "no width: the depth decides"
        );
        assert_eq!(point_count(r), 0);
        assert_eq!(last_error(r), "");
        psr_reconstructor_free(r);
    }
}

#[test]
fn setters_round_trip_and_reject_out_of_range_values_by_name() {
    let r = new_handle();
    unsafe {
        let (mut u, mut i, mut f, mut d) = (0u32, 0i32, 0f32, 0f64);
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_depth(r, &mut u), psr_status::Ok);
        assert_eq!(u, 6);
        assert_eq!(psr_reconstructor_set_full_depth(r, 2), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_full_depth(r, &mut u), psr_status::Ok);
        assert_eq!(u, 2);
        assert_eq!(
            psr_reconstructor_set_min_component_samples(r, 0),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_min_component_samples(r, &mut u),
            psr_status::Ok
        );
        assert_eq!(u, 0);
        assert_eq!(psr_reconstructor_set_kernel_depth(r, 4), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_get_kernel_depth(r, &mut i),
            psr_status::Ok
        );
        assert_eq!(i, 4);
        assert_eq!(psr_reconstructor_set_kernel_depth(r, -7), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_get_kernel_depth(r, &mut i),
            psr_status::Ok
        );
        assert_eq!(i, -1);
        assert_eq!(
            psr_reconstructor_set_samples_per_node(r, 3.5),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_samples_per_node(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(f, 3.5);
        assert_eq!(psr_reconstructor_set_scale(r, 1.25), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_scale(r, &mut f), psr_status::Ok);
        assert_eq!(f, 1.25);
        assert_eq!(psr_reconstructor_set_point_weight(r, 0.0), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_get_point_weight(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(f, 0.0);
        // The degree: 2 by default; setting it sets the point weight to 2 × degree; a bad
        // degree is refused with its name and leaves both as they were.
        let mut deg = 0i32;
        assert_eq!(psr_reconstructor_get_degree(r, &mut deg), psr_status::Ok);
        assert_eq!(deg, 2);
        assert_eq!(psr_reconstructor_set_degree(r, 1), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_degree(r, &mut deg), psr_status::Ok);
        assert_eq!(deg, 1);
        assert_eq!(
            psr_reconstructor_get_point_weight(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(f, 2.0);
        for bad in [0, 3, 7, -1, 257, i32::MIN] {
            assert_eq!(
                psr_reconstructor_set_degree(r, bad),
                psr_status::InvalidParameter
            );
            assert!(last_error(r).contains("degree"), "{}", last_error(r));
        }
        assert_eq!(psr_reconstructor_get_degree(r, &mut deg), psr_status::Ok);
        assert_eq!(deg, 1, "a rejected degree leaves the degree as it was");
        assert_eq!(
            psr_reconstructor_get_point_weight(r, &mut f),
            psr_status::Ok
        );
        assert_eq!(
            f, 2.0,
            "a rejected degree leaves the point weight as it was"
        );
        assert_eq!(psr_reconstructor_set_degree(r, 2), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_point_weight(r, 0.0), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_threads(r, 2), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_threads(r, &mut u), psr_status::Ok);
        assert_eq!(u, 2);
        assert_eq!(
            psr_reconstructor_set_max_solver_iterations(r, 25),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_max_solver_iterations(r, &mut u),
            psr_status::Ok
        );
        assert_eq!(u, 25);
        assert_eq!(
            psr_reconstructor_set_solver_tolerance(r, 1e-7),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_solver_tolerance(r, &mut d),
            psr_status::Ok
        );
        assert_eq!(d, 1e-7);
        assert_eq!(psr_reconstructor_set_width(r, 0.25), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_width(r, &mut d), psr_status::Ok);
        assert_eq!(d, 0.25);
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                psr_reconstructor_set_width(r, bad),
                psr_status::InvalidParameter
            );
            assert!(last_error(r).contains("width"), "{}", last_error(r));
        }
        assert_eq!(psr_reconstructor_get_width(r, &mut d), psr_status::Ok);
        assert_eq!(d, 0.25, "a rejected width leaves the width as it was");
        assert_eq!(psr_reconstructor_set_width(r, 0.0), psr_status::Ok);
        assert_eq!(psr_reconstructor_get_width(r, &mut d), psr_status::Ok);
        assert_eq!(d, 0.0, "0 turns the width off");

        // Each bad value: INVALID_PARAMETER, a message naming the parameter, old value kept.
        let bad: [(psr_status, &str); 14] = [
            (psr_reconstructor_set_depth(r, 0), "depth"),
            (psr_reconstructor_set_depth(r, 17), "depth"),
            (psr_reconstructor_set_full_depth(r, 17), "full_depth"),
            (psr_reconstructor_set_kernel_depth(r, 17), "kernel_depth"),
            (
                psr_reconstructor_set_samples_per_node(r, 0.5),
                "samples_per_node",
            ),
            (
                psr_reconstructor_set_samples_per_node(r, f32::NAN),
                "samples_per_node",
            ),
            (psr_reconstructor_set_scale(r, 0.9), "scale"),
            (psr_reconstructor_set_scale(r, f32::INFINITY), "scale"),
            (psr_reconstructor_set_point_weight(r, -1.0), "point_weight"),
            (psr_reconstructor_set_threads(r, 5000), "threads"),
            (
                psr_reconstructor_set_max_solver_iterations(r, 0),
                "max_solver_iterations",
            ),
            (
                psr_reconstructor_set_solver_tolerance(r, 1.0),
                "solver_tolerance",
            ),
            (
                psr_reconstructor_set_solver_tolerance(r, 0.0),
                "solver_tolerance",
            ),
            (
                psr_reconstructor_set_solver_tolerance(r, f64::NAN),
                "solver_tolerance",
            ),
        ];
        // The calls above ran in order; check each status, then the last message.
        for (status, name) in bad {
            assert_eq!(status, psr_status::InvalidParameter, "{name}");
        }
        assert!(
            last_error(r).contains("solver_tolerance"),
            "{}",
            last_error(r)
        );
        assert_eq!(
            psr_reconstructor_set_depth(r, 99),
            psr_status::InvalidParameter
        );
        let message = last_error(r);
        assert!(
            message.contains("psr_reconstructor_set_depth") && message.contains("99"),
            "{message}"
        );
        assert_eq!(psr_reconstructor_get_depth(r, &mut u), psr_status::Ok);
        assert_eq!(u, 6, "a rejected value leaves the parameter as it was");
        assert_eq!(
            psr_reconstructor_get_solver_tolerance(r, &mut d),
            psr_status::Ok
        );
        assert_eq!(d, 1e-7);
        psr_reconstructor_free(r);
    }
}

#[test]
fn setters_work_in_any_order_and_solve_checks_that_they_agree() {
    let r = new_handle();
    add_sphere(r, 50);
    unsafe {
        // kernel_depth 10 is fine on its own even while depth is still the default 8 ...
        assert_eq!(psr_reconstructor_set_kernel_depth(r, 10), psr_status::Ok);
        // ... but solve refuses the combination, naming the parameter.
        let mut mesh = sentinel_ptr::<psr_mesh>();
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InvalidParameter
        );
        assert_eq!(mesh, sentinel_ptr(), "out-parameter untouched on failure");
        assert!(last_error(r).contains("kernel_depth"), "{}", last_error(r));
        // Raising depth afterwards makes it consistent.
        assert_eq!(psr_reconstructor_set_depth(r, 12), psr_status::Ok);
        assert_eq!(last_error(r), "", "a successful call clears the message");
        psr_reconstructor_free(r);
    }
}

#[test]
fn solve_before_any_points_is_empty_input() {
    let r = new_handle();
    let mut mesh = sentinel_ptr::<psr_mesh>();
    unsafe {
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::EmptyInput
        );
        assert_eq!(mesh, sentinel_ptr());
        assert!(
            last_error(r).contains("no input points"),
            "{}",
            last_error(r)
        );
        // After clear_points too.
        add_sphere(r, 10);
        assert_eq!(psr_reconstructor_clear_points(r), psr_status::Ok);
        assert_eq!(point_count(r), 0);
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::EmptyInput
        );
        assert_eq!(mesh, sentinel_ptr());
        psr_reconstructor_free(r);
    }
}

// ------------------------------------------------------------------------------------------------
// Points
// ------------------------------------------------------------------------------------------------

#[test]
fn a_bad_point_in_a_second_batch_rejects_that_batch_only_and_names_its_index() {
    let r = new_handle();
    add_sphere(r, 3);
    assert_eq!(point_count(r), 3);
    let (mut p, mut n) = sphere(5, [0.0; 3], 2.0);
    unsafe {
        // NaN position at index 2 of the second batch.
        p[2 * 3 + 1] = f32::NAN;
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 5),
            psr_status::NonFinitePosition
        );
        let message = last_error(r);
        assert!(message.contains("point 2"), "{message}");
        assert!(
            message.contains("nothing from this batch was added"),
            "{message}"
        );
        assert_eq!(
            point_count(r),
            3,
            "the first batch is kept, nothing of the second"
        );

        // Infinite position.
        p[2 * 3 + 1] = 0.0;
        p[4 * 3] = f32::NEG_INFINITY;
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 5),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("point 4"), "{}", last_error(r));
        p[4 * 3] = 0.5;

        // Non-finite normal at index 1.
        n[3 + 2] = f32::INFINITY;
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 5),
            psr_status::NonFiniteNormal
        );
        assert!(last_error(r).contains("normal 1"), "{}", last_error(r));
        n[3 + 2] = 1.0;

        // Zero normal at index 3.
        n[9..12].copy_from_slice(&[0.0, 0.0, 0.0]);
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 5),
            psr_status::ZeroNormal
        );
        assert!(last_error(r).contains("normal 3"), "{}", last_error(r));
        assert_eq!(point_count(r), 3);

        // Fixed, the batch goes in whole.
        n[9..12].copy_from_slice(&[0.0, 0.0, -3.0]);
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 5),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 8);
        assert_eq!(last_error(r), "");
        psr_reconstructor_free(r);
    }
}

#[test]
fn interleaved_strides_are_read_and_bad_strides_refused() {
    #[repr(C)]
    struct Vertex {
        position: [f32; 3],
        colour: [u8; 4],
        normal: [f32; 3],
    }
    let vertices: Vec<Vertex> = (0..4)
        .map(|i| Vertex {
            position: [i as f32, 0.0, 0.0],
            colour: [0; 4],
            normal: [0.0, 0.0, 1.0],
        })
        .collect();
    let stride = std::mem::size_of::<Vertex>();
    let r = new_handle();
    unsafe {
        let base = vertices.as_ptr();
        let pos = ptr::addr_of!((*base).position).cast::<f32>();
        let nrm = ptr::addr_of!((*base).normal).cast::<f32>();
        assert_eq!(
            psr_reconstructor_add_points(r, pos, stride, nrm, stride, 4),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 4);

        // A NaN in the interleaved array is found at the right index.
        let mut bad: Vec<Vertex> = (0..4)
            .map(|i| Vertex {
                position: [i as f32, 0.0, 0.0],
                colour: [0; 4],
                normal: [1.0, 0.0, 0.0],
            })
            .collect();
        bad[3].normal[1] = f32::NAN;
        let base = bad.as_ptr();
        let pos = ptr::addr_of!((*base).position).cast::<f32>();
        let nrm = ptr::addr_of!((*base).normal).cast::<f32>();
        assert_eq!(
            psr_reconstructor_add_points(r, pos, stride, nrm, stride, 4),
            psr_status::NonFiniteNormal
        );
        assert!(last_error(r).contains("normal 3"), "{}", last_error(r));

        // Strides shorter than one element.
        let p = [0.0f32; 12];
        let n = [1.0f32; 12];
        for short in [1usize, 4, 8, 11] {
            assert_eq!(
                psr_reconstructor_add_points(r, p.as_ptr(), short, n.as_ptr(), 0, 2),
                psr_status::InvalidArgument
            );
            assert!(
                last_error(r).contains("position_stride_bytes"),
                "{}",
                last_error(r)
            );
            assert_eq!(
                psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), short, 2),
                psr_status::InvalidArgument
            );
            assert!(
                last_error(r).contains("normal_stride_bytes"),
                "{}",
                last_error(r)
            );
        }
        assert_eq!(point_count(r), 4);
        psr_reconstructor_free(r);
    }
}

#[test]
fn counts_whose_byte_length_overflows_are_refused_before_any_read() {
    let r = new_handle();
    // Dangling pointers: reading them would crash, so passing proves nothing is read.
    let p = sentinel_ptr::<f32>();
    unsafe {
        for (count, stride) in [
            (usize::MAX, 0),
            (usize::MAX / 8, 12),
            (usize::MAX / 24 + 2, 24),
            (3, usize::MAX),
        ] {
            assert_eq!(
                psr_reconstructor_add_points(r, p, stride, p, 0, count),
                psr_status::InvalidArgument,
                "count {count} stride {stride}"
            );
            assert!(
                last_error(r).contains("more bytes than memory can hold"),
                "{}",
                last_error(r)
            );
        }
        assert_eq!(point_count(r), 0);
        psr_reconstructor_free(r);
    }
}

// ------------------------------------------------------------------------------------------------
// Mesh functions (on a known mesh; no core needed)
// ------------------------------------------------------------------------------------------------

#[test]
fn mesh_views_and_copies_on_a_known_mesh() {
    let m = tetrahedron();
    unsafe {
        assert_eq!(psr_mesh_vertex_count(m), 4);
        assert_eq!(psr_mesh_triangle_count(m), 4);
        assert_eq!(psr_mesh_isovalue(m), 0.5);
        let pos = std::slice::from_raw_parts(psr_mesh_positions(m), 12);
        assert_eq!(&pos[3..6], &[1.0, 0.0, 0.0]);
        let tri = std::slice::from_raw_parts(psr_mesh_triangles(m), 12);
        assert_eq!(&tri[9..12], &[1, 2, 3]);
        let den = std::slice::from_raw_parts(psr_mesh_densities(m), 4);
        assert_eq!(den, &[1.0, 2.0, 3.0, 4.0]);

        let mut fbuf = [0.0f32; 12];
        let mut ubuf = [0u32; 12];
        assert_eq!(
            psr_mesh_copy_positions(m, fbuf.as_mut_ptr(), 12),
            psr_status::Ok
        );
        assert_eq!(&fbuf[..], pos);
        assert_eq!(
            psr_mesh_copy_triangles(m, ubuf.as_mut_ptr(), 12),
            psr_status::Ok
        );
        assert_eq!(&ubuf[..], tri);
        let mut dbuf = [0.0f32; 4];
        assert_eq!(
            psr_mesh_copy_densities(m, dbuf.as_mut_ptr(), 4),
            psr_status::Ok
        );
        assert_eq!(&dbuf[..], den);
        psr_mesh_free(m);
    }
}

#[test]
fn short_copy_out_buffers_are_refused_and_left_untouched() {
    let m = tetrahedron();
    unsafe {
        let mut fbuf = [-7.0f32; 12];
        let mut ubuf = [777u32; 12];
        for capacity in [0, 1, 11] {
            assert_eq!(
                psr_mesh_copy_positions(m, fbuf.as_mut_ptr(), capacity),
                psr_status::BufferTooSmall
            );
            assert_eq!(
                psr_mesh_copy_triangles(m, ubuf.as_mut_ptr(), capacity),
                psr_status::BufferTooSmall
            );
        }
        assert_eq!(
            psr_mesh_copy_densities(m, fbuf.as_mut_ptr(), 3),
            psr_status::BufferTooSmall
        );
        assert!(
            fbuf.iter().all(|&v| v == -7.0),
            "nothing written on BUFFER_TOO_SMALL"
        );
        assert!(ubuf.iter().all(|&v| v == 777));
        // A larger buffer is fine; the tail is not touched.
        let mut big = [-7.0f32; 20];
        assert_eq!(
            psr_mesh_copy_positions(m, big.as_mut_ptr(), 20),
            psr_status::Ok
        );
        assert!(big[12..].iter().all(|&v| v == -7.0));
        psr_mesh_free(m);
    }
}

#[test]
fn an_empty_mesh_has_null_views_and_accepts_null_destinations() {
    let m = debug_mesh_new(psr::Mesh::default());
    unsafe {
        assert_eq!(psr_mesh_vertex_count(m), 0);
        assert!(psr_mesh_positions(m).is_null());
        assert!(psr_mesh_triangles(m).is_null());
        assert!(psr_mesh_densities(m).is_null());
        assert_eq!(
            psr_mesh_copy_positions(m, ptr::null_mut(), 0),
            psr_status::Ok
        );
        assert_eq!(
            psr_mesh_copy_triangles(m, ptr::null_mut(), 0),
            psr_status::Ok
        );
        assert_eq!(
            psr_mesh_copy_densities(m, ptr::null_mut(), 0),
            psr_status::Ok
        );
        psr_mesh_free(m);
    }
}

// ------------------------------------------------------------------------------------------------
// Panics, statuses, versions
// ------------------------------------------------------------------------------------------------

#[test]
fn a_forced_internal_panic_is_internal_error_then_the_handle_is_poisoned() {
    let r = new_handle();
    add_sphere(r, 20);
    unsafe {
        debug_panic_next_solve(r);
        let mut mesh = sentinel_ptr::<psr_mesh>();
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InternalError
        );
        assert_eq!(mesh, sentinel_ptr(), "out-parameter untouched");
        let message = last_error(r);
        assert!(
            message.contains("panic") && message.contains("test hook"),
            "{message}"
        );

        // Everything but last_error and free is refused now.
        let poisoned = psr_status::HandlePoisoned;
        let (mut u, mut i, mut f, mut d, mut z) = (5u32, 5i32, 5f32, 5f64, 5usize);
        let p = [0.0f32, 0.0, 0.0];
        let n = [0.0f32, 0.0, 1.0];
        assert_eq!(psr_reconstructor_solve(r, &mut mesh), poisoned);
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, 1),
            poisoned
        );
        assert_eq!(psr_reconstructor_point_count(r, &mut z), poisoned);
        assert_eq!(psr_reconstructor_clear_points(r), poisoned);
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, None, ptr::null_mut()),
            poisoned
        );
        assert_eq!(psr_reconstructor_set_depth(r, 5), poisoned);
        assert_eq!(psr_reconstructor_get_depth(r, &mut u), poisoned);
        assert_eq!(psr_reconstructor_set_full_depth(r, 5), poisoned);
        assert_eq!(psr_reconstructor_get_full_depth(r, &mut u), poisoned);
        assert_eq!(psr_reconstructor_set_kernel_depth(r, 5), poisoned);
        assert_eq!(psr_reconstructor_get_kernel_depth(r, &mut i), poisoned);
        assert_eq!(psr_reconstructor_set_samples_per_node(r, 2.0), poisoned);
        assert_eq!(psr_reconstructor_get_samples_per_node(r, &mut f), poisoned);
        assert_eq!(psr_reconstructor_set_scale(r, 2.0), poisoned);
        assert_eq!(psr_reconstructor_get_scale(r, &mut f), poisoned);
        assert_eq!(psr_reconstructor_set_point_weight(r, 2.0), poisoned);
        assert_eq!(psr_reconstructor_get_point_weight(r, &mut f), poisoned);
        assert_eq!(psr_reconstructor_set_threads(r, 1), poisoned);
        assert_eq!(psr_reconstructor_get_threads(r, &mut u), poisoned);
        assert_eq!(psr_reconstructor_set_max_solver_iterations(r, 5), poisoned);
        assert_eq!(
            psr_reconstructor_get_max_solver_iterations(r, &mut u),
            poisoned
        );
        assert_eq!(psr_reconstructor_set_solver_tolerance(r, 1e-3), poisoned);
        assert_eq!(psr_reconstructor_get_solver_tolerance(r, &mut d), poisoned);
        assert_eq!(
            (u, i, f, d, z),
            (5, 5, 5.0, 5.0, 5),
            "out-parameters untouched"
        );
        assert_eq!(mesh, sentinel_ptr());
        // The message still tells the original cause.
        let message = last_error(r);
        assert!(
            message.contains("refused") && message.contains("test hook"),
            "{message}"
        );
        psr_reconstructor_free(r);
    }
    // Other handles are unaffected.
    let other = new_handle();
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(other, 5), psr_status::Ok);
        psr_reconstructor_free(other);
    }
}

#[test]
fn status_strings_take_any_int() {
    let name = |s: i32| {
        unsafe { CStr::from_ptr(psr_status_string(s)) }
            .to_str()
            .unwrap()
    };
    assert_eq!(name(0), "PSR_STATUS_OK");
    assert_eq!(
        name(psr_status::BufferTooSmall as i32),
        "PSR_STATUS_BUFFER_TOO_SMALL"
    );
    assert_eq!(name(11), "PSR_STATUS_INTERNAL_ERROR");
    assert_eq!(name(12), "PSR_STATUS_THREADS_UNAVAILABLE");
    assert_eq!(name(13), "PSR_STATUS_NON_FINITE_ATTRIBUTE");
    assert_eq!(name(14), "PSR_STATUS_INVALID_WEIGHT");
    assert_eq!(name(15), "PSR_STATUS_INVALID_TRANSFORM");
    assert_eq!(name(16), "PSR_STATUS_TOO_LARGE");
    assert_eq!(name(17), "PSR_STATUS_OUT_OF_MEMORY");
    assert_eq!(name(18), "PSR_STATUS_IO_ERROR");
    assert_eq!(name(19), "PSR_STATUS_INVALID_FILE");
    assert_eq!(name(20), "PSR_STATUS_UNKNOWN");
    assert_eq!(name(-1), "PSR_STATUS_UNKNOWN");
    assert_eq!(name(i32::MIN), "PSR_STATUS_UNKNOWN");
}

/// Proves: psr_stage_string names every stage by psr_stage's numbers (density before octree),
/// agrees with the Rust names, and takes any int.
#[test]
fn stage_strings_name_each_stage_and_take_any_int() {
    let name = |s: i32| {
        let p = psr_stage_string(s);
        assert!(!p.is_null(), "psr_stage_string never returns NULL");
        unsafe { CStr::from_ptr(p) }.to_str().unwrap()
    };
    let expected = [
        (psr_stage::Points, "points"),
        (psr_stage::Density, "density"),
        (psr_stage::Octree, "octree"),
        (psr_stage::Splat, "splat"),
        (psr_stage::System, "system"),
        (psr_stage::Solve, "solve"),
        (psr_stage::Isovalue, "isovalue"),
        (psr_stage::Extract, "extract"),
        (psr_stage::Mesh, "mesh"),
        (psr_stage::Normals, "normals"),
        (psr_stage::Trim, "trim"),
    ];
    for (stage, text) in expected {
        assert_eq!(name(stage as i32), text, "{stage:?}");
    }
    for stage in psr::Stage::ALL {
        assert_eq!(name(stage as i32), stage.name());
    }
    for unknown in [-1, 11, i32::MAX, i32::MIN] {
        assert_eq!(name(unknown), "unknown");
    }
}

#[test]
fn status_numbers_are_stable() {
    // These numbers are ABI: never change or reuse one.
    let expected = [
        (psr_status::Ok, 0),
        (psr_status::NullArgument, 1),
        (psr_status::InvalidArgument, 2),
        (psr_status::EmptyInput, 3),
        (psr_status::NonFinitePosition, 4),
        (psr_status::NonFiniteNormal, 5),
        (psr_status::ZeroNormal, 6),
        (psr_status::InvalidParameter, 7),
        (psr_status::Cancelled, 8),
        (psr_status::BufferTooSmall, 9),
        (psr_status::HandlePoisoned, 10),
        (psr_status::InternalError, 11),
        (psr_status::ThreadsUnavailable, 12),
        (psr_status::NonFiniteAttribute, 13),
        (psr_status::InvalidWeight, 14),
        (psr_status::InvalidTransform, 15),
        (psr_status::TooLarge, 16),
        (psr_status::OutOfMemory, 17),
    ];
    for (status, number) in expected {
        assert_eq!(status as i32, number, "{status:?}");
    }
    assert_eq!(
        std::mem::size_of::<psr_status>(),
        std::mem::size_of::<std::ffi::c_int>()
    );
}

#[test]
fn version_functions_agree_with_the_crate() {
    let v = unsafe { CStr::from_ptr(psr_version()) }.to_str().unwrap();
    assert_eq!(v, env!("CARGO_PKG_VERSION"));
    assert_eq!(
        psr_version_major().to_string(),
        env!("CARGO_PKG_VERSION_MAJOR")
    );
    assert_eq!(
        psr_version_minor().to_string(),
        env!("CARGO_PKG_VERSION_MINOR")
    );
    assert_eq!(
        psr_version_patch().to_string(),
        env!("CARGO_PKG_VERSION_PATCH")
    );
    assert_eq!(
        (PSR_VERSION_MAJOR, PSR_VERSION_MINOR, PSR_VERSION_PATCH),
        (
            psr_version_major(),
            psr_version_minor(),
            psr_version_patch()
        )
    );
}

// ------------------------------------------------------------------------------------------------
// With the core: real meshes, progress, cancellation, threads
// ------------------------------------------------------------------------------------------------

#[derive(Default)]
struct Recorder {
    calls: usize,
    stages: Vec<psr_stage>,
    /// psr_stage_string of each entry of `stages`, asked from inside the callback.
    names: Vec<String>,
    threads: Vec<std::thread::ThreadId>,
    bad_fractions: usize,
    /// Return false on this call (1-based); 0 = never.
    cancel_on_call: usize,
    /// Handle to poke from inside the callback (reentrancy check).
    reenter: *mut psr_reconstructor,
    reentry_statuses: Vec<psr_status>,
}

unsafe extern "C" fn record(user: *mut c_void, stage: psr_stage, fraction: f32) -> bool {
    let rec = &mut *user.cast::<Recorder>();
    rec.calls += 1;
    if rec.stages.last() != Some(&stage) {
        rec.stages.push(stage);
        let name = CStr::from_ptr(psr_stage_string(stage as i32));
        rec.names.push(name.to_str().unwrap().to_owned());
    }
    rec.threads.push(std::thread::current().id());
    if !(0.0..=1.0).contains(&fraction) {
        rec.bad_fractions += 1;
    }
    if !rec.reenter.is_null() {
        let mut n = 0usize;
        rec.reentry_statuses
            .push(psr_reconstructor_point_count(rec.reenter, &mut n));
        rec.reentry_statuses
            .push(psr_reconstructor_set_depth(rec.reenter, 3));
        psr_reconstructor_free(rec.reenter); // must do nothing
    }
    rec.cancel_on_call == 0 || rec.calls < rec.cancel_on_call
}

/// Positions, triangles, densities and the isovalue's bits of a mesh.
type MeshArrays = (Vec<f32>, Vec<u32>, Vec<f32>, u64);

fn mesh_arrays(m: *const psr_mesh) -> MeshArrays {
    unsafe {
        let (nv, nt) = (psr_mesh_vertex_count(m), psr_mesh_triangle_count(m));
        let mut p = vec![0.0f32; 3 * nv];
        let mut t = vec![0u32; 3 * nt];
        let mut d = vec![0.0f32; nv];
        assert_eq!(
            psr_mesh_copy_positions(m, p.as_mut_ptr(), p.len()),
            psr_status::Ok
        );
        assert_eq!(
            psr_mesh_copy_triangles(m, t.as_mut_ptr(), t.len()),
            psr_status::Ok
        );
        assert_eq!(
            psr_mesh_copy_densities(m, d.as_mut_ptr(), d.len()),
            psr_status::Ok
        );
        (p, t, d, psr_mesh_isovalue(m).to_bits())
    }
}

/// Proves: the figures a host reads through the C API are the Rust `Stats`: the depth used
/// (here chosen by a width), the finest depth, the nodes per depth (a count query, a short
/// buffer refused untouched) and every solve (an unset struct_size and an index past the end
/// refused untouched); a mesh no reconstruction made reports none.
#[test]
fn mesh_figures_are_the_reconstructions_stats() {
    let r = new_handle();
    let (p, nrm) = sphere(3000, [0.1, -0.2, 0.3], 1.0);
    let points =
        psr::PointSet::from_slices(triples(&p).as_slice(), triples(&nrm).as_slice()).unwrap();
    // Cube side about 2.2: a width of 0.05 needs 2^d >= 44, depth 6.
    let params = psr::Params::default().with_width(Some(0.05));
    let want = psr::reconstruct(&points, &params).unwrap().stats;
    assert_eq!(want.depth, 6);
    unsafe {
        assert_eq!(psr_reconstructor_set_width(r, 0.05), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, nrm.as_ptr(), 0, 3000),
            psr_status::Ok
        );
    }
    let Some(m) = solve_or_skip(r, "mesh_figures_are_the_reconstructions_stats") else {
        unsafe { psr_reconstructor_free(r) };
        return;
    };
    unsafe {
        psr_reconstructor_free(r);
        let (mut depth, mut finest) = (0u32, 0u32);
        assert_eq!(psr_mesh_depth(m, &mut depth), psr_status::Ok);
        assert_eq!(psr_mesh_finest_depth(m, &mut finest), psr_status::Ok);
        assert_eq!((depth, finest), (want.depth, want.finest_depth()));

        let mut count = 0usize;
        assert_eq!(
            psr_mesh_node_counts(m, ptr::null_mut(), 0, &mut count),
            psr_status::Ok
        );
        assert_eq!(count, finest as usize + 1);
        let mut short = vec![7u64; count - 1];
        let mut unchanged = 99usize;
        assert_eq!(
            psr_mesh_node_counts(m, short.as_mut_ptr(), short.len(), &mut unchanged),
            psr_status::BufferTooSmall
        );
        assert!(short.iter().all(|&n| n == 7) && unchanged == 99);
        let mut nodes = vec![0u64; count + 2];
        assert_eq!(
            psr_mesh_node_counts(m, nodes.as_mut_ptr(), nodes.len(), &mut count),
            psr_status::Ok
        );
        let want_nodes: Vec<u64> = want.nodes_per_depth.iter().map(|&n| n as u64).collect();
        assert_eq!(&nodes[..count], &want_nodes[..]);
        assert_eq!(&nodes[count..], &[0, 0], "nothing past the entries");

        let solves = psr_mesh_solve_count(m);
        assert_eq!(solves, want.solves.len());
        assert!(solves > 0);
        let size = std::mem::size_of::<psr_depth_solve>();
        for (k, w) in want.solves.iter().enumerate() {
            let mut s = psr_depth_solve {
                struct_size: size,
                depth: 0,
                iterations: 0,
                unknowns: 0,
                relative_residual: 0.0,
                seconds: 0.0,
            };
            assert_eq!(psr_mesh_solve_stats(m, k, &mut s), psr_status::Ok);
            assert_eq!(s.struct_size, size, "left as the caller set it");
            assert_eq!(
                (s.depth, s.unknowns, s.iterations),
                (w.depth, w.unknowns as u64, w.iterations)
            );
            // Same input, same parameters: the same residual bit for bit; timings differ.
            assert_eq!(s.relative_residual, w.relative_residual);
            assert!(s.seconds >= 0.0 && s.seconds.is_finite());
        }
        let sentinel = psr_depth_solve {
            struct_size: size,
            depth: 5,
            iterations: 5,
            unknowns: 5,
            relative_residual: 5.0,
            seconds: 5.0,
        };
        let mut s = sentinel;
        assert_eq!(
            psr_mesh_solve_stats(m, solves, &mut s),
            psr_status::InvalidArgument
        );
        assert_eq!(s, sentinel, "an index past the end writes nothing");
        for bad in [0, 8, size - 1, 1 << 20] {
            s.struct_size = bad;
            assert_eq!(
                psr_mesh_solve_stats(m, 0, &mut s),
                psr_status::InvalidArgument,
                "struct_size {bad}"
            );
            assert_eq!(
                (s.depth, s.unknowns),
                (5, 5),
                "a refused size writes nothing"
            );
        }
        // A newer header's larger struct: the fields this library does not know are zeroed.
        #[repr(C)]
        struct Newer {
            known: psr_depth_solve,
            later: [u64; 2],
        }
        let mut newer = Newer {
            known: sentinel,
            later: [0xABAB; 2],
        };
        newer.known.struct_size = std::mem::size_of::<Newer>();
        assert_eq!(psr_mesh_solve_stats(m, 0, &mut newer.known), psr_status::Ok);
        assert_eq!(newer.known.depth, want.solves[0].depth);
        assert_eq!(newer.later, [0, 0]);
        psr_mesh_free(m);

        // A mesh no reconstruction made: depth 0, no nodes, no solves.
        let t = tetrahedron();
        assert_eq!(psr_mesh_depth(t, &mut depth), psr_status::Ok);
        assert_eq!(depth, 0);
        assert_eq!(
            psr_mesh_node_counts(t, ptr::null_mut(), 0, &mut count),
            psr_status::Ok
        );
        assert_eq!(count, 0);
        assert_eq!(psr_mesh_solve_count(t), 0);
        assert_eq!(
            psr_mesh_solve_stats(t, 0, &mut s),
            psr_status::InvalidArgument
        );
        psr_mesh_free(t);
    }
}

/// Flat x y z floats as triples.
fn triples(flat: &[f32]) -> Vec<[f32; 3]> {
    flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}

#[test]
fn solve_gives_a_mesh_that_outlives_its_reconstructor() {
    let r = new_handle();
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
    }
    add_sphere(r, 2000);
    let Some(m) = solve_or_skip(r, "solve_gives_a_mesh_that_outlives_its_reconstructor") else {
        unsafe { psr_reconstructor_free(r) };
        return;
    };
    unsafe {
        assert_eq!(last_error(r), "");
        assert_eq!(point_count(r), 2000, "solve keeps the points");
        psr_reconstructor_free(r);
        let (nv, nt) = (psr_mesh_vertex_count(m), psr_mesh_triangle_count(m));
        assert!(nv > 100 && nt > 100, "{nv} vertices, {nt} triangles");
        assert!(psr_mesh_isovalue(m).is_finite());
        // Borrowed views agree with the copies, after the reconstructor is gone.
        let (p, t, d, _) = mesh_arrays(m);
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_positions(m), 3 * nv),
            &p[..]
        );
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_triangles(m), 3 * nt),
            &t[..]
        );
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_densities(m), nv),
            &d[..]
        );
        assert!(t.iter().all(|&i| (i as usize) < nv));
        // Vertices lie near the unit sphere around the centre.
        for v in p.chunks(3) {
            let rad = ((v[0] - 0.1).powi(2) + (v[1] + 0.2).powi(2) + (v[2] - 0.3).powi(2)).sqrt();
            assert!((rad - 1.0).abs() < 0.15, "vertex at radius {rad}");
        }
        // Short buffers on a real mesh.
        let mut short = vec![0.0f32; 3 * nv - 1];
        assert_eq!(
            psr_mesh_copy_positions(m, short.as_mut_ptr(), short.len()),
            psr_status::BufferTooSmall
        );
        assert!(short.iter().all(|&v| v == 0.0));
        let mut short_t = vec![0u32; 3 * nt - 1];
        assert_eq!(
            psr_mesh_copy_triangles(m, short_t.as_mut_ptr(), short_t.len()),
            psr_status::BufferTooSmall
        );
        let mut short_d = vec![0.0f32; nv - 1];
        assert_eq!(
            psr_mesh_copy_densities(m, short_d.as_mut_ptr(), short_d.len()),
            psr_status::BufferTooSmall
        );
        psr_mesh_free(m);
    }
}

#[test]
fn progress_runs_on_the_calling_thread_through_the_stages_in_order() {
    let r = new_handle();
    let mut rec = Recorder::default();
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_threads(r, 2), psr_status::Ok);
        let user = ptr::addr_of_mut!(rec).cast::<c_void>();
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, Some(record), user),
            psr_status::Ok
        );
    }
    add_sphere(r, 1000);
    let Some(m) = solve_or_skip(
        r,
        "progress_runs_on_the_calling_thread_through_the_stages_in_order",
    ) else {
        unsafe { psr_reconstructor_free(r) };
        return;
    };
    unsafe {
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
    assert!(rec.calls > 0, "the callback was called");
    let me = std::thread::current().id();
    assert!(
        rec.threads.iter().all(|&t| t == me),
        "every call on the thread that called solve"
    );
    assert_eq!(rec.bad_fractions, 0, "fractions within [0, 1]");
    // Each stage is reported in one stretch (the pipeline never goes back to a stage), from
    // PSR_STAGE_POINTS to PSR_STAGE_MESH. (The core may order some stages differently from the
    // enum's numbering, e.g. density before octree.)
    let mut seen = rec.stages.clone();
    seen.sort_by_key(|&s| s as u32);
    seen.dedup();
    assert_eq!(
        seen.len(),
        rec.stages.len(),
        "a stage was reported in two stretches: {:?}",
        rec.stages
    );
    assert_eq!(
        rec.stages.first(),
        Some(&psr_stage::Points),
        "{:?}",
        rec.stages
    );
    assert_eq!(
        rec.stages.last(),
        Some(&psr_stage::Mesh),
        "{:?}",
        rec.stages
    );
    // psr_stage_string works from inside the callback and names the stages reported.
    assert_eq!(rec.names.len(), rec.stages.len());
    assert_eq!(rec.names.first().map(String::as_str), Some("points"));
    assert_eq!(rec.names.last().map(String::as_str), Some("mesh"));
    assert!(!rec.names.iter().any(|n| n == "unknown"), "{:?}", rec.names);
}

/// What `stop_inside` saw: it says stop at the first call reporting `stage` below 1 (the
/// stage still running).
struct StopInside {
    stage: psr_stage,
    stopped_at: Option<f32>,
    calls_after_stop: usize,
}

unsafe extern "C" fn stop_inside(user: *mut c_void, stage: psr_stage, fraction: f32) -> bool {
    let s = &mut *user.cast::<StopInside>();
    if s.stopped_at.is_some() {
        s.calls_after_stop += 1;
        return false;
    }
    if stage == s.stage && fraction < 1.0 {
        s.stopped_at = Some(fraction);
        return false;
    }
    true
}

/// Proves (issue 18): a C host's callback is called inside the extraction and the solve, not
/// only between stages, and a stop there returns PSR_STATUS_CANCELLED with no mesh and no
/// further call; the same handle then solves again to the mesh a fresh handle makes, bit for
/// bit. (100,000 points at depth 8: each of these stages lasts far longer than the 20 ms
/// between calls.)
#[test]
fn a_stop_inside_a_long_stage_cancels_and_the_handle_solves_the_same_after() {
    let setup = |r: *mut psr_reconstructor| unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 8), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_threads(r, 2), psr_status::Ok);
        add_sphere(r, 100_000);
    };
    let fresh = new_handle();
    setup(fresh);
    let Some(m) = solve_or_skip(fresh, "a_stop_inside_a_long_stage_cancels") else {
        unsafe { psr_reconstructor_free(fresh) };
        return;
    };
    let want = mesh_arrays(m);
    unsafe {
        psr_mesh_free(m);
        psr_reconstructor_free(fresh);
    }
    let r = new_handle();
    setup(r);
    for stage in [psr_stage::Solve, psr_stage::Extract] {
        let mut s = StopInside {
            stage,
            stopped_at: None,
            calls_after_stop: 0,
        };
        let mut mesh = sentinel_ptr::<psr_mesh>();
        let status = unsafe {
            let user = ptr::addr_of_mut!(s).cast::<c_void>();
            assert_eq!(
                psr_reconstructor_set_progress_callback(r, Some(stop_inside), user),
                psr_status::Ok
            );
            psr_reconstructor_solve(r, &mut mesh)
        };
        assert_eq!(
            status,
            psr_status::Cancelled,
            "{stage:?}: {}",
            last_error(r)
        );
        assert_eq!(mesh, sentinel_ptr(), "no mesh on cancellation");
        let fraction = s.stopped_at.expect("the stage was reported while it ran");
        assert!((0.0..1.0).contains(&fraction), "{stage:?}: {fraction}");
        assert_eq!(s.calls_after_stop, 0, "{stage:?}: called after the stop");
    }
    unsafe {
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, None, ptr::null_mut()),
            psr_status::Ok
        );
        let mut m = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_solve(r, &mut m),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        assert!(mesh_arrays(m) == want, "the mesh after the cancels differs");
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
}

#[test]
fn returning_false_from_the_callback_cancels() {
    for cancel_on_call in [1, 3] {
        let r = new_handle();
        let mut rec = Recorder {
            cancel_on_call,
            ..Default::default()
        };
        unsafe {
            assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
            let user = ptr::addr_of_mut!(rec).cast::<c_void>();
            assert_eq!(
                psr_reconstructor_set_progress_callback(r, Some(record), user),
                psr_status::Ok
            );
        }
        add_sphere(r, 1000);
        let mut mesh = sentinel_ptr::<psr_mesh>();
        let status = unsafe { psr_reconstructor_solve(r, &mut mesh) };
        if status == psr_status::InternalError && last_error(r).contains(PLACEHOLDER) {
            eprintln!("SKIP returning_false_from_the_callback_cancels: the reconstruction core is not in yet");
            unsafe { psr_reconstructor_free(r) };
            return;
        }
        assert_eq!(status, psr_status::Cancelled, "{}", last_error(r));
        assert_eq!(mesh, sentinel_ptr(), "no mesh on cancellation");
        assert_eq!(
            rec.calls, cancel_on_call,
            "no callback after the one that said stop"
        );
        assert!(last_error(r).contains("cancelled"), "{}", last_error(r));
        // The handle is still usable: without the callback the same solve succeeds.
        unsafe {
            assert_eq!(
                psr_reconstructor_set_progress_callback(r, None, ptr::null_mut()),
                psr_status::Ok
            );
            assert_eq!(
                psr_reconstructor_solve(r, &mut mesh),
                psr_status::Ok,
                "{}",
                last_error(r)
            );
            psr_mesh_free(mesh);
            psr_reconstructor_free(r);
        }
    }
}

#[test]
fn calls_on_the_same_handle_from_inside_its_callback_are_refused() {
    let r = new_handle();
    let mut rec = Recorder {
        reenter: r,
        ..Default::default()
    };
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 4), psr_status::Ok);
        let user = ptr::addr_of_mut!(rec).cast::<c_void>();
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, Some(record), user),
            psr_status::Ok
        );
    }
    add_sphere(r, 500);
    let Some(m) = solve_or_skip(
        r,
        "calls_on_the_same_handle_from_inside_its_callback_are_refused",
    ) else {
        unsafe { psr_reconstructor_free(r) };
        return;
    };
    assert!(!rec.reentry_statuses.is_empty());
    assert!(
        rec.reentry_statuses
            .iter()
            .all(|&s| s == psr_status::InvalidArgument),
        "{:?}",
        rec.reentry_statuses
    );
    unsafe {
        let mut depth = 0;
        assert_eq!(psr_reconstructor_get_depth(r, &mut depth), psr_status::Ok);
        assert_eq!(depth, 4, "the refused set_depth changed nothing");
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
}

/// One complete run on its own handle, as a thread of a host application would do it.
fn run_once(points: usize, depth: u32, threads: u32) -> Option<MeshArrays> {
    let r = new_handle();
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, depth), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_threads(r, threads), psr_status::Ok);
    }
    add_sphere(r, points);
    let out = solve_or_skip(r, "two_handles_on_two_threads_match_sequential_runs").map(|m| {
        let arrays = mesh_arrays(m);
        unsafe { psr_mesh_free(m) };
        arrays
    });
    unsafe { psr_reconstructor_free(r) };
    out
}

#[test]
fn two_handles_on_two_threads_match_sequential_runs() {
    let Some(first) = run_once(1500, 5, 1) else {
        return;
    };
    let Some(second) = run_once(800, 5, 2) else {
        return;
    };
    let a = std::thread::spawn(|| run_once(1500, 5, 1));
    let b = std::thread::spawn(|| run_once(800, 5, 2));
    let (a, b) = (a.join().unwrap().unwrap(), b.join().unwrap().unwrap());
    assert!(
        a == first,
        "handle 1 on its own thread differs from the sequential run"
    );
    assert!(
        b == second,
        "handle 2 on its own thread differs from the sequential run"
    );
}

/// Proves: the boundary, splatting and vertex placement choices are set and read back as
/// integers (boundary: Neumann 0, free 1, Dirichlet 2), default to Neumann, B-spline and
/// fitted, and any other integer is refused with
/// INVALID_PARAMETER naming the parameter, leaving the value as it was.
#[test]
fn boundary_splatting_and_vertex_placement_choices_round_trip_and_reject_unknown_values() {
    let r = new_handle();
    unsafe {
        let mut v = -7i32;
        assert_eq!(psr_reconstructor_get_boundary(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_boundary::Neumann as i32);
        assert_eq!(psr_reconstructor_get_splatting(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_splatting::Bspline as i32);
        assert_eq!(
            psr_reconstructor_get_vertex_placement(r, &mut v),
            psr_status::Ok
        );
        assert_eq!(v, psr_vertex_placement::Fitted as i32);
        assert_eq!(
            psr_reconstructor_set_vertex_placement(r, psr_vertex_placement::OnIsosurface as i32),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_vertex_placement(r, &mut v),
            psr_status::Ok
        );
        assert_eq!(v, psr_vertex_placement::OnIsosurface as i32);
        assert_eq!(
            psr_reconstructor_set_boundary(r, psr_boundary::Free as i32),
            psr_status::Ok
        );
        assert_eq!(psr_reconstructor_get_boundary(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_boundary::Free as i32);
        // Dirichlet (added after the others, so its number is new and theirs unchanged).
        assert_eq!(
            (
                psr_boundary::Neumann as i32,
                psr_boundary::Free as i32,
                psr_boundary::Dirichlet as i32
            ),
            (0, 1, 2)
        );
        assert_eq!(
            psr_reconstructor_set_boundary(r, psr_boundary::Dirichlet as i32),
            psr_status::Ok
        );
        assert_eq!(psr_reconstructor_get_boundary(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_boundary::Dirichlet as i32);
        assert_eq!(
            psr_reconstructor_set_boundary(r, psr_boundary::Free as i32),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_set_splatting(r, psr_splatting::Trilinear as i32),
            psr_status::Ok
        );
        assert_eq!(psr_reconstructor_get_splatting(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_splatting::Trilinear as i32);
        // Each setter refuses the value with INVALID_PARAMETER and names its parameter.
        let refused = |status: psr_status, name: &str| {
            assert_eq!(status, psr_status::InvalidParameter, "{name}");
            assert!(last_error(r).contains(name), "{}", last_error(r));
        };
        for bad in [-1, 3, i32::MAX] {
            refused(psr_reconstructor_set_boundary(r, bad), "boundary");
        }
        for bad in [-1, 2, i32::MAX] {
            refused(psr_reconstructor_set_splatting(r, bad), "splatting");
            refused(
                psr_reconstructor_set_vertex_placement(r, bad),
                "vertex_placement",
            );
        }
        assert_eq!(
            psr_reconstructor_get_vertex_placement(r, &mut v),
            psr_status::Ok
        );
        assert_eq!(v, psr_vertex_placement::OnIsosurface as i32);
        assert_eq!(psr_reconstructor_get_boundary(r, &mut v), psr_status::Ok);
        assert_eq!(v, psr_boundary::Free as i32);
        assert_eq!(
            psr_reconstructor_set_boundary(ptr::null_mut(), 0),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_splatting(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_set_vertex_placement(ptr::null_mut(), 0),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_vertex_placement(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        psr_reconstructor_free(r);
    }
}

/// Six times the signed volume of a mesh handle's triangles: positive when they face outward.
fn signed_volume6(m: *const psr_mesh) -> f64 {
    unsafe {
        let (nv, nt) = (psr_mesh_vertex_count(m), psr_mesh_triangle_count(m));
        let v = std::slice::from_raw_parts(psr_mesh_positions(m), 3 * nv);
        let t = std::slice::from_raw_parts(psr_mesh_triangles(m), 3 * nt);
        t.chunks_exact(3)
            .map(|tri| {
                let p = |k: usize| {
                    let i = tri[k] as usize;
                    [v[3 * i] as f64, v[3 * i + 1] as f64, v[3 * i + 2] as f64]
                };
                let (a, b, c) = (p(0), p(1), p(2));
                a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0])
            })
            .sum()
    }
}

/// Proves: points added without normals are counted, cleared, checked like other points, and
/// reconstructed with estimated normals into an outward-facing closed mesh; too few of them for
/// the neighbour count is a clear error at solve.
#[test]
fn points_without_normals_are_estimated_at_solve() {
    let r = new_handle();
    let (p, _) = sphere(3000, [0.1, -0.2, 0.3], 1.0);
    unsafe {
        assert_eq!(
            psr_reconstructor_add_positions(r, ptr::null(), 0, 3),
            psr_status::NullArgument
        );
        let mut bad = p[..9].to_vec();
        bad[4] = f32::NAN;
        assert_eq!(
            psr_reconstructor_add_positions(r, bad.as_ptr(), 0, 3),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("1"), "{}", last_error(r));
        assert_eq!(point_count(r), 0);
        assert_eq!(
            psr_reconstructor_add_positions(r, p.as_ptr(), 0, 10),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 10);
        assert_eq!(
            psr_reconstructor_set_normal_neighbors(r, 20),
            psr_status::Ok
        );
        let mut mesh = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InvalidArgument
        );
        assert!(mesh.is_null());
        assert!(last_error(r).contains("neighbo"), "{}", last_error(r));
        assert_eq!(psr_reconstructor_clear_points(r), psr_status::Ok);
        assert_eq!(point_count(r), 0);
        assert_eq!(
            psr_reconstructor_add_positions(r, p.as_ptr(), 0, 3000),
            psr_status::Ok
        );
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        // A unit sphere: 6 × its volume is 8π; the mesh lies just inside the samples.
        let volume6 = signed_volume6(mesh);
        assert!(
            (volume6 / (8.0 * std::f64::consts::PI) - 1.0).abs() < 0.05,
            "6 × volume {volume6}: inside-out or wrong"
        );
        psr_mesh_free(mesh);
        psr_reconstructor_free(r);
    }
}

/// Proves: estimating the normals of points added without them is reported as
/// PSR_STAGE_NORMALS, first and in one stretch, on the calling thread, and a callback that says
/// stop there cancels the solve (no mesh, no further call) and leaves the handle usable.
#[test]
fn normal_estimation_reports_progress_first_and_can_be_cancelled() {
    let (p, _) = sphere(3000, [0.0, 0.0, 0.0], 1.0);
    for cancel_on_call in [0, 1, 2] {
        let r = new_handle();
        let mut rec = Recorder {
            cancel_on_call,
            ..Default::default()
        };
        let mut mesh = sentinel_ptr::<psr_mesh>();
        let status = unsafe {
            assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
            let user = ptr::addr_of_mut!(rec).cast::<c_void>();
            assert_eq!(
                psr_reconstructor_set_progress_callback(r, Some(record), user),
                psr_status::Ok
            );
            assert_eq!(
                psr_reconstructor_add_positions(r, p.as_ptr(), 0, 3000),
                psr_status::Ok
            );
            psr_reconstructor_solve(r, &mut mesh)
        };
        assert_eq!(
            rec.stages.first(),
            Some(&psr_stage::Normals),
            "{:?}",
            rec.stages
        );
        assert_eq!(rec.names.first().map(String::as_str), Some("normals"));
        assert_eq!(rec.bad_fractions, 0, "fractions within [0, 1]");
        let me = std::thread::current().id();
        assert!(rec.threads.iter().all(|&t| t == me));
        if cancel_on_call == 0 {
            assert_eq!(status, psr_status::Ok, "{}", last_error(r));
            assert_eq!(
                &rec.stages[..2],
                &[psr_stage::Normals, psr_stage::Points],
                "normals once, then the pipeline: {:?}",
                rec.stages
            );
            assert_eq!(rec.stages.last(), Some(&psr_stage::Mesh));
            unsafe { psr_mesh_free(mesh) };
        } else {
            assert_eq!(status, psr_status::Cancelled, "{}", last_error(r));
            assert_eq!(mesh, sentinel_ptr(), "no mesh on cancellation");
            assert_eq!(rec.calls, cancel_on_call, "no call after the stop");
            assert_eq!(rec.stages, [psr_stage::Normals]);
            // Still usable: without the callback the same solve succeeds.
            unsafe {
                assert_eq!(
                    psr_reconstructor_set_progress_callback(r, None, ptr::null_mut()),
                    psr_status::Ok
                );
                let mut mesh = ptr::null_mut();
                assert_eq!(
                    psr_reconstructor_solve(r, &mut mesh),
                    psr_status::Ok,
                    "{}",
                    last_error(r)
                );
                psr_mesh_free(mesh);
            }
        }
        unsafe { psr_reconstructor_free(r) };
    }
}

/// Proves: the estimation's settings have their documented defaults, keep their value when a
/// value is refused, a viewpoint selects the viewpoint orientation, and the reconstruction's
/// orientation and iteration count round-trip.
#[test]
fn normal_estimation_settings_round_trip_and_refuse_bad_values() {
    let r = new_handle();
    unsafe {
        let (mut k, mut o) = (0u32, -1i32);
        assert_eq!(
            psr_reconstructor_get_normal_neighbors(r, &mut k),
            psr_status::Ok
        );
        assert_eq!(k, psr::NormalEstimation::default().neighbors as u32);
        assert_eq!(
            psr_reconstructor_get_normal_orientation(r, &mut o),
            psr_status::Ok
        );
        assert_eq!(o, psr_orientation::Propagate as i32);
        for bad in [0, 1001] {
            assert_eq!(
                psr_reconstructor_set_normal_neighbors(r, bad),
                psr_status::InvalidParameter
            );
            assert!(last_error(r).contains("neighbors"), "{}", last_error(r));
        }
        assert_eq!(
            psr_reconstructor_set_normal_neighbors(r, 12),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_normal_neighbors(r, &mut k),
            psr_status::Ok
        );
        assert_eq!(k, 12);
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 1),
            psr_status::InvalidParameter,
            "viewpoint orientation before any viewpoint"
        );
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 7),
            psr_status::InvalidParameter
        );
        assert_eq!(
            psr_reconstructor_set_viewpoint(r, 0.0, f64::NAN, 1.0),
            psr_status::InvalidParameter
        );
        assert_eq!(
            psr_reconstructor_set_viewpoint(r, 0.0, 0.0, 10.0),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_normal_orientation(r, &mut o),
            psr_status::Ok
        );
        assert_eq!(o, psr_orientation::Viewpoint as i32);
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 0),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 1),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_normal_orientation(r, &mut o),
            psr_status::Ok
        );
        assert_eq!(o, psr_orientation::Viewpoint as i32);
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 3),
            psr_status::Ok
        );
        assert_eq!(orientation_of(r), psr_orientation::Reconstruction as i32);
        assert_eq!(
            psr_reconstructor_get_normal_reconstruction_iterations(r, &mut k),
            psr_status::Ok
        );
        assert_eq!(
            k,
            psr::NormalEstimation::default().reconstruction_iterations
        );
        for bad in [0, 1001] {
            assert_eq!(
                psr_reconstructor_set_normal_reconstruction_iterations(r, bad),
                psr_status::InvalidParameter
            );
            assert!(
                last_error(r).contains("reconstruction_iterations"),
                "{}",
                last_error(r)
            );
        }
        assert_eq!(
            psr_reconstructor_set_normal_reconstruction_iterations(r, 7),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_normal_reconstruction_iterations(r, &mut k),
            psr_status::Ok
        );
        assert_eq!(k, 7);
        assert_eq!(
            psr_reconstructor_set_normal_neighbors(ptr::null_mut(), 5),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_normal_orientation(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        psr_reconstructor_free(r);
    }
}

fn orientation_of(r: *const psr_reconstructor) -> i32 {
    let mut o = -1;
    assert_eq!(
        unsafe { psr_reconstructor_get_normal_orientation(r, &mut o) },
        psr_status::Ok
    );
    o
}

/// Proves: batches with sensors are checked whole (a NaN sensor or position, a short sensor
/// stride: nothing appended, orientation unchanged), select PSR_ORIENTATION_SENSORS, and that
/// orientation refuses at solve a cloud where some points without normals have no sensor,
/// naming the first; choosing another orientation sets the sensors aside.
#[test]
fn sensor_batches_are_checked_whole_and_every_unoriented_point_needs_a_sensor() {
    let r = new_handle();
    let (p, _) = sphere(1500, [0.1, -0.2, 0.3], 1.0);
    let outside = [0.0f32, 0.0, 10.0];
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
        let nan = [0.0f32, f32::NAN, 10.0];
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(r, p.as_ptr(), 0, 10, nan.as_ptr()),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("sensor"), "{}", last_error(r));
        let mut sensors = [0.0f32; 3 * 10];
        sensors[3 * 2 + 2] = f32::INFINITY;
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(r, p.as_ptr(), 0, sensors.as_ptr(), 0, 10),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("sensor 2"), "{}", last_error(r));
        sensors[3 * 2 + 2] = 0.0;
        let mut bad = p[..30].to_vec();
        bad[3 + 1] = f32::NAN;
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(
                r,
                bad.as_ptr(),
                0,
                sensors.as_ptr(),
                0,
                10
            ),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("point 1"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(r, p.as_ptr(), 0, sensors.as_ptr(), 8, 10),
            psr_status::InvalidArgument
        );
        assert!(
            last_error(r).contains("sensor_stride_bytes"),
            "{}",
            last_error(r)
        );
        assert_eq!(point_count(r), 0);
        assert_eq!(orientation_of(r), psr_orientation::Propagate as i32);

        // One scan seen from one sensor, then points with no sensor: refused at solve.
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(r, p.as_ptr(), 0, 1000, outside.as_ptr()),
            psr_status::Ok
        );
        assert_eq!(orientation_of(r), psr_orientation::Sensors as i32);
        assert_eq!(
            psr_reconstructor_add_positions(r, p[3000..].as_ptr(), 0, 500),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 1500);
        let mut mesh = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InvalidArgument
        );
        assert!(mesh.is_null());
        let message = last_error(r);
        assert!(
            message.contains("500 of the 1500") && message.contains("point 1000"),
            "{message}"
        );
        // Another orientation sets the sensors aside; selecting SENSORS again brings them back.
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, psr_orientation::Propagate as i32),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        psr_mesh_free(mesh);
        mesh = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, psr_orientation::Sensors as i32),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_set_normal_orientation(r, 4),
            psr_status::InvalidParameter
        );
        assert!(
            last_error(r).contains("PSR_ORIENTATION_SENSORS"),
            "{}",
            last_error(r)
        );
        assert_eq!(orientation_of(r), psr_orientation::Sensors as i32);
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InvalidArgument
        );

        // Cleared, the orientation stays; points without any sensor are refused too.
        assert_eq!(psr_reconstructor_clear_points(r), psr_status::Ok);
        assert_eq!(orientation_of(r), psr_orientation::Sensors as i32);
        assert_eq!(
            psr_reconstructor_add_positions(r, p.as_ptr(), 0, 1500),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::InvalidArgument
        );
        assert!(
            last_error(r).contains("none of the 1500"),
            "{}",
            last_error(r)
        );
        assert!(mesh.is_null());
        psr_reconstructor_free(r);
    }
}

/// A sphere of `n` samples around `centre` (radius 1) seen from six sensors at distance 3 along
/// the axes: each sample with the sensor that sees it most squarely (on a sphere n·(s − p) > 0
/// holds for it, i.e. the sensor sees the sample). Returns the samples grouped by sensor, packed,
/// and each group's sensor and length.
fn sphere_seen_from_six(n: usize, centre: [f32; 3]) -> (Vec<f32>, Vec<([f32; 3], usize)>) {
    let (p, normals) = sphere(n, centre, 1.0);
    let mut groups: Vec<Vec<f32>> = vec![Vec::new(); 6];
    let mut sensors = [[0.0f32; 3]; 6];
    for (k, sensor) in sensors.iter_mut().enumerate() {
        *sensor = centre;
        sensor[k / 2] += if k % 2 == 0 { 3.0 } else { -3.0 };
    }
    for (point, normal) in p.chunks_exact(3).zip(normals.chunks_exact(3)) {
        let axis = (0..3)
            .max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs()))
            .unwrap();
        let k = 2 * axis + usize::from(normal[axis] < 0.0);
        let s = sensors[k];
        let facing: f32 = (0..3).map(|c| normal[c] * (s[c] - point[c])).sum();
        assert!(facing > 0.0, "sensor {k} sees the sample");
        groups[k].extend_from_slice(point);
    }
    let layout = groups
        .iter()
        .zip(sensors)
        .map(|(g, s)| (s, g.len() / 3))
        .collect();
    (groups.concat(), layout)
}

/// Proves: sensor orientation gives outward normals on a sphere sampled from six outside sensor
/// positions (the mesh encloses the sphere's volume with outward triangles), the same mesh bit
/// for bit whether each scan is one batch with its sensor or each point carries its own
/// (interleaved x y z sx sy sz records), and inward normals when every sensor is at the centre:
/// the sensors, not propagation, decide the signs.
#[test]
fn sensors_orient_estimated_normals_towards_them() {
    let centre = [0.1f32, -0.2, 0.3];
    let (grouped, layout) = sphere_seen_from_six(3000, centre);
    let sphere_volume6 = 8.0 * std::f64::consts::PI;
    unsafe {
        // One batch per scan.
        let r = new_handle();
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        let mut start = 0;
        for &(sensor, count) in &layout {
            assert_eq!(
                psr_reconstructor_add_positions_seen_from(
                    r,
                    grouped[3 * start..].as_ptr(),
                    0,
                    count,
                    sensor.as_ptr()
                ),
                psr_status::Ok,
                "{}",
                last_error(r)
            );
            start += count;
        }
        let Some(per_scan) = solve_or_skip(r, "sensors_orient_estimated_normals_towards_them")
        else {
            psr_reconstructor_free(r);
            return;
        };
        let volume6 = signed_volume6(per_scan);
        assert!(
            (volume6 / sphere_volume6 - 1.0).abs() < 0.05,
            "6 × volume {volume6}: inside-out or wrong"
        );
        psr_reconstructor_free(r);

        // The same points, each with its own sensor, interleaved.
        let mut records = Vec::with_capacity(2 * grouped.len());
        let mut points = grouped.chunks_exact(3);
        for &(sensor, count) in &layout {
            for point in points.by_ref().take(count) {
                records.extend_from_slice(point);
                records.extend_from_slice(&sensor);
            }
        }
        let r = new_handle();
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_add_positions_with_sensors(
                r,
                records.as_ptr(),
                24,
                records[3..].as_ptr(),
                24,
                grouped.len() / 3
            ),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        let per_point = solve_or_skip(r, "sensors_orient_estimated_normals_towards_them").unwrap();
        assert!(
            mesh_arrays(per_point) == mesh_arrays(per_scan),
            "one sensor per batch and one per point give different meshes"
        );
        psr_mesh_free(per_point);
        psr_mesh_free(per_scan);
        psr_reconstructor_free(r);

        // Every sensor inside: every normal faces inward, and so does the mesh.
        let r = new_handle();
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_add_positions_seen_from(
                r,
                grouped.as_ptr(),
                0,
                grouped.len() / 3,
                centre.as_ptr()
            ),
            psr_status::Ok
        );
        let inside_out = solve_or_skip(r, "sensors_orient_estimated_normals_towards_them").unwrap();
        let volume6 = signed_volume6(inside_out);
        assert!(
            (volume6 / sphere_volume6 + 1.0).abs() < 0.05,
            "6 × volume {volume6}: should be minus the sphere's"
        );
        psr_mesh_free(inside_out);
        psr_reconstructor_free(r);
    }
}
// ------------------------------------------------------------------------------------------------
// Trimming: psr_trim_options (sized, extensible), psr_mesh_trim, the threshold it cut at
// ------------------------------------------------------------------------------------------------

/// The upper half of a 20k-point sphere, reconstructed at depth 6 in Rust (the C handle wraps
/// it with debug_mesh_new), and the Rust mesh itself to compare with.
fn hemisphere_mesh() -> (psr::Mesh, *mut psr_mesh) {
    let (p, n) = sphere(20_000, [0.0; 3], 1.0);
    let (mut positions, mut normals) = (Vec::new(), Vec::new());
    for i in 0..p.len() / 3 {
        if p[3 * i + 2] > 0.0 {
            positions.push([p[3 * i], p[3 * i + 1], p[3 * i + 2]]);
            normals.push([n[3 * i], n[3 * i + 1], n[3 * i + 2]]);
        }
    }
    let points = psr::PointSet::from_slices(&positions, &normals).unwrap();
    let mesh = psr::reconstruct(&points, &psr::Params::default().with_depth(6)).unwrap();
    let handle = debug_mesh_new(mesh.clone());
    (mesh, handle)
}

fn trim_options() -> psr_trim_options {
    let mut opts = std::mem::MaybeUninit::<psr_trim_options>::uninit();
    let size = std::mem::size_of::<psr_trim_options>();
    assert_eq!(
        unsafe { psr_trim_options_init(opts.as_mut_ptr(), size) },
        psr_status::Ok
    );
    unsafe { opts.assume_init() }
}

/// Trims `m` with the options at `opts` (any struct whose first field is its size) and returns
/// the status and the new mesh (NULL on failure; `out` starts as a sentinel that must stay).
fn trim_with<T>(m: *const psr_mesh, opts: *const T) -> (psr_status, *mut psr_mesh) {
    let sentinel = sentinel_ptr::<psr_mesh>();
    let mut out = sentinel;
    let status = unsafe { psr_mesh_trim(m, opts.cast(), &mut out) };
    if status == psr_status::Ok {
        assert!(!out.is_null() && out != sentinel);
        (status, out)
    } else {
        assert_eq!(out, sentinel, "*out must be left untouched on failure");
        (status, ptr::null_mut())
    }
}

/// Proves: psr_trim_options_init writes the Rust API's defaults and the size given, NULL and
/// impossible sizes are refused without writing, and every NULL the trim functions get is
/// handled (a status for psr_mesh_trim, NaN for the two getters).
#[test]
fn trim_options_init_gives_the_defaults_and_null_is_refused() {
    let opts = trim_options();
    let d = psr::Trimming::default();
    assert_eq!(opts.struct_size, std::mem::size_of::<psr_trim_options>());
    assert_eq!(opts.threshold, psr_trim_threshold::Automatic as i32);
    assert_eq!(opts.threshold_value, 0.0);
    assert_eq!(opts.min_piece_area, d.min_piece_area);
    assert_eq!(opts.min_piece_triangles, d.min_piece_triangles);
    assert_eq!(opts.threads as usize, d.threads);
    assert!(opts.progress.is_none() && opts.progress_user_data.is_null());
    unsafe {
        assert_eq!(
            psr_trim_options_init(ptr::null_mut(), 32),
            psr_status::NullArgument
        );
        let mut bytes = [0xABu8; 64];
        for bad in [0usize, 7, 4097, usize::MAX] {
            assert_eq!(
                psr_trim_options_init(bytes.as_mut_ptr().cast(), bad),
                psr_status::InvalidArgument,
                "struct_size {bad}"
            );
        }
        assert!(bytes.iter().all(|&b| b == 0xAB), "a refused init wrote");

        let tetra = tetrahedron();
        let mut out = sentinel_ptr::<psr_mesh>();
        assert_eq!(
            psr_mesh_trim(ptr::null(), &opts, &mut out),
            psr_status::NullArgument
        );
        assert_eq!(out, sentinel_ptr());
        assert_eq!(
            psr_mesh_trim(tetra, &opts, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert!(psr_mesh_trim_density(ptr::null()).is_nan());
        assert!(psr_mesh_trim_depth(ptr::null()).is_nan());
        assert!(psr_mesh_trim_density(tetra).is_nan(), "an untrimmed mesh");
        assert!(psr_mesh_trim_depth(tetra).is_nan());
        psr_mesh_free(tetra);
    }
}

/// Proves: psr_mesh_trim gives the mesh psr::trim gives, with the threshold it cut at, for
/// NULL options (the defaults) and for each threshold kind; the trimmed mesh outlives its
/// source; the source is left as it was.
#[test]
fn trimming_through_c_equals_the_rust_api() {
    let (mesh, m) = hemisphere_mesh();
    let before = mesh_arrays(m);
    let kinds = [
        (
            psr_trim_threshold::Automatic,
            0.0,
            psr::Threshold::Automatic,
        ),
        (
            psr_trim_threshold::Density,
            2.0,
            psr::Threshold::Density(2.0),
        ),
        (
            psr_trim_threshold::Quantile,
            0.7,
            psr::Threshold::Quantile(0.7),
        ),
        (psr_trim_threshold::Depth, 5.5, psr::Threshold::Depth(5.5)),
    ];
    let (status, from_null) = trim_with::<psr_trim_options>(m, ptr::null());
    assert_eq!(status, psr_status::Ok);
    let rust = psr::trim(&mesh, &psr::Trimming::default()).unwrap();
    assert_eq!(mesh_arrays(from_null).1, rust.triangles.as_flattened());
    unsafe { psr_mesh_free(from_null) };
    for (kind, value, threshold) in kinds {
        let mut opts = trim_options();
        opts.threshold = kind as i32;
        opts.threshold_value = value;
        let (status, trimmed) = trim_with(m, &opts);
        assert_eq!(status, psr_status::Ok, "{kind:?}");
        let rust = psr::trim(&mesh, &psr::Trimming::default().with_threshold(threshold)).unwrap();
        let (positions, triangles, densities, _) = mesh_arrays(trimmed);
        assert_eq!(positions, rust.positions.as_flattened(), "{kind:?}");
        assert_eq!(triangles, rust.triangles.as_flattened(), "{kind:?}");
        assert_eq!(densities, rust.densities, "{kind:?}");
        let report = rust.stats.trim.as_ref().unwrap();
        unsafe {
            assert_eq!(psr_mesh_trim_density(trimmed), report.density, "{kind:?}");
            assert_eq!(
                psr_mesh_trim_depth(trimmed).to_bits(),
                report.depth.to_bits()
            );
            assert!(psr_mesh_triangle_count(trimmed) < psr_mesh_triangle_count(m) || value == 0.0);
            if kind == psr_trim_threshold::Depth {
                assert!((psr_mesh_trim_depth(trimmed) - 5.5).abs() < 1e-6);
            }
            // The trimmed mesh is independent of its source.
            psr_mesh_free(trimmed);
        }
    }
    // The source is unchanged, and a trimmed mesh outlives it.
    assert!(mesh_arrays(m) == before);
    let (_, trimmed) = trim_with::<psr_trim_options>(m, ptr::null());
    unsafe { psr_mesh_free(m) };
    assert!(unsafe { psr_mesh_vertex_count(trimmed) } > 0);
    assert!(unsafe { psr_mesh_trim_density(trimmed) } > 0.0);
    unsafe { psr_mesh_free(trimmed) };
}

/// The first fields of psr_trim_options, as an older header would have had them (no piece
/// rule): a struct smaller than this library's.
#[repr(C)]
struct OlderTrimOptions {
    struct_size: usize,
    threshold: i32,
    threads: u32,
    threshold_value: f64,
}

/// Proves: a struct from an older header, smaller than this library's, still works: init writes
/// only its bytes, the fields it has are read and the missing ones take their defaults (the
/// same mesh as the full struct with those defaults).
#[test]
fn an_older_smaller_options_struct_still_works() {
    let (_, m) = hemisphere_mesh();
    // The older struct, followed by bytes init must not touch.
    #[repr(C)]
    struct Guarded {
        older: OlderTrimOptions,
        after: [u8; 16],
    }
    let mut guarded = Guarded {
        older: OlderTrimOptions {
            struct_size: 0,
            threshold: -1,
            threads: 99,
            threshold_value: f64::NAN,
        },
        after: [0xAB; 16],
    };
    let size = std::mem::size_of::<OlderTrimOptions>();
    assert_eq!(size, 24);
    let status = unsafe {
        psr_trim_options_init(
            ptr::from_mut(&mut guarded.older).cast::<psr_trim_options>(),
            size,
        )
    };
    assert_eq!(status, psr_status::Ok);
    assert!(
        guarded.after.iter().all(|&b| b == 0xAB),
        "init wrote past the struct"
    );
    assert_eq!(guarded.older.struct_size, size);
    assert_eq!(guarded.older.threshold, 0);
    assert_eq!(guarded.older.threads, 0);
    assert_eq!(guarded.older.threshold_value, 0.0);
    guarded.older.threshold = psr_trim_threshold::Depth as i32;
    guarded.older.threshold_value = 5.5;
    let (status, old) = trim_with(m, &guarded.older);
    assert_eq!(status, psr_status::Ok);
    let mut full = trim_options();
    full.threshold = psr_trim_threshold::Depth as i32;
    full.threshold_value = 5.5;
    let (_, new) = trim_with(m, &full);
    assert!(mesh_arrays(old) == mesh_arrays(new));
    // Only the size field: every option at its default.
    let only_size: usize = std::mem::size_of::<usize>();
    let (status, defaults) = trim_with(m, &only_size);
    assert_eq!(status, psr_status::Ok);
    let (_, null) = trim_with::<psr_trim_options>(m, ptr::null());
    assert!(mesh_arrays(defaults) == mesh_arrays(null));
    unsafe {
        for mesh in [old, new, defaults, null, m] {
            psr_mesh_free(mesh);
        }
    }
}

/// Proves: a struct from a newer header, larger than this library's, is accepted while the
/// fields this library does not know are zero (init zeroes them), and refused with
/// INVALID_ARGUMENT once one is set.
#[test]
fn a_newer_larger_options_struct_works_while_its_unknown_fields_are_zero() {
    let (_, m) = hemisphere_mesh();
    #[repr(C)]
    struct NewerTrimOptions {
        known: psr_trim_options,
        later: [u64; 2],
    }
    let mut newer = std::mem::MaybeUninit::<NewerTrimOptions>::uninit();
    let size = std::mem::size_of::<NewerTrimOptions>();
    assert_eq!(
        unsafe { psr_trim_options_init(newer.as_mut_ptr().cast(), size) },
        psr_status::Ok
    );
    let mut newer = unsafe { newer.assume_init() };
    assert_eq!(newer.known.struct_size, size);
    assert_eq!(newer.later, [0, 0]);
    let (status, trimmed) = trim_with(m, &newer);
    assert_eq!(status, psr_status::Ok);
    newer.later[1] = 1;
    assert_eq!(trim_with(m, &newer).0, psr_status::InvalidArgument);
    unsafe {
        psr_mesh_free(trimmed);
        psr_mesh_free(m);
    }
}

/// What a trim's progress callback saw (its user pointer points here).
#[derive(Default)]
struct TrimCalls {
    seen: Vec<(psr_stage, f32)>,
    /// Return false from this call on (counting from 0); None: never.
    stop_at: Option<usize>,
}

unsafe extern "C" fn record_trim_progress(user: *mut c_void, stage: psr_stage, f: f32) -> bool {
    // SAFETY: the tests pass a TrimCalls that outlives psr_mesh_trim as the user pointer.
    let calls = unsafe { &mut *user.cast::<TrimCalls>() };
    calls.seen.push((stage, f));
    calls.stop_at.is_none_or(|at| calls.seen.len() <= at)
}

/// Proves: psr_trim_options.progress is called with PSR_STAGE_TRIM and its user pointer, from 0
/// to 1, and does not change the mesh; returning false gives PSR_STATUS_CANCELLED, no mesh and
/// no call after; a struct that ends before the progress fields (an older header's) trims
/// without calling anything.
#[test]
fn the_trim_reports_progress_through_its_options_and_can_be_cancelled() {
    let (_, m) = hemisphere_mesh();
    let (_, plain) = trim_with(m, &trim_options());
    let mut calls = TrimCalls::default();
    let mut opts = trim_options();
    opts.progress = Some(record_trim_progress);
    opts.progress_user_data = ptr::from_mut(&mut calls).cast();
    let (status, reported) = trim_with(m, &opts);
    assert_eq!(status, psr_status::Ok);
    assert!(mesh_arrays(reported) == mesh_arrays(plain));
    assert!(calls.seen.iter().all(|&(s, _)| s == psr_stage::Trim));
    assert_eq!(calls.seen.first().map(|c| c.1), Some(0.0));
    assert_eq!(calls.seen.last().map(|c| c.1), Some(1.0));

    let mut stopping = TrimCalls {
        stop_at: Some(0),
        ..TrimCalls::default()
    };
    opts.progress_user_data = ptr::from_mut(&mut stopping).cast();
    assert_eq!(trim_with(m, &opts).0, psr_status::Cancelled);
    assert_eq!(stopping.seen.len(), 1, "called after the stop");

    // The fields before the progress callback only: the callback after them is not read.
    let mut older = opts;
    older.struct_size = std::mem::offset_of!(psr_trim_options, progress);
    let (status, old) = trim_with(m, &older);
    assert_eq!(status, psr_status::Ok);
    assert_eq!(
        stopping.seen.len(),
        1,
        "an older struct's trim called the callback"
    );
    assert!(mesh_arrays(old) == mesh_arrays(plain));
    unsafe {
        for mesh in [plain, reported, old, m] {
            psr_mesh_free(mesh);
        }
    }
}

/// Proves: sizes no header has, unknown threshold kinds and values out of range are refused
/// (INVALID_ARGUMENT for the struct, INVALID_PARAMETER for a value), leaving *out alone.
#[test]
fn bad_trim_options_are_refused() {
    let (_, m) = hemisphere_mesh();
    let refused = |change: &dyn Fn(&mut psr_trim_options), want: psr_status| {
        let mut opts = trim_options();
        change(&mut opts);
        assert_eq!(trim_with(m, &opts).0, want, "{opts:?}");
    };
    refused(&|o| o.struct_size = 0, psr_status::InvalidArgument);
    refused(&|o| o.struct_size = 4, psr_status::InvalidArgument);
    refused(&|o| o.struct_size = 1 << 20, psr_status::InvalidArgument);
    refused(&|o| o.threshold = 4, psr_status::InvalidParameter);
    refused(&|o| o.threshold = -1, psr_status::InvalidParameter);
    let with = |kind: psr_trim_threshold, value: f64| {
        move |o: &mut psr_trim_options| {
            o.threshold = kind as i32;
            o.threshold_value = value;
        }
    };
    refused(
        &with(psr_trim_threshold::Density, -1.0),
        psr_status::InvalidParameter,
    );
    refused(
        &with(psr_trim_threshold::Density, f64::NAN),
        psr_status::InvalidParameter,
    );
    refused(
        &with(psr_trim_threshold::Density, 1e300),
        psr_status::InvalidParameter,
    );
    refused(
        &with(psr_trim_threshold::Quantile, 1.5),
        psr_status::InvalidParameter,
    );
    refused(
        &with(psr_trim_threshold::Depth, 40.0),
        psr_status::InvalidParameter,
    );
    refused(&|o| o.min_piece_area = 2.0, psr_status::InvalidParameter);
    refused(
        &|o| o.min_piece_area = f32::NAN,
        psr_status::InvalidParameter,
    );
    refused(&|o| o.threads = 5000, psr_status::InvalidParameter);
    // The automatic threshold ignores the value.
    let mut opts = trim_options();
    opts.threshold_value = f64::NAN;
    let (status, trimmed) = trim_with(m, &opts);
    assert_eq!(status, psr_status::Ok);
    unsafe {
        psr_mesh_free(trimmed);
        psr_mesh_free(m);
    }
}

/// Proves: several threads may trim the same mesh at once, each getting the same result.
#[test]
fn threads_may_trim_one_mesh_at_once() {
    struct Shared(*mut psr_mesh);
    // SAFETY: a psr_mesh is never changed after creation; its const functions may be called
    // from several threads at once (the header's THREADING section).
    unsafe impl Sync for Shared {}
    let (_, m) = hemisphere_mesh();
    let shared = Shared(m);
    let results: Vec<MeshArrays> = std::thread::scope(|s| {
        let runs: Vec<_> = (0..3)
            .map(|_| {
                s.spawn(|| {
                    let shared = &shared;
                    let (status, trimmed) = trim_with::<psr_trim_options>(shared.0, ptr::null());
                    assert_eq!(status, psr_status::Ok);
                    let arrays = mesh_arrays(trimmed);
                    unsafe { psr_mesh_free(trimmed) };
                    arrays
                })
            })
            .collect();
        runs.into_iter().map(|r| r.join().unwrap()).collect()
    });
    assert!(results.windows(2).all(|w| w[0] == w[1]));
    unsafe { psr_mesh_free(m) };
}

// ------------------------------------------------------------------------------------------------
// Points with confidence, colours and channels (psr_point_arrays); the mesh's normals, colours
// and channels
// ------------------------------------------------------------------------------------------------

/// A struct initialised by psr_point_arrays_init with the library's own size.
fn point_arrays() -> psr_point_arrays {
    let mut a = std::mem::MaybeUninit::<psr_point_arrays>::uninit();
    let size = std::mem::size_of::<psr_point_arrays>();
    assert_eq!(
        unsafe { psr_point_arrays_init(a.as_mut_ptr(), size) },
        psr_status::Ok
    );
    let a = unsafe { a.assume_init() };
    assert_eq!(a.struct_size, size);
    assert!(a.count == 0 && a.positions.is_null() && a.channel_names.is_null());
    a
}

/// The first six fields of psr_point_arrays: what a caller compiled against an older, smaller
/// header would pass (positions and normals only).
#[repr(C)]
struct OlderPointArrays {
    struct_size: usize,
    count: usize,
    positions: *const f32,
    position_stride_bytes: usize,
    normals: *const f32,
    normal_stride_bytes: usize,
}

/// psr_point_arrays followed by one field a newer header might add.
#[repr(C)]
struct NewerPointArrays {
    current: psr_point_arrays,
    future_field: usize,
}

fn add_arrays(r: *mut psr_reconstructor, a: &psr_point_arrays) -> psr_status {
    unsafe { psr_reconstructor_add_point_arrays(r, a) }
}

/// Proves: psr_point_arrays_init and psr_reconstructor_add_point_arrays refuse NULL and bad
/// sizes (below the first fields, above 4096) with the documented statuses; a struct from an older (smaller) header works, its
/// missing fields counting as absent; a struct from a newer header works while its unknown
/// fields are zero and is refused (not silently ignored) when they are set; count 0 reads
/// nothing else.
#[test]
fn point_arrays_null_and_struct_sizes() {
    let r = new_handle();
    let (p, n) = sphere(50, [0.0; 3], 1.0);
    unsafe {
        let size = std::mem::size_of::<psr_point_arrays>();
        assert_eq!(
            psr_point_arrays_init(ptr::null_mut(), size),
            psr_status::NullArgument
        );
        let mut a = point_arrays();
        a.struct_size = 77;
        assert_eq!(
            psr_point_arrays_init(&mut a, 3 * std::mem::size_of::<usize>()),
            psr_status::InvalidArgument
        );
        assert_eq!(a.struct_size, 77, "nothing written on failure");

        assert_eq!(
            psr_reconstructor_add_point_arrays(ptr::null_mut(), &point_arrays()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_add_point_arrays(r, ptr::null()),
            psr_status::NullArgument
        );
        assert!(last_error(r).contains("a is NULL"), "{}", last_error(r));

        // An uninitialised (zero) size is refused with the way out.
        let mut a = point_arrays();
        a.struct_size = 0;
        assert_eq!(add_arrays(r, &a), psr_status::InvalidArgument);
        assert!(
            last_error(r).contains("psr_point_arrays_init"),
            "{}",
            last_error(r)
        );

        // A garbage size above 4096 (a struct never set up) is refused, neither read nor
        // written past the struct (found by fuzzing: both read and zeroed struct_size bytes).
        let mut a = point_arrays();
        a.struct_size = 4097;
        assert_eq!(add_arrays(r, &a), psr_status::InvalidArgument);
        assert!(last_error(r).contains("4096"), "{}", last_error(r));
        a.struct_size = 77;
        assert_eq!(
            psr_point_arrays_init(&mut a, usize::MAX),
            psr_status::InvalidArgument
        );
        assert_eq!(a.struct_size, 77, "nothing written on failure");

        // count 0: nothing else is read (all pointers NULL).
        assert_eq!(add_arrays(r, &point_arrays()), psr_status::Ok);
        assert_eq!(point_count(r), 0);

        // A caller of an older header: positions and normals only.
        let older = OlderPointArrays {
            struct_size: std::mem::size_of::<OlderPointArrays>(),
            count: 50,
            positions: p.as_ptr(),
            position_stride_bytes: 0,
            normals: n.as_ptr(),
            normal_stride_bytes: 12,
        };
        let status =
            psr_reconstructor_add_point_arrays(r, (&older as *const OlderPointArrays).cast());
        assert_eq!(status, psr_status::Ok, "{}", last_error(r));
        assert_eq!(point_count(r), 50);
        // ... and one whose size ends before normals: they count as absent, and are required.
        let cut = OlderPointArrays {
            struct_size: 4 * std::mem::size_of::<usize>(),
            ..older
        };
        let status =
            psr_reconstructor_add_point_arrays(r, (&cut as *const OlderPointArrays).cast());
        assert_eq!(status, psr_status::NullArgument);
        assert!(last_error(r).contains("normals"), "{}", last_error(r));

        // A caller of a newer header: fine while the unknown field is zero.
        let mut newer = NewerPointArrays {
            current: point_arrays(),
            future_field: 0,
        };
        newer.current.struct_size = std::mem::size_of::<NewerPointArrays>();
        newer.current.count = 50;
        newer.current.positions = p.as_ptr();
        newer.current.normals = n.as_ptr();
        let newer_ptr = (&newer as *const NewerPointArrays).cast::<psr_point_arrays>();
        assert_eq!(
            psr_reconstructor_add_point_arrays(r, newer_ptr),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 100);
        newer.future_field = 1;
        let newer_ptr = (&newer as *const NewerPointArrays).cast::<psr_point_arrays>();
        assert_eq!(
            psr_reconstructor_add_point_arrays(r, newer_ptr),
            psr_status::InvalidArgument
        );
        assert!(
            last_error(r).contains("older than the header"),
            "{}",
            last_error(r)
        );
        assert_eq!(point_count(r), 100);
        psr_reconstructor_free(r);
    }
}

/// Proves: a batch is checked whole, field by field, with the documented status and a message
/// naming the argument or the first bad index in the batch; nothing of a bad batch is added.
#[test]
fn point_arrays_are_checked_whole() {
    let count = 20;
    let (p, n) = sphere(count, [0.0; 3], 1.0);
    let colors: Vec<f32> = (0..3 * count).map(|i| (i % 7) as f32 / 7.0).collect();
    // RGBA for the batch whose colours differ in kind: an array as long as the fields say, so
    // the library may read all of it (a 3-component array described as 4 components would be
    // read past its end, which AddressSanitizer reports).
    let rgba: Vec<f32> = (0..4 * count).map(|i| (i % 5) as f32 / 5.0).collect();
    let values: Vec<f32> = (0..2 * count).map(|i| i as f32).collect();
    let weights = vec![1.0f32; count];
    let names = [c"intensity".as_ptr(), c"label".as_ptr()];
    // The same names in another order, bound here: a temporary array's pointer taken inside the
    // struct literal below would dangle once that statement ends.
    let swapped = [c"label".as_ptr(), c"intensity".as_ptr()];
    let full = || {
        let mut a = point_arrays();
        a.count = count;
        a.positions = p.as_ptr();
        a.normals = n.as_ptr();
        a.confidence = weights.as_ptr();
        a.colors = colors.as_ptr();
        a.color_components = 3;
        a.channels = values.as_ptr();
        a.channel_count = 2;
        a.channel_names = names.as_ptr();
        a
    };
    let r = new_handle();
    let check = |a: psr_point_arrays, want: psr_status, words: &[&str]| {
        assert_eq!(add_arrays(r, &a), want, "{}", last_error(r));
        let message = last_error(r);
        for w in words {
            assert!(message.contains(w), "{w:?} not in {message}");
        }
        assert_eq!(point_count(r), 0, "nothing from a bad batch is added");
    };
    use psr_status::*;
    check(
        psr_point_arrays {
            positions: ptr::null(),
            ..full()
        },
        NullArgument,
        &["positions"],
    );
    check(
        psr_point_arrays {
            normals: ptr::null(),
            ..full()
        },
        NullArgument,
        &["normals", "psr_reconstructor_add_positions"],
    );
    check(
        psr_point_arrays {
            colors: ptr::null(),
            ..full()
        },
        NullArgument,
        &["colors", "color_components 3"],
    );
    check(
        psr_point_arrays {
            color_components: 5,
            ..full()
        },
        InvalidArgument,
        &["color_components is 5"],
    );
    check(
        psr_point_arrays {
            color_stride_bytes: 8,
            ..full()
        },
        InvalidArgument,
        &["color_stride_bytes is 8"],
    );
    check(
        psr_point_arrays {
            confidence_stride_bytes: 2,
            ..full()
        },
        InvalidArgument,
        &["confidence_stride_bytes"],
    );
    check(
        psr_point_arrays {
            channels: ptr::null(),
            ..full()
        },
        NullArgument,
        &["channels"],
    );
    check(
        psr_point_arrays {
            channel_names: ptr::null(),
            ..full()
        },
        NullArgument,
        &["channel_names"],
    );
    check(
        psr_point_arrays {
            channel_stride_bytes: 4,
            ..full()
        },
        InvalidArgument,
        &["channel_stride_bytes is 4"],
    );
    check(
        psr_point_arrays {
            count: usize::MAX / 2,
            ..full()
        },
        InvalidArgument,
        &["more bytes than memory"],
    );
    let null_name = [c"intensity".as_ptr(), ptr::null()];
    check(
        psr_point_arrays {
            channel_names: null_name.as_ptr(),
            ..full()
        },
        NullArgument,
        &["channel_names[1]"],
    );
    let twice = [c"x2".as_ptr(), c"x2".as_ptr()];
    check(
        psr_point_arrays {
            channel_names: twice.as_ptr(),
            ..full()
        },
        InvalidArgument,
        &["\"x2\"", "twice"],
    );
    let spaced = [c"in tensity".as_ptr(), c"label".as_ptr()];
    check(
        psr_point_arrays {
            channel_names: spaced.as_ptr(),
            ..full()
        },
        InvalidArgument,
        &["whitespace"],
    );
    let not_utf8 = [c"\xff".as_ptr(), c"label".as_ptr()];
    check(
        psr_point_arrays {
            channel_names: not_utf8.as_ptr(),
            ..full()
        },
        InvalidArgument,
        &["UTF-8"],
    );

    let mut bad = colors.clone();
    bad[3 * 7 + 1] = f32::NAN;
    check(
        psr_point_arrays {
            colors: bad.as_ptr(),
            ..full()
        },
        NonFiniteAttribute,
        &["colors", "point 7"],
    );
    let mut bad = values.clone();
    bad[2 * 11 + 1] = f32::INFINITY;
    check(
        psr_point_arrays {
            channels: bad.as_ptr(),
            ..full()
        },
        NonFiniteAttribute,
        &["label", "point 11"],
    );
    let mut bad = weights.clone();
    bad[4] = -1.0;
    check(
        psr_point_arrays {
            confidence: bad.as_ptr(),
            ..full()
        },
        InvalidWeight,
        &["weight 4"],
    );
    let mut bad = p.clone();
    bad[3 * 9] = f32::NAN;
    check(
        psr_point_arrays {
            positions: bad.as_ptr(),
            ..full()
        },
        NonFinitePosition,
        &["point 9"],
    );

    // A good batch; then batches whose attributes differ are refused, the same kind is not.
    assert_eq!(add_arrays(r, &full()), Ok, "{}", last_error(r));
    assert_eq!(point_count(r), count);
    let refused = [
        psr_point_arrays {
            colors: ptr::null(),
            color_components: 0,
            ..full()
        },
        psr_point_arrays {
            colors: rgba.as_ptr(),
            color_components: 4,
            ..full()
        },
        psr_point_arrays {
            channel_count: 1,
            ..full()
        },
        psr_point_arrays {
            channel_names: swapped.as_ptr(),
            ..full()
        },
    ];
    for a in refused {
        assert_eq!(add_arrays(r, &a), InvalidArgument, "{}", last_error(r));
        assert!(last_error(r).contains("carry"), "{}", last_error(r));
    }
    // Weights may differ between batches (absent = 1).
    assert_eq!(
        add_arrays(
            r,
            &psr_point_arrays {
                confidence: ptr::null(),
                ..full()
            }
        ),
        Ok
    );
    assert_eq!(point_count(r), 2 * count);
    // Points without attributes cannot join them, whichever comes first.
    unsafe {
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, count),
            InvalidArgument
        );
        assert_eq!(psr_reconstructor_add_positions(r, p.as_ptr(), 0, count), Ok);
        let mut m = ptr::null_mut();
        assert_eq!(psr_reconstructor_solve(r, &mut m), InvalidArgument);
        assert!(
            last_error(r).contains("points without normals"),
            "{}",
            last_error(r)
        );
        assert!(m.is_null());
    }
    assert_eq!(add_arrays(r, &full()), InvalidArgument);
    assert!(
        last_error(r).contains("without normals"),
        "{}",
        last_error(r)
    );
    assert_eq!(point_count(r), 3 * count);
    unsafe {
        assert_eq!(psr_reconstructor_clear_points(r), Ok);
        // Once cleared, a batch without attributes starts afresh.
        assert_eq!(
            psr_reconstructor_add_points(r, p.as_ptr(), 0, n.as_ptr(), 0, count),
            Ok
        );
        assert_eq!(add_arrays(r, &full()), InvalidArgument);
        psr_reconstructor_free(r);
    }
}

/// Proves: the vertex normals setting defaults to false and round-trips; NULL is refused.
#[test]
fn vertex_normals_setting_round_trips() {
    let r = new_handle();
    unsafe {
        let mut on = true;
        assert_eq!(
            psr_reconstructor_get_vertex_normals(r, &mut on),
            psr_status::Ok
        );
        assert!(!on);
        assert_eq!(
            psr_reconstructor_set_vertex_normals(r, true),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_get_vertex_normals(r, &mut on),
            psr_status::Ok
        );
        assert!(on);
        assert_eq!(
            psr_reconstructor_set_vertex_normals(ptr::null_mut(), true),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_vertex_normals(ptr::null(), &mut on),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_vertex_normals(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        psr_reconstructor_free(r);
    }
}

/// Proves: the screening-follows-noise setting defaults to true and round-trips, NULL is
/// refused, and the mesh reports what the reconstruction did: without it the screening depth is
/// the depth and the noise NaN; with it, on a jittered sphere, the Rust API's figures.
#[test]
fn screening_follows_noise_round_trips_and_the_mesh_reports_the_noise() {
    let status = psr_status::Ok;
    let (p, nrm) = sphere(20_000, [0.1, -0.2, 0.3], 1.0);
    // A deterministic jitter of 0.01 along each axis (a sawtooth over the index).
    let jittered: Vec<f32> = p
        .iter()
        .enumerate()
        .map(|(i, v)| v + 0.02 * ((i * 7919 % 1000) as f32 / 1000.0 - 0.5))
        .collect();
    unsafe {
        let mut on = true;
        assert_eq!(
            psr_reconstructor_set_screening_follows_noise(ptr::null_mut(), true),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_screening_follows_noise(ptr::null(), &mut on),
            psr_status::NullArgument
        );
        let (mut depth, mut noise) = (0.0f64, 0.0f64);
        assert_eq!(
            psr_mesh_screening_depth(ptr::null(), &mut depth),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_mesh_sample_noise(ptr::null(), &mut noise),
            psr_status::NullArgument
        );
        for follows in [false, true] {
            let r = new_handle();
            assert_eq!(
                psr_reconstructor_get_screening_follows_noise(r, &mut on),
                status
            );
            assert!(on);
            assert_eq!(
                psr_reconstructor_get_screening_follows_noise(r, ptr::null_mut()),
                psr_status::NullArgument
            );
            assert_eq!(
                psr_reconstructor_set_screening_follows_noise(r, follows),
                status
            );
            assert_eq!(
                psr_reconstructor_get_screening_follows_noise(r, &mut on),
                status
            );
            assert_eq!(on, follows);
            assert_eq!(psr_reconstructor_set_depth(r, 8), status);
            assert_eq!(
                psr_reconstructor_add_points(r, jittered.as_ptr(), 0, nrm.as_ptr(), 0, 20_000),
                status
            );
            let Some(m) = solve_or_skip(r, "screening_follows_noise_round_trips") else {
                psr_reconstructor_free(r);
                return;
            };
            psr_reconstructor_free(r);
            assert_eq!(
                psr_mesh_screening_depth(m, ptr::null_mut()),
                psr_status::NullArgument
            );
            assert_eq!(psr_mesh_screening_depth(m, &mut depth), status);
            assert_eq!(psr_mesh_sample_noise(m, &mut noise), status);
            let points =
                psr::PointSet::from_slices(triples(&jittered).as_slice(), triples(&nrm).as_slice())
                    .unwrap();
            let params = psr::Params::default()
                .with_depth(8)
                .with_screening_follows_noise(follows);
            let want = psr::reconstruct(&points, &params).unwrap().stats;
            assert_eq!(depth, want.screening_depth);
            match want.sample_noise {
                Some(sigma) => {
                    assert_eq!(noise, sigma);
                    assert!(sigma > 0.0 && depth < 8.0, "{sigma} {depth}");
                }
                None => assert!(noise.is_nan() && depth == 8.0, "{noise} {depth}"),
            }
            psr_mesh_free(m);
        }
    }
}

/// The tetrahedron with normals, RGBA colours and two channels.
fn tetrahedron_with_attributes() -> *mut psr_mesh {
    let mut mesh = psr::Mesh::default();
    mesh.positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    mesh.triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    mesh.densities = vec![1.0; 4];
    mesh.normals = vec![
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    mesh.colors = Some(psr::Colors::Rgba(vec![[0.1, 0.2, 0.3, 1.0]; 4]));
    mesh.channels = vec![
        psr::Channel::new("intensity", vec![1.0, 2.0, 3.0, 4.0]),
        psr::Channel::new("label", vec![5.0, 6.0, 7.0, 8.0]),
    ];
    debug_mesh_new(mesh)
}

/// Proves: the mesh's normals, colours and channels are read through borrowed views and
/// copies, with NULL, short buffers and indices out of range refused as documented, and a mesh
/// without them gives NULL views, 0 counts and empty copies.
#[test]
fn mesh_normals_colours_and_channels_views_and_copies() {
    use psr_status::*;
    let m = tetrahedron_with_attributes();
    let null_m: *const psr_mesh = ptr::null();
    unsafe {
        let normals = std::slice::from_raw_parts(psr_mesh_normals(m), 12);
        assert_eq!(&normals[..3], &[-1.0, 0.0, 0.0]);
        assert_eq!(psr_mesh_color_components(m), 4);
        let colors = std::slice::from_raw_parts(psr_mesh_colors(m), 16);
        assert_eq!(&colors[..4], &[0.1, 0.2, 0.3, 1.0]);
        assert_eq!(psr_mesh_channel_count(m), 2);
        assert_eq!(
            CStr::from_ptr(psr_mesh_channel_name(m, 0)).to_str(),
            std::result::Result::Ok("intensity")
        );
        assert_eq!(
            CStr::from_ptr(psr_mesh_channel_name(m, 1)).to_str(),
            std::result::Result::Ok("label")
        );
        assert!(psr_mesh_channel_name(m, 2).is_null());
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_channel(m, 1), 4),
            &[5.0, 6.0, 7.0, 8.0]
        );
        assert!(psr_mesh_channel(m, 2).is_null());

        let mut buf = [9.0f32; 16];
        assert_eq!(psr_mesh_copy_normals(m, buf.as_mut_ptr(), 12), Ok);
        assert_eq!(&buf[..12], normals);
        assert_eq!(psr_mesh_copy_colors(m, buf.as_mut_ptr(), 16), Ok);
        assert_eq!(&buf[..], colors);
        assert_eq!(psr_mesh_copy_channel(m, 0, buf.as_mut_ptr(), 4), Ok);
        assert_eq!(&buf[..4], &[1.0, 2.0, 3.0, 4.0]);
        let mut short = [9.0f32; 16];
        assert_eq!(
            psr_mesh_copy_normals(m, short.as_mut_ptr(), 11),
            BufferTooSmall
        );
        assert_eq!(
            psr_mesh_copy_colors(m, short.as_mut_ptr(), 15),
            BufferTooSmall
        );
        assert_eq!(
            psr_mesh_copy_channel(m, 1, short.as_mut_ptr(), 3),
            BufferTooSmall
        );
        assert_eq!(short, [9.0; 16], "nothing written");
        assert_eq!(
            psr_mesh_copy_channel(m, 2, short.as_mut_ptr(), 16),
            InvalidArgument
        );
        assert_eq!(psr_mesh_copy_normals(m, ptr::null_mut(), 12), NullArgument);
        assert_eq!(psr_mesh_copy_colors(m, ptr::null_mut(), 16), NullArgument);
        assert_eq!(
            psr_mesh_copy_channel(m, 0, ptr::null_mut(), 4),
            NullArgument
        );

        // NULL mesh.
        assert!(psr_mesh_normals(null_m).is_null() && psr_mesh_colors(null_m).is_null());
        assert_eq!(psr_mesh_color_components(null_m), 0);
        assert_eq!(psr_mesh_channel_count(null_m), 0);
        assert!(
            psr_mesh_channel_name(null_m, 0).is_null() && psr_mesh_channel(null_m, 0).is_null()
        );
        assert_eq!(
            psr_mesh_copy_normals(null_m, buf.as_mut_ptr(), 16),
            NullArgument
        );
        assert_eq!(
            psr_mesh_copy_colors(null_m, buf.as_mut_ptr(), 16),
            NullArgument
        );
        assert_eq!(
            psr_mesh_copy_channel(null_m, 0, buf.as_mut_ptr(), 16),
            NullArgument
        );
        psr_mesh_free(m);

        // A mesh without them.
        let plain = tetrahedron();
        assert!(psr_mesh_normals(plain).is_null() && psr_mesh_colors(plain).is_null());
        assert_eq!(psr_mesh_color_components(plain), 0);
        assert_eq!(psr_mesh_channel_count(plain), 0);
        assert_eq!(psr_mesh_copy_normals(plain, ptr::null_mut(), 0), Ok);
        assert_eq!(psr_mesh_copy_colors(plain, ptr::null_mut(), 0), Ok);
        assert_eq!(
            psr_mesh_copy_channel(plain, 0, buf.as_mut_ptr(), 16),
            InvalidArgument
        );
        psr_mesh_free(plain);
    }
}

/// Proves: colours and a channel given through psr_point_arrays (interleaved with the
/// positions, with weights) reach the mesh: on a sphere coloured by height, every vertex's
/// colour is close to the colour of the sphere at its height, the channel likewise, and the
/// requested normals are unit and outward.
#[test]
fn colours_and_channels_reach_the_mesh_through_c() {
    let count = 4000;
    let (p, n) = sphere(count, [0.0; 3], 1.0);
    // Interleaved records: x y z r g b height.
    let mut records = Vec::with_capacity(7 * count);
    for i in 0..count {
        let z = p[3 * i + 2];
        records.extend_from_slice(&p[3 * i..3 * i + 3]);
        records.extend_from_slice(&[(z + 1.0) / 2.0, 0.5, (1.0 - z) / 2.0, z]);
    }
    let names = [c"height".as_ptr()];
    let mut a = point_arrays();
    a.count = count;
    a.positions = records.as_ptr();
    a.position_stride_bytes = 28;
    a.normals = n.as_ptr();
    a.colors = records[3..].as_ptr();
    a.color_stride_bytes = 28;
    a.color_components = 3;
    a.channels = records[6..].as_ptr();
    a.channel_stride_bytes = 28;
    a.channel_count = 1;
    a.channel_names = names.as_ptr();
    let weights = vec![2.0f32; count];
    a.confidence = weights.as_ptr();
    let r = new_handle();
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 5), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_set_vertex_normals(r, true),
            psr_status::Ok
        );
        assert_eq!(add_arrays(r, &a), psr_status::Ok, "{}", last_error(r));
        let Some(m) = solve_or_skip(r, "colours_and_channels_reach_the_mesh_through_c") else {
            return;
        };
        let nv = psr_mesh_vertex_count(m);
        assert_eq!(psr_mesh_color_components(m), 3);
        assert_eq!(psr_mesh_channel_count(m), 1);
        assert_eq!(
            CStr::from_ptr(psr_mesh_channel_name(m, 0)).to_str(),
            Ok("height")
        );
        let positions = std::slice::from_raw_parts(psr_mesh_positions(m), 3 * nv);
        let colors = std::slice::from_raw_parts(psr_mesh_colors(m), 3 * nv);
        let height = std::slice::from_raw_parts(psr_mesh_channel(m, 0), nv);
        let normals = std::slice::from_raw_parts(psr_mesh_normals(m), 3 * nv);
        let mut worst = 0.0f32;
        for v in 0..nv {
            let q = &positions[3 * v..3 * v + 3];
            let length = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            let z = q[2] / length;
            worst = worst
                .max((colors[3 * v] - (z + 1.0) / 2.0).abs())
                .max((colors[3 * v + 1] - 0.5).abs())
                .max((colors[3 * v + 2] - (1.0 - z) / 2.0).abs())
                .max((height[v] - z).abs() / 2.0);
            let nn = &normals[3 * v..3 * v + 3];
            let unit = (nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]).sqrt();
            assert!((unit - 1.0).abs() < 1e-4, "vertex {v}: |n| = {unit}");
            let outward = (nn[0] * q[0] + nn[1] * q[1] + nn[2] * q[2]) / length;
            assert!(outward > 0.9, "vertex {v}: n . q/|q| = {outward}");
        }
        // A depth-5 kernel is about 0.1 wide here, over which the colour changes by ~0.05.
        assert!(worst < 0.03, "largest colour error {worst}");
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
}

// ------------------------------------------------------------------------------------------------
// The implicit function (psr_implicit)
// ------------------------------------------------------------------------------------------------

/// A reconstructor over a sphere at depth 5, solved keeping χ; the mesh too.
fn solve_implicit() -> (*mut psr_reconstructor, *mut psr_mesh, *mut psr_implicit) {
    let r = new_handle();
    add_sphere(r, 2000);
    assert_eq!(unsafe { psr_reconstructor_set_depth(r, 5) }, psr_status::Ok);
    let (mut m, mut f) = (ptr::null_mut(), ptr::null_mut());
    let status = unsafe { psr_reconstructor_solve_implicit(r, &mut m, &mut f) };
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(!m.is_null() && !f.is_null());
    (r, m, f)
}

#[test]
fn implicit_null_handles_arrays_and_outs_are_refused() {
    unsafe {
        psr_implicit_free(ptr::null_mut());
        assert!(psr_implicit_isovalue(ptr::null()).is_nan());
        let mut out = [7.0f32; 8];
        let points = [0.0f32; 6];
        let (mut origin, mut size) = ([0.0f64; 3], 0.0f64);
        let null: *const psr_implicit = ptr::null();
        assert_eq!(
            psr_implicit_evaluate(null, points.as_ptr(), 2, out.as_mut_ptr()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_gradient(null, points.as_ptr(), 2, out.as_mut_ptr()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_sample_grid(null, 2, out.as_mut_ptr(), 8),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_cube(null, origin.as_mut_ptr(), &mut size),
            psr_status::NullArgument
        );
        assert_eq!(out, [7.0; 8]);

        // The solve: r and out_implicit may not be NULL; out_mesh may.
        let r = new_handle();
        add_sphere(r, 500);
        let mut f = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_solve_implicit(ptr::null_mut(), ptr::null_mut(), &mut f),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_solve_implicit(r, ptr::null_mut(), ptr::null_mut()),
            psr_status::NullArgument
        );
        assert!(last_error(r).contains("out_implicit"), "{}", last_error(r));
        assert_eq!(psr_reconstructor_set_depth(r, 4), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_solve_implicit(r, ptr::null_mut(), &mut f),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        assert!(!f.is_null());
        // Every pointer of a live handle's functions.
        assert_eq!(
            psr_implicit_evaluate(f, ptr::null(), 2, out.as_mut_ptr()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_evaluate(f, points.as_ptr(), 2, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_gradient(f, ptr::null(), 2, out.as_mut_ptr()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_gradient(f, points.as_ptr(), 2, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_sample_grid(f, 2, ptr::null_mut(), 8),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_cube(f, ptr::null_mut(), &mut size),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_cube(f, origin.as_mut_ptr(), ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(size, 0.0);
        // Count 0: NULL arrays are fine and nothing is written.
        assert_eq!(
            psr_implicit_evaluate(f, ptr::null(), 0, ptr::null_mut()),
            psr_status::Ok
        );
        assert_eq!(
            psr_implicit_gradient(f, ptr::null(), 0, ptr::null_mut()),
            psr_status::Ok
        );
        // Counts whose byte length overflows, refused before any read.
        assert_eq!(
            psr_implicit_evaluate(f, sentinel_ptr(), usize::MAX / 3 + 1, sentinel_ptr()),
            psr_status::InvalidArgument
        );
        assert_eq!(
            psr_implicit_gradient(f, sentinel_ptr(), usize::MAX / 8, sentinel_ptr()),
            psr_status::InvalidArgument
        );
        assert_eq!(out, [7.0; 8]);
        psr_implicit_free(f);
        psr_reconstructor_free(r);
    }
}

#[test]
fn implicit_evaluation_grid_and_errors_through_the_c_api() {
    let (r, m, f) = solve_implicit();
    unsafe {
        assert_eq!(psr_implicit_isovalue(f), psr_mesh_isovalue(m));
        let (mut origin, mut size) = ([0.0f64; 3], 0.0f64);
        assert_eq!(
            psr_implicit_cube(f, origin.as_mut_ptr(), &mut size),
            psr_status::Ok
        );
        assert!(size > 2.0 && size < 2.5, "{size}");
        // The grid is evaluation at the cells' centres, z fastest.
        let n = 8usize;
        let mut grid = vec![0.0f32; n * n * n];
        assert_eq!(
            psr_implicit_sample_grid(f, n, grid.as_mut_ptr(), grid.len()),
            psr_status::Ok
        );
        let mut points = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    for (a, index) in [i, j, k].into_iter().enumerate() {
                        points.push((origin[a] + (index as f64 + 0.5) * size / n as f64) as f32);
                    }
                }
            }
        }
        let mut values = vec![0.0f32; n * n * n];
        assert_eq!(
            psr_implicit_evaluate(f, points.as_ptr(), n * n * n, values.as_mut_ptr()),
            psr_status::Ok
        );
        let gamma = psr_implicit_isovalue(f) as f32;
        for (at, (g, v)) in grid.iter().zip(&values).enumerate() {
            // The C points are the grid's rounded to float: equal up to that rounding.
            assert!((g - v).abs() < 1e-4 * gamma.abs().max(1.0), "{at}: {g} {v}");
        }
        // The centre of the sphere is inside (χ − γ < 0), and ∇χ points outward there.
        let inside = [0.1f32, -0.2, 0.3];
        let on = [1.1f32, -0.2, 0.3];
        let mut value = [0.0f32];
        assert_eq!(
            psr_implicit_evaluate(f, inside.as_ptr(), 1, value.as_mut_ptr()),
            psr_status::Ok
        );
        assert!(value[0] < gamma, "{} {gamma}", value[0]);
        let mut gradient = [0.0f32; 3];
        assert_eq!(
            psr_implicit_gradient(f, on.as_ptr(), 1, gradient.as_mut_ptr()),
            psr_status::Ok
        );
        assert!(
            gradient[0] > 0.0 && gradient[0] > 10.0 * gradient[1].abs(),
            "{gradient:?}"
        );
        // A NaN coordinate: refused, nothing written.
        let bad = [0.0f32, 0.0, 0.0, 0.0, f32::NAN, 0.0];
        let mut two = [9.0f32; 6];
        assert_eq!(
            psr_implicit_evaluate(f, bad.as_ptr(), 2, two.as_mut_ptr()),
            psr_status::NonFinitePosition
        );
        assert_eq!(
            psr_implicit_gradient(f, bad.as_ptr(), 2, two.as_mut_ptr()),
            psr_status::NonFinitePosition
        );
        assert_eq!(two, [9.0; 6]);
        // Resolutions: 0 and absurd ones are parameters out of range; a short buffer is
        // refused and left untouched.
        let mut small = [5.0f32; 8];
        for resolution in [0, 4097, usize::MAX] {
            assert_eq!(
                psr_implicit_sample_grid(f, resolution, small.as_mut_ptr(), small.len()),
                psr_status::InvalidParameter,
                "{resolution}"
            );
        }
        assert_eq!(
            psr_implicit_sample_grid(f, 3, small.as_mut_ptr(), small.len()),
            psr_status::BufferTooSmall
        );
        assert_eq!(small, [5.0; 8]);
        assert_eq!(
            psr_implicit_sample_grid(f, 2, small.as_mut_ptr(), small.len()),
            psr_status::Ok
        );
        // A box: over the cube, the grid's values bit for bit; over another box, evaluation at
        // its cells' centres.
        let cube_max = origin.map(|o| o + size);
        let mut boxed = vec![0.0f32; n * n * n];
        assert_eq!(
            psr_implicit_sample_box(
                f,
                origin.as_ptr(),
                cube_max.as_ptr(),
                n,
                boxed.as_mut_ptr(),
                boxed.len()
            ),
            psr_status::Ok
        );
        assert!(boxed
            .iter()
            .zip(&grid)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let (lo, hi) = ([-0.3f64, -0.9, 0.0], [0.5f64, 0.1, 0.0]);
        let mut flat = vec![0.0f32; 27];
        assert_eq!(
            psr_implicit_sample_box(f, lo.as_ptr(), hi.as_ptr(), 3, flat.as_mut_ptr(), 27),
            psr_status::Ok
        );
        let mut centres = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    for (a, index) in [i, j, k].into_iter().enumerate() {
                        let at = lo[a] + (index as f64 + 0.5) * (hi[a] - lo[a]) / 3.0;
                        centres.push(at as f32);
                    }
                }
            }
        }
        let mut want = vec![0.0f32; 27];
        assert_eq!(
            psr_implicit_evaluate(f, centres.as_ptr(), 27, want.as_mut_ptr()),
            psr_status::Ok
        );
        for (at, (g, v)) in flat.iter().zip(&want).enumerate() {
            assert!((g - v).abs() < 1e-4 * gamma.abs().max(1.0), "{at}: {g} {v}");
        }
        // Bad boxes and arguments: refused, nothing written.
        let nan = [0.0, f64::NAN, 0.0];
        let infinite = [0.0, 0.0, f64::INFINITY];
        for (min, max, status) in [
            (ptr::null(), hi.as_ptr(), psr_status::NullArgument),
            (lo.as_ptr(), ptr::null(), psr_status::NullArgument),
            (hi.as_ptr(), lo.as_ptr(), psr_status::InvalidParameter),
            (nan.as_ptr(), hi.as_ptr(), psr_status::InvalidParameter),
            (lo.as_ptr(), infinite.as_ptr(), psr_status::InvalidParameter),
        ] {
            assert_eq!(
                psr_implicit_sample_box(f, min, max, 2, small.as_mut_ptr(), small.len()),
                status
            );
        }
        small = [5.0; 8];
        assert_eq!(
            psr_implicit_sample_box(f, lo.as_ptr(), hi.as_ptr(), 3, small.as_mut_ptr(), 8),
            psr_status::BufferTooSmall
        );
        assert_eq!(
            psr_implicit_sample_box(f, lo.as_ptr(), hi.as_ptr(), 2, ptr::null_mut(), 8),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_implicit_sample_box(
                ptr::null(),
                lo.as_ptr(),
                hi.as_ptr(),
                2,
                small.as_mut_ptr(),
                8
            ),
            psr_status::NullArgument
        );
        assert_eq!(small, [5.0; 8]);
        // The handle outlives the reconstructor and the mesh.
        psr_mesh_free(m);
        psr_reconstructor_free(r);
        assert_eq!(
            psr_implicit_evaluate(f, inside.as_ptr(), 1, value.as_mut_ptr()),
            psr_status::Ok
        );
        psr_implicit_free(f);
    }
}

#[test]
fn one_implicit_handle_is_evaluated_from_many_threads_at_once() {
    let (r, m, f) = solve_implicit();
    unsafe {
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
    let points: Vec<f32> = (0..3 * 5000)
        .map(|i| ((i * 37) % 200) as f32 / 100.0 - 1.0)
        .collect();
    let mut expected = vec![0.0f32; 5000];
    assert_eq!(
        unsafe { psr_implicit_evaluate(f, points.as_ptr(), 5000, expected.as_mut_ptr()) },
        psr_status::Ok
    );
    let shared = f as usize;
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                let f = shared as *const psr_implicit;
                let mut values = vec![0.0f32; 5000];
                for _ in 0..3 {
                    let status = unsafe {
                        psr_implicit_evaluate(f, points.as_ptr(), 5000, values.as_mut_ptr())
                    };
                    assert_eq!(status, psr_status::Ok);
                    assert_eq!(values, expected);
                }
            });
        }
    });
    unsafe { psr_implicit_free(f) };
}

// ------------------------------------------------------------------------------------------------
// Double-precision points, transforms and vertices (issue 17)
// ------------------------------------------------------------------------------------------------

const IDENTITY: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, //
    0.0, 1.0, 0.0, 0.0, //
    0.0, 0.0, 1.0, 0.0, //
    0.0, 0.0, 0.0, 1.0,
];

/// Proves: the double entries refuse NULL handles, arrays and transforms, strides below one
/// double triple, bad points (index named, nothing appended) and bad transforms
/// (PSR_STATUS_INVALID_TRANSFORM, even for an empty batch); a mesh's origin and double copy
/// refuse NULL and short buffers, writing nothing.
#[test]
fn double_entries_check_their_arguments() {
    let r = new_handle();
    let p = [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0];
    let n = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    unsafe {
        let null_r: *mut psr_reconstructor = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_add_points_f64(null_r, p.as_ptr(), 0, n.as_ptr(), 0, 2),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_add_points_f64(r, ptr::null(), 0, n.as_ptr(), 0, 2),
            psr_status::NullArgument
        );
        assert!(last_error(r).contains("positions"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_points_f64(r, p.as_ptr(), 0, ptr::null(), 0, 2),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_add_points_f64(r, ptr::null(), 0, ptr::null(), 0, 0),
            psr_status::Ok
        );
        assert_eq!(
            psr_reconstructor_add_points_f64(r, p.as_ptr(), 12, n.as_ptr(), 0, 2),
            psr_status::InvalidArgument,
            "a float stride is too short for doubles"
        );
        assert!(last_error(r).contains("24 bytes"), "{}", last_error(r));
        assert_eq!(
            psr_reconstructor_add_points_f64(r, p.as_ptr(), usize::MAX, n.as_ptr(), 0, 2),
            psr_status::InvalidArgument
        );
        let bad = [0.0f64, 0.0, 0.0, f64::NAN, 0.0, 0.0];
        assert_eq!(
            psr_reconstructor_add_points_f64(r, bad.as_ptr(), 0, n.as_ptr(), 0, 2),
            psr_status::NonFinitePosition
        );
        assert!(last_error(r).contains("point 1"), "{}", last_error(r));
        assert_eq!(point_count(r), 0);
        assert_eq!(
            psr_reconstructor_add_points_f64(r, p.as_ptr(), 0, n.as_ptr(), 0, 2),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 2);

        assert_eq!(
            psr_reconstructor_add_points_transformed(
                null_r,
                p.as_ptr(),
                0,
                n.as_ptr(),
                0,
                2,
                IDENTITY.as_ptr()
            ),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_add_points_transformed(
                r,
                p.as_ptr(),
                0,
                n.as_ptr(),
                0,
                2,
                ptr::null()
            ),
            psr_status::NullArgument
        );
        assert!(last_error(r).contains("transform"), "{}", last_error(r));
        let mut projective = IDENTITY;
        projective[12] = 1.0;
        let mut singular = IDENTITY;
        singular[10] = 0.0;
        let mut nan = IDENTITY;
        nan[3] = f64::NAN;
        for bad in [projective, singular, nan] {
            for count in [2, 0] {
                assert_eq!(
                    psr_reconstructor_add_points_transformed(
                        r,
                        p.as_ptr(),
                        0,
                        n.as_ptr(),
                        0,
                        count,
                        bad.as_ptr()
                    ),
                    psr_status::InvalidTransform,
                    "{count}"
                );
            }
        }
        assert!(last_error(r).contains("transform"), "{}", last_error(r));
        assert_eq!(point_count(r), 2);
        assert_eq!(
            psr_reconstructor_add_points_transformed(
                r,
                p.as_ptr(),
                0,
                n.as_ptr(),
                0,
                2,
                IDENTITY.as_ptr()
            ),
            psr_status::Ok
        );
        assert_eq!(point_count(r), 4);
        psr_reconstructor_free(r);

        let m = tetrahedron();
        let mut origin = [f64::NAN; 3];
        assert_eq!(
            psr_mesh_origin(ptr::null(), origin.as_mut_ptr()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_mesh_origin(m, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(psr_mesh_origin(m, origin.as_mut_ptr()), psr_status::Ok);
        assert_eq!(origin, [0.0; 3]);
        let mut out = [-1.0f64; 12];
        assert_eq!(
            psr_mesh_copy_positions_f64(ptr::null(), out.as_mut_ptr(), 12),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_mesh_copy_positions_f64(m, ptr::null_mut(), 12),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_mesh_copy_positions_f64(m, out.as_mut_ptr(), 11),
            psr_status::BufferTooSmall
        );
        assert_eq!(out, [-1.0; 12], "nothing written");
        assert_eq!(
            psr_mesh_copy_positions_f64(m, out.as_mut_ptr(), 12),
            psr_status::Ok
        );
        assert_eq!(&out[3..6], &[1.0, 0.0, 0.0]);
        psr_mesh_free(m);
        let empty = debug_mesh_new(psr::Mesh::default());
        assert_eq!(
            psr_mesh_copy_positions_f64(empty, ptr::null_mut(), 0),
            psr_status::Ok
        );
        psr_mesh_free(empty);
    }
}

/// Proves: a sphere 10^6 away added in double (packed, then through a transform that is a pure
/// translation) gives the mesh of the same sphere near 0 in float, once psr_mesh_origin is
/// added back (psr_mesh_copy_positions_f64), to 1e-6 of the diagonal.
#[test]
fn double_points_far_away_give_the_mesh_near_zero() {
    let shift = [1e6f64, -2e6, 3e5];
    let (p, nrm) = sphere(2000, [0.1, -0.2, 0.3], 1.0);
    let count = p.len() / 3;
    let near = new_handle();
    unsafe {
        assert_eq!(
            psr_reconstructor_add_points(near, p.as_ptr(), 0, nrm.as_ptr(), 0, count),
            psr_status::Ok
        );
    }
    let Some(near_mesh) = solve_or_skip(near, "double_points_far_away_give_the_mesh_near_zero")
    else {
        return;
    };
    let want = mesh_arrays(near_mesh);
    let local: Vec<f64> = p.iter().map(|&c| c as f64).collect();
    let moved: Vec<f64> = local
        .iter()
        .enumerate()
        .map(|(i, &c)| c + shift[i % 3])
        .collect();
    let mut translate = IDENTITY;
    translate[3] = shift[0];
    translate[7] = shift[1];
    translate[11] = shift[2];
    for how in ["f64", "transformed"] {
        let far = new_handle();
        let status = unsafe {
            match how {
                "f64" => {
                    psr_reconstructor_add_points_f64(far, moved.as_ptr(), 0, nrm.as_ptr(), 0, count)
                }
                _ => psr_reconstructor_add_points_transformed(
                    far,
                    local.as_ptr(),
                    0,
                    nrm.as_ptr(),
                    0,
                    count,
                    translate.as_ptr(),
                ),
            }
        };
        assert_eq!(status, psr_status::Ok, "{}", last_error(far));
        let m = solve_or_skip(far, how).unwrap();
        let vertices = unsafe { psr_mesh_vertex_count(m) };
        assert_eq!(vertices, want.0.len() / 3, "{how}");
        let mut origin = [0.0; 3];
        let mut exact = vec![0.0f64; 3 * vertices];
        unsafe {
            assert_eq!(psr_mesh_origin(m, origin.as_mut_ptr()), psr_status::Ok);
            assert_eq!(
                psr_mesh_copy_positions_f64(m, exact.as_mut_ptr(), exact.len()),
                psr_status::Ok
            );
        }
        assert!(
            origin.iter().zip(&shift).all(|(o, s)| (o - s).abs() < 8.0),
            "{origin:?}"
        );
        let worst = exact
            .iter()
            .zip(&want.0)
            .enumerate()
            .map(|(i, (&e, &w))| (e - shift[i % 3] - w as f64).abs())
            .fold(0.0, f64::max);
        // The sphere's diagonal is 2√3.
        assert!(worst < 1e-6 * 2.0 * 3f64.sqrt(), "{how}: {worst}");
        let mut triangles = vec![0u32; 3 * unsafe { psr_mesh_triangle_count(m) }];
        unsafe {
            assert_eq!(
                psr_mesh_copy_triangles(m, triangles.as_mut_ptr(), triangles.len()),
                psr_status::Ok
            );
        }
        assert_eq!(
            triangles, want.1,
            "{how}: the same triangles, index for index"
        );
        unsafe {
            psr_mesh_free(m);
            psr_reconstructor_free(far);
        }
    }
    unsafe {
        psr_mesh_free(near_mesh);
        psr_reconstructor_free(near);
    }
}

/// Proves (issue 19): the memory limit defaults to 0 (none), round-trips, and NULLs are
/// refused with out-parameters untouched; the estimates are written only on success; a limit
/// far too small gives PSR_STATUS_OUT_OF_MEMORY with no mesh and a message naming the limit,
/// the handle is not poisoned, and its next solve without a limit gives the mesh of a handle
/// that never failed, bit for bit.
#[test]
fn a_memory_limit_fails_typed_and_leaves_the_handle_usable() {
    let r = new_handle();
    let fresh = new_handle();
    add_sphere(r, 2000);
    add_sphere(fresh, 2000);
    let mut bytes = 99u64;
    unsafe {
        assert_eq!(
            psr_reconstructor_get_max_memory(r, &mut bytes),
            psr_status::Ok
        );
        assert_eq!(bytes, 0);
        assert_eq!(
            psr_reconstructor_set_max_memory(ptr::null_mut(), 5),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_get_max_memory(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        let mut estimate = 7u64;
        assert_eq!(
            psr_reconstructor_estimate_memory(ptr::null(), &mut estimate),
            psr_status::NullArgument
        );
        assert_eq!(estimate, 7);
        assert_eq!(
            psr_reconstructor_estimate_memory(r, ptr::null_mut()),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_estimate_memory(r, &mut estimate),
            psr_status::Ok
        );
        assert!(estimate > 1 << 20, "{estimate}");
        let mut free_estimate = 7u64;
        assert_eq!(
            psr_estimate_memory(0, 2000, &mut free_estimate),
            psr_status::InvalidParameter
        );
        assert_eq!(free_estimate, 7);
        assert_eq!(
            psr_estimate_memory(8, 2000, ptr::null_mut()),
            psr_status::NullArgument
        );
        // The handle's default depth is 8, so the free estimate at depth 8 is the same.
        assert_eq!(
            psr_estimate_memory(8, 2000, &mut free_estimate),
            psr_status::Ok
        );
        assert_eq!(free_estimate, estimate);

        assert_eq!(psr_reconstructor_set_max_memory(r, 1000), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_get_max_memory(r, &mut bytes),
            psr_status::Ok
        );
        assert_eq!(bytes, 1000);
        let mut mesh = sentinel_ptr::<psr_mesh>();
        assert_eq!(
            psr_reconstructor_solve(r, &mut mesh),
            psr_status::OutOfMemory
        );
        assert_eq!(mesh, sentinel_ptr(), "out-parameter untouched on failure");
        let message = last_error(r);
        assert!(
            message.contains("memory limit of 1000 bytes") && message.contains("allow at least"),
            "{message}"
        );
        let name = CStr::from_ptr(psr_status_string(psr_status::OutOfMemory as i32));
        assert_eq!(name.to_str().unwrap(), "PSR_STATUS_OUT_OF_MEMORY");

        assert_eq!(psr_reconstructor_set_max_memory(r, 0), psr_status::Ok);
        let mut after = ptr::null_mut();
        let mut expected = ptr::null_mut();
        assert_eq!(psr_reconstructor_solve(r, &mut after), psr_status::Ok);
        assert_eq!(
            psr_reconstructor_solve(fresh, &mut expected),
            psr_status::Ok
        );
        let nv = psr_mesh_vertex_count(after);
        let nt = psr_mesh_triangle_count(after);
        assert_eq!(nv, psr_mesh_vertex_count(expected));
        assert_eq!(nt, psr_mesh_triangle_count(expected));
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_positions(after), 3 * nv),
            std::slice::from_raw_parts(psr_mesh_positions(expected), 3 * nv)
        );
        assert_eq!(
            std::slice::from_raw_parts(psr_mesh_triangles(after), 3 * nt),
            std::slice::from_raw_parts(psr_mesh_triangles(expected), 3 * nt)
        );
        // A limit of the estimate lets the same solve through.
        assert_eq!(
            psr_reconstructor_set_max_memory(r, estimate),
            psr_status::Ok
        );
        let mut again = ptr::null_mut();
        assert_eq!(
            psr_reconstructor_solve(r, &mut again),
            psr_status::Ok,
            "{}",
            last_error(r)
        );
        psr_mesh_free(again);
        psr_mesh_free(after);
        psr_mesh_free(expected);
        psr_reconstructor_free(r);
        psr_reconstructor_free(fresh);
    }
}

// ---------------------------------------------------------------------------------------------
// PLY files: psr_ply_read and its views, psr_mesh_write_ply
// ---------------------------------------------------------------------------------------------

/// A fresh, empty directory of its own under the system's temporary directory, removed with
/// the value (so that a test run leaves nothing behind).
struct ScratchDir(std::path::PathBuf);

impl ScratchDir {
    fn new(test: &str) -> ScratchDir {
        let dir = std::env::temp_dir().join(format!("psr-ffi-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        ScratchDir(dir)
    }

    fn path(&self, name: &str) -> std::path::PathBuf {
        self.0.join(name)
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn c_path(path: &std::path::Path) -> std::ffi::CString {
    std::ffi::CString::new(path.to_str().unwrap()).unwrap()
}

/// psr_ply_read's status, handle (NULL on failure; `out` must then be untouched) and message.
fn read_ply(path: *const std::ffi::c_char) -> (psr_status, *mut psr_ply, String) {
    let sentinel = sentinel_ptr::<psr_ply>();
    let mut out = sentinel;
    let mut message = [0x55 as std::ffi::c_char; 512];
    let status = unsafe { psr_ply_read(path, &mut out, message.as_mut_ptr(), message.len()) };
    let text = unsafe { CStr::from_ptr(message.as_ptr()) }
        .to_string_lossy()
        .into_owned();
    if status == psr_status::Ok {
        assert!(!out.is_null() && out != sentinel);
        assert_eq!(text, "", "a success writes an empty message");
        (status, out, text)
    } else {
        assert_eq!(out, sentinel, "*out must be left untouched on failure");
        (status, ptr::null_mut(), text)
    }
}

/// `count` values at `p` (NULL: none) as a vector.
fn values<T: Copy>(p: *const T, count: usize) -> Option<Vec<T>> {
    (!p.is_null()).then(|| unsafe { std::slice::from_raw_parts(p, count) }.to_vec())
}

/// Proves: psr_ply_read reads the sample cloud as the Rust reader does (positions and normals,
/// no faces, no colours), and the views are NULL for what the file lacks and for a NULL handle.
#[test]
fn ply_read_gives_what_the_rust_reader_reads() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/kitten_cgal.ply");
    let expected = psr::ply::read_points(&path).unwrap();
    let (status, p, _) = read_ply(c_path(&path).as_ptr());
    assert_eq!(status, psr_status::Ok);
    unsafe {
        let n = psr_ply_vertex_count(p);
        assert_eq!(n, expected.positions.len());
        assert_eq!(
            values(psr_ply_positions(p), 3 * n).unwrap(),
            expected.positions.as_flattened()
        );
        assert_eq!(
            values(psr_ply_normals(p), 3 * n).unwrap(),
            expected.normals.as_flattened()
        );
        assert!(psr_ply_positions_f64(p).is_null() && psr_ply_colors(p).is_null());
        assert_eq!(psr_ply_color_components(p), 0);
        assert!(psr_ply_sensors(p).is_null() && psr_ply_triangles(p).is_null());
        assert_eq!(psr_ply_triangle_count(p), 0);
        assert_eq!(psr_ply_channel_count(p), expected.channels.len());
        assert!(psr_ply_channel_name(p, 99).is_null() && psr_ply_channel(p, 99).is_null());
        psr_ply_free(p);
        // NULL handles: zero counts and NULL views, and free(NULL) does nothing.
        let null = ptr::null();
        assert_eq!(psr_ply_vertex_count(null) + psr_ply_triangle_count(null), 0);
        assert!(psr_ply_positions(null).is_null() && psr_ply_channel_name(null, 0).is_null());
        psr_ply_free(ptr::null_mut());
    }
}

/// Proves: bad arguments and bad files get their statuses and a message that names the
/// function and the problem (the path, the system's reason, the line), *out is untouched, and
/// a short or absent message buffer is safe.
#[test]
fn ply_read_refuses_bad_arguments_and_files_with_a_message() {
    let (status, _, message) = read_ply(ptr::null());
    assert_eq!(status, psr_status::NullArgument);
    assert_eq!(message, "psr_ply_read: path is NULL");
    let empty = std::ffi::CString::new("").unwrap();
    assert_eq!(read_ply(empty.as_ptr()).0, psr_status::InvalidArgument);
    let kitten = c_path(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/kitten_cgal.ply"),
    );
    assert_eq!(
        unsafe { psr_ply_read(kitten.as_ptr(), ptr::null_mut(), ptr::null_mut(), 0) },
        psr_status::NullArgument
    );

    let dir = ScratchDir::new("ply-read");
    let missing = dir.path("missing.ply");
    let (status, _, message) = read_ply(c_path(&missing).as_ptr());
    assert_eq!(status, psr_status::IoError);
    assert!(
        message.starts_with("psr_ply_read: ") && message.contains("missing.ply"),
        "{message}"
    );

    let bad = dir.path("bad.ply");
    let cases: [(&[u8], &str); 4] = [
        (b"solid cube\n", "not a PLY file"),
        (
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
            "x y z",
        ),
        (
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 0\n1 1\n",
            "line 9",
        ),
        (
            b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\n\
              property float y\nproperty float z\nend_header\n\0\0\0\0",
            "truncated",
        ),
    ];
    for (bytes, says) in cases {
        std::fs::write(&bad, bytes).unwrap();
        let (status, _, message) = read_ply(c_path(&bad).as_ptr());
        assert_eq!(status, psr_status::InvalidFile, "{message}");
        assert!(message.contains(says), "wanted '{says}' in: {message}");
    }
    // A message buffer of 8 bytes gets 7 bytes and the NUL; NULL gets nothing.
    let mut short = [0x55 as std::ffi::c_char; 12];
    let mut out = ptr::null_mut();
    let status = unsafe { psr_ply_read(c_path(&bad).as_ptr(), &mut out, short.as_mut_ptr(), 8) };
    assert_eq!(status, psr_status::InvalidFile);
    assert_eq!(
        unsafe { CStr::from_ptr(short.as_ptr()) }.to_bytes(),
        b"psr_ply"
    );
    assert_eq!(short[8], 0x55, "wrote past the capacity");
    let status = unsafe { psr_ply_read(c_path(&bad).as_ptr(), &mut out, ptr::null_mut(), 99) };
    assert_eq!(status, psr_status::InvalidFile);
}

/// Proves: psr_mesh_write_ply writes the bytes the Rust writer (the psr program's) writes, in
/// each format; psr_ply_read gives the mesh back (positions, triangles, densities as `value`,
/// normals, colours, channels); bad flags and an unwritable path are refused with a message.
#[test]
fn mesh_write_ply_writes_what_the_program_writes_and_reads_back() {
    let mut mesh = psr::Mesh::default();
    mesh.positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.25],
        [1.0, 1.0, 0.5],
    ];
    mesh.triangles = vec![[0, 1, 2], [2, 1, 3]];
    mesh.densities = vec![1.0, 2.0, 3.0, 4.0];
    mesh.normals = vec![[0.0, 0.0, 1.0]; 4];
    mesh.colors = Some(psr::Colors::Rgba(vec![[0.2, 0.4, 0.6, 1.0]; 4]));
    mesh.channels = vec![psr::Channel::new("time", vec![9.0, 8.0, 7.0, 6.0])];
    let m = debug_mesh_new(mesh.clone());
    let dir = ScratchDir::new("ply-write");
    let path = dir.path("mesh.ply");
    let cpath = c_path(&path);
    for (flags, format) in [
        (0, psr::ply::PlyFormat::BinaryLittleEndian),
        (PSR_PLY_ASCII, psr::ply::PlyFormat::Ascii),
        (PSR_PLY_BIG_ENDIAN, psr::ply::PlyFormat::BinaryBigEndian),
    ] {
        let mut message = [0x55 as std::ffi::c_char; 64];
        let status = unsafe {
            psr_mesh_write_ply(
                m,
                cpath.as_ptr(),
                flags,
                message.as_mut_ptr(),
                message.len(),
            )
        };
        assert_eq!(status, psr_status::Ok);
        assert_eq!(message[0], 0, "a success writes an empty message");
        let mut expected = Vec::new();
        let options = psr::ply::WriteOptions::default().with_format(format);
        psr::ply::write_mesh_to_with(&mut expected, &mesh, &options).unwrap();
        assert!(std::fs::read(&path).unwrap() == expected, "{format:?}");

        let (status, p, _) = read_ply(cpath.as_ptr());
        assert_eq!(status, psr_status::Ok);
        unsafe {
            assert_eq!(psr_ply_vertex_count(p), 4);
            assert_eq!(
                values(psr_ply_triangles(p), 6).unwrap(),
                mesh.triangles.as_flattened()
            );
            assert_eq!(
                values(psr_ply_positions(p), 12).unwrap(),
                mesh.positions.as_flattened()
            );
            assert_eq!(values(psr_ply_confidence(p), 4).unwrap(), mesh.densities);
            assert_eq!(
                values(psr_ply_normals(p), 12).unwrap(),
                mesh.normals.as_flattened()
            );
            assert_eq!(psr_ply_color_components(p), 4);
            // uchar colours: within half a step of 1/255.
            let colors = values(psr_ply_colors(p), 16).unwrap();
            let want = mesh.colors.as_ref().unwrap().as_flattened();
            assert!(colors
                .iter()
                .zip(want)
                .all(|(a, b)| (a - b).abs() <= 0.5 / 255.0 + 1e-6));
            assert_eq!(psr_ply_channel_count(p), 1);
            assert_eq!(
                CStr::from_ptr(psr_ply_channel_name(p, 0)).to_str().unwrap(),
                "time"
            );
            assert_eq!(
                values(psr_ply_channel(p, 0), 4).unwrap(),
                mesh.channels[0].values
            );
            psr_ply_free(p);
        }
    }
    // Double positions: x y z as double, read back exactly through psr_ply_positions_f64.
    let status = unsafe {
        psr_mesh_write_ply(
            m,
            cpath.as_ptr(),
            PSR_PLY_DOUBLE_POSITIONS,
            ptr::null_mut(),
            0,
        )
    };
    assert_eq!(status, psr_status::Ok);
    let (_, p, _) = read_ply(cpath.as_ptr());
    let exact = unsafe { values(psr_ply_positions_f64(p), 12) }.expect("double positions");
    assert!(exact
        .iter()
        .zip(mesh.positions.as_flattened())
        .all(|(&a, &b)| a == b as f64));
    unsafe { psr_ply_free(p) };

    let write = |m: *const psr_mesh, path: *const std::ffi::c_char, flags: u32| {
        let mut message = [0 as std::ffi::c_char; 256];
        let status =
            unsafe { psr_mesh_write_ply(m, path, flags, message.as_mut_ptr(), message.len()) };
        let text = unsafe { CStr::from_ptr(message.as_ptr()) }
            .to_string_lossy()
            .into_owned();
        (status, text)
    };
    assert_eq!(
        write(ptr::null(), cpath.as_ptr(), 0).0,
        psr_status::NullArgument
    );
    assert_eq!(write(m, ptr::null(), 0).0, psr_status::NullArgument);
    let (status, message) = write(m, cpath.as_ptr(), PSR_PLY_ASCII | PSR_PLY_BIG_ENDIAN);
    assert_eq!(status, psr_status::InvalidArgument);
    assert!(message.contains("text or binary"), "{message}");
    let (status, message) = write(m, cpath.as_ptr(), 1 << 8);
    assert_eq!(status, psr_status::InvalidArgument);
    assert!(message.contains("0x100"), "{message}");
    let nowhere = dir.path("no/such/dir/mesh.ply");
    let (status, message) = write(m, c_path(&nowhere).as_ptr(), 0);
    assert_eq!(status, psr_status::IoError);
    assert!(message.contains("no/such/dir"), "{message}");
    unsafe { psr_mesh_free(m) };
}

// ---------------------------------------------------------------------------------------------
// Out of core: psr_reconstructor_solve_file_out_of_core
// ---------------------------------------------------------------------------------------------

/// A [`ScratchDir`] with a subdirectory `temp` for the run's temporary directory, so that what
/// the run leaves there can be listed.
struct OutOfCoreDir(ScratchDir);

impl OutOfCoreDir {
    fn new(test: &str) -> OutOfCoreDir {
        let dir = ScratchDir::new(&format!("ooc-{test}"));
        std::fs::create_dir_all(dir.path("temp")).unwrap();
        OutOfCoreDir(dir)
    }

    fn path(&self, name: &str) -> std::path::PathBuf {
        self.0.path(name)
    }

    /// What the runs left under `temp`.
    fn left_in_temp(&self) -> Vec<String> {
        std::fs::read_dir(self.path("temp"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect()
    }
}

/// Writes `n` oriented points on a sphere (binary PLY) to `path` with psr's writer, and returns
/// them flattened as [`sphere`] gives them.
fn write_sphere_ply(path: &std::path::Path, n: usize) -> (Vec<f32>, Vec<f32>) {
    let (p, nrm) = sphere(n, [0.1, -0.2, 0.3], 1.0);
    write_cloud_ply(path, &p, &nrm);
    (p, nrm)
}

/// Writes a binary PLY of the points with positions `p` and normals `nrm` (x y z per point).
fn write_cloud_ply(path: &std::path::Path, p: &[f32], nrm: &[f32]) {
    let triples = |v: &[f32]| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let mut cloud = psr::ply::PlyPoints::default();
    cloud.positions = triples(p);
    cloud.normals = triples(nrm);
    psr::ply::write_point_cloud(path, &cloud, psr::ply::PlyFormat::BinaryLittleEndian).unwrap();
}

/// A report whose every field is a value no run gives, to see that a failure leaves it alone.
fn sentinel_report() -> psr_out_of_core_report {
    psr_out_of_core_report {
        points: 77,
        vertices: 77,
        triangles: 77,
        slabs: 77,
        depth: 77,
        attributes_dropped: 77,
        unsupported_components: 77,
        isovalue: 77.0,
        seconds: 77.0,
    }
}

/// The parameters of these tests, on `r`: depth 6 and full depth 4. The slabs' shared base is
/// solved to the depth − 3 but at least the full depth, and must stay 2 below the finest depth
/// the samples reach (6 for 20,000 points on the unit sphere), so the default full depth of 5
/// would be refused (PSR_STATUS_INVALID_PARAMETER, base_depth).
fn out_of_core_parameters(r: *mut psr_reconstructor) {
    unsafe {
        assert_eq!(psr_reconstructor_set_depth(r, 6), psr_status::Ok);
        assert_eq!(psr_reconstructor_set_full_depth(r, 4), psr_status::Ok);
    }
}

/// psr_reconstructor_solve_file_out_of_core on paths, with the report it wrote (or left).
fn solve_file_out_of_core(
    r: *mut psr_reconstructor,
    input: &std::path::Path,
    output: &std::path::Path,
    temp_dir: Option<&std::path::Path>,
    slabs: usize,
) -> (psr_status, psr_out_of_core_report) {
    let (input, output) = (c_path(input), c_path(output));
    let temp_dir = temp_dir.map(c_path);
    let mut report = sentinel_report();
    let status = unsafe {
        psr_reconstructor_solve_file_out_of_core(
            r,
            input.as_ptr(),
            output.as_ptr(),
            temp_dir.as_ref().map_or(ptr::null(), |t| t.as_ptr()),
            slabs,
            0,
            &mut report,
        )
    };
    (status, report)
}

/// Proves: NULL for the handle or either path is PSR_STATUS_NULL_ARGUMENT, an empty path (the
/// input, the output or the temporary directory's parent) PSR_STATUS_INVALID_ARGUMENT, a
/// missing input PSR_STATUS_IO_ERROR with the path in psr_reconstructor_last_error, vertex
/// normals and zero slabs without a memory limit PSR_STATUS_INVALID_PARAMETER naming the
/// parameter; each leaves the report untouched and writes no output; a NULL report is allowed.
#[test]
fn out_of_core_refuses_null_and_empty_arguments_a_missing_file_and_bad_parameters() {
    let dir = OutOfCoreDir::new("arguments");
    let input = dir.path("sphere.ply");
    write_sphere_ply(&input, 20_000);
    let output = dir.path("mesh.ply");
    let (cin, cout) = (c_path(&input), c_path(&output));
    let empty = std::ffi::CString::new("").unwrap();
    let r = new_handle();
    unsafe {
        let mut report = sentinel_report();
        let call = |r, i, o, t, report: *mut psr_out_of_core_report| {
            psr_reconstructor_solve_file_out_of_core(r, i, o, t, 3, 0, report)
        };
        assert_eq!(
            call(
                ptr::null_mut(),
                cin.as_ptr(),
                cout.as_ptr(),
                ptr::null(),
                &mut report
            ),
            psr_status::NullArgument
        );
        assert!(last_error(ptr::null()).contains("NULL"));
        assert_eq!(
            call(r, ptr::null(), cout.as_ptr(), ptr::null(), &mut report),
            psr_status::NullArgument
        );
        assert!(last_error(r).contains("NULL"), "{}", last_error(r));
        assert_eq!(
            call(r, cin.as_ptr(), ptr::null(), ptr::null(), &mut report),
            psr_status::NullArgument
        );
        for (i, o, t) in [
            (empty.as_ptr(), cout.as_ptr(), ptr::null()),
            (cin.as_ptr(), empty.as_ptr(), ptr::null()),
            (cin.as_ptr(), cout.as_ptr(), empty.as_ptr()),
        ] {
            assert_eq!(
                call(r, i, o, t, &mut report),
                psr_status::InvalidArgument,
                "{}",
                last_error(r)
            );
            assert!(
                last_error(r).starts_with("psr_reconstructor_solve_file_out_of_core"),
                "{}",
                last_error(r)
            );
        }
        assert_eq!(report, sentinel_report(), "failures leave the report alone");
    }
    assert!(!output.exists(), "no output from refused arguments");

    let missing = dir.path("no-such-cloud.ply");
    let (status, report) = solve_file_out_of_core(r, &missing, &output, None, 3);
    assert_eq!(status, psr_status::IoError, "{}", last_error(r));
    assert!(
        last_error(r).contains("no-such-cloud.ply"),
        "the message names the path: {}",
        last_error(r)
    );
    assert_eq!(report, sentinel_report());

    // Zero slabs chooses them from the memory limit, so one must be set.
    out_of_core_parameters(r);
    let (status, report) = solve_file_out_of_core(r, &input, &output, None, 0);
    assert_eq!(status, psr_status::InvalidParameter, "{}", last_error(r));
    assert!(last_error(r).contains("max_memory"), "{}", last_error(r));
    assert_eq!(report, sentinel_report());
    // Vertex normals are not written on this path.
    unsafe {
        assert_eq!(
            psr_reconstructor_set_vertex_normals(r, true),
            psr_status::Ok
        )
    };
    let (status, _) = solve_file_out_of_core(r, &input, &output, None, 3);
    assert_eq!(status, psr_status::InvalidParameter, "{}", last_error(r));
    assert!(
        last_error(r).contains("vertex_normals"),
        "{}",
        last_error(r)
    );
    unsafe {
        assert_eq!(
            psr_reconstructor_set_vertex_normals(r, false),
            psr_status::Ok
        )
    };
    assert!(!output.exists());

    // The handle still works, and report may be NULL.
    let status = unsafe {
        psr_reconstructor_solve_file_out_of_core(
            r,
            cin.as_ptr(),
            cout.as_ptr(),
            ptr::null(),
            2,
            0,
            ptr::null_mut(),
        )
    };
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(output.exists());
    unsafe { psr_reconstructor_free(r) };
}

/// Proves: a run on 20,000 oriented points at depth 6 in 3 slabs writes a closed, manifold
/// mesh whose counts are the report's (read back with psr_ply_read), reports the points, the
/// slabs and the depth, removes its temporary directory from the temp_dir given, reports its
/// passes on the calling thread as stages in order (calls on the handle from the callback are
/// refused), and has the in-memory solve's vertex count to within 1%.
#[test]
fn out_of_core_writes_the_mesh_its_report_describes_and_leaves_no_temporary_file() {
    const N: usize = 20_000;
    let dir = OutOfCoreDir::new("run");
    let input = dir.path("sphere.ply");
    let (p, nrm) = write_sphere_ply(&input, N);
    let output = dir.path("mesh.ply");
    let r = new_handle();
    out_of_core_parameters(r);
    let mut rec = Recorder {
        reenter: r,
        ..Default::default()
    };
    unsafe {
        let user = ptr::addr_of_mut!(rec).cast::<c_void>();
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, Some(record), user),
            psr_status::Ok
        );
    }
    let (status, report) = solve_file_out_of_core(r, &input, &output, Some(&dir.path("temp")), 3);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(
        dir.left_in_temp().is_empty(),
        "temporary files left: {:?}",
        dir.left_in_temp()
    );
    assert_eq!(report.points, N as u64);
    assert_eq!(report.slabs, 3);
    assert_eq!(report.depth, 6);
    assert_eq!(report.attributes_dropped, 0);
    assert_eq!(report.unsupported_components, 0);
    assert!(report.isovalue.is_finite() && report.isovalue != 77.0);
    assert!(report.seconds >= 0.0 && report.seconds < 60.0);

    // The file holds what the report says, as a closed manifold surface.
    let (status, ply, message) = read_ply(c_path(&output).as_ptr());
    assert_eq!(status, psr_status::Ok, "{message}");
    let (nv, nt) = unsafe { (psr_ply_vertex_count(ply), psr_ply_triangle_count(ply)) };
    assert_eq!(report.vertices, nv as u64);
    assert_eq!(report.triangles, nt as u64);
    let positions = values(unsafe { psr_ply_positions(ply) }, 3 * nv).unwrap();
    let triangles = values(unsafe { psr_ply_triangles(ply) }, 3 * nt).unwrap();
    assert!(
        !unsafe { psr_ply_confidence(ply) }.is_null(),
        "the densities are written as value"
    );
    unsafe { psr_ply_free(ply) };
    let topology = psr_test_support::MeshTopology::of(
        &triples(&positions),
        &triangles
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect::<Vec<_>>(),
    );
    assert_eq!(topology.boundary_edges, 0, "{topology:?}");
    assert_eq!(topology.non_manifold_edges, 0, "{topology:?}");
    assert_eq!(topology.duplicate_vertices, 0, "{topology:?}");
    assert_eq!(topology.components, 1, "{topology:?}");

    // The passes were reported on this thread, as stages in order, each fraction in [0, 1];
    // calls on r from the callback were refused.
    let me = std::thread::current().id();
    assert!(rec.threads.iter().all(|&t| t == me));
    assert_eq!(rec.bad_fractions, 0);
    assert_eq!(
        rec.stages,
        [
            psr_stage::Points,
            psr_stage::System,
            psr_stage::Solve,
            psr_stage::Isovalue,
            psr_stage::Extract,
            psr_stage::Mesh
        ]
    );
    assert!(!rec.reentry_statuses.is_empty());
    assert!(rec
        .reentry_statuses
        .iter()
        .all(|&s| s == psr_status::InvalidArgument));

    // The in-memory mesh of the same points and parameters has as many vertices, within 1%.
    let memory = new_handle();
    out_of_core_parameters(memory);
    unsafe {
        assert_eq!(
            psr_reconstructor_add_points(memory, p.as_ptr(), 0, nrm.as_ptr(), 0, N),
            psr_status::Ok
        );
        let mut m = ptr::null_mut();
        assert_eq!(psr_reconstructor_solve(memory, &mut m), psr_status::Ok);
        let want = psr_mesh_vertex_count(m) as f64;
        assert!(
            (nv as f64 - want).abs() <= 0.01 * want,
            "{nv} vertices out of core, {want} in memory"
        );
        psr_mesh_free(m);
        psr_reconstructor_free(memory);
        psr_reconstructor_free(r);
    }
}

/// Proves psr_reconstructor_out_of_core_noise: NULL arguments are PSR_STATUS_NULL_ARGUMENT;
/// before any run, and after a failed one, PSR_STATUS_INVALID_ARGUMENT naming the function;
/// after a run on a sphere jittered by 0.004 of its radius in 3 slabs, the in-memory mesh's
/// psr_mesh_sample_noise and psr_mesh_screening_depth bit for bit (a sigma above 0, a screening
/// depth below the depth), no cell past the padding; with the screening not following the
/// noise, NaN and the depth.
#[test]
fn out_of_core_noise_is_the_in_memory_reading_of_the_last_run() {
    const N: usize = 20_000;
    let dir = OutOfCoreDir::new("noise");
    let (p, nrm) = sphere(N, [0.1, -0.2, 0.3], 1.0);
    let points: Vec<[f32; 3]> = p.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let jittered: Vec<f32> = psr_test_support::jitter_positions(&points, 0.004, 29)
        .into_iter()
        .flatten()
        .collect();
    let input = dir.path("noisy-sphere.ply");
    write_cloud_ply(&input, &jittered, &nrm);
    let output = dir.path("mesh.ply");
    let r = new_handle();
    out_of_core_parameters(r);
    let read = |r: *const psr_reconstructor| {
        let mut noise = psr_out_of_core_noise {
            sample_noise: 77.0,
            screening_depth: 77.0,
            cells_beyond_padding: 77,
        };
        let status = unsafe { psr_reconstructor_out_of_core_noise(r, &mut noise) };
        (status, noise)
    };
    unsafe {
        let mut noise = psr_out_of_core_noise::default();
        assert_eq!(
            psr_reconstructor_out_of_core_noise(ptr::null(), &mut noise),
            psr_status::NullArgument
        );
        assert_eq!(
            psr_reconstructor_out_of_core_noise(r, ptr::null_mut()),
            psr_status::NullArgument
        );
    }
    let refused = |r: *const psr_reconstructor| {
        let (status, noise) = read(r);
        assert_eq!(status, psr_status::InvalidArgument);
        assert_eq!(
            noise.cells_beyond_padding, 77,
            "a refusal leaves *out alone"
        );
        assert!(
            last_error(r).starts_with("psr_reconstructor_out_of_core_noise"),
            "{}",
            last_error(r)
        );
    };
    refused(r);

    // The in-memory reading of the same points and parameters.
    let memory = new_handle();
    out_of_core_parameters(memory);
    let (sigma, screening_depth) = unsafe {
        assert_eq!(
            psr_reconstructor_add_points(memory, jittered.as_ptr(), 0, nrm.as_ptr(), 0, N),
            psr_status::Ok
        );
        let mut m = ptr::null_mut();
        assert_eq!(psr_reconstructor_solve(memory, &mut m), psr_status::Ok);
        let (mut sigma, mut depth) = (0.0, 0.0);
        assert_eq!(psr_mesh_sample_noise(m, &mut sigma), psr_status::Ok);
        assert_eq!(psr_mesh_screening_depth(m, &mut depth), psr_status::Ok);
        psr_mesh_free(m);
        psr_reconstructor_free(memory);
        (sigma, depth)
    };
    assert!(
        sigma > 0.0 && screening_depth < 6.0,
        "σ {sigma}, s {screening_depth}"
    );

    let (status, _) = solve_file_out_of_core(r, &input, &output, None, 3);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    let (status, noise) = read(r);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert_eq!(
        noise.sample_noise.to_bits(),
        sigma.to_bits(),
        "{noise:?} against {sigma}"
    );
    assert_eq!(noise.screening_depth.to_bits(), screening_depth.to_bits());
    assert_eq!(noise.cells_beyond_padding, 0);

    unsafe {
        assert_eq!(
            psr_reconstructor_set_screening_follows_noise(r, false),
            psr_status::Ok
        );
    }
    let (status, _) = solve_file_out_of_core(r, &input, &output, None, 3);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    let (status, noise) = read(r);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(noise.sample_noise.is_nan(), "{noise:?}");
    assert_eq!(noise.screening_depth, 6.0);
    assert_eq!(noise.cells_beyond_padding, 0);

    // A failed run leaves nothing to read.
    let (status, _) = solve_file_out_of_core(r, &dir.path("missing.ply"), &output, None, 3);
    assert_eq!(status, psr_status::IoError);
    refused(r);
    unsafe { psr_reconstructor_free(r) };
}

/// Proves: a progress callback that says stop at the first report of any of the passes'
/// stages gets PSR_STATUS_CANCELLED, no call after it, the report untouched and no file left
/// in the temp_dir given; the handle then runs to the end.
#[test]
fn out_of_core_cancelled_from_the_callback_leaves_no_temporary_file() {
    let dir = OutOfCoreDir::new("cancel");
    let input = dir.path("sphere.ply");
    write_sphere_ply(&input, 20_000);
    let output = dir.path("mesh.ply");
    let temp = dir.path("temp");
    let r = new_handle();
    out_of_core_parameters(r);
    for stage in [
        psr_stage::Points,
        psr_stage::System,
        psr_stage::Solve,
        psr_stage::Isovalue,
        psr_stage::Extract,
        psr_stage::Mesh,
    ] {
        let mut s = StopInside {
            stage,
            stopped_at: None,
            calls_after_stop: 0,
        };
        unsafe {
            let user = ptr::addr_of_mut!(s).cast::<c_void>();
            assert_eq!(
                psr_reconstructor_set_progress_callback(r, Some(stop_inside), user),
                psr_status::Ok
            );
        }
        let (status, report) = solve_file_out_of_core(r, &input, &output, Some(&temp), 3);
        assert_eq!(
            status,
            psr_status::Cancelled,
            "{stage:?}: {}",
            last_error(r)
        );
        assert!(last_error(r).contains("cancelled"), "{}", last_error(r));
        assert!(s.stopped_at.is_some(), "{stage:?} was reported");
        assert_eq!(s.calls_after_stop, 0, "{stage:?}: called after the stop");
        assert_eq!(report, sentinel_report(), "{stage:?}");
        assert!(
            dir.left_in_temp().is_empty(),
            "{stage:?}: temporary files left: {:?}",
            dir.left_in_temp()
        );
    }
    unsafe {
        assert_eq!(
            psr_reconstructor_set_progress_callback(r, None, ptr::null_mut()),
            psr_status::Ok
        );
    }
    let (status, report) = solve_file_out_of_core(r, &input, &output, Some(&temp), 3);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert_eq!(report.slabs, 3);
    assert!(dir.left_in_temp().is_empty());
    unsafe { psr_reconstructor_free(r) };
}

/// Proves: zero slabs with a memory limit chooses the slabs from it; a limit no cut fits is
/// PSR_STATUS_OUT_OF_MEMORY before any slab is solved, its message giving a workable limit.
#[test]
fn out_of_core_slabs_from_the_memory_limit() {
    let dir = OutOfCoreDir::new("budget");
    let input = dir.path("sphere.ply");
    write_sphere_ply(&input, 20_000);
    let output = dir.path("mesh.ply");
    let r = new_handle();
    out_of_core_parameters(r);
    unsafe { assert_eq!(psr_reconstructor_set_max_memory(r, 4096), psr_status::Ok) };
    let (status, report) = solve_file_out_of_core(r, &input, &output, Some(&dir.path("temp")), 0);
    assert_eq!(status, psr_status::OutOfMemory, "{}", last_error(r));
    assert!(
        last_error(r).contains("memory limit of 4.00 KiB")
            && last_error(r).contains("allow at least"),
        "{}",
        last_error(r)
    );
    assert_eq!(report, sentinel_report());
    assert!(dir.left_in_temp().is_empty(), "{:?}", dir.left_in_temp());
    unsafe { assert_eq!(psr_reconstructor_set_max_memory(r, 1 << 30), psr_status::Ok) };
    let (status, report) = solve_file_out_of_core(r, &input, &output, Some(&dir.path("temp")), 0);
    assert_eq!(status, psr_status::Ok, "{}", last_error(r));
    assert!(report.slabs >= 1 && report.points == 20_000, "{report:?}");
    assert!(dir.left_in_temp().is_empty(), "{:?}", dir.left_in_temp());
    unsafe { psr_reconstructor_free(r) };
}

//! Fuzzer-chosen sequences of C API calls, as a C host could make them.
//!
//! Up to [`MAX_HANDLES`] reconstructors, meshes and implicit functions are live at once; each
//! operation picks one by index (or passes NULL), with arbitrary parameter values, strides,
//! struct sizes and buffer capacities. What the header allows a caller to get wrong is fuzzed
//! (NULLs, bad values, sizes, capacities, strides, call order); what it makes undefined is not
//! (a dangling handle, a buffer shorter than the count or capacity the caller states, a struct
//! smaller than the struct_size it states: [`StructBuffer`] is always as large as the largest
//! struct_size the library reads).
//!
//! Checked after every call: no status is PSR_STATUS_INTERNAL_ERROR or
//! PSR_STATUS_HANDLE_POISONED (a caught panic), every error message is a C string, every solved
//! mesh is an oriented manifold with finite vertices. Every handle is freed at the end (LeakSanitizer, which
//! cargo-fuzz's default AddressSanitizer build includes, reports a leak).
//!
//! Solves run only when the reconstructor asks for depth ≤ 7, no width, ≤ 8 threads and
//! ≤ 2,000 points, so that a run takes milliseconds.

use crate::mesh_check::{assert_finite, assert_oriented_manifold};
use arbitrary::{Arbitrary, Unstructured};
use psr::ffi::*;
use std::ffi::{c_void, CStr};
use std::mem::size_of;
use std::ptr;

/// Live handles of each kind at most.
const MAX_HANDLES: usize = 3;
/// Operations per input at most.
const MAX_OPS: usize = 64;
/// The largest struct_size the library accepts (it refuses larger ones without reading).
const STRUCT_BUFFER: usize = 4096;

/// One call, with the fuzzer's choices.
#[derive(Arbitrary, Debug)]
enum Op {
    New,
    Free(u8),
    SetParam(u8, Param),
    GetParams(u8, bool),
    AddPoints(u8, Batch),
    AddPointsF64(u8, Batch),
    AddPointsTransformed(u8, Batch, Option<[i8; 16]>),
    AddPositions(u8, Batch, Sensors),
    AddPointArrays(u8, Batch, Extras, u16),
    ClearPoints(u8),
    PointCount(u8),
    EstimateMemory(u8, u8, u32),
    Progress(u8, Option<u16>),
    Solve(u8, bool),
    MeshRead(u8, u32, u8),
    MeshTrim(u8, u8, i8, u16),
    MeshFree(u8),
    ImplicitRead(u8, Vec<[i8; 3]>, u8, u32),
    ImplicitFree(u8),
    Strings(i32),
}

/// A parameter and a raw value for its setter.
#[derive(Arbitrary, Debug)]
enum Param {
    Depth(u32),
    Width(f64),
    FullDepth(u32),
    KernelDepth(i32),
    SamplesPerNode(f32),
    Scale(f32),
    PointWeight(f32),
    Threads(u32),
    Iterations(u32),
    Tolerance(f64),
    Boundary(i32),
    Splatting(i32),
    Placement(i32),
    MinComponentSamples(u32),
    NormalNeighbors(u32),
    NormalOrientation(i32),
    Viewpoint(f64, f64, f64),
    VertexNormals(bool),
    Degree(i32),
    MaxMemory(u64),
}

/// Points of one batch: small integer coordinates (so duplicates and degenerate sets come
/// easily), spread by a scale, with a stride padding and the choice of NULL arrays.
#[derive(Arbitrary, Debug)]
struct Batch {
    points: Vec<([i8; 3], [i8; 3])>,
    scale_exponent: i8,
    /// Extra floats between points (0–3); 4 gives a stride too small to be valid.
    padding: u8,
    null_positions: bool,
    null_normals: bool,
    special: Option<(u8, Special)>,
}

/// A value planted at one coordinate.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Special {
    Nan,
    Infinity,
    Zero,
    Huge,
}

/// How positions without normals are added.
#[derive(Arbitrary, Debug)]
enum Sensors {
    None,
    SeenFrom(Option<[i8; 3]>),
    PerPoint(bool),
}

/// The optional arrays of psr_point_arrays.
#[derive(Arbitrary, Debug)]
struct Extras {
    confidence: Option<i8>,
    colors: Option<u8>,
    channels: Vec<(u8, i8)>,
}

/// Memory as large as the largest struct the library reads, zeroed, 8-byte aligned.
struct StructBuffer([u64; STRUCT_BUFFER / 8]);

impl StructBuffer {
    fn new() -> Box<Self> {
        Box::new(StructBuffer([0; STRUCT_BUFFER / 8]))
    }
    fn as_struct<T>(&mut self) -> *mut T {
        self.0.as_mut_ptr().cast()
    }
}

/// The progress callback's state: calls left before it cancels (None: never).
struct Canceller {
    calls_left: Option<u16>,
}

unsafe extern "C" fn progress(user: *mut c_void, _stage: psr_stage, fraction: f32) -> bool {
    assert!(
        (0.0..=1.0).contains(&fraction),
        "progress fraction {fraction}"
    );
    // SAFETY: user is the Canceller this harness registered and keeps alive.
    let canceller = unsafe { &mut *user.cast::<Canceller>() };
    match &mut canceller.calls_left {
        None => true,
        Some(0) => false,
        Some(n) => {
            *n -= 1;
            true
        }
    }
}

/// The live handles.
#[derive(Default)]
struct Handles {
    reconstructors: Vec<(*mut psr_reconstructor, Box<Canceller>)>,
    meshes: Vec<*mut psr_mesh>,
    implicits: Vec<*mut psr_implicit>,
}

impl Drop for Handles {
    fn drop(&mut self) {
        // SAFETY: every pointer here is a live handle this harness created and owns.
        unsafe {
            for (r, _) in self.reconstructors.drain(..) {
                psr_reconstructor_free(r);
            }
            for m in self.meshes.drain(..) {
                psr_mesh_free(m);
            }
            for f in self.implicits.drain(..) {
                psr_implicit_free(f);
            }
        }
    }
}

/// Index `i` of `list`, or NULL when `i` is past it (so the fuzzer passes NULL too).
fn pick<T>(list: &[T], i: u8) -> Option<&T> {
    list.get(i as usize % (list.len() + 1))
}

/// Panics on the statuses that only a bug gives.
fn check(status: psr_status, call: &str) {
    assert!(
        status != psr_status::InternalError && status != psr_status::HandlePoisoned,
        "{call} returned {status:?}"
    );
}

/// Runs one call sequence from `data`.
pub fn run(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let mut handles = Handles::default();
    for _ in 0..MAX_OPS {
        let Ok(op) = Op::arbitrary(&mut u) else {
            break;
        };
        // SAFETY: apply passes the library only live handles and buffers as large as it says.
        unsafe { apply(&mut handles, op) };
    }
}

unsafe fn apply(h: &mut Handles, op: Op) {
    let null_r = ptr::null_mut::<psr_reconstructor>();
    let r_of = |h: &Handles, i: u8| pick(&h.reconstructors, i).map_or(null_r, |(r, _)| *r);
    match op {
        Op::New => {
            if h.reconstructors.len() < MAX_HANDLES {
                let mut r = ptr::null_mut();
                check(unsafe { psr_reconstructor_new(&mut r) }, "new");
                assert!(!r.is_null(), "new gave NULL with OK");
                h.reconstructors
                    .push((r, Box::new(Canceller { calls_left: None })));
            }
            check(
                unsafe { psr_reconstructor_new(ptr::null_mut()) },
                "new(NULL)",
            );
        }
        Op::Free(i) => {
            let i = i as usize % (h.reconstructors.len() + 1);
            if i < h.reconstructors.len() {
                let (r, _) = h.reconstructors.swap_remove(i);
                unsafe { psr_reconstructor_free(r) };
            } else {
                unsafe { psr_reconstructor_free(null_r) };
            }
        }
        Op::SetParam(i, param) => unsafe { set_param(r_of(h, i), param) },
        Op::GetParams(i, null_out) => unsafe { get_params(r_of(h, i), null_out) },
        Op::AddPoints(i, batch) => {
            let b = Arrays::of(&batch, 3);
            let status = unsafe {
                psr_reconstructor_add_points(
                    r_of(h, i),
                    b.positions(&batch),
                    b.stride,
                    b.normals(&batch),
                    b.stride,
                    b.count,
                )
            };
            check(status, "add_points");
        }
        Op::AddPointsF64(i, batch) | Op::AddPointsTransformed(i, batch, None) => {
            let b = Arrays::of(&batch, 3);
            let status = unsafe {
                psr_reconstructor_add_points_f64(
                    r_of(h, i),
                    b.positions_f64(&batch),
                    b.stride_f64,
                    b.normals(&batch),
                    b.stride,
                    b.count,
                )
            };
            check(status, "add_points_f64");
        }
        Op::AddPointsTransformed(i, batch, Some(m)) => {
            let b = Arrays::of(&batch, 3);
            let transform = m.map(|c| f64::from(c) / 8.0);
            let status = unsafe {
                psr_reconstructor_add_points_transformed(
                    r_of(h, i),
                    b.positions_f64(&batch),
                    b.stride_f64,
                    b.normals(&batch),
                    b.stride,
                    b.count,
                    transform.as_ptr(),
                )
            };
            check(status, "add_points_transformed");
        }
        Op::AddPositions(i, batch, sensors) => {
            let b = Arrays::of(&batch, 3);
            let r = r_of(h, i);
            let status = match sensors {
                Sensors::None => unsafe {
                    psr_reconstructor_add_positions(r, b.positions(&batch), b.stride, b.count)
                },
                Sensors::SeenFrom(v) => {
                    let v = v.map(|v| v.map(f32::from));
                    unsafe {
                        psr_reconstructor_add_positions_seen_from(
                            r,
                            b.positions(&batch),
                            b.stride,
                            b.count,
                            v.as_ref().map_or(ptr::null(), |v| v.as_ptr()),
                        )
                    }
                }
                Sensors::PerPoint(null) => unsafe {
                    psr_reconstructor_add_positions_with_sensors(
                        r,
                        b.positions(&batch),
                        b.stride,
                        if null { ptr::null() } else { b.normals(&batch) },
                        b.stride,
                        b.count,
                    )
                },
            };
            check(status, "add_positions");
        }
        Op::AddPointArrays(i, batch, extras, struct_size) => unsafe {
            add_point_arrays(r_of(h, i), &batch, &extras, struct_size)
        },
        Op::ClearPoints(i) => check(
            unsafe { psr_reconstructor_clear_points(r_of(h, i)) },
            "clear_points",
        ),
        Op::PointCount(i) => {
            let mut n = 0usize;
            check(
                unsafe { psr_reconstructor_point_count(r_of(h, i), &mut n) },
                "point_count",
            );
        }
        Op::EstimateMemory(i, depth, points) => {
            let mut bytes = 0u64;
            check(
                unsafe { psr_reconstructor_estimate_memory(r_of(h, i), &mut bytes) },
                "reconstructor_estimate_memory",
            );
            check(
                unsafe { psr_estimate_memory(u32::from(depth), u64::from(points), &mut bytes) },
                "estimate_memory",
            );
        }
        Op::Progress(i, cancel_after) => {
            if let Some((r, canceller)) = pick(&h.reconstructors, i).map(|(r, c)| (*r, c)) {
                // The canceller's box stays where it is while the reconstructor lives.
                let user = ptr::from_ref::<Canceller>(canceller).cast_mut();
                unsafe { (*user).calls_left = cancel_after };
                let callback = cancel_after.map(|_| progress as unsafe extern "C" fn(_, _, _) -> _);
                check(
                    unsafe { psr_reconstructor_set_progress_callback(r, callback, user.cast()) },
                    "set_progress_callback",
                );
            } else {
                check(
                    unsafe {
                        psr_reconstructor_set_progress_callback(null_r, None, ptr::null_mut())
                    },
                    "set_progress_callback(NULL)",
                );
            }
        }
        Op::Solve(i, implicit) => unsafe { solve(h, r_of(h, i), implicit) },
        Op::MeshRead(i, capacity, index) => {
            if let Some(&m) = pick(&h.meshes, i) {
                unsafe { read_mesh(m, capacity, index) };
            } else {
                unsafe { read_mesh(ptr::null(), capacity, index) };
            }
        }
        Op::MeshTrim(i, threshold, value, struct_size) => {
            let m = pick(&h.meshes, i).copied().unwrap_or(ptr::null_mut());
            let mut buffer = StructBuffer::new();
            let options = buffer.as_struct::<psr_trim_options>();
            check(
                unsafe { psr_trim_options_init(options, size_of::<psr_trim_options>()) },
                "trim_options_init",
            );
            unsafe {
                (*options).struct_size = usize::from(struct_size);
                (*options).threshold = i32::from(threshold % 5) - 1;
                (*options).threshold_value = f64::from(value) / 16.0;
                (*options).min_piece_area = f32::from(value) / 64.0;
            }
            let mut out = ptr::null_mut();
            let status = unsafe { psr_mesh_trim(m, options, &mut out) };
            check(status, "mesh_trim");
            if status == psr_status::Ok {
                unsafe { check_mesh_arrays(out, false) };
                if h.meshes.len() < MAX_HANDLES {
                    h.meshes.push(out);
                } else {
                    unsafe { psr_mesh_free(out) };
                }
            }
        }
        Op::MeshFree(i) => {
            let i = i as usize % (h.meshes.len() + 1);
            if i < h.meshes.len() {
                let m = h.meshes.swap_remove(i);
                unsafe { psr_mesh_free(m) };
            } else {
                unsafe { psr_mesh_free(ptr::null_mut()) };
            }
        }
        Op::ImplicitRead(i, points, resolution, capacity) => {
            let f = pick(&h.implicits, i).copied().unwrap_or(ptr::null_mut());
            unsafe { read_implicit(f, &points, resolution, capacity) };
        }
        Op::ImplicitFree(i) => {
            let i = i as usize % (h.implicits.len() + 1);
            if i < h.implicits.len() {
                let f = h.implicits.swap_remove(i);
                unsafe { psr_implicit_free(f) };
            } else {
                unsafe { psr_implicit_free(ptr::null_mut()) };
            }
        }
        Op::Strings(code) => {
            for s in [
                psr_status_string(code),
                psr_stage_string(code),
                psr_version(),
            ] {
                assert!(!s.is_null(), "a string function gave NULL");
                // SAFETY: the library returns static NUL-terminated strings.
                let _ = unsafe { CStr::from_ptr(s) };
            }
        }
    }
    // Every live reconstructor's last error is a C string.
    for (r, _) in &h.reconstructors {
        let e = unsafe { psr_reconstructor_last_error(*r) };
        if !e.is_null() {
            let _ = unsafe { CStr::from_ptr(e) };
        }
    }
}

unsafe fn set_param(r: *mut psr_reconstructor, param: Param) {
    let status = unsafe {
        match param {
            Param::Depth(v) => psr_reconstructor_set_depth(r, v),
            Param::Width(v) => psr_reconstructor_set_width(r, v),
            Param::FullDepth(v) => psr_reconstructor_set_full_depth(r, v),
            Param::KernelDepth(v) => psr_reconstructor_set_kernel_depth(r, v),
            Param::SamplesPerNode(v) => psr_reconstructor_set_samples_per_node(r, v),
            Param::Scale(v) => psr_reconstructor_set_scale(r, v),
            Param::PointWeight(v) => psr_reconstructor_set_point_weight(r, v),
            Param::Threads(v) => psr_reconstructor_set_threads(r, v),
            Param::Iterations(v) => psr_reconstructor_set_max_solver_iterations(r, v),
            Param::Tolerance(v) => psr_reconstructor_set_solver_tolerance(r, v),
            Param::Boundary(v) => psr_reconstructor_set_boundary(r, v),
            Param::Splatting(v) => psr_reconstructor_set_splatting(r, v),
            Param::Placement(v) => psr_reconstructor_set_vertex_placement(r, v),
            Param::MinComponentSamples(v) => psr_reconstructor_set_min_component_samples(r, v),
            Param::NormalNeighbors(v) => psr_reconstructor_set_normal_neighbors(r, v),
            Param::NormalOrientation(v) => psr_reconstructor_set_normal_orientation(r, v),
            Param::Viewpoint(x, y, z) => psr_reconstructor_set_viewpoint(r, x, y, z),
            Param::VertexNormals(v) => psr_reconstructor_set_vertex_normals(r, v),
            Param::Degree(v) => psr_reconstructor_set_degree(r, v),
            Param::MaxMemory(v) => psr_reconstructor_set_max_memory(r, v),
        }
    };
    check(status, "a setter");
}

unsafe fn get_params(r: *mut psr_reconstructor, null_out: bool) {
    macro_rules! get {
        ($f:ident, $t:ty) => {{
            let mut v: $t = Default::default();
            let out: *mut $t = if null_out { ptr::null_mut() } else { &mut v };
            check(unsafe { $f(r, out) }, stringify!($f));
        }};
    }
    get!(psr_reconstructor_get_depth, u32);
    get!(psr_reconstructor_get_width, f64);
    get!(psr_reconstructor_get_full_depth, u32);
    get!(psr_reconstructor_get_kernel_depth, i32);
    get!(psr_reconstructor_get_samples_per_node, f32);
    get!(psr_reconstructor_get_scale, f32);
    get!(psr_reconstructor_get_point_weight, f32);
    get!(psr_reconstructor_get_threads, u32);
    get!(psr_reconstructor_get_max_solver_iterations, u32);
    get!(psr_reconstructor_get_solver_tolerance, f64);
    get!(psr_reconstructor_get_boundary, i32);
    get!(psr_reconstructor_get_splatting, i32);
    get!(psr_reconstructor_get_vertex_placement, i32);
    get!(psr_reconstructor_get_min_component_samples, u32);
    get!(psr_reconstructor_get_normal_neighbors, u32);
    get!(psr_reconstructor_get_normal_orientation, i32);
    get!(psr_reconstructor_get_vertex_normals, bool);
    get!(psr_reconstructor_get_screening_follows_noise, bool);
    get!(psr_reconstructor_get_degree, i32);
    get!(psr_reconstructor_get_max_memory, u64);
}

/// A batch laid out as the C API takes it: `floats` per point (positions, then normals or
/// sensors in a second array of the same layout), `padding` extra floats between points.
struct Arrays {
    positions: Vec<f32>,
    positions_f64: Vec<f64>,
    normals: Vec<f32>,
    stride: usize,
    stride_f64: usize,
    count: usize,
}

impl Arrays {
    fn of(batch: &Batch, floats: usize) -> Arrays {
        let count = batch.points.len();
        // padding 4 makes a stride of 2 floats: too small, refused with an error.
        let per_point = match batch.padding % 5 {
            4 => 2,
            p => floats + p as usize,
        };
        let scale = 2f32.powi(i32::from(batch.scale_exponent) / 2);
        let mut positions = vec![0f32; count * per_point.max(floats)];
        let mut normals = vec![0f32; count * per_point.max(floats)];
        for (i, (p, n)) in batch.points.iter().enumerate() {
            for k in 0..3 {
                positions[i * per_point + k] = f32::from(p[k]) * scale;
                normals[i * per_point + k] = f32::from(n[k]) / 16.0;
            }
        }
        if let Some((at, special)) = batch.special {
            if !positions.is_empty() {
                let value = match special {
                    Special::Nan => f32::NAN,
                    Special::Infinity => f32::INFINITY,
                    Special::Zero => 0.0,
                    Special::Huge => 3e38,
                };
                let at = usize::from(at) % positions.len();
                positions[at] = value;
                normals[at] = value;
            }
        }
        let positions_f64 = positions.iter().map(|&c| f64::from(c)).collect();
        Arrays {
            positions,
            positions_f64,
            normals,
            stride: per_point * size_of::<f32>(),
            stride_f64: per_point * size_of::<f64>(),
            count,
        }
    }
    fn positions(&self, batch: &Batch) -> *const f32 {
        if batch.null_positions {
            ptr::null()
        } else {
            self.positions.as_ptr()
        }
    }
    fn positions_f64(&self, batch: &Batch) -> *const f64 {
        if batch.null_positions {
            ptr::null()
        } else {
            self.positions_f64.as_ptr()
        }
    }
    fn normals(&self, batch: &Batch) -> *const f32 {
        if batch.null_normals {
            ptr::null()
        } else {
            self.normals.as_ptr()
        }
    }
}

unsafe fn add_point_arrays(
    r: *mut psr_reconstructor,
    batch: &Batch,
    extras: &Extras,
    struct_size: u16,
) {
    let b = Arrays::of(batch, 3);
    let n = b.count;
    let confidence: Vec<f32> = (0..n)
        .map(|i| f32::from(extras.confidence.unwrap_or(1)) * (i % 3) as f32 / 4.0)
        .collect();
    let components = usize::from(extras.colors.unwrap_or(0) % 6);
    let colors: Vec<f32> = (0..n * components.max(1))
        .map(|i| (i % 7) as f32 / 7.0)
        .collect();
    let channel_count = extras.channels.len().min(4);
    let names: Vec<std::ffi::CString> = extras.channels[..channel_count]
        .iter()
        .map(|(name, _)| {
            // Names from a small alphabet, so repeats, empty names and spaces occur.
            let text: String = (0..name % 4)
                .map(|k| b"a b"[(usize::from(*name) + usize::from(k)) % 3] as char)
                .collect();
            std::ffi::CString::new(text).expect("no NUL")
        })
        .collect();
    let name_ptrs: Vec<*const std::ffi::c_char> = names.iter().map(|s| s.as_ptr()).collect();
    let channels: Vec<f32> = (0..n * channel_count.max(1))
        .map(|i| {
            f32::from(
                extras
                    .channels
                    .get(i % channel_count.max(1))
                    .map_or(0, |c| c.1),
            ) + i as f32
        })
        .collect();
    let mut buffer = StructBuffer::new();
    let arrays = buffer.as_struct::<psr_point_arrays>();
    check(
        unsafe { psr_point_arrays_init(arrays, size_of::<psr_point_arrays>()) },
        "point_arrays_init",
    );
    unsafe {
        let a = &mut *arrays;
        a.struct_size = if struct_size.is_multiple_of(4) {
            size_of::<psr_point_arrays>()
        } else {
            usize::from(struct_size)
        };
        a.count = n;
        a.positions = b.positions(batch);
        a.position_stride_bytes = b.stride;
        a.normals = b.normals(batch);
        a.normal_stride_bytes = b.stride;
        if extras.confidence.is_some() {
            a.confidence = confidence.as_ptr();
        }
        if extras.colors.is_some() {
            a.colors = colors.as_ptr();
            a.color_components = components;
        }
        if channel_count > 0 {
            a.channels = channels.as_ptr();
            a.channel_count = channel_count;
            a.channel_names = name_ptrs.as_ptr();
        }
    }
    check(
        unsafe { psr_reconstructor_add_point_arrays(r, arrays) },
        "add_point_arrays",
    );
}

/// Solves when the reconstructor's settings keep it quick; keeps the mesh and implicit
/// function when there is room.
unsafe fn solve(h: &mut Handles, r: *mut psr_reconstructor, implicit: bool) {
    if !r.is_null() {
        let (mut depth, mut width, mut threads, mut points) = (0u32, 0f64, 0u32, 0usize);
        unsafe {
            check(psr_reconstructor_get_depth(r, &mut depth), "get_depth");
            check(psr_reconstructor_get_width(r, &mut width), "get_width");
            check(
                psr_reconstructor_get_threads(r, &mut threads),
                "get_threads",
            );
            check(psr_reconstructor_point_count(r, &mut points), "point_count");
        }
        if depth > 7 || width > 0.0 || threads > 8 || points > 2000 {
            return;
        }
    }
    let mut mesh = ptr::null_mut();
    let mut function = ptr::null_mut();
    let status = if implicit {
        unsafe { psr_reconstructor_solve_implicit(r, &mut mesh, &mut function) }
    } else {
        unsafe { psr_reconstructor_solve(r, &mut mesh) }
    };
    check(status, "solve");
    if status != psr_status::Ok {
        assert!(mesh.is_null(), "a failed solve gave a mesh");
        return;
    }
    unsafe { check_mesh_arrays(mesh, true) };
    if h.meshes.len() < MAX_HANDLES {
        h.meshes.push(mesh);
    } else {
        unsafe { psr_mesh_free(mesh) };
    }
    if implicit {
        assert!(!function.is_null(), "solve_implicit gave no function");
        if h.implicits.len() < MAX_HANDLES {
            h.implicits.push(function);
        } else {
            unsafe { psr_implicit_free(function) };
        }
    }
}

/// Copies out a mesh's arrays and checks them: a solved mesh is an oriented manifold (where its
/// open edges may lie is checked by the `reconstruct` target, which knows the cube); a trimmed
/// one may have any boundary, but indexes its own vertices.
unsafe fn check_mesh_arrays(m: *mut psr_mesh, solved: bool) {
    let vertices = unsafe { psr_mesh_vertex_count(m) };
    let triangles = unsafe { psr_mesh_triangle_count(m) };
    let mut positions = vec![0f32; vertices * 3];
    let mut indices = vec![0u32; triangles * 3];
    unsafe {
        check(
            psr_mesh_copy_positions(m, positions.as_mut_ptr(), positions.len()),
            "copy_positions",
        );
        check(
            psr_mesh_copy_triangles(m, indices.as_mut_ptr(), indices.len()),
            "copy_triangles",
        );
    }
    assert_finite(&positions, "C mesh vertex");
    let tris: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    if solved {
        assert_oriented_manifold(vertices, &tris, "C mesh");
    } else {
        for &v in &indices {
            assert!(
                (v as usize) < vertices,
                "trimmed mesh indexes vertex {v} of {vertices}"
            );
        }
    }
}

/// Every read of a mesh, with a fuzzer-chosen capacity (never more than the buffer holds).
unsafe fn read_mesh(m: *const psr_mesh, capacity: u32, index: u8) {
    let capacity = capacity as usize % 200_000;
    let mut floats = vec![0f32; capacity];
    let mut doubles = vec![0f64; capacity];
    let mut indices = vec![0u32; capacity];
    let mut counts = vec![0u64; capacity.min(64)];
    let index = usize::from(index % 4);
    unsafe {
        let _ = psr_mesh_vertex_count(m);
        let _ = psr_mesh_triangle_count(m);
        let _ = psr_mesh_positions(m);
        let _ = psr_mesh_triangles(m);
        let _ = psr_mesh_densities(m);
        let _ = psr_mesh_normals(m);
        let _ = psr_mesh_colors(m);
        let _ = psr_mesh_isovalue(m);
        let _ = psr_mesh_color_components(m);
        let _ = psr_mesh_channel_count(m);
        let _ = psr_mesh_channel(m, index);
        let name = psr_mesh_channel_name(m, index);
        if !name.is_null() {
            let _ = CStr::from_ptr(name);
        }
        let _ = psr_mesh_trim_density(m);
        let _ = psr_mesh_trim_depth(m);
        let _ = psr_mesh_unsupported_components(m);
        let _ = psr_mesh_solve_count(m);
        check(
            psr_mesh_copy_positions(m, floats.as_mut_ptr(), capacity),
            "copy_positions",
        );
        check(
            psr_mesh_copy_positions_f64(m, doubles.as_mut_ptr(), capacity),
            "copy_positions_f64",
        );
        check(
            psr_mesh_copy_triangles(m, indices.as_mut_ptr(), capacity),
            "copy_triangles",
        );
        check(
            psr_mesh_copy_densities(m, floats.as_mut_ptr(), capacity),
            "copy_densities",
        );
        check(
            psr_mesh_copy_normals(m, floats.as_mut_ptr(), capacity),
            "copy_normals",
        );
        check(
            psr_mesh_copy_colors(m, floats.as_mut_ptr(), capacity),
            "copy_colors",
        );
        check(
            psr_mesh_copy_channel(m, index, floats.as_mut_ptr(), capacity),
            "copy_channel",
        );
        let mut origin = [0f64; 3];
        check(psr_mesh_origin(m, origin.as_mut_ptr()), "origin");
        let mut depth = 0u32;
        check(psr_mesh_depth(m, &mut depth), "mesh_depth");
        let (mut screening_depth, mut noise) = (0.0f64, 0.0f64);
        check(
            psr_mesh_screening_depth(m, &mut screening_depth),
            "screening_depth",
        );
        assert!(screening_depth <= depth as f64, "screening past the depth");
        check(psr_mesh_sample_noise(m, &mut noise), "sample_noise");
        assert!(noise.is_nan() || noise >= 0.0, "negative noise");
        check(psr_mesh_finest_depth(m, &mut depth), "finest_depth");
        let mut count = 0usize;
        check(
            psr_mesh_node_counts(m, counts.as_mut_ptr(), counts.len(), &mut count),
            "node_counts",
        );
        let mut buffer = StructBuffer::new();
        let stats = buffer.as_struct::<psr_depth_solve>();
        (*stats).struct_size = if capacity.is_multiple_of(3) {
            size_of::<psr_depth_solve>()
        } else {
            capacity % STRUCT_BUFFER
        };
        check(psr_mesh_solve_stats(m, index, stats), "solve_stats");
    }
}

/// Evaluates, differentiates and samples an implicit function (or NULL).
unsafe fn read_implicit(f: *const psr_implicit, points: &[[i8; 3]], resolution: u8, capacity: u32) {
    let query: Vec<f32> = points
        .iter()
        .flat_map(|p| p.map(|c| f32::from(c) / 16.0))
        .collect();
    let mut values = vec![0f32; points.len()];
    let mut gradients = vec![0f32; points.len() * 3];
    let resolution = usize::from(resolution % 40);
    let capacity = (capacity as usize) % (40 * 40 * 40 + 1);
    let mut grid = vec![0f32; capacity];
    let (mut origin, mut size) = ([0f64; 3], 0f64);
    unsafe {
        let _ = psr_implicit_isovalue(f);
        check(
            psr_implicit_cube(f, origin.as_mut_ptr(), &mut size),
            "implicit_cube",
        );
        check(
            psr_implicit_evaluate(f, query.as_ptr(), points.len(), values.as_mut_ptr()),
            "implicit_evaluate",
        );
        check(
            psr_implicit_gradient(f, query.as_ptr(), points.len(), gradients.as_mut_ptr()),
            "implicit_gradient",
        );
        check(
            psr_implicit_sample_grid(f, resolution, grid.as_mut_ptr(), capacity),
            "implicit_sample_grid",
        );
        // A box between the first two query points, either way round (min above max is
        // refused).
        let corner = |k: usize| {
            points
                .get(k)
                .map_or([0.0; 3], |p| p.map(|c| f64::from(c) / 16.0))
        };
        let (lo, hi) = (corner(0), corner(1));
        check(
            psr_implicit_sample_box(
                f,
                lo.as_ptr(),
                hi.as_ptr(),
                resolution,
                grid.as_mut_ptr(),
                capacity,
            ),
            "implicit_sample_box",
        );
    }
}

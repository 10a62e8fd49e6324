//! Points with confidence, colours and channels through one extensible struct
//! (`psr_point_arrays`, psr_point_arrays_init, psr_reconstructor_add_point_arrays), the vertex
//! normals setting, and the mesh's normals, colours and channels (borrowed views and copies).
//!
//! The struct begins with its own size, so it can grow: every field is one word (a pointer or
//! a size_t), new fields go at the end, and the library reads only the fields that lie wholly
//! within the size the caller gives. A caller compiled against an older, smaller struct passes
//! its smaller size and its missing fields count as zero (absent); a caller compiled against a
//! newer header runs on an older library as long as the fields that library does not know are
//! zero (otherwise it is told so rather than having them ignored).

use super::mesh::psr_mesh;
use super::panic_boundary::{guard, guard_no_handle, guard_value, handle_mut, require_out};
use super::params::{get_param, set_param};
use super::points::{batch_failure, check_array, gather_vec3};
use super::reconstructor::psr_reconstructor;
use super::status::{psr_status, Failure, Outcome};
use super::MAX_STRUCT_SIZE;
use crate::{Colors, Mesh, PointSet};
use std::ffi::{c_char, CStr};
use std::mem::{offset_of, size_of};
use std::ptr;

/// Points for psr_reconstructor_add_point_arrays: positions and normals, and optionally a
/// confidence weight, a colour and named float channels per point. Every array is read with a
/// byte stride (0 = tightly packed; otherwise at least one element, so interleaved vertex
/// structs work; no alignment is required).
///
/// Always initialise it with psr_point_arrays_init(&a, sizeof a), which zeroes it (every
/// optional array absent) and sets struct_size; then set the fields you use. New fields will
/// only ever be added at the end, and a zero field always means "absent", so code compiled
/// against this header keeps working with later versions of the library.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct psr_point_arrays {
    /// The size of the struct as the caller's header declares it (psr_point_arrays_init sets
    /// it).
    pub struct_size: usize,
    /// Number of points.
    pub count: usize,
    /// Point i's position is the 3 floats at (const char *)positions + i * position_stride_bytes.
    /// Required (unless count is 0).
    pub positions: *const f32,
    /// 0 (12 bytes) or at least 12.
    pub position_stride_bytes: usize,
    /// Point i's normal, 3 floats (need not be unit length). Required (unless count is 0):
    /// points without normals go through psr_reconstructor_add_positions.
    pub normals: *const f32,
    /// 0 (12 bytes) or at least 12.
    pub normal_stride_bytes: usize,
    /// Point i's confidence weight, 1 float, finite and >= 0 (PoissonRecon --confidence):
    /// how much the point counts, in the surface and in the colours. NULL: every point 1.
    pub confidence: *const f32,
    /// 0 (4 bytes) or at least 4.
    pub confidence_stride_bytes: usize,
    /// Point i's colour, color_components floats (red, green, blue[, alpha]), finite, in any
    /// scale (0 to 1, or 0 to 255: the mesh's colours are weighted means of them). NULL: no
    /// colours.
    pub colors: *const f32,
    /// 0 (color_components floats) or at least that.
    pub color_stride_bytes: usize,
    /// 3 (RGB) or 4 (RGBA) when colors is set; 0 when it is NULL.
    pub color_components: usize,
    /// Point i's channel values: channel_count floats, finite, in the order of channel_names.
    /// Used when channel_count is not 0.
    pub channels: *const f32,
    /// 0 (channel_count floats) or at least that.
    pub channel_stride_bytes: usize,
    /// Number of channels per point (0: none).
    pub channel_count: usize,
    /// channel_count NUL-terminated UTF-8 names, distinct, non-empty and without whitespace
    /// (each becomes a PLY property name). The names are copied.
    pub channel_names: *const *const c_char,
}

/// Bytes of one field: every field of psr_point_arrays is one word.
const WORD: usize = size_of::<usize>();

/// The smallest struct_size accepted: up to and including position_stride_bytes (the fields
/// every batch needs; normals then count as absent and are reported missing).
const MIN_SIZE: usize = offset_of!(psr_point_arrays, position_stride_bytes) + WORD;

/// Prepares *a for psr_reconstructor_add_point_arrays: sets every field to zero (no arrays, no
/// points) and struct_size to `struct_size`, which must be the size of the struct as your code
/// sees it: pass sizeof *a. (The library cannot know how large the struct you compiled with
/// is; a library newer than your header must not write beyond it.)
///
/// a must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_INVALID_ARGUMENT (struct_size is smaller than the first four fields or larger
/// than 4096 bytes; nothing is written) or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `a` is NULL or valid for writes of `struct_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn psr_point_arrays_init(
    a: *mut psr_point_arrays,
    struct_size: usize,
) -> psr_status {
    const F: &str = "psr_point_arrays_init";
    guard_no_handle(F, || {
        require_out(F, "a", a)?;
        check_size(F, struct_size)?;
        // SAFETY: `a` is valid for writes of struct_size bytes (this function's contract);
        // zero bytes are a valid value of every field (NULL pointers, 0 sizes).
        unsafe {
            ptr::write_bytes(a.cast::<u8>(), 0, struct_size);
            a.cast::<usize>().write_unaligned(struct_size);
        }
        Ok(())
    })
}

/// Refuses a struct_size below the fields every batch needs, or above [`MAX_STRUCT_SIZE`]
/// (an unset or uninitialised size, which must not be read or written as a huge struct).
fn check_size(function: &str, struct_size: usize) -> Outcome {
    if (MIN_SIZE..=MAX_STRUCT_SIZE).contains(&struct_size) {
        return Ok(());
    }
    Err(Failure::new(
        psr_status::InvalidArgument,
        format!(
            "{function}: struct_size is {struct_size}, not the size of a psr_point_arrays \
             ({MIN_SIZE} to {MAX_STRUCT_SIZE} bytes); initialise the struct with \
             psr_point_arrays_init(&a, sizeof a)"
        ),
    ))
}

/// Reads the caller's struct: the fields wholly within its struct_size, the others zero.
///
/// # Safety
/// `a` is not NULL and is valid for reads of the struct_size bytes its first word gives.
unsafe fn read_arrays(
    function: &str,
    a: *const psr_point_arrays,
) -> Result<psr_point_arrays, Failure> {
    // SAFETY: every version of the struct begins with struct_size (this function's contract).
    let size = unsafe { a.cast::<usize>().read_unaligned() };
    check_size(function, size)?;
    let known = size_of::<psr_point_arrays>();
    let bytes = a.cast::<u8>();
    if size > known {
        // A newer header's struct: its fields beyond ours must be unused (zero).
        // SAFETY: the caller's struct is readable over its size (this function's contract).
        let extra = unsafe { std::slice::from_raw_parts(bytes.add(known), size - known) };
        if extra.iter().any(|&b| b != 0) {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{function}: the struct is {size} bytes and sets fields beyond the {known} \
                     this library knows: this psr is older than the header you compiled \
                     against; update the library or leave the newer fields zero"
                ),
            ));
        }
    }
    let mut arrays = psr_point_arrays {
        struct_size: size,
        count: 0,
        positions: ptr::null(),
        position_stride_bytes: 0,
        normals: ptr::null(),
        normal_stride_bytes: 0,
        confidence: ptr::null(),
        confidence_stride_bytes: 0,
        colors: ptr::null(),
        color_stride_bytes: 0,
        color_components: 0,
        channels: ptr::null(),
        channel_stride_bytes: 0,
        channel_count: 0,
        channel_names: ptr::null(),
    };
    // Whole fields only: a size that ends inside a field leaves it out.
    let copied = size.min(known) / WORD * WORD;
    // SAFETY: `copied` bytes are readable from the caller's struct (at most its size) and
    // writable in `arrays` (at most its size); every field is a word whose every bit pattern
    // is valid, and the two do not overlap.
    unsafe {
        ptr::copy_nonoverlapping(
            bytes,
            (&mut arrays as *mut psr_point_arrays).cast::<u8>(),
            copied,
        )
    };
    Ok(arrays)
}

/// Checks one strided float array of `floats` floats per point; `stride` 0 means packed.
fn check_floats(
    function: &str,
    name: &str,
    stride_name: &str,
    base: *const f32,
    stride: usize,
    floats: usize,
    count: usize,
) -> Outcome {
    if base.is_null() {
        return Err(Failure::null(
            function,
            &format!("{name} (with count {count})"),
        ));
    }
    let element = floats * size_of::<f32>();
    let stride = if stride == 0 { element } else { stride };
    if stride < element {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!(
                "{function}: {stride_name} is {stride} bytes, less than one element ({floats} \
                 floats = {element} bytes); use 0 for packed arrays"
            ),
        ));
    }
    let span = (count - 1)
        .checked_mul(stride)
        .and_then(|s| s.checked_add(element));
    match span {
        Some(span) if span <= isize::MAX as usize => Ok(()),
        _ => Err(Failure::new(
            psr_status::InvalidArgument,
            format!(
                "{function}: {count} points with a {stride}-byte {stride_name} span more bytes \
                 than memory can hold"
            ),
        )),
    }
}

/// Copies `count` groups of `floats` floats starting `stride` bytes apart (0 = packed), as
/// one flat vector.
///
/// # Safety
/// The array passed [`check_floats`] with these arguments and is readable over that span.
unsafe fn gather_floats(base: *const f32, stride: usize, floats: usize, count: usize) -> Vec<f32> {
    let element = floats * size_of::<f32>();
    let stride = if stride == 0 { element } else { stride };
    let bytes = base.cast::<u8>();
    let mut out = Vec::with_capacity(floats * count);
    for i in 0..count {
        for k in 0..floats {
            // SAFETY: i < count and k < floats, so these 4 bytes lie inside the span, which is
            // readable and fits in isize (this function's contract); reads are unaligned.
            out.push(unsafe { bytes.add(i * stride + k * 4).cast::<f32>().read_unaligned() });
        }
    }
    out
}

/// The batch `a` describes, checked and copied (not yet added).
///
/// # Safety
/// Every pointer in `a` is NULL or valid for reads of the strided span its fields describe;
/// `channel_names` holds `channel_count` NUL-terminated strings.
unsafe fn batch_of(function: &str, a: &psr_point_arrays) -> Result<PointSet, Failure> {
    let count = a.count;
    check_array(
        function,
        "positions",
        "position_stride_bytes",
        a.positions,
        a.position_stride_bytes,
        count,
    )?;
    if a.normals.is_null() {
        return Err(Failure::null(
            function,
            &format!(
                "normals (with count {count}; points without normals go through \
                 psr_reconstructor_add_positions)"
            ),
        ));
    }
    check_array(
        function,
        "normals",
        "normal_stride_bytes",
        a.normals,
        a.normal_stride_bytes,
        count,
    )?;
    if !a.confidence.is_null() {
        check_floats(
            function,
            "confidence",
            "confidence_stride_bytes",
            a.confidence,
            a.confidence_stride_bytes,
            1,
            count,
        )?;
    }
    let components = a.color_components;
    if a.colors.is_null() {
        if components != 0 {
            return Err(Failure::null(
                function,
                &format!("colors (with color_components {components})"),
            ));
        }
    } else {
        if components != 3 && components != 4 {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!("{function}: color_components is {components}: give 3 (RGB) or 4 (RGBA)"),
            ));
        }
        check_floats(
            function,
            "colors",
            "color_stride_bytes",
            a.colors,
            a.color_stride_bytes,
            components,
            count,
        )?;
    }
    let channels = a.channel_count;
    let mut names = Vec::with_capacity(channels.min(1 << 16));
    if channels > 0 {
        if a.channel_names.is_null() {
            return Err(Failure::null(
                function,
                &format!("channel_names (with channel_count {channels})"),
            ));
        }
        check_floats(
            function,
            "channels",
            "channel_stride_bytes",
            a.channels,
            a.channel_stride_bytes,
            channels,
            count,
        )?;
        for k in 0..channels {
            // SAFETY: channel_names holds channel_count pointers (this function's contract).
            let name = unsafe { a.channel_names.add(k).read_unaligned() };
            if name.is_null() {
                return Err(Failure::null(function, &format!("channel_names[{k}]")));
            }
            // SAFETY: a non-NULL name is NUL-terminated (this function's contract).
            let name = unsafe { CStr::from_ptr(name) };
            let Ok(name) = name.to_str() else {
                return Err(Failure::new(
                    psr_status::InvalidArgument,
                    format!("{function}: channel_names[{k}] is not valid UTF-8"),
                ));
            };
            names.push(name.to_string());
        }
    }
    // SAFETY: each array passed its check above and is readable over its span (this
    // function's contract).
    let (positions, normals, confidence, colors, values) = unsafe {
        (
            gather_vec3(a.positions, a.position_stride_bytes, count),
            gather_vec3(a.normals, a.normal_stride_bytes, count),
            (!a.confidence.is_null())
                .then(|| gather_floats(a.confidence, a.confidence_stride_bytes, 1, count)),
            (!a.colors.is_null())
                .then(|| gather_floats(a.colors, a.color_stride_bytes, components, count)),
            (channels > 0)
                .then(|| gather_floats(a.channels, a.channel_stride_bytes, channels, count)),
        )
    };
    let fail = |e| batch_failure(function, e);
    let mut batch = PointSet::new();
    batch
        .extend_weighted(&positions, &normals, confidence.as_deref())
        .map_err(fail)?;
    if let Some(colors) = colors {
        batch = batch
            .with_colors(Colors::from_flattened(components, &colors))
            .map_err(fail)?;
    }
    if let Some(values) = values {
        for (k, name) in names.into_iter().enumerate() {
            let column = values.iter().skip(k).step_by(channels).copied().collect();
            batch = batch.with_channel(name, column).map_err(fail)?;
        }
    }
    Ok(batch)
}

/// Appends the points *a describes to r: positions and normals, and when given, a confidence
/// weight, a colour and named channels per point (see psr_point_arrays). The mesh's vertices
/// then get colours and channels (psr_mesh_colors, psr_mesh_channel): at each vertex, the
/// weighted mean of the values of the points around it whose normals face the same way as the
/// surface there, so one face of a thin wall never colours the other.
///
/// Initialise *a with psr_point_arrays_init(&a, sizeof a) first; a struct from an older header
/// (smaller struct_size) works, its missing fields counting as absent. Everything is copied:
/// free your arrays as soon as this returns. Calls append, so a cloud can come in batches, but
/// every batch must carry the same attributes (colours or none, the same number of components,
/// the same channel names in the same order; weights may differ: absent ones are 1). The batch
/// is checked whole first; if anything is wrong nothing from it is appended, points from
/// earlier batches stay, and the message names the first bad index within this batch. Points
/// with colours or channels cannot be mixed with points added without normals
/// (psr_reconstructor_add_positions), which carry none.
///
/// r and a must not be NULL; with count 0 nothing is read but struct_size. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT (r, a, positions, normals, or an array whose count
/// or components say it is there), PSR_STATUS_INVALID_ARGUMENT (struct_size too small or above 4096, or
/// larger with fields this library does not know set; a stride below one element; count *
/// stride overflowing; color_components not 3 or 4; a channel name that is not UTF-8, empty,
/// has whitespace or repeats; attributes that differ from the earlier batches'),
/// PSR_STATUS_NON_FINITE_POSITION, PSR_STATUS_NON_FINITE_NORMAL, PSR_STATUS_ZERO_NORMAL,
/// PSR_STATUS_INVALID_WEIGHT (a weight negative, NaN or infinite),
/// PSR_STATUS_NON_FINITE_ATTRIBUTE (a colour or channel value NaN or infinite),
/// PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle; `a` is NULL or points to struct_size readable bytes that
/// begin with struct_size, and every array in it is NULL or readable over its strided span;
/// `channel_names` holds channel_count NUL-terminated strings.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_add_point_arrays(
    r: *mut psr_reconstructor,
    a: *const psr_point_arrays,
) -> psr_status {
    const F: &str = "psr_reconstructor_add_point_arrays";
    let body = || {
        // SAFETY: `r` is NULL or a live handle (this function's contract); guard runs the body
        // only when no other call on r is under way and holds no reference to r meanwhile.
        let handle = unsafe { handle_mut(F, r) }?;
        if a.is_null() {
            return Err(Failure::null(F, "a"));
        }
        // SAFETY: `a` is not NULL, so it points to struct_size readable bytes beginning with
        // struct_size (this function's contract).
        let arrays = unsafe { read_arrays(F, a) }?;
        if arrays.count == 0 {
            return Ok(());
        }
        // SAFETY: the arrays are NULL or readable over their spans and the names are
        // NUL-terminated (this function's contract).
        let batch = unsafe { batch_of(F, &arrays) }?;
        let carries = batch.colors().is_some() || !batch.channels().is_empty();
        if carries && !handle.positions_without_normals.is_empty() {
            return Err(Failure::new(
                psr_status::InvalidArgument,
                format!(
                    "{F}: r holds points without normals (psr_reconstructor_add_positions), \
                     which carry no colours or channels, so points with them cannot join them; \
                     nothing from this batch was added"
                ),
            ));
        }
        handle.points.append(batch).map_err(|e| batch_failure(F, e))
    };
    // SAFETY: `r` is NULL or a live handle (this function's contract); the body's reference to
    // it ends with the body.
    unsafe { guard(F, r, body) }
}

/// Sets whether the mesh gets a unit outward normal per vertex (psr_mesh_normals), the
/// normalised gradient of the indicator function there. Default false. PoissonRecon --normals.
///
/// r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
/// PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
/// or PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `r` is NULL or a live handle from psr_reconstructor_new.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_set_vertex_normals(
    r: *mut psr_reconstructor,
    vertex_normals: bool,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle (this function's contract).
    unsafe {
        set_param("psr_reconstructor_set_vertex_normals", r, |p| {
            p.vertex_normals = vertex_normals
        })
    }
}

/// Writes whether the mesh gets vertex normals to *out. r and out must not be NULL. Returns the
/// statuses of psr_reconstructor_get_depth.
///
/// # Safety
/// `r` is NULL or a live handle; `out` is NULL or valid for writes.
#[no_mangle]
pub unsafe extern "C" fn psr_reconstructor_get_vertex_normals(
    r: *const psr_reconstructor,
    out: *mut bool,
) -> psr_status {
    // SAFETY: `r` is NULL or a live handle and `out` is NULL or valid for writes (this
    // function's contract).
    unsafe {
        get_param("psr_reconstructor_get_vertex_normals", r, out, |p| {
            p.vertex_normals
        })
    }
}

/// The mesh behind `m`, if any.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
unsafe fn mesh_of<'a>(m: *const psr_mesh) -> Option<&'a psr_mesh> {
    // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change, so a
    // shared reference is sound even with other threads reading it.
    unsafe { m.as_ref() }
}

/// A borrowed view of an array a handle owns (a mesh's, a PLY file's): NULL when it is empty.
pub(super) fn view<T>(values: &[T]) -> *const T {
    if values.is_empty() {
        ptr::null()
    } else {
        values.as_ptr()
    }
}

/// The unit outward normals of m's vertices, 3 floats (nx, ny, nz) per vertex, owned by m
/// (valid until psr_mesh_free(m)). NULL if m is NULL, has no vertices, or was solved without
/// psr_reconstructor_set_vertex_normals(r, true).
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_normals(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_normals", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }.map_or(ptr::null(), |m| view(m.mesh.normals.as_flattened()))
    })
}

/// Components per vertex colour of m: 3 (RGB), 4 (RGBA), or 0 when m has no colours (its
/// points had none) or m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_color_components(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_color_components", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }
            .and_then(|m| m.mesh.colors.as_ref())
            .map_or(0, Colors::components)
    })
}

/// The colours of m's vertices, psr_mesh_color_components(m) floats per vertex, in the scale
/// of the points' colours, owned by m (valid until psr_mesh_free(m)). NULL if m is NULL, has no
/// vertices or no colours.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_colors(m: *const psr_mesh) -> *const f32 {
    guard_value("psr_mesh_colors", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }
            .and_then(|m| m.mesh.colors.as_ref())
            .map_or(ptr::null(), |c| view(c.as_flattened()))
    })
}

/// Number of channels of m (the channels its points had); 0 if m is NULL.
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_channel_count(m: *const psr_mesh) -> usize {
    guard_value("psr_mesh_channel_count", 0, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }.map_or(0, |m| m.mesh.channels.len())
    })
}

/// The name of m's channel `index` (0-based, in the order the points gave them) as a
/// NUL-terminated string owned by m (valid until psr_mesh_free(m), never to be freed). NULL if
/// m is NULL or index >= psr_mesh_channel_count(m).
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_channel_name(m: *const psr_mesh, index: usize) -> *const c_char {
    guard_value("psr_mesh_channel_name", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }
            .and_then(|m| m.channel_names.get(index))
            .map_or(ptr::null(), |name| name.as_ptr())
    })
}

/// The values of m's channel `index` at its vertices, one float per vertex, owned by m (valid
/// until psr_mesh_free(m)). NULL if m is NULL, has no vertices, or index >=
/// psr_mesh_channel_count(m).
///
/// # Safety
/// `m` is NULL or a live mesh from psr_reconstructor_solve.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_channel(m: *const psr_mesh, index: usize) -> *const f32 {
    guard_value("psr_mesh_channel", ptr::null(), || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        unsafe { mesh_of(m) }
            .and_then(|m| m.mesh.channels.get(index))
            .map_or(ptr::null(), |c| view(&c.values))
    })
}

/// Copies the array `array` picks from `m` into `dst` (room for `capacity` floats), with the
/// checks of the other psr_mesh_copy_* functions; on failure nothing is written. `array` gives
/// None for an index out of range.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity` floats.
unsafe fn copy_array(
    function: &'static str,
    m: *const psr_mesh,
    array: impl FnOnce(&Mesh) -> Result<&[f32], Failure>,
    dst: *mut f32,
    capacity: usize,
) -> psr_status {
    guard_no_handle(function, || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract).
        let m = unsafe { mesh_of(m) }.ok_or_else(|| Failure::null(function, "m"))?;
        let src = array(&m.mesh)?;
        if src.is_empty() {
            return Ok(());
        }
        if dst.is_null() {
            let dst = format!("dst (with {} values to copy)", src.len());
            return Err(Failure::null(function, &dst));
        }
        if capacity < src.len() {
            return Err(Failure::new(
                psr_status::BufferTooSmall,
                format!(
                    "{function}: capacity_floats is {capacity}, less than the {} values to \
                     copy; nothing was written",
                    src.len()
                ),
            ));
        }
        // SAFETY: `dst` is not NULL, so it is valid for writes of `capacity` >= src.len()
        // floats (this function's contract); it does not overlap the mesh's own array, which C
        // only ever gets as a pointer to const.
        unsafe { ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
        Ok(())
    })
}

/// Copies m's vertex normals into dst: 3 * psr_mesh_vertex_count(m) floats, or nothing when m
/// has no normals. capacity_floats is the number of floats dst can hold.
///
/// m must not be NULL; dst may be NULL only when there is nothing to copy. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_normals(
    m: *const psr_mesh,
    dst: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    let function = "psr_mesh_copy_normals";
    // SAFETY: forwarded from this function's contract.
    unsafe {
        copy_array(
            function,
            m,
            |mesh| Ok(mesh.normals.as_flattened()),
            dst,
            capacity_floats,
        )
    }
}

/// The flattened colours of `mesh`, empty when it has none.
fn colors_of(mesh: &Mesh) -> &[f32] {
    mesh.colors.as_ref().map_or(&[], Colors::as_flattened)
}

/// Copies m's vertex colours into dst: psr_mesh_color_components(m) *
/// psr_mesh_vertex_count(m) floats, or nothing when m has no colours. capacity_floats is the
/// number of floats dst can hold.
///
/// m must not be NULL; dst may be NULL only when there is nothing to copy. Returns the statuses
/// of psr_mesh_copy_normals.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_colors(
    m: *const psr_mesh,
    dst: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    let function = "psr_mesh_copy_colors";
    // SAFETY: forwarded from this function's contract.
    unsafe {
        copy_array(
            function,
            m,
            |mesh| Ok(colors_of(mesh)),
            dst,
            capacity_floats,
        )
    }
}

/// Copies the values of m's channel `index` into dst: psr_mesh_vertex_count(m) floats.
/// capacity_floats is the number of floats dst can hold.
///
/// m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (index >=
/// psr_mesh_channel_count(m)), PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
/// PSR_STATUS_INTERNAL_ERROR.
///
/// # Safety
/// `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_copy_channel(
    m: *const psr_mesh,
    index: usize,
    dst: *mut f32,
    capacity_floats: usize,
) -> psr_status {
    const F: &str = "psr_mesh_copy_channel";
    let out_of_range = |channels: usize| {
        Failure::new(
            psr_status::InvalidArgument,
            format!("{F}: index is {index} but the mesh has {channels} channels"),
        )
    };
    // SAFETY: forwarded from this function's contract.
    unsafe {
        copy_array(
            F,
            m,
            |mesh| {
                let channel = mesh.channels.get(index);
                channel
                    .map(|c| &c.values[..])
                    .ok_or_else(|| out_of_range(mesh.channels.len()))
            },
            dst,
            capacity_floats,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every field is one word, in the documented order, so that a prefix of the struct is an
    /// older version of it.
    #[test]
    fn the_struct_is_words_in_order() {
        assert_eq!(size_of::<psr_point_arrays>(), 15 * WORD);
        assert_eq!(offset_of!(psr_point_arrays, count), WORD);
        assert_eq!(offset_of!(psr_point_arrays, channel_names), 14 * WORD);
        assert_eq!(MIN_SIZE, 4 * WORD);
    }
}

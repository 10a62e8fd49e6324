//! PLY files through the library's own reader and writer: the `psr_ply` handle (what
//! psr_ply_read reads of a file: its vertices with their properties, and its faces as
//! triangles), its views, psr_ply_free, and psr_mesh_write_ply.
//!
//! These functions have no reconstructor to keep a failure's message on, and a file's problem
//! needs its message (which line, which element, the OS's reason), so they write it into a
//! buffer the caller passes (`message`, `message_capacity`; NULL and 0 for none).

use super::attributes::view;
use super::mesh::psr_mesh;
use super::panic_boundary::{guard_no_handle, guard_value, require_out, write_out};
use super::status::{psr_status, Failure, Outcome};
use crate::ply::{self, PlyErrorKind, PlyFormat, PlyPoints, WriteOptions};
use std::ffi::{c_char, CStr, CString};
use std::path::PathBuf;
use std::ptr;

/// psr_mesh_write_ply flag: write the body as text (`format ascii`) instead of binary
/// little-endian. PoissonRecon: --ascii.
pub const PSR_PLY_ASCII: u32 = 1;
/// psr_mesh_write_ply flag: write binary big-endian instead of little-endian (not with
/// PSR_PLY_ASCII).
pub const PSR_PLY_BIG_ENDIAN: u32 = 2;
/// psr_mesh_write_ply flag: write x y z as double: psr_mesh_origin + each position, added in
/// double. Without it they are written as float, unless the mesh's origin is not (0, 0, 0)
/// (points added in double far from 0), where float would lose what the origin keeps.
/// PoissonRecon: --double.
pub const PSR_PLY_DOUBLE_POSITIONS: u32 = 4;

/// Every flag this library knows; psr_mesh_write_ply refuses others.
const KNOWN_FLAGS: u32 = PSR_PLY_ASCII | PSR_PLY_BIG_ENDIAN | PSR_PLY_DOUBLE_POSITIONS;

/// What psr_ply_read read of a PLY file: its vertices (positions; normals, colours,
/// confidence or `value`, sensor positions and other scalar properties when present) and its
/// faces as triangles. Created by psr_ply_read, destroyed by psr_ply_free; never changed in
/// between, so any number of threads may read one at once. Opaque to C.
pub struct psr_ply {
    points: PlyPoints,
    triangles: Vec<[u32; 3]>,
    /// The channels' names as C strings, for psr_ply_channel_name (made once, so the pointers
    /// it returns live as long as the handle).
    channel_names: Vec<CString>,
}

/// Writes `text` into the caller's buffer of `capacity` bytes as a NUL-terminated string,
/// shortened at a character boundary when it does not fit; nothing when `buffer` is NULL or
/// `capacity` is 0.
///
/// # Safety
/// `buffer` is NULL or valid for writing `capacity` bytes.
unsafe fn write_message(buffer: *mut c_char, capacity: usize, text: &str) {
    if buffer.is_null() || capacity == 0 {
        return;
    }
    let mut end = text.len().min(capacity - 1);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    // SAFETY: `end` + 1 <= capacity bytes are written into the caller's buffer, valid for
    // `capacity` bytes (this function's contract); `text` is another object.
    unsafe {
        ptr::copy_nonoverlapping(text.as_ptr(), buffer.cast::<u8>(), end);
        buffer.add(end).write(0);
    }
}

/// Runs `body` behind the panic boundary and writes its failure's message (or "" on success)
/// into the caller's message buffer.
///
/// # Safety
/// `message` is NULL or valid for writing `capacity` bytes.
unsafe fn with_message(
    function: &str,
    message: *mut c_char,
    capacity: usize,
    body: impl FnOnce() -> Outcome,
) -> psr_status {
    let mut text = String::new();
    let status = guard_no_handle(function, || {
        body().inspect_err(|failure| text.clone_from(&failure.message))
    });
    if status == psr_status::InternalError && text.is_empty() {
        text = format!("{function}: internal error (a panic inside psr)");
    }
    // SAFETY: forwarded from this function's contract.
    unsafe { write_message(message, capacity, &text) };
    status
}

/// The path a C string names: its bytes as they are on Unix (any encoding the file system
/// takes), UTF-8 elsewhere.
fn path_of(function: &str, path: &CStr) -> Result<PathBuf, Failure> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let _ = function; // named only where a path can be refused
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(path.to_bytes())))
    }
    #[cfg(not(unix))]
    {
        path.to_str().map(PathBuf::from).map_err(|_| {
            Failure::new(
                psr_status::InvalidArgument,
                format!("{function}: path is not UTF-8"),
            )
        })
    }
}

/// The path argument, checked: not NULL, not empty.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string.
pub(super) unsafe fn path_argument(
    function: &str,
    path: *const c_char,
) -> Result<PathBuf, Failure> {
    if path.is_null() {
        return Err(Failure::null(function, "path"));
    }
    // SAFETY: `path` is a NUL-terminated string (this function's contract).
    let path = unsafe { CStr::from_ptr(path) };
    if path.is_empty() {
        return Err(Failure::new(
            psr_status::InvalidArgument,
            format!("{function}: path is empty"),
        ));
    }
    path_of(function, path)
}

/// Reads the PLY file at `path` (a NUL-terminated path; its bytes as they are on Unix) with
/// psr's own reader, the one the psr program uses, and writes a new handle to *out (free it
/// with psr_ply_free). ASCII and binary of either byte order, every scalar type; the `vertex`
/// element needs x y z; nx ny nz (or normal_x ...), red green blue and alpha if present (or
/// diffuse_red ..., r g b a; integer colours are scaled to 0..1), confidence (or else value:
/// the density a psr mesh carries), sensor_x sensor_y sensor_z (or vp_x ..., beamorigin_x ...)
/// and every other scalar property (a "channel") are read when present; a `face` element's vertex_indices (or
/// vertex_index) polygons become triangles, an n-gon a fan of n - 2 (none when the file has
/// no face element). Other elements and list properties are skipped. A point cloud, or a mesh
/// psr or another program wrote: the views below give every part.
///
/// path and out must not be NULL; message may be NULL (or message_capacity 0) for no message.
/// Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty
/// path), PSR_STATUS_IO_ERROR (the file cannot be opened or read: the message has the
/// system's reason), PSR_STATUS_INVALID_FILE (not PLY, a malformed or truncated file, no
/// vertex element or no x y z, a face index out of range: the message says where) or
/// PSR_STATUS_INTERNAL_ERROR. The message (at most message_capacity - 1 bytes and a NUL,
/// shortened if longer) is written on every return: "" on success. On failure *out is left
/// untouched. The file is read before anything is allocated for it, so a header that
/// promises more than the file holds is refused, not allocated. Thread-safe: no state is
/// shared between calls.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` is NULL or valid for writing one
/// pointer; `message` is NULL or valid for writing `message_capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_read(
    path: *const c_char,
    out: *mut *mut psr_ply,
    message: *mut c_char,
    message_capacity: usize,
) -> psr_status {
    const F: &str = "psr_ply_read";
    let body = || {
        // SAFETY: `path` is NULL or a NUL-terminated string (this function's contract).
        let path = unsafe { path_argument(F, path) }?;
        require_out(F, "out", out)?;
        let (points, triangles) = ply::read_points_and_triangles(&path).map_err(|e| {
            let status = match e.kind() {
                PlyErrorKind::Io { .. } => psr_status::IoError,
                _ => psr_status::InvalidFile,
            };
            Failure::new(status, format!("{F}: {e}"))
        })?;
        // A property name is a header word, which may hold a NUL byte: replaced.
        let channel_names = super::channel_names(&points.channels);
        let handle = Box::into_raw(Box::new(psr_ply {
            points,
            triangles,
            channel_names,
        }));
        // SAFETY: `out` is not NULL (checked) and valid for one pointer (this function's
        // contract).
        unsafe { write_out(F, "out", out, handle) }
    };
    // SAFETY: `message` is NULL or valid for message_capacity bytes (this function's contract).
    unsafe { with_message(F, message, message_capacity, body) }
}

/// Frees a handle from psr_ply_read and every view it gave; NULL is ignored.
///
/// # Safety
/// `p` is NULL or a handle from psr_ply_read not yet freed, used by no other thread.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_free(p: *mut psr_ply) {
    guard_value("psr_ply_free", (), || {
        if !p.is_null() {
            // SAFETY: `p` came from Box::into_raw in psr_ply_read and is freed once (the
            // contract).
            drop(unsafe { Box::from_raw(p) });
        }
    })
}

/// The handle behind `p`, or None for NULL.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
unsafe fn ply_of<'a>(p: *const psr_ply) -> Option<&'a psr_ply> {
    // SAFETY: `p` is NULL or a live handle (this function's contract); handles never change,
    // so a shared reference is sound with other threads reading it.
    unsafe { p.as_ref() }
}

/// Number of vertices (points) read; 0 if p is NULL.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_vertex_count(p: *const psr_ply) -> usize {
    guard_value("psr_ply_vertex_count", 0, || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(0, |p| p.points.len())
    })
}

/// The positions, 3 floats (x, y, z) per vertex (rounded to float when the file stores
/// double: psr_ply_positions_f64 has them exactly); owned by p, valid until psr_ply_free(p).
/// NULL if p is NULL or has no vertices. Give them to psr_reconstructor_add_points (or
/// psr_point_arrays) with the normals, or to psr_reconstructor_add_positions without.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_positions(p: *const psr_ply) -> *const f32 {
    guard_value("psr_ply_positions", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(ptr::null(), |p| view(p.points.positions.as_flattened()))
    })
}

/// The positions as the file stores them, 3 doubles per vertex, when any of x y z is a double
/// (georeferenced clouds: give them to psr_reconstructor_add_points_f64 so that nothing is lost
/// to float); owned by p. NULL if p is NULL, has no vertices, or the file stores float (or
/// integer) coordinates.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_positions_f64(p: *const psr_ply) -> *const f64 {
    guard_value("psr_ply_positions_f64", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.positions_f64.as_deref())
            .map_or(ptr::null(), |v| view(v.as_flattened()))
    })
}

/// The normals, 3 floats per vertex, as stored (not normalised); owned by p. NULL if p is
/// NULL, has no vertices, or the file has no normals.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_normals(p: *const psr_ply) -> *const f32 {
    guard_value("psr_ply_normals", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(ptr::null(), |p| view(p.points.normals.as_flattened()))
    })
}

/// 3 (RGB) or 4 (RGBA) when the file has colours; 0 if it has none or p is NULL.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_color_components(p: *const psr_ply) -> usize {
    guard_value("psr_ply_color_components", 0, || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.colors.as_ref())
            .map_or(0, |c| c.components())
    })
}

/// The colours, psr_ply_color_components floats per vertex in 0..1 (integer colours divided by
/// their type's full scale, 255 for uchar; float colours as stored); owned by p. NULL if p is
/// NULL, has no vertices, or the file has no colours.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_colors(p: *const psr_ply) -> *const f32 {
    guard_value("psr_ply_colors", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.colors.as_ref())
            .map_or(ptr::null(), |c| view(c.as_flattened()))
    })
}

/// The `confidence` property (or else `value`, which is the density in a mesh psr wrote), one
/// float per vertex; owned by p. NULL if p is NULL, has no vertices, or the file has neither.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_confidence(p: *const psr_ply) -> *const f32 {
    guard_value("psr_ply_confidence", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.confidence.as_deref())
            .map_or(ptr::null(), view)
    })
}

/// The position of the sensor that saw each vertex, 3 floats per vertex (for
/// psr_reconstructor_add_positions_with_sensors); owned by p. NULL if p is NULL, has no
/// vertices, or the file has no sensor_x sensor_y sensor_z (vp_x ..., beamorigin_x ...).
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_sensors(p: *const psr_ply) -> *const f32 {
    guard_value("psr_ply_sensors", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.sensors.as_deref())
            .map_or(ptr::null(), |s| view(s.as_flattened()))
    })
}

/// Number of channels: the vertex element's other scalar properties, in the file's order; 0 if
/// p is NULL.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_channel_count(p: *const psr_ply) -> usize {
    guard_value("psr_ply_channel_count", 0, || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(0, |p| p.points.channels.len())
    })
}

/// The name of channel `index` (the property's name) as a NUL-terminated string owned by p.
/// NULL if p is NULL or index >= psr_ply_channel_count(p).
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_channel_name(p: *const psr_ply, index: usize) -> *const c_char {
    guard_value("psr_ply_channel_name", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.channel_names.get(index))
            .map_or(ptr::null(), |name| name.as_ptr())
    })
}

/// The values of channel `index`, one float per vertex; owned by p. NULL if p is NULL, has no
/// vertices, or index >= psr_ply_channel_count(p).
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_channel(p: *const psr_ply, index: usize) -> *const f32 {
    guard_value("psr_ply_channel", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }
            .and_then(|p| p.points.channels.get(index))
            .map_or(ptr::null(), |c| view(&c.values))
    })
}

/// Number of triangles the file's faces gave; 0 if p is NULL or the file has no faces (a point
/// cloud).
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_triangle_count(p: *const psr_ply) -> usize {
    guard_value("psr_ply_triangle_count", 0, || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(0, |p| p.triangles.len())
    })
}

/// The triangles, 3 vertex indices each (below psr_ply_vertex_count), in the file's order and
/// orientation; owned by p. NULL if p is NULL or has none.
///
/// # Safety
/// `p` is NULL or a live handle from psr_ply_read.
#[no_mangle]
pub unsafe extern "C" fn psr_ply_triangles(p: *const psr_ply) -> *const u32 {
    guard_value("psr_ply_triangles", ptr::null(), || {
        // SAFETY: forwarded from this function's contract.
        unsafe { ply_of(p) }.map_or(ptr::null(), |p| view(p.triangles.as_flattened()))
    })
}

/// Writes m to the file at `path` (created or replaced) as PLY, with the writer the psr program
/// uses, so the same mesh gives the same bytes as `psr --out mesh.ply`: vertex x y z (float;
/// double with PSR_PLY_DOUBLE_POSITIONS or when m's origin is not 0), nx ny nz when m has
/// vertex normals, value (the density), red green blue and alpha if RGBA (uchar) when it has
/// colours, a float per channel; face `list uchar int vertex_indices` (uint past 2^31
/// vertices).
/// Binary little-endian unless `flags` has PSR_PLY_ASCII or PSR_PLY_BIG_ENDIAN.
///
/// m and path must not be NULL; message may be NULL (or message_capacity 0). Returns
/// PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty path, a flag
/// this library does not know, PSR_PLY_ASCII with PSR_PLY_BIG_ENDIAN), PSR_STATUS_TOO_LARGE
/// (more than 2^32 vertices: PLY has no standard 64-bit index), PSR_STATUS_IO_ERROR (the file
/// cannot be created or written, e.g. no such directory or a full disk: the message has the
/// system's reason; a partly written file may be left) or PSR_STATUS_INTERNAL_ERROR. The
/// message is written on every return ("" on success). m is only read: several threads may
/// write (or read) the same mesh at once.
///
/// # Safety
/// `m` is NULL or a live mesh; `path` is NULL or a NUL-terminated string; `message` is NULL
/// or valid for writing `message_capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn psr_mesh_write_ply(
    m: *const psr_mesh,
    path: *const c_char,
    flags: u32,
    message: *mut c_char,
    message_capacity: usize,
) -> psr_status {
    const F: &str = "psr_mesh_write_ply";
    let body = || {
        // SAFETY: `m` is NULL or a live mesh (this function's contract); meshes never change.
        let mesh = unsafe { m.as_ref() }.ok_or_else(|| Failure::null(F, "m"))?;
        // SAFETY: `path` is NULL or a NUL-terminated string (this function's contract).
        let path = unsafe { path_argument(F, path) }?;
        let options = write_options(F, flags)?;
        let vertices = mesh.mesh.positions.len() as u64;
        if vertices > ply::MAX_PLY_MESH_VERTICES {
            return Err(Failure::new(
                psr_status::TooLarge,
                format!(
                    "{F}: the mesh has {vertices} vertices, more than the 2^32 PLY's 32-bit \
                     indices can name"
                ),
            ));
        }
        ply::write_mesh_with(&path, &mesh.mesh, &options).map_err(|e| {
            Failure::new(
                psr_status::IoError,
                format!("{F}: cannot write {}: {e}", path.display()),
            )
        })
    };
    // SAFETY: `message` is NULL or valid for message_capacity bytes (this function's contract).
    unsafe { with_message(F, message, message_capacity, body) }
}

/// The write options `flags` ask for.
fn write_options(function: &str, flags: u32) -> Result<WriteOptions, Failure> {
    let bad = |why: String| Failure::new(psr_status::InvalidArgument, format!("{function}: {why}"));
    if flags & !KNOWN_FLAGS != 0 {
        return Err(bad(format!(
            "flags {flags:#x} has bits this library does not know ({:#x}): PSR_PLY_ASCII, \
             PSR_PLY_BIG_ENDIAN and PSR_PLY_DOUBLE_POSITIONS are the flags",
            flags & !KNOWN_FLAGS
        )));
    }
    let format = match (flags & PSR_PLY_ASCII != 0, flags & PSR_PLY_BIG_ENDIAN != 0) {
        (false, false) => PlyFormat::BinaryLittleEndian,
        (true, false) => PlyFormat::Ascii,
        (false, true) => PlyFormat::BinaryBigEndian,
        (true, true) => {
            return Err(bad(
                "PSR_PLY_ASCII and PSR_PLY_BIG_ENDIAN together: a file is text or binary"
                    .to_string(),
            ))
        }
    };
    Ok(WriteOptions::default()
        .with_format(format)
        .with_double_positions(flags & PSR_PLY_DOUBLE_POSITIONS != 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(capacity: usize, text: &str) -> Vec<u8> {
        let mut buffer = vec![0x55u8; capacity + 4];
        // SAFETY: the buffer has capacity + 4 writable bytes.
        unsafe { write_message(buffer.as_mut_ptr().cast(), capacity, text) };
        buffer
    }

    /// Proves the message is NUL-terminated within its capacity, cut at a character boundary,
    /// and that a zero capacity writes nothing.
    #[test]
    fn messages_fit_their_buffers() {
        assert_eq!(&written(8, "abc")[..4], b"abc\0");
        assert_eq!(&written(4, "abcdef")[..5], b"abc\0\x55");
        // "é" is two bytes: a buffer of 3 holds "a" and the NUL, not half of it.
        assert_eq!(&written(3, "aé")[..3], b"a\0\x55");
        assert_eq!(written(0, "abc")[0], 0x55);
        assert_eq!(&written(1, "abc")[..2], b"\0\x55");
    }

    /// Proves every flag combination maps to its format, and unknown bits or ASCII with
    /// big-endian are refused.
    #[test]
    fn flags_choose_the_format() {
        let format = |flags| write_options("f", flags).map(|o| o.format);
        assert_eq!(format(0).ok(), Some(PlyFormat::BinaryLittleEndian));
        assert_eq!(format(PSR_PLY_ASCII).ok(), Some(PlyFormat::Ascii));
        assert_eq!(
            format(PSR_PLY_BIG_ENDIAN).ok(),
            Some(PlyFormat::BinaryBigEndian)
        );
        let double = write_options("f", PSR_PLY_DOUBLE_POSITIONS).ok().unwrap();
        assert!(double.double_positions);
        for bad in [PSR_PLY_ASCII | PSR_PLY_BIG_ENDIAN, 8, 1 << 31] {
            let failure = write_options("f", bad).err().unwrap();
            assert_eq!(failure.status, psr_status::InvalidArgument, "{bad}");
        }
    }
}

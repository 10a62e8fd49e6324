//! Scans with missing regions, made from a complete sampling: the side of a shape one camera
//! sees, or the part on one side of a plane.

use crate::point::v3;
use glam::DVec3;

/// The samples (with outward normals) for which `keep(position, normal)` holds, as
/// (positions, normals).
fn keep_where(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    keep: impl Fn(DVec3, DVec3) -> bool,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    positions
        .iter()
        .zip(normals)
        .filter(|(p, n)| keep(v3(**p), v3(**n)))
        .map(|(p, n)| (*p, *n))
        .unzip()
}

/// A single-view capture: the samples a camera at `camera` sees, those whose outward normal
/// faces it (n·(camera − p) > 0). Occlusion is not modelled, so this is exactly what the
/// camera sees of a convex shape, and the side facing it for any other (a torus seen from
/// above keeps the inner wall of its far side, which the near side would hide).
pub fn capture_from(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    camera: [f64; 3],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let camera = DVec3::from_array(camera);
    keep_where(positions, normals, |p, n| n.dot(camera - p) > 0.0)
}

/// The samples on the positive side of a plane, `normal`·p ≥ `offset` (e.g. the upper
/// hemisphere of a sphere about the origin: normal (0, 0, 1), offset 0).
pub fn keep_above_plane(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    normal: [f64; 3],
    offset: f64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let normal = DVec3::from_array(normal);
    keep_where(positions, normals, |p, _| normal.dot(p) >= offset)
}

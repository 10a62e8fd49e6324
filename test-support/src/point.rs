//! Points as `[f32; 3]` or `[f64; 3]`, and the bounding box of a point set.

use glam::DVec3;

pub(crate) fn v3(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

pub(crate) fn f32x3(p: DVec3) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

/// A point given as `[f32; 3]` or `[f64; 3]`.
pub trait AsPoint {
    fn point(&self) -> DVec3;
}

impl AsPoint for [f32; 3] {
    fn point(&self) -> DVec3 {
        v3(*self)
    }
}

impl AsPoint for [f64; 3] {
    fn point(&self) -> DVec3 {
        DVec3::from_array(*self)
    }
}

/// Axis-aligned bounding box (min, max) of a point set; `None` when empty.
fn bounding_box<P: AsPoint>(points: &[P]) -> Option<([f64; 3], [f64; 3])> {
    let first = points.first()?.point();
    let (lo, hi) = points.iter().fold((first, first), |(lo, hi), p| {
        let p = p.point();
        (lo.min(p), hi.max(p))
    });
    Some((lo.to_array(), hi.to_array()))
}

/// Diagonal length of the bounding box of a point set (0 when empty).
pub fn bbox_diagonal<P: AsPoint>(points: &[P]) -> f64 {
    match bounding_box(points) {
        Some((lo, hi)) => (DVec3::from_array(hi) - DVec3::from_array(lo)).length(),
        None => 0.0,
    }
}

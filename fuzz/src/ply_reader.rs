//! Arbitrary bytes through every reader the CLI and the library offer. Each returns an error or
//! arrays whose lengths agree and whose triangles index existing vertices; none may panic,
//! hang or allocate by a count the data does not back (libFuzzer's `-rss_limit_mb` and
//! `-timeout` turn those into findings).

use psr::{npts, ply};

/// Runs every reader on `data`.
pub fn run(data: &[u8]) {
    if let Ok(points) = ply::read_point_cloud_from(data) {
        check_points(&points, true);
    }
    if let Ok(points) = ply::read_points_from(data) {
        check_points(&points, false);
    }
    if let Ok((positions, triangles)) = ply::read_mesh_from(data) {
        check_triangles(&triangles, positions.len());
    }
    // The C API's psr_ply_read: the vertices as read_points reads them, and the faces.
    if let Ok((points, triangles)) = ply::read_points_and_triangles_from(data) {
        check_points(&points, false);
        check_triangles(&triangles, points.positions.len());
        let alone = ply::read_points_from(data).expect("the vertices read alone");
        // Compared as text: a NaN in the file equals itself there.
        assert_eq!(
            format!("{alone:?}"),
            format!("{points:?}"),
            "the vertices differ from read_points's"
        );
    }
    // PoissonRecon's ASCII layout may be positions only (3 numbers a line).
    if let Ok(points) = npts::read_ascii_from(data) {
        check_points(&points, false);
    }
    for colors in [false, true] {
        if let Ok(points) = npts::read_binary_from(data, colors) {
            check_points(&points, true);
        }
    }
}

/// Every triangle indexes one of the `vertices` read.
fn check_triangles(triangles: &[[u32; 3]], vertices: usize) {
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            assert!(
                (v as usize) < vertices,
                "mesh triangle {t} indexes vertex {v} of {vertices}"
            );
        }
    }
}

/// The arrays of one read cloud agree in length.
fn check_points(points: &ply::PlyPoints, normals_required: bool) {
    let n = points.positions.len();
    if normals_required || !points.normals.is_empty() {
        assert_eq!(points.normals.len(), n, "normals per position");
    }
    if let Some(exact) = &points.positions_f64 {
        assert_eq!(exact.len(), n, "f64 positions per position");
    }
    if let Some(confidence) = &points.confidence {
        assert_eq!(confidence.len(), n, "confidences per position");
    }
    if let Some(colors) = &points.colors {
        assert_eq!(colors.len(), n, "colours per position");
    }
    if let Some(sensors) = &points.sensors {
        assert_eq!(sensors.len(), n, "sensor positions per position");
    }
    for channel in &points.channels {
        assert_eq!(
            channel.values.len(),
            n,
            "channel {}'s values per position",
            channel.name
        );
    }
}

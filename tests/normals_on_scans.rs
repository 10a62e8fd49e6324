//! Issue 15's criterion on real data: on the shared scans with their normals stripped, normals
//! estimated from the positions alone (default options: k = 20, propagation) give a
//! reconstruction that is closed and manifold, has no inside-out regions, and lies as close to
//! the input points as the reconstruction from the files' normals (within 1.2×).
//!
//! Per scan, both reconstructions run with default parameters at one depth (chosen so the
//! finest cell is about the sampling spacing or coarser, and the file runs in about a minute on
//! two cores), and the test prints:
//!
//! * agreement: the fraction of points whose estimated normal has a positive dot product with
//!   the file's normal;
//! * flipped area: the area fraction, among the mesh triangles whose centroid lies within two
//!   finest cells of an input point, of those whose normal points against that nearest point's
//!   normal in the file. An inside-out patch of the mesh shows up here whatever its size; the
//!   mesh from the files' normals has a small such fraction too (noise, thin places the depth
//!   cannot resolve), so the estimated normals' mesh is compared with it;
//! * the mean distance from the input points to each mesh.
//!
//! What the files' normals are (see the data README): the bunny's and the Buddha's were
//! estimated per scan and turned towards the scanner, so they are outward wherever a scanner saw
//! the surface; the kitten's and the oni's come with CGAL; the lion's come with the source.
//!
//! Findings, measured with this test (depths as below; "points" are percentage points):
//!
//! * Happy Buddha: the estimated normals agreed with the file on 98.71 % of the points when one
//!   spanning tree decided every sign. Most of the 1.3 % was one 5,000-point patch on the statue's
//!   left side and a few patches of a few hundred points, each bounded by creases and reached by
//!   the tree through a place where points of different scans with opposite normals lie 0.05–0.2
//!   mm apart (spacing 0.15 mm): the patch came out inside out and the mesh got an inside-out
//!   bulge (flipped area 1.26 % against 0.50 % with the file's normals, +0.76 points). Since the
//!   orientation joins large regions by the votes of all the edges between them
//!   (`src/normals/orient.rs`), 99.32 % agree and the flipped area is 0.58 % (+0.09 points). The
//!   rest lies in the narrow grooves of the drapery, where a neighbourhood spans both walls: there
//!   the fitted plane is off by tens of degrees (median |n·n_file| 0.4–0.8 in the larger clusters,
//!   against 0.996 overall) and the file's own normals oppose their neighbours' mean for up to
//!   half of the points, so neither sign is meaningful; plus isolated stray points around the
//!   base. These do not make inside-out regions. With the two-sheet split
//!   (`src/normals/sheets.rs`: 9.8 % of the Buddha's points have neighbours split off, nearly all
//!   in overlaps of misregistered scans, which keep their orientation because they are joined
//!   along the sheets where the scans meet): 99.3226 % agree (99.3165 % before), flipped area 0.61
//!   % against 0.50 % (+0.11 points, +0.09 before), mean distance 0.98× the file normals' mesh's;
//!   the mesh has 3 components (2 before: small closed pieces off the statue). Since the
//!   density reads samples at a bend finer (2026-12-05, `density::BENT_SPREAD`): flipped area
//!   0.62 % against 0.50 % (+0.12 points), distance ratio 0.98, 2 components.
//! * Lion: an open scene. Over all points 92.9 % agree (92.7 % before the two-sheet split), but
//!   the disagreement is in separate clusters of foliage and a fence seen from one side: open
//!   fragments whose side the cloud does not determine (the file turns them towards the camera;
//!   propagation gives each component its own convention). On the largest connected part (the
//!   statue, its pedestal and the wall: 298,708 of 341,989 points) 99.77 % agree, so the
//!   flipped area is measured there: 0.40 % against 0.24 % with the file's normals (+0.16
//!   points); distance ratio 0.92 (since the density change: 0.41 % against 0.26 %, +0.15
//!   points, ratio 0.92).
//! * Oni: 1,435 points; 88.5 % agree. The inside of the open mouth (124 points) comes out flipped
//!   and the mesh fills the mouth instead of hollowing it: flipped area 2.58 % against 0.26 %
//!   (+2.32 points; +2.22 when first measured), mean distance 1.87× the file normals' mesh's
//!   (at 0d6dab6, as the tries below; since the density change: 3.41 % against 0.25 %, +3.15
//!   points, ratio 1.98, the file normals' mesh itself 23 % closer to the points).
//!   Other neighbour counts do not fix it (agreement on 2026-12-05 at k = 6: 93.0 %, 8: 92.7 %,
//!   10: 84.9 %, 12: 90.1 %; see below for their meshes). What
//!   decides it, measured: the mouth is a pocket whose floor meets the chin in a lip only 2–3
//!   sample spacings thick (spacing about 0.03, the 20-neighbourhood's radius 0.07), and the lip's
//!   bend is not resolved by the sampling: at the points along it the PCA normal is more than 25°
//!   off the file's for 31 % of them at k = 20 and still 16 % at k = 3. The mouth's region is
//!   joined to the rest by the votes across that lip, cast by such normals and by points the
//!   spanning trees put on the wrong side of the fold, and all of them say "same side". With the
//!   file's lines (signs scrambled) propagation gets 99.2 % right and the mouth right; with the
//!   file's lines everywhere but at the 141 worst-fitted points it flips the mouth again. The
//!   two-sheet split does not apply: a fold is not two parallel sheets (1.3 % of the oni's points
//!   have neighbours split off). A global check would: with the generalized winding number w of
//!   the oriented cloud, flipping the mouth's region brings w at points half a neighbourhood off
//!   the surface closer to 0 or 1 (prototype, region flips minimising Σ min(w², (w − 1)²): it
//!   flips the mouth's main region first, 94 % agreement, the mouth 67–74 % right) but it needs a
//!   fast winding-number evaluation to run on the large scans and is not implemented. Votes from
//!   views around the cloud were tried too (2026-12-04, not kept): 26 orthographic depth images,
//!   each point seen from direction d voting n·d, summed per region and joined to the regions'
//!   graph as one more region, the outside. Seen points agree with the file's sign 1,090 to 44,
//!   and every region's summed vote has the file's sign, but the mouth's inside is a pocket seen
//!   from few directions: 21 of its 91 points seen, a net vote of about 3 against the +140 of
//!   389 edges across the lip, so the mouth stays flipped at any weight; and the inner wall of a
//!   hollow ball is seen from nowhere (at 5× weight its uneven case fell from 99.31 % to 92 %).
//!   Tried on 2026-12-05, not kept: (i) the reconstruction checking its own normals: χ solved
//!   at depth 6 from the estimated normals, every point flipped where n·∇χ < 0, repeated: 12,
//!   3, 2, 1 points flip, none of them in the mouth (agreement 88.5 → 89.8 %), because the
//!   flipped mouth is a consistent input whose χ agrees with it; flipping instead the clusters
//!   of points farther than a cell from χ's level set when that brings the points closer: only
//!   21 points lie that far, in clusters of 1–2, and the mouth stays. (ii) Each point's plane
//!   taken from the best-fitting neighbourhood that contains it (least λ₀/Σλ among its own and
//!   its neighbours'; a remedy for creases): at k = 20 the lines more than 25° off the file's
//!   go from 363 to 650–671 of the 1,435 points and the flipped area is unchanged (+2.5
//!   points); at k = 8 it is +0.64 points but the distance ratio 1.29. Plain smaller
//!   neighbourhoods come closest (k = 6: distance ratio 1.17, flipped +1.74 points; k = 8:
//!   1.20, +2.01), and the oni's lines disagree with the file's everywhere at k = 20 (25 % of
//!   them more than 25° off). (iii) An adaptive k, each point's plane from the prefix of its
//!   neighbours (6 to 20 of them) with the least λ₀/Σλ: lines off 363 → 210, but the mouth
//!   stays flipped (+2.07 points, distance ratio 1.70): propagation across the lip still reads
//!   "same side". (iv) 2026-12-06, not kept: the reconstruction as the judge of region flips.
//!   With every sign right (the k = 20 lines given the file's signs) the mesh lies 3.17e-3 from
//!   the points on average, 1.42× the file normals' mesh's 2.24e-3, so at k = 20 the lines
//!   alone already fail the 1.2× bound. Flipping each of the orientation's 19 regions in turn
//!   and solving at depth 6, the misfit (the RMS of χ − γ at the samples over the mean |∇χ|)
//!   falls most, by 10.8 %, for the mouth's main region (91 points, 84 of them against the
//!   file): agreement 88.5 → 93.9 %, distance ratio 1.98 → 1.54. But greedy flipping goes on
//!   with a region that is right (66 points, 4 against the file: misfit −1.5 %, distance
//!   +6.3 %), and at k = 12 the first flip it picks is wrong (agreement 90.1 → 85.0 % for a
//!   misfit 11.8 % lower, the distance 15.5 % lower): where the lines are this poor, the fit
//!   does not tell a right sign from a wrong one. With propagation (the default) the criterion
//!   still fails: it is asserted in an ignored test, `oni_estimated_normals_keep_the_mouth_open`,
//!   and the default test checks that the mesh is a closed manifold and prints the figures.
//!   `Orientation::Reconstruction` (2026-12-06, `src/normals/reconstruction.rs`) meets it:
//!   signs and lines read off a mesh reconstructed from the normals themselves, in rounds coarse
//!   to fine from an arbitrary start (and from propagation's, the better fit kept): 99.86 % agree
//!   (2 points), flipped area 0.48 % against 0.25 % (+0.23 points), distance ratio 1.14
//!   (`oni_from_reconstruction_normals`); the kitten too (100 %, +0.0003 points, 1.00).
//! * Bunny and kitten: no flipped regions (+0.0007 and −0.0002 points; +0.0009 and +0.0001
//!   since the density change); distance ratios 0.99 and 1.13 (0.99 and 1.15); 99.956 % and
//!   100 % agree (the bunny 99.961 % before the two-sheet split).

use psr::{estimate_normals, reconstruct, Mesh, NormalEstimation, Orientation, Params, PointSet};
use psr_test_support::{data_or_skip, MeshDistance, MeshTopology};
use std::collections::HashMap;
use std::time::Instant;

/// The file's points and normals, and the normals estimated from its positions.
struct Scan {
    positions: Vec<[f32; 3]>,
    given: Vec<[f32; 3]>,
    estimated: Vec<[f32; 3]>,
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f64 {
    (a[0] as f64) * (b[0] as f64) + (a[1] as f64) * (b[1] as f64) + (a[2] as f64) * (b[2] as f64)
}

/// Reads `name` (or skips) and estimates normals with the default options.
fn load(name: &str, test: &str) -> Option<Scan> {
    load_with(name, test, &NormalEstimation::default())
}

/// Reads `name` (or skips) and estimates normals with `options`.
fn load_with(name: &str, test: &str, options: &NormalEstimation) -> Option<Scan> {
    let path = data_or_skip(name, test)?;
    let cloud = psr::ply::read_point_cloud(&path).unwrap();
    let started = Instant::now();
    let estimated = estimate_normals(&cloud.positions, options).unwrap();
    let agree = estimated
        .iter()
        .zip(&cloud.normals)
        .filter(|(a, b)| dot(**a, **b) > 0.0)
        .count();
    eprintln!(
        "{name}: {} points, normals estimated in {:.2} s, agreement with the file {:.4} % ({} disagree)",
        cloud.len(),
        started.elapsed().as_secs_f64(),
        100.0 * agree as f64 / cloud.len() as f64,
        cloud.len() - agree
    );
    Some(Scan {
        positions: cloud.positions,
        given: cloud.normals,
        estimated,
    })
}

/// The finest cell's width at `depth`: the bounding box's longest side × the default scale
/// (1.1), over 2^depth.
fn finest_cell(positions: &[[f32; 3]], params: &Params) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    let side = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    side * params.scale as f64 / (1u64 << params.depth) as f64
}

/// The input points' nearest-point index: a BVH over the points as degenerate triangles (the
/// test-support BVH handles them exactly).
fn point_index(positions: &[[f32; 3]]) -> MeshDistance {
    let triangles: Vec<[u32; 3]> = (0..positions.len() as u32).map(|i| [i, i, i]).collect();
    MeshDistance::new(positions, &triangles)
}

/// Flipped area (see the module documentation): among the triangles whose centroid lies within
/// `near` of an input point counted by `counts`, the area fraction of those whose normal
/// points against that point's normal in `reference`.
fn flipped_area(
    mesh: &Mesh,
    points: &MeshDistance,
    reference: &[[f32; 3]],
    counts: &dyn Fn(usize) -> bool,
    near: f64,
) -> f64 {
    let (mut flipped, mut total) = (0.0, 0.0);
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize].map(|x| x as f64));
        let (u, v) = (
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let cross = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let area = 0.5 * (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
        let nearest = points.closest(centroid);
        if nearest.distance > near || !counts(nearest.triangle) {
            continue;
        }
        let n = reference[nearest.triangle];
        let agreement = cross[0] * n[0] as f64 + cross[1] * n[1] as f64 + cross[2] * n[2] as f64;
        total += area;
        if agreement < 0.0 {
            flipped += area;
        }
    }
    flipped / total
}

/// Mean distance from the input points to the mesh.
fn mean_distance(mesh: &Mesh, positions: &[[f32; 3]]) -> f64 {
    let d = MeshDistance::new(&mesh.positions, &mesh.triangles).distances(positions);
    d.iter().sum::<f64>() / d.len() as f64
}

/// Labels every point with its connected part, points closer than `radius` being connected
/// (a hash grid of cells `radius` wide, union–find); returns the labels and the largest part's.
fn parts(positions: &[[f32; 3]], radius: f64) -> (Vec<u32>, u32) {
    let cell = |p: [f32; 3]| p.map(|x| (x as f64 / radius).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (i, &p) in positions.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i as u32);
    }
    let mut parent: Vec<u32> = (0..positions.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for (i, &p) in positions.iter().enumerate() {
        let c = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(others) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &j in others {
                        if (j as usize) <= i {
                            continue;
                        }
                        let q = positions[j as usize];
                        let d2: f64 = (0..3).map(|a| (p[a] as f64 - q[a] as f64).powi(2)).sum();
                        if d2 <= radius * radius {
                            let (a, b) = (find(&mut parent, i as u32), find(&mut parent, j));
                            parent[a.max(b) as usize] = a.min(b);
                        }
                    }
                }
            }
        }
    }
    let labels: Vec<u32> = (0..positions.len() as u32)
        .map(|i| find(&mut parent, i))
        .collect();
    let mut size = vec![0u32; positions.len()];
    for &l in &labels {
        size[l as usize] += 1;
    }
    let largest = (0..positions.len()).max_by_key(|&l| size[l]).unwrap() as u32;
    (labels, largest)
}

/// What the test measured on one scan.
struct Figures {
    flipped_given: f64,
    flipped_estimated: f64,
    distance_given: f64,
    distance_estimated: f64,
}

/// Reconstructs `scan` from both sets of normals at `depth`, checks both meshes are closed
/// 2-manifolds, prints and returns the figures. With `largest_part_only`, the flipped area
/// counts only triangles whose nearest input point lies in the cloud's largest connected part
/// (points within two finest cells connected).
fn measure(name: &str, scan: &Scan, depth: u32, largest_part_only: bool) -> Figures {
    let params = Params::default().with_depth(depth);
    let h = finest_cell(&scan.positions, &params);
    let points = point_index(&scan.positions);
    let labels = largest_part_only.then(|| parts(&scan.positions, 2.0 * h));
    let counts = |i: usize| match &labels {
        Some((labels, largest)) => labels[i] == *largest,
        None => true,
    };
    if let Some((labels, largest)) = &labels {
        let inside: Vec<usize> = (0..labels.len())
            .filter(|&i| labels[i] == *largest)
            .collect();
        let agree = inside
            .iter()
            .filter(|&&i| dot(scan.estimated[i], scan.given[i]) > 0.0)
            .count();
        eprintln!(
            "{name}: largest connected part {} of {} points, agreement there {:.4} %",
            inside.len(),
            labels.len(),
            100.0 * agree as f64 / inside.len() as f64
        );
    }
    let mut figures = Vec::new();
    for (label, normals) in [("file", &scan.given), ("estimated", &scan.estimated)] {
        let started = Instant::now();
        let mesh = reconstruct(
            &PointSet::from_slices(&scan.positions, normals).unwrap(),
            &params,
        )
        .unwrap();
        let seconds = started.elapsed().as_secs_f64();
        let topo = MeshTopology::of(&mesh.positions, &mesh.triangles);
        assert!(
            topo.is_closed_manifold() && topo.is_consistently_oriented(),
            "{name}, {label} normals: not a closed oriented manifold: {topo}"
        );
        let flipped = flipped_area(&mesh, &points, &scan.given, &counts, 2.0 * h);
        let distance = mean_distance(&mesh, &scan.positions);
        eprintln!(
            "{name}, {label} normals, depth {depth}: {} triangles in {seconds:.2} s, {} components, \
             flipped area {:.4} %, mean distance to the points {distance:.4e} ({:.4} cells)",
            mesh.triangles.len(),
            topo.components,
            100.0 * flipped,
            distance / h
        );
        figures.push((flipped, distance));
    }
    let figures = Figures {
        flipped_given: figures[0].0,
        flipped_estimated: figures[1].0,
        distance_given: figures[0].1,
        distance_estimated: figures[1].1,
    };
    eprintln!(
        "{name}: flipped area estimated − file {:+.4} points; distance ratio estimated / file {:.4}",
        100.0 * (figures.flipped_estimated - figures.flipped_given),
        figures.distance_estimated / figures.distance_given
    );
    figures
}

/// How much more flipped area than the file's normals' mesh the estimated normals' mesh may
/// have, as a fraction of the near area: 0.3 percentage points. Between what the two meshes
/// differ by where neither side's sign is meaningful (measured: Buddha +0.09 points, lion
/// +0.16) and what an inside-out patch costs (the Buddha's 5,000-point patch +0.76, the oni's
/// mouth +2.24).
const FLIPPED_MARGIN: f64 = 0.003;

/// The bound on the distance from the points to the mesh.
const DISTANCE_RATIO: f64 = 1.2;

fn assert_criterion(name: &str, f: &Figures) {
    assert!(
        f.flipped_estimated <= f.flipped_given + FLIPPED_MARGIN,
        "{name}: flipped area {:.4} % with estimated normals against {:.4} % with the file's",
        100.0 * f.flipped_estimated,
        100.0 * f.flipped_given
    );
    assert!(
        f.distance_estimated <= DISTANCE_RATIO * f.distance_given,
        "{name}: mean distance {:.4e} with estimated normals against {:.4e} with the file's",
        f.distance_estimated,
        f.distance_given
    );
}

/// Proves: the bunny's scans (362k points) give a closed manifold from estimated normals with no
/// more flipped area than from the scanner-oriented normals, as close to the points.
#[test]
fn bunny_from_estimated_normals() {
    let name = "bunny_scans.ply";
    let Some(scan) = load(name, "bunny_from_estimated_normals") else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, 8, false));
}

/// Proves: the same for the Happy Buddha's scans (1.1M points); see the module documentation
/// for the disagreement that remains and why it does not flip the mesh.
#[test]
fn happy_buddha_from_estimated_normals() {
    let name = "happy_buddha_scans.ply";
    let Some(scan) = load(name, "happy_buddha_from_estimated_normals") else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, 8, false));
}

/// Proves: the same for CGAL's kitten (5k points, depth 7: its spacing is about a cell).
#[test]
fn kitten_from_estimated_normals() {
    let name = "kitten_cgal.ply";
    let Some(scan) = load(name, "kitten_from_estimated_normals") else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, 7, false));
}

/// Proves: the lion scene (342k points, open, with foliage) gives a closed manifold from
/// estimated normals, with no more flipped area on its largest connected part than from the
/// normals it ships with, as close to the points. See the module documentation for why only the
/// largest part's sign is checked.
#[test]
fn lion_from_estimated_normals() {
    let name = "lion_takanawa_rgb.ply";
    let Some(scan) = load(name, "lion_from_estimated_normals") else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, 8, true));
}

/// Proves: CGAL's oni (1.4k points, depth 6) gives a closed manifold from estimated normals.
/// Its flipped area and distance are printed, not asserted: they fail the criterion (see
/// `oni_estimated_normals_keep_the_mouth_open`).
#[test]
fn oni_from_estimated_normals() {
    let name = "oni_cgal.ply";
    let Some(scan) = load(name, "oni_from_estimated_normals") else {
        return;
    };
    measure(name, &scan, 6, false);
}

/// The criterion on the oni, which fails today: the inside of the mouth comes out
/// flipped and the mesh fills it (see the module documentation). Run with `--ignored`.
#[test]
#[ignore = "known failure: the oni's lip folds within a few sample spacings (issue 15)"]
fn oni_estimated_normals_keep_the_mouth_open() {
    let name = "oni_cgal.ply";
    let Some(scan) = load(name, "oni_estimated_normals_keep_the_mouth_open") else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, 6, false));
}

/// The criterion on `name` at `depth` with normals from `Orientation::Reconstruction`
/// (see [`measure`] for `largest_part_only`).
fn assert_with_reconstruction_normals(name: &str, test: &str, depth: u32, largest_part_only: bool) {
    let options = NormalEstimation::default().with_orientation(Orientation::Reconstruction);
    let Some(scan) = load_with(name, test, &options) else {
        return;
    };
    assert_criterion(name, &measure(name, &scan, depth, largest_part_only));
}

/// Proves: the oni meets the criterion with the orientation read off the reconstruction
/// itself (`Orientation::Reconstruction`): the mouth comes out open (no more flipped area than
/// with the file's normals beyond the margin) and the mesh within 1.2× of their distance.
#[test]
fn oni_from_reconstruction_normals() {
    assert_with_reconstruction_normals("oni_cgal.ply", "oni_from_reconstruction_normals", 6, false);
}

/// Proves: the bunny's scans meet the criterion with `Orientation::Reconstruction` too. Ignored
/// by default: minutes of rounds at depths up to 10 (docs/benchmarks.md).
#[test]
#[ignore = "minutes: Orientation::Reconstruction on 362k points"]
fn bunny_from_reconstruction_normals() {
    assert_with_reconstruction_normals(
        "bunny_scans.ply",
        "bunny_from_reconstruction_normals",
        8,
        false,
    );
}

/// Proves: the Happy Buddha's scans meet the criterion with `Orientation::Reconstruction`.
/// Ignored by default: minutes of rounds at depths up to 10 (docs/benchmarks.md).
#[test]
#[ignore = "minutes: Orientation::Reconstruction on 1.1M points"]
fn happy_buddha_from_reconstruction_normals() {
    assert_with_reconstruction_normals(
        "happy_buddha_scans.ply",
        "happy_buddha_from_reconstruction_normals",
        8,
        false,
    );
}

/// Proves: the lion scene meets the criterion on its largest part with
/// `Orientation::Reconstruction`. Ignored by default: minutes of rounds.
#[test]
#[ignore = "minutes: Orientation::Reconstruction on 342k points"]
fn lion_from_reconstruction_normals() {
    assert_with_reconstruction_normals(
        "lion_takanawa_rgb.ply",
        "lion_from_reconstruction_normals",
        8,
        true,
    );
}

/// Proves: the kitten meets it too with `Orientation::Reconstruction`.
#[test]
fn kitten_from_reconstruction_normals() {
    assert_with_reconstruction_normals(
        "kitten_cgal.ply",
        "kitten_from_reconstruction_normals",
        7,
        false,
    );
}

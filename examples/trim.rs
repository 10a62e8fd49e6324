//! Reconstructs a point cloud, trims the mesh at the automatic threshold (or the one given) and
//! prints what the trim did: how long it took at each thread count (fastest of `--repeat`
//! runs), where it cut, and with `--distances` the mean distance from the mesh to the points
//! and from the points to the mesh, before and after. Optionally writes both meshes.
//!
//! ```text
//! cargo run --release --example trim -- IN.ply [--depth 8] [--threads 1,2] [--repeat 3]
//!     [--trim-depth D] [--distances] [--out-before B.ply] [--out-after A.ply]
//! ```
//!
//! The figures in docs/benchmarks.md ("Issue 16 — trimming") come from it.

use psr::{ply, Params, PointSet, Threshold, Trimming};
use psr_test_support::{mesh_to_points_distance, one_sided_mesh_distance};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut input = None;
    let (mut depth, mut repeat, mut distances) = (8u32, 3usize, false);
    let mut threads = vec![1usize, 2];
    let mut trimming = Trimming::default();
    let (mut out_before, mut out_after) = (None, None);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--depth" => depth = value()?.parse()?,
            "--repeat" => repeat = value()?.parse()?,
            "--threads" => {
                threads = value()?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()?
            }
            "--trim-depth" => trimming.threshold = Threshold::Depth(value()?.parse()?),
            "--distances" => distances = true,
            "--out-before" => out_before = Some(PathBuf::from(value()?)),
            "--out-after" => out_after = Some(PathBuf::from(value()?)),
            _ if input.is_none() => input = Some(PathBuf::from(arg)),
            _ => return Err(format!("unexpected argument {arg}").into()),
        }
    }
    let input = input.ok_or("usage: trim IN.ply [options]")?;
    let cloud = ply::read_points(&input)?;
    let points = PointSet::from_slices(&cloud.positions, &cloud.normals)?;
    let started = Instant::now();
    let mesh = psr::reconstruct(&points, &Params::default().with_depth(depth))?;
    println!(
        "{}: {} points, depth {depth}: {} vertices, {} triangles in {:.2} s",
        input.display(),
        points.len(),
        mesh.positions.len(),
        mesh.triangles.len(),
        started.elapsed().as_secs_f64()
    );
    let mut trimmed = None;
    for &t in &threads {
        let options = trimming.clone().with_threads(t);
        let mut fastest = f64::INFINITY;
        for _ in 0..repeat.max(1) {
            let started = Instant::now();
            let result = psr::trim(&mesh, &options)?;
            fastest = fastest.min(started.elapsed().as_secs_f64());
            trimmed = Some(result);
        }
        println!("trim, {t} thread(s): {fastest:.3} s (fastest of {repeat})");
    }
    let trimmed = trimmed.ok_or("no thread count given")?;
    let report = trimmed.stats.trim.as_ref().ok_or("no trim report")?;
    println!(
        "cut at density {:.4} (depth-like {:.3}): {} vertices, {} triangles; {} crossings \
         snapped, {} kept apart; {} pieces, {} dropped; area {:.4} -> {:.4}",
        report.density,
        report.depth,
        trimmed.positions.len(),
        trimmed.triangles.len(),
        report.snapped_crossings,
        report.clamped_crossings,
        report.pieces,
        report.pieces_dropped,
        report.area_before,
        report.area_after
    );
    if distances {
        let m2p = |m: &psr::Mesh| {
            mesh_to_points_distance(&m.positions, &m.triangles, &cloud.positions, 200_000, 7).mean
        };
        let p2m = |m: &psr::Mesh| {
            one_sided_mesh_distance(&cloud.positions, &m.positions, &m.triangles).mean
        };
        let (before, after) = (m2p(&mesh), m2p(&trimmed));
        println!(
            "mesh -> points mean {before:.4e} -> {after:.4e} ({:.1}x less)",
            before / after
        );
        let (before, after) = (p2m(&mesh), p2m(&trimmed));
        println!(
            "points -> mesh mean {before:.4e} -> {after:.4e} ({:+.2} %)",
            100.0 * (after / before - 1.0)
        );
    }
    if let Some(path) = out_before {
        ply::write_mesh(&path, &mesh)?;
    }
    if let Some(path) = out_after {
        ply::write_mesh(&path, &trimmed)?;
    }
    Ok(())
}

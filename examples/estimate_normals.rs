//! Estimates and orients the normals of a point cloud's positions, the way psr does for a cloud
//! without normals, and prints how long it took and how many of the estimated normals agree in
//! sign with the file's own (when it has them). Optionally writes the oriented cloud.
//!
//! ```text
//! cargo run --release --example estimate_normals -- IN.ply [--neighbors 20] [--threads 0]
//!     [--orientation propagate|reconstruction] [--reconstruction-iterations 10]
//!     [--viewpoint X,Y,Z] [--out ORIENTED.ply]
//! ```
//!
//! `bench/normals.py` times it against Open3D's estimate_normals +
//! orient_normals_consistent_tangent_plane.

use psr::ply::{self, PlyFormat};
use psr::{estimate_normals, NormalEstimation, Orientation};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut input = None;
    let mut output = None;
    let mut options = NormalEstimation::default();
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--neighbors" => options.neighbors = value()?.parse()?,
            "--threads" => options.threads = value()?.parse()?,
            "--viewpoint" => {
                let v: Vec<f64> = value()?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()?;
                let [x, y, z] = v[..] else {
                    return Err("--viewpoint takes X,Y,Z".into());
                };
                options.orientation = Orientation::Viewpoint([x, y, z]);
            }
            "--orientation" => {
                options.orientation = match value()?.as_str() {
                    "propagate" => Orientation::Propagate,
                    "reconstruction" => Orientation::Reconstruction,
                    other => {
                        return Err(format!(
                            "--orientation takes propagate or reconstruction, not {other} \
                             (--viewpoint X,Y,Z selects the viewpoint)"
                        )
                        .into())
                    }
                }
            }
            "--reconstruction-iterations" => {
                options.reconstruction_iterations = value()?.parse()?
            }
            "--out" => output = Some(PathBuf::from(value()?)),
            _ if input.is_none() => input = Some(PathBuf::from(arg)),
            _ => return Err(format!("unexpected argument {arg}").into()),
        }
    }
    let input = input.ok_or("usage: estimate_normals IN.ply [options]")?;
    let mut cloud = ply::read_points(&input)?;
    let started = Instant::now();
    let normals = estimate_normals(&cloud.positions, &options)?;
    let seconds = started.elapsed().as_secs_f64();
    let agreement = if cloud.normals.len() == normals.len() {
        let agree = normals
            .iter()
            .zip(&cloud.normals)
            .filter(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0.0)
            .count();
        format!(
            "; {:.3} % agree in sign with the file's normals",
            100.0 * agree as f64 / normals.len() as f64
        )
    } else {
        String::new()
    };
    println!(
        "estimate_normals: {} points, k = {}, estimated and oriented in {seconds:.2} s{agreement}",
        normals.len(),
        options.neighbors
    );
    if let Some(output) = output {
        cloud.normals = normals;
        ply::write_point_cloud(&output, &cloud, PlyFormat::BinaryLittleEndian)?;
    }
    Ok(())
}

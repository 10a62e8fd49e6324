//! Small fuzzer-made clouds through the Rust API, with random parameters: each gives an error or
//! a closed, consistently oriented mesh with finite vertices and one density per vertex.
//!
//! The cloud's coordinates come from a few scales (unit, 10⁶ offsets, 10⁻³⁰ and 10³⁰ spans) so
//! that duplicates, collinear and coplanar sets and extreme ranges are reached by small inputs;
//! the depth stays at most 7 so that one run takes milliseconds (deep trees are the business of
//! the extreme-input tests).

use crate::mesh_check::{assert_finite, assert_oriented_manifold};
use arbitrary::{Result, Unstructured};
use psr::{
    estimate_normals, reconstruct, Boundary, NormalEstimation, Orientation, Params, PointSet,
    Splatting, VertexPlacement,
};

/// The most points one input makes (more make runs slow without reaching new code).
const MAX_POINTS: usize = 400;

/// Runs one reconstruction from `data`.
pub fn run(data: &[u8]) {
    let _ = run_unstructured(&mut Unstructured::new(data));
}

fn run_unstructured(u: &mut Unstructured<'_>) -> Result<()> {
    let params = params(u)?;
    let scale = *u.choose(&[1.0f32, 1e-3, 1e3, 1e-30, 1e30, 3e38])?;
    let offset = *u.choose(&[0.0f32, 1e6, -1e6, 1e30])?;
    let with_normals: bool = u.arbitrary()?;
    let count = u.int_in_range(0..=MAX_POINTS)?;
    let mut positions = Vec::with_capacity(count);
    let mut normals = Vec::with_capacity(count);
    for _ in 0..count {
        if u.is_empty() {
            break;
        }
        let q: [i8; 3] = u.arbitrary()?;
        positions.push(q.map(|c| offset + scale * f32::from(c) / 16.0));
        let m: [i8; 3] = u.arbitrary()?;
        normals.push(m.map(|c| f32::from(c) / 32.0));
    }
    let normals = if with_normals {
        normals
    } else {
        let mut options = NormalEstimation::default();
        options.neighbors = u.int_in_range(0..=40)?;
        options.orientation = if u.arbitrary()? {
            Orientation::Propagate
        } else {
            let v: [i8; 3] = u.arbitrary()?;
            Orientation::Viewpoint(v.map(|c| f64::from(offset) + f64::from(c)))
        };
        options.threads = params.threads;
        match estimate_normals(&positions, &options) {
            Ok(estimated) => {
                assert_eq!(estimated.len(), positions.len(), "one normal per point");
                for n in &estimated {
                    assert_finite(n, "estimated normal");
                }
                estimated
            }
            Err(_) => return Ok(()),
        }
    };
    // Choices added to the target later come from the input's end, so that the inputs of past
    // findings (fuzz/regressions/) still decode to the same cloud and parameters.
    let budgets = [None, Some(0), Some(1 << 16), Some(1 << 22), Some(1 << 30)];
    let params = params.with_max_memory(*u.choose(&budgets).unwrap_or(&None));
    let params = params.with_screening_follows_noise(u.arbitrary().unwrap_or(false));
    // A complete grid at depth 7 (full depth ≥ 7: 2.1 M unknowns) is legitimate work of seconds
    // (6.7 s on one thread), past a fuzz run's time per input under AddressSanitizer: full
    // grids stop at depth 6 here (deep and full trees are the extreme-input tests' business).
    let full_depth = params.full_depth.min(6);
    let params = params.with_full_depth(full_depth);
    let Ok(points) = PointSet::from_slices(&positions, &normals) else {
        return Ok(());
    };
    if let Ok(mesh) = reconstruct(&points, &params) {
        let flat: Vec<f32> = mesh.positions.iter().flatten().copied().collect();
        assert_finite(&flat, "mesh vertex");
        assert_eq!(
            mesh.densities.len(),
            mesh.positions.len(),
            "one density per vertex"
        );
        let stats = &mesh.stats;
        if let Some(noise) = stats.sample_noise {
            assert!(
                params.screening_follows_noise && noise.is_finite() && noise >= 0.0,
                "sample noise {noise} (estimated: {})",
                params.screening_follows_noise
            );
        }
        assert!(
            stats.screening_depth.is_finite() && stats.screening_depth <= params.depth as f64,
            "screening depth {} for depth {}",
            stats.screening_depth,
            params.depth
        );
        let boundary = assert_oriented_manifold(mesh.positions.len(), &mesh.triangles, "mesh");
        let cube = BoundingCube::of(&positions, params.scale, mesh.stats.depth);
        for (a, b) in boundary {
            for v in [a, b] {
                let p = mesh.positions[v as usize];
                assert!(
                    cube.on_a_face(p),
                    "open edge {a}-{b} away from the cube's faces: vertex {v} at {p:?}, {cube:?}"
                );
            }
        }
    }
    Ok(())
}

/// The cube psr reconstructs in, as `Params::scale` documents it: centred on the points'
/// bounding box, its edge `scale` times the box's longest side; and a quarter of a finest cell
/// (or f32's resolution at the cube's coordinates, when coarser) as the tolerance of "on a face".
#[derive(Debug)]
struct BoundingCube {
    low: [f64; 3],
    size: f64,
    tolerance: f64,
}

impl BoundingCube {
    fn of(positions: &[[f32; 3]], scale: f32, depth: u32) -> BoundingCube {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in positions {
            for a in 0..3 {
                lo[a] = lo[a].min(f64::from(p[a]));
                hi[a] = hi[a].max(f64::from(p[a]));
            }
        }
        let size = f64::from(scale) * (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let magnitude = (0..3)
            .map(|a| lo[a].abs().max(hi[a].abs()))
            .fold(size, f64::max);
        BoundingCube {
            low: std::array::from_fn(|a| (lo[a] + hi[a]) / 2.0 - size / 2.0),
            size,
            tolerance: (0.25 * size * (-f64::from(depth)).exp2())
                .max(4.0 * magnitude * f64::from(f32::EPSILON)),
        }
    }

    fn on_a_face(&self, p: [f32; 3]) -> bool {
        (0..3).any(|a| {
            let c = f64::from(p[a]) - self.low[a];
            c.abs() <= self.tolerance || (c - self.size).abs() <= self.tolerance
        })
    }
}

/// Parameters, valid or not (invalid ones must be refused with an error).
fn params(u: &mut Unstructured<'_>) -> Result<Params> {
    // The degree first: it also sets the point weight, which is then chosen below.
    Ok(Params::default()
        .with_degree(*u.choose(&[2u8, 1, 0, 3])?)
        .with_depth(u.int_in_range(0..=7)?)
        .with_full_depth(u.int_in_range(0..=8)?)
        .with_kernel_depth(if u.arbitrary()? {
            Some(u.int_in_range(0..=8)?)
        } else {
            None
        })
        .with_samples_per_node(*u.choose(&[1.5f32, 1.0, 0.0, 20.0, -1.0, f32::NAN])?)
        .with_scale(*u.choose(&[1.1f32, 1.0, 2.0, 0.5, 0.0, f32::INFINITY])?)
        .with_point_weight(*u.choose(&[4.0f32, 0.0, 1.0, 100.0, -1.0])?)
        .with_threads(u.int_in_range(1..=3)?)
        .with_max_solver_iterations(*u.choose(&[60u32, 0, 1, 5])?)
        .with_splatting(*u.choose(&[Splatting::BSpline, Splatting::Trilinear])?)
        .with_boundary(*u.choose(&[Boundary::Neumann, Boundary::Free, Boundary::Dirichlet])?)
        .with_vertex_placement(
            *u.choose(&[VertexPlacement::Fitted, VertexPlacement::OnIsosurface])?,
        )
        .with_vertex_normals(u.arbitrary()?)
        .with_min_component_samples(*u.choose(&[8u32, 0, 1, 1000])?))
}

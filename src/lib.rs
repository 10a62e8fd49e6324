//! # psr — Poisson surface reconstruction
//!
//! Turns oriented point samples into a watertight triangle mesh by solving a Poisson problem for
//! the indicator function and extracting its isosurface (Kazhdan, Bolitho & Hoppe, "Poisson
//! Surface Reconstruction", SGP 2006), with the screening term of Kazhdan & Hoppe (2013).
//!
//! ```no_run
//! let points = psr::PointSet::from_slices(&[[0.0, 0.0, 0.0]], &[[0.0, 0.0, 1.0]]).unwrap();
//! let mesh = psr::reconstruct(&points, &psr::Params::default()).unwrap();
//! println!("{} vertices, {} triangles", mesh.positions.len(), mesh.triangles.len());
//! ```
//!
//! The reconstruction is one straight pipeline; each stage is a module:
//! points → density → octree → splat → system → solve → isovalue → extract → mesh.

pub mod bspline;
pub mod density;
pub mod error;
pub mod evaluate;
pub mod extract;
pub mod ffi;
mod grid;
pub mod octree;
mod parallel;
pub mod params;
mod pipeline;
pub mod ply;
pub mod points;
pub mod solve;
pub mod splat;
pub mod system;

pub use error::{Error, Result};
pub use params::{Boundary, Params, Splatting, VertexPlacement};
pub use points::PointSet;

/// The stages of a reconstruction, in order, as reported to progress callbacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Stage {
    Points = 0,
    /// The density estimate comes before the octree: each sample's depth decides its nodes.
    Density = 1,
    Octree = 2,
    Splat = 3,
    System = 4,
    Solve = 5,
    Isovalue = 6,
    Extract = 7,
    Mesh = 8,
}

impl Stage {
    /// All stages in pipeline order.
    pub const ALL: [Stage; 9] = [
        Stage::Points,
        Stage::Density,
        Stage::Octree,
        Stage::Splat,
        Stage::System,
        Stage::Solve,
        Stage::Isovalue,
        Stage::Extract,
        Stage::Mesh,
    ];

    /// A short lower-case name ("solve").
    pub fn name(self) -> &'static str {
        match self {
            Stage::Points => "points",
            Stage::Octree => "octree",
            Stage::Density => "density",
            Stage::Splat => "splat",
            Stage::System => "system",
            Stage::Solve => "solve",
            Stage::Isovalue => "isovalue",
            Stage::Extract => "extract",
            Stage::Mesh => "mesh",
        }
    }
}

/// How one depth's linear solve ended.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthSolve {
    pub depth: u32,
    /// Unknowns (octree nodes) at this depth.
    pub unknowns: usize,
    pub iterations: u32,
    /// ‖b − Ax‖ / ‖b‖ at the end (0 when b = 0).
    pub relative_residual: f64,
    /// Wall seconds for this depth (right-hand side, operator set-up and iterations).
    pub seconds: f64,
}

/// Figures about a reconstruction, for logs and benchmarks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stats {
    pub points: usize,
    /// Octree nodes (unknowns) per depth, index = depth.
    pub nodes_per_depth: Vec<usize>,
    /// The isovalue γ the surface was extracted at (§4.4).
    pub isovalue: f64,
    pub solves: Vec<DepthSolve>,
    /// Wall seconds spent in each stage, in pipeline order.
    pub stage_seconds: Vec<(Stage, f64)>,
}

impl Stats {
    /// Total octree nodes over all depths.
    pub fn total_nodes(&self) -> usize {
        self.nodes_per_depth.iter().sum()
    }
}

/// A triangle mesh in the input's coordinates.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    /// Counter-clockwise seen from outside: normals point out of the reconstructed solid.
    pub triangles: Vec<[u32; 3]>,
    /// Sampling density estimate at each vertex (kernel density of §4.5, in samples per
    /// kernel-depth node): low values mark surface invented far from any sample (for trimming).
    pub densities: Vec<f32>,
    pub stats: Stats,
}

/// A progress callback: receives the stage and the fraction of it done (0..=1) and returns
/// `true` to go on, `false` to cancel. It is called on the thread that called
/// [`reconstruct_with_progress`], never concurrently.
pub type Progress<'a> = &'a mut dyn FnMut(Stage, f32) -> bool;

/// Reconstructs a watertight mesh from oriented points.
pub fn reconstruct(points: &PointSet, params: &Params) -> Result<Mesh> {
    reconstruct_with_progress(points, params, &mut |_, _| true)
}

/// [`reconstruct`] with a progress callback that may cancel (then the result is
/// `Err(Error::Cancelled)`).
pub fn reconstruct_with_progress(
    points: &PointSet,
    params: &Params,
    progress: Progress<'_>,
) -> Result<Mesh> {
    params.validate()?;
    if points.is_empty() {
        return Err(Error::EmptyInput);
    }
    let threads = if params.threads == 0 {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    } else {
        params.threads
    };
    // The pipeline runs on the caller's thread (so the progress callback does too); only its
    // parallel sections run inside this reconstruction's own pool. Its threads are joined
    // (pthread_join, not just finished) before this returns, so no psr code runs after it and a
    // host may unload the library at once.
    let mut workers = Vec::with_capacity(threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .spawn_handler(|thread| {
            let name = format!("psr-worker-{}", thread.index());
            workers.push(
                std::thread::Builder::new()
                    .name(name)
                    .spawn(move || thread.run())?,
            );
            Ok(())
        })
        .build()
        .map_err(|e| Error::ThreadsUnavailable {
            threads,
            reason: e.to_string(),
        })?;
    let result = pipeline::run(points, params, &pool, progress);
    drop(pool);
    for worker in workers {
        let _ = worker.join();
    }
    result
}

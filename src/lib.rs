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
//! points → density → octree → splat → system → solve → isovalue → extract → mesh
//! (`src/pipeline.rs` runs them; `docs/architecture.md` says where everything lives). The
//! public surface is [`reconstruct`], [`reconstruct_with_progress`] and their types, [`trim`]
//! (the mesh cut back to where its samples are, by their density), the normal estimation for
//! clouds without normals, the C API in [`ffi`], the PLY reader and writer in [`ply`], the OBJ
//! writer in [`obj`] and PoissonRecon's raw point files (ASCII, `.bnpts`) in [`npts`].
//! [`reconstruct_with_implicit`] also keeps the solved implicit function, to evaluate at any
//! point or sample on a grid ([`ImplicitFunction`]).
//! Points may carry colours and named channels onto the mesh ([`PointSet::with_colors`],
//! [`PointSet::with_channel`], [`Mesh::colors`]).

// Every unsafe operation sits in an explicit `unsafe {}` block with a `// SAFETY:` comment saying
// why it holds, also inside `unsafe fn` bodies; unsafe code lives in `ffi/` (the C API),
// `parallel.rs` (disjoint parallel writes), `memory.rs` (zeroed allocation that may fail),
// `cache.rs` (a cache prefetch hint) and `system/simd.rs` (SIMD kernels) only.
#![deny(unsafe_op_in_unsafe_fn, clippy::undocumented_unsafe_blocks)]
#![warn(missing_docs)]

mod attributes;
mod bspline;
mod cache;
mod components;
mod density;
mod error;
mod evaluate;
mod extract;
pub mod ffi;
mod grid;
mod implicit;
mod isovalue;
mod key_table;
mod memory;
mod mesh;
mod noise;
mod normals;
pub mod npts;
pub mod obj;
mod octree;
mod outofcore;
mod parallel;
mod params;
mod pipeline;
pub mod ply;
mod points;
mod solve;
mod splat;
mod system;
mod trim;

pub use attributes::{Channel, Colors};
pub use error::{Error, Result};
pub use implicit::{ImplicitFunction, MAX_GRID_RESOLUTION};
pub use mesh::{DepthSolve, Mesh, Stats, TrimReport};
pub use normals::{
    estimate_normals, estimate_normals_with_progress, orient_normals, orient_normals_with_progress,
    NormalEstimation, Orientation,
};
pub use outofcore::run::{OutOfCore, OutOfCoreReport};
pub use outofcore::team::{Alone, Team};
pub use outofcore::OutOfCoreError;
pub use params::{Boundary, Params, Splatting, VertexPlacement};
pub use pipeline::{Progress, Stage};
pub use points::PointSet;
pub use trim::{trim, trim_with_progress, Threshold, Trimming};

/// Reconstructs a watertight mesh from oriented points.
pub fn reconstruct(points: &PointSet, params: &Params) -> Result<Mesh> {
    reconstruct_with_progress(points, params, &mut |_, _| true)
}

/// [`reconstruct`], also keeping the solved indicator function χ (with its isovalue and the
/// bounding cube) to evaluate at any point or sample on a grid: see [`ImplicitFunction`].
/// The mesh is the same as [`reconstruct`]'s, bit for bit; keeping χ costs about the octree's
/// memory for as long as the [`ImplicitFunction`] lives.
pub fn reconstruct_with_implicit(
    points: &PointSet,
    params: &Params,
) -> Result<(Mesh, ImplicitFunction)> {
    reconstruct_with_implicit_and_progress(points, params, &mut |_, _| true)
}

/// [`reconstruct_with_implicit`] with a progress callback, as [`reconstruct_with_progress`].
pub fn reconstruct_with_implicit_and_progress(
    points: &PointSet,
    params: &Params,
    progress: Progress<'_>,
) -> Result<(Mesh, ImplicitFunction)> {
    let (mesh, implicit) = run(points, params, progress, true)?;
    let implicit = implicit.ok_or_else(|| Error::Internal("χ was not kept".to_string()))?;
    Ok((mesh, implicit))
}

/// [`reconstruct`] with a progress callback that may cancel (then the result is
/// `Err(Error::Cancelled)`).
pub fn reconstruct_with_progress(
    points: &PointSet,
    params: &Params,
    progress: Progress<'_>,
) -> Result<Mesh> {
    run(points, params, progress, false).map(|(mesh, _)| mesh)
}

/// Reconstructs the oriented points of the PLY file `input` into the mesh `output` (binary
/// PLY) without holding the whole cloud, its octree or its mesh in memory at once: the cloud
/// is read in chunks and binned across x into slabs in a temporary directory; the depths up to
/// a base depth are solved once for the whole cloud and the finer ones slab by slab, each over
/// its points and a padding of its neighbours'; the slabs evaluate one χ near their walls, so
/// the mesh is closed and manifold across them and each vertex on a wall is written once
/// (`docs/out-of-core.md`). The slabs' count follows [`Params::max_memory`] (the budget; a
/// budget too small for any cut is refused before the slabs are solved, with the smallest
/// workable one in [`Error::OutOfMemory`]'s `enough`) or [`OutOfCore::slabs`].
///
/// The mesh is the in-memory [`reconstruct`]'s to within the in-memory solver's own tolerance:
/// the finer depths are solved per slab, so χ differs from the in-memory one by less than that
/// differs from its converged solution (tested), not bit for bit. Vertices carry the sampling
/// density (`value`) as [`ply::write_mesh`] writes them; colours and channels are not carried
/// on this path (the report says when the points had some), and vertex normals are refused
/// ([`Params::vertex_normals`]: [`Error::InvalidParameter`]).
pub fn reconstruct_out_of_core(
    input: &std::path::Path,
    output: &std::path::Path,
    params: &Params,
    options: &OutOfCore,
) -> std::result::Result<OutOfCoreReport, OutOfCoreError> {
    reconstruct_out_of_core_with_progress(input, output, params, options, &mut |_, _| true)
}

/// [`reconstruct_out_of_core`] with a progress callback that may cancel (then the result is
/// `Err(OutOfCoreError::Reconstruction(Error::Cancelled))` and the temporary files are gone).
/// The passes report as the in-memory stages they correspond to: reading and binning as
/// [`Stage::Points`], the base as [`Stage::System`], the slabs as [`Stage::Solve`], the seams
/// and the isovalue as [`Stage::Isovalue`], the slabs' meshes as [`Stage::Extract`] and the
/// file as [`Stage::Mesh`].
pub fn reconstruct_out_of_core_with_progress(
    input: &std::path::Path,
    output: &std::path::Path,
    params: &Params,
    options: &OutOfCore,
    progress: Progress<'_>,
) -> std::result::Result<OutOfCoreReport, OutOfCoreError> {
    outofcore::run::run(input, output, params, options, &Alone, progress)
}

/// [`reconstruct_out_of_core_with_progress`] run by every member of `team` (the ranks of an
/// MPI job: the program `psr-mpi`, built with the `mpi` feature of psr-cli), each with the
/// same arguments: in every pass each member does its own slabs (slab k is rank k mod N's),
/// the sums over slabs are gathered and added in slab order on every member, rank 0 makes
/// `output` with its header and every member writes its slabs of the mesh into it. The mesh
/// is the one [`reconstruct_out_of_core`] writes with the same parameters and slabs, bit for
/// bit, whatever the team's size; the slabs are at least as many as the members. The members share the temporary directory ([`OutOfCore::temp_dir`] must
/// name one every member sees), and each holds one slab at a time beside the whole cloud's
/// density field and the base (`docs/distributed.md` measures what that leaves per member).
/// Every member returns the same report, or an error: its own, or
/// [`OutOfCoreError::Member`] naming the member that failed.
pub fn reconstruct_out_of_core_in_team(
    input: &std::path::Path,
    output: &std::path::Path,
    params: &Params,
    options: &OutOfCore,
    team: &dyn Team,
    progress: Progress<'_>,
) -> std::result::Result<OutOfCoreReport, OutOfCoreError> {
    outofcore::run::run(input, output, params, options, team, progress)
}

/// The memory a reconstruction of `points` with `params` is estimated to need at its peak, in
/// bytes, from the point count and the depth alone (before any work: it takes milliseconds),
/// counting the points given, the octree, the system, the solver and the extraction with the
/// mesh (`docs/architecture.md`, "Memory budget"). The depth a [`Params::width`] picks is
/// found from the points' bounding box. It is meant as an upper bound for scanned surfaces:
/// measured on the bunny and the Happy Buddha at depths 9–12 it is 1.8–2.5 times the
/// reconstruction's peak resident memory (`docs/benchmarks.md`, issue 19); an input far from
/// a sampled surface (a volume full of points) can need more. With [`Params::max_memory`] set,
/// the reconstruction itself checks a finer figure, from its octree's node counts
/// ([`Stats::estimated_memory`]), and fails with [`Error::OutOfMemory`] only when that
/// exceeds the limit; so setting `max_memory` to this estimate does not refuse a reconstruction
/// the estimate was made for.
pub fn estimate_memory(points: &PointSet, params: &Params) -> Result<u64> {
    params.validate()?;
    let depth = match params.width {
        None => params.depth,
        Some(_) if points.is_empty() => return Ok(0),
        Some(_) => {
            let map = match points.positions_f64() {
                Some(exact) => points::UnitCubeMap::fit_f64(exact, params.scale as f64),
                None => points::UnitCubeMap::fit(points.positions(), params.scale as f64),
            };
            params.depth_for_cube(map.size)
        }
    };
    let params = params.clone().with_depth(depth).with_width(None);
    Ok(memory::Footprint::predicted(
        points.len() as u64,
        points.attributes().width() as u64,
        depth,
        params.effective_full_depth(),
        params.effective_kernel_depth(),
    )
    .peak())
}

/// [`estimate_memory`] for `point_count` points with position and normal only, reconstructed
/// with `params` (at [`Params::depth`]: a [`Params::width`] needs the points, so it is refused
/// here with [`Error::InvalidParameter`]; use [`estimate_memory`]).
pub fn estimate_memory_for(point_count: usize, params: &Params) -> Result<u64> {
    params.validate()?;
    if let Some(width) = params.width {
        return Err(Error::InvalidParameter {
            name: "width",
            value: width.to_string(),
            expected:
                "no width: the depth a width picks depends on the points (use estimate_memory)",
        });
    }
    Ok(memory::Footprint::predicted(
        point_count as u64,
        0,
        params.depth,
        params.effective_full_depth(),
        params.effective_kernel_depth(),
    )
    .peak())
}

/// The reconstruction behind the public functions: χ is kept only when asked for.
fn run(
    points: &PointSet,
    params: &Params,
    progress: Progress<'_>,
    keep_implicit: bool,
) -> Result<(Mesh, Option<ImplicitFunction>)> {
    params.validate()?;
    if points.is_empty() {
        return Err(Error::EmptyInput);
    }
    let workers = Workers::start(params.threads)?;
    pipeline::run(points, params, workers.pool(), progress, keep_implicit)
}

/// A reconstruction's own worker threads. Dropping it, on return and while a panic unwinds
/// alike, ends the pool and joins every thread (pthread_join, not just finished), so no psr
/// code runs after the reconstruction returns and a host may unload the library at once.
pub(crate) struct Workers {
    pool: Option<rayon::ThreadPool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Workers {
    /// Starts `threads` worker threads (0 = one per core) named `psr-worker-N`.
    pub(crate) fn start(threads: usize) -> Result<Workers> {
        let threads = if threads == 0 {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
        } else {
            threads
        };
        // The caller's work runs on the caller's thread (so a progress callback does too); only
        // its parallel sections run inside this pool.
        let mut threads_started = Vec::with_capacity(threads);
        let built = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .spawn_handler(|thread| {
                let name = format!("psr-worker-{}", thread.index());
                threads_started.push(
                    std::thread::Builder::new()
                        .name(name)
                        .spawn(move || thread.run())?,
                );
                Ok(())
            })
            .build();
        let mut workers = Workers {
            pool: None,
            threads: threads_started,
        };
        workers.pool = Some(built.map_err(|e| Error::ThreadsUnavailable {
            threads,
            reason: e.to_string(),
        })?);
        Ok(workers)
    }

    /// The pool (present from `start` until `drop`).
    pub(crate) fn pool(&self) -> &rayon::ThreadPool {
        self.pool.as_ref().expect("set by Workers::start")
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        // Without its pool the threads finish their jobs and exit (rayon also ends the threads
        // it started when building the pool fails).
        drop(self.pool.take());
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
    }
}

//! The reconstruction, top to bottom: points → density → octree → splat → system → solve →
//! isovalue → extract → mesh. Each stage is a module that does its own work; [`run`] calls
//! them in order, times them and reports progress, and decides when each intermediate result
//! is dropped (the memory-saving interleavings are named where they happen).

use crate::attributes;
use crate::components;
use crate::density::{self, NormalSums};
use crate::evaluate::Indicator;
use crate::extract;
use crate::implicit::ImplicitFunction;
use crate::isovalue;
use crate::memory::{Budget, Footprint};
use crate::mesh::{self, Mesh, Stats};
use crate::noise;
use crate::octree::Octree;
use crate::parallel::{self, Watch};
use crate::points::{PointSet, Samples, UnitCubeMap};
use crate::solve::{self, Depths, System};
use crate::splat::splat_level;
use crate::system::{self, FieldCarry};
use crate::{Error, Params, Result, VertexPlacement};
use std::time::Instant;

/// The stages of a reconstruction, in order, as reported to progress callbacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
#[non_exhaustive]
pub enum Stage {
    /// Before the reconstruction, for points without normals only: estimating and orienting
    /// their normals (`normals/`, [`crate::estimate_normals_with_progress`]). Numbered after
    /// the others because it was added later; it comes first in [`Stage::ALL`].
    Normals = 9,
    /// Stage 1: Validating the points and mapping them into the unit cube (`points.rs`).
    Points = 0,
    /// Stage 2: The sampling density and each sample's depth (`density.rs`); before the octree,
    /// since each sample's depth decides its nodes.
    Density = 1,
    /// Stage 3: Building the octree (`octree.rs`).
    Octree = 2,
    /// Stage 4: Splatting the normals into the vector field V (`splat.rs`).
    Splat = 3,
    /// Stage 5: The right-hand sides of the linear system (`system/`).
    System = 4,
    /// Stage 6: Solving it, coarse to fine (`solve.rs`).
    Solve = 5,
    /// Stage 7: The isovalue (`isovalue.rs`).
    Isovalue = 6,
    /// Stage 8: Extracting the isosurface (`extract.rs`).
    Extract = 7,
    /// Stage 9: The output mesh in input coordinates (`mesh.rs`).
    Mesh = 8,
    /// After the reconstruction, when asked: cutting the mesh back to where the samples are
    /// (`trim.rs`, [`crate::trim_with_progress`]); never reported by a reconstruction.
    Trim = 10,
}

impl Stage {
    /// Every stage: the reconstruction's in pipeline order, then [`Stage::Trim`].
    pub const ALL: [Stage; 11] = [
        Stage::Normals,
        Stage::Points,
        Stage::Density,
        Stage::Octree,
        Stage::Splat,
        Stage::System,
        Stage::Solve,
        Stage::Isovalue,
        Stage::Extract,
        Stage::Mesh,
        Stage::Trim,
    ];

    /// A short lower-case name ("solve").
    pub fn name(self) -> &'static str {
        match self {
            Stage::Normals => "normals",
            Stage::Points => "points",
            Stage::Octree => "octree",
            Stage::Density => "density",
            Stage::Splat => "splat",
            Stage::System => "system",
            Stage::Solve => "solve",
            Stage::Isovalue => "isovalue",
            Stage::Extract => "extract",
            Stage::Mesh => "mesh",
            Stage::Trim => "trim",
        }
    }
}

/// A progress callback: receives the stage and the fraction of it done (0..=1) and returns
/// `true` to go on, `false` to cancel. It is called on the thread that called
/// [`crate::reconstruct_with_progress`], never concurrently.
///
/// It is called while each stage runs, not only between stages: the stage's work runs on the
/// worker threads while the calling thread waits in slices of at most 20 ms and calls it after
/// each slice with the fraction done so far (never less than the call before within a stage),
/// then once with 1 when the stage ends. After it returns `false` it is not called again: the
/// stage stops at its next cancel point (`docs/architecture.md`, "Progress and cancellation",
/// lists them: batches of work milliseconds apart, down to the bricks of the splat, the system
/// and the solver and the finest depth's octree passes; on a million points at depth 11 every
/// stop measured returned within 0.17 s on a 2-core machine at load 3, within 0.26 s at load
/// 5–8) and the reconstruction returns `Err(Error::Cancelled)` once its memory is freed. The output never depends on the callback.
pub type Progress<'a> = &'a mut dyn FnMut(Stage, f32) -> bool;

/// Times stages and forwards progress; turns a "stop" from the callback into `Cancelled`.
struct Clock<'p, 'q> {
    progress: &'p mut Progress<'q>,
    started: Instant,
    stats: Stats,
    /// Seconds of the current stage's time that belong to another stage (see
    /// [`Clock::done_moving`]).
    moved: f64,
}

impl Clock<'_, '_> {
    fn report(&mut self, stage: Stage, fraction: f32) -> Result<()> {
        if (self.progress)(stage, fraction) {
            Ok(())
        } else {
            Err(Error::Cancelled)
        }
    }

    /// Runs `job`, the work of `stage`, in `pool` through [`parallel::watched`]: the calling
    /// thread waits for it in slices of at most [`parallel::SLICE`], reporting the job's
    /// progress to the callback after each, and a "stop" cancels the job at its next cancel
    /// point ([`Watch::check`]).
    fn watch<R: Send>(
        &mut self,
        stage: Stage,
        pool: &rayon::ThreadPool,
        job: impl FnOnce(&Watch) -> Result<R> + Send,
    ) -> Result<R> {
        let progress = &mut self.progress;
        parallel::watched(pool, &mut |fraction| (progress)(stage, fraction), job)
    }

    fn done(&mut self, stage: Stage) -> Result<()> {
        let now = Instant::now();
        self.stats
            .stage_seconds
            .push((stage, (now - self.started).as_secs_f64() - self.moved));
        self.moved = 0.0;
        self.started = now;
        self.report(stage, 1.0)
    }

    /// [`Clock::done`], with `seconds` of this stage's time spent on work of the next stage
    /// (counted there).
    fn done_moving(&mut self, stage: Stage, seconds: f64) -> Result<()> {
        self.moved = seconds;
        self.done(stage)?;
        self.moved = -seconds;
        Ok(())
    }

    /// [`Clock::done`], with `seconds` of this stage's time spent on work of the stage before
    /// (counted there).
    fn done_returning(&mut self, stage: Stage, seconds: f64) -> Result<()> {
        if let Some((_, before)) = self.stats.stage_seconds.last_mut() {
            *before += seconds;
        }
        self.moved += seconds;
        self.done(stage)
    }
}

/// Reconstructs `points` with `params`, the parallel sections in `pool`, reporting each stage
/// to `progress` on the calling thread (which may cancel); with `keep_implicit`, also returns
/// the solved χ (which the pipeline otherwise drops on return).
pub(crate) fn run(
    points: &PointSet,
    params: &Params,
    pool: &rayon::ThreadPool,
    mut progress: Progress<'_>,
    keep_implicit: bool,
) -> Result<(Mesh, Option<ImplicitFunction>)> {
    let mut clock = Clock {
        progress: &mut progress,
        started: Instant::now(),
        stats: Stats::default(),
        moved: 0.0,
    };
    clock.stats.points = points.len();
    clock.report(Stage::Points, 0.0)?;

    // 1. Points: into the unit cube, in Morton order. A width chooses the depth from the cube.
    // Points given in f64 are fitted from their f64 values, and the mesh is given relative to a
    // round origin near them (Mesh::origin); f32 points take exactly the path they always did.
    let map = match points.positions_f64() {
        Some(exact) => UnitCubeMap::fit_f64(exact, params.scale as f64),
        None => UnitCubeMap::fit(points.positions(), params.scale as f64),
    };
    let origin = points.positions_f64().map(|_| map.nearby_origin());
    let params = &params.for_cube(map.size);
    clock.stats.depth = params.depth;

    // The memory budget, first from the point count (before anything is copied): the points'
    // arrays and the octree's complete depths are the least any reconstruction of them needs.
    let point_count = points.len() as u64;
    let attribute_width = points.attributes().width() as u64;
    let full_depth = params.effective_full_depth();
    let mut budget = Budget {
        limit: params.max_memory,
        estimate: Footprint::predicted(
            point_count,
            attribute_width,
            params.depth,
            full_depth,
            params.effective_kernel_depth(),
        )
        .peak(),
    };
    budget.check(
        "the points' arrays and the octree's complete depths",
        Footprint::at_least(point_count, attribute_width, full_depth).peak(),
    )?;
    let mut samples = clock.watch(Stage::Points, pool, |_| {
        Samples::in_morton_order(points, &map, params.depth)
    })?;
    clock.done(Stage::Points)?;

    // 2. Density: each sample's area and depth(s) (before the octree: they decide its nodes;
    // read finer where the normals under the density's kernel bend, `density::BENT_SPREAD`);
    // and when the screening is to follow the samples' noise, how far they scatter across the
    // surface (its 2^d scale then stops at the depth whose cells are 10 σ wide;
    // `system::screening_depth`).
    let kernel_depth = params.effective_kernel_depth();
    let (field, mut sample_density, noise) = clock.watch(Stage::Density, pool, |watch| {
        // The counts are the normal sums' first component: one splat gives both.
        let normal_sums = NormalSums::splat(
            &samples.positions,
            Some(&samples.confidence),
            &samples.normals,
            kernel_depth,
        );
        let field = normal_sums.kernel_counts().into_field();
        budget.check(
            "the density field and the samples' normals summed beside it",
            Footprint::reading_density(
                point_count,
                attribute_width,
                field.slots() as u64,
                field.kernel_slots() as u64,
            )
            .peak(),
        )?;
        watch.step(1, 2, 0.0, 1.0)?;
        let sample_density = density::estimate(
            &field,
            Some(&normal_sums),
            &samples.positions,
            params.depth,
            params.samples_per_node as f64,
            watch,
        )?;
        drop(normal_sums);
        let noise = params
            .screening_follows_noise
            .then(|| noise::estimate(&samples.positions, &sample_density.area, params.depth));
        Ok((field, sample_density, noise))
    })?;
    clock.stats.kernel_depth = kernel_depth;
    let density_slots = field.slots() as u64;
    clock.stats.density_slots = field.slots();
    clock.stats.sample_density_quantiles = std::mem::take(&mut sample_density.quantiles);
    clock.stats.sample_noise = noise.map(|noise| noise.sigma * map.size);
    let screening_depth = system::screening_depth(params.depth, noise.map_or(0.0, |n| n.sigma));
    clock.stats.screening_depth = screening_depth;
    clock.done(Stage::Density)?;

    // 3. Octree: around the cells of each sample at its one or two depths.
    let at_depth = density::samples_by_depth(
        &mut sample_density,
        &samples.confidence,
        params.depth,
        params.effective_full_depth(),
        Octree::coarsest_depth(params.boundary, params.node_degree()),
    );
    let tree = clock.watch(Stage::Octree, pool, |watch| {
        Octree::around_samples(
            &at_depth,
            &samples.positions,
            params.effective_full_depth(),
            params.boundary,
            params.node_degree(),
            watch,
            // Once the core sets are known, before the halos: each halo holds its core at least.
            &|cores| {
                budget.check(
                    "the octree's nodes, the system and the solve",
                    Footprint::with_nodes(point_count, attribute_width, cores, density_slots)
                        .peak(),
                )
            },
        )
    })?;
    let finest = tree.max_depth() as usize;
    clock.stats.nodes_per_depth = tree.levels.iter().map(|l| l.core.len()).collect();
    clock.stats.halo_nodes_per_depth = tree.levels.iter().map(|l| l.len()).collect();
    // Precisely, with the halos' node counts, before the system allocates anything.
    let halos: Vec<u64> = tree.levels.iter().map(|l| l.len() as u64).collect();
    budget.estimate =
        Footprint::with_nodes(point_count, attribute_width, &halos, density_slots).peak();
    clock.stats.estimated_memory = budget.estimate;
    budget.check(
        "the octree's nodes, the system and the solve",
        budget.estimate,
    )?;
    clock.done(Stage::Octree)?;

    // 4. Splat: V at each sample's one or two depths (§4.2, §4.5), finest depth first.
    // Interleaved for memory: the finest V is needed for nothing but ρ at that depth (no finer
    // depth prolongs it), so the system's first step runs here, before the coarser depths' V
    // exist; V's three vectors and ρ (four halo-sized vectors of the finest depth) are the
    // peak of these stages. Its time is counted in the system stage. The coarser depths are
    // splatted in the system stage, root first, as the carry of V asks (below).
    // The attributes' splat (stage 9) reads each sample's depths and normal again; without
    // attributes each depth's list goes once splatted, and the normals after the last.
    let carries_attributes = !samples.attributes.is_empty();
    let mut at_depth = at_depth;
    let spent = |at_depth: &mut [Vec<density::DepthSample>], d: usize| {
        if !carries_attributes {
            at_depth[d] = Vec::new();
        }
    };
    let (rho_finest, finest_system) = clock.watch(Stage::Splat, pool, |watch| {
        let v_finest = splat_level(&tree.levels[finest], &samples, &at_depth[finest], params)?;
        spent(&mut at_depth, finest);
        watch.step(1, 2, 0.0, 1.0)?;
        let finest_system = Instant::now();
        let rho_finest = system::finest_right_hand_side(&tree.levels[finest], v_finest)?;
        Ok((rho_finest, finest_system.elapsed().as_secs_f64()))
    })?;
    clock.done_moving(Stage::Splat, finest_system)?;

    // 5. System: the right-hand side of every depth and the samples' screening weights. The
    // coarser depths are splatted here, root first (their splat's time is counted in the splat
    // stage), each V spent at once on its own divergence and on the coarse divergences of the
    // depths above (`FieldCarry`), so that no more than two depths' V are ever alive and none
    // waits for the solve; then each depth's ρ by restriction. Cancel points between the
    // depths and between the restrictions.
    let (rho, coarse_div, screening_weights, splat_seconds) =
        clock.watch(Stage::System, pool, |watch| {
            let mut splat_seconds = 0.0;
            let mut carry = FieldCarry::new(&tree, finest as u32, finest);
            let own_divergence = system::coarser_divergences(
                &tree,
                |d| {
                    watch.step(d, finest, 0.0, 0.5)?;
                    let splat_started = Instant::now();
                    let v = splat_level(&tree.levels[d], &samples, &at_depth[d], params)?;
                    spent(&mut at_depth, d);
                    splat_seconds += splat_started.elapsed().as_secs_f64();
                    Ok(v)
                },
                |d, v| carry.push(d, v, pool),
            )?;
            let (coarse_div, _) = carry.finish();
            let rho = system::right_hand_sides(&tree, rho_finest, own_divergence, |fraction| {
                watch.set(0.5 + 0.5 * fraction);
                watch.check()
            })?;
            let screening_weights =
                system::sample_weights(&sample_density.area, &samples.confidence);
            Ok((rho, coarse_div, screening_weights, splat_seconds))
        })?;
    if !carries_attributes {
        at_depth = Vec::new();
        samples.normals = Vec::new();
    }
    clock.done_returning(Stage::System, splat_seconds)?;

    // 6. Solve, coarse to fine (each depth's ρ and coarse divergence are dropped once read).
    let system = System {
        tree: &tree,
        rho,
        coarse_div,
        positions: &samples.positions,
        screening_weights: &screening_weights,
        proxy_groups: None,
        screening: system::ScreeningWeights::new(
            params.point_weight,
            params.depth,
            screening_depth,
        ),
        depths: Depths::All,
    };
    let (coefficients, solves) = clock.watch(Stage::Solve, pool, |watch| {
        let mut on_solve = |fraction: f32| {
            watch.set(fraction);
            !watch.is_cancelled()
        };
        let mut solves = Vec::new();
        let coefficients = solve::cascade(system, params, pool, &mut on_solve, &mut solves)?;
        Ok((coefficients, solves))
    })?;
    clock.stats.solves.extend(solves);
    clock.done(Stage::Solve)?;

    // 7. Isovalue: the area-weighted mean of χ at the samples (§4.5).
    let chi = Indicator { tree, coefficients };
    let isovalue = clock.watch(Stage::Isovalue, pool, |watch| {
        isovalue::weighted_mean(
            &chi,
            &samples.positions,
            &sample_density.area,
            &samples.confidence,
            watch,
        )
    })?;
    clock.stats.isovalue = isovalue;
    clock.done(Stage::Isovalue)?;

    // 8. Extract on the tree's leaves, following the surface from the leaves that hold samples.
    let on_isosurface = params.vertex_placement == VertexPlacement::OnIsosurface;
    // Attributes and vertex normals need ∇χ at the vertices, which fitting computes anyway.
    let with_normals = carries_attributes || params.vertex_normals;
    // Tracing the surface is ~9/10 of the stage, leaving out the bubbles the rest.
    let (raw, removed) = clock.watch(Stage::Extract, pool, |watch| {
        let mut raw = extract::extract_around_samples(
            &chi,
            isovalue,
            &samples.positions,
            on_isosurface,
            with_normals,
            watch,
        )?;
        // The level set's closed pieces that too few samples support (bubbles) are left out.
        let removed = components::drop_unsupported(
            &mut raw,
            chi.tree.max_depth(),
            &samples.positions,
            params.min_component_samples,
            watch,
        )?;
        Ok((raw, removed))
    })?;
    clock.stats.unsupported_components = removed.components;
    clock.stats.unsupported_triangles = removed.triangles;
    clock.done(Stage::Extract)?;

    // 9. Mesh: back to input coordinates, with the sampling density at each vertex, and the
    // points' attributes and the normals when there are any.
    let (attributes, normals, mut mesh) = clock.watch(Stage::Mesh, pool, |watch| {
        let attributes = carries_attributes.then(|| {
            let field = attributes::SampleField {
                positions: &samples.positions,
                normals: &samples.normals,
                values: &samples.attributes,
                width: points.attributes().width(),
                weights: sample_density
                    .area
                    .iter()
                    .zip(&samples.confidence)
                    .map(|(a, c)| a * c)
                    .collect(),
                at_depth: &at_depth,
                key_depth: params.depth,
            };
            attributes::at_vertices(&field, &raw.vertices, &raw.normals, &raw.triangles)
        });
        watch.step(1, 3, 0.0, 0.5)?;
        let normals = params
            .vertex_normals
            .then(|| attributes::vertex_normals(&raw.vertices, &raw.normals, &raw.triangles));
        watch.step(2, 3, 0.0, 0.5)?;
        let mesh = mesh::in_input_coordinates(raw, &map, origin, &field, watch)?;
        Ok((attributes, normals, mesh))
    })?;
    if let Some(values) = attributes {
        mesh::set_attributes(&mut mesh, points.attributes(), &values);
    }
    mesh.normals = normals.unwrap_or_default();
    clock.done(Stage::Mesh)?;
    mesh.stats = clock.stats;
    let implicit = keep_implicit.then(|| ImplicitFunction::new(chi, isovalue, map, params.threads));
    Ok((mesh, implicit))
}

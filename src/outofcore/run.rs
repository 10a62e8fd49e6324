//! A reconstruction out of core from one file to another, top to bottom: the passes that solve
//! the slabs (`passes.rs`), each slab's part of the mesh (`seams.rs`), the pieces across walls
//! and the PLY (`assemble.rs`).

use super::assemble::{self, MeshLayout, Pieces};
use super::passes::{load_solution, solve_slabs, Plan, SlabCount, SolvedSlabs};
use super::seams::{margin, slab_part, SlabPart};
use super::team::{agreed, rounds, Team};
use super::OutOfCoreError;
use crate::grid::cell_of;
use crate::parallel::Watch;
use crate::pipeline::{Progress, Stage};
use crate::{Params, VertexPlacement, Workers};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How a reconstruction out of core ([`crate::reconstruct_out_of_core`]) cuts the cloud and
/// where it keeps its temporary files. The memory budget is [`Params::max_memory`].
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct OutOfCore {
    /// Slabs to cut the cloud into across x. `None`: the fewest whose largest fits
    /// [`Params::max_memory`] (one of the two must be given).
    pub slabs: Option<usize>,
    /// The directory under which the run makes its temporary directory (the system's
    /// temporary directory when `None`); it needs room for the points about twice over (40
    /// bytes a point, plus the slabs' padding) and the mesh. Removed on success, error and
    /// cancel.
    pub temp_dir: Option<PathBuf>,
    /// The depth up to which the system is solved once for the whole cloud, at least the full
    /// depth and at most the depth − 2. Finer depths are solved slab by slab, each slab over
    /// 24 columns of the base depth + 2 of padding on each side. `None`: the depth − 3, at
    /// most 7 and at least the full depth; or, under a memory budget ([`Params::max_memory`]
    /// with no [`OutOfCore::slabs`]), from that up to the depth − 2, the one whose fewest
    /// slabs that fit leave each member of the team the fewest octree nodes to work on (its
    /// share of the slabs' nodes finer than the base, padding included, plus the whole base,
    /// which every member solves): a budget that cuts the cloud thin takes a finer base,
    /// whose padding is thinner. Lowered when the samples do not reach two depths above it;
    /// the depth used is [`OutOfCoreReport::base_depth`].
    pub base_depth: Option<u32>,
    /// Weigh the points by their `confidence` (or `value`) property, as
    /// [`crate::PointSet::extend_weighted`] does (PoissonRecon's `--confidence`); a file
    /// without one is then refused. Off by default: the property is ignored.
    pub confidence: bool,
}

impl OutOfCore {
    /// These options with `slabs` slabs.
    pub fn with_slabs(mut self, slabs: Option<usize>) -> Self {
        self.slabs = slabs;
        self
    }

    /// These options with the temporary directory under `dir`.
    pub fn with_temp_dir(mut self, dir: Option<PathBuf>) -> Self {
        self.temp_dir = dir;
        self
    }

    /// These options weighing the points by their confidence, or not.
    pub fn with_confidence(mut self, confidence: bool) -> Self {
        self.confidence = confidence;
        self
    }

    /// These options with base depth `depth`.
    pub fn with_base_depth(mut self, depth: Option<u32>) -> Self {
        self.base_depth = depth;
        self
    }
}

/// What a reconstruction out of core did.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct OutOfCoreReport {
    /// Points read.
    pub points: u64,
    /// Slabs the cloud was cut into.
    pub slabs: usize,
    /// The base depth B used: depths 0..=B solved once for the whole cloud, the finer ones
    /// slab by slab ([`OutOfCore::base_depth`], or as the memory budget chose it).
    pub base_depth: u32,
    /// The depth used (from [`Params::width`] when set).
    pub depth: u32,
    /// Vertices written.
    pub vertices: u64,
    /// Triangles written.
    pub triangles: u64,
    /// Closed pieces left out for want of supporting samples (as [`crate::Stats`]'s
    /// `unsupported_components`).
    pub unsupported_components: usize,
    /// The isovalue.
    pub isovalue: f64,
    /// The samples' positional noise σ in input units, estimated from every slab's samples
    /// when [`Params::screening_follows_noise`] is set (the in-memory estimate's value,
    /// [`crate::Stats::sample_noise`]); `None` otherwise.
    pub sample_noise: Option<f64>,
    /// Cells of that estimate wider than their slab's padding reaches, fitted over the samples
    /// within it rather than all of theirs (0 unless the median sample is about three depths
    /// coarser than the slabs' walls; then the σ may differ slightly from the in-memory one).
    pub noise_cells_beyond_padding: u64,
    /// The noise's depth of the screening weight, as [`crate::Stats::screening_depth`].
    pub screening_depth: f64,
    /// The points carried colours or other channels, which this path does not carry onto the
    /// mesh (the in-memory path does).
    pub attributes_dropped: bool,
    /// Seconds, start to end.
    pub seconds: f64,
}

/// The run of one member of `team` (every member calls it with the same arguments, writes its
/// slabs of the mesh into the output rank 0 made, and returns the same report).
pub(crate) fn run(
    input: &Path,
    output: &Path,
    params: &Params,
    options: &OutOfCore,
    team: &dyn Team,
    progress: Progress<'_>,
) -> Result<OutOfCoreReport, OutOfCoreError> {
    let started = Instant::now();
    params.validate()?;
    if options.slabs == Some(0) {
        return Err(crate::Error::InvalidParameter {
            name: "slabs",
            value: "0".into(),
            expected: "at least 1 (or none: from the memory budget)",
        }
        .into());
    }
    if params.vertex_normals {
        return Err(crate::Error::InvalidParameter {
            name: "vertex_normals",
            value: "true".into(),
            expected: "false: a reconstruction out of core writes no vertex normals",
        }
        .into());
    }
    // (Agreed: a member without its threads must not leave the others waiting for it.)
    let workers = agreed(
        team,
        Workers::start(params.threads).map_err(OutOfCoreError::from),
    )?;
    let pool = workers.pool();
    let plan = Plan {
        base_depth: options.base_depth,
        slabs: match options.slabs {
            Some(n) => SlabCount::Exactly(n),
            None => SlabCount::Within(params.max_memory.ok_or(crate::Error::InvalidParameter {
                name: "max_memory",
                value: "none".into(),
                expected: "a memory budget in bytes (or a number of slabs) for a reconstruction \
                           out of core",
            })?),
        },
        // 24 columns of depth B + 2 (six nodes of depth B): the tree is exact from 6 on
        // (`tests.rs`), but the fine solve near a wall needs more. With 12, the Happy Buddha
        // at depth 10 in 4, 8 or 16 slabs came out with one handle more than the in-memory
        // mesh at a thin spot 4 columns from a wall (vertices up to 0.67 finest cell off);
        // with 24, the same genus and components, every vertex within 0.17 cell.
        padding: 24,
        chunk: 1 << 20,
        confidence: options.confidence,
        temp_dir: options.temp_dir.clone(),
    };
    let mut go_on = |stage: Stage, fraction: f32| progress(stage, fraction);
    let solved = solve_slabs(input, params, &plan, team, pool, &mut |pass, fraction| {
        let stage = match pass {
            "scan" | "columns" | "bin" | "density" => Stage::Points,
            "base" => Stage::System,
            "slabs" => Stage::Solve,
            _ => Stage::Isovalue,
        };
        go_on(stage, fraction)
    })?;
    let cancelled = || OutOfCoreError::Reconstruction(crate::Error::Cancelled);
    let params = &solved.params;
    let layout = &solved.layout;
    let slabs = layout.len();
    let finest = solved.finest;
    let fitted = params.vertex_placement != VertexPlacement::OnIsosurface;
    let watch = Watch::new();

    // Each slab's part of the mesh, saved for the passes below.
    let to_finest = finest - layout.wall_depth;
    rounds(
        team,
        slabs,
        |k| {
            if !go_on(Stage::Extract, k as f32 / (slabs as f32 * 2.0)) {
                return Err(cancelled());
            }
            let chi = load_solution(&solved, k, pool)?;
            let samples = solved.slab_samples(k, pool)?;
            let inv_h = (finest as f64).exp2();
            let seeds: Vec<[i64; 3]> = samples
                .samples
                .positions
                .iter()
                .map(|&p| cell_of(p, inv_h).map(i64::from))
                .collect();
            drop(samples);
            let owned_columns = layout.owned(k);
            let owned =
                (owned_columns.start as i64) << to_finest..(owned_columns.end as i64) << to_finest;
            let reach = margin(&chi.tree, &owned, fitted);
            let traced = owned.start - reach..owned.end + reach;
            let part = pool.install(|| {
                slab_part(
                    &chi,
                    solved.isovalue,
                    seeds,
                    owned,
                    traced,
                    !fitted,
                    fitted,
                    &watch,
                )
            })?;
            assemble::save_part(&part, &solved.scratch, k)?;
            Ok(Vec::new())
        },
        |_, _| Ok(()),
    )?;

    // The pieces across walls, their support, and the PLY, each member doing its slabs.
    let assembled = assemble_mesh(&solved, output, team, pool, &mut go_on)?;
    Ok(OutOfCoreReport {
        points: solved.scan.count,
        slabs,
        base_depth: solved.layout.wall_depth - 2,
        depth: params.depth,
        vertices: assembled.vertices,
        triangles: assembled.triangles,
        unsupported_components: assembled.unsupported_components,
        isovalue: solved.isovalue,
        sample_noise: solved
            .noise
            .map(|team| team.noise.sigma * solved.scan.map.size),
        noise_cells_beyond_padding: solved.noise.map_or(0, |team| team.cells_beyond_padding),
        screening_depth: solved.screening.noise_depth,
        attributes_dropped: solved.scan.has_attributes,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// What [`assemble_mesh`] wrote.
struct Written {
    vertices: u64,
    triangles: u64,
    unsupported_components: usize,
}

/// The slabs' parts joined into pieces across walls, the pieces no sample supports left out,
/// and the rest written to `output`, each member doing its slabs of each step.
fn assemble_mesh(
    solved: &SolvedSlabs,
    output: &Path,
    team: &dyn Team,
    pool: &rayon::ThreadPool,
    go_on: &mut dyn FnMut(Stage, f32) -> bool,
) -> Result<Written, OutOfCoreError> {
    let params = &solved.params;
    let slabs = solved.layout.len();
    let part =
        |k: usize| -> Result<SlabPart, OutOfCoreError> { assemble::load_part(&solved.scratch, k) };
    let fraction = |k: usize, from: f32, to: f32| from + (to - from) * k as f32 / slabs as f32;
    let pieces = Pieces::label(team, slabs, &part, &mut |k| {
        go_on(Stage::Extract, fraction(k, 0.5, 0.6))
    })?;
    let min_samples = params.min_component_samples as u64;
    let support = if min_samples == 0 {
        Vec::new()
    } else {
        let own = |k: usize| -> Result<Vec<DVec3>, OutOfCoreError> {
            let samples = solved.slab_samples(k, pool)?;
            Ok(samples
                .samples
                .positions
                .iter()
                .zip(&samples.owned)
                .filter(|(_, owned)| **owned)
                .map(|(p, _)| *p)
                .collect())
        };
        assemble::support(team, &pieces, slabs, solved.finest, &part, &own, &mut |k| {
            go_on(Stage::Extract, fraction(k, 0.6, 1.0))
        })?
    };
    let keep = |piece: u32| {
        min_samples == 0 || piece == pieces.largest() || support[piece as usize] >= min_samples
    };
    let unsupported_components = pieces.count_where(|p| !keep(p));
    let origin = solved
        .scan
        .positions_f64
        .then(|| solved.scan.map.nearby_origin());
    let layout = MeshLayout::plan(team, &pieces, slabs, &keep, origin.is_some(), &part)?;
    let (vertices, triangles) = assemble::write_ply(
        team,
        output,
        &layout,
        &pieces,
        &keep,
        &solved.scan.map,
        origin,
        &solved.field,
        &part,
        &mut |k| go_on(Stage::Mesh, fraction(k, 0.0, 1.0)),
    )?;
    // The mesh is written: a cancel now has nothing left to stop.
    go_on(Stage::Mesh, 1.0);
    Ok(Written {
        vertices,
        triangles,
        unsupported_components,
    })
}

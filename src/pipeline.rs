//! The reconstruction, top to bottom: points → density → octree → splat → system → solve →
//! isovalue → extract → mesh. Each stage is a module; this file only wires them together,
//! times them and reports progress.

use crate::density::{self, DensityField};
use crate::evaluate::Indicator;
use crate::grid::{cell_of, morton_nested};
use crate::octree::Octree;
use crate::points::UnitCubeMap;
use crate::solve::conjugate_gradients;
use crate::splat::{splat_depth, DepthSample};
use crate::system::{
    divergence, divergence_of, divergence_of_prolonged, fill_mirrors, fill_mirrors_field, prolong,
    restrict_into, DepthOperator, ProlongedField, Proxies,
};
use crate::{
    extract, Boundary, DepthSolve, Error, Mesh, Params, PointSet, Progress, Result, Stage, Stats,
    VertexPlacement,
};
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;

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
}

/// The samples in unit-cube coordinates, in Morton order of their cells at the requested depth
/// (so also at every coarser depth; ties in input order): the samples of a cell, and of
/// neighbouring cells mostly, are neighbours in memory for every stage that reads them by cell.
struct Samples {
    positions: Vec<DVec3>,
    /// Unit normals (the point set's), until splatted.
    normals: Vec<[f32; 3]>,
    /// Confidence weights (all 1 unless given).
    confidence: Vec<f64>,
}

impl Samples {
    fn in_morton_order(points: &PointSet, map: &UnitCubeMap, depth: u32) -> Samples {
        let inv_h = (depth as f64).exp2();
        let unit: Vec<DVec3> = points
            .positions()
            .par_iter()
            .map(|&p| map.to_unit(p))
            .collect();
        let mut order: Vec<(u64, u32)> = unit
            .par_iter()
            .enumerate()
            .map(|(s, &p)| {
                let c = cell_of(p, inv_h);
                (morton_nested(c.map(|v| v.max(0) as u32)), s as u32)
            })
            .collect();
        order.par_sort_unstable();
        Samples {
            positions: order.par_iter().map(|&(_, s)| unit[s as usize]).collect(),
            normals: order
                .par_iter()
                .map(|&(_, s)| points.normals()[s as usize])
                .collect(),
            confidence: match points.weights() {
                Some(w) => order
                    .par_iter()
                    .map(|&(_, s)| w[s as usize] as f64)
                    .collect(),
                None => vec![1.0; points.len()],
            },
        }
    }
}

pub(crate) fn run(
    points: &PointSet,
    params: &Params,
    pool: &rayon::ThreadPool,
    mut progress: Progress<'_>,
) -> Result<Mesh> {
    let mut clock = Clock {
        progress: &mut progress,
        started: Instant::now(),
        stats: Stats::default(),
        moved: 0.0,
    };
    let max_depth = params.depth;
    clock.stats.points = points.len();
    clock.report(Stage::Points, 0.0)?;

    // 1. Points: into the unit cube, in Morton order.
    let map = UnitCubeMap::fit(points.positions(), params.scale as f64);
    let mut samples = pool.install(|| Samples::in_morton_order(points, &map, params.depth));
    if samples.confidence.iter().all(|&c| c == 0.0) {
        return Err(Error::NoPositiveWeight);
    }
    let first = points.positions()[0];
    if points.positions().iter().all(|p| *p == first) {
        return Err(Error::DegenerateInput {
            points: points.len(),
        });
    }
    clock.done(Stage::Points)?;

    // 2. Density (before the octree: the sample depths decide which nodes the tree needs).
    let kernel_depth = params.effective_kernel_depth();
    let field = DensityField::splat(&samples.positions, Some(&samples.confidence), kernel_depth);
    let mut sample_density = pool.install(|| {
        density::estimate(
            &field,
            &samples.positions,
            max_depth,
            params.samples_per_node as f64,
        )
    });
    clock.done(Stage::Density)?;

    // 3. Octree: around the cells of each sample at its one or two depths.
    let neumann = params.boundary == Boundary::Neumann;
    let mut at_depth: Vec<Vec<DepthSample>> = vec![Vec::new(); max_depth as usize + 1];
    for s in 0..samples.positions.len() {
        let mass = sample_density.area[s] * samples.confidence[s];
        for (d, w) in depth_split(sample_density.depth[s]) {
            if w > 0.0 {
                at_depth[d as usize].push(DepthSample {
                    sample: s as u32,
                    mass: w * mass,
                });
            }
        }
    }
    // The fractional depths are spent; the areas weigh the isovalue at the end.
    sample_density.depth = Vec::new();
    // When the density puts no sample at the deepest depths (sparse scans at a high --depth),
    // those depths would hold no unknowns and only multiply the extraction grid: the tree, the
    // screening scale and the extraction stop at the finest depth that has samples.
    let finest = (0..=max_depth as usize)
        .rev()
        .find(|&d| !at_depth[d].is_empty())
        .unwrap_or(0)
        .max(params.effective_full_depth() as usize);
    at_depth.truncate(finest + 1);
    let sample_cells: Vec<Vec<[i32; 3]>> = at_depth
        .iter()
        .enumerate()
        .map(|(d, at)| {
            let inv_h = (d as f64).exp2();
            at.iter()
                .map(|s| cell_of(samples.positions[s.sample as usize], inv_h))
                .collect()
        })
        .collect();
    let tree = pool.install(|| Octree::build(sample_cells, params.effective_full_depth(), neumann));
    let max_depth = tree.max_depth();
    clock.stats.nodes_per_depth = tree.levels.iter().map(|l| l.core.len()).collect();
    clock.done(Stage::Octree)?;

    // 4. Splat: V at each sample's one or two depths (§4.2, §4.5), finest depth first. The
    // finest V is needed for nothing but ρ at that depth (no finer depth prolongs it), so the
    // system's first step runs here, before the coarser depths' V exist: V's three vectors and
    // ρ (four halo-sized vectors of the finest depth) are the peak of these stages. Its time is
    // counted in the system stage.
    let splat_at = |d: usize| {
        let mut v = splat_depth(
            &tree.levels[d],
            &samples.positions,
            &samples.normals,
            &at_depth[d],
            params.splatting,
            neumann,
        );
        fill_mirrors_field(&tree.levels[d], &mut v);
        v
    };
    let finest = max_depth as usize;
    let v_finest = pool.install(|| splat_at(finest));
    let finest_system = Instant::now();
    let mut rho_finest = pool.install(|| divergence(&tree.levels[finest], v_finest));
    fill_mirrors(&tree.levels[finest], &mut rho_finest);
    let finest_system = finest_system.elapsed().as_secs_f64();
    let mut field_v: Vec<[Vec<f64>; 3]> = pool.install(|| (0..finest).map(splat_at).collect());
    field_v.push(Default::default());
    drop(at_depth);
    samples.normals = Vec::new();
    clock.done_moving(Stage::Splat, finest_system)?;

    // 5. System: ρ_d = ⟨∇B_o, Σ_{e ≥ d} V_e⟩ on every halo, finest first (restriction is exact).
    let mut rho: Vec<Vec<f64>> = Vec::with_capacity(tree.levels.len());
    rho.push(rho_finest);
    for d in (0..finest).rev() {
        let level = &tree.levels[d];
        let mut r = pool.install(|| divergence_of(level, &field_v[d]));
        let finer: &Vec<f64> = rho.last().expect("finer level computed first");
        restrict_into(level, &tree.levels[d + 1], finer, &mut r);
        fill_mirrors(level, &mut r);
        rho.push(r);
        clock.report(
            Stage::System,
            (max_depth as usize - d + 1) as f32 / (max_depth as usize + 1) as f32,
        )?;
    }
    rho.reverse();
    // Screening weights: SPSR's α·Area/Σw·Σ w χ², with the area from the density estimate.
    let total_area: f64 = sample_density
        .area
        .iter()
        .zip(&samples.confidence)
        .map(|(a, c)| a * c)
        .sum();
    let total_confidence: f64 = samples.confidence.iter().sum();
    let screening_weights: Vec<f64> = samples
        .confidence
        .iter()
        .map(|c| c * total_area / total_confidence)
        .collect();
    clock.done(Stage::System)?;

    // 6. Solve, coarse to fine.
    // Screening weight α·2^D at every depth, D the requested depth: the finest depth's balance
    // between the Laplacian and the screening term (SPSR), kept at coarser depths, where it is then
    // relatively stronger. The cascade never revisits a coarse depth, so a coarse solution that
    // ignores the samples would leave an offset the thin finer bands cannot take out. (When the
    // tree stops short of D, keeping D's weight was measured to avoid a 76-vertex bubble beside
    // the oni's horn that the finest used depth's weight produced.)
    let screening = params.point_weight as f64 * (params.depth as f64).exp2();
    let mut coefficients: Vec<Vec<f64>> = Vec::with_capacity(tree.levels.len());
    // The coarse right-hand side of the next depth, ⟨∇B_o, coarser V prolonged⟩ on its core.
    let mut next_coarse_div: Option<Vec<f64>> = None;
    let depths = max_depth + 1;
    for d in 0..=max_depth as usize {
        let depth_started = Instant::now();
        let level = &tree.levels[d];
        let proxies = pool.install(|| {
            Proxies::build(
                level,
                &samples.positions,
                &screening_weights,
                proxy_depth(d as u32, max_depth),
            )
        });
        let mut op = pool.install(|| DepthOperator::new(level, &proxies, screening));
        // This depth's rho is used here for the last time.
        let is_finest = d == max_depth as usize;
        let rho_here = std::mem::take(&mut rho[d]);
        // The coarser solution, represented at this depth (stored: it is part of this depth's
        // coefficients).
        let y = pool.install(|| {
            if d == 0 {
                vec![0.0; level.len()]
            } else {
                let mut y = prolong(&tree.levels[d - 1], level, &coefficients[d - 1], 1.0);
                fill_mirrors(level, &mut y);
                y
            }
        });
        let coarse_div = next_coarse_div
            .take()
            .unwrap_or_else(|| vec![0.0; level.core.len()]);
        if !is_finest {
            // V of this depth and all coarser ones (accumulated here by the depth above) is
            // read for the last time, before this depth's vectors are allocated: prolonged to
            // the next depth (F̃ halves in width: ×1/8), where its divergence is that depth's
            // coarse right-hand side, and added to that depth's V (brick by brick, never as
            // three more halo vectors).
            let mut field = std::mem::take(&mut field_v[d]);
            fill_mirrors_field(level, &mut field);
            let finer = &tree.levels[d + 1];
            let prolonged = ProlongedField {
                coarse: level,
                fine: finer,
                field: [&field[0], &field[1], &field[2]],
                scale: 0.125,
            };
            next_coarse_div = Some(pool.install(|| divergence_of_prolonged(&prolonged)));
            if d + 1 < max_depth as usize {
                pool.install(|| prolonged.add_to(&mut field_v[d + 1]));
            }
        }
        // b − A·y on the core, computed in A·y's vector.
        let rhs = pool.install(|| {
            let mut rhs = vec![0.0; level.core.len()];
            op.apply(&y, &mut rhs);
            rhs.par_iter_mut()
                .zip(level.core.par_iter().zip(&coarse_div))
                .for_each(|(a, (&c, div))| *a = rho_here[c as usize] + div - *a);
            rhs
        });
        drop(rho_here);
        drop(coarse_div);
        let base = d as f32 / depths as f32;
        // The coefficients of this depth: the prolonged coarser solution plus the correction
        // the solve adds on the core.
        let mut z = y;
        let outcome = {
            let progress = &mut clock.progress;
            let mut keep_going = |f: f32| (progress)(Stage::Solve, base + f / depths as f32);
            conjugate_gradients(
                pool,
                &mut op,
                rhs,
                &mut z,
                params.max_solver_iterations,
                params.solver_tolerance,
                &mut keep_going,
            )
        };
        if outcome.cancelled {
            return Err(Error::Cancelled);
        }
        fill_mirrors(level, &mut z);
        coefficients.push(z);
        clock.stats.solves.push(DepthSolve {
            depth: d as u32,
            unknowns: level.core.len(),
            iterations: outcome.iterations,
            relative_residual: outcome.relative_residual,
            seconds: depth_started.elapsed().as_secs_f64(),
        });
    }
    drop(rho);
    drop(field_v);
    clock.done(Stage::Solve)?;

    // 7. Isovalue: the area-weighted mean of χ at the samples (§4.5).
    let chi = Indicator {
        tree: &tree,
        coefficients,
    };
    let (num, den) = pool.install(|| {
        let values: Vec<f64> = samples
            .positions
            .par_iter()
            .map(|&p| chi.value(p))
            .collect();
        let mut num = 0.0;
        let mut den = 0.0;
        for s in 0..values.len() {
            let w = sample_density.area[s] * samples.confidence[s];
            num += w * values[s];
            den += w;
        }
        (num, den)
    });
    let isovalue = if den > 0.0 { num / den } else { 0.0 };
    clock.stats.isovalue = isovalue;
    clock.done(Stage::Isovalue)?;

    // 8. Extract on the tree's leaves, following the surface from the leaves that hold samples.
    let inv_h = (max_depth as f64).exp2();
    let seeds: Vec<[i64; 3]> = samples
        .positions
        .iter()
        .map(|&p| {
            let c = cell_of(p, inv_h);
            [c[0] as i64, c[1] as i64, c[2] as i64]
        })
        .collect();
    let fitted = params.vertex_placement == VertexPlacement::Fitted;
    let mut raw = pool.install(|| extract::extract(&chi, isovalue, seeds, fitted));
    if fitted {
        pool.install(|| extract::fit_to_surface(&mut raw));
    }
    clock.done(Stage::Extract)?;

    // 9. Mesh: back to input coordinates, with the sampling density at each vertex.
    let (positions, densities) = pool.install(|| {
        let positions: Vec<[f32; 3]> = raw
            .vertices
            .par_iter()
            .map(|&v| {
                let p = map.to_input(v);
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect();
        let densities: Vec<f32> = raw
            .vertices
            .par_iter()
            .map(|&v| field.evaluate(v) as f32)
            .collect();
        (positions, densities)
    });
    clock.done(Stage::Mesh)?;
    Ok(Mesh {
        positions,
        triangles: raw.triangles,
        densities,
        stats: clock.stats,
    })
}

/// The depth at which the screening samples of depth d are grouped: two depths finer (16× less
/// sag of a proxy below a curved surface than grouping at d). On a 40k-point sphere at depth 7
/// grouping at d, at d + 2 or not at all (every sample) measured within 1% of each other; d + 2
/// keeps the proxies on the surface where samples are sparse and coarse cells large.
fn proxy_depth(d: u32, max_depth: u32) -> u32 {
    (d + 2).min(max_depth)
}

/// A fractional depth δ splats into ⌊δ⌋ with weight 1 − frac(δ) and ⌊δ⌋ + 1 with frac(δ).
fn depth_split(depth: f64) -> [(u32, f64); 2] {
    let base = depth.floor();
    let frac = depth - base;
    [(base as u32, 1.0 - frac), (base as u32 + 1, frac)]
}

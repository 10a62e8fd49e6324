//! Normals read off the reconstruction itself, repeated until they agree with it
//! ([`crate::Orientation::Reconstruction`]): the idea of iterative Poisson surface reconstruction
//! (Hou et al., "Iterative Poisson Surface Reconstruction (iPSR) for Unoriented Points", 2022),
//! here run coarse to fine and from two starts.
//!
//! A round: reconstruct a closed mesh from the points with their current normals; give each
//! triangle to the sample nearest its centroid; each sample's new normal is the sum of its
//! triangles' area-weighted normals (a sample no triangle chose keeps its normal). A closed mesh
//! has one inside and one outside everywhere, so its normals are consistent by construction,
//! and the triangles a sample collects (those nearer to it than to any other sample, including
//! the parts of the mesh far from every sample) tell it which side of the surface it lies on.
//! Propagation along a neighbour graph decides each sign from a few neighbours, which fails
//! where a fold's two sides are a few sample spacings apart (the mouth of CGAL's oni,
//! `tests/normals_on_scans.rs`); here every sign follows a reconstruction of the whole cloud.
//!
//! The rounds run at depth [`MIN_DEPTH`] first, then one depth finer at a time up to the depth
//! whose finest cells are half the points' median spacing (at most [`MAX_DEPTH`]). A depth ends
//! after the rounds allowed ([`crate::NormalEstimation::reconstruction_iterations`]) or as soon
//! as fewer than [`SETTLED`] of the signs changed in a round. Then each normal is taken from the
//! finest mesh near its point: the sum of the normals of the [`FINAL_TRIANGLES`] triangles whose
//! centroids lie nearest it, a tangent plane that follows the surface more closely than a plane
//! fitted to k neighbours where the sampling is sparse (the oni at depth 6: its mesh 1.14× the
//! file normals' mesh's distance from the points, 1.4–1.5× with the k = 20 planes given the
//! right signs).
//!
//! Two starts, measured (docs/benchmarks.md): from an arbitrary normal per point (a hash of its
//! index), rounds find the sides of a sparse cloud that propagation gets wrong (the oni's mouth:
//! 99.86 % of the signs right, against 96.2 % refining propagation's), but information travels
//! about a cell per round, so on a dense scan of a million points they have not undone the
//! arbitrary start everywhere by the time the signs settle (the Happy Buddha's scans: 85 %);
//! from propagation's normals, a round or two per depth fixes what propagation got wrong there
//! (99.32 → 99.73 %). Both run, and the start whose final mesh lies closer to the samples wins
//! (the mean distance from each sample to the nearest triangle centroid; a start with an
//! inside-out region has a mesh that bulges away from its points there): on the oni the
//! arbitrary start (7.1e-3 against 8.3e-3), on the Buddha propagation's (1.18e-4 against
//! 1.24e-4).
//!
//! The reconstructions use psr's defaults otherwise. The cost is a few reconstructions per
//! depth and start: meant for clouds where propagation fails, not a free default.
//!
//! Deterministic: the start is a function of the index, each reconstruction is the same bit for
//! bit at any thread count, nearest-point ties go to the smaller index, and the sums run in
//! triangle order.

use super::neighbors::{Neighbors, PointIndex};
use super::StepProgress;
use crate::error::{Error, Result};
use crate::{reconstruct_with_progress, Mesh, Params, PointSet, Stage};
use glam::DVec3;
use rayon::prelude::*;

/// The finest depth the rounds reconstruct at, whatever the spacing: each round costs a
/// reconstruction at its depth.
const MAX_DEPTH: u32 = 10;

/// The coarsest: below it the mesh cannot show a sample which side it is on.
const MIN_DEPTH: u32 = 5;

/// Triangles (nearest centroids) whose normals make each final normal.
const FINAL_TRIANGLES: usize = 3;

/// A depth is done when fewer than this fraction of the normals changed sign in a round (its
/// rounds then only move the lines). On the oni (1,435 points) that is a round with no change:
/// stopping at 0.1 % instead left its lip's corners for the finer depth, 99.65 % right instead
/// of 99.86 %.
const SETTLED: f64 = 0.0001;

/// The share of the progress span the refinement of the propagated normals takes (it settles
/// in a round or two per depth; the arbitrary start takes most of the rounds).
const SHARE_PROPAGATED: f32 = 0.25;

/// Normals for `positions` (checked by the caller: finite, more than one distinct): the
/// refinement of `propagated` (the normals propagation gave) or of the arbitrary start,
/// whichever mesh lies closer to the samples. `spacing` is [`median_spacing`] of propagation's
/// neighbours. `points_f32` are the same positions as the caller gave them, for the
/// reconstructions. Progress runs from 0 to 1.
#[allow(clippy::too_many_arguments)]
pub(super) fn iterate(
    positions: &[DVec3],
    points_f32: &[[f32; 3]],
    propagated: Vec<DVec3>,
    spacing: f64,
    iterations: u32,
    threads: usize,
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<Vec<DVec3>> {
    let finest = depth_for(positions, spacing);
    let samples = pool.install(|| PointIndex::new(positions));
    let run = Refinement {
        positions,
        points_f32,
        samples: &samples,
        schedule: Schedule::new(finest, iterations),
        threads,
        pool,
    };
    let from_propagation = run.refine(propagated, &mut |f| progress(SHARE_PROPAGATED * f))?;
    let arbitrary = (0..positions.len()).map(start_normal).collect();
    let from_arbitrary = run.refine(arbitrary, &mut |f| {
        progress(SHARE_PROPAGATED + (1.0 - SHARE_PROPAGATED) * f)
    })?;
    progress(1.0)?;
    Ok(if from_arbitrary.misfit < from_propagation.misfit {
        from_arbitrary.normals
    } else {
        from_propagation.normals
    })
}

/// One start's outcome: the normals read off its final mesh, and how far that mesh lies from
/// the samples (the mean distance from each sample to the nearest triangle centroid; the two
/// starts' final meshes have the same depth, so their triangles are alike in size).
struct Refined {
    normals: Vec<DVec3>,
    misfit: f64,
}

/// What every round reads: the points, their index, the depths and the threads.
struct Refinement<'a> {
    positions: &'a [DVec3],
    points_f32: &'a [[f32; 3]],
    samples: &'a PointIndex,
    schedule: Schedule,
    threads: usize,
    pool: &'a rayon::ThreadPool,
}

impl Refinement<'_> {
    /// Rounds from `normals`, depth by depth, then the final read-off.
    fn refine(&self, mut normals: Vec<DVec3>, progress: StepProgress<'_>) -> Result<Refined> {
        let (positions, schedule) = (self.positions, &self.schedule);
        let settled = (SETTLED * positions.len() as f64).ceil() as usize;
        for depth in schedule.first..=schedule.finest {
            let params = Params::default()
                .with_depth(depth)
                .with_threads(self.threads);
            for round in 0..schedule.iterations {
                let mesh = reconstruct_from(self.points_f32, &normals, &params, &mut |f| {
                    progress(schedule.fraction(depth, round as f32 + f))
                })?;
                let sums = self.pool.install(|| {
                    triangle_normals_by_nearest_sample(&mesh, self.samples, positions.len())
                });
                let mut flips = 0;
                for (n, sum) in normals.iter_mut().zip(sums) {
                    if sum.length_squared() > 0.0 {
                        let new = sum.normalize();
                        flips += usize::from(new.dot(*n) < 0.0);
                        *n = new;
                    }
                }
                if flips < settled {
                    break;
                }
            }
        }
        let params = Params::default()
            .with_depth(schedule.finest)
            .with_threads(self.threads);
        let mesh = reconstruct_from(self.points_f32, &normals, &params, &mut |f| {
            progress(schedule.fraction(schedule.finest + 1, f))
        })?;
        let nearest = self.pool.install(|| nearest_triangles(&mesh, positions));
        let mut distance = 0.0;
        for (n, (sum, d)) in normals.iter_mut().zip(nearest) {
            if sum.length_squared() > 0.0 {
                *n = sum.normalize();
            }
            distance += d;
        }
        Ok(Refined {
            normals,
            misfit: distance / positions.len() as f64,
        })
    }
}

/// Where a round stands in the whole work, for progress: each depth's share of the span grows
/// fourfold per depth (a surface's nodes do), its rounds split it evenly (a depth that settles
/// early jumps to its end), and the final read-off at the finest depth counts as one more of
/// its rounds, written as depth `finest + 1`.
struct Schedule {
    first: u32,
    finest: u32,
    iterations: u32,
    total: f32,
}

impl Schedule {
    fn new(finest: u32, iterations: u32) -> Schedule {
        let first = MIN_DEPTH.min(finest);
        let mut schedule = Schedule {
            first,
            finest,
            iterations,
            total: 1.0,
        };
        schedule.total = schedule.before(finest + 1) + schedule.weight(finest + 1);
        schedule
    }

    fn weight(&self, depth: u32) -> f32 {
        if depth > self.finest {
            self.weight(self.finest) / self.iterations as f32
        } else {
            4f32.powi((depth - self.first) as i32)
        }
    }

    fn before(&self, depth: u32) -> f32 {
        (self.first..depth).map(|d| self.weight(d)).sum()
    }

    /// The fraction done at `rounds` (fractional) rounds into `depth`.
    fn fraction(&self, depth: u32, rounds: f32) -> f32 {
        let per_round = if depth > self.finest {
            self.weight(depth)
        } else {
            self.weight(depth) / self.iterations as f32
        };
        ((self.before(depth) + rounds * per_round) / self.total).min(1.0)
    }
}

/// The median distance from a point to its nearest other point, over the points whose nearest
/// other point is somewhere else (duplicates do not count), read off propagation's neighbour
/// lists (nearest first). [`Error::DegenerateInput`] when every point coincides with another.
pub(super) fn median_spacing(positions: &[DVec3], neighbors: &Neighbors) -> Result<f64> {
    let mut distances: Vec<f64> = neighbors
        .rows()
        .enumerate()
        .map(|(i, row)| (positions[row[0] as usize] - positions[i]).length())
        .filter(|&d| d > 0.0)
        .collect();
    if distances.is_empty() {
        return Err(Error::DegenerateInput {
            points: positions.len(),
        });
    }
    let middle = distances.len() / 2;
    let (_, &mut spacing, _) = distances.select_nth_unstable_by(middle, f64::total_cmp);
    Ok(spacing)
}

/// The depth whose finest cell (the bounding box's longest side × the default scale over
/// 2^depth) is at most half `spacing`, within [`MIN_DEPTH`]..=[`MAX_DEPTH`].
fn depth_for(positions: &[DVec3], spacing: f64) -> u32 {
    let (lo, hi) = positions.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let side = (hi - lo).max_element() * Params::default().scale as f64;
    let depth = (side / (0.5 * spacing)).log2().ceil();
    (depth.max(MIN_DEPTH as f64) as u32).min(MAX_DEPTH)
}

/// The starting normal of point `i`: a unit vector from a hash of `i` (splitmix64), spread
/// over the sphere.
fn start_normal(i: usize) -> DVec3 {
    let mut state = (i as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    };
    // Uniform on the sphere: z uniform in [-1, 1], the angle around z uniform.
    let z = 2.0 * next() - 1.0;
    let angle = std::f64::consts::TAU * next();
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * angle.cos(), r * angle.sin(), z)
}

/// One reconstruction of the points with `normals`, its progress mapped onto `progress`.
fn reconstruct_from(
    points: &[[f32; 3]],
    normals: &[DVec3],
    params: &Params,
    progress: StepProgress<'_>,
) -> Result<Mesh> {
    let normals: Vec<[f32; 3]> = normals
        .iter()
        .map(|n| [n.x as f32, n.y as f32, n.z as f32])
        .collect();
    let set = PointSet::from_slices(points, &normals)?;
    let stages = (Stage::ALL.len() - 2) as f32;
    let mut failure = None;
    let mesh = reconstruct_with_progress(&set, params, &mut |stage, f| {
        // The reconstruction's stages in order (Stage::ALL without Normals and Trim).
        let done = Stage::ALL[1..Stage::ALL.len() - 1]
            .iter()
            .position(|&s| s == stage)
            .unwrap_or(0) as f32;
        match progress((done + f) / stages) {
            Ok(()) => true,
            Err(e) => {
                failure = Some(e);
                false
            }
        }
    });
    match (mesh, failure) {
        (_, Some(e)) => Err(e),
        (mesh, None) => mesh,
    }
}

/// A triangle's normal scaled by twice its area, and its centroid, in f64.
fn triangle(mesh: &Mesh, t: [u32; 3]) -> (DVec3, DVec3) {
    let [a, b, c] = t.map(|i| {
        let p = mesh.positions[i as usize];
        DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) + DVec3::from_array(mesh.origin)
    });
    ((b - a).cross(c - a), (a + b + c) / 3.0)
}

/// For every sample, the sum of the area-weighted normals of the triangles whose centroid lies
/// nearer to it than to any other sample (ties to the smaller index), added in triangle order.
fn triangle_normals_by_nearest_sample(
    mesh: &Mesh,
    samples: &PointIndex,
    count: usize,
) -> Vec<DVec3> {
    let owners: Vec<(u32, DVec3)> = mesh
        .triangles
        .par_iter()
        .map_init(Vec::new, |best, &t| {
            let (normal, centroid) = triangle(mesh, t);
            (samples.nearest(centroid, 1, best)[0].1, normal)
        })
        .collect();
    let mut sums = vec![DVec3::ZERO; count];
    for (owner, normal) in owners {
        sums[owner as usize] += normal;
    }
    sums
}

/// For each sample, the sum of the area-weighted normals of the [`FINAL_TRIANGLES`] triangles
/// whose centroids lie nearest it (ties to the smaller index), and its distance to the nearest
/// centroid; zero and infinity when the mesh is empty.
fn nearest_triangles(mesh: &Mesh, positions: &[DVec3]) -> Vec<(DVec3, f64)> {
    if mesh.triangles.is_empty() {
        return vec![(DVec3::ZERO, f64::INFINITY); positions.len()];
    }
    let (faces, centroids): (Vec<DVec3>, Vec<DVec3>) =
        mesh.triangles.iter().map(|&t| triangle(mesh, t)).unzip();
    let index = PointIndex::new(&centroids);
    positions
        .par_iter()
        .map_init(Vec::new, |best, &p| {
            let nearest = index.nearest(p, FINAL_TRIANGLES, best);
            let sum = nearest.iter().map(|&(_, j)| faces[j as usize]).sum();
            (sum, nearest[0].0.sqrt())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_normals_are_unit_and_spread() {
        let normals: Vec<DVec3> = (0..10_000).map(start_normal).collect();
        assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-12));
        let mean: DVec3 = normals.iter().copied().sum::<DVec3>() / normals.len() as f64;
        assert!(mean.length() < 0.05, "mean {mean}");
    }
}

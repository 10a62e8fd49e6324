//! Normal estimation and orientation for unoriented point clouds: a stage before `points`.
//!
//! [`estimate_normals`] gives every point a unit normal from its positions alone, in three
//! steps, each in its own file:
//!
//! 1. `neighbors.rs`: the k nearest other points of every point, exact, on a uniform bucket
//!    grid searched ring by ring until the k-th distance is certified; ties by index.
//! 2. `estimate.rs`: the normal of the least-squares plane through the point and its
//!    neighbours, the eigenvector of the smallest eigenvalue of their covariance (PCA; Hoppe et
//!    al. 1992, §3.2), in f64 by Jacobi rotations; `sheets.rs`: where the neighbourhood holds
//!    two parallel sheets of the surface, the normal of two parallel planes fitted to them, and
//!    which neighbours lie on the other sheet.
//! 3. `orient.rs`: the sign of each normal, by [`Orientation`]: propagation along a minimum
//!    spanning forest of the kNN graph (Hoppe et al. 1992, §3.3), or towards a viewpoint, or
//!    towards each point's sensor.
//!
//! [`Orientation::Reconstruction`] adds a fourth: `reconstruction.rs` reads every normal off a
//! mesh reconstructed from the normals themselves, repeated, from propagation's normals and from
//! an arbitrary start, and keeps the start whose mesh fits the points better.
//!
//! [`orient_normals`] runs step 3 alone on normals the caller already has but whose signs are
//! unreliable (e.g. normals from a mesher or a scanner that does not orient them).
//!
//! Deterministic like the rest of psr: every step reads only its inputs, neighbour lists and
//! the spanning forest break ties by index, and reductions run in index order, so the normals
//! are the same bit for bit at any thread count.
//!
//! Nothing here reads or changes the reconstruction's state; feed the result to
//! [`crate::PointSet::from_slices`].

mod estimate;
mod neighbors;
mod orient;
mod reconstruction;
mod sheets;

pub(crate) use estimate::{jacobi_eigen, scatter};

use crate::error::{Error, Result};
use crate::{Progress, Stage, Workers};
use glam::DVec3;

/// Points per batch of the neighbour search and the plane fits, between progress reports
/// (about 10 ms of work per core on current machines).
const BATCH: usize = 1 << 14;

/// A step's progress: called with the fraction of the step done; an error stops the step.
type StepProgress<'a> = &'a mut dyn FnMut(f32) -> Result<()>;

/// The fractions of [`Stage::Normals`] the neighbour search and the plane fits take (the rest
/// is the orientation), about as measured on the bunny scans at k = 20 on one thread (1.2 s,
/// 0.6 s with the two-sheet split, 1.4 s).
const SPAN_NEIGHBORS: f32 = 0.45;
const SPAN_FIT: f32 = 0.15;
/// The share of [`Stage::Normals`] that estimating and propagating takes before
/// [`Orientation::Reconstruction`]'s rounds (a few percent of their time, measured on the
/// bunny and the Buddha).
const SPAN_BEFORE_RECONSTRUCTION: f32 = 0.05;

/// The share of the fit span the first pass takes (the rest revisits ambiguous planes, a few
/// percent of the points; see `sheets.rs`).
const SPAN_FIRST_FIT: f32 = 0.9;

/// How the sign of each normal is chosen.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Orientation {
    /// Consistent signs by propagation (Hoppe et al. 1992): along a spanning forest of the kNN
    /// graph with edge weights 1 − |n_i·n_j| plus how far the edge leaves the two tangent
    /// planes, each child flipped to agree with its parent, grown only until its trees have a
    /// neighbourhood's worth of points; those regions are then joined by the summed votes of all
    /// the edges between them, so that no single edge decides the sign of a large patch. Each
    /// connected part of the cloud is oriented on its own: outward when it
    /// encloses volume (its net flux Σ a_i n_i·(p_i − centroid) is clearly positive for outward
    /// normals), else so that its point of largest x has a normal with non-negative x. The
    /// default. Open3D `orient_normals_consistent_tangent_plane`, PCL has none.
    ///
    /// Where two sheets of the surface come closer than a neighbourhood (thin plates and
    /// shells, touching parts), the neighbours on the other sheet are found from the positions
    /// and the sign is not carried across to them; two sheets joined by nothing else are
    /// oriented opposite ways, as the two sides of a thin part of a closed surface are.
    ///
    /// Known limit: a fold or lip whose two sides are only a few sample spacings apart and
    /// whose bend the sampling does not resolve (the mouth of CGAL's oni at k = 20) is not two
    /// parallel sheets, and one side may still come out flipped; use
    /// [`Orientation::Reconstruction`], a viewpoint or sensors there.
    Propagate,
    /// Every normal faces this point (n·(viewpoint − p) ≥ 0), as for a single scan. Open3D
    /// `orient_normals_towards_camera_location`, PCL `setViewPoint`.
    Viewpoint([f64; 3]),
    /// Every normal faces its own point's sensor: one position per input point (e.g. the scanner
    /// origin of each scan). Length must equal the number of points.
    Sensors(Vec<[f32; 3]>),
    /// Normals read off the reconstruction itself, repeated (iterative Poisson reconstruction,
    /// Hou et al. 2022; `reconstruction.rs`): in rounds, a mesh is reconstructed from the
    /// current normals and each point takes the area-weighted normal of the triangles nearer to
    /// it than to any other point; at the end each point takes the normal of the final mesh
    /// next to it. The rounds run coarse to fine (depth 5 up to the depth of the points' spacing,
    /// at most 10; at most [`NormalEstimation::reconstruction_iterations`] rounds per depth,
    /// fewer once almost no sign changes), from two starts: propagation's normals and an
    /// arbitrary one; the start whose final mesh lies closer to the points wins. Every sign then
    /// follows a closed surface of the whole cloud rather than a few neighbours, so it holds
    /// where propagation fails: folds and lips whose two sides are a few sample spacings apart,
    /// sparse clouds (CGAL's oni: 99.86 % of its 1,435 normals right, against 88.5 % by
    /// propagation, and a mesh within 1.14× of the file normals' distance to the points); on
    /// dense scans it refines propagation (the Happy Buddha's scans: 99.73 % against 99.32 %).
    /// It also gives the line, not only the sign ([`orient_normals`] keeps the given lines and
    /// takes only the signs), and every closed part comes out outward.
    ///
    /// Cost: a few reconstructions per depth for each start; about a second for thousands of
    /// points, minutes for a million (docs/benchmarks.md). Open3D, PCL, PoissonRecon: none (the
    /// iPSR authors' program).
    Reconstruction,
}

/// Options of [`estimate_normals`] and [`orient_normals`]. `NormalEstimation::default()` works;
/// set fields directly or with the `with_*` builders:
///
/// ```
/// let options = psr::NormalEstimation::default()
///     .with_neighbors(12)
///     .with_orientation(psr::Orientation::Viewpoint([0.0, 0.0, 10.0]));
/// assert_eq!(options.neighbors, 12);
/// ```
///
/// New fields may be added in any release (the struct is `#[non_exhaustive]`), so build it
/// from `NormalEstimation::default()`.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NormalEstimation {
    /// Neighbours per point (besides the point itself) for the plane fit and the orientation
    /// graph. Default 20, range 1..=1000 (at least 3 for the fit to define a plane; 10–30 is
    /// usual). More smooths noise and bridges uneven sampling, fewer keeps sharp edges and thin
    /// parts apart. Open3D `KDTreeSearchParamKNN(knn)` (its k counts the point itself),
    /// PCL `setKSearch`, PoissonRecon's `--nearest` in its normal tools.
    pub neighbors: usize,
    /// How signs are chosen. Default [`Orientation::Propagate`].
    pub orientation: Orientation,
    /// The most rounds [`Orientation::Reconstruction`] runs at each depth (a depth ends
    /// sooner once fewer than 0.01 % of the signs change in a round). Default 10, range
    /// 1..=1000; ignored by the other orientations.
    pub reconstruction_iterations: u32,
    /// Worker threads; 0 = all cores. Default 0. The normals do not depend on it.
    pub threads: usize,
}

impl Default for NormalEstimation {
    fn default() -> Self {
        NormalEstimation {
            neighbors: 20,
            orientation: Orientation::Propagate,
            reconstruction_iterations: 10,
            threads: 0,
        }
    }
}

impl NormalEstimation {
    /// These options with [`NormalEstimation::neighbors`] set to `neighbors`.
    pub fn with_neighbors(mut self, neighbors: usize) -> Self {
        self.neighbors = neighbors;
        self
    }

    /// These options with [`NormalEstimation::orientation`] set to `orientation`.
    pub fn with_orientation(mut self, orientation: Orientation) -> Self {
        self.orientation = orientation;
        self
    }

    /// These options with [`NormalEstimation::reconstruction_iterations`] set to `iterations`.
    pub fn with_reconstruction_iterations(mut self, iterations: u32) -> Self {
        self.reconstruction_iterations = iterations;
        self
    }

    /// These options with [`NormalEstimation::threads`] set to `threads`.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads;
        self
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<()> {
        if !(1..=1000).contains(&self.neighbors) {
            return Err(Error::InvalidParameter {
                name: "neighbors",
                value: self.neighbors.to_string(),
                expected: "an integer in 1..=1000",
            });
        }
        if !(1..=1000).contains(&self.reconstruction_iterations) {
            return Err(Error::InvalidParameter {
                name: "reconstruction_iterations",
                value: self.reconstruction_iterations.to_string(),
                expected: "an integer in 1..=1000",
            });
        }
        if self.threads > 4096 {
            return Err(Error::InvalidParameter {
                name: "threads",
                value: self.threads.to_string(),
                expected: "0 (all cores) or a count up to 4096",
            });
        }
        if let Orientation::Viewpoint(v) = &self.orientation {
            if !v.iter().all(|c| c.is_finite()) {
                return Err(Error::InvalidParameter {
                    name: "orientation",
                    value: format!("Viewpoint({v:?})"),
                    expected: "a viewpoint with finite coordinates",
                });
            }
        }
        if let Orientation::Sensors(sensors) = &self.orientation {
            if let Some(index) = sensors
                .iter()
                .position(|s| !s.iter().all(|c| c.is_finite()))
            {
                return Err(Error::InvalidParameter {
                    name: "orientation",
                    value: format!("Sensors(..) with sensor {index} = {:?}", sensors[index]),
                    expected: "sensor positions with finite coordinates",
                });
            }
        }
        Ok(())
    }
}

/// Estimates an oriented unit normal for every point of an unoriented cloud (one per position,
/// in the same order).
///
/// Errors: [`Error::InvalidParameter`] for options out of range, [`Error::EmptyInput`],
/// [`Error::NonFinitePosition`] (the first bad index), [`Error::TooFewPoints`] when there are
/// not more points than `neighbors`, [`Error::DegenerateInput`] when all points coincide,
/// [`Error::NoPlaneDefined`] when no neighbourhood spans a plane (e.g. all points on a line),
/// [`Error::LengthMismatch`] when [`Orientation::Sensors`] has the wrong length,
/// [`Error::ThreadsUnavailable`].
///
/// Duplicates and locally collinear points never give NaN: a neighbourhood that spans no plane
/// takes the normal of its nearest neighbour that has one (see `estimate.rs`); a part of the
/// cloud where no neighbourhood spans a plane keeps a deterministic unit vector perpendicular
/// to nothing in particular.
pub fn estimate_normals(
    positions: &[[f32; 3]],
    options: &NormalEstimation,
) -> Result<Vec<[f32; 3]>> {
    estimate_normals_with_progress(positions, options, &mut |_, _| true)
}

/// [`estimate_normals`] with a progress callback that may cancel (then the result is
/// `Err(Error::Cancelled)`). It receives [`Stage::Normals`] and the fraction done, on the
/// calling thread, never concurrently, at least every 16,384 points of each step (one step,
/// the sort of the orientation's graph edges, runs about 0.1 s per million points per core
/// between reports); with [`Orientation::Reconstruction`], also at every stage of each of its
/// reconstructions.
pub fn estimate_normals_with_progress(
    positions: &[[f32; 3]],
    options: &NormalEstimation,
    progress: Progress<'_>,
) -> Result<Vec<[f32; 3]>> {
    let raw = positions;
    let positions = checked_positions(positions, options)?;
    let workers = Workers::start(options.threads)?;
    let pool = workers.pool();
    let mut report = |fraction: f32| {
        if progress(Stage::Normals, fraction) {
            Ok(())
        } else {
            Err(Error::Cancelled)
        }
    };
    report(0.0)?;
    let by_reconstruction = options.orientation == Orientation::Reconstruction;
    let (signs, span) = first_signs(&options.orientation);
    let mut report_in_span = |f: f32| report(span * f);
    let neighbors = neighbors::k_nearest(&positions, options.neighbors, pool, &mut |f| {
        report_in_span(SPAN_NEIGHBORS * f)
    })?;
    let (mut fits, mut across, ambiguous) =
        estimate::fit_planes(&positions, &neighbors, pool, &mut |f| {
            report_in_span(SPAN_NEIGHBORS + SPAN_FIT * SPAN_FIRST_FIT * f)
        })?;
    if fits.iter().all(|f| !f.defined) {
        return Err(Error::NoPlaneDefined {
            points: positions.len(),
        });
    }
    sheets::revisit_ambiguous(
        &positions,
        &neighbors,
        &mut fits,
        &mut across,
        &ambiguous,
        pool,
        &mut |f| {
            report_in_span(
                SPAN_NEIGHBORS + SPAN_FIT * (SPAN_FIRST_FIT + (1.0 - SPAN_FIRST_FIT) * f),
            )
        },
    )?;
    estimate::fill_undefined(&positions, &mut fits, &neighbors);
    let mut normals: Vec<DVec3> = fits.into_iter().map(|f| f.normal).collect();
    let done = SPAN_NEIGHBORS + SPAN_FIT;
    orient(
        &positions,
        &mut normals,
        Some(&neighbors),
        Some(&across),
        signs,
        pool,
        &mut |f| report_in_span(done + (1.0 - done) * f),
    )?;
    if by_reconstruction {
        let spacing = reconstruction::median_spacing(&positions, &neighbors)?;
        drop((neighbors, across));
        normals = reconstruction::iterate(
            &positions,
            raw,
            normals,
            spacing,
            options.reconstruction_iterations,
            options.threads,
            pool,
            &mut |f| report(span + (1.0 - span) * f),
        )?;
    }
    report(1.0)?;
    Ok(to_f32(&normals))
}

/// Re-orients normals whose directions are right but whose signs are unreliable: keeps each
/// line, chooses each sign by `options.orientation` ([`Orientation::Propagate`] makes the signs
/// consistent and outward; where two sheets come closer than a neighbourhood, the neighbours on
/// the other sheet are found along the given lines, as in [`estimate_normals`]). Returns unit
/// normals.
///
/// Errors: those of [`estimate_normals`] (but not [`Error::NoPlaneDefined`]), and
/// [`Error::LengthMismatch`], [`Error::NonFiniteNormal`], [`Error::ZeroNormal`] for the
/// normals.
pub fn orient_normals(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    options: &NormalEstimation,
) -> Result<Vec<[f32; 3]>> {
    orient_normals_with_progress(positions, normals, options, &mut |_, _| true)
}

/// [`orient_normals`] with a progress callback that may cancel, as for
/// [`estimate_normals_with_progress`] ([`Stage::Normals`]).
pub fn orient_normals_with_progress(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    options: &NormalEstimation,
    progress: Progress<'_>,
) -> Result<Vec<[f32; 3]>> {
    if normals.len() != positions.len() {
        return Err(Error::LengthMismatch {
            what: "normals",
            positions: positions.len(),
            other: normals.len(),
        });
    }
    let raw = positions;
    let checked = checked_positions(positions, options)?;
    let mut unit = Vec::with_capacity(normals.len());
    for (index, n) in normals.iter().enumerate() {
        let n = to_f64(*n);
        if !n.is_finite() {
            return Err(Error::NonFiniteNormal { index });
        }
        let length = n.length();
        if length < f32::MIN_POSITIVE as f64 {
            return Err(Error::ZeroNormal { index });
        }
        unit.push(n / length);
    }
    let workers = Workers::start(options.threads)?;
    let pool = workers.pool();
    let mut report = |fraction: f32| {
        if progress(Stage::Normals, fraction) {
            Ok(())
        } else {
            Err(Error::Cancelled)
        }
    };
    report(0.0)?;
    let positions = checked;
    let by_reconstruction = options.orientation == Orientation::Reconstruction;
    let (signs, span) = first_signs(&options.orientation);
    let mut report_in_span = |f: f32| report(span * f);
    let neighbors = match signs {
        Orientation::Propagate => Some(neighbors::k_nearest(
            &positions,
            options.neighbors,
            pool,
            &mut |f| report_in_span(SPAN_NEIGHBORS * f),
        )?),
        _ => None,
    };
    let across = match &neighbors {
        Some(neighbors) => Some(sheets::across_given(
            &positions,
            neighbors,
            &unit,
            pool,
            &mut |f| report_in_span(SPAN_NEIGHBORS + SPAN_FIT * f),
        )?),
        None => None,
    };
    let lines = by_reconstruction.then(|| unit.clone());
    orient(
        &positions,
        &mut unit,
        neighbors.as_ref(),
        across.as_ref(),
        signs,
        pool,
        &mut |f| report_in_span(SPAN_NEIGHBORS + SPAN_FIT + (1.0 - SPAN_NEIGHBORS - SPAN_FIT) * f),
    )?;
    if let Some(lines) = lines {
        let propagation = neighbors.as_ref().ok_or_else(|| {
            Error::Internal("the reconstruction's start without propagation's neighbours".into())
        })?;
        let spacing = reconstruction::median_spacing(&positions, propagation)?;
        drop((neighbors, across));
        let reconstructed = reconstruction::iterate(
            &positions,
            raw,
            unit,
            spacing,
            options.reconstruction_iterations,
            options.threads,
            pool,
            &mut |f| report(span + (1.0 - span) * f),
        )?;
        // The given lines, each signed as the reconstruction's normal at its point.
        unit = lines
            .into_iter()
            .zip(reconstructed)
            .map(|(n, r)| if n.dot(r) < 0.0 { -n } else { n })
            .collect();
    }
    report(1.0)?;
    Ok(to_f32(&unit))
}

/// The sign step to run first and the share of the progress span it takes:
/// [`Orientation::Reconstruction`] starts from propagation's signs in the first
/// [`SPAN_BEFORE_RECONSTRUCTION`] of the span; the others are their own step over all of it.
fn first_signs(orientation: &Orientation) -> (&Orientation, f32) {
    match orientation {
        Orientation::Reconstruction => (&Orientation::Propagate, SPAN_BEFORE_RECONSTRUCTION),
        other => (other, 1.0),
    }
}

/// Validates the options and the positions, and returns the positions in f64.
fn checked_positions(positions: &[[f32; 3]], options: &NormalEstimation) -> Result<Vec<DVec3>> {
    options.validate()?;
    if positions.is_empty() {
        return Err(Error::EmptyInput);
    }
    if let Some(index) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Error::NonFinitePosition { index });
    }
    if let Orientation::Sensors(sensors) = &options.orientation {
        if sensors.len() != positions.len() {
            return Err(Error::LengthMismatch {
                what: "sensors",
                positions: positions.len(),
                other: sensors.len(),
            });
        }
    }
    if positions.len() <= options.neighbors {
        return Err(Error::TooFewPoints {
            points: positions.len(),
            neighbors: options.neighbors,
        });
    }
    if positions.len() > u32::MAX as usize {
        return Err(Error::InvalidParameter {
            name: "positions",
            value: positions.len().to_string(),
            expected: "at most 2^32 - 1 points",
        });
    }
    if positions.iter().all(|p| *p == positions[0]) {
        return Err(Error::DegenerateInput {
            points: positions.len(),
        });
    }
    Ok(positions.iter().map(|&p| to_f64(p)).collect())
}

/// Chooses the signs of `normals` by `orientation` (`neighbors` is needed for propagation).
fn orient(
    positions: &[DVec3],
    normals: &mut [DVec3],
    neighbors: Option<&neighbors::Neighbors>,
    sheets: Option<&sheets::Sheets>,
    orientation: &Orientation,
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<()> {
    match orientation {
        Orientation::Propagate => match neighbors {
            Some(neighbors) => {
                orient::propagate(positions, normals, neighbors, sheets, pool, progress)
            }
            None => Err(Error::Internal(
                "propagation without the neighbour graph".into(),
            )),
        },
        Orientation::Viewpoint(v) => {
            pool.install(|| orient::towards_viewpoint(positions, normals, DVec3::from_array(*v)));
            Ok(())
        }
        Orientation::Sensors(sensors) => {
            pool.install(|| orient::towards_sensors(positions, normals, sensors));
            Ok(())
        }
        Orientation::Reconstruction => Err(Error::Internal(
            "the reconstruction's orientation is not a sign step".into(),
        )),
    }
}

fn to_f64(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

fn to_f32(normals: &[DVec3]) -> Vec<[f32; 3]> {
    normals
        .iter()
        .map(|n| {
            let n = n.normalize();
            [n.x as f32, n.y as f32, n.z as f32]
        })
        .collect()
}

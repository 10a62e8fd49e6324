//! The solved implicit function χ as a product of its own: kept after a reconstruction
//! ([`crate::reconstruct_with_implicit`]) and evaluated at any point, with its gradient, or
//! sampled on a regular grid (PoissonRecon's `--grid`), for SDF and learning pipelines and other
//! meshers.
//!
//! χ = Σ_o x_o B_o is the solved indicator function (§4.3); the surface is its level set at the
//! isovalue γ (§4.4). It is evaluated by `evaluate.rs`, the code extraction uses: this module
//! only maps input coordinates into the unit cube (p_unit = (p − origin) / size) and the
//! gradient back out by the chain rule (∇_input χ = ∇_unit χ / size), and runs batches in
//! parallel.
//!
//! Conventions, as measured by `tests/implicit.rs`: χ − γ is negative inside the surface and
//! positive outside (psr's χ grows outward, as the normals point), so ∇χ points outward: the
//! mesh's vertex normals are ∇χ/|∇χ|. A signed-distance-like field is (χ − γ) / |∇χ|.

use crate::evaluate::Indicator;
use crate::points::UnitCubeMap;
use crate::{Error, Result, Workers};
use glam::DVec3;
use rayon::prelude::*;

/// The largest grid resolution [`ImplicitFunction::sample_grid`] accepts: 4096³ floats are
/// 256 GiB, so anything above is a mistake rather than a wish.
pub const MAX_GRID_RESOLUTION: usize = 4096;

/// Batches smaller than this are evaluated on the calling thread (starting a pool costs more).
const PARALLEL_BATCH: usize = 4096;

/// Points evaluated per parallel task (fixed, so the work split does not depend on the thread
/// count; each value is computed alone, so the result would not either way).
const CHUNK: usize = 1024;

/// The solved indicator function χ of one reconstruction, with its isovalue γ and the map from
/// input coordinates into the unit cube it was solved in. Owned and immutable: it can be shared
/// between threads and evaluated from all of them at once.
///
/// Get it with [`crate::reconstruct_with_implicit`]; it keeps the octree and the solved
/// coefficients of every depth (about as much memory as the octree the reconstruction built).
///
/// Evaluation is defined everywhere:
/// - Inside the bounding cube ([`ImplicitFunction::cube`]) it is χ, the same function
///   extraction contoured: the mesh's surface is where `value(p) == isovalue()`.
/// - Outside the cube psr solves nothing; χ is continued constantly along the cube's normals:
///   `value(p)` is χ at the point of the cube nearest to p, and `gradient(p)` has zero
///   components along the axes on which p lies outside.
/// - A point with a NaN or infinite coordinate gives NaN from [`ImplicitFunction::value`] and
///   [`ImplicitFunction::gradient`]; the batch functions refuse it with
///   [`Error::NonFinitePosition`] naming its index.
pub struct ImplicitFunction {
    chi: Indicator,
    isovalue: f64,
    map: UnitCubeMap,
    threads: usize,
}

impl std::fmt::Debug for ImplicitFunction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitFunction")
            .field("isovalue", &self.isovalue)
            .field("cube_origin", &self.map.origin)
            .field("cube_size", &self.map.size)
            .field("depth", &self.depth())
            .finish_non_exhaustive()
    }
}

impl ImplicitFunction {
    /// Keeps a reconstruction's χ; `threads` (0 = all cores) sizes the pools of the batch
    /// functions, as [`crate::Params::threads`] does the reconstruction's.
    pub(crate) fn new(
        chi: Indicator,
        isovalue: f64,
        map: UnitCubeMap,
        threads: usize,
    ) -> ImplicitFunction {
        ImplicitFunction {
            chi,
            isovalue,
            map,
            threads,
        }
    }

    /// The isovalue γ the mesh was extracted at (the same as [`crate::Stats::isovalue`]).
    pub fn isovalue(&self) -> f64 {
        self.isovalue
    }

    /// The bounding cube χ was solved in, in input coordinates: its minimum corner and its
    /// edge length (the points' bounding box enlarged by [`crate::Params::scale`]).
    pub fn cube(&self) -> ([f64; 3], f64) {
        (self.map.origin.to_array(), self.map.size)
    }

    /// The finest depth of the octree χ lives on (its finest cells are `size / 2^depth` wide).
    pub fn depth(&self) -> u32 {
        self.chi.tree.max_depth()
    }

    /// The point of the unit cube whose χ is p's: p mapped into the unit cube and clamped into
    /// [0, 1) per axis (the largest double below 1 stays in the cube's last cell), and which
    /// axes were clamped. `None` for a non-finite p.
    fn unit(&self, p: [f64; 3]) -> Option<(DVec3, [bool; 3])> {
        let p = DVec3::from_array(p);
        if !p.is_finite() {
            return None;
        }
        let q = (p - self.map.origin) / self.map.size;
        const BELOW_ONE: f64 = 1.0 - f64::EPSILON / 2.0;
        let clamped = q.clamp(DVec3::ZERO, DVec3::splat(BELOW_ONE));
        // An input just inside the cube's far face can round to 1 in the unit cube: that is
        // inside, not outside.
        let outside = [0, 1, 2].map(|a| q[a] < 0.0 || q[a] > 1.0);
        Some((clamped, outside))
    }

    /// χ at a point in input coordinates; NaN if a coordinate is NaN or infinite. Outside the
    /// bounding cube, χ at the nearest point of the cube (see [`ImplicitFunction`]).
    pub fn value(&self, p: [f64; 3]) -> f64 {
        match self.unit(p) {
            Some((q, _)) => self.chi.value(q),
            None => f64::NAN,
        }
    }

    /// ∇χ at a point in input coordinates, per input unit (the unit cube's gradient divided by
    /// the cube's size); NaN if a coordinate is NaN or infinite. Outside the bounding cube, the
    /// gradient at the nearest point of the cube with the components zeroed along the axes on
    /// which the point lies outside (the gradient of χ continued constantly). It points outward
    /// (χ − γ grows from inside to outside): the mesh's outward normal is ∇χ/|∇χ|.
    pub fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        match self.unit(p) {
            Some((q, outside)) => {
                let g = self.chi.gradient(q) / self.map.size;
                [0, 1, 2].map(|a| if outside[a] { 0.0 } else { g[a] })
            }
            None => [f64::NAN; 3],
        }
    }

    /// χ at many points in input coordinates, as f32, in the points' order; evaluated in
    /// parallel (on `threads` workers, as the reconstruction was) for large batches, with the
    /// same result as [`ImplicitFunction::value`] point by point, whatever the thread count.
    ///
    /// Errors: [`Error::NonFinitePosition`] for the first point with a NaN or infinite
    /// coordinate (nothing is evaluated), [`Error::ThreadsUnavailable`].
    pub fn values(&self, points: &[[f32; 3]]) -> Result<Vec<f32>> {
        check_finite(points)?;
        self.batch(points, |p| self.value(widen(p)) as f32)
    }

    /// ∇χ at many points in input coordinates, as f32 (see [`ImplicitFunction::gradient`] and
    /// [`ImplicitFunction::values`], whose errors these are).
    pub fn gradients(&self, points: &[[f32; 3]]) -> Result<Vec<[f32; 3]>> {
        check_finite(points)?;
        self.batch(points, |p| self.gradient(widen(p)).map(|g| g as f32))
    }

    /// The centre of grid cell (i, j, k) of a `resolution`³ grid over the box from `min` to
    /// `max`: `min + (index + ½) × (max − min) / resolution` per axis, in f64. The grid
    /// functions evaluate χ at exactly these points.
    pub fn grid_point(
        min: [f64; 3],
        max: [f64; 3],
        resolution: usize,
        ijk: [usize; 3],
    ) -> [f64; 3] {
        let n = resolution as f64;
        [0, 1, 2].map(|a| min[a] + (ijk[a] as f64 + 0.5) * (max[a] - min[a]) / n)
    }

    /// χ sampled on a `resolution`³ grid over the bounding cube ([`ImplicitFunction::cube`]),
    /// at the centres of its cells as PoissonRecon's `--grid` samples (its default, not
    /// `--primalGrid`); see [`ImplicitFunction::sample_box`] for the order and the errors.
    pub fn sample_grid(&self, resolution: usize) -> Result<Vec<f32>> {
        let (origin, size) = self.cube();
        self.sample_box(origin, origin.map(|o| o + size), resolution)
    }

    /// χ sampled on a `resolution`³ grid over the box from `min` to `max` (input coordinates;
    /// a side may have zero length, and the box may reach outside the bounding cube), at the
    /// cell centres [`ImplicitFunction::grid_point`] gives, as f32.
    ///
    /// Order: z fastest, then y, then x: the value at cell (i, j, k) (x, y, z indices) is at
    /// `(i * resolution + j) * resolution + k`, i.e. NumPy's C order for an array indexed
    /// `[x][y][z]` of shape `(resolution, resolution, resolution)`. Each value is
    /// [`ImplicitFunction::value`] at its grid point, rounded to f32, whatever the thread count.
    ///
    /// Errors: [`Error::InvalidParameter`] (name "resolution") for a resolution of 0, above
    /// [`MAX_GRID_RESOLUTION`], or whose grid cannot be allocated; (name "box") for a box with
    /// a non-finite corner or with `min > max` on an axis; [`Error::ThreadsUnavailable`].
    pub fn sample_box(&self, min: [f64; 3], max: [f64; 3], resolution: usize) -> Result<Vec<f32>> {
        let count = grid_size(min, max, resolution)?;
        let mut values: Vec<f32> = Vec::new();
        if values.try_reserve_exact(count).is_err() {
            return Err(too_large(resolution));
        }
        values.resize(count, 0.0);
        self.fill_box(min, max, resolution, &mut values)?;
        Ok(values)
    }

    /// [`ImplicitFunction::sample_box`] into `out`, which holds `grid_size(min, max,
    /// resolution)?` values: all of them are written, or none (the one failure,
    /// [`Error::ThreadsUnavailable`], comes before any write).
    pub(crate) fn fill_box(
        &self,
        min: [f64; 3],
        max: [f64; 3],
        resolution: usize,
        out: &mut [f32],
    ) -> Result<()> {
        let fill = |(index, row): (usize, &mut [f32])| {
            // One (i, j) row of `resolution` values along z.
            let (i, j) = (index / resolution, index % resolution);
            for (k, v) in row.iter_mut().enumerate() {
                let p = Self::grid_point(min, max, resolution, [i, j, k]);
                *v = self.value(p) as f32;
            }
        };
        if out.len() < PARALLEL_BATCH {
            out.chunks_mut(resolution).enumerate().for_each(fill);
        } else {
            let workers = Workers::start(self.threads)?;
            workers
                .pool()
                .install(|| out.par_chunks_mut(resolution).enumerate().for_each(fill));
        }
        Ok(())
    }

    /// `f` at every point, in parallel for large batches.
    fn batch<T: Send>(
        &self,
        points: &[[f32; 3]],
        f: impl Fn([f32; 3]) -> T + Sync + Send,
    ) -> Result<Vec<T>> {
        if points.len() < PARALLEL_BATCH {
            return Ok(points.iter().map(|&p| f(p)).collect());
        }
        let workers = Workers::start(self.threads)?;
        Ok(workers.pool().install(|| {
            points
                .par_iter()
                .with_min_len(CHUNK)
                .map(|&p| f(p))
                .collect()
        }))
    }
}

/// The number of values of a `resolution`³ grid over the box from `min` to `max`, after the
/// checks [`ImplicitFunction::sample_box`] documents (all but the allocation's).
pub(crate) fn grid_size(min: [f64; 3], max: [f64; 3], resolution: usize) -> Result<usize> {
    if resolution == 0 || resolution > MAX_GRID_RESOLUTION {
        return Err(Error::InvalidParameter {
            name: "resolution",
            value: resolution.to_string(),
            expected: "1..=4096 (samples per axis)",
        });
    }
    if !(0..3).all(|a| min[a].is_finite() && max[a].is_finite() && min[a] <= max[a]) {
        return Err(Error::InvalidParameter {
            name: "box",
            value: format!("{min:?}..{max:?}"),
            expected: "finite corners with min <= max on every axis",
        });
    }
    // resolution <= 4096, so resolution³ < 2^36; on a 32-bit target it may still overflow.
    resolution
        .checked_pow(3)
        .filter(|&c| c.checked_mul(4).is_some_and(|b| b <= isize::MAX as usize))
        .ok_or_else(|| too_large(resolution))
}

fn too_large(resolution: usize) -> Error {
    Error::InvalidParameter {
        name: "resolution",
        value: resolution.to_string(),
        expected: "a grid of resolution³ floats that fits in memory",
    }
}

fn widen(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

fn check_finite(points: &[[f32; 3]]) -> Result<()> {
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(index) => Err(Error::NonFinitePosition { index }),
        None => Ok(()),
    }
}

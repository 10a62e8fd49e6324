//! Stage 2b — the samples' positional noise: how far they scatter about the surface they
//! sample, for a screening term that does not pull the solution onto that scatter
//! ([`crate::Params::screening_follows_noise`]).
//!
//! The samples (in the unit cube, in Morton order) are grouped by the cells of the depth at
//! which a cell of the surface holds about [`SAMPLES_PER_CELL`] of them (from the density
//! estimate's areas). In each cell with at least [`MIN_SAMPLES`] the **residual** is the RMS
//! distance of its samples from their least-squares quadric (a height field over their plane:
//! a smooth surface's curvature is fitted, not counted as noise), unbiased for the quadric's six
//! coefficients; r₁ is its median over the cells, r₂ the same in cells twice as wide.
//!
//! Noise adds the same σ² at every cell width; what the quadric leaves of the shape, s(h),
//! grows with the width (as h⁶ on a smooth surface, and at least doubling from h to 2h for
//! detail at the cells' scale). So with r₁² = σ² + s(h) and r₂² = σ² + s(2h),
//! σ² ≥ 2·r₁² − r₂², taken as the estimate (at least 0): r₁² when r₂ = r₁ (noise alone), 0 when
//! r₂² ≥ 2·r₁² (shape, or a shape the cells cannot resolve), and never more than the noise while
//! the shape's part at least doubles. Measured (`docs/benchmarks.md`, issue 16): exact samples
//! of a sphere, a torus and a box read 0; Gaussian noise reads 0.7–0.9 of its σ (the median of
//! the cells' residuals lies below their RMS).
//!
//! That reading needs cells that resolve the surface, so that what the quadric leaves is noise
//! and the shape's part grows from one width to the next. Where the samples are so sparse that
//! a cell of [`SAMPLES_PER_CELL`] of them spans a bend of the shape (CGAL's oni: 1,435 points,
//! cells an eighth of the cube wide), the quadric leaves shape at both widths, that part no
//! longer grows, and 2·r₁² − r₂² reads it as noise. What tells the two apart is whether the
//! quadric's residual has structure: in each wider cell a cubic (four more terms) is fitted
//! too, and F = (what the cubic explains more, per term) / (what it leaves, per degree of
//! freedom) is about 1 where the residual is noise (an F(4, n − 10) deviate) and large where it
//! is shape. When the wider cells' median F exceeds [`SHAPE_F`], the residuals are taken for
//! shape and the estimate is 0 (the screening is left at 2^D).

use crate::grid::{cell_runs, cuts_between_cells};
use crate::normals::{jacobi_eigen, scatter};
use glam::DVec3;
use rayon::prelude::*;

/// About how many samples a cell of the estimate's finer depth holds: enough for a quadric fit
/// to leave the noise over ten degrees of freedom, few enough for the cell to be small against
/// the surface's shape.
pub(crate) const SAMPLES_PER_CELL: f64 = 16.0;
/// The fewest samples in a cell that count towards the estimate (four more than a quadric's
/// six coefficients).
pub(crate) const MIN_SAMPLES: usize = 10;

/// The wider cells' median F (see the module documentation) above which their quadrics'
/// residuals are shape, not noise: about the 95th percentile of F(4, 50), so that a cell of
/// about 60 samples whose residual is noise exceeds it once in twenty and the median of such
/// cells lies far below it (an F(4, ν) deviate's median is about 0.84). Measured (issue 16,
/// docs/benchmarks.md): 0.87–1.01 on spheres and tori with Gaussian noise of σ 0.001–0.01,
/// 0.93 and 0.83 on the bunny's and the Buddha's laser scans; 3.8 on the lion, 11 on the oni,
/// 31 on the kitten.
pub(crate) const SHAPE_F: f64 = 2.6;

/// The terms of the cubic height field fitted beside the quadric in the wider cells.
const CUBIC_TERMS: usize = 10;

/// The samples' positional noise as [`estimate`] measured it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SampleNoise {
    /// The finer depth of the cells the samples were grouped by.
    pub(crate) depth: u32,
    /// The cells at that depth that counted.
    pub(crate) cells: usize,
    /// The median, over the cells of the next coarser depth, of how much more of the heights a
    /// cubic explains than noise would let it (F); above [`SHAPE_F`] the estimate is 0.
    pub(crate) shape_f: f64,
    /// The noise σ, in the unit cube's units: 0 for samples that lie on a smooth surface, where
    /// the residual grows with the cells (detail), where what the quadrics leave is shape a
    /// cubic explains (samples too sparse for the cells to resolve the surface), and when too
    /// few cells hold enough samples to tell.
    pub(crate) sigma: f64,
}

/// The noise of `positions` (unit cube, Morton order at a depth ≥ `max_depth`), grouped at the
/// depth that `areas` (each sample's share of the surface, as the density estimate gives it)
/// say holds [`SAMPLES_PER_CELL`] a cell, at most `max_depth`.
///
/// In three steps that add up across pieces of the cloud (the out-of-core path runs them slab
/// by slab, `outofcore/noise.rs`): the areas counted by the depth they give
/// ([`AreaDepths`]), the cells fitted at that depth and the next coarser ([`CellFits`]), and
/// σ from the fits' medians ([`from_medians`]).
pub(crate) fn estimate(positions: &[DVec3], areas: &[f64], max_depth: u32) -> SampleNoise {
    let mut depths = AreaDepths::new(max_depth);
    depths.count(areas.iter().copied());
    let Some(depth) = depths.median_depth() else {
        return SampleNoise::default();
    };
    let mut fits = CellFits::at(depth, positions, &|_, _| true);
    from_medians(
        depth,
        fits.fine.len(),
        median(&mut fits.fine),
        median(&mut fits.coarse),
        median(&mut fits.cubic_f),
    )
}

/// The depth whose cells hold about [`SAMPLES_PER_CELL`] samples of area `area`: their width
/// √(16·area) rounded to the nearest depth, within 2..=max(`max_depth`, 2). Never larger for a
/// larger area, so the depth of the median area is the median of the areas' depths.
fn depth_of_area(area: f64, max_depth: u32) -> u32 {
    let cell_width = (SAMPLES_PER_CELL * area).sqrt();
    (-cell_width.log2())
        .round()
        .clamp(2.0, max_depth.max(2) as f64) as u32
}

/// The samples' positive areas counted by the depth each gives ([`depth_of_area`]): what the
/// estimate's depth is read from, added up over any split of the samples.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct AreaDepths {
    max_depth: u32,
    /// How many areas give each depth, 0..=max(max_depth, 2).
    pub(crate) counts: Vec<u64>,
}

impl AreaDepths {
    /// No areas counted yet, for depths up to `max_depth`.
    pub(crate) fn new(max_depth: u32) -> Self {
        AreaDepths {
            max_depth,
            counts: vec![0; max_depth.max(2) as usize + 1],
        }
    }

    /// Counts `areas` (those not positive are not counted: a sample no surface was read for).
    pub(crate) fn count(&mut self, areas: impl Iterator<Item = f64>) {
        for area in areas.filter(|&a| a > 0.0) {
            self.counts[depth_of_area(area, self.max_depth) as usize] += 1;
        }
    }

    /// Adds `counts` counted elsewhere (by another piece of the cloud, for the same depth).
    pub(crate) fn add(&mut self, counts: &[u64]) {
        for (total, count) in self.counts.iter_mut().zip(counts) {
            *total += count;
        }
    }

    /// The depth of the median area (the upper of the two middle ones, as [`median`] takes
    /// it): with the areas in increasing order their depths do not increase, so it is the
    /// depth at that place counted from the finest; `None` when nothing was counted.
    pub(crate) fn median_depth(&self) -> Option<u32> {
        let total: u64 = self.counts.iter().sum();
        let place = total / 2;
        let mut passed = 0;
        for (depth, &count) in self.counts.iter().enumerate().rev() {
            passed += count;
            if passed > place {
                return Some(depth as u32);
            }
        }
        None
    }
}

/// What the cells at the estimate's two depths say: every fitted cell's residual at the finer
/// depth and at the coarser, and the coarser cells' F ([`QuadricFit`]), each list in the
/// samples' order; lists of pieces of the cloud are concatenated, since only their medians
/// are read.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct CellFits {
    pub(crate) fine: Vec<f64>,
    pub(crate) coarse: Vec<f64>,
    pub(crate) cubic_f: Vec<f64>,
}

impl CellFits {
    /// The fits of the cells of `depth` and `depth` − 1 that `owns` (a cell's depth and
    /// coordinates) takes, over `positions` (unit cube, Morton order at a finer depth).
    pub(crate) fn at(
        depth: u32,
        positions: &[DVec3],
        owns: &(impl Fn(u32, [i32; 3]) -> bool + Sync),
    ) -> Self {
        let fine = fit_by_cell(positions, depth, false, owns);
        let coarse = fit_by_cell(positions, depth - 1, true, owns);
        CellFits {
            fine: fine.iter().map(|fit| fit.residual).collect(),
            coarse: coarse.iter().map(|fit| fit.residual).collect(),
            cubic_f: coarse.iter().filter_map(|fit| fit.cubic_f).collect(),
        }
    }

    /// Appends `other`'s fits.
    pub(crate) fn extend(&mut self, other: CellFits) {
        self.fine.extend(other.fine);
        self.coarse.extend(other.coarse);
        self.cubic_f.extend(other.cubic_f);
    }
}

/// The estimate at `depth` from the medians of the finer cells' residuals (r₁, over `cells`
/// cells), the coarser cells' (r₂) and their F: σ = √(2·r₁² − r₂²) (at least 0), or 0 when
/// the median F says the residuals are shape ([`SHAPE_F`]); 0 with no F when a median is
/// missing (no cell held enough samples).
pub(crate) fn from_medians(
    depth: u32,
    cells: usize,
    r1: Option<f64>,
    r2: Option<f64>,
    shape_f: Option<f64>,
) -> SampleNoise {
    let (Some(r1), Some(r2), Some(shape_f)) = (r1, r2, shape_f) else {
        return SampleNoise {
            depth,
            cells,
            ..SampleNoise::default()
        };
    };
    let sigma = if shape_f <= SHAPE_F {
        (2.0 * r1 * r1 - r2 * r2).max(0.0).sqrt()
    } else {
        0.0
    };
    SampleNoise {
        depth,
        cells,
        shape_f,
        sigma,
    }
}

/// The median of `values` (the upper of the two middle ones for an even count), reordering
/// them; `None` when there are none.
pub(crate) fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let middle = values.len() / 2;
    let (_, &mut value, _) = values.select_nth_unstable_by(middle, f64::total_cmp);
    Some(value)
}

/// A cell's quadric ([`quadric_fit`]).
#[derive(Debug, Clone, Copy)]
struct QuadricFit {
    /// The samples' RMS distance from it, unbiased for its six coefficients.
    residual: f64,
    /// How much more of the heights a cubic explains than noise would let it (the F statistic
    /// of the cubic's four more terms); `None` when not asked for or for too few samples.
    cubic_f: Option<f64>,
}

/// The quadric of every cell of `depth` that `owns` takes and whose samples fix one, and with
/// `cubic` its F against a cubic, in parallel over pieces cut between cells (the same values
/// at any thread count).
fn fit_by_cell(
    positions: &[DVec3],
    depth: u32,
    cubic: bool,
    owns: &(impl Fn(u32, [i32; 3]) -> bool + Sync),
) -> Vec<QuadricFit> {
    let cuts = cuts_between_cells(positions, depth, 1 << 14);
    cuts.par_windows(2)
        .flat_map_iter(|piece| {
            let piece = &positions[piece[0]..piece[1]];
            cell_runs(piece, depth)
                .filter(|(cell, _)| owns(depth, *cell))
                .filter_map(|(_, run)| quadric_fit(&piece[run], cubic))
        })
        .collect()
}

/// The least-squares quadric height field of `points` over their plane (w = a + b·u + c·v +
/// d·u² + e·u·v + f·v² in the frame of their covariance's eigenvectors): the RMS residual,
/// unbiased (squares over n − 6), and with `cubic` the F of a cubic's four more terms when
/// there are more than 14 points and they fix a cubic; `None` for fewer than [`MIN_SAMPLES`]
/// points or points that cannot fix a quadric (all on one or two lines, as across the scan
/// lines of a range scan).
fn quadric_fit(points: &[DVec3], cubic: bool) -> Option<QuadricFit> {
    let n = points.len();
    if n < MIN_SAMPLES {
        return None;
    }
    // The plane's axes (the two largest eigenvectors) scaled to the points' extent along them,
    // for a well-conditioned system; the height along the normal.
    let (mean, scatter_matrix) = scatter(points);
    let (_, [normal, a, b]) = jacobi_eigen(scatter_matrix);
    let extent = points
        .iter()
        .map(|p| (*p - mean).dot(a).abs().max((*p - mean).dot(b).abs()))
        .fold(0.0, f64::max);
    if extent <= 0.0 {
        return None;
    }
    // Each point's cubic terms (the quadric's six first) and height, once: both fits read them.
    let rows: Vec<([f64; CUBIC_TERMS], f64)> = points
        .iter()
        .map(|p| {
            let d = *p - mean;
            let (u, v) = (d.dot(b) / extent, d.dot(a) / extent);
            let terms = [
                1.0,
                u,
                v,
                u * u,
                u * v,
                v * v,
                u * u * u,
                u * u * v,
                u * v * v,
                v * v * v,
            ];
            (terms, d.dot(normal))
        })
        .collect();
    let quadric_squares = least_squares::<6>(&rows)?;
    let cubic_f = (cubic && n > CUBIC_TERMS + 4)
        .then(|| least_squares::<CUBIC_TERMS>(&rows))
        .flatten()
        .map(|cubic_squares| {
            let explained = (quadric_squares - cubic_squares).max(0.0) / (CUBIC_TERMS - 6) as f64;
            let left = cubic_squares / (n - CUBIC_TERMS) as f64;
            match (explained > 0.0, left > 0.0) {
                (_, true) => explained / left,
                (true, false) => f64::INFINITY,
                (false, false) => 0.0,
            }
        });
    Some(QuadricFit {
        residual: (quadric_squares / (n - 6) as f64).sqrt(),
        cubic_f,
    })
}

/// The least-squares fit of the heights by the first `K` terms of `rows` (the quadric's six or
/// all the cubic's ten): the sum of the squared residuals; `None` when the points do not fix
/// the terms.
fn least_squares<const K: usize>(rows: &[([f64; CUBIC_TERMS], f64)]) -> Option<f64> {
    let mut gram = [[0.0; K]; K];
    let mut rhs = [0.0; K];
    for (phi, w) in rows {
        for i in 0..K {
            rhs[i] += phi[i] * w;
            for j in 0..K {
                gram[i][j] += phi[i] * phi[j];
            }
        }
    }
    let coefficients = cholesky_solve(gram, rhs)?;
    Some(
        rows.iter()
            .map(|(phi, w)| {
                let fit: f64 = phi[..K].iter().zip(&coefficients).map(|(f, c)| f * c).sum();
                (w - fit) * (w - fit)
            })
            .sum(),
    )
}

/// x with `gram`·x = `rhs` for a symmetric positive definite `gram`, by Cholesky; `None` when a
/// pivot falls below 1e-9 of the largest diagonal entry (the points do not fix the terms).
fn cholesky_solve<const K: usize>(gram: [[f64; K]; K], rhs: [f64; K]) -> Option<[f64; K]> {
    let largest = (0..K).map(|i| gram[i][i]).fold(0.0, f64::max);
    let mut l = [[0.0; K]; K];
    for i in 0..K {
        for j in 0..=i {
            let sum = gram[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if sum <= 1e-9 * largest {
                    return None;
                }
                l[i][i] = sum.sqrt();
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    let mut y = [0.0; K];
    for i in 0..K {
        y[i] = (rhs[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0; K];
    for i in (0..K).rev() {
        x[i] = (y[i] - (i + 1..K).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{cell_of, morton_nested};

    /// `points` (in the unit cube) in Morton order at depth 16.
    fn sorted(mut points: Vec<DVec3>) -> Vec<DVec3> {
        points.sort_by_key(|p| morton_nested(cell_of(*p, 65536.0).map(|v| v as u32)));
        points
    }

    /// A small deterministic generator of standard normal deviates (Box–Muller over an LCG).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// `n` samples of the sphere of radius `r` about the cube's centre, each moved by `sigma`
    /// along every axis, with the area each stands for.
    fn sphere(n: usize, r: f64, sigma: f64) -> (Vec<DVec3>, Vec<f64>) {
        let mut normal = Normal(7);
        let points = (0..n)
            .map(|_| {
                let d = DVec3::new(normal.next(), normal.next(), normal.next()).normalize();
                let jitter = DVec3::new(normal.next(), normal.next(), normal.next()) * sigma;
                DVec3::splat(0.5) + d * r + jitter
            })
            .collect();
        let area = 4.0 * std::f64::consts::PI * r * r / n as f64;
        (sorted(points), vec![area; n])
    }

    #[test]
    fn exact_samples_of_a_curved_surface_read_no_noise() {
        let (points, areas) = sphere(100_000, 0.45, 0.0);
        let noise = estimate(&points, &areas, 10);
        assert!(noise.cells > 1000, "{noise:?}");
        // A plane through a cell's samples would leave the sphere's sag, about 1e-4 here.
        assert!(noise.sigma < 1e-7, "{noise:?}");
    }

    #[test]
    fn noisy_samples_read_their_noise() {
        for sigma in [2e-4, 1e-3] {
            let (points, areas) = sphere(100_000, 0.45, sigma);
            let noise = estimate(&points, &areas, 10);
            assert!(
                noise.sigma > 0.7 * sigma && noise.sigma < 1.1 * sigma,
                "σ {sigma}: {noise:?}"
            );
        }
    }

    #[test]
    fn detail_as_wide_as_the_cells_is_shape_not_noise() {
        // A plane rippled with a wavelength of four fine cells (depth 7: cells of 1/128), its
        // amplitude 1e-3: a quadric follows a quarter of a ripple in a fine cell closely (a
        // residual of 6.6e-6, which alone would read as noise) and half a ripple in a coarse
        // cell less so: the residual grows with the cells, and is shape, not noise.
        let n = 400;
        let wave = 4.0 / 128.0;
        let mut points = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (
                    0.2 + 0.6 * i as f64 / n as f64,
                    0.2 + 0.6 * j as f64 / n as f64,
                );
                let ripple = 1e-3 * (std::f64::consts::TAU * x / wave).sin();
                points.push(DVec3::new(x, y, 0.5 + ripple));
            }
        }
        let area = 0.36 / (n * n) as f64;
        let noise = estimate(&sorted(points), &vec![area; n * n], 10);
        assert_eq!(noise.depth, 7, "{noise:?}");
        assert!(noise.sigma < 1e-6, "{noise:?}");
    }

    #[test]
    fn a_cubic_tells_noise_from_shape() {
        // Noise: what the quadric leaves is an F(4, n − 10) deviate's worth for the cubic, a
        // median about 0.84 (cells of about 60 samples).
        let (points, areas) = sphere(100_000, 0.45, 1e-3);
        let noise = estimate(&points, &areas, 10);
        assert!(noise.shape_f > 0.5 && noise.shape_f < 1.5, "{noise:?}");
        assert!(noise.sigma > 0.0, "{noise:?}");
        // Shape: 1,500 exact samples of a sphere rippled by 4 % of its radius, a cell of 16
        // of them spanning about half a ripple; the cubic follows much of what the quadric
        // leaves.
        let mut normal = Normal(11);
        let points: Vec<DVec3> = (0..1_500)
            .map(|_| {
                let d = DVec3::new(normal.next(), normal.next(), normal.next()).normalize();
                let ripple = 1.0 + 0.04 * (8.0 * d.x).sin() * (8.0 * d.y).sin() * (8.0 * d.z).cos();
                DVec3::splat(0.5) + d * 0.4 * ripple
            })
            .collect();
        let area = 4.0 * std::f64::consts::PI * 0.16 / 1_500.0;
        let noise = estimate(&sorted(points), &vec![area; 1_500], 8);
        assert!(
            noise.shape_f > 2.0 * SHAPE_F && noise.sigma == 0.0,
            "{noise:?}"
        );
    }

    #[test]
    fn samples_on_planes_read_exactly_zero_and_few_samples_read_nothing() {
        // The faces of a box: every cell within a face is exact, the creases are a minority.
        let mut points = Vec::new();
        for i in 0..200 {
            for j in 0..200 {
                let (u, v) = (0.3 + 0.4 * i as f64 / 199.0, 0.3 + 0.4 * j as f64 / 199.0);
                points.extend([DVec3::new(u, v, 0.3), DVec3::new(u, v, 0.7)]);
                points.extend([DVec3::new(u, 0.3, v), DVec3::new(u, 0.7, v)]);
                points.extend([DVec3::new(0.3, u, v), DVec3::new(0.7, u, v)]);
            }
        }
        let n = points.len();
        let noise = estimate(&sorted(points), &vec![0.96 / n as f64; n], 10);
        assert!(noise.cells > 100 && noise.sigma < 1e-12, "{noise:?}");

        let few = sorted(vec![DVec3::splat(0.25), DVec3::splat(0.75)]);
        assert_eq!(estimate(&few, &[0.1, 0.1], 10).sigma, 0.0);
        assert_eq!(estimate(&[], &[], 10), SampleNoise::default());
    }
}

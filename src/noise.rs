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

/// The samples' positional noise as [`estimate`] measured it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SampleNoise {
    /// The finer depth of the cells the samples were grouped by.
    pub(crate) depth: u32,
    /// The cells at that depth that counted.
    pub(crate) cells: usize,
    /// The noise σ, in the unit cube's units: 0 for samples that lie on a smooth surface, where
    /// the residual grows with the cells (detail, or a shape the cells do not resolve), and
    /// when too few cells hold enough samples to tell.
    pub(crate) sigma: f64,
}

/// The noise of `positions` (unit cube, Morton order at a depth ≥ `max_depth`), grouped at the
/// depth that `areas` (each sample's share of the surface, as the density estimate gives it)
/// say holds [`SAMPLES_PER_CELL`] a cell, at most `max_depth`.
pub(crate) fn estimate(positions: &[DVec3], areas: &[f64], max_depth: u32) -> SampleNoise {
    let mut positive: Vec<f64> = areas.iter().copied().filter(|&a| a > 0.0).collect();
    let Some(median_area) = median(&mut positive) else {
        return SampleNoise::default();
    };
    let cell_width = (SAMPLES_PER_CELL * median_area).sqrt();
    let depth = (-cell_width.log2())
        .round()
        .clamp(2.0, max_depth.max(2) as f64) as u32;
    let mut fine = residual_by_cell(positions, depth);
    let mut coarse = residual_by_cell(positions, depth - 1);
    let cells = fine.len();
    let (Some(r1), Some(r2)) = (median(&mut fine), median(&mut coarse)) else {
        return SampleNoise {
            depth,
            cells,
            sigma: 0.0,
        };
    };
    SampleNoise {
        depth,
        cells,
        sigma: (2.0 * r1 * r1 - r2 * r2).max(0.0).sqrt(),
    }
}

/// The median of `values` (the upper of the two middle ones for an even count), reordering
/// them; `None` when there are none.
fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let middle = values.len() / 2;
    let (_, &mut value, _) = values.select_nth_unstable_by(middle, f64::total_cmp);
    Some(value)
}

/// The quadric residual of every cell of `depth` whose samples fix one, in parallel over pieces
/// cut between cells (the same values at any thread count).
fn residual_by_cell(positions: &[DVec3], depth: u32) -> Vec<f64> {
    let cuts = cuts_between_cells(positions, depth, 1 << 14);
    cuts.par_windows(2)
        .flat_map_iter(|piece| {
            let piece = &positions[piece[0]..piece[1]];
            cell_runs(piece, depth).filter_map(|(_, run)| quadric_residual(&piece[run]))
        })
        .collect()
}

/// The RMS residual of `points` from their least-squares quadric height field over their plane
/// (w = a + b·u + c·v + d·u² + e·u·v + f·v² in the frame of their covariance's eigenvectors),
/// unbiased (squares over n − 6); `None` for fewer than [`MIN_SAMPLES`] points or points that
/// cannot fix a quadric (all on one or two lines, as across the scan lines of a range scan).
fn quadric_residual(points: &[DVec3]) -> Option<f64> {
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
    // Each point's quadric terms and height, once: the normal equations and the residual
    // both read them.
    let rows: Vec<([f64; 6], f64)> = points
        .iter()
        .map(|p| {
            let d = *p - mean;
            let (u, v) = (d.dot(b) / extent, d.dot(a) / extent);
            ([1.0, u, v, u * u, u * v, v * v], d.dot(normal))
        })
        .collect();
    let mut gram = [[0.0; 6]; 6];
    let mut rhs = [0.0; 6];
    for (phi, w) in &rows {
        for i in 0..6 {
            rhs[i] += phi[i] * w;
            for j in 0..6 {
                gram[i][j] += phi[i] * phi[j];
            }
        }
    }
    let coefficients = cholesky_solve(gram, rhs)?;
    let squares: f64 = rows
        .iter()
        .map(|(phi, w)| {
            let fit: f64 = phi.iter().zip(&coefficients).map(|(f, c)| f * c).sum();
            (w - fit) * (w - fit)
        })
        .sum();
    Some((squares / (n - 6) as f64).sqrt())
}

/// x with `gram`·x = `rhs` for a symmetric positive definite `gram`, by Cholesky; `None` when a
/// pivot falls below 1e-9 of the largest diagonal entry (the points do not fix the terms).
fn cholesky_solve(gram: [[f64; 6]; 6], rhs: [f64; 6]) -> Option<[f64; 6]> {
    let largest = (0..6).map(|i| gram[i][i]).fold(0.0, f64::max);
    let mut l = [[0.0; 6]; 6];
    for i in 0..6 {
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
    let mut y = [0.0; 6];
    for i in 0..6 {
        y[i] = (rhs[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0; 6];
    for i in (0..6).rev() {
        x[i] = (y[i] - (i + 1..6).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
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

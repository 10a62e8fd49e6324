//! Stage 2b — the samples' positional noise: how far they scatter across the surface they
//! sample, for a screening term that does not pull the solution onto that scatter
//! ([`crate::Params::screening_follows_noise`]).
//!
//! The samples (in the unit cube, in Morton order) are grouped by the cells of the depth at
//! which a cell of the surface holds about [`SAMPLES_PER_CELL`] of them (from the density
//! estimate's areas). In each cell with at least [`MIN_SAMPLES`] the **thickness** is the RMS
//! distance of its samples from their least-squares plane (the square root of the smallest
//! eigenvalue of their covariance), and its median over the cells is taken, at that depth (t₁,
//! cells of width h) and one coarser (t₂, width 2h). The median ignores the minority of cells
//! across a crease or holding two sheets.
//!
//! A thickness holds two parts: the noise σ, the same in a cell of any width, and the sag of a
//! curved surface across the cell, which grows as the square of the width (about r²/(7R) for a
//! disc of radius r on a sphere of radius R): t² ≈ σ² + c·h⁴. So t₁² = σ² + c·h⁴ and t₂² = σ² +
//! 16·c·h⁴ give σ² = (16·t₁² − t₂²) / 15: exact samples of a curved surface read 0 (a sphere's
//! t₂ is 4·t₁), noisy ones σ (t₂ ≈ t₁). Measured on 100k samples of a sphere of radius 1 in a
//! cube of width 2.2 (`docs/benchmarks.md`, issue 16): exact 0; Gaussian noise of 0.001 and
//! 0.005 per coordinate read 3.6e-4 and 1.56e-3 of the cube (0.0008 and 0.0034 of the sphere's
//! units: a plane fit through 16 samples takes some of their scatter with it).

use crate::grid::{cell_of, cuts_between_cells};
use crate::normals::jacobi_eigen;
use glam::DVec3;
use rayon::prelude::*;

/// About how many samples a cell of the estimate's finer depth holds: enough for a plane fit
/// to see the scatter, few enough for the cell to be small against the surface's curvature.
pub(crate) const SAMPLES_PER_CELL: f64 = 16.0;
/// The fewest samples in a cell that count towards the estimate.
pub(crate) const MIN_SAMPLES: usize = 8;

/// The samples' positional noise as [`estimate`] measured it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SampleNoise {
    /// The finer depth of the cells the samples were grouped by.
    pub(crate) depth: u32,
    /// The cells at that depth with enough samples to count.
    pub(crate) cells: usize,
    /// The noise σ, in the unit cube's units: 0 for samples that lie on a smooth surface, and
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
    let mut fine = thickness_by_cell(positions, depth);
    let mut coarse = thickness_by_cell(positions, depth - 1);
    let cells = fine.len();
    let (Some(t1), Some(t2)) = (median(&mut fine), median(&mut coarse)) else {
        return SampleNoise {
            depth,
            cells,
            sigma: 0.0,
        };
    };
    SampleNoise {
        depth,
        cells,
        sigma: ((16.0 * t1 * t1 - t2 * t2) / 15.0).max(0.0).sqrt(),
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

/// The thickness of every cell of `depth` holding at least [`MIN_SAMPLES`] samples, in
/// parallel over pieces cut between cells (the same values at any thread count).
fn thickness_by_cell(positions: &[DVec3], depth: u32) -> Vec<f64> {
    let inv_h = (depth as f64).exp2();
    let cell = |s: usize| cell_of(positions[s], inv_h);
    let cuts = cuts_between_cells(positions, depth, 1 << 14);
    cuts.par_windows(2)
        .flat_map_iter(|piece| {
            let mut out = Vec::new();
            let mut s = piece[0];
            while s < piece[1] {
                let start = s;
                let here = cell(s);
                while s < piece[1] && cell(s) == here {
                    s += 1;
                }
                if s - start >= MIN_SAMPLES {
                    out.push(plane_thickness(&positions[start..s]));
                }
            }
            out.into_iter()
        })
        .collect()
}

/// The RMS distance of `points` from their least-squares plane.
fn plane_thickness(points: &[DVec3]) -> f64 {
    let n = points.len() as f64;
    let mean = points.iter().copied().sum::<DVec3>() / n;
    let mut covariance = [[0.0; 3]; 3];
    for p in points {
        let d = (*p - mean).to_array();
        for (i, row) in covariance.iter_mut().enumerate() {
            for (j, entry) in row.iter_mut().enumerate() {
                *entry += d[i] * d[j] / n;
            }
        }
    }
    let (values, _) = jacobi_eigen(covariance);
    values[0].max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::morton_nested;

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
        // The plane fits alone read the sphere's sag; the two depths take it out.
        let sag = thickness_by_cell(&points, noise.depth);
        assert!(sag.iter().any(|&t| t > 1e-6));
        assert!(
            noise.sigma < 0.1 * median(&mut sag.clone()).unwrap(),
            "{noise:?}"
        );
    }

    #[test]
    fn noisy_samples_read_their_noise() {
        for sigma in [2e-4, 1e-3] {
            let (points, areas) = sphere(100_000, 0.45, sigma);
            let noise = estimate(&points, &areas, 10);
            // A plane through 16 samples takes some of their scatter (3 of 16 degrees of
            // freedom), and the median of a thickness lies below its RMS.
            assert!(
                noise.sigma > 0.6 * sigma && noise.sigma < 1.1 * sigma,
                "σ {sigma}: {noise:?}"
            );
        }
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

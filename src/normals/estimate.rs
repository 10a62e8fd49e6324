//! Normals by principal component analysis of each point's neighbourhood.
//!
//! The neighbourhood of point i is i itself and its k nearest neighbours. Its covariance
//! C = Σ (p − p̄)(p − p̄)ᵀ (p̄ their mean; f64 throughout) has eigenvalues λ₀ ≤ λ₁ ≤ λ₂; the
//! least-squares plane through the neighbourhood has the normal e₀, the eigenvector of λ₀
//! (Hoppe et al. 1992, "Surface reconstruction from unorganized points", §3.2). Its sign is
//! arbitrary here; `orient.rs` chooses it.
//!
//! The eigenvectors come from cyclic Jacobi rotations on the 3×3 matrix: accurate to a few ulps
//! of ‖C‖ whatever the eigenvalue gaps, and for repeated eigenvalues still an orthonormal basis,
//! so never NaN. Each point's result depends on its own neighbourhood only (and, for the few
//! ambiguous planes `sheets.rs` revisits, on its neighbours' first fits).
//!
//! Where the neighbourhood holds two sheets of the surface, the plane through all of it is
//! wrong; `sheets.rs` finds that case from the same gathered points and replaces e₀ by the
//! normal of two parallel planes fitted to the two sheets.
//!
//! A neighbourhood whose points coincide (C = 0) or lie on one line (λ₁ ≤ [`PLANE_RATIO`] · λ₂)
//! defines no plane. Such a point is marked; `fill_undefined` then gives it the normal of its
//! nearest graph neighbour (kNN in either direction) that has one, in synchronous rounds (each
//! round reads only the previous round's normals), so the result is deterministic. Points with no
//! defined normal anywhere in reach keep the Jacobi vector (finite, unit, deterministic).

use super::neighbors::Neighbors;
use super::sheets::{self, Sheets};
use super::{StepProgress, BATCH};
use crate::error::Result;
use glam::DVec3;
use rayon::prelude::*;

/// A neighbourhood defines a plane when its middle eigenvalue is above this fraction of its
/// largest. f32 coordinates put rounding noise of about 1e-14 relative into collinear
/// neighbourhoods and Jacobi's error is about 1e-16 · ‖C‖; a neighbourhood that is spread in
/// two directions at all is many orders above this.
pub(super) const PLANE_RATIO: f64 = 1e-8;

/// A fitted normal (unit, f64) and whether the neighbourhood defines it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Fit {
    pub(super) normal: DVec3,
    pub(super) defined: bool,
}

/// The PCA normal of every point's neighbourhood (point itself + its neighbours), refined where
/// the neighbourhood holds two sheets (see `sheets.rs`), in `pool`, [`BATCH`] points at a time,
/// with `progress(fraction done)` called on the calling thread after each batch (it may stop the
/// work). Returns the fits, which neighbours lie on another sheet, and the points whose PCA
/// plane is ambiguous (for `sheets::revisit_ambiguous`), in index order.
pub(super) fn fit_planes(
    positions: &[DVec3],
    neighbors: &Neighbors,
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<(Vec<Fit>, Sheets, Vec<u32>)> {
    let n = positions.len();
    let mut fits = Vec::with_capacity(n);
    let mut sheets = Sheets::none(n, neighbors.k());
    let mut ambiguous = Vec::new();
    let batches = n.div_ceil(BATCH);
    let mut rows = sheets.rows_mut();
    for batch in 0..batches {
        let points = batch * BATCH..((batch + 1) * BATCH).min(n);
        let mut words: Vec<&mut [u64]> = rows.by_ref().take(points.len()).collect();
        let results: Vec<(Fit, bool)> = pool.install(|| {
            points
                .clone()
                .into_par_iter()
                .zip(words.par_iter_mut())
                .with_min_len(256)
                .map_init(
                    || {
                        (
                            sheets::Scratch::default(),
                            Vec::with_capacity(neighbors.k() + 1),
                        )
                    },
                    |(scratch, rel), (i, bits)| {
                        fit_plane(positions, neighbors, i, rel, scratch, bits)
                    },
                )
                .collect()
        });
        for (at, (fit, unclear)) in results.into_iter().enumerate() {
            if unclear {
                ambiguous.push((points.start + at) as u32);
            }
            fits.push(fit);
        }
        progress((batch + 1) as f32 / batches as f32)?;
    }
    drop(rows);
    Ok((fits, sheets, ambiguous))
}

/// The PCA normal of point `i`'s neighbourhood, or the normal of the two sheets it holds (then
/// `bits` marks the neighbours across); and whether the PCA plane is ambiguous and the
/// neighbourhood was not found to hold two sheets.
fn fit_plane(
    positions: &[DVec3],
    neighbors: &Neighbors,
    i: usize,
    rel: &mut Vec<DVec3>,
    scratch: &mut sheets::Scratch,
    bits: &mut [u64],
) -> (Fit, bool) {
    // Relative to the point itself: the covariance about the mean is the same, with less
    // cancellation far from the origin.
    sheets::offsets_around(i, positions, neighbors, rel);
    let (_, c) = scatter(rel);
    let (values, vectors) = jacobi_eigen(c);
    let defined = values[2] > 0.0 && values[1] > PLANE_RATIO * values[2];
    if !defined {
        return (
            Fit {
                normal: vectors[0],
                defined,
            },
            false,
        );
    }
    if let Some(two) = sheets::two_sheets(rel, vectors[0], scratch) {
        sheets::mark_across(scratch, bits);
        return (
            Fit {
                normal: two.normal,
                defined,
            },
            false,
        );
    }
    (
        Fit {
            normal: vectors[0],
            defined,
        },
        values[0] > sheets::AMBIGUOUS * values[1],
    )
}

/// Gives every point without a defined normal the normal of its nearest graph neighbour that
/// has one, round by round (graph neighbours: its own k nearest and the points that count it
/// among theirs, so that a stack of more than k duplicates still reaches the surface around
/// it; nearest by (squared distance, index)). Returns how many points are still undefined.
pub(super) fn fill_undefined(
    positions: &[DVec3],
    fits: &mut [Fit],
    neighbors: &Neighbors,
) -> usize {
    let mut pending: Vec<usize> = (0..fits.len()).filter(|&i| !fits[i].defined).collect();
    if pending.is_empty() {
        return 0;
    }
    // The points that count each point among their neighbours (CSR, by index).
    let n = fits.len();
    let mut start = vec![0u32; n + 1];
    for row in neighbors.rows() {
        for &j in row {
            start[j as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut next = start.clone();
    let mut reverse = vec![0u32; n * neighbors.k()];
    for (i, row) in neighbors.rows().enumerate() {
        for &j in row {
            reverse[next[j as usize] as usize] = i as u32;
            next[j as usize] += 1;
        }
    }
    loop {
        let found: Vec<(usize, DVec3)> = pending
            .iter()
            .filter_map(|&i| {
                let around = &reverse[start[i] as usize..start[i + 1] as usize];
                neighbors
                    .of(i)
                    .iter()
                    .chain(around)
                    .map(|&j| j as usize)
                    .filter(|&j| fits[j].defined)
                    .map(|j| ((positions[j] - positions[i]).length_squared(), j))
                    .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                    .map(|(_, j)| (i, fits[j].normal))
            })
            .collect();
        if found.is_empty() {
            return pending.len();
        }
        for &(i, normal) in &found {
            fits[i] = Fit {
                normal,
                defined: true,
            };
        }
        pending.retain(|&i| !fits[i].defined);
    }
}

/// The mean of `points` and their scatter matrix about it, Σ (p − mean)(p − mean)ᵀ (the
/// covariance times their count): the plane fits' input, here and in the noise estimate.
pub(crate) fn scatter(points: &[DVec3]) -> (DVec3, [[f64; 3]; 3]) {
    let mean = points.iter().fold(DVec3::ZERO, |s, &p| s + p) / points.len() as f64;
    let mut c = [[0.0f64; 3]; 3];
    for p in points {
        let d = *p - mean;
        for (a, row) in c.iter_mut().enumerate() {
            for (b, entry) in row.iter_mut().enumerate().skip(a) {
                *entry += d[a] * d[b];
            }
        }
    }
    (c[1][0], c[2][0], c[2][1]) = (c[0][1], c[0][2], c[1][2]);
    (mean, c)
}

/// Eigenvalues (ascending) and unit eigenvectors of the symmetric matrix `a`, by cyclic Jacobi
/// rotations (Golub & Van Loan §8.5), to full f64 accuracy.
pub(crate) fn jacobi_eigen(mut a: [[f64; 3]; 3]) -> ([f64; 3], [DVec3; 3]) {
    // Columns of v are the eigenvectors.
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..50 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off == 0.0 || off <= 1e-36 * diag {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            let apq = a[p][q];
            if apq == 0.0 {
                continue;
            }
            // The rotation in the (p, q) plane that zeroes a[p][q].
            let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
            let t = if theta.abs() > 1e150 {
                0.5 / theta
            } else {
                theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            let r = 3 - p - q;
            let (app, aqq, arp, arq) = (a[p][p], a[q][q], a[r][p], a[r][q]);
            a[p][p] = app - t * apq;
            a[q][q] = aqq + t * apq;
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            a[r][p] = c * arp - s * arq;
            a[p][r] = a[r][p];
            a[r][q] = s * arp + c * arq;
            a[q][r] = a[r][q];
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    // Ascending eigenvalue; equal values keep their column order (a stable sort).
    order.sort_by(|&x, &y| a[x][x].total_cmp(&a[y][y]));
    let values = order.map(|i| a[i][i]);
    let vectors = order.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize());
    (values, vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat_vec(a: &[[f64; 3]; 3], x: DVec3) -> DVec3 {
        DVec3::new(
            a[0][0] * x.x + a[0][1] * x.y + a[0][2] * x.z,
            a[1][0] * x.x + a[1][1] * x.y + a[1][2] * x.z,
            a[2][0] * x.x + a[2][1] * x.y + a[2][2] * x.z,
        )
    }

    /// A = Q diag(λ) Qᵀ for a rotation Q.
    fn compose(values: [f64; 3], q: [DVec3; 3]) -> [[f64; 3]; 3] {
        let mut a = [[0.0; 3]; 3];
        for (l, v) in values.iter().zip(q.iter()) {
            for r in 0..3 {
                for c in 0..3 {
                    a[r][c] += l * v[r] * v[c];
                }
            }
        }
        a
    }

    #[test]
    fn jacobi_recovers_known_eigenpairs_including_repeated_and_zero_values() {
        let e0 = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let e1 = DVec3::new(2.0, 1.0, -2.0) / 3.0;
        let e2 = e0.cross(e1);
        for values in [
            [1e-3, 0.5, 2.0],
            [0.0, 1.0, 1.0],
            [1e-12, 1e-12, 7.0],
            [3.0, 3.0, 3.0],
            [0.0, 0.0, 0.0],
            [1e-20, 1.0, 1e6],
        ] {
            let a = compose(values, [e0, e1, e2]);
            let (got, vectors) = jacobi_eigen(a);
            let scale = values[2].max(1e-300);
            for i in 0..3 {
                assert!(
                    (got[i] - values[i]).abs() <= 1e-13 * scale,
                    "{values:?}: eigenvalue {i} = {}",
                    got[i]
                );
                let v = vectors[i];
                assert!((v.length() - 1.0).abs() < 1e-14 && v.is_finite());
                let residual = (mat_vec(&a, v) - got[i] * v).length();
                assert!(residual <= 1e-13 * scale, "{values:?}: residual {residual}");
            }
            if values[1] - values[0] > 1e-6 * scale {
                assert!(vectors[0].dot(e0).abs() > 1.0 - 1e-12, "{values:?}");
            }
        }
    }
}

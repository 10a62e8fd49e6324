//! Two sheets of the surface in one neighbourhood.
//!
//! Where two sheets of the surface come closer than a neighbourhood (the two faces of a thin
//! plate or shell, two bodies a small gap apart, the walls of a narrow slot), a point's k
//! nearest neighbours hold points of both. The plane through all of them is then wrong (tilted,
//! or lying across the sheets when their distance is near the neighbourhood's radius: measured
//! on a 2 × 2 plate 0.02 thick, 0.7 radii of a 20-neighbourhood, 60,000 points, 51 % of the PCA
//! normals are more than 25° off, 7.7 % with the split below), and the graph edges between the
//! sheets mislead the orientation: they lie nearly in both tangent planes, so propagation
//! carries the sign straight across, and one sheet comes out with the other's orientation
//! (measured: half the points of that plate, or of a hollow ball with a wall half a radius
//! thick, flipped).
//!
//! The model: the neighbourhood is either one sheet or two parallel ones. For a direction u,
//! the offsets s_m = (p_m − p_i)·u of the neighbourhood's points are split into two groups at
//! the best place in sorted order (1-D two-means: the split with the least within-group sum of
//! squares W, exact over all k splits by prefix sums); two sheets show as a split with W below
//! [`SPLIT_RATIO`] of the total sum of squares T about the mean (one plane with noise gives
//! W/T ≈ 1 − 2/π ≈ 0.36, a curved cap or a uniform spread 0.25, two parallel planes their
//! noise over their distance, squared). The direction is refined by fitting two parallel planes
//! to the two groups (the smallest eigenvector of the sum of the groups' covariances, each about
//! its own mean, by two steps of inverse iteration from u) and measuring W/T of the same two
//! groups along it (grouping again along it when that is close, below [`REGROUP_BELOW`]).
//! Accepted when W/T < [`SPLIT_RATIO`] and the groups' mean offsets are at least
//! [`MIN_SEPARATION`] neighbourhood radii apart: the point's normal becomes the two planes'
//! normal, and the neighbours in the other group are marked as lying across.
//!
//! Start directions: the PCA normal, for every point (two sheets well inside the neighbourhood
//! leave it nearly right); and, when the PCA plane is ambiguous (λ₀ > [`AMBIGUOUS`] λ₁, as when
//! the sheets' distance nears the radius and the spread across them rivals the spread along
//! them), the dominant direction of the neighbours' own PCA normals (the largest eigenvector of
//! Σ n_j n_jᵀ: the neighbours' fits are tilted at random about the true normal, so their
//! direction tensor finds it). The second start reads only the first pass's normals, so the
//! result does not depend on the order of the work.

use super::estimate::{jacobi_eigen, Fit};
use super::neighbors::Neighbors;
use super::{StepProgress, BATCH};
use crate::error::Result;
use glam::DVec3;
use rayon::prelude::*;

/// A split with a within-group sum of squares below this fraction of the total is two sheets
/// (see the module documentation).
pub(super) const SPLIT_RATIO: f64 = 0.1;

/// Splits below this ratio are refined by a two-plane fit before they are judged: a tilted start
/// direction smears both groups (measured in a prototype on a 30,000-point hollow ball with a
/// wall 0.4 neighbourhood radii thick: 6 % of the points split at W/T 0.17–0.37 along their PCA
/// normal, while along the true normal their W/T is below 0.01).
const REFINE_BELOW: f64 = 0.35;

/// Refined splits between [`SPLIT_RATIO`] and this are grouped again along the refined
/// direction (measured on a hollow ball with a wall half a neighbourhood radius thick, sampled
/// with a 10× density contrast: 97.6 % of the normals outward without, 99.3 % with).
const REGROUP_BELOW: f64 = 0.2;

/// Two groups closer than this fraction of the neighbourhood's radius are one sheet.
const MIN_SEPARATION: f64 = 0.05;

/// A PCA plane is ambiguous when its smallest eigenvalue exceeds this fraction of the middle
/// one; then the neighbours' normals are tried as a second start direction.
pub(super) const AMBIGUOUS: f64 = 0.2;

/// Which neighbours of each point lie on another sheet than the point: bit `rank` of the
/// point's words.
#[derive(Debug, Clone)]
pub(super) struct Sheets {
    words: usize,
    across: Vec<u64>,
    /// Bit i: whether point i has any neighbour across (a compact index for `edge_across`).
    any: Vec<u64>,
}

impl Sheets {
    /// No neighbour of any of `n` points (with `k` neighbours each) lies across.
    pub(super) fn none(n: usize, k: usize) -> Sheets {
        let words = k.div_ceil(64);
        Sheets {
            words,
            across: vec![0; n * words],
            any: vec![0; n.div_ceil(64)],
        }
    }

    /// Every point's words, in point order, to be written in parallel.
    pub(super) fn rows_mut(&mut self) -> std::slice::ChunksExactMut<'_, u64> {
        self.across.chunks_exact_mut(self.words)
    }

    /// Whether any neighbour of point `i` lies on another sheet.
    pub(super) fn any(&self, i: usize) -> bool {
        self.any[i / 64] >> (i % 64) & 1 == 1
    }

    /// Fills the index of points with any neighbour across; called once the words are written.
    pub(super) fn index(&mut self) {
        for (i, words) in self.across.chunks_exact(self.words).enumerate() {
            if words.iter().any(|&w| w != 0) {
                self.any[i / 64] |= 1 << (i % 64);
            }
        }
    }

    /// Whether neighbour `rank` of point `i` lies on another sheet than `i`.
    pub(super) fn across(&self, i: usize, rank: usize) -> bool {
        self.across[i * self.words + rank / 64] >> (rank % 64) & 1 == 1
    }

    /// Whether the kNN edge from `i` to its neighbour of rank `rank` joins two sheets, as seen
    /// from either end.
    pub(super) fn edge_across(&self, neighbors: &Neighbors, i: usize, rank: usize) -> bool {
        if self.any(i) && self.across(i, rank) {
            return true;
        }
        let j = neighbors.of(i)[rank] as usize;
        self.any(j)
            && neighbors
                .of(j)
                .iter()
                .position(|&x| x as usize == i)
                .is_some_and(|back| self.across(j, back))
    }
}

/// Scratch space for one neighbourhood.
#[derive(Debug, Default)]
pub(super) struct Scratch {
    keys: Vec<u64>,
    offsets: Vec<f64>,
    same: Vec<bool>,
    trial: Vec<bool>,
}

/// A neighbourhood found to hold two sheets.
pub(super) struct TwoSheets {
    /// The two planes' unit normal (sign arbitrary).
    pub(super) normal: DVec3,
}

/// 1/c for the group sizes of neighbourhoods up to 64 points.
const INVERSE: [f64; 65] = {
    let mut table = [0.0; 65];
    let mut c = 1;
    while c < 65 {
        table[c] = 1.0 / c as f64;
        c += 1;
    }
    table
};

/// The best split of the offsets of `rel` along `u` into two groups (written to `same`: whether
/// each point is in the group of point 0), and its W/T (1 when the offsets do not vary).
fn split(
    rel: &[DVec3],
    u: DVec3,
    keys: &mut Vec<u64>,
    offsets: &mut Vec<f64>,
    same: &mut [bool],
) -> f64 {
    let m = rel.len();
    // Sort keys: the offset as f32 bits mapped to an order-preserving integer, then the index,
    // so that the order depends on the values alone (ties by index).
    keys.clear();
    offsets.clear();
    let (mut total, mut total_sq) = (0.0, 0.0);
    for (at, x) in rel.iter().enumerate() {
        let o = x.dot(u);
        offsets.push(o);
        total += o;
        total_sq += o * o;
        let bits = (o as f32).to_bits();
        let ordered = if bits >> 31 == 1 {
            !bits
        } else {
            bits | 0x8000_0000
        };
        keys.push(((ordered as u64) << 32) | at as u64);
    }
    keys.sort_unstable();
    let t = total_sq - total * total / m as f64;
    if t <= 0.0 || m < 2 {
        same.iter_mut().for_each(|s| *s = true);
        return 1.0;
    }
    let index = |key: u64| (key & 0xffff_ffff) as usize;
    // W(split after `at`) = Σ₁x² − (Σ₁x)²/m₁ + Σ₂x² − (Σ₂x)²/m₂, over the two groups' prefix
    // sums; m₁ W = m₁ q − s² etc., compared without dividing: the least W is the least of
    // (m₁ q − s²)/m₁ + …, so the divisions stay, but as multiplications by 1/m from a table.
    let inverse = |c: usize| INVERSE.get(c).copied().unwrap_or(1.0 / c as f64);
    let (mut s, mut q) = (0.0, 0.0);
    let mut best = (f64::INFINITY, 0usize);
    for (at, &key) in keys[..m - 1].iter().enumerate() {
        let x = offsets[index(key)];
        s += x;
        q += x * x;
        let rest = total - s;
        let w =
            (q - s * s * inverse(at + 1)) + ((total_sq - q) - rest * rest * inverse(m - at - 1));
        if w < best.0 {
            best = (w, at);
        }
    }
    let own_left = keys[..=best.1].iter().any(|&key| index(key) == 0);
    for (pos, &key) in keys.iter().enumerate() {
        same[index(key)] = (pos <= best.1) == own_left;
    }
    (best.0 / t).max(0.0)
}

/// W/T of the offsets of `rel` along `u` for the given two groups (1 when the offsets do not
/// vary).
fn grouped_ratio(rel: &[DVec3], u: DVec3, same: &[bool]) -> f64 {
    // Per group: count, sum, sum of squares.
    let mut g = [[0.0f64; 3]; 2];
    for (x, &s) in rel.iter().zip(same) {
        let o = x.dot(u);
        let g = &mut g[s as usize];
        g[0] += 1.0;
        g[1] += o;
        g[2] += o * o;
    }
    let ss = |g: [f64; 3]| {
        if g[0] > 0.0 {
            g[2] - g[1] * g[1] / g[0]
        } else {
            0.0
        }
    };
    let t = ss([g[0][0] + g[1][0], g[0][1] + g[1][1], g[0][2] + g[1][2]]);
    if t <= 0.0 {
        return 1.0;
    }
    ((ss(g[0]) + ss(g[1])) / t).max(0.0)
}

/// The normal of two parallel planes fitted to the two groups of `rel` (`same` and not): the
/// smallest eigenvector of the sum of the groups' covariances about their own means, by two
/// steps of inverse iteration from `start` (adj(C)·u is parallel to C⁻¹u and exists when C is
/// singular, as for exact planes). Returns `start` when C has rank below 2.
fn two_plane_normal(rel: &[DVec3], same: &[bool], start: DVec3) -> DVec3 {
    let mut c = [[0.0f64; 3]; 3];
    for group in [true, false] {
        let (sum, count) = rel
            .iter()
            .zip(same)
            .filter(|(_, &s)| s == group)
            .fold((DVec3::ZERO, 0usize), |(s, c), (x, _)| (s + *x, c + 1));
        if count == 0 {
            continue;
        }
        let mean = sum / count as f64;
        for (x, _) in rel.iter().zip(same).filter(|(_, &s)| s == group) {
            let d = *x - mean;
            for (a, row) in c.iter_mut().enumerate() {
                for (b, entry) in row.iter_mut().enumerate().skip(a) {
                    *entry += d[a] * d[b];
                }
            }
        }
    }
    let [[a, b, d], [_, e, f], [_, _, g]] = c;
    // The adjugate of the symmetric [[a, b, d], [b, e, f], [d, f, g]].
    let adj = [
        DVec3::new(e * g - f * f, d * f - b * g, b * f - d * e),
        DVec3::new(d * f - b * g, a * g - d * d, b * d - a * f),
        DVec3::new(b * f - d * e, b * d - a * f, a * e - b * b),
    ];
    let mut u = start;
    for _ in 0..2 {
        let x = DVec3::new(adj[0].dot(u), adj[1].dot(u), adj[2].dot(u));
        let length = x.length();
        if !(length > 0.0 && length.is_finite()) {
            return u;
        }
        u = x / length;
    }
    u
}

/// Whether the neighbourhood `rel` (the point itself first, at the origin, then its neighbours,
/// nearest first; the last one at the neighbourhood's radius) holds two sheets, from the start
/// direction `start`. On success `scratch.same` holds, per point, whether it lies on the point's
/// own sheet.
pub(super) fn two_sheets(rel: &[DVec3], start: DVec3, scratch: &mut Scratch) -> Option<TwoSheets> {
    let m = rel.len();
    scratch.same.resize(m, true);
    scratch.trial.resize(m, true);
    let mut u = start;
    let mut ratio = split(
        rel,
        u,
        &mut scratch.keys,
        &mut scratch.offsets,
        &mut scratch.trial,
    );
    if ratio < REFINE_BELOW {
        u = two_plane_normal(rel, &scratch.trial, u);
        ratio = grouped_ratio(rel, u, &scratch.trial);
        if (SPLIT_RATIO..REGROUP_BELOW).contains(&ratio) {
            // Nearly two sheets: the first grouping, along a tilted direction, may have put a
            // few points in the wrong group; group again along the refined direction.
            ratio = split(
                rel,
                u,
                &mut scratch.keys,
                &mut scratch.offsets,
                &mut scratch.trial,
            );
        }
    }
    if ratio >= SPLIT_RATIO {
        return None;
    }
    let (mut own, mut own_count, mut other, mut other_count) = (0.0, 0usize, 0.0, 0usize);
    for (x, &s) in rel.iter().zip(&scratch.trial) {
        if s {
            own += x.dot(u);
            own_count += 1;
        } else {
            other += x.dot(u);
            other_count += 1;
        }
    }
    if other_count == 0 {
        return None;
    }
    let separation = (own / own_count as f64 - other / other_count as f64).abs();
    if separation < MIN_SEPARATION * rel[m - 1].length() {
        return None;
    }
    std::mem::swap(&mut scratch.same, &mut scratch.trial);
    Some(TwoSheets { normal: u })
}

/// Writes the neighbours that `scratch.same` puts on the other sheet into `bits` (one point's
/// words; rank r is entry r + 1 of the neighbourhood).
pub(super) fn mark_across(scratch: &Scratch, bits: &mut [u64]) {
    for (rank, &same) in scratch.same[1..].iter().enumerate() {
        if !same {
            bits[rank / 64] |= 1 << (rank % 64);
        }
    }
}

/// Second pass: every point in `ambiguous` (sorted; their neighbourhoods were not found to hold
/// two sheets in the first pass) tries the dominant direction of its neighbours' first-pass
/// normals as a start (see the module documentation). Reads the first-pass normals only. Then
/// indexes `sheets` for [`Sheets::any`]. [`BATCH`] points at a time, with `progress(fraction
/// done)` after each batch (it may stop the work).
pub(super) fn revisit_ambiguous(
    positions: &[DVec3],
    neighbors: &Neighbors,
    fits: &mut [Fit],
    sheets: &mut Sheets,
    ambiguous: &[u32],
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<()> {
    let first: Vec<DVec3> = ambiguous
        .iter()
        .flat_map(|&i| {
            std::iter::once(i)
                .chain(neighbors.of(i as usize).iter().copied())
                .map(|j| fits[j as usize].normal)
        })
        .collect();
    let k = neighbors.k();
    let mut found: Vec<Option<(DVec3, Vec<u64>)>> = Vec::with_capacity(ambiguous.len());
    let batches = ambiguous.len().div_ceil(BATCH);
    for (batch, points) in ambiguous.chunks(BATCH).enumerate() {
        let offset = batch * BATCH;
        pool.install(|| {
            found.par_extend(points.par_iter().enumerate().with_min_len(64).map_init(
                || (Scratch::default(), Vec::with_capacity(k + 1)),
                |(scratch, rel), (at, &i)| {
                    let at = offset + at;
                    let i = i as usize;
                    let normals = &first[at * (k + 1)..(at + 1) * (k + 1)];
                    let mut t = [[0.0f64; 3]; 3];
                    for n in normals {
                        for (a, row) in t.iter_mut().enumerate() {
                            for (b, entry) in row.iter_mut().enumerate().skip(a) {
                                *entry += n[a] * n[b];
                            }
                        }
                    }
                    (t[1][0], t[2][0], t[2][1]) = (t[0][1], t[0][2], t[1][2]);
                    let start = jacobi_eigen(t).1[2];
                    offsets_around(i, positions, neighbors, rel);
                    two_sheets(rel, start, scratch).map(|found| {
                        let mut bits = vec![0u64; k.div_ceil(64)];
                        mark_across(scratch, &mut bits);
                        (found.normal, bits)
                    })
                },
            ))
        });
        progress((batch + 1) as f32 / batches as f32)?;
    }
    for (&i, found) in ambiguous.iter().zip(found) {
        if let Some((normal, bits)) = found {
            fits[i as usize].normal = normal;
            let words = sheets.words;
            sheets.across[i as usize * words..(i as usize + 1) * words].copy_from_slice(&bits);
        }
    }
    sheets.index();
    Ok(())
}

/// Point `i`'s neighbourhood as offsets from it, itself first (0): what the plane fit and
/// [`two_sheets`] read.
pub(super) fn offsets_around(
    i: usize,
    positions: &[DVec3],
    neighbors: &Neighbors,
    rel: &mut Vec<DVec3>,
) {
    rel.clear();
    rel.push(DVec3::ZERO);
    rel.extend(
        neighbors
            .of(i)
            .iter()
            .map(|&j| positions[j as usize] - positions[i]),
    );
}

/// Which neighbours lie on another sheet, for normals the caller gives (their lines are kept:
/// the split starts from each given normal), in `pool`, [`BATCH`] points at a time, with
/// `progress(fraction done)` after each batch (it may stop the work).
pub(super) fn across_given(
    positions: &[DVec3],
    neighbors: &Neighbors,
    normals: &[DVec3],
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<Sheets> {
    let n = positions.len();
    let k = neighbors.k();
    let mut sheets = Sheets::none(n, k);
    let words = sheets.words;
    let batches = n.div_ceil(BATCH);
    for (batch, rows) in sheets.across.chunks_mut(BATCH * words).enumerate() {
        pool.install(|| {
            rows.par_chunks_mut(words)
                .enumerate()
                .with_min_len(256)
                .for_each_init(
                    || (Scratch::default(), Vec::with_capacity(k + 1)),
                    |(scratch, rel), (at, bits)| {
                        let i = batch * BATCH + at;
                        offsets_around(i, positions, neighbors, rel);
                        if two_sheets(rel, normals[i], scratch).is_some() {
                            mark_across(scratch, bits);
                        }
                    },
                )
        });
        progress((batch + 1) as f32 / batches as f32)?;
    }
    sheets.index();
    Ok(sheets)
}

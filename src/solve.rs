//! Stage 6 — the coarse-to-fine solve (§4.3).
//!
//! Depth by depth from the root, the restriction A_d of the system to the depth-d unknowns is
//! solved with the contributions of all coarser depths moved to the right-hand side (they are
//! applied through the prolonged coarser solution, see [`crate::system`]). Each depth is solved
//! by conjugate gradients preconditioned with A_d's diagonal (the paper's method; the diagonal
//! evens out the screening weights, which vary from node to node).
//!
//! Reductions are computed in fixed chunks whose partial sums are added in order, so the result
//! is the same bit for bit whatever the number of threads.

use crate::octree::Level;
use crate::parallel::{scatter_by_chunk, CHUNK};
use crate::system::{update_on_core, DepthOperator};
use rayon::prelude::*;

/// How one depth's solve ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CgOutcome {
    pub iterations: u32,
    pub relative_residual: f64,
    /// The callback asked to stop.
    pub cancelled: bool,
}

/// Σ_{i < n} term(i) in parallel, deterministically: fixed chunks of [`CHUNK`] terms, each
/// summed in order, and the chunks' sums added in order, whatever the number of threads.
fn chunked_sum(n: usize, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| (c * CHUNK..n.min((c + 1) * CHUNK)).map(&term).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// Deterministic parallel dot product.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    chunked_sum(a.len(), |i| a[i] * b[i])
}

/// Σ r_i·(r_i·w_i): rᵀz for the preconditioned residual z = w∘r.
fn weighted_dot(r: &[f64], w: &[f32]) -> f64 {
    chunked_sum(r.len(), |i| r[i] * (r[i] * w[i] as f64))
}

/// One pass of a CG step over the core, chunk by chunk: x += α·p (x and p on K_d), r −= α·A·p,
/// and the new rᵀr and rᵀz (z = w∘r), each the sum [`dot`] and [`weighted_dot`] would give:
/// the same chunks, each summed in order, the chunks' sums added in order. One pass instead of
/// three over r.
fn step(
    level: &Level,
    x: &mut [f64],
    alpha: f64,
    p: &[f64],
    r: &mut [f64],
    ap: &[f64],
    w: &[f32],
) -> (f64, f64) {
    let partial: Vec<(f64, f64)> = scatter_by_chunk(&level.core, [x], r, |c, x, r| {
        let range = c * CHUNK..c * CHUNK + r.len();
        let nodes = x.indices();
        for (k, (r, a)) in r.iter_mut().zip(&ap[range.clone()]).enumerate() {
            let [x] = x.at(k);
            *x += alpha * p[nodes[k] as usize];
            *r -= alpha * a;
        }
        let w = &w[range];
        (
            r.iter().map(|r| r * r).sum::<f64>(),
            r.iter()
                .zip(w)
                .map(|(r, &w)| r * (r * w as f64))
                .sum::<f64>(),
        )
    });
    (
        partial.iter().map(|s| s.0).sum(),
        partial.iter().map(|s| s.1).sum(),
    )
}

/// Σ_i p[core node i]·a_i for `p` on K_d and `a` on the core.
fn dot_on_core(level: &Level, p: &[f64], a: &[f64]) -> f64 {
    chunked_sum(a.len(), |i| p[level.core[i] as usize] * a[i])
}

/// Solves A x = b on the core of `op.level` (x starts at zero) and adds x to `solution`, a
/// vector on K_d, at the core nodes (its mirror nodes are left to the caller). `b` becomes the
/// residual, so the solve holds no copy of it and no separate x. `keep_going` is called once
/// per iteration with the fraction of the iteration budget used; returning false stops.
pub fn conjugate_gradients(
    pool: &rayon::ThreadPool,
    op: &mut DepthOperator<'_>,
    b: Vec<f64>,
    solution: &mut [f64],
    max_iterations: u32,
    tolerance: f64,
    keep_going: &mut dyn FnMut(f32) -> bool,
) -> CgOutcome {
    let n = b.len();
    let b_norm = pool.install(|| dot(&b, &b)).sqrt();
    if b_norm == 0.0 || n == 0 {
        return CgOutcome {
            iterations: 0,
            relative_residual: 0.0,
            cancelled: false,
        };
    }
    // The Jacobi preconditioner in single precision (a preconditioner only steers the
    // iteration; half the memory of a core-sized vector).
    let inv_diag: Vec<f32> = pool.install(|| {
        op.diagonal()
            .into_par_iter()
            .map(|d| (1.0 / d) as f32)
            .collect()
    });
    let level = op.level;
    let mut r = b;
    // The search direction lives on K_d (zero beyond the core and its mirrors), the layout the
    // operator reads, so it is never copied there; the preconditioned residual z = r/diag is
    // not stored but recomputed where it is used.
    let mut p = vec![0.0; level.len()];
    let mut rz = pool.install(|| {
        update_on_core(level, &mut p, |i, _| r[i] * inv_diag[i] as f64);
        weighted_dot(&r, &inv_diag)
    });
    let mut ap = vec![0.0; n];
    let mut iterations = 0;
    let mut residual = 1.0;
    while iterations < max_iterations {
        if !keep_going(iterations as f32 / max_iterations as f32) {
            return CgOutcome {
                iterations,
                relative_residual: residual,
                cancelled: true,
            };
        }
        pool.install(|| op.apply(&p, &mut ap));
        let pap = pool.install(|| dot_on_core(level, &p, &ap));
        if !(pap > 0.0) {
            break;
        }
        let alpha = rz / pap;
        let (rr, rz_new) =
            pool.install(|| step(level, solution, alpha, &p, &mut r, &ap, &inv_diag));
        iterations += 1;
        residual = rr.sqrt() / b_norm;
        if residual <= tolerance {
            break;
        }
        let beta = rz_new / rz;
        rz = rz_new;
        pool.install(|| update_on_core(level, &mut p, |i, p| r[i] * inv_diag[i] as f64 + beta * p));
    }
    CgOutcome {
        iterations,
        relative_residual: residual,
        cancelled: false,
    }
}

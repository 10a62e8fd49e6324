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

use crate::error::{Error, Result};
use crate::memory::zeroed;
use crate::octree::{Level, Octree};
use crate::parallel::{scatter_by_chunk, CHUNK};
use crate::system::{
    fill_mirrors, prolong, proxy_depth, update_on_core, DepthOperator, Proxies, ScreeningWeights,
};

/// A cell of a proxy depth with its samples' Σ w·p and Σ w ([`crate::system::sample_groups`]).
pub(crate) type ProxyGroup = ([i32; 3], DVec3, f64);
use crate::{DepthSolve, Params};
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;

/// What the solve reads: the right-hand sides and the vector field of every depth, and the
/// screening samples.
pub(crate) struct System<'a> {
    pub(crate) tree: &'a Octree,
    /// ρ_d on K_d for every depth ([`crate::system::right_hand_sides`]); each is dropped once
    /// its depth is solved.
    pub(crate) rho: Vec<Vec<f64>>,
    /// The coarser depths' V at each depth's core ([`crate::system::FieldCarry`]; empty where
    /// none is carried); each is dropped once its depth is solved.
    pub(crate) coarse_div: Vec<Vec<f64>>,
    /// The samples in the unit cube (Morton order) and their screening weights.
    pub(crate) positions: &'a [DVec3],
    pub(crate) screening_weights: &'a [f64],
    /// Instead of the samples: their groups, already summed, for every depth solved (index d
    /// at [`proxy_depth`] of d, as [`crate::system::sample_groups`] makes them). The
    /// out-of-core base's, merged from its slabs' (`crate::outofcore::base::merge_groups`).
    pub(crate) proxy_groups: Option<&'a [Vec<ProxyGroup>]>,
    /// The screening term's weight α_d at each depth.
    pub(crate) screening: ScreeningWeights,
    /// Which depths to solve: all of them ([`Depths::All`]) as the in-memory pipeline does, or
    /// a base or the depths above one (the out-of-core path, `crate::outofcore`).
    pub(crate) depths: Depths,
}

/// The depths a [`cascade`] solves.
pub(crate) enum Depths {
    /// Every depth of the tree, from the root.
    All,
    /// Depths 0..=`last` of a tree whose levels stop there, as part of a reconstruction whose
    /// finest depth is `finest` (which sets the screening samples' grouping).
    Base { last: usize, finest: u32 },
    /// The depths above a base solved before (its coefficients, depths 0..=B), on a tree whose
    /// levels 0..=B are the base's.
    Above(Vec<Vec<f64>>),
}

/// What a base hands to the depths above it: the coefficients of depths 0..=B and V at depth B
/// with every coarser depth's prolonged into it (where [`crate::system::FieldCarry::from_base`]
/// starts).
#[derive(Debug)]
pub(crate) struct Solved {
    pub(crate) coefficients: Vec<Vec<f64>>,
    pub(crate) field_v: [Vec<f64>; 3],
}

/// Solves the system depth by depth from the root (or from the depth above a base, see
/// [`Depths`]) and returns z_d on K_d for every depth: the coarser solution prolonged to depth
/// d plus the correction solved there. Each depth's figures are appended to `solves`;
/// `progress(fraction of the whole solve)` is called once per iteration and between the steps
/// that set up each depth, and may cancel.
pub(crate) fn cascade(
    system: System<'_>,
    params: &Params,
    pool: &rayon::ThreadPool,
    progress: &mut dyn FnMut(f32) -> bool,
    solves: &mut Vec<DepthSolve>,
) -> Result<Vec<Vec<f64>>> {
    let System {
        tree,
        mut rho,
        mut coarse_div,
        positions,
        screening_weights,
        proxy_groups,
        screening,
        depths: which,
    } = system;
    // The reconstruction's finest depth, and the depths solved here.
    let (max_depth, first, last) = match &which {
        Depths::All => (tree.max_depth(), 0, tree.max_depth() as usize),
        Depths::Base { last, finest } => (*finest, 0, *last),
        Depths::Above(base) => (tree.max_depth(), base.len(), tree.max_depth() as usize),
    };
    let mut coefficients: Vec<Vec<f64>> = Vec::with_capacity(tree.levels.len());
    if let Depths::Above(base) = which {
        coefficients = base;
    }
    let depths = max_depth + 1;
    for d in first..=last {
        let depth_started = Instant::now();
        let level = &tree.levels[d];
        let base = d as f32 / depths as f32;
        // A cancel point between the set-up steps (each up to a few tenths of a second at the
        // finest depths of a large scan).
        let mut go_on = || -> Result<()> {
            if progress(base) {
                Ok(())
            } else {
                Err(Error::Cancelled)
            }
        };
        let proxies = pool.install(|| match proxy_groups {
            Some(groups) => {
                Proxies::from_groups(level, &groups[d], proxy_depth(d as u32, max_depth))
            }
            None => Proxies::build(
                level,
                positions,
                screening_weights,
                proxy_depth(d as u32, max_depth),
            ),
        });
        go_on()?;
        let mut op = pool.install(|| DepthOperator::new(level, &proxies, screening.at(d)));
        go_on()?;
        // This depth's rho is used here for the last time.
        let rho_here = std::mem::take(&mut rho[d]);
        // The coarser solution, represented at this depth (stored: it is part of this depth's
        // coefficients).
        let y = pool.install(|| -> Result<Vec<f64>> {
            if d == 0 {
                zeroed(level.len(), "the coefficients")
            } else {
                let mut y = prolong(&tree.levels[d - 1], level, &coefficients[d - 1], 1.0)?;
                fill_mirrors(level, &mut y);
                Ok(y)
            }
        })?;
        go_on()?;
        // The coarser depths' V at this depth (none at the root).
        let coarse_div = match coarse_div.get_mut(d).map(std::mem::take) {
            Some(div) if !div.is_empty() => div,
            _ => zeroed(level.core.len(), "a coarse right-hand side")?,
        };
        debug_assert_eq!(
            coarse_div.len(),
            level.core.len(),
            "one value per core node"
        );
        // b − A·y on the core, computed in the coarse divergence's vector, and A·y's vector is
        // the solver's A·p after: fresh pages for one core-sized vector instead of two. (Not
        // the search direction: it lives on K_d, and a fresh vector's pages beyond the core are
        // never touched, where a spent one's are all resident.)
        let (rhs, ay) = pool.install(|| -> Result<(Vec<f64>, Vec<f64>)> {
            let mut ay = zeroed(level.core.len(), "the solver's vectors")?;
            op.apply(&y, &mut ay);
            // Degree-1 face rows: ⟨∇B_o, V⟩ scaled as the Laplacian's rows are (the term taken
            // off is read before the divergence's vector turns into the right-hand side).
            let face_terms: Vec<(usize, f64)> = op
                .face_rows()
                .iter()
                .map(|&(position, scale)| {
                    let c = level.core[position] as usize;
                    (
                        position,
                        (1.0 - scale) * (rho_here[c] + coarse_div[position]),
                    )
                })
                .collect();
            let mut rhs = coarse_div;
            rhs.par_iter_mut()
                .zip(level.core.par_iter().zip(&ay))
                .for_each(|(div, (&c, a))| *div = rho_here[c as usize] + *div - a);
            for (position, term) in face_terms {
                rhs[position] -= term;
            }
            if let Some(target) = params.boundary.screening_target() {
                op.add_screening_target(target, &mut rhs);
            }
            Ok((rhs, ay))
        })?;
        drop(rho_here);
        go_on()?;
        // The coefficients of this depth: the prolonged coarser solution plus the correction
        // the solve adds on the core.
        let mut z = y;
        let outcome = {
            let mut keep_going = |f: f32| progress(base + f / depths as f32);
            conjugate_gradients(
                pool,
                &mut op,
                rhs,
                &mut z,
                CgLimits {
                    max_iterations: params.max_solver_iterations,
                    tolerance: params.solver_tolerance,
                },
                ay,
                &mut keep_going,
            )?
        };
        if outcome.cancelled {
            return Err(Error::Cancelled);
        }
        fill_mirrors(level, &mut z);
        coefficients.push(z);
        solves.push(DepthSolve {
            depth: d as u32,
            unknowns: level.core.len(),
            iterations: outcome.iterations,
            relative_residual: outcome.relative_residual,
            seconds: depth_started.elapsed().as_secs_f64(),
        });
    }
    Ok(coefficients)
}

/// When a depth's conjugate gradients stop: after `max_iterations`, or once the relative
/// residual is at most `tolerance`.
#[derive(Debug, Clone, Copy)]
struct CgLimits {
    max_iterations: u32,
    tolerance: f64,
}

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
/// residual, so the solve holds no copy of it and no separate x. A·p is computed in `ap` when it
/// has one element per core node (whatever their values; else in a fresh vector). `keep_going`
/// is called once per iteration with the fraction of the iteration budget used; returning false
/// stops.
fn conjugate_gradients(
    pool: &rayon::ThreadPool,
    op: &mut DepthOperator<'_>,
    b: Vec<f64>,
    solution: &mut [f64],
    CgLimits {
        max_iterations,
        tolerance,
    }: CgLimits,
    ap: Vec<f64>,
    keep_going: &mut dyn FnMut(f32) -> bool,
) -> Result<CgOutcome> {
    let n = b.len();
    let b_norm = pool.install(|| dot(&b, &b)).sqrt();
    if b_norm == 0.0 || n == 0 {
        return Ok(CgOutcome {
            iterations: 0,
            relative_residual: 0.0,
            cancelled: false,
        });
    }
    // The Jacobi preconditioner in single precision (a preconditioner only steers the
    // iteration; half the memory of a core-sized vector).
    let mut inv_diag: Vec<f32> = zeroed(n, "the solver's vectors")?;
    pool.install(|| {
        inv_diag
            .par_iter_mut()
            .zip(op.diagonal().into_par_iter())
            .for_each(|(w, d)| *w = (1.0 / d) as f32)
    });
    let level = op.level;
    let mut r = b;
    // The search direction lives on K_d (zero beyond the core and its mirrors), the layout the
    // operator reads, so it is never copied there; the preconditioned residual z = r/diag is
    // not stored but recomputed where it is used.
    let mut p = zeroed(level.len(), "the solver's vectors")?;
    let mut rz = pool.install(|| {
        update_on_core(level, &mut p, |i, _| r[i] * inv_diag[i] as f64);
        weighted_dot(&r, &inv_diag)
    });
    let mut ap = if ap.len() == n {
        ap // every element is written by the first product before it is read
    } else {
        zeroed(n, "the solver's vectors")?
    };
    let mut iterations = 0;
    let mut residual = 1.0;
    while iterations < max_iterations {
        if !keep_going(iterations as f32 / max_iterations as f32) {
            return Ok(CgOutcome {
                iterations,
                relative_residual: residual,
                cancelled: true,
            });
        }
        pool.install(|| op.apply(&p, &mut ap));
        let pap = pool.install(|| dot_on_core(level, &p, &ap));
        if pap.is_nan() || pap <= 0.0 {
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
    Ok(CgOutcome {
        iterations,
        relative_residual: residual,
        cancelled: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{cell_of, morton_nested};
    use crate::Boundary;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    /// Solves A x = A x_true on a complete 16³ level with free boundaries (A positive
    /// definite) and a screening term, from x = 0.
    fn solve_known_system(threads: usize) -> (Vec<f64>, Vec<f64>, CgOutcome) {
        let tree = Octree::build(vec![Vec::new(); 5], 4, Boundary::Free);
        let level = &tree.levels[4];
        // Proxies in a band of cells, so the screening varies from node to node.
        let mut positions: Vec<DVec3> = (0..4000)
            .map(|i| {
                let t = i as f64 / 4000.0;
                DVec3::new(0.1 + 0.8 * t, 0.5 + 0.3 * (17.0 * t).sin(), 0.4)
            })
            .collect();
        // In Morton order, as the pipeline's samples are (Proxies::build relies on it).
        positions.sort_by_key(|&p| morton_nested(cell_of(p, 1024.0).map(|v| v as u32)));
        let weights = vec![1e-3; positions.len()];
        let proxies = Proxies::build(level, &positions, &weights, 4);
        assert!(!proxies.is_empty());
        let mut op = DepthOperator::new(level, &proxies, 4.0 * 16.0);
        let mut x_true = vec![0.0; level.len()];
        for (k, &c) in level.core.iter().enumerate() {
            x_true[c as usize] = ((k * 37) % 101) as f64 / 101.0 - 0.5;
        }
        let mut b = vec![0.0; level.core.len()];
        op.apply(&x_true, &mut b);
        let mut x = vec![0.0; level.len()];
        let pool = pool(threads);
        let outcome = conjugate_gradients(
            &pool,
            &mut op,
            b,
            &mut x,
            CgLimits {
                max_iterations: 2000,
                tolerance: 1e-10,
            },
            Vec::new(),
            &mut |_| true,
        )
        .unwrap();
        (x, x_true, outcome)
    }

    /// Proves: preconditioned CG solves a depth's system (Laplacian plus screening) to the
    /// requested residual and recovers the known solution.
    #[test]
    fn conjugate_gradients_recovers_a_known_solution() {
        let (x, x_true, outcome) = solve_known_system(2);
        assert!(!outcome.cancelled);
        assert!(outcome.relative_residual <= 1e-10, "{outcome:?}");
        let err = x
            .iter()
            .zip(&x_true)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            err < 1e-6,
            "max error {err} after {} iterations",
            outcome.iterations
        );
    }

    /// Proves: the solve gives the same bits whatever the thread count (fixed chunks, partial
    /// sums added in order).
    #[test]
    fn conjugate_gradients_is_deterministic_across_thread_counts() {
        let (one, _, a) = solve_known_system(1);
        let (three, _, b) = solve_known_system(3);
        assert_eq!(a, b);
        assert!(one
            .iter()
            .zip(&three)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
    }

    /// Proves: a callback that says stop ends the solve at once, reporting it.
    #[test]
    fn conjugate_gradients_stops_when_asked() {
        let tree = Octree::build(vec![Vec::new(); 4], 3, Boundary::Free);
        let level = &tree.levels[3];
        let proxies = Proxies::default();
        let mut op = DepthOperator::new(level, &proxies, 0.0);
        let b = vec![1.0; level.core.len()];
        let mut x = vec![0.0; level.len()];
        let mut calls = 0;
        let outcome = conjugate_gradients(
            &pool(1),
            &mut op,
            b,
            &mut x,
            CgLimits {
                max_iterations: 100,
                tolerance: 1e-12,
            },
            Vec::new(),
            &mut |_| {
                calls += 1;
                calls < 3
            },
        )
        .unwrap();
        assert!(outcome.cancelled);
        assert_eq!(outcome.iterations, 2);
    }
}

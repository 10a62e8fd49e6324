//! The system's tests: operators against closed forms and node-by-node references.

use super::bricks::{window_regions, CoreBricks, WINDOW};
use super::rhs::{divergence, divergence_of, divergence_of_prolonged};
use super::screening::ScreeningCells;
use super::transfer::{prolonged_at, refinement_parents, restrict_into, ProlongedField};
use super::*;
use crate::bspline::Degree;
use crate::octree::{fill_mirrors_field, Level, Octree, NONE};
use crate::Boundary;
use glam::DVec3;

/// A complete 16³ grid with free boundaries: its halo reaches two nodes beyond the cube, so
/// every core node sees its whole 5³ neighbourhood.
fn grid() -> Octree {
    Octree::build(vec![Vec::new(); 5], 4, Boundary::Free)
}

/// Coefficients on K of the polynomial f in node units (t = p/h = i + ½ at node centres).
/// Quadratic B-splines reproduce quadratics: Σ_i b(t − t_i)·(t_i² − ¼) = t², Σ_i b(t − t_i)·t_i = t.
fn coefficients(level: &Level, f: impl Fn([f64; 3]) -> f64) -> Vec<f64> {
    (0..level.len() as u32)
        .map(|i| f(level.coord(i).map(|c| c as f64 + 0.5)))
        .collect()
}

#[test]
fn laplacian_of_quadratics_matches_integration_by_parts() {
    let tree = grid();
    let level = &tree.levels[4];
    let h = level.width();
    let proxies = Proxies::default();
    let mut op = DepthOperator::new(level, &proxies, 0.0);
    let mut out = vec![0.0; level.core.len()];
    // f = x² (unit coordinates) = h²(t² ): coefficients h²(t_i² − ¼). ⟨∇B_o, ∇f⟩ = −∫B_o Δf = −2h³.
    let x = coefficients(level, |t| h * h * (t[0] * t[0] - 0.25));
    op.apply(&x, &mut out);
    for v in &out {
        assert!(
            (v + 2.0 * h * h * h).abs() < 1e-12,
            "{v} vs {}",
            -2.0 * h * h * h
        );
    }
    // f = x² + y² − 2z² + 3xy is harmonic: ⟨∇B_o, ∇f⟩ = 0.
    let x = coefficients(level, |t| {
        h * h
            * ((t[0] * t[0] - 0.25) + (t[1] * t[1] - 0.25) - 2.0 * (t[2] * t[2] - 0.25)
                + 3.0 * t[0] * t[1])
    });
    op.apply(&x, &mut out);
    assert!(out.iter().all(|v| v.abs() < 1e-12));
}

#[test]
fn divergence_of_a_linear_field_is_its_constant_divergence() {
    let tree = grid();
    let level = &tree.levels[4];
    let h = level.width();
    // V = (x, 2y, −z): coefficients of the unit-integral F̃_o = B_o/h³ are h³·V(t_i·h).
    let v = [
        coefficients(level, |t| h * h * h * (h * t[0])),
        coefficients(level, |t| h * h * h * (2.0 * h * t[1])),
        coefficients(level, |t| h * h * h * (-h * t[2])),
    ];
    let div = divergence(level, v).unwrap();
    // ⟨∇B_o, V⟩ = −∫B_o ∇·V = −(1 + 2 − 1)·h³ at every core node.
    for &c in &level.core {
        let got = div[c as usize];
        assert!((got + 2.0 * h * h * h).abs() < 1e-12, "{got}");
    }
}

/// Every boundary kind, the mirrored ones (Neumann, Dirichlet) sharing one code path.
const BOUNDARIES: [Boundary; 3] = [Boundary::Free, Boundary::Neumann, Boundary::Dirichlet];

/// A complete 16³ tree and a sparse one (only part of the cube refined, down to depth 5),
/// with the given boundaries.
fn complete_and_sparse_trees(boundary: Boundary) -> [Octree; 2] {
    complete_and_sparse_trees_of(boundary, Degree::Two)
}

/// [`complete_and_sparse_trees`] for both degrees (degree 2's first).
fn trees_of_both_degrees(boundary: Boundary) -> impl Iterator<Item = Octree> {
    [Degree::Two, Degree::One]
        .into_iter()
        .flat_map(move |degree| complete_and_sparse_trees_of(boundary, degree))
}

/// [`complete_and_sparse_trees`] with node functions of `degree`.
fn complete_and_sparse_trees_of(boundary: Boundary, degree: Degree) -> [Octree; 2] {
    let sparse: Vec<Vec<[i32; 3]>> = (0..=5)
        .map(|d| {
            let n = 1 << d;
            (0..n)
                .flat_map(|i| [[i, i / 2, n / 3], [n - 1 - i, i, i / 3], [0, i, n - 1]])
                .collect()
        })
        .collect();
    [
        Octree::build_for(vec![Vec::new(); 5], 4, boundary, degree),
        Octree::build_for(sparse, 2, boundary, degree),
    ]
}

/// The brick-by-brick prolongations (of the coefficients, of V added to a field, and inside
/// the coarse divergence's windows), the restriction and the separable passes give the
/// node-by-node values bit for bit, with free and
/// with Neumann boundaries (mirror nodes beyond the cube), on sparse levels (only part of
/// the cube refined) as well as complete ones. The values are half-integers and the weights
/// dyadic, so every sum is exact whatever its order: the test checks which parents each node
/// takes and with which weights (the brick paths sum one axis at a time, node by node all
/// eight parents at once, which rounds differently on real data).
#[test]
fn brick_prolongations_match_node_by_node_prolongation() {
    for boundary in BOUNDARIES {
        for tree in trees_of_both_degrees(boundary) {
            for d in 1..tree.levels.len() {
                let (coarse, fine) = (&tree.levels[d - 1], &tree.levels[d]);
                let field: [Vec<f64>; 3] = std::array::from_fn(|a| {
                    (0..coarse.len())
                        .map(|i| ((i * (a + 5) + 3) % 13) as f64 - 6.5)
                        .collect()
                });
                let prolonged = ProlongedField {
                    coarse,
                    fine,
                    field: [&field[0], &field[1], &field[2]],
                    scale: 0.125,
                };
                let proxies = Proxies::default();
                let mut op = DepthOperator::new(fine, &proxies, 0.0);
                let by_node = op.divergence_on_core(|n| prolonged.at(n as u32));
                let by_brick = divergence_of_prolonged(&prolonged).unwrap();
                assert!(!by_node.is_empty());
                let same = |a: &[f64], b: &[f64], what: &str| {
                    assert_eq!(a.len(), b.len());
                    for (a, b) in a.iter().zip(b) {
                        // Bit for bit, but for the sign of a zero: a degree-1 Dirichlet node
                        // with no parent at all (depth 0's core is empty) sums nothing, −0
                        // node by node, +0 in the brick's window.
                        assert!(
                            a.to_bits() == b.to_bits() || (*a == 0.0 && *b == 0.0),
                            "{what}, depth {d}, {boundary:?}: {a} vs {b}"
                        );
                    }
                };
                same(&by_node, &by_brick, "divergence");
                let by_node: Vec<f64> = (0..fine.len() as u32)
                    .map(|i| prolonged_at(coarse, fine, [&field[0]], [2.0], i)[0])
                    .collect();
                same(
                    &by_node,
                    &prolong(coarse, fine, &field[0], 2.0).unwrap(),
                    "prolong",
                );
                let base: [Vec<f64>; 3] = std::array::from_fn(|a| {
                    (0..fine.len()).map(|i| (i % (a + 2)) as f64).collect()
                });
                let mut added = base.clone();
                prolonged.add_to(&mut added);
                let want: [Vec<f64>; 3] = std::array::from_fn(|a| {
                    (0..fine.len())
                        .map(|i| prolonged.at(i as u32)[a] + base[a][i])
                        .collect()
                });
                for a in 0..3 {
                    same(&want[a], &added[a], "add_to");
                }
                // Restriction (the transpose) brick by brick against node by node, with
                // zeros among the fine values as the pipeline's have.
                let fine_values: Vec<f64> = (0..fine.len())
                    .map(|i| {
                        if i % 5 == 0 {
                            0.0
                        } else {
                            (i % 9) as f64 - 4.0
                        }
                    })
                    .collect();
                let by_node = restricted_node_by_node(coarse, fine, &fine_values, 0.5);
                let mut by_brick = vec![0.5; coarse.len()];
                restrict_into(coarse, fine, &fine_values, &mut by_brick);
                same(&by_node, &by_brick, "restrict");
                // The divergence brick by brick against the 125-node sum node by node.
                let field: [Vec<f64>; 3] = std::array::from_fn(|a| {
                    (0..fine.len())
                        .map(|i| ((i * (a + 2) + 1) % 11) as f64 * 0.37 - 1.7)
                        .collect()
                });
                let got = divergence_of(fine, &field).unwrap();
                let t = fine.degree.tables();
                for i in 0..fine.len() as u32 {
                    let o = fine.coord(i);
                    let mut want = 0.0;
                    for k in 0..125 {
                        let d = [k % 5, k / 5 % 5, k / 25];
                        let Some(j) = fine.find(std::array::from_fn(|a| o[a] + d[a] as i32 - 2))
                        else {
                            continue;
                        };
                        let (m, g) = (t.mass, t.advection);
                        let v = field.each_ref().map(|c| c[j as usize]);
                        want += g[d[0]] * m[d[1]] * m[d[2]] * v[0]
                            + m[d[0]] * g[d[1]] * m[d[2]] * v[1]
                            + m[d[0]] * m[d[1]] * g[d[2]] * v[2];
                    }
                    want /= fine.width();
                    let err = (got[i as usize] - want).abs();
                    assert!(
                        err < 1e-9 * (1.0 + want.abs()),
                        "node {i}: {} vs {want}",
                        got[i as usize]
                    );
                }
            }
        }
    }
}

/// The window of every core brick gathered group by group from a vector (AVX-512's
/// expanding loads where the CPU has them) equals the node-by-node gather, with and without
/// mirror nodes, on sparse and complete levels; the windows' parts of the bricks around are
/// whole 2×2×2 groups, which the group walk relies on.
#[test]
fn vector_windows_match_the_node_by_node_gather() {
    for region in window_regions() {
        for word in region {
            assert!(word.to_le_bytes().iter().all(|&b| b == 0 || b == 0xff));
        }
    }
    #[cfg(target_arch = "x86_64")]
    if !std::arch::is_x86_feature_detected!("avx512f") {
        eprintln!("no AVX-512 on this CPU: checking the portable gather against itself");
    }
    for boundary in BOUNDARIES {
        for tree in complete_and_sparse_trees(boundary) {
            for level in &tree.levels {
                let input: Vec<f64> = (0..level.len()).map(|i| (i % 97) as f64 + 0.5).collect();
                let bricks = CoreBricks::new(level);
                let mut fast = [vec![[f64::NAN; WINDOW]; WINDOW * WINDOW]];
                let mut slow = fast.clone();
                for cb in 0..bricks.around.len() {
                    bricks.gather_values(level, cb, &input, &mut fast[0]);
                    bricks.gather(level, cb, &|n| [input[n]], &mut slow);
                    assert_eq!(fast, slow, "depth {} brick {cb}", level.depth);
                }
            }
        }
    }
}

#[test]
fn divergence_on_core_matches_the_full_divergence() {
    let tree = grid();
    let level = &tree.levels[4];
    let v: [Vec<f64>; 3] = std::array::from_fn(|a| {
        (0..level.len())
            .map(|i| ((i * (a + 3)) % 11) as f64 - 5.0)
            .collect()
    });
    let full = divergence(level, v.clone()).unwrap();
    let kept = divergence_of(level, &v).unwrap();
    assert!(full
        .iter()
        .zip(&kept)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let proxies = Proxies::default();
    let mut op = DepthOperator::new(level, &proxies, 0.0);
    let on_core = op.divergence_on_core(|n| [v[0][n], v[1][n], v[2][n]]);
    for (&c, got) in level.core.iter().zip(&on_core) {
        let want = full[c as usize];
        assert!(
            (got - want).abs() < 1e-12 * want.abs().max(1.0),
            "{got} vs {want}"
        );
    }
}

#[test]
fn prolongation_reproduces_coarse_quadratics_and_restriction_is_its_transpose() {
    let tree = grid();
    let (coarse, fine) = (&tree.levels[3], &tree.levels[4]);
    let f = |p: [f64; 3]| p[0] * p[0] + 0.5 * p[1] * p[2] - p[2];
    // Coefficients of f in each depth's basis (unit coordinates p = t·h).
    let at = |level: &Level| {
        let h = level.width();
        coefficients(level, |t| {
            let p = t.map(|v| v * h);
            f(p) - 0.25 * h * h // the −¼ correction of the x² term
        })
    };
    let got = prolong(coarse, fine, &at(coarse), 1.0).unwrap();
    let want = at(fine);
    for &c in &fine.core {
        assert!((got[c as usize] - want[c as usize]).abs() < 1e-12);
    }
    // ⟨R u, v⟩ = ⟨u, P v⟩ on vectors supported on the cores.
    let u: Vec<f64> = (0..fine.len())
        .map(|i| {
            if fine.flags[i] & crate::octree::CORE != 0 {
                (i % 7) as f64
            } else {
                0.0
            }
        })
        .collect();
    let v: Vec<f64> = (0..coarse.len())
        .map(|i| {
            if coarse.flags[i] & crate::octree::CORE != 0 {
                (i % 5) as f64 - 2.0
            } else {
                0.0
            }
        })
        .collect();
    let mut ru = vec![0.0; coarse.len()];
    restrict_into(coarse, fine, &u, &mut ru);
    let pv = prolong(coarse, fine, &v, 1.0).unwrap();
    let lhs: f64 = ru.iter().zip(&v).map(|(a, b)| a * b).sum();
    let rhs: f64 = u.iter().zip(&pv).map(|(a, b)| a * b).sum();
    assert!((lhs - rhs).abs() < 1e-9 * lhs.abs().max(1.0));
}

/// The restriction's reference: every fine node, in index order, adds w · value to each of
/// its `refinement_parents`, onto coarse nodes that start at `start`.
fn restricted_node_by_node(
    coarse: &Level,
    fine: &Level,
    fine_values: &[f64],
    start: f64,
) -> Vec<f64> {
    let mut by_node = vec![start; coarse.len()];
    for i in 0..fine.len() as u32 {
        for (n, w) in refinement_parents(coarse, fine, i) {
            if n != NONE && fine_values[i as usize] != 0.0 {
                by_node[n as usize] += w * fine_values[i as usize];
            }
        }
    }
    by_node
}

/// Proves: the restriction, whose coarse nodes are cut into one run of bricks per thread,
/// gives the node-by-node sums bit for bit at 1, 2, 3 and 7 threads, on levels of many bricks
/// (so that every split falls inside the level), for both degrees and every boundary.
#[test]
fn restriction_is_the_same_at_every_thread_count() {
    let mut most_bricks = 0;
    for boundary in BOUNDARIES {
        for tree in trees_of_both_degrees(boundary) {
            for d in 1..tree.levels.len() {
                let (coarse, fine) = (&tree.levels[d - 1], &tree.levels[d]);
                most_bricks = most_bricks.max(coarse.bricks().brick_count());
                let fine_values: Vec<f64> = (0..fine.len())
                    .map(|i| {
                        if i % 7 == 0 {
                            0.0
                        } else {
                            (i % 11) as f64 * 0.3 - 1.4
                        }
                    })
                    .collect();
                let by_node = restricted_node_by_node(coarse, fine, &fine_values, 0.25);
                for threads in [1, 2, 3, 7] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .expect("a thread pool");
                    let mut by_part = vec![0.25; coarse.len()];
                    pool.install(|| restrict_into(coarse, fine, &fine_values, &mut by_part));
                    for (i, (a, b)) in by_node.iter().zip(&by_part).enumerate() {
                        assert!(
                            a.to_bits() == b.to_bits() || (*a == 0.0 && *b == 0.0),
                            "{boundary:?} depth {d} node {i} at {threads} threads: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }
    assert!(
        most_bricks > 7,
        "the levels have {most_bricks} bricks at most"
    );
}

/// A proxy's stencil is the B-spline's values at the three nodes around its cell, as
/// [`crate::bspline::Degree::stencil27`] evaluates them at the proxy's position, for both
/// degrees.
#[test]
fn proxy_stencil_is_the_bspline_at_the_proxy() {
    let inv_h = 16.0;
    for (degree, p) in [Degree::Two, Degree::One].into_iter().flat_map(|d| {
        [
            DVec3::new(0.3, 0.51, 0.77),
            DVec3::new(0.0, 0.999, 0.5),
            DVec3::new(0.0625, 0.125, 0.9),
        ]
        .map(|p| (d, p))
    }) {
        let t = p * inv_h;
        let proxies = Proxies {
            cell: vec![0],
            weight: vec![1.0],
            offset: vec![[t.x, t.y, t.z].map(|v| (v - v.floor()) as f32)],
            degree,
        };
        let (_, want) = degree.stencil27(p, inv_h);
        let got = proxies.stencil(0);
        for a in 0..3 {
            for k in 0..3 {
                assert!(
                    (got[a][k] - want[a][k]).abs() < 1e-6,
                    "{degree:?} {p} axis {a} node {k}"
                );
            }
            assert!((got[a].iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }
}

/// Proxies in cells inside the cube within one node of the core (as the pipeline keeps them),
/// one to three per cell, at the faces too; some of those cells lie in bricks without core
/// nodes.
fn proxies_near_the_core(level: &Level) -> Proxies {
    let n = 1i32 << level.depth;
    let mut proxies = Proxies {
        degree: level.degree,
        ..Proxies::default()
    };
    let near: Vec<u32> = (0..level.len() as u32)
        .filter(|&i| level.flags[i as usize] & crate::octree::NEAR != 0)
        .collect();
    for (k, &c) in near.iter().enumerate() {
        let coord = level.coord(c);
        if coord.iter().any(|&v| v < 0 || v >= n) || k % 3 == 1 {
            continue;
        }
        for j in 0..1 + k % 3 {
            let f = |a: usize| ((k * 7 + j * 5 + a * 3) % 10) as f32 / 10.0 + 0.05;
            proxies.cell.push(c);
            proxies.weight.push(0.5 + (k % 5) as f64);
            proxies.offset.push([f(0), f(1), f(2)]);
        }
    }
    assert!(!proxies.is_empty());
    proxies
}

/// The operator the solver's conjugate gradients need: A = L + αS applied to vectors that live
/// on the core with their mirrors filled (x = P x_core, P the extension by ± the mirrored
/// value) is symmetric positive definite on the core, for every boundary kind. With Dirichlet
/// the mirrors take −value across one face; the Laplacian's free-space stencils on the
/// odd-extended x equal the Galerkin matrix of the odd-folded basis on the cube, and screening
/// is Pᵀ S P; both symmetric.
#[test]
fn the_operator_is_symmetric_positive_definite_for_every_boundary() {
    for boundary in BOUNDARIES {
        for tree in trees_of_both_degrees(boundary) {
            let level = &tree.levels[tree.levels.len() - 1];
            let proxies = proxies_near_the_core(level);
            let on_core = |seed: usize| {
                let mut x = vec![0.0; level.len()];
                update_on_core(level, &mut x, |i, _| {
                    ((i * (7 + seed) + 3 * seed) % 23) as f64 / 23.0 - 0.45
                });
                x
            };
            let core_dot = |x: &[f64], core_values: &[f64]| -> f64 {
                level
                    .core
                    .iter()
                    .zip(core_values)
                    .map(|(&c, v)| x[c as usize] * v)
                    .sum()
            };
            for alpha in [0.0, 3.5] {
                let mut op = DepthOperator::new(level, &proxies, alpha);
                let (x, y) = (on_core(1), on_core(2));
                let (mut ax, mut ay) = (vec![0.0; level.core.len()], vec![0.0; level.core.len()]);
                op.apply(&x, &mut ax);
                op.apply(&y, &mut ay);
                let (yax, xay) = (core_dot(&y, &ax), core_dot(&x, &ay));
                assert!(
                    (yax - xay).abs() < 1e-12 * yax.abs().max(1.0),
                    "{boundary:?} α {alpha}: yᵀAx {yax} vs xᵀAy {xay}"
                );
                let xax = core_dot(&x, &ax);
                assert!(xax > 0.0, "{boundary:?} α {alpha}: xᵀAx {xax}");
            }
        }
    }
}

/// The screening term applied brick by brick (and the diagonal) against a node-by-node
/// reference: every proxy reads χ from the 3×3×3 nodes around its cell and gives back to
/// them, mirror nodes folding into the inside nodes they reflect (with Dirichlet's signs);
/// free, Neumann and Dirichlet boundaries, proxies in the middle, at the faces, corners and
/// across brick edges. Likewise the screening target's right-hand side.
#[test]
fn brick_screening_matches_the_node_by_node_sum() {
    for boundary in BOUNDARIES {
        for tree in trees_of_both_degrees(boundary) {
            let level = &tree.levels[tree.levels.len() - 1];
            let proxies = proxies_near_the_core(level);
            let bricks = CoreBricks::new(level);
            let cells = ScreeningCells::new(level, &proxies, &bricks);
            if level.core.len() < level.len() / 2 && level.degree == Degree::Two {
                assert!(
                    !cells.outside_core_bricks.is_empty(),
                    "the sparse tree has proxy cells in bricks without core nodes"
                );
            }
            let x: Vec<f64> = (0..level.len())
                .map(|i| ((i * 13) % 17) as f64 / 17.0 - 0.4)
                .collect();
            let mut x = x;
            fill_mirrors(level, &mut x);
            let alpha = 3.5;
            let mut got = vec![0.0; level.core.len()];
            DepthOperator::new(level, &proxies, alpha).apply(&x, &mut got);
            let mut laplacian = vec![0.0; level.core.len()];
            DepthOperator::new(level, &proxies, 0.0).apply(&x, &mut laplacian);
            let mut screened = vec![0.0; level.len()];
            let mut squares = vec![0.0; level.len()];
            let target = -0.5;
            let mut targeted = vec![0.0; level.len()];
            for q in 0..proxies.len() {
                let block = level.block27(proxies.cell[q]);
                let st = &proxies.stencil(q);
                let b = |slot: usize| st[0][slot % 3] * st[1][slot / 3 % 3] * st[2][slot / 9];
                let chi: f64 = (0..27)
                    .filter(|&s| block[s] != NONE)
                    .map(|s| x[block[s] as usize] * b(s))
                    .sum();
                for s in 0..27 {
                    if block[s] != NONE {
                        screened[block[s] as usize] += proxies.weight[q] * chi * b(s);
                        targeted[block[s] as usize] += proxies.weight[q] * target * b(s);
                        squares[block[s] as usize] += proxies.weight[q] * b(s) * b(s);
                    }
                }
            }
            // Pᵀ: a mirror node's sum goes to the node it reflects with the boundary's sign
            // (the diagonal's squares unsigned, see `ScreeningCells::accumulate`).
            for m in &level.mirrors {
                screened[m.inside as usize] +=
                    level.mirror_sign(m.flips) * screened[m.outside as usize];
                targeted[m.inside as usize] +=
                    level.mirror_sign(m.flips) * targeted[m.outside as usize];
                squares[m.inside as usize] += squares[m.outside as usize];
            }
            let mut op = DepthOperator::new(level, &proxies, alpha);
            let diagonal = op.diagonal();
            let lap_diagonal = DepthOperator::new(level, &proxies, 0.0).diagonal();
            // The screening target's right-hand side: the same sums with W_q t for W_q χ(q).
            let mut target_rhs = vec![0.0; level.core.len()];
            op.add_screening_target(target, &mut target_rhs);
            for (k, &c) in level.core.iter().enumerate() {
                let want = laplacian[k] + alpha * screened[c as usize];
                assert!(
                    (got[k] - want).abs() < 1e-12 * want.abs().max(1.0),
                    "{boundary:?}, node {:?}: {} vs {want}",
                    level.coord(c),
                    got[k]
                );
                let want = lap_diagonal[k] + alpha * squares[c as usize];
                assert!((diagonal[k] - want).abs() < 1e-12 * want.abs().max(1.0));
                let want = alpha * targeted[c as usize];
                assert!((target_rhs[k] - want).abs() < 1e-12 * want.abs().max(1.0));
            }
        }
    }
}

#[test]
fn neumann_mirrors_make_constants_harmonic_up_to_the_faces() {
    // With reflected (even) node functions the constant 1 is in the space and has zero
    // gradient everywhere in the cube, so L·1 vanishes at every node, the face nodes too;
    // with free boundaries the node functions simply stop and the face nodes feel it.
    for (neumann, degree) in [
        (true, Degree::Two),
        (false, Degree::Two),
        (true, Degree::One),
        (false, Degree::One),
    ] {
        let boundary = if neumann {
            Boundary::Neumann
        } else {
            Boundary::Free
        };
        let tree = Octree::build_for(vec![Vec::new(); 4], 3, boundary, degree);
        let level = &tree.levels[3];
        let proxies = Proxies::default();
        let mut op = DepthOperator::new(level, &proxies, 0.0);
        let mut x: Vec<f64> = (0..level.len())
            .map(|i| {
                if level.flags[i] & crate::octree::CORE != 0 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        fill_mirrors(level, &mut x);
        let mut out = vec![0.0; level.core.len()];
        op.apply(&x, &mut out);
        let worst = out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if neumann {
            assert!(worst < 1e-14, "{degree:?}: {worst}");
        } else {
            assert!(worst > 1e-3, "{degree:?}: {worst}");
        }
    }
}

/// Degree 1: hats on the corners reproduce linear functions, so prolonging the coefficients of
/// an affine f (its values at the coarse corners) gives its values at the fine corners, on the
/// core and on the faces, with free and Neumann boundaries; and restriction is the transpose.
#[test]
fn degree_one_prolongation_reproduces_affine_functions_and_restriction_is_its_transpose() {
    for boundary in [Boundary::Free, Boundary::Neumann] {
        let tree = Octree::build_for(vec![Vec::new(); 5], 4, boundary, Degree::One);
        let (coarse, fine) = (&tree.levels[3], &tree.levels[4]);
        let f = |p: [f64; 3]| 0.3 + 2.0 * p[0] - p[1] + 0.25 * p[2];
        let at = |level: &Level| -> Vec<f64> {
            let h = level.width();
            (0..level.len() as u32)
                .map(|i| f(level.coord(i).map(|c| c as f64 * h)))
                .collect()
        };
        let got = prolong(coarse, fine, &at(coarse), 1.0).unwrap();
        let want = at(fine);
        for &c in &fine.core {
            assert!(
                (got[c as usize] - want[c as usize]).abs() < 1e-12,
                "{boundary:?} {:?}",
                fine.coord(c)
            );
        }
        let core = |level: &Level, i: usize| level.flags[i] & crate::octree::CORE != 0;
        let u: Vec<f64> = (0..fine.len())
            .map(|i| if core(fine, i) { (i % 7) as f64 } else { 0.0 })
            .collect();
        let v: Vec<f64> = (0..coarse.len())
            .map(|i| {
                if core(coarse, i) {
                    (i % 5) as f64 - 2.0
                } else {
                    0.0
                }
            })
            .collect();
        let mut ru = vec![0.0; coarse.len()];
        restrict_into(coarse, fine, &u, &mut ru);
        let pv = prolong(coarse, fine, &v, 1.0).unwrap();
        let lhs: f64 = ru.iter().zip(&v).map(|(a, b)| a * b).sum();
        let rhs: f64 = u.iter().zip(&pv).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-9 * lhs.abs().max(1.0), "{lhs} {rhs}");
    }
}

/// The carry's coarse divergence at every depth is ⟨∇B_o, Σ_{e<d} V_e⟩ with each coarser V
/// prolonged to depth d on its own (to rounding: the carry adds them up on the way); a carry
/// cut at a base depth and continued from its hand-off gives the uncut carry's divergences
/// bit for bit; nothing is carried to the root.
#[test]
fn the_carried_coarse_divergence_is_every_coarser_fields_divergence() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool");
    for boundary in BOUNDARIES {
        for tree in trees_of_both_degrees(boundary) {
            let finest = tree.max_depth() as usize;
            let field_v: Vec<[Vec<f64>; 3]> = (0..finest)
                .map(|d| {
                    let level = &tree.levels[d];
                    let mut v: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        (0..level.len())
                            .map(|i| ((i * (a + 3) + d) % 11) as f64 - 5.0)
                            .collect()
                    });
                    fill_mirrors_field(level, &mut v);
                    v
                })
                .collect();
            let mut carry = FieldCarry::new(&tree, finest as u32, finest);
            for (d, v) in field_v.iter().enumerate() {
                carry.push(d, v.clone(), &pool).unwrap();
            }
            let (carried, handed_over) = carry.finish();
            assert!(handed_over.is_none());
            assert!(carried[0].is_empty());
            for (d, level) in tree.levels.iter().enumerate().skip(1) {
                let mut sum: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; level.len()]);
                for (e, v) in field_v.iter().enumerate().take(d) {
                    let mut g = v.clone();
                    for k in e..d {
                        let (coarse, fine) = (&tree.levels[k], &tree.levels[k + 1]);
                        g = std::array::from_fn(|a| prolong(coarse, fine, &g[a], 0.125).unwrap());
                        fill_mirrors_field(fine, &mut g);
                    }
                    for (s, g) in sum.iter_mut().zip(&g) {
                        s.iter_mut().zip(g).for_each(|(s, g)| *s += g);
                    }
                }
                let whole = divergence_of(level, &sum).unwrap();
                let scale = whole.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                assert_eq!(carried[d].len(), level.core.len());
                for (i, &c) in level.core.iter().enumerate() {
                    let (got, want) = (carried[d][i], whole[c as usize]);
                    assert!(
                        (got - want).abs() <= 1e-12 * scale,
                        "{boundary:?}, {:?}, depth {d}: {got} vs {want}",
                        level.degree
                    );
                }
            }
            // Cut at a base depth, then continued from its hand-off.
            let base = 2;
            let mut cut = FieldCarry::new(&tree, finest as u32, base);
            for (d, v) in field_v.iter().enumerate().take(base + 1) {
                cut.push(d, v.clone(), &pool).unwrap();
            }
            let (below, handed_over) = cut.finish();
            let mut above =
                FieldCarry::from_base(&tree, base, handed_over.unwrap(), &pool).unwrap();
            for (d, v) in field_v.iter().enumerate().skip(base + 1) {
                above.push(d, v.clone(), &pool).unwrap();
            }
            let (above, _) = above.finish();
            for d in 1..=finest {
                let got = if d <= base { &below[d] } else { &above[d] };
                assert!(
                    got.iter()
                        .zip(&carried[d])
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{boundary:?}: depth {d} cut at {base}"
                );
                assert_eq!(got.len(), carried[d].len());
            }
        }
    }
}

/// Proves the screening's weights per depth: α·2^D at every depth when the samples read no
/// noise (the noise's depth is D, or past it), and with a noise depth s < D, α·2^D up to ⌊s⌋
/// and α·2^s at the finer depths.
#[test]
fn screening_weights_keep_the_full_pull_up_to_the_noise_depth() {
    for s in [10.0, 12.5] {
        let exact = ScreeningWeights::new(4.0, 10, s);
        assert!((0..=10).all(|d| exact.at(d) == 4096.0), "{exact:?}");
    }
    // σ = 2^−7.5 / 10: the noise's depth is 7.5.
    let noisy = ScreeningWeights::new(4.0, 10, screening_depth(10, 0.1 * 2f64.powf(-7.5)));
    for d in 0..=7 {
        assert_eq!(noisy.at(d), 4096.0, "depth {d}");
    }
    for d in 8..=10 {
        let expected = 4.0 * 2f64.powf(7.5);
        assert!((noisy.at(d) / expected - 1.0).abs() < 1e-12, "depth {d}");
    }
}

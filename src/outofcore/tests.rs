//! The out-of-core parts against the in-memory pipeline's.

use super::base::{coarse_cores, BaseParts};
use super::slabs::SlabLayout;
use crate::bspline::Degree;
use crate::density::{estimate, samples_by_depth, DensityField, NormalSums};
use crate::octree::{sample_cells, Octree};
use crate::parallel::Watch;
use crate::solve::Solved;
use crate::system::FieldCarry;
use crate::Boundary;
use glam::DVec3;

/// Samples of a sphere (a golden-angle spiral) and of a small second sphere, with a few stray
/// samples, inside the unit cube: dense and sparse parts, so the samples' depths vary.
fn cloud() -> Vec<DVec3> {
    let mut points = Vec::new();
    let mut spiral = |centre: DVec3, radius: f64, n: usize| {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            points.push(centre + radius * DVec3::new(r * t.cos(), r * t.sin(), z));
        }
    };
    spiral(DVec3::new(0.45, 0.5, 0.5), 0.3, 30_000);
    spiral(DVec3::new(0.85, 0.2, 0.3), 0.05, 600);
    points.extend([
        DVec3::new(0.1, 0.9, 0.1),
        DVec3::new(0.12, 0.88, 0.13),
        DVec3::new(0.95, 0.95, 0.9),
    ]);
    points
}

/// The samples splatted at each depth that lie where `keep` says.
fn at_depth_where(
    positions: &[DVec3],
    at_depth: &[Vec<crate::density::DepthSample>],
    keep: impl Fn(DVec3) -> bool,
) -> Vec<Vec<crate::density::DepthSample>> {
    at_depth
        .iter()
        .map(|at| {
            at.iter()
                .copied()
                .filter(|s| keep(positions[s.sample as usize]))
                .collect()
        })
        .collect()
}

/// Proves the premise of the base: the core sets the octree builds from all samples are, at
/// every depth, the union of those built from each slab's samples alone, for every boundary
/// and degree, with slabs of unequal widths (one holding only stray samples).
#[test]
fn the_core_sets_of_the_cloud_are_the_union_of_its_slabs() {
    let positions = cloud();
    let watch = Watch::new();
    let field = DensityField::splat(&positions, None, 7);
    let density = estimate(&field, None, &positions, 9, 1.5, &watch).expect("not cancelled");
    let confidence = vec![1.0; positions.len()];
    let unlimited = |_: &[u64]| Ok(());
    for boundary in [Boundary::Free, Boundary::Neumann, Boundary::Dirichlet] {
        for degree in [Degree::One, Degree::Two] {
            let mut density = crate::density::SampleDensity {
                area: density.area.clone(),
                depth: density.depth.clone(),
                quantiles: Vec::new(),
            };
            let coarsest = Octree::coarsest_depth(boundary, degree);
            let at_depth = samples_by_depth(&mut density, &confidence, 9, 3, coarsest);
            let whole = Octree::core_sets(
                sample_cells(&at_depth, &positions),
                3,
                boundary,
                degree,
                &watch,
                &unlimited,
            )
            .expect("not cancelled");
            let walls = [0.0, 0.2, 0.43, 0.5, 0.71, 1.0];
            let slabs: Vec<Vec<Vec<u64>>> = walls
                .windows(2)
                .map(|w| {
                    let at = at_depth_where(&positions, &at_depth, |p| {
                        (w[0]..w[1]).contains(&p.x) || (w[1] == 1.0 && p.x >= 1.0)
                    });
                    let cells = sample_cells(&at, &positions);
                    Octree::core_sets(cells, 3, boundary, degree, &watch, &unlimited)
                        .expect("not cancelled")
                })
                .collect();
            let depths = whole.len() as u32 - 1;
            let union = coarse_cores(slabs.iter().map(|s| s.as_slice()), depths);
            assert_eq!(union, whole, "{boundary:?}, degree {degree:?}");
            // And each slab alone holds less than the whole at the finest depth.
            assert!(slabs
                .iter()
                .all(|s| s[depths as usize].len() < whole[depths as usize].len()));
        }
    }
}

/// Proves the layout built from the cloud's column counts gives every sample one owner and
/// balances the owners' counts to within one column's count.
#[test]
fn the_layout_balances_the_clouds_columns() {
    let positions = cloud();
    let wall_depth = 6;
    let mut counts = vec![0u64; 1 << wall_depth];
    let probe = SlabLayout::balanced(&counts, wall_depth, 1, 0);
    for p in &positions {
        counts[probe.column_of(p.x) as usize] += 1;
    }
    let layout = SlabLayout::balanced(&counts, wall_depth, 5, 2);
    assert_eq!(layout.len(), 5);
    let mut owned = vec![0u64; layout.len()];
    for p in &positions {
        owned[layout.slab_of_column(layout.column_of(p.x))] += 1;
    }
    let share = positions.len() as u64 / 5;
    let widest_column = *counts.iter().max().expect("columns");
    assert_eq!(owned.iter().sum::<u64>(), positions.len() as u64);
    for (k, &n) in owned.iter().enumerate() {
        assert!(
            n.abs_diff(share) <= widest_column,
            "slab {k}: {n} points, share {share}"
        );
    }
}

/// A bumpy sphere's samples as the in-memory pipeline prepares them: in Morton order in the
/// unit cube, with their density and the samples splatted at each depth.
struct Cloud {
    samples: crate::points::Samples,
    area: Vec<f64>,
    at_depth: Vec<Vec<crate::density::DepthSample>>,
}

/// The positions and normals of the bumpy sphere, from a spiral of `n` (thinned near the poles).
fn bumpy_sphere_points(n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        if (z > 0.6 && i % 16 != 0) || (z < -0.6 && i % 64 != 0) {
            continue;
        }
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let bump = 1.0 + 0.05 * (5.0 * t.sin() * z).sin();
        let u = [r * t.cos(), r * t.sin(), z];
        positions.push(u.map(|c| (c * bump) as f32));
        normals.push(u.map(|c| c as f32));
    }
    (positions, normals)
}

/// A bumpy sphere sampled at three densities (16 and 64 times sparser near the poles, so that
/// samples are splatted at several depths and every depth's V has something to carry to the
/// next), ready for `params`.
fn bumpy_sphere(params: &crate::Params) -> Cloud {
    use crate::points::{PointSet, Samples, UnitCubeMap};
    let (positions, normals) = bumpy_sphere_points(40_000);
    let points = PointSet::from_slices(&positions, &normals).expect("valid points");
    let map = UnitCubeMap::fit(points.positions(), params.scale as f64);
    let samples = Samples::in_morton_order(&points, &map, params.depth).expect("fits");
    let watch = Watch::new();
    let field = DensityField::splat(&samples.positions, Some(&samples.confidence), 6);
    let normals = NormalSums::splat(
        &samples.positions,
        Some(&samples.confidence),
        &samples.normals,
        6,
    );
    let mut density = estimate(
        &field,
        Some(&normals),
        &samples.positions,
        params.depth,
        1.5,
        &watch,
    )
    .expect("not cancelled");
    let at_depth = samples_by_depth(
        &mut density,
        &samples.confidence,
        params.depth,
        params.effective_full_depth(),
        Octree::coarsest_depth(params.boundary, params.node_degree()),
    );
    Cloud {
        samples,
        area: density.area,
        at_depth,
    }
}

impl Cloud {
    /// The samples at each depth that `keep` admits (by position).
    fn at_depth_where(
        &self,
        keep: impl Fn(DVec3) -> bool,
    ) -> Vec<Vec<crate::density::DepthSample>> {
        at_depth_where(&self.samples.positions, &self.at_depth, keep)
    }

    /// The core sets of the samples `at_depth`.
    fn cores(
        &self,
        at_depth: &[Vec<crate::density::DepthSample>],
        params: &crate::Params,
    ) -> Vec<Vec<u64>> {
        Octree::core_sets(
            sample_cells(at_depth, &self.samples.positions),
            params.effective_full_depth(),
            params.boundary,
            params.node_degree(),
            &Watch::new(),
            &|_| Ok(()),
        )
        .expect("not cancelled")
    }

    /// ρ of every depth and V of every depth but the finest, splatted from the samples
    /// `at_depth` on `tree`, as the pipeline's splat and system stages compute them.
    fn right_hand_sides(
        &self,
        tree: &Octree,
        at_depth: &[Vec<crate::density::DepthSample>],
        params: &crate::Params,
    ) -> (Vec<Vec<f64>>, Vec<[Vec<f64>; 3]>) {
        let splat = |d: usize| {
            crate::splat::splat_level(&tree.levels[d], &self.samples, &at_depth[d], params)
        };
        let finest = tree.max_depth() as usize;
        let rho_finest = crate::system::finest_right_hand_side(
            &tree.levels[finest],
            splat(finest).expect("fits"),
        )
        .expect("fits");
        let mut field_v = Vec::new();
        let own = crate::system::coarser_divergences(tree, splat, |_, v| {
            field_v.push(v);
            Ok(())
        })
        .expect("fits");
        let rho = crate::system::right_hand_sides(tree, rho_finest, own, |_| Ok(()))
            .expect("not cancelled");
        (rho, field_v)
    }
}

/// The coarse divergences a [`FieldCarry`] leaves on `tree` from V of `field_v` (index d), as
/// the pipeline's and the passes' carries make them: from the root up to `last` (the finest,
/// or a base's last depth), or on from a base's hand-off (its depth and field); and the field
/// it hands over at `last`.
fn carried(
    tree: &Octree,
    field_v: &[[Vec<f64>; 3]],
    finest: u32,
    last: usize,
    base: Option<(usize, [Vec<f64>; 3])>,
) -> (Vec<Vec<f64>>, Option<[Vec<f64>; 3]>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool");
    let (mut carry, from) = match base {
        None => (FieldCarry::new(tree, finest, last), 0),
        Some((depth, field)) => (
            FieldCarry::from_base(tree, depth, field, &pool).expect("fits"),
            depth + 1,
        ),
    };
    for (d, v) in field_v.iter().enumerate().take(last + 1).skip(from) {
        carry.push(d, v.clone(), &pool).expect("fits");
    }
    carry.finish()
}

/// The in-memory pipeline's system for the bumpy sphere, up to the solve: the tree, ρ and V of
/// every depth, the samples and their screening weights.
struct SystemParts {
    tree: Octree,
    rho: Vec<Vec<f64>>,
    field_v: Vec<[Vec<f64>; 3]>,
    positions: Vec<DVec3>,
    screening_weights: Vec<f64>,
}

/// The bumpy sphere's χ solved in memory as the pipeline solves it, its isovalue, and its
/// samples in the unit cube: the whole surface the slabs' seams are measured against.
pub(super) fn bumpy_sphere_chi(
    params: &crate::Params,
) -> (crate::evaluate::Indicator, f64, Vec<DVec3>) {
    use crate::solve::{cascade, Depths, System};
    let cloud = bumpy_sphere(params);
    let parts = sphere_system(params);
    let finest = parts.tree.max_depth();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool");
    let coefficients = cascade(
        System {
            tree: &parts.tree,
            rho: parts.rho,
            coarse_div: carried(&parts.tree, &parts.field_v, finest, finest as usize, None).0,
            positions: &parts.positions,
            screening_weights: &parts.screening_weights,
            proxy_groups: None,
            screening: crate::system::ScreeningWeights::new(
                params.point_weight,
                params.depth,
                params.depth as f64,
            ),
            depths: Depths::All,
        },
        params,
        &pool,
        &mut |_| true,
        &mut Vec::new(),
    )
    .expect("solved");
    let chi = crate::evaluate::Indicator {
        tree: parts.tree,
        coefficients,
    };
    let isovalue = crate::isovalue::weighted_mean(
        &chi,
        &cloud.samples.positions,
        &cloud.area,
        &cloud.samples.confidence,
        &Watch::new(),
    )
    .expect("not cancelled");
    (chi, isovalue, cloud.samples.positions)
}

fn sphere_system(params: &crate::Params) -> SystemParts {
    let cloud = bumpy_sphere(params);
    let tree = Octree::from_cores(
        cloud.cores(&cloud.at_depth, params),
        params.boundary,
        params.node_degree(),
        &Watch::new(),
    )
    .expect("not cancelled");
    let (rho, field_v) = cloud.right_hand_sides(&tree, &cloud.at_depth, params);
    let screening_weights = crate::system::sample_weights(&cloud.area, &cloud.samples.confidence);
    SystemParts {
        tree,
        rho,
        field_v,
        positions: cloud.samples.positions,
        screening_weights,
    }
}

/// Proves the solve can be cut at a base depth B without changing a bit: solving depths
/// 0..=B on a tree that stops at B (as the out-of-core base does), then the depths above B
/// from the base's coefficients and its accumulated V, gives the coefficients of the whole
/// solve, for both degrees and every boundary.
#[test]
fn a_cascade_cut_at_the_base_depth_gives_the_whole_cascades_coefficients() {
    use crate::solve::{cascade, Depths, System};
    for (degree, boundary) in [
        (2, Boundary::Neumann),
        (2, Boundary::Free),
        (1, Boundary::Dirichlet),
        (1, Boundary::Neumann),
    ] {
        let params = crate::Params::default()
            .with_depth(7)
            .with_degree(degree)
            .with_boundary(boundary);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool");
        let solve = |parts: &SystemParts, coarse_div: Vec<Vec<f64>>, depths: Depths| {
            cascade(
                System {
                    tree: &parts.tree,
                    rho: parts.rho.clone(),
                    coarse_div,
                    positions: &parts.positions,
                    screening_weights: &parts.screening_weights,
                    proxy_groups: None,
                    screening: crate::system::ScreeningWeights::new(
                        params.point_weight,
                        params.depth,
                        params.depth as f64,
                    ),
                    depths,
                },
                &params,
                &pool,
                &mut |_| true,
                &mut Vec::new(),
            )
            .expect("solved")
        };
        let whole_parts = sphere_system(&params);
        let finest = whole_parts.tree.max_depth();
        let all = |parts: &SystemParts| {
            carried(&parts.tree, &parts.field_v, finest, finest as usize, None)
        };
        let whole = solve(&whole_parts, all(&whole_parts).0, Depths::All);
        for base_depth in [3usize, 5] {
            let mut base_parts = sphere_system(&params);
            base_parts.tree.levels.truncate(base_depth + 1);
            base_parts.rho.truncate(base_depth + 1);
            base_parts.field_v.truncate(base_depth + 1);
            let (base_div, handed_over) = carried(
                &base_parts.tree,
                &base_parts.field_v,
                finest,
                base_depth,
                None,
            );
            let base = solve(
                &base_parts,
                base_div,
                Depths::Base {
                    last: base_depth,
                    finest,
                },
            );
            assert_eq!(base.len(), base_depth + 1);
            let above_div = carried(
                &whole_parts.tree,
                &whole_parts.field_v,
                finest,
                finest as usize,
                Some((base_depth, handed_over.expect("a base below the finest"))),
            )
            .0;
            let above = solve(&whole_parts, above_div, Depths::Above(base));
            assert_eq!(above.len(), whole.len());
            for (d, (a, w)) in above.iter().zip(&whole).enumerate() {
                assert!(
                    a.iter().zip(w).all(|(a, w)| a.to_bits() == w.to_bits()),
                    "degree {degree}, {boundary:?}, base {base_depth}: depth {d} differs"
                );
            }
        }
    }
}

/// Proves the padding the design asks for: a slab's tree, its depths up to B taken from the
/// base (the union of the slabs' own cores) and the finer ones built from its points plus
/// those of its neighbours within the padding, has exactly the whole cloud's core nodes over
/// the slab's own columns at every depth above B, when the padding is three nodes of depth B
/// (12 columns of the wall depth B + 2); and not always with no padding. (Here the cores agree
/// from 6 columns on, 3 nodes of depth B + 1, a sample's reach in the core at every depth; the
/// halos two nodes wider need 4 more: 12 covers both.)
#[test]
fn a_slabs_tree_with_its_padding_is_the_whole_tree_over_its_columns() {
    use crate::octree::unpack;
    let positions = cloud();
    let watch = Watch::new();
    let field = DensityField::splat(&positions, None, 7);
    let mut density = estimate(&field, None, &positions, 9, 1.5, &watch).expect("not cancelled");
    let confidence = vec![1.0; positions.len()];
    let unlimited = |_: &[u64]| Ok(());
    let boundary = Boundary::Neumann;
    let degree = Degree::Two;
    let at_depth = samples_by_depth(&mut density, &confidence, 9, 3, 0);
    let finest = at_depth.len() - 1;
    let cores_of = |keep: &dyn Fn(DVec3) -> bool| {
        Octree::core_sets(
            sample_cells(&at_depth_where(&positions, &at_depth, keep), &positions),
            3,
            boundary,
            degree,
            &watch,
            &unlimited,
        )
        .expect("not cancelled")
    };
    let whole = cores_of(&|_| true);
    let base_depth = 5u32;
    let wall_depth = base_depth + 2;
    let mut counts = vec![0u64; 1 << wall_depth];
    let probe = SlabLayout::balanced(&counts, wall_depth, 1, 0);
    for p in &positions {
        counts[probe.column_of(p.x) as usize] += 1;
    }
    let mismatches = |padding: u32| -> usize {
        let layout = SlabLayout::balanced(&counts, wall_depth, 4, padding);
        let own: Vec<Vec<Vec<u64>>> = (0..layout.len())
            .map(|k| cores_of(&|p| layout.slab_of_column(layout.column_of(p.x)) == k))
            .collect();
        let base = coarse_cores(own.iter().map(|c| c.as_slice()), base_depth);
        assert_eq!(base[..], whole[..=base_depth as usize]);
        let mut mismatches = 0;
        for k in 0..layout.len() {
            let padded = layout.padded(k);
            let slab = cores_of(&|p| padded.contains(&layout.column_of(p.x)));
            let owned = layout.owned(k);
            for d in base_depth as usize + 1..=finest {
                // A node is over the slab's columns when its cell's x range lies in them.
                let in_owned = |key: &u64| {
                    let x = unpack(*key)[0] as i64;
                    let shift = d as i64 - wall_depth as i64;
                    let column = if shift >= 0 { x >> shift } else { x << -shift };
                    column >= owned.start as i64 && column < owned.end as i64
                };
                let a: Vec<u64> = whole[d].iter().copied().filter(in_owned).collect();
                let b: Vec<u64> = slab[d].iter().copied().filter(in_owned).collect();
                mismatches += a.len().abs_diff(b.len())
                    + a.iter().filter(|k| b.binary_search(k).is_err()).count();
            }
        }
        mismatches
    };
    assert_eq!(mismatches(12), 0);
    assert!(
        mismatches(0) > 0,
        "without padding the slabs lose nodes near their walls"
    );
}

/// Proves the base's right-hand sides and fields are sums over the slabs: on trees that share
/// the base's depths (the union of the slabs' own cores up to B) and have each slab's own finer
/// depths, the ρ and V each slab splats from its own samples add up, node by node, to the whole
/// cloud's at every depth up to B (to rounding: the sums are taken in another order).
#[test]
fn the_base_right_hand_sides_are_the_sums_of_the_slabs() {
    for (degree, boundary) in [(2, Boundary::Neumann), (1, Boundary::Dirichlet)] {
        let params = crate::Params::default()
            .with_depth(7)
            .with_degree(degree)
            .with_boundary(boundary);
        let cloud = bumpy_sphere(&params);
        let whole_tree = Octree::from_cores(
            cloud.cores(&cloud.at_depth, &params),
            boundary,
            params.node_degree(),
            &Watch::new(),
        )
        .expect("not cancelled");
        let (whole_rho, whole_v) = cloud.right_hand_sides(&whole_tree, &cloud.at_depth, &params);
        let base_depth = 4usize;
        let walls = [0.0, 0.35, 0.5, 0.62, 1.01];
        let own: Vec<_> = walls
            .windows(2)
            .map(|w| cloud.at_depth_where(|p| (w[0]..w[1]).contains(&p.x)))
            .collect();
        let own_cores: Vec<Vec<Vec<u64>>> = own.iter().map(|at| cloud.cores(at, &params)).collect();
        let base = coarse_cores(own_cores.iter().map(|c| c.as_slice()), base_depth as u32);
        let mut sums = BaseParts::default();
        for (at, cores) in own.iter().zip(own_cores) {
            let mut slab_cores = base.clone();
            slab_cores.extend(cores.into_iter().skip(base_depth + 1));
            let tree =
                Octree::from_cores(slab_cores, boundary, params.node_degree(), &Watch::new())
                    .expect("not cancelled");
            for d in 0..=base_depth {
                assert_eq!(
                    tree.levels[d].keys, whole_tree.levels[d].keys,
                    "the base's depth {d}"
                );
            }
            let (rho, v) = cloud.right_hand_sides(&tree, at, &params);
            sums.add(&rho, &v, base_depth);
        }
        // Rounding relative to the largest value of any depth (a depth whose values cancel,
        // like the root's, has no scale of its own).
        let largest = |vectors: &mut dyn Iterator<Item = &Vec<f64>>| {
            vectors.flatten().fold(0.0f64, |m, x| m.max(x.abs()))
        };
        let rho_scale = largest(&mut whole_rho.iter());
        let v_scale = largest(&mut whole_v.iter().flatten());
        let close = |a: &[f64], b: &[f64], scale: f64| {
            a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
        };
        for d in 0..=base_depth {
            assert!(
                close(&sums.rho[d], &whole_rho[d], rho_scale),
                "degree {degree}: ρ at depth {d}"
            );
            for (sum, whole) in sums.field_v[d].iter().zip(&whole_v[d]) {
                assert!(
                    close(sum, whole, v_scale),
                    "degree {degree}: V at depth {d}"
                );
            }
        }
        // (Not a test of zeros: from depth 2 on every depth has a right-hand side, and the
        // sparse caps put V at the base depth.)
        for (d, rho) in whole_rho.iter().enumerate().take(base_depth + 1).skip(2) {
            assert!(rho.iter().any(|&r| r != 0.0), "depth {d}'s ρ");
        }
        assert!(whole_v[base_depth][0].iter().any(|&v| v != 0.0));
    }
}

/// Proves the whole design in one process, on the bumpy sphere at depth 7 (full depth 3) with
/// base depth 4 and four slabs: the base solved from the slabs' summed parts, then each slab's finer depths on
/// its own points plus 12 columns of padding (graded as the runs grade it, which at depth 7
/// keeps the whole padding), give at every node a slab owns, at every depth
/// from the wall depth B + 2 on, coefficients that differ from the in-memory solve's by less than the
/// in-memory solve's own differ from the converged solution (its solver stops at a relative
/// residual of 1e-2 per depth).
#[test]
fn slabs_solved_above_a_shared_base_match_the_in_memory_solve() {
    slabs_above_a_shared_base_against_the_in_memory_solve(super::passes::FINE_PADDING_NODES);
}

/// Proves the graded padding ([`super::passes::grade_padding`]) where it cuts deep: with the
/// finest depth's splats kept within 6 of its nodes of a slab's columns (a quarter of the
/// padding's width) and the rest splatted one depth coarser, the slabs still match the
/// in-memory solve as the cascade's own tolerance does.
#[test]
fn slabs_with_a_narrow_graded_padding_match_the_in_memory_solve() {
    slabs_above_a_shared_base_against_the_in_memory_solve(6);
}

/// The bumpy sphere at depth 7 in four slabs above a base of depth 4, each slab's splats
/// graded to `fine_padding` nodes past the wall depth: at every node a slab owns, its
/// coefficient differs from the in-memory solve's by less than the in-memory solve's from the
/// converged one.
fn slabs_above_a_shared_base_against_the_in_memory_solve(fine_padding: u32) {
    use crate::solve::{cascade, Depths, System};
    // The base holds the complete depths (a complete depth spans the cube, far from any slab).
    let params = crate::Params::default().with_depth(7).with_full_depth(3);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool");
    let screening = crate::system::ScreeningWeights::new(
        params.point_weight,
        params.depth,
        params.depth as f64,
    );
    let cloud = bumpy_sphere(&params);
    let weights = crate::system::sample_weights(&cloud.area, &cloud.samples.confidence);
    let degree = params.node_degree();
    let tree_of = |cores: Vec<Vec<u64>>| {
        Octree::from_cores(cores, params.boundary, degree, &Watch::new()).expect("not cancelled")
    };
    let solve = |tree: &Octree, rho, coarse_div, depths, params: &crate::Params| {
        cascade(
            System {
                tree,
                rho,
                coarse_div,
                positions: &cloud.samples.positions,
                screening_weights: &weights,
                proxy_groups: None,
                screening,
                depths,
            },
            params,
            &pool,
            &mut |_| true,
            &mut Vec::new(),
        )
        .expect("solved")
    };
    // In memory, and converged.
    let whole_tree = tree_of(cloud.cores(&cloud.at_depth, &params));
    let finest = whole_tree.max_depth();
    let (rho, v) = cloud.right_hand_sides(&whole_tree, &cloud.at_depth, &params);
    let whole_div = carried(&whole_tree, &v, finest, finest as usize, None).0;
    let whole = solve(
        &whole_tree,
        rho.clone(),
        whole_div.clone(),
        Depths::All,
        &params,
    );
    let converged_params = params
        .clone()
        .with_solver_tolerance(1e-9)
        .with_max_solver_iterations(2000);
    let converged = solve(&whole_tree, rho, whole_div, Depths::All, &converged_params);

    // The slabs: balanced columns of depth B + 2.
    let base_depth = 4usize;
    let wall_depth = base_depth as u32 + 2;
    let mut counts = vec![0u64; 1 << wall_depth];
    let probe = SlabLayout::balanced(&counts, wall_depth, 1, 0);
    for p in &cloud.samples.positions {
        counts[probe.column_of(p.x) as usize] += 1;
    }
    let layout = SlabLayout::balanced(&counts, wall_depth, 4, 12);
    assert!(params.effective_full_depth() as usize <= base_depth);
    assert_eq!(layout.len(), 4);
    let column = |p: DVec3| layout.column_of(p.x);
    let own: Vec<_> = (0..layout.len())
        .map(|k| cloud.at_depth_where(|p| layout.slab_of_column(column(p)) == k))
        .collect();
    let own_cores: Vec<Vec<Vec<u64>>> = own.iter().map(|at| cloud.cores(at, &params)).collect();
    let base_cores = coarse_cores(own_cores.iter().map(|c| c.as_slice()), base_depth as u32);

    // The base: the slabs' own parts summed, solved on the base's depths alone.
    let mut sums = BaseParts::default();
    for (at, cores) in own.iter().zip(&own_cores) {
        let mut slab_cores = base_cores.clone();
        slab_cores.extend(cores.iter().skip(base_depth + 1).cloned());
        let (rho, v) = cloud.right_hand_sides(&tree_of(slab_cores), at, &params);
        sums.add(&rho, &v, base_depth);
    }
    let base_tree = tree_of(base_cores.clone());
    let (base_div, handed_over) = carried(&base_tree, &sums.field_v, finest, base_depth, None);
    let base = Solved {
        coefficients: solve(
            &base_tree,
            sums.rho,
            base_div,
            Depths::Base {
                last: base_depth,
                finest,
            },
            &params,
        ),
        field_v: handed_over.expect("a base below the finest"),
    };

    // Each slab above the base, on its points and padding; compared where it owns nodes.
    let mut worst_slab = 0.0f64;
    let mut worst_in_memory = 0.0f64;
    let mut compared = 0;
    for k in 0..layout.len() {
        let padded = layout.padded(k);
        let mut at = cloud.at_depth_where(|p| padded.contains(&column(p)));
        super::passes::grade_padding(&mut at, &cloud.samples.positions, &layout, k, fine_padding);
        let mut slab_cores = base_cores.clone();
        slab_cores.extend(cloud.cores(&at, &params).into_iter().skip(base_depth + 1));
        let tree = tree_of(slab_cores);
        let (rho, v) = cloud.right_hand_sides(&tree, &at, &params);
        let above = Some((base_depth, base.field_v.clone()));
        let slab_div = carried(&tree, &v, finest, finest as usize, above).0;
        let above = Depths::Above(base.coefficients.clone());
        let slab = solve(&tree, rho, slab_div, above, &params);
        let owned = layout.owned(k);
        for d in wall_depth as usize..=finest as usize {
            let level = &tree.levels[d];
            for &c in level.core.iter() {
                // Owned: the node's cell lies in the slab's columns (d > B + 2 here).
                let coord = level.coord(c);
                let x_column = (coord[0] as i64) >> (d - wall_depth as usize);
                if !(owned.start as i64..owned.end as i64).contains(&x_column) {
                    continue;
                }
                let w = whole_tree.levels[d]
                    .find(coord)
                    .expect("the slab's node is the whole's") as usize;
                worst_slab = worst_slab.max((slab[d][c as usize] - whole[d][w]).abs());
                worst_in_memory = worst_in_memory.max((whole[d][w] - converged[d][w]).abs());
                compared += 1;
            }
        }
    }
    assert!(compared > 10_000, "{compared} nodes compared");
    assert!(
        worst_slab < worst_in_memory,
        "slabs differ by up to {worst_slab:e}, the in-memory solve from the converged one by {worst_in_memory:e}"
    );
    assert!(worst_slab > 0.0, "the slabs solve their own systems");
}

/// Proves the base's screening samples are the merge of its slabs' groups: at every proxy
/// depth, the proxies built from the slabs' own samples' groups, merged, are those the whole
/// cloud's samples give (the same cells, weights and offsets, to rounding), with walls that
/// cut cells of every coarser proxy depth.
#[test]
fn the_base_proxies_are_the_merge_of_the_slabs_groups() {
    use super::base::merge_groups;
    use crate::system::{sample_groups, Proxies};
    let params = crate::Params::default().with_depth(7);
    let parts = sphere_system(&params);
    let walls = [0.0, 0.33, 0.5, 0.61, 1.01];
    for d in 0..=5u32 {
        let level = &parts.tree.levels[d as usize];
        let proxy_depth = crate::system::proxy_depth(d, parts.tree.max_depth());
        let whole = Proxies::build(
            level,
            &parts.positions,
            &parts.screening_weights,
            proxy_depth,
        );
        let slab_groups: Vec<_> = walls
            .windows(2)
            .map(|w| {
                let (positions, weights): (Vec<DVec3>, Vec<f64>) = parts
                    .positions
                    .iter()
                    .zip(&parts.screening_weights)
                    .filter(|(p, _)| (w[0]..w[1]).contains(&p.x))
                    .map(|(p, w)| (*p, *w))
                    .unzip();
                sample_groups(&positions, &weights, proxy_depth)
            })
            .collect();
        let merged = slab_groups
            .iter()
            .fold(Vec::new(), |merged, slab| merge_groups(merged, slab));
        let base = Proxies::from_groups(level, &merged, proxy_depth);
        assert_eq!(base.cell, whole.cell, "depth {d}");
        assert!(!whole.is_empty());
        for q in 0..whole.len() {
            let relative = (base.weight[q] - whole.weight[q]).abs() / whole.weight[q];
            assert!(relative < 1e-12, "depth {d}, proxy {q}: weight");
            for a in 0..3 {
                assert!(
                    (base.offset[q][a] - whole.offset[q][a]).abs() < 1e-6,
                    "depth {d}"
                );
            }
        }
    }
}

/// Proves the scan's cube is the in-memory one: the bounding box gathered chunk by chunk fits
/// the same unit-cube map as all the positions at once, for any chunk size.
#[test]
fn the_cube_fitted_from_chunks_is_the_cube_fitted_at_once() {
    use crate::points::{Bounds, UnitCubeMap};
    let positions: Vec<[f32; 3]> = cloud()
        .iter()
        .map(|p| [p.x as f32 * 3.0 - 1e3, p.y as f32 + 0.5, -(p.z as f32)])
        .collect();
    let whole = UnitCubeMap::fit(&positions, 1.1);
    for chunk in [1, 7, 1000, positions.len()] {
        let mut bounds = Bounds::default();
        for part in positions.chunks(chunk) {
            bounds.extend(part.iter().map(|p| DVec3::from(p.map(f64::from))));
        }
        assert_eq!(
            UnitCubeMap::fit_bounds(&bounds, 1.1),
            whole,
            "chunks of {chunk}"
        );
    }
}

/// The bumpy sphere's points (input coordinates) written as a binary PLY in `dir`.
fn bumpy_sphere_file(dir: &std::path::Path) -> (std::path::PathBuf, crate::PointSet) {
    let mut points = crate::ply::PlyPoints::default();
    (points.positions, points.normals) = bumpy_sphere_points(60_000);
    let path = dir.join("bumpy_sphere.ply");
    crate::ply::write_point_cloud(&path, &points, crate::ply::PlyFormat::BinaryLittleEndian)
        .expect("written");
    let set = crate::PointSet::from_slices(&points.positions, &points.normals).expect("valid");
    (path, set)
}

/// Proves the passes over files: the bumpy sphere read from a PLY in chunks, binned to four
/// slabs, its base solved from the slabs' summed parts and each slab above it, gives χ within
/// the in-memory solver's own error of the in-memory χ at every sample, the same isovalue to
/// that error, and one χ across every wall: the two slabs beside a wall evaluate the same
/// value, bit for bit, near it. The temporary directory is gone once the result is dropped.
#[test]
fn the_passes_over_files_solve_the_in_memory_chi_with_one_chi_across_walls() {
    use super::passes::{load_solution, solve_slabs, Plan, SlabCount};
    let dir = super::scratch::Scratch::create(None).expect("a directory for the input");
    let (path, points) = bumpy_sphere_file(dir.path());
    let params = crate::Params::default()
        .with_depth(8)
        .with_full_depth(3)
        .with_threads(2);
    let in_memory = crate::reconstruct_with_implicit(&points, &params)
        .expect("reconstructed")
        .1;
    let converged = crate::reconstruct_with_implicit(
        &points,
        &params
            .clone()
            .with_solver_tolerance(1e-9)
            .with_max_solver_iterations(3000),
    )
    .expect("reconstructed")
    .1;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool");
    let plan = Plan {
        base_depth: Some(4),
        slabs: SlabCount::Exactly(4),
        padding: 12,
        chunk: 5_000,
        confidence: false,
        temp_dir: Some(dir.path().to_path_buf()),
    };
    let solved = solve_slabs(
        &path,
        &params,
        &plan,
        &super::team::Alone,
        &pool,
        &mut |_, _| true,
    )
    .expect("solved out of core");
    assert_eq!(solved.layout.len(), 4);
    let scratch_dir = solved.scratch.path().to_path_buf();
    assert!(scratch_dir.is_dir());
    let map = solved.scan.map;
    let chis: Vec<_> = (0..4)
        .map(|k| load_solution(&solved, k, &pool).expect("loaded"))
        .collect();
    let (mut worst_slab, mut worst_in_memory) = (0.0f64, 0.0f64);
    for p in points.positions() {
        let unit = map.to_unit(*p);
        let k = solved
            .layout
            .slab_of_column(solved.layout.column_of(unit.x));
        let input = p.map(f64::from);
        let mem = in_memory.value(input);
        worst_slab = worst_slab.max((chis[k].value(unit) - mem).abs());
        worst_in_memory = worst_in_memory.max((mem - converged.value(input)).abs());
    }
    println!(
        "χ: slabs vs in memory {worst_slab:e}, in memory vs converged {worst_in_memory:e}; \
         γ {} vs {} (converged {})",
        solved.isovalue,
        in_memory.isovalue(),
        converged.isovalue()
    );
    assert!(worst_slab > 0.0 && worst_slab < worst_in_memory);
    assert!(
        (solved.isovalue - in_memory.isovalue()).abs()
            < (in_memory.isovalue() - converged.isovalue()).abs()
    );
    // One χ across each wall: points within two finest cells of it, on a grid across y and z.
    let finest_h = (-(solved.finest as f64)).exp2();
    let mut compared = 0;
    for k in 0..3 {
        let wall = solved.layout.walls[k + 1] as f64 / (1u64 << solved.layout.wall_depth) as f64;
        for i in 0..40 {
            for j in 0..40 {
                for dx in [-2.0, -0.5, 0.0, 0.7, 2.0] {
                    let q = glam::DVec3::new(
                        wall + dx * finest_h,
                        0.2 + 0.6 * i as f64 / 39.0,
                        0.2 + 0.6 * j as f64 / 39.0,
                    );
                    let (a, b) = (chis[k].value(q), chis[k + 1].value(q));
                    assert_eq!(a.to_bits(), b.to_bits(), "wall {k} at {q}: {a} vs {b}");
                    compared += 1;
                }
            }
        }
    }
    assert_eq!(compared, 3 * 40 * 40 * 5);
    drop(chis);
    drop(solved);
    assert!(!scratch_dir.exists(), "the temporary directory is removed");
}

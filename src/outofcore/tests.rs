//! The out-of-core parts against the in-memory pipeline's.

use super::base::coarse_cores;
use super::slabs::SlabLayout;
use crate::bspline::Degree;
use crate::density::{estimate, samples_by_depth, DensityField};
use crate::grid::cell_of;
use crate::octree::Octree;
use crate::parallel::Watch;
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

/// The cells holding the samples splatted at each depth, for the samples `keep` admits.
fn sample_cells(
    positions: &[DVec3],
    at_depth: &[Vec<crate::density::DepthSample>],
    keep: impl Fn(DVec3) -> bool,
) -> Vec<Vec<[i32; 3]>> {
    at_depth
        .iter()
        .enumerate()
        .map(|(d, at)| {
            let inv_h = (d as f64).exp2();
            at.iter()
                .map(|s| positions[s.sample as usize])
                .filter(|&p| keep(p))
                .map(|p| cell_of(p, inv_h))
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
    let density = estimate(&field, &positions, 9, 1.5, &watch).expect("not cancelled");
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
                sample_cells(&positions, &at_depth, |_| true),
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
                    let cells = sample_cells(&positions, &at_depth, |p| {
                        (w[0]..w[1]).contains(&p.x) || (w[1] == 1.0 && p.x >= 1.0)
                    });
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

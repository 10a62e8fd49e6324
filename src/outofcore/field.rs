//! The density field by slab: no member holds the whole cloud's.
//!
//! The density (`density.rs`) is the samples' kernel counts at the kernel depth K, restricted
//! to every coarser depth, and, while the samples' depths are read (pass A), their unit normals
//! summed with the counts at K. A slab reads it only near its samples (its own and its
//! padding's: their areas and depths, pass A) and near its vertices (the mesh's `value`). So
//! each slab, in the density round, splats its points and padding at K and restricts them
//! itself; the nodes it owns (their centres in its columns) are then the whole input's, bit
//! for bit, at every depth from K down to the coarsest exact depth C
//! ([`coarsest_exact_depth`]). It writes those finer than C, with the normal sums at K, to
//! its density file (`slab-k.density`), and sends those of C to every member, which restricts them to the depths
//! below: the coarse field, which every member holds (three depths below the kernel depth on
//! the planet at depth 12 under a 4 GiB budget: C = 7, K = 10, about a sixtieth of the field's
//! nodes). A slab's field is the coarse one with its finer depths read from the files of the
//! slabs whose nodes lie within its reach ([`FieldBySlab::for_samples`],
//! [`FieldBySlab::for_vertices`]).
//!
//! Every node's value is then the same additions in the same order as in the field of the
//! whole input (a node's count sums the points that splat onto it in input order; a coarser
//! node's, its finer contributors in key order, all of them exact where the slab computed it);
//! the evaluation reads every node it would have read in that field: the mesh is the single
//! process's, bit for bit.

use super::scratch::{scratch_error, Scratch};
use super::slabs::SlabLayout;
use super::team::{Packer, Unpacker};
use super::OutOfCoreError;
use crate::density::{node_centre_x, DensityField, KernelCounts, NormalSums, BRICK_SIDE};
use glam::{DVec3, DVec4};
use std::ops::{Range, RangeInclusive};
use std::path::PathBuf;

/// The coarsest depth at which every node a slab owns is the whole input's when the slab
/// splats and restricts its points and padding (`padding` columns of `wall_depth`) itself, the
/// kernel depth when none coarser is. A node of the kernel depth K sums the points within one
/// of its widths of its centre; a node of depth d < K sums the nodes of depth d + 1 within ¾ of
/// its width of its centre, so its points lie within ¾(2^−d + … + 2^−(K−1)) + 2^−K =
/// 1.5·2^−d − 0.5·2^−K of it: in columns, 1.5·2^(W − d) − 0.5·2^(W − K), which the padding
/// must hold. (K itself always is: the padding holds at least one node width of K,
/// `passes::padding_for`.)
pub(crate) fn coarsest_exact_depth(wall_depth: u32, padding: u32, kernel_depth: u32) -> u32 {
    let columns = |depth: u32| (f64::from(wall_depth) - f64::from(depth)).exp2();
    (0..kernel_depth)
        .find(|&d| 1.5 * columns(d) - 0.5 * columns(kernel_depth) <= f64::from(padding))
        .unwrap_or(kernel_depth)
}

/// Nodes of each depth beyond a slab's range whose values it reads: an evaluation at q reads
/// the nodes whose centres lie within 1.5 widths of q (the quadratic B-spline's support); two
/// is taken.
const READ_REACH_NODES: f64 = 2.0;

/// Columns of `wall_depth` beyond a range that a slab's field over it holds nodes of `depth`
/// from (a depth finer than the coarse ones, whose nodes are read from the slabs' files):
/// those within [`READ_REACH_NODES`] of the range, in whole bricks. What the planner counts a
/// slab's share of the field by (`passes.rs`).
pub(crate) fn held_margin_columns(wall_depth: u32, depth: u32) -> u32 {
    let nodes = READ_REACH_NODES + f64::from(BRICK_SIDE - 1);
    (nodes * (f64::from(wall_depth) - f64::from(depth)).exp2()).ceil() as u32
}

/// Slab k's part of the field, from its points and padding (`unit`, in the unit cube, in input
/// order, with their `confidence` and unit `normals`): the nodes it owns finer than
/// `coarse_depth`, with the normal sums at the kernel depth, written to `file`; the nodes it
/// owns of `coarse_depth` are returned, for every member's coarse field.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_own_part(
    file: &std::path::Path,
    unit: &[DVec3],
    confidence: &[f64],
    normals: &[[f32; 3]],
    layout: &SlabLayout,
    k: usize,
    kernel_depth: u32,
    coarse_depth: u32,
) -> Result<Vec<(u64, f64)>, OutOfCoreError> {
    let own = |x: f64| layout.slab_of_column(layout.column_of(x)) == k;
    let sums = NormalSums::splat(unit, Some(confidence), normals, kernel_depth);
    let kernel_nodes = sums.sorted_nodes_where(own);
    let mut p = Packer::default();
    p.u64s_by_steps(&kernel_nodes.iter().map(|n| n.0).collect::<Vec<_>>());
    p.f64s(
        &kernel_nodes
            .iter()
            .flat_map(|n| n.1.to_array())
            .collect::<Vec<_>>(),
    );
    let coarse = if coarse_depth == kernel_depth {
        kernel_nodes
            .iter()
            .map(|&(key, sum)| (key, sum.x))
            .collect()
    } else {
        drop(kernel_nodes);
        let counts = sums.kernel_counts();
        drop(sums);
        let mut coarse = Vec::new();
        counts.restrict_down_to(coarse_depth, own, |d, nodes| {
            if d == coarse_depth {
                coarse = nodes;
            } else {
                p.u64s_by_steps(&nodes.iter().map(|n| n.0).collect::<Vec<_>>());
                p.f64s(&nodes.iter().map(|n| n.1).collect::<Vec<_>>());
            }
        });
        coarse
    };
    std::fs::write(file, &p.bytes).map_err(scratch_error("write a slab's density", file))?;
    Ok(coarse)
}

/// The density field of the whole input, by slab: the coarse depths whole, the finer ones in
/// the slabs' files.
pub(crate) struct FieldBySlab {
    layout: SlabLayout,
    files: Vec<PathBuf>,
    kernel_depth: u32,
    /// Depths 0..=C, whole.
    coarse: DensityField,
}

/// A slab's density field: the whole input's wherever its evaluation reads within `x` (in the
/// unit cube).
pub(crate) struct SlabField {
    pub(crate) field: DensityField,
    x: Range<f64>,
}

impl SlabField {
    /// Whether the field is the whole input's at `q` (at every depth).
    pub(crate) fn holds(&self, q: DVec3) -> bool {
        self.x.start <= q.x && q.x <= self.x.end
    }

    /// W(q) at the kernel depth, or an error where the slab's field does not reach.
    pub(crate) fn evaluate(&self, q: DVec3) -> Result<f64, OutOfCoreError> {
        if !self.holds(q) {
            return Err(OutOfCoreError::internal(format!(
                "the density is read at x = {} beyond the slab's field ({}..{})",
                q.x, self.x.start, self.x.end
            )));
        }
        Ok(self.field.evaluate(q))
    }
}

impl FieldBySlab {
    /// The field from every slab's file (in `scratch`, [`FieldBySlab::file_of`]) and the nodes
    /// of `coarse_depth` every slab owns (`coarse`, all of them, in any order).
    pub(crate) fn new(
        scratch: &Scratch,
        layout: &SlabLayout,
        kernel_depth: u32,
        coarse: KernelCounts,
    ) -> Self {
        FieldBySlab {
            layout: layout.clone(),
            files: (0..layout.len())
                .map(|k| Self::file_of(scratch, k))
                .collect(),
            kernel_depth,
            coarse: coarse.into_field(),
        }
    }

    /// Slab k's field file.
    pub(crate) fn file_of(scratch: &Scratch, k: usize) -> PathBuf {
        scratch.file(&format!("slab-{k}.density"))
    }

    /// The field over slab k's samples (its columns and padding), with the normal sums at the
    /// kernel depth (pass A).
    pub(crate) fn for_samples(&self, k: usize) -> Result<(SlabField, NormalSums), OutOfCoreError> {
        let (field, sums) = self.over(self.layout.padded(k), true)?;
        Ok((field, sums.expect("asked for")))
    }

    /// The field over the vertices of a slab's part, whose x lie within `x` (those of its
    /// cells: a cell coarser than the walls, owned by the slab of its lower x corner, reaches
    /// past them). An empty `x` (no vertices) reads no file.
    pub(crate) fn for_vertices(&self, x: RangeInclusive<f64>) -> Result<SlabField, OutOfCoreError> {
        let layout = &self.layout;
        let columns = if x.is_empty() {
            0..0
        } else {
            layout.column_of(*x.start())..layout.column_of(*x.end()) + 1
        };
        Ok(self.over(columns, false)?.0)
    }

    /// The field over `columns` of the wall depth (and the normal sums at the kernel depth when
    /// `with_normals`): the coarse depths, and the finer ones' nodes within
    /// [`READ_REACH_NODES`] of the columns, from the files of the slabs that own them.
    fn over(
        &self,
        columns: Range<u32>,
        with_normals: bool,
    ) -> Result<(SlabField, Option<NormalSums>), OutOfCoreError> {
        let layout = &self.layout;
        let width = (-f64::from(layout.wall_depth)).exp2();
        let x = f64::from(columns.start) * width..f64::from(columns.end) * width;
        let coarse_depth = self.coarse.depth;
        let kernel_depth = self.kernel_depth;
        // Depth d's nodes read over `x`: those whose centres lie within reach of it.
        let reach = |d: u32| {
            let margin = READ_REACH_NODES * (-f64::from(d)).exp2();
            x.start - margin..x.end + margin
        };
        // The coarsest depth read from the files reaches farthest (the kernel depth's normal
        // sums, when the coarse field holds every depth).
        let widest = reach((coarse_depth + 1).min(kernel_depth));
        let slabs = if columns.is_empty() {
            0..0
        } else {
            layout.slab_of_column(layout.column_of(widest.start))
                ..layout.slab_of_column(layout.column_of(widest.end)) + 1
        };
        // finer[i]: depth C + 1 + i.
        let mut finer: Vec<Vec<(u64, f64)>> =
            vec![Vec::new(); (kernel_depth - coarse_depth) as usize];
        let mut sums: Vec<(u64, DVec4)> = Vec::new();
        for j in slabs {
            let path = &self.files[j];
            let bytes =
                std::fs::read(path).map_err(scratch_error("read a slab's density", path))?;
            let mut u = Unpacker::new(&bytes);
            let corrupt = || {
                OutOfCoreError::internal(format!(
                    "slab {j}'s density file does not match its nodes"
                ))
            };
            let keys = u.u64s_by_steps()?;
            let values = u.f64s()?;
            if values.len() != 4 * keys.len() {
                return Err(corrupt());
            }
            let within = reach(kernel_depth);
            for (key, sum) in keys.into_iter().zip(values.chunks_exact(4)) {
                if within.contains(&node_centre_x(key, kernel_depth)) {
                    if with_normals {
                        sums.push((key, DVec4::from_slice(sum)));
                    }
                    if let Some(kernel) = finer.last_mut() {
                        kernel.push((key, sum[0]));
                    }
                }
            }
            for d in (coarse_depth + 1..kernel_depth).rev() {
                let keys = u.u64s_by_steps()?;
                let values = u.f64s()?;
                if values.len() != keys.len() {
                    return Err(corrupt());
                }
                let within = reach(d);
                finer[(d - coarse_depth - 1) as usize].extend(
                    keys.into_iter()
                        .zip(values)
                        .filter(|&(key, _)| within.contains(&node_centre_x(key, d))),
                );
            }
        }
        let normal_sums = with_normals.then(|| {
            let mut normal_sums = NormalSums::new(kernel_depth);
            normal_sums.insert(sums);
            normal_sums
        });
        Ok((
            SlabField {
                field: self.coarse.with_finer(finer),
                x,
            },
            normal_sums,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outofcore::passes::padding_for;

    /// A sphere of `n` points rippled across x, with uneven confidences and the sphere's
    /// normals.
    fn rippled_sphere(n: usize) -> (Vec<DVec3>, Vec<f64>, Vec<[f32; 3]>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let points: Vec<DVec3> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let p = DVec3::splat(0.5) + 0.3 * DVec3::new(r * t.cos(), r * t.sin(), z);
                p + DVec3::new(0.05 * (p.y * 40.0).sin(), 0.0, 0.0)
            })
            .collect();
        let confidence = (0..n).map(|i| 0.5 + (i % 7) as f64).collect();
        let normals = points
            .iter()
            .map(|p| (*p - DVec3::splat(0.5)).normalize().as_vec3().to_array())
            .collect();
        (points, confidence, normals)
    }

    /// The field of `points` cut into five slabs at `wall_depth` with `padding`, each slab's
    /// part written from its points and padding (in input order) and the nodes of
    /// `coarse_depth` gathered, as the density round makes it; and the slab of each point.
    fn by_slab(
        scratch: &Scratch,
        (points, confidence, normals): &(Vec<DVec3>, Vec<f64>, Vec<[f32; 3]>),
        wall_depth: u32,
        padding: u32,
        kernel_depth: u32,
        coarse_depth: u32,
    ) -> FieldBySlab {
        let columns = SlabLayout::balanced(&vec![0; 1 << wall_depth], wall_depth, 1, 0);
        let mut counts = vec![0u64; 1 << wall_depth];
        for p in points {
            counts[columns.column_of(p.x) as usize] += 1;
        }
        let layout = SlabLayout::balanced(&counts, wall_depth, 5, padding);
        assert_eq!(layout.len(), 5);
        let mut coarse = KernelCounts::new(coarse_depth);
        for k in 0..layout.len() {
            let read: Vec<usize> = (0..points.len())
                .filter(|&i| {
                    layout
                        .slabs_reading(layout.column_of(points[i].x))
                        .contains(&k)
                })
                .collect();
            let own = write_own_part(
                &FieldBySlab::file_of(scratch, k),
                &read.iter().map(|&i| points[i]).collect::<Vec<_>>(),
                &read.iter().map(|&i| confidence[i]).collect::<Vec<_>>(),
                &read.iter().map(|&i| normals[i]).collect::<Vec<_>>(),
                &layout,
                k,
                kernel_depth,
                coarse_depth,
            )
            .unwrap();
            coarse.insert(own);
        }
        FieldBySlab::new(scratch, &layout, kernel_depth, coarse)
    }

    /// Whether every slab's fields are the whole cloud's bit for bit where they are read: at
    /// every depth and with the normal sums at each of its samples (its points and padding),
    /// and at the kernel depth on its columns, their walls included.
    fn same_as_whole(cloud: &(Vec<DVec3>, Vec<f64>, Vec<[f32; 3]>), slabs: &FieldBySlab) -> bool {
        let (points, confidence, normals) = cloud;
        let kernel_depth = slabs.kernel_depth;
        let whole = NormalSums::splat(points, Some(confidence), normals, kernel_depth);
        let whole_field = whole.kernel_counts().into_field();
        let layout = &slabs.layout;
        let width = (-f64::from(layout.wall_depth)).exp2();
        (0..layout.len()).all(|k| {
            let (field, sums) = slabs.for_samples(k).unwrap();
            let samples = points
                .iter()
                .filter(|p| layout.slabs_reading(layout.column_of(p.x)).contains(&k));
            let at_samples = samples.step_by(7).all(|&q| {
                let (a, b) = (sums.density_and_spread(q), whole.density_and_spread(q));
                field.holds(q)
                    && a.0.to_bits() == b.0.to_bits()
                    && a.1.to_bits() == b.1.to_bits()
                    && (0..=kernel_depth).all(|d| {
                        field.field.evaluate_at(d, q).to_bits()
                            == whole_field.evaluate_at(d, q).to_bits()
                    })
            });
            let owned = layout.owned(k);
            let vertices = slabs
                .for_vertices(f64::from(owned.start) * width..=f64::from(owned.end) * width)
                .unwrap();
            let on_columns = (0..=64).all(|i| {
                let x = (f64::from(owned.start) + f64::from(owned.len() as u32) * i as f64 / 64.0)
                    * width;
                let q = DVec3::new(x, 0.5, 0.2 + 0.6 * i as f64 / 64.0);
                vertices.evaluate(q).unwrap().to_bits() == whole_field.evaluate(q).to_bits()
            });
            at_samples && on_columns
        })
    }

    /// Proves the slabs' fields are the whole cloud's bit for bit where they are read, for
    /// kernels finer and coarser than the walls and thin and wide padding, with the coarse
    /// depths gathered from [`coarsest_exact_depth`]; that with a thin padding gathering one
    /// depth coarser is not exact (so the rule is needed; with the run's 24 columns on a cloud
    /// spanning 38 of 64, every slab reaches most of it and the rule is the safe side); and
    /// that a kernel far coarser than the walls needs the padding widened to its reach
    /// ([`padding_for`]).
    #[test]
    fn the_slabs_fields_are_the_whole_cloud_field_where_they_are_read() {
        let cloud = rippled_sphere(20_000);
        let wall_depth = 6;
        for (kernel_depth, asked) in [(8, 24), (8, 2), (6, 24), (6, 6), (6, 2), (5, 2), (2, 2)] {
            let padding = padding_for(asked, wall_depth, kernel_depth);
            let coarse_depth = coarsest_exact_depth(wall_depth, padding, kernel_depth);
            let scratch = Scratch::create(None).unwrap();
            let slabs = by_slab(
                &scratch,
                &cloud,
                wall_depth,
                padding,
                kernel_depth,
                coarse_depth,
            );
            assert!(
                same_as_whole(&cloud, &slabs),
                "kernel depth {kernel_depth}, padding {padding}, coarse depth {coarse_depth}"
            );
            if coarse_depth > 0 && padding < 24 {
                let too_coarse = by_slab(
                    &scratch,
                    &cloud,
                    wall_depth,
                    padding,
                    kernel_depth,
                    coarse_depth - 1,
                );
                assert!(
                    !same_as_whole(&cloud, &too_coarse),
                    "kernel depth {kernel_depth}, padding {padding}: {} also exact",
                    coarse_depth - 1
                );
            }
        }
        let scratch = Scratch::create(None).unwrap();
        let unwidened = by_slab(&scratch, &cloud, wall_depth, 2, 2, 2);
        assert!(!same_as_whole(&cloud, &unwidened));
    }

    /// Proves the depths each slab restricts itself follow the padding: the run's 24 columns
    /// keep four depths below the walls, a thin padding fewer.
    #[test]
    fn the_coarsest_exact_depth_follows_the_padding() {
        // The planet at depth 12 under 4 GiB: walls at 11, kernel at 10 (24 − 1 columns).
        assert_eq!(coarsest_exact_depth(11, 24, 10), 7);
        // The Buddha at depth 11: walls at 9, kernel at 9 (24 − 0.5).
        assert_eq!(coarsest_exact_depth(9, 24, 9), 5);
        // Depth 8 reaches 3 − 0.5 columns: in 3, not in 2.
        assert_eq!(coarsest_exact_depth(9, 3, 9), 8);
        assert_eq!(coarsest_exact_depth(9, 2, 9), 9);
        // A kernel coarser than the walls: depth 6 reaches 12 − 2 columns.
        assert_eq!(coarsest_exact_depth(9, 9, 7), 7);
        assert_eq!(coarsest_exact_depth(9, 10, 7), 6);
    }
}

//! The passes over the input file, each member of a team reading its part of it (the r-th of
//! N runs of points), in chunks (never whole): the scan (the points' count and the unit cube,
//! every point validated as the in-memory path validates it), the histogram of the points over
//! the wall depth's columns, and the binning of every point into the files of the slabs that
//! read it.

use super::cells::OccupiedCells;
use super::scratch::{PointRecord, Scratch, SlabWriter};
use super::slabs::SlabLayout;
use super::team::{Packer, Unpacker};
use super::OutOfCoreError;
use crate::density::KernelNodes;
use crate::ply::{read_point_cloud_part_chunks, PlyPoints};
use crate::points::{Bounds, PointSet, UnitCubeMap};
use crate::Error;
use glam::DVec3;
use std::path::{Path, PathBuf};

/// The input file and how it is read.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Input<'a> {
    pub(crate) path: &'a Path,
    /// Points per chunk.
    pub(crate) chunk: usize,
    /// Whether the points' confidence (the `confidence` or `value` property) weighs them.
    pub(crate) confidence: bool,
}

/// What the first pass learns about the input.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scan {
    pub(crate) count: u64,
    /// The unit cube: the in-memory path's for the same points and scale.
    pub(crate) map: UnitCubeMap,
    /// Whether the points are weighed by their confidence.
    pub(crate) weighted: bool,
    /// Whether they carry colours or other channels (which this path does not carry).
    pub(crate) has_attributes: bool,
    /// Whether the file stores positions in `double` (then the mesh is written in `double`
    /// around a nearby origin, as the in-memory path writes it).
    pub(crate) positions_f64: bool,
}

/// The points of `part` of the input (r of n: [`read_point_cloud_part_chunks`]), chunk by
/// chunk, as records (the values as read); with `check`, each chunk checked as [`PointSet`]
/// checks a batch (errors name the point's index in the file: the scan does it, the passes
/// after it read the points it checked); `keep_going` is asked before each chunk with the
/// number of points read so far, and `each` gets the chunk.
fn for_each_chunk(
    input: &Input<'_>,
    part: (usize, usize),
    check: bool,
    keep_going: &mut dyn FnMut(u64) -> bool,
    mut each: impl FnMut(&PlyPoints, Vec<PointRecord>) -> Result<(), OutOfCoreError>,
) -> Result<(), OutOfCoreError> {
    let mut done = 0u64;
    read_point_cloud_part_chunks(
        input.path,
        input.chunk,
        part,
        |offset, points: PlyPoints| {
            if !keep_going(done) {
                return Err(OutOfCoreError::Reconstruction(Error::Cancelled));
            }
            let weights = match (input.confidence, &points.confidence) {
                (false, _) => None,
                (true, Some(c)) => Some(c.as_slice()),
                (true, None) => {
                    return Err(OutOfCoreError::Reconstruction(Error::InvalidParameter {
                        name: "confidence",
                        value: "true".into(),
                        expected: "points with a confidence (or value) property",
                    }))
                }
            };
            if check {
                let checked = match &points.positions_f64 {
                    Some(exact) => {
                        PointSet::new().extend_weighted_f64(exact, &points.normals, weights)
                    }
                    None => {
                        PointSet::new().extend_weighted(&points.positions, &points.normals, weights)
                    }
                };
                checked.map_err(|e| OutOfCoreError::Reconstruction(at_offset(e, offset)))?;
            }
            let records = (0..points.normals.len())
                .map(|i| PointRecord {
                    position: match &points.positions_f64 {
                        Some(exact) => exact[i],
                        None => points.positions[i].map(f64::from),
                    },
                    normal: points.normals[i],
                    confidence: weights.map_or(1.0, |w| w[i]),
                })
                .collect();
            done += points.normals.len() as u64;
            each(&points, records)
        },
    )
    .map_err(OutOfCoreError::Input)?
}

/// A batch's error with the point's index in the whole file.
fn at_offset(error: Error, offset: u64) -> Error {
    let shift = |index: usize| index + offset as usize;
    match error {
        Error::NonFinitePosition { index } => Error::NonFinitePosition {
            index: shift(index),
        },
        Error::NonFiniteNormal { index } => Error::NonFiniteNormal {
            index: shift(index),
        },
        Error::ZeroNormal { index } => Error::ZeroNormal {
            index: shift(index),
        },
        Error::InvalidWeight { index } => Error::InvalidWeight {
            index: shift(index),
        },
        other => other,
    }
}

/// What pass 1 finds in one part of the input: its points' count and box, and what they carry.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ScannedPart {
    /// The input file's length in bytes (the same for every part of the same file).
    pub(crate) file_bytes: u64,
    pub(crate) count: u64,
    bounds: Bounds,
    has_attributes: bool,
    positions_f64: bool,
}

impl ScannedPart {
    /// As bytes, for a team's meeting.
    pub(crate) fn packed(&self) -> Vec<u8> {
        let mut p = Packer::default();
        p.u64(self.file_bytes);
        p.u64(self.count);
        p.f64s(&self.bounds.lo.to_array());
        p.f64s(&self.bounds.hi.to_array());
        p.u64(u64::from(self.has_attributes) | u64::from(self.positions_f64) << 1);
        p.bytes
    }

    pub(crate) fn unpacked(bytes: &[u8]) -> Result<ScannedPart, OutOfCoreError> {
        let mut u = Unpacker::new(bytes);
        let file_bytes = u.u64()?;
        let count = u.u64()?;
        let corner = |list: Vec<f64>| -> Result<DVec3, OutOfCoreError> {
            <[f64; 3]>::try_from(list)
                .map(DVec3::from)
                .map_err(|_| OutOfCoreError::internal("a scanned part's box is cut short"))
        };
        let lo = corner(u.f64s()?)?;
        let hi = corner(u.f64s()?)?;
        let flags = u.u64()?;
        Ok(ScannedPart {
            file_bytes,
            count,
            bounds: Bounds { lo, hi },
            has_attributes: flags & 1 != 0,
            positions_f64: flags & 2 != 0,
        })
    }
}

/// Pass 1 over `part` of the input (r of n: every point is in one part): the points checked,
/// counted and boxed.
pub(crate) fn scan_part(
    input: &Input<'_>,
    part: (usize, usize),
    keep_going: &mut dyn FnMut(u64) -> bool,
) -> Result<ScannedPart, OutOfCoreError> {
    let mut scanned = ScannedPart {
        file_bytes: 0,
        count: 0,
        bounds: Bounds::default(),
        has_attributes: false,
        positions_f64: false,
    };
    for_each_chunk(input, part, true, keep_going, |points, records| {
        scanned
            .bounds
            .extend(records.iter().map(|r| DVec3::from(r.position)));
        scanned.count += records.len() as u64;
        scanned.has_attributes |= points.colors.is_some() || !points.channels.is_empty();
        scanned.positions_f64 |= points.positions_f64.is_some();
        Ok(())
    })?;
    // (The file was read: its length is known.)
    scanned.file_bytes = std::fs::metadata(input.path).map_or(0, |m| m.len());
    Ok(scanned)
}

/// Pass 1's result from its `parts` (all of them, any order: counts add, boxes join): the
/// count, the cube (`scale` as [`crate::Params::scale`]) and what the points carry. An input
/// without points is [`Error::EmptyInput`].
pub(crate) fn scan_of_parts(
    parts: &[ScannedPart],
    input: &Input<'_>,
    scale: f64,
) -> Result<Scan, OutOfCoreError> {
    let mut bounds = Bounds::default();
    for part in parts {
        bounds.join(&part.bounds);
    }
    let count = parts.iter().map(|p| p.count).sum();
    if count == 0 {
        return Err(OutOfCoreError::Reconstruction(Error::EmptyInput));
    }
    Ok(Scan {
        count,
        map: UnitCubeMap::fit_bounds(&bounds, scale),
        weighted: input.confidence,
        has_attributes: parts.iter().any(|p| p.has_attributes),
        positions_f64: parts.iter().any(|p| p.positions_f64),
    })
}

/// What pass 2 finds in one part of the input: how many of its points lie in each column of
/// the wall depth and, when asked, which nodes of the kernel depth their splats touch and how
/// many cells of each depth they occupy.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ColumnsOfPart {
    /// Points per column (2^wall_depth of them).
    pub(crate) counts: Vec<u64>,
    /// The kernel depth's nodes the part's points splat onto, as sorted distinct keys (empty
    /// unless asked for).
    pub(crate) kernel_nodes: Vec<u64>,
    /// The cells of depths 0..=wall depth the part's points occupy, counted (when asked for,
    /// with the kernel nodes).
    pub(crate) occupied: Option<OccupiedCells>,
}

impl ColumnsOfPart {
    /// As bytes, for a team's meeting.
    pub(crate) fn packed(&self) -> Vec<u8> {
        let mut p = Packer::default();
        p.u64s(&self.counts);
        p.u64s_by_steps(&self.kernel_nodes);
        p.u64(u64::from(self.occupied.is_some()));
        if let Some(occupied) = &self.occupied {
            occupied.pack(&mut p);
        }
        p.bytes
    }

    pub(crate) fn unpacked(bytes: &[u8]) -> Result<ColumnsOfPart, OutOfCoreError> {
        let mut u = Unpacker::new(bytes);
        Ok(ColumnsOfPart {
            counts: u.u64s()?,
            kernel_nodes: u.u64s_by_steps()?,
            occupied: match u.u64()? {
                0 => None,
                _ => Some(OccupiedCells::unpack(&mut u)?),
            },
        })
    }
}

/// Pass 2 over `part` of the input (as [`scan_part`]): the number of its points in each column
/// of `wall_depth`, and with `kernel_depth` the nodes of that depth their splats touch (the
/// surface the memory budget's cut measures) and the cells of each depth up to `wall_depth`
/// they occupy (the base's screening groups, [`OccupiedCells`]). Exact whatever the parts: the
/// counts add, the nodes join into the whole input's, and the occupied cells' sketches join
/// into the one of the whole input.
pub(crate) fn columns_of_part(
    input: &Input<'_>,
    part: (usize, usize),
    map: &UnitCubeMap,
    wall_depth: u32,
    kernel_depth: Option<u32>,
    keep_going: &mut dyn FnMut(u64) -> bool,
) -> Result<ColumnsOfPart, OutOfCoreError> {
    let mut counts = vec![0u64; 1 << wall_depth];
    let columns = SlabLayout::balanced(&counts, wall_depth, 1, 0);
    let mut kernel_nodes = kernel_depth.map(KernelNodes::new);
    let mut occupied = kernel_depth.map(|_| OccupiedCells::new(wall_depth));
    for_each_chunk(input, part, false, keep_going, |_, records| {
        let unit: Vec<DVec3> = records
            .iter()
            .map(|r| map.to_unit_f64(r.position))
            .collect();
        if let Some(kernel_nodes) = &mut kernel_nodes {
            kernel_nodes.add(&unit);
        }
        if let Some(occupied) = &mut occupied {
            occupied.add(&unit);
        }
        for p in &unit {
            counts[columns.column_of(p.x) as usize] += 1;
        }
        Ok(())
    })?;
    Ok(ColumnsOfPart {
        counts,
        kernel_nodes: kernel_nodes.map_or_else(Vec::new, KernelNodes::into_sorted_keys),
        occupied,
    })
}

/// The file of slab k's points binned from part r of the input.
pub(crate) fn binned_file(scratch: &Scratch, k: usize, part: usize) -> PathBuf {
    scratch.file(&format!("slab-{k}-from-{part}.points"))
}

/// Pass 3 over `part` of the input (r of n): each of its points into the file of every slab
/// that reads it (its owner's and, within the padding, its neighbours'), one file per slab for
/// this part ([`binned_file`]), in input order. A slab's points in input order are then its
/// files of parts 0, 1, …, n − 1 read one after the other, whatever n is.
pub(crate) fn bin_part(
    input: &Input<'_>,
    part: (usize, usize),
    scan: &Scan,
    layout: &SlabLayout,
    scratch: &Scratch,
    keep_going: &mut dyn FnMut(u64) -> bool,
) -> Result<(), OutOfCoreError> {
    // A member writes to every slab at once: 1 MiB of buffer each up to 64 slabs, then 64 MiB
    // shared (64 KiB each, the least, past 1,024).
    let buffer = ((64usize << 20) / layout.len()).clamp(64 << 10, 1 << 20);
    let mut writers = (0..layout.len())
        .map(|k| SlabWriter::create(binned_file(scratch, k, part.0), buffer))
        .collect::<Result<Vec<_>, _>>()?;
    for_each_chunk(input, part, false, keep_going, |_, records| {
        for r in &records {
            let x = scan.map.to_unit_f64(r.position).x;
            for k in layout.slabs_reading(layout.column_of(x)) {
                writers[k].push(*r)?;
            }
        }
        Ok(())
    })?;
    for writer in writers {
        writer.finish()?;
    }
    Ok(())
}

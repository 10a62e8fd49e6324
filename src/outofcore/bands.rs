//! The wall bands (pass D): every node's coefficient is its owner's, so that neighbouring slabs
//! evaluate one χ near their walls. Each slab, once solved (pass C), writes for each slab
//! whose padding reaches its columns a band: the coefficients of the nodes it owns within
//! that slab's window ([`window`]), where the reader's tree can have nodes. The reader then
//! gives every node of its tree owned by a neighbour the neighbour's value from the band,
//! instead of loading the neighbour's whole solution and rebuilding its tree.
//!
//! The result is what reading the neighbours' solutions gave: a node of the reader's tree
//! owned by a neighbour takes the neighbour's value when the neighbour's tree has the node
//! and keeps its own otherwise. A node owned by a neighbour but outside the window (where the
//! reader's tree can have nodes, and [`WINDOW_MARGIN`] nodes more: the tree reaches one or two
//! past its samples' splats) would have no value written: the reader stops with an internal
//! error rather than keep its own there.
//!
//! A band is as wide as the padding up to the wall depth (the reader's tree spans its padded
//! columns there) and a few dozen nodes of each finer depth: on the bunny at depth 10 in 5
//! slabs, 0.4–1.3 million nodes, a third to a half of a neighbour's nodes finer than the base.
//! It goes through the temporary directory rather than the team's meetings: held until pass D,
//! the bands of every slab a member does would outgrow the one slab at a time the budget
//! counts.

use super::passes::FINE_PADDING_NODES;
use super::scratch::{read_lists, scratch_error, write_lists, Scratch};
use super::slabs::SlabLayout;
use super::OutOfCoreError;
use crate::evaluate::Indicator;
use crate::grid::unmorton;
use std::ops::Range;
use std::path::PathBuf;

/// Nodes of each depth beyond where a reader's samples splat that its window takes in: more
/// than its tree reaches past them (a splat touches one node on each side, the 2:1 balance
/// widens a parent's core by one node and the halo adds one or two).
const WINDOW_MARGIN: i64 = 8;

/// The x indices of depth `d`'s nodes in slab k's window: where its tree can have nodes, and
/// [`WINDOW_MARGIN`] nodes of that depth more on each side. Up to the wall depth that is its
/// padded columns (it holds their samples); finer, its graded band
/// ([`SlabLayout::band`] with [`FINE_PADDING_NODES`]), within which its splats stay.
fn window(layout: &SlabLayout, k: usize, d: u32) -> Range<i64> {
    let w = layout.wall_depth;
    let within = if d > w {
        layout.band(k, d, FINE_PADDING_NODES)
    } else {
        let padded = layout.padded(k);
        let shift = w - d;
        (padded.start as i64) >> shift..((padded.end as i64 - 1) >> shift) + 1
    };
    within.start - WINDOW_MARGIN..within.end + WINDOW_MARGIN
}

/// The band's files of slab j for slab k: the keys (Morton, ascending) and the coefficients,
/// one list per depth finer than the base.
fn band_files(scratch: &Scratch, j: usize, k: usize) -> [PathBuf; 2] {
    [
        scratch.file(&format!("band-{j}-to-{k}.keys")),
        scratch.file(&format!("band-{j}-to-{k}.coefficients")),
    ]
}

/// Writes slab j's bands from its solution `chi`: for each slab that reads it, the nodes of
/// depths finer than `base` that j owns within that slab's window.
pub(crate) fn write_bands(
    scratch: &Scratch,
    layout: &SlabLayout,
    j: usize,
    base: usize,
    chi: &Indicator,
) -> Result<(), OutOfCoreError> {
    for k in (0..layout.len()).filter(|&k| k != j && layout.slabs_read_by(k).contains(&j)) {
        let (mut keys, mut values) = (Vec::new(), Vec::new());
        for d in base + 1..chi.tree.levels.len() {
            let level = &chi.tree.levels[d];
            let (window, owned) = (window(layout, k, d as u32), layout.owned_at(j, d as u32));
            // In the level's order, which is the keys' (ascending).
            let (depth_keys, depth_values): (Vec<u64>, Vec<f64>) = level
                .keys
                .iter()
                .zip(&chi.coefficients[d])
                .filter(|&(&key, _)| {
                    let x = i64::from(unmorton(key)[0]);
                    window.contains(&x) && owned.contains(&x)
                })
                .unzip();
            keys.push(depth_keys);
            values.push(depth_values);
        }
        let [keys_file, values_file] = band_files(scratch, j, k);
        write_lists(&keys_file, &keys)?;
        write_lists(&values_file, &values)?;
    }
    Ok(())
}

/// Gives every node of slab k's solution `chi` finer than `base` that a neighbour owns the
/// neighbour's coefficient from its band, where the neighbour's tree has the node. One band
/// in memory at a time.
pub(crate) fn apply_bands(
    scratch: &Scratch,
    layout: &SlabLayout,
    k: usize,
    base: usize,
    chi: &mut Indicator,
) -> Result<(), OutOfCoreError> {
    for j in layout.slabs_read_by(k).filter(|&j| j != k) {
        let [keys_file, values_file] = band_files(scratch, j, k);
        let keys = read_lists::<u64>(&keys_file)?;
        let values = read_lists::<f64>(&values_file)?;
        // Read once: off the disk at once (the bands add up to a fair part of the solutions).
        for file in [&keys_file, &values_file] {
            std::fs::remove_file(file).map_err(scratch_error("remove a wall band", file))?;
        }
        let paired = keys.len() == values.len()
            && keys
                .iter()
                .zip(&values)
                .all(|(k, v)| k.len() == v.len() && k.is_sorted());
        if !paired {
            return Err(OutOfCoreError::internal(format!(
                "slab {j}'s band for slab {k}: its keys and coefficients do not pair up in order"
            )));
        }
        for d in base + 1..chi.tree.levels.len() {
            let level = &chi.tree.levels[d];
            let (window, owned) = (window(layout, k, d as u32), layout.owned_at(j, d as u32));
            let (band_keys, band_values) =
                match keys.get(d - base - 1).zip(values.get(d - base - 1)) {
                    Some((keys, values)) => (keys.as_slice(), values.as_slice()),
                    None => (&[][..], &[][..]),
                };
            // Both in ascending key order: one merge, the band's cursor only moving forward.
            let mut at = 0;
            for (i, &key) in level.keys.iter().enumerate() {
                let x = i64::from(unmorton(key)[0]);
                // (A node whose owner is beyond the padding is too far from the walls to reach
                // a point near them: it keeps the slab's value.)
                if !owned.contains(&x) {
                    continue;
                }
                if !window.contains(&x) {
                    return Err(OutOfCoreError::internal(format!(
                        "slab {k}'s node at {:?} (depth {d}), owned by slab {j}, lies outside \
                         the window of its band",
                        unmorton(key)
                    )));
                }
                at += band_keys[at..].partition_point(|&b| b < key);
                if band_keys.get(at) == Some(&key) {
                    chi.coefficients[d][i] = band_values[at];
                }
            }
        }
    }
    Ok(())
}

//! The samples' noise out of core ([`crate::Params::screening_follows_noise`]): the in-memory
//! estimate (`crate::noise`) from the slabs' parts, the same σ bit for bit when the estimate's
//! cells fit within a slab's padding.
//!
//! The estimate reads three things, each of which adds up over the slabs:
//! - its depth, from the samples' areas counted by the depth each gives
//!   ([`AreaDepths`]): pass A counts each slab's own samples as it prepares them;
//! - the cells' fits at that depth and the next coarser ([`CellFits`]): pass B fits, in each
//!   slab, the cells the slab owns ([`owner_of_cell`]: the slab of the cell's lowest column)
//!   from its samples with their padding, which are in the in-memory path's Morton order, so a
//!   cell's fit is the in-memory one whenever its columns lie within the padding;
//! - the medians of the fits' residuals and F values, found across the team without gathering
//!   the values ([`team_medians`]), before the base is solved with the screening they give.
//!
//! A cell wider than the padding reaches (2^(W − d) columns of the wall depth W past 25: the
//! estimate's cells hold about 16 samples, so only where the median sample is about three
//! depths coarser than the walls) is fitted from the samples the owner holds, and counted
//! ([`SlabNoise::cells_beyond_padding`]).

use super::slabs::SlabLayout;
use super::team::{gather, Packer, Team, Unpacker};
use super::OutOfCoreError;
use crate::noise::{from_medians, CellFits, SampleNoise, MIN_SAMPLES};
use glam::DVec3;

/// A member's part of the estimate, gathered over the slabs it does in pass B.
#[derive(Debug, Default)]
pub(crate) struct SlabNoise {
    /// The fits of the cells its slabs own.
    pub(crate) fits: CellFits,
    /// Cells of the coarser depth among them (those with at least [`MIN_SAMPLES`] samples)
    /// whose columns reach past their slab's padding: fitted over the samples within it. (A
    /// finer cell, half as wide, reaches past its owner's padding only inside such a coarser
    /// cell.)
    pub(crate) cells_beyond_padding: u64,
}

/// The estimate every member reads from the team's parts ([`SlabNoise::estimate`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TeamNoise {
    /// The same as the in-memory estimate when every cell lies within its slab's padding.
    pub(crate) noise: SampleNoise,
    /// The team's [`SlabNoise::cells_beyond_padding`], summed.
    pub(crate) cells_beyond_padding: u64,
}

/// The slab owning a cell of `depth` at `cell`: the slab of its lowest column of the wall
/// depth.
pub(crate) fn owner_of_cell(layout: &SlabLayout, depth: u32, cell: [i32; 3]) -> usize {
    layout.slab_of_column(columns_of_cell(layout, depth, cell).start)
}

/// The columns of the wall depth a cell of `depth` at `cell` spans (clamped to the cube).
fn columns_of_cell(layout: &SlabLayout, depth: u32, cell: [i32; 3]) -> std::ops::Range<u32> {
    let w = layout.wall_depth;
    let columns = 1i64 << w;
    let x = i64::from(cell[0]);
    let (first, end) = if depth <= w {
        (x << (w - depth), (x + 1) << (w - depth))
    } else {
        (x >> (depth - w), (x >> (depth - w)) + 1)
    };
    first.clamp(0, columns - 1) as u32..end.clamp(1, columns) as u32
}

impl SlabNoise {
    /// Adds the fits of the cells slab k owns at the estimate's `depth` and the next coarser,
    /// from its samples with their padding (`positions`: unit cube, Morton order).
    pub(crate) fn fit_slab(
        &mut self,
        layout: &SlabLayout,
        k: usize,
        depth: u32,
        positions: &[DVec3],
    ) {
        let owns = |d: u32, cell: [i32; 3]| owner_of_cell(layout, d, cell) == k;
        self.fits.extend(CellFits::at(depth, positions, &owns));
        let padded = layout.padded(k);
        self.cells_beyond_padding += crate::grid::cell_runs(positions, depth - 1)
            .filter(|(cell, run)| run.len() >= MIN_SAMPLES && owns(depth - 1, *cell))
            .filter(|(cell, _)| {
                let columns = columns_of_cell(layout, depth - 1, *cell);
                columns.start < padded.start || columns.end > padded.end
            })
            .count() as u64;
    }

    /// The estimate at `depth` from every member's part: the same as the in-memory
    /// [`crate::noise::estimate`] over the whole cloud (see the module's documentation). A
    /// collective step, every member calls it: two meetings of the team.
    pub(crate) fn estimate(self, team: &dyn Team, depth: u32) -> Result<TeamNoise, OutOfCoreError> {
        let fits = &self.fits;
        let team_medians = team_medians(
            team,
            &[&fits.fine, &fits.coarse, &fits.cubic_f],
            &[self.cells_beyond_padding],
        )?;
        let [r1, r2, shape_f] = team_medians.medians[..] else {
            unreachable!("three lists give three medians")
        };
        Ok(TeamNoise {
            noise: from_medians(depth, team_medians.counts[0] as usize, r1, r2, shape_f),
            cells_beyond_padding: team_medians.sums[0],
        })
    }
}

/// A key of `v` whose unsigned order is `f64::total_cmp`'s order of the values.
fn ordered_key(v: f64) -> u64 {
    let bits = v.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

/// How many of a key's leading bits name its bin in [`team_medians`]' first round: the sign,
/// the exponent and 4 bits of the fraction, so a bin spans at most 1/16 of a doubling.
const BIN_BITS: u32 = 16;

/// What [`team_medians`] finds across the team, the same on every member.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TeamMedians {
    /// Per list, the median of the values the members hold in it (the upper of the two middle
    /// values, as `crate::noise::median` takes it); `None` when none holds any.
    pub(crate) medians: Vec<Option<f64>>,
    /// Per list, how many values the members hold in it.
    pub(crate) counts: Vec<u64>,
    /// The members' `sums`, added up.
    pub(crate) sums: Vec<u64>,
}

/// The medians of several lists of values spread over the members of `team` (every member
/// passes the same number of lists and of `sums`), in two meetings whatever the number of
/// lists: every member counts each list's values by bins of their leading bits (with its
/// `sums`), the counts say which bin holds each median and its place there, and only the values
/// of those bins are gathered. No member holds another's whole lists. A collective step.
pub(crate) fn team_medians(
    team: &dyn Team,
    lists: &[&[f64]],
    sums: &[u64],
) -> Result<TeamMedians, OutOfCoreError> {
    let bin_of = |v: f64| ordered_key(v) >> (64 - BIN_BITS);
    let mut p = Packer::default();
    p.u64s(sums);
    for list in lists {
        let mut bins: Vec<u64> = list.iter().map(|&v| bin_of(v)).collect();
        bins.sort_unstable();
        let pairs: Vec<u64> = bins
            .chunk_by(|a, b| a == b)
            .flat_map(|run| [run[0], run.len() as u64])
            .collect();
        p.u64s(&pairs);
    }
    let mut summed = vec![0u64; sums.len()];
    let mut histograms = vec![std::collections::BTreeMap::<u64, u64>::new(); lists.len()];
    for bytes in gather(team, Ok(p.bytes))? {
        let mut u = Unpacker::new(&bytes);
        for (total, theirs) in summed.iter_mut().zip(u.u64s()?) {
            *total += theirs;
        }
        for histogram in &mut histograms {
            for pair in u.u64s()?.chunks_exact(2) {
                *histogram.entry(pair[0]).or_default() += pair[1];
            }
        }
    }
    // Per list: the bin holding the median and the median's place among that bin's values.
    let counts: Vec<u64> = histograms.iter().map(|h| h.values().sum()).collect();
    let places: Vec<Option<(u64, u64)>> = histograms
        .iter()
        .zip(&counts)
        .map(|(histogram, &count)| {
            let mut place = count / 2;
            histogram.iter().find_map(|(&bin, &in_bin)| {
                if place < in_bin {
                    Some((bin, place))
                } else {
                    place -= in_bin;
                    None
                }
            })
        })
        .collect();
    let mut p = Packer::default();
    for (list, place) in lists.iter().zip(&places) {
        let in_bin: Vec<f64> = match place {
            Some((median_bin, _)) => list
                .iter()
                .copied()
                .filter(|&v| bin_of(v) == *median_bin)
                .collect(),
            None => Vec::new(),
        };
        p.f64s(&in_bin);
    }
    let mut gathered = vec![Vec::new(); lists.len()];
    for bytes in gather(team, Ok(p.bytes))? {
        let mut u = Unpacker::new(&bytes);
        for values in &mut gathered {
            values.extend(u.f64s()?);
        }
    }
    let medians = gathered
        .iter_mut()
        .zip(&places)
        .map(|(values, place)| {
            let Some((_, place)) = *place else {
                return Ok(None);
            };
            values.sort_unstable_by(f64::total_cmp);
            values
                .get(place as usize)
                .copied()
                .map(Some)
                .ok_or_else(|| {
                    OutOfCoreError::internal(format!(
                        "the members' median bin holds {} values, not the {} counted past its \
                         place",
                        values.len(),
                        place + 1
                    ))
                })
        })
        .collect::<Result<_, _>>()?;
    Ok(TeamMedians {
        medians,
        counts,
        sums: summed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outofcore::team::tests::Threads;
    use crate::outofcore::team::Alone;

    /// Proves the slabs' fits are the in-memory fits: every cell fitted once, by its owner,
    /// from the samples of the slab's padded columns, so the medians are the same bits; and
    /// that with a padding narrower than the coarser cells the cells reaching past it are
    /// counted (each still fitted once, from the samples within the padding).
    #[test]
    fn the_slabs_fit_every_cell_once_as_in_memory() {
        use crate::grid::{cell_of, morton_nested};
        use crate::noise::median;
        // A noisy sphere of 40,000 samples in Morton order at depth 16.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut positions: Vec<DVec3> = (0..40_000)
            .map(|_| {
                let z: f64 = 2.0 * uniform() - 1.0;
                let phi = std::f64::consts::TAU * uniform();
                let r = (1.0 - z * z).sqrt();
                let jitter = 0.3 * (1.0 + 0.01 * (uniform() - 0.5));
                DVec3::splat(0.5) + DVec3::new(r * phi.cos(), r * phi.sin(), z) * jitter
            })
            .collect();
        positions.sort_by_key(|p| morton_nested(cell_of(*p, 65536.0).map(|v| v as u32)));
        let depth = 5;
        let mut whole = CellFits::at(depth, &positions, &|_, _| true);
        let wall_depth = 6;
        let mut counts = vec![0u64; 1 << wall_depth];
        for p in &positions {
            counts[(p.x * 64.0) as usize] += 1;
        }
        for (padding, beyond) in [(3u32, false), (1, true)] {
            let layout = SlabLayout::balanced(&counts, wall_depth, 4, padding);
            let mut noise = SlabNoise::default();
            for k in 0..layout.len() {
                let padded = layout.padded(k);
                let within: Vec<DVec3> = positions
                    .iter()
                    .copied()
                    .filter(|p| padded.contains(&layout.column_of(p.x)))
                    .collect();
                noise.fit_slab(&layout, k, depth, &within);
            }
            assert_eq!(noise.fits.fine.len(), whole.fine.len(), "padding {padding}");
            assert_eq!(
                noise.fits.coarse.len(),
                whole.coarse.len(),
                "padding {padding}"
            );
            assert_eq!(noise.cells_beyond_padding > 0, beyond, "padding {padding}");
            if !beyond {
                let mut fits = noise.fits;
                for (ours, theirs) in [
                    (&mut fits.fine, &mut whole.fine),
                    (&mut fits.coarse, &mut whole.coarse),
                    (&mut fits.cubic_f, &mut whole.cubic_f),
                ] {
                    assert_eq!(
                        median(ours).map(f64::to_bits),
                        median(theirs).map(f64::to_bits)
                    );
                }
            }
        }
    }

    /// Proves the team's medians are the in-memory medians of all the members' values bit for
    /// bit, found for every list in one call, for teams of 1 to 4 members, values split
    /// unevenly (one member with none), values repeated, of both signs, zeros of either sign
    /// and infinities, and a list with none at all; the counts and sums are the team's.
    #[test]
    fn the_team_medians_are_the_medians_of_every_members_values() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut lists: Vec<Vec<f64>> = Vec::new();
        for n in [1usize, 2, 3, 10, 1001, 20_000] {
            lists.push(
                (0..n)
                    .map(|_| (next() % 10_000) as f64 * 1e-7 + 3e-4)
                    .collect(),
            );
        }
        lists.push(vec![0.5; 7]);
        lists.push(vec![-1.0, 0.0, -0.0, f64::INFINITY, 2.0, 2.0, 1e-300, -5.0]);
        lists.push(Vec::new());
        let expected = TeamMedians {
            medians: lists
                .iter()
                .map(|values| crate::noise::median(&mut values.clone()))
                .collect(),
            counts: lists.iter().map(|values| values.len() as u64).collect(),
            sums: vec![lists.iter().map(|values| values.len() as u64).sum(), 0],
        };
        let bits = |found: TeamMedians| {
            let medians: Vec<Option<u64>> =
                found.medians.iter().map(|m| m.map(f64::to_bits)).collect();
            (medians, found.counts, found.sums)
        };
        let borrowed: Vec<&[f64]> = lists.iter().map(Vec::as_slice).collect();
        let alone = team_medians(&Alone, &borrowed, &[expected.sums[0], 0]).unwrap();
        assert_eq!(bits(alone), bits(expected.clone()));
        for members in 2..=4usize {
            // Member r holds the values at places ≡ r mod (members + 1), the last member also
            // those ≡ members: uneven parts, and member 0 none of a single value.
            let parts: Vec<Vec<Vec<f64>>> = (0..members)
                .map(|r| {
                    lists
                        .iter()
                        .map(|values| {
                            values
                                .iter()
                                .enumerate()
                                .filter(|(i, _)| {
                                    let slot = i % (members + 1);
                                    slot == r || (r == members - 1 && slot == members)
                                })
                                .map(|(_, &v)| v)
                                .collect()
                        })
                        .collect()
                })
                .collect();
            let team = Threads::new(members);
            let found: Vec<TeamMedians> = std::thread::scope(|s| {
                let handles: Vec<_> = (0..members)
                    .map(|r| {
                        let (team, part) = (&team, &parts[r]);
                        s.spawn(move || {
                            let borrowed: Vec<&[f64]> = part.iter().map(Vec::as_slice).collect();
                            let held = part.iter().map(|values| values.len() as u64).sum();
                            team_medians(&team.member(r), &borrowed, &[held, 0]).unwrap()
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            for member in found {
                assert_eq!(bits(member), bits(expected.clone()), "{members} members");
            }
        }
    }
}

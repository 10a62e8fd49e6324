//! The slabs: the unit cube cut across x into slabs holding about equal numbers of points,
//! each wall on a column boundary of the wall depth (a column is the set of cells of that depth
//! with one x index), and the padding each slab reads from its neighbours.

use std::ops::Range;

/// Where the walls between slabs are, in columns of `wall_depth` (2^wall_depth columns span
/// the unit cube's x from 0 to 1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct SlabLayout {
    pub(crate) wall_depth: u32,
    /// The first column of every slab, then the end of the last: `walls[k]..walls[k + 1]` are
    /// slab k's columns; strictly increasing, from 0 to 2^wall_depth.
    pub(crate) walls: Vec<u32>,
    /// Columns of padding on each side of a slab (clamped to the cube).
    pub(crate) padding: u32,
}

impl SlabLayout {
    /// Cuts the columns into at most `slabs` slabs of about equal point counts, from the number
    /// of points in each column (`counts`, 2^wall_depth of them): slab k ends at the first
    /// column where the running count reaches (k + 1)/slabs of the total. Empty slabs are not
    /// made (fewer slabs come back when the points fill fewer columns than asked for).
    pub(crate) fn balanced(counts: &[u64], wall_depth: u32, slabs: usize, padding: u32) -> Self {
        let columns = 1u32 << wall_depth;
        assert_eq!(counts.len(), columns as usize, "one count per column");
        let slabs = slabs.max(1) as u128;
        let total: u128 = counts.iter().map(|&c| c as u128).sum();
        let mut walls = vec![0u32];
        let mut running: u128 = 0;
        let mut next_slab: u128 = 1;
        for (column, &count) in counts.iter().enumerate() {
            running += count as u128;
            // The slab ends after this column once its share is reached (not at the last
            // column: the end is pushed below).
            // (No wall after the last point: the slab beyond would be empty.)
            if next_slab < slabs && running * slabs >= next_slab * total && running < total {
                let end = column as u32 + 1;
                if end < columns && end > *walls.last().expect("starts with 0") {
                    walls.push(end);
                }
                while next_slab < slabs && running * slabs >= next_slab * total {
                    next_slab += 1;
                }
            }
        }
        walls.push(columns);
        SlabLayout {
            wall_depth,
            walls,
            padding,
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.walls.len() - 1
    }

    /// The column of the wall depth holding x (clamped into the cube).
    pub(crate) fn column_of(&self, x: f64) -> u32 {
        let columns = 1u32 << self.wall_depth;
        let c = (x * columns as f64).floor();
        c.clamp(0.0, (columns - 1) as f64) as u32
    }

    /// The slab that owns column `column`.
    pub(crate) fn slab_of_column(&self, column: u32) -> usize {
        self.walls.partition_point(|&w| w <= column) - 1
    }

    /// Slab k's own columns.
    pub(crate) fn owned(&self, k: usize) -> Range<u32> {
        self.walls[k]..self.walls[k + 1]
    }

    /// Slab k's columns with its padding on both sides (within the cube).
    pub(crate) fn padded(&self, k: usize) -> Range<u32> {
        let columns = 1u32 << self.wall_depth;
        let owned = self.owned(k);
        owned.start.saturating_sub(self.padding)..(owned.end + self.padding).min(columns)
    }

    /// Slab k's band at `depth`, finer than the wall depth: the x indices of that depth's cells
    /// over its own columns and `nodes` cells on each side (the graded padding; it may reach
    /// past the cube, where no sample lies).
    pub(crate) fn band(&self, k: usize, depth: u32, nodes: u32) -> Range<i64> {
        debug_assert!(
            depth > self.wall_depth,
            "the band of a depth finer than the walls"
        );
        let shift = depth - self.wall_depth;
        let owned = self.owned(k);
        ((owned.start as i64) << shift) - nodes as i64..((owned.end as i64) << shift) + nodes as i64
    }

    /// The x indices of depth `depth`'s cells that slab k owns: those whose lower x corner lies
    /// in one of its columns. Cells beyond the cube belong to no slab.
    pub(crate) fn owned_at(&self, k: usize, depth: u32) -> Range<i64> {
        let owned = self.owned(k);
        let (start, end) = (i64::from(owned.start), i64::from(owned.end));
        if depth >= self.wall_depth {
            let shift = depth - self.wall_depth;
            start << shift..end << shift
        } else {
            // x · 2^shift in [start, end): the first x at or above start / 2^shift, up to end's.
            let shift = self.wall_depth - depth;
            let up = |c: i64| (c + (1 << shift) - 1) >> shift;
            up(start)..up(end)
        }
    }

    /// The slabs whose own columns slab k's padded range reaches, in order (k among them): the
    /// converse of [`SlabLayout::slabs_reading`].
    pub(crate) fn slabs_read_by(&self, k: usize) -> Range<usize> {
        let padded = self.padded(k);
        self.slab_of_column(padded.start)..self.slab_of_column(padded.end - 1) + 1
    }

    /// The slabs whose padded range holds column `column`, in order (its owner among them).
    pub(crate) fn slabs_reading(&self, column: u32) -> Range<usize> {
        let first = self.slab_of_column(column.saturating_sub(self.padding));
        let columns = 1u32 << self.wall_depth;
        let last = self.slab_of_column((column + self.padding).min(columns - 1));
        first..last + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves the walls split the points evenly when the columns allow it, cover every column
    /// once, and never make an empty slab.
    #[test]
    fn walls_balance_the_points_and_cover_every_column_once() {
        let counts: Vec<u64> = (0..64).map(|c| if c < 8 { 0 } else { 10 }).collect();
        let layout = SlabLayout::balanced(&counts, 6, 4, 2);
        assert_eq!(layout.len(), 4);
        let per_slab: Vec<u64> = (0..4)
            .map(|k| layout.owned(k).map(|c| counts[c as usize]).sum())
            .collect();
        assert_eq!(per_slab, vec![140, 140, 140, 140]);
        assert_eq!(layout.walls.first(), Some(&0));
        assert_eq!(layout.walls.last(), Some(&64));
        assert!(layout.walls.windows(2).all(|w| w[0] < w[1]));
        for column in 0..64 {
            let k = layout.slab_of_column(column);
            assert!(layout.owned(k).contains(&column));
            let reading = layout.slabs_reading(column);
            assert!(reading.contains(&k));
            for j in 0..layout.len() {
                assert_eq!(
                    reading.contains(&j),
                    layout.padded(j).contains(&column),
                    "column {column}, slab {j}"
                );
            }
        }
        for k in 0..layout.len() {
            for j in 0..layout.len() {
                assert_eq!(
                    layout.slabs_read_by(k).contains(&j),
                    layout
                        .owned(j)
                        .any(|c| layout.slabs_reading(c).contains(&k)),
                    "slab {k} reading slab {j}"
                );
            }
        }
        // Every depth's cells in the cube owned once, by the slab of their lower x's column.
        for depth in 0..9 {
            for x in 0..1i64 << depth {
                let column = if depth >= 6 {
                    x >> (depth - 6)
                } else {
                    x << (6 - depth)
                };
                let owners: Vec<usize> = (0..layout.len())
                    .filter(|&k| layout.owned_at(k, depth).contains(&x))
                    .collect();
                assert_eq!(
                    owners,
                    vec![layout.slab_of_column(column as u32)],
                    "depth {depth}"
                );
            }
            assert!((0..layout.len()).all(|k| !layout.owned_at(k, depth).contains(&-1)));
        }
        // All points in one column: one slab, whatever was asked.
        let mut one = vec![0u64; 64];
        one[30] = 1000;
        assert_eq!(SlabLayout::balanced(&one, 6, 8, 1).walls, vec![0, 64]);
        // More slabs than occupied columns: at most one slab per cut.
        let two: Vec<u64> = (0..64).map(|c| (c == 10 || c == 50) as u64).collect();
        assert_eq!(SlabLayout::balanced(&two, 6, 8, 1).len(), 2);
    }

    #[test]
    fn columns_clamp_to_the_cube() {
        let layout = SlabLayout::balanced(&[1; 16], 4, 2, 1);
        assert_eq!(layout.column_of(-0.1), 0);
        assert_eq!(layout.column_of(0.0), 0);
        assert_eq!(layout.column_of(0.5), 8);
        assert_eq!(layout.column_of(1.0), 15);
        assert_eq!(layout.padded(0), 0..9);
        assert_eq!(layout.padded(1), 7..16);
    }
}

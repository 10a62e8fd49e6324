//! Grid keys and cells, shared by every stage: node coordinates, their Morton keys (the order
//! every depth's nodes are stored in), a hash map keyed by them, and the cell of a point.
//!
//! A node of depth d has integer coordinates c (its cell is [c, c + 1)·2^−d of the unit cube);
//! halo nodes may lie a few nodes outside [0, 2^d), so keys store coordinates shifted by
//! [`OFFSET`].

use glam::DVec3;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::Range;

/// Coordinates are stored shifted by this much so that halo nodes just outside the cube are
/// representable as unsigned.
pub(crate) const OFFSET: i32 = 8;
/// Bits per axis in a key.
pub(crate) const BITS: u32 = 21;

/// The integer index of a node at some depth (may be slightly negative or ≥ 2^d in the halo).
pub type Coord = [i32; 3];

/// Morton key of a node coordinate (21 bits per axis after the offset).
#[inline]
pub fn morton(c: Coord) -> u64 {
    spread((c[0] + OFFSET) as u64)
        | (spread((c[1] + OFFSET) as u64) << 1)
        | (spread((c[2] + OFFSET) as u64) << 2)
}

/// Morton key of non-negative coordinates without the halo offset, so that the keys of a cell's
/// descendants at any finer depth are contiguous (sorting points by this key at depth D sorts
/// them by cell at every coarser depth too).
#[inline]
pub fn morton_nested(c: [u32; 3]) -> u64 {
    spread(c[0] as u64) | (spread(c[1] as u64) << 1) | (spread(c[2] as u64) << 2)
}

/// Inverse of [`morton`].
#[inline]
pub fn unmorton(k: u64) -> Coord {
    [
        compact(k) as i32 - OFFSET,
        compact(k >> 1) as i32 - OFFSET,
        compact(k >> 2) as i32 - OFFSET,
    ]
}

/// The low [`BITS`] bits of `v` spread to every third bit (bit i to bit 3i).
#[inline]
pub(crate) fn spread(v: u64) -> u64 {
    let mut x = v & ((1 << BITS) - 1);
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Inverse of [`spread`].
#[inline]
pub(crate) fn compact(v: u64) -> u64 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x | (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x | (x >> 32)) & ((1 << BITS) - 1);
    x
}

/// A multiplicative hasher for Morton keys (they are already well spread; SipHash is slow).
#[derive(Default, Clone, Copy)]
pub struct KeyHasher(u64);

impl Hasher for KeyHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    #[inline]
    fn write_u64(&mut self, k: u64) {
        self.0 = (k ^ (k >> 29))
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(26);
    }
}

/// A hash map from Morton keys.
pub type KeyMap<V> = HashMap<u64, V, BuildHasherDefault<KeyHasher>>;

/// ⌊x⌋, the same value as `x.floor()` for every `f64` (−0.0, infinities and NaN included),
/// without a call: x86-64's baseline instruction set (SSE2) has no rounding instruction, so
/// `f64::floor` is a call into the runtime's `floor`: 1.4 % of a one-thread degree-1 run's
/// time on the Happy Buddha at depth 10 (`perf`), from the cells and stencils of every sample
/// and of every point where χ is evaluated (a stencil per depth). Inlined, it is 0.05 %, with
/// the same mesh byte for byte. Beyond 2^52 in magnitude every `f64` is an integer.
#[inline(always)]
pub fn floor(x: f64) -> f64 {
    // Integers already, or NaN.
    if x.abs() >= 4_503_599_627_370_496.0 || x.is_nan() {
        return x;
    }
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else if t == x {
        x
    } else {
        t
    }
}

/// [`floor`] of each component.
#[inline(always)]
pub fn floor3(v: DVec3) -> DVec3 {
    DVec3::new(floor(v.x), floor(v.y), floor(v.z))
}

/// The node cell containing `p` at the depth of inverse width `inv_h`.
#[inline]
pub fn cell_of(p: DVec3, inv_h: f64) -> [i32; 3] {
    let t = floor3(p * inv_h);
    [t.x as i32, t.y as i32, t.z as i32]
}

/// The runs of consecutive `positions` in one cell of `depth`, in order: each cell with the
/// range of its points. For points in Morton order at a depth ≥ `depth` each cell has one run.
pub(crate) fn cell_runs(
    positions: &[DVec3],
    depth: u32,
) -> impl Iterator<Item = ([i32; 3], Range<usize>)> + '_ {
    let inv_h = (depth as f64).exp2();
    let mut start = 0;
    std::iter::from_fn(move || {
        let first = positions.get(start)?;
        let cell = cell_of(*first, inv_h);
        let run = start
            ..start
                + positions[start..]
                    .iter()
                    .position(|p| cell_of(*p, inv_h) != cell)
                    .unwrap_or(positions.len() - start);
        start = run.end;
        Some((cell, run))
    })
}

/// Where to cut `positions` (in Morton order at a depth ≥ `depth`, so that each cell's points
/// are consecutive) into pieces of about `per_piece` points without splitting a cell of
/// `depth`: the pieces' bounds, from 0 to the count (a fixed count apart, so the same pieces at
/// any thread count).
pub(crate) fn cuts_between_cells(positions: &[DVec3], depth: u32, per_piece: usize) -> Vec<usize> {
    let inv_h = (depth as f64).exp2();
    let cell = |s: usize| cell_of(positions[s], inv_h);
    let n = positions.len();
    let mut cuts = vec![0];
    while let Some(&last) = cuts.last() {
        let mut cut = last + per_piece;
        if cut >= n {
            break;
        }
        while cut < n && cell(cut) == cell(cut - 1) {
            cut += 1;
        }
        cuts.push(cut);
    }
    cuts.push(n);
    cuts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_is_f64_floor_bit_for_bit() {
        let mut special = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            0.999_999_999_999_999_9,
            -0.999_999_999_999_999_9,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            -4_503_599_627_370_497.0,
            9.3e18,
            -9.3e18,
            1e300,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..100_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            // Random bit patterns (every magnitude) and values near the integers of the grid.
            special.push(f64::from_bits(state));
            special.push((state % 4_000_000) as f64 / 1000.0 - 2000.0);
        }
        for x in special {
            let (got, want) = (floor(x), x.floor());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{x:e}: {got:e} against {want:e}"
            );
        }
    }

    #[test]
    fn morton_round_trips_including_halo_coordinates() {
        for c in [[0, 0, 0], [-2, 5, 7], [65537, -8, 3], [123, 456, 789]] {
            assert_eq!(unmorton(morton(c)), c);
        }
    }

    #[test]
    fn nested_keys_of_a_cells_descendants_are_contiguous() {
        let parent = morton_nested([3, 5, 6]);
        for child in 0..8u32 {
            let c = [6 + (child & 1), 10 + (child >> 1 & 1), 12 + (child >> 2)];
            assert_eq!(morton_nested(c) >> 3, parent);
        }
    }

    #[test]
    fn cells_floor_towards_negative_infinity() {
        assert_eq!(cell_of(DVec3::new(0.5, 0.0, -0.01), 4.0), [2, 0, -1]);
    }

    #[test]
    fn cell_runs_cover_the_points_in_order_one_run_per_change_of_cell() {
        // Depth 1 (cells of width 1/2): a run of two, one of one, then the first cell again
        // (not consecutive, so its own run), and a last point alone.
        let points = [
            DVec3::new(0.1, 0.1, 0.1),
            DVec3::new(0.4, 0.2, 0.3),
            DVec3::new(0.6, 0.1, 0.1),
            DVec3::new(0.2, 0.2, 0.2),
            DVec3::new(0.9, 0.9, 0.9),
        ];
        let runs: Vec<_> = cell_runs(&points, 1).collect();
        assert_eq!(
            runs,
            [
                ([0, 0, 0], 0..2),
                ([1, 0, 0], 2..3),
                ([0, 0, 0], 3..4),
                ([1, 1, 1], 4..5),
            ]
        );
        assert_eq!(cell_runs(&[], 3).count(), 0);
    }
}

//! How many cells of each depth the input's points occupy, counted in the columns pass without
//! holding the cells: what the memory budget's planner predicts the base's screening groups by
//! (one group per occupied cell of each proxy depth, `passes.rs`), for the whole cloud, before
//! any slab is cut.
//!
//! Each depth's count is a HyperLogLog sketch (Flajolet, Fusy, Gandouet & Meunier, 2007): a
//! cell's key is hashed, the hash's first [`INDEX_BITS`] bits choose a register and the register
//! keeps the longest run of leading zeros seen in the rest. The registers of two parts'
//! sketches merge by their maximum, so the members of a team count their parts and the sketches
//! joined count the whole input, exactly as one sketch of all of it would (the count does not
//! depend on the parts or their order). With 4,096 registers a depth, the count's relative
//! standard error is 1.04/√4096 = 1.6 %.

use super::team::{Packer, Unpacker};
use super::OutOfCoreError;
use glam::DVec3;

/// Bits of the hash that choose the register.
const INDEX_BITS: u32 = 12;
const REGISTERS: usize = 1 << INDEX_BITS;

/// The occupied cells of depths 0..=`finest`, counted by sketch.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OccupiedCells {
    /// `registers[d]`: depth d's sketch.
    registers: Vec<Vec<u8>>,
}

impl OccupiedCells {
    pub(crate) fn new(finest: u32) -> Self {
        debug_assert!(finest <= crate::params::MAX_DEPTH);
        OccupiedCells {
            registers: vec![vec![0; REGISTERS]; finest as usize + 1],
        }
    }

    /// Counts the cells holding the points at `unit` (in the unit cube).
    pub(crate) fn add(&mut self, unit: &[DVec3]) {
        let finest = self.registers.len() as u32 - 1;
        let side = f64::from(finest).exp2();
        let last = (1u64 << finest) - 1;
        for p in unit {
            // The cell at the finest depth; a coarser one is it shifted (x·2^d is exact).
            let cell = [p.x, p.y, p.z].map(|v| ((v * side).max(0.0) as u64).min(last));
            for (d, registers) in self.registers.iter_mut().enumerate() {
                let shift = finest - d as u32;
                let [x, y, z] = cell.map(|c| c >> shift);
                // 21 bits an axis hold any depth up to `params::MAX_DEPTH` (16).
                let hash = mix(x | y << 21 | z << 42);
                let register = (hash >> (64 - INDEX_BITS)) as usize;
                let rank = ((hash << INDEX_BITS) | (1 << (INDEX_BITS - 1))).leading_zeros() + 1;
                registers[register] = registers[register].max(rank as u8);
            }
        }
    }

    /// Joins the count of other points (another part's).
    pub(crate) fn join(&mut self, other: &OccupiedCells) {
        for (mine, theirs) in self.registers.iter_mut().zip(&other.registers) {
            for (a, b) in mine.iter_mut().zip(theirs) {
                *a = (*a).max(*b);
            }
        }
    }

    /// The estimated number of occupied cells of `depth`, at most the cells the depth has.
    pub(crate) fn at(&self, depth: u32) -> f64 {
        let registers = &self.registers[depth as usize];
        let m = REGISTERS as f64;
        let alpha = 0.7213 / (1.0 + 1.079 / m);
        let harmonic: f64 = registers.iter().map(|&r| (-f64::from(r)).exp2()).sum();
        let raw = alpha * m * m / harmonic;
        let empty = registers.iter().filter(|&&r| r == 0).count();
        // Few cells: the share of registers left empty counts them better (linear counting).
        let estimate = if raw <= 2.5 * m && empty > 0 {
            m * (m / empty as f64).ln()
        } else {
            raw
        };
        estimate.min((3.0 * f64::from(depth)).exp2())
    }

    pub(crate) fn pack(&self, p: &mut Packer) {
        p.u64(self.registers.len() as u64);
        for registers in &self.registers {
            p.u64s(
                &registers
                    .chunks_exact(8)
                    .map(|bytes| u64::from_le_bytes(bytes.try_into().expect("8 registers")))
                    .collect::<Vec<_>>(),
            );
        }
    }

    pub(crate) fn unpack(u: &mut Unpacker<'_>) -> Result<Self, OutOfCoreError> {
        let depths = u.u64()?;
        let registers = (0..depths)
            .map(|_| {
                let words = u.u64s()?;
                if words.len() * 8 != REGISTERS {
                    return Err(OutOfCoreError::internal(
                        "a part's count of occupied cells has the wrong size",
                    ));
                }
                Ok(words.iter().flat_map(|w| w.to_le_bytes()).collect())
            })
            .collect::<Result<Vec<Vec<u8>>, _>>()?;
        if registers.is_empty() {
            return Err(OutOfCoreError::internal(
                "a part's count of occupied cells has no depth",
            ));
        }
        Ok(OccupiedCells { registers })
    }
}

/// A 64-bit hash of a cell's packed coordinates (the finalizer of SplitMix64: every input bit
/// reaches every output bit).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outofcore::passes::tests::sphere;
    use std::collections::HashSet;

    fn exact(points: &[DVec3], depth: u32) -> usize {
        let side = f64::from(depth).exp2();
        points
            .iter()
            .map(|p| [p.x, p.y, p.z].map(|v| (v * side) as u64))
            .collect::<HashSet<_>>()
            .len()
    }

    /// Proves the counts are those of the cells, within four standard errors (6.5 %), from a
    /// handful of cells to more than the registers, and that counting in parts joined counts
    /// the same registers as counting at once.
    #[test]
    fn the_sketches_count_the_occupied_cells_whatever_the_parts() {
        let points = sphere(200_000);
        let mut whole = OccupiedCells::new(10);
        whole.add(&points);
        for depth in 0..=10 {
            let exact = exact(&points, depth) as f64;
            let counted = whole.at(depth);
            assert!(
                (counted - exact).abs() <= 0.065 * exact,
                "depth {depth}: {counted} counted, {exact} occupied"
            );
        }
        // Depth 10 has more occupied cells than registers: the raw estimate is what counts.
        assert!(exact(&points, 10) > 5 * REGISTERS);
        let mut joined = OccupiedCells::new(10);
        for part in points.chunks(30_001).rev() {
            let mut counted = OccupiedCells::new(10);
            counted.add(part);
            let mut p = Packer::default();
            counted.pack(&mut p);
            joined.join(&OccupiedCells::unpack(&mut Unpacker::new(&p.bytes)).unwrap());
        }
        assert_eq!(joined, whole);
    }

    /// Proves a count never passes the cells its depth has, and a point repeated is one cell.
    #[test]
    fn a_count_is_bounded_by_the_depths_cells() {
        let mut counted = OccupiedCells::new(3);
        counted.add(&sphere(5_000));
        counted.add(&sphere(5_000));
        assert_eq!(counted.at(0), 1.0);
        assert!(counted.at(1) <= 8.0);
        let mut one = OccupiedCells::new(6);
        one.add(&[DVec3::splat(0.3); 100]);
        for depth in 0..=6 {
            assert!((one.at(depth) - 1.0).abs() < 1e-3, "depth {depth}");
        }
    }
}

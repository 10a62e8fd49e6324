//! The system's SIMD code: the Laplacian's passes compiled for AVX-512 and the window gathers
//! with POPCNT and AVX-512 expanding loads, each chosen at run time when the CPU has the
//! feature and otherwise the portable code of [`super::bricks`]. Both paths give the same
//! values bit for bit (no fused multiply-adds, no reordering). The gathers announce the nodes
//! they will read a few bricks ahead (`crate::cache`).

use super::bricks::{BrickScratch, CoreBricks, WINDOW};
use crate::bspline::Tables;
use crate::cache::prefetch;
use crate::octree::Level;

/// How many core bricks ahead a window's gather announces the nodes it will read
/// ([`CoreBricks::prefetch_window`]).
const PREFETCH_AHEAD: usize = 2;

/// `f64` values per 64-byte cache line.
const NODES_PER_LINE: usize = 8;

impl BrickScratch {
    /// The Laplacian's z-pass (every row of the window at the brick's 8 depths: M and D
    /// along z) and y-pass (the brick's 8 × 8 rows: M_y M_z and D_y M_z + M_y D_z), leaving
    /// the x-pass's two inputs in `y`. The same code compiled for AVX-512 where the CPU has it
    /// (checked at run time): its 12-wide rows take 2 vector operations instead of SSE2's 6
    /// (0.090 -> 0.060 s per application at depth 10 on the Happy Buddha; AVX2 0.069 s). No
    /// fused multiply-adds and no reordering, so the values are the same bit for bit.
    pub(super) fn laplacian_passes<const REACH: usize>(&mut self, w: &[[f64; WINDOW]], t: &Tables) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has the feature the function is compiled for.
            unsafe { self.laplacian_passes_avx512::<REACH>(w, t) };
            return;
        }
        self.laplacian_passes_portable::<REACH>(w, t);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn laplacian_passes_avx512<const REACH: usize>(
        &mut self,
        w: &[[f64; WINDOW]],
        t: &Tables,
    ) {
        self.laplacian_passes_portable::<REACH>(w, t);
    }
}

impl CoreBricks {
    /// The components on the window of core brick `cb` (zero where K_d has no node), node by
    /// node. Counting a group's rank in its brick is a population count: with the POPCNT
    /// instruction (checked at run time on x86-64) it is one instruction instead of a dozen.
    pub(super) fn gather<const C: usize>(
        &self,
        level: &Level,
        cb: usize,
        read: &(impl Fn(usize) -> [f64; C] + Sync),
        windows: &mut [Vec<[f64; WINDOW]>; C],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU has the feature the function is compiled for.
            unsafe { self.gather_popcnt(level, cb, read, windows) };
            return;
        }
        self.gather_portable(level, cb, read, windows);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "popcnt")]
    unsafe fn gather_popcnt<const C: usize>(
        &self,
        level: &Level,
        cb: usize,
        read: &(impl Fn(usize) -> [f64; C] + Sync),
        windows: &mut [Vec<[f64; WINDOW]>; C],
    ) {
        self.gather_portable(level, cb, read, windows);
    }

    /// [`CoreBricks::gather`] of one vector: on x86-64 CPUs with AVX-512 each 2×2×2 group is
    /// one expanding load (its nodes are consecutive in `input`) and four stores, half the
    /// time of the node-by-node walk on the Laplacian's windows; the same values either way.
    pub(super) fn gather_values(
        &self,
        level: &Level,
        cb: usize,
        input: &[f64],
        window: &mut Vec<[f64; WINDOW]>,
    ) {
        self.prefetch(level, cb + PREFETCH_AHEAD, input);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            // SAFETY: the CPU has the features the function is compiled for.
            unsafe { self.gather_values_avx512(level, cb, input, window) };
            return;
        }
        self.gather(level, cb, &|n| [input[n]], std::array::from_mut(window));
    }

    /// [`CoreBricks::prefetch_window`], with the POPCNT instruction where the CPU has it
    /// (checked at run time on x86-64).
    fn prefetch(&self, level: &Level, cb: usize, input: &[f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU has the feature the function is compiled for.
            unsafe { self.prefetch_window_popcnt(level, cb, input) };
            return;
        }
        self.prefetch_window(level, cb, input);
    }

    /// [`CoreBricks::prefetch_window`] with the POPCNT instruction for its counts (three per
    /// occupancy word), which the portable code computes in a dozen instructions each: 8 %
    /// of the solve at depth 10 before.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "popcnt")]
    unsafe fn prefetch_window_popcnt(&self, level: &Level, cb: usize, input: &[f64]) {
        self.prefetch_window(level, cb, input);
    }

    /// Announces to the cache the nodes of `input` that the window of core brick `cb` reads
    /// (nothing past the last core brick): per occupancy word of each of the 27 bricks around,
    /// the nodes from its first to its last in the window, one hint per 64-byte line. Those
    /// bricks lie far apart in K_d's order (a brick's neighbours across y and z are rows and
    /// planes of bricks away) and a depth's vector is larger than the cache, so without the
    /// hint a window's gather waits on memory: measured on the Happy Buddha at depth 10
    /// (degree 1, one thread), hints two bricks ahead took the solve from 3.5 to 3.1 s and the
    /// system stage from 1.4 to 1.2 s (one to eight bricks ahead do about as well), and
    /// hinting only the words' wanted nodes rather than whole bricks 3 % more off the solve.
    #[inline(always)]
    fn prefetch_window(&self, level: &Level, cb: usize, input: &[f64]) {
        if cb >= self.len() {
            return;
        }
        self.for_each_window_word(level, cb, |_, _, before, occ, wanted| {
            // The nodes from the word's first wanted one to its last.
            let below = |bit: u32| (occ & ((1u64 << bit) - 1)).count_ones() as usize;
            let low = before + below(wanted.trailing_zeros());
            let high = before + below(63 - wanted.leading_zeros());
            if let Some(nodes) = input.get(low..=high) {
                // A hint every line's width from the first node, and the last node, whose line
                // the steps miss when the first is not at a line's start.
                for line in nodes.chunks(NODES_PER_LINE) {
                    prefetch(&line[0]);
                }
                prefetch(&nodes[nodes.len() - 1]);
            }
        });
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,popcnt")]
    unsafe fn gather_values_avx512(
        &self,
        level: &Level,
        cb: usize,
        input: &[f64],
        window: &mut [[f64; WINDOW]],
    ) {
        use std::arch::x86_64::*;
        window.fill([0.0; WINDOW]);
        let rows = window.len();
        let out = window.as_mut_ptr() as *mut f64;
        self.for_each_window_group(level, cb, |node, present, [x, y, z]| {
            // Corner c of the group (x + 2y + 4z) is lane c; lanes 2k, 2k + 1 are a pair of x
            // neighbours in window row (z + k/2, y + k%2).
            assert!(node + present.count_ones() as usize <= input.len());
            assert!((z + 1) * WINDOW + y + 1 < rows && x + 1 < WINDOW);
            // SAFETY: the load reads one element per set bit of `present` from `node` on, and
            // the stores write two elements at x in rows of the window (both checked above).
            unsafe {
                let v = _mm512_maskz_expandloadu_pd(present, input.as_ptr().add(node));
                let (low, high) = (
                    _mm512_extractf64x4_pd::<0>(v),
                    _mm512_extractf64x4_pd::<1>(v),
                );
                let at = |row: usize| out.add(row * WINDOW + x);
                _mm_storeu_pd(at(z * WINDOW + y), _mm256_castpd256_pd128(low));
                _mm_storeu_pd(at(z * WINDOW + y + 1), _mm256_extractf128_pd::<1>(low));
                _mm_storeu_pd(at((z + 1) * WINDOW + y), _mm256_castpd256_pd128(high));
                _mm_storeu_pd(
                    at((z + 1) * WINDOW + y + 1),
                    _mm256_extractf128_pd::<1>(high),
                );
            }
        });
    }
}

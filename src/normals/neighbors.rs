//! Exact k nearest neighbours of every point, on a uniform bucket grid.
//!
//! The grid covers the points' bounding box with cubic cells of width h, h chosen (by
//! bisection) as the smallest width whose grid has at most [`CELLS_PER_POINT`] cells per point
//! (flat or thin boxes get one layer of cells along their thin axes). The points are
//! counting-sorted by cell (and by index within a cell), so each cell is one contiguous range
//! and the queries, run in that order, walk memory in order.
//!
//! A query visits the rings of cells around its own cell (ring r: the cells at Chebyshev
//! distance r in cell units) outward, keeping the k best candidates by (squared distance, index).
//! After ring r every point not yet seen lies outside the (2r+1)³ block of cells, so at least as
//! far as the query's distance to that block's nearest face (a face on the grid's border does
//! not count: nothing lies beyond it). Once the k-th best distance is below that bound the list
//! is final: the search is exact, not approximate. Ties in distance go to the smaller index, so
//! the lists do not depend on the grid, the thread count or the order of the work.

use super::{StepProgress, BATCH};
use crate::error::Result;
use glam::DVec3;
use rayon::prelude::*;

/// Grid cells per point, at most. Points on a surface fill only a thin shell of the box's cells,
/// so a few cells per point still leaves a handful of points in each occupied cell.
const CELLS_PER_POINT: f64 = 2.0;

/// The k nearest other points of every point, as a row of `k` original indices per point,
/// nearest first (ties by index). A point is never its own neighbour; a duplicate of it is.
#[derive(Debug, Clone)]
pub(super) struct Neighbors {
    k: usize,
    indices: Vec<u32>,
}

impl Neighbors {
    /// Neighbours per point.
    pub(super) fn k(&self) -> usize {
        self.k
    }

    /// The neighbours of point `i`, nearest first.
    pub(super) fn of(&self, i: usize) -> &[u32] {
        &self.indices[i * self.k..(i + 1) * self.k]
    }

    /// Every row, in point order.
    pub(super) fn rows(&self) -> std::slice::ChunksExact<'_, u32> {
        self.indices.chunks_exact(self.k)
    }
}

/// Cells of width `h` on the box `lo..hi`, points sorted by cell.
struct Grid {
    lo: DVec3,
    h: f64,
    dims: [usize; 3],
    /// `cell_start[c]..cell_start[c + 1]` are the slots of cell c in `order`.
    cell_start: Vec<u32>,
    /// Original point indices sorted by (cell, index).
    order: Vec<u32>,
    /// `positions[order[s]]`, so that a cell's points are read contiguously.
    sorted: Vec<DVec3>,
}

impl Grid {
    fn new(positions: &[DVec3]) -> Grid {
        let (lo, hi) = positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let extent = hi - lo;
        let budget = (positions.len() as f64 * CELLS_PER_POINT).max(1.0);
        let cells_for = |h: f64| -> f64 {
            extent
                .to_array()
                .iter()
                .map(|&e| (e / h).ceil().max(1.0))
                .product()
        };
        // The smallest h whose grid fits the budget: cells_for falls as h grows, and the box's
        // largest extent (one cell) always fits.
        let mut high = extent.max_element().max(f64::MIN_POSITIVE);
        let mut low = high / budget;
        for _ in 0..64 {
            let mid = 0.5 * (low + high);
            if mid <= low || mid >= high {
                break;
            }
            if cells_for(mid) <= budget {
                high = mid;
            } else {
                low = mid;
            }
        }
        let h = high;
        let dims = extent.to_array().map(|e| ((e / h).ceil() as usize).max(1));
        let cells = dims[0] * dims[1] * dims[2];
        let mut grid = Grid {
            lo,
            h,
            dims,
            cell_start: Vec::new(),
            order: Vec::new(),
            sorted: Vec::new(),
        };
        let cell_of: Vec<u32> = positions
            .par_iter()
            .map(|&p| grid.linear(grid.cell(p)) as u32)
            .collect();
        let mut start = vec![0u32; cells + 1];
        for &c in &cell_of {
            start[c as usize + 1] += 1;
        }
        for c in 0..cells {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut order = vec![0u32; positions.len()];
        for (i, &c) in cell_of.iter().enumerate() {
            order[next[c as usize] as usize] = i as u32;
            next[c as usize] += 1;
        }
        grid.sorted = order.par_iter().map(|&i| positions[i as usize]).collect();
        grid.cell_start = start;
        grid.order = order;
        grid
    }

    /// The cell holding `p` (clamped into the grid).
    fn cell(&self, p: DVec3) -> [usize; 3] {
        let q = (p - self.lo) / self.h;
        let mut c = [0usize; 3];
        for a in 0..3 {
            c[a] = (q[a].max(0.0) as usize).min(self.dims[a] - 1);
        }
        c
    }

    fn linear(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// The k nearest other points of the point in slot `slot`, written to `row` (original
    /// indices). `best` is scratch space.
    fn query(&self, slot: usize, k: usize, best: &mut Vec<(f64, u32)>, row: &mut [u32]) {
        self.search(self.sorted[slot], self.order[slot], k, best);
        debug_assert_eq!(
            best.len(),
            k,
            "the caller checked that there are k other points"
        );
        for (out, &(_, j)) in row.iter_mut().zip(best.iter()) {
            *out = j;
        }
    }

    /// Fills `best` with the k nearest points to `p` other than the point `me` (u32::MAX for
    /// none), nearest first as (squared distance, index), ties by index; fewer when the grid
    /// holds fewer. `p` may lie outside the grid's box: its cell is clamped, and the bound below
    /// only counts faces with cells beyond them, so it stays a true lower bound.
    fn search(&self, p: DVec3, me: u32, k: usize, best: &mut Vec<(f64, u32)>) {
        let c = self.cell(p);
        best.clear();
        let mut r = 0usize;
        loop {
            self.visit_ring(c, r, me, p, k, best);
            // Distance from p to the nearest face of the visited block that has cells beyond it.
            let mut bound = f64::INFINITY;
            let mut covers_grid = true;
            for a in 0..3 {
                if c[a] > r {
                    covers_grid = false;
                    let face = self.lo[a] + (c[a] - r) as f64 * self.h;
                    bound = bound.min(p[a] - face);
                }
                if c[a] + r + 1 < self.dims[a] {
                    covers_grid = false;
                    let face = self.lo[a] + (c[a] + r + 1) as f64 * self.h;
                    bound = bound.min(face - p[a]);
                }
            }
            if covers_grid {
                break;
            }
            // Cell assignment and face positions round independently: keep a margin.
            let bound = (bound - 1e-9 * self.h).max(0.0);
            if best.len() == k && best[k - 1].0 < bound * bound {
                break;
            }
            r += 1;
        }
    }

    /// Offers every point of the cells at Chebyshev distance `r` from cell `c` to `best`.
    fn visit_ring(
        &self,
        c: [usize; 3],
        r: usize,
        me: u32,
        p: DVec3,
        k: usize,
        best: &mut Vec<(f64, u32)>,
    ) {
        let range = |a: usize| {
            let from = c[a].saturating_sub(r);
            let to = (c[a] + r).min(self.dims[a] - 1);
            from..=to
        };
        for z in range(2) {
            let z_shell = z.abs_diff(c[2]) == r;
            for y in range(1) {
                let yz_shell = z_shell || y.abs_diff(c[1]) == r;
                if yz_shell {
                    // The whole row is on the shell: one contiguous run of cells.
                    let xs = range(0);
                    let first = self.linear([*xs.start(), y, z]);
                    let last = self.linear([*xs.end(), y, z]);
                    self.offer(
                        self.cell_start[first] as usize..self.cell_start[last + 1] as usize,
                        me,
                        p,
                        k,
                        best,
                    );
                } else {
                    // Only the row's two ends are on the shell.
                    if c[0] >= r {
                        let cell = self.linear([c[0] - r, y, z]);
                        self.offer(self.cells(cell), me, p, k, best);
                    }
                    if r > 0 && c[0] + r < self.dims[0] {
                        let cell = self.linear([c[0] + r, y, z]);
                        self.offer(self.cells(cell), me, p, k, best);
                    }
                }
            }
        }
    }

    fn cells(&self, cell: usize) -> std::ops::Range<usize> {
        self.cell_start[cell] as usize..self.cell_start[cell + 1] as usize
    }

    /// Offers the points in `slots` to the sorted candidate list `best` (at most k, by
    /// (squared distance, index)).
    fn offer(
        &self,
        slots: std::ops::Range<usize>,
        me: u32,
        p: DVec3,
        k: usize,
        best: &mut Vec<(f64, u32)>,
    ) {
        for s in slots {
            let j = self.order[s];
            if j == me {
                continue;
            }
            let d2 = (self.sorted[s] - p).length_squared();
            let candidate = (d2, j);
            if best.len() == k {
                let worst = best[k - 1];
                if (candidate.0, candidate.1) >= (worst.0, worst.1) {
                    continue;
                }
                best.pop();
            }
            let at = best.partition_point(|&(d, i)| (d, i) < (candidate.0, candidate.1));
            best.insert(at, candidate);
        }
    }
}

/// Exact nearest-point queries from arbitrary points against a fixed set (e.g. from a mesh's
/// triangles to the samples): the same grid and ring search as [`k_nearest`].
pub(super) struct PointIndex {
    grid: Grid,
}

impl PointIndex {
    /// The index over `positions` (at least one, all finite; the caller checks).
    pub(super) fn new(positions: &[DVec3]) -> PointIndex {
        assert!(!positions.is_empty() && positions.len() <= u32::MAX as usize);
        PointIndex {
            grid: Grid::new(positions),
        }
    }

    /// The `k` points nearest to `p` (fewer when there are fewer), nearest first as (squared
    /// distance, index); ties by index. `best` is the answer's storage, reused across calls.
    pub(super) fn nearest<'a>(
        &self,
        p: DVec3,
        k: usize,
        best: &'a mut Vec<(f64, u32)>,
    ) -> &'a [(f64, u32)] {
        self.grid.search(p, u32::MAX, k, best);
        best
    }
}

/// The `k` nearest other points of every point (exact; ties by index). Needs more than `k`
/// points, all finite (the caller checks both). The searches run in `pool`, [`BATCH`] points at
/// a time, with `progress(fraction done)` called on the calling thread after each batch (it may
/// stop the work).
pub(super) fn k_nearest(
    positions: &[DVec3],
    k: usize,
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<Neighbors> {
    assert!(k >= 1 && positions.len() > k && positions.len() <= u32::MAX as usize);
    let grid = pool.install(|| Grid::new(positions));
    let mut by_slot = vec![0u32; positions.len() * k];
    let batches = positions.len().div_ceil(BATCH);
    for (batch, rows) in by_slot.chunks_mut(BATCH * k).enumerate() {
        pool.install(|| {
            rows.par_chunks_mut(k).enumerate().for_each_init(
                || Vec::with_capacity(k + 1),
                |best, (row_in_batch, row)| grid.query(batch * BATCH + row_in_batch, k, best, row),
            )
        });
        progress((batch + 1) as f32 / batches as f32)?;
    }
    // Back to the points' own order.
    let mut slot_of = vec![0u32; positions.len()];
    for (slot, &i) in grid.order.iter().enumerate() {
        slot_of[i as usize] = slot as u32;
    }
    let mut indices = vec![0u32; positions.len() * k];
    pool.install(|| {
        indices
            .par_chunks_mut(k)
            .zip(slot_of.par_iter())
            .for_each(|(row, &slot)| {
                let slot = slot as usize;
                row.copy_from_slice(&by_slot[slot * k..(slot + 1) * k]);
            })
    });
    Ok(Neighbors { k, indices })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact answer by brute force: every other point sorted by (squared distance, index).
    fn brute_force(positions: &[DVec3], k: usize) -> Vec<u32> {
        let mut out = Vec::new();
        for (i, &p) in positions.iter().enumerate() {
            let mut all: Vec<(f64, u32)> = positions
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(j, &q)| ((q - p).length_squared(), j as u32))
                .collect();
            all.sort_by(|a, b| a.partial_cmp(b).unwrap());
            out.extend(all[..k].iter().map(|&(_, j)| j));
        }
        out
    }

    /// A small deterministic pseudo-random sequence in [0, 1).
    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn matches_brute_force_on_scattered_clustered_and_flat_points() {
        let mut seed = 7;
        let mut clouds: Vec<Vec<DVec3>> = Vec::new();
        // Uniform in a cube.
        clouds.push(
            (0..600)
                .map(|_| DVec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
                .collect(),
        );
        // A flat square (zero extent in z) with a far outlier.
        let mut flat: Vec<DVec3> = (0..500)
            .map(|_| DVec3::new(lcg(&mut seed), lcg(&mut seed), 0.0))
            .collect();
        flat.push(DVec3::new(40.0, -3.0, 0.0));
        clouds.push(flat);
        // A lattice: many exactly equal distances, so ties decide; and duplicated points.
        let mut lattice = Vec::new();
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..3 {
                    lattice.push(DVec3::new(x as f64, y as f64, z as f64));
                }
            }
        }
        lattice.extend_from_within(..40);
        clouds.push(lattice);
        // Two clusters far apart.
        clouds.push(
            (0..400)
                .map(|i| {
                    let offset = if i % 2 == 0 { 0.0 } else { 1000.0 };
                    DVec3::new(lcg(&mut seed) + offset, lcg(&mut seed), lcg(&mut seed))
                })
                .collect(),
        );
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for (c, cloud) in clouds.iter().enumerate() {
            for k in [1, 6, 20] {
                let got = k_nearest(cloud, k, &pool, &mut |_| Ok(())).unwrap();
                assert_eq!(got.indices, brute_force(cloud, k), "cloud {c}, k = {k}");
            }
        }
    }
}

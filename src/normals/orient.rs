//! Choosing the sign of every normal.
//!
//! * Towards a viewpoint, or towards each point's own sensor: n ← −n where n·(v − p) < 0.
//! * Propagation (Hoppe, DeRose, Duchamp, McDonald & Stuetzle 1992, §3.3): the symmetrised kNN
//!   graph gets edge weights w_ij = 1 − |n_i·n_j| (small where the two tangent planes agree, so
//!   the sign is carried across where it is least ambiguous) plus (|n_i·d| + |n_j·d|)/2, d the
//!   unit vector from p_i to p_j: how far the edge leaves the two tangent planes. Without that
//!   term an edge straight across a thin wall (parallel planes, weight 0) is as good as one
//!   along the wall and the two sides get one sign (measured: a 2 × 2 × 0.08 plate sampled
//!   10× unevenly had 47.5 % of its normals flipped, 0.04 % with it). Its minimum spanning forest is
//!   found by Kruskal's algorithm over edges sorted by (w rounded to f32, edge number), the
//!   edge number being i·k + rank of j among i's neighbours (nearer first), so that equal
//!   weights go to the smaller index and then to the shorter edge, and the forest does not
//!   depend on the thread count. Walking each tree from its seed, every child is flipped to
//!   agree with its parent (n_child·n_parent ≥ 0).
//!
//!   Every tree (a connected component of the graph) gets its own seed: the component's point
//!   with the largest x (ties: the smaller index), whose normal is made to have a non-negative
//!   x component (on a closed surface the outward normal at the x-extreme point is +x). Then
//!   the component's sign is checked as a whole: by the divergence theorem
//!   ∮ n·(p − c) dA = 3·volume > 0 for outward normals of a closed surface, whatever c. The sum
//!   is estimated over the samples with area weights r_i² (r_i the distance to the k-th
//!   neighbour, so that unevenly sampled regions count by their area, not their sample count).
//!   When the net flux is at least [`CLOSED_FLUX_FRACTION`] of the total absolute flux
//!   Σ r_i² |n_i·(p_i − c)| the surface encloses volume and its sign decides; below that (an
//!   open sheet, where the flux is near zero either way) the seed's rule stands.

use super::neighbors::Neighbors;
use super::{StepProgress, BATCH};
use crate::error::{Error, Result};
use glam::DVec3;
use rayon::prelude::*;

/// The fraction of the total absolute flux above which the net flux decides a component's sign
/// (see the module documentation). On a closed surface the net flux is 3·volume; e.g. a sphere
/// has ratio 1, a ring torus with R/r = 1/0.35 about 0.8, a flat box of thickness t and side L
/// about 1. An open sheet has a net flux near 0.
const CLOSED_FLUX_FRACTION: f64 = 0.25;

/// Edges of Kruskal's loop between two progress reports (a few milliseconds of work).
const KRUSKAL_EDGES_PER_REPORT: usize = 1 << 18;

/// Flips every normal to face `viewpoint`.
pub(super) fn towards_viewpoint(positions: &[DVec3], normals: &mut [DVec3], viewpoint: DVec3) {
    normals
        .par_iter_mut()
        .zip(positions.par_iter())
        .for_each(|(n, &p)| {
            if n.dot(viewpoint - p) < 0.0 {
                *n = -*n;
            }
        });
}

/// Flips every normal to face its own sensor position.
pub(super) fn towards_sensors(positions: &[DVec3], normals: &mut [DVec3], sensors: &[[f32; 3]]) {
    normals
        .par_iter_mut()
        .zip(positions.par_iter())
        .zip(sensors.par_iter())
        .for_each(|((n, &p), s)| {
            let s = DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64);
            if n.dot(s - p) < 0.0 {
                *n = -*n;
            }
        });
}

/// Union–find over point indices, with path halving and union by size.
struct Forest {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl Forest {
    fn new(n: usize) -> Forest {
        Forest {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    /// Joins the sets of `a` and `b`; false when they were already one.
    fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
        true
    }
}

/// Orients `normals` consistently by propagation along the minimum spanning forest of the
/// kNN graph, each component's sign set as the module documentation says. The parallel parts
/// run in `pool`; `progress(fraction done)` is called on the calling thread between the steps
/// and every [`KRUSKAL_EDGES_PER_REPORT`] edges of Kruskal's loop (it may stop the work).
pub(super) fn propagate(
    positions: &[DVec3],
    normals: &mut [DVec3],
    neighbors: &Neighbors,
    pool: &rayon::ThreadPool,
    progress: StepProgress<'_>,
) -> Result<()> {
    let n = positions.len();
    let k = neighbors.k();
    if n.checked_mul(k)
        .is_none_or(|edges| edges > u32::MAX as usize)
    {
        return Err(Error::InvalidParameter {
            name: "neighbors",
            value: k.to_string(),
            expected: "a count with points × neighbors below 2^32 for orientation by propagation",
        });
    }
    let mut keys = Vec::new();
    let batches = n.div_ceil(BATCH);
    for batch in 0..batches {
        let points = batch * BATCH..((batch + 1) * BATCH).min(n);
        pool.install(|| keys.par_extend(edge_keys(positions, normals, neighbors, points)));
        progress(0.3 * (batch + 1) as f32 / batches as f32)?;
    }
    // The keys are distinct (distinct edge numbers), so the order is unique. (One call: the
    // only step that reports no progress for longer than a batch, about 0.1 s per million
    // points per core.)
    pool.install(|| keys.par_sort_unstable());
    progress(0.45)?;

    // Kruskal: the minimum spanning forest's edges, as (parent-to-be, child-to-be) pairs.
    let mut forest = Forest::new(n);
    let mut tree_edges: Vec<(u32, u32)> = Vec::with_capacity(n);
    let edges = keys.len();
    for (number, key) in keys.into_iter().enumerate() {
        if number % KRUSKAL_EDGES_PER_REPORT == KRUSKAL_EDGES_PER_REPORT - 1 {
            progress(0.45 + 0.4 * (number as f32 / edges as f32))?;
        }
        let edge = (key & 0xffff_ffff) as usize;
        let (i, j) = ((edge / k) as u32, neighbors.of(edge / k)[edge % k]);
        if forest.union(i, j) {
            tree_edges.push((i, j));
            if tree_edges.len() + 1 == n {
                break;
            }
        }
    }
    progress(0.85)?;

    // The forest's adjacency (CSR).
    let mut start = vec![0u32; n + 1];
    for &(a, b) in &tree_edges {
        start[a as usize + 1] += 1;
        start[b as usize + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut next = start.clone();
    let mut adjacent = vec![0u32; 2 * tree_edges.len()];
    for &(a, b) in &tree_edges {
        adjacent[next[a as usize] as usize] = b;
        next[a as usize] += 1;
        adjacent[next[b as usize] as usize] = a;
        next[b as usize] += 1;
    }

    // Components: their roots, seeds (largest x, then smallest index) and members.
    let root: Vec<u32> = (0..n as u32).map(|i| forest.find(i)).collect();
    let mut seed_of_root: Vec<u32> = vec![u32::MAX; n];
    for i in 0..n {
        let r = root[i] as usize;
        let s = seed_of_root[r];
        if s == u32::MAX || positions[i].x > positions[s as usize].x {
            seed_of_root[r] = i as u32;
        }
    }

    // Walk each tree from its seed, flipping children to agree with their parents.
    let mut visited = vec![false; n];
    let mut stack: Vec<u32> = Vec::new();
    for &seed in &seed_of_root {
        if seed == u32::MAX {
            continue;
        }
        let seed = seed as usize;
        if normals[seed].x < 0.0 {
            normals[seed] = -normals[seed];
        }
        visited[seed] = true;
        stack.push(seed as u32);
        while let Some(parent) = stack.pop() {
            let parent = parent as usize;
            for &child in &adjacent[start[parent] as usize..start[parent + 1] as usize] {
                let child = child as usize;
                if visited[child] {
                    continue;
                }
                visited[child] = true;
                if normals[child].dot(normals[parent]) < 0.0 {
                    normals[child] = -normals[child];
                }
                stack.push(child as u32);
            }
        }
    }
    debug_assert!(visited.iter().all(|&v| v));
    progress(0.93)?;

    // The net flux of each component decides its sign when it encloses volume.
    let area: Vec<f64> = pool.install(|| {
        (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let far = neighbors.of(i)[k - 1] as usize;
                (positions[far] - positions[i]).length_squared()
            })
            .collect()
    });
    let mut weight_sum = vec![0.0f64; n];
    let mut centroid = vec![DVec3::ZERO; n];
    for i in 0..n {
        let r = root[i] as usize;
        weight_sum[r] += area[i];
        centroid[r] += area[i] * positions[i];
    }
    let mut net = vec![0.0f64; n];
    let mut total = vec![0.0f64; n];
    for i in 0..n {
        let r = root[i] as usize;
        if weight_sum[r] <= 0.0 {
            continue;
        }
        let c = centroid[r] / weight_sum[r];
        let flux = area[i] * normals[i].dot(positions[i] - c);
        net[r] += flux;
        total[r] += flux.abs();
    }
    for i in 0..n {
        let r = root[i] as usize;
        if net[r] < 0.0 && -net[r] >= CLOSED_FLUX_FRACTION * total[r] {
            normals[i] = -normals[i];
        }
    }
    Ok(())
}

/// The undirected edges of the kNN graph from the points in `from`, as sort keys: the weight
/// (see the module documentation) as f32 bits in the high half, the edge number i·k + rank in
/// the low half. Edge i→j is kept unless j→i is also a kNN edge and j < i, so that over all
/// points each undirected edge appears once.
fn edge_keys<'a>(
    positions: &'a [DVec3],
    normals: &'a [DVec3],
    neighbors: &'a Neighbors,
    from: std::ops::Range<usize>,
) -> impl ParallelIterator<Item = u64> + 'a {
    let k = neighbors.k();
    from.into_par_iter()
        .with_min_len(1024)
        .flat_map_iter(move |i| {
            let row = neighbors.of(i);
            row.iter().enumerate().filter_map(move |(rank, &j)| {
                let j = j as usize;
                if j < i && neighbors.of(j).contains(&(i as u32)) {
                    return None;
                }
                let (a, b) = (normals[i], normals[j]);
                let d = (positions[j] - positions[i]).normalize_or_zero();
                let out_of_plane = 0.5 * (a.dot(d).abs() + b.dot(d).abs());
                let weight = ((1.0 - a.dot(b).abs()).max(0.0) + out_of_plane) as f32;
                // Non-negative f32s order like their bit patterns.
                Some(((weight.to_bits() as u64) << 32) | (i * k + rank) as u64)
            })
        })
}

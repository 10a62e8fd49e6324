//! The base: the depths 0..=B that are solved once for the whole cloud, from the sums of the
//! slabs' contributions.

use crate::grid::morton_nested;
use crate::solve::ProxyGroup;

/// The whole cloud's core sets at depths 0..=`base_depth` from the core sets of its slabs'
/// own points (each a `Vec` per depth of sorted packed keys, as
/// [`crate::octree::Octree::core_sets`] returns them): their union, depth by depth, sorted.
/// Exact, whatever the slabs and their padding, since the core sets of a union of samples are
/// the unions of their core sets.
pub(crate) fn coarse_cores<'a>(
    slab_cores: impl IntoIterator<Item = &'a [Vec<u64>]>,
    base_depth: u32,
) -> Vec<Vec<u64>> {
    let mut cores: Vec<Vec<u64>> = vec![Vec::new(); base_depth as usize + 1];
    for slab in slab_cores {
        for (union, keys) in cores.iter_mut().zip(slab) {
            union.extend_from_slice(keys);
        }
    }
    for union in &mut cores {
        union.sort_unstable();
        union.dedup();
    }
    cores
}

/// The screening groups at one proxy depth of the slabs before one, `merged` (in Morton order
/// of the cells, each cell once), with that slab's (`slab`, as [`crate::system::sample_groups`]
/// gives them): a cell split by a wall has a group in each slab, and their sums add up in slab
/// order. Merged slab by slab as they come, the whole cloud's groups are held once, not once
/// in the slabs' lists and again merged (on a 20-million-point cloud at a base of depth 9,
/// 14 million groups of 48 bytes).
pub(crate) fn merge_groups(merged: Vec<ProxyGroup>, slab: &[ProxyGroup]) -> Vec<ProxyGroup> {
    let key = |g: &ProxyGroup| morton_nested(g.0.map(|v| v.max(0) as u32));
    // `sample_groups` gives each cell once, in Morton order (and checks it).
    debug_assert!(
        slab.is_sorted_by_key(key),
        "a slab's groups not in Morton order"
    );
    let mut out: Vec<ProxyGroup> = Vec::with_capacity(merged.len() + slab.len());
    let mut add = |(cell, sum_p, sum_w): ProxyGroup| match out.last_mut() {
        Some(last) if last.0 == cell => {
            last.1 += sum_p;
            last.2 += sum_w;
        }
        _ => out.push((cell, sum_p, sum_w)),
    };
    let mut earlier = merged.into_iter().peekable();
    for &group in slab {
        while let Some(before) = earlier.next_if(|before| key(before) <= key(&group)) {
            add(before);
        }
        add(group);
    }
    earlier.for_each(add);
    out
}

/// The base's right-hand sides ρ_d and fields V_d, d ≤ B: the sums, node by node, of the
/// slabs' own parts, each computed on a tree whose depths up to B are the base's (so that the
/// same index is the same node in every slab).
#[derive(Debug, Default)]
pub(crate) struct BaseParts {
    pub(crate) rho: Vec<Vec<f64>>,
    pub(crate) field_v: Vec<[Vec<f64>; 3]>,
}

impl BaseParts {
    /// Adds one slab's ρ and V of depths 0..=`base_depth` (slabs added in order).
    pub(crate) fn add(&mut self, rho: &[Vec<f64>], field_v: &[[Vec<f64>; 3]], base_depth: usize) {
        if self.rho.is_empty() {
            self.rho = rho[..=base_depth].to_vec();
            self.field_v = field_v[..=base_depth].to_vec();
            return;
        }
        let add_into = |sum: &mut Vec<f64>, part: &Vec<f64>| {
            sum.iter_mut().zip(part).for_each(|(s, p)| *s += p);
        };
        for (sum, part) in self.rho.iter_mut().zip(rho) {
            add_into(sum, part);
        }
        for (sum, part) in self.field_v.iter_mut().zip(field_v) {
            for (s, p) in sum.iter_mut().zip(part) {
                add_into(s, p);
            }
        }
    }
}

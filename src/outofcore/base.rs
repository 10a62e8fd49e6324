//! The base: the depths 0..=B that are solved once for the whole cloud, from the sums of the
//! slabs' contributions.

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

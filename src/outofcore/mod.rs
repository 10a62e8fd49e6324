//! Reconstruction bigger than memory (issue 20): the slab decomposition of
//! `docs/out-of-core.md`, under construction.
//!
//! The unit cube is cut across x into slabs of balanced point counts ([`slabs`]); the depths up
//! to a base depth B are solved once for the whole cloud from the slabs' summed contributions
//! ([`base`]), the finer depths slab by slab over the slab's points and a padding of its
//! neighbours', with the base solution prolonged in.
//!
//! Built so far, each proved against the in-memory pipeline by `tests.rs`: the slab layout;
//! the base's core sets as the union of the slabs' own ([`base::coarse_cores`], exact:
//! [`crate::octree::Octree::core_sets`]); its ρ and V as sums of the slabs' own parts on trees
//! that share the base's depths; its screening proxies from the slabs' merged sample groups
//! ([`base::merge_groups`], [`crate::system::Proxies::from_groups`]); the cascade cut at the
//! base ([`crate::solve::Depths`]); and, in one process, slabs solved above the shared base
//! within the in-memory solver's own error of it. Not built: the input read in chunks and
//! binned to slab files, the passes over the slabs, the isovalue's and the extraction's seams,
//! the components across walls, the PLY written slab by slab, and the front ends.

pub(crate) mod base;
pub(crate) mod slabs;

#[cfg(test)]
mod tests;

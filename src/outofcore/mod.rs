//! Reconstruction bigger than memory (issue 20): the slab decomposition of
//! `docs/out-of-core.md`, under construction.
//!
//! The unit cube is cut across x into slabs of balanced point counts ([`slabs`]); the depths up
//! to a base depth B are solved once for the whole cloud from the slabs' summed contributions
//! ([`base`]), the finer depths slab by slab over the slab's points and a padding of its
//! neighbours', with the base solution prolonged in. Built so far: the slab layout and the base
//! depths' core sets as the union of the slabs' (exact: [`crate::octree::Octree::core_sets`]).

pub(crate) mod base;
pub(crate) mod slabs;

#[cfg(test)]
mod tests;

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
//! within the in-memory solver's own error of it; each slab's part of the mesh and the parts
//! welded by their vertices' keys, bit for bit the in-memory mesh over the same χ
//! ([`seams`]). Not built: the input read in chunks and binned to slab files, the passes over
//! the slabs, the isovalue's seams, the seeds exchanged between slabs, the components across
//! walls, the PLY written slab by slab, and the front ends.

pub(crate) mod assemble;
pub(crate) mod base;
pub(crate) mod passes;
pub(crate) mod run;
pub(crate) mod scan;
pub(crate) mod scratch;
pub(crate) mod seams;
pub(crate) mod slabs;

use crate::ply::PlyError;
use crate::Error;
use std::fmt;
use std::io;
use std::path::PathBuf;

/// Why a reconstruction out of core failed.
#[derive(Debug)]
pub enum OutOfCoreError {
    /// The input file could not be read.
    Input(PlyError),
    /// The points or the parameters were refused, or the reconstruction failed, as the
    /// in-memory path would say (a point's index is its index in the file).
    Reconstruction(Error),
    /// The temporary directory or a file in it could not be created, written or read (a full
    /// disk, a directory without write permission).
    Scratch {
        /// what was being done, e.g. "write a slab file"
        action: &'static str,
        /// the file or directory
        path: PathBuf,
        /// the operating system's error
        source: io::Error,
    },
    /// The output file could not be created or written.
    Output {
        /// the output file
        path: PathBuf,
        /// the operating system's error
        source: io::Error,
    },
}

impl fmt::Display for OutOfCoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OutOfCoreError::Input(e) => write!(f, "{e}"),
            OutOfCoreError::Reconstruction(e) => write!(f, "{e}"),
            OutOfCoreError::Scratch {
                action,
                path,
                source,
            } => write!(
                f,
                "could not {action} ({}): {source}; choose another temporary directory with \
                 enough free space",
                path.display()
            ),
            OutOfCoreError::Output { path, source } => {
                write!(
                    f,
                    "could not write the mesh to {}: {source}",
                    path.display()
                )
            }
        }
    }
}

impl std::error::Error for OutOfCoreError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            OutOfCoreError::Input(e) => Some(e),
            OutOfCoreError::Reconstruction(e) => Some(e),
            OutOfCoreError::Scratch { source, .. } | OutOfCoreError::Output { source, .. } => {
                Some(source)
            }
        }
    }
}

impl From<Error> for OutOfCoreError {
    fn from(e: Error) -> Self {
        OutOfCoreError::Reconstruction(e)
    }
}

#[cfg(test)]
mod tests;

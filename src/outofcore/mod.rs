//! Reconstruction bigger than memory (issue 20): the slab decomposition of
//! `docs/out-of-core.md`, from one PLY file to another ([`run`], public as
//! [`crate::reconstruct_out_of_core`]).
//!
//! The unit cube is cut across x into slabs of balanced point counts ([`slabs`]); the input is
//! read in chunks and binned to slab files in a temporary directory ([`scan`], [`scratch`]);
//! the depths up to a base depth B are solved once for the whole cloud from the slabs' summed
//! contributions ([`base`]), the finer depths slab by slab over the slab's points and a padding
//! of its neighbours', with the base solution prolonged in, and every node then takes its
//! owner's coefficient so that neighbours evaluate one χ near their walls ([`passes`]); each
//! slab extracts its part of the mesh with its vertices keyed by their edges ([`seams`]), and
//! the parts are joined into one PLY, the bubbles rule applied across walls ([`assemble`]).
//!
//! Proved against the in-memory pipeline by `tests.rs` part by part (the base's core sets,
//! right-hand sides and screening proxies as sums of the slabs'; the cascade cut at the base
//! bit for bit; the slabs' solve within the in-memory solver's own error; one χ across walls
//! bit for bit; each slab's part of the mesh bit for bit over the same χ), and end to end by
//! `tests/out_of_core.rs` against the in-memory meshes of a sphere and the shared scans.

pub(crate) mod assemble;
pub(crate) mod bands;
pub(crate) mod base;
pub(crate) mod cells;
pub(crate) mod field;
pub(crate) mod noise;
pub(crate) mod passes;
pub(crate) mod run;
pub(crate) mod scan;
pub(crate) mod scratch;
pub(crate) mod seams;
pub(crate) mod slabs;
pub(crate) mod team;

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
    /// Another member of the team ([`team::Team`]) failed; every other member ends with this.
    Member {
        /// the failed member's rank
        rank: usize,
        /// its error
        message: String,
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
                "could not {action} ({}): {source}; choose another temporary directory (one \
                 with enough free space, which every member of a team sees)",
                path.display()
            ),
            OutOfCoreError::Output { path, source } => {
                write!(
                    f,
                    "could not write the mesh to {}: {source}",
                    path.display()
                )
            }
            OutOfCoreError::Member { rank, message } => write!(f, "rank {rank} failed: {message}"),
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
            OutOfCoreError::Member { .. } => None,
        }
    }
}

impl OutOfCoreError {
    /// An internal error of the decomposition (a scratch file or a member's message that does
    /// not hold what its writer wrote, a node outside its band): a bug, not bad input.
    pub(crate) fn internal(message: impl Into<String>) -> Self {
        OutOfCoreError::Reconstruction(Error::Internal(message.into()))
    }
}

impl From<Error> for OutOfCoreError {
    fn from(e: Error) -> Self {
        OutOfCoreError::Reconstruction(e)
    }
}

#[cfg(test)]
mod tests;

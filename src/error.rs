//! Errors returned by every fallible psr function.
//!
//! Each variant says what went wrong and what the caller can do about it. `Internal` is reserved
//! for bugs in psr itself.

use std::fmt;

/// Everything that can go wrong in a reconstruction.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// No points were given: a reconstruction needs at least one oriented point.
    EmptyInput,
    /// `positions` and `normals` (or an optional per-point array) have different lengths.
    LengthMismatch {
        /// which array disagrees with `positions` (e.g. "normals")
        what: &'static str,
        /// entries in `positions`
        positions: usize,
        /// entries in the other array
        other: usize,
    },
    /// A position coordinate is NaN or infinite.
    NonFinitePosition {
        /// the point's index in its batch
        index: usize,
    },
    /// A normal component is NaN or infinite.
    NonFiniteNormal {
        /// the point's index in its batch
        index: usize,
    },
    /// A normal has zero (or denormal) length, so it gives no orientation.
    ZeroNormal {
        /// the point's index in its batch
        index: usize,
    },
    /// A per-point confidence weight is negative, NaN or infinite.
    InvalidWeight {
        /// the point's index in its batch
        index: usize,
    },
    /// Every confidence weight is 0, so no point counts.
    NoPositiveWeight,
    /// All points coincide: there is no extent in which to place a surface.
    DegenerateInput {
        /// how many points there are
        points: usize,
    },
    /// Normal estimation was asked for more neighbours than the cloud has other points.
    TooFewPoints {
        /// how many points there are
        points: usize,
        /// the neighbours asked for per point ([`crate::NormalEstimation::neighbors`])
        neighbors: usize,
    },
    /// Normal estimation found no neighbourhood that spans a plane: every point's neighbours
    /// coincide or lie on one line, so no normal is defined anywhere.
    NoPlaneDefined {
        /// how many points there are
        points: usize,
    },
    /// A parameter is outside its documented range.
    InvalidParameter {
        /// the parameter's name, as in [`crate::Params`]
        name: &'static str,
        /// the value given
        value: String,
        /// the documented range
        expected: &'static str,
    },
    /// A mesh given to [`crate::trim`] is inconsistent: a triangle names a vertex that does not
    /// exist, or a density is not finite. Meshes from [`crate::reconstruct`] never are; check
    /// how the mesh was built or changed.
    InvalidMesh(String),
    /// The caller's progress callback asked to stop.
    Cancelled,
    /// The operating system refused to start the reconstruction's worker threads (a limit on
    /// threads or processes, or no memory for their stacks). Nothing was computed; ask for
    /// fewer threads or free resources and try again.
    ThreadsUnavailable {
        /// the worker threads asked for
        threads: usize,
        /// the system's reason
        reason: String,
    },
    /// A per-point attribute value (a colour component or a channel's value) is NaN or
    /// infinite.
    NonFiniteAttribute {
        /// "colors" or the channel's name
        attribute: String,
        /// the point's index in its batch
        index: usize,
    },
    /// A per-point attribute has a different number of values than there are points.
    AttributeLength {
        /// "colors" or the channel's name
        attribute: String,
        /// the points it should give a value to
        points: usize,
        /// the values it has
        values: usize,
    },
    /// A batch of points carries other attributes than the points already in the set (colours
    /// where the set has none or the other way round, RGB against RGBA, other channel names or
    /// another order of them): every point of a set has the same attributes.
    AttributesDiffer {
        /// the set's attributes, e.g. `colors (RGB), channels [intensity]`
        set: String,
        /// the batch's attributes, in the same words
        batch: String,
    },
    /// A channel name is empty, holds whitespace or control characters (a PLY property name
    /// cannot), or is already taken by another channel of the set.
    InvalidChannelName {
        /// the name given
        name: String,
        /// what is wrong with it
        reason: &'static str,
    },
    /// A transform given with a batch of points ([`crate::PointSet::extend_transformed`]) has
    /// a NaN or infinite entry, is not affine (its last row is not `0 0 0 1`), or its 3×3 part
    /// is singular.
    InvalidTransform {
        /// what is wrong with it
        reason: &'static str,
    },
    /// A mesh has more vertices (or a point set more points) than 32-bit indices can name:
    /// triangles index vertices with `u32`. Reconstruct at a lower depth, or in pieces.
    TooLarge {
        /// what there are too many of, e.g. "mesh vertices"
        what: &'static str,
        /// how many there are (or would be)
        count: usize,
        /// the most there may be
        limit: usize,
    },
    /// The reconstruction needs more memory than [`crate::Params::max_memory`] allows, or the
    /// system refused an allocation. Nothing is kept: free memory, raise the limit (at least
    /// to `enough` when it is known) or lower the depth, and try again with the same points.
    OutOfMemory {
        /// what was about to be allocated, e.g. "the octree's nodes and the solve"
        what: &'static str,
        /// the bytes it needed (for a check against the limit: the reconstruction's estimate
        /// as known at that point, [`crate::estimate_memory`]'s accounting)
        needed: u64,
        /// the limit it exceeded; `None` when the system refused the allocation
        limit: Option<u64>,
        /// the smallest limit the accounting accepts for this reconstruction, when known
        enough: Option<u64>,
    },
    /// A bug in psr: please report it with the input that triggered it.
    Internal(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::EmptyInput => write!(f, "no input points: add at least one oriented point before reconstructing"),
            Error::LengthMismatch { what, positions, other } => write!(
                f,
                "{what} has {other} entries but positions has {positions}: give one entry per point"
            ),
            Error::NonFinitePosition { index } => {
                write!(f, "point {index} has a NaN or infinite coordinate: remove or fix it")
            }
            Error::NonFiniteNormal { index } => {
                write!(f, "normal {index} has a NaN or infinite component: remove or fix it")
            }
            Error::ZeroNormal { index } => write!(
                f,
                "normal {index} has zero length and gives no orientation: estimate normals first or drop the point"
            ),
            Error::InvalidWeight { index } => write!(
                f,
                "confidence weight {index} is negative, NaN or infinite: weights must be finite and >= 0"
            ),
            Error::NoPositiveWeight => {
                write!(f, "every confidence weight is 0: at least one point needs a positive weight")
            }
            Error::DegenerateInput { points } => write!(
                f,
                "all {points} points coincide: a surface needs points spread in space (at least two distinct positions)"
            ),
            Error::TooFewPoints { points, neighbors } => write!(
                f,
                "{points} points cannot each have {neighbors} neighbours: give at least {} points or ask for fewer neighbours",
                neighbors.saturating_add(1)
            ),
            Error::NoPlaneDefined { points } => write!(
                f,
                "the neighbourhoods of all {points} points are single points or lines, so no normal is defined: the points must sample a surface (use more neighbours if the sampling is very anisotropic)"
            ),
            Error::InvalidParameter { name, value, expected } => {
                write!(f, "parameter {name} = {value} is out of range: expected {expected}")
            }
            Error::InvalidMesh(msg) => write!(
                f,
                "the mesh is inconsistent: {msg}: give a mesh whose triangles, positions and densities agree, as reconstruct returns it"
            ),
            Error::Cancelled => write!(f, "reconstruction cancelled by the progress callback"),
            Error::ThreadsUnavailable { threads, reason } => write!(
                f,
                "the system refused to start {threads} worker threads ({reason}): set fewer threads or free resources and retry"
            ),
            Error::NonFiniteAttribute { attribute, index } => write!(
                f,
                "{attribute} of point {index} has a NaN or infinite value: remove or fix it"
            ),
            Error::AttributeLength { attribute, points, values } => write!(
                f,
                "{attribute} has {values} values for {points} points: give one per point"
            ),
            Error::AttributesDiffer { set, batch } => write!(
                f,
                "the points carry {batch} but the point set carries {set}: every batch of a set must carry the same colours and channels, in the same order"
            ),
            Error::InvalidChannelName { name, reason } => {
                write!(f, "channel name {name:?} {reason}: give each channel a distinct name without spaces")
            }
            Error::InvalidTransform { reason } => write!(
                f,
                "the transform is refused: {reason}: give a finite, invertible affine 4x4 matrix, row-major, last row 0 0 0 1"
            ),
            Error::TooLarge { what, count, limit } => write!(
                f,
                "{count} {what} is more than {limit}, the most 32-bit indices can name: reconstruct at a lower depth or in pieces"
            ),
            Error::OutOfMemory { what, needed, limit, enough } => {
                let needed = crate::memory::human(*needed);
                match limit {
                    Some(limit) => write!(
                        f,
                        "out of memory: {what} need {needed}, more than the memory limit of {}",
                        crate::memory::human(*limit)
                    )?,
                    None => write!(f, "out of memory: the system refused {needed} for {what}")?,
                }
                match enough {
                    Some(enough) => write!(
                        f,
                        ": allow at least {} (max_memory), or lower the depth",
                        crate::memory::human(*enough)
                    ),
                    None => write!(f, ": free memory, set a lower depth or a memory limit"),
                }
            }
            Error::Internal(msg) => write!(f, "internal error in psr (a bug, please report it): {msg}"),
        }
    }
}

impl std::error::Error for Error {}

/// Shorthand for results with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

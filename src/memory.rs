//! The memory budget: how many bytes a reconstruction needs, checked against
//! [`crate::Params::max_memory`] before it is spent, and the big vectors allocated so that a
//! refusal by the system is an [`Error::OutOfMemory`] too, never an abort.
//!
//! **The accounting** ([`Footprint`]) counts the arrays that grow with the input and the depth,
//! stage by stage, and takes the largest sum of what is alive at once:
//!
//! - per point: the caller's [`crate::PointSet`] (positions, normals, weights, `f64`
//!   positions), the samples (`f64` positions, normals, confidence, attributes), the density's
//!   area and depth per sample, the per-depth sample lists (one or two entries a sample) and
//!   their cells while the octree is built;
//! - per octree node (every node of every depth's halo, `Level::len`): its key, flags, core
//!   index, parent link and brick index, kept to the end; and per node, for all depths at once,
//!   the solved coefficients (`f64`), which the extraction reads;
//! - the stage peaks on top: the splat's V (three `f64` per node) of the depth being splatted
//!   and of the one carried below it, with the finest right-hand side, the finest depth's
//!   solver vectors (the prolonged coarse
//!   solution, p, r, A·p, the preconditioner, the operator's per-node data and the screening
//!   proxies), and the extraction's tables and the mesh, which grow with the finest depth's
//!   nodes.
//!
//! The per-node constants are measured, not derived: fitted (least squares on the three node
//! terms, then rounded up) so that the figure from the octree's node counts is above the peak
//! resident memory of the whole `psr` process on the bunny and the Happy Buddha scans at
//! depths 9–12, by 14–49 %; the estimate before the octree ([`predicted_nodes`]) is 1.8–2.5
//! times those peaks (`docs/benchmarks.md`, issue 19).
//!
//! **Where it is checked** (`pipeline.rs`): before the points are copied, with what the points
//! alone need (the per-point arrays and the complete octree down to the full depth): a limit
//! far too small fails there, in milliseconds; then once the octree's core sets are known
//! (the halos not yet built) and once the octree is complete, with its exact node counts,
//! before the system and the solver allocate anything. Each check that fails reports what
//! was about to be allocated, how much, the limit, and the estimate of the whole
//! reconstruction (the smallest limit this accounting accepts).
//!
//! **Fallible allocation**: [`zeroed`] and [`with_capacity`] allocate the big per-depth
//! vectors (V, the right-hand sides, the solver's vectors, the coefficients, the complete
//! grids) through the allocator's fallible interface; a refusal becomes
//! [`Error::OutOfMemory`] with `limit: None`.

use crate::error::{Error, Result};
use crate::params::MAX_DEPTH;

/// Bytes per input point alive at the points stage's peak and through the octree (see the
/// module docs: the point set, the samples, the density, the per-depth lists and cells).
const PER_POINT: u64 = 160;
/// Extra bytes per point of colours and channels: one `f32` per value, held twice (the point
/// set's and the samples').
const PER_ATTRIBUTE_VALUE: u64 = 8;
/// Bytes per octree node (every depth's halo) kept from the octree to the end: key, flags,
/// core index, parent, brick index (about 17 B measured after the octree stage), the solved
/// coefficient (`f64`), and each depth's ρ and coarse divergence until its depth is solved
/// (fitted when the coarser depths' V also waited for their solve: the peaks are lower
/// since, so the figure stays above them).
const PER_NODE_KEPT: u64 = 28;
/// Bytes per node of the largest depth's halo at the heaviest stage after the octree: the
/// splat's V and ρ, or the solver's vectors and operator, or the extraction's tables and the
/// mesh, whichever is largest.
const PER_HEAVIEST_NODE: u64 = 32;
/// Bytes per node slot of the density field's bricks (a count; the brick's key, mask and its
/// entry in the table of bricks, a 64th each; kept for the mesh's per-vertex densities).
const PER_DENSITY_SLOT: u64 = 9;
/// Bytes per node slot of the samples' counts and normals summed at the kernel depth, held
/// while the samples' depths are read (`density::NormalSums`: four `f64` a slot, and the
/// brick's key, mask and table entry, a 64th each), then dropped before the octree.
const PER_NORMAL_SUM_SLOT: u64 = 33;
/// What a reconstruction needs whatever its size (tables, thread stacks, small buffers).
const FIXED: u64 = 32 << 20;
/// Bytes per screening group of the out-of-core base (its cell, Σ w·p and Σ w): every member
/// holds the whole cloud's groups of every depth up to the base, merged from the slabs' in
/// pass B, until the base is solved.
const PER_BASE_GROUP: u64 = 48;
/// Bytes per screening proxy (its node, weight and offset), made from the groups of one depth
/// at a time while that depth is solved.
const PER_PROXY: u64 = 24;

/// The bytes a reconstruction's big arrays need, by part; [`Footprint::peak`] is the estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Footprint {
    /// The per-point arrays.
    pub(crate) points: u64,
    /// The octree's nodes, the coefficients and the density field, all depths.
    pub(crate) tree: u64,
    /// The heaviest stage's arrays on top of those.
    pub(crate) stage: u64,
}

impl Footprint {
    /// The estimate of the peak: every part at once, plus the fixed part.
    pub(crate) fn peak(&self) -> u64 {
        FIXED
            .saturating_add(self.points)
            .saturating_add(self.tree)
            .saturating_add(self.stage)
    }

    /// What the points need with a minimal octree (the complete grids down to `full_depth`):
    /// a lower bound of every reconstruction of `points` points, checked before anything is
    /// allocated.
    pub(crate) fn at_least(points: u64, attribute_width: u64, full_depth: u32) -> Footprint {
        // The cores of the complete depths alone: (2^d)³ nodes inside the cube.
        let grid: Vec<u64> = (0..=full_depth.min(MAX_DEPTH))
            .map(|d| 1u64 << (3 * d))
            .collect();
        Footprint::with_nodes(points, attribute_width, &grid, 0)
    }

    /// The footprint of a reconstruction whose depths have `nodes[d]` halo nodes each and
    /// whose density field has `density_slots` node slots.
    pub(crate) fn with_nodes(
        points: u64,
        attribute_width: u64,
        nodes: &[u64],
        density_slots: u64,
    ) -> Footprint {
        let total = nodes.iter().fold(0u64, |a, &n| a.saturating_add(n));
        let heaviest = nodes.iter().copied().max().unwrap_or(0);
        Footprint {
            points: points.saturating_mul(
                PER_POINT.saturating_add(PER_ATTRIBUTE_VALUE.saturating_mul(attribute_width)),
            ),
            tree: total
                .saturating_mul(PER_NODE_KEPT)
                .saturating_add(density_slots.saturating_mul(PER_DENSITY_SLOT)),
            stage: heaviest.saturating_mul(PER_HEAVIEST_NODE),
        }
    }

    /// What every member of an out-of-core run holds for the base's solve, with no slab in
    /// memory: the base's tree (`nodes` per depth, up to the base depth) and the whole cloud's
    /// screening groups of its depths (`groups` in all, `heaviest_groups` of the depth with
    /// the most); on top, the larger of a depth's groups held twice while a slab's are merged
    /// in (the slabs' come one by one) and the solve's vectors with that depth's proxies.
    pub(crate) fn base_solve(nodes: &[u64], groups: u64, heaviest_groups: u64) -> Footprint {
        let solving = Footprint::with_nodes(0, 0, nodes, 0);
        let merging = heaviest_groups.saturating_mul(2 * PER_BASE_GROUP);
        Footprint {
            tree: solving
                .tree
                .saturating_add(groups.saturating_mul(PER_BASE_GROUP)),
            stage: merging.max(
                solving
                    .stage
                    .saturating_add(heaviest_groups.saturating_mul(PER_PROXY)),
            ),
            ..solving
        }
    }

    /// What the density stage holds at once, before any octree exists: the points' arrays, the
    /// density field (`density_slots` node slots, all depths) and the samples' normals summed
    /// over the `kernel_slots` slots of its kernel depth. Below the later stages' peak on
    /// scans (measured on the Buddha at depth 12: 462 against 891 MiB), but not on a sparse
    /// cloud asked for a depth far finer than its spacing, where the kernel depth's bricks
    /// hold a few samples each.
    pub(crate) fn reading_density(
        points: u64,
        attribute_width: u64,
        density_slots: u64,
        kernel_slots: u64,
    ) -> Footprint {
        Footprint {
            tree: density_slots
                .saturating_mul(PER_DENSITY_SLOT)
                .saturating_add(kernel_slots.saturating_mul(PER_NORMAL_SUM_SLOT)),
            stage: 0,
            ..Footprint::with_nodes(points, attribute_width, &[], 0)
        }
    }

    /// The estimate before any octree exists, from the point count and the depths: the node
    /// counts of [`predicted_nodes`].
    pub(crate) fn predicted(
        points: u64,
        attribute_width: u64,
        depth: u32,
        full_depth: u32,
        kernel_depth: u32,
    ) -> Footprint {
        Footprint::with_nodes(
            points,
            attribute_width,
            &predicted_nodes(points, depth, full_depth),
            predicted_density_slots(points, kernel_depth),
        )
    }
}

/// The bytes of a density field whose bricks have `slots` node slots ([`DensityField::slots`]): the
/// part the out-of-core path holds for the whole cloud while it works slab by slab.
///
/// [`DensityField::slots`]: crate::density::DensityField
pub(crate) fn density_bytes(slots: u64) -> u64 {
    slots.saturating_mul(PER_DENSITY_SLOT)
}

/// The most bytes the noise estimate's fits of `points` samples take ([`crate::noise`]'s
/// `CellFits`: a residual per cell of its finer depth, a residual and an F per cell of the
/// coarser, every fitted cell holding at least `noise::MIN_SAMPLES` samples): what each
/// member of an out-of-core run keeps of its slabs' fits from pass B until the medians.
pub(crate) fn noise_fit_bytes(points: u64) -> u64 {
    points / crate::noise::MIN_SAMPLES as u64 * 3 * 8
}

/// The density field's node slots for `points` points at `kernel_depth`, predicted: its
/// finest depth holds the nodes the samples' trilinear splats touch, at most the surface's or
/// the points' count of core nodes ([`predicted_nodes`]'s rule without the saturation: the
/// kernel depth takes every sample), times [`HALO_PER_CORE`] for the 8 nodes around each
/// sample; the coarser depths a third of that; and [`DENSITY_SLOTS_PER_NODE`] slots per node.
fn predicted_density_slots(points: u64, kernel_depth: u32) -> u64 {
    let d = kernel_depth.min(MAX_DEPTH);
    let surface = CORE_PER_SURFACE_CELL.saturating_mul(1u64 << (2 * d));
    let entries = complete_grid(d)
        .min(surface.min(CORE_PER_POINT.saturating_mul(points)))
        .saturating_mul(HALO_PER_CORE);
    entries
        .saturating_add(entries / 3)
        .saturating_mul(DENSITY_SLOTS_PER_NODE)
}

/// Node slots of the density field's 4×4×4 bricks per node with a count, all depths, at most
/// (measured: 3.1–3.8 on the bunny and the Happy Buddha at depths 8–12, 5.8 on the bunny at
/// depth 12 whose kernel depth is finer than its sampling; with the bricks' vector grown to up
/// to twice its length).
const DENSITY_SLOTS_PER_NODE: u64 = 6;

/// Nodes of a complete grid at depth `d` with its halo, two nodes beyond the cube on every
/// side (the mirrors of Neumann and Dirichlet): (2^d + 4)³.
fn complete_grid(d: u32) -> u64 {
    let side = (1u64 << d.min(MAX_DEPTH)) + 4;
    side.saturating_mul(side).saturating_mul(side)
}

/// Core nodes per 4^d at depth d on a scanned surface, at most (measured: 7–11 on the bunny
/// and the Happy Buddha; `docs/benchmarks.md`, issue 19).
const CORE_PER_SURFACE_CELL: u64 = 12;
/// Core nodes per point at one depth, at most (measured: 6–7 at the depth where the sampling
/// runs out).
const CORE_PER_POINT: u64 = 8;
/// Halo nodes per core node (measured: 1.6–1.9).
const HALO_PER_CORE: u64 = 2;

/// Halo nodes per depth for a scan of `points` points reconstructed at `depth`, an upper
/// estimate from the point count alone. Each depth holds at most its complete grid; below
/// that a sampled surface has about [`CORE_PER_SURFACE_CELL`] × 4^d core nodes (its cells
/// crossed and the dilations around them) until the sampling runs out: at most
/// [`CORE_PER_POINT`] per point, and past the first depth that reaches it, the density
/// estimate moves the samples to coarser depths, which leaves a few stray nodes one depth
/// finer (counted as 1 per 20 points) and none beyond.
pub(crate) fn predicted_nodes(points: u64, depth: u32, full_depth: u32) -> Vec<u64> {
    nodes_of_surface(points, depth, full_depth, |d| {
        CORE_PER_SURFACE_CELL.saturating_mul(1u64 << (2 * d.min(MAX_DEPTH)))
    })
}

/// Halo nodes per depth, as [`predicted_nodes`] counts them, for a surface whose core nodes
/// at depth d number `surface_core(d)` until the sampling runs out.
pub(crate) fn nodes_of_surface(
    points: u64,
    depth: u32,
    full_depth: u32,
    surface_core: impl Fn(u32) -> u64,
) -> Vec<u64> {
    let mut saturated_at = None;
    (0..=depth.min(MAX_DEPTH))
        .map(|d| {
            let grid = complete_grid(d);
            if d <= full_depth {
                return grid;
            }
            let core = match saturated_at {
                Some(s) if d == s + 1 => points / 20,
                Some(_) => 0,
                None => {
                    let surface = surface_core(d);
                    let sampled = CORE_PER_POINT.saturating_mul(points);
                    if sampled <= surface {
                        saturated_at = Some(d);
                    }
                    surface.min(sampled)
                }
            };
            grid.min(core.saturating_mul(HALO_PER_CORE))
        })
        .collect()
}

/// Core nodes of depth d per node of the density field's kernel depth k over the same part of
/// the surface, times 4^(d − k) (a surface's cells quadruple with each depth), at most:
/// measured 2.0–2.35 on the bunny's and the Happy Buddha's scans at depths 9–11 and on the
/// 10-million-point procedural planet (`bench/procedural_cloud.py`) at depth 11, whose
/// surface fills more of the cube than a scan's (halo nodes 3.9–4.7 per kernel node × 4^(d − k),
/// [`HALO_PER_CORE`] of them per core node).
const CORE_PER_KERNEL_NODE: f64 = 2.5;

/// Halo nodes per depth for `points` points on a surface that `kernel_nodes` nodes of the
/// density field's `kernel_depth` cover: [`nodes_of_surface`] with the surface measured by
/// the field instead of bounded by [`CORE_PER_SURFACE_CELL`]: what the out-of-core path
/// predicts for a slab, whose part of the surface is known before its octree exists.
pub(crate) fn nodes_of_measured_surface(
    points: u64,
    kernel_nodes: f64,
    kernel_depth: u32,
    depth: u32,
    full_depth: u32,
) -> Vec<u64> {
    nodes_of_surface(points, depth, full_depth, |d| {
        let cells = kernel_nodes * (2.0 * (d as f64 - kernel_depth as f64)).exp2();
        (CORE_PER_KERNEL_NODE * cells).ceil().min(u64::MAX as f64) as u64
    })
}

/// The limit a reconstruction checks against: [`crate::Params::max_memory`], `None` for none.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Budget {
    pub(crate) limit: Option<u64>,
    /// The estimate of the whole reconstruction as known so far, reported with a failure.
    pub(crate) estimate: u64,
}

impl Budget {
    /// Fails with [`Error::OutOfMemory`] when `needed` bytes (for `what`) exceed the limit.
    pub(crate) fn check(&self, what: &'static str, needed: u64) -> Result<()> {
        match self.limit {
            Some(limit) if needed > limit => Err(Error::OutOfMemory {
                what,
                needed,
                limit: Some(limit),
                enough: Some(self.estimate.max(needed)),
            }),
            _ => Ok(()),
        }
    }
}

/// The system refused `bytes` for `what`.
fn refused(what: &'static str, bytes: u64) -> Error {
    Error::OutOfMemory {
        what,
        needed: bytes,
        limit: None,
        enough: None,
    }
}

/// Numbers whose all-zero bit pattern is 0 (what [`zeroed`] may allocate).
pub(crate) trait Zero: Copy {}
impl Zero for f64 {}
impl Zero for f32 {}
impl Zero for u32 {}
impl Zero for u64 {}
impl Zero for u8 {}

/// `vec![0; n]`, but a refusal by the allocator is [`Error::OutOfMemory`] naming `what`
/// instead of an abort. Like `vec![0; n]` it asks for zeroed memory (`calloc`), so the pages
/// never written stay shared zero pages: the same memory and time as before.
pub(crate) fn zeroed<T: Zero>(n: usize, what: &'static str) -> Result<Vec<T>> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let layout = std::alloc::Layout::array::<T>(n)
        .map_err(|_| refused(what, (n as u64).saturating_mul(size_of::<T>() as u64)))?;
    // SAFETY: the layout's size is not zero (n > 0 and every `Zero` type has a size).
    let ptr = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<T>();
    if ptr.is_null() {
        return Err(refused(what, layout.size() as u64));
    }
    // SAFETY: `ptr` comes from the global allocator with `T`'s alignment and room for exactly
    // `n` values (the layout of `[T; n]`), which is what a Vec of capacity `n` frees; all its
    // bytes are zero, a valid `T` for every `Zero` type, so all `n` values are initialised.
    Ok(unsafe { Vec::from_raw_parts(ptr, n, n) })
}

/// `Vec::with_capacity(n)`, but a refusal is [`Error::OutOfMemory`] naming `what`.
pub(crate) fn with_capacity<T>(n: usize, what: &'static str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|_| refused(what, (n as u64).saturating_mul(size_of::<T>() as u64)))?;
    Ok(v)
}

/// Bytes written for people: "1.50 GiB", "512.0 MiB", "800 bytes".
pub(crate) fn human(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    if bytes < 1024 {
        return format!("{bytes} bytes");
    }
    let mut value = bytes as f64 / 1024.0;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.2} {}", UNITS[unit])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_density_stage_counts_the_normal_sums_beside_the_field() {
        let field_alone = Footprint::reading_density(1000, 2, 1 << 20, 0).peak();
        assert_eq!(
            field_alone,
            FIXED + 1000 * (PER_POINT + 2 * PER_ATTRIBUTE_VALUE) + (1 << 20) * PER_DENSITY_SLOT
        );
        let with_sums = Footprint::reading_density(1000, 2, 1 << 20, 1 << 19).peak();
        assert_eq!(with_sums - field_alone, (1 << 19) * PER_NORMAL_SUM_SLOT);
    }

    /// Proves: an allocation the system cannot give is a typed error, not an abort, both when
    /// the size overflows and when the allocator says no (2^60 bytes is beyond any machine).
    #[test]
    fn a_refused_allocation_is_an_error() {
        for n in [usize::MAX / 4, 1 << 57] {
            let err = zeroed::<f64>(n, "a test vector").unwrap_err();
            assert!(
                matches!(
                    err,
                    Error::OutOfMemory {
                        what: "a test vector",
                        limit: None,
                        ..
                    }
                ),
                "{err:?}"
            );
            assert!(with_capacity::<u64>(n, "a test vector").is_err());
        }
        let ok: Vec<f64> = zeroed(1000, "small").unwrap();
        assert!(ok.len() == 1000 && ok.iter().all(|&v| v == 0.0));
    }

    /// Proves: the lower bound is below the prediction, the prediction grows with depth and
    /// points, and a limit is checked with the estimate reported as enough.
    #[test]
    fn bounds_are_ordered_and_checked() {
        let low = Footprint::at_least(1_000_000, 0, 5).peak();
        let d9 = Footprint::predicted(1_000_000, 0, 9, 5, 7).peak();
        let d12 = Footprint::predicted(1_000_000, 0, 12, 5, 10).peak();
        assert!(low < d9 && d9 <= d12, "{low} {d9} {d12}");
        assert!(Footprint::predicted(100_000, 0, 12, 5, 10).peak() < d12);
        let budget = Budget {
            limit: Some(1000),
            estimate: 5000,
        };
        assert!(budget.check("x", 1000).is_ok());
        assert_eq!(
            budget.check("x", 1001),
            Err(Error::OutOfMemory {
                what: "x",
                needed: 1001,
                limit: Some(1000),
                enough: Some(5000)
            })
        );
        assert_eq!(human(1536 << 20), "1.50 GiB");
    }
}

//! The passes of a reconstruction out of core, in order (`docs/out-of-core.md`, "Phases"):
//! the input scanned, its columns counted and its points binned to slab files (`scan.rs`), the
//! density's kernel counts summed slab by slab;
//! then over the slabs, one in memory at a time: their samples prepared (kept for the passes
//! after) and their own core sets up to the base depth (pass A), their own parts of the base's
//! right-hand sides and screening groups (pass B), the base solved once, each slab's finer
//! depths solved over its points and padding, writing its bands for its neighbours (pass C),
//! and every slab's coefficients made its owners' where slabs overlap from those bands
//! (`bands.rs`), with the isovalue's partial sums (pass D). What it leaves: one
//! solution file and one file of prepared samples per slab, each slab's χ agreeing with its
//! neighbours' near their walls, and the isovalue.

use super::bands::{apply_bands, write_bands};
use super::base::{coarse_cores, merge_groups, BaseParts};
use super::cells::OccupiedCells;
use super::field::{coarsest_exact_depth, held_margin_columns, write_own_part, FieldBySlab};
use super::noise::{SlabNoise, TeamNoise};
use super::scan::{
    bin_part, binned_file, columns_of_part, scan_of_parts, scan_part, ColumnsOfPart, Input, Scan,
    ScannedPart,
};
use super::scratch::{fresh_token, read_lists, read_slab, scratch_error, write_lists, Scratch};
use super::slabs::SlabLayout;
use super::team::{
    agreed, agreed_with, checked_by_others, from_first, rounds, Packer, Team, Unpacker,
};
use super::OutOfCoreError;
use crate::density::{
    estimate, samples_by_depth, DepthSample, KernelCounts, KernelNodes, SampleDensity,
};
use crate::evaluate::Indicator;
use crate::noise::AreaDepths;
use crate::octree::{sample_cells, Octree};
use crate::parallel::Watch;
use crate::points::{unit_normal, PointSet, Samples};
use crate::solve::{cascade, Depths, ProxyGroup, Solved, System};
use crate::system::{
    coarser_divergences, finest_right_hand_side, proxy_depth, right_hand_sides, sample_groups,
    sample_weights_from_totals, FieldCarry, ScreeningWeights,
};
use crate::{Params, Result};
use glam::DVec3;
use std::ops::{Range, RangeInclusive};
use std::path::{Path, PathBuf};

/// How the run is cut: the base depth, the slabs asked for, their padding.
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// B: depths 0..=B are solved once for the whole cloud (at least the full depth, at most
    /// the depth − 2); `None`: the depth − 3, at most 7 (unless the full depth is more), or
    /// under a budget the one [`cut`] chooses from there up to the depth − 2, and lower when
    /// the samples do not reach two depths above it.
    pub(crate) base_depth: Option<u32>,
    /// How many slabs.
    pub(crate) slabs: SlabCount,
    /// Columns of depth B + 2 each slab reads beyond its walls (the run takes 24, see
    /// `run.rs`; the tree alone needs 6, three nodes of depth B + 1, and its halos 4 more,
    /// see `tests.rs`); its finer depths splat within [`FINE_PADDING_NODES`] of theirs
    /// ([`grade_padding`]).
    pub(crate) padding: u32,
    /// Points per chunk read from the input.
    pub(crate) chunk: usize,
    /// Whether the points' confidence weighs them.
    pub(crate) confidence: bool,
    /// Where the temporary directory goes (the system's when `None`).
    pub(crate) temp_dir: Option<PathBuf>,
}

/// How many slabs a run cuts the cloud into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SlabCount {
    /// This many (fewer when the points fill fewer columns).
    Exactly(usize),
    /// The fewest whose largest, with its padding, fits this many bytes by the memory
    /// accounting (`memory.rs`) with its share of the density field (the tables' real size:
    /// their nodes are found before the slabs are counted), and whose base's solve fits them
    /// too.
    Within(u64),
}

/// How much of the samples' surface lies in each column of `wall_depth`: the nodes of the
/// kernel depth the samples' splats touch (their x indices, `node_x`) over the column (a node
/// wider than a column spread evenly over the columns it spans, one narrower counted in the
/// column holding it).
fn surface_by_column(
    node_x: impl Iterator<Item = i32>,
    kernel_depth: u32,
    wall_depth: u32,
) -> Vec<f64> {
    let columns = 1i64 << wall_depth;
    let mut surface = vec![0.0f64; columns as usize];
    for x in node_x {
        let x = i64::from(x);
        if kernel_depth >= wall_depth {
            let column = (x >> (kernel_depth - wall_depth)).clamp(0, columns - 1);
            surface[column as usize] += 1.0;
        } else {
            let span = 1i64 << (wall_depth - kernel_depth);
            let first = (x * span).clamp(0, columns);
            let end = ((x + 1) * span).clamp(0, columns);
            for column in first..end {
                surface[column as usize] += 1.0 / span as f64;
            }
        }
    }
    surface
}

/// What the memory accounting (`memory.rs`) predicts for the slabs of a cut at one base depth,
/// from the points' column counts and the surface's (`surface_by_column`, measured at
/// `kernel_depth`), both over the columns of the wall depth, the base depth + 2, and for the
/// base's solve from the cells the points occupy.
struct SlabModel<'a> {
    counts: &'a [u64],
    surface: &'a [f64],
    kernel_depth: u32,
    base_depth: u32,
    params: &'a Params,
    /// The base's halo nodes per depth, predicted for the whole cloud (every slab's tree has
    /// them up to the base depth).
    base: Vec<u64>,
    /// The base's screening groups, all its depths' and the most of one depth's: one per
    /// cell of the proxy depth (depth d's, d + 2, or the finest sample depth when coarser)
    /// that the points occupy.
    base_groups: (u64, u64),
    /// What a member holds of the density field beside a slab.
    field: FieldHeld,
    /// The whole surface, `surface` summed.
    surface_total: f64,
}

/// What a member holds of the density field (`outofcore/field.rs`), for the planner: the
/// coarse depths, whole, throughout; beside a slab, the finer depths over the columns it
/// reads, and through pass A the normals' sums over them.
#[derive(Debug, Clone, Default)]
struct FieldHeld {
    /// Bytes every member holds throughout: the field's depths up to the coarsest each slab
    /// has exact ([`coarsest_exact_depth`]), whole, and the noise estimate's fits when the
    /// screening follows the noise.
    shared: u64,
    /// Each finer depth's node slots, the whole cloud's, with the columns of the wall depth a
    /// slab holds them over beyond its padded columns ([`held_margin_columns`]).
    finer: Vec<(u64, u32)>,
    /// The kernel depth's slots, whole cloud, and the columns beyond: the normals' sums pass A
    /// holds over a slab's.
    kernel: (u64, u32),
}

impl FieldHeld {
    /// For the field whose bricks have `slots_by_depth[d]` slots at depth d (up to the kernel
    /// depth), cut with walls on `wall_depth` and `padding` columns of padding.
    fn of(
        slots_by_depth: &[u64],
        wall_depth: u32,
        padding: u32,
        kernel_depth: u32,
        noise_fits: u64,
    ) -> Self {
        let coarse_depth = coarsest_exact_depth(wall_depth, padding, kernel_depth);
        let slots = |d: u32| slots_by_depth.get(d as usize).copied().unwrap_or(0);
        let coarse: u64 = (0..=coarse_depth).map(slots).sum();
        FieldHeld {
            shared: crate::memory::density_bytes(coarse).saturating_add(noise_fits),
            finer: (coarse_depth + 1..=kernel_depth)
                .map(|d| (slots(d), held_margin_columns(wall_depth, d)))
                .collect(),
            kernel: (
                slots(kernel_depth),
                held_margin_columns(wall_depth, kernel_depth),
            ),
        }
    }
}

impl<'a> SlabModel<'a> {
    /// The model of a cut at `base_depth`; `occupied_at(D)`: the cells of depth D (at least
    /// up to the base depth + 2) the points occupy.
    fn new(
        counts: &'a [u64],
        surface: &'a [f64],
        kernel_depth: u32,
        base_depth: u32,
        params: &'a Params,
        occupied_at: impl Fn(u32) -> f64,
        field: FieldHeld,
    ) -> Self {
        let points: u64 = counts.iter().sum();
        let surface_total: f64 = surface.iter().sum();
        // The proxy depth d + 2 at most (the finest sample depth is not known before the
        // cut); a depth's groups are at most the points.
        let groups: Vec<u64> = (0..=base_depth)
            .map(|d| (occupied_at(d + 2).ceil() as u64).min(points))
            .collect();
        let mut model = SlabModel {
            counts,
            surface,
            kernel_depth,
            base_depth,
            params,
            base: Vec::new(),
            base_groups: (
                groups.iter().sum(),
                groups.iter().copied().max().unwrap_or(0),
            ),
            field,
            surface_total,
        };
        model.base = model.nodes(points, surface_total);
        model
    }

    /// Halo nodes per depth for `points` points over `surface` nodes of the kernel depth.
    fn nodes(&self, points: u64, surface: f64) -> Vec<u64> {
        crate::memory::nodes_of_measured_surface(
            points,
            surface,
            self.kernel_depth,
            self.params.depth,
            self.params.effective_full_depth(),
        )
    }

    /// The points and the surface in `columns`.
    fn within(&self, columns: Range<u32>) -> (u64, f64) {
        let points = columns
            .clone()
            .map(|c| self.counts[c as usize])
            .sum::<u64>();
        (
            points,
            columns.map(|c| self.surface[c as usize]).sum::<f64>(),
        )
    }

    /// Slab k's points with its padding, and its tree's halo nodes per depth: the base's up to
    /// the base depth, then its padded columns' up to the wall depth and, finer, its graded
    /// padding's band at each depth ([`grade_padding`]), in the whole columns that hold it.
    fn slab(&self, layout: &SlabLayout, k: usize) -> (u64, Vec<u64>) {
        let (points, padded_surface) = self.within(layout.padded(k));
        let mut tree = self.nodes(points, padded_surface);
        let b = self.base_depth as usize;
        tree[..=b].copy_from_slice(&self.base[..=b]);
        let wall_depth = layout.wall_depth;
        for d in wall_depth + 1..tree.len() as u32 {
            let band = layout.band(k, d, FINE_PADDING_NODES);
            let shift = d - wall_depth;
            let first = (band.start >> shift).max(0) as u32;
            let end = (((band.end - 1) >> shift) + 1).min(self.counts.len() as i64) as u32;
            let (band_points, band_surface) = self.within(first..end);
            tree[d as usize] = self.nodes(band_points, band_surface)[d as usize];
        }
        (points, tree)
    }

    /// The share of `slots` slots a slab holds over its padded columns `padded` and `margin`
    /// columns beyond: its part of the surface there (the slots follow the kernel nodes).
    fn held_slots(&self, padded: &Range<u32>, (slots, margin): (u64, u32)) -> u64 {
        let total = self.surface_total;
        if total <= 0.0 {
            return slots;
        }
        let columns = padded.start.saturating_sub(margin)
            ..padded
                .end
                .saturating_add(margin)
                .min(self.surface.len() as u32);
        let share = (self.within(columns).1 / total).min(1.0);
        (slots as f64 * share).ceil() as u64
    }

    /// The bytes slab k needs: the larger of its solve's footprint and its points' while pass
    /// A holds its normals' sums (`Footprint::reading_density` without the field), with its
    /// share of the field's finer depths, beside the bytes every member holds throughout.
    fn need(&self, layout: &SlabLayout, k: usize) -> u64 {
        let (points, tree) = self.slab(layout, k);
        let padded = layout.padded(k);
        let finer_slots: u64 = self
            .field
            .finer
            .iter()
            .map(|&depth| self.held_slots(&padded, depth))
            .sum();
        let sums_slots = self.held_slots(&padded, self.field.kernel);
        let solving = crate::memory::Footprint::with_nodes(points, 0, &tree, 0).peak();
        let preparing = crate::memory::Footprint::reading_density(points, 0, 0, sums_slots).peak();
        solving
            .max(preparing)
            .saturating_add(crate::memory::density_bytes(finer_slots))
            .saturating_add(self.field.shared)
    }

    /// The bytes every member needs for the base's solve, between pass B and pass C with no
    /// slab in memory ([`crate::memory::Footprint::base_solve`]), beside the bytes it holds
    /// throughout.
    fn base_need(&self) -> u64 {
        let (groups, heaviest) = self.base_groups;
        let base = &self.base[..=self.base_depth as usize];
        crate::memory::Footprint::base_solve(base, groups, heaviest)
            .peak()
            .saturating_add(self.field.shared)
    }

    /// The nodes one of `members` works on: its share of the slabs' trees finer than the base
    /// (the nodes each slab splats, solves and extracts over, padding included), and the
    /// whole base, which every member sums and solves itself.
    fn member_work(&self, layout: &SlabLayout, members: usize) -> u64 {
        let b = self.base_depth as usize;
        let slabs: u64 = (0..layout.len())
            .map(|k| self.slab(layout, k).1[b + 1..].iter().sum::<u64>())
            .sum();
        slabs.div_ceil(members.max(1) as u64) + self.base[..=b].iter().sum::<u64>()
    }
}

/// The fewest slabs for `budget` bytes (see [`SlabCount::Within`]) by `model`'s needs
/// ([`SlabModel::need`]: a slab, its share of the density field, and what every member holds
/// throughout) and the base's solve's
/// ([`SlabModel::base_need`], the same for every cut); or, when no number of slabs fits, the
/// smallest budget that any does (the most slabs' need, or the base's when larger).
///
/// The count is found by doubling it until a cut fits, then halving the interval between the
/// last that did not and the first that did: the need falls as slabs are added (up to the
/// rounding of the walls to columns), and a search of every count, each over all its slabs,
/// took seconds to refuse a budget at 4,096 columns, and minutes at 16,384.
fn slabs_within(
    budget: u64,
    model: &SlabModel<'_>,
    layout_of: impl Fn(usize) -> SlabLayout,
) -> std::result::Result<usize, u64> {
    // The base's solve needs the same whatever the cut.
    let base_need = model.base_need();
    let need_of = |slabs: usize| {
        let layout = layout_of(slabs);
        (0..layout.len())
            .map(|k| model.need(&layout, k))
            .max()
            .unwrap_or(0)
            .max(base_need)
    };
    let most = model.counts.len().max(1);
    if base_need > budget {
        return Err(need_of(most));
    }
    let mut least = u64::MAX;
    // The last count that did not fit (0: none tried), then the first that did.
    let mut too_few = 0;
    let mut slabs = 1;
    let mut fits = loop {
        let need = need_of(slabs);
        if need <= budget {
            break slabs;
        }
        least = least.min(need);
        if slabs == most {
            return Err(least);
        }
        too_few = slabs;
        slabs = (2 * slabs).min(most);
    };
    while fits - too_few > 1 {
        let middle = too_few + (fits - too_few) / 2;
        if need_of(middle) <= budget {
            fits = middle;
        } else {
            too_few = middle;
        }
    }
    Ok(layout_of(fits).len())
}

/// The base depth among `base_depths` and the fewest slabs at it for `budget` bytes: at each
/// base depth B the fewest slabs that fit ([`slabs_within`]), the walls on depth B + 2 with
/// `padding_of(B + 2)` columns of padding, the surface `surface_of(B + 2)` over those
/// columns, `occupied_at(D)` cells of depth D ≤ B + 2 holding points, and the density field
/// of `field_slots[d]` node slots at depth d held as [`FieldHeld`] says, beside `noise_fits`
/// bytes every member holds; of those cuts (at least one slab per member of `members`), the
/// one that leaves a member the fewest nodes to work on ([`SlabModel::member_work`]), the
/// coarsest base of equals. `counted` is the points per column of depth `counted_depth`, at least
/// `base_depths.end()` + 2. When no cut fits, the smallest budget that one at the coarsest base
/// depth does: the finer ones need samples reaching two depths above them, which pass A finds
/// out only after the cut (a run cut again at a coarser base must still fit what was named).
#[allow(clippy::too_many_arguments)]
fn base_and_slabs_within(
    budget: u64,
    counted: &[u64],
    counted_depth: u32,
    base_depths: RangeInclusive<u32>,
    surface_of: impl Fn(u32) -> Vec<f64>,
    padding_of: impl Fn(u32) -> u32,
    occupied_at: impl Fn(u32) -> f64,
    kernel_depth: u32,
    params: &Params,
    members: usize,
    field_slots: &[u64],
    noise_fits: u64,
) -> std::result::Result<(u32, usize), u64> {
    // (work, base depth, slabs) of the best cut so far.
    let mut best: Option<(u64, u32, usize)> = None;
    let mut least = None;
    for base_depth in base_depths {
        let wall_depth = base_depth + 2;
        let counts = coarser_columns(counted, counted_depth - wall_depth);
        let surface = surface_of(wall_depth);
        let padding = padding_of(wall_depth);
        let model = SlabModel::new(
            &counts,
            &surface,
            kernel_depth,
            base_depth,
            params,
            &occupied_at,
            FieldHeld::of(field_slots, wall_depth, padding, kernel_depth, noise_fits),
        );
        let layout_of = |slabs: usize| SlabLayout::balanced(&counts, wall_depth, slabs, padding);
        match slabs_within(budget, &model, layout_of) {
            Ok(slabs) => {
                let work = model.member_work(&layout_of(slabs.max(members)), members);
                if best.is_none_or(|(least_work, ..)| work < least_work) {
                    best = Some((work, base_depth, slabs));
                }
            }
            Err(enough) => {
                least.get_or_insert(enough);
            }
        }
    }
    best.map(|(_, base_depth, slabs)| (base_depth, slabs))
        .ok_or(least.unwrap_or(u64::MAX))
}

/// The columns of depth `wall_depth − shift` counted from those of `wall_depth` (a point's
/// column at a coarser depth is its finer column shifted: x·2^w is exact).
fn coarser_columns(counts: &[u64], shift: u32) -> Vec<u64> {
    counts
        .chunks(1 << shift)
        .map(|columns| columns.iter().sum())
        .collect()
}

/// What the passes leave for the extraction.
pub(crate) struct SolvedSlabs {
    /// The temporary directory, removed when this is dropped.
    pub(crate) scratch: Scratch,
    pub(crate) scan: Scan,
    /// The parameters as the in-memory path would use them for this cube.
    pub(crate) params: Params,
    pub(crate) layout: SlabLayout,
    /// The slabs' files (their prepared samples).
    pub(crate) files: SlabFiles,
    /// The base's core sets (depths 0..=B), shared by every slab's tree.
    pub(crate) base_cores: Vec<Vec<u64>>,
    /// The density of all the samples, by slab (the slabs' samples' depths and areas come from
    /// it, and the mesh's values).
    pub(crate) field: FieldBySlab,
    /// The finest depth any sample reaches: every slab's tree has it.
    pub(crate) finest: u32,
    pub(crate) isovalue: f64,
    /// The samples' noise, when the screening follows it (`outofcore/noise.rs`).
    pub(crate) noise: Option<TeamNoise>,
    /// The screening's weights per depth (from the noise when it is followed).
    pub(crate) screening: ScreeningWeights,
}

impl SolvedSlabs {
    /// Slab k's samples (its own and its padding), as the passes prepared them.
    pub(crate) fn slab_samples(
        &self,
        k: usize,
        pool: &rayon::ThreadPool,
    ) -> std::result::Result<SlabSamples, OutOfCoreError> {
        Run {
            params: &self.params,
            scan: &self.scan,
            layout: &self.layout,
            files: &self.files,
            field: &self.field,
            screening: self.screening,
            pool,
            watch: Watch::new(),
        }
        .load(k, Some(self.finest))
    }
}

/// One slab's samples as the in-memory pipeline prepares all of them: in Morton order in the
/// unit cube, with their areas and their splats per depth, and which of them the slab owns.
pub(crate) struct SlabSamples {
    pub(crate) samples: Samples,
    pub(crate) area: Vec<f64>,
    pub(crate) at_depth: Vec<Vec<DepthSample>>,
    pub(crate) owned: Vec<bool>,
}

impl SlabSamples {
    /// The splats of the samples the slab owns.
    fn own_at_depth(&self) -> Vec<Vec<DepthSample>> {
        self.at_depth
            .iter()
            .map(|at| {
                at.iter()
                    .copied()
                    .filter(|s| self.owned[s.sample as usize])
                    .collect()
            })
            .collect()
    }
}

/// Keeps a slab's prepared samples (positions in the unit cube in Morton order, normals,
/// confidence, and the density's area and depth of each) for the passes after the first:
/// 56 bytes a sample (the normals and the confidence, `f32` as read, two to a word).
fn write_prepared(
    path: &Path,
    samples: &Samples,
    density: &SampleDensity,
) -> std::result::Result<(), OutOfCoreError> {
    let pair = |a: f32, b: f32| (u64::from(a.to_bits()) << 32) | u64::from(b.to_bits());
    let positions: Vec<u64> = samples
        .positions
        .iter()
        .flat_map(|p| p.to_array().map(f64::to_bits))
        .collect();
    let normals_and_confidence: Vec<u64> = samples
        .normals
        .iter()
        .zip(&samples.confidence)
        .flat_map(|(n, &c)| [pair(n[0], n[1]), pair(n[2], c as f32)])
        .collect();
    let bits = |values: &[f64]| values.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
    write_lists(
        path,
        &[
            positions,
            normals_and_confidence,
            bits(&density.area),
            bits(&density.depth),
        ],
    )
}

/// Reads what [`write_prepared`] wrote: the same samples and density, bit for bit (the
/// confidence is an `f32` as read, widened to `f64`, and a normal's components are `f32`).
fn read_prepared(path: &Path) -> std::result::Result<(Samples, SampleDensity), OutOfCoreError> {
    let lists: Vec<Vec<u64>> = read_lists(path)?;
    let malformed = || OutOfCoreError::internal("a slab's prepared samples file is malformed");
    let [positions, normals_and_confidence, area, depth] =
        <[Vec<u64>; 4]>::try_from(lists).map_err(|_| malformed())?;
    let n = area.len();
    if positions.len() != 3 * n || normals_and_confidence.len() != 2 * n || depth.len() != n {
        return Err(malformed());
    }
    let high = |w: u64| f32::from_bits((w >> 32) as u32);
    let low = |w: u64| f32::from_bits(w as u32);
    let samples = Samples {
        positions: positions
            .chunks_exact(3)
            .map(|c| {
                glam::DVec3::new(
                    f64::from_bits(c[0]),
                    f64::from_bits(c[1]),
                    f64::from_bits(c[2]),
                )
            })
            .collect(),
        normals: normals_and_confidence
            .chunks_exact(2)
            .map(|c| [high(c[0]), low(c[0]), high(c[1])])
            .collect(),
        confidence: normals_and_confidence
            .chunks_exact(2)
            .map(|c| f64::from(low(c[1])))
            .collect(),
        attributes: Vec::new(),
    };
    let floats = |words: Vec<u64>| words.into_iter().map(f64::from_bits).collect::<Vec<f64>>();
    let density = SampleDensity {
        area: floats(area),
        depth: floats(depth),
        quantiles: Vec::new(),
    };
    Ok((samples, density))
}

/// The parts of the run every pass reads.
struct Run<'a> {
    params: &'a Params,
    scan: &'a Scan,
    layout: &'a SlabLayout,
    files: &'a SlabFiles,
    field: &'a FieldBySlab,
    /// The screening's weights per depth: α·2^D at every depth until the noise, when the
    /// screening follows it, is estimated after pass B.
    screening: ScreeningWeights,
    pool: &'a rayon::ThreadPool,
    watch: Watch,
}

impl Run<'_> {
    /// Slab k's samples; their splats reach `finest` (when given) at least. The first load
    /// prepares them from the slab's point file (Morton order, density) and keeps what it
    /// prepared in the slab's prepared file in place of the point file; the later loads (five
    /// more over the run) read that file, which gives the same samples bit for bit.
    fn load(
        &self,
        k: usize,
        finest: Option<u32>,
    ) -> std::result::Result<SlabSamples, OutOfCoreError> {
        let params = self.params;
        let prepared_file = &self.files.prepared[k];
        let (samples, mut density) = if prepared_file.exists() {
            read_prepared(prepared_file)?
        } else {
            self.prepare(k, prepared_file)?
        };
        let mut at_depth = samples_by_depth(
            &mut density,
            &samples.confidence,
            params.depth,
            params.effective_full_depth(),
            Octree::coarsest_depth(params.boundary, params.node_degree()),
        );
        if let Some(finest) = finest {
            at_depth.resize_with(finest as usize + 1, Vec::new);
        }
        let layout = self.layout;
        grade_padding(
            &mut at_depth,
            &samples.positions,
            layout,
            k,
            FINE_PADDING_NODES,
        );
        let owned = samples
            .positions
            .iter()
            .map(|p| layout.slab_of_column(layout.column_of(p.x)) == k)
            .collect();
        Ok(SlabSamples {
            samples,
            area: density.area,
            at_depth,
            owned,
        })
    }

    /// Slab k's samples prepared from its point file (Morton order, density), kept in
    /// `keep_in` for the later loads and the point file removed.
    fn prepare(
        &self,
        k: usize,
        keep_in: &Path,
    ) -> std::result::Result<(Samples, SampleDensity), OutOfCoreError> {
        let params = self.params;
        let records = read_slab(&self.files.points[k])?;
        let positions: Vec<[f64; 3]> = records.iter().map(|r| r.position).collect();
        let normals: Vec<[f32; 3]> = records.iter().map(|r| r.normal).collect();
        let weights: Vec<f32> = records.iter().map(|r| r.confidence).collect();
        drop(records);
        let mut set = PointSet::new();
        set.extend_weighted_f64(
            &positions,
            &normals,
            self.scan.weighted.then_some(weights.as_slice()),
        )?;
        drop((positions, normals, weights));
        let samples = self
            .pool
            .install(|| Samples::in_morton_order(&set, &self.scan.map, params.depth))?;
        drop(set);
        let (field, normal_sums) = self.field.for_samples(k)?;
        if let Some(p) = samples.positions.iter().find(|&&p| !field.holds(p)) {
            return Err(OutOfCoreError::internal(format!(
                "slab {k} holds a sample at x = {} beyond its padding",
                p.x
            )));
        }
        let density = self.pool.install(|| {
            estimate(
                &field.field,
                Some(&normal_sums),
                &samples.positions,
                params.depth,
                params.samples_per_node as f64,
                &self.watch,
            )
        })?;
        write_prepared(keep_in, &samples, &density)?;
        for file in &self.files.points[k] {
            std::fs::remove_file(file).map_err(scratch_error("remove a slab file", file))?;
        }
        Ok((samples, density))
    }

    /// The core sets of the samples `at_depth` of `slab` (every depth).
    fn cores(&self, slab: &SlabSamples, at_depth: &[Vec<DepthSample>]) -> Result<Vec<Vec<u64>>> {
        let params = self.params;
        self.pool.install(|| {
            Octree::core_sets(
                sample_cells(at_depth, &slab.samples.positions),
                params.effective_full_depth(),
                params.boundary,
                params.node_degree(),
                &self.watch,
                &|_| Ok(()),
            )
        })
    }

    /// The tree whose depths 0..=B are the base's and whose finer depths are `cores`'.
    fn slab_tree(&self, base_cores: &[Vec<u64>], cores: Vec<Vec<u64>>) -> Result<Octree> {
        let mut all = base_cores.to_vec();
        all.extend(cores.into_iter().skip(base_cores.len()));
        let params = self.params;
        self.pool
            .install(|| Octree::from_cores(all, params.boundary, params.node_degree(), &self.watch))
    }

    /// ρ of every depth of the samples `at_depth` on `tree`, as the pipeline's splat and system
    /// stages compute it, each depth's V but the finest's handed to `take_v` (depth, V) once
    /// its own divergence is taken, root first.
    fn right_hand_sides(
        &self,
        tree: &Octree,
        slab: &SlabSamples,
        at_depth: &[Vec<DepthSample>],
        take_v: impl FnMut(usize, [Vec<f64>; 3]) -> Result<()> + Send,
    ) -> Result<Vec<Vec<f64>>> {
        self.pool.install(|| {
            let splat = |d: usize| {
                crate::splat::splat_level(&tree.levels[d], &slab.samples, &at_depth[d], self.params)
            };
            let finest = tree.max_depth() as usize;
            let rho_finest = finest_right_hand_side(&tree.levels[finest], splat(finest)?)?;
            let own = coarser_divergences(tree, splat, take_v)?;
            right_hand_sides(tree, rho_finest, own, |_| Ok(()))
        })
    }

    fn solve(
        &self,
        tree: &Octree,
        rho: Vec<Vec<f64>>,
        coarse_div: Vec<Vec<f64>>,
        screening: Screening<'_>,
        depths: Depths,
        progress: &mut dyn FnMut(f32) -> bool,
    ) -> Result<Vec<Vec<f64>>> {
        let (positions, screening_weights, proxy_groups) = match screening {
            Screening::Samples(positions, weights) => (positions, weights, None),
            Screening::Groups(groups) => (&[][..], &[][..], Some(groups)),
        };
        cascade(
            System {
                tree,
                rho,
                coarse_div,
                positions,
                screening_weights,
                proxy_groups,
                screening: self.screening,
                depths,
            },
            self.params,
            self.pool,
            progress,
            &mut Vec::new(),
        )
    }
}

/// What a solve screens with: samples, or groups already summed.
enum Screening<'a> {
    Samples(&'a [glam::DVec3], &'a [f64]),
    Groups(&'a [Vec<ProxyGroup>]),
}

/// Slab k's files of its solution: its core sets above the base, its coefficients of every
/// depth.
fn solution_files(scratch: &Scratch, k: usize) -> [PathBuf; 2] {
    [
        scratch.file(&format!("slab-{k}.cores")),
        scratch.file(&format!("slab-{k}.coefficients")),
    ]
}

/// Slab k's χ from its solution files (its tree rebuilt from the base's cores and its own).
pub(crate) fn load_solution(
    solved: &SolvedSlabs,
    k: usize,
    pool: &rayon::ThreadPool,
) -> std::result::Result<Indicator, OutOfCoreError> {
    load_solution_in(&solved.scratch, k, &solved.base_cores, &solved.params, pool)
}

fn load_solution_in(
    scratch: &Scratch,
    k: usize,
    base_cores: &[Vec<u64>],
    params: &Params,
    pool: &rayon::ThreadPool,
) -> std::result::Result<Indicator, OutOfCoreError> {
    let [cores_file, coefficients_file] = solution_files(scratch, k);
    let mut cores = base_cores.to_vec();
    cores.extend(read_lists::<u64>(&cores_file)?);
    let coefficients = read_lists::<f64>(&coefficients_file)?;
    let tree = pool.install(|| {
        Octree::from_cores(cores, params.boundary, params.node_degree(), &Watch::new())
    })?;
    Ok(Indicator { tree, coefficients })
}

/// The cloud cut into slabs, binned, and pass A's sums: what a base depth decides.
struct Cut {
    /// B: depths 0..=B are solved once for the whole cloud; the walls lie on depth B + 2.
    base_depth: u32,
    layout: SlabLayout,
    scratch: Scratch,
    files: SlabFiles,
    field: FieldBySlab,
    /// Each slab's own core sets up to the base depth.
    own_cores: Vec<Vec<Vec<u64>>>,
    /// The finest depth any sample reaches.
    finest: u32,
    /// Σ area × confidence and Σ confidence over all the samples (the screening weights').
    total_area: f64,
    total_confidence: f64,
    /// With [`Params::screening_follows_noise`], the samples' areas counted by the depth each
    /// gives the noise estimate (`outofcore/noise.rs`).
    area_depths: Option<AreaDepths>,
}

/// Nodes of each depth finer than the walls that a slab's padding keeps on each side of its
/// columns: past the wall depth B + 2 the padding is graded, a fixed number of every depth's
/// own nodes (24 nodes of depth B + 3 are half the 24 columns of depth B + 2, of depth B + 4 a
/// quarter), since the finer depths' corrections reach a fixed number of their own cells. On
/// the Happy Buddha at depth 10 in 8 slabs, 12 and 24 both kept every vertex within 0.17 finest
/// cell of the in-memory mesh and its genus (`docs/out-of-core.md`); 24 for a margin.
pub(crate) const FINE_PADDING_NODES: u32 = 24;

/// The graded padding: past the wall depth, slab k's splats at each depth stay within its band
/// there ([`SlabLayout::band`], `nodes` nodes of that depth beyond its columns) and the splats
/// of the samples beyond it go one depth coarser, their mass added there (finest depth first,
/// so a splat moves down until a band holds it; at the wall depth every splat of the padding
/// stays). The field V the slab splats is then the whole of its samples', only coarser far
/// from its columns, so the fine solve near the band's edge sees a smooth field rather than a
/// cut one (dropping the splats instead gained the Buddha a handle). The splats of the samples
/// the slab owns never move: its columns lie in every band. Each depth's list stays in sample
/// order (a sample moved onto a depth where it splats already has two entries there).
pub(crate) fn grade_padding(
    at_depth: &mut [Vec<DepthSample>],
    positions: &[DVec3],
    layout: &SlabLayout,
    k: usize,
    nodes: u32,
) {
    let wall_depth = layout.wall_depth as usize;
    for d in (wall_depth + 1..at_depth.len()).rev() {
        let band = layout.band(k, d as u32, nodes);
        let cells = (d as f64).exp2();
        let (kept, beyond): (Vec<DepthSample>, Vec<DepthSample>) =
            at_depth[d].iter().partition(|s| {
                let x = (positions[s.sample as usize].x * cells).floor() as i64;
                band.contains(&x)
            });
        if beyond.is_empty() {
            continue;
        }
        at_depth[d] = kept;
        let coarser = &mut at_depth[d - 1];
        coarser.extend(beyond);
        coarser.sort_by_key(|s| s.sample);
    }
}

/// The columns of padding each slab reads beyond its walls: `asked`, or more when the density's
/// kernel is so coarse that a node the slab owns gathers points from farther away (a node of
/// the kernel depth reaches one node width from its centre, 2^(wall − kernel) columns when the
/// kernel depth is the coarser).
pub(crate) fn padding_for(asked: u32, wall_depth: u32, kernel_depth: u32) -> u32 {
    let reach = 1u32 << wall_depth.saturating_sub(kernel_depth).min(31);
    asked.max(reach)
}

/// The slabs' files: each slab's binned points (one file per part of the input, in part order)
/// and, once its samples are prepared, its prepared samples.
pub(crate) struct SlabFiles {
    points: Vec<Vec<PathBuf>>,
    prepared: Vec<PathBuf>,
}

impl SlabFiles {
    fn new(scratch: &Scratch, slabs: usize, parts: usize) -> Self {
        SlabFiles {
            points: (0..slabs)
                .map(|k| (0..parts).map(|r| binned_file(scratch, k, r)).collect())
                .collect(),
            prepared: (0..slabs)
                .map(|k| scratch.file(&format!("slab-{k}.prepared")))
                .collect(),
        }
    }
}

/// Chooses the base depth among `base_depths` and counts the columns of its depth + 2, cuts
/// them into slabs (as `plan` says), bins the points, sums the density's kernel counts slab by
/// slab, and runs pass A: each slab's own core sets up to the base depth, the finest depth, the
/// screening totals. Every member counts and bins its part of the input (`part` of it,
/// `part_count` points) and sums and prepares its own slabs.
///
/// Under a memory budget with more than one base depth to choose from, the cut of each is the
/// fewest slabs that fit (at least one per member), and the base depth is the one whose cut
/// leaves a member the fewest nodes to work on ([`SlabModel::member_work`]), the coarsest of
/// equals. A finer base thins every slab's padding (24 columns of its depth + 2 on each side),
/// which otherwise outgrows the slabs as a budget cuts them thin, at the price of a larger base
/// every member solves; a cut that fits in one slab has no padding and keeps the coarsest.
#[allow(clippy::too_many_arguments)]
fn cut(
    input: &Input<'_>,
    scratch: Scratch,
    scan: &Scan,
    part_count: u64,
    params: &Params,
    plan: &Plan,
    base_depths: RangeInclusive<u32>,
    team: &dyn Team,
    pool: &rayon::ThreadPool,
    keep_going: &mut dyn FnMut(&str, f32) -> bool,
) -> std::result::Result<Cut, OutOfCoreError> {
    let part = (team.rank(), team.size());
    let part_fraction = |done: u64| done as f32 / part_count.max(1) as f32;
    // The columns are counted at the finest wall depth that can be chosen, and summed into
    // each coarser one's.
    let counted_depth = base_depths.end() + 2;
    let kernel_depth = params.effective_kernel_depth();
    // The memory budget's cut measures the surface by the kernel's nodes.
    let budget = match plan.slabs {
        SlabCount::Within(budget) => Some(budget),
        SlabCount::Exactly(_) => None,
    };
    let counted = columns_of_part(
        input,
        part,
        &scan.map,
        counted_depth,
        budget.map(|_| kernel_depth),
        &mut |done| keep_going("columns", part_fraction(done)),
    );
    let (_, parts) = agreed_with(team, counted, ColumnsOfPart::packed)?;
    // Every member lays the slabs out itself, from the same parts, each unpacked in turn: the
    // counts added, the kernel nodes and the occupied cells joined (for a budget's cut, the
    // surface's measure and the base's screening groups).
    let mut counted_columns = vec![0u64; 1 << counted_depth];
    let mut surface = budget.map(|_| KernelNodes::new(kernel_depth));
    let mut occupied: Option<OccupiedCells> = None;
    for bytes in &parts {
        let part = ColumnsOfPart::unpacked(bytes)?;
        for (sum, count) in counted_columns.iter_mut().zip(&part.counts) {
            *sum += count;
        }
        if let Some(surface) = &mut surface {
            surface.insert(part.kernel_nodes);
        }
        match (&mut occupied, part.occupied) {
            (Some(joined), Some(theirs)) => joined.join(&theirs),
            (joined, theirs) => *joined = joined.take().or(theirs),
        }
    }
    drop(parts);
    let (base_depth, slabs) = match plan.slabs {
        SlabCount::Exactly(n) => (*base_depths.start(), n),
        SlabCount::Within(budget) => {
            // The surface as the whole input's kernel nodes (whose bricks are the field's).
            let (surface, occupied) = surface.zip(occupied).ok_or_else(|| {
                OutOfCoreError::internal("a budget's cut without the kernel nodes")
            })?;
            // Beside the field, every member holds the fits of the noise estimate's cells of its
            // slabs from pass B on (counted as if one member fitted the whole cloud's).
            let noise_fits = if params.screening_follows_noise {
                crate::memory::noise_fit_bytes(scan.count)
            } else {
                0
            };
            let slots_by_depth: Vec<u64> = surface
                .slots_by_depth()
                .into_iter()
                .map(|slots| slots as u64)
                .collect();
            base_and_slabs_within(
                budget,
                &counted_columns,
                counted_depth,
                base_depths,
                |wall_depth| surface_by_column(surface.node_x(), kernel_depth, wall_depth),
                |wall_depth| padding_for(plan.padding, wall_depth, kernel_depth),
                |depth| occupied.at(depth),
                kernel_depth,
                params,
                team.size(),
                &slots_by_depth,
                noise_fits,
            )
            .map_err(|enough| crate::Error::OutOfMemory {
                what: "the largest slab a cut of the cloud can make, with its padding",
                needed: enough,
                limit: Some(budget),
                enough: Some(enough),
            })?
        }
    };
    let wall_depth = base_depth + 2;
    let counts = coarser_columns(&counted_columns, counted_depth - wall_depth);
    let padding = padding_for(plan.padding, wall_depth, kernel_depth);
    // Every member has a slab to do (when the points fill enough columns).
    let layout = SlabLayout::balanced(&counts, wall_depth, slabs.max(team.size()), padding);
    let slabs = layout.len();
    let binned = bin_part(input, part, scan, &layout, &scratch, &mut |done| {
        keep_going("bin", part_fraction(done))
    });
    agreed(team, binned)?;
    let files = SlabFiles::new(&scratch, slabs, team.size());

    // The density, each slab summing the kernel counts of the nodes it owns (whose centre is
    // in its columns) over its points and padding in input order, and restricting them to the
    // coarser depths itself down to the coarsest it has exact: each node's sum is then the
    // single process's, whatever the parts and the members (`outofcore/field.rs`). Its nodes
    // of the coarsest are gathered by every member, the finer ones stay in its file.
    let coarse_depth = coarsest_exact_depth(wall_depth, padding, kernel_depth);
    let mut coarse = KernelCounts::new(coarse_depth);
    rounds(
        team,
        slabs,
        |k| {
            if !keep_going("density", k as f32 / slabs as f32) {
                return Err(OutOfCoreError::Reconstruction(crate::Error::Cancelled));
            }
            let records = read_slab(&files.points[k])?;
            let unit: Vec<DVec3> = records
                .iter()
                .map(|r| scan.map.to_unit_f64(r.position))
                .collect();
            let confidence: Vec<f64> = records.iter().map(|r| r.confidence as f64).collect();
            // As the point set makes them (a normal it would refuse adds nothing here; the
            // slab's preparation refuses it).
            let normals: Vec<[f32; 3]> = records
                .iter()
                .map(|r| unit_normal(r.normal).unwrap_or([0.0; 3]))
                .collect();
            drop(records);
            let own = write_own_part(
                &FieldBySlab::file_of(&scratch, k),
                &unit,
                &confidence,
                &normals,
                &layout,
                k,
                kernel_depth,
                coarse_depth,
            )?;
            let mut p = Packer::default();
            p.u64s_by_steps(&own.iter().map(|n| n.0).collect::<Vec<_>>());
            p.f64s(&own.iter().map(|n| n.1).collect::<Vec<_>>());
            Ok(p.bytes)
        },
        |_, bytes| {
            let mut u = Unpacker::new(bytes);
            let keys = u.u64s_by_steps()?;
            let counts = u.f64s()?;
            if counts.len() != keys.len() {
                return Err(crate::Error::Internal(
                    "a slab's coarse counts do not match their nodes".into(),
                )
                .into());
            }
            coarse.insert(keys.into_iter().zip(counts));
            Ok(())
        },
    )?;
    let field = FieldBySlab::new(&scratch, &layout, kernel_depth, coarse);
    let run = Run {
        params,
        scan,
        layout: &layout,
        files: &files,
        field: &field,
        screening: ScreeningWeights::full_at_every_depth(params.point_weight, params.depth),
        pool,
        watch: Watch::new(),
    };
    let slabs = layout.len();
    let mut own_cores: Vec<Vec<Vec<u64>>> = Vec::with_capacity(slabs);
    let mut finest = 0u32;
    let (mut total_area, mut total_confidence) = (0.0f64, 0.0f64);
    let following_noise = params.screening_follows_noise;
    let mut area_depths = following_noise.then(|| AreaDepths::new(params.depth));
    rounds(
        team,
        slabs,
        |k| {
            if !keep_going("base", k as f32 / (2 * slabs + 1) as f32) {
                return Err(OutOfCoreError::Reconstruction(crate::Error::Cancelled));
            }
            let slab = run.load(k, None)?;
            let (mut area, mut confidence) = (0.0f64, 0.0f64);
            for (s, owned) in slab.owned.iter().enumerate() {
                if *owned {
                    area += slab.area[s] * slab.samples.confidence[s];
                    confidence += slab.samples.confidence[s];
                }
            }
            let mut cores = run.cores(&slab, &slab.own_at_depth())?;
            cores.truncate(base_depth as usize + 1);
            // The own samples' areas counted by depth, only when the noise is followed.
            let own_area_depths = following_noise.then(|| {
                let mut counted = AreaDepths::new(params.depth);
                counted.count(
                    slab.area
                        .iter()
                        .zip(&slab.owned)
                        .filter(|(_, owned)| **owned)
                        .map(|(area, _)| *area),
                );
                counted
            });
            let mut p = Packer::default();
            p.u64(slab.at_depth.len() as u64 - 1);
            p.f64(area);
            p.f64(confidence);
            p.u64s(
                own_area_depths
                    .as_ref()
                    .map_or(&[], |counted| &counted.counts),
            );
            p.u64(cores.len() as u64);
            for keys in &cores {
                p.u64s_by_steps(keys);
            }
            Ok(p.bytes)
        },
        |_, bytes| {
            let mut u = Unpacker::new(bytes);
            finest = finest.max(u.u64()? as u32);
            total_area += u.f64()?;
            total_confidence += u.f64()?;
            let counts = u.u64s()?;
            if let Some(area_depths) = &mut area_depths {
                area_depths.add(&counts);
            }
            let depths = u.u64()?;
            own_cores.push(
                (0..depths)
                    .map(|_| u.u64s_by_steps())
                    .collect::<std::result::Result<_, _>>()?,
            );
            Ok(())
        },
    )?;
    Ok(Cut {
        base_depth,
        layout,
        scratch,
        files,
        field,
        own_cores,
        finest,
        total_area,
        total_confidence,
        area_depths,
    })
}

/// The run's temporary directory under `parent`, made by the first member of `team`. With
/// more than one member the maker leaves a fresh token in it and every other member must find
/// that token there before the run goes on: a directory not shared by the members (each
/// machine's own temporary directory) is refused at the start, by every member alike, with a
/// message that says so.
fn team_scratch(
    team: &dyn Team,
    parent: Option<&Path>,
) -> std::result::Result<Scratch, OutOfCoreError> {
    let alone = team.size() == 1;
    let (scratch, token) = from_first(
        team,
        || {
            let scratch = Scratch::create(parent)?;
            let token = fresh_token();
            if !alone {
                scratch.leave_token(token)?;
            }
            Ok((scratch, token))
        },
        |(scratch, token), p| {
            p.bytes(scratch.path().as_os_str().as_encoded_bytes());
            p.u64(*token);
        },
        |u| {
            let bytes = u.bytes()?;
            // SAFETY: the bytes are those of an `OsStr` of rank 0 on the same platform, as
            // `as_encoded_bytes` gave them (the members run the same program).
            let dir = unsafe { std::ffi::OsStr::from_encoded_bytes_unchecked(bytes) };
            Ok((Scratch::join(dir.into()), u.u64()?))
        },
    )?;
    checked_by_others(team, || scratch.find_token(token))?;
    Ok(scratch)
}

/// Runs the passes on the PLY file at `path` (oriented points) with `params`, cut as `plan`
/// says, each member of `team` doing its own slabs. `keep_going(pass, fraction)` is asked
/// between chunks and slabs; false cancels.
pub(crate) fn solve_slabs(
    path: &Path,
    params: &Params,
    plan: &Plan,
    team: &dyn Team,
    pool: &rayon::ThreadPool,
    keep_going: &mut dyn FnMut(&str, f32) -> bool,
) -> std::result::Result<SolvedSlabs, OutOfCoreError> {
    params.validate()?;
    let cancelled = || OutOfCoreError::Reconstruction(crate::Error::Cancelled);
    let input = Input {
        path,
        chunk: plan.chunk,
        confidence: plan.confidence,
    };
    // First the temporary directory, so that one the members do not share is refused before
    // any pass over the input.
    let scratch = team_scratch(team, plan.temp_dir.as_deref())?;
    // Each member scans its part of the input (r of n); they meet with what they found.
    let scanned = scan_part(&input, (team.rank(), team.size()), &mut |_| {
        keep_going("scan", 0.0)
    });
    let (_, parts) = agreed_with(team, scanned, ScannedPart::packed)?;
    let parts = parts
        .iter()
        .map(|bytes| ScannedPart::unpacked(bytes))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    if parts.iter().any(|p| p.file_bytes != parts[0].file_bytes) {
        return Err(crate::Error::InvalidParameter {
            name: "input",
            value: path.display().to_string(),
            expected: "the same file for every member of the team (they read files of different \
                       lengths)",
        }
        .into());
    }
    let scan = scan_of_parts(&parts, &input, params.scale as f64)?;
    let params = params.for_cube(scan.map.size);
    let full_depth = params.effective_full_depth();
    // The base holds the complete depths (a complete depth spans the cube, far from any slab)
    // and leaves two depths above it for the walls.
    let too_shallow = |depth: u32, what: &'static str| {
        OutOfCoreError::from(crate::Error::InvalidParameter {
            name: "depth",
            value: depth.to_string(),
            expected: what,
        })
    };
    let base_depths = match plan.base_depth {
        Some(b) if b < full_depth || b + 2 > params.depth => {
            return Err(crate::Error::InvalidParameter {
                name: "base_depth",
                value: b.to_string(),
                expected: "at least the full depth and at most the depth − 2",
            }
            .into())
        }
        Some(b) => b..=b,
        None if full_depth + 2 > params.depth => {
            return Err(too_shallow(
                params.depth,
                "at least the full depth + 2 for a reconstruction out of core (lower the full \
                 depth or raise the depth)",
            ))
        }
        None => {
            let default = params
                .depth
                .saturating_sub(3)
                .clamp(full_depth, 7.max(full_depth));
            match plan.slabs {
                // A budget chooses the base depth with the cut (see `cut`).
                SlabCount::Within(_) => default..=params.depth - 2,
                SlabCount::Exactly(_) => default..=default,
            }
        }
    };
    // The cut and pass A; cut again with a lower base when the samples do not reach two
    // depths above it (a sparse cloud at a depth its samples do not resolve).
    let part_count = parts[team.rank()].count;
    let mut cut_at = |scratch, base_depths| {
        cut(
            &input,
            scratch,
            &scan,
            part_count,
            &params,
            plan,
            base_depths,
            team,
            pool,
            keep_going,
        )
    };
    let mut cut = cut_at(scratch, base_depths.clone())?;
    if cut.finest < cut.base_depth + 2 {
        let lowest = cut.finest.saturating_sub(2);
        if plan.base_depth.is_some() || lowest < full_depth {
            return Err(too_shallow(
                params.depth,
                "a depth whose samples reach the base depth + 2 for a reconstruction out of \
                 core (these reach only their density's depth: lower the full depth, or \
                 reconstruct in memory)",
            ));
        }
        // Every member is done with the first cut's files before rank 0 removes them (with
        // their directory: the second cut has its own).
        agreed(team, Ok(()))?;
        drop(cut);
        let scratch = team_scratch(team, plan.temp_dir.as_deref())?;
        cut = cut_at(scratch, (*base_depths.start()).min(lowest)..=lowest)?;
    }
    let Cut {
        base_depth,
        layout,
        scratch,
        files,
        field,
        own_cores,
        finest,
        total_area,
        total_confidence,
        area_depths,
    } = cut;
    let mut run = Run {
        params: &params,
        scan: &scan,
        layout: &layout,
        files: &files,
        field: &field,
        screening: ScreeningWeights::full_at_every_depth(params.point_weight, params.depth),
        pool,
        watch: Watch::new(),
    };
    let slabs = layout.len();
    let b = base_depth as usize;
    let base_cores = coarse_cores(own_cores.iter().map(|c| c.as_slice()), base_depth);
    drop(own_cores);

    // Pass B: each slab's own ρ and V up to B and its own screening groups, summed; and when
    // the screening is to follow the samples' noise, the fits of the estimate's cells each
    // slab owns, kept by the member that fits them for the medians after the pass.
    let noise_depth = area_depths.and_then(|depths| depths.median_depth());
    let mut slab_noise = SlabNoise::default();
    let mut sums = BaseParts::default();
    // The whole cloud's screening groups of each depth up to B, merged as the slabs' come.
    let mut groups: Vec<Vec<ProxyGroup>> = vec![Vec::new(); b + 1];
    rounds(
        team,
        slabs,
        |k| {
            if !keep_going("base", (slabs + k) as f32 / (2 * slabs + 1) as f32) {
                return Err(cancelled());
            }
            let slab = run.load(k, Some(finest))?;
            let own = slab.own_at_depth();
            let tree = run.slab_tree(&base_cores, run.cores(&slab, &own)?)?;
            let mut base_v = Vec::with_capacity(b + 1);
            let rho = run.right_hand_sides(&tree, &slab, &own, |d, v| {
                if d <= b {
                    base_v.push(v);
                }
                Ok(())
            })?;
            let (positions, confidence): (Vec<_>, Vec<_>) = slab
                .samples
                .positions
                .iter()
                .zip(&slab.samples.confidence)
                .zip(&slab.owned)
                .filter(|(_, owned)| **owned)
                .map(|((p, c), _)| (*p, *c))
                .unzip();
            let weights = sample_weights_from_totals(&confidence, total_area, total_confidence);
            let mut p = Packer::default();
            for d in 0..=b {
                pack_sparse(&mut p, &rho[d]);
                for axis in &base_v[d] {
                    pack_sparse(&mut p, axis);
                }
                let cells = sample_groups(&positions, &weights, proxy_depth(d as u32, finest));
                pack_groups(&mut p, &cells);
            }
            if let Some(depth) = noise_depth {
                pool.install(|| {
                    slab_noise.fit_slab(&layout, k, depth, &slab.samples.positions);
                });
            }
            Ok(p.bytes)
        },
        |_, bytes| {
            let mut u = Unpacker::new(bytes);
            let (mut rho, mut field_v) = (Vec::with_capacity(b + 1), Vec::with_capacity(b + 1));
            for merged in groups.iter_mut() {
                rho.push(unpack_sparse(&mut u)?);
                field_v.push([
                    unpack_sparse(&mut u)?,
                    unpack_sparse(&mut u)?,
                    unpack_sparse(&mut u)?,
                ]);
                *merged = merge_groups(std::mem::take(merged), &unpack_groups(&mut u)?);
            }
            sums.add(&rho, &field_v, b);
            Ok(())
        },
    )?;
    // The noise's medians across the team, and the screening's depth from them (as in memory).
    let noise = match (params.screening_follows_noise, noise_depth) {
        (false, _) => None,
        (true, None) => Some(TeamNoise::default()),
        (true, Some(depth)) => Some(slab_noise.estimate(team, depth)?),
    };
    let screening_depth =
        crate::system::screening_depth(params.depth, noise.map_or(0.0, |team| team.noise.sigma));
    run.screening = ScreeningWeights::new(params.point_weight, params.depth, screening_depth);
    // The base, solved by every member (it is small beside a slab).
    let solved_base = (|| {
        let base_tree = run.slab_tree(&base_cores, Vec::new())?;
        let mut carry = FieldCarry::new(&base_tree, finest, b);
        for (d, v) in std::mem::take(&mut sums.field_v).into_iter().enumerate() {
            carry.push(d, v, pool)?;
        }
        let (coarse_div, handed_over) = carry.finish();
        let coefficients = run.solve(
            &base_tree,
            std::mem::take(&mut sums.rho),
            coarse_div,
            Screening::Groups(&groups),
            Depths::Base { last: b, finest },
            &mut |f| keep_going("base", ((2 * slabs) as f32 + f) / (2 * slabs + 1) as f32),
        )?;
        Ok(Solved {
            coefficients,
            field_v: handed_over.expect("the base's last depth is below the finest"),
        })
    })();
    drop(groups);
    let base = agreed(team, solved_base)?;

    // Pass C: each slab's depths above B over its points and padding, and its bands of
    // coefficients for the slabs whose padding reaches it (`outofcore/bands.rs`).
    rounds(
        team,
        slabs,
        |k| {
            if !keep_going("slabs", k as f32 / slabs as f32) {
                return Err(cancelled());
            }
            let mut slab = run.load(k, Some(finest))?;
            let cores = run.cores(&slab, &slab.at_depth)?;
            let [cores_file, coefficients_file] = solution_files(&scratch, k);
            write_lists(&cores_file, &cores[b + 1..])?;
            let tree = run.slab_tree(&base_cores, cores)?;
            // The base's V carried on through the slab's depths above it (the slab's own V
            // of the base's depths is in the base already).
            let mut carry = FieldCarry::from_base(&tree, b, base.field_v.clone(), pool)?;
            let rho = run.right_hand_sides(&tree, &slab, &slab.at_depth, |d, v| {
                if d > b {
                    carry.push(d, v, pool)
                } else {
                    Ok(())
                }
            })?;
            let (coarse_div, _) = carry.finish();
            // What the solve does not read goes before it: the splat's lists, the normals.
            slab.at_depth = Vec::new();
            slab.samples.normals = Vec::new();
            let weights =
                sample_weights_from_totals(&slab.samples.confidence, total_area, total_confidence);
            let coefficients = run.solve(
                &tree,
                rho,
                coarse_div,
                Screening::Samples(&slab.samples.positions, &weights),
                Depths::Above(base.coefficients.clone()),
                &mut |f| keep_going("slabs", (k as f32 + f) / slabs as f32),
            )?;
            write_lists(&coefficients_file, &coefficients)?;
            write_bands(&scratch, &layout, k, b, &Indicator { tree, coefficients })?;
            Ok(Vec::new())
        },
        |_, _| Ok(()),
    )?;

    // Pass D: every node's coefficient its owner's (so neighbours evaluate one χ near their
    // walls; from the bands of pass C), and the isovalue's partial sums over each slab's own
    // samples, added in slab order.
    let (mut weighted_sum, mut weight_sum) = (0.0f64, 0.0f64);
    rounds(
        team,
        slabs,
        |k| {
            if !keep_going("seams", k as f32 / slabs as f32) {
                return Err(cancelled());
            }
            let mut chi = load_solution_in(&scratch, k, &base_cores, &params, pool)?;
            apply_bands(&scratch, &layout, k, b, &mut chi)?;
            let slab = run.load(k, Some(finest))?;
            let values: Vec<f64> = pool.install(|| {
                use rayon::prelude::*;
                slab.samples
                    .positions
                    .par_iter()
                    .zip(&slab.owned)
                    .map(|(p, owned)| if *owned { chi.value(*p) } else { 0.0 })
                    .collect()
            });
            let (mut weighted, mut weight) = (0.0f64, 0.0f64);
            for (s, value) in values.iter().enumerate() {
                if slab.owned[s] {
                    let w = slab.area[s] * slab.samples.confidence[s];
                    weighted += w * value;
                    weight += w;
                }
            }
            // In place of the slab's own solution: no neighbour reads it any more.
            let [_, coefficients_file] = solution_files(&scratch, k);
            write_lists(&coefficients_file, &chi.coefficients)?;
            let mut p = Packer::default();
            p.f64(weighted);
            p.f64(weight);
            Ok(p.bytes)
        },
        |_, bytes| {
            let mut u = Unpacker::new(bytes);
            weighted_sum += u.f64()?;
            weight_sum += u.f64()?;
            Ok(())
        },
    )?;
    let isovalue = if weight_sum > 0.0 {
        weighted_sum / weight_sum
    } else {
        0.0
    };
    let screening = run.screening;
    Ok(SolvedSlabs {
        scratch,
        scan,
        params,
        layout,
        files,
        base_cores,
        field,
        finest,
        isovalue,
        noise,
        screening,
    })
}

/// A slab's part of the base (ρ or a component of V over every node of depths ≤ B) into `p`,
/// as the runs of its entries that are not +0.0: a slab touches the nodes near its own
/// samples, so most of the base is zeros it need not send. [`unpack_sparse`] gives back the
/// same bits (−0.0 included), so the sums over slabs are the dense ones bit for bit.
fn pack_sparse(p: &mut Packer, values: &[f64]) {
    let mut runs = Vec::new();
    let mut kept = Vec::new();
    let mut i = 0;
    while i < values.len() {
        if values[i].to_bits() == 0 {
            i += 1;
            continue;
        }
        let start = i;
        while i < values.len() && values[i].to_bits() != 0 {
            i += 1;
        }
        runs.extend([start as u64, (i - start) as u64]);
        kept.extend_from_slice(&values[start..i]);
    }
    p.u64(values.len() as u64);
    p.u64s_by_steps(&runs);
    p.f64s(&kept);
}

/// What [`pack_sparse`] packed, dense.
fn unpack_sparse(u: &mut Unpacker<'_>) -> std::result::Result<Vec<f64>, OutOfCoreError> {
    let len = u.u64()? as usize;
    let runs = u.u64s_by_steps()?;
    let kept = u.f64s()?;
    let bad = || OutOfCoreError::internal("a slab's part of the base does not fit its length");
    let mut values = vec![0.0f64; len];
    let mut taken = 0usize;
    for run in runs.chunks(2) {
        let [start, count] = run else {
            return Err(bad());
        };
        let (start, count) = (*start as usize, *count as usize);
        let target = values.get_mut(start..start.checked_add(count).ok_or_else(bad)?);
        let source = kept.get(taken..taken + count);
        match (target, source) {
            (Some(target), Some(source)) => target.copy_from_slice(source),
            _ => return Err(bad()),
        }
        taken += count;
    }
    if taken != kept.len() {
        return Err(bad());
    }
    Ok(values)
}

/// One slab's screening groups of one depth into `p`: the cells' coordinates as three lists
/// of steps ([`Packer::u64s_by_steps`]; the groups come in Morton order, a few cells apart,
/// so a cell takes 3 to 6 bytes instead of 24), then the sums as they are, bit for bit. The
/// cells were 40 % of pass B's messages (the groups 88–91 % of them, the rest ρ and V), which
/// every member receives from every slab.
fn pack_groups(p: &mut Packer, groups: &[ProxyGroup]) {
    p.u64(groups.len() as u64);
    for axis in 0..3 {
        let coordinates: Vec<u64> = groups.iter().map(|g| g.0[axis] as i64 as u64).collect();
        p.u64s_by_steps(&coordinates);
    }
    let sums: Vec<f64> = groups
        .iter()
        .flat_map(|(_, sum_p, sum_w)| [sum_p.x, sum_p.y, sum_p.z, *sum_w])
        .collect();
    p.f64s(&sums);
}

/// What [`pack_groups`] packed.
fn unpack_groups(u: &mut Unpacker<'_>) -> std::result::Result<Vec<ProxyGroup>, OutOfCoreError> {
    let bad = || OutOfCoreError::internal("a slab's screening groups do not fit their count");
    let n = u.u64()?;
    let axes = [u.u64s_by_steps()?, u.u64s_by_steps()?, u.u64s_by_steps()?];
    let sums = u.f64s()?;
    if axes.iter().any(|a| a.len() as u64 != n) || Some(sums.len() as u64) != n.checked_mul(4) {
        return Err(bad());
    }
    let coordinate = |v: u64| i32::try_from(v as i64).map_err(|_| bad());
    sums.chunks_exact(4)
        .enumerate()
        .map(|(i, sum)| {
            let cell = [
                coordinate(axes[0][i])?,
                coordinate(axes[1][i])?,
                coordinate(axes[2][i])?,
            ];
            Ok((cell, glam::DVec3::new(sum[0], sum[1], sum[2]), sum[3]))
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::{
        base_and_slabs_within, coarser_columns, coarsest_exact_depth, grade_padding, pack_groups,
        pack_sparse, padding_for, read_prepared, slabs_within, surface_by_column, unpack_groups,
        unpack_sparse, write_prepared, DepthSample, FieldHeld, KernelNodes, SampleDensity, Samples,
        SlabLayout, SlabModel,
    };
    use crate::Params;
    use glam::DVec3;
    use std::ops::RangeInclusive;

    /// Proves a slab's prepared samples read back bit for bit, and that a truncated file is an
    /// error, not samples.
    #[test]
    fn prepared_samples_read_back_bit_for_bit() {
        let positions = sphere(1000);
        let samples = Samples {
            normals: positions
                .iter()
                .map(|p| (*p - DVec3::splat(0.5)).normalize().as_vec3().to_array())
                .collect(),
            confidence: (0..1000).map(|i| f64::from(i as f32 * 0.37)).collect(),
            positions,
            attributes: Vec::new(),
        };
        let density = SampleDensity {
            area: (0..1000).map(|i| 1.0 / (i as f64 + 3.0)).collect(),
            depth: (0..1000)
                .map(|i| 4.0 + (i as f64).sin().abs() * 3.1)
                .collect(),
            quantiles: Vec::new(),
        };
        let dir = std::env::temp_dir().join(format!("psr-prepared-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("slab-0.prepared");
        write_prepared(&path, &samples, &density).unwrap();
        let (read, read_density) = read_prepared(&path).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let position_bits = |v: &[DVec3]| {
            v.iter()
                .flat_map(|p| p.to_array().map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            position_bits(&read.positions),
            position_bits(&samples.positions)
        );
        let normal_bits = |v: &[[f32; 3]]| {
            v.iter()
                .flat_map(|n| n.map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(normal_bits(&read.normals), normal_bits(&samples.normals));
        assert_eq!(bits(&read.confidence), bits(&samples.confidence));
        assert_eq!(bits(&read_density.area), bits(&density.area));
        assert_eq!(bits(&read_density.depth), bits(&density.depth));
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
        assert!(read_prepared(&path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Points on a sphere of radius 0.3 around (0.5, 0.5, 0.5) (a golden spiral).
    pub(crate) fn sphere(n: usize) -> Vec<DVec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                DVec3::splat(0.5) + 0.3 * DVec3::new(r * t.cos(), r * t.sin(), z)
            })
            .collect()
    }

    /// Proves a slab's part of the base comes back bit for bit (zeros of either sign, runs at
    /// either end), and that bytes that do not fit are an error, not values.
    #[test]
    fn a_sparse_part_of_the_base_reads_back_bit_for_bit() {
        use super::super::team::{Packer, Unpacker};
        let cases: Vec<Vec<f64>> = vec![
            Vec::new(),
            vec![0.0; 5],
            vec![1.0, 0.0, -0.0, 0.0, 2.5, 3.5, 0.0, f64::MIN_POSITIVE],
            vec![-0.0, 7.0, 0.0, 0.0],
            (0..1000)
                .map(|i| if i % 37 < 5 { (i as f64).sin() } else { 0.0 })
                .collect(),
        ];
        for values in &cases {
            let mut p = Packer::default();
            pack_sparse(&mut p, values);
            let back = unpack_sparse(&mut Unpacker::new(&p.bytes)).expect("read back");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&back), bits(values));
        }
        // A run past the length.
        let mut p = Packer::default();
        p.u64(2);
        p.u64s_by_steps(&[1, 2]);
        p.f64s(&[1.0, 2.0]);
        assert!(unpack_sparse(&mut Unpacker::new(&p.bytes)).is_err());
        // Values left over.
        let mut p = Packer::default();
        p.u64(4);
        p.u64s_by_steps(&[1, 1]);
        p.f64s(&[1.0, 2.0]);
        assert!(unpack_sparse(&mut Unpacker::new(&p.bytes)).is_err());
    }

    /// Proves a slab's screening groups come back bit for bit (cells anywhere in the i32 range,
    /// in any order, sums of any bits), that a surface's cells in Morton order take under 8
    /// bytes instead of 24, and that lists that do not fit are an error, not groups.
    #[test]
    fn screening_groups_read_back_bit_for_bit() {
        use super::super::team::{Packer, Unpacker};
        use crate::grid::morton_nested;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            state
        };
        let odd = [i32::MIN, i32::MAX, -1, 0, 1, i32::MIN + 1];
        let mut groups: Vec<([i32; 3], DVec3, f64)> = (0..500)
            .map(|i| {
                let cell = if i < 36 {
                    [odd[i % 6], odd[i / 6], odd[(i + 3) % 6]]
                } else {
                    [next() as i32, next() as i32, next() as i32]
                };
                let sum_p = DVec3::new(f64::from_bits(next()), -0.0, f64::from_bits(next() >> 2));
                (cell, sum_p, f64::from_bits(next() >> 1))
            })
            .collect();
        // And a surface's cells as the groups come: in Morton order, a few cells apart.
        let mut surface: Vec<[i32; 3]> = (0..4000)
            .map(|i| {
                let t = i as f64 * 0.0016;
                let r = 300.0 + 40.0 * (5.0 * t).sin();
                [
                    (512.0 + r * t.cos()) as i32,
                    (512.0 + r * t.sin()) as i32,
                    i / 40,
                ]
            })
            .collect();
        surface.sort_by_key(|c| morton_nested(c.map(|v| v as u32)));
        surface.dedup();
        let surface_groups: Vec<_> = surface
            .iter()
            .map(|&c| (c, DVec3::new(0.5, 0.25, 1.0), 3.0))
            .collect();
        groups.extend(surface_groups.iter().copied());
        let bits = |g: &[([i32; 3], DVec3, f64)]| {
            g.iter()
                .map(|(c, p, w)| (*c, p.to_array().map(f64::to_bits), w.to_bits()))
                .collect::<Vec<_>>()
        };
        for case in [&groups[..], &[], &surface_groups[..]] {
            let mut p = Packer::default();
            pack_groups(&mut p, case);
            let mut u = Unpacker::new(&p.bytes);
            assert_eq!(bits(&unpack_groups(&mut u).expect("read back")), bits(case));
            assert!(u.bytes().is_err(), "nothing left over");
        }
        let mut p = Packer::default();
        pack_groups(&mut p, &surface_groups);
        let per_group = p.bytes.len() as f64 / surface_groups.len() as f64;
        assert!(per_group < 32.0 + 8.0, "{per_group} bytes a group");
        // A count that does not fit the sums; a coordinate past i32.
        let mut p = Packer::default();
        p.u64(2);
        for _ in 0..3 {
            p.u64s_by_steps(&[0, 0]);
        }
        p.f64s(&[0.0; 4]);
        assert!(unpack_groups(&mut Unpacker::new(&p.bytes)).is_err());
        let mut p = Packer::default();
        p.u64(1);
        p.u64s_by_steps(&[1 << 31]);
        p.u64s_by_steps(&[0]);
        p.u64s_by_steps(&[0]);
        p.f64s(&[0.0; 4]);
        assert!(unpack_groups(&mut Unpacker::new(&p.bytes)).is_err());
    }

    /// Proves the surface's measure counts every node of the kernel depth once, in the columns
    /// over it, whether the columns are finer or coarser than the kernel depth's nodes.
    #[test]
    fn the_surface_by_column_counts_each_kernel_node_once_where_it_lies() {
        let mut kernel_nodes = KernelNodes::new(6);
        kernel_nodes.add(&sphere(20_000));
        let nodes = kernel_nodes.node_x().count() as f64;
        for wall_depth in [4, 6, 9] {
            let surface = surface_by_column(kernel_nodes.node_x(), 6, wall_depth);
            assert_eq!(surface.len(), 1 << wall_depth);
            let total: f64 = surface.iter().sum();
            assert!((total - nodes).abs() < 1e-6 * nodes, "{total} vs {nodes}");
            // Nothing beyond the sphere's x range (0.2..0.8) and its splats' one node.
            let columns = f64::from(1u32 << wall_depth);
            let reach = 2.0 / 64.0;
            for (c, s) in surface.iter().enumerate() {
                let (lo, hi) = (c as f64 / columns, (c + 1) as f64 / columns);
                if hi < 0.2 - reach || lo > 0.8 + reach {
                    assert_eq!(*s, 0.0, "column {c} of depth {wall_depth}");
                }
            }
        }
    }

    /// Proves a slab's predicted need follows its part of the surface: the need of the cut
    /// falls as slabs are added (its tree shares the whole surface's nodes among the slabs,
    /// not the whole surface's per slab), so a cloud whose tree outweighs its points fits a
    /// budget a few slabs make room for; a slab over more surface needs more; a slab holds
    /// its share of the density field's finer depths and of the normals' sums, so a field
    /// bigger than the budget fits in more slabs; and the base's solve, the same for every
    /// cut, refuses every cut of a budget below it.
    #[test]
    fn a_slab_needs_its_part_of_the_surface() {
        // A sphere's surface and its samples are uniform across x (Archimedes): 10 million
        // points at depth 12 over the middle 80 % of the columns of depth 9, the surface as
        // the 10-million-point planet's field measures it (1.8 million nodes of depth 10).
        let params = Params::default().with_depth(12);
        let (wall_depth, base_depth, kernel_depth, padding) = (9u32, 7u32, 10u32, 24u32);
        let columns = 1usize << wall_depth;
        let filled = columns / 10..columns - columns / 10;
        let mut counts = vec![0u64; columns];
        let mut surface = vec![0.0f64; columns];
        for c in filled.clone() {
            counts[c] = 10_000_000 / filled.len() as u64;
            surface[c] = 1.8e6 / filled.len() as f64;
        }
        let layout_of = |slabs| SlabLayout::balanced(&counts, wall_depth, slabs, padding);
        let field_of =
            |field_slots: &[u64]| FieldHeld::of(field_slots, wall_depth, padding, kernel_depth, 0);
        let fewest_with = |budget: u64, surface: &[f64], field_slots: &[u64]| {
            let model = SlabModel::new(
                &counts,
                surface,
                kernel_depth,
                base_depth,
                &params,
                |_| 0.0,
                field_of(field_slots),
            );
            slabs_within(budget, &model, layout_of)
        };
        let fewest = |budget: u64, surface: &[f64]| fewest_with(budget, surface, &[]);
        let least = fewest(0, &surface).expect_err("nothing fits no memory");
        let mut previous = 0;
        for gib in [16u64, 8, 4, 3] {
            let slabs = fewest(gib << 30, &surface).expect("a few slabs fit");
            assert!(
                slabs > previous,
                "{gib} GiB: {slabs} slabs after {previous}"
            );
            previous = slabs;
        }
        assert!(previous <= 16, "3 GiB takes {previous} slabs");
        assert!(least < 2 << 30, "the most slabs need {least} bytes");
        // The same points over four times the surface: more nodes, so more slabs.
        let rougher: Vec<f64> = surface.iter().map(|s| 4.0 * s).collect();
        assert!(fewest(6 << 30, &rougher).unwrap() > fewest(6 << 30, &surface).unwrap());
        // The field: its coarse depths (up to 5 with 24 columns of padding, 4 under the walls)
        // held whole by every member, the finer ones (6..=10) and the normals' sums at the
        // kernel depth by share. Small, they bind no more slabs than the solve does; 12 GiB of
        // them, whole, would outweigh an 8 GiB budget, but a slab's share fits in more slabs.
        assert_eq!(coarsest_exact_depth(wall_depth, padding, kernel_depth), 5);
        let small = [0, 0, 0, 0, 0, 0, 0, 1 << 10, 1 << 12, 1 << 14, 1 << 16];
        assert_eq!(
            fewest_with(4 << 30, &surface, &small),
            fewest(4 << 30, &surface)
        );
        let big = [0, 0, 0, 0, 0, 0, 0, 0, 0, (4 << 30) / 9, (8 << 30) / 9];
        let whole_field = crate::memory::density_bytes(big.iter().sum());
        assert!(whole_field > 11 << 30, "{whole_field}");
        let slabs = fewest_with(8 << 30, &surface, &big).expect("the field's shares fit");
        assert!(slabs > fewest(8 << 30, &surface).unwrap(), "{slabs} slabs");
        // Its coarse depths are every member's: 9 GiB of them at depth 5 fit no 8 GiB cut.
        let coarse = [0, 0, 0, 0, 0, (9 << 30) / 9];
        let enough = fewest_with(8 << 30, &surface, &coarse).expect_err("coarse over budget");
        assert!(enough > 9 << 30, "the most slabs need {enough} bytes");
        // The base's screening groups: 5 million a depth of the 8 (48 bytes each, held once,
        // and the largest depth's twice more while a slab's are merged in) need what no cut can
        // share; the most slabs' need is then the base's.
        let grouped = SlabModel::new(
            &counts,
            &surface,
            kernel_depth,
            base_depth,
            &params,
            |_| 5e6,
            field_of(&[]),
        );
        let base_need = grouped.base_need();
        assert!(base_need > 8 * 5_000_000 * 48 + 2 * 5_000_000 * 48);
        assert_eq!(
            slabs_within(base_need - 1, &grouped, layout_of),
            Err(base_need)
        );
        assert!(slabs_within(base_need, &grouped, layout_of).is_ok());
    }

    /// Proves the base depth a budget chooses: a cloud one slab holds keeps the coarsest base
    /// (no padding to thin); a budget that cuts many slabs takes a finer base, whose thinner
    /// padding leaves a member less to do and bins fewer points than the coarsest base's cut;
    /// a team of many members gets no finer base than one process (every member solves the
    /// base); and a budget no cut fits is refused with the least that one at the coarsest base
    /// does, which then fits.
    #[test]
    fn a_budget_chooses_the_base_depth_whose_cut_leaves_the_least_work() {
        // 200 million points at depth 12 over the middle 90 % of the columns, uniform across x
        // as on a sphere, the surface about as the planet's field measures it (1.9 million
        // nodes of the kernel depth 10; a whole number of them in each column, as
        // `surface_by_column` gives, so the surface sums alike at every wall depth).
        let params = Params::default().with_depth(12);
        let (kernel_depth, base_depths) = (10u32, 7u32..=10);
        let counted_depth = base_depths.end() + 2;
        let columns = 1usize << counted_depth;
        let filled = columns / 20..columns - columns / 20;
        let mut counted = vec![0u64; columns];
        for c in filled.clone() {
            counted[c] = 200_000_000 / filled.len() as u64;
        }
        let kernel_nodes: Vec<u64> = counted
            .iter()
            .map(|&n| if n > 0 { 512 } else { 0 })
            .collect();
        let surface_of = |wall_depth: u32| {
            coarser_columns(&kernel_nodes, counted_depth - wall_depth)
                .into_iter()
                .map(|n| n as f64)
                .collect::<Vec<f64>>()
        };
        let padding_of = |wall_depth: u32| padding_for(24, wall_depth, kernel_depth);
        // The cells the points occupy: a quarter as many as the kernel's nodes at depth 10, 4
        // times more a depth finer (the bunny's and the Buddha's scans have 2.0–2.1 kernel
        // nodes per occupied cell of their kernel depth; on a sphere the splats of a cell
        // reach across the nodes of its neighbours).
        let occupied_at = |depth: u32| 0.5e6 * 4f64.powi(depth as i32 - 10);
        let choose = |budget: u64, depths: RangeInclusive<u32>, members: usize| {
            base_and_slabs_within(
                budget,
                &counted,
                counted_depth,
                depths,
                surface_of,
                padding_of,
                occupied_at,
                kernel_depth,
                &params,
                members,
                &[],
                0,
            )
        };
        // The points each slab reads, padding included, summed over the cut.
        let binned = |base_depth: u32, slabs: usize| {
            let wall_depth = base_depth + 2;
            let counts = coarser_columns(&counted, counted_depth - wall_depth);
            let layout = SlabLayout::balanced(&counts, wall_depth, slabs, padding_of(wall_depth));
            (0..layout.len())
                .map(|k| layout.padded(k).map(|c| counts[c as usize]).sum::<u64>())
                .sum::<u64>()
        };
        assert_eq!(choose(1 << 50, base_depths.clone(), 1), Ok((7, 1)));
        for gib in [16u64, 8, 4] {
            let (base_depth, slabs) = choose(gib << 30, base_depths.clone(), 1).unwrap();
            let (_, coarsest_slabs) = choose(gib << 30, 7..=7, 1).unwrap();
            assert!(base_depth > 7, "{gib} GiB");
            assert!(
                binned(base_depth, slabs) < binned(7, coarsest_slabs),
                "{gib} GiB"
            );
        }
        let alone = choose(8 << 30, base_depths.clone(), 1).unwrap();
        let team = choose(8 << 30, base_depths.clone(), 64).unwrap();
        assert!(team.0 <= alone.0, "{team:?} against {alone:?}");
        // Refused with the least budget of the coarsest base (which a run cut again at a
        // coarser base, its samples not reaching the finer one's walls, still fits).
        let least = choose(1 << 20, base_depths.clone(), 1).expect_err("1 MiB fits no cut");
        assert_eq!(choose(1 << 20, 7..=7, 1), Err(least));
        assert!(choose(least, 7..=7, 1).is_ok());
        choose(least, base_depths.clone(), 1).expect("the least budget fits");
    }

    /// Proves the graded padding: past the wall depth no splat lies beyond its depth's band,
    /// the splats beyond it went one depth coarser (or more, until a band holds them) with
    /// their mass, every sample's total mass is kept, the owned samples' splats and the wall
    /// depth's are where they were, and every list stays in sample order.
    #[test]
    fn the_graded_padding_moves_the_splats_beyond_a_band_coarser_with_their_mass() {
        let wall_depth = 4u32;
        let finest = 7usize;
        let mut counts = vec![0u64; 1 << wall_depth];
        // Samples across x at every depth from the wall depth to the finest, every other one
        // splitting its mass between two depths.
        let positions: Vec<DVec3> = (0..400)
            .map(|i| DVec3::new((i as f64 + 0.5) / 400.0, 0.3 + 0.001 * i as f64, 0.5))
            .collect();
        let mut at_depth: Vec<Vec<DepthSample>> = vec![Vec::new(); finest + 1];
        for (i, p) in positions.iter().enumerate() {
            counts[(p.x * 16.0) as usize] += 1;
            let d = wall_depth as usize + i % (finest - wall_depth as usize + 1);
            let mass = 1.0 + i as f64;
            if d < finest && i % 2 == 0 {
                at_depth[d].push(DepthSample {
                    sample: i as u32,
                    mass: 0.25 * mass,
                });
                at_depth[d + 1].push(DepthSample {
                    sample: i as u32,
                    mass: 0.75 * mass,
                });
            } else {
                at_depth[d].push(DepthSample {
                    sample: i as u32,
                    mass,
                });
            }
        }
        let layout = SlabLayout::balanced(&counts, wall_depth, 4, 3);
        let mass_of = |at: &[Vec<DepthSample>]| {
            let mut m = vec![0.0f64; positions.len()];
            at.iter()
                .flatten()
                .for_each(|s| m[s.sample as usize] += s.mass);
            m
        };
        for k in 0..layout.len() {
            let padded = layout.padded(k);
            let mut graded: Vec<Vec<DepthSample>> = at_depth
                .iter()
                .map(|at| {
                    at.iter()
                        .copied()
                        .filter(|s| {
                            padded.contains(&layout.column_of(positions[s.sample as usize].x))
                        })
                        .collect()
                })
                .collect();
            let before = graded.clone();
            grade_padding(&mut graded, &positions, &layout, k, 2);
            for (after, was) in mass_of(&graded).iter().zip(mass_of(&before)) {
                assert!(
                    (after - was).abs() <= 1e-12 * was,
                    "slab {k}: a sample's mass"
                );
            }
            let owned = |s: &DepthSample| {
                layout.slab_of_column(layout.column_of(positions[s.sample as usize].x)) == k
            };
            let cell = |s: &DepthSample, d: usize| {
                (positions[s.sample as usize].x * (1u64 << d) as f64).floor() as i64
            };
            let mut moved = 0;
            for d in 0..=finest {
                assert!(graded[d].windows(2).all(|w| w[0].sample <= w[1].sample));
                let own_before: Vec<_> = before[d].iter().filter(|s| owned(s)).collect();
                let own_after: Vec<_> = graded[d].iter().filter(|s| owned(s)).collect();
                assert_eq!(
                    own_before, own_after,
                    "slab {k} depth {d}: the owned splats"
                );
                if d as u32 > wall_depth {
                    let band = layout.band(k, d as u32, 2);
                    assert!(graded[d].iter().all(|s| band.contains(&cell(s, d))));
                    moved += before[d]
                        .iter()
                        .filter(|s| !band.contains(&cell(s, d)))
                        .count();
                } else {
                    // At the wall depth and coarser, every splat stays (the wall depth gains).
                    let mut kept = graded[d].iter();
                    assert!(before[d].iter().all(|s| kept.any(|t| t == s)));
                }
            }
            assert!(moved > 0, "slab {k}: some splats lay beyond a band");
        }
    }
}

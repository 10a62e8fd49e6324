//! Trimming, after stage 9: the surface cut back to where the samples are.
//!
//! The reconstruction closes every hole of its input: where no sample is, it invents surface (a
//! lid over a scan's missing side, a skin around an open scene). The kernel density of §4.5
//! tells the two apart. At a point q it is W(q) = Σ_o count_o B_o(q) over the kernel-depth
//! nodes o (width h = 2^−D̂ of the cube), whose counts are the samples splatted trilinearly and
//! whose functions B_o are the degree-2 B-splines (`density.rs`). So
//!
//! * W is exactly 0 farther than 2.5 h (per axis) from every sample: a lid is cut away by any
//!   threshold above 0;
//! * on a surface sampled with ρ samples per unit area, W ≈ ρ h² B₄(0), with B₄ the quartic
//!   B-spline, so W is proportional to the local sampling density and a sparse region has
//!   proportionally lower W, not 0;
//! * across the edge of a sampled region W falls as the tail of B₄ (the trilinear hat
//!   convolved with the quadratic B-spline, across the edge): half its inside value at the last
//!   samples, about a quarter 0.4 h beyond them, a tenth at 0.8 h, 1 % at 1.5 h.
//!
//! Measured on the hemisphere of `tests/trim.rs` at depth 8, vertices binned by their distance
//! to the nearest sample: median W 11.5 within 0.1 h (the samples' own median is 11.5), 2.4 at
//! 0.5–1 h, 0.7 at 1–1.5 h, 0 beyond 2.5 h; with the sampling thinned tenfold on one side the
//! same profile scales down with the local density, and on the lion scan likewise.
//!
//! **The threshold.** [`Threshold::Automatic`] cuts at half the density below which 0.1 % of
//! the input samples lie (kept in [`crate::Stats::sample_density_quantiles`]). A sample whose
//! own density is at least the threshold keeps the surface around it; by construction at most
//! 0.1 % of the samples have less, so the cut takes away surface near at most 0.1 % of the
//! samples (stray points and the sparsest fringe of a scan). The sparsest regions' edges have
//! about that density (half their inside value), so the boundary runs about 0.4 h beyond them,
//! and beyond denser regions' edges at most where W falls to a few percent of their inside
//! value, about 1–1.5 h. A global reference from the samples' own densities makes the rule
//! scale-free (the same at every depth and for every unit) and keeps unevenly sampled parts.
//!
//! **The cut** is the level set {f = t} of the piecewise-linear interpolation f of the vertex
//! densities; the kept surface is {f ≥ t}.
//!
//! 1. *Signs.* A vertex is inside when f_v ≥ t and outside otherwise: a vertex exactly at t
//!    counts as inside, as if f_v were t + ε (simulation of simplicity), so the level set never
//!    passes through a vertex by accident and its two sides are decided by the vertices alone.
//! 2. *Snapping.* A crossing closer than [`SNAP`] of its edge's length to an end would leave a
//!    sliver; it is moved onto that end (as Raman & Wenger 2008 snap an isosurface's vertices
//!    onto grid vertices), closest first, when every vertex around stays manifold. Around a
//!    vertex the kept surface is made of its triangles' kept corners (polygons with area at the
//!    vertex), two consecutive corners glued when the edge between them keeps a piece at the
//!    vertex; a crossing moved onto a vertex can leave two corners touching at the vertex alone
//!    (at a saddle of the density), so a move is taken only when every vertex of the edge's two
//!    triangles still has at most one glued chain of corners. A crossing that cannot move is
//!    clamped to [`SNAP`] from the end instead, which keeps a neck of that width open.
//! 3. *Cut.* Every edge with an inside and an outside end gets one new vertex (unless its
//!    crossing moved onto an end), shared by the edge's two triangles, so the cut is
//!    watertight, with the position and density interpolated linearly. Each triangle keeps the
//!    polygon of its inside vertices and its crossings, in its own winding (so orientation is
//!    kept), ends that coincide merged: a triangle, or a quadrilateral split along the diagonal
//!    whose worse triangle is the better.
//! 4. *Pieces.* The connected pieces of what is kept; those smaller than the size rule are
//!    dropped ([`Trimming::min_piece_area`], [`Trimming::min_piece_triangles`]).
//!
//! Why the result is a manifold with boundary when the input is one: every kept edge lies in
//! the same one or two triangles as in the input (a piece of an input edge) or inside one
//! triangle (a contour segment or a diagonal), and the two triangles of an input edge agree on
//! its crossing, so no edge is used more than twice or twice in the same direction. An inside
//! vertex no crossing moved onto keeps the whole corner of each of its triangles (its fan is the
//! input's); a new vertex lies inside one edge, a half disc; every other kept vertex had a
//! crossing moved onto it and step 2 checked that its corners form one chain. Crossings left
//! inside their edges lie at least [`SNAP`] from the ends, so every new triangle keeps a
//! bounded share of its source's shape (`tests/trim.rs` measures the worst ratio: 0.18).
//!
//! Deterministic at any thread count: signs, crossings, polygons and areas are parallel maps,
//! the crossed edges sorted keys; the snapping runs sequentially over the crossings sorted by
//! distance then edge, and the pieces over the triangles in order.

use crate::attributes::{Channel, Colors};
use crate::components::vertex_components;
use crate::error::{Error, Result};
use crate::mesh::{Mesh, TrimReport};
use crate::parallel::{self, Watch};
use crate::pipeline::{Progress, Stage};
use crate::Workers;
use rayon::prelude::*;
use std::time::Instant;

/// Crossings closer than this fraction of an edge to an end are moved onto the end, or where
/// that would pinch a vertex, to this distance from it. A fifth keeps every piece of a cut
/// triangle within a bounded shape ratio of its source (see `tests/trim.rs`) while moving the
/// contour by at most a fifth of an edge.
pub const SNAP: f64 = 0.2;

/// [`Threshold::Automatic`]'s reference: the density below which this fraction of the input
/// samples lie (one in a thousand)...
const AUTOMATIC_QUANTILE: f64 = 0.001;
/// ...times this factor.
const AUTOMATIC_FACTOR: f64 = 0.5;

/// Where the surface is cut: every [`Threshold`] resolves to a density t, and the surface is
/// kept where its density is at least t.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Threshold {
    /// Half the density below which 0.1 % of the input samples lie
    /// ([`crate::Stats::sample_density_quantiles`]): the cut runs a little beyond the edges of
    /// the sparsest sampled regions and takes surface away from at most about 0.1 % of the
    /// samples. Needs a mesh from [`crate::reconstruct`]. The default.
    Automatic,
    /// An absolute density, in the unit of [`crate::Mesh::densities`] (samples per kernel-depth
    /// node, [`crate::Params::kernel_depth`]); finite and ≥ 0. 0 keeps everything.
    Density(f32),
    /// The lowest density below which at least the fraction q of the mesh's surface area lies
    /// (each vertex standing for a third of its triangles' area), q in [0, 1]: the cut removes
    /// about that fraction of the surface, more where many vertices share one density (a lid
    /// far from every sample has density 0 all over and goes as a whole). 0 keeps everything, 1
    /// nothing. Open3D's tutorial removes the vertices below a quantile of the vertex densities
    /// by count, which depends on how finely each part is tessellated.
    Quantile(f32),
    /// PoissonRecon's depth-like value d: the density 4^(d − D̂) (D̂ = [`crate::Stats::kernel_depth`]),
    /// i.e. the octree depth at which a node around the point would hold one sample: the
    /// formula of PoissonRecon's `--density` vertex value (its kernel depth plus log₄ of its
    /// density estimate). Range [0, 32]. PoissonRecon's SurfaceTrimmer `--trim d`. Its density
    /// kernel is normalised differently from psr's, so the same d may cut somewhat further in
    /// or out there (not measured: PoissonRecon is not installed here); the automatic threshold
    /// came out at 6.8–7.7 on the lion and Buddha scans at depths 8–10.
    Depth(f32),
}

/// Options of [`trim`]. `Trimming::default()` works (the automatic threshold, every piece
/// kept); set fields directly or with the `with_*` builders:
///
/// ```
/// let options = psr::Trimming::default()
///     .with_threshold(psr::Threshold::Depth(7.0))
///     .with_min_piece_area(0.01);
/// assert_eq!(options.min_piece_area, 0.01);
/// ```
///
/// New fields may be added in any release (the struct is `#[non_exhaustive]`), so build it from
/// `Trimming::default()`.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Trimming {
    /// Where to cut. Default [`Threshold::Automatic`].
    pub threshold: Threshold,
    /// Pieces left by the cut whose area is less than this fraction of the whole cut surface's
    /// area are dropped. Range [0, 1]. Default 0, every piece kept: the automatic threshold
    /// only keeps surface near samples, so its small pieces are small sampled parts (on the
    /// lion scan at depth 9, leaves and twigs: PoissonRecon's default 0.001 would drop 34 of
    /// its 53 pieces, which stand for about 2,000 samples, and raise the mean distance from the
    /// points to the mesh by 8 %). PoissonRecon's SurfaceTrimmer `--aRatio` (default 0.001
    /// there).
    pub min_piece_area: f32,
    /// Pieces of fewer triangles than this are dropped too. Default 0 (no rule). PoissonRecon:
    /// none.
    pub min_piece_triangles: u32,
    /// Worker threads; 0 = all cores. Default 0. The result does not depend on it.
    pub threads: usize,
}

impl Default for Trimming {
    fn default() -> Self {
        Trimming {
            threshold: Threshold::Automatic,
            min_piece_area: 0.0,
            min_piece_triangles: 0,
            threads: 0,
        }
    }
}

impl Trimming {
    /// These options with [`Trimming::threshold`] set to `threshold`.
    pub fn with_threshold(mut self, threshold: Threshold) -> Self {
        self.threshold = threshold;
        self
    }

    /// These options with [`Trimming::min_piece_area`] set to `min_piece_area`.
    pub fn with_min_piece_area(mut self, min_piece_area: f32) -> Self {
        self.min_piece_area = min_piece_area;
        self
    }

    /// These options with [`Trimming::min_piece_triangles`] set to `min_piece_triangles`.
    pub fn with_min_piece_triangles(mut self, min_piece_triangles: u32) -> Self {
        self.min_piece_triangles = min_piece_triangles;
        self
    }

    /// These options with [`Trimming::threads`] set to `threads`.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads;
        self
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<()> {
        fn bad(name: &'static str, value: impl ToString, expected: &'static str) -> Error {
            Error::InvalidParameter {
                name,
                value: value.to_string(),
                expected,
            }
        }
        match self.threshold {
            Threshold::Automatic => {}
            Threshold::Density(t) if !(t.is_finite() && t >= 0.0) => {
                return Err(bad(
                    "threshold",
                    format!("Density({t})"),
                    "a density that is finite and >= 0",
                ))
            }
            Threshold::Quantile(q) if !(q.is_finite() && (0.0..=1.0).contains(&q)) => {
                return Err(bad(
                    "threshold",
                    format!("Quantile({q})"),
                    "a quantile in [0, 1]",
                ))
            }
            Threshold::Depth(d) if !(d.is_finite() && (0.0..=32.0).contains(&d)) => {
                return Err(bad(
                    "threshold",
                    format!("Depth({d})"),
                    "a depth-like value in [0, 32]",
                ))
            }
            _ => {}
        }
        if !(self.min_piece_area.is_finite() && (0.0..=1.0).contains(&self.min_piece_area)) {
            return Err(bad(
                "min_piece_area",
                self.min_piece_area,
                "a fraction of the area in [0, 1]",
            ));
        }
        if self.threads > 4096 {
            return Err(bad(
                "threads",
                self.threads,
                "0 (all cores) or a count up to 4096",
            ));
        }
        Ok(())
    }
}

/// `mesh` cut back to where its density is at least the threshold `trimming` gives, small
/// pieces dropped: a mesh with boundary, manifold and consistently oriented when `mesh` is,
/// whose new vertices carry interpolated positions and densities. `mesh` is left as it is
/// (the untrimmed surface stays available); the result's [`crate::Stats::trim`] says what was
/// cut. Cutting everything away gives an empty mesh, not an error.
///
/// Errors: [`Error::InvalidParameter`] for options out of range, or for
/// [`Threshold::Automatic`] on a mesh without [`crate::Stats::sample_density_quantiles`];
/// [`Error::LengthMismatch`] when `mesh.densities` does not have one entry per vertex;
/// [`Error::InvalidMesh`] for a triangle naming a vertex that does not exist or a density that
/// is not finite; [`Error::TooLarge`] when the mesh, or the cut, has more vertices than `u32`
/// indices name; [`Error::ThreadsUnavailable`].
///
/// ```no_run
/// # let points = psr::PointSet::from_slices(&[[0.0, 0.0, 0.0]], &[[0.0, 0.0, 1.0]]).unwrap();
/// let mesh = psr::reconstruct(&points, &psr::Params::default())?;
/// let trimmed = psr::trim(&mesh, &psr::Trimming::default())?;
/// println!("cut at density {}", trimmed.stats.trim.as_ref().unwrap().density);
/// # Ok::<(), psr::Error>(())
/// ```
pub fn trim(mesh: &Mesh, trimming: &Trimming) -> Result<Mesh> {
    trim_with_progress(mesh, trimming, &mut |_, _| true)
}

/// [`trim`] with a progress callback that may cancel, as for a reconstruction
/// ([`crate::reconstruct_with_progress`]): it is called with [`Stage::Trim`] on the calling
/// thread while the cut runs on the worker threads, every 20 ms at most, with the fraction done,
/// and once with 1 at the end; when it returns `false` the cut stops at its next cancel point
/// (between its steps, each a parallel pass over the mesh) and the result is
/// `Err(Error::Cancelled)`. The trimmed mesh never depends on the callback.
pub fn trim_with_progress(
    mesh: &Mesh,
    trimming: &Trimming,
    progress: Progress<'_>,
) -> Result<Mesh> {
    trimming.validate()?;
    let workers = Workers::start(trimming.threads)?;
    let mut report = |fraction: f32| progress(Stage::Trim, fraction);
    if !report(0.0) {
        return Err(Error::Cancelled);
    }
    // Everything parallel runs in this call's own pool, the mesh's checks too: a rayon call
    // outside it would start rayon's global pool, whose threads outlive the call.
    let trimmed = parallel::watched(workers.pool(), &mut report, |watch| {
        check_mesh(mesh)?;
        watch.step(1, STEPS, 0.0, 1.0)?;
        cut(mesh, trimming, watch)
    })?;
    if report(1.0) {
        Ok(trimmed)
    } else {
        Err(Error::Cancelled)
    }
}

/// The steps of a trim between which it reports progress and may stop: the mesh's checks, the
/// threshold, the crossings, the snapping, the new vertices, the cut triangles, the pieces,
/// the renumbering and the carried per-vertex arrays.
const STEPS: usize = 9;

/// The checks [`trim`] makes of its mesh.
fn check_mesh(mesh: &Mesh) -> Result<()> {
    let n = mesh.positions.len();
    // Triangles name vertices with u32; the cut numbers them with u32 too.
    if n > u32::MAX as usize {
        return Err(Error::TooLarge {
            what: "mesh vertices",
            count: n,
            limit: u32::MAX as usize,
        });
    }
    if mesh.densities.len() != n {
        return Err(Error::LengthMismatch {
            what: "densities",
            positions: n,
            other: mesh.densities.len(),
        });
    }
    // The other per-vertex arrays are carried through the cut: each has a value per vertex
    // (the normals may also be absent).
    let lengths = [
        (
            "normals",
            if mesh.normals.is_empty() {
                n
            } else {
                mesh.normals.len()
            },
        ),
        ("colors", mesh.colors.as_ref().map_or(n, |c| c.len())),
    ]
    .into_iter()
    .chain(mesh.channels.iter().map(|c| ("channels", c.values.len())));
    for (what, other) in lengths {
        if other != n {
            return Err(Error::LengthMismatch {
                what,
                positions: n,
                other,
            });
        }
    }
    if let Some(i) = mesh.densities.par_iter().position_first(|d| !d.is_finite()) {
        return Err(Error::InvalidMesh(format!(
            "vertex {i} has the density {}, which is not finite",
            mesh.densities[i]
        )));
    }
    if let Some(i) = mesh
        .triangles
        .par_iter()
        .position_first(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(Error::InvalidMesh(format!(
            "triangle {i} is {:?} but the mesh has {n} vertices",
            mesh.triangles[i]
        )));
    }
    Ok(())
}

/// Vertex signs: below the threshold, or at or above it.
const OUT: u8 = 0;
const IN: u8 = 1;

/// Where a crossing is put: inside its edge (clamped to [`SNAP`, 1 − `SNAP`]), or onto its
/// inside or its outside end.
const INTERIOR: u8 = 0;
const AT_IN: u8 = 1;
const AT_OUT: u8 = 2;

/// The threshold `threshold` means for `mesh`, as a density.
fn resolve(threshold: Threshold, mesh: &Mesh) -> Result<f64> {
    Ok(match threshold {
        Threshold::Automatic => {
            let q = &mesh.stats.sample_density_quantiles;
            if q.len() < 2 {
                return Err(Error::InvalidParameter {
                    name: "threshold",
                    value: "Automatic".to_string(),
                    expected: "Density, Quantile or Depth for a mesh without \
                               Stats::sample_density_quantiles (one not made by reconstruct)",
                });
            }
            let index = ((q.len() - 1) as f64 * AUTOMATIC_QUANTILE).round() as usize;
            AUTOMATIC_FACTOR * q[index] as f64
        }
        Threshold::Density(t) => t as f64,
        Threshold::Depth(d) => (2.0 * (d as f64 - mesh.stats.kernel_depth as f64)).exp2(),
        Threshold::Quantile(q) => area_quantile(mesh, q as f64),
    })
}

/// The smallest vertex density t such that the vertices below t stand for at least the
/// fraction `q` of `mesh`'s area, each vertex standing for a third of the area of its
/// triangles; +∞ when only the whole area does (q = 1).
fn area_quantile(mesh: &Mesh, q: f64) -> f64 {
    let mut area = vec![0.0f64; mesh.positions.len()];
    let areas: Vec<f64> = mesh
        .triangles
        .par_iter()
        .map(|t| triangle_area(t.map(|v| f64x3(mesh.positions[v as usize]))))
        .collect();
    for (t, a) in mesh.triangles.iter().zip(&areas) {
        for &v in t {
            area[v as usize] += a / 3.0;
        }
    }
    let total: f64 = area.iter().sum();
    let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    order.par_sort_unstable_by(|&a, &b| {
        mesh.densities[a as usize]
            .total_cmp(&mesh.densities[b as usize])
            .then(a.cmp(&b))
    });
    // `below`: the area of the vertices of lower density than the current one.
    let (mut below, mut running) = (0.0, 0.0);
    let mut previous = f32::NEG_INFINITY;
    for &v in &order {
        let d = mesh.densities[v as usize];
        if d != previous {
            below = running;
            previous = d;
        }
        if below >= q * total && (q < 1.0 || below >= total) && d != f32::NEG_INFINITY {
            return d as f64;
        }
        running += area[v as usize];
    }
    f64::INFINITY
}

fn f64x3(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm2(a: [f64; 3]) -> f64 {
    a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
}

fn triangle_area([a, b, c]: [[f64; 3]; 3]) -> f64 {
    0.5 * norm2(cross(sub(b, a), sub(c, a))).sqrt()
}

/// A triangle's shape quality 4√3·area / Σ edge², 1 for an equilateral triangle and 0 for a
/// degenerate one.
pub(crate) fn quality(t: [[f64; 3]; 3]) -> f64 {
    let edges = norm2(sub(t[1], t[0])) + norm2(sub(t[2], t[1])) + norm2(sub(t[0], t[2]));
    if edges > 0.0 {
        4.0 * 3f64.sqrt() * triangle_area(t) / edges
    } else {
        0.0
    }
}

/// The key of the undirected edge {a, b}.
fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    ((lo as u64) << 32) | hi as u64
}

/// The triangles around one vertex v, in order: each as (triangle, a, b) where the triangle is
/// (v, a, b) in its winding, so that the next one counter-clockwise is (v, a', b') with
/// b' = a, and the edge between them (a "spoke") is v–a.
struct Fan {
    corners: Vec<(u32, u32, u32)>,
    closed: bool,
}

impl Fan {
    /// The fan of `v` from its incident triangles, or `None` when they do not form a single
    /// consistently oriented fan (a non-manifold vertex, or a triangle repeating an index).
    fn of(v: u32, incident: &[u32], triangles: &[[u32; 3]]) -> Option<Fan> {
        let mut corners = Vec::with_capacity(incident.len());
        for &ti in incident {
            let t = triangles[ti as usize];
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return None;
            }
            let k = t.iter().position(|&x| x == v)?;
            corners.push((ti, t[(k + 1) % 3], t[(k + 2) % 3]));
        }
        let k = corners.len();
        let unique = |mut ends: Vec<u32>| {
            ends.sort_unstable();
            ends.windows(2).all(|w| w[0] != w[1])
        };
        if k == 0
            || !unique(corners.iter().map(|c| c.1).collect())
            || !unique(corners.iter().map(|c| c.2).collect())
        {
            return None;
        }
        // Open fans start at the corner no other corner leads to; closed ones at the first.
        let start = (0..k)
            .find(|&i| !corners.iter().any(|c| c.1 == corners[i].2))
            .unwrap_or(0);
        let mut ordered = Vec::with_capacity(k);
        let mut at = start;
        loop {
            ordered.push(corners[at]);
            match corners.iter().position(|c| c.2 == corners[at].1) {
                Some(next) if next != start && ordered.len() < k => at = next,
                _ => break,
            }
        }
        if ordered.len() != k {
            return None;
        }
        let closed = ordered[k - 1].1 == ordered[0].2;
        Some(Fan {
            corners: ordered,
            closed,
        })
    }
}

/// The crossings of the level set with the mesh's edges and where each is put.
struct Crossings<'m> {
    mesh: &'m Mesh,
    t: f64,
    state: Vec<u8>,
    /// The crossed edges' keys, sorted.
    keys: Vec<u64>,
    /// Each crossing's parameter along its edge from the inside end, unclamped.
    s: Vec<f64>,
    /// Each crossing's place: [`INTERIOR`], [`AT_IN`] or [`AT_OUT`].
    place: Vec<u8>,
}

impl Crossings<'_> {
    fn index(&self, a: u32, b: u32) -> usize {
        self.keys
            .binary_search(&edge_key(a, b))
            .expect("every edge with an inside and an outside end is a crossing")
    }

    /// The inside and the outside end of crossing k.
    fn ends(&self, k: usize) -> (u32, u32) {
        let (a, b) = ((self.keys[k] >> 32) as u32, self.keys[k] as u32);
        if self.state[a as usize] == IN {
            (a, b)
        } else {
            (b, a)
        }
    }

    /// The output vertex of the crossing on edge {a, b}: one of its ends when snapped there,
    /// else new vertex n + k.
    fn point(&self, a: u32, b: u32) -> u32 {
        let k = self.index(a, b);
        match self.place[k] {
            AT_IN => self.ends(k).0,
            AT_OUT => self.ends(k).1,
            _ => {
                let id = self.mesh.positions.len() + k;
                debug_assert!(
                    id < u32::MAX as usize,
                    "checked when the crossings were made"
                );
                id as u32
            }
        }
    }

    /// The part of triangle `tri` at or above the threshold, as a polygon in the triangle's
    /// winding (its inside vertices and crossings, ends that coincide merged): up to 4
    /// vertices, fewer than 3 when nothing with area is kept.
    fn polygon(&self, tri: [u32; 3]) -> ([u32; 4], usize) {
        let mut polygon = [0u32; 4];
        let mut count = 0;
        let mut push = |v: u32| {
            if count == 0 || polygon[count - 1] != v {
                polygon[count] = v;
                count += 1;
            }
        };
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (sa, sb) = (self.state[a as usize], self.state[b as usize]);
            if sa == IN {
                push(a);
            }
            if sa != sb {
                push(self.point(a, b));
            }
        }
        if count > 1 && polygon[count - 1] == polygon[0] {
            count -= 1;
        }
        (polygon, count)
    }

    /// Whether the kept part of edge v–a contains a piece of the edge at v.
    fn spoke_kept(&self, v: u32, a: u32) -> bool {
        match (self.state[v as usize], self.state[a as usize]) {
            (IN, IN) => true,
            (IN, _) => self.place[self.index(v, a)] != AT_IN,
            (_, IN) => self.place[self.index(v, a)] == AT_OUT,
            _ => false,
        }
    }

    /// How many separate pieces of surface meet at `v` (its fan): kept corners (triangles whose
    /// kept polygon has area at v) glued to the next one around by a kept spoke. 1 or 0 for a
    /// manifold vertex; a fan kept all the way round is one piece.
    fn pieces_at(&self, v: u32, fan: &Fan) -> usize {
        let corner_kept: Vec<bool> = fan
            .corners
            .iter()
            .map(|&(ti, _, _)| {
                let (polygon, count) = self.polygon(self.mesh.triangles[ti as usize]);
                count >= 3 && polygon[..count].contains(&v)
            })
            .collect();
        let k = corner_kept.len();
        // Corner i is glued to corner i − 1 across spoke v–b_i (= v–a_{i−1}).
        let glued = |i: usize| {
            let previous = if i > 0 {
                Some(i - 1)
            } else {
                fan.closed.then_some(k - 1)
            };
            previous.is_some_and(|p| corner_kept[p] && self.spoke_kept(v, fan.corners[i].2))
        };
        let starts = (0..k).filter(|&i| corner_kept[i] && !glued(i)).count();
        if starts == 0 && corner_kept.iter().all(|&c| c) {
            1
        } else {
            starts
        }
    }
}

/// Puts crossings closer than [`SNAP`] to an end of their edge onto that end, closest first,
/// each only when every vertex around it stays manifold; returns how many moved and how many
/// could not (they stay inside their edge, clamped).
fn snap(crossings: &mut Crossings) -> (usize, usize) {
    let mesh = crossings.mesh;
    let n = mesh.positions.len();
    // The crossings near an end, with that end.
    let mut near: Vec<(f64, u64, usize, u8)> = crossings
        .s
        .par_iter()
        .enumerate()
        .filter_map(|(k, &s)| {
            if s < SNAP {
                Some((s, crossings.keys[k], k, AT_IN))
            } else if 1.0 - s < SNAP {
                Some((1.0 - s, crossings.keys[k], k, AT_OUT))
            } else {
                None
            }
        })
        .collect();
    if near.is_empty() {
        return (0, 0);
    }
    // The fans of the vertices crossings may move onto.
    let mut slot = vec![u32::MAX; n];
    let mut targets: Vec<u32> = near
        .iter()
        .map(|&(_, _, k, place)| {
            let (inside, outside) = crossings.ends(k);
            if place == AT_IN {
                inside
            } else {
                outside
            }
        })
        .collect();
    targets.sort_unstable();
    targets.dedup();
    for (i, &v) in targets.iter().enumerate() {
        slot[v as usize] = i as u32;
    }
    let mut start = vec![0u32; targets.len() + 1];
    for tri in &mesh.triangles {
        for &v in tri {
            if slot[v as usize] != u32::MAX {
                start[slot[v as usize] as usize + 1] += 1;
            }
        }
    }
    for i in 0..targets.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut incident = vec![0u32; start[targets.len()] as usize];
    for (ti, tri) in mesh.triangles.iter().enumerate() {
        for &v in tri {
            let s = slot[v as usize];
            if s != u32::MAX {
                incident[fill[s as usize] as usize] = ti as u32;
                fill[s as usize] += 1;
            }
        }
    }
    let fans: Vec<Option<Fan>> = targets
        .par_iter()
        .enumerate()
        .map(|(i, &v)| {
            Fan::of(
                v,
                &incident[start[i] as usize..start[i + 1] as usize],
                &mesh.triangles,
            )
        })
        .collect();
    let fan_of = |v: u32| match slot[v as usize] {
        u32::MAX => None,
        i => fans[i as usize].as_ref(),
    };

    // Closest first, ties by edge.
    near.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut snapped_to = vec![0u32; targets.len()];
    let mut moved = 0;
    let mut kept_apart = 0;
    for &(_, _, k, place) in &near {
        let (inside, outside) = crossings.ends(k);
        let (target, other) = if place == AT_IN {
            (inside, outside)
        } else {
            (outside, inside)
        };
        let Some(fan) = fan_of(target) else {
            kept_apart += 1;
            continue;
        };
        crossings.place[k] = place;
        snapped_to[slot[target as usize] as usize] += 1;
        // The vertices whose surroundings changed: those of the edge's triangles. Only those
        // with a crossing on them can have lost surface (any other inside vertex keeps the
        // whole corner of every triangle).
        let manifold = fan
            .corners
            .iter()
            .filter(|&&(_, a, b)| a == other || b == other)
            .all(|&(ti, _, _)| {
                mesh.triangles[ti as usize].iter().all(|&w| {
                    let s = slot[w as usize];
                    s == u32::MAX
                        || snapped_to[s as usize] == 0
                        || fans[s as usize]
                            .as_ref()
                            .is_some_and(|f| crossings.pieces_at(w, f) <= 1)
                })
            });
        if manifold {
            moved += 1;
        } else {
            crossings.place[k] = INTERIOR;
            snapped_to[slot[target as usize] as usize] -= 1;
            kept_apart += 1;
        }
    }
    (moved, kept_apart)
}

/// The cut itself (in the caller's pool).
fn cut(mesh: &Mesh, trimming: &Trimming, watch: &Watch) -> Result<Mesh> {
    let started = Instant::now();
    let step = |done: usize| watch.step(done, STEPS, 0.0, 1.0);
    let t = resolve(trimming.threshold, mesh)?;
    step(2)?;
    let n = mesh.positions.len();

    let f = |v: u32| mesh.densities[v as usize] as f64;

    // 1. Signs: inside when f ≥ t (a vertex at t is inside).
    let state: Vec<u8> = mesh
        .densities
        .par_iter()
        .map(|&d| if d as f64 >= t { IN } else { OUT })
        .collect();

    // The crossed edges, each once, in key order, with their parameters from the inside end.
    let mut keys: Vec<u64> = mesh
        .triangles
        .par_iter()
        .flat_map_iter(|tri| {
            let state = &state;
            (0..3).filter_map(move |k| {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                (state[a as usize] != state[b as usize]).then(|| edge_key(a, b))
            })
        })
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    // Every vertex id of the cut (old vertices, then one per crossing) fits in u32 below
    // u32::MAX (the renumbering's UNUSED): checked once here, so `point` and the renumbering
    // convert with `as` (debug-asserted).
    if n + keys.len() > u32::MAX as usize {
        return Err(Error::TooLarge {
            what: "vertices after the cut",
            count: n + keys.len(),
            limit: u32::MAX as usize,
        });
    }
    let s: Vec<f64> = keys
        .par_iter()
        .map(|&key| {
            let (a, b) = ((key >> 32) as u32, key as u32);
            let (p, m) = if state[a as usize] == IN {
                (a, b)
            } else {
                (b, a)
            };
            (f(p) - t) / (f(p) - f(m))
        })
        .collect();
    let mut crossings = Crossings {
        mesh,
        t,
        place: vec![INTERIOR; keys.len()],
        state,
        keys,
        s,
    };
    step(3)?;

    // 2. Snapping.
    let (snapped_crossings, clamped_crossings) = snap(&mut crossings);
    step(4)?;

    // 3. The new vertices of the crossings left inside their edges, clamped away from the
    // ends, with interpolated positions and densities (and, below, every other per-vertex
    // array); `new_edges` says where each lies: its edge's two ends and the parameter s.
    let new_edges: Vec<(u32, u32, f64)> = (0..crossings.keys.len())
        .into_par_iter()
        .map(|k| {
            let (p, m) = crossings.ends(k);
            (p, m, crossings.s[k].clamp(SNAP, 1.0 - SNAP))
        })
        .collect();
    let new_vertices: Vec<([f32; 3], f32)> = new_edges
        .par_iter()
        .map(|&(p, m, s)| {
            let (pp, pm) = (
                f64x3(mesh.positions[p as usize]),
                f64x3(mesh.positions[m as usize]),
            );
            let position = [0, 1, 2].map(|i| (pp[i] + s * (pm[i] - pp[i])) as f32);
            (position, (f(p) + s * (f(m) - f(p))) as f32)
        })
        .collect();
    step(5)?;
    let position = |v: u32| -> [f64; 3] {
        if (v as usize) < n {
            f64x3(mesh.positions[v as usize])
        } else {
            f64x3(new_vertices[v as usize - n].0)
        }
    };

    // Each triangle's kept polygon, triangulated, in triangle order.
    let crossings = &crossings;
    let pieces: Vec<[u32; 3]> = mesh
        .triangles
        .par_iter()
        .flat_map_iter(|&tri| {
            let mut out = [[0u32; 3]; 2];
            let repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2];
            let (polygon, corners) = if repeated {
                ([0; 4], 0)
            } else {
                crossings.polygon(tri)
            };
            let [p0, p1, p2, p3] = polygon;
            let count = match corners {
                3 => {
                    out[0] = [p0, p1, p2];
                    1
                }
                4 => {
                    let worse = |a: [u32; 3], b: [u32; 3]| {
                        quality(a.map(position)).min(quality(b.map(position)))
                    };
                    let (first, second) = ([p0, p1, p2], [p0, p2, p3]);
                    let (third, fourth) = ([p1, p2, p3], [p1, p3, p0]);
                    (out[0], out[1]) = if worse(third, fourth) > worse(first, second) {
                        (third, fourth)
                    } else {
                        (first, second)
                    };
                    2
                }
                _ => 0,
            };
            out.into_iter().take(count)
        })
        .collect();
    step(6)?;

    // 4. Pieces: components by shared vertices, their areas, the size rule.
    let vertices = n + crossings.keys.len();
    let component = vertex_components(vertices, &pieces);
    let areas: Vec<f64> = pieces
        .par_iter()
        .map(|p| triangle_area(p.map(position)))
        .collect();
    let mut piece_area = vec![0.0f64; vertices];
    let mut piece_triangles = vec![0u32; vertices];
    let mut roots = Vec::with_capacity(pieces.len());
    for (p, &a) in pieces.iter().zip(&areas) {
        let r = component[p[0] as usize];
        piece_area[r as usize] += a;
        piece_triangles[r as usize] += 1;
        roots.push(r);
    }
    let cut_area: f64 = areas.iter().sum();
    let small = |r: u32| {
        piece_area[r as usize] < trimming.min_piece_area as f64 * cut_area
            || piece_triangles[r as usize] < trimming.min_piece_triangles
    };
    let mut all_pieces = 0;
    let mut pieces_dropped = 0;
    for r in 0..vertices as u32 {
        if piece_triangles[r as usize] > 0 {
            all_pieces += 1;
            pieces_dropped += small(r) as usize;
        }
    }

    step(7)?;

    // 5. The vertices the kept triangles use, renumbered in order (old vertices, then new).
    const UNUSED: u32 = u32::MAX;
    let mut index = vec![UNUSED; vertices];
    let mut triangles = Vec::with_capacity(pieces.len());
    let mut area_after = 0.0;
    for ((p, &r), &a) in pieces.iter().zip(&roots).zip(&areas) {
        if !small(r) {
            triangles.push(*p);
            area_after += a;
            for &v in p {
                index[v as usize] = 0;
            }
        }
    }
    let mut kept = Vec::new();
    for (v, slot) in index.iter_mut().enumerate() {
        if *slot != UNUSED {
            // v < vertices ≤ u32::MAX, checked with the crossings.
            debug_assert!(v < u32::MAX as usize);
            *slot = kept.len() as u32;
            kept.push(v as u32);
        }
    }
    triangles
        .par_iter_mut()
        .for_each(|tri| *tri = tri.map(|v| index[v as usize]));
    let (positions, densities): (Vec<[f32; 3]>, Vec<f32>) = kept
        .par_iter()
        .map(|&v| {
            if (v as usize) < n {
                (mesh.positions[v as usize], mesh.densities[v as usize])
            } else {
                new_vertices[v as usize - n]
            }
        })
        .unzip();

    let area_before: f64 = mesh
        .triangles
        .par_iter()
        .map(|tri| triangle_area(tri.map(|v| f64x3(mesh.positions[v as usize]))))
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    step(8)?;
    // Every other per-vertex array, `width` values a vertex, carried the same way.
    let carry = |values: &[f32], width: usize| -> Vec<f32> {
        kept.par_iter()
            .flat_map_iter(|&v| {
                let v = v as usize;
                let value: Vec<f32> = if v < n {
                    values[v * width..(v + 1) * width].to_vec()
                } else {
                    let (p, m, s) = new_edges[v - n];
                    let (p, m) = (p as usize * width, m as usize * width);
                    (0..width)
                        .map(|i| {
                            let (a, b) = (values[p + i] as f64, values[m + i] as f64);
                            (a + s * (b - a)) as f32
                        })
                        .collect()
                };
                value
            })
            .collect()
    };
    let normals: Vec<[f32; 3]> = if mesh.normals.len() == n {
        carry(mesh.normals.as_flattened(), 3)
            .chunks_exact(3)
            .map(|c| {
                let length = (c[0] as f64).hypot(c[1] as f64).hypot(c[2] as f64);
                if length > 0.0 {
                    [c[0], c[1], c[2]].map(|x| (x as f64 / length) as f32)
                } else {
                    [c[0], c[1], c[2]]
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    let colors = mesh.colors.as_ref().map(|colors| {
        let width = colors.components();
        Colors::from_flattened(width, &carry(colors.as_flattened(), width))
    });
    let channels: Vec<Channel> = mesh
        .channels
        .iter()
        .map(|c| Channel::new(c.name.clone(), carry(&c.values, 1)))
        .collect();

    let mut stats = mesh.stats.clone();
    stats.trim = Some(TrimReport {
        density: crossings.t,
        depth: mesh.stats.kernel_depth as f64 + 0.5 * t.log2(),
        snapped_crossings,
        clamped_crossings,
        pieces: all_pieces,
        pieces_dropped,
        area_before,
        area_after,
        seconds: started.elapsed().as_secs_f64(),
    });
    Ok(Mesh {
        positions,
        origin: mesh.origin,
        triangles,
        densities,
        stats,
        normals,
        colors,
        channels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves fans are ordered around their vertex, closed or open, and that a vertex where
    /// two fans meet (a bowtie) or a triangle repeats an index has none.
    #[test]
    fn fans_are_ordered_and_bowties_have_none() {
        // Vertex 0 surrounded by 1..=4, counter-clockwise: a closed fan of four.
        let closed = vec![[0, 1, 2], [0, 3, 4], [0, 2, 3], [0, 4, 1]];
        let fan = Fan::of(0, &[0, 1, 2, 3], &closed).expect("a fan");
        assert!(fan.closed);
        // Each corner's next neighbour is the following corner's previous one.
        for (i, corner) in fan.corners.iter().enumerate() {
            assert_eq!(fan.corners[(i + 1) % 4].2, corner.1);
        }
        // Without one triangle it is open and starts after the gap.
        let open = Fan::of(0, &[0, 1, 2], &closed).expect("an open fan");
        assert!(!open.closed);
        assert_eq!(open.corners[0].0, 1, "starts at the triangle after the gap");
        // Two triangles touching at vertex 0 only.
        let bowtie = vec![[0, 1, 2], [0, 3, 4]];
        assert!(Fan::of(0, &[0, 1], &bowtie).is_none());
        let repeated = vec![[0, 1, 1]];
        assert!(Fan::of(0, &[0], &repeated).is_none());
    }

    /// Proves the quality measure: 1 for an equilateral triangle, 0 for a degenerate one.
    #[test]
    fn quality_of_equilateral_and_degenerate_triangles() {
        let h = 3f64.sqrt() / 2.0;
        let equilateral = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, h, 0.0]];
        assert!((quality(equilateral) - 1.0).abs() < 1e-12);
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(quality(flat), 0.0);
    }
}

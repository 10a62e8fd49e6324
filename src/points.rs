//! Stage 1 — points: copy and validate the input, and map it into the unit cube.
//!
//! Positions must be finite; normals finite and non-zero (they are stored normalised, so a
//! normal's length never weighs a sample); confidence weights, when given, finite and ≥ 0. The
//! bounding box of the positions, enlarged by `scale` about its centre, is mapped onto `[0,1]³`
//! by a uniform scale, and the inverse map takes mesh vertices back to input coordinates.
//!
//! Positions may be given in `f64` ([`PointSet::extend_f64`], [`PointSet::extend_transformed`]):
//! the set then keeps them as given beside their `f32` rounding, the unit cube is fitted to and
//! the samples mapped from the `f64` values, so that a cloud far from the origin (georeferenced
//! coordinates, 10⁶ m away) loses nothing to `f32`'s resolution there. A set given only `f32`
//! positions stores nothing more and computes exactly what it did before.
//!
//! A set may also carry attributes, the same for every point: colours and named float channels
//! (finite values; see [`crate::attributes`] for how they reach the mesh).

use crate::attributes::{Channel, Colors, PointAttributes};
use crate::error::{Error, Result};
use crate::grid::{cell_of, morton_nested};
use glam::DVec3;
use rayon::prelude::*;

/// Oriented input points: positions, unit normals, optional confidence weights, and optional
/// attributes carried onto the mesh (colours, named channels).
///
/// Appending validates the whole batch first and appends nothing when any entry is bad, so a
/// failed batch never leaves half of itself behind.
///
/// ```
/// use psr::{Colors, PointSet};
/// let points = PointSet::from_slices(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], &[[0.0, 0.0, 1.0]; 2])?
///     .with_colors(Colors::Rgb(vec![[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))?
///     .with_channel("intensity", vec![0.25, 0.75])?;
/// assert_eq!(points.channels()[0].name, "intensity");
/// # Ok::<(), psr::Error>(())
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointSet {
    /// The positions (rounded to `f32` when given in `f64`).
    positions: Vec<[f32; 3]>,
    /// The positions as given, once any batch came in `f64`: every point's, the `f32` ones
    /// widened exactly. `None` on the `f32` path, which then costs nothing more.
    positions_f64: Option<Vec<[f64; 3]>>,
    normals: Vec<[f32; 3]>,
    /// Per-point confidence (PoissonRecon `--confidence`); `None` means all 1.
    weights: Option<Vec<f32>>,
    /// Colours and channels, one value each per point.
    attributes: PointAttributes,
}

impl PointSet {
    /// An empty set.
    pub fn new() -> Self {
        PointSet::default()
    }

    /// A set holding the given points (validated, normals normalised).
    pub fn from_slices(positions: &[[f32; 3]], normals: &[[f32; 3]]) -> Result<Self> {
        let mut set = PointSet::new();
        set.extend(positions, normals)?;
        Ok(set)
    }

    /// Appends a batch of points with unit confidence. On error nothing is appended and the
    /// error names the first bad index *within this batch*.
    pub fn extend(&mut self, positions: &[[f32; 3]], normals: &[[f32; 3]]) -> Result<()> {
        self.extend_weighted(positions, normals, None)
    }

    /// Appends a batch of points with optional per-point confidence weights (finite, ≥ 0).
    /// A set that carries colours or channels takes new points through [`PointSet::append`]
    /// only (they must bring theirs).
    pub fn extend_weighted(
        &mut self,
        positions: &[[f32; 3]],
        normals: &[[f32; 3]],
        weights: Option<&[f32]>,
    ) -> Result<()> {
        self.check_batch(positions.len(), normals.len(), weights)?;
        let unit_normals = validate_batch(positions, normals, weights)?;
        let old_len = self.positions.len();
        self.positions.extend_from_slice(positions);
        if let Some(exact) = &mut self.positions_f64 {
            exact.extend(positions.iter().map(|p| p.map(f64::from)));
        }
        self.push_normals_and_weights(old_len, unit_normals, weights);
        Ok(())
    }

    /// A set holding the given points, positions in `f64` (validated, normals normalised): see
    /// [`PointSet::extend_f64`].
    pub fn from_slices_f64(positions: &[[f64; 3]], normals: &[[f32; 3]]) -> Result<Self> {
        let mut set = PointSet::new();
        set.extend_f64(positions, normals)?;
        Ok(set)
    }

    /// Appends a batch of points whose positions are `f64`, with unit confidence. The set keeps
    /// the positions as given (and their `f32` rounding for [`PointSet::positions`]); the
    /// reconstruction maps them into the unit cube from the `f64` values, and its mesh has
    /// vertices relative to a [`crate::Mesh::origin`] near them, so that coordinates far from
    /// 0 (a georeferenced scan 10⁶ m away) keep the precision of the object's own size.
    /// Coordinates must be finite and within `f32`'s range (|c| < 3.4·10³⁸), else
    /// [`Error::NonFinitePosition`]. Memory: 24 more bytes per point, for every point of the
    /// set, once any batch came in `f64`.
    pub fn extend_f64(&mut self, positions: &[[f64; 3]], normals: &[[f32; 3]]) -> Result<()> {
        self.extend_weighted_f64(positions, normals, None)
    }

    /// [`PointSet::extend_f64`] with optional per-point confidence weights (finite, ≥ 0), as
    /// [`PointSet::extend_weighted`].
    pub fn extend_weighted_f64(
        &mut self,
        positions: &[[f64; 3]],
        normals: &[[f32; 3]],
        weights: Option<&[f32]>,
    ) -> Result<()> {
        self.check_batch(positions.len(), normals.len(), weights)?;
        let unit_normals = validate_batch(positions, normals, weights)?;
        self.push_f64(positions, unit_normals, weights);
        Ok(())
    }

    /// Appends a batch of points placed by an affine `transform` (row-major 4×4: the position
    /// `p` becomes `M·p + t` with `M = transform[0..3][0..3]` and `t` its last column), computed
    /// in `f64`; normals are transformed by `M`'s inverse transpose and renormalised, so they
    /// stay normal to the surface under shears and non-uniform scales (and outward under a
    /// reflection). The result is kept like [`PointSet::extend_f64`]'s. For registering scans
    /// (each with its pose) and placing local coordinates in a georeferenced frame;
    /// PoissonRecon's `--xForm`.
    ///
    /// The transform must be finite, affine (last row exactly `0 0 0 1`) and invertible (`M`'s
    /// determinant not 0 relative to its rows' lengths), else [`Error::InvalidTransform`];
    /// positions or normals bad before or after it are reported as by [`PointSet::extend`].
    /// On error nothing is appended.
    pub fn extend_transformed(
        &mut self,
        positions: &[[f64; 3]],
        normals: &[[f32; 3]],
        transform: &[[f64; 4]; 4],
    ) -> Result<()> {
        self.extend_transformed_weighted(positions, normals, None, transform)
    }

    /// [`PointSet::extend_transformed`] with optional per-point confidence weights (finite,
    /// ≥ 0), as [`PointSet::extend_weighted`].
    pub fn extend_transformed_weighted(
        &mut self,
        positions: &[[f64; 3]],
        normals: &[[f32; 3]],
        weights: Option<&[f32]>,
        transform: &[[f64; 4]; 4],
    ) -> Result<()> {
        self.check_batch(positions.len(), normals.len(), weights)?;
        let affine = Affine::new(transform)?;
        // The inputs themselves first, so that a bad entry is named before the transform
        // could hide it (a huge coordinate scaled down, a NaN anywhere).
        validate_batch(positions, normals, weights)?;
        let moved: Vec<[f64; 3]> = positions.iter().map(|&p| affine.point(p)).collect();
        let turned: Vec<[f32; 3]> = normals.iter().map(|&n| affine.normal(n)).collect();
        let unit_normals = validate_batch(&moved, &turned, weights)?;
        self.push_f64(&moved, unit_normals, weights);
        Ok(())
    }

    /// The checks every batch shares: lengths agree, and the set carries no attributes (a set
    /// with attributes takes new points through [`PointSet::append`] only).
    fn check_batch(&self, len: usize, normals: usize, weights: Option<&[f32]>) -> Result<()> {
        if self.attributes.width() > 0 && len > 0 {
            return Err(Error::AttributesDiffer {
                set: self.attributes.describe(),
                batch: PointAttributes::default().describe(),
            });
        }
        if normals != len {
            return Err(Error::LengthMismatch {
                what: "normals",
                positions: len,
                other: normals,
            });
        }
        if let Some(w) = weights {
            if w.len() != len {
                return Err(Error::LengthMismatch {
                    what: "weights",
                    positions: len,
                    other: w.len(),
                });
            }
        }
        Ok(())
    }

    /// Appends a validated batch of `f64` positions, widening the set's positions to `f64`
    /// first if they were all `f32` until now (exactly).
    fn push_f64(
        &mut self,
        positions: &[[f64; 3]],
        unit_normals: Vec<[f32; 3]>,
        weights: Option<&[f32]>,
    ) {
        let old_len = self.positions.len();
        let f32s = &self.positions;
        let exact = self
            .positions_f64
            .get_or_insert_with(|| f32s.iter().map(|p| p.map(f64::from)).collect());
        exact.extend_from_slice(positions);
        self.positions
            .extend(positions.iter().map(|p| p.map(|c| c as f32)));
        self.push_normals_and_weights(old_len, unit_normals, weights);
    }

    /// Appends a validated batch's normals and weights to a set that had `old_len` points.
    fn push_normals_and_weights(
        &mut self,
        old_len: usize,
        unit_normals: Vec<[f32; 3]>,
        weights: Option<&[f32]>,
    ) {
        self.normals.extend(unit_normals);
        match (weights, &mut self.weights) {
            (Some(w), Some(existing)) => existing.extend_from_slice(w),
            (Some(w), None) => {
                let mut all = vec![1.0; old_len];
                all.extend_from_slice(w);
                self.weights = Some(all);
            }
            (None, Some(existing)) => existing.resize(self.positions.len(), 1.0),
            (None, None) => {}
        }
    }

    /// These points with per-point colours, one per point (RGB or RGBA, finite, in any scale:
    /// the mesh's colours are weighted means of them). Replaces colours given before.
    pub fn with_colors(mut self, colors: Colors) -> Result<Self> {
        PointAttributes::check_colors(&colors, self.len())?;
        self.attributes.colors = Some(colors);
        Ok(self)
    }

    /// These points with one more named channel, one finite value per point. The name must be
    /// new to the set, non-empty and without whitespace (it becomes a PLY property name).
    pub fn with_channel(mut self, name: impl Into<String>, values: Vec<f32>) -> Result<Self> {
        let channel = Channel::new(name, values);
        self.attributes.check_channel(&channel, self.len())?;
        self.attributes.channels.push(channel);
        Ok(self)
    }

    /// Appends the points of `other` with their weights and attributes. Unless this set is
    /// empty (then it takes `other`'s attributes), `other` must carry the same attributes
    /// (colours of the same kind, the same channels in the same order); otherwise nothing is
    /// appended.
    pub fn append(&mut self, other: PointSet) -> Result<()> {
        if self.is_empty() {
            *self = other;
            return Ok(());
        }
        if !self.attributes.same_layout(&other.attributes) {
            return Err(Error::AttributesDiffer {
                set: self.attributes.describe(),
                batch: other.attributes.describe(),
            });
        }
        let old_len = self.len();
        match (other.positions_f64, &mut self.positions_f64) {
            (Some(theirs), Some(ours)) => ours.extend(theirs),
            (Some(theirs), None) => {
                let mut all: Vec<[f64; 3]> =
                    self.positions.iter().map(|p| p.map(f64::from)).collect();
                all.extend(theirs);
                self.positions_f64 = Some(all);
            }
            (None, Some(ours)) => ours.extend(other.positions.iter().map(|p| p.map(f64::from))),
            (None, None) => {}
        }
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        match (other.weights, &mut self.weights) {
            (Some(w), Some(existing)) => existing.extend(w),
            (Some(w), None) => {
                let mut all = vec![1.0; old_len];
                all.extend(w);
                self.weights = Some(all);
            }
            (None, Some(existing)) => existing.resize(self.positions.len(), 1.0),
            (None, None) => {}
        }
        self.attributes.append(other.attributes);
        Ok(())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The positions, in input coordinates (rounded to `f32` when they were given in `f64`:
    /// see [`PointSet::positions_f64`]).
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// The positions in `f64`, as given, when any batch was given in `f64`
    /// ([`PointSet::extend_f64`], [`PointSet::extend_transformed`]; `f32` batches widened
    /// exactly); `None` when every position came in `f32`.
    pub fn positions_f64(&self) -> Option<&[[f64; 3]]> {
        self.positions_f64.as_deref()
    }

    /// The normals, normalised to unit length.
    pub fn normals(&self) -> &[[f32; 3]] {
        &self.normals
    }

    /// The confidence weights, if any were given.
    pub fn weights(&self) -> Option<&[f32]> {
        self.weights.as_deref()
    }

    /// The colours, if given.
    pub fn colors(&self) -> Option<&Colors> {
        self.attributes.colors.as_ref()
    }

    /// The named channels, in the order given.
    pub fn channels(&self) -> &[Channel] {
        &self.attributes.channels
    }

    /// The colours and channels.
    pub(crate) fn attributes(&self) -> &PointAttributes {
        &self.attributes
    }

    /// Removes every point, with its weights, colours and channels.
    pub fn clear(&mut self) {
        self.positions.clear();
        self.positions_f64 = None;
        self.normals.clear();
        self.weights = None;
        self.attributes = PointAttributes::default();
    }
}

/// `n` scaled to unit length (in f64, rounded to f32), or `None` when it has no length to
/// scale (zero, or too small to trust: at most 1e-20) or is not finite.
pub(crate) fn unit_normal(n: [f32; 3]) -> Option<[f32; 3]> {
    let n64 = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    let len = n64.length();
    if !len.is_finite() || len <= 1e-20 {
        return None;
    }
    let u = n64 / len;
    Some([u.x as f32, u.y as f32, u.z as f32])
}

/// Checks one batch and returns its normals normalised.
/// Positions are `f32` or `f64`; an `f64` coordinate must also be finite once rounded to `f32`
/// (within its range), since the set keeps that rounding too.
fn validate_batch<T: Copy + Into<f64>>(
    positions: &[[T; 3]],
    normals: &[[f32; 3]],
    weights: Option<&[f32]>,
) -> Result<Vec<[f32; 3]>> {
    let mut unit = Vec::with_capacity(normals.len());
    for (index, (p, n)) in positions.iter().zip(normals).enumerate() {
        if !p.iter().all(|&c| (c.into() as f32).is_finite()) {
            return Err(Error::NonFinitePosition { index });
        }
        if !n.iter().all(|c| c.is_finite()) {
            return Err(Error::NonFiniteNormal { index });
        }
        unit.push(unit_normal(*n).ok_or(Error::ZeroNormal { index })?);
        if let Some(w) = weights {
            if !(w[index].is_finite() && w[index] >= 0.0) {
                return Err(Error::InvalidWeight { index });
            }
        }
    }
    Ok(unit)
}

/// A validated affine transform (see [`PointSet::extend_transformed`]): the 3×3 part, its
/// translation, and the matrix that takes normals (the cofactors of the 3×3 part, signed by its
/// determinant: its inverse transpose up to a positive factor, which renormalising removes).
struct Affine {
    m: [[f64; 3]; 3],
    t: [f64; 3],
    normal: [[f64; 3]; 3],
}

impl Affine {
    fn new(transform: &[[f64; 4]; 4]) -> Result<Affine> {
        let refuse = |reason: &'static str| Err(Error::InvalidTransform { reason });
        if !transform.iter().flatten().all(|c| c.is_finite()) {
            return refuse("it has a NaN or infinite entry");
        }
        if transform[3] != [0.0, 0.0, 0.0, 1.0] {
            return refuse(
                "its last row is not 0 0 0 1 (a projective transform, not an affine one)",
            );
        }
        let m = [0, 1, 2].map(|r| [transform[r][0], transform[r][1], transform[r][2]]);
        let t = [0, 1, 2].map(|r| transform[r][3]);
        // Cofactor matrix C: C[r][c] = the (r, c) cofactor; M's inverse is Cᵀ / det.
        let cof = |r: usize, c: usize| {
            let (r0, r1) = ((r + 1) % 3, (r + 2) % 3);
            let (c0, c1) = ((c + 1) % 3, (c + 2) % 3);
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        let c = [0, 1, 2].map(|r| [0, 1, 2].map(|col| cof(r, col)));
        let det = m[0][0] * c[0][0] + m[0][1] * c[0][1] + m[0][2] * c[0][2];
        let rows: f64 = m
            .iter()
            .map(|row| row.iter().map(|v| v * v).sum::<f64>().sqrt())
            .product();
        // Entries near f64's limit can overflow the products to ∞ and ∞ − ∞ to NaN: refused too.
        if det.is_nan() || det.abs() <= 1e-12 * rows {
            return refuse(
                "its 3×3 part is singular (it flattens space onto a plane, a line or a point)",
            );
        }
        let sign = det.signum();
        let normal = c.map(|row| row.map(|v| v * sign));
        Ok(Affine { m, t, normal })
    }

    /// M·p + t.
    fn point(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2]
            .map(|r| self.m[r][0] * p[0] + self.m[r][1] * p[1] + self.m[r][2] * p[2] + self.t[r])
    }

    /// M⁻ᵀ·n up to a positive factor (normalised later, with the other normals).
    fn normal(&self, n: [f32; 3]) -> [f32; 3] {
        let n = n.map(f64::from);
        let v = [0, 1, 2].map(|r| {
            self.normal[r][0] * n[0] + self.normal[r][1] * n[1] + self.normal[r][2] * n[2]
        });
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        // Normalised here so that a large matrix does not overflow f32; a length of 0 (a zero
        // normal in) stays 0 and is refused as one.
        let s = if len > 0.0 { 1.0 / len } else { 0.0 };
        v.map(|c| (c * s) as f32)
    }
}

/// The bounding box of positions, gathered in parts ([`UnitCubeMap::fit_bounds`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Bounds {
    pub(crate) lo: DVec3,
    pub(crate) hi: DVec3,
}

impl Default for Bounds {
    /// The empty box.
    fn default() -> Self {
        Bounds {
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
        }
    }
}

impl Bounds {
    /// Grows the box to hold `positions`.
    pub(crate) fn extend(&mut self, positions: impl IntoIterator<Item = DVec3>) {
        for v in positions {
            self.lo = self.lo.min(v);
            self.hi = self.hi.max(v);
        }
    }

    /// Grows the box to hold `other` (nothing when `other` is empty).
    pub(crate) fn join(&mut self, other: &Bounds) {
        self.lo = self.lo.min(other.lo);
        self.hi = self.hi.max(other.hi);
    }
}

/// The similarity that maps input coordinates into the unit cube: `unit = (p − origin) / size`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitCubeMap {
    /// Input-space corner that maps to (0,0,0).
    pub origin: DVec3,
    /// Input-space edge length of the cube.
    pub size: f64,
}

impl UnitCubeMap {
    /// The cube centred on the bounding box of `positions`, with edge `scale` × its longest side.
    /// A degenerate box (one point, or all points on a plane or a line) still gets a cube: its
    /// size falls back to the longest side, then to a size relative to the coordinates.
    pub fn fit(positions: &[[f32; 3]], scale: f64) -> Self {
        Self::fit_to(
            positions.iter().map(|p| DVec3::from(p.map(f64::from))),
            scale,
        )
    }

    /// [`UnitCubeMap::fit`] for `f64` positions.
    pub fn fit_f64(positions: &[[f64; 3]], scale: f64) -> Self {
        Self::fit_to(positions.iter().map(|&p| DVec3::from(p)), scale)
    }

    fn fit_to(positions: impl Iterator<Item = DVec3>, scale: f64) -> Self {
        let mut bounds = Bounds::default();
        bounds.extend(positions);
        Self::fit_bounds(&bounds, scale)
    }

    /// [`UnitCubeMap::fit`] from the bounding box of the positions, gathered by
    /// [`Bounds::extend`] in any number of parts (the out-of-core scan reads its input in
    /// chunks): the same map as the positions fitted at once.
    pub(crate) fn fit_bounds(bounds: &Bounds, scale: f64) -> Self {
        let (lo, hi) = (bounds.lo, bounds.hi);
        let extent = (hi - lo).max_element();
        let magnitude = lo.abs().max(hi.abs()).max_element();
        // A zero extent (all points coincide) gets a cube a little larger than f32 resolution at
        // that magnitude, so the octree still has room for the samples' neighbourhoods.
        let base = if extent > 0.0 {
            extent
        } else {
            (magnitude * 1e-4).max(1e-6)
        };
        let size = base * scale;
        let origin = (lo + hi) * 0.5 - DVec3::splat(size * 0.5);
        UnitCubeMap { origin, size }
    }

    /// Input coordinates → unit cube.
    pub fn to_unit(self, p: [f32; 3]) -> DVec3 {
        (DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - self.origin) / self.size
    }

    /// [`UnitCubeMap::to_unit`] for an `f64` position.
    pub fn to_unit_f64(self, p: [f64; 3]) -> DVec3 {
        (DVec3::from(p) - self.origin) / self.size
    }

    /// Unit cube → input coordinates.
    pub fn to_input(self, q: DVec3) -> DVec3 {
        q * self.size + self.origin
    }

    /// A point near the cube for `f32` coordinates to be relative to (see
    /// [`crate::Mesh::origin`]): its centre rounded to a multiple of the smallest power of two
    /// at least its size `s`, so within `s` of every point of the cube (a vertex relative to it
    /// keeps `f32`'s relative precision, 6·10⁻⁸, of about 2`s`), a round number, and 0 when the
    /// cube is within `s`/2 of 0 anyway.
    pub fn nearby_origin(self) -> DVec3 {
        let grid = self.size.log2().ceil().exp2();
        let centre = self.origin + DVec3::splat(self.size * 0.5);
        (centre / grid).round() * grid
    }
}

/// The samples in unit-cube coordinates, in Morton order of their cells at the requested depth
/// (so also at every coarser depth; ties in input order): the samples of a cell, and of
/// neighbouring cells mostly, are neighbours in memory for every stage that reads them by cell.
pub(crate) struct Samples {
    pub(crate) positions: Vec<DVec3>,
    /// Unit normals (the point set's), until splatted.
    pub(crate) normals: Vec<[f32; 3]>,
    /// Confidence weights (all 1 unless given).
    pub(crate) confidence: Vec<f64>,
    /// The points' colours and channels, [`PointAttributes::width`] values per sample (empty
    /// when the points carry none).
    pub(crate) attributes: Vec<f32>,
}

impl Samples {
    /// The points mapped by `map`, in Morton order at `depth`. Refuses inputs no surface can be
    /// placed in: every weight zero, or every point at one position.
    pub(crate) fn in_morton_order(
        points: &PointSet,
        map: &UnitCubeMap,
        depth: u32,
    ) -> Result<Samples> {
        // Samples are named by u32 indices from here on (the Morton order, the density's and the
        // attributes' per-depth lists): checked once.
        if points.len() > u32::MAX as usize {
            return Err(Error::TooLarge {
                what: "points",
                count: points.len(),
                limit: u32::MAX as usize,
            });
        }
        let inv_h = (depth as f64).exp2();
        let unit: Vec<DVec3> = match points.positions_f64() {
            Some(exact) => exact.par_iter().map(|&p| map.to_unit_f64(p)).collect(),
            None => points
                .positions()
                .par_iter()
                .map(|&p| map.to_unit(p))
                .collect(),
        };
        let mut order: Vec<(u64, u32)> = unit
            .par_iter()
            .enumerate()
            .map(|(s, &p)| {
                let c = cell_of(p, inv_h);
                (morton_nested(c.map(|v| v.max(0) as u32)), s as u32)
            })
            .collect();
        order.par_sort_unstable();
        let samples = Samples {
            positions: order.par_iter().map(|&(_, s)| unit[s as usize]).collect(),
            normals: order
                .par_iter()
                .map(|&(_, s)| points.normals()[s as usize])
                .collect(),
            confidence: match points.weights() {
                Some(w) => order
                    .par_iter()
                    .map(|&(_, s)| w[s as usize] as f64)
                    .collect(),
                None => vec![1.0; points.len()],
            },
            attributes: {
                let attributes = points.attributes();
                let width = attributes.width();
                let mut values = vec![0.0; points.len() * width];
                if width > 0 {
                    values
                        .par_chunks_mut(width)
                        .zip(order.par_iter())
                        .for_each(|(out, &(_, s))| attributes.write_point(s as usize, out));
                }
                values
            },
        };
        if samples.confidence.iter().all(|&c| c == 0.0) {
            return Err(Error::NoPositiveWeight);
        }
        let coincide = match points.positions_f64() {
            Some(exact) => exact.iter().all(|p| *p == exact[0]),
            None => points
                .positions()
                .iter()
                .all(|p| *p == points.positions()[0]),
        };
        if coincide {
            return Err(Error::DegenerateInput {
                points: points.len(),
            });
        }
        Ok(samples)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_entries_with_their_index_and_appends_nothing() {
        let mut set = PointSet::from_slices(&[[0.0; 3]], &[[0.0, 0.0, 2.0]]).unwrap();
        assert_eq!(set.normals()[0], [0.0, 0.0, 1.0]);
        let bad = set.extend(&[[0.0; 3], [f32::NAN, 0.0, 0.0]], &[[1.0, 0.0, 0.0]; 2]);
        assert_eq!(bad, Err(Error::NonFinitePosition { index: 1 }));
        assert_eq!(set.len(), 1);
        assert_eq!(
            set.extend(&[[0.0; 3]], &[[0.0; 3]]),
            Err(Error::ZeroNormal { index: 0 })
        );
        assert_eq!(
            set.extend(&[[0.0; 3]], &[[f32::INFINITY, 0.0, 0.0]]),
            Err(Error::NonFiniteNormal { index: 0 })
        );
        assert!(matches!(
            set.extend(&[[0.0; 3]; 2], &[[1.0, 0.0, 0.0]]),
            Err(Error::LengthMismatch { .. })
        ));
        assert_eq!(set.len(), 1);
    }

    #[test]
    fn unit_cube_map_round_trips_and_centres_the_box() {
        let pts = [[1.0, 2.0, 3.0], [3.0, 2.5, 3.5]];
        let map = UnitCubeMap::fit(&pts, 1.1);
        assert!((map.size - 2.2).abs() < 1e-12);
        let c = map.to_unit([2.0, 2.25, 3.25]);
        assert!((c - DVec3::splat(0.5)).length() < 1e-12);
        let back = map.to_input(map.to_unit(pts[1]));
        assert!((back - DVec3::new(3.0, 2.5, 3.5)).length() < 1e-12);
    }

    /// Proves: a transformed normal stays perpendicular to the transformed surface under a
    /// shear and a non-uniform scale (the inverse transpose), and outward under a reflection.
    #[test]
    fn transformed_normals_stay_normal_and_outward() {
        let shear = [
            [2.0, 1.0, 0.0, 5.0],
            [0.0, 1.0, 0.0, -3.0],
            [0.0, 0.0, 0.5, 1e6],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let affine = Affine::new(&shear).unwrap();
        // The plane x + y = 1 with normal (1, 1, 0)/√2; two tangents.
        let n = affine.normal([
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::FRAC_1_SQRT_2,
            0.0,
        ]);
        for t in [[1.0, -1.0, 0.0], [0.0, 0.0, 1.0]] {
            let (a, b) = (affine.point([0.0; 3]), affine.point(t));
            let moved = [0, 1, 2].map(|k| b[k] - a[k]);
            let dot: f64 = (0..3).map(|k| moved[k] * n[k] as f64).sum();
            assert!(dot.abs() < 1e-6, "{dot}");
        }
        assert_eq!(affine.point([1.0, 1.0, 1.0]), [8.0, -2.0, 1e6 + 0.5]);
        let mirror = [
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let affine = Affine::new(&mirror).unwrap();
        assert_eq!(affine.point([1.0, 0.0, 0.0]), [-1.0, 0.0, 0.0]);
        assert_eq!(affine.normal([1.0, 0.0, 0.0]), [-1.0, 0.0, 0.0]);
    }

    /// Proves: f32 and f64 batches mix in one set, the f32 ones widened exactly, and a set
    /// given only f32 keeps no f64 copy.
    #[test]
    fn f32_and_f64_batches_mix() {
        let mut set = PointSet::from_slices(&[[0.5, 0.0, 0.0]], &[[1.0, 0.0, 0.0]]).unwrap();
        assert!(set.positions_f64().is_none());
        set.extend_f64(&[[1e6 + 0.125, 0.0, 0.1]], &[[1.0, 0.0, 0.0]])
            .unwrap();
        set.extend(&[[2.0, 0.0, 0.0]], &[[1.0, 0.0, 0.0]]).unwrap();
        assert_eq!(
            set.positions_f64().unwrap(),
            &[[0.5, 0.0, 0.0], [1e6 + 0.125, 0.0, 0.1], [2.0, 0.0, 0.0]]
        );
        assert_eq!(set.positions()[1], [1e6 + 0.125, 0.0, 0.1f64 as f32]);
        let mut other = PointSet::from_slices(&[[3.0, 0.0, 0.0]], &[[1.0, 0.0, 0.0]]).unwrap();
        other.append(set.clone()).unwrap();
        assert_eq!(other.positions_f64().unwrap().len(), 4);
        set.clear();
        assert!(set.positions_f64().is_none());
    }

    #[test]
    fn degenerate_boxes_still_get_a_cube() {
        let map = UnitCubeMap::fit(&[[5.0, 5.0, 5.0]; 3], 1.1);
        assert!(map.size > 0.0);
        let c = map.to_unit([5.0, 5.0, 5.0]);
        assert!((c - DVec3::splat(0.5)).length() < 1e-9);
    }
}

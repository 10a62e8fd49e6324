//! Stage 1 — points: copy and validate the input, and map it into the unit cube.
//!
//! Positions must be finite; normals finite and non-zero (they are stored normalised, so a
//! normal's length never weighs a sample); confidence weights, when given, finite and ≥ 0. The
//! bounding box of the positions, enlarged by `scale` about its centre, is mapped onto `[0,1]³`
//! by a uniform scale, and the inverse map takes mesh vertices back to input coordinates.
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
    positions: Vec<[f32; 3]>,
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
        if self.attributes.width() > 0 && !positions.is_empty() {
            return Err(Error::AttributesDiffer {
                set: self.attributes.describe(),
                batch: PointAttributes::default().describe(),
            });
        }
        if normals.len() != positions.len() {
            return Err(Error::LengthMismatch {
                what: "normals",
                positions: positions.len(),
                other: normals.len(),
            });
        }
        if let Some(w) = weights {
            if w.len() != positions.len() {
                return Err(Error::LengthMismatch {
                    what: "weights",
                    positions: positions.len(),
                    other: w.len(),
                });
            }
        }
        let unit_normals = validate_batch(positions, normals, weights)?;
        let old_len = self.positions.len();
        self.positions.extend_from_slice(positions);
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
        Ok(())
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

    /// The positions, in input coordinates.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
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
        self.normals.clear();
        self.weights = None;
        self.attributes = PointAttributes::default();
    }
}

/// Checks one batch and returns its normals normalised.
fn validate_batch(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    weights: Option<&[f32]>,
) -> Result<Vec<[f32; 3]>> {
    let mut unit = Vec::with_capacity(normals.len());
    for (index, (p, n)) in positions.iter().zip(normals).enumerate() {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(Error::NonFinitePosition { index });
        }
        if !n.iter().all(|c| c.is_finite()) {
            return Err(Error::NonFiniteNormal { index });
        }
        let n64 = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
        let len = n64.length();
        if len.is_nan() || len <= 1e-20 {
            return Err(Error::ZeroNormal { index });
        }
        let u = n64 / len;
        unit.push([u.x as f32, u.y as f32, u.z as f32]);
        if let Some(w) = weights {
            if !(w[index].is_finite() && w[index] >= 0.0) {
                return Err(Error::InvalidWeight { index });
            }
        }
    }
    Ok(unit)
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
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in positions {
            let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            lo = lo.min(v);
            hi = hi.max(v);
        }
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

    /// Unit cube → input coordinates.
    pub fn to_input(self, q: DVec3) -> DVec3 {
        q * self.size + self.origin
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
        let inv_h = (depth as f64).exp2();
        let unit: Vec<DVec3> = points
            .positions()
            .par_iter()
            .map(|&p| map.to_unit(p))
            .collect();
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
        let first = points.positions()[0];
        if points.positions().iter().all(|p| *p == first) {
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

    #[test]
    fn degenerate_boxes_still_get_a_cube() {
        let map = UnitCubeMap::fit(&[[5.0, 5.0, 5.0]; 3], 1.1);
        assert!(map.size > 0.0);
        let c = map.to_unit([5.0, 5.0, 5.0]);
        assert!((c - DVec3::splat(0.5)).length() < 1e-9);
    }
}

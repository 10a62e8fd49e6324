//! Attributes: per-point colours and named float channels carried onto the mesh's vertices, and
//! the vertex normals from ∇χ (both part of stage 9, the mesh).
//!
//! **The field.** An attribute is splatted like the normals (§4.2, §4.5): every sample s puts
//! its value a_s, weighted, at each of its one or two depths d, with the same mass m_{s,d} the
//! normals get there (its area 1/W(s) × its confidence × its share of depth d, see
//! [`crate::density`]), and the value at a point q is the weighted mean
//!
//! ```text
//!     a(q) = Σ_d Σ_s w_{s,d}(q) a_s / Σ_d Σ_s w_{s,d}(q),
//!     w_{s,d}(q) = m_{s,d} · B((q − s)/h_d) · max(0, n_s · n_q),
//! ```
//!
//! where B(t) = b(t_x) b(t_y) b(t_z) is the degree-2 B-spline of the node functions (support
//! ±1.5 node widths h_d = 2^−d, so a sample reaches as far at its depth as its normal's splat
//! does) and n_q the unit outward normal of the surface at q (∇χ/|∇χ|, which extraction
//! computes at every vertex anyway). The area weight keeps dense regions from outweighing
//! sparse ones; the depth makes the kernel as wide as the local sample spacing, so every vertex
//! near the samples sees several of them and colour detail is kept down to that spacing.
//!
//! **No bleeding across thin walls.** The two faces of a wall thinner than the kernel (or two
//! surfaces facing each other across a thin gap) have opposite normals. The factor
//! max(0, n_s · n_q) gives a sample no weight at a vertex whose surface faces away from it, so
//! one face never colours the other (PoissonRecon's data field has no such factor, a known
//! complaint). It also fades samples of a surface meeting the vertex's at a sharp edge.
//!
//! **Holes.** A vertex that no sample reaches with positive weight (surface Poisson invented
//! across a hole, the cap on the bounding cube, which has no normal) takes the mean of its
//! mesh neighbours that have a value, ring by ring inward from the rim of the hole, so holes
//! are coloured from their rims along the surface, never through the air. A part of the mesh
//! that no sample reaches at all takes the area-weighted mean of all samples.
//!
//! **Cost.** Nothing when the points carry no attributes (and no vertex normals were asked
//! for). Otherwise proportional to the output: the vertices are visited in Morton order, and
//! for each depth the samples of the few cells of the next coarser depth around a vertex are
//! found by binary search among that depth's samples (which are in Morton order already) and
//! reused by the following vertices in the same cells. Each vertex's sums run in a fixed order
//! (depths coarse to fine, cells, samples in order), so the result does not depend on the
//! number of threads; the hole filling reads only the previous ring, so neither does it.

use crate::density::DepthSample;
use crate::error::{Error, Result};
use crate::grid::{cell_of, morton_nested, KeyMap};
use glam::DVec3;
use rayon::prelude::*;

/// Colours of points or vertices: red, green, blue and optionally alpha, as floats.
///
/// psr treats colours as numbers it averages, so any scale works (0–1 or 0–255); the mesh's
/// colours are weighted means of the points', so they keep that scale and stay within the
/// range of the input. [`crate::ply`] reads and writes them scaled to 0–1.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Colors {
    /// Red, green, blue.
    Rgb(Vec<[f32; 3]>),
    /// Red, green, blue, alpha.
    Rgba(Vec<[f32; 4]>),
}

impl Colors {
    /// Number of colours (points or vertices).
    pub fn len(&self) -> usize {
        match self {
            Colors::Rgb(c) => c.len(),
            Colors::Rgba(c) => c.len(),
        }
    }

    /// True when there are no colours.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Components per colour: 3 (RGB) or 4 (RGBA).
    pub fn components(&self) -> usize {
        match self {
            Colors::Rgb(_) => 3,
            Colors::Rgba(_) => 4,
        }
    }

    /// The components of every colour one after the other (r, g, b, and a when RGBA; then
    /// the next colour's).
    pub fn as_flattened(&self) -> &[f32] {
        match self {
            Colors::Rgb(c) => c.as_flattened(),
            Colors::Rgba(c) => c.as_flattened(),
        }
    }

    /// Colours with `components` (3 or 4) components each from their flattened values.
    pub(crate) fn from_flattened(components: usize, values: &[f32]) -> Colors {
        if components == 4 {
            Colors::Rgba(
                values
                    .chunks_exact(4)
                    .map(|c| [c[0], c[1], c[2], c[3]])
                    .collect(),
            )
        } else {
            Colors::Rgb(values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        }
    }

    /// "RGB" or "RGBA".
    fn kind(&self) -> &'static str {
        match self {
            Colors::Rgb(_) => "RGB",
            Colors::Rgba(_) => "RGBA",
        }
    }
}

/// A named float value per point or vertex (intensity, a label probability, a scalar field…),
/// carried onto the mesh like the colours.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Channel {
    /// The channel's name (what the PLY property is called).
    pub name: String,
    /// One value per point or vertex.
    pub values: Vec<f32>,
}

impl Channel {
    /// A channel named `name` with `values`.
    pub fn new(name: impl Into<String>, values: Vec<f32>) -> Self {
        Channel {
            name: name.into(),
            values,
        }
    }
}

/// The colours and channels of a point set, kept beside its positions and normals.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct PointAttributes {
    pub(crate) colors: Option<Colors>,
    pub(crate) channels: Vec<Channel>,
}

impl PointAttributes {
    /// Values per point: colour components, then one per channel.
    pub(crate) fn width(&self) -> usize {
        self.colors.as_ref().map_or(0, Colors::components) + self.channels.len()
    }

    /// Words for error messages: "no colours or channels", "colors (RGB), channels [a, b]".
    pub(crate) fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(c) = &self.colors {
            parts.push(format!("colors ({})", c.kind()));
        }
        if !self.channels.is_empty() {
            let names: Vec<&str> = self.channels.iter().map(|c| c.name.as_str()).collect();
            parts.push(format!("channels [{}]", names.join(", ")));
        }
        if parts.is_empty() {
            "no colours or channels".to_string()
        } else {
            parts.join(", ")
        }
    }

    /// True when `other` carries the same colours (kind) and channels (names, in order).
    pub(crate) fn same_layout(&self, other: &PointAttributes) -> bool {
        self.colors.as_ref().map(Colors::components)
            == other.colors.as_ref().map(Colors::components)
            && self.channels.len() == other.channels.len()
            && self
                .channels
                .iter()
                .zip(&other.channels)
                .all(|(a, b)| a.name == b.name)
    }

    /// Writes point `i`'s values (colour components, then channels) into `out` (`width()` long).
    pub(crate) fn write_point(&self, i: usize, out: &mut [f32]) {
        let mut k = 0;
        match &self.colors {
            Some(Colors::Rgb(c)) => {
                out[..3].copy_from_slice(&c[i]);
                k = 3;
            }
            Some(Colors::Rgba(c)) => {
                out[..4].copy_from_slice(&c[i]);
                k = 4;
            }
            None => {}
        }
        for (slot, channel) in out[k..].iter_mut().zip(&self.channels) {
            *slot = channel.values[i];
        }
    }

    /// Appends `other`'s values (same layout, checked by the caller).
    pub(crate) fn append(&mut self, other: PointAttributes) {
        match (&mut self.colors, other.colors) {
            (Some(Colors::Rgb(a)), Some(Colors::Rgb(b))) => a.extend(b),
            (Some(Colors::Rgba(a)), Some(Colors::Rgba(b))) => a.extend(b),
            _ => {}
        }
        for (a, b) in self.channels.iter_mut().zip(other.channels) {
            a.values.extend(b.values);
        }
    }

    /// Checks colours for `points` points (length, finite values).
    pub(crate) fn check_colors(colors: &Colors, points: usize) -> Result<()> {
        if colors.len() != points {
            return Err(Error::AttributeLength {
                attribute: "colors".into(),
                points,
                values: colors.len(),
            });
        }
        let components = colors.components();
        if let Some(at) = colors.as_flattened().iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFiniteAttribute {
                attribute: "colors".into(),
                index: at / components,
            });
        }
        Ok(())
    }

    /// Checks a new channel for `points` points against the channels already present.
    pub(crate) fn check_channel(&self, channel: &Channel, points: usize) -> Result<()> {
        check_channel_name(&channel.name)?;
        if self.channels.iter().any(|c| c.name == channel.name) {
            return Err(Error::InvalidChannelName {
                name: channel.name.clone(),
                reason: "is given twice",
            });
        }
        if channel.values.len() != points {
            return Err(Error::AttributeLength {
                attribute: channel.name.clone(),
                points,
                values: channel.values.len(),
            });
        }
        if let Some(index) = channel.values.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFiniteAttribute {
                attribute: channel.name.clone(),
                index,
            });
        }
        Ok(())
    }
}

/// A channel name must be something a PLY header (and a C string) can hold as one word.
fn check_channel_name(name: &str) -> Result<()> {
    let reason = if name.is_empty() {
        "is empty"
    } else if name.chars().any(|c| c.is_whitespace() || c.is_control()) {
        "holds whitespace or control characters"
    } else {
        return Ok(());
    };
    Err(Error::InvalidChannelName {
        name: name.to_string(),
        reason,
    })
}

/// What the vertex evaluation reads about the samples, all in Morton order at `key_depth`.
pub(crate) struct SampleField<'a> {
    /// Unit-cube positions.
    pub(crate) positions: &'a [DVec3],
    /// Unit normals.
    pub(crate) normals: &'a [[f32; 3]],
    /// `width` values per sample.
    pub(crate) values: &'a [f32],
    pub(crate) width: usize,
    /// Each sample's weight for the fallback mean of a part no sample reaches (area ×
    /// confidence).
    pub(crate) weights: Vec<f64>,
    /// The samples at each depth, in sample order (as [`crate::density::samples_by_depth`]
    /// makes them).
    pub(crate) at_depth: &'a [Vec<DepthSample>],
    /// The depth of the Morton order the samples are in.
    pub(crate) key_depth: u32,
}

/// Vertices per parallel task: fixed, though nothing here sums across vertices.
const VERTEX_CHUNK: usize = 2048;

/// One depth's samples grouped by the cell of the next coarser depth (a bucket) they lie in.
struct DepthSamples<'a> {
    inv_h: f64,
    /// The depth of the buckets: one coarser than the samples' (0 at depth 0), so that the
    /// 3×3×3 buckets around a vertex's bucket hold every sample whose kernel reaches it.
    bucket_depth: u32,
    /// Node widths h_d per bucket: 2 (or 1 at depth 0).
    bucket_width: f64,
    /// Each bucket's range of `entries`, by the bucket's Morton key.
    buckets: KeyMap<(u32, u32)>,
    entries: &'a [DepthSample],
}

impl<'a> DepthSamples<'a> {
    /// Groups `entries` (in sample order, so in Morton order at `key_depth`) by bucket.
    fn new(field: &SampleField<'a>, depth: u32, entries: &'a [DepthSample]) -> Self {
        let bucket_depth = depth.saturating_sub(1);
        let shift = 3 * (field.key_depth - bucket_depth);
        let key_inv_h = (field.key_depth as f64).exp2();
        let keys: Vec<u64> = entries
            .par_iter()
            .map(|e| sample_key(field.positions[e.sample as usize], key_inv_h) >> shift)
            .collect();
        let mut buckets = KeyMap::default();
        let mut start = 0;
        for k in 1..=keys.len() {
            if k == keys.len() || keys[k] != keys[start] {
                buckets.insert(keys[start], (start as u32, k as u32));
                start = k;
            }
        }
        DepthSamples {
            inv_h: (depth as f64).exp2(),
            bucket_depth,
            bucket_width: ((depth - bucket_depth) as f64).exp2(),
            buckets,
            entries,
        }
    }
}

/// The buckets around one vertex's bucket at one depth, kept while the following vertices fall
/// in the same bucket: (bucket coordinates, range of the depth's entries).
#[derive(Default)]
struct Window {
    bucket: Option<[i64; 3]>,
    ranges: Vec<([i64; 3], u32, u32)>,
}

/// Each vertex's attribute values (`field.width` per vertex) at `vertices` (unit cube) with
/// outward unit `normals` (zero where unknown), the holes filled from their rims along
/// `triangles`.
pub(crate) fn at_vertices(
    field: &SampleField<'_>,
    vertices: &[DVec3],
    normals: &[DVec3],
    triangles: &[[u32; 3]],
) -> Vec<f32> {
    let width = field.width;
    let depths: Vec<DepthSamples<'_>> = field
        .at_depth
        .iter()
        .enumerate()
        .filter(|(_, entries)| !entries.is_empty())
        .map(|(d, entries)| DepthSamples::new(field, d as u32, entries))
        .collect();

    // Vertices in Morton order, so that consecutive ones share their cells at every depth.
    let key_inv_h = (field.key_depth as f64).exp2();
    let mut order: Vec<(u64, u32)> = vertices
        .par_iter()
        .enumerate()
        .map(|(i, &v)| (sample_key(v, key_inv_h), i as u32))
        .collect();
    order.par_sort_unstable();

    let mut sorted = vec![0.0f32; vertices.len() * width];
    let mut reached = vec![false; vertices.len()];
    sorted
        .par_chunks_mut(VERTEX_CHUNK * width.max(1))
        .zip(reached.par_chunks_mut(VERTEX_CHUNK))
        .zip(order.par_chunks(VERTEX_CHUNK))
        .for_each(|((out, reached), chunk)| {
            let mut windows: Vec<Window> = depths.iter().map(|_| Window::default()).collect();
            let mut sum = vec![0.0f64; width];
            for (k, &(_, v)) in chunk.iter().enumerate() {
                let total = vertex_sum(
                    field,
                    &depths,
                    &mut windows,
                    vertices[v as usize],
                    normals[v as usize],
                    &mut sum,
                );
                if total > 0.0 {
                    reached[k] = true;
                    for (o, s) in out[k * width..(k + 1) * width].iter_mut().zip(&sum) {
                        *o = (s / total) as f32;
                    }
                }
            }
        });

    let mut values = vec![0.0f32; vertices.len() * width];
    let mut known = vec![false; vertices.len()];
    for (k, &(_, v)) in order.iter().enumerate() {
        let v = v as usize;
        values[v * width..(v + 1) * width].copy_from_slice(&sorted[k * width..(k + 1) * width]);
        known[v] = reached[k];
    }
    fill_from_rims(&mut values, &mut known, width, triangles);
    if known.iter().any(|k| !k) {
        let mean = weighted_mean(field);
        for (v, _) in known.iter().enumerate().filter(|(_, k)| !**k) {
            values[v * width..(v + 1) * width].copy_from_slice(&mean);
        }
    }
    values
}

/// The Morton key at the depth of `inv_h` of a unit-cube point's cell (as the samples are
/// sorted: coordinates below 0 clamped to 0).
fn sample_key(p: DVec3, inv_h: f64) -> u64 {
    let c = cell_of(p, inv_h);
    morton_nested(c.map(|v| v.max(0) as u32))
}

/// Σ w a (into `sum`) and Σ w (returned) for one vertex at `q` with normal `n`.
fn vertex_sum(
    field: &SampleField<'_>,
    depths: &[DepthSamples<'_>],
    windows: &mut [Window],
    q: DVec3,
    n: DVec3,
    sum: &mut [f64],
) -> f64 {
    sum.fill(0.0);
    let mut total = 0.0;
    if n == DVec3::ZERO {
        return 0.0;
    }
    for (depth, window) in depths.iter().zip(windows.iter_mut()) {
        // q's bucket, and the samples of the 27 buckets around it (those within ±1.5 node
        // widths of q are in them: a bucket is two node widths wide).
        let t = q * depth.inv_h;
        let at = (t / depth.bucket_width).floor();
        let bucket = [at.x as i64, at.y as i64, at.z as i64];
        if window.bucket != Some(bucket) {
            window.bucket = Some(bucket);
            window.ranges.clear();
            let last = 1i64 << depth.bucket_depth; // (inclusive: a sample at 1.0 clamps there)
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let b = [bucket[0] + dx, bucket[1] + dy, bucket[2] + dz];
                        if b.iter().any(|&v| v < 0 || v > last) {
                            continue;
                        }
                        let key = morton_nested(b.map(|v| v as u32));
                        if let Some(&(start, end)) = depth.buckets.get(&key) {
                            window.ranges.push((b, start, end));
                        }
                    }
                }
            }
        }
        for &(b, start, end) in &window.ranges {
            // Skip a bucket wholly beyond the kernel's reach.
            let near = (0..3).all(|a| {
                let lo = b[a] as f64 * depth.bucket_width;
                t[a] > lo - 1.5 && t[a] < lo + depth.bucket_width + 1.5
            });
            if !near {
                continue;
            }
            for e in &depth.entries[start as usize..end as usize] {
                let s = e.sample as usize;
                let offset = (q - field.positions[s]) * depth.inv_h;
                if offset.abs().max_element() >= 1.5 {
                    continue;
                }
                let ns = field.normals[s];
                let facing = n.x * ns[0] as f64 + n.y * ns[1] as f64 + n.z * ns[2] as f64;
                if facing <= 0.0 {
                    continue;
                }
                let kernel = crate::bspline::value(offset.x)
                    * crate::bspline::value(offset.y)
                    * crate::bspline::value(offset.z);
                let w = e.mass * kernel * facing;
                if w > 0.0 {
                    total += w;
                    let a = &field.values[s * field.width..(s + 1) * field.width];
                    for (acc, &v) in sum.iter_mut().zip(a) {
                        *acc += w * v as f64;
                    }
                }
            }
        }
    }
    total
}

/// Gives every vertex that is not `known` the mean of its known neighbours, ring by ring inward
/// from the known ones (each ring reads only the rings before it, so the order within a ring
/// does not matter).
fn fill_from_rims(values: &mut [f32], known: &mut [bool], width: usize, triangles: &[[u32; 3]]) {
    let n = known.len();
    if known.iter().all(|&k| k) || width == 0 {
        return;
    }
    // Neighbours of each vertex (each edge twice on a closed mesh, which weighs all alike).
    let mut start = vec![0u32; n + 1];
    for t in triangles {
        for &v in t {
            start[v as usize + 1] += 2;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut next = start.clone();
    let mut neighbours = vec![0u32; start[n] as usize];
    for t in triangles {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            for other in [b, c] {
                neighbours[next[a as usize] as usize] = other;
                next[a as usize] += 1;
            }
        }
    }
    let around = |v: usize| &neighbours[start[v] as usize..start[v + 1] as usize];
    let mut ring: Vec<u32> = (0..n as u32)
        .filter(|&v| !known[v as usize] && around(v as usize).iter().any(|&u| known[u as usize]))
        .collect();
    let mut queued = vec![false; n];
    while !ring.is_empty() {
        let fresh: Vec<f32> = ring
            .par_iter()
            .flat_map_iter(|&v| {
                let mut sum = vec![0.0f64; width];
                let mut count = 0u32;
                for &u in around(v as usize) {
                    if known[u as usize] {
                        count += 1;
                        let a = &values[u as usize * width..(u as usize + 1) * width];
                        for (s, &x) in sum.iter_mut().zip(a) {
                            *s += x as f64;
                        }
                    }
                }
                sum.into_iter().map(move |s| (s / count as f64) as f32)
            })
            .collect();
        for (k, &v) in ring.iter().enumerate() {
            let v = v as usize;
            values[v * width..(v + 1) * width].copy_from_slice(&fresh[k * width..(k + 1) * width]);
            known[v] = true;
        }
        let mut following = Vec::new();
        for &v in &ring {
            for &u in around(v as usize) {
                if !known[u as usize] && !queued[u as usize] {
                    queued[u as usize] = true;
                    following.push(u);
                }
            }
        }
        following.sort_unstable();
        ring = following;
    }
}

/// The mean of every sample's values weighted by its area × confidence (in sample order).
fn weighted_mean(field: &SampleField<'_>) -> Vec<f32> {
    let width = field.width;
    let mut sum = vec![0.0f64; width];
    let mut total = 0.0;
    for (s, &w) in field.weights.iter().enumerate() {
        total += w;
        for (acc, &v) in sum
            .iter_mut()
            .zip(&field.values[s * width..(s + 1) * width])
        {
            *acc += w * v as f64;
        }
    }
    sum.iter()
        .map(|s| if total > 0.0 { (s / total) as f32 } else { 0.0 })
        .collect()
}

/// Unit outward vertex normals: ∇χ/|∇χ| where extraction gave one; elsewhere (the cap on the
/// bounding cube, where χ is not defined beyond the face) the area-weighted mean of the normals
/// of the triangles around the vertex (zero only around degenerate triangles).
pub(crate) fn vertex_normals(
    vertices: &[DVec3],
    normals: &[DVec3],
    triangles: &[[u32; 3]],
) -> Vec<[f32; 3]> {
    let mut out: Vec<DVec3> = normals.to_vec();
    if out.contains(&DVec3::ZERO) {
        let missing: Vec<bool> = out.iter().map(|n| *n == DVec3::ZERO).collect();
        for t in triangles {
            let [a, b, c] = t.map(|i| i as usize);
            if !(missing[a] || missing[b] || missing[c]) {
                continue;
            }
            // Twice the area times the unit normal; counter-clockwise seen from outside.
            let face = (vertices[b] - vertices[a]).cross(vertices[c] - vertices[a]);
            for v in [a, b, c] {
                if missing[v] {
                    out[v] += face;
                }
            }
        }
        for (n, m) in out.iter_mut().zip(&missing) {
            if *m {
                *n = n.normalize_or_zero();
            }
        }
    }
    out.iter()
        .map(|n| [n.x as f32, n.y as f32, n.z as f32])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples on both faces of a plate much thinner than a cell (red on top, facing +z, blue
    /// below, facing −z): vertices on either face take their own face's colour alone, though
    /// the kernel reaches across; without the orientation factor they would mix about half and
    /// half.
    #[test]
    fn a_thin_plate_does_not_bleed_between_its_faces() {
        let depth = 6;
        let h = 1.0 / 64.0;
        let gap = 0.1 * h;
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut values = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (0.3 + i as f64 * h * 0.5, 0.3 + j as f64 * h * 0.5);
                positions.push(DVec3::new(x, y, 0.5 + gap / 2.0));
                normals.push([0.0, 0.0, 1.0]);
                values.extend([1.0f32, 0.0, 0.0]);
                positions.push(DVec3::new(x, y, 0.5 - gap / 2.0));
                normals.push([0.0, 0.0, -1.0]);
                values.extend([0.0f32, 0.0, 1.0]);
            }
        }
        let (field_positions, field_normals, field_values, at_depth) =
            morton_sorted(&positions, &normals, &values, 3, depth);
        let field = SampleField {
            positions: &field_positions,
            normals: &field_normals,
            values: &field_values,
            width: 3,
            weights: vec![1.0; field_positions.len()],
            at_depth: &at_depth,
            key_depth: depth,
        };
        let vertices = vec![
            DVec3::new(0.4, 0.4, 0.5 + gap / 2.0),
            DVec3::new(0.4, 0.4, 0.5 - gap / 2.0),
        ];
        let vertex_normals = vec![DVec3::Z, DVec3::NEG_Z];
        let got = at_vertices(&field, &vertices, &vertex_normals, &[]);
        assert_eq!(&got[..3], &[1.0, 0.0, 0.0], "top face");
        assert_eq!(&got[3..], &[0.0, 0.0, 1.0], "bottom face");
    }

    /// A linear colour field is reproduced exactly at a vertex in the middle of a uniform
    /// sampling (the kernel is symmetric), and holes take their rim's values.
    #[test]
    fn linear_fields_are_reproduced_and_holes_filled_from_their_rims() {
        let depth = 5;
        let h = 1.0 / 32.0;
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut values = Vec::new();
        for i in -20..=20 {
            for j in -20..=20 {
                let (x, y) = (0.5 + i as f64 * h * 0.5, 0.5 + j as f64 * h * 0.5);
                positions.push(DVec3::new(x, y, 0.5));
                normals.push([0.0, 0.0, 1.0]);
                values.push((2.0 * x + 3.0 * y) as f32);
            }
        }
        let (p, n, v, at_depth) = morton_sorted(&positions, &normals, &values, 1, depth);
        let field = SampleField {
            positions: &p,
            normals: &n,
            values: &v,
            width: 1,
            weights: vec![1.0; p.len()],
            at_depth: &at_depth,
            key_depth: depth,
        };
        // Vertex 0 among the samples; 1 and 2 far from every sample, in a triangle with 0.
        let vertices = vec![
            DVec3::new(0.5, 0.5, 0.5),
            DVec3::new(0.95, 0.95, 0.95),
            DVec3::new(0.96, 0.95, 0.95),
        ];
        let vertex_normals = vec![DVec3::Z; 3];
        let triangles = [[0, 1, 2]];
        let got = at_vertices(&field, &vertices, &vertex_normals, &triangles);
        assert!((got[0] - 2.5).abs() < 1e-6, "{got:?}");
        assert_eq!(got[1], got[0], "the rim's value");
        assert_eq!(got[2], got[0], "the rim's value");
    }

    /// The samples sorted by Morton key at `depth`, all at that depth with unit mass.
    #[allow(clippy::type_complexity)]
    fn morton_sorted(
        positions: &[DVec3],
        normals: &[[f32; 3]],
        values: &[f32],
        width: usize,
        depth: u32,
    ) -> (Vec<DVec3>, Vec<[f32; 3]>, Vec<f32>, Vec<Vec<DepthSample>>) {
        let inv_h = (depth as f64).exp2();
        let mut order: Vec<(u64, usize)> = positions
            .iter()
            .enumerate()
            .map(|(i, &p)| (sample_key(p, inv_h), i))
            .collect();
        order.sort_unstable();
        let p = order.iter().map(|&(_, i)| positions[i]).collect();
        let n = order.iter().map(|&(_, i)| normals[i]).collect();
        let v = order
            .iter()
            .flat_map(|&(_, i)| values[i * width..(i + 1) * width].iter().copied())
            .collect();
        let mut at_depth = vec![Vec::new(); depth as usize + 1];
        at_depth[depth as usize] = (0..order.len() as u32)
            .map(|sample| DepthSample { sample, mass: 1.0 })
            .collect();
        (p, n, v, at_depth)
    }
}

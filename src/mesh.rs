//! Stage 9 — the mesh: vertices back in input coordinates, with the sampling density at each;
//! and the types a reconstruction returns.

use crate::attributes::{Channel, Colors, PointAttributes};
use crate::density::DensityField;
use crate::error::Result;
use crate::extract::RawMesh;
use crate::parallel::{map_in_blocks, Watch};
use crate::points::UnitCubeMap;
use crate::Stage;
use glam::DVec3;
use rayon::prelude::*;

/// How one depth's linear solve ended.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct DepthSolve {
    /// The octree depth.
    pub depth: u32,
    /// Unknowns (octree nodes) at this depth.
    pub unknowns: usize,
    /// Conjugate-gradient iterations run.
    pub iterations: u32,
    /// ‖b − Ax‖ / ‖b‖ at the end (0 when b = 0).
    pub relative_residual: f64,
    /// Wall seconds for this depth (right-hand side, operator set-up and iterations).
    pub seconds: f64,
}

/// Figures about a reconstruction, for logs and benchmarks.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct Stats {
    /// Input points.
    pub points: usize,
    /// The maximum depth D the reconstruction used: [`crate::Params::depth`], or the depth
    /// [`crate::Params::width`] chose. 0 for a mesh not made by a reconstruction.
    pub depth: u32,
    /// Octree nodes (unknowns) per depth, index = depth, from 0 to [`Stats::finest_depth`].
    pub nodes_per_depth: Vec<usize>,
    /// The isovalue γ the surface was extracted at (§4.4).
    pub isovalue: f64,
    /// How each depth's solve ended, coarse to fine.
    pub solves: Vec<DepthSolve>,
    /// Wall seconds spent in each stage, in pipeline order.
    pub stage_seconds: Vec<(Stage, f64)>,
    /// The kernel depth D̂ at which the sampling density was estimated (§4.5): the unit of
    /// [`Mesh::densities`] is samples per depth-D̂ node, and trimming's depth-like threshold
    /// ([`crate::Threshold::Depth`]) is D̂ + log₄ of the density.
    pub kernel_depth: u32,
    /// The sampling density at the input samples themselves, as 1001 quantiles: entry k is the
    /// density (in the unit of [`Mesh::densities`]) below which k / 1000 of the samples lie,
    /// entry 0 the lowest and entry 1000 the highest. The scale trimming's automatic threshold
    /// is taken from ([`crate::Threshold::Automatic`]). Empty for a mesh not made by a
    /// reconstruction.
    pub sample_density_quantiles: Vec<f32>,
    /// How the mesh was cut back to its samples by [`crate::trim`]; `None` for a mesh as the
    /// reconstruction made it.
    pub trim: Option<TrimReport>,
    /// Closed components of the level set left out of the mesh because fewer than
    /// [`crate::Params::min_component_samples`] samples support them (bubbles beside the
    /// surface), and their triangles.
    pub unsupported_components: usize,
    /// The triangles of [`Stats::unsupported_components`].
    pub unsupported_triangles: usize,
    /// Halo nodes per depth (every node a depth's vectors hold: the unknowns and the nodes
    /// around them), index = depth.
    pub halo_nodes_per_depth: Vec<usize>,
    /// The memory accounting's estimate of this reconstruction's peak, in bytes, from its
    /// octree's node counts: what [`crate::Params::max_memory`] was checked against before the
    /// system was built (`docs/benchmarks.md`, issue 19, compares it with measured peaks).
    pub estimated_memory: u64,
    /// Node slots of the density field's bricks (all its depths), which the memory accounting
    /// counts.
    pub density_slots: usize,
    /// The samples' positional noise σ, in input units (the RMS scatter across the surface,
    /// 0 for exact samples of a smooth surface), when [`crate::Params::screening_follows_noise`]
    /// asked for it; `None` otherwise.
    pub sample_noise: Option<f64>,
    /// The noise's depth s of the screening weight ([`crate::Params::point_weight`]): the depths
    /// finer than s were pulled with α·2^s instead of α·2^D (those up to ⌊s⌋ keep α·2^D). The
    /// depth D when the samples read no noise or the screening did not follow it; less when it
    /// followed the noise (the depth whose cells are 10 σ wide, fractional). 0 for a mesh not
    /// made by a reconstruction.
    pub screening_depth: f64,
}

/// What [`crate::trim`] did: the threshold it cut at, in both of its units, and what it kept.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct TrimReport {
    /// The density threshold the surface was cut at (unit of [`Mesh::densities`]): whatever
    /// [`crate::Threshold`] was asked for, resolved to a density.
    pub density: f64,
    /// The same threshold as PoissonRecon's depth-like value, D̂ + log₄(density) (−∞ for a
    /// threshold of 0).
    pub depth: f64,
    /// Crossings of the contour with an edge that were moved onto the edge's end, being
    /// closer to it than a fifth of the edge (to avoid slivers).
    pub snapped_crossings: usize,
    /// Crossings as close to an end that could not be moved there (it would have pinched the
    /// surface at that vertex, as at a saddle of the density): kept a fifth of the edge away.
    pub clamped_crossings: usize,
    /// Connected pieces left by the cut, and how many of them the size rule dropped.
    pub pieces: usize,
    /// Pieces dropped for being smaller than [`crate::Trimming::min_piece_area`] or
    /// [`crate::Trimming::min_piece_triangles`].
    pub pieces_dropped: usize,
    /// Surface area before the cut and after it (pieces dropped), in input units squared.
    pub area_before: f64,
    /// See [`TrimReport::area_before`].
    pub area_after: f64,
    /// Wall seconds the trim took.
    pub seconds: f64,
}

impl Stats {
    /// The octree's finest depth: D, or less when the sampling density put no sample that deep
    /// (sparse points at a high depth), in which case the tree and the mesh stop there (never
    /// above the full depth). 0 for a mesh not made by a reconstruction.
    pub fn finest_depth(&self) -> u32 {
        self.nodes_per_depth.len().saturating_sub(1) as u32
    }

    /// Total octree nodes over all depths.
    pub fn total_nodes(&self) -> usize {
        self.nodes_per_depth.iter().sum()
    }
}

/// A triangle mesh in the input's coordinates.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct Mesh {
    /// Vertex positions, relative to [`Mesh::origin`]: a vertex is at `origin + position` in
    /// input coordinates ([`Mesh::positions_f64`] adds them in `f64`). The origin is 0, so these
    /// are the input coordinates themselves, unless the points were given in `f64`.
    pub positions: Vec<[f32; 3]>,
    /// The point the positions are relative to, in input coordinates: `[0, 0, 0]` unless the
    /// points were given in `f64` ([`crate::PointSet::extend_f64`],
    /// [`crate::PointSet::extend_transformed`]). Then it is the centre of the reconstruction's
    /// bounding cube rounded to a multiple of the smallest power of two at least the cube's
    /// side `s` (0 when the cube is within `s`/2 of 0), so every vertex is within about 2`s` of
    /// it and its `f32` position keeps `f32`'s relative precision of the object's size
    /// (6·10⁻⁸ × 2`s`) however far the object is from 0 — 10⁶ m away, `f32` input coordinates
    /// have a resolution of 6 cm. Each position was rounded once, from `f64`.
    pub origin: [f64; 3],
    /// Counter-clockwise seen from outside: normals point out of the reconstructed solid.
    pub triangles: Vec<[u32; 3]>,
    /// Sampling density estimate at each vertex (kernel density of §4.5, in samples per
    /// kernel-depth node): low values mark surface invented far from any sample (for trimming).
    pub densities: Vec<f32>,
    /// Figures about the reconstruction that made it.
    pub stats: Stats,
    /// Unit outward normal at each vertex (∇χ/|∇χ|) when [`crate::Params::vertex_normals`]
    /// asked for them; empty otherwise.
    pub normals: Vec<[f32; 3]>,
    /// A colour per vertex when the points had colours ([`crate::PointSet::with_colors`]).
    ///
    /// Each vertex's colour is the weighted mean of the colours of the samples around it,
    /// splatted like the normals: each sample weighs its mass there (its area, confidence and
    /// share of its octree depth) times the node function's B-spline at its distance in node
    /// widths of its depth, times max(0, n_sample · n_vertex), so that a sample never colours
    /// a surface facing away from it (the other face of a thin wall). Vertices no sample
    /// reaches (surface invented across holes) take the mean of their neighbours, ring by ring
    /// from the rim of the hole.
    pub colors: Option<Colors>,
    /// The points' named channels ([`crate::PointSet::with_channel`]), a value per vertex each,
    /// in the points' order, carried like the colours.
    pub channels: Vec<Channel>,
}

impl Mesh {
    /// The vertices in input coordinates, in `f64`: [`Mesh::origin`] + each position.
    pub fn positions_f64(&self) -> Vec<[f64; 3]> {
        let o = self.origin;
        self.positions
            .iter()
            .map(|p| [0, 1, 2].map(|a| o[a] + p[a] as f64))
            .collect()
    }
}

/// Stage 9: `raw`'s vertices mapped back to input coordinates by `map`, relative to `origin`
/// when one is given (see [`Mesh::origin`]), each with the sampling density there (`density`,
/// for trimming); its figures are left for the caller. The densities, most of the work, are
/// evaluated in blocks with cancel points, reporting to `watch` (from 0.5 to 1).
pub(crate) fn in_input_coordinates(
    raw: RawMesh,
    map: &UnitCubeMap,
    origin: Option<DVec3>,
    density: &DensityField,
    watch: &Watch,
) -> Result<Mesh> {
    let positions: Vec<[f32; 3]> = match origin {
        // The f32 path: exactly as before origins existed.
        None => raw
            .vertices
            .par_iter()
            .map(|&v| {
                let p = map.to_input(v);
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect(),
        Some(origin) => raw
            .vertices
            .par_iter()
            .map(|&v| (map.to_input(v) - origin).as_vec3().to_array())
            .collect(),
    };
    let densities: Vec<f32> = map_in_blocks(
        &raw.vertices,
        |&v| density.evaluate(v) as f32,
        watch,
        0.5,
        1.0,
    )?;
    Ok(Mesh {
        positions,
        origin: origin.map_or([0.0; 3], |o| o.to_array()),
        triangles: raw.triangles,
        densities,
        ..Mesh::default()
    })
}

/// Gives `mesh` the attributes the points had (`points` says which), from the flattened values
/// per vertex that [`crate::attributes::at_vertices`] made.
pub(crate) fn set_attributes(mesh: &mut Mesh, points: &PointAttributes, values: &[f32]) {
    let width = points.width();
    let n = mesh.positions.len();
    let mut column = 0;
    if let Some(colors) = &points.colors {
        let components = colors.components();
        let flat: Vec<f32> = (0..n)
            .flat_map(|v| values[v * width..v * width + components].iter().copied())
            .collect();
        mesh.colors = Some(Colors::from_flattened(components, &flat));
        column = components;
    }
    mesh.channels = points
        .channels
        .iter()
        .enumerate()
        .map(|(k, channel)| {
            let values = (0..n).map(|v| values[v * width + column + k]).collect();
            Channel::new(channel.name.clone(), values)
        })
        .collect();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves: stage 9 maps every vertex back through the unit-cube map and gives it the
    /// density there, keeping the triangles as they are.
    #[test]
    fn vertices_go_back_to_input_coordinates_with_their_density() {
        let map = UnitCubeMap::fit(&[[10.0, 20.0, 30.0], [14.0, 22.0, 31.0]], 1.0);
        let samples: Vec<DVec3> = (0..50)
            .map(|i| DVec3::new(0.2 + 0.01 * i as f64, 0.5, 0.5))
            .collect();
        let density = DensityField::splat(&samples, None, 5);
        let vertices = vec![DVec3::new(0.25, 0.5, 0.5), DVec3::new(0.9, 0.1, 0.1)];
        let raw = RawMesh {
            vertices: vertices.clone(),
            triangles: vec![[0, 1, 0]],
            normals: Vec::new(),
        };
        let raw_again = RawMesh {
            vertices: vertices.clone(),
            triangles: vec![[0, 1, 0]],
            normals: Vec::new(),
        };
        let watch = Watch::new();
        let mesh = in_input_coordinates(raw_again, &map, None, &density, &watch).unwrap();
        let far = UnitCubeMap {
            origin: map.origin + DVec3::new(1e6, -2e6, 3e5),
            ..map
        };
        let shifted =
            in_input_coordinates(raw, &far, Some(far.nearby_origin()), &density, &watch).unwrap();
        assert_eq!(shifted.origin, [1e6 + 12.0, -2e6 + 20.0, 3e5 + 32.0]);
        for (p, q) in shifted.positions_f64().iter().zip(&mesh.positions) {
            let want = [1e6, -2e6, 3e5];
            assert!(
                (0..3).all(|a| (p[a] - want[a] - q[a] as f64).abs() < 1e-5),
                "{p:?}"
            );
        }
        assert_eq!(mesh.triangles, vec![[0, 1, 0]]);
        for (k, v) in vertices.iter().enumerate() {
            let want = map.to_input(*v);
            let got = mesh.positions[k];
            assert!(
                (0..3).all(|a| (got[a] as f64 - want[a]).abs() < 1e-5),
                "{got:?}"
            );
            assert_eq!(mesh.densities[k], density.evaluate(*v) as f32);
        }
        assert!(mesh.densities[0] > 0.0, "near the samples");
        assert_eq!(mesh.densities[1], 0.0, "far from every sample");
    }
}

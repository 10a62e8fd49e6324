//! Utilities for psr's integration tests (a dev-dependency of `psr`, never published).
//!
//! Self-contained: std, glam and rayon only (psr's own dependencies), no `rand`.
//!
//! * [`Rng`]: a deterministic SplitMix64 generator, so every test input is fixed by its seed.
//! * Point samplers for analytic shapes with outward unit normals: [`sample_sphere`],
//!   [`sample_torus`], [`sample_sphere_nonuniform`], [`sample_box`] (sharp edges; thin plates),
//!   [`sample_two_tori`] (two nearly touching parts), [`thin_unevenly`]; noise: [`perturb_normals`],
//!   [`perturb_normals_gaussian`], [`jitter_positions`].
//! * Exact distances to those shapes: [`sphere_distance`], [`torus_distance`], and their
//!   bounding-box diagonals for normalisation.
//! * Mesh topology: [`MeshTopology::of`] (boundary / non-manifold edges, non-manifold vertices,
//!   orientation, components, Euler characteristic, duplicate vertices, degenerate triangles),
//!   [`vertex_components`] (the component of each vertex), [`signed_volume`], [`surface_area`].
//! * Distances to a triangle mesh: [`MeshDistance`] (a bounding-volume hierarchy with exact
//!   point–triangle distances), [`sample_mesh`], [`chamfer_to_surface`],
//!   [`one_sided_mesh_distance`].
//! * Scans with missing regions ([`capture_from`]: the side one camera sees;
//!   [`keep_above_plane`]: e.g. a hemisphere) and the distance from a mesh back to its points
//!   ([`mesh_to_points_distance`], [`nearest_point_distances`]), for trimming.
//! * Boundaries of open meshes: [`boundary_loops`], [`loop_length`], their smoothness
//!   ([`loop_excess_length`]), and [`triangle_quality`] for slivers.
//! * Small reference meshes ([`octahedron`], [`icosphere`], [`torus_mesh`]).
//! * The process's running threads by name ([`running_threads_named`], Linux).
//! * The shared data directory ([`data_dir`]) and the rule for tests that read it
//!   ([`data_or_skip`]: skip visibly on a developer's machine without the data, fail on CI).
//!   PLY files are read with the library's own reader, `psr::ply` (`read_point_cloud`,
//!   `read_mesh`).
//!
//! Points and meshes are passed the way `psr::Mesh` stores them: positions `&[[f32; 3]]` and
//! counter-clockwise triangles `&[[u32; 3]]` (e.g. `&mesh.positions, &mesh.triangles`).
//! Everything is computed in f64.
//!
//! The modules split the code by concern; everything is re-exported at the crate root, so tests
//! write `use psr_test_support::{sample_sphere, MeshTopology};`. The utilities are themselves
//! tested by `tests/test_utilities.rs` in the psr package.

mod boundary;
mod capture;
mod data;
mod distance;
mod point;
mod rng;
mod shapes;
mod threads;
mod topology;

pub use boundary::*;
pub use capture::*;
pub use data::*;
pub use distance::*;
pub use point::*;
pub use rng::*;
pub use shapes::*;
#[cfg(target_os = "linux")]
pub use threads::running_threads_named;
pub use topology::*;

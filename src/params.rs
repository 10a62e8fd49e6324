//! Reconstruction parameters, their defaults and their validation.
//!
//! Defaults follow Kazhdan's PoissonRecon (18.75) wherever the two methods share a parameter, so
//! that results are comparable option for option.

use crate::error::{Error, Result};

/// The deepest octree depth psr accepts. Depth 16 is a 65,536³ grid, far beyond what any scan
/// needs; node keys have room for it.
pub const MAX_DEPTH: u32 = 16;

/// What to do at the faces of the bounding cube.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Boundary {
    /// The 2006 paper: node functions are integrated over all of space and simply end a little
    /// beyond the cube, which pulls χ towards 0 there (like a Dirichlet condition one node out).
    /// Close to the cube's faces this distorts the surface.
    Free,
    /// ∂χ/∂n = 0 on the cube's faces: node functions are reflected at the faces (the even,
    /// folded basis). PoissonRecon's and Open3D's default; the most accurate near the faces.
    Neumann,
    /// χ = 0 on the cube's faces: node functions are reflected at the faces with a change of
    /// sign (the odd, folded basis), so every function of the space vanishes on the faces. Zero
    /// is χ's value outside the surface, so the cube's faces are outside: where a scan is open
    /// (a terrain, a room, a tunnel, a scan seen from one side), the surface closes on itself
    /// inside the cube, curving in from the open rim, instead of running out to the cube's
    /// faces and closing with a cap lying on them as [`Boundary::Neumann`] does. Use it for
    /// open scans whose rims come near the cube; on closed, well-sampled surfaces away from
    /// the faces it gives nearly the same mesh as Neumann. Costs the same as Neumann.
    /// PoissonRecon `--bType 2`; Open3D and PCL have no equivalent.
    Dirichlet,
}

impl Boundary {
    /// The sign a node value takes in its mirror image across one face of the cube: +1 for
    /// [`Boundary::Neumann`] (even reflection), −1 for [`Boundary::Dirichlet`] (odd); `None`
    /// for [`Boundary::Free`], which has no mirror nodes. One code path serves both mirrored
    /// kinds: a node beyond k faces takes (sign)^k times its image's value.
    pub(crate) fn mirror_sign(self) -> Option<f64> {
        match self {
            Boundary::Free => None,
            Boundary::Neumann => Some(1.0),
            Boundary::Dirichlet => Some(-1.0),
        }
    }

    /// The value the screening term pulls χ to at the samples when it is not 0. χ jumps by 1
    /// across the surface, from inside to outside (∇χ = V points along the outward normals).
    /// Free and Neumann boundaries leave χ's constant to the screening, which pulls χ to 0 at
    /// the samples: outside is then about +½. Dirichlet fixes χ = 0 on the cube's faces, which
    /// must read as outside, so the samples are pulled to −½ (PoissonRecon pulls them to ½
    /// with the opposite sign convention): outside 0, inside −1, and the faces lie half a jump
    /// away from the isovalue rather than on it. `None` (no right-hand side to add, the same
    /// arithmetic as before Dirichlet existed) for free and Neumann.
    pub(crate) fn screening_target(self) -> Option<f64> {
        match self {
            Boundary::Free | Boundary::Neumann => None,
            Boundary::Dirichlet => Some(-0.5),
        }
    }
}

/// How a sample's weighted normal is spread over the nodes of its depth (§4.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Splatting {
    /// Weights b(t) of the node functions themselves, 3 nodes per axis: the vector field's
    /// kernel is then b∗b, smoother than the paper's. Measured at depth 8 on a 100k-point random
    /// sphere: mean vertex error 7.9e-5 vs 1.2e-4 trilinear (max 6e-4 vs 1.5e-3); on the bunny
    /// scans reference→mesh mean 4.88e-5 m vs 5.18e-5 m. Both kinds build the same octree
    /// (every node whose function covers a sample's cell), so neither is cheaper.
    BSpline,
    /// The 2006 paper: trilinear weights over the 8 nearest nodes.
    Trilinear,
}

/// Where the mesh's vertices go (stage 8, extraction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum VertexPlacement {
    /// Each vertex is found on {χ = γ}, then moved along the surface normal by the mean sag of
    /// the chords around it, so that the flat triangles straddle the curved surface instead of
    /// lying on its concave side (`fit_to_surface` in `extract.rs`). Measured at depth 7
    /// (thousandths of the diagonal, on the isosurface → fitted): mean distance to an exact
    /// torus 0.043 → 0.030, to a sphere 0.022 → 0.021; from the input points to the mesh on
    /// CGAL's kitten 0.41 → 0.30 and oni 1.66 → 1.36; on the bunny scans at depth 8 −2%, the
    /// Happy Buddha at depths 9 and 10 under −1%. Where noise rather than curvature shapes χ's
    /// level set, the mesh keeps a little more of it (a sphere with 15° normal noise at depth 8:
    /// 0.083 → 0.086). Costs about 1% of the run (Buddha depth 10: 0.29 s of 24 s on 1 thread).
    Fitted,
    /// Every vertex exactly on {χ = γ}, as PoissonRecon places them: for users who evaluate χ
    /// at the vertices or want the level set itself.
    OnIsosurface,
}

/// Parameters of one reconstruction. `Params::default()` works; every field documents its
/// default, its range and the equivalent option of the incumbents. Set fields directly or with
/// the `with_*` builders:
///
/// ```
/// let params = psr::Params::default().with_depth(10).with_point_weight(2.0);
/// assert_eq!((params.depth, params.point_weight), (10, 2.0));
/// ```
///
/// New fields may be added in any release (the struct is `#[non_exhaustive]`), so build it
/// from `Params::default()`, not with a struct literal.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Params {
    /// Maximum octree depth D: the finest cells are 2^-D of the (scaled) bounding cube.
    /// Default 8, range 1..=16. PoissonRecon `--depth`, Open3D `depth`, PCL `setDepth`.
    /// Ignored when [`Params::width`] is set, which chooses the depth instead.
    pub depth: u32,
    /// Target width of the finest cells, in input units: when set, it overrides
    /// [`Params::depth`] with the smallest depth whose finest cell (the bounding cube's side,
    /// that is the bounding box's longest side × [`Params::scale`], over 2^depth) is at most
    /// `width`, at least 1 and at most 16 (a finer width gets depth 16, whose
    /// cells are wider than asked). The depth used is in [`crate::Stats::depth`]. Default
    /// `None` (the depth decides); range: finite and positive. PoissonRecon `--width` (which
    /// likewise overrides `--depth` when positive, by the same rule); Open3D's `width`
    /// argument of `create_from_point_cloud_poisson` (ignored there when depth is given).
    pub width: Option<f64>,
    /// Depth down to which the octree is complete (every node exists), so that the coarse
    /// solution is defined everywhere. Default 5, range 0..=depth (clamped to depth when larger).
    /// PoissonRecon `--fullDepth`, PCL `setMinDepth`.
    pub full_depth: u32,
    /// Depth at which the sampling density is estimated (§4.5, D̂). `None` = depth − 2 (at least
    /// 0). Range 0..=depth. PoissonRecon `--kernelDepth`.
    pub kernel_depth: Option<u32>,
    /// Target number of samples per octree node: a sample whose density estimate is lower than
    /// this is splatted at a coarser, fractional depth (§4.5). Default 1.5, range [1, 1e6].
    /// PoissonRecon `--samplesPerNode`, PCL `setSamplesPerNode`, counted differently: psr
    /// compares the density estimate W itself, which a surface with n samples per node area
    /// reads as about 0.6·n, where PoissonRecon divides that factor out, so the same value puts
    /// psr's samples about a third of a depth coarser (what keeps exact samples of sharp shapes
    /// free of bumps; measured in `docs/benchmarks.md`), except where the surface bends under
    /// the density's kernel, where psr reads it as PoissonRecon does, up to the next whole
    /// depth.
    pub samples_per_node: f32,
    /// The bounding cube is the points' bounding box enlarged by this factor. Default 1.1, range
    /// [1, 100]. PoissonRecon `--scale`, Open3D `scale`, PCL `setScale`.
    pub scale: f32,
    /// Screening weight α (Kazhdan & Hoppe 2013): how strongly the surface is pulled onto the
    /// samples. 0 gives the 2006 method. Default 4 (2 × the B-spline degree, PoissonRecon's rule);
    /// [`Params::with_degree`] sets it to 2 × the new degree, so set it after the degree to
    /// override. Range [0, 1e6]. The pull is scaled by 2^depth, and at the depths finer than
    /// the samples' noise supports by that depth's 2^s ([`Params::screening_follows_noise`],
    /// on by default). PoissonRecon `--pointWeight`, PCL `setPointWeight`, Open3D's fixed 2
    /// (with degree 1).
    pub point_weight: f32,
    /// Whether the screening follows the samples' positional noise: the samples' scatter
    /// across the surface is estimated from themselves (σ, reported in
    /// [`crate::Stats::sample_noise`]; 0 on exact samples of a smooth surface), and the depths
    /// finer than the one whose cells are 10 σ wide (s, [`crate::Stats::screening_depth`]) are
    /// pulled with α·2^s instead of α·2^depth, so that a finer depth does not pull the surface
    /// onto the noise (the coarser depths keep α·2^depth, which keeps small detached parts of
    /// a scan on the surface). Exact samples keep 2^depth, and so do clouds
    /// so sparse that the cells holding enough samples to measure are too coarse to resolve
    /// the surface (the 1,435-point oni: what the cells' quadrics leave there has shape a cubic
    /// explains, and it reads no noise). Out of core ([`crate::reconstruct_out_of_core`], and
    /// across MPI ranks) the slabs estimate the same σ from their parts.
    ///
    /// Default `true`. `false` keeps 2^depth at any noise, the scale of SPSR and PoissonRecon:
    /// on noisy clouds the surface then follows the noise more with every depth past the
    /// samples' (on noisy spheres 60 % farther from the truth at depth 11 than at 8; on the
    /// bunny's scans 8 % farther from samples held out of the reconstruction at depth 12 than
    /// at 9, where following the noise stays flat and closer than Open3D's), and lies closer
    /// to the very points it was fitted to (docs/benchmarks.md, issue 16). No PoissonRecon,
    /// Open3D or PCL equivalent.
    pub screening_follows_noise: bool,
    /// Degree of the B-spline node functions: 2 (default; support 3 cells, continuous ∇χ) or 1
    /// (piecewise-linear hats on the cell corners, support 2 cells: 3-wide stencils instead of
    /// 5-wide, so cheaper per unknown, and a continuous χ whose gradient jumps across cells).
    /// Both give closed manifold meshes by the same extraction, with every boundary kind.
    /// PoissonRecon `--degree` (its default is 1), Open3D's fixed degree 1, PCL `setDegree`. See [`Params::with_degree`] for the point weight that
    /// follows it.
    pub degree: u8,
    /// Worker threads for this reconstruction; 0 = all cores. Default 0. The result does not
    /// depend on it. Open3D `n_threads`, PCL `setThreads`.
    pub threads: usize,
    /// Conjugate-gradient iterations per depth at most. Default 60, range 1..=10,000.
    /// PoissonRecon `--iters` (its Gauss–Seidel count, not the same unit).
    pub max_solver_iterations: u32,
    /// Relative residual ‖b − Ax‖/‖b‖ at which a depth's solve stops. Default 1e-2: the
    /// cascade starts each depth from the coarser solution, so each depth's system only
    /// carries what the coarser depths could not resolve, and solving it further was measured
    /// to change no reconstruction (sphere, torus, non-uniform and noisy spheres, bunny scans:
    /// distances to the truth within ±1% from 1e-2 down to 1e-5) while costing up to 40% more
    /// time. Range [1e-12, 1). PoissonRecon `--cgAccuracy` (coarsest level only).
    pub solver_tolerance: f64,
    /// Splatting weights. Default [`Splatting::BSpline`]; [`Splatting::Trilinear`] is the paper's.
    pub splatting: Splatting,
    /// Boundary condition at the bounding cube. Default [`Boundary::Neumann`] (PoissonRecon
    /// `--bType 3`, Open3D's only choice); [`Boundary::Dirichlet`] (`--bType 2`) for open scans,
    /// [`Boundary::Free`] (`--bType 1`) the 2006 paper's.
    pub boundary: Boundary,
    /// Where the vertices go. Default [`VertexPlacement::Fitted`];
    /// [`VertexPlacement::OnIsosurface`] keeps them on the level set.
    pub vertex_placement: VertexPlacement,
    /// Whether the mesh gets a unit outward normal per vertex ([`crate::Mesh::normals`]),
    /// ∇χ/|∇χ| at the vertex. Default false. PoissonRecon `--normals`.
    pub vertex_normals: bool,
    /// The fewest input samples that must lie within one cell of a closed component's vertices
    /// (the finest cell, or the component's mean edge length where it was meshed at a coarser
    /// depth) for the component to stay (the largest component always stays). The
    /// level set of χ can have tiny closed pieces ("bubbles") beside the surface, around a few
    /// stray samples or none; a real part of the scan, however small, carries its own samples.
    /// Default 8: the smallest closed surface extraction makes crosses 2 × 2 × 2 cells, and the
    /// density estimate calls a node sampled at [`Params::samples_per_node`] (1.5) samples, so
    /// fewer than 8 cannot define one. 0 keeps every component. The number removed is in
    /// [`crate::Stats::unsupported_components`]. No PoissonRecon equivalent (its output keeps
    /// them; its SurfaceTrimmer's `--aRatio` drops small pieces by area instead).
    pub min_component_samples: u32,
    /// The most memory this reconstruction may use, in bytes: its accounting of the big arrays
    /// (points, octree, system, solver, extraction, mesh; [`crate::estimate_memory`]) is
    /// checked against it before they are allocated, first from the point count, then with the
    /// octree's node counts before the system is built, and a reconstruction that would need
    /// more fails with [`crate::Error::OutOfMemory`] instead of growing past it. Default `None`
    /// (no limit: only the system's refusal, which is also `OutOfMemory`); range: at least 1
    /// byte. No PoissonRecon, Open3D or PCL equivalent.
    pub max_memory: Option<u64>,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            depth: 8,
            width: None,
            full_depth: 5,
            kernel_depth: None,
            samples_per_node: 1.5,
            scale: 1.1,
            point_weight: 4.0,
            screening_follows_noise: true,
            degree: 2,
            threads: 0,
            max_solver_iterations: 60,
            solver_tolerance: 1e-2,
            splatting: Splatting::BSpline,
            boundary: Boundary::Neumann,
            vertex_placement: VertexPlacement::Fitted,
            vertex_normals: false,
            min_component_samples: 8,
            max_memory: None,
        }
    }
}

impl Params {
    /// These parameters with [`Params::depth`] set to `depth`.
    pub fn with_depth(mut self, depth: u32) -> Self {
        self.depth = depth;
        self
    }

    /// These parameters with [`Params::width`] set to `width` (`None` lets
    /// [`Params::depth`] decide again).
    pub fn with_width(mut self, width: Option<f64>) -> Self {
        self.width = width;
        self
    }

    /// These parameters with [`Params::full_depth`] set to `full_depth`.
    pub fn with_full_depth(mut self, full_depth: u32) -> Self {
        self.full_depth = full_depth;
        self
    }

    /// These parameters with [`Params::kernel_depth`] set to `kernel_depth`.
    pub fn with_kernel_depth(mut self, kernel_depth: Option<u32>) -> Self {
        self.kernel_depth = kernel_depth;
        self
    }

    /// These parameters with [`Params::samples_per_node`] set to `samples_per_node`.
    pub fn with_samples_per_node(mut self, samples_per_node: f32) -> Self {
        self.samples_per_node = samples_per_node;
        self
    }

    /// These parameters with [`Params::scale`] set to `scale`.
    pub fn with_scale(mut self, scale: f32) -> Self {
        self.scale = scale;
        self
    }

    /// These parameters with [`Params::point_weight`] set to `point_weight`.
    pub fn with_point_weight(mut self, point_weight: f32) -> Self {
        self.point_weight = point_weight;
        self
    }

    /// These parameters with [`Params::screening_follows_noise`] set to `follows`.
    pub fn with_screening_follows_noise(mut self, follows: bool) -> Self {
        self.screening_follows_noise = follows;
        self
    }

    /// These parameters with [`Params::degree`] set to `degree` and [`Params::point_weight`] to
    /// 2 × `degree`, PoissonRecon's default for that degree (so `with_degree(1)` screens as
    /// PoissonRecon's and Open3D's defaults do); call [`Params::with_point_weight`] after it for
    /// another weight. A degree other than 1 or 2 is refused by [`Params::validate`] (and the
    /// point weight is then left as it was).
    pub fn with_degree(mut self, degree: u8) -> Self {
        self.degree = degree;
        if (1..=2).contains(&degree) {
            self.point_weight = 2.0 * degree as f32;
        }
        self
    }

    /// The degree as the node functions' [`crate::bspline::Degree`] (validated parameters).
    pub(crate) fn node_degree(&self) -> crate::bspline::Degree {
        match self.degree {
            1 => crate::bspline::Degree::One,
            _ => crate::bspline::Degree::Two,
        }
    }

    /// These parameters with [`Params::threads`] set to `threads`.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads;
        self
    }

    /// These parameters with [`Params::max_solver_iterations`] set to `max_solver_iterations`.
    pub fn with_max_solver_iterations(mut self, max_solver_iterations: u32) -> Self {
        self.max_solver_iterations = max_solver_iterations;
        self
    }

    /// These parameters with [`Params::solver_tolerance`] set to `solver_tolerance`.
    pub fn with_solver_tolerance(mut self, solver_tolerance: f64) -> Self {
        self.solver_tolerance = solver_tolerance;
        self
    }

    /// These parameters with [`Params::splatting`] set to `splatting`.
    pub fn with_splatting(mut self, splatting: Splatting) -> Self {
        self.splatting = splatting;
        self
    }

    /// These parameters with [`Params::boundary`] set to `boundary`.
    pub fn with_boundary(mut self, boundary: Boundary) -> Self {
        self.boundary = boundary;
        self
    }

    /// These parameters with [`Params::vertex_placement`] set to `vertex_placement`.
    pub fn with_vertex_placement(mut self, vertex_placement: VertexPlacement) -> Self {
        self.vertex_placement = vertex_placement;
        self
    }

    /// These parameters with [`Params::vertex_normals`] set to `vertex_normals`.
    pub fn with_vertex_normals(mut self, vertex_normals: bool) -> Self {
        self.vertex_normals = vertex_normals;
        self
    }

    /// These parameters with [`Params::min_component_samples`] set to `samples` (0 keeps every
    /// component).
    pub fn with_min_component_samples(mut self, samples: u32) -> Self {
        self.min_component_samples = samples;
        self
    }

    /// These parameters with [`Params::max_memory`] set to `bytes` (`None`: no limit).
    pub fn with_max_memory(mut self, bytes: Option<u64>) -> Self {
        self.max_memory = bytes;
        self
    }

    /// The maximum depth a reconstruction uses for a bounding cube of side `cube_side` (input
    /// units): [`Params::depth`], or, when [`Params::width`] is set, the smallest depth in
    /// 1..=16 whose cells `cube_side / 2^depth` are no wider than it (16 when none is).
    pub fn depth_for_cube(&self, cube_side: f64) -> u32 {
        let Some(width) = self.width else {
            return self.depth;
        };
        (1..=MAX_DEPTH)
            .find(|&d| cube_side / (d as f64).exp2() <= width)
            .unwrap_or(MAX_DEPTH)
    }

    /// These parameters with the depth chosen for a bounding cube of side `cube_side`
    /// ([`Params::depth_for_cube`]) and no width, as the pipeline runs them.
    pub(crate) fn for_cube(&self, cube_side: f64) -> Params {
        Params {
            depth: self.depth_for_cube(cube_side),
            width: None,
            ..self.clone()
        }
    }

    /// The kernel depth actually used (resolves `None` to depth − 2).
    pub fn effective_kernel_depth(&self) -> u32 {
        self.kernel_depth
            .unwrap_or(self.depth.saturating_sub(2))
            .min(self.depth)
    }

    /// The full depth actually used (never deeper than `depth`).
    pub fn effective_full_depth(&self) -> u32 {
        self.full_depth.min(self.depth)
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
        if !(1..=MAX_DEPTH).contains(&self.depth) {
            return Err(bad("depth", self.depth, "an integer in 1..=16"));
        }
        if self.full_depth > MAX_DEPTH {
            return Err(bad(
                "full_depth",
                self.full_depth,
                "an integer in 0..=16 (values above depth act as depth)",
            ));
        }
        if let Some(width) = self.width {
            if !(width.is_finite() && width > 0.0) {
                return Err(bad("width", width, "a finite number > 0 (or no width)"));
            }
        }
        if let Some(k) = self.kernel_depth {
            // With a width the depth is only known once the points are, and a larger kernel
            // depth acts as the depth chosen.
            if self.width.is_some() && k > MAX_DEPTH {
                return Err(bad(
                    "kernel_depth",
                    k,
                    "an integer in 0..=16 (with a width, values above the chosen depth act as it)",
                ));
            }
            if self.width.is_none() && k > self.depth {
                return Err(bad("kernel_depth", k, "an integer in 0..=depth"));
            }
        }
        if !(self.samples_per_node.is_finite() && (1.0..=1e6).contains(&self.samples_per_node)) {
            return Err(bad(
                "samples_per_node",
                self.samples_per_node,
                "a number in [1, 1e6]",
            ));
        }
        if !(self.scale.is_finite() && (1.0..=100.0).contains(&self.scale)) {
            return Err(bad("scale", self.scale, "a number in [1, 100]"));
        }
        if !(self.point_weight.is_finite() && (0.0..=1e6).contains(&self.point_weight)) {
            return Err(bad(
                "point_weight",
                self.point_weight,
                "a number in [0, 1e6]",
            ));
        }
        if !(1..=2).contains(&self.degree) {
            return Err(bad("degree", self.degree, "1 or 2"));
        }

        if self.threads > 4096 {
            return Err(bad(
                "threads",
                self.threads,
                "0 (all cores) or a count up to 4096",
            ));
        }
        if !(1..=10_000).contains(&self.max_solver_iterations) {
            return Err(bad(
                "max_solver_iterations",
                self.max_solver_iterations,
                "an integer in 1..=10000",
            ));
        }
        if !(self.solver_tolerance.is_finite()
            && self.solver_tolerance >= 1e-12
            && self.solver_tolerance < 1.0)
        {
            return Err(bad(
                "solver_tolerance",
                self.solver_tolerance,
                "a number in [1e-12, 1)",
            ));
        }
        if self.max_memory == Some(0) {
            return Err(bad("max_memory", 0, "a number of bytes > 0 (or no limit)"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves: a width picks the smallest depth whose cells (cube side / 2^depth) are no wider,
    /// a cell exactly as wide included; at least 1 and at most 16; without a width the depth
    /// stands.
    #[test]
    fn a_width_picks_the_smallest_depth_with_cells_no_wider() {
        let with = |w: f64| Params::default().with_width(Some(w));
        let side = 2.2;
        assert_eq!(with(side / 128.0).depth_for_cube(side), 7, "exactly 2^-7");
        assert_eq!(with(side / 128.0 * 0.999).depth_for_cube(side), 8);
        assert_eq!(with(side / 128.0 * 1.001).depth_for_cube(side), 7);
        assert_eq!(with(side * 10.0).depth_for_cube(side), 1, "never below 1");
        assert_eq!(with(side * 1e-9).depth_for_cube(side), MAX_DEPTH, "capped");
        assert_eq!(Params::default().with_depth(5).depth_for_cube(side), 5);
        let resolved = with(side / 128.0).with_depth(11).for_cube(side);
        assert_eq!((resolved.depth, resolved.width), (7, None));
    }

    /// Proves: a width must be finite and positive; with one, a kernel depth above the depth
    /// field is allowed (it acts as the depth chosen), but not above 16.
    #[test]
    fn widths_are_checked_and_free_the_kernel_depth_from_the_depth_field() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = Params::default().with_width(Some(bad)).validate();
            assert!(
                matches!(err, Err(Error::InvalidParameter { name: "width", .. })),
                "{bad}: {err:?}"
            );
        }
        let p = Params::default().with_depth(4).with_kernel_depth(Some(9));
        assert!(p.validate().is_err());
        assert!(p.clone().with_width(Some(0.01)).validate().is_ok());
        let p = p.with_width(Some(0.01)).with_kernel_depth(Some(17));
        assert!(p.validate().is_err());
    }
}

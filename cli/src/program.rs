//! The programs `psr` and `psr-mpi` (`src/main.rs`, `src/bin/psr-mpi.rs`), which share their
//! options and all their code but the MPI start-up: this crate's library.
//!
//! `psr`: reconstructs a watertight triangle mesh from a point cloud, oriented or not.
//!
//! ```text
//! psr --in cloud.ply --out mesh.ply [--depth 8 | --width W] [--full-depth 5] [--kernel-depth N]
//!     [--samples-per-node 1.5] [--scale 1.1] [--point-weight 4] [--screening-follows-noise true]
//!     [--threads 0] [--iters 60]
//!     [--tolerance 1e-2] [--boundary neumann|free|dirichlet] [--splatting bspline|trilinear]
//!     [--vertices fitted|on-isosurface] [--normals auto|estimate|reorient] [--neighbors 20]
//!     [--orientation propagate|viewpoint|sensors|reconstruction] [--viewpoint X,Y,Z]
//!     [--reconstruction-iterations 10] [--confidence]
//!     [--no-density] [--no-attributes] [--vertex-normals] [--min-component-samples 8]
//!     [--trim | --trim-depth D | --trim-density W | --trim-quantile Q]
//!     [--min-piece-area F] [--min-piece-triangles N] [--colors] [--ascii] [--quiet] [--verbose]
//!     [--grid FILE.npy|FILE.raw [--grid-resolution N] [--grid-box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX]]
//!     [--max-memory SIZE] [--estimate-memory]
//! ```
//!
//! The input's colours and every other vertex property (but the ones psr interprets) are
//! carried onto the mesh's vertices, as PoissonRecon does, unless `--no-attributes`. The output
//! is the untrimmed, watertight mesh unless a `--trim*` option asks for it to be cut back to
//! where the points are (`psr::trim`).
//!
//! The file names' extensions (any case) say the formats: the input is PLY (`.ply`),
//! PoissonRecon's binary points (`.bnpts`) or ASCII points (`.npts`, `.xyz`; see `psr::npts`);
//! the output is PLY (`.ply`, binary unless `--ascii`) or Wavefront OBJ (`.obj`). Any other
//! extension is refused with the list of those accepted, so that a file never holds a format
//! its name denies. `psr --help` gives each option's PoissonRecon 18.75 equivalent
//! (`tests/cli.rs` checks that every option has one).
//!
//! `psr-mpi` (built with the `mpi` feature; `mpirun -n N psr-mpi --in scan.ply --out mesh.ply
//! ...`) takes the same options and always runs out of core, its N ranks sharing the slabs
//! (`psr::reconstruct_out_of_core_in_team`); rank 0 reports.
//!
//! Exit status: 0 on success, 2 for a usage or parameter error, 1 for an input/output or
//! reconstruction error, 3 when the reconstruction needs more memory than `--max-memory` (or
//! the system) allows.

#[cfg(target_os = "linux")]
pub mod allocator;

use std::ffi::OsString;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::builder::{OsStringValueParser, TypedValueParser};
use clap::{ArgGroup, Parser};
use psr::{
    npts, obj, ply, Boundary, Mesh, NormalEstimation, Orientation, Params, PointSet, Splatting,
    Stage, Threshold, Trimming, VertexPlacement,
};

/// Poisson surface reconstruction: turns a point cloud (PLY, or PoissonRecon's .bnpts or ASCII
/// points, with normals or without: psr estimates and orients them when they are missing) into a
/// watertight triangle mesh (PLY or OBJ).
///
/// Each option's help ends with its equivalent in Kazhdan's PoissonRecon 18.75, or says that
/// there is none.
#[derive(Parser, Debug)]
#[command(
    name = "psr",
    version,
    max_term_width = 100,
    after_help = "PoissonRecon 18.75 options not named above have no counterpart here, notably \
                  --degree (psr's B-splines have degree 2; PoissonRecon's default is 1). The \
                  --trim options stand for PoissonRecon's separate SurfaceTrimmer program run on \
                  its --density output.",
    group = ArgGroup::new("trimming").multiple(false)
)]
struct Args {
    /// Input point cloud, in the format its extension (any case) names: .ply, PLY (ASCII or
    /// binary) whose vertex element has x y z, and nx ny nz or see --normals; .bnpts,
    /// PoissonRecon's binary points, per point six little-endian float32 x y z nx ny nz (and
    /// three colour bytes with --colors); .npts or .xyz, ASCII, one point per line: x y z, or
    /// x y z nx ny nz, or x y z nx ny nz r g b with colours 0-255, the same on every line
    /// (blank lines and lines starting with # are skipped; positions whose digits say more
    /// than float32 holds, as georeferenced ones do, are kept in double, as a PLY's double x y
    /// z are, and the mesh is written with double x y z). PoissonRecon: --in (which reads
    /// every name but .ply and .bnpts as ASCII, its numbers in any line layout).
    #[arg(long = "in", value_name = "FILE", value_parser = OsStringValueParser::new().try_map(input_path))]
    input: PathBuf,

    /// Output mesh, in the format its extension (any case) names: .ply, binary little-endian
    /// PLY (ASCII with --ascii): vertex x y z; nx ny nz with --vertex-normals; value unless
    /// --no-density; the input's colours, in its type, and its other vertex properties as
    /// floats unless --no-attributes; face vertex_indices as int (uint past 2^31 vertices;
    /// PLY cannot index past 2^32, such a mesh is refused: write .obj). Or .obj, Wavefront
    /// OBJ: v x y z (v x y z r g b, 0-1, when coloured); vn with --vertex-normals; f with
    /// 1-based indices (no limit); no density or other properties. PoissonRecon: --out (PLY
    /// only).
    #[arg(long = "out", value_name = "FILE", value_parser = OsStringValueParser::new().try_map(output_path))]
    output: PathBuf,

    /// Maximum octree depth (1..=16): the finest cells are 2^-depth of the bounding cube.
    /// PoissonRecon: --depth.
    #[arg(long, value_name = "D", default_value_t = Params::default().depth)]
    depth: u32,

    /// Target width of the finest cells, in input units (> 0): chooses the depth instead of
    /// --depth (the smallest in 1..=16 whose cells, the bounding cube's side over 2^depth, are at
    /// most W wide); the depth used is printed. PoissonRecon: --width (which also overrides
    /// --depth when > 0).
    #[arg(long, value_name = "W")]
    width: Option<f64>,

    /// Depth down to which the octree is complete (0..=16; values above --depth act as it).
    /// PoissonRecon: --fullDepth.
    #[arg(long, alias = "fullDepth", value_name = "D", default_value_t = Params::default().full_depth)]
    full_depth: u32,

    /// Depth at which the sampling density is estimated (0..=depth) [default: depth - 2].
    /// PoissonRecon: --kernelDepth.
    #[arg(long, alias = "kernelDepth", value_name = "D")]
    kernel_depth: Option<u32>,

    /// Target number of samples per octree node (1..=1e6); higher is smoother for noisy data.
    /// PoissonRecon: --samplesPerNode (psr's count reads about 0.6 of PoissonRecon's, so the
    /// same value is about a third of a depth coarser, except where the surface bends under
    /// the density's kernel: there psr reads it as PoissonRecon does).
    #[arg(long, alias = "samplesPerNode", value_name = "N", default_value_t = Params::default().samples_per_node)]
    samples_per_node: f32,

    /// The bounding cube is the points' bounding box enlarged by this factor (1..=100).
    /// PoissonRecon: --scale.
    #[arg(long, value_name = "S", default_value_t = Params::default().scale)]
    scale: f32,

    /// Screening weight (0..=1e6): how strongly the surface is pulled onto the samples; 0 is the
    /// unscreened 2006 method. Default 2 × --degree (4 at psr's default degree 2, 2 at degree
    /// 1). The pull is scaled by 2^--depth, and at the depths finer than the samples' noise
    /// supports by that depth's 2^s (--screening-follows-noise, on by default). PoissonRecon:
    /// --pointWeight (default 2 × the B-spline degree there too: 2 for its default --degree 1).
    #[arg(long, alias = "pointWeight", value_name = "W")]
    point_weight: Option<f32>,

    /// Whether the screening follows the samples' noise: estimate how far the samples scatter
    /// across the surface (σ, printed with --verbose) and pull the depths finer than the one
    /// whose cells are 10 σ wide (s) with 2^s instead of 2^--depth, so that a high --depth
    /// does not pull the surface onto the noise (the coarser depths keep 2^--depth, which
    /// keeps small detached parts of a scan); exact samples keep 2^--depth, and so do clouds
    /// too sparse for the estimate to resolve the surface (it reads no noise there). With
    /// --out-of-core the same σ is estimated slab by slab. `--screening-follows-noise false`
    /// keeps 2^--depth at any noise (PoissonRecon's scale: on noisy scans the surface then
    /// follows the noise more with every depth past the samples'). PoissonRecon: none.
    #[arg(
        long,
        value_name = "BOOL",
        default_value_t = true,
        num_args = 0..=1,
        default_missing_value = "true",
        action = clap::ArgAction::Set
    )]
    screening_follows_noise: bool,

    /// Degree of the B-spline node functions: 2 (default; smooth gradient) or 1 (piecewise-linear,
    /// PoissonRecon's and Open3D's default: cheaper per unknown). Also sets the default
    /// --point-weight to 2 × degree. PoissonRecon: --degree
    #[arg(long, value_name = "1|2", default_value_t = Params::default().degree)]
    degree: u8,

    /// Worker threads; 0 = all cores. The result does not depend on it. PoissonRecon: none in
    /// 18.75 (it uses all cores).
    #[arg(long, value_name = "N", default_value_t = Params::default().threads)]
    threads: usize,

    /// Conjugate-gradient iterations per depth at most (1..=10000). PoissonRecon: --iters, in
    /// another unit (Gauss–Seidel relaxations per level of its multigrid solver, default 8).
    #[arg(long, value_name = "N", default_value_t = Params::default().max_solver_iterations)]
    iters: u32,

    /// Relative residual at which a depth's solve stops (1e-12 <= t < 1). PoissonRecon:
    /// --cgAccuracy (which applies to its coarsest levels' conjugate gradients only).
    #[arg(long, value_name = "T", default_value_t = Params::default().solver_tolerance)]
    tolerance: f64,

    /// Boundary condition at the bounding cube: neumann (PoissonRecon's and Open3D's default), free
    /// (the 2006 paper) or dirichlet (chi = 0 on the cube: for open scans such as terrain, rooms or
    /// tunnels, whose surface then closes inside the cube instead of running out to the cube's
    /// faces and being capped there). PoissonRecon: --bType (3 = neumann, 1 = free, 2 =
    /// dirichlet).
    #[arg(long, value_enum, default_value_t = BoundaryArg::Neumann)]
    boundary: BoundaryArg,

    /// Splatting weights: bspline (smoother, more accurate) or trilinear (the 2006 paper).
    /// PoissonRecon: none (it splats with degree-2 B-splines, as bspline).
    #[arg(long, value_enum, default_value_t = SplattingArg::Bspline)]
    splatting: SplattingArg,

    /// Where the vertices go: fitted (moved off the isosurface by the mean sag of their chords,
    /// so that the flat triangles straddle it) or on-isosurface (exactly on it). PoissonRecon:
    /// none (its vertices are on the isosurface, as on-isosurface).
    #[arg(long, value_enum, default_value_t = VerticesArg::Fitted)]
    vertices: VerticesArg,

    /// Where the normals come from: auto (the file's when it has nx ny nz, else estimated),
    /// estimate (estimated from the positions even when the file has normals), or reorient (the
    /// file's directions, their signs chosen again consistently, for normals whose sign is
    /// unreliable). PoissonRecon: none (it needs oriented points; its --normals writes vertex
    /// normals, see --vertex-normals).
    #[arg(long, value_enum, default_value_t = NormalsArg::Auto)]
    normals: NormalsArg,

    /// Neighbours per point for estimating and orienting normals (1..=1000; 10-30 is usual).
    /// PoissonRecon: none (Open3D's KDTreeSearchParamKNN counts the point itself).
    #[arg(long, value_name = "K", default_value_t = NormalEstimation::default().neighbors)]
    neighbors: usize,

    /// How estimated normals get their signs: propagate (consistent over each connected part,
    /// outward where a part encloses volume), viewpoint (facing --viewpoint, as for a single
    /// scan) or sensors (each facing its own point's sensor, e.g. the scanner origin of each
    /// scan or a mobile scanner's trajectory, read from the vertex properties sensor_x sensor_y
    /// sensor_z, or PCL's vp_x vp_y vp_z, or PDAL's beamoriginx beamoriginy beamoriginz), or
    /// reconstruction (read off a mesh reconstructed from the normals themselves, in rounds
    /// coarse to fine, from propagation's normals and from an arbitrary start, keeping the
    /// better fit: holds where propagation fails, at folds and lips a few sample spacings thick
    /// and on sparse clouds, and gives the normal's line too; costs a few reconstructions per
    /// depth, a second for thousands of points, minutes for a million). PoissonRecon: none
    /// (Open3D's orient_normals_consistent_tangent_plane /
    /// orient_normals_towards_camera_location; iPSR's program for reconstruction).
    #[arg(long, value_enum, default_value_t = OrientationArg::Propagate)]
    orientation: OrientationArg,

    /// The most rounds --orientation reconstruction runs at each depth (1..=1000; a depth ends
    /// sooner once almost no sign changes). PoissonRecon: none (iPSR's --iters).
    #[arg(
        long,
        value_name = "N",
        default_value_t = NormalEstimation::default().reconstruction_iterations
    )]
    reconstruction_iterations: u32,

    /// The scanner's position X,Y,Z for --orientation viewpoint (input coordinates); giving it
    /// alone selects that orientation (not with --orientation sensors). PoissonRecon: none.
    #[arg(long, value_name = "X,Y,Z", value_parser = point3, allow_hyphen_values = true)]
    viewpoint: Option<[f64; 3]>,

    /// Weigh each point by the input's `confidence` (or `value`) property. PoissonRecon:
    /// --confidence (which takes each point's weight from its normal's length instead).
    #[arg(long)]
    confidence: bool,

    /// Do not write the per-vertex density (`value` property) to the output. PoissonRecon: the
    /// inverse of --density (it writes the density only when asked).
    #[arg(long)]
    no_density: bool,

    /// Cut the surface back to where the points are, at the automatic threshold: half the
    /// sampling density below which 0.1 % of the points lie (the surface closing holes and
    /// wrapping open scenes goes; the points keep theirs). Without a --trim option the output
    /// is the untrimmed, watertight mesh. PoissonRecon: SurfaceTrimmer --trim (which needs a
    /// value; see --trim-depth).
    #[arg(long, group = "trimming")]
    trim: bool,

    /// Cut where PoissonRecon's depth-like density value falls below D (0..=32): the octree
    /// depth at which a node around the point would hold one sample; higher cuts more (7 is a
    /// usual start at depths 8-10). PoissonRecon: SurfaceTrimmer --trim D.
    #[arg(long, value_name = "D", group = "trimming")]
    trim_depth: Option<f32>,

    /// Cut where the sampling density (the output's `value`: samples per kernel-depth node)
    /// falls below W (>= 0). PoissonRecon: none (SurfaceTrimmer's value is depth-like).
    #[arg(
        long,
        value_name = "W",
        group = "trimming",
        allow_negative_numbers = true
    )]
    trim_density: Option<f32>,

    /// Cut away the least densely sampled fraction Q (0..=1) of the surface's area (more where a
    /// whole region shares one density, as a closing lid at 0 does). PoissonRecon: none.
    #[arg(long, value_name = "Q", group = "trimming")]
    trim_quantile: Option<f32>,

    /// With trimming, drop the pieces left by the cut whose area is under this fraction (0..=1)
    /// of the cut surface's [default: 0, keep every piece]. PoissonRecon: SurfaceTrimmer
    /// --aRatio (default 0.001 there).
    #[arg(long, value_name = "F", requires = "trimming")]
    min_piece_area: Option<f32>,

    /// With trimming, drop the pieces left by the cut with fewer than N triangles [default: 0].
    /// PoissonRecon: none.
    #[arg(long, value_name = "N", requires = "trimming")]
    min_piece_triangles: Option<u32>,

    /// Do not carry the input's colours (red green blue [alpha], or diffuse_red..., or r g b
    /// [a]) and its other vertex properties onto the mesh; by default every scalar vertex
    /// property but x y z, the normals, confidence/value and the sensor positions is carried,
    /// averaged over the samples around each vertex that face the same way. PoissonRecon: none
    /// (it always carries a PLY input's colours and other vertex data, and a raw input's
    /// colours under --colors; its --data is its pull factor for extrapolating them into holes
    /// from coarser depths, where psr fills holes from their rims along the surface).
    #[arg(long)]
    no_attributes: bool,

    /// The raw input's points have a colour after their normal: a .bnpts record is then 27
    /// bytes (six float32, then r g b as bytes) instead of 24, which the file cannot tell. An
    /// ASCII input is read by its count of numbers per line (9 = with colours) either way;
    /// with --colors it must have them. PLY inputs declare their colours in the header, so it
    /// changes nothing there. PoissonRecon: --colors.
    #[arg(long)]
    colors: bool,

    /// Apply this affine transform to the input points before reconstructing: a text file of 16
    /// numbers (whitespace or commas between them), a 4x4 matrix in row-major order, last row
    /// 0 0 0 1; positions become M p + t in double precision, normals M's inverse transpose
    /// times n, renormalised. Normals are estimated or re-oriented (--normals, --viewpoint,
    /// sensors) in the file's own frame, before the transform. The output is then written with
    /// double x y z when the transformed points are far from 0. PoissonRecon: --xForm (the same
    /// 16 numbers).
    #[arg(long, value_name = "FILE")]
    transform: Option<PathBuf>,

    /// Write a .ply output's x y z as double. Without it they are double when the input's x y z
    /// were (a PLY with double coordinates: psr then reads and reconstructs them in double, and
    /// the mesh keeps their precision, however far from 0), and float otherwise; an .obj output
    /// is text, written at full precision either way. PoissonRecon: --double (its build on
    /// double-precision reals; float x y z otherwise, whatever the input).
    #[arg(long)]
    double: bool,

    /// Write a .ply output as ASCII PLY (larger and slower than binary; for reading by eye or
    /// by tools without binary PLY). An .obj output is text anyway. PoissonRecon: --ascii.
    #[arg(long)]
    ascii: bool,

    /// Write a unit outward normal per vertex (nx ny nz, the gradient of the indicator
    /// function). PoissonRecon: --normals.
    #[arg(long)]
    vertex_normals: bool,

    /// Leave out every closed component of the surface but the largest that fewer than N input
    /// samples support (lie within one cell of it, at its own resolution): the tiny "bubbles"
    /// the level set can have beside the surface around a few stray samples. A real part of the
    /// scan carries its own samples and stays, however small. 0 keeps every component.
    /// PoissonRecon: none (it keeps them; its SurfaceTrimmer's --aRatio drops small pieces by
    /// area).
    #[arg(long, value_name = "N", default_value_t = Params::default().min_component_samples)]
    min_component_samples: u32,

    /// Also write the solved implicit function χ sampled on a regular N×N×N grid over the
    /// bounding cube, at the centres of its cells, as little-endian float32: .npy, a NumPy
    /// array of shape (N, N, N) indexed [x][y][z] (z fastest; numpy.load reads it), or .raw,
    /// the same values with no header. The surface is where χ equals the isovalue; χ minus
    /// it is negative inside. The cube (origin, size), the cell width and the isovalue are
    /// printed (not --quiet). PoissonRecon: --grid (which writes the resolution and a transform
    /// before the values).
    #[arg(long, value_name = "FILE", value_parser = OsStringValueParser::new().try_map(grid_path))]
    grid: Option<PathBuf>,

    /// Samples per axis of --grid (1..=4096) [default: 2^depth, at most 512]. PoissonRecon:
    /// none (its grid has 2^depth samples per axis).
    #[arg(long, value_name = "N", requires = "grid")]
    grid_resolution: Option<usize>,

    /// Sample --grid over this box instead of the bounding cube: its two corners
    /// XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX in input coordinates (min at most max on every axis; a side
    /// may have zero length, for a slice), N samples per axis at the centres of its cells.
    /// PoissonRecon: none.
    #[arg(
        long,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        value_parser = grid_box,
        requires = "grid",
        allow_hyphen_values = true
    )]
    grid_box: Option<([f64; 3], [f64; 3])>,

    /// The most memory the reconstruction may use: a number of bytes with an optional unit,
    /// K, M, G, T or KiB, MiB, GiB, TiB (powers of 1024), kB, MB, GB, TB (powers of 1000), B;
    /// e.g. 8G, 512M, 1.5GiB, 2000000000. psr counts its big arrays and checks them against the
    /// limit before allocating them (from the point count, then from the octree's node counts),
    /// and stops with exit status 3 and a message naming what needed how much, and the least
    /// limit that would do, rather than grow past it. 0 = no limit (the default). The limit
    /// covers the reconstruction, not reading the input or writing the mesh. PoissonRecon:
    /// none.
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    max_memory: Option<u64>,

    /// Reconstruct without holding the whole cloud, octree or mesh in memory: the input is read
    /// in chunks and binned across x into slabs in a temporary directory (--temp-dir), the
    /// coarse depths are solved once for the whole cloud and the fine ones slab by slab, and
    /// the mesh is written slab by slab into one PLY (seams closed, their vertices written
    /// once). The slabs' count follows --max-memory (the budget; a budget no cut fits is
    /// refused up front with the smallest workable one) or --slabs [default budget: half the
    /// machine's memory]. For clouds bigger than memory (docs/out-of-core.md): the mesh is the
    /// in-memory one to within the solver's tolerance. Needs a .ply input with normals and a
    /// .ply output; carries no colours or other properties, writes no vertex normals, and
    /// takes none of --grid, --trim*, --transform, --normals estimate|reorient. PoissonRecon:
    /// none (its distributed reconstruction is a separate client/server program).
    #[arg(long)]
    out_of_core: bool,

    /// With --out-of-core: cut the cloud into N slabs across x (fewer when the points fill
    /// fewer columns) instead of choosing their count from --max-memory. PoissonRecon: none.
    #[arg(long, value_name = "N", requires = "out_of_core")]
    slabs: Option<usize>,

    /// With --out-of-core: the depth up to which the system is solved once for the whole
    /// cloud (at least --full-depth, at most the depth − 2; finer depths are solved slab by
    /// slab, each with 24 columns of this depth + 2 of padding on each side) [default: depth
    /// − 3, at most 7; with --max-memory and no --slabs, from there up to the depth − 2, the
    /// one whose cut leaves each rank the least work, a finer one for thinner slabs].
    /// PoissonRecon: --baseDepth (of its distributed programs).
    #[arg(long, value_name = "D", requires = "out_of_core")]
    base_depth: Option<u32>,

    /// With --out-of-core: where to make the temporary directory (it needs about twice the
    /// points' size, 40 bytes a point, plus the mesh); removed on success, error and Ctrl-C
    /// alike [default: the system's temporary directory]. With psr-mpi, one every rank sees (on
    /// a cluster a shared file system, not a node's own /tmp; refused otherwise), as must be
    /// --out. PoissonRecon: --tempDir (of its distributed programs).
    #[arg(long, value_name = "DIR", requires = "out_of_core")]
    temp_dir: Option<PathBuf>,

    /// Print the memory the reconstruction is estimated to need (from the point count and the
    /// depth: an upper bound for scanned surfaces, see docs/benchmarks.md) and exit without
    /// reconstructing; --out is checked but not written. PoissonRecon: none.
    #[arg(long)]
    estimate_memory: bool,

    /// Print nothing but errors. PoissonRecon: none (it is quiet unless --verbose).
    #[arg(long, short, conflicts_with = "verbose")]
    quiet: bool,

    /// Also print the per-depth node counts and solves, the isovalue, and the peak memory after
    /// each stage. PoissonRecon: --verbose.
    #[arg(long, short)]
    verbose: bool,
}

/// A point given as `X,Y,Z` (three finite numbers).
fn point3(text: &str) -> Result<[f64; 3], String> {
    let parts = numbers(text)?;
    match parts[..] {
        [x, y, z] if parts.iter().all(|v| v.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("expected three finite numbers X,Y,Z, got '{text}'")),
    }
}

/// The comma-separated numbers of an option's value (`--viewpoint`, `--grid-box`).
fn numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("'{v}': {e}")))
        .collect()
}

/// The value of `--grid-box`: six finite numbers, the box's lower corner then its upper one,
/// the lower at most the upper on every axis.
fn grid_box(text: &str) -> Result<([f64; 3], [f64; 3]), String> {
    let parts = numbers(text)?;
    match parts[..] {
        [x0, y0, z0, x1, y1, z1] if parts.iter().all(|v| v.is_finite()) => {
            if x0 <= x1 && y0 <= y1 && z0 <= z1 {
                Ok(([x0, y0, z0], [x1, y1, z1]))
            } else {
                Err(format!(
                    "the lower corner ({x0}, {y0}, {z0}) is above the upper one ({x1}, {y1}, \
                     {z1}) on an axis"
                ))
            }
        }
        _ => Err(format!(
            "expected six finite numbers XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX, got '{text}'"
        )),
    }
}

/// The formats `--in` reads, by extension.
#[derive(Clone, Copy, Debug, PartialEq)]
enum InputFormat {
    /// PLY, ASCII or binary (`psr::ply`).
    Ply,
    /// PoissonRecon's binary points (`psr::npts::read_binary`).
    Bnpts,
    /// PoissonRecon's ASCII points (`psr::npts::read_ascii`).
    Ascii,
}

/// The extensions `--in` accepts (any case), in the order the messages list them.
const INPUT_EXTENSIONS: [(&str, InputFormat); 4] = [
    ("ply", InputFormat::Ply),
    ("bnpts", InputFormat::Bnpts),
    ("npts", InputFormat::Ascii),
    ("xyz", InputFormat::Ascii),
];

/// The formats `--out` writes, by extension.
#[derive(Clone, Copy, Debug, PartialEq)]
enum OutputFormat {
    /// PLY, binary or ASCII (`psr::ply::write_mesh_with`).
    Ply,
    /// Wavefront OBJ (`psr::obj::write_mesh`).
    Obj,
}

/// The extensions `--out` accepts (any case).
const OUTPUT_EXTENSIONS: [(&str, OutputFormat); 2] =
    [("ply", OutputFormat::Ply), ("obj", OutputFormat::Obj)];

/// The format of `path` among `known` by its extension (any case), or a message that lists
/// the extensions accepted: a name psr does not know is refused rather than guessed at.
fn format_of<F: Copy>(path: &Path, known: &[(&str, F)], what: &str) -> Result<F, String> {
    let list: Vec<String> = known.iter().map(|(ext, _)| format!(".{ext}")).collect();
    let list = match list.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    };
    match path.extension() {
        Some(ext) => known
            .iter()
            .find(|(known, _)| ext.eq_ignore_ascii_case(known))
            .map(|&(_, format)| format)
            .ok_or_else(|| {
                format!(
                    "{what} {list} files: give a file name ending in one of those, not .{}",
                    ext.to_string_lossy()
                )
            }),
        None => Err(format!(
            "{what} {list} files: give a file name ending in one of those"
        )),
    }
}

fn input_format(path: &Path) -> Result<InputFormat, String> {
    format_of(path, &INPUT_EXTENSIONS, "psr reads point clouds from")
}

fn output_format(path: &Path) -> Result<OutputFormat, String> {
    format_of(path, &OUTPUT_EXTENSIONS, "psr writes meshes to")
}

/// The formats `--grid` writes, by extension.
#[derive(Clone, Copy, Debug, PartialEq)]
enum GridFormat {
    /// NumPy's .npy, format version 1.0: a header giving dtype `<f4` and shape (N, N, N).
    Npy,
    /// The values alone.
    Raw,
}

/// The extensions `--grid` accepts (any case).
const GRID_EXTENSIONS: [(&str, GridFormat); 2] =
    [("npy", GridFormat::Npy), ("raw", GridFormat::Raw)];

fn grid_format(path: &Path) -> Result<GridFormat, String> {
    format_of(path, &GRID_EXTENSIONS, "psr writes grids to")
}

/// The value of `--grid`: a file whose name says a format psr writes grids in.
fn grid_path(name: OsString) -> Result<PathBuf, String> {
    let path = PathBuf::from(name);
    grid_format(&path).map(|_| path)
}

/// The largest default --grid-resolution (512³ float32 are 512 MiB).
const DEFAULT_GRID_RESOLUTION_CAP: u32 = 512;

/// The value of `--in`: a file whose name says a format psr reads.
fn input_path(name: OsString) -> Result<PathBuf, String> {
    let path = PathBuf::from(name);
    input_format(&path).map(|_| path)
}

/// The value of `--out`: a file whose name says a format psr writes (a mesh.stl that held PLY
/// would mislead whatever opens it).
fn output_path(name: OsString) -> Result<PathBuf, String> {
    let path = PathBuf::from(name);
    output_format(&path).map(|_| path)
}

impl Args {
    /// The parameters the options give; a parameter the library adds keeps its default here
    /// until it gets an option.
    fn params(&self) -> Params {
        let params = Params::default()
            .with_depth(self.depth)
            .with_width(self.width)
            .with_full_depth(self.full_depth)
            .with_kernel_depth(self.kernel_depth)
            .with_samples_per_node(self.samples_per_node)
            .with_scale(self.scale)
            .with_degree(self.degree);
        let params = match self.point_weight {
            Some(w) => params.with_point_weight(w),
            None => params,
        };
        params
            .with_screening_follows_noise(self.screening_follows_noise)
            .with_threads(self.threads)
            .with_max_solver_iterations(self.iters)
            .with_solver_tolerance(self.tolerance)
            .with_boundary(match self.boundary {
                BoundaryArg::Neumann => Boundary::Neumann,
                BoundaryArg::Free => Boundary::Free,
                BoundaryArg::Dirichlet => Boundary::Dirichlet,
            })
            .with_splatting(match self.splatting {
                SplattingArg::Bspline => Splatting::BSpline,
                SplattingArg::Trilinear => Splatting::Trilinear,
            })
            .with_vertex_placement(match self.vertices {
                VerticesArg::Fitted => VertexPlacement::Fitted,
                VerticesArg::OnIsosurface => VertexPlacement::OnIsosurface,
            })
            .with_vertex_normals(self.vertex_normals)
            .with_min_component_samples(self.min_component_samples)
            .with_max_memory(self.max_memory.filter(|&bytes| bytes > 0))
    }

    /// The trimming the options ask for, or `None` (the untrimmed mesh) when none does.
    fn trimming(&self) -> Option<Trimming> {
        let threshold = if self.trim {
            Threshold::Automatic
        } else if let Some(d) = self.trim_depth {
            Threshold::Depth(d)
        } else if let Some(w) = self.trim_density {
            Threshold::Density(w)
        } else if let Some(q) = self.trim_quantile {
            Threshold::Quantile(q)
        } else {
            return None;
        };
        let defaults = Trimming::default();
        Some(
            defaults
                .clone()
                .with_threshold(threshold)
                .with_min_piece_area(self.min_piece_area.unwrap_or(defaults.min_piece_area))
                .with_min_piece_triangles(
                    self.min_piece_triangles
                        .unwrap_or(defaults.min_piece_triangles),
                )
                .with_threads(self.threads),
        )
    }

    /// The option that set the [`Trimming`] field `name`.
    fn trim_option_of(&self, name: &str) -> &'static str {
        match name {
            "min_piece_area" => "--min-piece-area",
            "threads" => "--threads",
            _ if self.trim_depth.is_some() => "--trim-depth",
            _ if self.trim_density.is_some() => "--trim-density",
            _ if self.trim_quantile.is_some() => "--trim-quantile",
            _ => "--trim",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, clap::ValueEnum)]
enum NormalsArg {
    Auto,
    Estimate,
    Reorient,
}

#[derive(Clone, Copy, Debug, PartialEq, clap::ValueEnum)]
enum OrientationArg {
    Propagate,
    Viewpoint,
    Sensors,
    Reconstruction,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum BoundaryArg {
    Neumann,
    Free,
    Dirichlet,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum SplattingArg {
    Bspline,
    Trilinear,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum VerticesArg {
    Fitted,
    OnIsosurface,
}

/// Why the run failed, which decides the exit status.
enum Failure {
    /// Bad arguments or parameters (exit 2).
    Usage(String),
    /// Input, output or reconstruction failed (exit 1).
    Run(String),
    /// The reconstruction needed more memory than --max-memory or the system allowed (exit 3).
    OutOfMemory(String),
}

/// The program `psr`: its arguments from the command line, its exit status.
pub fn main() -> ExitCode {
    let args = Args::parse();
    exit_status(run(&args, &psr::Alone, &mut |_| {}), true)
}

/// The program `psr-mpi` run by one member of `team` (an MPI rank): `psr`'s arguments, always
/// out of core (`--out-of-core` is implied), with one slab per member unless `--slabs` or
/// `--max-memory` says otherwise (each member's budget). Only rank 0 shows progress and
/// reports, errors included (another member's named by its rank); every member returns the
/// same exit status. `on_stage` hears each stage of the run as it begins on this member (for
/// `psr-mpi --verbose`'s account of each stage).
pub fn main_in_team(team: &dyn psr::Team, on_stage: &mut dyn FnMut(Stage)) -> ExitCode {
    let mut argv: Vec<OsString> = std::env::args_os().collect();
    if !argv.iter().any(|a| a == "--out-of-core") {
        argv.insert(1.min(argv.len()), "--out-of-core".into());
    }
    let speaks = team.rank() == 0;
    // A usage error, --help or --version: said once, by rank 0, and every rank returns (so
    // that MPI is finalised everywhere).
    let mut args = match Args::try_parse_from(argv) {
        Ok(args) => args,
        Err(e) => {
            if speaks {
                let _ = e.print();
            }
            return ExitCode::from(e.exit_code() as u8);
        }
    };
    args.quiet |= !speaks;
    if args.slabs.is_none() && args.max_memory.is_none() {
        args.slabs = Some(team.size());
    }
    exit_status(run(&args, team, on_stage), speaks)
}

/// The exit status of a run's result, its error printed when `speaks`.
fn exit_status(result: Result<(), Failure>, speaks: bool) -> ExitCode {
    let (code, message) = match result {
        Ok(()) => return ExitCode::SUCCESS,
        Err(Failure::Usage(message)) => (2, message),
        Err(Failure::Run(message)) => (1, message),
        Err(Failure::OutOfMemory(message)) => (3, message),
    };
    if speaks {
        eprintln!("psr: error: {message}");
    }
    ExitCode::from(code)
}

/// Fills or re-orients `cloud`'s normals as `--normals` asks, reporting to `progress`, and says
/// where they came from.
fn oriented_normals(
    args: &Args,
    cloud: &mut ply::PlyPoints,
    progress: psr::Progress<'_>,
) -> Result<&'static str, Failure> {
    let orientation = match (&args.viewpoint, args.orientation) {
        (Some(_), OrientationArg::Sensors | OrientationArg::Reconstruction) => {
            return Err(Failure::Usage(format!(
                "--viewpoint and --orientation {} exclude each other: give one",
                if args.orientation == OrientationArg::Sensors {
                    "sensors"
                } else {
                    "reconstruction"
                }
            )))
        }
        (None, OrientationArg::Sensors) => match cloud.sensors.take() {
            Some(sensors) => Orientation::Sensors(sensors),
            None => {
                let conventions: Vec<String> = ply::SENSOR_PROPERTIES
                    .iter()
                    .map(|names| names.join(" "))
                    .collect();
                return Err(Failure::Usage(format!(
                    "--orientation sensors needs each point's sensor position, and {} has none: \
                     give its vertex element the properties {} (or use another --orientation)",
                    args.input.display(),
                    conventions.join(", or ")
                )));
            }
        },
        (Some(v), _) => Orientation::Viewpoint(*v),
        (None, OrientationArg::Viewpoint) => {
            return Err(Failure::Usage(
                "--orientation viewpoint needs --viewpoint X,Y,Z".to_string(),
            ))
        }
        (None, OrientationArg::Propagate) => Orientation::Propagate,
        (None, OrientationArg::Reconstruction) => Orientation::Reconstruction,
    };
    let options = NormalEstimation::default()
        .with_neighbors(args.neighbors)
        .with_orientation(orientation)
        .with_reconstruction_iterations(args.reconstruction_iterations)
        .with_threads(args.threads);
    let failed = |e: psr::Error| match e {
        psr::Error::InvalidParameter {
            name: "reconstruction_iterations",
            ..
        } => Failure::Usage(format!("{e} (option --reconstruction-iterations)")),
        psr::Error::InvalidParameter { .. } => Failure::Usage(format!("{e} (option --neighbors)")),
        _ => Failure::Run(format!("{}: normals: {e}", args.input.display())),
    };
    let has_normals = !cloud.normals.is_empty();
    match args.normals {
        NormalsArg::Auto if has_normals => Ok("normals from the file"),
        NormalsArg::Auto | NormalsArg::Estimate => {
            cloud.normals =
                psr::estimate_normals_with_progress(&cloud.positions, &options, progress)
                    .map_err(failed)?;
            Ok("normals estimated")
        }
        NormalsArg::Reorient if has_normals => {
            cloud.normals = psr::orient_normals_with_progress(
                &cloud.positions,
                &cloud.normals,
                &options,
                progress,
            )
            .map_err(failed)?;
            Ok("normals re-oriented")
        }
        NormalsArg::Reorient => Err(Failure::Usage(format!(
            "--normals reorient needs normals, and {} has no nx ny nz (use --normals estimate)",
            args.input.display()
        ))),
    }
}

fn run(args: &Args, team: &dyn psr::Team, on_stage: &mut dyn FnMut(Stage)) -> Result<(), Failure> {
    // Under a memory budget, freed pages are given back at once: the budget is planned from
    // psr's own accounting, which knows nothing of pages kept for reuse.
    #[cfg(target_os = "linux")]
    if args.max_memory.is_some_and(|bytes| bytes > 0) {
        allocator::keep_at_most(0);
    }
    let params = args.params();
    params.validate().map_err(|e| match &e {
        psr::Error::InvalidParameter { name, .. } => {
            Failure::Usage(format!("{e} (option --{})", option_of(name)))
        }
        _ => Failure::Usage(e.to_string()),
    })?;
    let trimming = args.trimming();
    if let Some(trimming) = &trimming {
        trimming.validate().map_err(|e| match &e {
            psr::Error::InvalidParameter { name, .. } => {
                Failure::Usage(format!("{e} (option {})", args.trim_option_of(name)))
            }
            _ => Failure::Usage(e.to_string()),
        })?;
    }
    check_output_dir(&args.output)?;
    if let Some(grid) = &args.grid {
        check_output_dir(grid)?;
        if let Some(n) = args.grid_resolution {
            if n == 0 || n > psr::MAX_GRID_RESOLUTION {
                return Err(Failure::Usage(format!(
                    "--grid-resolution {n} is out of range: give 1..={}",
                    psr::MAX_GRID_RESOLUTION
                )));
            }
        }
    }

    if args.out_of_core {
        return run_out_of_core(args, params, team, on_stage);
    }
    let show_progress = !args.quiet && std::io::stderr().is_terminal();
    let mut progress = ProgressLine::default();
    let start = Instant::now();
    let mut cloud = read_input(args)?;
    let normals_from = oriented_normals(args, &mut cloud, &mut |stage, fraction| {
        if show_progress {
            progress.update(stage, fraction);
        }
        true
    });
    progress.clear();
    let normals_from = normals_from?;
    let weights = if args.confidence {
        match &cloud.confidence {
            Some(c) => Some(c.as_slice()),
            None => {
                return Err(Failure::Usage(format!(
                    "--confidence was given but {} has no confidence (or value) property",
                    args.input.display()
                )))
            }
        }
    } else {
        None
    };
    let in_input = |e: psr::Error| Failure::Run(format!("{}: {e}", args.input.display()));
    let transform = match &args.transform {
        Some(path) => Some(read_transform(path)?),
        None => None,
    };
    let double_input = cloud.positions_f64.is_some();
    let mut points = PointSet::new();
    match (&transform, &cloud.positions_f64) {
        (Some(t), exact) => {
            let widened;
            let positions = match exact {
                Some(exact) => exact,
                None => {
                    widened = cloud
                        .positions
                        .iter()
                        .map(|p| p.map(f64::from))
                        .collect::<Vec<_>>();
                    &widened
                }
            };
            points
                .extend_transformed_weighted(positions, &cloud.normals, weights, t)
                .map_err(|e| match e {
                    psr::Error::InvalidTransform { .. } => Failure::Usage(format!(
                        "--transform {}: {e}",
                        args.transform.as_deref().unwrap_or(Path::new("")).display()
                    )),
                    e => in_input(e),
                })?
        }
        (None, Some(exact)) => points
            .extend_weighted_f64(exact, &cloud.normals, weights)
            .map_err(in_input)?,
        (None, None) => points
            .extend_weighted(&cloud.positions, &cloud.normals, weights)
            .map_err(in_input)?,
    }
    let color_type = cloud.color_type;
    if !args.no_attributes {
        if let Some(colors) = cloud.colors.take() {
            points = points.with_colors(colors).map_err(in_input)?;
        }
        for channel in std::mem::take(&mut cloud.channels) {
            points = points
                .with_channel(channel.name, channel.values)
                .map_err(in_input)?;
        }
    }
    drop(cloud);
    let read_seconds = start.elapsed().as_secs_f64();
    if args.verbose {
        eprintln!(
            "psr: read {} points from {} ({normals_from}) in {read_seconds:.2}s{}{}",
            points.len(),
            args.input.display(),
            if points.weights().is_some() {
                " (with confidence)"
            } else {
                ""
            },
            carried(&points)
        );
        eprintln!("psr: {params:?}");
    }

    if args.estimate_memory {
        let bytes = psr::estimate_memory(&points, &params).map_err(in_input)?;
        println!(
            "{bytes} bytes ({:.1} MiB): estimated peak memory of reconstructing {} points at \
             depth {}",
            bytes as f64 / (1u64 << 20) as f64,
            points.len(),
            params.depth
        );
        return Ok(());
    }

    let mut peaks: Vec<(Stage, u64)> = Vec::new();
    let start = Instant::now();
    let mut on_progress = |stage: Stage, fraction: f32| {
        if show_progress {
            progress.update(stage, fraction);
        }
        if args.verbose && fraction >= 1.0 {
            if let Some(kib) = peak_resident_kib() {
                match peaks.iter_mut().find(|(s, _)| *s == stage) {
                    Some(entry) => entry.1 = kib,
                    None => peaks.push((stage, kib)),
                }
            }
        }
        true
    };
    let result = if args.grid.is_some() {
        psr::reconstruct_with_implicit_and_progress(&points, &params, &mut on_progress)
            .map(|(mesh, implicit)| (mesh, Some(implicit)))
    } else {
        psr::reconstruct_with_progress(&points, &params, &mut on_progress).map(|m| (m, None))
    };
    progress.clear();
    let (mut mesh, implicit) = result.map_err(|e| match e {
        psr::Error::OutOfMemory { .. } => {
            Failure::OutOfMemory(format!("reconstruction failed: {e} (option --max-memory)"))
        }
        e => Failure::Run(format!("reconstruction failed: {e}")),
    })?;
    let reconstruct_seconds = start.elapsed().as_secs_f64();
    if let (Some(path), Some(implicit)) = (&args.grid, implicit) {
        write_grid(args, path, &implicit, mesh.stats.depth)?;
    }
    if let Some(trimming) = &trimming {
        let trimmed = psr::trim_with_progress(&mesh, trimming, &mut |stage, fraction| {
            if show_progress {
                progress.update(stage, fraction);
            }
            true
        });
        progress.clear();
        mesh = trimmed.map_err(|e| Failure::Run(format!("trimming failed: {e}")))?;
    }

    if args.no_density {
        mesh.densities = Vec::new();
    }
    let start = Instant::now();
    write_output(args, &mesh, color_type, double_input)?;
    let write_seconds = start.elapsed().as_secs_f64();

    if args.verbose {
        print_details(&mesh);
        if !peaks.is_empty() {
            let list: Vec<String> = peaks
                .iter()
                .map(|(stage, kib)| format!("{} {}", stage.name(), kib / 1024))
                .collect();
            eprintln!(
                "psr: peak resident MiB at the end of each stage: {}",
                list.join(" ")
            );
        }
    }
    if !args.quiet {
        eprintln!(
            "{}",
            summary(&mesh, reconstruct_seconds, read_seconds, write_seconds)
        );
    }
    Ok(())
}

/// `--out-of-core`: from the input file to the output file through `psr::reconstruct_out_of_core`.
fn run_out_of_core(
    args: &Args,
    params: Params,
    team: &dyn psr::Team,
    on_stage: &mut dyn FnMut(Stage),
) -> Result<(), Failure> {
    let mut refused: Vec<&str> = Vec::new();
    for (given, option) in [
        (args.grid.is_some(), "--grid"),
        (args.trimming().is_some(), "--trim*"),
        (args.transform.is_some(), "--transform"),
        (
            args.normals != NormalsArg::Auto,
            "--normals estimate|reorient",
        ),
        (args.vertex_normals, "--vertex-normals"),
        (args.estimate_memory, "--estimate-memory"),
        (args.ascii, "--ascii"),
        (args.no_density, "--no-density"),
    ] {
        if given {
            refused.push(option);
        }
    }
    if !refused.is_empty() {
        return Err(Failure::Usage(format!(
            "--out-of-core does not take {}",
            refused.join(", ")
        )));
    }
    if input_format(&args.input).map_err(Failure::Usage)? != InputFormat::Ply
        || output_format(&args.output).map_err(Failure::Usage)? != OutputFormat::Ply
    {
        return Err(Failure::Usage(
            "--out-of-core reads a .ply and writes a .ply".to_string(),
        ));
    }
    let params = if args.slabs.is_none() && params.max_memory.is_none() {
        params.with_max_memory(Some(physical_memory() / 2))
    } else {
        params
    };
    let options = psr::OutOfCore::default()
        .with_slabs(args.slabs)
        .with_base_depth(args.base_depth)
        .with_temp_dir(args.temp_dir.clone())
        .with_confidence(args.confidence);
    let show_progress = !args.quiet && std::io::stderr().is_terminal();
    let mut progress = ProgressLine::default();
    // Ctrl-C (or a SIGTERM) asks the run to stop at its next progress report, so that its
    // temporary directory (gigabytes for a large cloud) is removed before the program exits.
    stop_on_interrupt();
    let mut current: Option<Stage> = None;
    let result = psr::reconstruct_out_of_core_in_team(
        &args.input,
        &args.output,
        &params,
        &options,
        team,
        &mut |stage, fraction| {
            if current != Some(stage) {
                current = Some(stage);
                on_stage(stage);
            }
            if show_progress {
                progress.update(stage, fraction);
            }
            !INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed)
        },
    );
    progress.clear();
    if INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed) {
        if team.rank() == 0 {
            eprintln!("psr: interrupted; the temporary files are removed");
        }
        std::process::exit(130);
    }
    let report = result.map_err(|e| match e {
        psr::OutOfCoreError::Reconstruction(psr::Error::OutOfMemory { .. }) => {
            Failure::OutOfMemory(format!("reconstruction failed: {e} (option --max-memory)"))
        }
        psr::OutOfCoreError::Reconstruction(psr::Error::InvalidParameter { name, .. }) => {
            Failure::Usage(format!("{e} (option --{})", option_of(name)))
        }
        e => Failure::Run(format!("reconstruction failed: {e}")),
    })?;
    if !args.quiet {
        if report.attributes_dropped {
            eprintln!(
                "psr: warning: the points' colours and other properties are not carried out of core"
            );
        }
        eprintln!(
            "psr: {} points, depth {}, {} slabs, base depth {}: {} vertices, {} triangles in \
             {:.2}s{}",
            report.points,
            report.depth,
            report.slabs,
            report.base_depth,
            report.vertices,
            report.triangles,
            report.seconds,
            peak_resident_kib()
                .map(|kib| format!(", peak {} MiB", kib / 1024))
                .unwrap_or_default()
        );
        if args.verbose {
            eprintln!(
                "{}",
                screening_line(report.depth, report.screening_depth, report.sample_noise)
            );
            if report.noise_cells_beyond_padding > 0 {
                eprintln!(
                    "psr: {} cells of the noise estimate were wider than their slab's padding \
                     (fitted over the samples within it)",
                    report.noise_cells_beyond_padding
                );
            }
        }
    }
    Ok(())
}

/// The --verbose line on the screening's scale at the depths (2^depth, or 2^s finer than the
/// noise's depth s), and the noise that set s when the screening followed it.
fn screening_line(depth: u32, screening_depth: f64, sample_noise: Option<f64>) -> String {
    let noise = match sample_noise {
        Some(sigma) => format!(" (the samples' noise: {sigma:.4e} in input units)"),
        None => String::new(),
    };
    if screening_depth < depth as f64 {
        format!(
            "psr: screening weight scaled by 2^{depth} up to depth {}, by 2^{screening_depth:.2} \
             finer{noise}",
            screening_depth.floor()
        )
    } else {
        format!("psr: screening weight scaled by 2^{screening_depth:.2}{noise}")
    }
}

/// Set by [`stop_on_interrupt`]'s handler.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// From now on SIGINT and SIGTERM set [`INTERRUPTED`] instead of ending the process.
fn stop_on_interrupt() {
    extern "C" fn on_signal(_: libc::c_int) {
        // Only an atomic store: async-signal-safe.
        INTERRUPTED.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    let handler: extern "C" fn(libc::c_int) = on_signal;
    // SAFETY: the handler does nothing but an atomic store, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
        libc::signal(libc::SIGTERM, handler as libc::sighandler_t);
    }
}

/// The machine's physical memory in bytes (8 GiB when it cannot be read).
fn physical_memory() -> u64 {
    // SAFETY: sysconf reads system constants; it has no preconditions.
    let (pages, page) = unsafe {
        (
            libc::sysconf(libc::_SC_PHYS_PAGES),
            libc::sysconf(libc::_SC_PAGE_SIZE),
        )
    };
    if pages > 0 && page > 0 {
        (pages as u64).saturating_mul(page as u64)
    } else {
        8 << 30
    }
}

/// Reads the input in the format its name says.
fn read_input(args: &Args) -> Result<ply::PlyPoints, Failure> {
    let format = input_format(&args.input).map_err(Failure::Usage)?;
    match format {
        InputFormat::Ply => ply::read_points(&args.input).map_err(|e| Failure::Run(e.to_string())),
        InputFormat::Bnpts => npts::read_binary(&args.input, args.colors).map_err(|e| {
            Failure::Run(if e.kind() == std::io::ErrorKind::InvalidData {
                format!("{e} (.bnpts records are 24 bytes, 27 with --colors)")
            } else {
                e.to_string()
            })
        }),
        InputFormat::Ascii => {
            let cloud = npts::read_ascii(&args.input).map_err(|e| Failure::Run(e.to_string()))?;
            if args.colors && cloud.colors.is_none() && !cloud.is_empty() {
                return Err(Failure::Usage(format!(
                    "--colors was given but {} has no colours: a coloured point is \
                     x y z nx ny nz r g b, 9 numbers on a line",
                    args.input.display()
                )));
            }
            Ok(cloud)
        }
    }
}

/// Samples χ on the --grid and writes it in the format its name says.
fn write_grid(
    args: &Args,
    path: &Path,
    implicit: &psr::ImplicitFunction,
    depth: u32,
) -> Result<(), Failure> {
    let n = args
        .grid_resolution
        .unwrap_or(1usize << depth.min(DEFAULT_GRID_RESOLUTION_CAP.ilog2()));
    let start = Instant::now();
    let (origin, size) = implicit.cube();
    let (min, max) = args.grid_box.unwrap_or((origin, origin.map(|o| o + size)));
    let values = implicit
        .sample_box(min, max, n)
        .map_err(|e| Failure::Run(format!("--grid: {e} (option --grid-resolution)")))?;
    let format = grid_format(path).map_err(Failure::Usage)?;
    let mut bytes = match format {
        GridFormat::Npy => npy_header(n),
        GridFormat::Raw => Vec::new(),
    };
    bytes.reserve(4 * values.len());
    for v in &values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, &bytes)
        .map_err(|e| Failure::Run(format!("{}: cannot write the grid: {e}", path.display())))?;
    if !args.quiet {
        let region = match args.grid_box {
            Some(_) => format!(
                "the box from ({}, {}, {}) to ({}, {}, {}) (cell {} x {} x {})",
                min[0],
                min[1],
                min[2],
                max[0],
                max[1],
                max[2],
                (max[0] - min[0]) / n as f64,
                (max[1] - min[1]) / n as f64,
                (max[2] - min[2]) / n as f64
            ),
            None => format!(
                "the cube at ({}, {}, {}) of size {size} (cell {})",
                origin[0],
                origin[1],
                origin[2],
                size / n as f64
            ),
        };
        eprintln!(
            "psr: grid {n}x{n}x{n} of chi [x][y][z] (z fastest) written to {} in {:.2}s: cell \
             centres over {region}, isovalue {}",
            path.display(),
            start.elapsed().as_secs_f64(),
            implicit.isovalue()
        );
    }
    Ok(())
}

/// The header of a NumPy .npy file (format version 1.0) holding a C-order float32 array of
/// shape (n, n, n): magic, version, header length, then the header dictionary padded with
/// spaces and ended by a newline so that the data starts at a multiple of 64 bytes.
fn npy_header(n: usize) -> Vec<u8> {
    let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({n}, {n}, {n}), }}");
    let unpadded = 10 + dict.len() + 1;
    let padding = (64 - unpadded % 64) % 64;
    let header_len = u16::try_from(dict.len() + padding + 1).expect("a header under 200 bytes");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&header_len.to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.extend(std::iter::repeat_n(b' ', padding));
    bytes.push(b'\n');
    bytes
}

/// Writes the mesh in the format the output's name says.
/// Reads `--transform`'s file: 16 numbers, a row-major 4×4 matrix.
fn read_transform(path: &Path) -> Result<[[f64; 4]; 4], Failure> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Failure::Usage(format!("--transform {}: {e}", path.display())))?;
    let numbers: Vec<f64> = text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|w| !w.is_empty())
        .map(|w| w.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| {
            Failure::Usage(format!("--transform {}: not a number: {e}", path.display()))
        })?;
    if numbers.len() != 16 {
        return Err(Failure::Usage(format!(
            "--transform {}: {} numbers, expected 16 (a 4x4 matrix, row-major)",
            path.display(),
            numbers.len()
        )));
    }
    Ok([0, 1, 2, 3].map(|r| [0, 1, 2, 3].map(|c| numbers[4 * r + c])))
}

fn write_output(
    args: &Args,
    mesh: &Mesh,
    color_type: ply::ColorType,
    double_input: bool,
) -> Result<(), Failure> {
    let format = output_format(&args.output).map_err(Failure::Usage)?;
    let written = match format {
        OutputFormat::Ply => {
            let options = ply::WriteOptions::default()
                .with_double_positions(args.double || double_input)
                .with_color_type(color_type)
                .with_format(if args.ascii {
                    ply::PlyFormat::Ascii
                } else {
                    ply::PlyFormat::BinaryLittleEndian
                });
            ply::write_mesh_with(&args.output, mesh, &options)
        }
        OutputFormat::Obj => {
            let mut left_out: Vec<String> = Vec::new();
            if !mesh.densities.is_empty() {
                left_out.push("the density (value)".to_string());
            }
            left_out.extend(mesh.channels.iter().map(|c| c.name.clone()));
            if args.verbose && !left_out.is_empty() {
                eprintln!(
                    "psr: OBJ has no place for {}; not written (a .ply output keeps them)",
                    left_out.join(", ")
                );
            }
            obj::write_mesh(&args.output, mesh)
        }
    };
    written.map_err(|e| Failure::Run(e.to_string()))
}

/// The attributes the points carry onto the mesh, for --verbose: "" or ", carrying colors
/// (RGB) and channels [a, b]".
fn carried(points: &PointSet) -> String {
    let mut parts = Vec::new();
    if let Some(colors) = points.colors() {
        parts.push(format!("colors ({} components)", colors.components()));
    }
    if !points.channels().is_empty() {
        let names: Vec<&str> = points.channels().iter().map(|c| c.name.as_str()).collect();
        parts.push(format!("channels [{}]", names.join(", ")));
    }
    if parts.is_empty() {
        String::new()
    } else {
        format!(", carrying {}", parts.join(" and "))
    }
}

/// The process's peak resident set so far (Linux: VmHWM in /proc/self/status), in KiB.
pub fn peak_resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The command-line option that sets the [`Params`] field `name`.
/// A --max-memory SIZE: a number (digits, an optional fraction) and an optional unit; see the
/// option's help.
fn parse_size(text: &str) -> Result<u64, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let value: f64 = number.parse().map_err(|_| {
        format!("{text:?} is not a size: give a number of bytes, e.g. 8G, 512M, 1.5GiB")
    })?;
    let factor: f64 = match unit.trim() {
        "" | "B" | "b" => 1.0,
        "K" | "k" | "KiB" => 1024.0,
        "M" | "m" | "MiB" => 1024f64.powi(2),
        "G" | "g" | "GiB" => 1024f64.powi(3),
        "T" | "t" | "TiB" => 1024f64.powi(4),
        "kB" | "KB" => 1e3,
        "MB" => 1e6,
        "GB" => 1e9,
        "TB" => 1e12,
        other => {
            return Err(format!(
                "unknown unit {other:?} in {text:?}: use B, K/KiB, M/MiB, G/GiB, T/TiB (1024s) or kB, MB, GB, TB (1000s)"
            ))
        }
    };
    let bytes = (value * factor).round();
    if !(bytes.is_finite() && bytes < u64::MAX as f64) {
        return Err(format!("{text:?} is too large a size"));
    }
    Ok(bytes as u64)
}

fn option_of(name: &str) -> String {
    match name {
        "max_solver_iterations" => "iters".to_string(),
        "solver_tolerance" => "tolerance".to_string(),
        other => other.replace('_', "-"),
    }
}

/// Fails early, before the long reconstruction, when the output cannot be created.
fn check_output_dir(output: &Path) -> Result<(), Failure> {
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Failure::Run(format!(
            "{}: cannot write the output: directory {} does not exist",
            output.display(),
            dir.display()
        )));
    }
    if output.is_dir() {
        return Err(Failure::Run(format!(
            "{}: cannot write the output: it is a directory",
            output.display()
        )));
    }
    Ok(())
}

/// The one-line report printed at the end of a run.
fn summary(mesh: &Mesh, reconstruct_seconds: f64, read_seconds: f64, write_seconds: f64) -> String {
    let stats = &mesh.stats;
    let stages: Vec<String> = stats
        .stage_seconds
        .iter()
        .map(|(stage, seconds)| format!("{} {seconds:.2}s", stage.name()))
        .collect();
    let trimmed = match &stats.trim {
        Some(t) => format!(
            " (trimmed at density {:.4}, depth-like {:.2}, in {:.2}s)",
            t.density, t.depth, t.seconds
        ),
        None => String::new(),
    };
    // The depth used (chosen by --width, or --depth), and the tree's finest where the samples'
    // density stopped it above that.
    let depth = if stats.finest_depth() < stats.depth {
        format!("depth {} (finest {})", stats.depth, stats.finest_depth())
    } else {
        format!("depth {}", stats.depth)
    };
    format!(
        "psr: {} points, {depth}, {} nodes, {} vertices, {} triangles{trimmed}; {}{}total \
         {reconstruct_seconds:.2}s (read {read_seconds:.2}s, write {write_seconds:.2}s)",
        stats.points,
        stats.total_nodes(),
        mesh.positions.len(),
        mesh.triangles.len(),
        stages.join(" "),
        if stages.is_empty() { "" } else { " " },
    )
}

/// The --verbose report: nodes and solve per depth, and the isovalue.
fn print_details(mesh: &Mesh) {
    let stats = &mesh.stats;
    let depths = stats.nodes_per_depth.len().max(
        stats
            .solves
            .iter()
            .map(|s| s.depth as usize + 1)
            .max()
            .unwrap_or(0),
    );
    let mut out = format!(
        "psr: depth {} used, octree to depth {}\n",
        stats.depth,
        stats.finest_depth()
    );
    out.push_str("psr: depth   unknowns  iterations  rel. residual  seconds\n");
    for depth in 0..depths {
        let nodes = stats.nodes_per_depth.get(depth).copied().unwrap_or(0);
        out.push_str(&format!("psr: {depth:>5} {nodes:>10}"));
        match stats.solves.iter().find(|s| s.depth as usize == depth) {
            Some(s) => out.push_str(&format!(
                " {:>11} {:>14.3e} {:>8.3}\n",
                s.iterations, s.relative_residual, s.seconds
            )),
            None => out.push_str(&format!(" {:>11} {:>14} {:>8}\n", "-", "-", "-")),
        }
    }
    out.push_str(&format!(
        "psr: memory accounting: {} bytes ({:.1} MiB) from the octree's {} nodes ({:?} per depth) and {} density slots\n",
        stats.estimated_memory,
        stats.estimated_memory as f64 / (1u64 << 20) as f64,
        stats.halo_nodes_per_depth.iter().sum::<usize>(),
        stats.halo_nodes_per_depth,
        stats.density_slots
    ));
    out.push_str(&screening_line(
        stats.depth,
        stats.screening_depth,
        stats.sample_noise,
    ));
    out.push('\n');
    out.push_str(&format!("psr: isovalue {}", stats.isovalue));
    out.push_str(&format!(
        "\npsr: {} unsupported components left out ({} triangles; --min-component-samples)",
        stats.unsupported_components, stats.unsupported_triangles
    ));
    if let Some(t) = &stats.trim {
        out.push_str(&format!(
            "\npsr: trimmed at density {} (depth-like {:.3}): {} crossings snapped onto \
             vertices, {} kept apart; {} pieces, {} dropped; area {:.6} -> {:.6}",
            t.density,
            t.depth,
            t.snapped_crossings,
            t.clamped_crossings,
            t.pieces,
            t.pieces_dropped,
            t.area_before,
            t.area_after
        ));
    }
    eprintln!("{out}");
}

/// The `\r[stage] NN%` line shown on a terminal.
#[derive(Default)]
struct ProgressLine {
    shown: Option<(Stage, u32)>,
}

impl ProgressLine {
    fn update(&mut self, stage: Stage, fraction: f32) {
        let percent = (fraction.clamp(0.0, 1.0) * 100.0) as u32;
        if self.shown == Some((stage, percent)) {
            return;
        }
        self.shown = Some((stage, percent));
        let mut err = std::io::stderr().lock();
        let _ = write!(err, "\r[{:<8}] {percent:>3}%", stage.name());
        let _ = err.flush();
    }

    fn clear(&mut self) {
        if self.shown.take().is_some() {
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r{:20}\r", "");
            let _ = err.flush();
        }
    }
}

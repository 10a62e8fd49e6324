/*
 * psr.h — the C API of psr, Poisson surface reconstruction (Kazhdan, Bolitho & Hoppe 2006, with
 * the screening of Kazhdan & Hoppe 2013).
 *
 * Typical use:
 *
 *     psr_reconstructor *r = NULL;
 *     psr_mesh *m = NULL;
 *     if (psr_reconstructor_new(&r) != PSR_STATUS_OK) abort();
 *     psr_reconstructor_set_depth(r, 8);
 *     psr_status s = psr_reconstructor_add_points(r, xyz, 0, nxyz, 0, n);
 *     if (s == PSR_STATUS_OK) s = psr_reconstructor_solve(r, &m);
 *     if (s != PSR_STATUS_OK)
 *         fprintf(stderr, "%s: %s\n", psr_status_string(s), psr_reconstructor_last_error(r));
 *     else
 *         use(psr_mesh_positions(m), psr_mesh_vertex_count(m),
 *             psr_mesh_triangles(m), psr_mesh_triangle_count(m));
 *     psr_mesh_free(m);
 *     psr_reconstructor_free(r);
 *
 * OWNERSHIP
 *   - Two opaque handles: psr_reconstructor (parameters + points, reusable) and psr_mesh (one
 *     result). Each psr_reconstructor_new has one psr_reconstructor_free; each mesh written by
 *     psr_reconstructor_solve or psr_mesh_trim has one psr_mesh_free. Both free functions
 *     accept NULL.
 *   - A mesh is independent of the reconstructor (or the mesh, for psr_mesh_trim) that made
 *     it: either may be freed first.
 *   - A third handle, psr_implicit, is the solved indicator function kept by
 *     psr_reconstructor_solve_implicit (with the mesh): evaluate it and its gradient at points,
 *     sample it on a grid. One psr_implicit_free each (NULL accepted); independent of the
 *     reconstructor and the mesh.
 *   - A fourth, psr_ply, is what psr_ply_read read of a PLY file (the psr program's reader):
 *     its vertices with every property and its faces as triangles, borrowed through its views
 *     until psr_ply_free. psr_mesh_write_ply writes a mesh with the program's writer.
 *   - psr_reconstructor_add_points, psr_reconstructor_add_point_arrays,
 *     psr_reconstructor_add_positions and its _seen_from and _with_sensors variants copy their
 *     input (positions, normals, weights, colours, channels and their names, sensors): free
 *     your arrays as soon as they return.
 *   - Pointers returned by psr_mesh_positions / _triangles / _densities / _normals / _colors /
 *     _channel / _channel_name are borrowed from the mesh and stay valid until psr_mesh_free.
 *     The psr_mesh_copy_* functions copy into your buffer instead, given its capacity. psr
 *     never hands you memory to free(); strings it returns are either static or owned by a
 *     handle.
 *
 * ERRORS
 *   - Every function that can fail returns a psr_status: PSR_STATUS_OK (0) or an error. The
 *     numbers are stable and never reused; psr_status_string(s) gives a static name for any int.
 *   - Results go to trailing out-parameters, written only on success: on failure they keep
 *     whatever they held.
 *   - psr_reconstructor_last_error(r) explains the last failed call on r in words: which
 *     argument was NULL, which point index was NaN, which parameter was out of range. The
 *     file functions (psr_ply_read, psr_mesh_write_ply) write their message into a buffer you
 *     pass instead, as no reconstructor is involved.
 *   - Input is checked at the boundary: NULL with a non-zero count, strides below one element,
 *     sizes that overflow, NaN or infinite coordinates, zero normals. A rejected batch of points
 *     is not appended at all; earlier batches stay.
 *   - No Rust panic ever crosses into your code. A bug caught inside psr returns
 *     PSR_STATUS_INTERNAL_ERROR and poisons the reconstructor: every later call on it but
 *     psr_reconstructor_last_error and psr_reconstructor_free returns
 *     PSR_STATUS_HANDLE_POISONED.
 *   - Setters check their value alone (any order works); solve checks that they agree.
 *   - Running out of memory is an error, never an abort: when the solve would need more than
 *     psr_reconstructor_set_max_memory allows (checked before the memory is allocated), or the
 *     system refuses one of its big allocations, it returns PSR_STATUS_OUT_OF_MEMORY (17), the
 *     message names what needed how many bytes and the limit, and the handle stays usable.
 *     psr_reconstructor_estimate_memory says beforehand how much a solve is expected to need.
 *
 * THREADING
 *   - psr keeps no global state. A handle may be moved between threads, but one handle must not
 *     be used from two threads at once. Different handles may be used concurrently on different
 *     threads, and give the same meshes as when run one after the other.
 *   - A psr_mesh is never modified after creation: its const functions may be called from
 *     several threads at once. So is a psr_implicit: psr_implicit_evaluate, _gradient and
 *     _sample_grid may run on one handle from many threads at once (each call starts its own
 *     worker threads for a large batch, as many as the solve had).
 *   - psr_reconstructor_solve runs on the calling thread and starts its own worker threads for
 *     the duration of the call (psr_reconstructor_set_threads; 0 = one per core). It never uses
 *     a thread pool of the host application, and the mesh does not depend on the thread count.
 *   - The progress callback is called only from inside psr_reconstructor_solve, on the thread
 *     that called it. Returning false cancels the solve (PSR_STATUS_CANCELLED).
 *
 * VERSIONING
 *   - PSR_VERSION_MAJOR / _MINOR / _PATCH give the version of this header; psr_version() and
 *     psr_version_major() / _minor() / _patch() give the version of the library loaded at run
 *     time. Both come from the one crate version.
 *   - The shared library's SONAME follows cargo-c: libpsr.so.0.MINOR while the major version is
 *     0 (any 0.x minor release may change the ABI), libpsr.so.MAJOR from 1.0 on.
 *   - The ABI grows by adding functions, never by changing a signature or a struct: parameters
 *     are set one by one (no config struct by value). The structs you fill in,
 *     psr_point_arrays (per-point weights, colours, channels) and psr_trim_options, are passed
 *     by pointer, begin with their own size and only ever grow at their end.
 *     psr_point_arrays: a caller compiled against an older header passes its smaller size and
 *     works (the fields it lacks count as absent); on a library older than its header a caller
 *     works as long as it leaves the fields that library does not know zero.
 *     psr_trim_options (struct_size set by psr_trim_options_init(&opts, sizeof opts)): the
 *     library reads the fields your struct has and takes the defaults for the rest, and
 *     refuses a newer struct only if it sets a field the library does not know.
 */

#ifndef PSR_H
#define PSR_H

/*
 * Generated by cbindgen from src/ffi/ and cbindgen.toml: do not edit.
 * Regenerate with scripts/gen_header.sh.
 */

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/**
 * How many steps [`quantiles`] divides the samples' density distribution into.
 */
#define QUANTILE_STEPS 1000

/**
 * Major version of the header you compiled against (the crate version's first number).
 * Compare with psr_version_major() to detect a header/library mismatch.
 */
#define PSR_VERSION_MAJOR 0

/**
 * Minor version of the header you compiled against.
 */
#define PSR_VERSION_MINOR 1

/**
 * Patch version of the header you compiled against.
 */
#define PSR_VERSION_PATCH 0

/**
 * psr_mesh_write_ply flag: write the body as text (`format ascii`) instead of binary
 * little-endian. PoissonRecon: --ascii.
 */
#define PSR_PLY_ASCII 1

/**
 * psr_mesh_write_ply flag: write binary big-endian instead of little-endian (not with
 * PSR_PLY_ASCII).
 */
#define PSR_PLY_BIG_ENDIAN 2

/**
 * psr_mesh_write_ply flag: write x y z as double: psr_mesh_origin + each position, added in
 * double. Without it they are written as float, unless the mesh's origin is not (0, 0, 0)
 * (points added in double far from 0), where float would lose what the origin keeps.
 * PoissonRecon: --double.
 */
#define PSR_PLY_DOUBLE_POSITIONS 4

/**
 * Crossings closer than this fraction of an edge to an end are moved onto the end, or where
 * that would pinch a vertex, to this distance from it. A fifth keeps every piece of a cut
 * triangle within a bounded shape ratio of its source (see `tests/trim.rs`) while moving the
 * contour by at most a fifth of an edge.
 */
#define SNAP 0.2

/**
 * What a fallible psr function reports. 0 is success; the numbers are stable and never reused:
 * new statuses get new numbers. Functions that receive a status from you (psr_status_string)
 * take it as an int, so any value is safe to pass.
 */
typedef enum {
    /**
     * Success.
     */
    PSR_STATUS_OK = 0,
    /**
     * A required pointer argument was NULL (the message names it).
     */
    PSR_STATUS_NULL_ARGUMENT = 1,
    /**
     * An argument is malformed: a stride smaller than 3 floats, a count whose byte length
     * overflows, a call from inside the handle's own progress callback (the message says which).
     */
    PSR_STATUS_INVALID_ARGUMENT = 2,
    /**
     * psr_reconstructor_solve was called on a reconstructor holding no points.
     */
    PSR_STATUS_EMPTY_INPUT = 3,
    /**
     * A position, of a point or of a sensor, has a NaN or infinite coordinate (the message says
     * which and gives its index in the batch).
     */
    PSR_STATUS_NON_FINITE_POSITION = 4,
    /**
     * A normal has a NaN or infinite component (the message gives its index in the batch).
     */
    PSR_STATUS_NON_FINITE_NORMAL = 5,
    /**
     * A normal has zero length (the message gives its index in the batch).
     */
    PSR_STATUS_ZERO_NORMAL = 6,
    /**
     * A parameter is outside its documented range (the message names it, its value and the
     * range), or two parameters disagree at solve time (kernel_depth > depth).
     */
    PSR_STATUS_INVALID_PARAMETER = 7,
    /**
     * The progress callback returned false.
     */
    PSR_STATUS_CANCELLED = 8,
    /**
     * A copy-out buffer is smaller than the data; nothing was written.
     */
    PSR_STATUS_BUFFER_TOO_SMALL = 9,
    /**
     * An earlier call on this reconstructor hit an internal error (a bug); the handle refuses
     * everything but psr_reconstructor_last_error and psr_reconstructor_free.
     */
    PSR_STATUS_HANDLE_POISONED = 10,
    /**
     * A bug in psr. If it came from a panic, the handle is now poisoned. Please report it with
     * the message and the input that triggered it.
     */
    PSR_STATUS_INTERNAL_ERROR = 11,
    /**
     * The operating system refused to start the solve's worker threads (a thread or process
     * limit, or no memory for their stacks). Nothing was computed and the handle stays usable:
     * set fewer threads (psr_reconstructor_set_threads) or free resources and try again.
     */
    PSR_STATUS_THREADS_UNAVAILABLE = 12,
    /**
     * A colour component or channel value given with a point is NaN or infinite (the message
     * names the colours or the channel and gives the point's index in the batch).
     */
    PSR_STATUS_NON_FINITE_ATTRIBUTE = 13,
    /**
     * A confidence weight is negative, NaN or infinite (the message gives its index in the
     * batch), or, at solve, every weight is 0.
     */
    PSR_STATUS_INVALID_WEIGHT = 14,
    /**
     * A transform given with points (psr_reconstructor_add_points_transformed) has a NaN or
     * infinite entry, is not affine (last row not 0 0 0 1) or is singular (the message says
     * which).
     */
    PSR_STATUS_INVALID_TRANSFORM = 15,
    /**
     * The mesh would have more vertices, or the input more points, than 32-bit indices can
     * name (the message gives the count): reconstruct at a lower depth or in pieces.
     */
    PSR_STATUS_TOO_LARGE = 16,
    /**
     * The solve needs more memory than psr_reconstructor_set_max_memory allows (checked
     * before the memory is allocated: from the point count, then from the octree's node
     * counts), or the system refused an allocation. The message names what was being
     * allocated, the bytes needed, the limit and, when known, the smallest limit that would
     * do. Nothing was kept and the handle stays usable: raise the limit, lower the depth or
     * free memory, and solve again (the same mesh as a handle that never failed).
     */
    PSR_STATUS_OUT_OF_MEMORY = 17,
    /**
     * A file could not be opened, read, created or written (psr_ply_read, psr_mesh_write_ply):
     * the message has the path and the system's reason (no such file, permission denied, disk
     * full).
     */
    PSR_STATUS_IO_ERROR = 18,
    /**
     * A file was read but is not what it should be (psr_ply_read): not PLY, a malformed header
     * or value, a truncated body, no vertex element or no x y z, a face index out of range. The
     * message says where (line, element, entry).
     */
    PSR_STATUS_INVALID_FILE = 19,
} psr_status;

/**
 * The pipeline stages reported to the progress callback, numbered in pipeline order except
 * PSR_STAGE_NORMALS, which comes first (only when points were added without normals).
 * psr_stage_string gives their names.
 */
typedef enum {
    /**
     * Copying the points and mapping them into the unit cube.
     */
    PSR_STAGE_POINTS = 0,
    /**
     * Estimating the sampling density (it decides the depths the octree needs).
     */
    PSR_STAGE_DENSITY = 1,
    /**
     * Building the octree.
     */
    PSR_STAGE_OCTREE = 2,
    /**
     * Splatting the normals into the vector field.
     */
    PSR_STAGE_SPLAT = 3,
    /**
     * Assembling the linear system.
     */
    PSR_STAGE_SYSTEM = 4,
    /**
     * Solving it, depth by depth.
     */
    PSR_STAGE_SOLVE = 5,
    /**
     * Computing the isovalue.
     */
    PSR_STAGE_ISOVALUE = 6,
    /**
     * Extracting the isosurface.
     */
    PSR_STAGE_EXTRACT = 7,
    /**
     * Assembling the output mesh.
     */
    PSR_STAGE_MESH = 8,
    /**
     * Estimating and orienting the normals of the points added with
     * psr_reconstructor_add_positions, before all the others (numbered last because it was
     * added later).
     */
    PSR_STAGE_NORMALS = 9,
    /**
     * Trimming a mesh (psr_mesh_trim with psr_trim_options.progress set); never reported by
     * psr_reconstructor_solve.
     */
    PSR_STAGE_TRIM = 10,
} psr_stage;

/**
 * Boundary conditions at the bounding cube, for psr_reconstructor_set_boundary.
 */
typedef enum {
    /**
     * Zero normal derivative on the cube's faces (the default; PoissonRecon --bType 3, Open3D).
     */
    PSR_BOUNDARY_NEUMANN = 0,
    /**
     * The 2006 paper: node functions simply end beyond the cube (PoissonRecon --bType 1).
     */
    PSR_BOUNDARY_FREE = 1,
    /**
     * chi = 0 on the cube's faces, which are then outside the surface: an open scan (terrain,
     * room, tunnel) closes on itself inside the cube instead of running out to the faces and
     * being capped there as with Neumann (PoissonRecon --bType 2; no Open3D or PCL
     * equivalent). Costs the same as Neumann.
     */
    PSR_BOUNDARY_DIRICHLET = 2,
} psr_boundary;

/**
 * Splatting weights, for psr_reconstructor_set_splatting.
 */
typedef enum {
    /**
     * The node functions' own B-spline weights over 3x3x3 nodes (the default; smoother and
     * more accurate, about 1.6x the time).
     */
    PSR_SPLATTING_BSPLINE = 0,
    /**
     * The 2006 paper's trilinear weights over the 8 nearest nodes.
     */
    PSR_SPLATTING_TRILINEAR = 1,
} psr_splatting;

/**
 * Where the mesh's vertices go, for psr_reconstructor_set_vertex_placement.
 */
typedef enum {
    /**
     * Found on the isosurface, then moved along the normal by the mean sag of the chords they
     * end, so that the flat triangles straddle the curved surface (the default; closer to the
     * surface and to the input points).
     */
    PSR_VERTEX_PLACEMENT_FITTED = 0,
    /**
     * Exactly on the isosurface {chi = isovalue}, as PoissonRecon places them.
     */
    PSR_VERTEX_PLACEMENT_ON_ISOSURFACE = 1,
} psr_vertex_placement;

/**
 * How the normals psr estimates get their signs (psr_reconstructor_set_normal_orientation).
 */
typedef enum {
    /**
     * Consistent over each connected part of the cloud by propagation along a minimum spanning
     * tree (Hoppe et al. 1992), outward where a part encloses volume. The default. Open3D
     * orient_normals_consistent_tangent_plane.
     */
    PSR_ORIENTATION_PROPAGATE = 0,
    /**
     * Facing the point set with psr_reconstructor_set_viewpoint (a single scan's scanner).
     * Open3D orient_normals_towards_camera_location, PCL setViewPoint.
     */
    PSR_ORIENTATION_VIEWPOINT = 1,
    /**
     * Each normal facing its own point's sensor, the scanner position given with the point by
     * psr_reconstructor_add_positions_seen_from (one per batch, e.g. per scan of a registered
     * multi-scan cloud) or psr_reconstructor_add_positions_with_sensors (one per point, e.g.
     * a mobile scanner's trajectory); those functions select it. Every point added without
     * normals must then have a sensor (psr_reconstructor_solve checks). PCL
     * flipNormalTowardsViewpoint with each point's vp_x vp_y vp_z; Open3D has none.
     */
    PSR_ORIENTATION_SENSORS = 2,
    /**
     * Read off the reconstruction itself, repeated (iterative Poisson reconstruction, Hou et
     * al. 2022): in rounds, coarse to fine, the points are reconstructed with their current
     * normals and each takes the normal of the mesh's triangles nearest it, from two starts
     * (propagation's normals and an arbitrary one), keeping the one whose mesh fits the points
     * better. Holds where propagation fails (folds and lips a few sample spacings thick, sparse
     * clouds) and gives the normal's line too, at the cost of a few reconstructions per depth
     * up to the depth of the points' spacing (at most 10): a second for thousands of points,
     * minutes for a million. psr_reconstructor_set_normal_reconstruction_iterations bounds the
     * rounds per depth. Open3D, PCL, PoissonRecon: none.
     */
    PSR_ORIENTATION_RECONSTRUCTION = 3,
} psr_orientation;

/**
 * What psr_trim_options.threshold_value means (psr_trim_options.threshold).
 */
typedef enum {
    /**
     * Half the density below which 0.1 % of the input samples lie: the surface is cut a little
     * beyond the edges of the sparsest sampled regions, and at most about 0.1 % of the samples
     * lose the surface around them. threshold_value is ignored. The default.
     */
    PSR_TRIM_THRESHOLD_AUTOMATIC = 0,
    /**
     * threshold_value is a density (the unit of psr_mesh_densities: samples per kernel-depth
     * node), finite and >= 0; 0 keeps everything.
     */
    PSR_TRIM_THRESHOLD_DENSITY = 1,
    /**
     * threshold_value is a fraction q in [0, 1] of the mesh's area: the cut is at the lowest
     * density below which at least that much of the area lies (more goes where a whole region
     * shares one density, such as a lid far from every sample, at 0).
     */
    PSR_TRIM_THRESHOLD_QUANTILE = 2,
    /**
     * threshold_value is PoissonRecon's depth-like value d in [0, 32] (its --density output
     * and SurfaceTrimmer --trim): the density 4^(d - kernel depth).
     */
    PSR_TRIM_THRESHOLD_DEPTH = 3,
} psr_trim_threshold;

/**
 * The solved indicator function χ of one reconstruction, with its isovalue and bounding cube.
 * Created by psr_reconstructor_solve_implicit, destroyed by psr_implicit_free; independent of
 * the reconstructor and the mesh. Never modified: its functions may be called from several
 * threads at once. Opaque to C.
 */
typedef struct psr_implicit psr_implicit;

/**
 * A reconstructed triangle mesh. Created by psr_reconstructor_solve (or psr_mesh_trim, from
 * another mesh), destroyed by psr_mesh_free; independent of the reconstructor or mesh that
 * made it. Opaque to C.
 */
typedef struct psr_mesh psr_mesh;

/**
 * What psr_ply_read read of a PLY file: its vertices (positions; normals, colours,
 * confidence or `value`, sensor positions and other scalar properties when present) and its
 * faces as triangles. Created by psr_ply_read, destroyed by psr_ply_free; never changed in
 * between, so any number of threads may read one at once. Opaque to C.
 */
typedef struct psr_ply psr_ply;

/**
 * A reusable reconstruction: parameters, accumulated points, an optional progress callback and
 * the message of the last failed call. Created by psr_reconstructor_new, destroyed by
 * psr_reconstructor_free. Opaque to C.
 */
typedef struct psr_reconstructor psr_reconstructor;

/**
 * A progress callback: receives your user pointer, the current stage and the fraction of that
 * stage done (0 to 1, not necessarily reaching 1), and returns true to go on or false to cancel
 * (psr_reconstructor_solve then returns PSR_STATUS_CANCELLED and no mesh).
 *
 * It is called only from inside psr_reconstructor_solve (or psr_mesh_trim, when set in its
 * psr_trim_options; the same rules hold there, with PSR_STAGE_TRIM), on the thread that called
 * it, never concurrently with itself. It is called while each stage runs, not only between
 * stages: the stage's work runs on psr's worker threads while the calling thread waits in
 * slices of at most 20 ms and calls it after each slice with the fraction of the stage done so
 * far (within a stage never less than the call before), then with 1 when the stage ends; so a
 * host that polls for a "stop" (a Cancel button, Ctrl-C) from the callback sees it within
 * about 20 ms plus the callback's own time. After it returns false it is not called again: the
 * stage stops at its next cancel point (docs/architecture.md lists them: batches of work
 * milliseconds apart, down to the bricks of the splat, the system and the solver and the
 * finest depth's octree passes; on a million points at depth 11 every stop measured returned
 * within 0.17 s on a 2-core machine at load 3, within 0.26 s at load 5-8) and
 * psr_reconstructor_solve returns once the reconstruction's memory is freed. The mesh never
 * depends on the callback. It must not call any function on the reconstructor being solved
 * (such calls are refused with PSR_STATUS_INVALID_ARGUMENT, and psr_reconstructor_free does
 * nothing); it may use other handles, psr_status_string, psr_stage_string and the version
 * functions. It must not unwind (no C++ exception or longjmp out of it).
 */
typedef bool (*psr_progress_fn)(void *user, psr_stage stage, float fraction);

/**
 * Options of psr_mesh_trim. Fill it with psr_trim_options_init(&opts, sizeof opts), which
 * writes the defaults and struct_size, then change the fields you need. Fields are only ever
 * added at the end: a program built with this header keeps working with later libraries, and
 * a later program with this library as long as it leaves the fields this header lacks at
 * their defaults (zero).
 */
typedef struct {
    /**
     * The size of this struct as your header defines it (sizeof(psr_trim_options)); set by
     * psr_trim_options_init. It tells the library which fields you have.
     */
    size_t struct_size;
    /**
     * A psr_trim_threshold: how threshold_value is read. Default PSR_TRIM_THRESHOLD_AUTOMATIC.
     */
    int32_t threshold;
    /**
     * Worker threads for the trim; 0 = one per core. Default 0. The result does not depend on
     * it.
     */
    uint32_t threads;
    /**
     * The threshold, in the unit psr_trim_threshold gives it; ignored for
     * PSR_TRIM_THRESHOLD_AUTOMATIC. Default 0.
     */
    double threshold_value;
    /**
     * Pieces left by the cut with less than this fraction of the cut surface's area are
     * dropped; range [0, 1]. Default 0 (every piece kept: pieces left near samples are small
     * sampled parts). PoissonRecon's SurfaceTrimmer --aRatio (default 0.001 there).
     */
    float min_piece_area;
    /**
     * Pieces of fewer triangles than this are dropped too. Default 0.
     */
    uint32_t min_piece_triangles;
    /**
     * A progress callback for the trim, or NULL (the default) for none: called as for
     * psr_reconstructor_solve (see psr_progress_fn) with PSR_STAGE_TRIM, on the thread that
     * called psr_mesh_trim, at least every 20 ms while the cut runs, then with 1; returning
     * false cancels (psr_mesh_trim returns PSR_STATUS_CANCELLED and no mesh, within a step of
     * the cut: 9 steps, each a parallel pass over the mesh). A struct from a header without
     * this field ends before it: then no callback is called.
     */
    psr_progress_fn progress;
    /**
     * Passed as the callback's first argument; the library never reads it. Default NULL.
     */
    void *progress_user_data;
} psr_trim_options;

/**
 * Points for psr_reconstructor_add_point_arrays: positions and normals, and optionally a
 * confidence weight, a colour and named float channels per point. Every array is read with a
 * byte stride (0 = tightly packed; otherwise at least one element, so interleaved vertex
 * structs work; no alignment is required).
 *
 * Always initialise it with psr_point_arrays_init(&a, sizeof a), which zeroes it (every
 * optional array absent) and sets struct_size; then set the fields you use. New fields will
 * only ever be added at the end, and a zero field always means "absent", so code compiled
 * against this header keeps working with later versions of the library.
 */
typedef struct {
    /**
     * The size of the struct as the caller's header declares it (psr_point_arrays_init sets
     * it).
     */
    size_t struct_size;
    /**
     * Number of points.
     */
    size_t count;
    /**
     * Point i's position is the 3 floats at (const char *)positions + i * position_stride_bytes.
     * Required (unless count is 0).
     */
    const float *positions;
    /**
     * 0 (12 bytes) or at least 12.
     */
    size_t position_stride_bytes;
    /**
     * Point i's normal, 3 floats (need not be unit length). Required (unless count is 0):
     * points without normals go through psr_reconstructor_add_positions.
     */
    const float *normals;
    /**
     * 0 (12 bytes) or at least 12.
     */
    size_t normal_stride_bytes;
    /**
     * Point i's confidence weight, 1 float, finite and >= 0 (PoissonRecon --confidence):
     * how much the point counts, in the surface and in the colours. NULL: every point 1.
     */
    const float *confidence;
    /**
     * 0 (4 bytes) or at least 4.
     */
    size_t confidence_stride_bytes;
    /**
     * Point i's colour, color_components floats (red, green, blue[, alpha]), finite, in any
     * scale (0 to 1, or 0 to 255: the mesh's colours are weighted means of them). NULL: no
     * colours.
     */
    const float *colors;
    /**
     * 0 (color_components floats) or at least that.
     */
    size_t color_stride_bytes;
    /**
     * 3 (RGB) or 4 (RGBA) when colors is set; 0 when it is NULL.
     */
    size_t color_components;
    /**
     * Point i's channel values: channel_count floats, finite, in the order of channel_names.
     * Used when channel_count is not 0.
     */
    const float *channels;
    /**
     * 0 (channel_count floats) or at least that.
     */
    size_t channel_stride_bytes;
    /**
     * Number of channels per point (0: none).
     */
    size_t channel_count;
    /**
     * channel_count NUL-terminated UTF-8 names, distinct, non-empty and without whitespace
     * (each becomes a PLY property name). The names are copied.
     */
    const char *const *channel_names;
} psr_point_arrays;

/**
 * How one depth's linear solve ended (psr_mesh_solve_stats). Set struct_size to
 * sizeof(psr_depth_solve) before the call: it tells the library how much it may write.
 */
typedef struct {
    /**
     * The size of this struct as your header defines it (sizeof(psr_depth_solve)); set it
     * before calling psr_mesh_solve_stats, which leaves it as it is.
     */
    size_t struct_size;
    /**
     * The octree depth of this solve.
     */
    uint32_t depth;
    /**
     * Conjugate-gradient iterations run.
     */
    uint32_t iterations;
    /**
     * Unknowns (octree nodes) at this depth.
     */
    uint64_t unknowns;
    /**
     * |b - Ax| / |b| at the end (0 when b = 0).
     */
    double relative_residual;
    /**
     * Wall seconds for this depth (right-hand side, operator set-up and iterations).
     */
    double seconds;
} psr_depth_solve;

/**
 * What psr_reconstructor_solve_file_out_of_core did.
 */
typedef struct {
    /**
     * Points read from the input file.
     */
    uint64_t points;
    /**
     * Vertices written to the output file.
     */
    uint64_t vertices;
    /**
     * Triangles written to the output file.
     */
    uint64_t triangles;
    /**
     * Slabs the cloud was cut into.
     */
    uint64_t slabs;
    /**
     * The depth used (from the width when one is set).
     */
    uint32_t depth;
    /**
     * 1 when the points had colours or other properties, which this path does not carry.
     */
    uint32_t attributes_dropped;
    /**
     * Closed pieces left out for want of supporting samples (psr_reconstructor_set_min_component_samples).
     */
    uint64_t unsupported_components;
    /**
     * The isovalue.
     */
    double isovalue;
    /**
     * Seconds the run took.
     */
    double seconds;
} psr_out_of_core_report;

/**
 * The samples' noise as a reconstruction out of core measured it
 * (psr_reconstructor_out_of_core_noise): what psr_mesh_sample_noise and
 * psr_mesh_screening_depth tell of an in-memory mesh, which psr_out_of_core_report (a fixed
 * struct) has no room for.
 */
typedef struct {
    /**
     * The samples' positional noise sigma in input units (0 for exact samples of a smooth
     * surface), or NaN when the screening did not follow it
     * (psr_reconstructor_set_screening_follows_noise was false). The in-memory estimate of the
     * same cloud, bit for bit, when cells_beyond_padding is 0.
     */
    double sample_noise;
    /**
     * The noise's depth s of the screening weight, as psr_mesh_screening_depth: the depth
     * used when the samples read no noise or the screening did not follow it.
     */
    double screening_depth;
    /**
     * Cells of the estimate wider than their slab's padding, fitted from the samples within
     * it (0 unless the median sample lies about three depths coarser than the slabs' walls).
     */
    uint64_t cells_beyond_padding;
} psr_out_of_core_noise;



#ifdef __cplusplus
extern "C" {
#endif // __cplusplus

/**
 * The name of a status, e.g. "PSR_STATUS_ZERO_NORMAL", as a static NUL-terminated string
 * (never free it). Any int is accepted: unknown values give "PSR_STATUS_UNKNOWN". Never NULL.
 */
const char *psr_status_string(int status);

/**
 * The short lower-case name of a stage, e.g. "density", as a static NUL-terminated string
 * (never free it): "points", "density", "octree", "splat", "system", "solve", "isovalue",
 * "extract", "mesh", "normals" or "trim", in psr_stage's order. Any int is accepted: unknown
 * values give "unknown". Never NULL.
 */
const char *psr_stage_string(int stage);

/**
 * The library's version, "MAJOR.MINOR.PATCH", as a static NUL-terminated string (never free
 * it). Never NULL.
 */
const char *psr_version(void);

/**
 * The library's major version. A program compiled against PSR_VERSION_MAJOR.PSR_VERSION_MINOR
 * can check at run time that the library it loaded is ABI-compatible: for 0.x versions the
 * major and minor must both match; from 1.0 on the major must match and the minor be at least
 * the header's.
 */
uint32_t psr_version_major(void);

/**
 * The library's minor version (see psr_version_major).
 */
uint32_t psr_version_minor(void);

/**
 * The library's patch version (see psr_version_major).
 */
uint32_t psr_version_patch(void);

/**
 * Creates a reconstructor with every parameter at its default and no points, and writes it to
 * *out. Free it with psr_reconstructor_free.
 *
 * out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT (out is NULL) or
 * PSR_STATUS_INTERNAL_ERROR. On failure *out is left untouched.
 *
 * # Safety
 * `out` is NULL or valid for writing one pointer.
 */
psr_status psr_reconstructor_new(psr_reconstructor **out);

/**
 * Destroys a reconstructor, its points and its last message. Meshes it produced stay valid.
 * r may be NULL (nothing happens); poisoned handles are freed like any other. Calling it from
 * inside r's own progress callback does nothing.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new, not used again afterwards.
 */
void psr_reconstructor_free(psr_reconstructor *r);

/**
 * The message of the last failed call on r, naming the bad argument, index or parameter, or
 * "" when the last call on r succeeded. The string belongs to r: it stays valid until the next
 * call on r (any psr_reconstructor_* function but this one) and must not be freed. Works on
 * poisoned handles. If r is NULL, returns a static message saying so. Never NULL.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
const char *psr_reconstructor_last_error(const psr_reconstructor *r);

/**
 * Sets the maximum octree depth D: the finest cells are 2^-D of the bounding cube, so each
 * extra level gives about 4x the triangles. Default 8, range 1 to 16.
 * PoissonRecon --depth, PCL setDepth, Open3D depth.
 *
 * r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_PARAMETER (value out of range; the parameter keeps its value),
 * PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
 * or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_depth(psr_reconstructor *r, uint32_t depth);

/**
 * Writes the maximum octree depth to *out. r and out must not be NULL. Returns PSR_STATUS_OK,
 * PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called
 * from r's progress callback) or PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_depth(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets the target width of the finest cells, in input units, which then chooses the depth
 * instead of psr_reconstructor_set_depth: the smallest depth from 1 to 16 whose cells (the
 * bounding cube's side, the points' bounding box's longest side times the scale, over 2^depth)
 * are at most width wide; 16 when even those are wider. psr_mesh_depth reports the depth
 * used. 0 turns it off (the default: the depth decides); otherwise finite and > 0.
 * PoissonRecon --width (which, when > 0, likewise overrides --depth), Open3D's width argument
 * of create_from_point_cloud_poisson (ignored there when depth is given); PCL has none.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth (negative, NaN or
 * infinite: PSR_STATUS_INVALID_PARAMETER).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_width(psr_reconstructor *r, double width);

/**
 * Writes the target width of the finest cells to *out, 0 when it is off (the depth decides).
 * r and out must not be NULL. Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_width(const psr_reconstructor *r, double *out);

/**
 * Sets the depth down to which the octree is complete, so the coarse solution is defined
 * everywhere. Default 5, range 0 to 16 (values above depth act as depth).
 * PoissonRecon --fullDepth, PCL setMinDepth.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_full_depth(psr_reconstructor *r, uint32_t full_depth);

/**
 * Writes the full depth to *out. r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_full_depth(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets the depth at which the sampling density is estimated. A negative value (the default,
 * -1) means automatic: depth - 2, at least 0. Range: negative, or 0 to 16; it must not exceed
 * depth, which psr_reconstructor_solve checks (PSR_STATUS_INVALID_PARAMETER), so setters may
 * come in any order; with a width set (psr_reconstructor_set_width) a larger value acts as
 * the depth the width chooses. PoissonRecon --kernelDepth.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_kernel_depth(psr_reconstructor *r, int32_t kernel_depth);

/**
 * Writes the kernel depth to *out: -1 when automatic, else the depth that was set (not the
 * resolved automatic value). r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_kernel_depth(const psr_reconstructor *r, int32_t *out);

/**
 * Sets the target number of samples per octree node: sparser samples are splatted at coarser
 * depths, which smooths noisy input. Default 1.5, range 1 to 1e6.
 * PoissonRecon --samplesPerNode, PCL setSamplesPerNode (psr's count reads about 0.6 of
 * PoissonRecon's, so the same value is about a third of a depth coarser, except where the
 * surface bends under the density's kernel: there psr reads it as PoissonRecon does).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth (NaN and infinities
 * give PSR_STATUS_INVALID_PARAMETER).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_samples_per_node(psr_reconstructor *r, float samples_per_node);

/**
 * Writes the samples per node to *out. r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_samples_per_node(const psr_reconstructor *r, float *out);

/**
 * Sets the ratio between the reconstruction cube and the points' bounding box. Default 1.1,
 * range 1 to 100. PoissonRecon --scale, PCL setScale, Open3D scale.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_scale(psr_reconstructor *r, float scale);

/**
 * Writes the scale to *out. r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_scale(const psr_reconstructor *r, float *out);

/**
 * Sets the screening weight alpha (Kazhdan & Hoppe 2013): how strongly the surface is pulled
 * onto the samples; 0 gives the unscreened 2006 method. Default 4 (2 x the default degree 2;
 * psr_reconstructor_set_degree sets it to 2 x the degree), range 0 to 1e6. The pull is
 * scaled by 2^depth, and at the depths finer than the samples' noise supports by that
 * depth's 2^s (psr_reconstructor_set_screening_follows_noise, on by default). PoissonRecon
 * --pointWeight, PCL setPointWeight.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_point_weight(psr_reconstructor *r, float point_weight);

/**
 * Writes the screening weight to *out. r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_point_weight(const psr_reconstructor *r, float *out);

/**
 * Sets whether the screening follows the samples' noise: the reconstruction estimates how far
 * the samples scatter across the surface (sigma, psr_mesh_sample_noise) and pulls the depths
 * finer than the one whose cells are 10 sigma wide (s, psr_mesh_screening_depth) with alpha
 * 2^s instead of alpha 2^depth, so that a high depth does not pull the surface onto the
 * noise (the coarser depths keep alpha 2^depth, which keeps small detached parts of a scan);
 * exact samples keep 2^depth; so do clouds too sparse for the estimate to resolve the surface
 * (it reads no noise there). Out of core (psr_reconstructor_solve_file_out_of_core) the slabs
 * estimate the same sigma from their parts (psr_reconstructor_out_of_core_noise). Default true
 * (it was false before the 2026-12-06 build).
 * false keeps 2^depth at any noise, the scale of SPSR and PoissonRecon: on noisy clouds the
 * surface then follows the noise more with every depth past the samples' own (farther from
 * the true surface and from samples held out of the reconstruction, closer to the points it
 * was fitted to; psr's docs/benchmarks.md, issue 16). No PoissonRecon, Open3D or PCL
 * equivalent.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_vertex_normals.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_screening_follows_noise(psr_reconstructor *r, bool follows);

/**
 * Writes whether the screening follows the samples' noise to *out. r and out must not be
 * NULL. Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_screening_follows_noise(const psr_reconstructor *r, bool *out);

/**
 * Sets the degree of the B-spline node functions: 2 (the default; a smooth gradient) or 1
 * (piecewise-linear, PoissonRecon's and Open3D's default; cheaper per unknown). Also sets the
 * screening weight to 2 x degree (PoissonRecon's default for that degree): call
 * psr_reconstructor_set_point_weight after this for another weight. PoissonRecon --degree,
 * PCL setDegree.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for any value but 1 and 2, leaving the degree and the
 * screening weight as they were).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_degree(psr_reconstructor *r, int32_t degree);

/**
 * Writes the B-spline degree (1 or 2) to *out. r and out must not be NULL. Returns the
 * statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_degree(const psr_reconstructor *r, int32_t *out);

/**
 * Sets the number of worker threads psr_reconstructor_solve uses; 0 (the default) means one
 * per core. Each solve starts and stops its own workers: psr never uses a global or
 * host-provided thread pool, and the mesh does not depend on this count. Range 0 to 4096.
 * Open3D n_threads, PCL setThreads.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_threads(psr_reconstructor *r, uint32_t threads);

/**
 * Writes the thread count to *out (0 = one per core). r and out must not be NULL. Returns the
 * statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_threads(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets the most conjugate-gradient iterations per depth. Default 60, range 1 to 10000.
 * PoissonRecon --iters (counts Gauss-Seidel sweeps, not the same unit).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_max_solver_iterations(psr_reconstructor *r, uint32_t iterations);

/**
 * Writes the most solver iterations per depth to *out. r and out must not be NULL. Returns
 * the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_max_solver_iterations(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets the relative residual |b - Ax| / |b| at which a depth's solve stops. Default 1e-2,
 * range 1e-12 (inclusive) to 1 (exclusive). PoissonRecon --cgAccuracy (coarsest level only).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_solver_tolerance(psr_reconstructor *r, double tolerance);

/**
 * Writes the solver tolerance to *out. r and out must not be NULL. Returns the statuses of
 * psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_solver_tolerance(const psr_reconstructor *r, double *out);

/**
 * Sets the boundary condition: PSR_BOUNDARY_NEUMANN (0, the default), PSR_BOUNDARY_FREE (1)
 * or PSR_BOUNDARY_DIRICHLET (2, for open scans). PoissonRecon --bType (3, 1 and 2).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for any other value).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_boundary(psr_reconstructor *r, int32_t boundary);

/**
 * Writes the boundary condition (a psr_boundary value) to *out. r and out must not be NULL.
 * Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_boundary(const psr_reconstructor *r, int32_t *out);

/**
 * Sets the splatting weights: PSR_SPLATTING_BSPLINE (0, the default) or
 * PSR_SPLATTING_TRILINEAR (1, the 2006 paper's).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for any other value).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_splatting(psr_reconstructor *r, int32_t splatting);

/**
 * Writes the splatting weights (a psr_splatting value) to *out. r and out must not be NULL.
 * Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_splatting(const psr_reconstructor *r, int32_t *out);

/**
 * Sets where the mesh's vertices go: PSR_VERTEX_PLACEMENT_FITTED (0, the default: moved off the
 * isosurface by the mean sag of their chords, so that the triangles straddle it) or
 * PSR_VERTEX_PLACEMENT_ON_ISOSURFACE (1: exactly on it, as PoissonRecon places them).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for any other value).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_vertex_placement(psr_reconstructor *r, int32_t placement);

/**
 * Writes where the vertices go (a psr_vertex_placement value) to *out. r and out must not be
 * NULL. Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_vertex_placement(const psr_reconstructor *r, int32_t *out);

/**
 * Sets the fewest input samples that must lie within one cell of a closed component of the
 * surface (the finest cell, or its mean edge length where it was meshed coarser) for it to stay
 * in the mesh (the largest component always stays): the level
 * set's tiny "bubbles" beside the surface, around a few stray samples, are left out, while a
 * real part of the scan, however small, carries its own samples. Default 8; 0 keeps every
 * component. psr_mesh_unsupported_components tells how many were left out. No PoissonRecon
 * equivalent.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_min_component_samples(psr_reconstructor *r, uint32_t samples);

/**
 * Writes the fewest samples a closed component needs to stay (see
 * psr_reconstructor_set_min_component_samples) to *out. r and out must not be NULL. Returns
 * the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_min_component_samples(const psr_reconstructor *r, uint32_t *out);

/**
 * Appends `count` oriented points to r. Position i is the 3 floats at
 * `(const char *)positions + i * position_stride_bytes`, normal i likewise; a stride of 0 means
 * tightly packed (12 bytes), otherwise it must be at least 12 (interleaved vertex structs are
 * fine; no alignment is required). Normals need not be unit length; they are normalised.
 *
 * The points are copied: the arrays may be freed as soon as this returns. Calls append, so a
 * cloud can be added in batches. The batch is checked whole first: if any position is NaN or
 * infinite, or any normal is NaN, infinite or zero, nothing from this batch is appended, points
 * from earlier batches stay, and the message names the first bad index within this batch.
 *
 * Per-point confidence weights, colours and channels come through
 * psr_reconstructor_add_point_arrays, whose struct begins with its own size; this signature
 * never changes.
 *
 * r must not be NULL; positions and normals may be NULL only when count is 0 (then nothing
 * happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
 * stride below 12, count * stride overflowing, or points before in r carry colours or
 * channels, which these would lack), PSR_STATUS_NON_FINITE_POSITION,
 * PSR_STATUS_NON_FINITE_NORMAL, PSR_STATUS_ZERO_NORMAL, PSR_STATUS_HANDLE_POISONED or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
 * strided spans described above.
 */
psr_status psr_reconstructor_add_points(psr_reconstructor *r, const float *positions, size_t position_stride_bytes, const float *normals, size_t normal_stride_bytes, size_t count);

/**
 * psr_reconstructor_add_points with positions in double precision: 3 doubles per position
 * (position_stride_bytes 0 = packed, 24 bytes, else at least 24), normals in float as there.
 * The reconstructor keeps the doubles, fits the bounding cube to them and returns a mesh whose
 * float positions are relative to a round origin near the points (psr_mesh_origin;
 * psr_mesh_copy_positions_f64 gives the vertices in double, in the input's coordinates), so
 * coordinates far from 0, such as georeferenced scans 10^6 m away, keep the precision of the
 * object's own size. Coordinates must also be within float range (|c| < 3.4e38). Costs 24
 * more bytes per point held, for every point of r, once any batch came in double.
 *
 * r must not be NULL; positions and normals may be NULL only when count is 0. Returns the
 * statuses of psr_reconstructor_add_points (a stride below 24 for positions is
 * PSR_STATUS_INVALID_ARGUMENT).
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
 * strided spans described above.
 */
psr_status psr_reconstructor_add_points_f64(psr_reconstructor *r, const double *positions, size_t position_stride_bytes, const float *normals, size_t normal_stride_bytes, size_t count);

/**
 * psr_reconstructor_add_points_f64 with an affine transform applied to the batch first:
 * transform is 16 doubles, a 4x4 matrix in row-major order (element 4 * row + column), so
 * position p becomes M p + t with M the upper-left 3x3 block and t its last column (elements
 * 3, 7 and 11); the last row (elements 12 to 15) must be exactly 0 0 0 1. Normals are transformed
 * by M's inverse transpose and renormalised (they stay perpendicular to the surface under
 * non-uniform scales and shears, and outward under reflections). For registering scans, each
 * with its pose, and placing local coordinates in a georeferenced frame; PoissonRecon's
 * --xForm (a file of the same 16 numbers, row-major).
 *
 * r must not be NULL; transform must not be NULL, even when count is 0 (it is checked then
 * too); positions and normals may be NULL only when count is 0. Returns the statuses of
 * psr_reconstructor_add_points_f64, and PSR_STATUS_INVALID_TRANSFORM for a NaN or infinite
 * entry, a last row other than 0 0 0 1, or a singular M (nothing from the batch is added).
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` and `normals` are NULL or valid for reads of the
 * strided spans described above; `transform` is NULL or valid for reads of 16 doubles.
 */
psr_status psr_reconstructor_add_points_transformed(psr_reconstructor *r, const double *positions, size_t position_stride_bytes, const float *normals, size_t normal_stride_bytes, size_t count, const double *transform);

/**
 * Writes the number of points r holds to *out (with and without normals). r and out must not
 * be NULL. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_HANDLE_POISONED,
 * PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback) or PSR_STATUS_INTERNAL_ERROR;
 * *out is written only on success.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_point_count(const psr_reconstructor *r, size_t *out);

/**
 * Removes every point from r, with and without normals, and their sensors (parameters, the
 * orientation among them, and the callback stay), so the handle can be reused for another
 * cloud. r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
 * or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_clear_points(psr_reconstructor *r);

/**
 * Sets (or, with callback NULL, removes) the progress callback of r. See psr_progress_fn for
 * when and on which thread it is called. user is passed back to it untouched and may be NULL.
 *
 * r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
 * or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `callback`, if set, is safe to call with `user` until it is
 * replaced or r is freed.
 */
psr_status psr_reconstructor_set_progress_callback(psr_reconstructor *r, psr_progress_fn callback, void *user);

/**
 * Reconstructs a watertight mesh from r's points and parameters and writes a new mesh to
 * *out; free it with psr_mesh_free. r keeps its points and parameters and may be solved again.
 * Runs on the calling thread, using the number of worker threads set with
 * psr_reconstructor_set_threads; the progress callback, if any, is called on the calling thread,
 * during every stage at least every 20 ms (see psr_progress_fn).
 *
 * r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_EMPTY_INPUT (no points), PSR_STATUS_INVALID_PARAMETER (kernel_depth > depth),
 * PSR_STATUS_CANCELLED (the callback returned false), PSR_STATUS_HANDLE_POISONED,
 * PSR_STATUS_INVALID_ARGUMENT (called from r's own progress callback, all points coincide, the
 * points added without normals cannot be given normals: fewer of them than the neighbour
 * count + 1, or all on a line, or PSR_ORIENTATION_SENSORS while some of them have no sensor,
 * or they meet points with colours or channels), PSR_STATUS_INVALID_WEIGHT (every confidence
 * weight is 0),
 * PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR (a bug; if it was a panic, r is
 * now poisoned). On failure *out is left untouched. Points added without normals get them (estimated and oriented, see
 * psr_reconstructor_add_positions) before the reconstruction starts.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writing one pointer.
 */
psr_status psr_reconstructor_solve(psr_reconstructor *r, psr_mesh **out);

#if defined(PSR_TEST_PANIC)
/**
 * Test hook, compiled only with the cargo feature "test-panic" (CMake: -DPSR_TEST_PANIC=ON):
 * makes the next psr_reconstructor_solve on r panic inside the library, which must come back
 * as PSR_STATUS_INTERNAL_ERROR and poison r. Never use it in applications.
 *
 * r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INVALID_ARGUMENT.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_debug_panic_next_solve(psr_reconstructor *r);
#endif

/**
 * Number of vertices of m; 0 if m is NULL.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
size_t psr_mesh_vertex_count(const psr_mesh *m);

/**
 * Number of triangles of m; 0 if m is NULL.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
size_t psr_mesh_triangle_count(const psr_mesh *m);

/**
 * The vertex positions of m, 3 floats (x, y, z) per vertex, in the input's coordinates less
 * psr_mesh_origin(m), which is (0, 0, 0) unless points were added in double
 * (psr_reconstructor_add_points_f64, psr_reconstructor_add_points_transformed); owned by m:
 * valid until psr_mesh_free(m), never to be freed or written. NULL if m is NULL or has no
 * vertices.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
const float *psr_mesh_positions(const psr_mesh *m);

/**
 * The triangles of m, 3 zero-based vertex indices per triangle, counter-clockwise seen from
 * outside (so face normals point out of the solid), owned by m: valid until psr_mesh_free(m).
 * NULL if m is NULL or has no triangles.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
const uint32_t *psr_mesh_triangles(const psr_mesh *m);

/**
 * The sampling density estimate at each vertex (one float per vertex), owned by m: valid until
 * psr_mesh_free(m). Low values mark surface invented far from any sample; psr_mesh_trim cuts
 * the surface back along a threshold of it (like PoissonRecon's SurfaceTrimmer). NULL if m is
 * NULL or has no vertices.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
const float *psr_mesh_densities(const psr_mesh *m);

/**
 * The isovalue the surface was extracted at (the indicator function's mean over the samples,
 * paper section 4.4). NaN if m is NULL.
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim).
 */
double psr_mesh_isovalue(const psr_mesh *m);

/**
 * Copies the vertex positions of m into dst: 3 * psr_mesh_vertex_count(m) floats.
 * capacity_floats is the number of floats dst can hold.
 *
 * m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
 */
psr_status psr_mesh_copy_positions(const psr_mesh *m, float *dst, size_t capacity_floats);

/**
 * Writes to out[0..3] the point m's positions are relative to, in the input's coordinates:
 * (0, 0, 0) unless points were added in double, else the centre of the reconstruction's
 * bounding cube rounded to a multiple of the smallest power of two at least the cube's side
 * (so a round number, and 0 for a cube near 0). A vertex is at origin + position; in float,
 * positions relative to it keep float's relative precision (6e-8) of the object's size
 * however far the object is from 0.
 *
 * m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
 * PSR_STATUS_INTERNAL_ERROR; out is written only on success.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes of 3 doubles.
 */
psr_status psr_mesh_origin(const psr_mesh *m, double *out);

/**
 * Copies the vertex positions of m into dst in double, in the input's coordinates
 * (psr_mesh_origin(m) + each float position, added in double): 3 * psr_mesh_vertex_count(m)
 * doubles. capacity_doubles is the number of doubles dst can hold. For points added in double,
 * the vertices as accurate as the reconstruction (not float's 6 cm steps at 10^6 m).
 *
 * m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_doubles` doubles.
 */
psr_status psr_mesh_copy_positions_f64(const psr_mesh *m, double *dst, size_t capacity_doubles);

/**
 * Copies the triangles of m into dst: 3 * psr_mesh_triangle_count(m) vertex indices.
 * capacity_indices is the number of uint32_t dst can hold.
 *
 * m must not be NULL; dst may be NULL only when the mesh has no triangles. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_indices` values.
 */
psr_status psr_mesh_copy_triangles(const psr_mesh *m, uint32_t *dst, size_t capacity_indices);

/**
 * Copies the per-vertex densities of m into dst: psr_mesh_vertex_count(m) floats.
 * capacity_floats is the number of floats dst can hold.
 *
 * m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
 */
psr_status psr_mesh_copy_densities(const psr_mesh *m, float *dst, size_t capacity_floats);

/**
 * Destroys a mesh and its arrays; pointers from psr_mesh_positions and the like become invalid.
 * m may be NULL (nothing happens).
 *
 * # Safety
 * `m` is NULL or a live mesh (from psr_reconstructor_solve or psr_mesh_trim), not used
 * again afterwards.
 */
void psr_mesh_free(psr_mesh *m);

/**
 * Appends `count` points without normals to r: position i is the 3 floats at
 * `(const char *)positions + i * position_stride_bytes` (0 = packed). psr_reconstructor_solve
 * estimates their normals from these positions (a plane through each point and its nearest
 * neighbours, see psr_reconstructor_set_normal_neighbors), orients them (see
 * psr_reconstructor_set_normal_orientation) and reconstructs them together with the points added
 * with normals. Use it for a scanner's or photogrammetry's x y z export; add all of one cloud's
 * unoriented points before solving, since the neighbourhoods are found among them. When the
 * scanner's position is known, add the points with psr_reconstructor_add_positions_seen_from
 * or psr_reconstructor_add_positions_with_sensors instead.
 *
 * The positions are copied; the batch is checked whole first (a NaN or infinite coordinate
 * appends nothing and the message names its index in this batch). psr_reconstructor_point_count
 * counts these points too and psr_reconstructor_clear_points removes them. The estimation is
 * reported to the progress callback as PSR_STAGE_NORMALS (before PSR_STAGE_POINTS) and may be
 * cancelled there like any stage; it takes about 2 s per million points per core.
 *
 * r must not be NULL; positions may be NULL only when count is 0. Returns PSR_STATUS_OK,
 * PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a stride below 12, or count * stride
 * overflowing), PSR_STATUS_NON_FINITE_POSITION, PSR_STATUS_HANDLE_POISONED or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` is NULL or valid for reads of the strided span
 * described above.
 */
psr_status psr_reconstructor_add_positions(psr_reconstructor *r, const float *positions, size_t position_stride_bytes, size_t count);

/**
 * Appends `count` points without normals that one sensor saw, e.g. one scan of a registered
 * multi-scan cloud: like psr_reconstructor_add_positions, and `sensor` points to the 3 floats
 * x, y, z of the scanner's origin in the points' coordinates. psr_reconstructor_solve turns
 * each estimated normal to face its point's sensor (n · (sensor − p) ≥ 0), which is right
 * wherever the sensor could see the point, thin walls and parts that touch included, where
 * propagation can fail. Call it once per scan.
 *
 * Selects PSR_ORIENTATION_SENSORS, which needs a sensor for every point added without normals:
 * psr_reconstructor_solve refuses a mix with points from psr_reconstructor_add_positions
 * (PSR_STATUS_INVALID_ARGUMENT, naming the first point without a sensor). Choosing another
 * orientation afterwards (psr_reconstructor_set_normal_orientation,
 * psr_reconstructor_set_viewpoint) keeps the sensors but does not use them.
 *
 * The positions and the sensor are copied; the batch is checked whole first (nothing is
 * appended and the orientation is unchanged if a position or the sensor has a NaN or infinite
 * coordinate; the message says which). psr_reconstructor_clear_points removes the points and
 * their sensors.
 *
 * r must not be NULL; positions and sensor may be NULL only when count is 0 (then nothing
 * happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
 * stride below 12, or count * stride overflowing), PSR_STATUS_NON_FINITE_POSITION (a point's
 * or the sensor's coordinate), PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` is NULL or valid for reads of the strided span
 * described above; `sensor` is NULL or valid for reads of 3 floats.
 */
psr_status psr_reconstructor_add_positions_seen_from(psr_reconstructor *r, const float *positions, size_t position_stride_bytes, size_t count, const float *sensor);

/**
 * Appends `count` points without normals, each with the position of the sensor that saw it,
 * e.g. a mobile scanner's trajectory sampled at each shot: like
 * psr_reconstructor_add_positions_seen_from, but sensor i is the 3 floats at
 * `(const char *)sensors + i * sensor_stride_bytes` (0 = packed; interleaved x y z sx sy sz
 * records work with both strides 24). When a batch of points shares one sensor,
 * psr_reconstructor_add_positions_seen_from says so without repeating it.
 *
 * Selects PSR_ORIENTATION_SENSORS, with the same rule for points without sensors as
 * psr_reconstructor_add_positions_seen_from. The arrays are copied and checked whole first
 * (a NaN or infinite coordinate in either appends nothing, and the message names its index in
 * this batch).
 *
 * r must not be NULL; positions and sensors may be NULL only when count is 0 (then nothing
 * happens). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (a
 * stride below 12, or count * stride overflowing), PSR_STATUS_NON_FINITE_POSITION (a point's
 * or a sensor's coordinate), PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `positions` and `sensors` are NULL or valid for reads of the
 * strided spans described above.
 */
psr_status psr_reconstructor_add_positions_with_sensors(psr_reconstructor *r, const float *positions, size_t position_stride_bytes, const float *sensors, size_t sensor_stride_bytes, size_t count);

/**
 * Sets how many nearest neighbours (besides the point itself) fit each estimated normal's plane
 * and link the points for orientation. Default 20, range 1 to 1000 (10 to 30 is usual; at
 * least 3 for a plane): more smooths noise and bridges uneven sampling, fewer keeps sharp edges
 * and thin parts apart. Open3D KDTreeSearchParamKNN (which counts the point itself), PCL
 * setKSearch.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_normal_neighbors(psr_reconstructor *r, uint32_t neighbors);

/**
 * Writes the neighbour count of normal estimation to *out. r and out must not be NULL. Returns
 * the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_normal_neighbors(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets how estimated normals get their signs: PSR_ORIENTATION_PROPAGATE (0, the default),
 * PSR_ORIENTATION_VIEWPOINT (1, facing the point given to psr_reconstructor_set_viewpoint,
 * which must be called first), PSR_ORIENTATION_SENSORS (2, each facing its point's sensor;
 * adding points with a sensor selects it, and psr_reconstructor_solve refuses it unless every
 * point added without normals has a sensor) or PSR_ORIENTATION_RECONSTRUCTION (3, read off
 * the reconstruction itself, repeated; see psr_orientation).
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for any other value, or for VIEWPOINT before a viewpoint).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_normal_orientation(psr_reconstructor *r, int32_t orientation);

/**
 * Writes the orientation of estimated normals (a psr_orientation value) to *out. r and out must
 * not be NULL. Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_normal_orientation(const psr_reconstructor *r, int32_t *out);

/**
 * Sets the most rounds PSR_ORIENTATION_RECONSTRUCTION runs at each depth (a depth ends sooner
 * once fewer than 0.01 % of the signs change in a round). Default 10, range 1 to 1000; each
 * round costs about a reconstruction at that depth. Ignored by the other orientations.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_normal_reconstruction_iterations(psr_reconstructor *r, uint32_t iterations);

/**
 * Writes the most rounds per depth of PSR_ORIENTATION_RECONSTRUCTION to *out. r and out must
 * not be NULL. Returns the statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_normal_reconstruction_iterations(const psr_reconstructor *r, uint32_t *out);

/**
 * Sets the viewpoint (x, y, z, in the points' coordinates, e.g. the scanner's position) that
 * estimated normals face, and selects PSR_ORIENTATION_VIEWPOINT (points' sensors, if any, are
 * kept but not used). The coordinates must be finite. For several scans, give each its own
 * sensor with psr_reconstructor_add_positions_seen_from instead. Open3D
 * orient_normals_towards_camera_location, PCL setViewPoint.
 *
 * r must not be NULL. Returns the statuses of psr_reconstructor_set_depth
 * (PSR_STATUS_INVALID_PARAMETER for a NaN or infinite coordinate).
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_viewpoint(psr_reconstructor *r, double x, double y, double z);

/**
 * Fills *opts (struct_size bytes, sizeof(psr_trim_options) as the caller's header defines it)
 * with the default options: every field it knows set to its default, any later field zeroed,
 * and opts->struct_size = struct_size. Pass sizeof of your struct, so that a newer library
 * never writes beyond it.
 *
 * opts must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_ARGUMENT (struct_size below sizeof(size_t) or above 4096; nothing is
 * written) or PSR_STATUS_INTERNAL_ERROR. Thread-safe.
 *
 * # Safety
 * `opts` is NULL or valid for writing `struct_size` bytes.
 */
psr_status psr_trim_options_init(psr_trim_options *opts, size_t struct_size);

/**
 * Cuts m back to where its sampling density is at least a threshold (psr_trim_options) and
 * writes the result to *out as a new mesh (free it with psr_mesh_free); m itself is left as
 * it is, so the untrimmed surface stays available. The cut follows the density's contour
 * across triangles; the result is a mesh with boundary: every edge in one or two triangles,
 * every vertex a single fan, oriented like m, with one density per vertex (interpolated on
 * the cut). Cutting everything away gives a mesh with no vertices, not an error.
 * psr_mesh_trim_density and psr_mesh_trim_depth give the threshold it was cut at. The Rust
 * API's psr::trim; PoissonRecon's SurfaceTrimmer.
 *
 * m and out must not be NULL; options may be NULL for the defaults (the automatic threshold,
 * every piece kept). Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_ARGUMENT (options->struct_size not set by psr_trim_options_init, or a
 * field this library does not know set to non-zero), PSR_STATUS_INVALID_PARAMETER (an unknown
 * threshold kind, or a value out of the range its field documents), PSR_STATUS_CANCELLED
 * (options->progress returned false), PSR_STATUS_THREADS_UNAVAILABLE or
 * PSR_STATUS_INTERNAL_ERROR. A mesh function keeps no message (there is no reconstructor to
 * keep it on). On failure *out is left untouched.
 *
 * Runs on the calling thread with its own worker threads (options->threads). m is only read:
 * several threads may trim (or read) the same mesh at once.
 *
 * # Safety
 * `m` is NULL or a live mesh; `options` is NULL or points to a psr_trim_options of
 * `options->struct_size` readable bytes, whose progress, if set, is safe to call with its
 * progress_user_data during the call; `out` is NULL or valid for writing one pointer.
 */
psr_status psr_mesh_trim(const psr_mesh *m, const psr_trim_options *options, psr_mesh **out);

/**
 * The density m was cut at by psr_mesh_trim (whatever psr_trim_threshold asked for, resolved to
 * a density); NaN if m is NULL or was not made by psr_mesh_trim.
 *
 * # Safety
 * `m` is NULL or a live mesh.
 */
double psr_mesh_trim_density(const psr_mesh *m);

/**
 * The same threshold as PoissonRecon's depth-like value, kernel depth + log4(density)
 * (-infinity for a density of 0); NaN if m is NULL or was not made by psr_mesh_trim.
 *
 * # Safety
 * `m` is NULL or a live mesh.
 */
double psr_mesh_trim_depth(const psr_mesh *m);

/**
 * Prepares *a for psr_reconstructor_add_point_arrays: sets every field to zero (no arrays, no
 * points) and struct_size to `struct_size`, which must be the size of the struct as your code
 * sees it: pass sizeof *a. (The library cannot know how large the struct you compiled with
 * is; a library newer than your header must not write beyond it.)
 *
 * a must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_ARGUMENT (struct_size is smaller than the first four fields or larger
 * than 4096 bytes; nothing is written) or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `a` is NULL or valid for writes of `struct_size` bytes.
 */
psr_status psr_point_arrays_init(psr_point_arrays *a, size_t struct_size);

/**
 * Appends the points *a describes to r: positions and normals, and when given, a confidence
 * weight, a colour and named channels per point (see psr_point_arrays). The mesh's vertices
 * then get colours and channels (psr_mesh_colors, psr_mesh_channel): at each vertex, the
 * weighted mean of the values of the points around it whose normals face the same way as the
 * surface there, so one face of a thin wall never colours the other.
 *
 * Initialise *a with psr_point_arrays_init(&a, sizeof a) first; a struct from an older header
 * (smaller struct_size) works, its missing fields counting as absent. Everything is copied:
 * free your arrays as soon as this returns. Calls append, so a cloud can come in batches, but
 * every batch must carry the same attributes (colours or none, the same number of components,
 * the same channel names in the same order; weights may differ: absent ones are 1). The batch
 * is checked whole first; if anything is wrong nothing from it is appended, points from
 * earlier batches stay, and the message names the first bad index within this batch. Points
 * with colours or channels cannot be mixed with points added without normals
 * (psr_reconstructor_add_positions), which carry none.
 *
 * r and a must not be NULL; with count 0 nothing is read but struct_size. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT (r, a, positions, normals, or an array whose count
 * or components say it is there), PSR_STATUS_INVALID_ARGUMENT (struct_size too small or above 4096, or
 * larger with fields this library does not know set; a stride below one element; count *
 * stride overflowing; color_components not 3 or 4; a channel name that is not UTF-8, empty,
 * has whitespace or repeats; attributes that differ from the earlier batches'),
 * PSR_STATUS_NON_FINITE_POSITION, PSR_STATUS_NON_FINITE_NORMAL, PSR_STATUS_ZERO_NORMAL,
 * PSR_STATUS_INVALID_WEIGHT (a weight negative, NaN or infinite),
 * PSR_STATUS_NON_FINITE_ATTRIBUTE (a colour or channel value NaN or infinite),
 * PSR_STATUS_HANDLE_POISONED or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle; `a` is NULL or points to struct_size readable bytes that
 * begin with struct_size, and every array in it is NULL or readable over its strided span;
 * `channel_names` holds channel_count NUL-terminated strings.
 */
psr_status psr_reconstructor_add_point_arrays(psr_reconstructor *r, const psr_point_arrays *a);

/**
 * Sets whether the mesh gets a unit outward normal per vertex (psr_mesh_normals), the
 * normalised gradient of the indicator function there. Default false. PoissonRecon --normals.
 *
 * r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
 * or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_vertex_normals(psr_reconstructor *r, bool vertex_normals);

/**
 * Writes whether the mesh gets vertex normals to *out. r and out must not be NULL. Returns the
 * statuses of psr_reconstructor_get_depth.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_vertex_normals(const psr_reconstructor *r, bool *out);

/**
 * The unit outward normals of m's vertices, 3 floats (nx, ny, nz) per vertex, owned by m
 * (valid until psr_mesh_free(m)). NULL if m is NULL, has no vertices, or was solved without
 * psr_reconstructor_set_vertex_normals(r, true).
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
const float *psr_mesh_normals(const psr_mesh *m);

/**
 * Components per vertex colour of m: 3 (RGB), 4 (RGBA), or 0 when m has no colours (its
 * points had none) or m is NULL.
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
size_t psr_mesh_color_components(const psr_mesh *m);

/**
 * The colours of m's vertices, psr_mesh_color_components(m) floats per vertex, in the scale
 * of the points' colours, owned by m (valid until psr_mesh_free(m)). NULL if m is NULL, has no
 * vertices or no colours.
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
const float *psr_mesh_colors(const psr_mesh *m);

/**
 * Number of channels of m (the channels its points had); 0 if m is NULL.
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
size_t psr_mesh_channel_count(const psr_mesh *m);

/**
 * The name of m's channel `index` (0-based, in the order the points gave them) as a
 * NUL-terminated string owned by m (valid until psr_mesh_free(m), never to be freed). NULL if
 * m is NULL or index >= psr_mesh_channel_count(m).
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
const char *psr_mesh_channel_name(const psr_mesh *m, size_t index);

/**
 * The values of m's channel `index` at its vertices, one float per vertex, owned by m (valid
 * until psr_mesh_free(m)). NULL if m is NULL, has no vertices, or index >=
 * psr_mesh_channel_count(m).
 *
 * # Safety
 * `m` is NULL or a live mesh from psr_reconstructor_solve.
 */
const float *psr_mesh_channel(const psr_mesh *m, size_t index);

/**
 * Copies m's vertex normals into dst: 3 * psr_mesh_vertex_count(m) floats, or nothing when m
 * has no normals. capacity_floats is the number of floats dst can hold.
 *
 * m must not be NULL; dst may be NULL only when there is nothing to copy. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
 */
psr_status psr_mesh_copy_normals(const psr_mesh *m, float *dst, size_t capacity_floats);

/**
 * Copies m's vertex colours into dst: psr_mesh_color_components(m) *
 * psr_mesh_vertex_count(m) floats, or nothing when m has no colours. capacity_floats is the
 * number of floats dst can hold.
 *
 * m must not be NULL; dst may be NULL only when there is nothing to copy. Returns the statuses
 * of psr_mesh_copy_normals.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
 */
psr_status psr_mesh_copy_colors(const psr_mesh *m, float *dst, size_t capacity_floats);

/**
 * Copies the values of m's channel `index` into dst: psr_mesh_vertex_count(m) floats.
 * capacity_floats is the number of floats dst can hold.
 *
 * m must not be NULL; dst may be NULL only when the mesh has no vertices. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (index >=
 * psr_mesh_channel_count(m)), PSR_STATUS_BUFFER_TOO_SMALL (nothing is written) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `dst` is NULL or valid for writes of `capacity_floats` floats.
 */
psr_status psr_mesh_copy_channel(const psr_mesh *m, size_t index, float *dst, size_t capacity_floats);

/**
 * Writes to *out the maximum octree depth the reconstruction of m used: the depth set with
 * psr_reconstructor_set_depth, or the one psr_reconstructor_set_width chose. 0 for a mesh no
 * reconstruction made. A trimmed mesh reports the figures of the mesh it was cut from (so do
 * the other functions here).
 *
 * m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
 * PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes.
 */
psr_status psr_mesh_depth(const psr_mesh *m, uint32_t *out);

/**
 * Writes to *out the octree's finest depth: psr_mesh_depth's, or less when the sampling
 * density put no sample that deep (sparse points at a high depth), where the tree and the
 * surface stop (never above the full depth). psr_mesh_node_counts has this + 1 entries.
 *
 * m and out must not be NULL. Returns the statuses of psr_mesh_depth.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes.
 */
psr_status psr_mesh_finest_depth(const psr_mesh *m, uint32_t *out);

/**
 * Writes to *out the noise's depth s of the screening weight: the depths finer than s were
 * pulled with alpha 2^s instead of alpha 2^depth (those up to floor(s) keep alpha 2^depth).
 * psr_mesh_depth's when the samples read no noise or the screening did not follow it
 * (psr_reconstructor_set_screening_follows_noise); less (fractional) when the noise set it.
 * 0 for a mesh no reconstruction made.
 *
 * m and out must not be NULL. Returns the statuses of psr_mesh_depth.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes.
 */
psr_status psr_mesh_screening_depth(const psr_mesh *m, double *out);

/**
 * Writes to *out the samples' positional noise sigma in input units (their RMS scatter across
 * the surface; 0 for exact samples of a smooth surface) as the reconstruction of m estimated
 * it, or NaN when it did not (psr_reconstructor_set_screening_follows_noise was false).
 *
 * m and out must not be NULL. Returns the statuses of psr_mesh_depth.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes.
 */
psr_status psr_mesh_sample_noise(const psr_mesh *m, double *out);

/**
 * Copies the octree's node (unknown) counts per depth into out, index = depth, from 0 to
 * psr_mesh_finest_depth; capacity is the number of uint64_t out can hold, and *count gets
 * the number written. To ask for the count alone, pass out = NULL and capacity = 0: *count
 * gets the number of entries there are. A mesh no reconstruction made has none.
 *
 * m and count must not be NULL; out may be NULL only with capacity 0. Returns PSR_STATUS_OK,
 * PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_BUFFER_TOO_SMALL (capacity > 0 but less than the
 * entries; nothing is written, *count neither) or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or valid for writes of `capacity` values; `count`
 * is NULL or valid for writes.
 */
psr_status psr_mesh_node_counts(const psr_mesh *m, uint64_t *out, size_t capacity, size_t *count);

/**
 * Number of closed components of the level set that the reconstruction left out of m because
 * too few samples support them (psr_reconstructor_set_min_component_samples); 0 if m is NULL
 * or no reconstruction made it.
 *
 * # Safety
 * `m` is NULL or a live mesh.
 */
size_t psr_mesh_unsupported_components(const psr_mesh *m);

/**
 * Number of per-depth solves of m, coarse to fine (psr_mesh_solve_stats' indices); 0 if m is
 * NULL or no reconstruction made it.
 *
 * # Safety
 * `m` is NULL or a live mesh.
 */
size_t psr_mesh_solve_count(const psr_mesh *m);

/**
 * Writes how the solve at index (0 = the coarsest, up to psr_mesh_solve_count(m) - 1) ended
 * into *out: its depth, unknowns, iterations, final relative residual and seconds. Set
 * out->struct_size = sizeof(psr_depth_solve) first: the library writes the fields it knows
 * that fit in that size, and sets the rest of a larger (newer) struct to zero.
 *
 * m and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_ARGUMENT (index out of range, or out->struct_size smaller than this
 * header's first psr_depth_solve or implausibly large: not set) or PSR_STATUS_INTERNAL_ERROR;
 * *out is written only on success.
 *
 * # Safety
 * `m` is NULL or a live mesh; `out` is NULL or points to a psr_depth_solve whose struct_size
 * bytes are writable.
 */
psr_status psr_mesh_solve_stats(const psr_mesh *m, size_t index, psr_depth_solve *out);

/**
 * psr_reconstructor_solve, also keeping the solved indicator function χ: writes a new
 * psr_implicit to *out_implicit (free it with psr_implicit_free) and, unless out_mesh is NULL,
 * the mesh to *out_mesh (free it with psr_mesh_free; the same mesh psr_reconstructor_solve
 * gives). The psr_implicit keeps the octree and its coefficients: about the octree's memory
 * until it is freed.
 *
 * r and out_implicit must not be NULL; out_mesh may be. Returns the statuses of
 * psr_reconstructor_solve. On failure neither out-parameter is written.
 *
 * # Safety
 * `r` is NULL or a live handle; `out_mesh` is NULL or valid for writing one pointer, and so is
 * `out_implicit`.
 */
psr_status psr_reconstructor_solve_implicit(psr_reconstructor *r, psr_mesh **out_mesh, psr_implicit **out_implicit);

/**
 * Destroys an implicit function. f may be NULL (nothing happens).
 *
 * # Safety
 * `f` is NULL or a live psr_implicit, not used again afterwards (by any thread).
 */
void psr_implicit_free(psr_implicit *f);

/**
 * The isovalue γ the mesh was extracted at (psr_mesh_isovalue of the mesh from the same
 * solve): the surface is where χ = γ. NaN if f is NULL.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit.
 */
double psr_implicit_isovalue(const psr_implicit *f);

/**
 * Writes the bounding cube χ was solved in, in input coordinates: its minimum corner to
 * origin[0..3] and its edge length to *size (the points' bounding box enlarged by
 * psr_reconstructor_set_scale's factor). psr_implicit_sample_grid samples this cube.
 *
 * f, origin and size must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT or
 * PSR_STATUS_INTERNAL_ERROR; nothing is written on failure.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit; `origin` is NULL or valid for writes of 3 doubles;
 * `size` is NULL or valid for writes of one.
 */
psr_status psr_implicit_cube(const psr_implicit *f, double *origin, double *size);

/**
 * Evaluates χ at count points: points holds 3 floats (x, y, z) per point in the input's
 * coordinates, values receives one float per point. The surface is where χ equals
 * psr_implicit_isovalue(f); χ − isovalue is negative inside and positive outside. Outside the
 * bounding cube (psr_implicit_cube) χ is continued constantly along the cube's normals (the
 * value at the nearest point of the cube). Large batches run on worker threads started for the
 * call (as many as psr_reconstructor_set_threads gave the solve); the values do not depend on
 * their number.
 *
 * f must not be NULL; points and values may be NULL only when count is 0. Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (3 × count floats
 * overflow), PSR_STATUS_NON_FINITE_POSITION (a NaN or infinite coordinate; nothing is written),
 * PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR. values is written only on
 * success.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit; `points` is NULL or valid for reads of 3 × count floats;
 * `values` is NULL or valid for writes of count floats and does not overlap `points`.
 */
psr_status psr_implicit_evaluate(const psr_implicit *f, const float *points, size_t count, float *values);

/**
 * Evaluates ∇χ at count points (see psr_implicit_evaluate): gradients receives 3 floats per
 * point, the derivatives per input unit along x, y, z. ∇χ points outward (the mesh's vertex
 * normals are ∇χ/|∇χ|); outside the bounding cube its components along the axes on which the
 * point lies outside are 0.
 *
 * f must not be NULL; points and gradients may be NULL only when count is 0. Returns the
 * statuses of psr_implicit_evaluate; gradients is written only on success.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit; `points` is NULL or valid for reads of 3 × count floats;
 * `gradients` is NULL or valid for writes of 3 × count floats and does not overlap `points`.
 */
psr_status psr_implicit_gradient(const psr_implicit *f, const float *points, size_t count, float *gradients);

/**
 * Samples χ on a resolution³ grid over the bounding cube (psr_implicit_cube), at the centres
 * of its cells, as PoissonRecon's --grid does: the value of cell (i, j, k) (x, y, z indices)
 * is χ at origin + (i + 0.5, j + 0.5, k + 0.5) × size / resolution and goes to
 * out[(i * resolution + j) * resolution + k]: z fastest, NumPy's C order for an array of
 * shape (resolution, resolution, resolution) indexed (i, j, k). Each value is what psr_implicit_evaluate gives at that point (computed in double
 * precision, rounded to float once). capacity_floats is the number of floats out can hold:
 * at least resolution³. Runs on worker threads started for the call, like
 * psr_implicit_evaluate.
 *
 * f must not be NULL, nor out. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_PARAMETER (resolution 0 or above 4096, or resolution³ floats too many for
 * the address space), PSR_STATUS_BUFFER_TOO_SMALL (nothing is written),
 * PSR_STATUS_THREADS_UNAVAILABLE or PSR_STATUS_INTERNAL_ERROR. out is written only on
 * success.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit; `out` is NULL or valid for writes of capacity_floats
 * floats.
 */
psr_status psr_implicit_sample_grid(const psr_implicit *f, size_t resolution, float *out, size_t capacity_floats);

/**
 * Samples χ on a resolution³ grid over the box from min to max (3 doubles each, input
 * coordinates; a side may have zero length, and the box may reach outside the bounding cube),
 * at the centres of its cells: the value of cell (i, j, k) (x, y, z indices) is χ at
 * min + (i + 0.5, j + 0.5, k + 0.5) × (max − min) / resolution and goes to
 * out[(i * resolution + j) * resolution + k], the order of psr_implicit_sample_grid (which is
 * this function over the bounding cube). For a region of interest finer than the cube's grid,
 * or a grid aligned with the object rather than with the cube. capacity_floats is the number
 * of floats out can hold: at least resolution³.
 *
 * f, min, max and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_PARAMETER (a corner with a NaN or infinite coordinate, min above max on
 * an axis, resolution 0 or above 4096, or resolution³ floats too many for the address space),
 * PSR_STATUS_BUFFER_TOO_SMALL (nothing is written), PSR_STATUS_THREADS_UNAVAILABLE or
 * PSR_STATUS_INTERNAL_ERROR. out is written only on success.
 *
 * # Safety
 * `f` is NULL or a live psr_implicit; `min` and `max` are NULL or valid for reads of 3
 * doubles; `out` is NULL or valid for writes of capacity_floats floats.
 */
psr_status psr_implicit_sample_box(const psr_implicit *f, const double *min, const double *max, size_t resolution, float *out, size_t capacity_floats);

/**
 * Sets the most memory a solve on r may use, in bytes; 0 (the default) means no limit. psr
 * counts the big arrays of a reconstruction (the points, the octree, the system, the solver,
 * the extraction and the mesh; see psr_reconstructor_estimate_memory) and checks the count
 * against the limit before allocating them: first from the point count, before anything is
 * copied (a limit far too small fails within milliseconds), then from the octree's node
 * counts, before the system is built. A solve that would need more returns
 * PSR_STATUS_OUT_OF_MEMORY, naming what needed how much, the limit and the smallest limit that
 * would do, and keeps nothing; the handle stays usable. Any value is accepted (0 or 1 to
 * 2^64 - 1). The limit covers psr's own big arrays, not the memory the host holds, the
 * thread stacks or the allocator's overhead. Without a limit, the system's refusal of one of
 * the big allocations is PSR_STATUS_OUT_OF_MEMORY too. No PoissonRecon, PCL or Open3D
 * equivalent.
 *
 * r must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress callback)
 * or PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `r` is NULL or a live handle from psr_reconstructor_new.
 */
psr_status psr_reconstructor_set_max_memory(psr_reconstructor *r, uint64_t bytes);

/**
 * Writes the memory limit in bytes (0: no limit, the default) to *out. r and out must not be
 * NULL. Returns the statuses of psr_reconstructor_get_depth; *out is written only on success.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_get_max_memory(const psr_reconstructor *r, uint64_t *out);

/**
 * Writes to *out the memory, in bytes, a solve of r's points with r's parameters is estimated
 * to need at its peak, before solving: computed from the point count and the depth (the depth
 * psr_reconstructor_set_width picks is found from the points' bounding box) in well under a
 * second. It counts the points r holds, the octree, the system, the solver, the extraction
 * and the mesh; not the host's own memory, the mesh after the solve returns, nor, for points
 * without normals, the normal estimation. Meant as an upper bound for scanned surfaces:
 * measured on the bunny and the Happy Buddha scans at depths 9 to 12 it is 1.8 to 2.5 times
 * the peak resident memory of the whole process (docs/benchmarks.md, issue 19). A limit set to
 * it with psr_reconstructor_set_max_memory lets that solve through, since the solve checks
 * the finer count from its octree. With no points the estimate is that of the smallest
 * reconstruction (the complete octree down to the full depth).
 *
 * r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_PARAMETER (two parameters disagree, as psr_reconstructor_solve would
 * report), PSR_STATUS_HANDLE_POISONED, PSR_STATUS_INVALID_ARGUMENT (called from r's progress
 * callback) or PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_estimate_memory(const psr_reconstructor *r, uint64_t *out);

/**
 * Writes to *out the memory, in bytes, a reconstruction of point_count points (position and
 * normal) at depth is estimated to need at its peak, every other parameter at its default:
 * the estimate of psr_reconstructor_estimate_memory, for a host that has no reconstructor
 * yet (e.g. to choose the depth for the memory it has). depth must be 1 to 16.
 *
 * out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_PARAMETER (depth out of range; *out untouched) or
 * PSR_STATUS_INTERNAL_ERROR.
 *
 * # Safety
 * `out` is NULL or valid for writes.
 */
psr_status psr_estimate_memory(uint32_t depth, uint64_t point_count, uint64_t *out);

/**
 * Reads the PLY file at `path` (a NUL-terminated path; its bytes as they are on Unix) with
 * psr's own reader, the one the psr program uses, and writes a new handle to *out (free it
 * with psr_ply_free). ASCII and binary of either byte order, every scalar type; the `vertex`
 * element needs x y z; nx ny nz (or normal_x ...), red green blue and alpha if present (or
 * diffuse_red ..., r g b a; integer colours are scaled to 0..1), confidence (or else value:
 * the density a psr mesh carries), sensor_x sensor_y sensor_z (or vp_x ..., beamorigin_x ...)
 * and every other scalar property (a "channel") are read when present; a `face` element's vertex_indices (or
 * vertex_index) polygons become triangles, an n-gon a fan of n - 2 (none when the file has
 * no face element). Other elements and list properties are skipped. A point cloud, or a mesh
 * psr or another program wrote: the views below give every part.
 *
 * path and out must not be NULL; message may be NULL (or message_capacity 0) for no message.
 * Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty
 * path), PSR_STATUS_IO_ERROR (the file cannot be opened or read: the message has the
 * system's reason), PSR_STATUS_INVALID_FILE (not PLY, a malformed or truncated file, no
 * vertex element or no x y z, a face index out of range: the message says where) or
 * PSR_STATUS_INTERNAL_ERROR. The message (at most message_capacity - 1 bytes and a NUL,
 * shortened if longer) is written on every return: "" on success. On failure *out is left
 * untouched. The file is read before anything is allocated for it, so a header that
 * promises more than the file holds is refused, not allocated. Thread-safe: no state is
 * shared between calls.
 *
 * # Safety
 * `path` is NULL or a NUL-terminated string; `out` is NULL or valid for writing one
 * pointer; `message` is NULL or valid for writing `message_capacity` bytes.
 */
psr_status psr_ply_read(const char *path, psr_ply **out, char *message, size_t message_capacity);

/**
 * Frees a handle from psr_ply_read and every view it gave; NULL is ignored.
 *
 * # Safety
 * `p` is NULL or a handle from psr_ply_read not yet freed, used by no other thread.
 */
void psr_ply_free(psr_ply *p);

/**
 * Number of vertices (points) read; 0 if p is NULL.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
size_t psr_ply_vertex_count(const psr_ply *p);

/**
 * The positions, 3 floats (x, y, z) per vertex (rounded to float when the file stores
 * double: psr_ply_positions_f64 has them exactly); owned by p, valid until psr_ply_free(p).
 * NULL if p is NULL or has no vertices. Give them to psr_reconstructor_add_points (or
 * psr_point_arrays) with the normals, or to psr_reconstructor_add_positions without.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_positions(const psr_ply *p);

/**
 * The positions as the file stores them, 3 doubles per vertex, when any of x y z is a double
 * (georeferenced clouds: give them to psr_reconstructor_add_points_f64 so that nothing is lost
 * to float); owned by p. NULL if p is NULL, has no vertices, or the file stores float (or
 * integer) coordinates.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const double *psr_ply_positions_f64(const psr_ply *p);

/**
 * The normals, 3 floats per vertex, as stored (not normalised); owned by p. NULL if p is
 * NULL, has no vertices, or the file has no normals.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_normals(const psr_ply *p);

/**
 * 3 (RGB) or 4 (RGBA) when the file has colours; 0 if it has none or p is NULL.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
size_t psr_ply_color_components(const psr_ply *p);

/**
 * The colours, psr_ply_color_components floats per vertex in 0..1 (integer colours divided by
 * their type's full scale, 255 for uchar; float colours as stored); owned by p. NULL if p is
 * NULL, has no vertices, or the file has no colours.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_colors(const psr_ply *p);

/**
 * The `confidence` property (or else `value`, which is the density in a mesh psr wrote), one
 * float per vertex; owned by p. NULL if p is NULL, has no vertices, or the file has neither.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_confidence(const psr_ply *p);

/**
 * The position of the sensor that saw each vertex, 3 floats per vertex (for
 * psr_reconstructor_add_positions_with_sensors); owned by p. NULL if p is NULL, has no
 * vertices, or the file has no sensor_x sensor_y sensor_z (vp_x ..., beamorigin_x ...).
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_sensors(const psr_ply *p);

/**
 * Number of channels: the vertex element's other scalar properties, in the file's order; 0 if
 * p is NULL.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
size_t psr_ply_channel_count(const psr_ply *p);

/**
 * The name of channel `index` (the property's name) as a NUL-terminated string owned by p.
 * NULL if p is NULL or index >= psr_ply_channel_count(p).
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const char *psr_ply_channel_name(const psr_ply *p, size_t index);

/**
 * The values of channel `index`, one float per vertex; owned by p. NULL if p is NULL, has no
 * vertices, or index >= psr_ply_channel_count(p).
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const float *psr_ply_channel(const psr_ply *p, size_t index);

/**
 * Number of triangles the file's faces gave; 0 if p is NULL or the file has no faces (a point
 * cloud).
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
size_t psr_ply_triangle_count(const psr_ply *p);

/**
 * The triangles, 3 vertex indices each (below psr_ply_vertex_count), in the file's order and
 * orientation; owned by p. NULL if p is NULL or has none.
 *
 * # Safety
 * `p` is NULL or a live handle from psr_ply_read.
 */
const uint32_t *psr_ply_triangles(const psr_ply *p);

/**
 * Writes m to the file at `path` (created or replaced) as PLY, with the writer the psr program
 * uses, so the same mesh gives the same bytes as `psr --out mesh.ply`: vertex x y z (float;
 * double with PSR_PLY_DOUBLE_POSITIONS or when m's origin is not 0), nx ny nz when m has
 * vertex normals, value (the density), red green blue and alpha if RGBA (uchar) when it has
 * colours, a float per channel; face `list uchar int vertex_indices` (uint past 2^31
 * vertices).
 * Binary little-endian unless `flags` has PSR_PLY_ASCII or PSR_PLY_BIG_ENDIAN.
 *
 * m and path must not be NULL; message may be NULL (or message_capacity 0). Returns
 * PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty path, a flag
 * this library does not know, PSR_PLY_ASCII with PSR_PLY_BIG_ENDIAN), PSR_STATUS_TOO_LARGE
 * (more than 2^32 vertices: PLY has no standard 64-bit index), PSR_STATUS_IO_ERROR (the file
 * cannot be created or written, e.g. no such directory or a full disk: the message has the
 * system's reason; a partly written file may be left) or PSR_STATUS_INTERNAL_ERROR. The
 * message is written on every return ("" on success). m is only read: several threads may
 * write (or read) the same mesh at once.
 *
 * # Safety
 * `m` is NULL or a live mesh; `path` is NULL or a NUL-terminated string; `message` is NULL
 * or valid for writing `message_capacity` bytes.
 */
psr_status psr_mesh_write_ply(const psr_mesh *m, const char *path, uint32_t flags, char *message, size_t message_capacity);

/**
 * Reconstructs the oriented points of the PLY file input_path into the mesh output_path
 * (binary PLY: vertex x y z, float or, for double input, double; value, the sampling density;
 * face vertex_indices as int) without holding the whole cloud, its octree or its mesh in
 * memory at once (docs/out-of-core.md): the cloud is read in chunks and binned across x into
 * slabs in a temporary directory made under temp_dir (NULL: the system's) and removed however
 * the call ends; the coarse depths are solved once for the whole cloud and the finer ones slab
 * by slab; the mesh is written slab by slab, closed across the slabs' walls, each wall vertex
 * once. r's points are not used: its parameters, threads and progress callback are (the passes
 * report as the stages they correspond to: reading PSR_STAGE_POINTS, the base PSR_STAGE_SYSTEM,
 * the slabs PSR_STAGE_SOLVE, seams and isovalue PSR_STAGE_ISOVALUE, the slabs' meshes
 * PSR_STAGE_EXTRACT, the file PSR_STAGE_MESH). slabs 0 chooses the fewest slabs whose largest
 * fits r's memory limit (psr_reconstructor_set_max_memory; then one must be set), and with
 * them the depth up to which the whole cloud is solved at once (a finer one for a limit that
 * cuts the cloud thin, so that each slab's padding is thinner: docs/out-of-core.md); a limit
 * no cut fits is refused with PSR_STATUS_OUT_OF_MEMORY before the slabs are solved, the
 * message giving the smallest workable limit. use_confidence non-zero weighs the points by their
 * confidence (or value) property. The mesh is the in-memory psr_reconstructor_solve's to within
 * the solver's tolerance, not bit for bit; colours and channels are not carried and vertex
 * normals are refused (PSR_STATUS_INVALID_PARAMETER). report may be NULL.
 *
 * r, input_path and output_path must not be NULL. Returns PSR_STATUS_OK,
 * PSR_STATUS_NULL_ARGUMENT, PSR_STATUS_INVALID_ARGUMENT (an empty path, a call from r's own
 * progress callback), PSR_STATUS_IO_ERROR (the input cannot be read, the output or a temporary
 * file cannot be written: the message has the path and the system's reason),
 * PSR_STATUS_INVALID_FILE (the input is not a PLY of oriented points), the statuses of
 * psr_reconstructor_solve for the points and parameters (their indices are the file's),
 * PSR_STATUS_OUT_OF_MEMORY, PSR_STATUS_CANCELLED, PSR_STATUS_HANDLE_POISONED or
 * PSR_STATUS_INTERNAL_ERROR. On failure *report is left untouched and no file is left at
 * output_path by this call (the mesh is written there last, and removed if that fails).
 *
 * # Safety
 * `r` is NULL or a live handle; the paths are NULL or NUL-terminated strings; `report` is NULL
 * or valid for writing one psr_out_of_core_report.
 */
psr_status psr_reconstructor_solve_file_out_of_core(psr_reconstructor *r, const char *input_path, const char *output_path, const char *temp_dir, size_t slabs, int32_t use_confidence, psr_out_of_core_report *report);

/**
 * Writes to *out the samples' noise as the last psr_reconstructor_solve_file_out_of_core on r
 * measured it (see psr_out_of_core_noise).
 *
 * r and out must not be NULL. Returns PSR_STATUS_OK, PSR_STATUS_NULL_ARGUMENT,
 * PSR_STATUS_INVALID_ARGUMENT (no reconstruction out of core on r yet, or the last one failed;
 * or called from r's progress callback), PSR_STATUS_HANDLE_POISONED or
 * PSR_STATUS_INTERNAL_ERROR; *out is written only on success.
 *
 * # Safety
 * `r` is NULL or a live handle; `out` is NULL or valid for writes.
 */
psr_status psr_reconstructor_out_of_core_noise(const psr_reconstructor *r, psr_out_of_core_noise *out);

#ifdef __cplusplus
}  // extern "C"
#endif  // __cplusplus

#endif  /* PSR_H */

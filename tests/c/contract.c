/*
 * Contract tests of the psr C API, from C, against the installed header and library:
 * NULL for every pointer argument, free(NULL), solve before any points, a bad point in the
 * middle of a second batch, strides and overflow, points without normals and with sensors,
 * points with colours and channels (psr_point_arrays, a struct from an older header
 * included), short copy-out buffers, out-parameters left
 * alone on failure, the names of statuses and stages, cancellation from the callback, a forced
 * internal panic (when the library was built with the test hook), two handles on two threads
 * matching sequential runs, and trimming: psr_trim_options from this header, from an older
 * (smaller) and a newer (larger) one, bad sizes and values, its progress callback and cancel,
 * and the trimmed mesh outliving its source; the target width, and the mesh's figures (depths, nodes per depth, psr_depth_solve
 * from this header and from a newer one, bad sizes and indices); the implicit function
 * (psr_implicit: evaluation, gradient, grid, bad arguments); PLY files through the library
 * (psr_mesh_write_ply, psr_ply_read: round trip, bad files and arguments); reconstruction out
 * of core (psr_reconstructor_solve_file_out_of_core: bad arguments, a missing file, its report
 * against the file it wrote, cancellation, no temporary file left; the noise it measured,
 * psr_reconstructor_out_of_core_noise).
 *
 * Prints one line per check and a closing "N passed, N failed" line; exits non-zero on any
 * failure. Meant to run under valgrind or AddressSanitizer as well.
 */
#define _POSIX_C_SOURCE 200809L
#include <psr.h>

#include <dirent.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int passed, failed;

#define CHECK(cond)                                                     \
    do {                                                                \
        if (cond) {                                                     \
            passed++;                                                   \
        } else {                                                        \
            failed++;                                                   \
            printf("FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);      \
        }                                                               \
    } while (0)

#define CHECK_STATUS(call, want)                                                      \
    do {                                                                              \
        psr_status got_ = (call);                                                     \
        if (got_ == (want)) {                                                         \
            passed++;                                                                 \
        } else {                                                                      \
            failed++;                                                                 \
            printf("FAIL %s:%d: %s returned %s, want %s\n", __FILE__, __LINE__, #call, \
                   psr_status_string((int)got_), psr_status_string((int)(want)));     \
        }                                                                             \
    } while (0)

static void section(const char *name) { printf("-- %s\n", name); }

static int contains(const char *haystack, const char *needle) {
    return haystack != NULL && strstr(haystack, needle) != NULL;
}

/* n points on a sphere (Fibonacci lattice) of radius 1 with outward normals, packed. */
static void sphere(size_t n, float *positions, float *normals) {
    const double golden = 3.14159265358979323846 * (3.0 - sqrt(5.0));
    size_t i;
    for (i = 0; i < n; i++) {
        double y = 1.0 - 2.0 * ((double)i + 0.5) / (double)n;
        double ring = sqrt(1.0 - y * y), phi = golden * (double)i;
        double d[3];
        int k;
        d[0] = ring * cos(phi);
        d[1] = y;
        d[2] = ring * sin(phi);
        for (k = 0; k < 3; k++) {
            positions[3 * i + k] = (float)(0.25 + d[k]);
            normals[3 * i + k] = (float)d[k];
        }
    }
}

static psr_reconstructor *new_with_sphere(size_t n, unsigned depth) {
    psr_reconstructor *r = NULL;
    float *p = malloc(3 * n * sizeof(float)), *nr = malloc(3 * n * sizeof(float));
    sphere(n, p, nr);
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(r, depth), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, nr, 0, n), PSR_STATUS_OK);
    free(p); /* add_points copied them */
    free(nr);
    return r;
}

static void test_null_arguments(void) {
    psr_reconstructor *r = NULL;
    psr_mesh *m = (psr_mesh *)&r; /* sentinel: must stay as it is */
    psr_mesh *const sentinel = m;
    uint32_t u = 7;
    int32_t i = 7;
    float f = 7.0f, buf[8];
    double d = 7.0;
    size_t z = 7;
    float p[3] = {0, 0, 0}, n[3] = {0, 0, 1};

    section("NULL for every pointer argument");
    psr_reconstructor_free(NULL);
    psr_mesh_free(NULL);
    CHECK_STATUS(psr_reconstructor_new(NULL), PSR_STATUS_NULL_ARGUMENT);

    CHECK_STATUS(psr_reconstructor_set_depth(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_full_depth(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_min_component_samples(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_kernel_depth(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_samples_per_node(NULL, 2.0f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_scale(NULL, 1.2f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_point_weight(NULL, 1.0f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_degree(NULL, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_threads(NULL, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_max_solver_iterations(NULL, 9), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_solver_tolerance(NULL, 1e-3), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_depth(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_full_depth(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_min_component_samples(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_kernel_depth(NULL, &i), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_samples_per_node(NULL, &f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_scale(NULL, &f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_point_weight(NULL, &f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_degree(NULL, &i), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_threads(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_max_solver_iterations(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_solver_tolerance(NULL, &d), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_point_count(NULL, &z), PSR_STATUS_NULL_ARGUMENT);
    CHECK(u == 7 && i == 7 && f == 7.0f && d == 7.0 && z == 7);
    CHECK_STATUS(psr_reconstructor_add_points(NULL, p, 0, n, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_positions(NULL, p, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(NULL, p, 0, 1, n), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(NULL, p, 0, n, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_normal_neighbors(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_neighbors(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_normal_orientation(NULL, PSR_ORIENTATION_SENSORS), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(NULL, &i), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_normal_reconstruction_iterations(NULL, 5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_reconstruction_iterations(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_viewpoint(NULL, 0.0, 0.0, 1.0), PSR_STATUS_NULL_ARGUMENT);
    CHECK(u == 7 && i == 7);
    CHECK_STATUS(psr_reconstructor_clear_points(NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_progress_callback(NULL, NULL, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve(NULL, &m), PSR_STATUS_NULL_ARGUMENT);
    CHECK(m == sentinel);
    CHECK(contains(psr_reconstructor_last_error(NULL), "NULL"));

    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_depth(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "out is NULL"));
    CHECK_STATUS(psr_reconstructor_get_full_depth(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_min_component_samples(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    {
        uint32_t min_samples = 7;
        CHECK_STATUS(psr_reconstructor_get_min_component_samples(r, &min_samples), PSR_STATUS_OK);
        CHECK(min_samples == 8);
        CHECK_STATUS(psr_reconstructor_set_min_component_samples(r, 0), PSR_STATUS_OK);
        CHECK_STATUS(psr_reconstructor_get_min_component_samples(r, &min_samples), PSR_STATUS_OK);
        CHECK(min_samples == 0);
        CHECK_STATUS(psr_reconstructor_set_min_component_samples(r, 8), PSR_STATUS_OK);
    }
    CHECK_STATUS(psr_reconstructor_get_kernel_depth(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_samples_per_node(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_scale(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_point_weight(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_degree(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_threads(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_max_solver_iterations(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_solver_tolerance(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_point_count(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points(r, NULL, 0, n, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "positions"));
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, NULL, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "normals"));
    CHECK_STATUS(psr_reconstructor_add_points(r, NULL, 0, NULL, 0, 0), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, NULL, 0, 1, n), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "positions"));
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, p, 0, 1, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "sensor"));
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, NULL, 0, n, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "positions"));
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, p, 0, NULL, 0, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "sensors"));
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, NULL, 0, 0, NULL), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, NULL, 0, NULL, 0, 0), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_neighbors(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_reconstruction_iterations(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    psr_reconstructor_free(r);

    CHECK(psr_mesh_vertex_count(NULL) == 0);
    CHECK(psr_mesh_triangle_count(NULL) == 0);
    CHECK(psr_mesh_positions(NULL) == NULL);
    CHECK(psr_mesh_triangles(NULL) == NULL);
    CHECK(psr_mesh_densities(NULL) == NULL);
    CHECK(isnan(psr_mesh_isovalue(NULL)));
    CHECK_STATUS(psr_mesh_copy_positions(NULL, buf, 8), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_copy_triangles(NULL, (uint32_t *)buf, 8), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_copy_densities(NULL, buf, 8), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_width(NULL, 0.5), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_width(NULL, &d), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_depth(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_finest_depth(NULL, &u), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_screening_depth(NULL, &d), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_sample_noise(NULL, &d), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_node_counts(NULL, NULL, 0, &z), PSR_STATUS_NULL_ARGUMENT);
    CHECK(psr_mesh_solve_count(NULL) == 0);
    CHECK(psr_mesh_unsupported_components(NULL) == 0);
    {
        psr_depth_solve s;
        s.struct_size = sizeof s;
        CHECK_STATUS(psr_mesh_solve_stats(NULL, 0, &s), PSR_STATUS_NULL_ARGUMENT);
    }
    CHECK(u == 7 && d == 7.0 && z == 7);
}

/* A psr_depth_solve from a newer header: this one's fields and one more. */
typedef struct {
    psr_depth_solve known;
    uint64_t later;
} newer_depth_solve;

static void test_stats(void) {
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    const size_t n = 3000;
    float *p = malloc(3 * n * sizeof(float)), *nr = malloc(3 * n * sizeof(float));
    uint32_t depth = 0, finest = 0;
    uint64_t nodes[20], short_nodes[2] = {7, 7};
    size_t count = 0, unchanged = 99, k, solves;
    double width = 0.0, screening_depth = 0.0, noise = 0.0;
    psr_depth_solve s;
    newer_depth_solve newer;

    section("the width, and the mesh's depths, nodes per depth and solves");
    sphere(n, p, nr);
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_width(r, &width), PSR_STATUS_OK);
    CHECK(width == 0.0);
    CHECK_STATUS(psr_reconstructor_set_width(r, -1.0), PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "width"));
    /* The unit sphere's cube is 2.2 wide: cells of at most 0.05 need 2^depth >= 44, depth 6. */
    CHECK_STATUS(psr_reconstructor_set_width(r, 0.05), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_width(r, &width), PSR_STATUS_OK);
    CHECK(width == 0.05);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 3), PSR_STATUS_OK); /* the width wins */
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, nr, 0, n), PSR_STATUS_OK);
    free(p);
    free(nr);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    psr_reconstructor_free(r);
    if (m == NULL)
        return;

    CHECK_STATUS(psr_mesh_depth(m, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_depth(m, &depth), PSR_STATUS_OK);
    CHECK(depth == 6);
    CHECK_STATUS(psr_mesh_finest_depth(m, &finest), PSR_STATUS_OK);
    CHECK(finest >= 5 && finest <= depth);
    /* The screening's 2^d scale: the noise is estimated (the default), the unit sphere's exact
       samples read none (their float rounding at most), so the scale stays at the depth. */
    CHECK_STATUS(psr_mesh_screening_depth(m, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_screening_depth(m, &screening_depth), PSR_STATUS_OK);
    CHECK(screening_depth == 6.0);
    CHECK_STATUS(psr_mesh_sample_noise(m, &noise), PSR_STATUS_OK);
    CHECK(noise >= 0.0 && noise < 1e-6);

    CHECK_STATUS(psr_mesh_node_counts(m, NULL, 0, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_node_counts(m, NULL, 4, &count), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_node_counts(m, NULL, 0, &count), PSR_STATUS_OK);
    CHECK(count == (size_t)finest + 1);
    CHECK_STATUS(psr_mesh_node_counts(m, short_nodes, 2, &unchanged), PSR_STATUS_BUFFER_TOO_SMALL);
    CHECK(short_nodes[0] == 7 && short_nodes[1] == 7 && unchanged == 99);
    CHECK_STATUS(psr_mesh_node_counts(m, nodes, 20, &count), PSR_STATUS_OK);
    CHECK(count == (size_t)finest + 1);
    CHECK(nodes[0] == 1 && nodes[1] == 8); /* complete to the full depth */
    CHECK(nodes[finest] > 0);

    CHECK(psr_mesh_unsupported_components(m) == 0); /* a clean sphere has no bubbles */
    solves = psr_mesh_solve_count(m);
    CHECK(solves > 0 && solves <= count);
    for (k = 0; k < solves; k++) {
        memset(&s, 0, sizeof s);
        s.struct_size = sizeof s;
        CHECK_STATUS(psr_mesh_solve_stats(m, k, &s), PSR_STATUS_OK);
        CHECK(s.struct_size == sizeof s);
        CHECK(s.depth <= finest && s.unknowns > 0);
        CHECK(s.relative_residual >= 0.0 && s.seconds >= 0.0);
    }
    CHECK(s.depth == finest); /* coarse to fine: the last is the finest */
    s.depth = 77;
    CHECK_STATUS(psr_mesh_solve_stats(m, solves, &s), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(s.depth == 77);
    s.struct_size = sizeof s - 1; /* smaller than any header's: not set */
    CHECK_STATUS(psr_mesh_solve_stats(m, 0, &s), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(s.depth == 77);
    CHECK_STATUS(psr_mesh_solve_stats(m, 0, NULL), PSR_STATUS_NULL_ARGUMENT);
    newer.known.struct_size = sizeof newer;
    newer.later = 0xABABABABu;
    CHECK_STATUS(psr_mesh_solve_stats(m, 0, &newer.known), PSR_STATUS_OK);
    CHECK(newer.known.struct_size == sizeof newer && newer.known.unknowns > 0);
    CHECK(newer.later == 0); /* a field this library does not know: not reported */
    psr_mesh_free(m);
}

static void test_order_and_parameters(void) {
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    uint32_t depth = 0;
    int32_t kernel = 0;

    section("defaults, setters, solve before any points, status and stage names");
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_depth(r, &depth), PSR_STATUS_OK);
    CHECK(depth == 8);
    CHECK_STATUS(psr_reconstructor_get_kernel_depth(r, &kernel), PSR_STATUS_OK);
    CHECK(kernel == -1);
    CHECK(strcmp(psr_reconstructor_last_error(r), "") == 0);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 0), PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "depth"));
    CHECK_STATUS(psr_reconstructor_set_scale(r, (float)NAN), PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "scale"));
    CHECK_STATUS(psr_reconstructor_set_solver_tolerance(r, 2.0), PSR_STATUS_INVALID_PARAMETER);
    {
        /* The degree: 2 by default; 0 and 3 refused, naming it, and leaving it as it was. */
        int32_t degree = 0;
        CHECK_STATUS(psr_reconstructor_get_degree(r, &degree), PSR_STATUS_OK);
        CHECK(degree == 2);
        CHECK_STATUS(psr_reconstructor_set_degree(r, 0), PSR_STATUS_INVALID_PARAMETER);
        CHECK(contains(psr_reconstructor_last_error(r), "degree"));
        CHECK_STATUS(psr_reconstructor_set_degree(r, 3), PSR_STATUS_INVALID_PARAMETER);
        CHECK_STATUS(psr_reconstructor_get_degree(r, &degree), PSR_STATUS_OK);
        CHECK(degree == 2);
    }
    CHECK_STATUS(psr_reconstructor_get_depth(r, &depth), PSR_STATUS_OK);
    CHECK(depth == 8);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_EMPTY_INPUT);
    CHECK(m == NULL);
    CHECK(contains(psr_reconstructor_last_error(r), "no input points"));
    psr_reconstructor_free(r);

    CHECK(strcmp(psr_status_string(PSR_STATUS_OK), "PSR_STATUS_OK") == 0);
    CHECK(strcmp(psr_status_string(9), "PSR_STATUS_BUFFER_TOO_SMALL") == 0);
    CHECK(strcmp(psr_status_string(-5), "PSR_STATUS_UNKNOWN") == 0);
    CHECK(strcmp(psr_status_string(PSR_STATUS_INVALID_TRANSFORM), "PSR_STATUS_INVALID_TRANSFORM") == 0);
    CHECK(strcmp(psr_status_string(PSR_STATUS_TOO_LARGE), "PSR_STATUS_TOO_LARGE") == 0);
    CHECK(strcmp(psr_status_string(1000), "PSR_STATUS_UNKNOWN") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_POINTS), "points") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_DENSITY), "density") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_OCTREE), "octree") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_SPLAT), "splat") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_SYSTEM), "system") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_SOLVE), "solve") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_ISOVALUE), "isovalue") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_EXTRACT), "extract") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_MESH), "mesh") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_NORMALS), "normals") == 0);
    CHECK(strcmp(psr_stage_string(PSR_STAGE_TRIM), "trim") == 0);
    CHECK(psr_stage_string(PSR_STAGE_MESH) == psr_stage_string(PSR_STAGE_MESH)); /* static */
    CHECK(strcmp(psr_stage_string(-1), "unknown") == 0);
    CHECK(strcmp(psr_stage_string(11), "unknown") == 0);
    CHECK(strcmp(psr_stage_string(1000), "unknown") == 0);
    CHECK(psr_version_major() == PSR_VERSION_MAJOR && psr_version_minor() == PSR_VERSION_MINOR &&
          psr_version_patch() == PSR_VERSION_PATCH);
}

static void test_bad_batches(void) {
    psr_reconstructor *r = NULL;
    float p[15], n[15];
    size_t count = 0;
    const float *far = (const float *)p;

    section("a NaN in the middle of a second batch; strides; overflow");
    r = new_with_sphere(4, 5);
    sphere(5, p, n);
    p[2 * 3 + 1] = (float)NAN;
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, n, 0, 5), PSR_STATUS_NON_FINITE_POSITION);
    CHECK(contains(psr_reconstructor_last_error(r), "point 2"));
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == 4);
    p[2 * 3 + 1] = 0.0f;
    n[3 * 3] = n[3 * 3 + 1] = n[3 * 3 + 2] = 0.0f;
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, n, 0, 5), PSR_STATUS_ZERO_NORMAL);
    CHECK(contains(psr_reconstructor_last_error(r), "normal 3"));
    n[3 * 3 + 2] = (float)INFINITY;
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, n, 0, 5), PSR_STATUS_NON_FINITE_NORMAL);
    n[3 * 3 + 2] = 1.0f;
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 8, n, 0, 2), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "position_stride_bytes"));
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, n, 11, 2), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points(r, far, 0, far, 0, (size_t)-1), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points(r, far, 1000, far, 0, ((size_t)-1) / 100), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == 4);
    /* Interleaved: positions and normals in one array with a 24-byte stride. */
    {
        float interleaved[12] = {0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1};
        CHECK_STATUS(psr_reconstructor_add_points(r, interleaved, 24, interleaved + 3, 24, 2), PSR_STATUS_OK);
        CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
        CHECK(count == 6);
    }
    CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == 0);
    psr_reconstructor_free(r);
}

static void test_mesh(void) {
    psr_reconstructor *r = new_with_sphere(1000, 5);
    psr_mesh *m = NULL;
    size_t nv, nt, k;
    float *pos, *den;
    uint32_t *tri;
    int same = 1;

    section("solve, views, copies, short buffers, mesh outliving its reconstructor");
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m == NULL) {
        printf("   (%s)\n", psr_reconstructor_last_error(r));
        psr_reconstructor_free(r);
        return;
    }
    psr_reconstructor_free(r); /* the mesh stays valid */
    nv = psr_mesh_vertex_count(m);
    nt = psr_mesh_triangle_count(m);
    CHECK(nv > 100 && nt > 100);
    CHECK(isfinite(psr_mesh_isovalue(m)));
    pos = malloc(3 * nv * sizeof(float));
    den = malloc(nv * sizeof(float));
    tri = malloc(3 * nt * sizeof(uint32_t));
    pos[0] = -123.0f;
    CHECK_STATUS(psr_mesh_copy_positions(m, pos, 3 * nv - 1), PSR_STATUS_BUFFER_TOO_SMALL);
    CHECK(pos[0] == -123.0f);
    CHECK_STATUS(psr_mesh_copy_triangles(m, tri, 3 * nt - 1), PSR_STATUS_BUFFER_TOO_SMALL);
    CHECK_STATUS(psr_mesh_copy_densities(m, den, nv - 1), PSR_STATUS_BUFFER_TOO_SMALL);
    CHECK_STATUS(psr_mesh_copy_positions(m, pos, 0), PSR_STATUS_BUFFER_TOO_SMALL);
    CHECK_STATUS(psr_mesh_copy_positions(m, NULL, 3 * nv), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_copy_positions(m, pos, 3 * nv), PSR_STATUS_OK);
    CHECK_STATUS(psr_mesh_copy_triangles(m, tri, 3 * nt), PSR_STATUS_OK);
    CHECK_STATUS(psr_mesh_copy_densities(m, den, nv), PSR_STATUS_OK);
    CHECK(memcmp(pos, psr_mesh_positions(m), 3 * nv * sizeof(float)) == 0);
    CHECK(memcmp(tri, psr_mesh_triangles(m), 3 * nt * sizeof(uint32_t)) == 0);
    CHECK(memcmp(den, psr_mesh_densities(m), nv * sizeof(float)) == 0);
    for (k = 0; k < 3 * nt; k++) same &= tri[k] < nv;
    CHECK(same);
    free(pos);
    free(den);
    free(tri);
    psr_mesh_free(m);
}

/* The memory budget: the limit set and read back, the estimates (NULL checks, out-parameters
 * untouched on failure), a limit far too small refused with PSR_STATUS_OUT_OF_MEMORY and no
 * mesh, and the same handle then solving, with no limit, the mesh of a handle that never
 * failed, byte for byte. */
static void test_memory(void) {
    psr_reconstructor *r = new_with_sphere(1000, 5);
    psr_reconstructor *fresh = new_with_sphere(1000, 5);
    psr_mesh *m = NULL, *expected = NULL;
    uint64_t bytes = 12345, estimate = 0, small = 0, large = 0;

    section("memory budget: limit, estimates, out of memory, the handle reusable");
    CHECK(strcmp(psr_status_string(PSR_STATUS_OUT_OF_MEMORY), "PSR_STATUS_OUT_OF_MEMORY") == 0);
    CHECK(PSR_STATUS_OUT_OF_MEMORY == 17);
    CHECK_STATUS(psr_reconstructor_set_max_memory(NULL, 1), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_max_memory(NULL, &bytes), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_max_memory(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_max_memory(r, &bytes), PSR_STATUS_OK);
    CHECK(bytes == 0);
    CHECK_STATUS(psr_reconstructor_estimate_memory(NULL, &estimate), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_estimate_memory(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_estimate_memory(r, &estimate), PSR_STATUS_OK);
    CHECK(estimate > 1000000);
    CHECK_STATUS(psr_estimate_memory(8, 1000, NULL), PSR_STATUS_NULL_ARGUMENT);
    bytes = 7;
    CHECK_STATUS(psr_estimate_memory(17, 1000, &bytes), PSR_STATUS_INVALID_PARAMETER);
    CHECK(bytes == 7);
    CHECK_STATUS(psr_estimate_memory(8, 100000, &small), PSR_STATUS_OK);
    CHECK_STATUS(psr_estimate_memory(10, 100000, &large), PSR_STATUS_OK);
    CHECK(small > 0 && large > small);

    CHECK_STATUS(psr_reconstructor_set_max_memory(r, 4096), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_max_memory(r, &bytes), PSR_STATUS_OK);
    CHECK(bytes == 4096);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OUT_OF_MEMORY);
    CHECK(m == NULL);
    CHECK(contains(psr_reconstructor_last_error(r), "memory limit of 4.00 KiB"));
    CHECK(contains(psr_reconstructor_last_error(r), "allow at least"));

    CHECK_STATUS(psr_reconstructor_set_max_memory(r, 0), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(fresh, &expected), PSR_STATUS_OK);
    if (m != NULL && expected != NULL) {
        size_t nv = psr_mesh_vertex_count(m), nt = psr_mesh_triangle_count(m);
        CHECK(nv == psr_mesh_vertex_count(expected) && nt == psr_mesh_triangle_count(expected));
        if (nv == psr_mesh_vertex_count(expected) && nt == psr_mesh_triangle_count(expected)) {
            CHECK(memcmp(psr_mesh_positions(m), psr_mesh_positions(expected),
                         3 * nv * sizeof(float)) == 0);
            CHECK(memcmp(psr_mesh_triangles(m), psr_mesh_triangles(expected),
                         3 * nt * sizeof(uint32_t)) == 0);
        }
    }
    /* A limit of the estimate lets the same solve through. */
    CHECK_STATUS(psr_reconstructor_set_max_memory(r, estimate), PSR_STATUS_OK);
    psr_mesh_free(m);
    m = NULL;
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    psr_mesh_free(m);
    psr_mesh_free(expected);
    psr_reconstructor_free(r);
    psr_reconstructor_free(fresh);
}

/* The boundary kinds by their header names: each set and read back, any other value refused
 * (the setting unchanged), and a sphere solved with Dirichlet (chi = 0 on the cube's faces)
 * into a mesh. */
static void test_boundaries(void) {
    const int32_t kinds[3] = {PSR_BOUNDARY_NEUMANN, PSR_BOUNDARY_FREE, PSR_BOUNDARY_DIRICHLET};
    psr_reconstructor *r = new_with_sphere(1000, 5);
    psr_mesh *m = NULL;
    int32_t v = -7;
    int k;

    section("boundary kinds: Neumann, free, Dirichlet");
    CHECK(PSR_BOUNDARY_NEUMANN == 0 && PSR_BOUNDARY_FREE == 1 && PSR_BOUNDARY_DIRICHLET == 2);
    CHECK_STATUS(psr_reconstructor_get_boundary(r, &v), PSR_STATUS_OK);
    CHECK(v == PSR_BOUNDARY_NEUMANN);
    for (k = 0; k < 3; k++) {
        CHECK_STATUS(psr_reconstructor_set_boundary(r, kinds[k]), PSR_STATUS_OK);
        CHECK_STATUS(psr_reconstructor_get_boundary(r, &v), PSR_STATUS_OK);
        CHECK(v == kinds[k]);
    }
    CHECK_STATUS(psr_reconstructor_set_boundary(r, 3), PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "PSR_BOUNDARY_DIRICHLET"));
    CHECK_STATUS(psr_reconstructor_set_boundary(r, -1), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_reconstructor_get_boundary(r, &v), PSR_STATUS_OK);
    CHECK(v == PSR_BOUNDARY_DIRICHLET);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    CHECK(m != NULL && psr_mesh_vertex_count(m) > 100 && psr_mesh_triangle_count(m) > 100);
    psr_mesh_free(m);
    psr_reconstructor_free(r);
}

/* Points in double, far from 0, directly and through a translation: the mesh's double vertices
 * (origin + float positions) are the same sphere's near 0, shifted; bad transforms, NULLs and
 * short buffers are refused. */
static void test_double_points(void) {
    enum { N = 1000 };
    static const double shift[3] = {1e6, -2e6, 3e5};
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    double translate[16], singular[16], projective[16], origin[3] = {-1, -1, -1};
    float p[3 * N], n[3 * N], *near_pos;
    double local[3 * N], moved[3 * N], *exact;
    psr_reconstructor *near_r = NULL, *far_r = NULL, *moved_r = NULL;
    psr_mesh *near_m = NULL, *far_m = NULL, *moved_m = NULL;
    size_t k, nv;
    double worst = 0.0, worst_moved = 0.0;

    section("points in double, transforms, double vertices");
    sphere(N, p, n);
    for (k = 0; k < 3 * N; k++) {
        local[k] = p[k];
        moved[k] = p[k] + shift[k % 3];
    }
    memcpy(translate, identity, sizeof translate);
    translate[3] = shift[0];
    translate[7] = shift[1];
    translate[11] = shift[2];
    memcpy(singular, identity, sizeof singular);
    singular[5] = 0.0;
    memcpy(projective, identity, sizeof projective);
    projective[14] = 2.0;

    CHECK_STATUS(psr_reconstructor_new(&near_r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_new(&far_r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_new(&moved_r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(near_r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(far_r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(moved_r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_points(near_r, p, 0, n, 0, N), PSR_STATUS_OK);

    CHECK_STATUS(psr_reconstructor_add_points_f64(NULL, moved, 0, n, 0, N),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points_f64(far_r, NULL, 0, n, 0, N),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points_f64(far_r, moved, 12, n, 0, N),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points_f64(far_r, moved, 0, n, 0, N), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_points_transformed(moved_r, local, 0, n, 0, N, NULL),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_points_transformed(moved_r, local, 0, n, 0, N, singular),
                 PSR_STATUS_INVALID_TRANSFORM);
    CHECK(contains(psr_reconstructor_last_error(moved_r), "singular"));
    CHECK_STATUS(psr_reconstructor_add_points_transformed(moved_r, NULL, 0, NULL, 0, 0, projective),
                 PSR_STATUS_INVALID_TRANSFORM);
    CHECK_STATUS(psr_reconstructor_add_points_transformed(moved_r, local, 0, n, 0, N, translate),
                 PSR_STATUS_OK);

    CHECK_STATUS(psr_reconstructor_solve(near_r, &near_m), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(far_r, &far_m), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(moved_r, &moved_m), PSR_STATUS_OK);
    if (near_m != NULL && far_m != NULL && moved_m != NULL) {
        nv = psr_mesh_vertex_count(near_m);
        CHECK(nv > 100 && psr_mesh_vertex_count(far_m) == nv &&
              psr_mesh_vertex_count(moved_m) == nv);
        CHECK_STATUS(psr_mesh_origin(far_m, NULL), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_mesh_origin(NULL, origin), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_mesh_origin(near_m, origin), PSR_STATUS_OK);
        CHECK(origin[0] == 0.0 && origin[1] == 0.0 && origin[2] == 0.0);
        CHECK_STATUS(psr_mesh_origin(far_m, origin), PSR_STATUS_OK);
        CHECK(fabs(origin[0] - shift[0]) < 8.0 && fabs(origin[1] - shift[1]) < 8.0);
        exact = malloc(3 * nv * sizeof(double));
        exact[0] = -7.0;
        CHECK_STATUS(psr_mesh_copy_positions_f64(far_m, exact, 3 * nv - 1),
                     PSR_STATUS_BUFFER_TOO_SMALL);
        CHECK(exact[0] == -7.0);
        CHECK_STATUS(psr_mesh_copy_positions_f64(far_m, NULL, 3 * nv), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_mesh_copy_positions_f64(NULL, exact, 3 * nv), PSR_STATUS_NULL_ARGUMENT);
        near_pos = (float *)psr_mesh_positions(near_m);
        CHECK_STATUS(psr_mesh_copy_positions_f64(far_m, exact, 3 * nv), PSR_STATUS_OK);
        for (k = 0; k < 3 * nv; k++) {
            double d = fabs(exact[k] - shift[k % 3] - near_pos[k]);
            if (d > worst) worst = d;
        }
        CHECK_STATUS(psr_mesh_copy_positions_f64(moved_m, exact, 3 * nv), PSR_STATUS_OK);
        for (k = 0; k < 3 * nv; k++) {
            double d = fabs(exact[k] - shift[k % 3] - near_pos[k]);
            if (d > worst_moved) worst_moved = d;
        }
        /* 3e-5 of the sphere's diagonal 2*sqrt(3) (tests/precision.rs: default parameters). */
        CHECK(worst < 1e-4);
        CHECK(worst_moved < 1e-4);
        free(exact);
    }
    psr_mesh_free(near_m);
    psr_mesh_free(far_m);
    psr_mesh_free(moved_m);
    psr_reconstructor_free(near_r);
    psr_reconstructor_free(far_r);
    psr_reconstructor_free(moved_r);
}

/* Points without normals: counted, refused when bad, and reconstructed with estimated
 * normals into a mesh whose triangles face outward (positive signed volume). */
static double signed_volume6(const psr_mesh *m);

static void test_positions_without_normals(void) {
    enum { N = 2000 };
    float *positions = malloc(3 * N * sizeof(float)), *normals = malloc(3 * N * sizeof(float));
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    size_t count = 0, k, nt;
    uint32_t neighbors = 0;
    int32_t orientation = -1;
    double volume6 = 0.0;

    section("points without normals: add_positions, estimation settings, solve");
    sphere(N, positions, normals);
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions(r, NULL, 0, 3), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_positions(r, positions, 4, 3), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_get_normal_neighbors(r, &neighbors), PSR_STATUS_OK);
    CHECK(neighbors == 20);
    CHECK_STATUS(psr_reconstructor_set_normal_neighbors(r, 0), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_reconstructor_set_normal_orientation(r, PSR_ORIENTATION_VIEWPOINT),
                 PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_reconstructor_set_viewpoint(r, 0.0, 0.0, 50.0), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(r, &orientation), PSR_STATUS_OK);
    CHECK(orientation == PSR_ORIENTATION_VIEWPOINT);
    CHECK_STATUS(psr_reconstructor_set_normal_orientation(r, PSR_ORIENTATION_PROPAGATE),
                 PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions(r, positions, 0, N), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == N);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m != NULL) {
        const float *v = psr_mesh_positions(m);
        const uint32_t *t = psr_mesh_triangles(m);
        nt = psr_mesh_triangle_count(m);
        for (k = 0; k < nt; k++) {
            const float *a = v + 3 * t[3 * k], *b = v + 3 * t[3 * k + 1], *c = v + 3 * t[3 * k + 2];
            volume6 += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                       (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                       (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
        }
        CHECK(volume6 > 0.0);
    }
    psr_mesh_free(m);
    m = NULL;

    /* The same points with the orientation read off the reconstruction itself. */
    CHECK_STATUS(psr_reconstructor_get_normal_reconstruction_iterations(r, &neighbors), PSR_STATUS_OK);
    CHECK(neighbors == 10);
    CHECK_STATUS(psr_reconstructor_set_normal_reconstruction_iterations(r, 0), PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "reconstruction_iterations"));
    CHECK_STATUS(psr_reconstructor_set_normal_reconstruction_iterations(r, 1001), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_reconstructor_set_normal_reconstruction_iterations(r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_normal_reconstruction_iterations(r, &neighbors), PSR_STATUS_OK);
    CHECK(neighbors == 5);
    CHECK_STATUS(psr_reconstructor_set_normal_orientation(r, PSR_ORIENTATION_RECONSTRUCTION), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(r, &orientation), PSR_STATUS_OK);
    CHECK(orientation == PSR_ORIENTATION_RECONSTRUCTION);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    CHECK(m != NULL && psr_mesh_triangle_count(m) > 0 && signed_volume6(m) > 0.0);
    psr_mesh_free(m);
    psr_reconstructor_free(r);
    free(positions);
    free(normals);
}

/* Six times the signed volume of a mesh: positive when its triangles face outward. */
static double signed_volume6(const psr_mesh *m) {
    const float *v = psr_mesh_positions(m);
    const uint32_t *t = psr_mesh_triangles(m);
    size_t k, nt = psr_mesh_triangle_count(m);
    double volume6 = 0.0;
    for (k = 0; k < nt; k++) {
        const float *a = v + 3 * t[3 * k], *b = v + 3 * t[3 * k + 1], *c = v + 3 * t[3 * k + 2];
        volume6 += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                   (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                   (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return volume6;
}

/* Points with the sensor that saw them: bad sensors and strides refused whole, the sensor
 * orientation selected by them and refused at solve when some points have no sensor, and a
 * sphere (centre (0.25, 0.25, 0.25), radius 1) scanned from six outside positions, one batch
 * per scan, reconstructed facing outward; one sensor at the centre turns it inside out. */
static void test_sensors(void) {
    enum { N = 2000 };
    float *positions = malloc(3 * N * sizeof(float)), *normals = malloc(3 * N * sizeof(float));
    float *scans = malloc(3 * N * sizeof(float)), *records = malloc(6 * N * sizeof(float));
    float sensors[6][3], centre[3] = {0.25f, 0.25f, 0.25f}, nan_sensor[3] = {0.0f, (float)NAN, 9.0f};
    size_t scan_size[6] = {0, 0, 0, 0, 0, 0}, count = 0, start = 0, i, k;
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    int32_t orientation = -1;
    const double sphere6 = 8.0 * 3.14159265358979323846;

    section("points with sensors: add_positions_seen_from, _with_sensors, PSR_ORIENTATION_SENSORS");
    sphere(N, positions, normals);
    for (k = 0; k < 6; k++) {
        for (i = 0; i < 3; i++) sensors[k][i] = centre[i];
        sensors[k][k / 2] += k % 2 == 0 ? 3.0f : -3.0f;
    }
    /* Group the samples by the sensor that sees them most squarely (it sees them: on a sphere
     * n . (s - p) > 0 for it). */
    for (k = 0; k < 6; k++) {
        for (i = 0; i < N; i++) {
            const float *nr = normals + 3 * i;
            size_t axis = 0;
            if (fabsf(nr[1]) > fabsf(nr[axis])) axis = 1;
            if (fabsf(nr[2]) > fabsf(nr[axis])) axis = 2;
            if (2 * axis + (nr[axis] < 0.0f ? 1 : 0) != k) continue;
            memcpy(scans + 3 * count, positions + 3 * i, 3 * sizeof(float));
            memcpy(records + 6 * count, positions + 3 * i, 3 * sizeof(float));
            memcpy(records + 6 * count + 3, sensors[k], 3 * sizeof(float));
            count++;
            scan_size[k]++;
        }
    }
    CHECK(count == N);

    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, scans, 0, 10, nan_sensor),
                 PSR_STATUS_NON_FINITE_POSITION);
    CHECK(contains(psr_reconstructor_last_error(r), "sensor"));
    records[6 * 4 + 5] = (float)INFINITY;
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, records, 24, records + 3, 24, 10),
                 PSR_STATUS_NON_FINITE_POSITION);
    CHECK(contains(psr_reconstructor_last_error(r), "sensor 4"));
    records[6 * 4 + 5] = sensors[0][2];
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, records, 24, records + 3, 6, 10),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "sensor_stride_bytes"));
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == 0);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(r, &orientation), PSR_STATUS_OK);
    CHECK(orientation == PSR_ORIENTATION_PROPAGATE);
    CHECK_STATUS(psr_reconstructor_set_normal_orientation(r, 4), PSR_STATUS_INVALID_PARAMETER);

    /* Mismatched use: one scan with its sensor, the rest without. */
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, scans, 0, scan_size[0], sensors[0]),
                 PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_normal_orientation(r, &orientation), PSR_STATUS_OK);
    CHECK(orientation == PSR_ORIENTATION_SENSORS);
    CHECK_STATUS(psr_reconstructor_add_positions(r, scans + 3 * scan_size[0], 0, N - scan_size[0]),
                 PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(m == NULL);
    CHECK(contains(psr_reconstructor_last_error(r), "no sensor"));
    CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_OK);

    /* One batch per scan: outward. */
    for (k = 0; k < 6; k++) {
        CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, scans + 3 * start, 0, scan_size[k], sensors[k]),
                     PSR_STATUS_OK);
        start += scan_size[k];
    }
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m != NULL) CHECK(fabs(signed_volume6(m) / sphere6 - 1.0) < 0.1);
    psr_mesh_free(m);
    m = NULL;

    /* One sensor per point, interleaved records: outward as well. */
    CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions_with_sensors(r, records, 24, records + 3, 24, N), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m != NULL) CHECK(fabs(signed_volume6(m) / sphere6 - 1.0) < 0.1);
    psr_mesh_free(m);
    m = NULL;

    /* Seen from inside: the sensors, not propagation, decide the sign. */
    CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_positions_seen_from(r, scans, 0, N, centre), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m != NULL) CHECK(fabs(signed_volume6(m) / sphere6 + 1.0) < 0.1);
    psr_mesh_free(m);
    psr_reconstructor_free(r);
    free(positions);
    free(normals);
    free(scans);
    free(records);
}

struct progress_state {
    int calls, stop_at, named;
};

static bool stop_early(void *user, psr_stage stage, float fraction) {
    struct progress_state *s = (struct progress_state *)user;
    const char *name = psr_stage_string((int)stage); /* allowed inside the callback */
    (void)fraction;
    s->calls++;
    s->named += name != NULL && strcmp(name, "unknown") != 0;
    return s->calls < s->stop_at;
}

static void test_cancel(void) {
    psr_reconstructor *r = new_with_sphere(1000, 5);
    psr_mesh *m = NULL;
    struct progress_state state = {0, 2, 0};

    section("cancellation from the progress callback");
    CHECK_STATUS(psr_reconstructor_set_progress_callback(r, stop_early, &state), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_CANCELLED);
    CHECK(m == NULL);
    CHECK(state.calls == 2);
    CHECK(state.named == 2);
    CHECK(contains(psr_reconstructor_last_error(r), "cancelled"));
    /* Still usable afterwards. */
    CHECK_STATUS(psr_reconstructor_set_progress_callback(r, NULL, NULL), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    CHECK(psr_mesh_triangle_count(m) > 0);
    psr_mesh_free(m);
    psr_reconstructor_free(r);
}

struct stop_inside_state {
    psr_stage stage;
    int stopped, calls_after_stop;
    float fraction;
};

/* Says stop at the first call reporting s->stage below 1 (the stage still running). */
static bool stop_inside(void *user, psr_stage stage, float fraction) {
    struct stop_inside_state *s = (struct stop_inside_state *)user;
    if (s->stopped) {
        s->calls_after_stop++;
        return false;
    }
    if (stage == s->stage && fraction < 1.0f) {
        s->stopped = 1;
        s->fraction = fraction;
        return false;
    }
    return true;
}

/* Issue 18: the callback is called while the extraction runs, not only between stages; a stop
   there cancels, and the handle then solves to the mesh a fresh handle makes, byte for byte.
   (40,000 points at depth 8: the extraction lasts far longer than the 20 ms between calls.) */
static void test_cancel_inside_a_stage(void) {
    psr_reconstructor *fresh = new_with_sphere(40000, 8), *r = new_with_sphere(40000, 8);
    psr_mesh *want = NULL, *m = NULL;
    struct stop_inside_state state = {PSR_STAGE_EXTRACT, 0, 0, -1.0f};

    section("cancellation inside the extraction, and the same mesh after");
    CHECK_STATUS(psr_reconstructor_solve(fresh, &want), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_progress_callback(r, stop_inside, &state), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_CANCELLED);
    CHECK(m == NULL);
    CHECK(state.stopped == 1);
    CHECK(state.fraction >= 0.0f && state.fraction < 1.0f);
    CHECK(state.calls_after_stop == 0);
    CHECK_STATUS(psr_reconstructor_set_progress_callback(r, NULL, NULL), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    if (m != NULL && want != NULL) {
        size_t nv = psr_mesh_vertex_count(m), nt = psr_mesh_triangle_count(m);
        CHECK(nv == psr_mesh_vertex_count(want) && nt == psr_mesh_triangle_count(want));
        if (nv == psr_mesh_vertex_count(want) && nt == psr_mesh_triangle_count(want)) {
            CHECK(memcmp(psr_mesh_positions(m), psr_mesh_positions(want), 3 * nv * sizeof(float)) == 0);
            CHECK(memcmp(psr_mesh_triangles(m), psr_mesh_triangles(want), 3 * nt * sizeof(uint32_t)) == 0);
        }
    }
    psr_mesh_free(m);
    psr_mesh_free(want);
    psr_reconstructor_free(r);
    psr_reconstructor_free(fresh);
}

static void test_panic(void) {
    section("a forced internal panic");
#if defined(PSR_TEST_PANIC)
    {
        psr_reconstructor *r = new_with_sphere(100, 4);
        psr_mesh *m = NULL;
        uint32_t depth = 99;
        size_t count = 99;
        CHECK_STATUS(psr_reconstructor_debug_panic_next_solve(r), PSR_STATUS_OK);
        CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_INTERNAL_ERROR);
        CHECK(m == NULL);
        CHECK(contains(psr_reconstructor_last_error(r), "panic"));
        CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_HANDLE_POISONED);
        CHECK_STATUS(psr_reconstructor_set_depth(r, 5), PSR_STATUS_HANDLE_POISONED);
        CHECK_STATUS(psr_reconstructor_get_depth(r, &depth), PSR_STATUS_HANDLE_POISONED);
        CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_HANDLE_POISONED);
        CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_HANDLE_POISONED);
        CHECK(depth == 99 && count == 99 && m == NULL);
        CHECK(contains(psr_reconstructor_last_error(r), "test hook"));
        psr_reconstructor_free(r);
    }
#else
    printf("SKIP forced panic: this psr was built without -DPSR_TEST_PANIC=ON\n");
#endif
}

struct run {
    size_t points;
    unsigned threads;
    size_t nv, nt;
    float *positions;
    uint32_t *triangles;
};

static void *run_once(void *arg) {
    struct run *run = (struct run *)arg;
    psr_reconstructor *r = new_with_sphere(run->points, 5);
    psr_mesh *m = NULL;
    psr_reconstructor_set_threads(r, run->threads);
    if (psr_reconstructor_solve(r, &m) == PSR_STATUS_OK) {
        run->nv = psr_mesh_vertex_count(m);
        run->nt = psr_mesh_triangle_count(m);
        run->positions = malloc(3 * run->nv * sizeof(float));
        run->triangles = malloc(3 * run->nt * sizeof(uint32_t));
        psr_mesh_copy_positions(m, run->positions, 3 * run->nv);
        psr_mesh_copy_triangles(m, run->triangles, 3 * run->nt);
    }
    psr_mesh_free(m);
    psr_reconstructor_free(r);
    return NULL;
}

static int same_run(const struct run *a, const struct run *b) {
    return a->nv == b->nv && a->nt == b->nt && a->positions && b->positions &&
           memcmp(a->positions, b->positions, 3 * a->nv * sizeof(float)) == 0 &&
           memcmp(a->triangles, b->triangles, 3 * a->nt * sizeof(uint32_t)) == 0;
}

static void test_threads(void) {
    struct run seq[2] = {{1200, 1, 0, 0, NULL, NULL}, {700, 2, 0, 0, NULL, NULL}};
    struct run par[2] = {{1200, 1, 0, 0, NULL, NULL}, {700, 2, 0, 0, NULL, NULL}};
    pthread_t t[2];
    int k;

    section("two handles on two threads give the meshes of sequential runs");
    run_once(&seq[0]);
    run_once(&seq[1]);
    for (k = 0; k < 2; k++) pthread_create(&t[k], NULL, run_once, &par[k]);
    for (k = 0; k < 2; k++) pthread_join(t[k], NULL);
    CHECK(seq[0].nt > 0 && seq[1].nt > 0);
    CHECK(same_run(&seq[0], &par[0]));
    CHECK(same_run(&seq[1], &par[1]));
    for (k = 0; k < 2; k++) {
        free(seq[k].positions);
        free(seq[k].triangles);
        free(par[k].positions);
        free(par[k].triangles);
    }
}

/* The first fields of psr_trim_options, as an older header would have had them (no piece
 * rule): a smaller struct the library must still read. */
typedef struct {
    size_t struct_size;
    int32_t threshold;
    uint32_t threads;
    double threshold_value;
} older_trim_options;

/* A newer header's struct: this one's fields and one more. */
typedef struct {
    psr_trim_options known;
    uint64_t later;
} newer_trim_options;

/* Copies of a mesh's triangles, to compare two meshes. */
static uint32_t *triangles_of(const psr_mesh *m, size_t *count) {
    uint32_t *t;
    *count = psr_mesh_triangle_count(m);
    t = malloc(3 * *count * sizeof(uint32_t) + 1);
    if (*count > 0) psr_mesh_copy_triangles(m, t, 3 * *count);
    return t;
}

static int same_triangles(const psr_mesh *a, const psr_mesh *b) {
    size_t na, nb;
    uint32_t *ta = triangles_of(a, &na), *tb = triangles_of(b, &nb);
    int same = na == nb && memcmp(ta, tb, 3 * na * sizeof(uint32_t)) == 0;
    free(ta);
    free(tb);
    return same;
}

/* A trim's progress callback: counts its calls, remembers the last stage and fraction, and says
 * stop from call stop_at on (0: never). */
typedef struct {
    int calls, stop_at, stage;
    float first, last;
} trim_progress;

static bool on_trim_progress(void *user, psr_stage stage, float fraction) {
    trim_progress *tp = user;
    if (tp->calls == 0) tp->first = fraction;
    tp->calls++;
    tp->stage = (int)stage;
    tp->last = fraction;
    return tp->stop_at == 0 || tp->calls < tp->stop_at;
}

static void test_trim(void) {
    enum { N = 6000 };
    float *p = malloc(3 * N * sizeof(float)), *nr = malloc(3 * N * sizeof(float));
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL, *t = NULL, *t_old = NULL, *t_new = NULL;
    psr_mesh *const sentinel = (psr_mesh *)&r;
    psr_mesh *out = sentinel;
    psr_trim_options opts;
    struct {
        older_trim_options older;
        unsigned char after[16];
    } guarded;
    newer_trim_options newer;
    size_t k, half = 0;
    int untouched = 1;

    section("trim: options from this, an older and a newer header; bad values; lifetimes");
    sphere(N, p, nr);
    /* Keep the upper half (y > 0: the lattice's first points): a scan with a missing side. */
    for (k = 0; k < N; k++)
        if (p[3 * k + 1] > 0.0f) half = k + 1;
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 6), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, nr, 0, half), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    psr_reconstructor_free(r);
    free(p);
    free(nr);
    if (m == NULL) return;

    /* NULL and sizes no header has. */
    CHECK_STATUS(psr_trim_options_init(NULL, sizeof opts), PSR_STATUS_NULL_ARGUMENT);
    memset(&opts, 0xAB, sizeof opts);
    CHECK_STATUS(psr_trim_options_init(&opts, 3), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(opts.struct_size != 3); /* nothing written */
    CHECK_STATUS(psr_trim_options_init(&opts, sizeof opts), PSR_STATUS_OK);
    CHECK(opts.struct_size == sizeof opts && opts.threshold == PSR_TRIM_THRESHOLD_AUTOMATIC);
    CHECK(opts.threads == 0 && opts.threshold_value == 0.0 && opts.min_piece_area == 0.0f);
    CHECK(opts.min_piece_triangles == 0);
    CHECK(opts.progress == NULL && opts.progress_user_data == NULL);
    CHECK_STATUS(psr_mesh_trim(NULL, &opts, &out), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_trim(m, &opts, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK(out == sentinel);
    CHECK(isnan(psr_mesh_trim_density(NULL)) && isnan(psr_mesh_trim_depth(NULL)));
    CHECK(isnan(psr_mesh_trim_density(m))); /* not trimmed */

    /* The automatic threshold cuts the lid away. */
    CHECK_STATUS(psr_mesh_trim(m, &opts, &t), PSR_STATUS_OK);
    if (t != NULL) {
        CHECK(psr_mesh_triangle_count(t) > 0);
        CHECK(psr_mesh_triangle_count(t) < psr_mesh_triangle_count(m));
        CHECK(psr_mesh_densities(t) != NULL);
        CHECK(psr_mesh_trim_density(t) > 0.0);
        CHECK(isfinite(psr_mesh_trim_depth(t)));
    }
    out = sentinel;
    CHECK_STATUS(psr_mesh_trim(m, NULL, &out), PSR_STATUS_OK); /* NULL: the defaults */
    if (out != sentinel && t != NULL) CHECK(same_triangles(out, t));
    if (out != sentinel) psr_mesh_free(out);

    /* Progress: PSR_STAGE_TRIM from 0 to 1 with the user pointer, the same mesh; a stop at the
     * first call cancels, with no call after it and *out untouched. */
    {
        trim_progress tp = {0, 0, -1, -1.0f, -1.0f};
        opts.progress = on_trim_progress;
        opts.progress_user_data = &tp;
        out = sentinel;
        CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_OK);
        CHECK(tp.calls >= 2 && tp.stage == PSR_STAGE_TRIM && tp.first == 0.0f && tp.last == 1.0f);
        if (out != sentinel && t != NULL) CHECK(same_triangles(out, t));
        if (out != sentinel) psr_mesh_free(out);
        tp.calls = 0;
        tp.stop_at = 1;
        out = sentinel;
        CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_CANCELLED);
        CHECK(tp.calls == 1 && out == sentinel);
        CHECK(strcmp(psr_stage_string(PSR_STAGE_TRIM), "trim") == 0);
        opts.progress = NULL;
        opts.progress_user_data = NULL;
    }

    /* Bad values: INVALID_PARAMETER, *out untouched. */
    out = sentinel;
    opts.threshold = 9;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_INVALID_PARAMETER);
    opts.threshold = PSR_TRIM_THRESHOLD_QUANTILE;
    opts.threshold_value = 1.5;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_INVALID_PARAMETER);
    opts.threshold = PSR_TRIM_THRESHOLD_DENSITY;
    opts.threshold_value = -1.0;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_INVALID_PARAMETER);
    opts.threshold_value = 1.0;
    opts.min_piece_area = 2.0f;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_INVALID_PARAMETER);
    opts.min_piece_area = 0.0f;
    opts.struct_size = 1u << 20;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &out), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(out == sentinel);

    /* An older, smaller struct: init writes only its bytes; the missing fields are defaults. */
    memset(guarded.after, 0xAB, sizeof guarded.after);
    CHECK_STATUS(psr_trim_options_init((psr_trim_options *)&guarded.older, sizeof guarded.older),
                 PSR_STATUS_OK);
    for (k = 0; k < sizeof guarded.after; k++) untouched &= guarded.after[k] == 0xAB;
    CHECK(untouched);
    CHECK(guarded.older.struct_size == sizeof(older_trim_options));
    guarded.older.threshold = PSR_TRIM_THRESHOLD_DEPTH;
    guarded.older.threshold_value = 5.5;
    CHECK_STATUS(psr_mesh_trim(m, (const psr_trim_options *)&guarded.older, &t_old),
                 PSR_STATUS_OK);
    CHECK_STATUS(psr_trim_options_init(&opts, sizeof opts), PSR_STATUS_OK);
    opts.threshold = PSR_TRIM_THRESHOLD_DEPTH;
    opts.threshold_value = 5.5;
    CHECK_STATUS(psr_mesh_trim(m, &opts, &t_new), PSR_STATUS_OK);
    if (t_old != NULL && t_new != NULL) {
        CHECK(same_triangles(t_old, t_new));
        CHECK(fabs(psr_mesh_trim_depth(t_old) - 5.5) < 1e-6);
    }

    /* A newer, larger struct: fine while its unknown field is zero, refused once it is set. */
    CHECK_STATUS(psr_trim_options_init(&newer.known, sizeof newer), PSR_STATUS_OK);
    CHECK(newer.later == 0 && newer.known.struct_size == sizeof newer);
    out = sentinel;
    CHECK_STATUS(psr_mesh_trim(m, &newer.known, &out), PSR_STATUS_OK);
    if (out != sentinel) psr_mesh_free(out);
    newer.later = 1;
    out = sentinel;
    CHECK_STATUS(psr_mesh_trim(m, &newer.known, &out), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(out == sentinel);

    /* A trimmed mesh outlives its source. */
    psr_mesh_free(m);
    if (t != NULL) CHECK(psr_mesh_vertex_count(t) > 0 && psr_mesh_positions(t) != NULL);
    psr_mesh_free(t);
    psr_mesh_free(t_old);
    psr_mesh_free(t_new);
}

/* What a caller compiled against an older header would pass: the first six fields of
 * psr_point_arrays (positions and normals only), with its own, smaller size. */
typedef struct {
    size_t struct_size;
    size_t count;
    const float *positions;
    size_t position_stride_bytes;
    const float *normals;
    size_t normal_stride_bytes;
} older_point_arrays;

/* Points with colours, a channel and weights through psr_point_arrays: NULL and size checks,
 * a struct from an older header, bad values, and the mesh's colours, channels and normals. */
static void test_point_arrays(void) {
    enum { N = 3000 };
    float *positions = malloc(3 * N * sizeof(float)), *normals = malloc(3 * N * sizeof(float));
    float *colors = malloc(4 * N * sizeof(float)), *heights = malloc(N * sizeof(float));
    float *weights = malloc(N * sizeof(float));
    const char *names[1] = {"height"};
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    psr_point_arrays a;
    older_point_arrays old;
    size_t count = 0, k, nv;
    bool vertex_normals = true, follows = true;
    float worst = 0.0f, *buffer;
    int unit_outward = 1;

    section("points with colours and channels: psr_point_arrays, older struct, mesh attributes");
    sphere(N, positions, normals);
    for (k = 0; k < N; k++) {
        float z = normals[3 * k + 2];
        colors[4 * k] = (z + 1.0f) / 2.0f;
        colors[4 * k + 1] = 0.5f;
        colors[4 * k + 2] = (1.0f - z) / 2.0f;
        colors[4 * k + 3] = 1.0f;
        heights[k] = z;
        weights[k] = 1.0f;
    }
    CHECK_STATUS(psr_point_arrays_init(NULL, sizeof a), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_point_arrays_init(&a, 2 * sizeof(size_t)), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_point_arrays_init(&a, sizeof a), PSR_STATUS_OK);
    CHECK(a.struct_size == sizeof a && a.count == 0 && a.colors == NULL && a.channel_count == 0);
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_point_arrays(NULL, &a), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "a is NULL"));
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_OK); /* count 0 */
    CHECK_STATUS(psr_reconstructor_get_vertex_normals(r, &vertex_normals), PSR_STATUS_OK);
    CHECK(!vertex_normals);
    CHECK_STATUS(psr_reconstructor_get_vertex_normals(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_vertex_normals(NULL, true), PSR_STATUS_NULL_ARGUMENT);
    /* The screening that follows the noise: on by default, round-trips. */
    CHECK_STATUS(psr_reconstructor_get_screening_follows_noise(r, &follows), PSR_STATUS_OK);
    CHECK(follows);
    CHECK_STATUS(psr_reconstructor_set_screening_follows_noise(r, false), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_screening_follows_noise(r, &follows), PSR_STATUS_OK);
    CHECK(!follows);
    CHECK_STATUS(psr_reconstructor_set_screening_follows_noise(r, true), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_get_screening_follows_noise(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_set_screening_follows_noise(NULL, true), PSR_STATUS_NULL_ARGUMENT);

    /* A struct from an older header: its smaller size, its fields only. */
    old.struct_size = sizeof old;
    old.count = N;
    old.positions = positions;
    old.position_stride_bytes = 0;
    old.normals = normals;
    old.normal_stride_bytes = 0;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, (const psr_point_arrays *)(const void *)&old),
                 PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == N);
    old.struct_size = 0; /* never initialised */
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, (const psr_point_arrays *)(const void *)&old),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "psr_point_arrays_init"));
    CHECK_STATUS(psr_reconstructor_clear_points(r), PSR_STATUS_OK);

    /* Bad batches: nothing is added. */
    a.count = N;
    a.positions = positions;
    a.normals = normals;
    a.colors = colors;
    a.color_components = 3;
    a.color_stride_bytes = 4 * sizeof(float); /* RGB read out of RGBA records */
    a.channels = heights;
    a.channel_count = 1;
    a.channel_names = names;
    a.confidence = weights;
    a.normals = NULL;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "normals"));
    a.normals = normals;
    a.color_components = 2;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_INVALID_ARGUMENT);
    a.color_components = 3;
    a.channel_names = NULL;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_NULL_ARGUMENT);
    a.channel_names = names;
    colors[4 * 17 + 2] = NAN;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_NON_FINITE_ATTRIBUTE);
    CHECK(contains(psr_reconstructor_last_error(r), "point 17"));
    colors[4 * 17 + 2] = 0.5f;
    weights[5] = -2.0f;
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_INVALID_WEIGHT);
    CHECK(contains(psr_reconstructor_last_error(r), "weight 5"));
    weights[5] = 1.0f;
    CHECK_STATUS(psr_reconstructor_point_count(r, &count), PSR_STATUS_OK);
    CHECK(count == 0);
    CHECK(strcmp(psr_status_string(PSR_STATUS_NON_FINITE_ATTRIBUTE), "PSR_STATUS_NON_FINITE_ATTRIBUTE") == 0);
    CHECK(strcmp(psr_status_string(PSR_STATUS_INVALID_WEIGHT), "PSR_STATUS_INVALID_WEIGHT") == 0);

    /* A good batch; the arrays may go at once. */
    CHECK_STATUS(psr_reconstructor_add_point_arrays(r, &a), PSR_STATUS_OK);
    free(colors);
    free(heights);
    free(weights);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_vertex_normals(r, true), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    psr_reconstructor_free(r);
    if (m != NULL) {
        const float *p = psr_mesh_positions(m), *c = psr_mesh_colors(m);
        const float *h = psr_mesh_channel(m, 0), *n = psr_mesh_normals(m);
        nv = psr_mesh_vertex_count(m);
        CHECK(psr_mesh_color_components(m) == 3 && psr_mesh_channel_count(m) == 1);
        CHECK(strcmp(psr_mesh_channel_name(m, 0), "height") == 0);
        CHECK(psr_mesh_channel_name(m, 1) == NULL && psr_mesh_channel(m, 1) == NULL);
        CHECK(p != NULL && c != NULL && h != NULL && n != NULL);
        for (k = 0; p != NULL && c != NULL && h != NULL && n != NULL && k < nv; k++) {
            float x = p[3 * k] - 0.25f, y = p[3 * k + 1] - 0.25f, z = p[3 * k + 2] - 0.25f;
            float len = sqrtf(x * x + y * y + z * z), zz = z / len;
            float e = fabsf(c[3 * k] - (zz + 1.0f) / 2.0f);
            if (fabsf(h[k] - zz) / 2.0f > e) e = fabsf(h[k] - zz) / 2.0f;
            if (e > worst) worst = e;
            unit_outward &= fabsf(n[3 * k] * n[3 * k] + n[3 * k + 1] * n[3 * k + 1] +
                                  n[3 * k + 2] * n[3 * k + 2] - 1.0f) < 1e-4f &&
                            (n[3 * k] * x + n[3 * k + 1] * y + n[3 * k + 2] * z) / len > 0.9f;
        }
        CHECK(worst < 0.03f);
        CHECK(unit_outward);
        buffer = malloc(3 * nv * sizeof(float));
        CHECK_STATUS(psr_mesh_copy_colors(m, buffer, 3 * nv - 1), PSR_STATUS_BUFFER_TOO_SMALL);
        CHECK_STATUS(psr_mesh_copy_colors(m, buffer, 3 * nv), PSR_STATUS_OK);
        CHECK(memcmp(buffer, c, 3 * nv * sizeof(float)) == 0);
        CHECK_STATUS(psr_mesh_copy_normals(m, buffer, 3 * nv), PSR_STATUS_OK);
        CHECK(memcmp(buffer, n, 3 * nv * sizeof(float)) == 0);
        CHECK_STATUS(psr_mesh_copy_channel(m, 0, buffer, nv), PSR_STATUS_OK);
        CHECK(memcmp(buffer, h, nv * sizeof(float)) == 0);
        CHECK_STATUS(psr_mesh_copy_channel(m, 1, buffer, nv), PSR_STATUS_INVALID_ARGUMENT);
        CHECK_STATUS(psr_mesh_copy_channel(NULL, 0, buffer, nv), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_mesh_copy_normals(m, NULL, 3 * nv), PSR_STATUS_NULL_ARGUMENT);
        free(buffer);
        psr_mesh_free(m);
    }
    CHECK(psr_mesh_colors(NULL) == NULL && psr_mesh_normals(NULL) == NULL);
    CHECK(psr_mesh_color_components(NULL) == 0 && psr_mesh_channel_count(NULL) == 0);
    CHECK(psr_mesh_channel_name(NULL, 0) == NULL && psr_mesh_channel(NULL, 0) == NULL);
    free(positions);
    free(normals);
}

/* The implicit function: kept by psr_reconstructor_solve_implicit, evaluated from C, sampled
 * on a grid that agrees with evaluation at the cells' centres (z fastest) and over a box,
 * NULL arguments, count 0, NaN queries, bad boxes, bad resolutions and short buffers; the
 * handle outlives the reconstructor and the mesh. */
static void test_implicit(void) {
    psr_reconstructor *r = new_with_sphere(2000, 5);
    psr_mesh *m = NULL;
    psr_implicit *f = NULL;
    double origin[3] = {0, 0, 0}, size = 0.0;
    float grid[4 * 4 * 4], values[4 * 4 * 4], points[3 * 4 * 4 * 4], gradient[3] = {0, 0, 0};
    float centre[3] = {0.25f, 0.25f, 0.25f}, on[3] = {1.25f, 0.25f, 0.25f};
    float nan_point[3] = {0.0f, 0.0f, 0.0f}, small[8], value = 0.0f;
    size_t i, j, k, n = 4;
    int agree = 1, untouched = 1;
    section("implicit function");
    nan_point[1] = (float)NAN;
    psr_implicit_free(NULL);
    CHECK(isnan(psr_implicit_isovalue(NULL)));
    CHECK_STATUS(psr_reconstructor_solve_implicit(NULL, &m, &f), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_implicit(r, &m, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK(m == NULL);
    CHECK_STATUS(psr_reconstructor_solve_implicit(r, &m, &f), PSR_STATUS_OK);
    CHECK(m != NULL && f != NULL);
    if (f == NULL) {
        psr_mesh_free(m);
        psr_reconstructor_free(r);
        return;
    }
    CHECK(psr_implicit_isovalue(f) == psr_mesh_isovalue(m));
    psr_mesh_free(m);
    psr_reconstructor_free(r);

    CHECK_STATUS(psr_implicit_cube(NULL, origin, &size), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_cube(f, NULL, &size), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_cube(f, origin, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_cube(f, origin, &size), PSR_STATUS_OK);
    CHECK(size > 2.0 && size < 2.5);

    CHECK_STATUS(psr_implicit_sample_grid(f, n, grid, n * n * n), PSR_STATUS_OK);
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            for (k = 0; k < n; k++) {
                size_t at = (i * n + j) * n + k, ijk[3];
                int a;
                ijk[0] = i;
                ijk[1] = j;
                ijk[2] = k;
                for (a = 0; a < 3; a++)
                    points[3 * at + a] =
                        (float)(origin[a] + ((double)ijk[a] + 0.5) * size / (double)n);
            }
    CHECK_STATUS(psr_implicit_evaluate(f, points, n * n * n, values), PSR_STATUS_OK);
    for (i = 0; i < n * n * n; i++) agree &= fabsf(grid[i] - values[i]) < 1e-4f;
    CHECK(agree);
    CHECK_STATUS(psr_implicit_evaluate(f, centre, 1, &value), PSR_STATUS_OK);
    CHECK(value < psr_implicit_isovalue(f));
    CHECK_STATUS(psr_implicit_gradient(f, on, 1, gradient), PSR_STATUS_OK);
    CHECK(gradient[0] > 0.0f && gradient[0] > 10.0f * fabsf(gradient[1]));

    CHECK_STATUS(psr_implicit_evaluate(NULL, centre, 1, &value), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_evaluate(f, NULL, 1, &value), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_evaluate(f, centre, 1, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_evaluate(f, NULL, 0, NULL), PSR_STATUS_OK);
    CHECK_STATUS(psr_implicit_gradient(NULL, centre, 1, gradient), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_gradient(f, NULL, 1, gradient), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_gradient(f, centre, 1, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_gradient(f, NULL, 0, NULL), PSR_STATUS_OK);
    CHECK_STATUS(psr_implicit_evaluate(f, centre, (size_t)-1, &value),
                 PSR_STATUS_INVALID_ARGUMENT);
    value = 42.0f;
    CHECK_STATUS(psr_implicit_evaluate(f, nan_point, 1, &value), PSR_STATUS_NON_FINITE_POSITION);
    CHECK_STATUS(psr_implicit_gradient(f, nan_point, 1, gradient),
                 PSR_STATUS_NON_FINITE_POSITION);
    CHECK(value == 42.0f);

    for (i = 0; i < 8; i++) small[i] = 5.0f;
    CHECK_STATUS(psr_implicit_sample_grid(NULL, 2, small, 8), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_sample_grid(f, 2, NULL, 8), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_implicit_sample_grid(f, 0, small, 8), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_implicit_sample_grid(f, 4097, small, 8), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_implicit_sample_grid(f, (size_t)-1, small, 8), PSR_STATUS_INVALID_PARAMETER);
    CHECK_STATUS(psr_implicit_sample_grid(f, 3, small, 8), PSR_STATUS_BUFFER_TOO_SMALL);
    for (i = 0; i < 8; i++) untouched &= small[i] == 5.0f;
    CHECK(untouched);
    CHECK_STATUS(psr_implicit_sample_grid(f, 2, small, 8), PSR_STATUS_OK);

    /* A box: over the bounding cube it is the grid, bit for bit; over a smaller box its cell
     * centres are the box's; a flat box (one side of zero length) is allowed. */
    {
        double lo[3], hi[3], flat_hi[3], bad_lo[3];
        float box[4 * 4 * 4], one = 0.0f;
        int same = 1;
        for (i = 0; i < 3; i++) {
            lo[i] = origin[i];
            hi[i] = origin[i] + size;
        }
        CHECK_STATUS(psr_implicit_sample_box(f, lo, hi, n, box, n * n * n), PSR_STATUS_OK);
        for (i = 0; i < n * n * n; i++) same &= memcmp(&box[i], &grid[i], sizeof(float)) == 0;
        CHECK(same);
        lo[0] = 0.0;
        lo[1] = 0.0;
        lo[2] = 0.0;
        hi[0] = 0.5;
        hi[1] = 0.5;
        hi[2] = 0.5;
        CHECK_STATUS(psr_implicit_sample_box(f, lo, hi, 1, &one, 1), PSR_STATUS_OK);
        CHECK_STATUS(psr_implicit_evaluate(f, centre, 1, &value), PSR_STATUS_OK);
        CHECK(fabsf(one - value) < 1e-4f);
        for (i = 0; i < 3; i++) flat_hi[i] = i == 2 ? lo[i] : hi[i];
        CHECK_STATUS(psr_implicit_sample_box(f, lo, flat_hi, 2, small, 8), PSR_STATUS_OK);
        for (i = 0; i < 8; i++) small[i] = 5.0f;
        untouched = 1;
        CHECK_STATUS(psr_implicit_sample_box(NULL, lo, hi, 2, small, 8),
                     PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_implicit_sample_box(f, NULL, hi, 2, small, 8), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_implicit_sample_box(f, lo, NULL, 2, small, 8), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_implicit_sample_box(f, lo, hi, 2, NULL, 8), PSR_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(psr_implicit_sample_box(f, hi, lo, 2, small, 8),
                     PSR_STATUS_INVALID_PARAMETER);
        for (i = 0; i < 3; i++) bad_lo[i] = lo[i];
        bad_lo[1] = (double)NAN;
        CHECK_STATUS(psr_implicit_sample_box(f, bad_lo, hi, 2, small, 8),
                     PSR_STATUS_INVALID_PARAMETER);
        bad_lo[1] = -(double)INFINITY;
        CHECK_STATUS(psr_implicit_sample_box(f, bad_lo, hi, 2, small, 8),
                     PSR_STATUS_INVALID_PARAMETER);
        CHECK_STATUS(psr_implicit_sample_box(f, lo, hi, 0, small, 8),
                     PSR_STATUS_INVALID_PARAMETER);
        CHECK_STATUS(psr_implicit_sample_box(f, lo, hi, 3, small, 8),
                     PSR_STATUS_BUFFER_TOO_SMALL);
        for (i = 0; i < 8; i++) untouched &= small[i] == 5.0f;
        CHECK(untouched);
    }
    psr_implicit_free(f);
}

/* PLY through the library: psr_mesh_write_ply writes a solved mesh, psr_ply_read gives it back
 * (positions, triangles, densities as confidence); a missing file, a file that is not PLY, bad
 * flags and NULLs get their statuses and a message in the caller's buffer. */
static void test_ply_files(void) {
    enum { N = 3000 };
    float *p = malloc(3 * N * sizeof(float)), *nr = malloc(3 * N * sizeof(float));
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    psr_ply *ply = NULL, *const sentinel = (psr_ply *)&r, *out = sentinel;
    char path[512], message[256], tiny[8];
    const char *dir = getenv("TMPDIR");
    FILE *f;

    section("PLY files: psr_mesh_write_ply, psr_ply_read, bad files and arguments");
    snprintf(path, sizeof path, "%s/psr_contract_%ld.ply", dir != NULL ? dir : "/tmp",
             (long)getpid());
    sphere(N, p, nr);
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 5), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_add_points(r, p, 0, nr, 0, N), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_solve(r, &m), PSR_STATUS_OK);
    psr_reconstructor_free(r);
    free(p);
    free(nr);
    if (m == NULL) return;

    memset(message, 'x', sizeof message);
    CHECK_STATUS(psr_mesh_write_ply(m, path, 0, message, sizeof message), PSR_STATUS_OK);
    CHECK(message[0] == '\0');
    CHECK_STATUS(psr_ply_read(path, &ply, message, sizeof message), PSR_STATUS_OK);
    if (ply != NULL) {
        size_t nv = psr_mesh_vertex_count(m), nt = psr_mesh_triangle_count(m);
        CHECK(psr_ply_vertex_count(ply) == nv && psr_ply_triangle_count(ply) == nt);
        CHECK(memcmp(psr_ply_positions(ply), psr_mesh_positions(m), 3 * nv * sizeof(float)) == 0);
        CHECK(memcmp(psr_ply_triangles(ply), psr_mesh_triangles(m), 3 * nt * sizeof(uint32_t)) ==
              0);
        CHECK(memcmp(psr_ply_confidence(ply), psr_mesh_densities(m), nv * sizeof(float)) == 0);
        CHECK(psr_ply_normals(ply) == NULL && psr_ply_colors(ply) == NULL);
        CHECK(psr_ply_positions_f64(ply) == NULL && psr_ply_channel_count(ply) == 0);
        psr_ply_free(ply);
    }
    psr_ply_free(NULL);

    /* Text, then a file that is not PLY. */
    CHECK_STATUS(psr_mesh_write_ply(m, path, PSR_PLY_ASCII, NULL, 0), PSR_STATUS_OK);
    f = fopen(path, "r");
    CHECK(f != NULL && fgets(message, sizeof message, f) != NULL && strcmp(message, "ply\n") == 0 &&
          fgets(message, sizeof message, f) != NULL && contains(message, "format ascii"));
    if (f != NULL) fclose(f);
    f = fopen(path, "w");
    if (f != NULL) {
        fputs("solid not a ply\n", f);
        fclose(f);
    }
    CHECK_STATUS(psr_ply_read(path, &out, message, sizeof message), PSR_STATUS_INVALID_FILE);
    CHECK(out == sentinel && contains(message, "not a PLY file"));
    /* A short buffer: 7 bytes and the NUL. */
    CHECK_STATUS(psr_ply_read(path, &out, tiny, sizeof tiny), PSR_STATUS_INVALID_FILE);
    CHECK(strcmp(tiny, "psr_ply") == 0);
    remove(path);
    CHECK_STATUS(psr_ply_read(path, &out, message, sizeof message), PSR_STATUS_IO_ERROR);
    CHECK(out == sentinel && contains(message, "psr_contract_"));

    /* Bad arguments. */
    CHECK_STATUS(psr_ply_read(NULL, &out, message, sizeof message), PSR_STATUS_NULL_ARGUMENT);
    CHECK(strcmp(message, "psr_ply_read: path is NULL") == 0);
    CHECK_STATUS(psr_ply_read(path, NULL, NULL, 0), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_ply_read("", &out, NULL, 0), PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_mesh_write_ply(NULL, path, 0, NULL, 0), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_write_ply(m, NULL, 0, NULL, 0), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_mesh_write_ply(m, path, PSR_PLY_ASCII | PSR_PLY_BIG_ENDIAN, NULL, 0),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_mesh_write_ply(m, path, 64, message, sizeof message),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK(contains(message, "flags"));
    CHECK_STATUS(psr_mesh_write_ply(m, "/nonexistent-dir/psr/mesh.ply", 0, message, sizeof message),
                 PSR_STATUS_IO_ERROR);
    CHECK(contains(message, "nonexistent-dir"));
    CHECK(strcmp(psr_status_string(PSR_STATUS_IO_ERROR), "PSR_STATUS_IO_ERROR") == 0);
    CHECK(strcmp(psr_status_string(PSR_STATUS_INVALID_FILE), "PSR_STATUS_INVALID_FILE") == 0);
    CHECK(out == sentinel);
    psr_mesh_free(m);
}

/* The entries of directory dir other than . and .. (-1 when it cannot be read). */
static int entries(const char *dir) {
    DIR *d = opendir(dir);
    struct dirent *e;
    int n = 0;
    if (d == NULL) return -1;
    while ((e = readdir(d)) != NULL)
        n += strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0;
    closedir(d);
    return n;
}

/* Writes n points of sphere() with their normals to path as an ASCII PLY; 1 on success. */
static int write_sphere_ply(const char *path, size_t n) {
    float *p = malloc(3 * n * sizeof(float)), *nr = malloc(3 * n * sizeof(float));
    FILE *f = fopen(path, "w");
    size_t i;
    int ok = f != NULL && p != NULL && nr != NULL;
    if (ok) {
        sphere(n, p, nr);
        fprintf(f, "ply\nformat ascii 1.0\nelement vertex %lu\n", (unsigned long)n);
        fputs("property float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\nend_header\n", f);
        for (i = 0; i < n; i++)
            fprintf(f, "%.9g %.9g %.9g %.9g %.9g %.9g\n", p[3 * i], p[3 * i + 1], p[3 * i + 2],
                    nr[3 * i], nr[3 * i + 1], nr[3 * i + 2]);
    }
    if (f != NULL) ok = fclose(f) == 0 && ok;
    free(p);
    free(nr);
    return ok;
}

/* A report no run gives, to see that a failure leaves *report alone. */
static psr_out_of_core_report untouched_report(void) {
    psr_out_of_core_report report;
    memset(&report, 0, sizeof report);
    report.points = report.vertices = report.triangles = report.slabs = 77;
    report.depth = report.attributes_dropped = 77;
    report.unsupported_components = 77;
    report.isovalue = report.seconds = 77.0;
    return report;
}

/* Reconstruction out of core, PLY file to PLY file: NULLs, empty paths, a missing input (the
 * path in the message), zero slabs without a memory limit; 20,000 points at depth 6 in 3 slabs
 * giving a closed genus-0 mesh whose counts are the report's (read back with psr_ply_read) and
 * leaving nothing in the temp_dir given; a cancel from the progress callback in two of the
 * passes, with no temporary file left and the report untouched. Depth 6 with full depth 4: the
 * slabs' shared base is solved to the depth - 3 but at least the full depth, and must stay 2
 * below the finest depth the samples reach (6 here). */
static void test_out_of_core(void) {
    enum { N = 20000 };
    const psr_stage stops[2] = {PSR_STAGE_SOLVE, PSR_STAGE_EXTRACT};
    const char *tmp = getenv("TMPDIR");
    char dir[400], input[450], output[450], temp[450], missing[450];
    psr_reconstructor *r = NULL;
    psr_out_of_core_report report = untouched_report();
    const psr_out_of_core_report untouched = untouched_report();
    psr_out_of_core_noise noise = {-1.0, -1.0, 77};
    psr_ply *ply = NULL;
    int k;

    section("out of core: psr_reconstructor_solve_file_out_of_core, its report, temporary files");
    snprintf(dir, sizeof dir, "%s/psr_contract_ooc_XXXXXX", tmp != NULL ? tmp : "/tmp");
    if (mkdtemp(dir) == NULL) {
        CHECK(!"mkdtemp");
        return;
    }
    snprintf(input, sizeof input, "%s/sphere.ply", dir);
    snprintf(output, sizeof output, "%s/mesh.ply", dir);
    snprintf(temp, sizeof temp, "%s/temp", dir);
    snprintf(missing, sizeof missing, "%s/missing.ply", dir);
    CHECK(mkdir(temp, 0700) == 0);
    CHECK(write_sphere_ply(input, N));
    CHECK_STATUS(psr_reconstructor_new(&r), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_depth(r, 6), PSR_STATUS_OK);
    CHECK_STATUS(psr_reconstructor_set_full_depth(r, 4), PSR_STATUS_OK);

    /* Refusals: nothing written, the report untouched. */
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(NULL, input, output, temp, 3, 0, &report),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, NULL, output, temp, 3, 0, &report),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "NULL"));
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, NULL, temp, 3, 0, &report),
                 PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, "", output, temp, 3, 0, &report),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, "", temp, 3, 0, &report),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, output, "", 3, 0, &report),
                 PSR_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, missing, output, temp, 3, 0, &report),
                 PSR_STATUS_IO_ERROR);
    CHECK(contains(psr_reconstructor_last_error(r), missing));
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, output, temp, 0, 0, &report),
                 PSR_STATUS_INVALID_PARAMETER);
    CHECK(contains(psr_reconstructor_last_error(r), "max_memory"));
    CHECK(memcmp(&report, &untouched, sizeof report) == 0);
    CHECK(access(output, F_OK) != 0);
    CHECK(entries(temp) == 0);
    /* No run yet: no noise to read. */
    CHECK_STATUS(psr_reconstructor_out_of_core_noise(NULL, &noise), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_out_of_core_noise(r, NULL), PSR_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(psr_reconstructor_out_of_core_noise(r, &noise), PSR_STATUS_INVALID_ARGUMENT);
    CHECK(contains(psr_reconstructor_last_error(r), "psr_reconstructor_out_of_core_noise"));
    CHECK(noise.cells_beyond_padding == 77);

    /* A run in 3 slabs: the file holds what the report says. */
    CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, output, temp, 3, 0, &report),
                 PSR_STATUS_OK);
    CHECK(report.points == N && report.slabs == 3 && report.depth == 6);
    CHECK(report.attributes_dropped == 0 && report.unsupported_components == 0);
    CHECK(isfinite(report.isovalue) && report.seconds >= 0.0);
    CHECK(entries(temp) == 0);
    CHECK_STATUS(psr_ply_read(output, &ply, NULL, 0), PSR_STATUS_OK);
    if (ply != NULL) {
        CHECK(psr_ply_vertex_count(ply) == report.vertices);
        CHECK(psr_ply_triangle_count(ply) == report.triangles);
        CHECK(report.triangles > 1000);
        /* Closed and of genus 0 (each edge in two triangles): V - E + F = V - F / 2 = 2. */
        CHECK(2 * report.vertices == report.triangles + 4);
        CHECK(psr_ply_confidence(ply) != NULL); /* the densities, as value */
        psr_ply_free(ply);
    }
    /* The exact sphere reads no noise: sigma 0, the screening at the depth. */
    CHECK_STATUS(psr_reconstructor_out_of_core_noise(r, &noise), PSR_STATUS_OK);
    CHECK(noise.sample_noise == 0.0 && noise.screening_depth == 6.0);
    CHECK(noise.cells_beyond_padding == 0);

    /* A stop from the progress callback inside a pass: cancelled, nothing left behind. */
    for (k = 0; k < 2; k++) {
        struct stop_inside_state state = {PSR_STAGE_POINTS, 0, 0, -1.0f};
        state.stage = stops[k];
        report = untouched_report();
        CHECK_STATUS(psr_reconstructor_set_progress_callback(r, stop_inside, &state), PSR_STATUS_OK);
        CHECK_STATUS(psr_reconstructor_solve_file_out_of_core(r, input, output, temp, 3, 0, &report),
                     PSR_STATUS_CANCELLED);
        CHECK(contains(psr_reconstructor_last_error(r), "cancelled"));
        CHECK(state.stopped == 1 && state.calls_after_stop == 0);
        CHECK(memcmp(&report, &untouched, sizeof report) == 0);
        CHECK(entries(temp) == 0);
        CHECK_STATUS(psr_reconstructor_out_of_core_noise(r, &noise), PSR_STATUS_INVALID_ARGUMENT);
    }
    CHECK_STATUS(psr_reconstructor_set_progress_callback(r, NULL, NULL), PSR_STATUS_OK);
    psr_reconstructor_free(r);
    remove(input);
    remove(output);
    rmdir(temp);
    CHECK(rmdir(dir) == 0);
}

int main(void) {
    printf("psr %s C contract test\n", psr_version());
    test_null_arguments();
    test_order_and_parameters();
    test_bad_batches();
    test_mesh();
    test_boundaries();
    test_double_points();
    test_positions_without_normals();
    test_sensors();
    test_point_arrays();
    test_cancel();
    test_cancel_inside_a_stage();
    test_panic();
    test_threads();
    test_trim();
    test_stats();
    test_implicit();
    test_memory();
    test_ply_files();
    test_out_of_core();
    printf("%d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}

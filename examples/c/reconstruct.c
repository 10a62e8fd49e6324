/*
 * Reconstructs a surface from an oriented point cloud with the psr C API and prints the mesh's
 * size and isovalue.
 *
 *   reconstruct_c [cloud.ply [depth]]
 *
 * The cloud is a binary little-endian PLY whose vertices are float x y z nx ny nz (as the shipped
 * examples/data/kitten_cgal.ply); the reader below handles exactly that.
 */
#include <psr.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef PSR_EXAMPLE_DATA
#define PSR_EXAMPLE_DATA "kitten_cgal.ply"
#endif

/* Reads the vertices of a binary little-endian PLY with float x y z nx ny nz, interleaved:
 * 6 floats per point. Returns a malloc'ed array (free it) and the count, or NULL. */
static float *read_ply(const char *path, size_t *count) {
    FILE *f = fopen(path, "rb");
    char line[512];
    size_t n = 0;
    int properties = 0, binary_le = 0, in_vertex = 0;
    const char *expected[6] = {"x", "y", "z", "nx", "ny", "nz"};
    float *data = NULL;
    unsigned probe = 1;

    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return NULL;
    }
    if (*(unsigned char *)&probe != 1) {
        fprintf(stderr, "this example reader only runs on little-endian machines\n");
        fclose(f);
        return NULL;
    }
    if (!fgets(line, sizeof line, f) || strncmp(line, "ply", 3) != 0) {
        fprintf(stderr, "%s is not a PLY file\n", path);
        fclose(f);
        return NULL;
    }
    while (fgets(line, sizeof line, f)) {
        char kind[64], type[64], name[64];
        unsigned long value;
        if (strncmp(line, "end_header", 10) == 0) {
            break;
        } else if (strncmp(line, "format binary_little_endian 1.0", 31) == 0) {
            binary_le = 1;
        } else if (sscanf(line, "element %63s %lu", kind, &value) == 2) {
            in_vertex = strcmp(kind, "vertex") == 0;
            if (in_vertex) n = (size_t)value;
        } else if (in_vertex && sscanf(line, "property %63s %63s", type, name) == 2) {
            if (properties >= 6 || strcmp(type, "float") != 0 || strcmp(name, expected[properties]) != 0) {
                fprintf(stderr, "%s: vertices must be exactly float x y z nx ny nz\n", path);
                fclose(f);
                return NULL;
            }
            properties++;
        }
    }
    if (!binary_le || properties != 6 || n == 0) {
        fprintf(stderr, "%s: need binary_little_endian vertices with float x y z nx ny nz\n", path);
        fclose(f);
        return NULL;
    }
    data = malloc(n * 6 * sizeof(float));
    if (!data || fread(data, 6 * sizeof(float), n, f) != n) {
        fprintf(stderr, "%s: truncated vertex data\n", path);
        free(data);
        fclose(f);
        return NULL;
    }
    fclose(f);
    *count = n;
    return data;
}

/* Prints each stage once, when it starts. Runs on the thread that called solve. */
static bool on_progress(void *user, psr_stage stage, float fraction) {
    int *last = (int *)user;
    (void)fraction;
    if ((int)stage != *last) {
        fprintf(stderr, "  stage: %s\n", psr_stage_string((int)stage));
        *last = (int)stage;
    }
    return true; /* return false to cancel */
}

/* Prints the failed call's status and message, and jumps to cleanup. */
#define CHECK(call)                                                                        \
    do {                                                                                   \
        psr_status status_ = (call);                                                       \
        if (status_ != PSR_STATUS_OK) {                                                    \
            fprintf(stderr, "%s failed: %s: %s\n", #call, psr_status_string((int)status_), \
                    psr_reconstructor_last_error(r));                                      \
            goto done;                                                                     \
        }                                                                                  \
    } while (0)

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : PSR_EXAMPLE_DATA;
    unsigned depth = argc > 2 ? (unsigned)strtoul(argv[2], NULL, 10) : 7;
    psr_reconstructor *r = NULL;
    psr_mesh *mesh = NULL;
    size_t count = 0, stored = 0;
    int last_stage = -1, exit_code = 1;
    float *points = read_ply(path, &count);

    if (!points) return 1;
    if (psr_version_major() != PSR_VERSION_MAJOR || psr_version_minor() != PSR_VERSION_MINOR) {
        fprintf(stderr, "header %d.%d does not match library %s\n", PSR_VERSION_MAJOR,
                PSR_VERSION_MINOR, psr_version());
        free(points);
        return 1;
    }
    printf("psr %s: %zu points from %s, depth %u\n", psr_version(), count, path, depth);

    if (psr_reconstructor_new(&r) != PSR_STATUS_OK) {
        free(points);
        return 1;
    }
    CHECK(psr_reconstructor_set_depth(r, depth));
    CHECK(psr_reconstructor_set_progress_callback(r, on_progress, &last_stage));
    /* Interleaved x y z nx ny nz: both arrays have a 24-byte stride. The points are copied. */
    CHECK(psr_reconstructor_add_points(r, points, 6 * sizeof(float), points + 3,
                                       6 * sizeof(float), count));
    free(points);
    points = NULL;
    CHECK(psr_reconstructor_point_count(r, &stored));
    CHECK(psr_reconstructor_solve(r, &mesh));

    printf("vertices: %zu\n", psr_mesh_vertex_count(mesh));
    printf("triangles: %zu\n", psr_mesh_triangle_count(mesh));
    printf("isovalue: %.6f\n", psr_mesh_isovalue(mesh));
    if (psr_mesh_vertex_count(mesh) > 0) {
        const float *p = psr_mesh_positions(mesh);
        printf("first vertex: %.4f %.4f %.4f\n", p[0], p[1], p[2]);
    }
    exit_code = psr_mesh_triangle_count(mesh) > 0 && stored == count ? 0 : 1;

done:
    free(points);
    psr_mesh_free(mesh);
    psr_reconstructor_free(r);
    return exit_code;
}

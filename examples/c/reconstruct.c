/*
 * Reconstructs a surface from a point cloud with the psr C API, prints the mesh's size and
 * isovalue, and writes it as PLY when given an output path.
 *
 *   reconstruct_c [cloud.ply [depth [mesh.ply]]]
 *
 * The cloud is read with psr's own PLY reader (psr_ply_read: ASCII or binary, any property
 * types); its normals are used when it has them, otherwise psr estimates and orients them. The
 * mesh is written with psr's writer (psr_mesh_write_ply), the bytes the psr program writes.
 */
#include <psr.h>

#include <stdio.h>
#include <stdlib.h>

#ifndef PSR_EXAMPLE_DATA
#define PSR_EXAMPLE_DATA "kitten_cgal.ply"
#endif

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
    const char *out_path = argc > 3 ? argv[3] : NULL;
    char message[512];
    psr_ply *cloud = NULL;
    psr_reconstructor *r = NULL;
    psr_mesh *mesh = NULL;
    size_t count = 0, stored = 0;
    int last_stage = -1, exit_code = 1;

    if (psr_version_major() != PSR_VERSION_MAJOR || psr_version_minor() != PSR_VERSION_MINOR) {
        fprintf(stderr, "header %d.%d does not match library %s\n", PSR_VERSION_MAJOR,
                PSR_VERSION_MINOR, psr_version());
        return 1;
    }
    /* A file's problem comes back in words: which line, which element, the system's reason. */
    if (psr_ply_read(path, &cloud, message, sizeof message) != PSR_STATUS_OK) {
        fprintf(stderr, "%s\n", message);
        return 1;
    }
    count = psr_ply_vertex_count(cloud);
    printf("psr %s: %zu points from %s (%s), depth %u\n", psr_version(), count, path,
           psr_ply_normals(cloud) != NULL ? "with normals" : "normals to estimate", depth);

    if (psr_reconstructor_new(&r) != PSR_STATUS_OK) {
        psr_ply_free(cloud);
        return 1;
    }
    CHECK(psr_reconstructor_set_depth(r, depth));
    CHECK(psr_reconstructor_set_progress_callback(r, on_progress, &last_stage));
    /* The points are copied: the cloud may be freed as soon as they are added. */
    if (psr_ply_normals(cloud) != NULL)
        CHECK(psr_reconstructor_add_points(r, psr_ply_positions(cloud), 0, psr_ply_normals(cloud),
                                           0, count));
    else
        CHECK(psr_reconstructor_add_positions(r, psr_ply_positions(cloud), 0, count));
    psr_ply_free(cloud);
    cloud = NULL;
    CHECK(psr_reconstructor_point_count(r, &stored));
    CHECK(psr_reconstructor_solve(r, &mesh));

    printf("vertices: %zu\n", psr_mesh_vertex_count(mesh));
    printf("triangles: %zu\n", psr_mesh_triangle_count(mesh));
    printf("isovalue: %.6f\n", psr_mesh_isovalue(mesh));
    if (psr_mesh_vertex_count(mesh) > 0) {
        const float *p = psr_mesh_positions(mesh);
        printf("first vertex: %.4f %.4f %.4f\n", p[0], p[1], p[2]);
    }
    if (out_path != NULL) {
        if (psr_mesh_write_ply(mesh, out_path, 0, message, sizeof message) != PSR_STATUS_OK) {
            fprintf(stderr, "%s\n", message);
            goto done;
        }
        printf("wrote %s\n", out_path);
    }
    exit_code = psr_mesh_triangle_count(mesh) > 0 && stored == count ? 0 : 1;

done:
    psr_ply_free(cloud);
    psr_mesh_free(mesh);
    psr_reconstructor_free(r);
    return exit_code;
}

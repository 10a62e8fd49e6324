/* The C side of bench/python_overhead.py: the reconstruction a C host does, timed from C.
 *
 *     python_overhead POINTS.bin COUNT DEPTH
 *
 * POINTS.bin holds COUNT records of six float32 (x y z nx ny nz). Times what psr.reconstruct
 * does through the C ABI (new, set_depth, add_points, solve, copy of positions, triangles and
 * densities out, free) with CLOCK_MONOTONIC, and the process's CPU time (user + system, all threads)
 * over the same calls, and prints "seconds cpu_seconds vertices triangles". */
#include <psr.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <time.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double cpu(void) {
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * (double)(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s POINTS.bin COUNT DEPTH\n", argv[0]);
        return 2;
    }
    size_t n = strtoull(argv[2], NULL, 10);
    unsigned depth = (unsigned)strtoul(argv[3], NULL, 10);
    float *xyzn = malloc(n * 6 * sizeof(float));
    FILE *f = fopen(argv[1], "rb");
    if (!xyzn || !f || fread(xyzn, 6 * sizeof(float), n, f) != n) {
        fprintf(stderr, "cannot read %zu points from %s\n", n, argv[1]);
        return 1;
    }
    fclose(f);

    double start = now(), start_cpu = cpu();
    psr_reconstructor *r = NULL;
    psr_mesh *m = NULL;
    psr_status s = psr_reconstructor_new(&r);
    if (s == PSR_STATUS_OK) s = psr_reconstructor_set_depth(r, depth);
    if (s == PSR_STATUS_OK) s = psr_reconstructor_add_points(r, xyzn, 24, xyzn + 3, 24, n);
    if (s == PSR_STATUS_OK) s = psr_reconstructor_solve(r, &m);
    if (s != PSR_STATUS_OK) {
        fprintf(stderr, "%s: %s\n", psr_status_string(s), psr_reconstructor_last_error(r));
        return 1;
    }
    size_t nv = psr_mesh_vertex_count(m), nt = psr_mesh_triangle_count(m);
    float *positions = malloc(3 * nv * sizeof(float));
    uint32_t *triangles = malloc(3 * nt * sizeof(uint32_t));
    float *densities = malloc(nv * sizeof(float));
    if (psr_mesh_copy_positions(m, positions, 3 * nv) != PSR_STATUS_OK ||
        psr_mesh_copy_triangles(m, triangles, 3 * nt) != PSR_STATUS_OK ||
        psr_mesh_copy_densities(m, densities, nv) != PSR_STATUS_OK) {
        fprintf(stderr, "copy-out failed\n");
        return 1;
    }
    psr_mesh_free(m);
    psr_reconstructor_free(r);
    double seconds = now() - start, cpu_seconds = cpu() - start_cpu;
    printf("%.6f %.6f %zu %zu\n", seconds, cpu_seconds, nv, nt);
    free(positions);
    free(triangles);
    free(densities);
    free(xyzn);
    return 0;
}

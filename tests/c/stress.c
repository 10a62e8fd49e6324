/*
 * Many hosts at once: N threads each drive psr reconstructors through the C API for a bounded
 * time, with random parameters, random thread counts, random cancellations from the progress
 * callback, handles freed between any two calls and new ones made, and handles passed from
 * one thread to another through a shared pool.
 *
 *   stress [--threads N] [--seconds S] [--seed X] [--configs K]
 *
 * Before the threads start, K random configurations (a synthetic cloud: a sphere, a torus or
 * two spheres, small enough that a solve takes well under a second; and a value for every
 * parameter, each within its documented range) are solved once each on one handle with one
 * worker thread: the references. Then every completed solve on any thread, at any thread count,
 * must give a mesh bit-for-bit equal to its configuration's reference (vertex positions,
 * triangles, densities, and vertex normals when asked for); every cancelled solve must return
 * PSR_STATUS_CANCELLED with no mesh, only after the callback said stop, and leave the handle
 * usable (its points and parameters kept; half the time it is solved again at once and
 * checked). The callback checks it runs on the solving thread with a known stage and a fraction
 * in [0, 1].
 *
 * Not a timed test: it prints what it did (solves completed, cancelled, handles created, freed
 * and moved) and exits non-zero on the first wrong result. Meant to run under
 * AddressSanitizer/LeakSanitizer (.ci/sanitizers.sh) or valgrind as well.
 */
#define _POSIX_C_SOURCE 200809L
#include <psr.h>

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- random numbers: splitmix64, one state per thread ------------------------------------- */

static uint64_t next_u64(uint64_t *state) {
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* An integer in [lo, hi]. */
static uint32_t uniform_int(uint64_t *state, uint32_t lo, uint32_t hi) {
    return lo + (uint32_t)(next_u64(state) % ((uint64_t)hi - lo + 1));
}

/* A double in [0, 1). */
static double uniform(uint64_t *state) { return (double)(next_u64(state) >> 11) * 0x1.0p-53; }

static int chance(uint64_t *state, double p) { return uniform(state) < p; }

/* ---- clouds -------------------------------------------------------------------------------- */

enum shape { SPHERE, TORUS, TWO_SPHERES, SHAPES };
static const char *const shape_names[SHAPES] = {"sphere", "torus", "two spheres"};

/* n points with unit outward normals, packed xyz; the sample positions follow a Fibonacci
 * lattice (sphere) or a golden-ratio grid (torus), jittered by the configuration's seed so that
 * configurations differ. */
static void make_cloud(enum shape shape, size_t n, uint64_t seed, float *p, float *nrm) {
    const double pi = 3.14159265358979323846, golden = pi * (3.0 - sqrt(5.0));
    uint64_t rng = seed;
    size_t i;
    for (i = 0; i < n; i++) {
        double pos[3], dir[3], t = ((double)i + 0.5) / (double)n;
        double jitter = 0.3 * (uniform(&rng) - 0.5);
        int k;
        if (shape == TORUS) {
            const double big = 1.0, small = 0.35;
            double u = 2.0 * pi * t, v = 2.0 * pi * fmod((double)i * 0.6180339887498949 + jitter / (double)n, 1.0);
            dir[0] = cos(u) * cos(v);
            dir[1] = sin(u) * cos(v);
            dir[2] = sin(v);
            pos[0] = (big + small * cos(v)) * cos(u);
            pos[1] = (big + small * cos(v)) * sin(u);
            pos[2] = small * sin(v);
        } else {
            /* TWO_SPHERES: even points on one sphere, odd on a smaller one beside it. */
            int second = shape == TWO_SPHERES && (i & 1);
            double radius = second ? 0.5 : 1.0, y, ring, phi;
            double centre = shape == TWO_SPHERES ? (second ? 1.9 : -0.2) : 0.0;
            size_t j = shape == TWO_SPHERES ? i / 2 : i, m = shape == TWO_SPHERES ? (n + 1) / 2 : n;
            y = 1.0 - 2.0 * ((double)j + 0.5) / (double)m;
            ring = sqrt(1.0 - y * y);
            phi = golden * (double)j + jitter;
            dir[0] = ring * cos(phi);
            dir[1] = y;
            dir[2] = ring * sin(phi);
            for (k = 0; k < 3; k++) pos[k] = radius * dir[k];
            pos[0] += centre;
        }
        for (k = 0; k < 3; k++) {
            p[3 * i + k] = (float)(pos[k] + 0.25 * k);
            nrm[3 * i + k] = (float)dir[k];
        }
    }
}

/* ---- configurations and their reference meshes ---------------------------------------------- */

struct mesh_copy {
    size_t nv, nt;
    float *positions, *densities, *normals; /* normals only with vertex_normals */
    uint32_t *triangles;
};

struct config {
    enum shape shape;
    size_t points;
    float *positions, *normals;
    uint32_t depth, full_depth, iterations, min_component_samples;
    int32_t kernel_depth, boundary, splatting, placement;
    float samples_per_node, scale, point_weight;
    double tolerance;
    bool vertex_normals;
    struct mesh_copy reference;
    int callbacks; /* progress calls during the reference solve */
};

/* Configuration number k: the shapes in turn, everything else drawn from rng. */
static void random_config(struct config *c, int k, uint64_t *rng) {
    c->shape = (enum shape)(k % SHAPES);
    c->points = uniform_int(rng, 300, 2500);
    c->positions = malloc(3 * c->points * sizeof(float));
    c->normals = malloc(3 * c->points * sizeof(float));
    make_cloud(c->shape, c->points, next_u64(rng), c->positions, c->normals);
    c->depth = uniform_int(rng, 3, 7);
    c->full_depth = uniform_int(rng, 0, c->depth);
    c->kernel_depth = chance(rng, 0.5) ? -1 : (int32_t)uniform_int(rng, 0, c->depth);
    c->samples_per_node = (float)(1.0 + 4.0 * uniform(rng));
    c->scale = (float)(1.05 + uniform(rng));
    c->point_weight = (float)(10.0 * uniform(rng));
    c->iterations = uniform_int(rng, 5, 100);
    c->tolerance = pow(10.0, -1.0 - 4.0 * uniform(rng));
    c->boundary = (int32_t)uniform_int(rng, 0, 2);
    c->splatting = (int32_t)uniform_int(rng, 0, 1);
    c->placement = (int32_t)uniform_int(rng, 0, 1);
    c->min_component_samples = uniform_int(rng, 0, 16);
    c->vertex_normals = chance(rng, 0.3);
}

static void print_config(int index, const struct config *c) {
    printf("config %d: %s of %zu points, depth %u, full %u, kernel %d, spn %.3f, scale %.3f, "
           "weight %.3f, iters %u, tol %.2e, boundary %d, splat %d, placement %d, min comp %u, "
           "normals %d: %zu vertices, %zu triangles, %d progress calls\n",
           index, shape_names[c->shape], c->points, c->depth, c->full_depth, c->kernel_depth,
           (double)c->samples_per_node, (double)c->scale, (double)c->point_weight, c->iterations,
           c->tolerance, c->boundary, c->splatting, c->placement, c->min_component_samples,
           (int)c->vertex_normals, c->reference.nv, c->reference.nt, c->callbacks);
}

/* ---- failures ------------------------------------------------------------------------------ */

static atomic_int failures;

#define FAIL(...)                                            \
    do {                                                     \
        atomic_fetch_add(&failures, 1);                      \
        flockfile(stdout);                                   \
        printf("FAIL %s:%d: ", __FILE__, __LINE__);          \
        printf(__VA_ARGS__);                                 \
        printf("\n");                                        \
        fflush(stdout);                                      \
        funlockfile(stdout);                                 \
    } while (0)

#define EXPECT_OK(call)                                                                     \
    do {                                                                                    \
        psr_status s_ = (call);                                                             \
        if (s_ != PSR_STATUS_OK) FAIL("%s returned %s", #call, psr_status_string((int)s_)); \
    } while (0)

/* ---- one handle's setup, solve and check ----------------------------------------------------- */

/* Sets every parameter of c on r (the same setters whatever the handle held before). */
static void apply(psr_reconstructor *r, const struct config *c, uint32_t threads) {
    EXPECT_OK(psr_reconstructor_set_depth(r, c->depth));
    EXPECT_OK(psr_reconstructor_set_full_depth(r, c->full_depth));
    EXPECT_OK(psr_reconstructor_set_kernel_depth(r, c->kernel_depth));
    EXPECT_OK(psr_reconstructor_set_samples_per_node(r, c->samples_per_node));
    EXPECT_OK(psr_reconstructor_set_scale(r, c->scale));
    EXPECT_OK(psr_reconstructor_set_point_weight(r, c->point_weight));
    EXPECT_OK(psr_reconstructor_set_max_solver_iterations(r, c->iterations));
    EXPECT_OK(psr_reconstructor_set_solver_tolerance(r, c->tolerance));
    EXPECT_OK(psr_reconstructor_set_boundary(r, c->boundary));
    EXPECT_OK(psr_reconstructor_set_splatting(r, c->splatting));
    EXPECT_OK(psr_reconstructor_set_vertex_placement(r, c->placement));
    EXPECT_OK(psr_reconstructor_set_min_component_samples(r, c->min_component_samples));
    EXPECT_OK(psr_reconstructor_set_vertex_normals(r, c->vertex_normals));
    EXPECT_OK(psr_reconstructor_set_threads(r, threads));
}

/* Replaces r's points by c's, in one batch or split in two at a random index (the same points in
 * the same order: the same point set). */
static void load(psr_reconstructor *r, const struct config *c, uint64_t *rng) {
    size_t split = chance(rng, 0.5) ? c->points : uniform_int(rng, 1, (uint32_t)c->points - 1);
    EXPECT_OK(psr_reconstructor_clear_points(r));
    EXPECT_OK(psr_reconstructor_add_points(r, c->positions, 0, c->normals, 0, split));
    if (split < c->points)
        EXPECT_OK(psr_reconstructor_add_points(r, c->positions + 3 * split, 3 * sizeof(float),
                                               c->normals + 3 * split, 0, c->points - split));
}

static void copy_mesh(const psr_mesh *m, bool with_normals, struct mesh_copy *out) {
    out->nv = psr_mesh_vertex_count(m);
    out->nt = psr_mesh_triangle_count(m);
    out->positions = malloc((3 * out->nv + 1) * sizeof(float));
    out->densities = malloc((out->nv + 1) * sizeof(float));
    out->triangles = malloc((3 * out->nt + 1) * sizeof(uint32_t));
    out->normals = with_normals ? malloc((3 * out->nv + 1) * sizeof(float)) : NULL;
    EXPECT_OK(psr_mesh_copy_positions(m, out->positions, 3 * out->nv));
    EXPECT_OK(psr_mesh_copy_densities(m, out->densities, out->nv));
    EXPECT_OK(psr_mesh_copy_triangles(m, out->triangles, 3 * out->nt));
    if (with_normals) EXPECT_OK(psr_mesh_copy_normals(m, out->normals, 3 * out->nv));
}

static void free_mesh_copy(struct mesh_copy *c) {
    free(c->positions);
    free(c->densities);
    free(c->triangles);
    free(c->normals);
}

/* Whether m is bit for bit c's reference; compared through the borrowed pointers, which must
 * stay valid as long as the mesh (even after its reconstructor is freed). */
static int equals_reference(const psr_mesh *m, const struct config *c) {
    const struct mesh_copy *ref = &c->reference;
    size_t nv = psr_mesh_vertex_count(m), nt = psr_mesh_triangle_count(m);
    if (nv != ref->nv || nt != ref->nt) return 0;
    if (memcmp(psr_mesh_positions(m), ref->positions, 3 * nv * sizeof(float)) != 0) return 0;
    if (memcmp(psr_mesh_triangles(m), ref->triangles, 3 * nt * sizeof(uint32_t)) != 0) return 0;
    if (memcmp(psr_mesh_densities(m), ref->densities, nv * sizeof(float)) != 0) return 0;
    if (c->vertex_normals && memcmp(psr_mesh_normals(m), ref->normals, 3 * nv * sizeof(float)) != 0)
        return 0;
    return 1;
}

/* What the progress callback sees and does: counts its calls, checks its thread and
 * arguments, and says stop at call number stop_at (never when stop_at is 0). */
struct progress {
    pthread_t solver;
    int calls, stop_at, stopped, bad;
};

static bool on_progress(void *user, psr_stage stage, float fraction) {
    struct progress *p = (struct progress *)user;
    if (!pthread_equal(pthread_self(), p->solver)) p->bad |= 1;
    if ((int)stage < 0 || (int)stage > (int)PSR_STAGE_NORMALS) p->bad |= 2;
    if (!(fraction >= 0.0f && fraction <= 1.0f)) p->bad |= 4;
    p->calls++;
    if (p->stop_at > 0 && p->calls >= p->stop_at) {
        p->stopped = 1;
        return false;
    }
    return true;
}

/* ---- the workers --------------------------------------------------------------------------- */

static struct config *configs;
static int config_count;
static double deadline;

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Idle handles any thread may pick up: handles move between threads through it. */
#define POOL 4
static struct {
    pthread_mutex_t lock;
    psr_reconstructor *handle[POOL];
    int loaded[POOL];
} pool = {PTHREAD_MUTEX_INITIALIZER, {NULL}, {0}};

struct counts {
    long solves, completed, cancelled, rechecked, created, freed, moved, mesh_outlived;
};

struct worker {
    int index;
    uint64_t rng;
    struct counts n;
};

/* Swaps the caller's handle with a random pool slot (either may be NULL). */
static void swap_with_pool(psr_reconstructor **r, int *loaded, uint64_t *rng) {
    int slot = (int)uniform_int(rng, 0, POOL - 1), tmp_loaded;
    psr_reconstructor *tmp;
    pthread_mutex_lock(&pool.lock);
    tmp = pool.handle[slot];
    tmp_loaded = pool.loaded[slot];
    pool.handle[slot] = *r;
    pool.loaded[slot] = *loaded;
    pthread_mutex_unlock(&pool.lock);
    *r = tmp;
    *loaded = tmp_loaded;
}

/* One solve of config `ci` on r, checked. */
static void solve_and_check(struct worker *w, psr_reconstructor **r, int ci) {
    const struct config *c = &configs[ci];
    struct progress prog;
    psr_mesh *m = NULL;
    psr_status s;
    int mode = (int)uniform_int(&w->rng, 0, 9); /* 0-3 cancel, 4-5 no callback, 6-9 count */
    size_t count = 0;

    memset(&prog, 0, sizeof prog);
    prog.solver = pthread_self();
    if (mode <= 3) prog.stop_at = (int)uniform_int(&w->rng, 1, (uint32_t)c->callbacks + 1);
    if (mode == 4 || mode == 5)
        EXPECT_OK(psr_reconstructor_set_progress_callback(*r, NULL, NULL));
    else
        EXPECT_OK(psr_reconstructor_set_progress_callback(*r, on_progress, &prog));

    s = psr_reconstructor_solve(*r, &m);
    w->n.solves++;
    if (prog.bad) FAIL("config %d: progress callback saw bad arguments (flags %d)", ci, prog.bad);
    if (s == PSR_STATUS_CANCELLED) {
        w->n.cancelled++;
        if (!prog.stopped) FAIL("config %d: cancelled but the callback never said stop", ci);
        if (m != NULL) FAIL("config %d: a cancelled solve wrote a mesh", ci);
        if (prog.calls != prog.stop_at) FAIL("config %d: %d progress calls after stop at %d", ci, prog.calls, prog.stop_at);
        if (strstr(psr_reconstructor_last_error(*r), "cancel") == NULL)
            FAIL("config %d: last error after a cancel is \"%s\"", ci, psr_reconstructor_last_error(*r));
        /* The handle stays usable: same points, same parameters, and it solves again. */
        EXPECT_OK(psr_reconstructor_point_count(*r, &count));
        if (count != c->points) FAIL("config %d: %zu points after a cancel, want %zu", ci, count, c->points);
        EXPECT_OK(psr_reconstructor_set_progress_callback(*r, NULL, NULL));
        if (chance(&w->rng, 0.5)) {
            s = psr_reconstructor_solve(*r, &m);
            w->n.solves++;
            w->n.rechecked++;
            if (s != PSR_STATUS_OK) {
                FAIL("config %d: solve after a cancel returned %s: %s", ci, psr_status_string((int)s),
                     psr_reconstructor_last_error(*r));
                return;
            }
        } else {
            return;
        }
    } else if (s != PSR_STATUS_OK) {
        FAIL("config %d: solve returned %s: %s", ci, psr_status_string((int)s), psr_reconstructor_last_error(*r));
        return;
    } else if (prog.stopped) {
        FAIL("config %d: the callback said stop but the solve returned OK", ci);
    }
    /* Completed: sometimes free the reconstructor first, the mesh outliving it. */
    w->n.completed++;
    if (chance(&w->rng, 0.1)) {
        psr_reconstructor_free(*r);
        *r = NULL;
        w->n.freed++;
        w->n.mesh_outlived++;
    }
    if (!equals_reference(m, c)) {
        FAIL("config %d on worker %d: mesh of %zu vertices, %zu triangles differs from the reference "
             "(%zu, %zu)",
             ci, w->index, psr_mesh_vertex_count(m), psr_mesh_triangle_count(m), c->reference.nv,
             c->reference.nt);
    }
    psr_mesh_free(m);
}

static void *work(void *arg) {
    struct worker *w = (struct worker *)arg;
    psr_reconstructor *r = NULL;
    int loaded = -1; /* the config whose points r holds, or -1 */

    while (now() < deadline && atomic_load(&failures) == 0) {
        uint32_t action = uniform_int(&w->rng, 0, 99);
        if (r == NULL) {
            if (psr_reconstructor_new(&r) != PSR_STATUS_OK) {
                FAIL("psr_reconstructor_new failed");
                break;
            }
            w->n.created++;
            loaded = -1;
        }
        if (action < 5) { /* free the handle between two calls, whatever it holds */
            psr_reconstructor_free(r);
            r = NULL;
            w->n.freed++;
        } else if (action < 10) { /* hand it to whichever thread takes it next */
            swap_with_pool(&r, &loaded, &w->rng);
            w->n.moved++;
        } else {
            int ci = (int)uniform_int(&w->rng, 0, (uint32_t)config_count - 1);
            /* 0 = one per core, else 1 to 4: the mesh must not depend on it. */
            uint32_t threads = uniform_int(&w->rng, 0, 4);
            if (ci != loaded || chance(&w->rng, 0.2)) {
                load(r, &configs[ci], &w->rng);
                loaded = ci;
            }
            apply(r, &configs[ci], threads);
            if (chance(&w->rng, 0.05)) { /* set up, then dropped before the solve */
                psr_reconstructor_free(r);
                r = NULL;
                w->n.freed++;
                continue;
            }
            solve_and_check(w, &r, ci);
            if (r == NULL) loaded = -1;
        }
    }
    psr_reconstructor_free(r);
    if (r != NULL) w->n.freed++;
    return NULL;
}

/* ---- main ---------------------------------------------------------------------------------- */

static void usage(void) {
    fprintf(stderr, "usage: stress [--threads N] [--seconds S] [--seed X] [--configs K]\n");
    exit(2);
}

int main(int argc, char **argv) {
    int threads = 4, k, i;
    double seconds = 10.0, started, reference_seconds;
    unsigned long long seed = 1;
    uint64_t rng;
    struct worker *workers;
    pthread_t *ids;
    struct counts total;

    config_count = 8;
    for (i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (i + 1 >= argc) usage();
        if (strcmp(a, "--threads") == 0)
            threads = atoi(argv[++i]);
        else if (strcmp(a, "--seconds") == 0)
            seconds = atof(argv[++i]);
        else if (strcmp(a, "--seed") == 0)
            seed = strtoull(argv[++i], NULL, 10);
        else if (strcmp(a, "--configs") == 0)
            config_count = atoi(argv[++i]);
        else
            usage();
    }
    if (threads < 1 || threads > 1024 || config_count < 1 || config_count > 1000 || !(seconds >= 0.0))
        usage();
    printf("stress: psr %s, %d threads, %.0f s, seed %llu, %d configurations\n", psr_version(), threads,
           seconds, seed, config_count);

    /* The references: each configuration solved once, alone, on one worker thread. */
    started = now();
    rng = (uint64_t)seed;
    configs = calloc((size_t)config_count, sizeof *configs);
    for (k = 0; k < config_count; k++) {
        struct config *c = &configs[k];
        psr_reconstructor *r = NULL;
        psr_mesh *m = NULL;
        struct progress prog;
        psr_status s;
        random_config(c, k, &rng);
        memset(&prog, 0, sizeof prog);
        prog.solver = pthread_self();
        EXPECT_OK(psr_reconstructor_new(&r));
        EXPECT_OK(psr_reconstructor_add_points(r, c->positions, 0, c->normals, 0, c->points));
        apply(r, c, 1);
        EXPECT_OK(psr_reconstructor_set_progress_callback(r, on_progress, &prog));
        s = psr_reconstructor_solve(r, &m);
        if (s != PSR_STATUS_OK) {
            FAIL("reference %d: %s: %s", k, psr_status_string((int)s), psr_reconstructor_last_error(r));
            return 1;
        }
        c->callbacks = prog.calls;
        copy_mesh(m, c->vertex_normals, &c->reference);
        if (c->reference.nt == 0) FAIL("reference %d: empty mesh", k);
        print_config(k, c);
        psr_mesh_free(m);
        psr_reconstructor_free(r);
    }
    reference_seconds = now() - started;
    printf("references: %.1f s\n", reference_seconds);
    fflush(stdout);

    started = now();
    deadline = started + seconds;
    workers = calloc((size_t)threads, sizeof *workers);
    ids = calloc((size_t)threads, sizeof *ids);
    for (k = 0; k < threads; k++) {
        workers[k].index = k;
        workers[k].rng = (uint64_t)seed * 7919u + (uint64_t)k + 1u;
        if (pthread_create(&ids[k], NULL, work, &workers[k]) != 0) {
            fprintf(stderr, "stress: pthread_create failed\n");
            return 1;
        }
    }
    memset(&total, 0, sizeof total);
    for (k = 0; k < threads; k++) {
        pthread_join(ids[k], NULL);
        total.solves += workers[k].n.solves;
        total.completed += workers[k].n.completed;
        total.cancelled += workers[k].n.cancelled;
        total.rechecked += workers[k].n.rechecked;
        total.created += workers[k].n.created;
        total.freed += workers[k].n.freed;
        total.moved += workers[k].n.moved;
        total.mesh_outlived += workers[k].n.mesh_outlived;
    }
    /* Handles left in the pool are freed too. */
    for (k = 0; k < POOL; k++) {
        if (pool.handle[k] != NULL) total.freed++;
        psr_reconstructor_free(pool.handle[k]);
    }

    printf("stress: %d threads x %.1f s (seed %llu): %ld solves, %ld completed and equal to their "
           "reference, %ld cancelled (%ld solved again at once), %ld handles created, %ld freed "
           "(%ld before their mesh), %ld moved between threads, %d failures\n",
           threads, now() - started, seed, total.solves, total.completed, total.cancelled,
           total.rechecked, total.created, total.freed, total.mesh_outlived, total.moved,
           atomic_load(&failures));
    if (total.created != total.freed) FAIL("%ld handles created but %ld freed", total.created, total.freed);

    for (k = 0; k < config_count; k++) {
        free_mesh_copy(&configs[k].reference);
        free(configs[k].positions);
        free(configs[k].normals);
    }
    free(configs);
    free(workers);
    free(ids);
    return atomic_load(&failures) == 0 ? 0 : 1;
}

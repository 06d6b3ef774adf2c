/*
 * Robustness of the C API:
 *  1. aborting at every progress-callback position: stop at the 1st call,
 *     the 2nd, ... until a run completes; each aborted run returns
 *     PMC_STATUS_ABORTED, stores NULL, calls the callback exactly up to the
 *     stop, and leaks nothing (checked by the ASan and valgrind passes);
 *  2. pmc_extract from several threads at once on one shared read-only
 *     volume and one shared options handle: every result is identical to
 *     the one computed alone;
 *  3. options and meshes freed in any order, meshes valid after their
 *     options are freed.
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>

#include "common.h"

/* ---- 1. abort at every position ------------------------------------------- */

static void abort_everywhere(const pmc_volume *v, double iso, pmc_options *o, long max_runs,
                             const char *what) {
    progress_counter c;
    long stop;
    int completed = 0;
    pmc_mesh *reference = NULL;
    CHECK_STATUS(pmc_options_set_progress(o, NULL, NULL), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(v, iso, o, &reference), PMC_STATUS_OK);
    for (stop = 1; stop <= max_runs && !completed; stop++) {
        pmc_mesh *m = (pmc_mesh *)&c; /* must be overwritten with NULL */
        pmc_status st;
        memset(&c, 0, sizeof c);
        c.stop_at = stop;
        c.monotone = 1;
        CHECK_STATUS(pmc_options_set_progress(o, count_progress, &c), PMC_STATUS_OK);
        st = pmc_extract(v, iso, o, &m);
        if (st == PMC_STATUS_OK) {
            /* The run finished before the stop position: every call
             * continued, the last one was 1.0, the mesh is the same. */
            completed = 1;
            CHECK(c.calls < stop);
            CHECK(c.last == 1.0);
            CHECK(m != NULL && meshes_equal(m, reference));
            pmc_mesh_free(m);
        } else {
            CHECK_STATUS(st, PMC_STATUS_ABORTED);
            CHECK(m == NULL);
            CHECK(c.calls == stop); /* never called after asking to stop */
        }
        CHECK(c.monotone);
    }
    CHECK(completed);
    printf("%s: aborted at positions 1..%ld, completed at %ld calls\n", what, stop - 2,
           c.calls);
    CHECK_STATUS(pmc_options_set_progress(o, NULL, NULL), PMC_STATUS_OK);
    pmc_mesh_free(reference);
}

/* ---- 2. concurrent extractions ---------------------------------------------- */

typedef struct {
    const pmc_volume *volume;
    const pmc_options *options;
    double iso;
    pmc_mesh *mesh;
    pmc_status status;
} job;

static void *run_job(void *arg) {
    job *j = (job *)arg;
    j->status = pmc_extract(j->volume, j->iso, j->options, &j->mesh);
    return NULL;
}

static void concurrent(const pmc_volume *v, double iso, const pmc_options *o, int nthreads,
                       int rounds) {
    pmc_mesh *reference = NULL;
    job jobs[8];
    pthread_t tid[8];
    int r, i;
    CHECK_STATUS(pmc_extract(v, iso, o, &reference), PMC_STATUS_OK);
    CHECK(pmc_mesh_triangle_count(reference) > 0);
    for (r = 0; r < rounds; r++) {
        for (i = 0; i < nthreads; i++) {
            jobs[i].volume = v;
            jobs[i].options = o;
            jobs[i].iso = iso;
            jobs[i].mesh = NULL;
            jobs[i].status = PMC_STATUS_INTERNAL_ERROR;
            CHECK(pthread_create(&tid[i], NULL, run_job, &jobs[i]) == 0);
        }
        for (i = 0; i < nthreads; i++) {
            CHECK(pthread_join(tid[i], NULL) == 0);
            CHECK_STATUS(jobs[i].status, PMC_STATUS_OK);
            CHECK(jobs[i].mesh != NULL && meshes_equal(jobs[i].mesh, reference));
            CHECK(check_mesh(jobs[i].mesh, v, 5));
        }
        /* Free in a different order each round. */
        for (i = 0; i < nthreads; i++) pmc_mesh_free(jobs[(i + r) % nthreads].mesh);
    }
    pmc_mesh_free(reference);
}

/* ---- 3. free order -------------------------------------------------------------- */

static void free_orders(const pmc_volume *v, double iso) {
    int order;
    for (order = 0; order < 6; order++) {
        pmc_options *o = pmc_options_new();
        pmc_mesh *a = NULL, *b = NULL;
        uint64_t na, nb;
        CHECK(o != NULL);
        CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_GRADIENT), PMC_STATUS_OK);
        CHECK_STATUS(pmc_extract(v, iso, o, &a), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_topology(o, PMC_TOPOLOGY_CLASSIC), PMC_STATUS_OK);
        CHECK_STATUS(pmc_extract(v, iso, o, &b), PMC_STATUS_OK);
        na = pmc_mesh_point_count(a);
        nb = pmc_mesh_point_count(b);
        switch (order) {
        case 0: pmc_options_free(o); pmc_mesh_free(a); pmc_mesh_free(b); o = NULL; a = b = NULL; break;
        case 1: pmc_options_free(o); pmc_mesh_free(b); pmc_mesh_free(a); o = NULL; a = b = NULL; break;
        case 2: pmc_mesh_free(a); pmc_options_free(o); o = NULL; a = NULL; break;
        case 3: pmc_mesh_free(b); pmc_options_free(o); o = NULL; b = NULL; break;
        case 4: pmc_mesh_free(a); pmc_mesh_free(b); a = b = NULL; break;
        default: pmc_options_free(o); o = NULL; break;
        }
        /* What is left stays readable after its options are gone. */
        if (a) {
            CHECK(pmc_mesh_point_count(a) == na && check_mesh(a, v, 5));
            CHECK(pmc_mesh_normals(a) != NULL);
        }
        if (b) CHECK(pmc_mesh_point_count(b) == nb && check_mesh(b, v, 5));
        pmc_mesh_free(b);
        pmc_options_free(o);
        pmc_mesh_free(a);
        /* NULL everywhere is accepted. */
        pmc_mesh_free(NULL);
        pmc_options_free(NULL);
    }
}

int main(void) {
    /* Under valgrind (PMC_TEST_ITERATIONS set by run.sh) everything is ~50x
     * slower: a smaller volume keeps the number of positions similar. */
    int slow = getenv("PMC_TEST_ITERATIONS") != NULL;
    uint64_t n = slow ? 24 : 64;
    pmc_volume big = make_sphere(n, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_volume small = make_sphere(12, PMC_SCALAR_TYPE_I16, 10.0);
    pmc_options *o = pmc_options_new();
    double iso = 0.4 * (double)n;

    /* 1. Refinement with a triangle cap: the run goes through the output,
     * count and final passes, each of which can be interrupted. */
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0005), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 6), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, slow ? 20000 : 150000), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 2), PMC_STATUS_OK);
    abort_everywhere(&big, iso, o, 400, "capped refinement");
    /* Plain Marching Cubes with normals, one thread. */
    CHECK_STATUS(pmc_options_set_max_triangles(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_CENTRAL_DIFFERENCE), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 1), PMC_STATUS_OK);
    abort_everywhere(&big, iso, o, 400, "marching cubes");
    /* A small volume: 0.0, 0.97 and 1.0 only. */
    abort_everywhere(&small, 40.0, o, 10, "small volume");

    /* 2. Four threads sharing the volume and the options (each extraction
     * with 2 worker threads), three rounds. */
    CHECK_STATUS(pmc_options_set_max_level(o, 5), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.005), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_GRADIENT), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 2), PMC_STATUS_OK);
    concurrent(&big, iso, o, 4, slow ? 1 : 3);
    /* And with the default options (NULL). */
    concurrent(&small, 40.0, NULL, 4, 2);

    /* 3. Free order. */
    free_orders(&small, 40.0);

    pmc_options_free(o);
    free((void *)big.data);
    free((void *)small.data);
    return test_finish("test_robust");
}

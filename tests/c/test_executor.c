/*
 * A host's thread pool lent through pmc_options_set_executor: a pthread
 * executor that runs a batch's tasks on several threads in a scrambled
 * order gives meshes bit-identical to the library's own threads; an
 * executor that drops a task makes pmc_extract fail cleanly; progress and
 * stopping still work; invalid concurrencies are refused.
 */
#include <pthread.h>

#include "common.h"

typedef struct {
    int threads;        /* worker threads of a batch (the caller is one) */
    int drop_index;     /* a task index never run (-1: none) */
    int twice;          /* also call every task a second time, and out of range */
    long batches;       /* batches run so far */
    long calls;         /* task calls so far */
    pthread_t caller;   /* the thread that called pmc_extract */
    int foreign_caller; /* set if the executor was called on another thread */
} pool;

typedef struct {
    pool *p;
    uint64_t count;
    uint64_t *order;
    uint64_t next;
    pthread_mutex_t lock;
    pmc_task_fn task;
    void *task_data;
} batch;

static void *work(void *arg) {
    batch *b = (batch *)arg;
    for (;;) {
        pthread_mutex_lock(&b->lock);
        uint64_t k = b->next++;
        if (k < b->count) b->p->calls++;
        pthread_mutex_unlock(&b->lock);
        if (k >= b->count) return NULL;
        if ((int)b->order[k] == b->p->drop_index) continue;
        b->task(b->task_data, b->order[k]);
    }
}

static void run_batch(void *data, uint64_t count, pmc_task_fn task, void *task_data) {
    pool *p = (pool *)data;
    if (!pthread_equal(pthread_self(), p->caller)) p->foreign_caller = 1;
    p->batches++;
    batch b;
    b.p = p;
    b.count = count;
    b.order = (uint64_t *)malloc((count ? count : 1) * sizeof *b.order);
    b.next = 0;
    b.task = task;
    b.task_data = task_data;
    pthread_mutex_init(&b.lock, NULL);
    for (uint64_t i = 0; i < count; i++) b.order[i] = i;
    for (uint64_t i = count; i > 1; i--) { /* Fisher-Yates */
        uint64_t j = rng_below(i), t = b.order[i - 1];
        b.order[i - 1] = b.order[j];
        b.order[j] = t;
    }
    pthread_t th[8];
    int n = p->threads < 8 ? p->threads : 8;
    for (int i = 0; i < n; i++) pthread_create(&th[i], NULL, work, &b);
    work(&b); /* the calling thread takes part, as TBB's does */
    for (int i = 0; i < n; i++) pthread_join(th[i], NULL);
    if (p->twice) {
        for (uint64_t i = 0; i < count; i++) task(task_data, i);
        task(task_data, count);
        task(task_data, UINT64_MAX);
    }
    pthread_mutex_destroy(&b.lock);
    free(b.order);
}

static void init_pool(pool *p, int threads) {
    memset(p, 0, sizeof *p);
    p->threads = threads;
    p->drop_index = -1;
    p->caller = pthread_self();
}

static pmc_mesh *extract(const pmc_volume *v, double iso, double eps, pmc_topology topo,
                         pmc_normals normals, uint32_t threads, pool *p) {
    pmc_options *o = pmc_options_new();
    CHECK_STATUS(pmc_options_set_epsilon(o, eps), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_topology(o, topo), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, normals), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, threads), PMC_STATUS_OK);
    if (p) {
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, p, (uint32_t)(p->threads + 1)),
                     PMC_STATUS_OK);
    }
    pmc_mesh *m = NULL;
    CHECK_STATUS(pmc_extract(v, iso, o, &m), PMC_STATUS_OK);
    pmc_options_free(o);
    return m;
}

int main(void) {
    /* Same meshes as the library's own threads, on several volumes,
     * settings and pool sizes. */
    const pmc_scalar_type types[3] = {PMC_SCALAR_TYPE_F32, PMC_SCALAR_TYPE_U8,
                                      PMC_SCALAR_TYPE_I16};
    for (int t = 0; t < 3; t++) {
        /* Samples: the distance to the centre (times 4 or 100 for the
         * integer types, rounded); spheres of radius 25.3, 12.6 and 12.
         * Each grid has over 131 072 cells, so plain Marching Cubes cuts
         * it into slabs (of at least 65 536 cells) on a pool of two or
         * more. */
        pmc_volume v = make_sphere(t == 0 ? 70 : 52, types[t], t == 0 ? 1.0 : (t == 1 ? 4.0 : 100.0));
        double iso = t == 0 ? 25.3 : (t == 1 ? 50.5 : 1200.5);
        for (int setting = 0; setting < 3; setting++) {
            double eps = setting == 2 ? 0.001 : 0.0;
            pmc_topology topo = setting == 1 ? PMC_TOPOLOGY_CLASSIC : PMC_TOPOLOGY_TRILINEAR;
            pmc_normals normals = setting == 2 ? PMC_NORMALS_GRADIENT : PMC_NORMALS_NONE;
            pmc_mesh *own = extract(&v, iso, eps, topo, normals, 1, NULL);
            for (int threads = 0; threads < 4; threads++) {
                pool p;
                init_pool(&p, threads);
                pmc_mesh *lent = extract(&v, iso, eps, topo, normals, 1, &p);
                CHECK(own && lent && meshes_equal(own, lent));
                CHECK(lent && pmc_mesh_triangle_count(lent) > 0);
                CHECK(lent && check_mesh(lent, &v, 5));
                /* Concurrency 1 without refinement runs on the calling thread. */
                CHECK((p.batches > 0 || (threads == 0 && eps == 0.0)) && !p.foreign_caller);
                if (own && lent && normals == PMC_NORMALS_GRADIENT) {
                    size_t n = 3 * (size_t)pmc_mesh_point_count(own);
                    CHECK(memcmp(pmc_mesh_normals(own), pmc_mesh_normals(lent),
                                 n * sizeof(float)) == 0);
                }
                pmc_mesh_free(lent);
            }
            /* Tasks called twice and out of range change nothing. */
            pool p;
            init_pool(&p, 2);
            p.twice = 1;
            pmc_mesh *lent = extract(&v, iso, eps, topo, normals, 1, &p);
            CHECK(own && lent && meshes_equal(own, lent));
            pmc_mesh_free(lent);
            pmc_mesh_free(own);
        }
        free((void *)v.data);
    }

    /* Over 131 072 cells: two slabs without refinement. */
    pmc_volume v = make_sphere(52, PMC_SCALAR_TYPE_F32, 1.0);

    /* A dropped task: an error with a message, no mesh, no crash. */
    for (int drop = 0; drop < 3; drop++) {
        pool p;
        init_pool(&p, 1);
        p.drop_index = drop;
        pmc_options *o = pmc_options_new();
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, &p, 2), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_epsilon(o, drop == 0 ? 0.0 : 0.001), PMC_STATUS_OK);
        pmc_mesh *m = (pmc_mesh *)&p; /* must be overwritten with NULL */
        CHECK_STATUS(pmc_extract(&v, 17.3, o, &m), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(m == NULL);
        char msg[256];
        pmc_last_error_message(msg, sizeof msg);
        CHECK(strstr(msg, "executor") != NULL);
        pmc_options_free(o);
    }

    /* Progress: reported (the calling thread runs tasks), never
     * decreasing, ending at 1; a stop request aborts with no mesh. */
    for (long stop = 0; stop < 3; stop++) {
        pool p;
        init_pool(&p, 1);
        progress_counter log = {0, stop, 0.0, 1};
        pmc_options *o = pmc_options_new();
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, &p, 2), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_epsilon(o, 0.0005), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_progress(o, count_progress, &log), PMC_STATUS_OK);
        pmc_mesh *m = NULL;
        pmc_status s = pmc_extract(&v, 17.3, o, &m);
        if (stop == 0) {
            CHECK(s == PMC_STATUS_OK && m != NULL);
            CHECK(log.calls >= 3 && log.monotone && log.last == 1.0);
        } else {
            CHECK(s == PMC_STATUS_ABORTED && m == NULL);
            CHECK(log.calls == stop);
        }
        pmc_mesh_free(m);
        pmc_options_free(o);
    }

    /* Concurrency must be 1..PMC_MAX_THREADS; NULL clears the executor. */
    {
        pool p;
        init_pool(&p, 1);
        pmc_options *o = pmc_options_new();
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, &p, 0), PMC_STATUS_INVALID_ARGUMENT);
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, &p, PMC_MAX_THREADS + 1),
                     PMC_STATUS_INVALID_ARGUMENT);
        CHECK_STATUS(pmc_options_set_executor(NULL, run_batch, &p, 2), PMC_STATUS_NULL_ARGUMENT);
        CHECK_STATUS(pmc_options_set_executor(o, run_batch, &p, PMC_MAX_THREADS), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_executor(o, NULL, &p, 0), PMC_STATUS_OK);
        pmc_mesh *m = NULL;
        CHECK_STATUS(pmc_extract(&v, 17.3, o, &m), PMC_STATUS_OK);
        CHECK(p.batches == 0); /* cleared: not called */
        pmc_mesh_free(m);
        pmc_options_free(o);
    }
    free((void *)v.data);
    return test_finish("test_executor");
}

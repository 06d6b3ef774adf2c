/*
 * The progress callback: called on the calling thread, first with 0.0,
 * never decreasing, last with 1.0 on success; a non-zero return aborts
 * with PMC_STATUS_ABORTED and no mesh.
 */
#include "common.h"

typedef struct {
    long calls;
    double first, last;
    int monotone, in_range;
    long stop_after; /* return non-zero on this call (1-based); 0 = never */
} progress_log;

static int on_progress(void *user_data, double fraction) {
    progress_log *log = (progress_log *)user_data;
    if (log->calls == 0) log->first = fraction;
    else if (fraction < log->last) log->monotone = 0;
    if (!(fraction >= 0.0 && fraction <= 1.0)) log->in_range = 0;
    log->last = fraction;
    log->calls++;
    return log->stop_after != 0 && log->calls >= log->stop_after;
}

static void reset(progress_log *log, long stop_after) {
    memset(log, 0, sizeof *log);
    log->monotone = 1;
    log->in_range = 1;
    log->first = -1.0;
    log->stop_after = stop_after;
}

static int g_other_calls = 0;
static int other_progress(void *user_data, double fraction) {
    (void)user_data;
    (void)fraction;
    g_other_calls++;
    return 0;
}

int main(void) {
    pmc_volume small = make_sphere(16, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_volume big = make_sphere(96, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_options *o = pmc_options_new();
    progress_log log;
    pmc_mesh *m = NULL, *plain = NULL;
    long stop;

    /* A full run: first 0.0, monotone, last 1.0. */
    reset(&log, 0);
    CHECK_STATUS(pmc_options_set_progress(o, on_progress, &log), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&small, 5.0, o, &m), PMC_STATUS_OK);
    CHECK(m != NULL);
    CHECK(log.calls >= 2);
    CHECK(log.first == 0.0);
    CHECK(log.last == 1.0);
    CHECK(log.monotone && log.in_range);
    /* The callback does not change the result. */
    CHECK_STATUS(pmc_extract(&small, 5.0, NULL, &plain), PMC_STATUS_OK);
    CHECK(meshes_equal(m, plain));
    pmc_mesh_free(m);
    pmc_mesh_free(plain);

    /* A longer run, several threads: still monotone, with a triangle cap
     * that forces the extra passes. */
    reset(&log, 0);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.001), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, 60000), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 2), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&big, 40.0, o, &m), PMC_STATUS_OK);
    CHECK(log.first == 0.0 && log.last == 1.0 && log.monotone && log.in_range);
    {
        pmc_stats s = {.struct_size = sizeof(pmc_stats)};
        CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
        CHECK(s.budget_reached == 1);
    }
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_max_triangles(o, 0), PMC_STATUS_OK);

    /* Abort on the first call, and at later calls (a successful run makes at
     * least 3: 0.0, 0.97 and 1.0): ABORTED, *out NULL. */
    for (stop = 1; stop <= 3; stop++) {
        reset(&log, stop);
        m = (pmc_mesh *)&log;
        CHECK_STATUS(pmc_extract(stop == 1 ? &small : &big, 40.0, o, &m), PMC_STATUS_ABORTED);
        CHECK(m == NULL);
        CHECK(log.calls == stop); /* not called again after asking to stop */
        CHECK(log.first == 0.0 && log.monotone);
        {
            char msg[128];
            pmc_last_error_message(msg, sizeof msg);
            CHECK(strstr(msg, "aborted") != NULL);
        }
    }

    /* Clearing the callback: no more calls, the options work again. */
    reset(&log, 1);
    CHECK_STATUS(pmc_options_set_progress(o, NULL, &log), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&small, 5.0, o, &m), PMC_STATUS_OK);
    CHECK(log.calls == 0);
    pmc_mesh_free(m);

    /* Replacing the callback and user data. */
    CHECK_STATUS(pmc_options_set_progress(o, other_progress, NULL), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&small, 5.0, o, &m), PMC_STATUS_OK);
    CHECK(g_other_calls >= 2);
    pmc_mesh_free(m);

    /* Invalid input fails before the callback is ever called. */
    reset(&log, 0);
    CHECK_STATUS(pmc_options_set_progress(o, on_progress, &log), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&small, NAN, o, &m), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(log.calls == 0 && m == NULL);

    pmc_options_free(o);
    free((void *)small.data);
    free((void *)big.data);
    return test_finish("test_progress");
}

/*
 * Many seeded random calls: random types, dimensions, strides (padded,
 * permuted, sometimes negative), buffer lengths (exact or too short),
 * values (with NaN), isovalues and options. Each buffer is allocated with
 * exactly `len` elements so that the sanitizers and valgrind catch any
 * read beyond it. The status must be exactly the predicted one and every
 * mesh must satisfy the invariants.
 */
#include "common.h"

static double random_value(pmc_scalar_type t, int narrow) {
    /* A small range makes surfaces likely; the full range tests conversion. */
    static const double lo[10] = {-128, 0, -32768, 0, -2147483648.0, 0, -9.2e18, 0, -1e30, -1e300};
    static const double hi[10] = {127, 255, 32767, 65535, 2147483647.0, 4294967295.0, 9.2e18,
                                  1.8e19, 1e30, 1e300};
    if (narrow) return (double)rng_below(21);
    return lo[t] + rng_unit() * (hi[t] - lo[t]);
}

int main(void) {
    long iters = test_iterations(400), it;
    long ok_runs = 0, failed_runs = 0;
    const char *seed = getenv("PMC_TEST_SEED");
    g_rng ^= seed ? (uint64_t)strtoull(seed, NULL, 10) * 0x9E3779B97F4A7C15ull : 0;
    for (it = 0; it < iters; it++) {
        pmc_volume v;
        pmc_options *o = pmc_options_new();
        pmc_mesh *m = (pmc_mesh *)&v;
        pmc_status want = PMC_STATUS_OK, got;
        pmc_scalar_type t = (pmc_scalar_type)rng_below(10);
        int a, narrow = rng_below(4) != 0, contiguous = rng_below(5) == 0;
        int perm[3] = {0, 1, 2};
        uint64_t required = 1, len, i, elem;
        double iso;
        uint32_t max_level = (uint32_t)rng_below(4);
        void *buf;

        memset(&v, 0, sizeof v);
        v.struct_size = sizeof v;
        v.scalar_type = t;
        for (a = 0; a < 3; a++) {
            v.dims[a] = 2 + rng_below(9);
            if (rng_below(40) == 0) {
                v.dims[a] = rng_below(2); /* 0 or 1 */
                want = PMC_STATUS_INVALID_ARGUMENT;
            }
            v.origin[a] = (rng_unit() - 0.5) * 100.0;
            v.spacing[a] = 0.1 + rng_unit() * 3.0;
        }
        if (rng_below(40) == 0) {
            v.spacing[rng_below(3)] = rng_below(2) ? 0.0 : -1.0;
            want = PMC_STATUS_INVALID_ARGUMENT;
        }
        /* Strides: a random axis order with padding, or all zero. */
        for (a = 2; a > 0; a--) {
            int b = (int)rng_below((uint64_t)a + 1), tmp = perm[a];
            perm[a] = perm[b];
            perm[b] = tmp;
        }
        if (contiguous) {
            required = v.dims[0] * v.dims[1] * v.dims[2];
        } else {
            int64_t s = 1;
            for (a = 0; a < 3; a++) {
                int ax = perm[a];
                v.strides[ax] = s;
                s *= (int64_t)(v.dims[ax] + rng_below(3));
            }
            for (a = 0; a < 3; a++) required += (v.dims[a] ? v.dims[a] - 1 : 0) * (uint64_t)v.strides[a];
            if (rng_below(20) == 0) {
                v.strides[rng_below(3)] *= -1;
                if (want == PMC_STATUS_OK) want = PMC_STATUS_INVALID_ARGUMENT;
            }
        }
        len = required;
        if (rng_below(10) == 0) {
            len = required - 1 - rng_below(required);
            if (want == PMC_STATUS_OK) want = PMC_STATUS_INVALID_ARGUMENT;
        }
        elem = scalar_size(t);
        buf = malloc((size_t)(len ? len * elem : 1));
        for (i = 0; i < len; i++) {
            double x = random_value(t, narrow);
            if ((t == PMC_SCALAR_TYPE_F32 || t == PMC_SCALAR_TYPE_F64) && rng_below(50) == 0) x = NAN;
            store(buf, t, (size_t)i, x);
        }
        v.data = buf;
        v.len = len;
        if (rng_below(50) == 0) {
            v.scalar_type = 10 + (uint32_t)rng_below(0xFFFFFFF0u);
            want = PMC_STATUS_INVALID_ARGUMENT;
        }
        iso = narrow ? 0.5 + (double)rng_below(20) : random_value(t, 0) * 0.5;
        if (rng_below(50) == 0) {
            iso = NAN;
            want = PMC_STATUS_INVALID_ARGUMENT;
        }

        /* Options, all valid. */
        CHECK_STATUS(pmc_options_set_epsilon(o, rng_below(4) == 0 ? 0.0 : 0.001 + rng_unit() * 0.1),
                     PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_max_level(o, max_level), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_rule(o, (pmc_rule)rng_below(4)), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_topology(o, (pmc_topology)rng_below(2)), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_normals(o, (pmc_normals)rng_below(3)), PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_max_triangles(o, rng_below(3) == 0 ? rng_below(200) : 0),
                     PMC_STATUS_OK);
        CHECK_STATUS(pmc_options_set_threads(o, (uint32_t)rng_below(4)), PMC_STATUS_OK);
        {
            int64_t off[3];
            for (a = 0; a < 3; a++) off[a] = (int64_t)rng_below(2001) - 1000;
            CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        }
        /* And some invalid values, which must not change anything. */
        CHECK_STATUS(pmc_options_set_rule(o, 4 + (uint32_t)rng_below(1000)), PMC_STATUS_INVALID_ARGUMENT);
        CHECK_STATUS(pmc_options_set_epsilon(o, -rng_unit() - 1e-9), PMC_STATUS_INVALID_ARGUMENT);

        got = pmc_extract(&v, iso, rng_below(10) == 0 ? NULL : o, &m);
        if (got != want) {
            char msg[256];
            pmc_last_error_message(msg, sizeof msg);
            fprintf(stderr, "iteration %ld: status %u, expected %u (%s)\n", it, (unsigned)got,
                    (unsigned)want, msg);
            CHECK(0);
        } else {
            CHECK(1);
        }
        if (got == PMC_STATUS_OK) {
            CHECK(m != NULL);
            CHECK(check_mesh(m, &v, 5));
            ok_runs++;
        } else {
            CHECK(m == NULL);
            failed_runs++;
        }
        pmc_mesh_free(m);
        pmc_options_free(o);
        free(buf);
    }
    printf("test_random: %ld iterations, %ld extracted, %ld rejected\n", iters, ok_runs, failed_runs);
    CHECK(ok_runs > 0 && failed_runs > 0);
    return test_finish("test_random");
}

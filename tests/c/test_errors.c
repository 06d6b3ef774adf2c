/*
 * Every error path of the C API: NULL arguments, invalid volumes, invalid
 * option values (unknown enumeration integers included), status strings,
 * the last error message and its truncation, NULL-tolerant accessors.
 */
#include "common.h"

static char g_msg[1024];

/* The last error message (into g_msg). */
static const char *last_error(void) {
    pmc_last_error_message(g_msg, sizeof g_msg);
    return g_msg;
}

/* Extraction must fail with `want`, leave *out NULL and set a message. */
static void expect_fail(const pmc_volume *v, double iso, const pmc_options *o, pmc_status want,
                        const char *needle, int line) {
    pmc_mesh *m = (pmc_mesh *)&g_msg; /* garbage that must be overwritten */
    pmc_status st = pmc_extract(v, iso, o, &m);
    if (st != want || m != NULL || strstr(last_error(), needle) == NULL) {
        fprintf(stderr, "line %d: status %u (want %u), mesh %p, message '%s' (want '%s')\n", line,
                (unsigned)st, (unsigned)want, (void *)m, g_msg, needle);
        g_checks_failed++;
    } else {
        g_checks_passed++;
    }
    if (st == PMC_STATUS_OK) pmc_mesh_free(m);
}
#define EXPECT_FAIL(v, iso, o, want, needle) expect_fail(v, iso, o, want, needle, __LINE__)

static void test_status_strings(void) {
    pmc_status s;
    CHECK(strcmp(pmc_status_string(PMC_STATUS_OK), "ok") == 0);
    CHECK(strcmp(pmc_status_string(PMC_STATUS_NULL_ARGUMENT), "null argument") == 0);
    CHECK(strcmp(pmc_status_string(PMC_STATUS_INVALID_ARGUMENT), "invalid argument") == 0);
    CHECK(strcmp(pmc_status_string(PMC_STATUS_ABORTED), "aborted by the progress callback") == 0);
    CHECK(strcmp(pmc_status_string(PMC_STATUS_OUT_OF_MEMORY), "out of memory") == 0);
    CHECK(strcmp(pmc_status_string(PMC_STATUS_INTERNAL_ERROR), "internal error") == 0);
    CHECK(strcmp(pmc_status_string(6), "unknown status") == 0);
    CHECK(strcmp(pmc_status_string(7), "unknown status") == 0);
    CHECK(strcmp(pmc_status_string(0xFFFFFFFFu), "unknown status") == 0);
    for (s = 0; s < 6; s++) CHECK(pmc_status_string(s) == pmc_status_string(s)); /* static */
    CHECK(strcmp(pmc_version_string(), PMC_VERSION_STRING) == 0);
    {
        char buf[64];
        sprintf(buf, "%d.%d.%d", PMC_VERSION_MAJOR, PMC_VERSION_MINOR, PMC_VERSION_PATCH);
        CHECK(strncmp(buf, PMC_VERSION_STRING, strlen(buf)) == 0);
    }
}

static void test_options_setters(void) {
    pmc_options *o = pmc_options_new();
    int64_t off[3] = {-5, 7, 1000000};
    static const uint32_t bad_enums[] = {4, 7, 100, 0x80000000u, 0xFFFFFFFFu};
    size_t i;
    CHECK(o != NULL);

    /* Valid values. */
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, 1e-9), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.5), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, 1e300), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, -0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, PMC_MAX_LEVEL_LIMIT), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_A), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_A1), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_A2), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_B), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_topology(o, PMC_TOPOLOGY_TRILINEAR), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_topology(o, PMC_TOPOLOGY_CLASSIC), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_NONE), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_GRADIENT), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_CENTRAL_DIFFERENCE), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, 1), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, UINT64_MAX), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, 1), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_threads(o, PMC_MAX_THREADS), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_progress(o, NULL, NULL), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_progress(o, NULL, o), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);

    /* Invalid values. */
    CHECK_STATUS(pmc_options_set_epsilon(o, -1e-12), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strstr(last_error(), "epsilon") != NULL);
    CHECK_STATUS(pmc_options_set_epsilon(o, -1.0), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_epsilon(o, NAN), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_epsilon(o, INFINITY), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_epsilon(o, -INFINITY), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_max_level(o, PMC_MAX_LEVEL_LIMIT + 1), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strstr(last_error(), "max level") != NULL);
    CHECK_STATUS(pmc_options_set_max_level(o, 0xFFFFFFFFu), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_threads(o, PMC_MAX_THREADS + 1), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_threads(o, 0xFFFFFFFFu), PMC_STATUS_INVALID_ARGUMENT);
    for (i = 0; i < sizeof bad_enums / sizeof bad_enums[0]; i++) {
        uint32_t b = bad_enums[i];
        CHECK_STATUS(pmc_options_set_rule(o, (pmc_rule)b), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(strstr(last_error(), "rule") != NULL);
        if (b >= 2) {
            CHECK_STATUS(pmc_options_set_topology(o, (pmc_topology)b), PMC_STATUS_INVALID_ARGUMENT);
            CHECK(strstr(last_error(), "topology") != NULL);
        }
        if (b >= 3) {
            CHECK_STATUS(pmc_options_set_normals(o, (pmc_normals)b), PMC_STATUS_INVALID_ARGUMENT);
            CHECK(strstr(last_error(), "normals") != NULL);
        }
    }
    CHECK_STATUS(pmc_options_set_topology(o, 2), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_normals(o, 3), PMC_STATUS_INVALID_ARGUMENT);
    /* The gradients flag is 0 or 1, nothing else. */
    CHECK_STATUS(pmc_options_set_gradients(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_gradients(o, 1), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_gradients(o, 2), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strstr(last_error(), "gradients must be 0 (off) or 1 (on), not 2") != NULL);
    CHECK_STATUS(pmc_options_set_gradients(o, -1), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_index_offset(o, NULL), PMC_STATUS_NULL_ARGUMENT);
    CHECK(strstr(last_error(), "offset") != NULL);

    /* NULL options everywhere. */
    CHECK_STATUS(pmc_options_set_epsilon(NULL, 0.1), PMC_STATUS_NULL_ARGUMENT);
    CHECK(strstr(last_error(), "options is NULL") != NULL);
    CHECK_STATUS(pmc_options_set_max_level(NULL, 1), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_rule(NULL, PMC_RULE_A), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_topology(NULL, PMC_TOPOLOGY_CLASSIC), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_normals(NULL, PMC_NORMALS_NONE), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_gradients(NULL, 1), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_max_triangles(NULL, 5), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_threads(NULL, 1), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_progress(NULL, NULL, NULL), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_options_set_index_offset(NULL, off), PMC_STATUS_NULL_ARGUMENT);
    pmc_options_free(NULL);
    pmc_options_free(o);
}

/* A rejected setter leaves the option unchanged: the output still equals
 * the defaults'. */
static void test_rejected_values_keep_options(void) {
    pmc_volume v = make_sphere(10, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_options *o = pmc_options_new();
    pmc_mesh *a = NULL, *b = NULL;
    CHECK_STATUS(pmc_extract(&v, 3.3, NULL, &a), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, -2.0), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_max_level(o, 11), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_rule(o, 7), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_topology(o, 7), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_normals(o, 7), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_gradients(o, 7), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_options_set_threads(o, 0xFFFFFFFFu), PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_extract(&v, 3.3, o, &b), PMC_STATUS_OK);
    CHECK(meshes_equal(a, b));
    CHECK(pmc_mesh_normals(b) == NULL);
    CHECK(pmc_mesh_gradients(b) == NULL);
    pmc_mesh_free(a);
    pmc_mesh_free(b);
    pmc_options_free(o);
    free((void *)v.data);
}

static void test_extract_errors(void) {
    pmc_volume good = make_sphere(8, PMC_SCALAR_TYPE_F32, 1.0), v;
    pmc_options *o = pmc_options_new();
    pmc_mesh *m = NULL;
    int a;

    /* NULL arguments. */
    CHECK_STATUS(pmc_extract(&good, 3.0, NULL, NULL), PMC_STATUS_NULL_ARGUMENT);
    CHECK(strstr(last_error(), "out_mesh") != NULL);
    CHECK_STATUS(pmc_extract(NULL, 3.0, NULL, NULL), PMC_STATUS_NULL_ARGUMENT);
    EXPECT_FAIL(NULL, 3.0, NULL, PMC_STATUS_NULL_ARGUMENT, "volume is NULL");
    EXPECT_FAIL(NULL, 3.0, o, PMC_STATUS_NULL_ARGUMENT, "volume is NULL");
    v = good;
    v.data = NULL;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_NULL_ARGUMENT, "data is NULL");
    v.len = 0;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_NULL_ARGUMENT, "data is NULL");

    /* Unknown scalar types. */
    v = good;
    v.scalar_type = 10;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "scalar type 10");
    v.scalar_type = 0xFFFFFFFFu;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "unknown scalar type");

    /* Dimensions below 2 on each axis, including 0. */
    for (a = 0; a < 3; a++) {
        v = good;
        v.dims[a] = 1;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "at least 2");
        v.dims[a] = 0;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "at least 2");
    }
    /* Dimensions whose product overflows 64 bits (or any address space). */
    v = good;
    v.dims[0] = v.dims[1] = v.dims[2] = (uint64_t)1 << 22;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "overflow");
    /* Dimensions above the per-axis cap of 2^40: the message names it. */
    v.dims[0] = v.dims[1] = v.dims[2] = UINT64_MAX;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "the limit is 2^40");
    v.dims[0] = UINT64_MAX / 2;
    v.dims[1] = 3;
    v.dims[2] = 2;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "the limit is 2^40");
    v.dims[0] = (uint64_t)1 << 32;
    v.dims[1] = (uint64_t)1 << 32;
    v.dims[2] = 2;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "invalid volume");

    /* Spacing zero, negative, NaN, infinite; origin not finite. */
    for (a = 0; a < 3; a++) {
        v = good;
        v.spacing[a] = 0.0;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "spacing");
        v.spacing[a] = -1.0;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "spacing");
        v.spacing[a] = NAN;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "spacing");
        v.spacing[a] = INFINITY;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "spacing");
        v = good;
        v.origin[a] = NAN;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "origin");
        v.origin[a] = -INFINITY;
        EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "origin");
    }

    /* Isovalue NaN or infinite. */
    EXPECT_FAIL(&good, NAN, NULL, PMC_STATUS_INVALID_ARGUMENT, "isovalue");
    EXPECT_FAIL(&good, INFINITY, NULL, PMC_STATUS_INVALID_ARGUMENT, "isovalue");
    EXPECT_FAIL(&good, -INFINITY, o, PMC_STATUS_INVALID_ARGUMENT, "isovalue");

    /* len too small by one element, and 0. */
    v = good;
    v.len = good.len - 1;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "outside the buffer");
    v.len = 0;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "outside the buffer");
    /* len whose byte size exceeds the address space. */
    v.len = UINT64_MAX;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "address space");
    v.len = UINT64_MAX / 4 + 1; /* * 4 bytes overflows 64 bits */
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "address space");

    /* Strides that would read out of bounds. */
    v = good;
    v.strides[0] = 1;
    v.strides[1] = 8;
    v.strides[2] = 65; /* one past */
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "outside the buffer");
    /* Negative strides (before data): named with their axis, not as the
     * negative sample index they would address. */
    v.strides[2] = -64;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT,
                "invalid volume: stride 2 is -64; strides must not be negative");
    v.strides[0] = -1; /* x reversed: {-1, 8, 64} */
    v.strides[2] = 64;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT,
                "invalid volume: stride 0 is -1; strides must not be negative");
    v.strides[0] = INT64_MAX;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "outside the buffer");
    v.strides[0] = INT64_MIN;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT,
                "stride 0 is -9223372036854775808; strides must not be negative");
    v.strides[0] = v.strides[1] = v.strides[2] = INT64_MAX;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "outside the buffer");
    v = good;
    v.strides[0] = 0;
    v.strides[1] = 0;
    v.strides[2] = 1; /* not all zero: a stride of 0 would alias samples */
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "aliases samples");

    /* Misaligned data for a multi-byte type. */
    v = good;
    v.data = (const char *)good.data + 1;
    v.len = good.len - 1;
    EXPECT_FAIL(&v, 3.0, NULL, PMC_STATUS_INVALID_ARGUMENT, "aligned");

    /* Index offset out of range (beyond +/-PMC_MAX_INDEX_OFFSET) is
     * rejected at extraction. */
    {
        int64_t off[3] = {0, (int64_t)1 << 60, 0};
        CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        EXPECT_FAIL(&good, 3.0, o, PMC_STATUS_INVALID_ARGUMENT,
                    "index offset 1 (y) is 1152921504606846976");
        off[1] = INT64_MIN;
        CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        EXPECT_FAIL(&good, 3.0, o, PMC_STATUS_INVALID_ARGUMENT, "index offset 1 (y) is");
        off[1] = PMC_MAX_INDEX_OFFSET + 1;
        CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        EXPECT_FAIL(&good, 3.0, o, PMC_STATUS_INVALID_ARGUMENT, "index offset 1 (y) is 2147483649");
        off[1] = -PMC_MAX_INDEX_OFFSET;
        CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        CHECK_STATUS(pmc_extract(&good, 3.0, o, &m), PMC_STATUS_OK);
        pmc_mesh_free(m);
        off[1] = -(int64_t)1000000;
        CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
        CHECK_STATUS(pmc_extract(&good, 3.0, o, &m), PMC_STATUS_OK);
        CHECK(check_mesh(m, &good, PMC_MAX_LEVEL_LIMIT));
        pmc_mesh_free(m);
    }

    /* After all these failures a valid call still works. */
    CHECK_STATUS(pmc_extract(&good, 3.0, NULL, &m), PMC_STATUS_OK);
    CHECK(m != NULL && pmc_mesh_triangle_count(m) > 0);
    pmc_mesh_free(m);
    pmc_options_free(o);
    free((void *)good.data);
}

static void test_null_accessors(void) {
    pmc_stats s = {.struct_size = sizeof(pmc_stats)};
    pmc_volume v = make_sphere(6, PMC_SCALAR_TYPE_U8, 1.0);
    pmc_mesh *m = NULL;
    CHECK(pmc_mesh_point_count(NULL) == 0);
    CHECK(pmc_mesh_triangle_count(NULL) == 0);
    CHECK(pmc_mesh_points(NULL) == NULL);
    CHECK(pmc_mesh_index_points(NULL) == NULL);
    CHECK(pmc_mesh_triangles(NULL) == NULL);
    CHECK(pmc_mesh_normals(NULL) == NULL);
    CHECK(pmc_mesh_gradients(NULL) == NULL);
    CHECK(pmc_mesh_triangle_levels(NULL) == NULL);
    CHECK_STATUS(pmc_mesh_stats(NULL, &s), PMC_STATUS_NULL_ARGUMENT);
    CHECK(strstr(last_error(), "mesh is NULL") != NULL);
    CHECK_STATUS(pmc_mesh_stats(NULL, NULL), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_extract(&v, 2.0, NULL, &m), PMC_STATUS_OK);
    CHECK_STATUS(pmc_mesh_stats(m, NULL), PMC_STATUS_NULL_ARGUMENT);
    CHECK(strstr(last_error(), "out is NULL") != NULL);
    pmc_mesh_free(m);
    pmc_mesh_free(NULL);
    free((void *)v.data);
}

static void test_last_error_message(void) {
    char buf[256];
    size_t full, n;
    pmc_options *o = pmc_options_new();
    CHECK_STATUS(pmc_options_set_epsilon(o, -3.0), PMC_STATUS_INVALID_ARGUMENT);
    full = pmc_last_error_message(NULL, 0);
    CHECK(full > 10);
    n = pmc_last_error_message(buf, sizeof buf);
    CHECK(n == full && strlen(buf) == full);
    CHECK(strcmp(buf, "epsilon -3 must be finite and >= 0 (cell units)") == 0);
    /* Truncation: len - 1 bytes and a NUL; never beyond len. */
    {
        size_t len;
        for (len = 1; len <= full + 2; len++) {
            char *b = (char *)malloc(len + 1);
            memset(b, 'X', len + 1);
            CHECK(pmc_last_error_message(b, len) == full);
            CHECK(strlen(b) == (len - 1 < full ? len - 1 : full));
            CHECK(strncmp(b, buf, strlen(b)) == 0);
            CHECK(b[len] == 'X'); /* the byte after the buffer is untouched */
            free(b);
        }
    }
    /* len 0 with a real buffer: nothing written. */
    buf[0] = 'Z';
    CHECK(pmc_last_error_message(buf, 0) == full && buf[0] == 'Z');
    /* NULL buffer with non-zero len: nothing written, length returned. */
    CHECK(pmc_last_error_message(NULL, 100) == full);
    /* Success does not clear; the next failure replaces. */
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.5), PMC_STATUS_OK);
    CHECK(pmc_last_error_message(NULL, 0) == full);
    CHECK_STATUS(pmc_options_set_rule(o, 0xFFFFFFFFu), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strcmp(last_error(), "unknown rule 4294967295") == 0);
    pmc_options_free(o);
}

/* Measure settings: the setters refuse what the library cannot use (with
 * a message, the settings unchanged), and pmc_measure with them gives
 * the samples they ask for; NULL settings are pmc_measure_distance's. */
static void test_measure_options(void) {
    pmc_volume v = make_sphere(12, PMC_SCALAR_TYPE_F64, 1.0);
    pmc_options *eo = pmc_options_new();
    pmc_measure_options *o = pmc_measure_options_new();
    pmc_mesh *m = NULL;
    pmc_distance plain, with_null, dense, dense2;
    uint64_t np, nt;
    CHECK(o != NULL && eo != NULL);
    CHECK_STATUS(pmc_options_set_epsilon(eo, 0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 3.5, eo, &m), PMC_STATUS_OK);
    np = pmc_mesh_point_count(m);
    nt = pmc_mesh_triangle_count(m);
    CHECK(nt > 50);
    memset(&plain, 0, sizeof plain);
    plain.struct_size = sizeof plain;
    with_null = dense = dense2 = plain;
    CHECK_STATUS(pmc_measure_distance(&v, 3.5, pmc_mesh_points(m), np, pmc_mesh_triangles(m), nt,
                                      0, &plain),
                 PMC_STATUS_OK);
    CHECK_STATUS(pmc_measure(&v, 3.5, pmc_mesh_points(m), np, pmc_mesh_triangles(m), nt, NULL,
                             &with_null),
                 PMC_STATUS_OK);
    CHECK(memcmp(&plain, &with_null, sizeof plain) == 0);
    CHECK(plain.samples == nt * 15); /* density 4 */

    CHECK_STATUS(pmc_measure_options_set_density(o, 0), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strcmp(last_error(), "measure density 0 is outside 1..=1024") == 0);
    CHECK_STATUS(pmc_measure_options_set_density(o, PMC_MAX_MEASURE_DENSITY + 1),
                 PMC_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(pmc_measure_options_set_threads(o, PMC_MAX_THREADS + 1),
                 PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strcmp(last_error(), "4097 threads is above the limit of 4096") == 0);
    CHECK_STATUS(pmc_measure_options_set_tolerance(o, PMC_MIN_MEASURE_TOLERANCE / 2, 0.02),
                 PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strstr(last_error(), "at least 1e-8 cells") != NULL);
    CHECK_STATUS(pmc_measure_options_set_tolerance(o, 1e-5, 1.0), PMC_STATUS_INVALID_ARGUMENT);
    CHECK(strcmp(last_error(), "relative measure tolerance 1 must be in [0, 1)") == 0);
    CHECK_STATUS(pmc_measure_options_set_density(NULL, 4), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_measure_options_set_threads(NULL, 1), PMC_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(pmc_measure_options_set_tolerance(NULL, 1e-5, 0.02), PMC_STATUS_NULL_ARGUMENT);
    /* Nothing refused above changed the settings: still the defaults. */
    CHECK_STATUS(pmc_measure(&v, 3.5, pmc_mesh_points(m), np, pmc_mesh_triangles(m), nt, o,
                             &with_null),
                 PMC_STATUS_OK);
    CHECK(memcmp(&plain, &with_null, sizeof plain) == 0);

    CHECK_STATUS(pmc_measure_options_set_density(o, 9), PMC_STATUS_OK);
    CHECK_STATUS(pmc_measure_options_set_tolerance(o, 1e-6, 0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_measure_options_set_threads(o, 1), PMC_STATUS_OK);
    CHECK_STATUS(pmc_measure(&v, 3.5, pmc_mesh_points(m), np, pmc_mesh_triangles(m), nt, o, &dense),
                 PMC_STATUS_OK);
    CHECK(dense.samples == nt * 55); /* (9 + 1)(9 + 2) / 2 a triangle */
    CHECK(dense.max >= plain.max - 2e-5 - 0.02 * plain.max);
    CHECK_STATUS(pmc_measure_options_set_threads(o, 2), PMC_STATUS_OK);
    CHECK_STATUS(pmc_measure(&v, 3.5, pmc_mesh_points(m), np, pmc_mesh_triangles(m), nt, o,
                             &dense2),
                 PMC_STATUS_OK);
    CHECK(memcmp(&dense, &dense2, sizeof dense) == 0); /* any thread count */

    /* Index points: the mesh's own (origin 0 and spacing 1 here, so the
     * same numbers as its world points and the same result); an offset
     * beyond 2^31 is refused and changes nothing; NULL goes back to world
     * points. */
    {
        const int64_t zero[3] = {0, 0, 0}, bad[3] = {0, 0, PMC_MAX_INDEX_OFFSET + 1};
        pmc_distance by_index = plain;
        CHECK_STATUS(pmc_measure_options_set_index_points(o, zero), PMC_STATUS_OK);
        CHECK_STATUS(pmc_measure_options_set_index_points(o, bad), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(strstr(last_error(), "index offset 2 (z) is 2147483649") != NULL);
        CHECK_STATUS(pmc_measure(&v, 3.5, pmc_mesh_index_points(m), np, pmc_mesh_triangles(m), nt,
                                 o, &by_index),
                     PMC_STATUS_OK);
        CHECK(memcmp(&dense, &by_index, sizeof dense) == 0);
        CHECK_STATUS(pmc_measure_options_set_index_points(o, NULL), PMC_STATUS_OK);
        CHECK_STATUS(pmc_measure_options_set_index_points(NULL, zero), PMC_STATUS_NULL_ARGUMENT);
    }

    pmc_measure_options_free(o);
    pmc_measure_options_free(NULL);
    pmc_mesh_free(m);
    pmc_options_free(eo);
    free((void *)v.data);
}

int main(void) {
    char buf[8] = "garbage";
    /* Before any failure the message is empty. */
    CHECK(pmc_last_error_message(buf, sizeof buf) == 0 && buf[0] == '\0');
    test_status_strings();
    test_options_setters();
    test_rejected_values_keep_options();
    test_extract_errors();
    test_null_accessors();
    test_last_error_message();
    test_measure_options();
    return test_finish("test_errors");
}

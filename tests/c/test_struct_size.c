/*
 * struct_size, the first field of pmc_volume, pmc_stats and pmc_distance
 * (so that later versions can append fields without an ABI break):
 *   - 0 and sizeof - 1 are PMC_STATUS_INVALID_ARGUMENT with a message that
 *     names the field, checked before anything else is read or written;
 *   - a larger struct (a later header's: the struct and bytes it does not
 *     know) is accepted; its trailing bytes are neither read (input) nor
 *     written (output), nor is struct_size;
 *   - an output struct of exactly sizeof gets every field written and no
 *     byte past it.
 */
#include "common.h"

static char g_msg[1024];

/* The last error message (into g_msg). */
static const char *last_error(void) {
    pmc_last_error_message(g_msg, sizeof g_msg);
    return g_msg;
}

/* Whether the last error starts "<name>.struct_size is <size>" and says to
 * set it to sizeof(<name>). */
static int names_field(const char *name, uint64_t size) {
    char start[128], set[128];
    sprintf(start, "%s.struct_size is %llu", name, (unsigned long long)size);
    sprintf(set, "set it to sizeof(%s)", name);
    last_error();
    if (strncmp(g_msg, start, strlen(start)) == 0 && strstr(g_msg, set) != NULL) return 1;
    fprintf(stderr, "message '%s' does not start '%s' or lacks '%s'\n", g_msg, start, set);
    return 0;
}

#define CANARY 0xA5
#define TAIL 40

/* Each struct followed by bytes it does not know: what a caller built
 * against a later header passes. */
typedef struct {
    pmc_volume v;
    unsigned char tail[TAIL];
} big_volume;
typedef struct {
    pmc_stats s;
    unsigned char tail[TAIL];
} big_stats;
typedef struct {
    pmc_distance d;
    unsigned char tail[TAIL];
} big_distance;

/* Whether the `n` bytes at `p` are all CANARY. */
static int all_canary(const void *p, size_t n) {
    const unsigned char *b = (const unsigned char *)p;
    size_t i;
    for (i = 0; i < n; i++)
        if (b[i] != CANARY) return 0;
    return 1;
}

/* Whether every field but struct_size is equal (bitwise for doubles: the
 * same mesh's statistics). */
static int stats_equal(const pmc_stats *a, const pmc_stats *b) {
    return a->cells == b->cells && a->mc_triangles == b->mc_triangles &&
           a->output_triangles == b->output_triangles && a->output_points == b->output_points &&
           a->ambiguous_cells == b->ambiguous_cells &&
           a->skipped_nonfinite_cells == b->skipped_nonfinite_cells &&
           a->samples_evaluated == b->samples_evaluated && a->split_points == b->split_points &&
           a->projection_failures == b->projection_failures &&
           a->faces_above_epsilon == b->faces_above_epsilon && a->max_level == b->max_level &&
           a->effective_max_level == b->effective_max_level &&
           memcmp(&a->mean_level, &b->mean_level, sizeof(double)) == 0 &&
           a->budget_reached == b->budget_reached &&
           memcmp(&a->time_mc, &b->time_mc, sizeof(double)) == 0 &&
           memcmp(&a->time_refine, &b->time_refine, sizeof(double)) == 0 &&
           memcmp(&a->time_assemble, &b->time_assemble, sizeof(double)) == 0 &&
           memcmp(&a->time_normals, &b->time_normals, sizeof(double)) == 0 &&
           memcmp(&a->time_total, &b->time_total, sizeof(double)) == 0;
}

static int distance_equal(const pmc_distance *a, const pmc_distance *b) {
    return memcmp(&a->max, &b->max, sizeof(double)) == 0 &&
           memcmp(&a->mean, &b->mean, sizeof(double)) == 0 &&
           memcmp(&a->rms, &b->rms, sizeof(double)) == 0 && a->samples == b->samples &&
           a->unresolved == b->unresolved;
}

static pmc_volume g_volume;
static pmc_mesh *g_mesh;

static pmc_status measure(const pmc_volume *v, double iso, pmc_distance *out) {
    return pmc_measure_distance(v, iso, pmc_mesh_points(g_mesh), pmc_mesh_point_count(g_mesh),
                                pmc_mesh_triangles(g_mesh), pmc_mesh_triangle_count(g_mesh), 1,
                                out);
}

static void test_volume(void) {
    /* Above 64 KiB: what a caller built against a header without
     * struct_size passes there (its data pointer). */
    const uint64_t bad[5] = {0, 1, sizeof(pmc_volume) - 1, 65537,
                             (uint64_t)(uintptr_t)&g_volume};
    big_volume big;
    pmc_mesh *m;
    int i;
    for (i = 0; i < 5; i++) {
        pmc_volume v = g_volume;
        pmc_distance d = {.struct_size = sizeof(pmc_distance)};
        v.struct_size = bad[i];
        m = (pmc_mesh *)&g_msg;
        CHECK_STATUS(pmc_extract(&v, 3.5, NULL, &m), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(m == NULL);
        CHECK(names_field("pmc_volume", bad[i]));
        /* Before any other field: a NULL data is not what is reported. */
        v.data = NULL;
        CHECK_STATUS(pmc_extract(&v, 3.5, NULL, &m), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(names_field("pmc_volume", bad[i]));
        d.max = d.mean = 1.0;
        CHECK_STATUS(measure(&v, 3.5, &d), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(names_field("pmc_volume", bad[i]));
        /* The output is zeroed, as on any failure past its own check. */
        CHECK(d.max == 0.0 && d.mean == 0.0 && d.struct_size == sizeof d);
    }
    /* A larger struct: accepted, its tail never read (valgrind and ASan
     * would see uninitialised or out-of-bounds reads of a shorter one;
     * here the tail holds canaries, and the output equals the plain
     * volume's). */
    memset(&big, CANARY, sizeof big);
    big.v = g_volume;
    big.v.struct_size = sizeof big;
    m = NULL;
    CHECK_STATUS(pmc_extract(&big.v, 3.5, NULL, &m), PMC_STATUS_OK);
    CHECK(m != NULL && meshes_equal(m, g_mesh));
    CHECK(all_canary(big.tail, TAIL) && big.v.struct_size == sizeof big);
    pmc_mesh_free(m);
    {
        pmc_distance want = {.struct_size = sizeof(pmc_distance)};
        pmc_distance got = {.struct_size = sizeof(pmc_distance)};
        CHECK_STATUS(measure(&g_volume, 3.5, &want), PMC_STATUS_OK);
        CHECK_STATUS(measure(&big.v, 3.5, &got), PMC_STATUS_OK);
        CHECK(want.samples > 0 && distance_equal(&want, &got));
    }
}

static void test_stats(void) {
    const uint64_t bad[4] = {0, 1, sizeof(pmc_stats) - 1, 65537};
    const uint64_t good[2] = {sizeof(pmc_stats), sizeof(big_stats)};
    pmc_stats want = {.struct_size = sizeof(pmc_stats)};
    big_stats b;
    int i;
    CHECK_STATUS(pmc_mesh_stats(g_mesh, &want), PMC_STATUS_OK);
    CHECK(want.struct_size == sizeof want && want.output_triangles > 0);
    /* Rejected: nothing written. */
    for (i = 0; i < 4; i++) {
        memset(&b, CANARY, sizeof b);
        b.s.struct_size = bad[i];
        CHECK_STATUS(pmc_mesh_stats(g_mesh, &b.s), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(names_field("pmc_stats", bad[i]));
        CHECK(b.s.struct_size == bad[i]);
        CHECK(all_canary((const unsigned char *)&b + sizeof(uint64_t),
                         sizeof b - sizeof(uint64_t)));
    }
    /* Exactly sizeof, then larger: every field written, struct_size kept,
     * no byte past the struct. */
    for (i = 0; i < 2; i++) {
        memset(&b, CANARY, sizeof b);
        b.s.struct_size = good[i];
        CHECK_STATUS(pmc_mesh_stats(g_mesh, &b.s), PMC_STATUS_OK);
        CHECK(b.s.struct_size == good[i]);
        CHECK(stats_equal(&b.s, &want));
        CHECK(all_canary(b.tail, TAIL));
    }
}

static void test_distance(void) {
    const uint64_t bad[4] = {0, 1, sizeof(pmc_distance) - 1, 65537};
    const uint64_t good[2] = {sizeof(pmc_distance), sizeof(big_distance)};
    pmc_distance want = {.struct_size = sizeof(pmc_distance)};
    big_distance b;
    int i;
    CHECK_STATUS(measure(&g_volume, 3.5, &want), PMC_STATUS_OK);
    CHECK(want.samples > 0 && want.max > 0.0);
    /* Rejected: nothing written; checked before the volume. */
    for (i = 0; i < 4; i++) {
        memset(&b, CANARY, sizeof b);
        b.d.struct_size = bad[i];
        CHECK_STATUS(measure(&g_volume, 3.5, &b.d), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(names_field("pmc_distance", bad[i]));
        CHECK(b.d.struct_size == bad[i]);
        CHECK(all_canary((const unsigned char *)&b + sizeof(uint64_t),
                         sizeof b - sizeof(uint64_t)));
        CHECK_STATUS(measure(NULL, 3.5, &b.d), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(names_field("pmc_distance", bad[i]));
        CHECK(all_canary((const unsigned char *)&b + sizeof(uint64_t),
                         sizeof b - sizeof(uint64_t)));
    }
    for (i = 0; i < 2; i++) {
        /* Exactly sizeof, then larger: every field written, struct_size
         * kept, no byte past the struct. */
        memset(&b, CANARY, sizeof b);
        b.d.struct_size = good[i];
        CHECK_STATUS(measure(&g_volume, 3.5, &b.d), PMC_STATUS_OK);
        CHECK(b.d.struct_size == good[i]);
        CHECK(distance_equal(&b.d, &want));
        CHECK(all_canary(b.tail, TAIL));
        /* A later failure zeroes the known fields, and only those. */
        memset(&b, CANARY, sizeof b);
        b.d.struct_size = good[i];
        CHECK_STATUS(measure(&g_volume, NAN, &b.d), PMC_STATUS_INVALID_ARGUMENT);
        CHECK(b.d.struct_size == good[i]);
        CHECK(b.d.max == 0.0 && b.d.mean == 0.0 && b.d.rms == 0.0 && b.d.samples == 0 &&
              b.d.unresolved == 0);
        CHECK(all_canary(b.tail, TAIL));
    }
}

int main(void) {
    CHECK(sizeof(big_volume) > sizeof(pmc_volume) + 8);
    CHECK(sizeof(big_stats) > sizeof(pmc_stats) + 8);
    CHECK(sizeof(big_distance) > sizeof(pmc_distance) + 8);
    g_volume = make_sphere(10, PMC_SCALAR_TYPE_F32, 1.0);
    g_mesh = NULL;
    CHECK_STATUS(pmc_extract(&g_volume, 3.5, NULL, &g_mesh), PMC_STATUS_OK);
    if (g_mesh != NULL) {
        test_volume();
        test_stats();
        test_distance();
    }
    pmc_mesh_free(g_mesh);
    free((void *)g_volume.data);
    return test_finish("test_struct_size");
}

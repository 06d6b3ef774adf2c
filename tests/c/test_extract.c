/*
 * Full extractions through the C API: a sphere (closed, oriented, right
 * volume), every scalar type, strides, pieces with index offsets, options
 * that change the output, normals and statistics.
 */
#include <stddef.h>

#include "common.h"

#define N 24
#define RADIUS 8.0

static const double PI = 3.14159265358979323846;

/* Extracts with `o` (may be NULL); returns the mesh or NULL. */
static pmc_mesh *extract(const pmc_volume *v, double iso, const pmc_options *o) {
    pmc_mesh *m = NULL;
    CHECK_STATUS(pmc_extract(v, iso, o, &m), PMC_STATUS_OK);
    CHECK(m != NULL);
    return m;
}

static void test_layout(void) {
    /* Pinned ABI: the Rust tests (tests/c_api.rs) check the same numbers. */
    CHECK(sizeof(pmc_volume) == 128);
    CHECK(offsetof(pmc_volume, struct_size) == 0);
    CHECK(offsetof(pmc_volume, data) == 8);
    CHECK(offsetof(pmc_volume, len) == 16);
    CHECK(offsetof(pmc_volume, scalar_type) == 24);
    CHECK(offsetof(pmc_volume, dims) == 32);
    CHECK(offsetof(pmc_volume, strides) == 56);
    CHECK(offsetof(pmc_volume, origin) == 80);
    CHECK(offsetof(pmc_volume, spacing) == 104);
    CHECK(sizeof(pmc_stats) == 152);
    CHECK(offsetof(pmc_stats, struct_size) == 0);
    CHECK(offsetof(pmc_stats, cells) == 8);
    CHECK(offsetof(pmc_stats, max_level) == 88);
    CHECK(offsetof(pmc_stats, mean_level) == 96);
    CHECK(offsetof(pmc_stats, budget_reached) == 104);
    CHECK(offsetof(pmc_stats, time_total) == 144);
    CHECK(sizeof(pmc_distance) == 48);
    CHECK(offsetof(pmc_distance, struct_size) == 0);
    CHECK(offsetof(pmc_distance, max) == 8);
    CHECK(offsetof(pmc_distance, unresolved) == 40);
    CHECK(sizeof(pmc_status) == 4 && sizeof(pmc_scalar_type) == 4);
    CHECK(PMC_STATUS_OK == 0 && PMC_STATUS_NULL_ARGUMENT == 1 && PMC_STATUS_INVALID_ARGUMENT == 2 &&
          PMC_STATUS_ABORTED == 3 && PMC_STATUS_OUT_OF_MEMORY == 4 && PMC_STATUS_INTERNAL_ERROR == 5);
    CHECK(PMC_SCALAR_TYPE_I8 == 0 && PMC_SCALAR_TYPE_U8 == 1 && PMC_SCALAR_TYPE_I16 == 2 &&
          PMC_SCALAR_TYPE_U16 == 3 && PMC_SCALAR_TYPE_I32 == 4 && PMC_SCALAR_TYPE_U32 == 5 &&
          PMC_SCALAR_TYPE_I64 == 6 && PMC_SCALAR_TYPE_U64 == 7 && PMC_SCALAR_TYPE_F32 == 8 &&
          PMC_SCALAR_TYPE_F64 == 9);
    CHECK(PMC_TOPOLOGY_TRILINEAR == 0 && PMC_TOPOLOGY_CLASSIC == 1);
    CHECK(PMC_RULE_A == 0 && PMC_RULE_A1 == 1 && PMC_RULE_A2 == 2 && PMC_RULE_B == 3);
    CHECK(PMC_NORMALS_NONE == 0 && PMC_NORMALS_GRADIENT == 1 && PMC_NORMALS_CENTRAL_DIFFERENCE == 2);
}

static void test_sphere(void) {
    pmc_volume v = make_sphere(N, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_mesh *m = extract(&v, RADIUS, NULL);
    pmc_stats s = {.struct_size = sizeof(pmc_stats)};
    double vol, exact = 4.0 / 3.0 * PI * RADIUS * RADIUS * RADIUS;
    uint64_t i, np = pmc_mesh_point_count(m);
    const double *p = pmc_mesh_points(m);
    double c = 0.5 * (N - 1), worst = 0.0;

    CHECK(np > 0);
    CHECK(pmc_mesh_triangle_count(m) > 0);
    CHECK(check_mesh(m, &v, 5));
    CHECK(mesh_is_closed(m));
    CHECK(pmc_mesh_normals(m) == NULL); /* not requested */
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.cells == (uint64_t)(N - 1) * (N - 1) * (N - 1));
    CHECK(s.mc_triangles > 0 && s.output_triangles >= s.mc_triangles);
    CHECK(s.split_points > 0 && s.samples_evaluated >= s.split_points);
    CHECK(s.max_level >= 1 && s.max_level <= 5);
    CHECK(s.mean_level > 0.0 && s.mean_level <= s.max_level);
    CHECK(s.budget_reached == 0);
    CHECK(s.effective_max_level == 5);
    CHECK(s.skipped_nonfinite_cells == 0);
    CHECK(s.time_total >= 0.0 && s.time_total >= s.time_mc);
    /* Oriented towards lower values (inwards): negative signed volume. */
    vol = mesh_signed_volume(m);
    CHECK(vol < 0.0);
    CHECK(fabs(-vol - exact) < 0.02 * exact);
    for (i = 0; i < np; i++) {
        double x = p[3 * i] - c, y = p[3 * i + 1] - c, z = p[3 * i + 2] - c;
        double e = fabs(sqrt(x * x + y * y + z * z) - RADIUS);
        if (e > worst) worst = e;
    }
    CHECK(worst < 0.05);
    pmc_mesh_free(m);
    free((void *)v.data);
}

/* The triangles move out without a copy and outlive their mesh; the
 * world points, computed on request, are origin + spacing * index point. */
static void test_take_triangles(void) {
    pmc_volume v = make_sphere(N, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_mesh *m;
    uint64_t i, nt, np, count = 12345;
    int64_t *taken, *copy;
    const double *w, *ijk;
    int same = 1;

    v.origin[0] = -2.5; v.origin[1] = 4.0; v.origin[2] = 0.125;
    v.spacing[0] = 0.5; v.spacing[1] = 1.25; v.spacing[2] = 3.0;
    m = extract(&v, RADIUS, NULL);
    nt = pmc_mesh_triangle_count(m);
    np = pmc_mesh_point_count(m);
    CHECK(nt > 0 && np > 0);
    w = pmc_mesh_points(m);
    ijk = pmc_mesh_index_points(m);
    CHECK(w != NULL && ijk != NULL && pmc_mesh_points(m) == w);
    for (i = 0; i < np; i++) {
        int d;
        for (d = 0; d < 3; d++) {
            same &= w[3 * i + d] == v.origin[d] + v.spacing[d] * ijk[3 * i + d];
        }
    }
    CHECK(same);
    copy = malloc(sizeof(int64_t) * 3 * nt);
    memcpy(copy, pmc_mesh_triangles(m), sizeof(int64_t) * 3 * nt);
    taken = pmc_mesh_take_triangles(m, &count);
    CHECK(taken != NULL && count == nt);
    CHECK(pmc_mesh_triangle_count(m) == 0 && pmc_mesh_triangles(m) == NULL);
    CHECK(pmc_mesh_point_count(m) == np && pmc_mesh_triangle_levels(m) != NULL);
    CHECK(pmc_mesh_take_triangles(m, &count) == NULL && count == 0);
    pmc_mesh_free(m);
    CHECK(memcmp(copy, taken, sizeof(int64_t) * 3 * nt) == 0);
    pmc_buffer_free(taken);
    pmc_buffer_free(NULL);
    /* The freed arrays were kept for the next extraction; releasing them
       reports at least the triangles' bytes, and only once. */
    CHECK(pmc_release_memory() >= sizeof(int64_t) * 3 * nt);
    CHECK(pmc_release_memory() == 0);
    free(copy);
    free((void *)v.data);
}

/* Every scalar type gives the mesh of the same values in doubles. The
 * values lie around 0 for the signed types and across the signed maximum
 * for the unsigned ones (in steps of 4096 for uint64_t, where doubles are
 * that coarse), so that a sample read with the wrong signedness or width
 * changes the surface. */
static void test_scalar_types(void) {
    pmc_scalar_type t;
    for (t = 0; t < 10; t++) {
        const int is_signed = t == PMC_SCALAR_TYPE_I8 || t == PMC_SCALAR_TYPE_I16 ||
                              t == PMC_SCALAR_TYPE_I32 || t == PMC_SCALAR_TYPE_I64 ||
                              t == PMC_SCALAR_TYPE_F32 || t == PMC_SCALAR_TYPE_F64;
        const double scale = t == PMC_SCALAR_TYPE_U64 ? 4096.0 : 1.0;
        const double edge = is_signed ? 0.0 /* the values' middle: 0, or the signed maximum + 1 */
                            : t == PMC_SCALAR_TYPE_U8  ? 128.0
                            : t == PMC_SCALAR_TYPE_U16 ? 32768.0
                            : t == PMC_SCALAR_TYPE_U32 ? 2147483648.0
                                                       : 9223372036854775808.0;
        const double shift = edge - 20.0 * scale;
        pmc_volume v = make_sphere(16, PMC_SCALAR_TYPE_F64, 4.0), ref = v;
        double *d = (double *)v.data;
        void *buf = malloc((size_t)v.len * scalar_size(t));
        int below = 0, above = 0;
        pmc_mesh *m, *mref;
        uint64_t i;
        for (i = 0; i < v.len; i++) {
            d[i] = floor(d[i] + 0.5) * scale + shift; /* exact in doubles */
            store(buf, t, (size_t)i, d[i]);
            below |= d[i] < edge;
            above |= d[i] >= edge;
        }
        CHECK(below && above);
        v.data = buf;
        v.scalar_type = t;
        m = extract(&v, 20.5 * scale + shift, NULL);
        mref = extract(&ref, 20.5 * scale + shift, NULL);
        CHECK(pmc_mesh_triangle_count(mref) > 100);
        CHECK(check_mesh(m, &v, 5));
        CHECK(mesh_is_closed(m));
        if (!meshes_equal(m, mref)) {
            fprintf(stderr, "scalar type %u differs from f64\n", (unsigned)t);
            CHECK(0);
        }
        pmc_mesh_free(m);
        pmc_mesh_free(mref);
        free(buf);
        free((void *)ref.data);
    }
}

/* A volume embedded with padding and permuted strides reads the same. */
static void test_strides(void) {
    const uint64_t n = 12;
    pmc_volume v = make_sphere(n, PMC_SCALAR_TYPE_F64, 1.0);
    pmc_mesh *a = extract(&v, 4.2, NULL), *b;
    /* Layout z fastest, then x, then y, with padding on every axis. */
    const uint64_t pz = n + 3, px = n + 1;
    uint64_t len = pz * px * n + 5, i, j, k;
    double *buf = (double *)malloc((size_t)len * sizeof *buf);
    const double *src = (const double *)v.data;
    pmc_volume w = v;
    for (i = 0; i < len; i++) buf[i] = NAN; /* padding must never be read */
    for (k = 0; k < n; k++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) buf[j * (pz * px) + i * pz + k] = src[(k * n + j) * n + i];
    w.data = buf;
    w.len = pz * px * (n - 1) + pz * (n - 1) + (n - 1) + 1; /* exactly enough */
    w.strides[0] = (int64_t)pz;
    w.strides[1] = (int64_t)(pz * px);
    w.strides[2] = 1;
    b = extract(&w, 4.2, NULL);
    CHECK(meshes_equal(a, b));
    {
        pmc_stats s = {.struct_size = sizeof(pmc_stats)};
        CHECK_STATUS(pmc_mesh_stats(b, &s), PMC_STATUS_OK);
        CHECK(s.skipped_nonfinite_cells == 0);
    }
    /* Explicit contiguous strides equal the all-zero shorthand. */
    v.strides[0] = 1;
    v.strides[1] = (int64_t)n;
    v.strides[2] = (int64_t)(n * n);
    pmc_mesh_free(b);
    b = extract(&v, 4.2, NULL);
    CHECK(meshes_equal(a, b));
    pmc_mesh_free(a);
    pmc_mesh_free(b);
    free(buf);
    free((void *)v.data);
}

static int cmp_point_bytes(const void *a, const void *b) {
    return memcmp(a, b, 3 * sizeof(double));
}

/* Two pieces sharing the layer k = 10 produce bit-identical points on it,
 * equal to those of the whole volume. */

static void test_pieces(void) {
    const uint64_t n = 20, cut = 10;
    pmc_volume whole = make_sphere(n, PMC_SCALAR_TYPE_F32, 1.0), lo = whole, hi = whole;
    pmc_options *o = pmc_options_new();
    int64_t off[3] = {0, 0, 0};
    pmc_mesh *mw, *ml, *mh;
    double zcut;
    uint64_t i, on_lo = 0, on_hi = 0, matched = 0;
    whole.origin[0] = -3.25;
    whole.origin[1] = 1.5;
    whole.origin[2] = 0.125;
    whole.spacing[0] = 0.5;
    whole.spacing[1] = 0.75;
    whole.spacing[2] = 0.3;
    lo = hi = whole;
    lo.dims[2] = cut + 1;
    lo.len = n * n * (cut + 1);
    lo.strides[0] = 1;
    lo.strides[1] = (int64_t)n;
    lo.strides[2] = (int64_t)(n * n);
    hi.data = (const float *)whole.data + n * n * cut;
    hi.dims[2] = n - cut;
    hi.len = n * n * (n - cut);
    mw = extract(&whole, 7.0, o);
    ml = extract(&lo, 7.0, o);
    off[2] = (int64_t)cut;
    CHECK_STATUS(pmc_options_set_index_offset(o, off), PMC_STATUS_OK);
    mh = extract(&hi, 7.0, o);
    zcut = whole.origin[2] + whole.spacing[2] * (double)cut;
    CHECK(pmc_mesh_triangle_count(ml) + pmc_mesh_triangle_count(mh) == pmc_mesh_triangle_count(mw));
    {
        const double *pl = pmc_mesh_points(ml), *ph = pmc_mesh_points(mh);
        const double *il = pmc_mesh_index_points(ml), *ih = pmc_mesh_index_points(mh);
        uint64_t nl = pmc_mesh_point_count(ml), nh = pmc_mesh_point_count(mh), a, b;
        for (a = 0; a < nh; a++) CHECK(ih[3 * a + 2] >= (double)cut);
        for (a = 0; a < nl; a++) {
            if (il[3 * a + 2] != (double)cut) continue;
            on_lo++;
            CHECK(pl[3 * a + 2] == zcut);
            for (b = 0; b < nh; b++)
                if (memcmp(pl + 3 * a, ph + 3 * b, 3 * sizeof(double)) == 0) {
                    matched++;
                    break;
                }
        }
        for (b = 0; b < nh; b++) on_hi += ih[3 * b + 2] == (double)cut;
    }
    CHECK(on_lo > 0);
    CHECK(on_lo == on_hi);
    CHECK(matched == on_lo);
    /* Every point of either piece is, bit for bit, a point of the whole
     * volume's mesh (points sorted by their bytes, then searched). */
    {
        uint64_t nw = pmc_mesh_point_count(mw), missing = 0, k;
        double *sorted = (double *)malloc((size_t)(3 * nw) * sizeof *sorted);
        const pmc_mesh *piece[2];
        piece[0] = ml;
        piece[1] = mh;
        memcpy(sorted, pmc_mesh_points(mw), (size_t)(3 * nw) * sizeof *sorted);
        qsort(sorted, (size_t)nw, 3 * sizeof *sorted, cmp_point_bytes);
        for (k = 0; k < 2; k++) {
            const double *pp = pmc_mesh_points(piece[k]);
            for (i = 0; i < pmc_mesh_point_count(piece[k]); i++)
                missing += bsearch(pp + 3 * i, sorted, (size_t)nw, 3 * sizeof *sorted,
                                   cmp_point_bytes) == NULL;
        }
        CHECK(nw > 0 && missing == 0);
        free(sorted);
    }
    pmc_mesh_free(mw);
    pmc_mesh_free(ml);
    pmc_mesh_free(mh);
    pmc_options_free(o);
    free((void *)whole.data);
}

/* Options reach the core: plain MC, rules, topology, normals, cap, threads. */
static void test_options_effects(void) {
    pmc_volume v = make_sphere(16, PMC_SCALAR_TYPE_F64, 1.0);
    pmc_options *o = pmc_options_new();
    pmc_mesh *def = extract(&v, 5.3, o), *m;
    pmc_stats s = {.struct_size = sizeof(pmc_stats)}, sd = {.struct_size = sizeof(pmc_stats)};
    pmc_rule r;
    uint32_t th;

    CHECK_STATUS(pmc_mesh_stats(def, &sd), PMC_STATUS_OK);
    /* NULL options = defaults. */
    m = extract(&v, 5.3, NULL);
    CHECK(meshes_equal(m, def));
    pmc_mesh_free(m);

    /* epsilon 0: plain Marching Cubes. */
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.output_triangles == s.mc_triangles && s.max_level == 0 && s.split_points == 0);
    CHECK(s.mc_triangles == sd.mc_triangles);
    CHECK(mesh_is_closed(m));
    pmc_mesh_free(m);
    /* max level 0: the same. */
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.01), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 0), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.output_triangles == s.mc_triangles && s.max_level == 0);
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_max_level(o, 5), PMC_STATUS_OK);

    /* Every rule gives a valid closed mesh. */
    for (r = PMC_RULE_A; r <= PMC_RULE_B; r++) {
        CHECK_STATUS(pmc_options_set_rule(o, r), PMC_STATUS_OK);
        m = extract(&v, 5.3, o);
        CHECK(check_mesh(m, &v, 5));
        CHECK(mesh_is_closed(m));
        pmc_mesh_free(m);
    }
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_A1), PMC_STATUS_OK);

    /* Classic topology: no ambiguous-cell decisions. */
    CHECK_STATUS(pmc_options_set_topology(o, PMC_TOPOLOGY_CLASSIC), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.ambiguous_cells == 0);
    CHECK(check_mesh(m, &v, 5));
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_topology(o, PMC_TOPOLOGY_TRILINEAR), PMC_STATUS_OK);

    /* Normals: unit, pointing inwards (towards lower values). */
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_GRADIENT), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK(pmc_mesh_normals(m) != NULL);
    CHECK(check_mesh(m, &v, 5));
    {
        const double *p = pmc_mesh_points(m);
        const float *nr = pmc_mesh_normals(m);
        uint64_t i, np = pmc_mesh_point_count(m), inward = 0;
        for (i = 0; i < np; i++) {
            double d = (p[3 * i] - 7.5) * nr[3 * i] + (p[3 * i + 1] - 7.5) * nr[3 * i + 1] +
                       (p[3 * i + 2] - 7.5) * nr[3 * i + 2];
            inward += d < 0.0;
        }
        CHECK(inward == np);
    }
    CHECK(meshes_equal(m, def)); /* normals do not change the geometry */
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_CENTRAL_DIFFERENCE), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK(pmc_mesh_normals(m) != NULL);
    CHECK(pmc_mesh_gradients(m) == NULL); /* not requested */
    CHECK(check_mesh(m, &v, 5));
    pmc_mesh_free(m);

    /* Gradients: outwards (towards higher values), each normal the
     * negated, normalised gradient; the geometry unchanged. */
    CHECK_STATUS(pmc_options_set_gradients(o, 1), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK(pmc_mesh_gradients(m) != NULL && pmc_mesh_normals(m) != NULL);
    CHECK(meshes_equal(m, def));
    {
        const double *p = pmc_mesh_points(m);
        const float *g = pmc_mesh_gradients(m);
        const float *nr = pmc_mesh_normals(m);
        uint64_t i, np = pmc_mesh_point_count(m), outward = 0, along = 0;
        for (i = 0; i < np; i++) {
            double len = sqrt((double)g[3 * i] * g[3 * i] + (double)g[3 * i + 1] * g[3 * i + 1] +
                              (double)g[3 * i + 2] * g[3 * i + 2]);
            double d = (p[3 * i] - 7.5) * g[3 * i] + (p[3 * i + 1] - 7.5) * g[3 * i + 1] +
                       (p[3 * i + 2] - 7.5) * g[3 * i + 2];
            outward += d > 0.0;
            along += len > 0.0 && fabs(nr[3 * i] + g[3 * i] / len) < 1e-5 &&
                     fabs(nr[3 * i + 1] + g[3 * i + 1] / len) < 1e-5 &&
                     fabs(nr[3 * i + 2] + g[3 * i + 2] / len) < 1e-5;
        }
        CHECK(outward == np);
        CHECK(along == np);
    }
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_gradients(o, 0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_normals(o, PMC_NORMALS_NONE), PMC_STATUS_OK);

    /* Triangle cap below the default output: refinement stops early. */
    CHECK_STATUS(pmc_options_set_max_triangles(o, sd.mc_triangles + 1), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.budget_reached == 1);
    CHECK(s.effective_max_level < 5);
    CHECK(s.output_triangles <= sd.output_triangles);
    CHECK(check_mesh(m, &v, 5));
    pmc_mesh_free(m);
    /* With refinement off (max level 0 or epsilon 0) a cap below the
     * Marching Cubes count lowers no level: the budget is not reached and
     * the Marching Cubes triangles are all kept. */
    CHECK_STATUS(pmc_options_set_max_triangles(o, 10), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 0), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.budget_reached == 0 && s.effective_max_level == 0);
    CHECK(s.output_triangles == sd.mc_triangles);
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_max_level(o, 5), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0), PMC_STATUS_OK);
    m = extract(&v, 5.3, o);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.budget_reached == 0 && s.output_triangles == sd.mc_triangles);
    pmc_mesh_free(m);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.01), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_triangles(o, 0), PMC_STATUS_OK);

    /* Any thread count gives the same mesh. */
    for (th = 0; th <= 3; th++) {
        CHECK_STATUS(pmc_options_set_threads(o, th), PMC_STATUS_OK);
        m = extract(&v, 5.3, o);
        CHECK(meshes_equal(m, def));
        pmc_mesh_free(m);
    }

    /* Origin and spacing map index points to world points. */
    v.origin[0] = 10.0;
    v.origin[1] = -2.0;
    v.origin[2] = 0.5;
    v.spacing[0] = 0.25;
    v.spacing[1] = 2.0;
    v.spacing[2] = 1.5;
    m = extract(&v, 5.3, o);
    CHECK(check_mesh(m, &v, 5));
    CHECK(pmc_mesh_point_count(m) == pmc_mesh_point_count(def));
    CHECK(memcmp(pmc_mesh_index_points(m), pmc_mesh_index_points(def),
                 (size_t)pmc_mesh_point_count(m) * 3 * sizeof(double)) == 0);
    pmc_mesh_free(m);

    /* An isovalue outside the data: an empty mesh with NULL arrays. */
    m = extract(&v, 1000.0, o);
    CHECK(pmc_mesh_point_count(m) == 0 && pmc_mesh_triangle_count(m) == 0);
    CHECK(pmc_mesh_points(m) == NULL && pmc_mesh_triangles(m) == NULL);
    CHECK(pmc_mesh_index_points(m) == NULL && pmc_mesh_triangle_levels(m) == NULL);
    CHECK(pmc_mesh_normals(m) == NULL);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.output_triangles == 0 && s.mc_triangles == 0);
    pmc_mesh_free(m);

    pmc_mesh_free(def);
    pmc_options_free(o);
    free((void *)v.data);
}

/* NaN samples skip their cells instead of failing. */
static void test_nonfinite_samples(void) {
    pmc_volume v = make_sphere(12, PMC_SCALAR_TYPE_F32, 1.0);
    pmc_mesh *m;
    pmc_stats s = {.struct_size = sizeof(pmc_stats)};
    ((float *)v.data)[5 + 12 * (5 + 12 * 1)] = NAN;
    ((float *)v.data)[6 + 12 * (6 + 12 * 6)] = INFINITY;
    m = extract(&v, 4.0, NULL);
    CHECK_STATUS(pmc_mesh_stats(m, &s), PMC_STATUS_OK);
    CHECK(s.skipped_nonfinite_cells > 0);
    CHECK(check_mesh(m, &v, 5));
    pmc_mesh_free(m);
    free((void *)v.data);
}

/* An n x n x n float64 volume over `data`, unit spacing. */
static void cube_volume(pmc_volume *v, double *data, int n) {
    memset(v, 0, sizeof *v);
    v->struct_size = sizeof *v;
    v->data = data;
    v->len = (uint64_t)n * n * n;
    v->scalar_type = PMC_SCALAR_TYPE_F64;
    v->dims[0] = v->dims[1] = v->dims[2] = (uint64_t)n;
    for (int a = 0; a < 3; a++) v->spacing[a] = 1.0;
}

/* A cell where straight gradient lines from two split points meet on the
 * surface: the refined patch is unsound, so the cell is refined again on
 * its faces only, and the count says so (0 for NULL). */
static void test_cells_refined_on_faces_only(void) {
    static const double f[8] = {-1, -3, -1, 1, 5, 3, -3, -1};
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    double data[64];
    pmc_volume v;
    pmc_options *o = pmc_options_new();
    pmc_mesh *m = NULL;
    for (int i = 0; i < 64; i++) data[i] = -1.0;
    for (int c = 0; c < 8; c++)
        data[(corner[c][0] + 1) + 4 * (corner[c][1] + 1) + 16 * (corner[c][2] + 1)] = f[c];
    cube_volume(&v, data, 4);
    CHECK(pmc_mesh_cells_refined_on_faces_only(NULL) == 0);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.01), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 3), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_rule(o, PMC_RULE_B), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 1e-9, o, &m), PMC_STATUS_OK);
    CHECK(pmc_mesh_cells_refined_on_faces_only(m) > 0);
    CHECK(mesh_is_closed(m));
    pmc_mesh_free(m);
    pmc_options_free(o);
}

/* A cell where the surface hugs the top face: the case table's diagonal
 * crosses the part of the cell the surface never enters, so refinement
 * re-cuts the polygon first, and the count says so (0 for NULL and with
 * refinement off). Corner values from the "atoms" sample. */
static void test_recut_polygons(void) {
    static const double f[8] = {113.68658, 99.584435, 71.3651, 118.850815,
                                49.37087, 48.697723, 40.276493, 68.39907};
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    double data[27];
    pmc_volume v;
    pmc_options *o = pmc_options_new();
    pmc_mesh *m = NULL;
    /* A 3x3x3 volume whose first cell is the one above; the other
     * samples copy their nearest corner of it. */
    for (int z = 0; z < 3; z++)
        for (int y = 0; y < 3; y++)
            for (int x = 0; x < 3; x++) {
                int c = 0;
                for (int k = 0; k < 8; k++)
                    if (corner[k][0] == (x > 0) && corner[k][1] == (y > 0) && corner[k][2] == (z > 0))
                        c = k;
                data[x + 3 * y + 9 * z] = f[c];
            }
    cube_volume(&v, data, 3);
    CHECK(pmc_mesh_recut_polygons(NULL) == 0);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 50.5, o, &m), PMC_STATUS_OK);
    CHECK(pmc_mesh_recut_polygons(m) == 0);
    pmc_mesh_free(m);
    m = NULL;
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.001), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 50.5, o, &m), PMC_STATUS_OK);
    CHECK(pmc_mesh_recut_polygons(m) > 0);
    pmc_mesh_free(m);
    pmc_options_free(o);
}

/* A cell of the EPI scan where the surface folds through a neck at a face's
 * saddle: refinement stalls there, so the cell is meshed again on
 * sub-cells, and the count says so (0 for NULL and with refinement off).
 * Values x fastest, less the isovalue. */
static void test_cells_on_subcells(void) {
    static double data[8] = {-7.102, 20.898, -106.102, -87.102,
                             33.898, -77.102, -49.102, 161.898};
    pmc_volume v;
    pmc_options *o = pmc_options_new();
    pmc_mesh *m = NULL;
    cube_volume(&v, data, 2);
    CHECK(pmc_mesh_cells_on_subcells(NULL) == 0);
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.0), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 0.0, o, &m), PMC_STATUS_OK);
    CHECK(pmc_mesh_cells_on_subcells(m) == 0);
    pmc_mesh_free(m);
    m = NULL;
    CHECK_STATUS(pmc_options_set_epsilon(o, 0.01), PMC_STATUS_OK);
    CHECK_STATUS(pmc_options_set_max_level(o, 5), PMC_STATUS_OK);
    CHECK_STATUS(pmc_extract(&v, 0.0, o, &m), PMC_STATUS_OK);
    CHECK(pmc_mesh_cells_on_subcells(m) == 1);
    pmc_mesh_free(m);
    pmc_options_free(o);
}

int main(void) {
    test_layout();
    test_sphere();
    test_take_triangles();
    test_scalar_types();
    test_strides();
    test_pieces();
    test_options_effects();
    test_nonfinite_samples();
    test_cells_refined_on_faces_only();
    test_recut_polygons();
    test_cells_on_subcells();
    return test_finish("test_extract");
}

/*
 * Shared helpers of the C API tests: a tiny check framework, volume
 * builders and mesh invariants. Header-only (static functions).
 */
#ifndef PMC_TEST_COMMON_H
#define PMC_TEST_COMMON_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "precisemc.h"

static long g_checks_passed = 0;
static long g_checks_failed = 0;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (cond) {                                                                  \
            g_checks_passed++;                                                       \
        } else {                                                                     \
            g_checks_failed++;                                                       \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                            \
    } while (0)

/* Checks that `expr` returns status `want`; prints the last error otherwise. */
#define CHECK_STATUS(expr, want)                                                       \
    do {                                                                               \
        pmc_status got_ = (expr);                                                      \
        if (got_ == (pmc_status)(want)) {                                              \
            g_checks_passed++;                                                         \
        } else {                                                                       \
            char msg_[512];                                                            \
            pmc_last_error_message(msg_, sizeof msg_);                                 \
            g_checks_failed++;                                                         \
            fprintf(stderr, "%s:%d: %s returned %u (%s), expected %s; last error: %s\n", \
                    __FILE__, __LINE__, #expr, (unsigned)got_, pmc_status_string(got_),  \
                    #want, msg_);                                                      \
        }                                                                              \
    } while (0)

/* Prints the summary of this program; returns its exit code. */
static inline int test_finish(const char *name) {
    printf("%s: %ld checks ok, %ld checks failed\n", name, g_checks_passed, g_checks_failed);
    return g_checks_failed == 0 && g_checks_passed > 0 ? 0 : 1;
}

/* Reproducible random numbers (xorshift64*). */
static uint64_t g_rng = 0x9E3779B97F4A7C15ull;
static inline uint64_t rng_next(void) {
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    return g_rng * 0x2545F4914F6CDD1Dull;
}
/* Uniform in [0, n). */
static inline uint64_t rng_below(uint64_t n) { return n ? rng_next() % n : 0; }
/* Uniform in [0, 1). */
static inline double rng_unit(void) { return (double)(rng_next() >> 11) / 9007199254740992.0; }

/* Size in bytes of one element of a scalar type. */
static inline size_t scalar_size(pmc_scalar_type t) {
    static const size_t sizes[10] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
    return t < 10 ? sizes[t] : 0;
}

/* Stores `v` (already in range) as element `i` of a buffer of type `t`. */
static inline void store(void *buf, pmc_scalar_type t, size_t i, double v) {
    switch (t) {
    case PMC_SCALAR_TYPE_I8: ((int8_t *)buf)[i] = (int8_t)v; break;
    case PMC_SCALAR_TYPE_U8: ((uint8_t *)buf)[i] = (uint8_t)v; break;
    case PMC_SCALAR_TYPE_I16: ((int16_t *)buf)[i] = (int16_t)v; break;
    case PMC_SCALAR_TYPE_U16: ((uint16_t *)buf)[i] = (uint16_t)v; break;
    case PMC_SCALAR_TYPE_I32: ((int32_t *)buf)[i] = (int32_t)v; break;
    case PMC_SCALAR_TYPE_U32: ((uint32_t *)buf)[i] = (uint32_t)v; break;
    case PMC_SCALAR_TYPE_I64: ((int64_t *)buf)[i] = (int64_t)v; break;
    case PMC_SCALAR_TYPE_U64: ((uint64_t *)buf)[i] = (uint64_t)v; break;
    case PMC_SCALAR_TYPE_F32: ((float *)buf)[i] = (float)v; break;
    case PMC_SCALAR_TYPE_F64: ((double *)buf)[i] = v; break;
    default: break;
    }
}

/* A contiguous volume of `n^3` samples of type `t` holding
 * round(scale * distance to the centre); the caller frees `v->data`. */
static inline pmc_volume make_sphere(uint64_t n, pmc_scalar_type t, double scale) {
    pmc_volume v;
    uint64_t i, j, k;
    double c = 0.5 * (double)(n - 1);
    void *buf = malloc((size_t)(n * n * n) * scalar_size(t));
    memset(&v, 0, sizeof v);
    v.struct_size = sizeof v;
    for (k = 0; k < n; k++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) {
                double x = (double)i - c, y = (double)j - c, z = (double)k - c;
                double d = sqrt(x * x + y * y + z * z) * scale;
                if (t != PMC_SCALAR_TYPE_F32 && t != PMC_SCALAR_TYPE_F64) d = floor(d + 0.5);
                store(buf, t, (size_t)((k * n + j) * n + i), d);
            }
    v.data = buf;
    v.len = n * n * n;
    v.scalar_type = t;
    v.dims[0] = v.dims[1] = v.dims[2] = n;
    v.spacing[0] = v.spacing[1] = v.spacing[2] = 1.0;
    return v;
}

static inline int cmp_u64_pair(const void *a, const void *b) {
    const uint64_t *x = (const uint64_t *)a, *y = (const uint64_t *)b;
    if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
    if (x[1] != y[1]) return x[1] < y[1] ? -1 : 1;
    return 0;
}

/* Checks the invariants every mesh satisfies: consistent counts, finite
 * points, indices in range, levels <= max level, unit normals, points equal
 * to origin + spacing * index points. Returns 1 if all hold. */
static inline int check_mesh(const pmc_mesh *m, const pmc_volume *v, uint32_t max_level) {
    uint64_t np = pmc_mesh_point_count(m), nt = pmc_mesh_triangle_count(m), i;
    const double *p = pmc_mesh_points(m);
    const double *ip = pmc_mesh_index_points(m);
    const int64_t *t = pmc_mesh_triangles(m);
    const uint8_t *lv = pmc_mesh_triangle_levels(m);
    const float *nrm = pmc_mesh_normals(m);
    pmc_stats s = {.struct_size = sizeof(pmc_stats)};
    int ok = 1;
    if (pmc_mesh_stats(m, &s) != PMC_STATUS_OK) return 0;
    ok &= s.output_points == np && s.output_triangles == nt;
    ok &= (np == 0) == (p == NULL) && (np == 0) == (ip == NULL);
    ok &= (nt == 0) == (t == NULL) && (nt == 0) == (lv == NULL);
    ok &= s.max_level <= max_level && s.effective_max_level <= max_level;
    if (!ok) fprintf(stderr, "check_mesh: counts, arrays or stats levels wrong\n");
    for (i = 0; ok && i < 3 * np; i++) {
        int a = (int)(i % 3);
        double expect = v->origin[a] + v->spacing[a] * ip[i];
        ok &= isfinite(p[i]) && isfinite(ip[i]);
        ok &= fabs(p[i] - expect) <= 1e-9 * (1.0 + fabs(expect));
        if (!ok) fprintf(stderr, "check_mesh: point %g != origin + spacing * %g\n", p[i], ip[i]);
    }
    for (i = 0; ok && i < 3 * nt; i++) ok &= t[i] >= 0 && (uint64_t)t[i] < np;
    if (!ok) fprintf(stderr, "check_mesh: triangle index out of range\n");
    for (i = 0; ok && i < nt; i++) ok &= lv[i] <= s.max_level;
    if (!ok) fprintf(stderr, "check_mesh: triangle level above max level\n");
    if (nrm != NULL)
        for (i = 0; ok && i < np; i++) {
            double l = sqrt((double)nrm[3 * i] * nrm[3 * i] + (double)nrm[3 * i + 1] * nrm[3 * i + 1] +
                            (double)nrm[3 * i + 2] * nrm[3 * i + 2]);
            /* (0, 0, 0) where the gradient vanishes or is not finite. */
            ok &= fabs(l - 1.0) < 1e-3 || l == 0.0;
            if (!ok) fprintf(stderr, "check_mesh: normal %llu has length %g\n", (unsigned long long)i, l);
        }
    if (!ok) fprintf(stderr, "check_mesh: invariant violated (%llu points, %llu triangles)\n",
                     (unsigned long long)np, (unsigned long long)nt);
    return ok;
}

/* Whether the mesh is closed and consistently oriented: every directed
 * edge appears exactly once and its reverse exists, so every undirected
 * edge is used by exactly two triangles. */
static inline int mesh_is_closed(const pmc_mesh *m) {
    uint64_t nt = pmc_mesh_triangle_count(m), i, e = 3 * nt;
    const int64_t *t = pmc_mesh_triangles(m);
    uint64_t *dir, *und;
    int ok = nt > 0;
    if (!ok) return 0;
    dir = (uint64_t *)malloc((size_t)e * 2 * sizeof *dir);
    und = (uint64_t *)malloc((size_t)e * 2 * sizeof *und);
    for (i = 0; i < nt; i++) {
        int c;
        for (c = 0; c < 3; c++) {
            uint64_t a = (uint64_t)t[3 * i + c], b = (uint64_t)t[3 * i + (c + 1) % 3];
            uint64_t *d = dir + 2 * (3 * i + c), *u = und + 2 * (3 * i + c);
            d[0] = a;
            d[1] = b;
            u[0] = a < b ? a : b;
            u[1] = a < b ? b : a;
            if (a == b) ok = 0;
        }
    }
    qsort(dir, (size_t)e, 2 * sizeof *dir, cmp_u64_pair);
    qsort(und, (size_t)e, 2 * sizeof *und, cmp_u64_pair);
    for (i = 0; ok && i < e; i += 2) {
        /* Undirected: exactly pairs. */
        ok &= i + 1 < e && cmp_u64_pair(und + 2 * i, und + 2 * (i + 1)) == 0;
        ok &= i + 2 >= e || cmp_u64_pair(und + 2 * i, und + 2 * (i + 2)) != 0;
    }
    for (i = 0; ok && i + 1 < e; i++) ok &= cmp_u64_pair(dir + 2 * i, dir + 2 * (i + 1)) != 0;
    free(dir);
    free(und);
    return ok;
}

/* Signed volume enclosed by the mesh (divergence theorem). */
static inline double mesh_signed_volume(const pmc_mesh *m) {
    uint64_t nt = pmc_mesh_triangle_count(m), i;
    const int64_t *t = pmc_mesh_triangles(m);
    const double *p = pmc_mesh_points(m);
    double vol = 0.0;
    for (i = 0; i < nt; i++) {
        const double *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
        vol += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
               a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return vol / 6.0;
}

/* Whether two meshes are identical (counts, bits of points, triangles). */
static inline int meshes_equal(const pmc_mesh *a, const pmc_mesh *b) {
    uint64_t np = pmc_mesh_point_count(a), nt = pmc_mesh_triangle_count(a);
    if (np != pmc_mesh_point_count(b) || nt != pmc_mesh_triangle_count(b)) return 0;
    if (np && memcmp(pmc_mesh_points(a), pmc_mesh_points(b), (size_t)np * 3 * sizeof(double)))
        return 0;
    if (nt && memcmp(pmc_mesh_triangles(a), pmc_mesh_triangles(b), (size_t)nt * 3 * sizeof(int64_t)))
        return 0;
    return 1;
}

/* A progress callback's log: its calls, the last fraction, whether the
 * fractions never decreased; the callback asks to stop on call `stop_at`
 * (1-based; 0 = never). */
typedef struct {
    long calls;
    long stop_at;
    double last;
    int monotone;
} progress_counter;

static inline int count_progress(void *user_data, double fraction) {
    progress_counter *c = (progress_counter *)user_data;
    if (c->calls > 0 && fraction < c->last) c->monotone = 0;
    c->last = fraction;
    c->calls++;
    return c->stop_at != 0 && c->calls >= c->stop_at;
}

/* Number of test iterations: PMC_TEST_ITERATIONS or `dflt`. */
static inline long test_iterations(long dflt) {
    const char *s = getenv("PMC_TEST_ITERATIONS");
    long n = s ? strtol(s, NULL, 10) : 0;
    return n > 0 ? n : dflt;
}

#endif /* PMC_TEST_COMMON_H */

// The header from C++11: extern "C" linkage, enums with a fixed underlying
// type, a small extraction.
#include "precisemc.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

static_assert(sizeof(pmc_status) == 4, "pmc_status is 32 bits");
static_assert(sizeof(pmc_scalar_type) == 4, "pmc_scalar_type is 32 bits");
static_assert(PMC_STATUS_INTERNAL_ERROR == 5, "stable value");
static_assert(PMC_NORMALS_CENTRAL_DIFFERENCE == 2, "stable value");

static int failures = 0, passes = 0;
#define CHECK(c) ((c) ? (void)++passes : (void)(++failures, std::fprintf(stderr, "%s:%d: %s\n", __FILE__, __LINE__, #c)))

extern "C" int cxx_progress(void *user_data, double fraction) {
    *static_cast<double *>(user_data) = fraction;
    return 0;
}

int main() {
    const int n = 12;
    std::vector<double> data;
    for (int k = 0; k < n; k++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) data.push_back(std::sqrt(double((i - 5) * (i - 5) + (j - 6) * (j - 6) + (k - 5) * (k - 5))));
    pmc_volume v;
    std::memset(&v, 0, sizeof v);
    v.struct_size = sizeof v;
    v.data = data.data();
    v.len = data.size();
    v.scalar_type = PMC_SCALAR_TYPE_F64;
    v.dims[0] = v.dims[1] = v.dims[2] = n;
    v.spacing[0] = v.spacing[1] = v.spacing[2] = 1.0;

    pmc_options *o = pmc_options_new();
    double last = -1.0;
    CHECK(pmc_options_set_rule(o, PMC_RULE_B) == PMC_STATUS_OK);
    CHECK(pmc_options_set_normals(o, PMC_NORMALS_GRADIENT) == PMC_STATUS_OK);
    CHECK(pmc_options_set_progress(o, cxx_progress, &last) == PMC_STATUS_OK);
    // Unknown enumerators need a cast in C++ and are rejected.
    CHECK(pmc_options_set_topology(o, static_cast<pmc_topology>(7)) == PMC_STATUS_INVALID_ARGUMENT);
    CHECK(std::strcmp(pmc_status_string(static_cast<pmc_status>(99)), "unknown status") == 0);

    pmc_mesh *m = nullptr;
    CHECK(pmc_extract(&v, 4.0, o, &m) == PMC_STATUS_OK);
    CHECK(m != nullptr);
    CHECK(pmc_mesh_triangle_count(m) > 0);
    CHECK(pmc_mesh_normals(m) != nullptr);
    CHECK(last == 1.0);
    pmc_stats s;
    s.struct_size = sizeof s;
    CHECK(pmc_mesh_stats(m, &s) == PMC_STATUS_OK && s.output_points == pmc_mesh_point_count(m));
    pmc_mesh_free(m);
    pmc_options_free(o);
    CHECK(std::strcmp(pmc_version_string(), PMC_VERSION_STRING) == 0);
    std::printf("test_cxx: %d checks ok, %d checks failed\n", passes, failures);
    return failures == 0 ? 0 : 1;
}

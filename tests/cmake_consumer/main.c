/* Consumer of the installed PreciseMC package: version check and a small
 * extraction. Exit status 0 on success. */
#include <stdio.h>
#include <string.h>

#include <precisemc.h>

int main(void) {
    enum { N = 10 };
    static float data[N * N * N];
    pmc_volume v;
    pmc_mesh *mesh = NULL;
    pmc_status st;
    int i, j, k;
    if (strcmp(pmc_version_string(), PMC_VERSION_STRING) != 0) {
        fprintf(stderr, "header %s, library %s\n", PMC_VERSION_STRING, pmc_version_string());
        return 1;
    }
    for (k = 0; k < N; k++)
        for (j = 0; j < N; j++)
            for (i = 0; i < N; i++)
                /* Squared distance to the centre (no libm needed here). */
                data[(k * N + j) * N + i] =
                    (float)((i - 4.5) * (i - 4.5) + (j - 4.5) * (j - 4.5) + (k - 4.5) * (k - 4.5));
    memset(&v, 0, sizeof v);
    v.struct_size = sizeof v; /* first: see pmc_volume */
    v.data = data;
    v.len = N * N * N;
    v.scalar_type = PMC_SCALAR_TYPE_F32;
    v.dims[0] = v.dims[1] = v.dims[2] = N;
    v.spacing[0] = v.spacing[1] = v.spacing[2] = 1.0;
    st = pmc_extract(&v, 9.0, NULL, &mesh);
    if (st != PMC_STATUS_OK || pmc_mesh_triangle_count(mesh) == 0) {
        char msg[256];
        pmc_last_error_message(msg, sizeof msg);
        fprintf(stderr, "extraction failed: %s: %s\n", pmc_status_string(st), msg);
        return 1;
    }
    printf("precisemc %s: %llu points, %llu triangles\n", pmc_version_string(),
           (unsigned long long)pmc_mesh_point_count(mesh),
           (unsigned long long)pmc_mesh_triangle_count(mesh));
    pmc_mesh_free(mesh);
    return 0;
}

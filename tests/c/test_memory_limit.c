/*
 * Running out of memory while refining is reported, not fatal: under an
 * address-space limit (setrlimit RLIMIT_AS, in a forked child per limit),
 * an extraction whose refined output outgrows the limit returns
 * PMC_STATUS_OUT_OF_MEMORY with a NULL mesh and a message, and the process
 * goes on. (A slab's buffers grew by plain pushes while a patch was
 * emitted: Rust aborts the process on such a failure.) One thread, so that
 * the refinement's own buffers are what meets the limit. Not run under
 * sanitizers or valgrind, which reserve address space of their own.
 */
#define _DEFAULT_SOURCE
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common.h"

/* The process's address space in MiB (VmSize), or -1. */
static long vm_size_mib(void) {
    FILE* f = fopen("/proc/self/status", "r");
    char line[256];
    long kib = -1;
    if (!f) return -1;
    while (fgets(line, sizeof line, f)) {
        if (sscanf(line, "VmSize: %ld kB", &kib) == 1) break;
    }
    fclose(f);
    return kib < 0 ? -1 : kib / 1024;
}

/* In the child: extract under `limit_mib` more MiB of address space. Exit
 * status 0 when the extraction failed cleanly with OUT_OF_MEMORY. */
static int child(const float* data, uint64_t n, uint64_t side, long limit_mib) {
    pmc_volume v;
    pmc_options* o = pmc_options_new();
    pmc_mesh* mesh = (pmc_mesh*)1;
    char msg[256] = "";
    struct rlimit rl;
    long base = vm_size_mib();
    pmc_status st;
    memset(&v, 0, sizeof v);
    v.data = data;
    v.len = n;
    v.scalar_type = PMC_SCALAR_TYPE_F32;
    v.dims[0] = v.dims[1] = v.dims[2] = side;
    v.spacing[0] = v.spacing[1] = v.spacing[2] = 1.0;
    if (!o || base < 0) return 2;
    pmc_options_set_threads(o, 1);
    pmc_options_set_epsilon(o, 0.0001);
    rl.rlim_cur = rl.rlim_max = (rlim_t)(base + limit_mib) << 20;
    if (setrlimit(RLIMIT_AS, &rl) != 0) return 3;
    st = pmc_extract(&v, 0.5, o, &mesh);
    pmc_last_error_message(msg, sizeof msg);
    printf("limit +%ld MiB: %s, mesh %s, \"%s\"\n", limit_mib, pmc_status_string(st),
           mesh ? "set" : "NULL", msg);
    fflush(stdout);
    pmc_options_free(o);
    return st == PMC_STATUS_OUT_OF_MEMORY && mesh == NULL && strstr(msg, "out of memory") ? 0 : 4;
}

int main(void) {
    /* Noise: refined at epsilon 1e-4 it needs gigabytes. */
    const uint64_t side = 160, n = side * side * side;
    const long limits[] = {96, 160, 256};
    float* data = (float*)malloc(n * sizeof(float));
    uint64_t s = 88172645463325252ull;
    size_t i, k;
    if (!data) return 1;
    for (i = 0; i < n; i++) {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        data[i] = (float)(s % 1000) / 1000.0f;
    }
    for (k = 0; k < sizeof limits / sizeof limits[0]; k++) {
        int status = 0;
        pid_t pid;
        fflush(stdout);
        pid = fork();
        if (pid == 0) _exit(child(data, n, side, limits[k]));
        CHECK(pid > 0);
        if (pid <= 0) break;
        CHECK(waitpid(pid, &status, 0) == pid);
        if (WIFSIGNALED(status)) {
            fprintf(stderr, "limit +%ld MiB: killed by signal %d\n", limits[k], WTERMSIG(status));
        } else if (WEXITSTATUS(status) != 0) {
            fprintf(stderr, "limit +%ld MiB: child status %d\n", limits[k], WEXITSTATUS(status));
        }
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    free(data);
    return test_finish("test_memory_limit");
}

/*
 * Unloading the library, and forking, after extractions on several
 * threads. The helper threads the library keeps between calls must never
 * run its code after dlclose has unmapped it: the library stops and joins
 * them when it is unloaded (or glibc keeps it mapped while they live).
 * Extracts with 2 threads (plain and refined), forks a child that
 * extracts again (it has none of the parent's helper threads: it must
 * start its own, not wait for them), dlcloses, checks that either the
 * library is still mapped or none of its helper threads is left, waits
 * past the helpers' idle time (a helper left in unmapped code would crash
 * when its wait ends), then loads it again and does it all again.
 * Last, forks once more with the library unloaded: the fork handlers
 * the library registers (it takes its locks around fork) must have gone
 * with it, or this fork would call into unmapped code.
 * First of all, before any helper thread keeps the library mapped: loads
 * it, extracts on the calling thread, forks, unloads it, and checks that
 * it is unmapped (forking once must not keep it loaded: it did while the
 * fork handlers kept their locks' guards in a thread-local that needs a
 * destructor) and that a fork then does not call into it.
 *
 * Usage: test_unload PATH_OF_libprecisemc.so
 */
#define _DEFAULT_SOURCE /* realpath, dirent, fork under -std=c99 */
#include <dirent.h>
#include <dlfcn.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common.h"

typedef pmc_status (*extract_fn)(const pmc_volume *, double, const pmc_options *, pmc_mesh **);
typedef pmc_options *(*options_new_fn)(void);
typedef void (*options_free_fn)(pmc_options *);
typedef pmc_status (*set_u32_fn)(pmc_options *, uint32_t);
typedef pmc_status (*set_f64_fn)(pmc_options *, double);
typedef pmc_status (*mesh_stats_fn)(const pmc_mesh *, pmc_stats *);
typedef void (*mesh_free_fn)(pmc_mesh *);

/* Threads of this process whose name starts with "precisemc". */
static int helper_threads(void) {
    int n = 0;
    DIR *d = opendir("/proc/self/task");
    struct dirent *e;
    if (!d) return -1;
    while ((e = readdir(d)) != NULL) {
        char path[300], name[64] = {0};
        FILE *f;
        if (e->d_name[0] == '.') continue;
        snprintf(path, sizeof path, "/proc/self/task/%s/comm", e->d_name);
        f = fopen(path, "r");
        if (!f) continue;
        if (fgets(name, sizeof name, f) && strncmp(name, "precisemc", 9) == 0) n++;
        fclose(f);
    }
    closedir(d);
    return n;
}

/* Whether a mapping of the file `path` is in this process. */
static int mapped(const char *path) {
    char line[4096];
    char real[4096];
    int found = 0;
    FILE *f = fopen("/proc/self/maps", "r");
    if (!f || !realpath(path, real)) {
        if (f) fclose(f);
        return -1;
    }
    while (fgets(line, sizeof line, f))
        if (strstr(line, real)) found = 1;
    fclose(f);
    return found;
}

/* Refined extractions on 2 threads in a child process; whether it exited
 * with 0 (all succeeded) within 60 s. */
static int child_extracts(extract_fn extract, options_new_fn options_new,
                          options_free_fn options_free, set_u32_fn set_threads,
                          mesh_free_fn mesh_free, const pmc_volume *v) {
    pid_t pid = fork();
    if (pid < 0) return 0;
    if (pid == 0) {
        int ok = 1;
        for (int i = 0; i < 3; i++) {
            pmc_options *o = options_new();
            pmc_mesh *m = NULL;
            ok &= set_threads(o, 2) == PMC_STATUS_OK;
            ok &= extract(v, 20.5, o, &m) == PMC_STATUS_OK && m != NULL;
            if (m) mesh_free(m);
            options_free(o);
        }
        _exit(ok ? 0 : 1);
    }
    for (int waited = 0; waited < 6000; waited++) {
        int status;
        if (waitpid(pid, &status, WNOHANG) == pid)
            return WIFEXITED(status) && WEXITSTATUS(status) == 0;
        usleep(10000);
    }
    fprintf(stderr, "the forked child hangs\n");
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    return 0;
}

/* The library's entry points these tests call, looked up after dlopen. */
typedef struct {
    void *lib;
    extract_fn extract;
    options_new_fn options_new;
    options_free_fn options_free;
    set_u32_fn set_threads;
    set_f64_fn set_epsilon;
    mesh_stats_fn mesh_stats;
    mesh_free_fn mesh_free;
} api;

/* Loads the library at `path`; whether it and every entry point were
 * found (a is zeroed first; a->lib is set whenever dlopen succeeded). */
static int load_api(const char *path, api *a) {
    memset(a, 0, sizeof *a);
    a->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    CHECK(a->lib != NULL);
    if (!a->lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 0;
    }
    a->extract = (extract_fn)(uintptr_t)dlsym(a->lib, "pmc_extract");
    a->options_new = (options_new_fn)(uintptr_t)dlsym(a->lib, "pmc_options_new");
    a->options_free = (options_free_fn)(uintptr_t)dlsym(a->lib, "pmc_options_free");
    a->set_threads = (set_u32_fn)(uintptr_t)dlsym(a->lib, "pmc_options_set_threads");
    a->set_epsilon = (set_f64_fn)(uintptr_t)dlsym(a->lib, "pmc_options_set_epsilon");
    a->mesh_stats = (mesh_stats_fn)(uintptr_t)dlsym(a->lib, "pmc_mesh_stats");
    a->mesh_free = (mesh_free_fn)(uintptr_t)dlsym(a->lib, "pmc_mesh_free");
    int all = a->extract && a->options_new && a->options_free && a->set_threads &&
              a->set_epsilon && a->mesh_stats && a->mesh_free;
    CHECK(all);
    return all;
}

/* Loads the library, extracts twice on 2 threads, forks a child that
 * extracts, unloads the library. */
static void round_trip(const char *path, const pmc_volume *v) {
    api a;
    int ok = load_api(path, &a);
    if (!a.lib) return;
    if (ok) {
        for (int refined = 0; refined < 2; refined++) {
            pmc_options *o = a.options_new();
            pmc_mesh *m = NULL;
            pmc_stats st = {.struct_size = sizeof(pmc_stats)};
            CHECK(a.set_threads(o, 2) == PMC_STATUS_OK);
            /* Plain Marching Cubes, or refinement (epsilon 0.001). */
            CHECK(a.set_epsilon(o, refined ? 0.001 : 0.0) == PMC_STATUS_OK);
            CHECK(a.extract(v, 20.5, o, &m) == PMC_STATUS_OK);
            CHECK(m != NULL);
            if (m) {
                CHECK(a.mesh_stats(m, &st) == PMC_STATUS_OK);
                CHECK(st.output_triangles > 1000);
                a.mesh_free(m);
            }
            a.options_free(o);
        }
    }
    /* The extractions above ran on helper threads (2 threads asked). */
    CHECK(helper_threads() >= 1);
    if (ok)
        CHECK(child_extracts(a.extract, a.options_new, a.options_free, a.set_threads,
                             a.mesh_free, v));
    CHECK(dlclose(a.lib) == 0);
    int still = mapped(path), helpers = helper_threads();
    printf("after dlclose: library %s, %d helper thread(s)\n",
           still ? "still mapped" : "unmapped", helpers);
    CHECK(still >= 0 && helpers >= 0);
    /* Unmapped code must have no thread left in it. */
    CHECK(still || helpers == 0);
    /* Past the helpers' idle time (1 s): a helper in unmapped code would
     * crash now; the idle ones have returned. */
    sleep(2);
    CHECK(helper_threads() == 0);
}

/* Forks a child that exits at once; whether both sides came through. */
static int plain_fork(void) {
    pid_t pid = fork();
    if (pid < 0) return 0;
    if (pid == 0) _exit(0);
    int status;
    if (waitpid(pid, &status, 0) != pid) return 0;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

/* Loads the library, extracts on the calling thread alone (no helper
 * thread: none keeps the library mapped), forks, unloads it; then it must
 * be unmapped, and a fork must not call into it. */
static void fork_then_unload(const char *path, const pmc_volume *v) {
    api a;
    int ok = load_api(path, &a);
    if (!a.lib) return;
    if (ok) {
        pmc_options *o = a.options_new();
        pmc_mesh *m = NULL;
        CHECK(a.set_threads(o, 1) == PMC_STATUS_OK);
        CHECK(a.extract(v, 20.5, o, &m) == PMC_STATUS_OK && m != NULL);
        if (m) a.mesh_free(m);
        a.options_free(o);
    }
    CHECK(helper_threads() == 0);
    CHECK(plain_fork());
    CHECK(dlclose(a.lib) == 0);
    int still = mapped(path);
    printf("after fork and dlclose: library %s\n", still ? "still mapped" : "unmapped");
    CHECK(still == 0);
    /* The library's fork handlers went with it (or this crashes). */
    CHECK(plain_fork());
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s PATH_OF_libprecisemc.so\n", argv[0]);
        return 2;
    }
    /* 96^3 cells: plain Marching Cubes on 2 threads starts a helper. */
    pmc_volume v = make_sphere(97, PMC_SCALAR_TYPE_F32, 1.0);
    fork_then_unload(argv[1], &v);
    round_trip(argv[1], &v);
    round_trip(argv[1], &v);
    CHECK(plain_fork());
    free((void *)v.data);
    return test_finish("test_unload");
}

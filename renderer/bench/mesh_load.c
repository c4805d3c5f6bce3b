/* mesh_load.c: what loading a scene with a large mesh costs, by stage.

   usage: mesh_load CONFIG [--rounds N] [--set KEY=VALUE]...

   Stages, each timed N times (default 3), median reported, wall clock and
   CPU time of the process (CLOCK_PROCESS_CPUTIME_ID: Embree builds its BVH
   on several threads):
     config_load      the YAML, the mesh files (assimp), transforms, checks
     watertight       watertight_stitch over every shape's faces (the
                      T-junction stitching scene_create runs first)
     scene_create     the whole scene build: stitching, Embree geometry and
                      BVH, lights and portals
   the digest of the stitched faces (FNV-1a of watertight_stitch's output,
   to check that a faster stitch computes the same), and the peak resident
   set size (getrusage ru_maxrss) after the first
   config_load and at the end. Prints one JSON object on stdout. */
#include <inttypes.h>
#include <stdint.h>
#include <sys/resource.h>

#include "bench_util.h"
#include "config/config.h"
#include "scene/scene.h"
#include "geometry/watertight.h"

static double process_cpu_s(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double peak_rss_mb(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
    return (double)ru.ru_maxrss / 1024.0; /* kilobytes on Linux */
}

static uint64_t fnv1a64(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

struct stage {
    double wall[64], cpu[64];
};

static void print_stage(const char *name, struct stage *s, int rounds, const char *sep)
{
    printf("  \"%s\": {\"wall_s\": %.6f, \"cpu_s\": %.6f}%s\n", name, bench_median(s->wall, rounds),
           bench_median(s->cpu, rounds), sep);
}

int main(int argc, char **argv)
{
    const char *path = NULL;
    int rounds = 3;
    struct bench_overrides ov = { 0 };
    for (int i = 1; i < argc; ++i) {
        if (bench_take_set(&ov, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--rounds") && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (!path && argv[i][0] != '-') path = argv[i];
        else {
            fprintf(stderr, "usage: %s CONFIG [--rounds N] [--set KEY=VALUE]...\n", argv[0]);
            return 2;
        }
    }
    if (!path || rounds < 1 || rounds > 64) {
        fprintf(stderr, "usage: %s CONFIG [--rounds N (1..64)] [--set KEY=VALUE]...\n", argv[0]);
        return 2;
    }
    struct stage load, stitch, build;
    double rss_load = 0.0;
    int n_faces = 0, n_inserted = 0;
    uint64_t digest = 0;
    for (int r = 0; r < rounds; ++r) {
        struct config cfg;
        struct error err = { "" };
        double w0 = timing_now_s(), c0 = process_cpu_s();
        if (!config_load(path, ov.items, ov.n, &cfg, &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 2;
        }
        load.wall[r] = timing_now_s() - w0, load.cpu[r] = process_cpu_s() - c0;
        if (r == 0) rss_load = peak_rss_mb();

        struct watertight_face *faces;
        if (!scene_collect_faces(&cfg, &faces, &n_faces, &err)) {
            fprintf(stderr, "%s: %s\n", path, err.message);
            return 1;
        }
        struct watertight w;
        w0 = timing_now_s(), c0 = process_cpu_s();
        bool ok = watertight_stitch(faces, n_faces, &w, &err);
        stitch.wall[r] = timing_now_s() - w0, stitch.cpu[r] = process_cpu_s() - c0;
        free(faces);
        if (!ok) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        n_inserted = w.n_inserted;
        /* The stitched output's digest: equal before and after a change of
           watertight.c's speed, or the change altered what it computes. */
        digest = fnv1a64(14695981039346656037ull, w.first, sizeof *w.first * ((size_t)w.n_faces + 1));
        digest = fnv1a64(digest, w.tris, sizeof *w.tris * (size_t)w.n_triangles);
        watertight_free(&w);

        struct scene scene;
        w0 = timing_now_s(), c0 = process_cpu_s();
        ok = scene_create(&cfg, &scene, &err);
        build.wall[r] = timing_now_s() - w0, build.cpu[r] = process_cpu_s() - c0;
        if (!ok) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        scene_destroy(&scene);
        config_free(&cfg);
    }
    printf("{\n  \"config\": \"%s\",\n  \"rounds\": %d,\n  \"faces\": %d,\n  \"inserted\": %d,\n", path, rounds,
           n_faces, n_inserted);
    printf("  \"stitch_digest\": \"%016" PRIx64 "\",\n", digest);
    print_stage("config_load", &load, rounds, ",");
    print_stage("watertight", &stitch, rounds, ",");
    print_stage("scene_create", &build, rounds, ",");
    printf("  \"peak_rss_mb_after_load\": %.1f,\n  \"peak_rss_mb\": %.1f\n}\n", rss_load, peak_rss_mb());
    return 0;
}

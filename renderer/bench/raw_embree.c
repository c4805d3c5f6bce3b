/* raw_embree.c: the raw ray-tracing limit of a scene, the yardstick for the
   renderer's rays/s. The scene is loaded exactly as the renderer loads it
   (config_load + scene_create), then ray batches of the three kinds the
   renderer traces are precomputed and only tracing is timed:

     camera  closest hit, pinhole rays jittered in scan-line order;
     bounce  closest hit, cosine-distributed from the camera hit points;
     shadow  occlusion, from the hit points to uniform points on a light
             (only where the light faces the point and the point faces the
             light, as the renderer traces them);
     mix     the three interleaved per camera sample in the renderer's order
             (camera, shadow, bounce), i.e. the renderer's own ray mix.

   Three APIs are timed on the same batches: "wrapper" (scene_intersect /
   scene_occluded, the renderer's thin one-ray wrappers over rtcIntersect1 /
   rtcOccluded1: double->float conversion, normal normalisation), "embree"
   (rtcIntersect1 / rtcOccluded1 on prebuilt float rays: the floor of
   single-ray tracing) and "stream" (rtcIntersect1M / rtcOccluded1M over
   chunks of 1024 rays split by kind: what a wavefront renderer gets; the
   renderer traces a film row's camera, shadow and BSDF rays as streams),
   and "packet4", "packet8", "packet16" (rtcIntersect4/8/16 and
   rtcOccluded4/8/16 on the same chunks, each kind's rays W at a time in
   their order, the SoA copy timed: what a renderer tracing a row's rays as
   packets pays). Each (kind, api, threads) cell runs for a fixed time, repeated
   round-robin, and the median is reported as JSON on stdout. Last, the scene is rebuilt without RTC_SCENE_FLAG_ROBUST (which
   scene.c sets) and the mix is timed again, to show what the flag costs. */
#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <pthread.h>
#include <stdint.h>
#include <xmmintrin.h>

#include "bench_util.h"
#include "scene/camera.h"
#include "config/config.h"
#include "base/rng.h"
#include "scene/scene.h"

enum ray_kind { RAY_CAMERA, RAY_BOUNCE, RAY_SHADOW };
enum batch_id { BATCH_CAMERA, BATCH_BOUNCE, BATCH_SHADOW, BATCH_MIX, BATCH_COUNT };
static const char *const batch_names[BATCH_COUNT] = { "camera", "bounce", "shadow", "mix" };
enum api_id { API_WRAPPER, API_EMBREE, API_STREAM, API_PACKET4, API_PACKET8, API_PACKET16, API_COUNT };
static const char *const api_names[API_COUNT] = { "wrapper", "embree", "stream", "packet4", "packet8", "packet16" };

struct ray_rec {
    struct vec3 o, d;
    double tmax;
    int kind;
};

struct batch {
    int n, cap;
    struct ray_rec *rays;
    struct RTCRayHit *rh; /* the same rays in Embree's float layout */
};

static void batch_push(struct batch *b, struct vec3 o, struct vec3 d, double tmax, int kind)
{
    if (b->n == b->cap) {
        b->cap = b->cap ? 2 * b->cap : 4096;
        b->rays = realloc(b->rays, sizeof *b->rays * (size_t)b->cap);
        if (!b->rays) {
            fprintf(stderr, "raw_embree: out of memory\n");
            exit(1);
        }
    }
    b->rays[b->n++] = (struct ray_rec){ o, d, tmax, kind };
}

static void batch_finish(struct batch *b)
{
    void *mem = NULL;
    if (posix_memalign(&mem, 64, sizeof *b->rh * (size_t)(b->n > 0 ? b->n : 1)) != 0) mem = NULL;
    b->rh = mem;
    if (!b->rh) {
        fprintf(stderr, "raw_embree: out of memory\n");
        exit(1);
    }
    for (int i = 0; i < b->n; ++i) {
        const struct ray_rec *r = &b->rays[i];
        struct RTCRayHit *x = &b->rh[i];
        memset(x, 0, sizeof *x);
        x->ray.org_x = (float)r->o.x, x->ray.org_y = (float)r->o.y, x->ray.org_z = (float)r->o.z;
        x->ray.dir_x = (float)r->d.x, x->ray.dir_y = (float)r->d.y, x->ray.dir_z = (float)r->d.z;
        x->ray.tnear = 0.0f;
        x->ray.tfar = r->tmax < 3.0e38 ? (float)r->tmax : INFINITY;
        x->ray.mask = ~0u;
        x->hit.geomID = RTC_INVALID_GEOMETRY_ID;
        x->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
}

/* Uniform point on a convex polygon: a fan triangle by area, then uniform in it. */
static struct vec3 polygon_uniform_point(const struct polygon *poly, double u0, double u1, double u2)
{
    double total = 0.0, areas[POLYGON_MAX];
    for (int k = 0; k + 2 < poly->n; ++k) {
        struct vec3 e1 = vec3_sub(poly->v[k + 1], poly->v[0]), e2 = vec3_sub(poly->v[k + 2], poly->v[0]);
        areas[k] = 0.5 * vec3_length(vec3_cross(e1, e2));
        total += areas[k];
    }
    int k = 0;
    double x = u0 * total;
    while (k + 3 < poly->n && x >= areas[k]) x -= areas[k++];
    double su = sqrt(u1);
    double b0 = 1.0 - su, b1 = u2 * su;
    struct vec3 a = poly->v[0], b = poly->v[k + 1], c = poly->v[k + 2];
    return vec3_add(vec3_add(vec3_scale(a, b0), vec3_scale(b, b1)), vec3_scale(c, 1.0 - b0 - b1));
}

/* Builds the four batches from `spp` jittered camera samples per pixel. */
static void build_batches(const struct config *cfg, const struct scene *sc, int spp, struct batch b[BATCH_COUNT])
{
    struct camera cam;
    camera_init(&cam, &cfg->camera, cfg->width, cfg->height);
    for (int s = 0; s < spp; ++s)
        for (int y = 0; y < cfg->height; ++y)
            for (int x = 0; x < cfg->width; ++x) {
                struct rng rng;
                rng_seed(&rng, 12345, (uint64_t)y * (uint64_t)cfg->width + (uint64_t)x, (uint64_t)s);
                struct vec3 d = camera_ray(&cam, x + rng_uniform(&rng), y + rng_uniform(&rng));
                batch_push(&b[BATCH_CAMERA], cam.origin, d, INFINITY, RAY_CAMERA);
                batch_push(&b[BATCH_MIX], cam.origin, d, INFINITY, RAY_CAMERA);
                struct hit h;
                if (!scene_intersect(sc, cam.origin, d, INFINITY, &h) || h.light >= 0) continue;
                struct vec3 wo = vec3_neg(d);
                struct vec3 n = vec3_dot(h.ng, wo) > 0.0 ? h.ng : vec3_neg(h.ng);
                struct frame fr = frame_from_normal(n);

                if (sc->n_lights > 0) {
                    int li = (int)(rng_uniform(&rng) * sc->n_lights);
                    if (li >= sc->n_lights) li = sc->n_lights - 1;
                    const struct light *l = &sc->lights[li];
                    struct vec3 yl = polygon_uniform_point(&l->target.polygon, rng_uniform(&rng), rng_uniform(&rng),
                                                           rng_uniform(&rng));
                    struct vec3 to = vec3_sub(yl, h.p);
                    double dist = vec3_length(to);
                    struct vec3 wi = vec3_scale(to, 1.0 / dist);
                    bool facing = l->two_sided || vec3_dot(wi, l->target.normal) < 0.0;
                    if (dist > 0.0 && facing && vec3_dot(wi, n) > 0.0) {
                        struct vec3 o = scene_offset_origin(sc, h.p, n, wi);
                        double len = vec3_length(vec3_sub(yl, o));
                        double tmax = len * (1.0 - 1e-4) /* shadow rays stop short of the light */;
                        batch_push(&b[BATCH_SHADOW], o, wi, tmax, RAY_SHADOW);
                        batch_push(&b[BATCH_MIX], o, wi, tmax, RAY_SHADOW);
                    }
                }
                double u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
                double r = sqrt(u1), phi = 2.0 * M_PI * u2;
                struct vec3 wl = vec3_make(r * cos(phi), r * sin(phi), sqrt(fmax(0.0, 1.0 - u1)));
                struct vec3 wi = vec3_normalize(frame_to_world(&fr, wl));
                struct vec3 o = scene_offset_origin(sc, h.p, n, wi);
                batch_push(&b[BATCH_BOUNCE], o, wi, INFINITY, RAY_BOUNCE);
                batch_push(&b[BATCH_MIX], o, wi, INFINITY, RAY_BOUNCE);
            }
    for (int k = 0; k < BATCH_COUNT; ++k) batch_finish(&b[k]);
}

#define CHUNK 1024

/* trace_packetsW: rays idx[0..m) of a batch (all of one kind) as packets
   of W lanes, in order; a last partial packet masks its empty lanes off
   (valid 0; they repeat the packet's first ray so that they hold finite
   values). Returns the hits (occluded rays count as hits). One definition
   per width: Embree's packet types differ only in W. */
#define DEFINE_TRACE_PACKETS(W)                                                                                        \
    static uint64_t trace_packets##W(RTCScene rs, struct RTCIntersectContext *ctx, const struct RTCRayHit *rh,         \
                                     const int *idx, int m, bool occlusion)                                            \
    {                                                                                                                  \
        uint64_t hits = 0;                                                                                             \
        for (int p = 0; p < m; p += W) {                                                                               \
            struct RTCRayHit##W x;                                                                                     \
            RTC_ALIGN(64) int valid[W];                                                                                \
            for (int l = 0; l < W; ++l) {                                                                              \
                valid[l] = p + l < m ? -1 : 0;                                                                         \
                const struct RTCRay *r = &rh[idx[p + l < m ? p + l : p]].ray;                                          \
                x.ray.org_x[l] = r->org_x, x.ray.org_y[l] = r->org_y, x.ray.org_z[l] = r->org_z;                       \
                x.ray.dir_x[l] = r->dir_x, x.ray.dir_y[l] = r->dir_y, x.ray.dir_z[l] = r->dir_z;                       \
                x.ray.tnear[l] = r->tnear, x.ray.tfar[l] = r->tfar, x.ray.time[l] = 0.0f;                              \
                x.ray.mask[l] = ~0u, x.ray.id[l] = 0u, x.ray.flags[l] = 0u;                                            \
                x.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID, x.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;               \
            }                                                                                                          \
            if (occlusion) {                                                                                           \
                rtcOccluded##W(valid, rs, ctx, &x.ray);                                                                \
                for (int l = 0; l < W; ++l) hits += valid[l] && x.ray.tfar[l] < 0.0f;                                  \
            } else {                                                                                                   \
                rtcIntersect##W(valid, rs, ctx, &x);                                                                   \
                for (int l = 0; l < W; ++l) hits += valid[l] && x.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;            \
            }                                                                                                          \
        }                                                                                                              \
        return hits;                                                                                                   \
    }
DEFINE_TRACE_PACKETS(4)
DEFINE_TRACE_PACKETS(8)
DEFINE_TRACE_PACKETS(16)

/* Traces rays [i0, i1) of a batch; returns the number of hits (occluded rays
   count as hits), so the work cannot be optimised away. */
static uint64_t trace_range(const struct scene *sc, const struct batch *b, int api, int i0, int i1)
{
    uint64_t hits = 0;
    if (api == API_WRAPPER) {
        for (int i = i0; i < i1; ++i) {
            const struct ray_rec *r = &b->rays[i];
            if (r->kind == RAY_SHADOW) {
                hits += scene_occluded(sc, r->o, r->d, r->tmax);
            } else {
                struct hit h;
                hits += scene_intersect(sc, r->o, r->d, r->tmax, &h);
            }
        }
    } else if (api == API_STREAM) {
        /* What a wavefront renderer would do with the chunk: the rays of
           each kind in one rtcIntersect1M / rtcOccluded1M call, in order. */
        struct RTCRayHit x[CHUNK];
        RTCScene rs = sc->rtc_scene;
        for (int kind = RAY_CAMERA; kind <= RAY_SHADOW; ++kind) {
            int m = 0;
            for (int i = i0; i < i1; ++i)
                if (b->rays[i].kind == kind) x[m++] = b->rh[i];
            if (m == 0) continue;
            struct RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            /* Camera rays of neighbouring pixels are coherent: Embree may
               then trace them as packets. */
            if (kind == RAY_CAMERA) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
            if (kind == RAY_SHADOW) {
                rtcOccluded1M(rs, &ctx, &x[0].ray, (unsigned)m, sizeof x[0]);
                for (int k = 0; k < m; ++k) hits += x[k].ray.tfar < 0.0f;
            } else {
                rtcIntersect1M(rs, &ctx, x, (unsigned)m, sizeof x[0]);
                for (int k = 0; k < m; ++k) hits += x[k].hit.geomID != RTC_INVALID_GEOMETRY_ID;
            }
        }
    } else if (api == API_PACKET4 || api == API_PACKET8 || api == API_PACKET16) {
        /* The chunk's rays of each kind as packets, as the streams take them. */
        int idx[CHUNK];
        RTCScene rs = sc->rtc_scene;
        for (int kind = RAY_CAMERA; kind <= RAY_SHADOW; ++kind) {
            int m = 0;
            for (int i = i0; i < i1; ++i)
                if (b->rays[i].kind == kind) idx[m++] = i;
            if (m == 0) continue;
            struct RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            if (kind == RAY_CAMERA) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
            bool occ = kind == RAY_SHADOW;
            if (api == API_PACKET4) hits += trace_packets4(rs, &ctx, b->rh, idx, m, occ);
            else if (api == API_PACKET8) hits += trace_packets8(rs, &ctx, b->rh, idx, m, occ);
            else hits += trace_packets16(rs, &ctx, b->rh, idx, m, occ);
        }
    } else {
        RTCScene rs = sc->rtc_scene;
        for (int i = i0; i < i1; ++i) {
            struct RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            struct RTCRayHit x = b->rh[i];
            if (b->rays[i].kind == RAY_SHADOW) {
                rtcOccluded1(rs, &ctx, &x.ray);
                hits += x.ray.tfar < 0.0f;
            } else {
                rtcIntersect1(rs, &ctx, &x);
                hits += x.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            }
        }
    }
    return hits;
}

struct worker {
    pthread_t thread;
    const struct scene *sc;
    const struct batch *b;
    int api, start;
    double seconds;
    pthread_barrier_t *barrier;
    uint64_t rays, hits;
    double wall_s, cpu_s;
};

static void *worker_main(void *arg)
{
    struct worker *w = arg;
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    pthread_barrier_wait(w->barrier);
    double t0 = timing_now_s(), c0 = timing_thread_cpu_s();
    int i = w->start, n = w->b->n;
    uint64_t rays = 0, hits = 0;
    double t = t0;
    while (t - t0 < w->seconds) {
        int i1 = i + CHUNK < n ? i + CHUNK : n;
        hits += trace_range(w->sc, w->b, w->api, i, i1);
        rays += (uint64_t)(i1 - i);
        i = i1 == n ? 0 : i1;
        t = timing_now_s();
    }
    w->wall_s = t - t0;
    w->cpu_s = timing_thread_cpu_s() - c0;
    w->rays = rays;
    w->hits = hits;
    return NULL;
}

struct measurement {
    double rays_per_s;     /* all threads, per wall second */
    double rays_per_cpu_s; /* per second of thread CPU time */
};

static struct measurement measure(const struct scene *sc, const struct batch *b, int api, int threads, double seconds)
{
    struct worker w[16];
    pthread_barrier_t barrier;
    pthread_barrier_init(&barrier, NULL, (unsigned)threads);
    for (int k = 0; k < threads; ++k) {
        w[k] = (struct worker){ .sc = sc, .b = b, .api = api, .seconds = seconds, .barrier = &barrier };
        /* Threads start at different places so they do not walk the batch in lockstep. */
        w[k].start = (int)((int64_t)b->n * k / threads / CHUNK * CHUNK);
        if (pthread_create(&w[k].thread, NULL, worker_main, &w[k]) != 0) {
            fprintf(stderr, "raw_embree: cannot start thread %d\n", k);
            exit(1);
        }
    }
    uint64_t rays = 0;
    double wall = 0.0, cpu = 0.0;
    for (int k = 0; k < threads; ++k) {
        pthread_join(w[k].thread, NULL);
        rays += w[k].rays;
        wall = fmax(wall, w[k].wall_s);
        cpu += w[k].cpu_s;
    }
    pthread_barrier_destroy(&barrier);
    return (struct measurement){ (double)rays / wall, (double)rays / fmax(cpu, 1e-9) };
}

static void usage(const char *argv0)
{
    fprintf(stderr,
            "usage: %s CONFIG [--set KEY=VALUE]... [--seconds S] [--reps R] [--max-threads T] [--spp K]\n"
            "          [--mix-only]\n"
            "Times incoherent camera, bounce and shadow rays of CONFIG's scene with 1..T threads;\n"
            "prints one JSON object on stdout, progress on stderr. --mix-only: only the mixed batch,\n"
            "single rays, streams and packets (a quick yardstick next to a render).\n",
            argv0);
}

int main(int argc, char **argv)
{
    const char *path = NULL;
    struct bench_overrides ov = { 0 };
    double seconds = 0.3;
    int reps = 5, max_threads = 2, spp = 2;
    bool mix_only = false;
    for (int i = 1; i < argc; ++i) {
        if (bench_take_set(&ov, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--mix-only")) mix_only = true;
        else if (!strcmp(argv[i], "--seconds") && i + 1 < argc) seconds = atof(argv[++i]);
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--max-threads") && i + 1 < argc) max_threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--spp") && i + 1 < argc) spp = atoi(argv[++i]);
        else if (argv[i][0] != '-' && !path) path = argv[i];
        else {
            usage(argv[0]);
            return 2;
        }
    }
    if (!path || seconds <= 0.0 || reps < 1 || reps > 64 || max_threads < 1 || max_threads > 16 || spp < 1) {
        usage(argv[0]);
        return 2;
    }
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);

    struct error err = { { 0 } };
    struct config cfg;
    if (!config_load(path, ov.items, ov.n, &cfg, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 2;
    }
    struct scene sc;
    if (!scene_create(&cfg, &sc, &err)) {
        fprintf(stderr, "%s\n", err.message);
        config_free(&cfg);
        return 2;
    }
    ssize_t ver = rtcGetDeviceProperty(sc.device, RTC_DEVICE_PROPERTY_VERSION);

    struct batch b[BATCH_COUNT];
    memset(b, 0, sizeof b);
    build_batches(&cfg, &sc, spp, b);
    fprintf(stderr, "raw_embree: %dx%d x %d spp: %d camera, %d bounce, %d shadow rays (%d mixed)\n", cfg.width,
            cfg.height, spp, b[BATCH_CAMERA].n, b[BATCH_BOUNCE].n, b[BATCH_SHADOW].n, b[BATCH_MIX].n);

    /* --mix-only: the mix batch with rtcIntersect1/rtcOccluded1, streams and
       packets, nothing else (a quick yardstick to take right next to a render). */
    int k0 = mix_only ? BATCH_MIX : 0, a0 = mix_only ? API_EMBREE : 0;
    /* Every API must find the same hits on the same rays (a packet lane
       that traced garbage would be fast and wrong): the hit fraction of
       each, in the chunks the timing uses. */
    double hit_fraction[BATCH_COUNT][API_COUNT];
    for (int k = k0; k < BATCH_COUNT; ++k)
        for (int a = 0; a < API_COUNT; ++a) {
            uint64_t hits = 0;
            for (int i = 0; i < b[k].n; i += CHUNK)
                hits += trace_range(&sc, &b[k], a, i, i + CHUNK < b[k].n ? i + CHUNK : b[k].n);
            hit_fraction[k][a] = b[k].n ? (double)hits / b[k].n : 0.0;
        }
    for (int k = k0; k < BATCH_COUNT; ++k)
        for (int a = 0; a < API_COUNT; ++a)
            if (fabs(hit_fraction[k][a] - hit_fraction[k][API_EMBREE]) > 1e-3)
                fprintf(stderr, "raw_embree: warning: %s/%s hits %.6f of the rays, rtcIntersect1/rtcOccluded1 %.6f\n",
                        batch_names[k], api_names[a], hit_fraction[k][a], hit_fraction[k][API_EMBREE]);
    /* Which packet widths this Embree build traces natively on this CPU
       (the others it emulates with narrower ones). */
    int native[3] = { (int)rtcGetDeviceProperty(sc.device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED),
                      (int)rtcGetDeviceProperty(sc.device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED),
                      (int)rtcGetDeviceProperty(sc.device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) };
    int streams = (int)rtcGetDeviceProperty(sc.device, RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED);

    /* Warm-up: caches, page faults of the batches, CPU clocks. */
    for (int k = k0; k < BATCH_COUNT; ++k)
        for (int a = a0; a < API_COUNT; ++a) measure(&sc, &b[k], a, 1, 0.05);

    static double wall[BATCH_COUNT][API_COUNT][16][64], cpu[BATCH_COUNT][API_COUNT][16][64];
    for (int r = 0; r < reps; ++r) {
        fprintf(stderr, "raw_embree: round %d/%d\n", r + 1, reps);
        for (int k = k0; k < BATCH_COUNT; ++k)
            for (int a = a0; a < API_COUNT; ++a)
                for (int t = 1; t <= max_threads; ++t) {
                    struct measurement m = measure(&sc, &b[k], a, t, seconds);
                    wall[k][a][t - 1][r] = m.rays_per_s;
                    cpu[k][a][t - 1][r] = m.rays_per_cpu_s;
                }
    }

    /* The renderer builds with RTC_SCENE_FLAG_ROBUST (scene.c): rebuild
       without it and time the mix again, to show what the flag costs. */
    double nr_wall[64] = { 0 }, nr_cpu[64] = { 0 };
    rtcSetSceneFlags(sc.rtc_scene, RTC_SCENE_FLAG_NONE);
    rtcCommitScene(sc.rtc_scene);
    if (!mix_only) measure(&sc, &b[BATCH_MIX], API_EMBREE, 1, 0.05);
    for (int r = 0; r < (mix_only ? 0 : reps); ++r) {
        struct measurement m = measure(&sc, &b[BATCH_MIX], API_EMBREE, 1, seconds);
        nr_wall[r] = m.rays_per_s;
        nr_cpu[r] = m.rays_per_cpu_s;
    }

    printf("{\"embree_version\":\"%d.%d.%d\",\"config\":\"%s\",\"width\":%d,\"height\":%d,\"spp\":%d,"
           "\"seconds_per_cell\":%g,\"reps\":%d,\"api_note\":\"wrapper = scene_intersect/scene_occluded "
           "(renderer wrappers over rtcIntersect1/rtcOccluded1); embree = rtcIntersect1/rtcOccluded1 on "
           "prebuilt float rays; stream = rtcIntersect1M/rtcOccluded1M on the same rays, each chunk of %d "
           "split by kind; packetW = rtcIntersectW/rtcOccludedW, W rays of a kind at a time in the same "
           "chunks, the copy into SoA timed\",\"native_ray4\":%s,\"native_ray8\":%s,\"native_ray16\":%s,"
           "\"ray_stream_supported\":%s,\"batches\":{",
           (int)(ver / 10000), (int)(ver / 100 % 100), (int)(ver % 100), path, cfg.width, cfg.height, spp, seconds,
           reps, CHUNK, native[0] ? "true" : "false", native[1] ? "true" : "false", native[2] ? "true" : "false",
           streams ? "true" : "false");
    for (int k = k0; k < BATCH_COUNT; ++k) {
        printf("%s\"%s\":{\"rays\":%d,\"hit_fraction\":%.6f,\"hit_fraction_by_api\":{", k > k0 ? "," : "",
               batch_names[k], b[k].n, hit_fraction[k][API_EMBREE]);
        for (int a = 0; a < API_COUNT; ++a) printf("%s\"%s\":%.6f", a ? "," : "", api_names[a], hit_fraction[k][a]);
        printf("}}");
    }
    printf("},\"cells\":[");
    int first = 1;
    for (int k = k0; k < BATCH_COUNT; ++k)
        for (int a = a0; a < API_COUNT; ++a)
            for (int t = 1; t <= max_threads; ++t) {
                printf("%s{\"kind\":\"%s\",\"api\":\"%s\",\"threads\":%d,\"rays_per_s\":[", first ? "" : ",",
                       batch_names[k], api_names[a], t);
                first = 0;
                for (int r = 0; r < reps; ++r) printf("%s%.1f", r ? "," : "", wall[k][a][t - 1][r]);
                printf("],\"rays_per_cpu_s\":[");
                for (int r = 0; r < reps; ++r) printf("%s%.1f", r ? "," : "", cpu[k][a][t - 1][r]);
                double mw = bench_median(wall[k][a][t - 1], reps), mc = bench_median(cpu[k][a][t - 1], reps);
                printf("],\"median_rays_per_s\":%.1f,\"median_rays_per_s_per_thread\":%.1f,"
                       "\"median_rays_per_cpu_s\":%.1f}",
                       mw, mw / t, mc);
            }
    if (mix_only) printf("],\"mix_embree_1t_without_robust_flag\":null}\n");
    else
        printf("],\"mix_embree_1t_without_robust_flag\":{\"median_rays_per_s\":%.1f,\"median_rays_per_cpu_s\":%.1f}}\n",
               bench_median(nr_wall, reps), bench_median(nr_cpu, reps));

    for (int k = 0; k < BATCH_COUNT; ++k) {
        free(b[k].rays);
        free(b[k].rh);
    }
    scene_destroy(&sc);
    config_free(&cfg);
    return 0;
}

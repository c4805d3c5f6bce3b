/* replay.c: replays the samples of one pixel of a lampshade render
   (s_L = 1.2, direct, antishadow_exact, mis power) with the renderer's own
   per-(pixel, pass) streams and prints the passes with a large value.
   Usage: replay seed x y spp [threshold [config]] */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>

#include "scene/camera.h"
#include "config/config.h"
#include "sampling/integrator.h"
#include "base/rng.h"
#include "scene/ray_stream.h"
#include "scene/scene.h"
#include "sampling/shading.h"
#include "sampling/strategy.h"

int main(int argc, char **argv)
{
    if (argc < 5) return 2;
    uint64_t seed = strtoull(argv[1], NULL, 10);
    int x = atoi(argv[2]), y = atoi(argv[3]);
    long spp = atol(argv[4]);
    double thr = argc > 5 ? atof(argv[5]) : 0.1;
    struct config_override ov[] = { { "params.s_L", "1.2" },
                                    { "render.strategy", "antishadow_exact" },
                                    { "render.mis", "power" },
                                    { "render.integrator", "direct" } };
    struct config cfg;
    struct scene sc;
    struct error err;
    if (!config_load(argc > 6 ? argv[6] : "configs/scenes/lampshade.yaml", ov, 4, &cfg, &err) ||
        !scene_create(&cfg, &sc, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    struct strategy st;
    struct strategy_scratch scr;
    if (!strategy_init(&st, &sc, &cfg.render, &err) || !strategy_scratch_init(&st, &scr, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    struct integrator it;
    integrator_init(&it, &cfg.render, &sc, &st);
    struct camera cam;
    camera_init(&cam, &cfg.camera, cfg.width, cfg.height);
    struct integrator_stats stats = { 0 };
    struct ray_stream rs;
    struct error rerr;
    if (!ray_stream_init(&rs, 1, &rerr)) {
        fprintf(stderr, "%s\n", rerr.message);
        return 1;
    }
    double sum = 0.0, sum2 = 0.0;
    for (long pass = 0; pass < spp; ++pass) {
        struct rng r = rng_seeded(seed, (uint64_t)y * (uint64_t)cfg.width + (uint64_t)x, (uint64_t)pass);
        struct rng_draw jx = rng_draw(r.state, r.inc), jy = rng_draw(jx.state, r.inc);
        struct sampler rr = sampler_of_rng((struct rng){ jy.state, r.inc });
        r.state = jy.state;
        struct vec3 d = camera_ray(&cam, x + jx.u, y + jy.u);
        struct hit h;
        bool found;
        scene_intersect_coherent(&sc, cam.origin, &d, 1, &rs, &h, &found);
        struct rng rsave = rr.rng;
        struct rgb c = integrator_radiance_from(&it, &scr, cam.origin, d, found ? &h : NULL, &rr, &stats);
        sum += c.r;
        sum2 += c.r * c.r;
        if (c.r > thr) {
            printf("pass %ld R=%.6f hit p=(%.9f,%.9f,%.9f) ng=(%g,%g,%g)\n", pass, c.r, h.p.x, h.p.y, h.p.z, h.ng.x,
                   h.ng.y, h.ng.z);
            /* Re-derive the BSDF direction: 4 light uniforms, then 2 BSDF uniforms. */
            struct rng q = rsave;
            double ul[4], ub[2];
            for (int k = 0; k < 4; ++k) ul[k] = rng_uniform(&q);
            ub[0] = rng_uniform(&q);
            ub[1] = rng_uniform(&q);
            struct vertex v;
            vertex_init(&sc, h.p, h.ng, h.material, vec3_neg(d), &v);
            struct strategy_point sp;
            strategy_prepare(&st, &scr, h.p, v.n, &sp);
            struct light_sample ls;
            bool ok = strategy_sample(&st, &sp, ul, &ls);
            struct bsdf_query bq;
            bsdf_setup(&sc, &v, ub, &bq);
            int l = scene_first_light(&sc, bq.ray.o, bq.ray.d, bq.ray.tmax);
            double pdf = l >= 0 ? strategy_pdf(&st, &sp, l, bq.ray.d) : -1;
            double t = (2.2 - bq.ray.o.y) / bq.ray.d.y;
            struct vec3 cr = vec3_madd(bq.ray.o, bq.ray.d, t);
            double t6 = (2.6 - bq.ray.o.y) / bq.ray.d.y;
            struct vec3 c6 = vec3_madd(bq.ray.o, bq.ray.d, t6);
            printf(
                "  region=%d light sample ok=%d light=%d pdf=%.5g | bsdf o=(%.9f,%.9f,%.9f) d=(%.12f,%.12f,%.12f) "
                "pdf=%.5g first_light=%d strategy_pdf=%.6g\n  crosses y=2.2 at (%.9f, %.9f), y=2.6 at (%.9f, %.9f)\n",
                scr.region[0], ok, ls.light, ls.pdf_sa, bq.ray.o.x, bq.ray.o.y, bq.ray.o.z, bq.ray.d.x, bq.ray.d.y,
                bq.ray.d.z, bq.pdf, l, pdf, cr.x, cr.z, c6.x, c6.z);
            struct hit h2;
            if (scene_intersect(&sc, bq.ray.o, bq.ray.d, INFINITY, &h2))
                printf("  first hit t=%.9f p=(%.9f,%.9f,%.9f) light=%d mat=%d\n", h2.t, h2.p.x, h2.p.y, h2.p.z,
                       h2.light, h2.material);
        }
    }
    double mean = sum / spp;
    printf("mean R=%.6f var-of-mean=%.3g\n", mean, (sum2 / spp - mean * mean) / spp);
    ray_stream_free(&rs);
    return 0;
}

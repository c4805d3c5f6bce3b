/* firefly.c: BSDF-sampled directions from floor points of the lampshade
   (s_L = 1.2) that reach the light where the antishadow_exact strategy's
   pdf is 0 (MIS weight ~1). Usage: firefly [directions_per_point] [points]
   [px py half-size]. See README.md. */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>

#include "scene/camera.h"
#include "config/config.h"
#include "sampling/integrator.h"
#include "base/rng.h"
#include "scene/scene.h"
#include "sampling/shading.h"
#include "sampling/strategy.h"

static bool hits_box(struct vec3 o, struct vec3 d, struct vec3 lo, struct vec3 hi)
{
    double t0 = 0.0, t1 = INFINITY;
    double oo[3] = { o.x, o.y, o.z }, dd[3] = { d.x, d.y, d.z }, l[3] = { lo.x, lo.y, lo.z },
           h[3] = { hi.x, hi.y, hi.z };
    for (int k = 0; k < 3; ++k) {
        double a = (l[k] - oo[k]) / dd[k], b = (h[k] - oo[k]) / dd[k];
        if (a > b) {
            double t = a;
            a = b;
            b = t;
        }
        if (a > t0) t0 = a;
        if (b < t1) t1 = b;
    }
    return t0 <= t1;
}

int main(int argc, char **argv)
{
    long per_point = argc > 1 ? atol(argv[1]) : 1000;
    long n_points = argc > 2 ? atol(argv[2]) : 1000;
    double cx = argc > 3 ? atof(argv[3]) : 130.5, cy = argc > 4 ? atof(argv[4]) : 204.5;
    double half = argc > 5 ? atof(argv[5]) : 3.0;
    struct config_override ov[] = { { "params.s_L", "1.2" },
                                    { "render.strategy", "antishadow_exact" },
                                    { "render.mis", "power" } };
    struct config cfg;
    struct scene sc;
    struct error err;
    if (!config_load("configs/scenes/lampshade.yaml", ov, 3, &cfg, &err) || !scene_create(&cfg, &sc, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    struct strategy st;
    struct strategy_scratch scr;
    if (!strategy_init(&st, &sc, &cfg.render, &err) || !strategy_scratch_init(&st, &scr, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    struct camera cam;
    camera_init(&cam, &cfg.camera, cfg.width, cfg.height);
    double a = 1.2 / 2 + 0.05, hh = 0.15;
    struct vec3 blo = vec3_make(-a - 1e-3, 2.2 - 1e-3, -a - 1e-3), bhi = vec3_make(a + 1e-3, 2.65 + 1e-3, a + 1e-3);
    struct rng rng;
    rng_seed(&rng, 12345, 0, 0);
    long total = 0, traced = 0, hit_light = 0, through_portal_hits = 0, zero = 0, small = 0, zero_in_portal = 0;
    long regions[8] = { 0 }, n_where[4] = { 0 };
    for (long ip = 0; ip < n_points; ++ip) {
        double px = cx + half * (2 * rng_uniform(&rng) - 1), py = cy + half * (2 * rng_uniform(&rng) - 1);
        struct vec3 dcam = camera_ray(&cam, px, py);
        struct hit h;
        if (!scene_intersect(&sc, cam.origin, dcam, INFINITY, &h) || h.light >= 0) continue;
        struct vertex v;
        if (!vertex_init(&sc, h.p, h.ng, h.material, vec3_neg(dcam), &v)) continue;
        struct strategy_point sp;
        strategy_prepare(&st, &scr, h.p, v.n, &sp);
        int reg = scr.region[0];
        regions[reg < 8 ? reg : 7]++;
        for (long k = 0; k < per_point; ++k) {
            double u[2] = { rng_uniform(&rng), rng_uniform(&rng) };
            struct bsdf_query q;
            bsdf_setup(&sc, &v, u, &q);
            ++total;
            if (!q.trace || !hits_box(q.ray.o, q.ray.d, blo, bhi)) continue;
            ++traced;
            int l = scene_first_light(&sc, q.ray.o, q.ray.d, q.ray.tmax);
            if (l < 0) continue;
            ++hit_light;
            double t = (2.2 - q.ray.o.y) / q.ray.d.y;
            struct vec3 c = vec3_madd(q.ray.o, q.ray.d, t);
            bool in_portal = fabs(c.x) <= hh && fabs(c.z) <= hh;
            through_portal_hits += in_portal;
            double pdf = strategy_pdf(&st, &sp, l, q.ray.d);
            double w = mis_weight(MIS_POWER, q.pdf, pdf);
            if (pdf == 0.0) ++zero;
            if (w > 0.5) {
                ++small;
                zero_in_portal += in_portal;
                /* Where it crosses the wall planes, too. */
                /* The ray Embree traces (float origin and direction), met
                   exactly with the float plane y = 2.2f. */
                struct vec3 of = vec3_make((float)q.ray.o.x, (float)q.ray.o.y, (float)q.ray.o.z);
                struct vec3 df = vec3_make((float)q.ray.d.x, (float)q.ray.d.y, (float)q.ray.d.z);
                double tf = ((double)2.2f - of.y) / df.y;
                struct vec3 cf = vec3_madd(of, df, tf);
                double ex = fabs(cf.x) - (double)0.15f, ez = fabs(cf.z) - (double)0.15f;
                const char *where = "elsewhere";
                if (fabs(ez) < 1e-5 && fabs(cf.x) > 0.15f)
                    where = "T-junction |z|=h, |x|>h (bottom_back/front vs left/right)";
                else if (fabs(ex) < 1e-5 && fabs(cf.z) < 0.15f) where = "hole edge |x|=h";
                else if (fabs(ez) < 1e-5 && fabs(cf.x) <= 0.15f) where = "hole edge |z|=h";
                else if (fabs(fabs(cf.x) - (double)0.65f) < 1e-5 || fabs(fabs(cf.z) - (double)0.65f) < 1e-5)
                    where = "plate/wall rim";
                ++n_where[where[0] == 'T' ? 0 : where[0] == 'h' ? 1 : where[0] == 'p' ? 2 : 3];
                printf("  float ray at y=2.2f: (%.9f, %.9f), |x|-hf=%.3g |z|-hf=%.3g: %s\n", cf.x, cf.z, ex, ez, where);
                printf("EVENT p=(%.6f,%.6f,%.6f) region=%d d=(%.9f,%.9f,%.9f) pdf_bsdf=%.4g pdf_light=%.4g w=%.4f "
                       "y2.2:(%.9f,%.9f) y2.2f:(%.9f,%.9f) in_portal=%d\n",
                       h.p.x, h.p.y, h.p.z, reg, q.ray.d.x, q.ray.d.y, q.ray.d.z, q.pdf, pdf, w, c.x, c.z, cf.x, cf.z,
                       in_portal);
            }
        }
    }
    printf("total=%ld traced(box)=%ld hit_light=%ld through_portal=%ld pdf0=%ld w>0.5=%ld (in_portal %ld)\n", total,
           traced, hit_light, through_portal_hits, zero, small, zero_in_portal);
    printf("where: T-junction %ld, hole edge %ld, rim %ld, elsewhere %ld\n", n_where[0], n_where[1], n_where[2],
           n_where[3]);
    printf("regions:");
    for (int i = 0; i < 8; ++i) printf(" %ld", regions[i]);
    printf("\n");
    return 0;
}

/* strategy_util.h: scenes for strategy tests built by hand (no Embree: the
   strategies only read lights and portals), and a chi-square adapter. */
#ifndef STRATEGY_UTIL_H
#define STRATEGY_UTIL_H

#include <string.h>

#include "chi2.h"
#include "scene/scene.h"
#include "sampling/strategy.h"
#include "testlib.h"

#define TS_MAX 16

struct test_scene {
    struct scene scene;
    struct light lights[TS_MAX];
    struct portal portals[TS_MAX];
    struct target targets[TS_MAX];   /* portals[k].target is targets[k] */
    struct emitter emitters[TS_MAX]; /* one per light (polygon lights) */
};

static inline struct polygon square_y(double cx, double y, double cz, double side, bool facing_down)
{
    double h = side / 2;
    struct polygon p = {
        4, { { cx - h, y, cz - h }, { cx + h, y, cz - h }, { cx + h, y, cz + h }, { cx - h, y, cz + h } }
    };
    if (!facing_down) {
        struct vec3 t = p.v[1];
        p.v[1] = p.v[3];
        p.v[3] = t;
    }
    return p;
}

static inline void ts_init(struct test_scene *ts)
{
    memset(ts, 0, sizeof *ts);
    ts->scene.lights = ts->lights;
    ts->scene.portals = ts->portals;
    ts->scene.emitters = ts->emitters;
    /* Bounds as scene_create would set them: a room around everything. */
    ts->scene.bounds_lo = vec3_make(-5, -1, -5);
    ts->scene.bounds_hi = vec3_make(5, 5, 5);
    ts->scene.scale = vec3_length(vec3_sub(ts->scene.bounds_hi, ts->scene.bounds_lo));
}

/* Releases what ts_add_portal built (the pairs' antishadows); ts_init may
   then start a new scene in ts. */
static inline void ts_free(struct test_scene *ts)
{
    for (int k = 0; k < ts->scene.n_portals; ++k) antishadow_free(&ts->portals[k].antishadow);
    ts->scene.n_portals = 0;
}

/* Adds a light; its portals must be added right after it. */
static inline int ts_add_light(struct test_scene *ts, struct polygon poly, struct rgb radiance, bool two_sided)
{
    int i = ts->scene.n_lights++;
    CHECK(light_init(&ts->lights[i], &poly, radiance, two_sided));
    ts->lights[i].first_portal = ts->scene.n_portals;
    int e = ts->scene.n_emitters++;
    ts->lights[i].emitter = e;
    ts->emitters[e] = (struct emitter){ i, 1, ts->lights[i].power, NULL };
    return i;
}

static inline void ts_add_portal(struct test_scene *ts, int light, struct polygon poly)
{
    int k = ts->scene.n_portals++;
    struct portal *pt = &ts->portals[k];
    struct error err;
    pt->light = light;
    CHECK(target_init(&ts->targets[k], &poly));
    pt->target = &ts->targets[k];
    pt->centroid = polygon_centroid(&pt->target->polygon);
    bool ok = antishadow_build(&ts->lights[light].target.polygon, &pt->target->polygon, &pt->antishadow, &err);
    CHECK_MSG(ok, "antishadow_build: %s", err.message);
    ts->lights[light].n_portals++;
}

/* Adds a mesh light: each of the n triangles becomes a light of one new
   emitter, each with its own copy of each of the n_portals portals (the
   layout scene_create builds, scene.h). Returns the emitter. */
static inline int ts_add_mesh_light(struct test_scene *ts, const struct polygon *tris, int n, struct rgb radiance,
                                    bool two_sided, const struct polygon *portals, int n_portals)
{
    int e = ts->scene.n_emitters++;
    ts->emitters[e] = (struct emitter){ ts->scene.n_lights, n, 0.0, NULL };
    for (int i = 0; i < n; ++i) {
        int l = ts->scene.n_lights++;
        CHECK(light_init(&ts->lights[l], &tris[i], radiance, two_sided));
        ts->lights[l].first_portal = ts->scene.n_portals;
        ts->lights[l].emitter = e;
        ts->emitters[e].power += ts->lights[l].power;
        for (int k = 0; k < n_portals; ++k) ts_add_portal(ts, l, portals[k]);
    }
    return e;
}

/* The first light along dir from p (-1 if none) and its distance. */
static inline int ts_first_light(const struct test_scene *ts, struct vec3 p, struct vec3 dir, double *dist)
{
    int best = -1;
    double tbest = INFINITY;
    for (int i = 0; i < ts->scene.n_lights; ++i) {
        double t;
        if (polygon_intersect_ray(&ts->lights[i].target.polygon, p, dir, &t) && t < tbest) tbest = t, best = i;
    }
    if (dist) *dist = tbest;
    return best;
}

/* Chi-square context: a prepared point of a strategy. Samples whose
   direction misses the light count as failures (they carry no light); the
   pdf is the strategy's density of directions that reach a light. */
struct strategy_chi2 {
    const struct test_scene *ts;
    const struct strategy *s;
    struct strategy_point pt;
    struct rng rng;        /* the fourth uniform */
    long successes;        /* samples that reached a light */
    long pdf_mismatches;   /* samples whose reported pdf differs from strategy_pdf */
    long light_mismatches; /* samples whose light is not the first light along wi */
};

static inline bool strategy_chi2_sample(void *ctx, double u1, double u2, double u3, struct vec3 *dir)
{
    struct strategy_chi2 *c = ctx;
    double u[4] = { u1, u2, u3, rng_uniform(&c->rng) };
    struct light_sample ls;
    if (!strategy_sample(c->s, &c->pt, u, &ls) || ls.light < 0) return false;
    double ref = strategy_pdf(c->s, &c->pt, ls.light, ls.wi);
    if (!(fabs(ref - ls.pdf_sa) <= 1e-6 * ref)) ++c->pdf_mismatches;
    /* The sample must lie on its light at the reported distance... */
    double dist;
    if (!polygon_intersect_ray(&c->ts->lights[ls.light].target.polygon, c->pt.p, ls.wi, &dist) ||
        fabs(dist - ls.dist) > 1e-6 * dist)
        ++c->light_mismatches;
    /* ...and if another light lies in front, the shadow ray is blocked: the
       sample carries no light, like a failure. */
    if (ts_first_light(c->ts, c->pt.p, ls.wi, NULL) != ls.light) return false;
    *dir = ls.wi;
    ++c->successes;
    return true;
}

static inline double strategy_chi2_pdf(void *ctx, struct vec3 dir)
{
    struct strategy_chi2 *c = ctx;
    int l = ts_first_light(c->ts, c->pt.p, dir, NULL);
    return l < 0 ? 0.0 : strategy_pdf(c->s, &c->pt, l, dir);
}

/* Runs the chi-square test of strategy `kind` at p (normal n) with the cap
   fitted around `aim` (directions of the vertices to cover). */
/* strategy_init and strategy_scratch_init of rd on sc, or a failed check
   naming the error (and nothing left to free). */
static inline bool ts_open_strategy(const struct scene *sc, const struct render_desc *rd, struct strategy *s,
                                    struct strategy_scratch *scratch)
{
    struct error err;
    if (!strategy_init(s, sc, rd, &err)) {
        CHECK_MSG(false, "%s", err.message);
        return false;
    }
    if (!strategy_scratch_init(s, scratch, &err)) {
        CHECK_MSG(false, "%s", err.message);
        strategy_free(s);
        return false;
    }
    return true;
}

static inline void ts_close_strategy(struct strategy *s, struct strategy_scratch *scratch)
{
    strategy_scratch_free(scratch);
    strategy_free(s);
}

static inline bool strategy_chi2_run(const struct test_scene *ts, enum strategy_kind kind, double defensive,
                                     enum portal_weight_kind weight, struct vec3 p, struct vec3 n,
                                     const struct vec3 *aim, int n_aim, double significance, uint64_t seed,
                                     double min_success, double *p_value, char *report, size_t report_len)
{
    struct render_desc rd;
    memset(&rd, 0, sizeof rd);
    rd.strategy = kind;
    rd.defensive = defensive;
    rd.portal_weight = weight;
    struct strategy s;
    struct strategy_scratch scratch;
    struct error err;
    if (!strategy_init(&s, &ts->scene, &rd, &err) || !strategy_scratch_init(&s, &scratch, &err)) {
        snprintf(report, report_len, "strategy init: %.400s", err.message);
        return false;
    }
    struct strategy_chi2 c;
    memset(&c, 0, sizeof c);
    c.ts = ts;
    c.s = &s;
    rng_seed(&c.rng, seed, 99, 0);
    strategy_prepare(&s, &scratch, p, n, &c.pt);
    struct vec3 dirs[4 * TS_MAX * 2];
    for (int i = 0; i < n_aim; ++i) dirs[i] = vec3_normalize(vec3_sub(aim[i], p));
    struct chi2_config cfg;
    chi2_config_init(&cfg, vec3_make(0, 0, 1), M_PI);
    chi2_config_cap(&cfg, dirs, n_aim);
    cfg.samples = 200000;
    cfg.seed = seed;
    cfg.significance = significance;
    bool ok = chi2_test(&cfg, strategy_chi2_sample, strategy_chi2_pdf, &c, p_value, report, report_len);
    /* A strategy that samples nothing passes the chi-square test trivially
       (no samples, zero pdf): where light is expected, demand it. */
    if (c.successes < min_success * cfg.samples) {
        snprintf(report, report_len, "only %ld of %ld samples reached a light", c.successes, cfg.samples);
        ok = false;
    }
    if (c.pdf_mismatches || c.light_mismatches) {
        snprintf(report, report_len, "%ld samples report a pdf != strategy_pdf, %ld a wrong light/distance",
                 c.pdf_mismatches, c.light_mismatches);
        ok = false;
    }
    strategy_scratch_free(&scratch);
    strategy_free(&s);
    return ok;
}

#endif

/* Light-sampling strategies: every strategy's sampled directions follow the
   density strategy_pdf reports (chi-square), at points in every antishadow
   region, with several lights and portals, and with defensive mixing. */
#include "scene_util.h"
#include "strategy_util.h"

#define N_CHI2_TESTS 64
#define SIGNIFICANCE (0.01 / N_CHI2_TESTS)

static const struct rgb warm = { 40, 34, 24 };

/* Lampshade geometry: light of side s_l at y = 2.6 facing down, portal of
   side 0.3 at y = 2.2. */
static void lampshade(struct test_scene *ts, double s_l)
{
    ts_init(ts);
    int l = ts_add_light(ts, square_y(0, 2.6, 0, s_l, true), warm, false);
    ts_add_portal(ts, l, square_y(0, 2.2, 0, 0.3, true));
}

static int aim_at(const struct test_scene *ts, struct vec3 *aim)
{
    int n = 0;
    for (int i = 0; i < ts->scene.n_lights; ++i)
        for (int k = 0; k < ts->lights[i].target.polygon.n; ++k) aim[n++] = ts->lights[i].target.polygon.v[k];
    return n;
}

/* inside: p is on the light's side of the portal, where only the light-only
   and antishadow strategies are expected to deliver light. */
static void check_strategies(const struct test_scene *ts, struct vec3 p, const char *what, uint64_t seed, bool inside)
{
    struct vec3 aim[4 * TS_MAX * 2];
    int n_aim = aim_at(ts, aim);
    struct vec3 up = vec3_make(0, 1, 0);
    for (int k = 0; k < STRATEGY_COUNT; ++k) {
        double pv;
        char report[512];
        bool plain_portal = k == STRATEGY_PORTAL || k == STRATEGY_PROJECTION;
        double min_success = inside && plain_portal ? 0.0 : 0.05;
        bool ok = strategy_chi2_run(ts, (enum strategy_kind)k, 0.0, PORTAL_WEIGHT_IRRADIANCE, p, up, aim, n_aim,
                                    SIGNIFICANCE, seed + (uint64_t)k, min_success, &pv, report, sizeof report);
        CHECK_MSG(ok, "%s, strategy %s: p = %.3g: %s", what, strategy_names[k], pv, report);
    }
}

/* Points on the floor in each region of the lampshade, for both a light
   larger and a light smaller than the portal. */
static void test_lampshade_regions(void)
{
    struct test_scene ts;
    lampshade(&ts, 0.6); /* projected light 0.51 > 0.3: anti-antumbra below */
    check_strategies(&ts, vec3_make(0, 0, 0), "s_L=0.6 below (anti-antumbra)", 100, false);
    check_strategies(&ts, vec3_make(1.0, 0, 0.4), "s_L=0.6 penumbra", 200, false);
    /* Inside the shade (the light's side of the portal plane): the portal
       does not apply, the light is sampled directly. */
    check_strategies(&ts, vec3_make(0.25, 2.4, -0.1), "s_L=0.6 inside the shade", 150, true);
    ts_free(&ts);
    lampshade(&ts, 0.15); /* projected light 0.127 < 0.3: anti-umbra below */
    check_strategies(&ts, vec3_make(0.1, 0, -0.1), "s_L=0.15 below (anti-umbra)", 300, false);
    check_strategies(&ts, vec3_make(0.9, 0, 0.3), "s_L=0.15 penumbra", 400, false);
    ts_free(&ts);
}

/* A pentagon light behind a tilted portal: general polygons. */
static void test_tilted_pentagon(void)
{
    struct test_scene ts;
    ts_init(&ts);
    struct polygon penta;
    penta.n = 5;
    for (int i = 0; i < 5; ++i) {
        /* Wound so that its normal (by winding) is -y: it faces the
           points below. (Wound the other way until 0.11.4, it showed them
           its back, which the light-only strategies now cull.) */
        double a = 2.0 * M_PI * i / 5.0;
        penta.v[i] = vec3_make(0.25 * cos(a), 2.6, 0.25 * sin(a));
    }
    int l = ts_add_light(&ts, penta, warm, false);
    /* Portal tilted by ~18 degrees about the x axis. */
    struct polygon tilted = { 4,
                              { { -0.2, 2.15, -0.2 }, { 0.2, 2.15, -0.2 }, { 0.2, 2.28, 0.2 }, { -0.2, 2.28, 0.2 } } };
    ts_add_portal(&ts, l, tilted);
    check_strategies(&ts, vec3_make(0.05, 0, 0.1), "pentagon/tilted below", 500, false);
    check_strategies(&ts, vec3_make(0.9, 0.3, -0.5), "pentagon/tilted side", 600, false);
    ts_free(&ts);
}

/* Several lights: one with two portals (two-sided light in a tube), one
   with a portal, one without; and defensive mixing. */
static void test_many_lights(void)
{
    struct test_scene ts;
    ts_init(&ts);
    int a = ts_add_light(&ts, square_y(0, 2.6, 0, 0.4, true), warm, true);
    ts_add_portal(&ts, a, square_y(0, 2.3, 0, 0.3, true));
    ts_add_portal(&ts, a, square_y(0, 2.9, 0, 0.3, true));
    int b = ts_add_light(&ts, square_y(1.0, 2.5, 0.5, 0.3, true), rgb_make(10, 10, 10), false);
    ts_add_portal(&ts, b, square_y(1.0, 2.3, 0.5, 0.2, true));
    ts_add_light(&ts, square_y(-1.0, 3.0, -0.5, 0.2, true), rgb_make(5, 5, 5), false);
    struct vec3 aim[4 * TS_MAX * 2];
    int n_aim = aim_at(&ts, aim);
    /* Below, above (top portal), inside the tube of the two-sided light. */
    struct vec3 points[] = { { 0.3, 0, 0.2 }, { 0.2, 3.9, 0.1 }, { 0.18, 2.45, -0.1 } };
    struct vec3 normals[] = { { 0, 1, 0 }, { 0, -1, 0 }, { -1, 0, 0 } };
    const enum portal_weight_kind weights[] = { PORTAL_WEIGHT_AREA, PORTAL_WEIGHT_DISTANCE, PORTAL_WEIGHT_IRRADIANCE,
                                                PORTAL_WEIGHT_IRRADIANCE_ESTIMATE };
    for (int i = 0; i < 3; ++i)
        for (int w = 0; w < PORTAL_WEIGHT_COUNT; ++w)
            for (int def = 0; def < 2; ++def) {
                enum strategy_kind kinds[] = { STRATEGY_ANTISHADOW_EXACT, STRATEGY_ANTISHADOW, STRATEGY_PORTAL };
                for (int k = 0; k < 3; ++k) {
                    /* antishadow_exact everywhere; the others with the default weight below. */
                    if (k > 0 && (weights[w] != PORTAL_WEIGHT_IRRADIANCE || i > 0)) continue;
                    double pv;
                    char report[512];
                    bool ok = strategy_chi2_run(&ts, kinds[k], def ? 0.2 : 0.0, weights[w], points[i], normals[i], aim,
                                                n_aim, SIGNIFICANCE, 700 + (uint64_t)(100 * i + 10 * w + def + 3 * k),
                                                0.05, &pv, report, sizeof report);
                    CHECK_MSG(ok, "point %d, %s, weight %s, defensive %d: p = %.3g: %s", i, strategy_names[kinds[k]],
                              portal_weight_names[weights[w]], def, pv, report);
                }
            }
    ts_free(&ts);
}

/* Selection by power: a light with twice the power is picked twice as often. */
static void test_power_selection(void)
{
    struct test_scene ts;
    ts_init(&ts);
    ts_add_light(&ts, square_y(-1, 2, 0, 0.5, true), rgb_make(2, 2, 2), false);
    ts_add_light(&ts, square_y(1, 2, 0, 0.5, true), rgb_make(4, 4, 4), false);
    struct render_desc rd;
    memset(&rd, 0, sizeof rd);
    rd.strategy = STRATEGY_LIGHT;
    struct strategy s;
    struct strategy_scratch scratch;
    struct error err;
    CHECK(strategy_init(&s, &ts.scene, &rd, &err) && strategy_scratch_init(&s, &scratch, &err));
    struct strategy_point pt;
    strategy_prepare(&s, &scratch, vec3_make(0, 0, 0), vec3_make(0, 1, 0), &pt);
    struct rng r;
    rng_seed(&r, 1, 2, 3);
    int n = 30000, second = 0;
    for (int i = 0; i < n; ++i) {
        double u[4] = { rng_uniform(&r), rng_uniform(&r), rng_uniform(&r), rng_uniform(&r) };
        struct light_sample ls;
        CHECK(strategy_sample(&s, &pt, u, &ls));
        second += ls.light == 1;
    }
    /* Binomial(n, 2/3): 5 sigma. */
    double sigma = sqrt(n * (2.0 / 3.0) * (1.0 / 3.0));
    CHECK_NEAR(second, n * 2.0 / 3.0, 5 * sigma);
    ts_close_strategy(&s, &scratch);
    ts_free(&ts);
}

/* Outside the antishadow the antishadow strategies produce nothing (no ray
   is traced); `portal` still tries and misses. */
static void test_outside_returns_nothing(void)
{
    struct test_scene ts;
    lampshade(&ts, 0.6);
    struct render_desc rd;
    memset(&rd, 0, sizeof rd);
    struct vec3 p = vec3_make(2.9, 0, 0.5); /* beyond the penumbra (half-width 2.6 at y = 0) */
    for (int k = STRATEGY_ANTISHADOW; k <= STRATEGY_ANTISHADOW_EXACT; ++k) {
        rd.strategy = (enum strategy_kind)k;
        struct strategy s;
        struct strategy_scratch scratch;
        struct error err;
        CHECK(strategy_init(&s, &ts.scene, &rd, &err) && strategy_scratch_init(&s, &scratch, &err));
        struct strategy_point pt;
        strategy_prepare(&s, &scratch, p, vec3_make(0, 1, 0), &pt);
        double u[4] = { 0.3, 0.4, 0.5, 0.6 };
        struct light_sample ls;
        CHECK(!strategy_sample(&s, &pt, u, &ls));
        CHECK(strategy_pdf(&s, &pt, 0, vec3_normalize(vec3_sub(vec3_make(0, 2.6, 0), p))) == 0.0);
        ts_close_strategy(&s, &scratch);
    }
    ts_free(&ts);
}

/* The light-only strategies draw nothing for a light that can deliver
   nothing at the point (light_culled): behind a one-sided light, or with
   the whole light below the point's horizon. No sample, one point at a
   time or batched, and a density of zero towards the light; in front of
   it, above the horizon, a two-sided light from behind, a point with no
   receiving side, and points within rounding of the light's plane sample
   as before. */
static void test_light_culled_draws_nothing(void)
{
    struct test_scene ts;
    lampshade(&ts, 0.6); /* one-sided, emitting down from y = 2.6 */
    const struct light *l = &ts.lights[0];
    struct vec3 up = vec3_make(0, 1, 0), down = vec3_make(0, -1, 0), zero = vec3_make(0, 0, 0);
    struct vec3 centre = vec3_make(0, 2.6, 0);
    struct {
        struct vec3 p, n;
        bool culled;
        const char *what;
    } cases[] = {
        { { 0.1, 3.0, 0.2 }, up, true, "behind the light" },
        { { 0.1, 3.0, 0.2 }, zero, true, "behind the light, no receiving side" },
        { { 0.2, 0.0, -0.1 }, down, true, "the light below the horizon" },
        { { 0.2, 2.5, -0.1 }, vec3_make(0, 0.6, 0.8), false, "part of the light above the horizon" },
        { { 0.2, 0.0, -0.1 }, up, false, "in front, above the horizon" },
        { { 0.2, 0.0, -0.1 }, zero, false, "in front, no receiving side" },
        /* 1e-12 behind the plane: within the margin, sampled as before. */
        { { 0.1, 2.6 + 1e-12, 0.2 }, zero, false, "within rounding of the plane" },
        { { 2.0, 2.6 - 1e-12, 0.0 }, up, false, "within rounding of the horizon" },
    };
    int n_cases = (int)(sizeof cases / sizeof cases[0]);
    for (int c = 0; c < n_cases; ++c)
        CHECK_MSG(light_culled(l, cases[c].p, cases[c].n) == cases[c].culled, "%s", cases[c].what);
    /* A two-sided light is never culled for being behind. */
    struct test_scene two;
    ts_init(&two);
    ts_add_light(&two, square_y(0, 2.6, 0, 0.6, true), warm, true);
    CHECK(!light_culled(&two.lights[0], vec3_make(0.1, 3.0, 0.2), zero));
    CHECK(light_culled(&two.lights[0], vec3_make(0.1, 3.0, 0.2), up));

    const enum strategy_kind kinds[] = { STRATEGY_LIGHT, STRATEGY_LIGHT_AREA };
    for (int k = 0; k < 2; ++k) {
        struct render_desc rd;
        memset(&rd, 0, sizeof rd);
        rd.strategy = kinds[k];
        struct strategy s;
        struct strategy_scratch scratch;
        if (!ts_open_strategy(&ts.scene, &rd, &s, &scratch)) continue;
        for (int c = 0; c < n_cases; ++c) {
            struct strategy_point pts[5];
            double u[5][4];
            struct light_sample one[5], many[5];
            bool ok_one[5], ok_many[5];
            for (int i = 0; i < 5; ++i) {
                strategy_prepare(&s, &scratch, cases[c].p, cases[c].n, &pts[i]);
                for (int j = 0; j < 4; ++j) u[i][j] = (i + 1) / 6.0 + 0.03 * j;
                ok_one[i] = strategy_sample(&s, &pts[i], u[i], &one[i]);
                ok_many[i] = !ok_one[i];
            }
            strategy_sample_many(&s, pts, (const double(*)[4])u, 5, many, ok_many);
            double pdf = strategy_pdf(&s, &pts[0], 0, vec3_normalize(vec3_sub(centre, cases[c].p)));
            if (cases[c].culled) {
                for (int i = 0; i < 5; ++i)
                    CHECK_MSG(!ok_one[i] && !ok_many[i], "%s, %s: sampled", strategy_names[kinds[k]], cases[c].what);
                CHECK_MSG(pdf == 0.0, "%s, %s: density %g", strategy_names[kinds[k]], cases[c].what, pdf);
            } else if (c == 4 || c == 5) {
                /* Well in front: every uniform gives a sample, with the
                   density strategy_pdf reports in its direction. */
                for (int i = 0; i < 5; ++i) {
                    CHECK_MSG(ok_one[i] && ok_many[i], "%s, %s: no sample", strategy_names[kinds[k]], cases[c].what);
                    double again = strategy_pdf(&s, &pts[i], one[i].light, one[i].wi);
                    CHECK_NEAR(again, one[i].pdf_sa, 1e-9 * one[i].pdf_sa);
                }
                CHECK(pdf > 0.0);
            }
        }
        ts_close_strategy(&s, &scratch);
    }
    ts_free(&ts);
    ts_free(&two);
}

/* strategy_point_unlit lets the direct integrator skip a point, so it must
   be conservative: where it says unlit, no direction on the point's
   receiving side (any direction for a point without one) meets an
   emitting face of any light, and the light sample draws nothing. On the
   lampshade (one polygon light), multi_lamp (six, one two-sided) and the
   Little Lamp (a 400-triangle mesh light): random points and normals, and
   each scene must have both outcomes. */
static struct vec3 random_dir(struct rng *r);

static void test_point_unlit_is_conservative(void)
{
    const char *scenes[] = { "configs/scenes/lampshade.yaml", "configs/scenes/multi_lamp.yaml",
                             "configs/scenes/little_lamp.yaml" };
    for (int si = 0; si < 3; ++si) {
        struct config cfg;
        struct scene sc;
        if (!test_scene_load(scenes[si], NULL, 0, &cfg, &sc)) {
            CHECK_MSG(false, "%s", scenes[si]);
            continue;
        }
        struct render_desc rd = cfg.render;
        rd.strategy = STRATEGY_LIGHT;
        struct strategy s;
        struct strategy_scratch scratch;
        if (!ts_open_strategy(&sc, &rd, &s, &scratch)) {
            scene_destroy(&sc);
            config_free(&cfg);
            continue;
        }
        /* The scene's extent, from its lights' vertices, widened. */
        struct vec3 lo = sc.lights[0].target.polygon.v[0], hi = lo;
        for (int i = 0; i < sc.n_lights; ++i)
            for (int k = 0; k < sc.lights[i].target.polygon.n; ++k) {
                struct vec3 v = sc.lights[i].target.polygon.v[k];
                lo = vec3_make(fmin(lo.x, v.x), fmin(lo.y, v.y), fmin(lo.z, v.z));
                hi = vec3_make(fmax(hi.x, v.x), fmax(hi.y, v.y), fmax(hi.z, v.z));
            }
        struct vec3 mid = vec3_scale(vec3_add(lo, hi), 0.5);
        double size = fmax(vec3_length(vec3_sub(hi, lo)), 0.05);
        struct rng r;
        rng_seed(&r, 99, (uint64_t)si, 0);
        int unlit = 0, lit = 0, wrong = 0;
        for (int i = 0; i < 3000; ++i) {
            struct vec3 p = vec3_madd(mid, random_dir(&r), 2.0 * size * rng_uniform(&r));
            struct vec3 n = i % 9 == 0 ? vec3_make(0, 0, 0) : random_dir(&r);
            /* The answer must not depend on the hint. */
            int hint = (int)(rng_uniform(&r) * (sc.n_emitters + 2)) - 1, hint0 = 0;
            bool unlit_here = strategy_point_unlit(&s, p, n, &hint);
            CHECK(unlit_here == strategy_point_unlit(&s, p, n, &hint0));
            if (!unlit_here) {
                ++lit;
                continue;
            }
            ++unlit;
            for (int j = 0; j < 200; ++j) {
                struct vec3 w = random_dir(&r);
                if (vec3_dot(w, n) < 0.0) w = vec3_neg(w);
                for (int l = 0; l < sc.n_lights; ++l) {
                    double t;
                    if (polygon_intersect_ray(&sc.lights[l].target.polygon, p, w, &t) &&
                        !rgb_is_black(light_emitted(&sc.lights[l], vec3_neg(w))))
                        ++wrong;
                }
            }
            struct strategy_point pt;
            strategy_prepare(&s, &scratch, p, n, &pt);
            struct light_sample ls;
            double u[4] = { rng_uniform(&r), rng_uniform(&r), rng_uniform(&r), rng_uniform(&r) };
            wrong += strategy_sample(&s, &pt, u, &ls) && !rgb_is_black(ls.radiance);
        }
        printf("  %s: %d unlit and %d lit points\n", scenes[si], unlit, lit);
        CHECK_MSG(wrong == 0, "%s: %d directions from unlit points reach an emitting face", scenes[si], wrong);
        CHECK_MSG(unlit > 100 && lit > 100, "%s: %d unlit, %d lit", scenes[si], unlit, lit);
        ts_close_strategy(&s, &scratch);
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* ---- batched sampling ------------------------------------------------------
   strategy_sample_many must give what strategy_sample gives, bit for bit,
   for the strategies that batch (the light-only ones): the renderer draws a
   row's light samples together and its images must not change for it. On
   the multi-lamp scene: five lights of different power, one two-sided, one
   without a portal. */

/* Field by field (the struct has padding after `light`). */
static bool light_sample_equal(const struct light_sample *a, const struct light_sample *b)
{
    return same_bits(a->wi.x, b->wi.x) && same_bits(a->wi.y, b->wi.y) && same_bits(a->wi.z, b->wi.z) &&
           same_bits(a->pdf_sa, b->pdf_sa) && a->light == b->light && same_bits(a->dist, b->dist) &&
           same_bits(a->radiance.r, b->radiance.r) && same_bits(a->radiance.g, b->radiance.g) &&
           same_bits(a->radiance.b, b->radiance.b);
}

static double unit_or_end(struct rng *r)
{
    double k = rng_uniform(r);
    return k < 0.05 ? 0.0 : k < 0.1 ? nextafter(1.0, 0.0) : rng_uniform(r);
}

static struct vec3 random_dir(struct rng *r)
{
    for (;;) {
        struct vec3 v = vec3_make(2 * rng_uniform(r) - 1, 2 * rng_uniform(r) - 1, 2 * rng_uniform(r) - 1);
        double l = vec3_length(v);
        if (l > 0.1 && l <= 1.0) return vec3_scale(v, 1.0 / l);
    }
}

#define MANY_POINTS 400

static void test_sample_many_matches_one(void)
{
    struct config cfg;
    struct scene sc;
    if (!test_scene_load("configs/scenes/multi_lamp.yaml", NULL, 0, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    CHECK(sc.n_lights >= 4);
    static struct strategy_point pts[MANY_POINTS];
    static double u[MANY_POINTS][4];
    static struct light_sample one[MANY_POINTS], many[MANY_POINTS];
    static bool ok_one[MANY_POINTS], ok_many[MANY_POINTS];
    const enum strategy_kind kinds[] = { STRATEGY_LIGHT, STRATEGY_LIGHT_AREA };
    for (int k = 0; k < 2; ++k) {
        struct render_desc rd = cfg.render;
        rd.strategy = kinds[k];
        struct strategy s;
        struct strategy_scratch scratch;
        if (!ts_open_strategy(&sc, &rd, &s, &scratch)) continue;
        CHECK(strategy_batches(&s));
        struct rng r;
        rng_seed(&r, 4242, (uint64_t)k, 0);
        int lights_hit[8] = { 0 };
        long n_ok = 0, n_fail = 0;
        for (int rep = 0; rep < 20; ++rep) {
            /* Shading points anywhere in the room, and around the lights: in
               a light's plane (area fallback below min_height, failures), a
               hair off it on either side, far from every light (area
               fallback below the spherical samplers' smallest solid angle). Normals
               random, sometimes zero (allowed: no receiving side). */
            for (int i = 0; i < MANY_POINTS; ++i) {
                struct vec3 p = vec3_make(6 * rng_uniform(&r) - 3, 4 * rng_uniform(&r), 6 * rng_uniform(&r) - 3);
                if (i % 5 == 0) {
                    const struct light *l = &sc.lights[(int)(rng_uniform(&r) * sc.n_lights)];
                    const struct polygon *poly = &l->target.polygon;
                    struct vec3 c = polygon_centroid(poly);
                    struct vec3 q =
                        vec3_add(c, vec3_scale(vec3_sub(poly->v[i / 5 % poly->n], c), 3 * rng_uniform(&r) - 1));
                    /* 3e3: every light subtends below 1e-7 sr there, so
                       its rectangle is sampled by area. */
                    double off[] = { 0.0, 1e-9, -1e-9, 1e-3, -1e-3, 0.5, 3e3 };
                    p = vec3_madd(q, l->target.normal, off[i / 5 % 7]);
                }
                struct vec3 nrm = i % 7 == 0 ? vec3_make(0, 0, 0) : random_dir(&r);
                strategy_prepare(&s, &scratch, p, nrm, &pts[i]);
                for (int j = 0; j < 4; ++j) u[i][j] = unit_or_end(&r);
            }
            /* The same bytes in both before, so that unwritten lanes agree. */
            memset(one, 0x5a, sizeof one);
            memset(many, 0x5a, sizeof many);
            for (int i = 0; i < MANY_POINTS; ++i) ok_one[i] = strategy_sample(&s, &pts[i], u[i], &one[i]);
            /* Runs of every length around the chunk of 64, from varying
               offsets; ok[] prefilled both ways so that every lane must be
               written. */
            int off = rep % 3 == 0 ? 0 : (int)(rng_uniform(&r) * 50);
            const int sizes[] = { 0, 1, 63, 64, 65, 129, MANY_POINTS - 50 };
            int n = sizes[rep % 7];
            for (int fill = 0; fill < 2; ++fill) {
                for (int i = 0; i < MANY_POINTS; ++i) ok_many[i] = fill;
                strategy_sample_many(&s, pts + off, (const double(*)[4])(u + off), n, many + off, ok_many + off);
                int bad = 0;
                for (int i = off; i < off + n; ++i) {
                    if (ok_many[i] == ok_one[i] && light_sample_equal(&many[i], &one[i])) continue;
                    if (bad++ < 3)
                        fprintf(stderr,
                                "  %s, n = %d lane %d, p (%.17g, %.17g, %.17g) u %.17g %.17g %.17g %.17g:\n"
                                "    many ok %d light %d wi (%.17g, %.17g, %.17g) dist %.17g pdf %.17g\n"
                                "    one  ok %d light %d wi (%.17g, %.17g, %.17g) dist %.17g pdf %.17g\n",
                                strategy_names[kinds[k]], n, i - off, pts[i].p.x, pts[i].p.y, pts[i].p.z, u[i][0],
                                u[i][1], u[i][2], u[i][3], ok_many[i], many[i].light, many[i].wi.x, many[i].wi.y,
                                many[i].wi.z, many[i].dist, many[i].pdf_sa, ok_one[i], one[i].light, one[i].wi.x,
                                one[i].wi.y, one[i].wi.z, one[i].dist, one[i].pdf_sa);
                }
                CHECK_MSG(bad == 0, "%s, n = %d: %d points differ from strategy_sample", strategy_names[kinds[k]], n,
                          bad);
                for (int i = 0; i < MANY_POINTS; ++i)
                    if (i < off || i >= off + n) CHECK_MSG(ok_many[i] == fill, "ok[%d] outside the run written", i);
                if (bad) break;
            }
            for (int i = 0; i < MANY_POINTS; ++i) {
                if (ok_one[i]) ++n_ok, ++lights_hit[one[i].light >= 0 && one[i].light < 8 ? one[i].light : 7];
                else ++n_fail;
            }
        }
        /* Every light was sampled, and both outcomes occurred. */
        for (int l = 0; l < sc.n_lights && l < 8; ++l)
            CHECK_MSG(lights_hit[l] > 0, "%s: light %d never sampled", strategy_names[kinds[k]], l);
        CHECK(n_ok > 0);
        printf("  %s: %ld samples, %ld failures, as strategy_sample\n", strategy_names[kinds[k]], n_ok, n_fail);
        ts_close_strategy(&s, &scratch);
    }
    /* The strategies that keep per-point state in the scratch must not be
       batched (strategy_sample_many does not read the scratch). */
    const enum strategy_kind portal_kinds[] = { STRATEGY_PORTAL, STRATEGY_PROJECTION, STRATEGY_ANTISHADOW,
                                                STRATEGY_ANTISHADOW_EXACT };
    for (int k = 0; k < 4; ++k) {
        struct render_desc rd = cfg.render;
        rd.strategy = portal_kinds[k];
        struct strategy s;
        struct error err;
        if (!strategy_init(&s, &sc, &rd, &err)) {
            CHECK_MSG(false, "%s", err.message);
            continue;
        }
        CHECK_MSG(!strategy_batches(&s), "%s batches", strategy_names[portal_kinds[k]]);
        strategy_free(&s);
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

/* An octahedron of 8 triangles emitting outwards (a mesh light, one
   emitter) behind a square portal, beside a quad light: every strategy
   picks a triangle by power within the mesh light's pair, so the density
   of a direction is that of the triangle it reaches. */
static void test_mesh_light(void)
{
    struct test_scene ts;
    ts_init(&ts);
    struct vec3 c = vec3_make(0.05, 2.45, 0.0), ax[3] = { { 0.12, 0, 0 }, { 0, 0.1, 0 }, { 0, 0, 0.08 } };
    struct polygon tris[8];
    for (int i = 0; i < 8; ++i) {
        struct vec3 x = vec3_scale(ax[0], i & 1 ? -1 : 1), y = vec3_scale(ax[1], i & 2 ? -1 : 1),
                    z = vec3_scale(ax[2], i & 4 ? -1 : 1);
        /* Counter-clockwise seen from outside: x, y, z is right-handed for an even number of flips. */
        bool even = ((i & 1) + ((i >> 1) & 1) + ((i >> 2) & 1)) % 2 == 0;
        tris[i] = (struct polygon){ 3, { vec3_add(c, x), vec3_add(c, even ? y : z), vec3_add(c, even ? z : y) } };
    }
    struct polygon portal = square_y(0, 2.2, 0, 0.3, true);
    ts_add_mesh_light(&ts, tris, 8, warm, false, &portal, 1);
    int l = ts_add_light(&ts, square_y(1.2, 2.6, 0.3, 0.2, true), warm, false);
    ts_add_portal(&ts, l, square_y(1.2, 2.2, 0.3, 0.15, true));
    CHECK(ts.scene.n_emitters == 2 && ts.scene.n_lights == 9 && ts.scene.n_portals == 9);
    check_strategies(&ts, vec3_make(0.0, 0, 0.05), "mesh light below", 700, false);
    check_strategies(&ts, vec3_make(0.7, 0, -0.4), "mesh light penumbra", 800, false);
    check_strategies(&ts, vec3_make(0.15, 2.3, -0.1), "mesh light inside the shade", 900, true);
    /* The octahedron shows each point four faces and hides four: every
       strategy that picks triangles draws none of the hidden ones
       (light_culled), and gives them no density, while the chi-square
       runs above check the rest. */
    struct vec3 p = vec3_make(0.0, 0, 0.05), up = vec3_make(0, 1, 0);
    int hidden = 0;
    for (int i = 0; i < 8; ++i) hidden += light_culled(&ts.scene.lights[i], p, up);
    CHECK_MSG(hidden == 4, "%d faces hidden", hidden);
    for (int k = STRATEGY_PROJECTION; k <= STRATEGY_ANTISHADOW_EXACT; ++k) {
        struct render_desc rd;
        memset(&rd, 0, sizeof rd);
        rd.strategy = (enum strategy_kind)k;
        rd.portal_weight = PORTAL_WEIGHT_IRRADIANCE;
        struct strategy s;
        struct strategy_scratch scratch;
        if (!ts_open_strategy(&ts.scene, &rd, &s, &scratch)) continue;
        struct strategy_point pt;
        strategy_prepare(&s, &scratch, p, up, &pt);
        struct rng r;
        rng_seed(&r, 31, (uint64_t)k, 0);
        int drawn = 0, from_hidden = 0;
        for (int j = 0; j < 4000; ++j) {
            double u[4] = { rng_uniform(&r), rng_uniform(&r), rng_uniform(&r), rng_uniform(&r) };
            struct light_sample ls;
            if (!strategy_sample(&s, &pt, u, &ls) || ls.light < 0) continue;
            ++drawn;
            from_hidden += ls.light < 8 && light_culled(&ts.scene.lights[ls.light], p, up);
        }
        CHECK_MSG(drawn > 1000 && from_hidden == 0, "%s: %d samples, %d of hidden faces", strategy_names[k], drawn,
                  from_hidden);
        for (int i = 0; i < 8; ++i)
            if (light_culled(&ts.scene.lights[i], p, up))
                CHECK(strategy_pdf(&s, &pt, i, vec3_normalize(vec3_sub(ts.scene.lights[i].centroid, p))) == 0.0);
        ts_close_strategy(&s, &scratch);
    }
    ts_free(&ts);
}

/* The region of a mesh light's pair (strategy_pair_irradiance, as the
   region AOV asks) against the quad it tessellates: the same class at
   every point where the quad is outside, in the anti-umbra or in the
   anti-penumbra; in the quad's anti-antumbra the mesh says anti-antumbra
   or anti-penumbra (no one triangle need fill the portal). */
static void test_mesh_pair_region(void)
{
    for (int size = 0; size < 2; ++size) {
        double s_l = size ? 0.6 : 0.15;
        struct test_scene quad, mesh;
        lampshade(&quad, s_l);
        ts_init(&mesh);
        struct polygon sq = square_y(0, 2.6, 0, s_l, true), tris[4];
        struct vec3 mid = vec3_make(0.0, 2.6, 0.0);
        for (int k = 0; k < 4; ++k) tris[k] = (struct polygon){ 3, { sq.v[k], sq.v[(k + 1) % 4], mid } };
        struct polygon portal = square_y(0, 2.2, 0, 0.3, true);
        ts_add_mesh_light(&mesh, tris, 4, warm, false, &portal, 1);
        struct render_desc rd;
        memset(&rd, 0, sizeof rd);
        rd.strategy = STRATEGY_ANTISHADOW_EXACT;
        struct strategy sq_s, mesh_s;
        struct error err;
        CHECK(strategy_init(&sq_s, &quad.scene, &rd, &err) && strategy_init(&mesh_s, &mesh.scene, &rd, &err));
        struct rng r;
        rng_seed(&r, 4242, (uint64_t)size, 0);
        int counts[5] = { 0 }, mismatches = 0;
        for (int i = 0; i < 20000; ++i) {
            struct vec3 p = vec3_make(6 * rng_uniform(&r) - 3, 2.15 * rng_uniform(&r), 6 * rng_uniform(&r) - 3);
            enum region rq, rm;
            strategy_pair_irradiance(&sq_s, 0, p, vec3_make(0, 0, 0), &rq);
            strategy_pair_irradiance(&mesh_s, 0, p, vec3_make(0, 0, 0), &rm);
            ++counts[rq];
            bool ok = rq == REGION_ANTI_ANTUMBRA ? rm == REGION_ANTI_ANTUMBRA || rm == REGION_ANTI_PENUMBRA : rm == rq;
            if (!ok && mismatches++ < 5)
                fprintf(stderr, "  s_L %.2f (%.3f, %.3f, %.3f): quad %d mesh %d\n", s_l, p.x, p.y, p.z, rq, rm);
        }
        CHECK_MSG(mismatches == 0, "s_L %.2f: %d points where the mesh's region differs", s_l, mismatches);
        /* Every class the quad has here was visited. */
        CHECK(counts[REGION_OUTSIDE] > 0 && counts[REGION_ANTI_PENUMBRA] > 0);
        CHECK(counts[size ? REGION_ANTI_ANTUMBRA : REGION_ANTI_UMBRA] > 0);
        strategy_free(&sq_s);
        strategy_free(&mesh_s);
        ts_free(&quad);
        ts_free(&mesh);
    }
}

/* strategy_sample_begin and strategy_sample_finish_many give what
   strategy_sample gives, bit for bit, for the portal strategies as a film
   row uses them: each point prepared in the one scratch and begun at once
   (a visible rectangle is copied into pend),
   the waiting samples finished together after the last point (so that the
   scratch holds another point by then). With and without defensive
   sampling, on multi_lamp (single- and two-portal lamps, a portal-less
   light) and the lampshade (one pair). */
static void test_sample_begin_matches_one(void)
{
    const char *scenes[] = { "configs/scenes/multi_lamp.yaml", "configs/scenes/lampshade.yaml" };
    const enum strategy_kind kinds[] = { STRATEGY_PORTAL, STRATEGY_PROJECTION, STRATEGY_ANTISHADOW,
                                         STRATEGY_ANTISHADOW_EXACT };
    static struct strategy_point pts[MANY_POINTS];
    static struct strategy_pending pend[MANY_POINTS];
    static double u[MANY_POINTS][4];
    static struct light_sample one[MANY_POINTS], two[MANY_POINTS];
    static bool ok_one[MANY_POINTS], ok_two[MANY_POINTS];
    for (int c = 0; c < 2; ++c) {
        struct config cfg;
        struct scene sc;
        if (!test_scene_load(scenes[c], NULL, 0, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        for (int k = 0; k < 4; ++k) {
            for (int d = 0; d < 2; ++d) {
                struct render_desc rd = cfg.render;
                rd.strategy = kinds[k];
                rd.defensive = d ? 0.1 : 0.0;
                struct strategy s;
                struct strategy_scratch scratch;
                if (!ts_open_strategy(&sc, &rd, &s, &scratch)) continue;
                struct rng r;
                rng_seed(&r, 777, (uint64_t)(8 * c + 2 * k + d), 0);
                long waiting = 0, visible = 0, bad = 0, n_ok = 0;
                for (int rep = 0; rep < 5; ++rep) {
                    memset(one, 0x5a, sizeof one);
                    memset(two, 0x5a, sizeof two);
                    for (int i = 0; i < MANY_POINTS; ++i) {
                        struct vec3 lo = sc.bounds_lo, hi = sc.bounds_hi;
                        struct vec3 p =
                            vec3_make(lo.x + (hi.x - lo.x) * rng_uniform(&r), lo.y + (hi.y - lo.y) * rng_uniform(&r),
                                      lo.z + (hi.z - lo.z) * rng_uniform(&r));
                        struct vec3 nrm = i % 7 == 0 ? vec3_make(0, 0, 0) : random_dir(&r);
                        for (int j = 0; j < 4; ++j) u[i][j] = unit_or_end(&r);
                        strategy_prepare(&s, &scratch, p, nrm, &pts[i]);
                        ok_one[i] = strategy_sample(&s, &pts[i], u[i], &one[i]);
                        ok_two[i] = strategy_sample_begin(&s, &pts[i], u[i], &two[i], &pend[i]);
                        waiting += pend[i].waiting;
                        /* A copy of the point's visible rectangle, which the
                           next point's preparation overwrites in the scratch. */
                        visible += pend[i].waiting && pend[i].target == &pend[i].visible;
                    }
                    strategy_sample_finish_many(&s, pts, (const double(*)[4])u, pend, MANY_POINTS, two, ok_two);
                    for (int i = 0; i < MANY_POINTS; ++i) {
                        n_ok += ok_one[i];
                        if (ok_one[i] == ok_two[i] && (!ok_one[i] || light_sample_equal(&one[i], &two[i]))) continue;
                        if (bad++ < 3)
                            fprintf(stderr, "  %s %s defensive %d lane %d: ok %d / %d, pdf %.17g / %.17g\n", scenes[c],
                                    strategy_names[kinds[k]], d, i, ok_one[i], ok_two[i], one[i].pdf_sa, two[i].pdf_sa);
                    }
                }
                CHECK_MSG(bad == 0, "%s %s: %ld samples differ from strategy_sample", scenes[c],
                          strategy_names[kinds[k]], bad);
                CHECK(n_ok > 0);
                /* The exact strategies sample whole rectangles somewhere. */
                if (kinds[k] == STRATEGY_ANTISHADOW_EXACT) CHECK_MSG(waiting > 0, "%s: no sample waited", scenes[c]);
                /* The lampshade's box pair clips to rectangles. */
                if (kinds[k] == STRATEGY_ANTISHADOW_EXACT && c == 1)
                    CHECK_MSG(visible > 0, "%s: no visible rectangle waited", scenes[c]);
                printf("  %s %s defensive %.1f: %ld of %d samples waited (%ld of a visible rectangle)\n", scenes[c],
                       strategy_names[kinds[k]], rd.defensive, waiting, 5 * MANY_POINTS, visible);
                ts_close_strategy(&s, &scratch);
            }
        }
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* A path inside the lampshade meets the inner face of the shade's bottom
   plate, which lies in the portal's plane (y = 2.2). The hit point is
   computed from Embree's float distance, so it lands up to ~1e-7 above or
   below that plane. Seen from either, the point is inside the shade (its
   normal faces the lamp), and every portal strategy must be able to sample
   the lamp there: a zero density makes every BSDF ray that reaches the lamp
   count with MIS weight 1, the lamp's whole radiance (the fireflies of
   lampshade_ratio_path at ratio 0.25). */
static void test_point_on_portal_plane_inside(void)
{
    struct config cfg;
    struct scene sc;
    struct config_override ov[] = { { "params.s_L", "0.075" } };
    if (!test_scene_load("configs/scenes/lampshade.yaml", ov, 1, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    const enum strategy_kind kinds[] = { STRATEGY_ANTISHADOW_EXACT, STRATEGY_ANTISHADOW, STRATEGY_PORTAL,
                                         STRATEGY_PROJECTION };
    const struct vec3 up = { 0, 1, 0 }, lamp = { 0, 2.6, 0 };
    const double dy[] = { -2e-7, -1e-12, 0.0, 1e-12, 2e-7 };
    for (int k = 0; k < 4; ++k) {
        struct render_desc rd = cfg.render;
        rd.strategy = kinds[k];
        struct strategy s;
        struct strategy_scratch scratch;
        if (!ts_open_strategy(&sc, &rd, &s, &scratch)) continue;
        for (int i = 0; i < 5; ++i) {
            /* On the plate between the opening (|x| < 0.15) and the wall (0.2). */
            struct vec3 p = { 0.17, 2.2 + dy[i], 0.03 };
            struct strategy_point pt;
            strategy_prepare(&s, &scratch, p, up, &pt);
            struct vec3 wi = vec3_normalize(vec3_sub(lamp, p));
            double pdf = strategy_pdf(&s, &pt, 0, wi);
            bool classifies = kinds[k] == STRATEGY_ANTISHADOW_EXACT || kinds[k] == STRATEGY_ANTISHADOW;
            if (classifies)
                CHECK_MSG(pdf > 0.0, "%s, %.0e off the plane: density 0 towards the lamp", strategy_names[kinds[k]],
                          dy[i]);
        }
        ts_close_strategy(&s, &scratch);
    }
    printf(
        "  lamp density from the inner face of the shade's plate: 4 strategies x 5 heights about the portal plane\n");
    scene_destroy(&sc);
    config_free(&cfg);
}

static const struct test_case tests[] = {
    { "mesh_pair_region", test_mesh_pair_region },
    { "mesh_light", test_mesh_light },
    { "lampshade_regions", test_lampshade_regions },
    { "tilted_pentagon", test_tilted_pentagon },
    { "many_lights", test_many_lights },
    { "power_selection", test_power_selection },
    { "outside_returns_nothing", test_outside_returns_nothing },
    { "light_culled_draws_nothing", test_light_culled_draws_nothing },
    { "point_unlit_is_conservative", test_point_unlit_is_conservative },
    { "sample_many_matches_one", test_sample_many_matches_one },
    { "sample_begin_matches_one", test_sample_begin_matches_one },
    { "point_on_portal_plane_inside", test_point_on_portal_plane_inside },
};
TEST_MAIN(tests)

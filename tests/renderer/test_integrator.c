/* test_integrator.c: integrator_radiance_row, the row-at-a-time path the
   render threads take (direct lighting with a batching strategy draws the
   row's light samples together), against integrator_radiance_from pixel by
   pixel: same radiance bit for bit, same random streams afterwards, same
   counters, on film rows of the lampshade scene (and, for the portal
   strategies, of multi_lamp and little_lamp) built exactly as render.c's
   render_row builds them. */
#include <string.h>

#include "scene/camera.h"
#include "config/config.h"
#include "sampling/integrator.h"
#include "scene/scene.h"
#include "scene_util.h"
#include "sampling/strategy.h"
#include "testlib.h"

#define SCENE "configs/scenes/lampshade.yaml"

/* What the rows' camera rays hit: each kind of surface must be among them
   for the comparison to cover it. */
struct coverage {
    long light, floor, red, green, shade, other, miss;
    long lit; /* pixels with non-zero radiance */
    long shadow_rays, unblocked;
};

static void classify(const struct config *cfg, const struct hit *h, bool found, struct coverage *cov)
{
    if (!found) {
        ++cov->miss;
        return;
    }
    if (h->light >= 0) {
        ++cov->light;
        return;
    }
    /* The shade: |x|, |z| <= a, 2.2 <= y <= 2.65 (a = 0.35 for s_L = 0.6). */
    const double a = 0.35 + 1e-6;
    const char *name = cfg->materials[h->material].name;
    if (fabs(h->p.x) <= a && fabs(h->p.z) <= a && h->p.y >= 2.2 - 1e-6 && h->p.y <= 2.65 + 1e-6) ++cov->shade;
    else if (fabs(h->p.y) < 1e-6) ++cov->floor;
    else if (!strcmp(name, "red")) ++cov->red;
    else if (!strcmp(name, "green")) ++cov->green;
    else ++cov->other;
}

/* One configuration of integrator and strategy on rows `rows` of the film
   seen by cfg's camera, for two passes. */
static void compare_rows(const struct config *cfg, const struct scene *sc, enum integrator_kind kind,
                         enum strategy_kind strategy, enum mis_kind mis, const int *rows, int n_rows,
                         struct coverage *cov)
{
    struct render_desc rd = cfg->render;
    rd.integrator = kind;
    rd.strategy = strategy;
    rd.mis = mis;
    struct strategy s;
    struct strategy_scratch scratch_row, scratch_one;
    struct error err;
    if (!strategy_init(&s, sc, &rd, &err) || !strategy_scratch_init(&s, &scratch_row, &err) ||
        !strategy_scratch_init(&s, &scratch_one, &err)) {
        CHECK_MSG(false, "%s", err.message);
        return;
    }
    struct integrator it;
    integrator_init(&it, &rd, sc, &s);
    struct camera cam;
    camera_init(&cam, &cfg->camera, cfg->width, cfg->height);
    int w = cfg->width;
    struct integrator_row *row = integrator_row_create(w, &err);
    struct sampler *rng_row = malloc(sizeof *rng_row * (size_t)w), *rng_one = malloc(sizeof *rng_one * (size_t)w);
    struct vec3 *d = malloc(sizeof *d * (size_t)w);
    struct hit *hits = malloc(sizeof *hits * (size_t)w);
    bool *found = malloc(sizeof *found * (size_t)w);
    struct rgb *out_row = malloc(sizeof *out_row * (size_t)w), *out_one = malloc(sizeof *out_one * (size_t)w);
    if (!rng_row || !rng_one || !d || !hits || !found || !out_row || !out_one || !row) {
        CHECK_MSG(false, "out of memory");
        goto done;
    }
    const char *what = strategy_names[strategy];
    const char *ik = kind == INTEGRATOR_DIRECT ? "direct" : "path";
    for (int pass = 0; pass < 2; ++pass)
        for (int r = 0; r < n_rows; ++r) {
            int y = rows[r];
            /* The row as render_row builds it: one stream per (pixel, pass),
               seeded from the config's seed, the jitter drawn first. */
            for (int x = 0; x < w; ++x) {
                sampler_start(&rng_row[x], cfg->render.sampler, cfg->render.seed,
                              (uint64_t)y * (uint64_t)w + (uint64_t)x, (uint64_t)(3 * pass));
                double j[2];
                sampler_camera(&rng_row[x], j);
                d[x] = camera_ray(&cam, x + j[0], y + j[1]);
                found[x] = scene_intersect(sc, cam.origin, d[x], INFINITY, &hits[x]);
                if (pass == 0) classify(cfg, &hits[x], found[x], cov);
                rng_one[x] = rng_row[x];
            }
            struct integrator_stats st_row, st_one;
            memset(&st_row, 0, sizeof st_row);
            memset(&st_one, 0, sizeof st_one);
            integrator_radiance_row(&it, row, &scratch_row, d, hits, found, w, rng_row, out_row, &st_row);
            for (int x = 0; x < w; ++x)
                out_one[x] = integrator_radiance_from(&it, &scratch_one, cam.origin, d[x], found[x] ? &hits[x] : NULL,
                                                      &rng_one[x], &st_one);
            int bad = 0;
            for (int x = 0; x < w; ++x) {
                bool same = same_bits(out_row[x].r, out_one[x].r) && same_bits(out_row[x].g, out_one[x].g) &&
                            same_bits(out_row[x].b, out_one[x].b);
                /* The streams must end where the one-pixel path leaves them:
                   the next pass's or bounce's draws depend on it. */
                bool same_rng =
                    rng_row[x].rng.state == rng_one[x].rng.state && rng_row[x].rng.inc == rng_one[x].rng.inc;
                if (!rgb_is_black(out_one[x])) ++cov->lit;
                if (same && same_rng) continue;
                struct vec3 hp = found[x] ? hits[x].p : vec3_make(0, 0, 0);
                if (bad++ < 3)
                    fprintf(
                        stderr,
                        "  %s/%s row %d pass %d pixel %d (hit %d, light %d, p (%.9g, %.9g, %.9g)): row (%.17g, %.17g, "
                        "%.17g) vs one (%.17g, %.17g, %.17g), rng %s\n",
                        ik, what, y, pass, x, found[x], found[x] ? hits[x].light : -1, hp.x, hp.y, hp.z, out_row[x].r,
                        out_row[x].g, out_row[x].b, out_one[x].r, out_one[x].g, out_one[x].b,
                        same_rng ? "same" : "differs");
            }
            CHECK_MSG(bad == 0, "%s/%s row %d pass %d: %d pixels differ", ik, what, y, pass, bad);
            CHECK_MSG(st_row.rays == st_one.rays && st_row.shadow_rays == st_one.shadow_rays &&
                          st_row.shadow_blocked == st_one.shadow_blocked &&
                          st_row.light_samples == st_one.light_samples && st_row.light_missed == st_one.light_missed,
                      "%s/%s row %d pass %d: stats rays %llu/%llu shadow %llu/%llu blocked %llu/%llu samples %llu/%llu "
                      "missed %llu/%llu",
                      ik, what, y, pass, (unsigned long long)st_row.rays, (unsigned long long)st_one.rays,
                      (unsigned long long)st_row.shadow_rays, (unsigned long long)st_one.shadow_rays,
                      (unsigned long long)st_row.shadow_blocked, (unsigned long long)st_one.shadow_blocked,
                      (unsigned long long)st_row.light_samples, (unsigned long long)st_one.light_samples,
                      (unsigned long long)st_row.light_missed, (unsigned long long)st_one.light_missed);
            cov->shadow_rays += (long)st_one.shadow_rays;
            cov->unblocked += (long)(st_one.shadow_rays - st_one.shadow_blocked);
        }
done:
    integrator_row_destroy(row);
    free(rng_row);
    free(rng_one);
    free(d);
    free(hits);
    free(found);
    free(out_row);
    free(out_one);
    strategy_scratch_free(&scratch_row);
    strategy_scratch_free(&scratch_one);
    strategy_free(&s);
}

static const struct {
    enum integrator_kind kind;
    enum strategy_kind strategy;
    enum mis_kind mis;
} combos[] = {
    { INTEGRATOR_DIRECT, STRATEGY_LIGHT, MIS_POWER },
    { INTEGRATOR_DIRECT, STRATEGY_LIGHT_AREA, MIS_POWER },
    { INTEGRATOR_DIRECT, STRATEGY_ANTISHADOW_EXACT, MIS_POWER },
    { INTEGRATOR_PATH, STRATEGY_LIGHT, MIS_POWER },
    /* The wavefront path: portal strategies re-prepare a vertex whose BSDF
       ray reaches the light; without MIS that light counts nothing. */
    { INTEGRATOR_PATH, STRATEGY_ANTISHADOW_EXACT, MIS_POWER },
    { INTEGRATOR_PATH, STRATEGY_PORTAL, MIS_BALANCE },
    { INTEGRATOR_PATH, STRATEGY_LIGHT, MIS_NONE },
    /* The batched direct path without the BSDF half. */
    { INTEGRATOR_DIRECT, STRATEGY_LIGHT, MIS_NONE },
};
#define N_COMBOS (int)(sizeof combos / sizeof combos[0])

/* The scene's own camera: rows through the ceiling and back wall (60), the
   shade (100), the back wall and side walls (128) and the floor (200). */
static void test_row_matches_pixels(void)
{
    struct config cfg;
    struct scene sc;
    if (!test_scene_load(SCENE, NULL, 0, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    CHECK(cfg.width == 256 && cfg.height == 256);
    const int rows[] = { 60, 100, 128, 200 };
    for (int c = 0; c < N_COMBOS; ++c) {
        struct coverage cov;
        memset(&cov, 0, sizeof cov);
        compare_rows(&cfg, &sc, combos[c].kind, combos[c].strategy, combos[c].mis, rows, 4, &cov);
        CHECK_MSG(cov.floor > 0 && cov.red > 0 && cov.green > 0 && cov.shade > 0 && cov.other > 0 && cov.lit > 0,
                  "rows miss a surface: floor %ld red %ld green %ld shade %ld other %ld lit %ld", cov.floor, cov.red,
                  cov.green, cov.shade, cov.other, cov.lit);
        /* Next-event estimation ran and delivered light (not a vacuous
           comparison). */
        CHECK_MSG(cov.unblocked > 0, "%s: no unblocked shadow ray", strategy_names[combos[c].strategy]);
        if (c == 0)
            printf(
                "  scene camera, rows 60 100 128 200: floor %ld, red wall %ld, green wall %ld, shade %ld, other %ld, "
                "light %ld pixels\n",
                cov.floor, cov.red, cov.green, cov.shade, cov.other, cov.light);
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

/* The light is inside the shade: the scene's camera never sees it. A
   camera below the opening, looking up through it, sees the light itself
   (emission, no light sampling) next to the shade's underside. */
static void test_row_matches_pixels_light_seen(void)
{
    const struct config_override ov[] = {
        { "camera.position.1", "0.5" },
        { "camera.position.2", "1.0" },
        { "camera.look_at.1", "2.6" },
        { "camera.look_at.2", "-0.2" },
    };
    struct config cfg;
    struct scene sc;
    if (!test_scene_load(SCENE, ov, 4, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    const int rows[] = { 100, 128, 156 };
    for (int c = 0; c < N_COMBOS; ++c) {
        struct coverage cov;
        memset(&cov, 0, sizeof cov);
        compare_rows(&cfg, &sc, combos[c].kind, combos[c].strategy, combos[c].mis, rows, 3, &cov);
        CHECK_MSG(cov.light > 0 && cov.shade > 0, "rows miss the light (%ld) or the shade (%ld)", cov.light, cov.shade);
        /* The light's own pixels are bright (shading points here are the
           ceiling and the shade's underside, dark to next-event estimation). */
        CHECK(cov.lit >= cov.light);
        if (c == 0)
            printf("  camera below the opening, rows 100 128 156: light %ld, shade %ld, other %ld pixels\n", cov.light,
                   cov.shade, cov.floor + cov.red + cov.green + cov.other);
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

/* The portal strategies on the scenes with several lamps (multi_lamp:
   several pairs per point, the irradiance weight, a lamp without portal, a
   glossy box) and with a mesh light behind two portals (little_lamp):
   the row prepares and samples each point in turn and prepares a point
   again when its BSDF ray reaches a light, which must give the same bits
   as the one-pixel path. Rows spread over the image. */
static void test_row_matches_pixels_portal_scenes(void)
{
    static const char *const scenes[] = { "configs/scenes/multi_lamp.yaml", "configs/scenes/little_lamp.yaml" };
    static const enum strategy_kind kinds[] = { STRATEGY_ANTISHADOW_EXACT, STRATEGY_ANTISHADOW, STRATEGY_PORTAL,
                                                STRATEGY_PROJECTION };
    for (int i = 0; i < 2; ++i) {
        struct config cfg;
        struct scene sc;
        if (!test_scene_load(scenes[i], NULL, 0, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        int h = cfg.height;
        const int rows[] = { h / 8, h / 3, h / 2, 2 * h / 3, 7 * h / 8 };
        for (int k = 0; k < 4; ++k)
            for (int m = 0; m < 2; ++m) {
                struct coverage cov;
                memset(&cov, 0, sizeof cov);
                compare_rows(&cfg, &sc, INTEGRATOR_DIRECT, kinds[k], m ? MIS_NONE : MIS_POWER, rows, 5, &cov);
                /* Plain portal sampling rarely reaches the Little Lamp's
                   5 mm bulb: in these rows, never. */
                bool rare = i == 1 && kinds[k] == STRATEGY_PORTAL;
                CHECK_MSG(rare || (cov.unblocked > 0 && cov.lit > 0), "%s %s: no light delivered", scenes[i],
                          strategy_names[kinds[k]]);
            }
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

static const struct test_case integrator_tests[] = {
    { "row_matches_pixels", test_row_matches_pixels },
    { "row_matches_pixels_light_seen", test_row_matches_pixels_light_seen },
    { "row_matches_pixels_portal_scenes", test_row_matches_pixels_portal_scenes },
};

TEST_MAIN(integrator_tests)

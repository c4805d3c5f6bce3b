/* Direct radiance at floor points, estimated by every strategy through the
   full renderer (Embree visibility, MIS with BSDF sampling), against
   (1) the closed form on the lampshade scene: the light projected through
   the point onto the portal plane, clipped to the portal, and Lambert's
   polygon irradiance of that visible part; and (2) brute-force numerical
   integration over the lights, with ray-traced visibility, on the multi-lamp
   scene with its tilted portal. Agreement within 5 standard errors of each
   estimate (plus, for the brute force, its own discretisation error). */
#include <string.h>

#include "config/config.h"
#include "sampling/integrator.h"
#include "scene/scene.h"
#include "scene_util.h"
#include "sampling/strategy.h"
#include "direct_estimate.h"
#include "testlib.h"

static bool load_scene(const char *path, const char *s_l, struct config *cfg, struct scene *sc)
{
    struct config_override ov[] = { { "params.s_L", s_l } };
    return test_scene_load(path, ov, s_l ? 1 : 0, cfg, sc);
}

static int material_named(const struct config *cfg, const char *name)
{
    for (int i = 0; i < cfg->n_materials; ++i)
        if (!strcmp(cfg->materials[i].name, name)) return i;
    return -1;
}

/* Exact reflected radiance (red) at a floor point of the lampshade scene. */
static double lampshade_exact(const struct scene *sc, const struct config *cfg, int material, struct vec3 p)
{
    struct polygon vis;
    double albedo = cfg->materials[material].albedo.r;
    if (antishadow_visible_polygon(&sc->portals[0].antishadow, p, &vis) < 3) return 0.0;
    return albedo / M_PI * sc->lights[0].radiance.r * polygon_projected_solid_angle(&vis, p, vec3_make(0, 1, 0));
}

static void check_estimates(const struct scene *sc, const struct config *cfg, int material, struct vec3 p,
                            struct vec3 ng, double exact, double exact_err, const char *what)
{
    for (int k = 0; k < STRATEGY_COUNT; ++k) {
        struct render_desc rd = cfg->render;
        rd.integrator = INTEGRATOR_DIRECT;
        rd.mis = MIS_POWER;
        rd.strategy = (enum strategy_kind)k;
        struct estimate e = estimate_at(sc, &rd, p, ng, material, 40000, 17 + (uint64_t)k);
        double tol = 5.0 * e.se + exact_err + 1e-12 * fabs(exact);
        if (getenv("VERBOSE"))
            fprintf(stderr, "  %s %s: %.8g +- %.2g exact %.8g\n", what, strategy_names[k], e.mean, e.se, exact);
        CHECK_MSG(fabs(e.mean - exact) <= tol, "%s (%.3f, %.3f, %.3f) %s: %.6g +- %.2g vs exact %.6g (+- %.2g)", what,
                  p.x, p.y, p.z, strategy_names[k], e.mean, e.se, exact, exact_err);
        /* An estimate that is exactly right with zero variance is fine; one
           that is zero where light arrives is not. */
        if (exact > 0.0) CHECK_MSG(e.mean > 0.0, "%s %s: no light where light arrives", what, strategy_names[k]);
    }
}

/* Floor points in every region of the lampshade, and on region boundaries:
   s_L = 0.6 (anti-antumbra |x|, |z| < 0.676 at y = 0, penumbra to 2.6);
   s_L = 0.15 (anti-umbra |x|, |z| < 0.5625, penumbra to 1.39); s_L = 1.2. */
static void test_lampshade_closed_form(void)
{
    static const struct {
        const char *s_l;
        struct vec3 p;
    } cases[] = {
        { "0.6", { 0, 0, 0 } },       { "0.6", { -0.3, 0, 0.2 } },   { "0.6", { -0.676, 0, 0 } },
        { "0.6", { -1.0, 0, 0.4 } },  { "0.6", { 0, 0, 2.0 } },      { "0.6", { -2.55, 0, 0.3 } },
        { "0.6", { -2.9, 0, 0 } },    { "0.15", { 0.2, 0, 0.1 } },   { "0.15", { -0.5625, 0, 0 } },
        { "0.15", { -0.9, 0, 0.3 } }, { "0.15", { -2.0, 0, 0 } },    { "1.2", { 0, 0, -0.4 } },
        { "1.2", { -1.6, 0, 1.2 } },  { "0.3", { -0.25, 0, 0.25 } }, { "0.075", { 0.3, 0, -0.2 } },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        struct config cfg;
        struct scene sc;
        if (!load_scene("configs/scenes/lampshade.yaml", cases[i].s_l, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        int white = material_named(&cfg, "white");
        double exact = lampshade_exact(&sc, &cfg, white, cases[i].p);
        char what[64];
        snprintf(what, sizeof what, "s_L=%s region %d", cases[i].s_l,
                 (int)antishadow_classify(&sc.portals[0].antishadow, cases[i].p));
        check_estimates(&sc, &cfg, white, cases[i].p, vec3_make(0, 1, 0), exact, 0.0, what);
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* Inside the shade, on the inner face of its left wall (x = -a, normal +x):
   the light is seen directly, not through the portal; exact value from the
   light's own polygon. `portal` and `projection` sample through the portal
   only and are not expected to find this light (BSDF sampling does, by MIS,
   so their estimates stay unbiased: they are checked too). */
static void test_inside_shade(void)
{
    static const char *sizes[] = { "0.6", "0.15" };
    for (int i = 0; i < 2; ++i) {
        struct config cfg;
        struct scene sc;
        if (!load_scene("configs/scenes/lampshade.yaml", sizes[i], &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        int white = material_named(&cfg, "white");
        double a = fmax(atof(sizes[i]), 0.3) / 2 + 0.05; /* the shade's half-width */
        /* Mid-wall, and half a millimetre below the light's plane, where the
           light is seen at grazing angles (float precision of the light's
           plane must not let it shadow its own samples). */
        double heights[] = { 2.4, 2.6 - 5e-4 };
        for (int h = 0; h < 2; ++h) {
            struct vec3 p = vec3_make(-a, heights[h], 0.05), n = vec3_make(1, 0, 0);
            double exact = cfg.materials[white].albedo.r / M_PI * sc.lights[0].radiance.r *
                           polygon_projected_solid_angle(&sc.lights[0].target.polygon, p, n);
            check_estimates(&sc, &cfg, white, p, n, exact, 0.0, "inside the shade");
        }
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* One cell of the midpoint rules below: L_e cos cos / r^2 dA from point y
   of light li (cell area da) to p (normal n, rays leaving from origin),
   with ray-traced visibility. */
static double cell_contribution(const struct scene *sc, const struct light *li, struct vec3 origin, struct vec3 p,
                                struct vec3 n, struct vec3 y, double da)
{
    struct vec3 d = vec3_sub(y, p);
    double r2 = vec3_length2(d);
    struct vec3 w = vec3_scale(d, 1.0 / sqrt(r2));
    double cos_p = vec3_dot(w, n);
    double le = light_emitted(li, vec3_neg(w)).r;
    if (cos_p <= 0.0 || le == 0.0) return 0.0;
    if (test_segment_occluded(sc, origin, scene_offset_origin(sc, y, li->target.normal, vec3_neg(w)))) return 0.0;
    return le * cos_p * fabs(vec3_dot(w, li->target.normal)) / r2 * da;
}

/* Midpoint rule over each light (rectangles: g x g cells), with ray-traced
   visibility from the floor point: sum of L_e cos cos / r^2 dA. */
static double brute_force(const struct scene *sc, struct vec3 p, double albedo, int g)
{
    struct vec3 n = vec3_make(0, 1, 0);
    struct vec3 origin = scene_offset_origin(sc, p, n, n);
    double sum = 0.0;
    for (int l = 0; l < sc->n_lights; ++l) {
        const struct light *li = &sc->lights[l];
        if (!li->target.is_rectangle) return NAN;
        double da = li->target.area / ((double)g * g);
        for (int i = 0; i < g; ++i)
            for (int j = 0; j < g; ++j) {
                const struct sphrect_frame *f = &li->target.frame;
                struct vec3 y = vec3_add(f->corner, vec3_add(vec3_scale(f->x, f->ex_len * (i + 0.5) / g),
                                                             vec3_scale(f->y, f->ey_len * (j + 0.5) / g)));
                sum += cell_contribution(sc, li, origin, p, n, y, da);
            }
    }
    return albedo / M_PI * sum;
}

/* The multi-lamp scene: several lights, two portals on one light, a tilted
   portal, a light without portal. Points below the tilted opening. */
static void test_multi_lamp_brute_force(void)
{
    struct config cfg;
    struct scene sc;
    if (!load_scene("configs/scenes/multi_lamp.yaml", NULL, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    int white = material_named(&cfg, "white");
    struct vec3 points[] = { { 0.0, 0, 1.3 }, { 0.6, 0, 1.9 }, { -0.5, 0, 0.4 }, { -1.5, 0, -1.0 } };
    for (size_t i = 0; i < sizeof points / sizeof points[0]; ++i) {
        double fine = brute_force(&sc, points[i], cfg.materials[white].albedo.r, 320);
        double coarse = brute_force(&sc, points[i], cfg.materials[white].albedo.r, 160);
        /* Midpoint with a visibility edge: error ~ 1/g; twice the fine/coarse
           gap bounds it comfortably. */
        check_estimates(&sc, &cfg, white, points[i], vec3_make(0, 1, 0), fine, 2.0 * fabs(fine - coarse), "multi_lamp");
        /* The O(1) weight picks pairs otherwise, never where they give nothing. */
        struct config estimate = cfg;
        estimate.render.portal_weight = PORTAL_WEIGHT_IRRADIANCE_ESTIMATE;
        check_estimates(&sc, &estimate, white, points[i], vec3_make(0, 1, 0), fine, 2.0 * fabs(fine - coarse),
                        "multi_lamp irradiance_estimate");
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

/* The lampshade's lamp as a mesh light (good/mesh_light_grid.yaml: the
   same square as 12 unequal triangles) gives the quad lamp's closed form at
   floor points of every region: each strategy picks a triangle by power and
   classifies it on its own, so a point sees triangles of several regions. */
static void test_mesh_light_grid(void)
{
    struct config cfg, qcfg;
    struct scene sc, qsc;
    if (!load_scene("tests/configs/good/mesh_light_grid.yaml", NULL, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    if (!load_scene("configs/scenes/lampshade.yaml", "0.6", &qcfg, &qsc)) {
        CHECK(false);
        scene_destroy(&sc);
        config_free(&cfg);
        return;
    }
    CHECK(sc.n_emitters == 1 && sc.n_lights == 12 && sc.n_portals == 12);
    int white = material_named(&cfg, "white");
    struct vec3 points[] = { { 0, 0, 0 },      { -0.3, 0, 0.2 }, { -0.676, 0, 0 },
                             { -1.0, 0, 0.4 }, { 0, 0, 2.0 },    { -2.55, 0, 0.3 } };
    for (size_t i = 0; i < sizeof points / sizeof points[0]; ++i) {
        double exact = lampshade_exact(&qsc, &qcfg, material_named(&qcfg, "white"), points[i]);
        check_estimates(&sc, &cfg, white, points[i], vec3_make(0, 1, 0), exact, 0.0, "mesh light grid");
    }
    scene_destroy(&qsc);
    config_free(&qcfg);
    scene_destroy(&sc);
    config_free(&cfg);
}

/* Midpoint rule over every light triangle (each cut into g^2 triangles),
   with ray-traced visibility from p (normal n): sum of L_e cos cos / r^2 dA. */
static double brute_force_triangles(const struct scene *sc, struct vec3 p, struct vec3 n, double albedo, int g)
{
    struct vec3 origin = scene_offset_origin(sc, p, n, n);
    double sum = 0.0;
    for (int l = 0; l < sc->n_lights; ++l) {
        const struct light *li = &sc->lights[l];
        if (li->target.polygon.n != 3) return NAN;
        const struct vec3 *v = li->target.polygon.v;
        struct vec3 e1 = vec3_sub(v[1], v[0]), e2 = vec3_sub(v[2], v[0]);
        double da = li->target.area / ((double)g * g);
        for (int i = 0; i < g; ++i)
            for (int j = 0; i + j < g; ++j)
                for (int up = 0; up < (i + j < g - 1 ? 2 : 1); ++up) {
                    double a = (3.0 * i + 1.0 + up) / (3.0 * g), b = (3.0 * j + 1.0 + up) / (3.0 * g);
                    struct vec3 y = vec3_add(v[0], vec3_add(vec3_scale(e1, a), vec3_scale(e2, b)));
                    sum += cell_contribution(sc, li, origin, p, n, y, da);
                }
    }
    return albedo / M_PI * sum;
}

/* A round bulb (good/mesh_light_sphere.yaml: 80 triangles emitting
   outwards, moved off-centre by a transform) behind the square opening:
   floor points below and beside the opening, and a point inside the shade
   on the inner face of its left wall, against brute-force integration. */
static void test_mesh_light_sphere(void)
{
    struct config cfg;
    struct scene sc;
    if (!load_scene("tests/configs/good/mesh_light_sphere.yaml", NULL, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    CHECK(sc.n_emitters == 1 && sc.n_lights == 80);
    int white = material_named(&cfg, "white");
    double albedo = cfg.materials[white].albedo.r;
    static const struct {
        struct vec3 p, n;
    } cases[] = {
        { { 0.0, 0, 0.0 }, { 0, 1, 0 } }, { { 0.3, 0, -0.2 }, { 0, 1, 0 } },    { { -0.8, 0, 0.5 }, { 0, 1, 0 } },
        { { 0.0, 0, 1.6 }, { 0, 1, 0 } }, { { -0.35, 2.4, 0.0 }, { 1, 0, 0 } },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        double fine = brute_force_triangles(&sc, cases[i].p, cases[i].n, albedo, 24);
        double coarse = brute_force_triangles(&sc, cases[i].p, cases[i].n, albedo, 12);
        check_estimates(&sc, &cfg, white, cases[i].p, cases[i].n, fine, 2.0 * fabs(fine - coarse), "mesh light sphere");
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

static const struct test_case tests[] = {
    { "mesh_light_grid", test_mesh_light_grid },
    { "mesh_light_sphere", test_mesh_light_sphere },
    { "lampshade_closed_form", test_lampshade_closed_form },
    { "multi_lamp_brute_force", test_multi_lamp_brute_force },
    { "inside_shade", test_inside_shade },
};
TEST_MAIN(tests)

/* The region AOV: the classifier at chosen points of the lampshade (by
   light/portal ratio, inside the shade, back faces, a light without
   portals), and through full renders: the AOV agrees with the classifier
   at each pixel's hits, fractions sum to 1 (also with dropped samples), the
   radiance channels are the same bits with the AOV on or off, and the AOV
   is the same for every thread count and strategy. */
#include "render/aov.h"
#include "scene/camera.h"
#include "render_util.h"
#include "scene_util.h"
#include "testlib.h"

#define SCENE "configs/scenes/lampshade.yaml"
#define MULTI "configs/scenes/multi_lamp.yaml"

struct fixture {
    struct config cfg;
    struct scene sc;
    struct aov_classifier aov;
    struct aov_scratch scratch;
    struct camera cam;
};

static bool fixture_load(struct fixture *f, const char *path, const struct config_override *ov, int n)
{
    struct error err;
    if (!test_scene_load(path, ov, n, &f->cfg, &f->sc)) return false;
    if (!aov_classifier_init(&f->aov, &f->sc, &err) || !aov_scratch_init(&f->aov, &f->scratch, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        return false;
    }
    camera_init(&f->cam, &f->cfg.camera, f->cfg.width, f->cfg.height);
    return true;
}

static void fixture_free(struct fixture *f)
{
    aov_scratch_free(&f->scratch);
    aov_classifier_free(&f->aov);
    scene_destroy(&f->sc);
    config_free(&f->cfg);
}

static enum aov_region class_at(struct fixture *f, double x, double y, double z, double nx, double ny, double nz)
{
    return aov_classify_point(&f->aov, &f->scratch, vec3_make(x, y, z), vec3_make(nx, ny, nz));
}

/* The class of the camera ray through film position (px, py). */
static enum aov_region class_through(struct fixture *f, double px, double py)
{
    struct vec3 d = camera_ray(&f->cam, px, py);
    struct hit h;
    bool found = scene_intersect(&f->sc, f->cam.origin, d, INFINITY, &h);
    return aov_classify_hit(&f->aov, &f->scratch, d, found ? &h : NULL);
}

/* The pixel whose footprint holds world point p. */
static bool pixel_of(const struct camera *c, struct vec3 p, int *x, int *y)
{
    struct vec3 d = vec3_sub(p, c->origin);
    double depth = vec3_dot(d, c->forward);
    if (depth <= 0.0) return false;
    struct vec3 q = vec3_sub(vec3_scale(d, 1.0 / depth), c->top_left);
    double px = vec3_dot(q, c->dx) / vec3_dot(c->dx, c->dx), py = vec3_dot(q, c->dy) / vec3_dot(c->dy, c->dy);
    *x = (int)floor(px), *y = (int)floor(py);
    return *x >= 0 && *x < c->width && *y >= 0 && *y < c->height;
}

static float fraction(const struct film_image *img, int x, int y, int k)
{
    return img->region[AOV_REGION_COUNT * ((size_t)y * img->width + x) + k];
}

static int dominant(const struct film_image *img, int x, int y)
{
    int best = 0;
    for (int k = 1; k < AOV_REGION_COUNT; ++k)
        if (fraction(img, x, y, k) > fraction(img, x, y, best)) best = k;
    return best;
}

/* Every pixel's fractions sum to 1. */
static void check_sums(const struct film_image *img, const char *what)
{
    int bad = 0;
    for (int y = 0; y < img->height; ++y)
        for (int x = 0; x < img->width; ++x) {
            double sum = 0.0;
            for (int k = 0; k < AOV_REGION_COUNT; ++k) sum += fraction(img, x, y, k);
            bad += !(fabs(sum - 1.0) < 1e-6);
        }
    CHECK_MSG(bad == 0, "%s: %d pixels whose fractions do not sum to 1", what, bad);
}

/* Pixels whose centre and four inner corners all give the same class
   directly (the samples of a pixel fall between them): the AOV's dominant
   class there must be that class, with all of the pixel's samples. Counts
   such pixels per class into uniform[]. */
static void check_against_direct(struct fixture *f, const struct film_image *img, int uniform[AOV_REGION_COUNT],
                                 const char *what)
{
    static const double at[5][2] = { { 0.5, 0.5 }, { 0.02, 0.02 }, { 0.98, 0.02 }, { 0.02, 0.98 }, { 0.98, 0.98 } };
    int wrong = 0, partial = 0;
    memset(uniform, 0, sizeof(int) * AOV_REGION_COUNT);
    for (int y = 0; y < img->height; ++y)
        for (int x = 0; x < img->width; ++x) {
            enum aov_region c = class_through(f, x + at[0][0], y + at[0][1]);
            bool same = true;
            for (int k = 1; k < 5 && same; ++k) same = class_through(f, x + at[k][0], y + at[k][1]) == c;
            if (!same) continue;
            ++uniform[c];
            if (dominant(img, x, y) != (int)c) {
                if (wrong++ < 3)
                    fprintf(stderr, "  %s: pixel (%d, %d) is %s directly, %s in the AOV\n", what, x, y,
                            aov_region_names[c], aov_region_names[dominant(img, x, y)]);
            }
            partial += fraction(img, x, y, c) != 1.0f;
        }
    CHECK_MSG(wrong == 0, "%s: %d pixels disagree with the classifier", what, wrong);
    /* A boundary can pass between the corners, rarely. */
    CHECK_MSG(partial <= img->width * img->height / 100, "%s: %d uniform pixels with mixed samples", what, partial);
}

/* A render's final image with the AOV (region layer) and the overrides. */
static bool render_aov(const char *path, const struct config_override *extra, int n, struct film_image *img,
                       struct render_result *res)
{
    struct config_override ov[24];
    int m = 0;
    ov[m++] = (struct config_override){ "render.aov.region", "true" };
    ov[m++] = (struct config_override){ "render.snapshots.every_spp", "1000000" };
    for (int i = 0; i < n && m < 24; ++i) ov[m++] = extra[i];
    if (!render_to_image(path, ov, m, img, res)) return false;
    if (!img->region) {
        fprintf(stderr, "  %s: final.exr has no region channels\n", path);
        film_image_free(img);
        return false;
    }
    return true;
}

/* Below the lamp the floor sees the whole light through the opening when
   the light is small (ratio 0.25), and the whole opening filled by light
   when it is large (ratio 4); far to the side nothing comes through the
   small one. */
static void test_points_by_ratio(void)
{
    static const struct {
        const char *s_L;
        double x;
        enum aov_region want;
    } cases[] = {
        { "0.075", 0.0, AOV_REGION_ANTI_UMBRA },   { "0.075", -2.0, AOV_REGION_OUTSIDE },
        { "1.2", 0.0, AOV_REGION_ANTI_ANTUMBRA },  { "1.2", -2.0, AOV_REGION_ANTI_ANTUMBRA },
        { "0.6", -2.0, AOV_REGION_ANTI_PENUMBRA },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        struct config_override ov[] = { { "params.s_L", cases[i].s_L } };
        struct fixture f;
        if (!fixture_load(&f, SCENE, ov, 1)) {
            CHECK(false);
            continue;
        }
        enum aov_region got = class_at(&f, cases[i].x, 0, 0, 0, 1, 0);
        CHECK_MSG(got == cases[i].want, "s_L=%s floor x=%g: %s, expected %s", cases[i].s_L, cases[i].x,
                  aov_region_names[got], aov_region_names[cases[i].want]);
        /* The floor's underside receives nothing. */
        CHECK(class_at(&f, cases[i].x, 0, 0, 0, -1, 0) == AOV_REGION_OUTSIDE);
        fixture_free(&f);
    }
}

/* On the lit side of the floor, the class is the antishadow classifier's
   region of the scene's one pair wherever it is not outside. */
static void test_floor_matches_antishadow(void)
{
    static const char *const s_L[] = { "0.075", "0.6", "1.2" };
    for (int s = 0; s < 3; ++s) {
        struct config_override ov[] = { { "params.s_L", s_L[s] } };
        struct fixture f;
        if (!fixture_load(&f, SCENE, ov, 1)) {
            CHECK(false);
            continue;
        }
        int seen[AOV_REGION_COUNT] = { 0 }, wrong = 0;
        for (double x = -2.95; x < 3.0; x += 0.1)
            for (double z = -2.95; z < 3.0; z += 0.1) {
                struct vec3 p = vec3_make(x, 0, z);
                enum region r = antishadow_classify(&f.sc.portals[0].antishadow, p);
                enum aov_region c = class_at(&f, x, 0, z, 0, 1, 0);
                wrong += (int)c != (int)r;
                ++seen[c];
            }
        CHECK_MSG(wrong == 0, "s_L=%s: %d floor points differ from antishadow_classify", s_L[s], wrong);
        CHECK(seen[AOV_REGION_ANTI_PENUMBRA] > 0);
        CHECK(seen[s == 0 ? AOV_REGION_ANTI_UMBRA : AOV_REGION_ANTI_ANTUMBRA] > 0);
        fixture_free(&f);
    }
}

/* Inside the shade (the inner face of a side wall, the plate around the
   opening seen from above) the light is seen directly: inside. The outer
   face of the same wall sees nothing. A light hit is an emitter, a miss a
   miss. */
static void test_inside_emitter_miss(void)
{
    struct fixture f;
    if (!fixture_load(&f, SCENE, NULL, 0)) {
        CHECK(false);
        return;
    }
    double a = 0.35; /* the shade's half-width at s_L = 0.6 */
    CHECK(class_at(&f, -a, 2.4, 0, 1, 0, 0) == AOV_REGION_INSIDE);
    CHECK(class_at(&f, 0.25, 2.2 + 1e-9, 0.1, 0, 1, 0) == AOV_REGION_INSIDE);
    CHECK(class_at(&f, -a, 2.4, 0, -1, 0, 0) == AOV_REGION_OUTSIDE);
    struct hit h = { 1.0, vec3_make(0, 2.6, 0), vec3_make(0, -1, 0), -1, 0 };
    CHECK(aov_classify_hit(&f.aov, &f.scratch, vec3_make(0, 1, 0), &h) == AOV_REGION_EMITTER);
    CHECK(aov_classify_hit(&f.aov, &f.scratch, vec3_make(0, 1, 0), NULL) == AOV_REGION_MISS);
    fixture_free(&f);
}

/* Several lights: right under the ceiling panel (a light without portals)
   facing it, the panel carries most light: anti_umbra (it is seen whole);
   facing away from it, no light reaches the point: outside. */
static void test_light_without_portal(void)
{
    struct fixture f;
    if (!fixture_load(&f, MULTI, NULL, 0)) {
        CHECK(false);
        return;
    }
    CHECK(class_at(&f, 1.8, 3.5, 1.8, 0, 1, 0) == AOV_REGION_ANTI_UMBRA);
    CHECK(class_at(&f, 1.8, 3.5, 1.8, 0, -1, 0) == AOV_REGION_OUTSIDE);
    fixture_free(&f);
}

/* Through a full render: the pixel over the floor point below the lamp and
   the one far to the side have all their samples in the expected class. */
static void test_render_points_by_ratio(void)
{
    static const struct {
        const char *s_L;
        double x;
        enum aov_region want;
    } cases[] = {
        { "0.075", 0.0, AOV_REGION_ANTI_UMBRA },
        { "0.075", -2.0, AOV_REGION_OUTSIDE },
        { "1.2", 0.0, AOV_REGION_ANTI_ANTUMBRA },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        struct config_override ov[] = {
            { "params.s_L", cases[i].s_L }, { "film.width", "64" }, { "film.height", "64" }, { "render.spp", "4" }
        };
        struct fixture f;
        struct film_image img = { 0 };
        if (!fixture_load(&f, SCENE, ov, 4) || !render_aov(SCENE, ov, 4, &img, NULL)) {
            CHECK(false);
            continue;
        }
        int x = 0, y = 0;
        CHECK(pixel_of(&f.cam, vec3_make(cases[i].x, 0, 0), &x, &y));
        CHECK_MSG(fraction(&img, x, y, cases[i].want) == 1.0f, "s_L=%s pixel (%d, %d): %s %g, dominant %s",
                  cases[i].s_L, x, y, aov_region_names[cases[i].want], fraction(&img, x, y, cases[i].want),
                  aov_region_names[dominant(&img, x, y)]);
        film_image_free(&img);
        fixture_free(&f);
    }
}

/* Whole 32x32 renders against the classifier, pixel by pixel: the scene's
   camera (the room and its open side), a camera below the opening that
   sees the light through it, and one beside it that looks through the
   opening at the inside of the shade (its lit walls; the wall above the
   one-sided light and the plate's underside are outside). */
static void test_render_matches_classifier(void)
{
    static const struct config_override scene_camera[] = { { "film.width", "32" },
                                                           { "film.height", "32" },
                                                           { "render.spp", "8" } };
    static const struct config_override below[] = {
        { "film.width", "32" },         { "film.height", "32" },        { "render.spp", "8" },
        { "camera.position.1", "0.5" }, { "camera.position.2", "1.0" }, { "camera.look_at.1", "2.6" },
        { "camera.look_at.2", "-0.2" },
    };
    static const struct config_override beside[] = {
        { "film.width", "32" },          { "film.height", "32" },        { "render.spp", "8" },
        { "camera.position.0", "-1.5" }, { "camera.position.1", "1.2" }, { "camera.position.2", "0" },
        { "camera.look_at.0", "0.2" },   { "camera.look_at.1", "2.35" }, { "camera.look_at.2", "0" },
        { "camera.fov_y", "12" },
    };
    static const struct {
        const char *what;
        const struct config_override *ov;
        int n_ov;
        enum aov_region must[3];
    } views[] = {
        { "scene camera", scene_camera, 3, { AOV_REGION_MISS, AOV_REGION_ANTI_PENUMBRA, AOV_REGION_OUTSIDE } },
        { "camera below the opening", below, 7, { AOV_REGION_EMITTER, AOV_REGION_OUTSIDE, AOV_REGION_OUTSIDE } },
        { "camera beside the opening", beside, 10, { AOV_REGION_INSIDE, AOV_REGION_OUTSIDE, AOV_REGION_OUTSIDE } },
    };
    for (int v = 0; v < 3; ++v) {
        struct fixture f;
        struct film_image img = { 0 };
        if (!fixture_load(&f, SCENE, views[v].ov, views[v].n_ov) ||
            !render_aov(SCENE, views[v].ov, views[v].n_ov, &img, NULL)) {
            CHECK(false);
            continue;
        }
        int uniform[AOV_REGION_COUNT];
        check_sums(&img, views[v].what);
        check_against_direct(&f, &img, uniform, views[v].what);
        for (int k = 0; k < 3; ++k)
            CHECK_MSG(uniform[views[v].must[k]] > 0, "%s: no pixel entirely %s", views[v].what,
                      aov_region_names[views[v].must[k]]);
        film_image_free(&img);
        fixture_free(&f);
    }
}

static bool same_floats(const float *a, const float *b, size_t n)
{
    return a && b && !memcmp(a, b, n * sizeof(float));
}

/* The AOV changes nothing else: radiance and variance are the same bits
   with it on or off (and off writes no region channels); the AOV itself is
   the same for 1 and 3 threads, and for every strategy. */
static void test_bit_identical(void)
{
    static const char *const strategies[] = { "antishadow", "light", "antishadow_exact", "portal" };
    struct film_image base = { 0 };
    struct config_override ov[] = { { "film.width", "32" },          { "film.height", "32" },
                                    { "render.spp", "4" },           { "render.strategy", "antishadow" },
                                    { "render.threads", "2" },       { "render.integrator", "direct" },
                                    { "render.aov.region", "false" } };
    CHECK(render_to_image(SCENE, ov, 7, &base, NULL));
    CHECK(base.rgb && base.region == NULL);
    size_t n3 = (size_t)3 * 32 * 32, n7 = (size_t)AOV_REGION_COUNT * 32 * 32;
    struct film_image first = { 0 };
    for (int s = 0; s < 4; ++s)
        for (int t = 0; t < 2; ++t) {
            struct film_image img = { 0 }, off = { 0 };
            ov[3].value = strategies[s];
            ov[4].value = t == 0 ? "1" : "3";
            ov[5].value = s == 1 ? "path" : "direct";
            if (!render_aov(SCENE, ov, 6, &img, NULL)) {
                CHECK(false);
                continue;
            }
            if (!(s == 0 && t == 0)) CHECK(render_to_image(SCENE, ov, 7, &off, NULL));
            const struct film_image *ref = s == 0 && t == 0 ? &base : &off;
            CHECK_MSG(same_floats(img.rgb, ref->rgb, n3) && same_floats(img.variance, ref->variance, n3),
                      "%s, %s threads: radiance differs with the AOV on", strategies[s], ov[4].value);
            if (!first.region) first = img;
            else {
                CHECK_MSG(same_floats(img.region, first.region, n7), "%s, %s threads: another AOV", strategies[s],
                          ov[4].value);
                film_image_free(&img);
            }
            film_image_free(&off);
        }
    film_image_free(&first);
    film_image_free(&base);
}

/* Dropped non-finite samples are not counted: each pixel's classes still
   sum to its own sample count. */
static void test_dropped_samples(void)
{
    struct config_override ov[] = { { "film.width", "16" }, { "film.height", "16" }, { "render.spp", "8" } };
    struct film_image img = { 0 };
    struct render_result res;
    setenv("PORTAL_LIGHTS_FAULT_NONFINITE", "5", 1);
    bool ok = render_aov(SCENE, ov, 3, &img, &res);
    unsetenv("PORTAL_LIGHTS_FAULT_NONFINITE");
    CHECK(ok);
    if (!ok) return;
    CHECK_MSG(res.nonfinite_samples > 100, "only %llu samples dropped", (unsigned long long)res.nonfinite_samples);
    check_sums(&img, "with dropped samples");
    film_image_free(&img);
}

static const struct test_case tests[] = {
    { "points_by_ratio", test_points_by_ratio },
    { "floor_matches_antishadow", test_floor_matches_antishadow },
    { "inside_emitter_miss", test_inside_emitter_miss },
    { "light_without_portal", test_light_without_portal },
    { "render_points_by_ratio", test_render_points_by_ratio },
    { "render_matches_classifier", test_render_matches_classifier },
    { "bit_identical", test_bit_identical },
    { "dropped_samples", test_dropped_samples },
};
TEST_MAIN(tests)

/* End-to-end properties of the renderer on the lampshade scene at a small
   resolution: determinism across thread counts, direct == path(max_depth 1),
   and agreement of estimators within their own measured variance. */
#include "render_util.h"
#include "testlib.h"

#define SCENE "configs/scenes/lampshade.yaml"

static const struct config_override small[] = {
    { "film.width", "32" },
    { "film.height", "32" },
    { "render.snapshots.every_spp", "1000000" },
};

static bool render_small(const char *k1, const char *v1, const char *k2, const char *v2, const char *k3, const char *v3,
                         struct film_image *img)
{
    struct config_override ov[8];
    int n = 0;
    for (size_t i = 0; i < sizeof small / sizeof small[0]; ++i) ov[n++] = small[i];
    if (k1) ov[n++] = (struct config_override){ k1, v1 };
    if (k2) ov[n++] = (struct config_override){ k2, v2 };
    if (k3) ov[n++] = (struct config_override){ k3, v3 };
    return render_to_image(SCENE, ov, n, img, NULL);
}

static bool bit_identical(const struct film_image *a, const struct film_image *b)
{
    size_t n = (size_t)3 * a->width * a->height;
    return a->width == b->width && a->height == b->height && !memcmp(a->rgb, b->rgb, n * sizeof(float)) &&
           !memcmp(a->variance, b->variance, n * sizeof(float));
}

/* Same seed and sample count: 1, 2 and 3 threads give the same bits. */
static void test_threads_bit_identical(void)
{
    struct film_image a = { 0 }, b = { 0 }, c = { 0 };
    CHECK(render_small("render.threads", "1", "render.spp", "8", "render.integrator", "path", &a));
    CHECK(render_small("render.threads", "2", "render.spp", "8", "render.integrator", "path", &b));
    CHECK(render_small("render.threads", "3", "render.spp", "8", "render.integrator", "path", &c));
    CHECK(bit_identical(&a, &b));
    CHECK(bit_identical(&a, &c));
    film_image_free(&a), film_image_free(&b), film_image_free(&c);
}

/* A different seed changes the image (the test above could not fail if the
   seed were ignored and the image constant). */
static void test_seed_changes_image(void)
{
    struct film_image a = { 0 }, b = { 0 };
    CHECK(render_small("render.seed", "1", "render.spp", "4", NULL, NULL, &a));
    CHECK(render_small("render.seed", "2", "render.spp", "4", NULL, NULL, &b));
    CHECK(!bit_identical(&a, &b));
    film_image_free(&a), film_image_free(&b);
}

/* The path tracer stopped after one bounce draws the same random numbers
   as the direct integrator, so the images must be identical bit for bit. */
static void test_direct_equals_path_depth1(void)
{
    static const char *strategies[] = { "light", "antishadow_exact" };
    for (int s = 0; s < 2; ++s) {
        struct film_image a = { 0 }, b = { 0 };
        struct config_override ov[] = { small[0],
                                        small[1],
                                        small[2],
                                        { "render.spp", "8" },
                                        { "render.strategy", strategies[s] },
                                        { "render.integrator", "direct" } };
        CHECK(render_to_image(SCENE, ov, 6, &a, NULL));
        struct config_override ov2[] = { small[0],
                                         small[1],
                                         small[2],
                                         { "render.spp", "8" },
                                         { "render.strategy", strategies[s] },
                                         { "render.integrator", "path" },
                                         { "render.max_depth", "1" },
                                         { "render.rr_depth", "5" } };
        CHECK(render_to_image(SCENE, ov2, 8, &b, NULL));
        CHECK_MSG(bit_identical(&a, &b), "strategy %s", strategies[s]);
        film_image_free(&a), film_image_free(&b);
    }
}

/* Light sampling with and without MIS, and area vs solid-angle sampling,
   estimate the same image: block means agree within 5 sigma of their own
   variance estimates. */
static void test_estimators_agree(void)
{
    struct film_image ref = { 0 };
    CHECK(render_small("render.spp", "256", "render.mis", "power", "render.strategy", "light", &ref));
    static const char *const variants[][2] = {
        { "mis", "none" },
        { "mis", "balance" },
        { "strategy", "light_area" },
    };
    for (int v = 0; v < 3; ++v) {
        struct film_image img = { 0 };
        char key[64];
        snprintf(key, sizeof key, "render.%s", variants[v][0]);
        CHECK(render_small("render.spp", "256", key, variants[v][1], "render.seed", "7", &img));
        double z = images_max_block_z(&ref, &img, 4);
        /* 64 blocks x 3 channels: 5 sigma keeps the false-alarm rate ~1e-4. */
        CHECK_MSG(z < 5.0, "%s=%s: max block z = %.2f", key, variants[v][1], z);
        film_image_free(&img);
    }
    film_image_free(&ref);
}

/* Every strategy converges to the image of `light`, on the lampshade (two
   light/portal ratios) and on the multi-lamp scene: block means agree within
   5 sigma and the relMSE between the renders stays below its expectation
   from their own variances plus 5 standard deviations. */
static void test_strategies_same_image(void)
{
    static const char *const scenes[][2] = {
        { "configs/scenes/lampshade.yaml", "0.6" },
        { "configs/scenes/lampshade.yaml", "1.2" },
        { "configs/scenes/multi_lamp.yaml", NULL },
    };
    for (int sc = 0; sc < 3; ++sc) {
        struct config_override base[] = { small[0],
                                          small[1],
                                          small[2],
                                          { "render.spp", "512" },
                                          { "render.integrator", "direct" },
                                          { "render.strategy", "light" },
                                          { "params.s_L", scenes[sc][1] } };
        int nb = scenes[sc][1] ? 7 : 6;
        struct film_image ref = { 0 };
        CHECK(render_to_image(scenes[sc][0], base, nb, &ref, NULL));
        for (int k = 0; k < STRATEGY_COUNT; ++k) {
            if (k == STRATEGY_LIGHT) continue;
            struct film_image img = { 0 };
            base[5].value = strategy_names[k];
            base[3].value = k == STRATEGY_LIGHT_AREA || k == STRATEGY_PORTAL ? "512" : "256";
            struct config_override seeded[8];
            memcpy(seeded, base, sizeof base);
            seeded[nb] = (struct config_override){ "render.seed", "5" };
            CHECK(render_to_image(scenes[sc][0], seeded, nb + 1, &img, NULL));
            double z = images_max_block_z(&ref, &img, 4), rel, bound;
            images_relmse(&img, &ref, 5.0, &rel, &bound);
            CHECK_MSG(z < 5.0, "%s s_L=%s %s: max block z = %.2f", scenes[sc][0], scenes[sc][1] ? scenes[sc][1] : "-",
                      strategy_names[k], z);
            CHECK_MSG(rel <= bound, "%s s_L=%s %s: relMSE %.3g > bound %.3g", scenes[sc][0],
                      scenes[sc][1] ? scenes[sc][1] : "-", strategy_names[k], rel, bound);
            film_image_free(&img);
        }
        film_image_free(&ref);
    }
}

static const struct test_case tests[] = {
    { "strategies_same_image", test_strategies_same_image },
    { "threads_bit_identical", test_threads_bit_identical },
    { "seed_changes_image", test_seed_changes_image },
    { "direct_equals_path_depth1", test_direct_equals_path_depth1 },
    { "estimators_agree", test_estimators_agree },
};
TEST_MAIN(tests)

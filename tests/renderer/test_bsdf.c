/* BSDF models: sampled directions follow the reported pdf (chi-square),
   sample() agrees with eval()/pdf(), reciprocity, and energy: a white
   Lambertian reflects exactly its albedo, GGX never more than 1. */
#include "scene/bsdf.h"
#include "chi2.h"
#include "testlib.h"

struct bsdf_ctx {
    struct material m;
    struct vec3 wo;
};

static bool sample_dir(void *ctx, double u1, double u2, double u3, struct vec3 *dir)
{
    struct bsdf_ctx *c = ctx;
    (void)u3;
    struct bsdf_sample s;
    if (!bsdf_sample(&c->m, c->wo, u1, u2, &s)) return false;
    *dir = s.wi;
    return true;
}

static double pdf_dir(void *ctx, struct vec3 dir)
{
    struct bsdf_ctx *c = ctx;
    return bsdf_pdf(&c->m, c->wo, dir);
}

static struct vec3 dir_from_angles(double theta_deg, double phi_deg)
{
    double t = theta_deg * M_PI / 180.0, p = phi_deg * M_PI / 180.0;
    return vec3_make(sin(t) * cos(p), sin(t) * sin(p), cos(t));
}

static const struct material lambert = { MATERIAL_DIFFUSE, { 0.5, 0.6, 0.7 }, 0.0 };

static void test_chi2_sampling(void)
{
    struct bsdf_ctx cases[] = {
        { lambert, { 0, 0, 1 } },
        { { MATERIAL_GGX, { 0.9, 0.9, 0.9 }, 0.5 }, { 0, 0, 1 } },
        { { MATERIAL_GGX, { 0.9, 0.9, 0.9 }, 0.2 }, { 0, 0, 1 } },
        { { MATERIAL_GGX, { 0.9, 0.9, 0.9 }, 0.2 }, { 0, 0, 1 } },
        { { MATERIAL_GGX, { 0.9, 0.9, 0.9 }, 0.05 }, { 0, 0, 1 } },
    };
    cases[1].wo = dir_from_angles(30, 10);
    cases[2].wo = dir_from_angles(60, 70);
    cases[3].wo = dir_from_angles(85, 0);
    cases[4].wo = dir_from_angles(40, 200);
    int n = (int)(sizeof cases / sizeof cases[0]);
    for (int i = 0; i < n; ++i) {
        struct chi2_config cfg;
        /* Glossy lobes are narrow: centre a cap on the mirror direction. */
        struct vec3 wo = cases[i].wo, mirror = vec3_make(-wo.x, -wo.y, wo.z);
        double cap = cases[i].m.kind == MATERIAL_DIFFUSE ? M_PI : (cases[i].m.roughness < 0.1 ? 0.6 : M_PI);
        chi2_config_init(&cfg, cases[i].m.kind == MATERIAL_DIFFUSE ? vec3_make(0, 0, 1) : mirror, cap);
        cfg.samples = 400000;
        cfg.seed = 11 + (uint64_t)i;
        cfg.significance = 0.01 / n;
        double p;
        char report[512];
        bool ok = chi2_test(&cfg, sample_dir, pdf_dir, &cases[i], &p, report, sizeof report);
        CHECK_MSG(ok, "case %d: p = %.3g: %s", i, p, report);
    }
}

/* sample() reports exactly eval() and pdf() of its own direction. */
static void test_sample_consistent(void)
{
    struct material ggx = { MATERIAL_GGX, { 0.8, 0.7, 0.6 }, 0.3 };
    struct rng r;
    rng_seed(&r, 3, 0, 0);
    for (int i = 0; i < 2000; ++i) {
        const struct material *m = i % 2 ? &ggx : &lambert;
        struct vec3 wo = dir_from_angles(89.0 * rng_uniform(&r), 360.0 * rng_uniform(&r));
        struct bsdf_sample s;
        if (!bsdf_sample(m, wo, rng_uniform(&r), rng_uniform(&r), &s)) continue;
        struct rgb f = bsdf_eval(m, wo, s.wi);
        CHECK_NEAR(s.f.r, f.r, 1e-12 * (1 + f.r));
        CHECK_NEAR(s.pdf, bsdf_pdf(m, wo, s.wi), 1e-12 * (1 + s.pdf));
        /* Reciprocity f(wo, wi) = f(wi, wo). */
        CHECK_NEAR(bsdf_eval(m, s.wi, wo).g, f.g, 1e-9 * (1 + f.g));
    }
}

/* Albedo by importance sampling: E[f cos / pdf] over the sampled directions.
   Lambert: exactly the albedo (the estimator has zero variance). GGX: at
   most 1 for a white F0, and close to 1 for smooth surfaces seen head-on
   (single scattering loses little energy there). */
static void test_energy(void)
{
    struct rng r;
    rng_seed(&r, 5, 0, 0);
    struct vec3 wo = dir_from_angles(30, 0);
    double sum = 0.0;
    int n = 10000;
    for (int i = 0; i < n; ++i) {
        struct bsdf_sample s;
        if (bsdf_sample(&lambert, wo, rng_uniform(&r), rng_uniform(&r), &s)) sum += s.f.r * s.wi.z / s.pdf;
    }
    CHECK_NEAR(sum / n, 0.5, 1e-9);

    struct material white = { MATERIAL_GGX, { 1, 1, 1 }, 0.1 };
    double mean = 0.0, m2 = 0.0;
    n = 200000;
    for (int i = 0; i < n; ++i) {
        struct bsdf_sample s;
        double x = 0.0;
        if (bsdf_sample(&white, wo, rng_uniform(&r), rng_uniform(&r), &s)) x = s.f.r * s.wi.z / s.pdf;
        double d = x - mean;
        mean += d / (i + 1);
        m2 += d * (x - mean);
    }
    double se = sqrt(m2 / (n - 1) / n);
    CHECK_MSG(mean <= 1.0 + 5 * se, "GGX albedo %.5f +- %.5f exceeds 1", mean, se);
    CHECK_MSG(mean > 0.95, "GGX alpha 0.1 albedo %.5f: too much energy lost", mean);
}

static void test_below_surface(void)
{
    struct vec3 up = vec3_make(0, 0, 1), down = vec3_make(0.3, 0, -0.95);
    CHECK(rgb_is_black(bsdf_eval(&lambert, up, down)));
    CHECK(bsdf_pdf(&lambert, up, down) == 0.0);
    struct bsdf_sample s;
    CHECK(!bsdf_sample(&lambert, down, 0.3, 0.3, &s));
}

/* The inline Lambertian f and pdf that the vectorised lanes use are
   bsdf_eval's f bit for bit and bsdf_pdf's density up to one rounding. */
static void test_lambert_inline(void)
{
    struct vec3 wo = vec3_make(0.0, 0.6, 0.8);
    int bad = 0;
    for (int i = 1; i <= 1000; ++i) {
        double z = i / 1000.0, s = sqrt(1.0 - z * z);
        struct vec3 wi = vec3_make(s * 0.6, s * 0.8, z);
        struct rgb f = bsdf_eval(&lambert, wo, wi), g = bsdf_lambert_f(lambert.albedo);
        bad += !same_bits(f.r, g.r) || !same_bits(f.g, g.g) || !same_bits(f.b, g.b);
        double p = bsdf_pdf(&lambert, wo, wi), q = bsdf_lambert_pdf(z);
        bad += !(fabs(p - q) <= 0x1p-52 * p);
    }
    CHECK_MSG(bad == 0, "%d directions differ", bad);
}

static const struct test_case tests[] = {
    { "chi2_sampling", test_chi2_sampling }, { "sample_consistent", test_sample_consistent }, { "energy", test_energy },
    { "below_surface", test_below_surface }, { "lambert_inline", test_lambert_inline },
};
TEST_MAIN(tests)

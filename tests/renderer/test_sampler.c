/* test_sampler.c: the samplers of render.sampler (sampler.h). The Sobol
   tables against Joe and Kuo's direction numbers; Owen scrambling keeps
   nested intervals; chi-square of the 2D points; (0,2)-net stratification
   per pixel surviving the scrambles; a lower error than `independent` on
   the lampshade floor's closed form, and no bias; one thread equals
   several, bit for bit, and the row path equals the per-pixel path. */
#include <stdint.h>
#include <string.h>

#include "geometry/antishadow.h"
#include "chi2.h"
#include "config/config.h"
#include "sampling/integrator.h"
#include "render_util.h"
#include "sampling/sampler.h"
#include "scene/scene.h"
#include "scene_util.h"
#include "sampling/sobol.h"
#include "sampling/strategy.h"
#include "testlib.h"

#define SCENE "configs/scenes/lampshade.yaml"

/* ---- the Sobol tables and the scramble ---------------------------------- */

/* The first rows of new-joe-kuo-6.21201 (d, s, a, m_1..m_s), and the
   direction numbers derived here the way Joe and Kuo's notes do, apart
   from the generator script. */
static void test_matrices_from_joe_kuo(void)
{
    static const struct {
        int s;
        unsigned a;
        uint32_t m[3];
    } rows[] = { { 1, 0, { 1 } }, { 2, 1, { 1, 3 } }, { 3, 1, { 1, 3, 1 } } };
    for (int j = 0; j < 32; ++j) {
        CHECK(sobol_matrices[0][j] == 0x80000000u >> j);
        CHECK(sobol_matrices_reversed[0][j] == sobol_reverse_bits(sobol_matrices[0][j]));
    }
    for (int d = 1; d < SOBOL_DIMS; ++d) {
        int s = rows[d - 1].s;
        uint32_t m[33];
        for (int i = 1; i <= s; ++i) m[i] = rows[d - 1].m[i - 1];
        /* m_i = 2 a_1 m_{i-1} ^ 4 a_2 m_{i-2} ^ ... ^ 2^s m_{i-s} ^ m_{i-s} */
        for (int i = s + 1; i <= 32; ++i) {
            uint32_t x = m[i - s] ^ (m[i - s] << s);
            for (int k = 1; k < s; ++k)
                if ((rows[d - 1].a >> (s - 1 - k)) & 1u) x ^= m[i - k] << k;
            m[i] = x;
        }
        int bad = 0;
        for (int i = 1; i <= 32; ++i) {
            uint32_t v = m[i] << (32 - i);
            bad += sobol_matrices[d][i - 1] != v;
            bad += sobol_matrices_reversed[d][i - 1] != sobol_reverse_bits(v);
        }
        CHECK_MSG(bad == 0, "dimension %d: %d columns differ from Joe and Kuo's", d, bad);
    }
    /* sobol_point and sobol_point_reversed agree. */
    for (uint32_t i = 0; i < 5000; i += 7)
        for (int d = 0; d < SOBOL_DIMS; ++d)
            CHECK(sobol_reverse_bits(sobol_point_reversed(sobol_reverse_bits(i), d)) == sobol_point(i, d));
}

/* Length of the common prefix of two 32-bit fractions. */
static int common_prefix(uint32_t a, uint32_t b)
{
    int n = 0;
    while (n < 32 && !((a ^ b) & (0x80000000u >> n))) ++n;
    return n;
}

/* An Owen scramble maps dyadic intervals onto dyadic intervals of the same
   size: two fractions with a common prefix of t bits keep exactly t. And
   each level is scrambled: the first bit flips for about half the seeds. */
static void test_owen_scramble_nested(void)
{
    struct rng r;
    rng_seed(&r, 5, 0, 0);
    int bad = 0, flips = 0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
        uint32_t seed = rng_next_u32(&r), x = rng_next_u32(&r);
        int t = (int)(rng_next_u32(&r) % 32u);
        uint32_t y = x ^ (0x80000000u >> t) ^ (rng_next_u32(&r) & (0xffffffffu >> t >> 1));
        if (t == 31) y = x ^ 1u;
        bad += common_prefix(sobol_owen_scramble(x, seed), sobol_owen_scramble(y, seed)) != common_prefix(x, y);
        flips += (sobol_owen_scramble(x, seed) ^ x) >> 31;
    }
    CHECK_MSG(bad == 0, "%d of %d pairs changed their common prefix", bad, n);
    /* Binomial(n, 1/2): 5 sigma. */
    CHECK_MSG(fabs(flips - 0.5 * n) < 5.0 * sqrt(0.25 * n), "top bit flipped %d of %d times", flips, n);
}

/* ---- the points ----------------------------------------------------------- */

/* One 2D projection of the sobol sampler's draws: what a sample of pass
   `pass` of pixel `pixel` gives for it. */
enum projection {
    PROJ_CAMERA,        /* camera jitter (block 0, Sobol dims 0, 1) */
    PROJ_LIGHT_POINT,   /* light sample u[2], u[3] at bounce 0 (dims 0, 1) */
    PROJ_LIGHT_CHOICE,  /* light sample u[0], u[1] at bounce 0 (dims 2, 3) */
    PROJ_BSDF_DEEP,     /* BSDF sample at bounce 3 (dims 0, 1) */
    PROJ_CAMERA_LIGHT,  /* camera x against the light point's u: two blocks */
    PROJ_LIGHT_BOUNCES, /* light point u at bounces 0 and 1 */
    PROJ_COUNT
};
static const char *const projection_names[PROJ_COUNT] = { "camera",        "light point",  "light choice",
                                                          "bsdf bounce 3", "camera/light", "light 0/1" };

static void draw(enum projection p, uint64_t seed, uint64_t pixel, int64_t pass, double out[2])
{
    struct sampler s;
    double c[2], l[4], l1[4], b[2];
    sampler_start(&s, SAMPLER_SOBOL, seed, pixel, pass);
    sampler_camera(&s, c);
    sampler_light(&s, 0, l);
    sampler_light(&s, 1, l1);
    sampler_bsdf(&s, 3, b);
    const double pairs[PROJ_COUNT][2] = { { c[0], c[1] }, { l[2], l[3] }, { l[0], l[1] },
                                          { b[0], b[1] }, { c[0], l[2] }, { l[2], l1[2] } };
    out[0] = pairs[p][0];
    out[1] = pairs[p][1];
}

/* 16 x 16 bins over the first 16 passes of 4096 pixels: uniform (the
   upper tail; per-pixel stratification only lowers the statistic). */
static void test_chi_square_2d(void)
{
    enum { BINS = 16, PIXELS = 4096, PASSES = 16 };
    for (int p = 0; p < PROJ_COUNT; ++p) {
        static double count[BINS * BINS];
        memset(count, 0, sizeof count);
        int outside = 0;
        for (uint64_t px = 0; px < PIXELS; ++px)
            for (int64_t i = 0; i < PASSES; ++i) {
                double u[2];
                draw((enum projection)p, 11, px, i, u);
                if (!(u[0] >= 0.0 && u[0] < 1.0 && u[1] >= 0.0 && u[1] < 1.0)) {
                    ++outside;
                    continue;
                }
                count[(int)(u[0] * BINS) * BINS + (int)(u[1] * BINS)] += 1.0;
            }
        double expected = (double)PIXELS * PASSES / (BINS * BINS), chi2 = 0.0;
        for (int k = 0; k < BINS * BINS; ++k) chi2 += (count[k] - expected) * (count[k] - expected) / expected;
        double pvalue = chi2_gamma_q(0.5 * (BINS * BINS - 1), 0.5 * chi2);
        if (getenv("VERBOSE")) fprintf(stderr, "  %s: chi2 %.1f, p %.3g\n", projection_names[p], chi2, pvalue);
        CHECK(outside == 0);
        CHECK_MSG(pvalue >= 0.01 / PROJ_COUNT, "%s: chi2 %.1f on %d dof, p = %.3g", projection_names[p], chi2,
                  BINS * BINS - 1, pvalue);
    }
}

/* Whether the n points (x, y) have exactly one point in every elementary
   interval of 2^-a by 2^-(k-a) (n = 2^k). */
static bool stratified(const double *x, const double *y, int k, int a, unsigned char *cells)
{
    int n = 1 << k;
    memset(cells, 0, (size_t)n);
    for (int i = 0; i < n; ++i) {
        int cx = (int)(x[i] * (double)(1 << a)), cy = (int)(y[i] * (double)(1 << (k - a)));
        if (cells[(cx << (k - a)) | cy]++) return false;
    }
    return true;
}

/* Per pixel, the first 2^k passes (k <= 10) of every pair of Sobol
   dimensions of a block are stratified on every elementary interval shape
   on which the unscrambled sequence's first 2^k points are: Owen
   scrambling and the shuffle of the sample order keep the net. Dimensions
   0 and 1 are a (0,2)-sequence: every shape. */
static void test_elementary_intervals(void)
{
    enum { K = 10, N = 1 << K };
    static double raw[4][N], got[4][N];
    static unsigned char cells[N];
    int shapes01 = 0, checked = 0;
    for (uint64_t px = 0; px < 6; ++px) {
        for (int64_t i = 0; i < N; ++i) {
            struct sampler s;
            double l[4];
            sampler_start(&s, SAMPLER_SOBOL, 3, px * 7919, i);
            sampler_light(&s, 0, l);
            /* Light block: Sobol dims 0..3 are u[2], u[3], u[0], u[1]. */
            got[0][i] = l[2], got[1][i] = l[3], got[2][i] = l[0], got[3][i] = l[1];
            for (int d = 0; d < 4; ++d) raw[d][i] = sobol_point((uint32_t)i, d) * 0x1.0p-32;
        }
        for (int d0 = 0; d0 < 4; ++d0)
            for (int d1 = d0 + 1; d1 < 4; ++d1)
                for (int k = 1; k <= K; ++k)
                    for (int a = 0; a <= k; ++a) {
                        bool want = stratified(raw[d0], raw[d1], k, a, cells);
                        if (d0 == 0 && d1 == 1) {
                            CHECK_MSG(want, "Sobol dims 0, 1: 2^%d points not stratified on %d x %d", k, a, k - a);
                            shapes01 += px == 0;
                        }
                        if (!want) continue;
                        ++checked;
                        CHECK_MSG(stratified(got[d0], got[d1], k, a, cells),
                                  "pixel %d dims %d, %d: the first 2^%d passes are not stratified on 2^-%d x 2^-%d",
                                  (int)px, d0, d1, k, a, k - a);
                    }
        /* The camera jitter: dims 0, 1 of its own block. */
        for (int64_t i = 0; i < N; ++i) {
            struct sampler s;
            double c[2];
            sampler_start(&s, SAMPLER_SOBOL, 3, px * 7919, i);
            sampler_camera(&s, c);
            got[0][i] = c[0], got[1][i] = c[1];
        }
        for (int k = 1; k <= K; ++k)
            for (int a = 0; a <= k; ++a)
                CHECK_MSG(stratified(got[0], got[1], k, a, cells), "pixel %d camera: 2^%d passes on %d x %d", (int)px,
                          k, a, k - a);
    }
    CHECK(shapes01 == (K + 1) * (K + 2) / 2 - 1);
    if (getenv("VERBOSE")) fprintf(stderr, "  %d (pair, k, shape) cases checked\n", checked);
}

/* ---- estimates on the lampshade floor --------------------------------- */

/* Exact reflected radiance (red) at a floor point of the lampshade scene
   (as test_closed_form.c computes it). */
static double lampshade_exact(const struct scene *sc, const struct config *cfg, int material, struct vec3 p)
{
    struct polygon vis;
    double albedo = cfg->materials[material].albedo.r;
    if (antishadow_visible_polygon(&sc->portals[0].antishadow, p, &vis) < 3) return 0.0;
    return albedo / M_PI * sc->lights[0].radiance.r * polygon_projected_solid_angle(&vis, p, vec3_make(0, 1, 0));
}

/* Lit floor points of the lampshade at s_L = 0.6 that nothing but the
   shade shadows: anti-antumbra, penumbra, far penumbra (test_closed_form.c). */
static const struct vec3 floor_points[] = { { 0, 0, 0 },      { -0.3, 0, 0.2 }, { -0.676, 0, 0 },
                                            { -1.0, 0, 0.4 }, { 0, 0, 2.0 },    { -2.55, 0, 0.3 } };
#define N_POINTS ((int)(sizeof floor_points / sizeof floor_points[0]))

struct floor_setup {
    struct config cfg;
    struct scene sc;
    int white;
    double exact[N_POINTS];
};

static bool floor_setup(struct floor_setup *f)
{
    struct config_override ov[] = { { "params.s_L", "0.6" } };
    if (!test_scene_load(SCENE, ov, 1, &f->cfg, &f->sc)) return false;
    f->white = -1;
    for (int i = 0; i < f->cfg.n_materials; ++i)
        if (!strcmp(f->cfg.materials[i].name, "white")) f->white = i;
    for (int k = 0; k < N_POINTS; ++k) f->exact[k] = lampshade_exact(&f->sc, &f->cfg, f->white, floor_points[k]);
    return f->white >= 0;
}

static void floor_free(struct floor_setup *f)
{
    scene_destroy(&f->sc);
    config_free(&f->cfg);
}

/* The n-pass estimate (red) of one pixel at floor point k, from the
   `direct` integrator's estimator (light sample, BSDF sample, MIS). */
static double pixel_estimate(const struct integrator *it, struct strategy_scratch *scratch, int material,
                             enum sampler_kind kind, uint64_t seed, uint64_t pixel, int k, int n,
                             struct integrator_stats *stats)
{
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        struct sampler s;
        sampler_start(&s, kind, seed, pixel, i);
        struct rgb c = integrator_direct_at(it, scratch, floor_points[k], vec3_make(0, 1, 0), material,
                                            vec3_make(0, 1, 0), &s, stats);
        sum += c.r;
    }
    return sum / n;
}

/* Mean and standard error of the relative squared error of `trials`
   pixels per floor point at n passes. */
struct mse {
    double mean, se;
};

static struct mse floor_mse(const struct floor_setup *f, enum strategy_kind strategy, enum sampler_kind kind, int n,
                            int trials)
{
    struct render_desc rd = f->cfg.render;
    rd.integrator = INTEGRATOR_DIRECT;
    rd.strategy = strategy;
    struct strategy st;
    struct strategy_scratch scratch;
    struct error err;
    struct mse m = { NAN, NAN };
    if (!strategy_init(&st, &f->sc, &rd, &err) || !strategy_scratch_init(&st, &scratch, &err)) return m;
    struct integrator it;
    integrator_init(&it, &rd, &f->sc, &st);
    struct integrator_stats stats;
    memset(&stats, 0, sizeof stats);
    double s1 = 0.0, s2 = 0.0;
    int count = 0;
    for (int k = 0; k < N_POINTS; ++k)
        for (int t = 0; t < trials; ++t) {
            double e = pixel_estimate(&it, &scratch, f->white, kind, 23, (uint64_t)(k * trials + t), k, n, &stats);
            double r = (e - f->exact[k]) / f->exact[k];
            s1 += r * r;
            s2 += r * r * r * r;
            ++count;
        }
    m.mean = s1 / count;
    m.se = sqrt(fmax(s2 / count - m.mean * m.mean, 0.0) / (count - 1));
    strategy_scratch_free(&scratch);
    strategy_free(&st);
    return m;
}

/* At equal passes, sobol's relative MSE is below independent's by more
   than 5 standard errors of the difference, for plain light sampling (a
   shadow edge in the integrand) and the exact antishadow (smooth). With
   PORTAL_LIGHTS_MEASURE set, prints the ratios at 16, 64 and 256 passes. */
static void test_lower_error_than_independent(void)
{
    struct floor_setup f;
    if (!floor_setup(&f)) {
        CHECK(false);
        return;
    }
    static const enum strategy_kind strategies[] = { STRATEGY_LIGHT, STRATEGY_ANTISHADOW_EXACT };
    bool measure = getenv("PORTAL_LIGHTS_MEASURE") != NULL;
    static const int spps[] = { 16, 64, 256 };
    for (int s = 0; s < 2; ++s)
        for (int j = 0; j < (measure ? 3 : 1); ++j) {
            int n = measure ? spps[j] : 128, trials = 256;
            struct mse ind = floor_mse(&f, strategies[s], SAMPLER_INDEPENDENT, n, trials);
            struct mse sob = floor_mse(&f, strategies[s], SAMPLER_SOBOL, n, trials);
            double diff = ind.mean - sob.mean, se = sqrt(ind.se * ind.se + sob.se * sob.se);
            if (measure || getenv("VERBOSE"))
                fprintf(stderr, "  %s %d spp: relMSE independent %.4g +- %.2g, sobol %.4g +- %.2g, RMSE ratio %.3f\n",
                        strategy_names[strategies[s]], n, ind.mean, ind.se, sob.mean, sob.se,
                        sqrt(sob.mean / ind.mean));
            CHECK_MSG(diff > 5.0 * se, "%s %d spp: relMSE independent %.4g +- %.2g, sobol %.4g +- %.2g",
                      strategy_names[strategies[s]], n, ind.mean, ind.se, sob.mean, sob.se);
        }
    floor_free(&f);
}

/* The mean of many independently scrambled pixels (4 passes each) is the
   closed form within 5 standard errors: Owen scrambling keeps every
   sample uniform, so the estimator stays unbiased. */
static void test_unbiased(void)
{
    struct floor_setup f;
    if (!floor_setup(&f)) {
        CHECK(false);
        return;
    }
    static const enum strategy_kind strategies[] = { STRATEGY_LIGHT, STRATEGY_ANTISHADOW_EXACT };
    for (int s = 0; s < 2; ++s)
        for (int k = 0; k < N_POINTS; ++k) {
            struct render_desc rd = f.cfg.render;
            rd.integrator = INTEGRATOR_DIRECT;
            rd.strategy = strategies[s];
            struct strategy st;
            struct strategy_scratch scratch;
            struct error err;
            if (!strategy_init(&st, &f.sc, &rd, &err) || !strategy_scratch_init(&st, &scratch, &err)) {
                CHECK_MSG(false, "%s", err.message);
                continue;
            }
            struct integrator it;
            integrator_init(&it, &rd, &f.sc, &st);
            struct integrator_stats stats;
            memset(&stats, 0, sizeof stats);
            const int pixels = 3000;
            double mean = 0.0, m2 = 0.0;
            for (int t = 0; t < pixels; ++t) {
                double e =
                    pixel_estimate(&it, &scratch, f.white, SAMPLER_SOBOL, 41 + (uint64_t)s, (uint64_t)t, k, 4, &stats);
                double d = e - mean;
                mean += d / (t + 1);
                m2 += d * (e - mean);
            }
            double se = sqrt(m2 / (pixels - 1) / pixels);
            CHECK_MSG(fabs(mean - f.exact[k]) <= 5.0 * se + 1e-9 * f.exact[k],
                      "%s point %d: mean %.8g +- %.2g, exact %.8g (%.1f standard errors)",
                      strategy_names[strategies[s]], k, mean, se, f.exact[k], (mean - f.exact[k]) / se);
            strategy_scratch_free(&scratch);
            strategy_free(&st);
        }
    floor_free(&f);
}

/* ---- whole renders ------------------------------------------------------ */

static bool render_sobol(const char *threads, const char *seed, const char *integrator, const char *sampler,
                         struct film_image *img)
{
    struct config_override ov[] = { { "film.width", "32" },
                                    { "film.height", "32" },
                                    { "render.snapshots.every_spp", "1000000" },
                                    { "render.spp", "8" },
                                    { "render.threads", threads },
                                    { "render.seed", seed },
                                    { "render.integrator", integrator },
                                    { "render.sampler", sampler } };
    return render_to_image(SCENE, ov, 8, img, NULL);
}

static bool same_image(const struct film_image *a, const struct film_image *b)
{
    size_t n = (size_t)3 * a->width * a->height;
    return a->width == b->width && a->height == b->height && !memcmp(a->rgb, b->rgb, n * sizeof(float)) &&
           !memcmp(a->variance, b->variance, n * sizeof(float));
}

/* 1, 2 and 3 threads give the same bits (path tracing: every bounce's
   blocks); another seed, or the independent sampler, another image. */
static void test_threads_bit_identical(void)
{
    struct film_image a = { 0 }, b = { 0 }, c = { 0 }, d = { 0 }, e = { 0 };
    CHECK(render_sobol("1", "1", "path", "sobol", &a));
    CHECK(render_sobol("2", "1", "path", "sobol", &b));
    CHECK(render_sobol("3", "1", "path", "sobol", &c));
    CHECK(render_sobol("2", "2", "path", "sobol", &d));
    CHECK(render_sobol("2", "1", "path", "independent", &e));
    CHECK(same_image(&a, &b));
    CHECK(same_image(&a, &c));
    CHECK(!same_image(&a, &d));
    CHECK(!same_image(&a, &e));
    film_image_free(&a), film_image_free(&b), film_image_free(&c), film_image_free(&d), film_image_free(&e);
}

/* The direct integrator's row path (all light samples of a row at once)
   and the path tracer stopped after one bounce (one pixel at a time) draw
   the same blocks, so their images are the same bits. */
static void test_direct_equals_path_depth1(void)
{
    static const char *strategies[] = { "light", "antishadow_exact" };
    for (int s = 0; s < 2; ++s) {
        struct film_image a = { 0 }, b = { 0 };
        struct config_override ov[] = { { "film.width", "32" },
                                        { "film.height", "32" },
                                        { "render.snapshots.every_spp", "1000000" },
                                        { "render.spp", "8" },
                                        { "render.strategy", strategies[s] },
                                        { "render.sampler", "sobol" },
                                        { "render.integrator", "direct" },
                                        { "render.max_depth", "1" } };
        CHECK(render_to_image(SCENE, ov, 7, &a, NULL));
        ov[6].value = "path";
        CHECK(render_to_image(SCENE, ov, 8, &b, NULL));
        CHECK_MSG(same_image(&a, &b), "%s: direct and path (max_depth 1) differ", strategies[s]);
        film_image_free(&a), film_image_free(&b);
    }
}

/* sampler_light_bsdf_many against sampler_light + sampler_bsdf one sampler
   at a time: the same numbers and states, bit for bit, for both kinds,
   with and without the BSDF half, over more samplers than one batch and
   in a shuffled order of pixels (as a row's shading points come). */
static void test_light_bsdf_many_matches_one(void)
{
    enum { N = 150 };
    const enum sampler_kind kinds[] = { SAMPLER_INDEPENDENT, SAMPLER_SOBOL };
    int differ = 0, checked = 0;
    for (int ki = 0; ki < 2; ++ki)
        for (int with_bsdf = 0; with_bsdf < 2; ++with_bsdf)
            for (int depth = 0; depth < 3; ++depth) {
                static struct sampler many[N], one[N];
                static double u_many[N][4], u_one[N][4], ub_many[N][2], ub_one[N][2];
                int pixel[N], n = 0;
                for (int x = 0; x < N; ++x) {
                    sampler_start(&many[x], kinds[ki], 42, 1000u + (uint64_t)x, 3 + depth);
                    double cam[2];
                    sampler_camera(&many[x], cam);
                    one[x] = many[x];
                    /* Every third pixel has no shading point; the others
                       come in a scrambled order. */
                    if (x % 3 != 2) pixel[n++] = (x * 37) % N;
                }
                /* (x * 37) mod N is a permutation (37 and N coprime): no pixel twice. */
                sampler_light_bsdf_many(many, pixel, n, depth, u_many, with_bsdf ? ub_many : NULL);
                for (int k = 0; k < n; ++k) {
                    sampler_light(&one[pixel[k]], depth, u_one[k]);
                    if (with_bsdf) sampler_bsdf(&one[pixel[k]], depth, ub_one[k]);
                    differ += memcmp(u_one[k], u_many[k], sizeof u_one[k]) != 0;
                    if (with_bsdf) differ += memcmp(ub_one[k], ub_many[k], sizeof ub_one[k]) != 0;
                    ++checked;
                }
                for (int x = 0; x < N; ++x)
                    differ += many[x].rng.state != one[x].rng.state || many[x].rng.inc != one[x].rng.inc;
                /* What comes next is the same too (the roulette draw). */
                for (int x = 0; x < N; ++x)
                    differ += sampler_roulette(&many[x], depth) != sampler_roulette(&one[x], depth);
            }
    CHECK_MSG(differ == 0, "%d draws or states differ", differ);
    CHECK(checked == 2 * 2 * 3 * 100);
}

static const struct test_case tests[] = {
    { "light_bsdf_many_matches_one", test_light_bsdf_many_matches_one },
    { "matrices_from_joe_kuo", test_matrices_from_joe_kuo },
    { "owen_scramble_nested", test_owen_scramble_nested },
    { "chi_square_2d", test_chi_square_2d },
    { "elementary_intervals", test_elementary_intervals },
    { "lower_error_than_independent", test_lower_error_than_independent },
    { "unbiased", test_unbiased },
    { "threads_bit_identical", test_threads_bit_identical },
    { "direct_equals_path_depth1", test_direct_equals_path_depth1 },
};

TEST_MAIN(tests)

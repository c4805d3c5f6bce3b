/* test_shading.c: the set-up of direct lighting's shadow and BSDF rays.
   shading_setup_many (a row at a time, vectorised for Lambertian points)
   against shadow_setup / bsdf_setup one point at a time: the same queries
   bit for bit and the same counters, over random points of Lambertian,
   black and GGX materials, every MIS kind, with and without BSDF rays, for
   rows that do not fill the last block; the row's rays, which it writes to
   ray streams, are the one-point queries' rays as ray_stream_set converts
   them (inactive where a query traces nothing). And the Lambertian fast path
   against the generic formulas: value = f Le cos w / pdf with f = albedo /
   pi and w the MIS weight of mis_weight, the BSDF ray the one bsdf_sample
   draws, its weight f cos / pdf = albedo. */
#include <string.h>

#include "base/rng.h"
#include "sampling/shading.h"
#include "testlib.h"

enum { N_POINTS = 1003, N_MATERIALS = 4, N_LIGHTS = 2 };

static const struct material materials[N_MATERIALS] = {
    { MATERIAL_DIFFUSE, { 0.5, 0.5, 0.5 }, 0.0 },
    { MATERIAL_DIFFUSE, { 0.63, 0.065, 0.05 }, 0.0 },
    { MATERIAL_DIFFUSE, { 0.0, 0.0, 0.0 }, 0.0 }, /* black: no shadow ray */
    { MATERIAL_GGX, { 0.9, 0.6, 0.3 }, 0.3 },
};

struct fixture {
    struct scene sc;
    struct material mats[N_MATERIALS];
    struct light lights[N_LIGHTS];
    int n;
    struct vertex v[N_POINTS];
    bool ok[N_POINTS];
    struct light_sample ls[N_POINTS];
    double ub[N_POINTS][2];
    long diffuse, ggx;
};

static double uniform(struct rng *r, double lo, double hi)
{
    return lo + (hi - lo) * rng_uniform(r);
}

static struct vec3 unit(struct rng *r)
{
    double z = uniform(r, -1.0, 1.0), phi = uniform(r, 0.0, 2.0 * M_PI), s = sqrt(1.0 - z * z);
    return vec3_make(s * cos(phi), s * sin(phi), z);
}

/* Random shading points and light samples, with every early out of
   shadow_setup represented: no sample, a direction that misses the light,
   black radiance, zero or infinite pdf, light behind the surface, segments
   too short. */
static void fixture_init(struct fixture *f, uint64_t seed)
{
    memset(f, 0, sizeof *f);
    memcpy(f->mats, materials, sizeof materials);
    f->sc.n_materials = N_MATERIALS;
    f->sc.materials = f->mats;
    f->sc.n_lights = N_LIGHTS;
    f->sc.lights = f->lights;
    f->sc.scale = 12.0;
    f->lights[0].target.normal = vec3_make(0.0, -1.0, 0.0);
    f->lights[1].target.normal = vec3_normalize(vec3_make(0.3, -1.0, 0.2));
    struct rng r;
    rng_seed(&r, seed, 0, 0);
    while (f->n < N_POINTS) {
        int material = (int)(rng_uniform(&r) * N_MATERIALS);
        struct vec3 p = vec3_make(uniform(&r, -3, 3), uniform(&r, 0, 4), uniform(&r, -3, 3));
        struct vertex *v = &f->v[f->n];
        if (!vertex_init(&f->sc, p, unit(&r), material, unit(&r), v)) continue;
        struct light_sample *ls = &f->ls[f->n];
        double kind = rng_uniform(&r);
        f->ok[f->n] = kind > 0.05;
        ls->light = kind < 0.1 ? -1 : (rng_uniform(&r) < 0.5 ? 0 : 1);
        ls->wi = unit(&r);
        ls->dist = kind < 0.13 ? 1e-9 : exp(uniform(&r, log(1e-3), log(10.0)));
        ls->pdf_sa = kind < 0.16 ? 0.0 : (kind < 0.18 ? INFINITY : exp(uniform(&r, log(1e-3), log(1e6))));
        ls->radiance = kind >= 0.18 && kind < 0.22
                           ? rgb_make(0, 0, 0)
                           : rgb_make(uniform(&r, 0, 50), uniform(&r, 0, 40), uniform(&r, 0, 30));
        f->ub[f->n][0] = rng_uniform(&r);
        f->ub[f->n][1] = rng_uniform(&r);
        if (materials[material].kind == MATERIAL_DIFFUSE) ++f->diffuse;
        else ++f->ggx;
        ++f->n;
    }
}

static bool same_vec(struct vec3 a, struct vec3 b)
{
    return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

static bool same_rgb(struct rgb a, struct rgb b)
{
    return same_bits(a.r, b.r) && same_bits(a.g, b.g) && same_bits(a.b, b.b);
}

static bool same_stats(const struct integrator_stats *a, const struct integrator_stats *b)
{
    return a->rays == b->rays && a->shadow_rays == b->shadow_rays && a->shadow_blocked == b->shadow_blocked &&
           a->light_samples == b->light_samples && a->light_missed == b->light_missed;
}

static bool same_float(float a, float b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

/* Ray k of a stream is the query's ray (or inactive when it traces nothing). */
static bool stream_holds(const struct ray_stream *r, int k, bool trace, const struct scene_ray *ray)
{
    if (!trace) return r->tnear[k] > r->tfar[k];
    struct ray_stream one;
    if (!ray_stream_init(&one, 1, NULL)) return false;
    ray_stream_set(&one, 0, ray->o, ray->d, ray->tmax);
    bool same = same_float(r->ox[k], one.ox[0]) && same_float(r->oy[k], one.oy[0]) && same_float(r->oz[k], one.oz[0]) &&
                same_float(r->dx[k], one.dx[0]) && same_float(r->dy[k], one.dy[0]) && same_float(r->dz[k], one.dz[0]) &&
                same_float(r->tnear[k], one.tnear[0]) && same_float(r->tfar[k], one.tfar[0]);
    ray_stream_free(&one);
    return same;
}

static void stream_scribble(struct ray_stream *r, int n)
{
    float *arrays[] = { r->ox, r->oy, r->oz, r->dx, r->dy, r->dz, r->tnear, r->tfar };
    for (size_t a = 0; a < sizeof arrays / sizeof arrays[0]; ++a)
        for (int k = 0; k < n; ++k) arrays[a][k] = -1.0f - (float)k;
}

/* The row's queries hold no rays (the streams do), except the BSDF ray's
   direction. */
static bool same_shadow(const struct shadow_query *one, const struct shadow_query *many, const struct ray_stream *rays,
                        int k)
{
    return one->trace == many->trace && same_rgb(one->value, many->value) &&
           stream_holds(rays, k, one->trace, &one->ray);
}

static bool same_bsdf(const struct bsdf_query *one, const struct bsdf_query *many, const struct ray_stream *rays, int k)
{
    if (one->trace != many->trace || !stream_holds(rays, k, one->trace, &one->ray)) return false;
    return !one->trace || (same_vec(one->ray.o, many->ray.o) && same_vec(one->ray.d, many->ray.d) &&
                           same_rgb(one->weight, many->weight) && same_bits(one->pdf, many->pdf));
}

static struct shadow_query shadow_one[N_POINTS], shadow_many[N_POINTS];
static struct bsdf_query bsdf_one[N_POINTS], bsdf_many[N_POINTS];

static void test_many_matches_one(void)
{
    static struct fixture f;
    fixture_init(&f, 7);
    const enum mis_kind kinds[] = { MIS_NONE, MIS_BALANCE, MIS_POWER };
    const int sizes[] = { N_POINTS, 16, 17, 1, 0 };
    long traced = 0, counted_short = 0;
    struct ray_stream shadow_rays, bsdf_rays;
    CHECK(ray_stream_init(&shadow_rays, N_POINTS, NULL) && ray_stream_init(&bsdf_rays, N_POINTS, NULL));
    for (int mk = 0; mk < 3; ++mk)
        for (int with_bsdf = 0; with_bsdf < 2; ++with_bsdf)
            for (int si = 0; si < 5; ++si) {
                int n = sizes[si];
                const double(*ub)[2] = with_bsdf ? (const double(*)[2])f.ub : NULL;
                struct integrator_stats s1 = { 0, 0, 0, 0, 0 }, s2 = s1;
                memset(shadow_one, 0xab, sizeof shadow_one);
                memset(shadow_many, 0xcd, sizeof shadow_many);
                for (int k = 0; k < n; ++k) {
                    shadow_setup(&f.sc, kinds[mk], &f.v[k], f.ok[k], &f.ls[k], &s1, &shadow_one[k]);
                    if (ub) bsdf_setup(&f.sc, &f.v[k], ub[k], &bsdf_one[k]);
                }
                /* Streams start as garbage: every ray must be written. */
                stream_scribble(&shadow_rays, N_POINTS);
                stream_scribble(&bsdf_rays, N_POINTS);
                shading_setup_many(&f.sc, kinds[mk], f.v, f.ok, f.ls, ub, n, &s2, shadow_many, &shadow_rays, bsdf_many,
                                   &bsdf_rays);
                int differ = 0;
                for (int k = 0; k < n; ++k) {
                    differ += !same_shadow(&shadow_one[k], &shadow_many[k], &shadow_rays, k);
                    /* Never NaN, also for an infinite pdf (either path, any material). */
                    differ += !rgb_is_finite(shadow_many[k].value);
                    if (ub) differ += !same_bsdf(&bsdf_one[k], &bsdf_many[k], &bsdf_rays, k);
                    traced += shadow_one[k].trace;
                }
                CHECK_MSG(differ == 0, "mis %d, bsdf %d, n %d: %d queries differ", (int)kinds[mk], with_bsdf, n,
                          differ);
                CHECK_MSG(same_stats(&s1, &s2), "mis %d, bsdf %d, n %d: counters differ", (int)kinds[mk], with_bsdf, n);
                if (n == N_POINTS) counted_short += (long)s1.shadow_rays;
            }
    ray_stream_free(&shadow_rays);
    ray_stream_free(&bsdf_rays);
    /* The comparison must have covered both kinds of material and traced rays. */
    fprintf(stderr, "  %ld Lambertian and %ld GGX points, %ld shadow rays traced\n", f.diffuse, f.ggx, traced);
    CHECK(f.diffuse > 500 && f.ggx > 100);
    CHECK(traced > 1000);
    CHECK(counted_short > traced / 30);
}

/* The Lambertian lanes against the generic formulas. */
static void test_lambert_matches_generic(void)
{
    static struct fixture f;
    fixture_init(&f, 11);
    const enum mis_kind kinds[] = { MIS_NONE, MIS_BALANCE, MIS_POWER };
    long checked = 0;
    struct ray_stream shadow_rays, bsdf_rays;
    CHECK(ray_stream_init(&shadow_rays, N_POINTS, NULL) && ray_stream_init(&bsdf_rays, N_POINTS, NULL));
    for (int mk = 0; mk < 3; ++mk) {
        struct integrator_stats s = { 0, 0, 0, 0, 0 };
        shading_setup_many(&f.sc, kinds[mk], f.v, f.ok, f.ls, (const double(*)[2])f.ub, f.n, &s, shadow_many,
                           &shadow_rays, bsdf_many, &bsdf_rays);
        for (int k = 0; k < f.n; ++k) {
            const struct vertex *v = &f.v[k];
            if (v->m->kind != MATERIAL_DIFFUSE) continue;
            /* The segments: those of the one-point queries, which are the
               row's bit for bit (many_matches_one). */
            shadow_setup(&f.sc, kinds[mk], v, f.ok[k], &f.ls[k], &s, &shadow_one[k]);
            bsdf_setup(&f.sc, v, f.ub[k], &bsdf_one[k]);
            const struct light_sample *ls = &f.ls[k];
            /* Shadow: the generic estimator f Le cos w / pdf. */
            struct vec3 wi_local = frame_to_local(&v->frame, ls->wi);
            bool expect = f.ok[k] && ls->light >= 0 && !rgb_is_black(ls->radiance) && ls->pdf_sa > 0.0 &&
                          wi_local.z > 0.0 && !rgb_is_black(v->m->albedo);
            struct rgb fv = bsdf_eval(v->m, v->wo_local, wi_local);
            double w = mis_weight(kinds[mk], ls->pdf_sa, bsdf_pdf(v->m, v->wo_local, wi_local));
            struct rgb want =
                expect ? rgb_scale(rgb_mul(fv, ls->radiance), wi_local.z * w / ls->pdf_sa) : rgb_make(0, 0, 0);
            struct rgb got = shadow_many[k].value;
            /* An infinite density weighs ~1e-150 in the lanes (0 here). */
            double tol = 1e-13 * (fabs(want.r) + fabs(want.g) + fabs(want.b)) + 1e-140;
            CHECK(rgb_is_finite(shadow_many[k].value));
            CHECK_NEAR(got.r, want.r, tol);
            CHECK_NEAR(got.g, want.g, tol);
            CHECK_NEAR(got.b, want.b, tol);
            if (shadow_many[k].trace) {
                /* The segment lies on the sampled line, between the two ends. */
                struct vec3 from = vec3_sub(shadow_one[k].ray.o, v->p);
                CHECK_NEAR(vec3_length(vec3_cross(from, ls->wi)), 0.0, 1e-12);
                CHECK(vec3_dot(from, ls->wi) > 0.0);
                CHECK(vec3_dot(from, ls->wi) + shadow_one[k].ray.tmax < ls->dist);
            }
            /* BSDF: the direction bsdf_sample draws, its weight the albedo. */
            struct bsdf_sample bs;
            bool sampled = bsdf_sample(v->m, v->wo_local, f.ub[k][0], f.ub[k][1], &bs);
            CHECK(bsdf_many[k].trace == sampled);
            if (!sampled) continue;
            CHECK(same_vec(bsdf_many[k].ray.d, frame_to_world(&v->frame, bs.wi)));
            CHECK_NEAR(bsdf_many[k].pdf, bs.pdf, 1e-15 * bs.pdf);
            struct rgb wg = rgb_scale(bs.f, bs.wi.z / bs.pdf);
            CHECK_NEAR(bsdf_many[k].weight.r, wg.r, 1e-14);
            CHECK_NEAR(bsdf_many[k].weight.g, wg.g, 1e-14);
            CHECK_NEAR(bsdf_many[k].weight.b, wg.b, 1e-14);
            CHECK(vec3_dot(vec3_sub(bsdf_one[k].ray.o, v->p), bsdf_one[k].ray.d) > 0.0);
            ++checked;
        }
    }
    ray_stream_free(&shadow_rays);
    ray_stream_free(&bsdf_rays);
    CHECK(checked > 1500);
}

static const struct test_case tests[] = {
    { "many_matches_one", test_many_matches_one },
    { "lambert_matches_generic", test_lambert_matches_generic },
};

TEST_MAIN(tests)

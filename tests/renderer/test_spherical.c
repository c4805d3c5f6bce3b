/* test_spherical.c: the solid-angle samplers (sphrect, sphtri, sphpoly)
   against the geometry of polygon.c: solid angle, samples inside the shape,
   a chi-square test of the direction histogram against the uniform
   solid-angle pdf in many configurations, area preservation, and
   self-tests showing that the chi-square test rejects wrong samplers.
   Set CHI2_VERBOSE=1 to print every chi-square report. */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "chi2.h"
#include "geometry/polygon.h"
#include "base/rng.h"
#include "geometry/spherical.h"
#include "geometry/target.h"
#include "testlib.h"

/* Chi-square tests expected to pass in this file: Bonferroni over them. */
#define CHI2_TESTS   25
#define SIGNIFICANCE (0.01 / CHI2_TESTS)
#define CHI2_SAMPLES 200000

enum sampler_kind { SAMPLER_RECT, SAMPLER_TRI, SAMPLER_POLY };

struct scene {
    const char *name;
    enum sampler_kind kind;
    struct polygon poly; /* the shape as a polygon: the ground truth */
    struct vec3 o;
    struct vec3 s, ex, ey; /* SAMPLER_RECT only */
};

/* The ground truth for the chi-square pdf and the inside check: does the
   ray from o along d hit the polygon? The polygon's plane and inward edge
   planes are precomputed since the chi-square integration asks ~1e6 times;
   the boundary counts as inside within 1e-9 of the polygon's size. */
struct hit_test {
    struct vec3 o, n, edge_n[POLYGON_MAX];
    double dist, edge_c[POLYGON_MAX], tol;
    int count;
};

static void hit_test_init(struct hit_test *h, const struct polygon *p, struct vec3 o)
{
    struct vec3 c = polygon_centroid(p);
    h->o = o;
    h->n = polygon_normal(p);
    h->dist = vec3_dot(h->n, vec3_sub(c, o));
    h->count = p->n;
    double size = 0.0;
    for (int i = 0; i < p->n; ++i) {
        struct vec3 e = vec3_sub(p->v[(i + 1) % p->n], p->v[i]);
        size = fmax(size, vec3_length(vec3_sub(p->v[i], c)));
        h->edge_n[i] = vec3_normalize(vec3_cross(h->n, e));
        if (vec3_dot(h->edge_n[i], vec3_sub(c, p->v[i])) < 0.0) h->edge_n[i] = vec3_neg(h->edge_n[i]);
        h->edge_c[i] = vec3_dot(h->edge_n[i], vec3_sub(p->v[i], o));
    }
    h->tol = 1e-9 * size;
}

static bool hit_test_run(const struct hit_test *h, struct vec3 d)
{
    double denom = vec3_dot(h->n, d);
    if (denom == 0.0) return false;
    double t = h->dist / denom;
    if (!(t > 0.0)) return false;
    struct vec3 x = vec3_scale(d, t); /* relative to o */
    for (int i = 0; i < h->count; ++i)
        if (vec3_dot(h->edge_n[i], x) - h->edge_c[i] < -h->tol) return false;
    return true;
}

/* Sampler state plus the knobs the self-tests use to break it. */
struct sampler {
    const struct scene *sc;
    struct hit_test hit;
    struct sphrect rect;
    struct sphtri tri;
    struct sphpoly sp;
    double omega;      /* polygon_solid_angle: the pdf is 1 / omega inside */
    long misses;       /* sampled directions whose ray misses the polygon */
    double u_exponent; /* sample with u^exponent (1: unbiased) */
    double fail_rate;  /* report failure when u3 < fail_rate */
    double pdf_scale;  /* claim pdf_scale / omega */
};

static struct polygon rect_polygon(struct vec3 s, struct vec3 ex, struct vec3 ey)
{
    struct polygon p;
    p.n = 4;
    p.v[0] = s;
    p.v[1] = vec3_add(s, ex);
    p.v[2] = vec3_add(vec3_add(s, ex), ey);
    p.v[3] = vec3_add(s, ey);
    return p;
}

static struct scene rect_scene(const char *name, struct vec3 s, struct vec3 ex, struct vec3 ey, struct vec3 o)
{
    struct scene sc;
    sc.name = name;
    sc.kind = SAMPLER_RECT;
    sc.poly = rect_polygon(s, ex, ey);
    sc.o = o;
    sc.s = s;
    sc.ex = ex;
    sc.ey = ey;
    return sc;
}

static struct scene poly_scene(const char *name, enum sampler_kind kind, int n, const struct vec3 *v, struct vec3 o)
{
    struct scene sc;
    memset(&sc, 0, sizeof sc);
    sc.name = name;
    sc.kind = kind;
    sc.poly.n = n;
    for (int i = 0; i < n; ++i) sc.poly.v[i] = v[i];
    sc.o = o;
    return sc;
}

/* A fixed rotation so that shapes are not axis-aligned. */
static struct vec3 rot(struct vec3 x)
{
    struct frame f = frame_from_normal(vec3_normalize(vec3_make(-0.4, 0.7, 0.59)));
    return frame_to_world(&f, x);
}

static struct scene regular_scene(const char *name, int n, double radius, struct vec3 centre, struct vec3 o)
{
    struct vec3 v[POLYGON_MAX];
    for (int i = 0; i < n; ++i) {
        double a = 0.3 + 2.0 * M_PI * i / n;
        v[i] = vec3_add(centre, rot(vec3_make(radius * cos(a), radius * sin(a), 0.0)));
    }
    return poly_scene(name, SAMPLER_POLY, n, v, o);
}

/* The configurations: near and far, grazing, large and tiny solid angles,
   o on both sides, o beyond the rectangle's extent, arbitrary frames. */
static int scenes_make(struct scene *out)
{
    int k = 0;
    struct vec3 s0 = vec3_make(0, 0, 0), ux = vec3_make(1, 0, 0), uy = vec3_make(0, 1, 0);
    out[k++] = rect_scene("rect near", s0, ux, uy, vec3_make(0.5, 0.5, 0.3));
    out[k++] = rect_scene("rect far", s0, ux, uy, vec3_make(0.4, 0.55, 20.0));
    out[k++] = rect_scene("rect grazing", s0, ux, uy, vec3_make(3.0, 0.5, 0.05));
    out[k++] = rect_scene("rect off-axis beyond extent", s0, ux, uy, vec3_make(2.5, -1.5, 1.0));
    out[k++] = rect_scene("rect other side", s0, ux, uy, vec3_make(0.3, 0.7, -0.5));
    out[k++] = rect_scene("rect near hemisphere", s0, ux, uy, vec3_make(0.45, 0.5, 0.01));
    out[k++] =
        rect_scene("rect tiny (1e-6 sr)", s0, vec3_scale(ux, 1e-3), vec3_scale(uy, 1e-3), vec3_make(0.2, -0.3, 1.0));
    out[k++] = rect_scene("rect tiny (1e-9 sr)", vec3_make(5, 5, 5), vec3_scale(ux, 3e-5), vec3_scale(uy, 3e-5),
                          vec3_make(5.5, 5.2, 6.0));
    out[k++] = rect_scene("rect rotated", vec3_make(1, 2, 3), rot(vec3_make(1.5, 0, 0)), rot(vec3_make(0, 0.4, 0)),
                          vec3_add(vec3_make(1, 2, 3), rot(vec3_make(-0.7, 0.9, -0.6))));

    const struct vec3 octant[3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } };
    out[k++] = poly_scene("tri octant", SAMPLER_TRI, 3, octant, s0);
    const struct vec3 wide[3] = { { 1, 0, 0.05 }, { -0.5, 0.866, 0.05 }, { -0.5, -0.866, 0.05 } };
    out[k++] = poly_scene("tri near hemisphere", SAMPLER_TRI, 3, wide, s0);
    const struct vec3 cw[3] = { { 0.2, 1.1, 0.9 }, { -0.3, 1.0, 2.1 }, { 0.9, 0.8, 1.7 } };
    out[k++] = poly_scene("tri generic, both windings", SAMPLER_TRI, 3, cw, vec3_make(0.1, 0.05, 0.1));
    const struct vec3 sliver[3] = { { 0, 0, 1 }, { 1, 0, 1 }, { 0.5, 0.01, 1 } };
    out[k++] = poly_scene("tri sliver", SAMPLER_TRI, 3, sliver, s0);
    const struct vec3 tiny[3] = { { 1, 2, 3 }, { 1.0012, 2, 3 }, { 1, 2.0009, 3.0004 } };
    out[k++] = poly_scene("tri tiny (1e-7 sr)", SAMPLER_TRI, 3, tiny, vec3_make(0.5, 1.5, 1.0));
    const struct vec3 tinier[3] = { { 1, 2, 3 }, { 1.000012, 2, 3 }, { 1, 2.000009, 3.000004 } };
    out[k++] = poly_scene("tri tiny (1e-11 sr)", SAMPLER_TRI, 3, tinier, vec3_make(0.5, 1.5, 1.0));

    out[k++] =
        regular_scene("poly hexagon near", 6, 1.0, vec3_make(0, 0, 0), vec3_add(rot(vec3_make(0.3, -0.2, 0.25)), s0));
    out[k++] = regular_scene("poly octagon far", 8, 0.5, vec3_make(1, 1, 1),
                             vec3_add(vec3_make(1, 1, 1), rot(vec3_make(2, 1, -15))));
    out[k++] =
        regular_scene("poly pentagon tiny (1e-8 sr)", 5, 1e-4, vec3_make(0, 0, 0), rot(vec3_make(0.5, 0.3, -2.0)));
    out[k++] =
        regular_scene("poly 24-gon near hemisphere", 24, 3.0, vec3_make(0, 0, 0), rot(vec3_make(0.1, 0.2, 0.02)));
    {
        /* The overlap of two rotated squares (an octagon from
           polygon_clip_convex), seen from below at a slant. */
        struct polygon a = rect_polygon(vec3_make(-1, -1, 0), vec3_make(2, 0, 0), vec3_make(0, 2, 0));
        struct polygon b;
        b.n = 4;
        for (int i = 0; i < 4; ++i) b.v[i] = vec3_make(1.3 * cos(M_PI / 2 * i), 1.3 * sin(M_PI / 2 * i), 0);
        struct polygon c;
        polygon_clip_convex(&a, &b, &c); /* an octagon */
        out[k++] = poly_scene("poly clipped octagon, below", SAMPLER_POLY, c.n, c.v, vec3_make(1.5, 0.4, -0.7));
    }
    {
        /* A square with an extra vertex on an edge, listed so that the fan's
           first triangle (1,0) (1,0.5) (1,1) is degenerate and skipped. */
        const struct vec3 v[5] = { { 1, 0, 0 }, { 1, 0.5, 0 }, { 1, 1, 0 }, { 0, 1, 0 }, { 0, 0, 0 } };
        out[k++] = poly_scene("poly collinear vertex", SAMPLER_POLY, 5, v, vec3_make(0.6, 0.3, 0.8));
    }
    return k;
}

#define SCENES_MAX 32

static bool sampler_init(struct sampler *s, const struct scene *sc)
{
    memset(s, 0, sizeof *s);
    s->sc = sc;
    hit_test_init(&s->hit, &sc->poly, sc->o);
    s->omega = polygon_solid_angle(&sc->poly, sc->o);
    s->u_exponent = 1.0;
    s->pdf_scale = 1.0;
    switch (sc->kind) {
    case SAMPLER_RECT:
        return sphrect_init(&s->rect, sc->o, sc->s, sc->ex, sc->ey);
    case SAMPLER_TRI:
        return sphtri_init(&s->tri, vec3_sub(sc->poly.v[0], sc->o), vec3_sub(sc->poly.v[1], sc->o),
                           vec3_sub(sc->poly.v[2], sc->o));
    case SAMPLER_POLY:
        return sphpoly_init(&s->sp, &sc->poly, sc->o);
    }
    return false;
}

static double sampler_solid_angle(const struct sampler *s)
{
    switch (s->sc->kind) {
    case SAMPLER_RECT:
        return s->rect.solid_angle;
    case SAMPLER_TRI:
        return s->tri.area;
    case SAMPLER_POLY:
        return s->sp.solid_angle;
    }
    return 0.0;
}

static struct vec3 sampler_direction(const struct sampler *s, double u1, double u2, double u3)
{
    switch (s->sc->kind) {
    case SAMPLER_RECT:
        return vec3_normalize(vec3_sub(sphrect_sample(&s->rect, u1, u2), s->sc->o));
    case SAMPLER_TRI:
        return sphtri_sample(&s->tri, u1, u2);
    case SAMPLER_POLY:
        return sphpoly_sample(&s->sp, u3, u1, u2);
    }
    return vec3_make(0, 0, 0);
}

static bool sample_fn(void *ctx, double u1, double u2, double u3, struct vec3 *dir)
{
    struct sampler *s = ctx;
    if (s->fail_rate > 0.0) {
        if (u3 < s->fail_rate) return false;
        u3 = (u3 - s->fail_rate) / (1.0 - s->fail_rate);
    }
    *dir = sampler_direction(s, s->u_exponent == 1.0 ? u1 : pow(u1, s->u_exponent), u2, u3);
    if (!hit_test_run(&s->hit, *dir)) ++s->misses;
    return true;
}

static double pdf_fn(void *ctx, struct vec3 dir)
{
    struct sampler *s = ctx;
    return hit_test_run(&s->hit, dir) ? s->pdf_scale / s->omega : 0.0;
}

static void chi2_config_for(struct chi2_config *cfg, const struct scene *sc, uint64_t seed)
{
    struct vec3 dirs[POLYGON_MAX];
    for (int i = 0; i < sc->poly.n; ++i) dirs[i] = vec3_sub(sc->poly.v[i], sc->o);
    chi2_config_init(cfg, vec3_make(0, 0, 1), M_PI);
    chi2_config_cap(cfg, dirs, sc->poly.n);
    cfg->samples = CHI2_SAMPLES;
    cfg->seed = seed;
    cfg->significance = SIGNIFICANCE;
}

static bool run_chi2(struct sampler *s, uint64_t seed, double *p, char *report, size_t len)
{
    struct chi2_config cfg;
    chi2_config_for(&cfg, s->sc, seed);
    bool ok = chi2_test(&cfg, sample_fn, pdf_fn, s, p, report, len);
    if (getenv("CHI2_VERBOSE")) printf("  %-34s %s\n", s->sc->name, report);
    return ok;
}

/* Relative accuracy of the samplers' solid angle: 1e-13, plus the loss of
   forming unit directions to nearby vertices (sphtri and sphpoly work on
   normalised directions whose errors of ~eps are relative to the shape's
   angular size ~sqrt(omega)). */
static double omega_tol(double omega)
{
    return omega * (1e-13 + 16.0 * DBL_EPSILON / sqrt(omega));
}

static void test_solid_angles(void)
{
    struct scene sc[SCENES_MAX];
    int n = scenes_make(sc);
    for (int i = 0; i < n; ++i) {
        struct sampler s;
        CHECK_MSG(sampler_init(&s, &sc[i]), "%s: init failed", sc[i].name);
        CHECK_MSG(fabs(sampler_solid_angle(&s) - s.omega) <= omega_tol(s.omega), "%s: %.17g vs polygon %.17g",
                  sc[i].name, sampler_solid_angle(&s), s.omega);
    }
    /* Triangle orientation does not matter. */
    struct sphtri t1, t2;
    const struct scene *g = &sc[11];
    CHECK(sphtri_init(&t1, g->poly.v[0], g->poly.v[1], g->poly.v[2]) &&
          sphtri_init(&t2, g->poly.v[0], g->poly.v[2], g->poly.v[1]));
    CHECK_NEAR(t1.area, t2.area, 1e-15);
}

static void test_init_refuses_degenerate(void)
{
    struct sphrect r;
    struct vec3 s = vec3_make(0, 0, 0), ex = vec3_make(1, 0, 0), ey = vec3_make(0, 1, 0);
    CHECK(!sphrect_init(&r, vec3_make(0.5, 0.5, 0.0), s, ex, ey));
    CHECK(!sphrect_init(&r, vec3_make(3.0, 0.5, 0.0), s, ex, ey));
    CHECK(!sphrect_init(&r, vec3_make(0.5, 0.5, 1e6), s, ex, ey)); /* 1e-12 sr */
    CHECK(sphrect_init(&r, vec3_make(0.5, 0.5, 1e5), s, ex, ey));  /* 1e-10 sr */
    CHECK(!sphrect_init(&r, vec3_make(0.5, 0.5, 1.0), s, vec3_make(0, 0, 0), ey));
    struct sphtri t;
    CHECK(!sphtri_init(&t, vec3_make(1, 0, 0), vec3_make(0, 1, 0), vec3_make(1, 1, 0)));
    CHECK(!sphtri_init(&t, vec3_make(1, 0, 0), vec3_make(1, 0, 0), vec3_make(0, 0, 1)));
    struct sphpoly sp;
    struct scene scs[SCENES_MAX];
    int n = scenes_make(scs);
    CHECK(sphpoly_init(&sp, &scs[n - 1].poly, scs[n - 1].o) && sp.n == 2); /* degenerate fan triangle skipped */
    CHECK(sphpoly_init(&sp, &scs[n - 2].poly, scs[n - 2].o) && sp.n == 6); /* the clipped octagon */
    struct polygon sq = rect_polygon(s, ex, ey);
    CHECK(!sphpoly_init(&sp, &sq, vec3_make(2, 2, 0)));
    CHECK(!sphpoly_init(&sp, &sq, vec3_make(0.5, 0.5, 1e-14)));
    CHECK(!sphpoly_init(&sp, &sq, vec3_make(0.5, 0.5, 1e7)));
    CHECK(sphpoly_init(&sp, &sq, vec3_make(0.5, 0.5, 1.0)) && sp.n == 2);
}

/* Every sample must lie in the shape: checked on all chi-square samples
   (sample_fn counts rays that miss the polygon), here on the corners of the
   unit square of (u, v), where the mappings are most strained. */
static void test_samples_inside_corners(void)
{
    struct scene sc[SCENES_MAX];
    int n = scenes_make(sc);
    const double us[] = { 0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0 - DBL_EPSILON / 2 };
    for (int i = 0; i < n; ++i) {
        struct sampler s;
        if (!sampler_init(&s, &sc[i])) continue;
        for (size_t a = 0; a < 5; ++a)
            for (size_t b = 0; b < 5; ++b)
                for (size_t c = 0; c < 5; ++c) {
                    struct vec3 d;
                    sample_fn(&s, us[a], us[b], us[c], &d);
                    CHECK_MSG(isfinite(d.x) && isfinite(d.y) && isfinite(d.z), "%s", sc[i].name);
                }
        CHECK_MSG(s.misses == 0, "%s: %ld corner samples outside", sc[i].name, s.misses);
    }
    /* sphrect maps (0, 0) to the corner s and (1, 1) to the opposite one. */
    struct sphrect r;
    struct vec3 s0 = vec3_make(1, 2, 3), ex = rot(vec3_make(1.5, 0, 0)), ey = rot(vec3_make(0, 0.4, 0));
    CHECK(sphrect_init(&r, vec3_make(0.2, 0.1, 0.3), s0, ex, ey));
    CHECK(vec3_length(vec3_sub(sphrect_sample(&r, 0, 0), s0)) < 1e-12);
    CHECK(vec3_length(vec3_sub(sphrect_sample(&r, 1, 1), vec3_add(s0, vec3_add(ex, ey)))) < 1e-12);
}

static void chi2_scene_range(int first, int last)
{
    struct scene sc[SCENES_MAX];
    int n = scenes_make(sc);
    for (int i = first; i <= last && i < n; ++i) {
        struct sampler s;
        if (!sampler_init(&s, &sc[i])) {
            CHECK_MSG(false, "%s: init failed", sc[i].name);
            continue;
        }
        double p;
        char report[512];
        bool ok = run_chi2(&s, 1000 + (uint64_t)i, &p, report, sizeof report);
        CHECK_MSG(ok, "%s: %s", sc[i].name, report);
        CHECK_MSG(s.misses == 0, "%s: %ld samples outside the shape", sc[i].name, s.misses);
    }
}

static void test_chi2_sphrect(void)
{
    chi2_scene_range(0, 8);
}
static void test_chi2_sphtri(void)
{
    chi2_scene_range(9, 14);
}
static void test_chi2_sphpoly(void)
{
    chi2_scene_range(15, 20);
}

/* Both windings of the same triangle, and the polygon sampler on a
   rectangle, give the same distribution. */
static void test_chi2_variants(void)
{
    struct scene sc[SCENES_MAX];
    scenes_make(sc);
    struct scene tri = sc[11];
    struct vec3 t = tri.poly.v[1];
    tri.poly.v[1] = tri.poly.v[2];
    tri.poly.v[2] = t;
    tri.name = "tri generic, reversed";
    struct scene rp = sc[3];
    rp.kind = SAMPLER_POLY;
    rp.name = "poly on rect off-axis";
    struct scene rg = sc[2];
    rg.kind = SAMPLER_POLY;
    rg.name = "poly on rect grazing";
    const struct scene *list[] = { &tri, &rp, &rg };
    for (int i = 0; i < 3; ++i) {
        struct sampler s;
        CHECK(sampler_init(&s, list[i]));
        double p;
        char report[512];
        CHECK_MSG(run_chi2(&s, 2000 + (uint64_t)i, &p, report, sizeof report), "%s: %s", list[i]->name, report);
        CHECK(s.misses == 0);
    }
}

/* The mean of max(0, n . w) over sampled directions, times the solid
   angle, estimates the projected solid angle; an area-preserving map gives
   polygon_projected_solid_angle. (u, v) are jittered on a 64 x 64 grid and
   the error bar comes from 16 independent replicates (5 sigma). */
static void test_area_preservation(void)
{
    struct scene sc[SCENES_MAX];
    int n = scenes_make(sc);
    enum { grid = 64, reps = 16 };
    for (int i = 0; i < n; ++i) {
        struct sampler s;
        if (!sampler_init(&s, &sc[i])) continue;
        /* A receiver normal across the shape so that part of it is below
           the horizon: perpendicular to the direction of the centroid,
           tilted towards it. */
        struct vec3 c = vec3_normalize(vec3_sub(polygon_centroid(&sc[i].poly), sc[i].o));
        struct frame f = frame_from_normal(c);
        struct vec3 nrm = vec3_normalize(vec3_add(f.x, vec3_scale(c, 0.3)));
        double expect = polygon_projected_solid_angle(&sc[i].poly, sc[i].o, nrm);
        struct rng rng;
        rng_seed(&rng, 77, (uint64_t)i, 0);
        double est[16], mean = 0.0, var = 0.0;
        for (int r = 0; r < reps; ++r) {
            double acc = 0.0;
            for (int a = 0; a < grid; ++a)
                for (int b = 0; b < grid; ++b) {
                    double u = (a + rng_uniform(&rng)) / grid, v = (b + rng_uniform(&rng)) / grid;
                    struct vec3 w = sampler_direction(&s, u, v, rng_uniform(&rng));
                    acc += fmax(0.0, vec3_dot(nrm, w));
                }
            est[r] = acc / (grid * grid) * sampler_solid_angle(&s);
            mean += est[r] / reps;
        }
        for (int r = 0; r < reps; ++r) var += (est[r] - mean) * (est[r] - mean) / (reps - 1);
        double se = sqrt(var / reps);
        /* Beyond the statistics: the samplers' solid angle and direction
           rounding, ~1e-10 relative at worst (omega_tol, sphrect's jitter). */
        CHECK_MSG(fabs(mean - expect) <= 5.0 * se + 1e-10 * expect, "%s: %.12g vs %.12g (se %.2g)", sc[i].name, mean,
                  expect, se);
        CHECK(expect > 0.0);
    }
}

/* Direct checks of the area fractions. sphrect: the strip [x0, xu] of the
   rectangle subtends u times its solid angle. sphtri: with v = 1 the sample
   is the vertex c' that cuts off the sub-triangle (a, b, c') of area u A. */
static void test_area_fractions(void)
{
    struct scene sc[SCENES_MAX];
    int n = scenes_make(sc);
    const double us[] = { 0.1, 0.37, 0.5, 0.81, 0.999 };
    for (int i = 0; i < n; ++i) {
        struct sampler s;
        if (!sampler_init(&s, &sc[i])) continue;
        for (size_t k = 0; k < 5; ++k) {
            double u = us[k];
            if (sc[i].kind == SAMPLER_RECT) {
                struct vec3 p = sphrect_sample(&s.rect, u, 0.3);
                double xu = vec3_dot(vec3_sub(p, sc[i].s), vec3_normalize(sc[i].ex));
                struct polygon strip = rect_polygon(sc[i].s, vec3_scale(vec3_normalize(sc[i].ex), xu), sc[i].ey);
                double frac = polygon_solid_angle(&strip, sc[i].o) / s.omega;
                /* sphrect's own error: ~eps / omega relative (see spherical.c). */
                CHECK_MSG(fabs(frac - u) <= 1e-10 + 64.0 * DBL_EPSILON / s.omega, "%s: u %g -> fraction %.12g",
                          sc[i].name, u, frac);
            } else if (sc[i].kind == SAMPLER_TRI) {
                struct vec3 cp = sphtri_sample(&s.tri, u, 1.0);
                struct sphtri sub;
                double area = sphtri_init(&sub, s.tri.a, s.tri.b, cp) ? sub.area : 0.0;
                CHECK_MSG(fabs(area / s.tri.area - u) <= 1e-9, "%s: u %g -> fraction %.12g", sc[i].name, u,
                          area / s.tri.area);
            }
        }
    }
}

/* The chi-square machinery: Q against closed forms, and wrong samplers or
   pdfs must be rejected (the test can fail). */
static void test_chi2_gamma_q(void)
{
    for (double x = 0.0; x < 50.0; x += 0.7) {
        CHECK_NEAR(chi2_gamma_q(1.0, x), exp(-x), 1e-14 * exp(-x) + 1e-300);
        CHECK_NEAR(chi2_gamma_q(0.5, x), erfc(sqrt(x)), 1e-12 * erfc(sqrt(x)) + 1e-300);
        /* Q(2, x) = (1 + x) e^-x (chi-square with 4 degrees of freedom). */
        CHECK_NEAR(chi2_gamma_q(2.0, x), (1.0 + x) * exp(-x), 1e-13 * (1.0 + x) * exp(-x) + 1e-300);
    }
    /* Large dof: chi^2 = dof gives p a little below 1/2. */
    double q = chi2_gamma_q(400.0, 400.0);
    CHECK(q > 0.48 && q < 0.5);
}

static void test_chi2_rejects_wrong(void)
{
    struct scene sc[SCENES_MAX];
    scenes_make(sc);
    char report[512];
    double p;
    struct sampler s;

    /* A 3% distortion of the rectangle's u coordinate. */
    CHECK(sampler_init(&s, &sc[3]));
    s.u_exponent = 1.03;
    CHECK_MSG(!run_chi2(&s, 3000, &p, report, sizeof report), "biased sampler passed: %s", report);
    CHECK(p < SIGNIFICANCE);
    /* A tiny triangle sampled with a distorted u. */
    CHECK(sampler_init(&s, &sc[14]));
    s.u_exponent = 1.05;
    CHECK_MSG(!run_chi2(&s, 3001, &p, report, sizeof report), "biased tiny sampler passed: %s", report);
    /* A pdf claiming 20% too much. */
    CHECK(sampler_init(&s, &sc[0]));
    s.pdf_scale = 1.2;
    CHECK_MSG(!run_chi2(&s, 3002, &p, report, sizeof report), "scaled pdf passed: %s", report);
    /* A pdf 2% short: the test expects 2% failures and sees none. */
    CHECK(sampler_init(&s, &sc[16]));
    s.pdf_scale = 0.98;
    CHECK_MSG(!run_chi2(&s, 3003, &p, report, sizeof report), "defective pdf passed: %s", report);
    /* Failures that the pdf does not account for. */
    CHECK(sampler_init(&s, &sc[0]));
    s.fail_rate = 0.02;
    CHECK_MSG(!run_chi2(&s, 3004, &p, report, sizeof report), "unreported failures passed: %s", report);
    /* The right answer for the wrong shape: the triangle's pdf, sampled over
       the polygon that contains it. */
    CHECK(sampler_init(&s, &sc[15]));
    struct scene half = sc[15];
    half.poly.n = 3;
    struct sampler truth;
    CHECK(sampler_init(&truth, &half));
    s.sc = &half;
    s.hit = truth.hit;
    s.omega = truth.omega;
    CHECK_MSG(!run_chi2(&s, 3005, &p, report, sizeof report), "sampler outside the support passed: %s", report);
    CHECK(s.misses > 0);
}

/* Failures matched by a defective pdf are consistent: this must pass. */
static void test_chi2_accepts_consistent_failures(void)
{
    struct scene sc[SCENES_MAX];
    scenes_make(sc);
    struct sampler s;
    CHECK(sampler_init(&s, &sc[3]));
    s.fail_rate = 0.1;
    s.pdf_scale = 0.9;
    double p;
    char report[512];
    CHECK_MSG(run_chi2(&s, 4000, &p, report, sizeof report), "%s", report);
}

/* ---- batched samplers ------------------------------------------------------
   sphrect_sample_many and target_sample_solid_angle_many promise the results
   of their one-lane counterparts bit for bit (the renderer's images must not
   depend on which path sampled a pixel). Compared with memcmp, so that a
   differing sign of zero or NaN payload counts too (same_bits). */

static bool same_vec_bits(struct vec3 a, struct vec3 b)
{
    return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

/* Uniform in [-a, a). */
static double symm(struct rng *r, double a)
{
    return (2.0 * rng_uniform(r) - 1.0) * a;
}

static struct vec3 random_unit(struct rng *r)
{
    for (;;) {
        struct vec3 v = vec3_make(symm(r, 1.0), symm(r, 1.0), symm(r, 1.0));
        double l = vec3_length(v);
        if (l > 0.1 && l <= 1.0) return vec3_scale(v, 1.0 / l);
    }
}

/* A rectangle in general position: random corner, random perpendicular
   edges of random lengths 1e-3..10 (log-uniform). */
static void random_rect(struct rng *r, struct vec3 *s, struct vec3 *ex, struct vec3 *ey)
{
    struct vec3 a = random_unit(r);
    struct vec3 b = vec3_normalize(vec3_cross(a, random_unit(r)));
    *s = vec3_make(symm(r, 5.0), symm(r, 5.0), symm(r, 5.0));
    *ex = vec3_scale(a, pow(10.0, -3.0 + 4.0 * rng_uniform(r)));
    *ey = vec3_scale(b, pow(10.0, -3.0 + 4.0 * rng_uniform(r)));
}

/* u or v: mostly random, sometimes the ends of [0, 1). */
static double random_uv(struct rng *r)
{
    double k = rng_uniform(r);
    if (k < 0.1) return 0.0;
    if (k < 0.2) return nextafter(1.0, 0.0);
    return rng_uniform(r);
}

/* Viewpoints for the frame f, by kind: near (either side, heights
   1e-3..10 times the rectangle's size, beyond its extent too), exactly or
   nearly in its plane, far enough for a solid angle below 1e-12, anywhere
   in a box around everything. */
enum { VIEW_NEAR, VIEW_PLANE, VIEW_FAR, VIEW_BOX, VIEW_KINDS };

static struct vec3 random_view(struct rng *r, const struct sphrect_frame *f, int kind)
{
    double size = fmax(f->ex_len, f->ey_len);
    struct vec3 in_plane = vec3_add(f->corner, vec3_add(vec3_scale(f->x, f->ex_len * (-1.0 + 3.0 * rng_uniform(r))),
                                                        vec3_scale(f->y, f->ey_len * (-1.0 + 3.0 * rng_uniform(r)))));
    switch (kind) {
    case VIEW_NEAR:
        return vec3_madd(in_plane, f->z,
                         (rng_uniform(r) < 0.5 ? -1.0 : 1.0) * size * pow(10.0, -3.0 + 4.0 * rng_uniform(r)));
    case VIEW_PLANE:
        return in_plane;
    case VIEW_FAR:
        return vec3_madd(f->corner, random_unit(r), size * 1e7);
    default:
        return vec3_make(symm(r, 10.0), symm(r, 10.0), symm(r, 10.0));
    }
}

/* Lane i of a sphrect_sample_many call against sphrect_init_frame +
   sphrect_sample_dir. Returns 1 when init accepted the lane, 0 when it
   refused (then only solid_angle == 0 is required), -1 on a mismatch. */
static int rect_lane_check(const struct sphrect_frame *f, struct vec3 o, double u, double v, struct vec3 wi,
                           double dist, double sa, int lane)
{
    struct sphrect r;
    if (!sphrect_init_frame(&r, f, o)) {
        if (sa == 0.0) return 0;
        fprintf(stderr, "  lane %d: init refuses o = (%.17g, %.17g, %.17g), many gives solid angle %.17g\n", lane, o.x,
                o.y, o.z, sa);
        return -1;
    }
    double d_ref;
    struct vec3 w_ref = sphrect_sample_dir(&r, u, v, &d_ref);
    if (same_vec_bits(wi, w_ref) && same_bits(dist, d_ref) && same_bits(sa, r.solid_angle)) return 1;
    fprintf(
        stderr,
        "  lane %d: corner (%.17g, %.17g, %.17g) x (%.17g, %.17g, %.17g) y (%.17g, %.17g, %.17g) lengths %.17g %.17g,\n"
        "    o (%.17g, %.17g, %.17g), u %.17g v %.17g:\n"
        "    many wi (%.17g, %.17g, %.17g) dist %.17g sa %.17g\n"
        "    one  wi (%.17g, %.17g, %.17g) dist %.17g sa %.17g\n",
        lane, f->corner.x, f->corner.y, f->corner.z, f->x.x, f->x.y, f->x.z, f->y.x, f->y.y, f->y.z, f->ex_len,
        f->ey_len, o.x, o.y, o.z, u, v, wi.x, wi.y, wi.z, dist, sa, w_ref.x, w_ref.y, w_ref.z, d_ref, r.solid_angle);
    return -1;
}

#define RECT_FRAMES    40
#define RECT_LANES_MAX 1000

/* sphrect_sample_many on n lanes (frames from a pool, so that neighbouring
   lanes differ) against the one-lane path; lanes beyond n untouched.
   Counts the accepted and refused lanes. */
static void rect_many_run(struct rng *r, const struct sphrect_frame *pool, int n_pool, int n, int fixed_kind,
                          long *accepted, long *refused)
{
    static const struct sphrect_frame *frames[RECT_LANES_MAX + 4];
    static struct vec3 o[RECT_LANES_MAX + 4], wi[RECT_LANES_MAX + 4];
    static double u[RECT_LANES_MAX + 4], v[RECT_LANES_MAX + 4], dist[RECT_LANES_MAX + 4], sa[RECT_LANES_MAX + 4];
    for (int i = 0; i < n + 4; ++i) {
        frames[i] = &pool[(int)(rng_uniform(r) * n_pool)];
        o[i] = random_view(r, frames[i], fixed_kind >= 0 ? fixed_kind : (int)(rng_uniform(r) * VIEW_KINDS));
        u[i] = random_uv(r);
        v[i] = random_uv(r);
        wi[i] = vec3_make(-7.0, -7.0, -7.0);
        dist[i] = sa[i] = -7.0;
    }
    sphrect_sample_many(frames, o, u, v, n, wi, dist, sa);
    int bad = 0;
    for (int i = 0; i < n; ++i) {
        int k = rect_lane_check(frames[i], o[i], u[i], v[i], wi[i], dist[i], sa[i], i);
        if (k < 0) ++bad;
        else if (k > 0) ++*accepted;
        else ++*refused;
    }
    CHECK_MSG(bad == 0, "n = %d: %d lanes differ from the one-lane sampler", n, bad);
    for (int i = n; i < n + 4; ++i)
        CHECK_MSG(wi[i].x == -7.0 && wi[i].y == -7.0 && wi[i].z == -7.0 && dist[i] == -7.0 && sa[i] == -7.0,
                  "n = %d: lane %d beyond n written", n, i);
}

static void test_sphrect_many_matches_one(void)
{
    struct rng r;
    rng_seed(&r, 515, 1, 0);
    struct sphrect_frame pool[RECT_FRAMES];
    for (int i = 0; i < RECT_FRAMES; ++i) {
        struct vec3 s, ex, ey;
        random_rect(&r, &s, &ex, &ey);
        CHECK(sphrect_frame_init(&pool[i], s, ex, ey));
    }
    long accepted = 0, refused = 0;
    /* Block sizes around the internal block of 16, and larger runs. */
    const int sizes[] = { 0, 1, 2, 15, 16, 17, 31, 32, 33, 100, 1000 };
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k)
        for (int rep = 0; rep < 20; ++rep) rect_many_run(&r, pool, RECT_FRAMES, sizes[k], -1, &accepted, &refused);
    /* One frame for all lanes, and each kind of viewpoint alone. */
    for (int kind = 0; kind < VIEW_KINDS; ++kind) {
        long a0 = accepted, r0 = refused;
        rect_many_run(&r, pool + kind, 1, 100, kind, &accepted, &refused);
        rect_many_run(&r, pool, RECT_FRAMES, 100, kind, &accepted, &refused);
        /* Far points subtend < 1e-12 sr: all refused. */
        if (kind == VIEW_FAR) CHECK_MSG(accepted == a0, "far viewpoints accepted: %ld", accepted - a0);
        if (kind == VIEW_NEAR) CHECK(accepted - a0 == 200 && refused == r0);
    }
    /* Points exactly in the plane of an axis-aligned rectangle (z0 = 0
       without rounding), and just off it: refused, so solid angle 0. */
    struct sphrect_frame flat;
    CHECK(sphrect_frame_init(&flat, vec3_make(0.25, -0.5, 2.0), vec3_make(1.5, 0, 0), vec3_make(0, 0.75, 0)));
    const struct sphrect_frame *ff[17];
    struct vec3 fo[17], fw[17];
    double fu[17], fv[17], fd[17], fs[17];
    for (int i = 0; i < 17; ++i) {
        ff[i] = &flat;
        fo[i] = vec3_make(-1.0 + 0.25 * i, 0.1 * i - 1.0, i % 2 ? 2.0 : 2.0 + 1e-13 * (i % 3));
        fu[i] = random_uv(&r);
        fv[i] = random_uv(&r);
    }
    sphrect_sample_many(ff, fo, fu, fv, 17, fw, fd, fs);
    for (int i = 0; i < 17; ++i) {
        struct sphrect rr;
        CHECK_MSG(!sphrect_init_frame(&rr, &flat, fo[i]), "lane %d accepted in the plane", i);
        CHECK_MSG(fs[i] == 0.0, "lane %d: solid angle %.17g in the plane", i, fs[i]);
    }
    /* Both outcomes must have been exercised. */
    CHECK(accepted > 1000 && refused > 1000);
    printf("  sphrect_sample_many: %ld lanes sampled, %ld refused, all as the one-lane sampler\n", accepted, refused);
}

/* Targets: rectangles (is_rectangle, the vectorised path), a
   parallelogram, a triangle and a pentagon (the one-point path inside the
   many call), each in general position. */
#define MANY_TARGETS 12

static struct polygon random_convex(struct rng *r, int kind)
{
    struct vec3 s, ex, ey;
    random_rect(r, &s, &ex, &ey);
    struct polygon p;
    switch (kind) {
    case 0: /* rectangle */
        p.n = 4;
        p.v[0] = s;
        p.v[1] = vec3_add(s, ex);
        p.v[2] = vec3_add(vec3_add(s, ex), ey);
        p.v[3] = vec3_add(s, ey);
        break;
    case 1: /* parallelogram: not a rectangle */
        p.n = 4;
        p.v[0] = s;
        p.v[1] = vec3_add(s, ex);
        p.v[2] = vec3_add(vec3_add(s, ex), vec3_add(ey, vec3_scale(ex, 0.4)));
        p.v[3] = vec3_add(s, vec3_add(ey, vec3_scale(ex, 0.4)));
        break;
    case 2: /* triangle */
        p.n = 3;
        p.v[0] = s;
        p.v[1] = vec3_add(s, ex);
        p.v[2] = vec3_add(s, vec3_add(ey, vec3_scale(ex, 0.3)));
        break;
    default: { /* regular pentagon */
        p.n = 5;
        double rad = vec3_length(ex);
        struct vec3 a = vec3_normalize(ex), b = vec3_normalize(ey);
        for (int i = 0; i < 5; ++i) {
            double t = 2.0 * M_PI * i / 5.0;
            p.v[i] = vec3_add(s, vec3_add(vec3_scale(a, rad * cos(t)), vec3_scale(b, rad * sin(t))));
        }
    }
    }
    return p;
}

/* Where p stands relative to target t, as target_sample_solid_angle
   decides: below min_height, solid angle usable, or too small. */
enum { TP_LOW, TP_SOLID, TP_TINY };

static int target_case(const struct target *t, struct vec3 p)
{
    double h = fabs(vec3_dot(vec3_sub(p, t->polygon.v[0]), t->normal));
    if (h <= t->min_height) return TP_LOW;
    double omega = polygon_solid_angle(&t->polygon, p);
    return omega >= 1e-7 ? TP_SOLID : TP_TINY;
}

static struct vec3 random_target_view(struct rng *r, const struct target *t, int kind)
{
    struct vec3 c = polygon_centroid(&t->polygon);
    double size = polygon_size(&t->polygon);
    struct vec3 in_plane = vec3_add(
        c, vec3_scale(vec3_sub(t->polygon.v[(int)(rng_uniform(r) * t->polygon.n)], c), -1.0 + 3.0 * rng_uniform(r)));
    double side = rng_uniform(r) < 0.5 ? -1.0 : 1.0;
    switch (kind) {
    case 0: /* near, either side */
        return vec3_madd(in_plane, t->normal, side * size * pow(10.0, -2.0 + 3.0 * rng_uniform(r)));
    case 1: /* below min_height: area sampling */
        return vec3_madd(in_plane, t->normal, side * t->min_height * rng_uniform(r));
    case 2: /* far: solid angle 1e-16..1e-6, area sampling below 1e-7 */
        return vec3_madd(c, random_unit(r), size * pow(10.0, 2.5 + 5.0 * rng_uniform(r)));
    default:
        return vec3_make(symm(r, 10.0), symm(r, 10.0), symm(r, 10.0));
    }
}

/* target_init_polygon then target_finish (a portal strategy's deferred
   target) must make the same target as target_init, field for field, and
   refuse the same polygons: the kinds of random_convex, with a repeated
   and a collinear vertex inserted as clipping leaves them, and degenerate
   ones (a segment, three points on a line, two points). */
static void test_target_two_steps_match_init(void)
{
    struct rng r;
    rng_seed(&r, 71, 3, 0);
    int checked = 0;
    for (int i = 0; i < 200; ++i) {
        struct polygon p = random_convex(&r, i % 4);
        if (i % 3 == 1) { /* a repeated vertex */
            for (int k = p.n; k > 1; --k) p.v[k] = p.v[k - 1];
            ++p.n;
        } else if (i % 3 == 2) { /* a vertex on the first edge */
            for (int k = p.n; k > 1; --k) p.v[k] = p.v[k - 1];
            p.v[1] = vec3_madd(p.v[0], vec3_sub(p.v[2], p.v[0]), 0.25);
            ++p.n;
        }
        if (i % 10 == 9) { /* degenerate: all on the first edge's line */
            struct vec3 a = p.v[0], d = vec3_sub(p.v[1], p.v[0]);
            p.n = 2 + i % 3;
            for (int k = 0; k < p.n; ++k) p.v[k] = vec3_madd(a, d, (double)k);
        }
        struct target one, two;
        memset(&one, 0, sizeof one);
        memset(&two, 0, sizeof two);
        bool ok_one = target_init(&one, &p);
        bool ok_two = target_init_polygon(&two, &p) && target_finish(&two);
        CHECK_MSG(ok_one == ok_two, "polygon %d: target_init %d, two steps %d", i, ok_one, ok_two);
        if (!ok_one || !ok_two) continue;
        ++checked;
        CHECK(one.polygon.n == two.polygon.n &&
              memcmp(one.polygon.v, two.polygon.v, sizeof one.polygon.v[0] * (size_t)one.polygon.n) == 0);
        CHECK(memcmp(&one.normal, &two.normal, sizeof one.normal) == 0 && one.area == two.area &&
              one.min_height == two.min_height && one.is_rectangle == two.is_rectangle);
        CHECK(!one.is_rectangle || memcmp(&one.frame, &two.frame, sizeof one.frame) == 0);
    }
    CHECK(checked >= 170); /* all but the 20 degenerate ones */
}

static void test_target_many_matches_one(void)
{
    struct rng r;
    rng_seed(&r, 616, 1, 0);
    struct target targets[MANY_TARGETS];
    int rects = 0;
    for (int i = 0; i < MANY_TARGETS; ++i) {
        /* Half of them rectangles. */
        struct polygon p = random_convex(&r, i % 2 ? 0 : i / 2 % 4);
        CHECK(target_init(&targets[i], &p));
        rects += targets[i].is_rectangle;
    }
    CHECK(rects >= MANY_TARGETS / 2 && !targets[2].is_rectangle); /* the parallelogram is not one */
    enum { N = 700 };
    static const struct target *tt[N];
    static struct vec3 p[N];
    static double u[N][3];
    static struct target_point one[N], many[N];
    static bool ok_one[N], ok_many[N];
    long cases[2][3] = { { 0 } }; /* [rectangle][target_case] */
    long total_ok = 0;
    const int sizes[] = { 0, 1, 17, 63, 64, 65, 128, 129, 200, N };
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k)
        for (int rep = 0; rep < 5; ++rep) {
            int n = sizes[k];
            for (int i = 0; i < n; ++i) {
                tt[i] = &targets[(int)(rng_uniform(&r) * MANY_TARGETS)];
                p[i] = random_target_view(&r, tt[i], (int)(rng_uniform(&r) * 4));
                for (int j = 0; j < 3; ++j) u[i][j] = random_uv(&r);
                ++cases[tt[i]->is_rectangle][target_case(tt[i], p[i])];
            }
            /* The same bytes in both before: lanes a path leaves unwritten
               must then agree too. */
            memset(one, 0x5a, sizeof one);
            memset(many, 0x5a, sizeof many);
            for (int i = 0; i < n; ++i)
                ok_one[i] = target_sample_solid_angle(tt[i], p[i], u[i][0], u[i][1], u[i][2], &one[i]);
            /* ok[] prefilled both ways: every lane must be written. */
            for (int fill = 0; fill < 2; ++fill) {
                for (int i = 0; i < N; ++i) ok_many[i] = fill;
                target_sample_solid_angle_many(tt, p, (const double(*)[3])u, n, many, ok_many);
                int bad = 0;
                for (int i = 0; i < n; ++i) {
                    if (ok_many[i] == ok_one[i] && !memcmp(&many[i], &one[i], sizeof one[i])) continue;
                    if (bad++ < 3)
                        fprintf(stderr,
                                "  n = %d lane %d (%s, %d vertices, case %d), p (%.17g, %.17g, %.17g), u %.17g %.17g "
                                "%.17g:\n"
                                "    many ok %d wi (%.17g, %.17g, %.17g) dist %.17g pdf %.17g\n"
                                "    one  ok %d wi (%.17g, %.17g, %.17g) dist %.17g pdf %.17g\n",
                                n, i, tt[i]->is_rectangle ? "rectangle" : "polygon", tt[i]->polygon.n,
                                target_case(tt[i], p[i]), p[i].x, p[i].y, p[i].z, u[i][0], u[i][1], u[i][2], ok_many[i],
                                many[i].wi.x, many[i].wi.y, many[i].wi.z, many[i].dist, many[i].pdf_sa, ok_one[i],
                                one[i].wi.x, one[i].wi.y, one[i].wi.z, one[i].dist, one[i].pdf_sa);
                }
                CHECK_MSG(bad == 0, "n = %d: %d lanes differ from target_sample_solid_angle", n, bad);
                for (int i = n; i < N; ++i) CHECK_MSG(ok_many[i] == fill, "n = %d: ok[%d] beyond n written", n, i);
                if (bad) break;
            }
            for (int i = 0; i < n; ++i) total_ok += ok_one[i];
        }
    /* Every way through, for rectangles and for the other polygons. */
    for (int rect = 0; rect < 2; ++rect)
        for (int c = 0; c < 3; ++c)
            CHECK_MSG(cases[rect][c] > 50, "rectangle %d case %d: %ld lanes", rect, c, cases[rect][c]);
    CHECK(total_ok > 0);
    printf(
        "  target_sample_solid_angle_many: rectangles %ld low / %ld solid angle / %ld tiny, polygons %ld / %ld / %ld "
        "lanes, all as the one-point sampler\n",
        cases[1][0], cases[1][1], cases[1][2], cases[0][0], cases[0][1], cases[0][2]);
}

static const struct test_case spherical_tests[] = {
    { "solid_angles", test_solid_angles },
    { "init_refuses_degenerate", test_init_refuses_degenerate },
    { "samples_inside_corners", test_samples_inside_corners },
    { "area_fractions", test_area_fractions },
    { "area_preservation", test_area_preservation },
    { "chi2_gamma_q", test_chi2_gamma_q },
    { "chi2_sphrect", test_chi2_sphrect },
    { "chi2_sphtri", test_chi2_sphtri },
    { "chi2_sphpoly", test_chi2_sphpoly },
    { "chi2_variants", test_chi2_variants },
    { "chi2_accepts_consistent_failures", test_chi2_accepts_consistent_failures },
    { "chi2_rejects_wrong", test_chi2_rejects_wrong },
    { "sphrect_many_matches_one", test_sphrect_many_matches_one },
    { "target_many_matches_one", test_target_many_matches_one },
    { "target_two_steps_match_init", test_target_two_steps_match_init },
};

TEST_MAIN(spherical_tests)

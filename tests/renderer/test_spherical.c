/* test_spherical.c: the solid-angle samplers (sphrect, sphtri, sphpoly)
   against the geometry of polygon.c: solid angle, samples inside the shape,
   a chi-square test of the direction histogram against the uniform
   solid-angle pdf in many configurations, area preservation, and
   self-tests showing that the chi-square test rejects wrong samplers.
   Set CHI2_VERBOSE=1 to print every chi-square report. */
#include <float.h>
#include <stdlib.h>

#include "chi2.h"
#include "polygon.h"
#include "spherical.h"
#include "testlib.h"

/* Chi-square tests expected to pass in this file: Bonferroni over them. */
#define CHI2_TESTS 25
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
    double omega;       /* polygon_solid_angle: the pdf is 1 / omega inside */
    long misses;        /* sampled directions whose ray misses the polygon */
    double u_exponent;  /* sample with u^exponent (1: unbiased) */
    double fail_rate;   /* report failure when u3 < fail_rate */
    double pdf_scale;   /* claim pdf_scale / omega */
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
    out[k++] = rect_scene("rect tiny (1e-6 sr)", s0, vec3_scale(ux, 1e-3), vec3_scale(uy, 1e-3),
                          vec3_make(0.2, -0.3, 1.0));
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

    out[k++] = regular_scene("poly hexagon near", 6, 1.0, vec3_make(0, 0, 0), vec3_add(rot(vec3_make(0.3, -0.2, 0.25)), s0));
    out[k++] = regular_scene("poly octagon far", 8, 0.5, vec3_make(1, 1, 1), vec3_add(vec3_make(1, 1, 1), rot(vec3_make(2, 1, -15))));
    out[k++] = regular_scene("poly pentagon tiny (1e-8 sr)", 5, 1e-4, vec3_make(0, 0, 0), rot(vec3_make(0.5, 0.3, -2.0)));
    out[k++] = regular_scene("poly 24-gon near hemisphere", 24, 3.0, vec3_make(0, 0, 0), rot(vec3_make(0.1, 0.2, 0.02)));
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
    CHECK(!sphrect_init(&r, vec3_make(0.5, 0.5, 1e6), s, ex, ey));  /* 1e-12 sr */
    CHECK(sphrect_init(&r, vec3_make(0.5, 0.5, 1e5), s, ex, ey));   /* 1e-10 sr */
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

static void test_chi2_sphrect(void) { chi2_scene_range(0, 8); }
static void test_chi2_sphtri(void) { chi2_scene_range(9, 14); }
static void test_chi2_sphpoly(void) { chi2_scene_range(15, 20); }

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
};

TEST_MAIN(spherical_tests)

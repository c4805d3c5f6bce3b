/* test_antishadow.c: the antishadow classifier and visible polygon against
   hand-derived values (the lampshade) and against a brute force that knows
   nothing of the planes: it projects light points from p onto the portal
   plane and measures how far inside the portal they land, and traces rays
   from p through portal points to the light's plane. */
#include <float.h>
#include <string.h>
#include <time.h>

#include "geometry/antishadow.h"
#include "config/config.h"
#include "geometry/polygon.h"
#include "base/rng.h"
#include "geometry/target.h"
#include "testlib.h"

/* Rotation of v about the unit axis by angle (Rodrigues). */
static struct vec3 rotate_axis(struct vec3 v, struct vec3 axis, double angle)
{
    double c = cos(angle), s = sin(angle);
    return vec3_add(vec3_add(vec3_scale(v, c), vec3_scale(vec3_cross(axis, v), s)),
                    vec3_scale(axis, vec3_dot(axis, v) * (1.0 - c)));
}

/* Regular n-gon of circumradius r centred at c in the plane spanned by the
   unit vectors u, v (counter-clockwise about cross(u, v)). */
static struct polygon ngon(struct vec3 c, struct vec3 u, struct vec3 v, double r, int n, double phase)
{
    struct polygon p;
    p.n = n;
    for (int i = 0; i < n; ++i) {
        double a = phase + 2.0 * M_PI * i / n;
        p.v[i] = vec3_add(c, vec3_add(vec3_scale(u, r * cos(a)), vec3_scale(v, r * sin(a))));
    }
    return p;
}

/* Square of the given side, edges along u and v. */
static struct polygon square(struct vec3 c, struct vec3 u, struct vec3 v, double side)
{
    return ngon(c, vec3_scale(vec3_add(u, v), sqrt(0.5)), vec3_scale(vec3_sub(v, u), sqrt(0.5)), side * sqrt(0.5), 4,
                0.0);
}

static struct polygon reversed(const struct polygon *p)
{
    struct polygon r;
    r.n = p->n;
    for (int i = 0; i < p->n; ++i) r.v[i] = p->v[p->n - 1 - i];
    return r;
}

static struct polygon rotated(const struct polygon *p, struct vec3 centre, struct vec3 axis, double angle)
{
    struct polygon r = *p;
    for (int i = 0; i < p->n; ++i) r.v[i] = vec3_add(centre, rotate_axis(vec3_sub(p->v[i], centre), axis, angle));
    return r;
}

static const struct vec3 X = { 1, 0, 0 }, Y = { 0, 1, 0 }, Z = { 0, 0, 1 };

/* The lampshade pair: light square side s_L at y = 2.6, portal square side
   0.3 at y = 2.2, both centred on the y axis. */
static void lampshade(double s_light, struct polygon *light, struct polygon *portal)
{
    *light = square(vec3_make(0, 2.6, 0), X, Z, s_light); /* winding normal -y: faces the room */
    *portal = square(vec3_make(0, 2.2, 0), X, Z, 0.3);
}

/* A polygon as a flat region: Newell normal and inward edge normals, so that
   inside_margin is the smallest distance (in its plane) to an edge line,
   positive inside. 1-Lipschitz in x. */
struct flat {
    int n;
    struct vec3 normal;
    double offset;
    struct vec3 edge_normal[POLYGON_MAX];
    double edge_offset[POLYGON_MAX];
};

static bool flat_init(struct flat *f, const struct polygon *poly)
{
    struct vec3 nrm = vec3_make(0, 0, 0), mean = vec3_make(0, 0, 0);
    for (int i = 0; i < poly->n; ++i) {
        nrm = vec3_add(nrm, vec3_cross(poly->v[i], poly->v[(i + 1) % poly->n]));
        mean = vec3_add(mean, vec3_scale(poly->v[i], 1.0 / poly->n));
    }
    if (!(vec3_length(nrm) > 1e-14)) return false;
    f->normal = vec3_normalize(nrm);
    f->offset = vec3_dot(f->normal, mean);
    f->n = 0;
    for (int i = 0; i < poly->n; ++i) {
        struct vec3 a = poly->v[i], e = vec3_sub(poly->v[(i + 1) % poly->n], a);
        if (!(vec3_length(e) > 1e-12)) continue;
        f->edge_normal[f->n] = vec3_normalize(vec3_cross(f->normal, e));
        f->edge_offset[f->n] = vec3_dot(f->edge_normal[f->n], a);
        ++f->n;
    }
    return f->n >= 3;
}

static double flat_inside(const struct flat *f, struct vec3 x)
{
    double m = INFINITY;
    for (int i = 0; i < f->n; ++i) m = fmin(m, vec3_dot(f->edge_normal[i], x) - f->edge_offset[i]);
    return m;
}

/* Uniform point in a convex polygon: a fan triangle by area, then uniform
   barycentrics. */
static struct vec3 polygon_uniform(const struct polygon *poly, struct rng *r)
{
    double area[POLYGON_MAX], total = 0.0;
    for (int i = 1; i + 1 < poly->n; ++i) {
        area[i] = vec3_length(vec3_cross(vec3_sub(poly->v[i], poly->v[0]), vec3_sub(poly->v[i + 1], poly->v[0])));
        total += area[i];
    }
    double u = rng_uniform(r) * total;
    int k = 1;
    while (k + 2 < poly->n && u > area[k]) u -= area[k++];
    double b1 = rng_uniform(r), b2 = rng_uniform(r);
    if (b1 + b2 > 1.0) {
        b1 = 1.0 - b1;
        b2 = 1.0 - b2;
    }
    return vec3_add(poly->v[0], vec3_add(vec3_scale(vec3_sub(poly->v[k], poly->v[0]), b1),
                                         vec3_scale(vec3_sub(poly->v[k + 1], poly->v[0]), b2)));
}

#define BF_LIGHT_SAMPLES  24
#define BF_PORTAL_SAMPLES 24
/* Margin (metres) under which a brute-force decision counts as ambiguous. */
#define BF_DELTA     1e-4
#define BF_MAX_DEPTH 14
#define BF_MAX_EVALS 3000

struct brute {
    struct polygon light, portal;
    struct flat light_flat, portal_flat;
    struct vec3 beyond; /* unit normal of the portal plane, away from the light */
    double beyond_offset;
    struct vec3 light_samples[BF_LIGHT_SAMPLES + POLYGON_INPUT_MAX];
    struct vec3 portal_samples[BF_PORTAL_SAMPLES + POLYGON_INPUT_MAX];
    int n_light_samples, n_portal_samples;
};

static void brute_init(struct brute *b, const struct polygon *light, const struct polygon *portal, uint64_t seed)
{
    b->light = *light;
    b->portal = *portal;
    CHECK(flat_init(&b->light_flat, light));
    CHECK(flat_init(&b->portal_flat, portal));
    b->beyond = b->portal_flat.normal;
    b->beyond_offset = b->portal_flat.offset;
    if (vec3_dot(b->beyond, light->v[0]) - b->beyond_offset > 0.0) {
        b->beyond = vec3_neg(b->beyond);
        b->beyond_offset = -b->beyond_offset;
    }
    struct rng r;
    rng_seed(&r, seed, 1, 0);
    b->n_light_samples = 0;
    for (int i = 0; i < light->n; ++i) b->light_samples[b->n_light_samples++] = light->v[i];
    for (int i = 0; i < BF_LIGHT_SAMPLES; ++i) b->light_samples[b->n_light_samples++] = polygon_uniform(light, &r);
    b->n_portal_samples = 0;
    for (int i = 0; i < portal->n; ++i) b->portal_samples[b->n_portal_samples++] = portal->v[i];
    for (int i = 0; i < BF_PORTAL_SAMPLES; ++i) b->portal_samples[b->n_portal_samples++] = polygon_uniform(portal, &r);
}

static double beyond_distance(const struct brute *b, struct vec3 x)
{
    return vec3_dot(b->beyond, x) - b->beyond_offset;
}

/* How far inside the portal the segment from p (beyond, at distance dp) to
   the light point l crosses the portal plane. */
static double light_point_margin(const struct brute *b, struct vec3 p, double dp, struct vec3 l)
{
    double dl = beyond_distance(b, l);
    struct vec3 x = vec3_madd(p, vec3_sub(l, p), dp / (dp - dl));
    return flat_inside(&b->portal_flat, x);
}

/* How far inside the light the ray from p through q meets the light's plane;
   -infinity when it never does. */
static double portal_point_margin(const struct brute *b, struct vec3 p, struct vec3 q)
{
    struct vec3 w = vec3_sub(q, p);
    double denom = vec3_dot(b->light_flat.normal, w);
    double num = b->light_flat.offset - vec3_dot(b->light_flat.normal, p);
    if (denom == 0.0) return -INFINITY;
    double t = num / denom;
    if (!(t > 0.0)) return -INFINITY;
    return flat_inside(&b->light_flat, vec3_madd(p, w, t));
}

enum tri_state { TRI_NO, TRI_YES, TRI_UNSURE };

/* Does any light point reach p through the portal (margin BF_DELTA)? A yes
   is a witness; a no is a proof by branch and bound over a subdivision of
   the light: on a triangle T of diameter h the margin is at most its largest
   vertex margin + K_T h, with K_T a bound on the Lipschitz constant of the
   projection l -> x(l) = p + t (l - p), t = dp / (dp - d(l)), over T: its
   Jacobian t I + (l - p) grad(t)^T has norm <= t + |l - p| t^2 / dp, where t
   is largest at T's vertex nearest the portal plane and |l - p| at T's
   farthest vertex (d is affine and |l - p| convex on T). */
static double triangle_lipschitz(const struct brute *b, struct vec3 p, double dp, const struct vec3 *v)
{
    double d_near = INFINITY, far = 0.0;
    for (int i = 0; i < 3; ++i) {
        d_near = fmin(d_near, -beyond_distance(b, v[i]));
        far = fmax(far, vec3_length(vec3_sub(v[i], p)));
    }
    double t_max = dp / (dp + d_near);
    return t_max + far * t_max * t_max / dp;
}

static enum tri_state brute_any_visible(const struct brute *b, struct vec3 p, double dp)
{
    struct node {
        struct vec3 v[3];
        double m[3];
        int depth;
    } stack[256];
    int top = 0, evals = 0;
    bool unsure = false;
    double m0 = light_point_margin(b, p, dp, b->light.v[0]);
    for (int i = 1; i + 1 < b->light.n; ++i) {
        struct node nd = { { b->light.v[0], b->light.v[i], b->light.v[i + 1] }, { m0, 0, 0 }, 0 };
        nd.m[1] = light_point_margin(b, p, dp, nd.v[1]);
        nd.m[2] = light_point_margin(b, p, dp, nd.v[2]);
        stack[top++] = nd;
    }
    while (top > 0) {
        struct node nd = stack[--top];
        double mmax = fmax(nd.m[0], fmax(nd.m[1], nd.m[2]));
        if (mmax >= BF_DELTA) return TRI_YES;
        double diam = fmax(vec3_length(vec3_sub(nd.v[0], nd.v[1])),
                           fmax(vec3_length(vec3_sub(nd.v[1], nd.v[2])), vec3_length(vec3_sub(nd.v[2], nd.v[0]))));
        if (mmax + triangle_lipschitz(b, p, dp, nd.v) * diam < -BF_DELTA) continue;
        if (nd.depth >= BF_MAX_DEPTH || evals >= BF_MAX_EVALS || top + 4 > 256) {
            unsure = true;
            continue;
        }
        struct vec3 mid[3];
        double mm[3];
        for (int e = 0; e < 3; ++e) {
            mid[e] = vec3_scale(vec3_add(nd.v[e], nd.v[(e + 1) % 3]), 0.5);
            mm[e] = light_point_margin(b, p, dp, mid[e]);
        }
        evals += 3;
        struct node kids[4] = {
            { { nd.v[0], mid[0], mid[2] }, { nd.m[0], mm[0], mm[2] }, nd.depth + 1 },
            { { mid[0], nd.v[1], mid[1] }, { mm[0], nd.m[1], mm[1] }, nd.depth + 1 },
            { { mid[2], mid[1], nd.v[2] }, { mm[2], mm[1], nd.m[2] }, nd.depth + 1 },
            { { mid[0], mid[1], mid[2] }, { mm[0], mm[1], mm[2] }, nd.depth + 1 },
        };
        for (int c = 0; c < 4; ++c) stack[top++] = kids[c];
    }
    return unsure ? TRI_UNSURE : TRI_NO;
}

/* A region, or -1 when the brute force cannot decide with margin. */
static int brute_region(const struct brute *b, struct vec3 p)
{
    double dp = beyond_distance(b, p);
    if (dp < -BF_DELTA) return REGION_OUTSIDE;
    if (dp <= BF_DELTA) return -1;

    /* Whole light seen: every light sample crosses inside the portal. The
       vertices among the samples make this exact: the margin is concave on
       the portal plane, so its minimum over the convex L' is at a vertex. */
    double m_min = INFINITY;
    for (int i = 0; i < b->n_light_samples; ++i) m_min = fmin(m_min, light_point_margin(b, p, dp, b->light_samples[i]));
    enum tri_state umbra = m_min >= BF_DELTA ? TRI_YES : m_min <= -BF_DELTA ? TRI_NO : TRI_UNSURE;

    /* Whole portal filled: every ray through a portal sample hits the light
       (exact at the vertices for the same reason, in the light's plane). */
    double u_min = INFINITY;
    for (int i = 0; i < b->n_portal_samples; ++i) u_min = fmin(u_min, portal_point_margin(b, p, b->portal_samples[i]));
    enum tri_state antumbra = u_min >= BF_DELTA ? TRI_YES : u_min <= -BF_DELTA ? TRI_NO : TRI_UNSURE;

    if (umbra == TRI_YES) return antumbra == TRI_YES ? -1 : REGION_ANTI_UMBRA;
    if (antumbra == TRI_YES) return REGION_ANTI_ANTUMBRA;
    if (umbra == TRI_UNSURE || antumbra == TRI_UNSURE) return -1;
    switch (brute_any_visible(b, p, dp)) {
    case TRI_YES:
        return REGION_ANTI_PENUMBRA;
    case TRI_NO:
        return REGION_OUTSIDE;
    case TRI_UNSURE:
        return -1;
    }
    return -1;
}

struct pair_setup {
    const char *name;
    struct polygon light, portal;
    struct vec3 box_lo, box_hi;     /* the room */
    struct vec3 focus_lo, focus_hi; /* around and below the portal */
    struct vec3 near_lo, near_hi;   /* just beyond the portal, where the anti-umbra is */
    struct vec3 axis;               /* unit, from the light's centroid through the portal's */
    bool expect_antumbra;
};

static struct pair_setup setup_make(const char *name, struct polygon light, struct polygon portal, bool antumbra)
{
    struct pair_setup c;
    c.name = name;
    c.light = light;
    c.portal = portal;
    c.box_lo = vec3_make(-3, 0, -3);
    c.box_hi = vec3_make(3, 4, 3);
    c.focus_lo = vec3_make(-1, 0, -1);
    c.focus_hi = vec3_make(1, 2.8, 1);
    struct vec3 cp = polygon_centroid(&portal);
    c.near_lo = vec3_add(cp, vec3_make(-0.25, -0.35, -0.25));
    c.near_hi = vec3_add(cp, vec3_make(0.25, 0.05, 0.25));
    c.axis = vec3_normalize(vec3_sub(cp, polygon_centroid(&light)));
    c.expect_antumbra = antumbra;
    return c;
}

#define N_FIXED 9

static void fixed_setups(struct pair_setup *c)
{
    static const double s_light[5] = { 0.075, 0.15, 0.3, 0.6, 1.2 };
    static const char *names[5] = { "lampshade s_L=0.075", "lampshade s_L=0.15", "lampshade s_L=0.3",
                                    "lampshade s_L=0.6", "lampshade s_L=1.2" };
    for (int i = 0; i < 5; ++i) {
        struct polygon l, p;
        lampshade(s_light[i], &l, &p);
        /* Alternate the windings: the classifier must not depend on them. */
        if (i % 2) p = reversed(&p);
        if (i == 4) l = reversed(&l);
        c[i] = setup_make(names[i], l, p, s_light[i] > 0.3);
    }
    struct polygon l, p;
    lampshade(0.6, &l, &p);
    c[5] = setup_make("portal tilted 30 deg", l, rotated(&p, vec3_make(0, 2.2, 0), X, M_PI / 6.0), true);
    c[6] =
        setup_make("portal turned 20 deg about y", l, rotated(&p, vec3_make(0, 2.2, 0), Y, 20.0 * M_PI / 180.0), true);
    /* Triangle light, slightly tilted, over a pentagon portal. */
    struct polygon tri = ngon(vec3_make(0.05, 2.6, 0), X, Z, 0.45, 3, 0.3);
    tri = rotated(&tri, vec3_make(0.05, 2.6, 0), vec3_normalize(vec3_make(1, 0, 1)), 0.2);
    c[7] = setup_make("triangle light, pentagon portal", tri, ngon(vec3_make(0, 2.2, 0), Z, X, 0.16, 5, 0.1), true);
    /* Portal offset sideways and tilted 25 deg about z, about an oblique
       axis as well, under a light tilted the other way. */
    struct polygon side = square(vec3_make(0.35, 2.0, -0.1), X, Z, 0.25);
    side = rotated(&side, vec3_make(0.35, 2.0, -0.1), Z, 25.0 * M_PI / 180.0);
    side = rotated(&side, vec3_make(0.35, 2.0, -0.1), vec3_normalize(vec3_make(1, 1, 1)), 0.15);
    struct polygon tl = rotated(&l, vec3_make(0, 2.6, 0), X, -0.15);
    c[8] = setup_make("tilted light, non-parallel portal offset sideways", tl, side, true);
}

static struct vec3 random_in_box(struct rng *r, struct vec3 lo, struct vec3 hi)
{
    return vec3_make(lo.x + (hi.x - lo.x) * rng_uniform(r), lo.y + (hi.y - lo.y) * rng_uniform(r),
                     lo.z + (hi.z - lo.z) * rng_uniform(r));
}

/* A random point of the config: a quarter each in the room, the focus box,
   the near box and a column along the axis (where the anti-antumbra is),
   none within 1 cm of the portal plane. */
static struct vec3 setup_point(const struct pair_setup *c, const struct brute *b, struct rng *r, int i)
{
    for (;;) {
        struct vec3 p;
        switch (i % 4) {
        case 0:
            p = random_in_box(r, c->box_lo, c->box_hi);
            break;
        case 1:
            p = random_in_box(r, c->focus_lo, c->focus_hi);
            break;
        case 2:
            p = random_in_box(r, c->near_lo, c->near_hi);
            break;
        default:
            p = vec3_madd(random_in_box(r, vec3_make(-0.35, -0.35, -0.35), vec3_make(0.35, 0.35, 0.35)), c->axis,
                          0.2 + 2.3 * rng_uniform(r));
            p = vec3_add(p, polygon_centroid(&c->portal));
            break;
        }
        if (fabs(beyond_distance(b, p)) > 0.01) return p;
    }
}

struct agreement {
    int compared, skipped, disagreements;
    int count[4];
};

/* Compares the classifier with the brute force at n points; prints the first
   few disagreements. */
static struct agreement agree(const struct antishadow *a, const struct brute *b, const struct pair_setup *c, int n,
                              uint64_t seed)
{
    struct agreement g = { 0, 0, 0, { 0, 0, 0, 0 } };
    struct rng r;
    rng_seed(&r, seed, 2, 0);
    for (int i = 0; i < n; ++i) {
        struct vec3 p = setup_point(c, b, &r, i);
        int want = brute_region(b, p);
        if (want < 0) {
            ++g.skipped;
            continue;
        }
        ++g.compared;
        ++g.count[want];
        enum region got = antishadow_classify(a, p);
        if ((int)got != want) {
            if (++g.disagreements <= 5)
                fprintf(stderr, "  %s: p = (%.9g, %.9g, %.9g): classifier %d, brute force %d\n", c->name, p.x, p.y, p.z,
                        (int)got, want);
        }
    }
    return g;
}

static void test_build_plane_counts(void)
{
    /* Parallel aligned squares: each separating plane arises twice (through a
       portal edge and through the parallel light edge) and is kept once. */
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    for (int i = 0; i < N_FIXED; ++i) {
        struct antishadow a;
        struct error err = { { 0 } };
        bool ok = antishadow_build(&c[i].light, &c[i].portal, &a, &err);
        CHECK_MSG(ok, "%s: %s", c[i].name, err.message);
        if (!ok) continue;
        printf("  %-50s separating %2d  umbra %d  antumbra %d%s\n", c[i].name, a.n_separating, a.n_umbra, a.n_antumbra,
               a.has_antumbra ? "" : " (empty)");
        CHECK(a.n_umbra == c[i].portal.n);
        CHECK(a.has_antumbra && a.n_antumbra == c[i].light.n);
        CHECK(a.n_separating >= c[i].portal.n && a.n_separating <= c[i].portal.n + 2 * c[i].light.n);
        if (i < 5) CHECK(a.n_separating == 4);
        /* Beyond the portal is away from the light. */
        for (int k = 0; k < c[i].light.n; ++k) CHECK(plane_distance(&a.portal_plane, c[i].light.v[k]) < 0.0);
        antishadow_free(&a);
    }
}

static void test_lampshade_hand_checked(void)
{
    static const double s_light[5] = { 0.075, 0.15, 0.3, 0.6, 1.2 };
    for (int i = 0; i < 5; ++i) {
        double s = s_light[i];
        struct polygon light, portal;
        lampshade(s, &light, &portal);
        struct antishadow a;
        struct error err;
        CHECK(antishadow_build(&light, &portal, &a, &err));

        /* Straight below: the light projects to a centred square of side
           s * dp / (dp + 0.4) (similar triangles, dp the depth below the
           portal); smaller than the portal -> anti-umbra, larger ->
           anti-antumbra. On the floor that is s * 2.2 / 2.6. */
        static const double heights[5] = { 0.0, 0.5, 1.0, 1.5, 2.0 };
        for (int h = 0; h < 5; ++h) {
            double dp = 2.2 - heights[h];
            double side = s * dp / (dp + 0.4);
            if (fabs(side - 0.3) < 1e-3) continue;
            enum region want = side < 0.3 ? REGION_ANTI_UMBRA : REGION_ANTI_ANTUMBRA;
            enum region got = antishadow_classify(&a, vec3_make(0, heights[h], 0));
            CHECK_MSG(got == want, "s_L %g, y %g: region %d, want %d", s, heights[h], (int)got, (int)want);
        }
        CHECK(antishadow_classify(&a, vec3_make(0, 0, 0)) ==
              (s * 2.2 / 2.6 < 0.3 ? REGION_ANTI_UMBRA : REGION_ANTI_ANTUMBRA));

        /* Near the walls and on the ceiling, between portal and light: outside.
           (From (2.9, 1, 0) the segment to the farthest light corner,
           x = -0.6, meets y = 2.2 at x = 2.9 - 0.75 * 3.5 = 0.275 > 0.15.) */
        static const double outside[][3] = { { 2.9, 1.0, 0.0 },  { -2.9, 2.0, 1.0 }, { 0.5, 1.5, -2.9 },
                                             { 0.0, 4.0, 0.0 },  { 1.0, 4.0, -1.0 }, { 0.0, 2.4, 0.0 },
                                             { 0.05, 2.25, 0.0 } };
        for (size_t k = 0; k < sizeof outside / sizeof outside[0]; ++k) {
            struct vec3 p = vec3_make(outside[k][0], outside[k][1], outside[k][2]);
            CHECK_MSG(antishadow_classify(&a, p) == REGION_OUTSIDE, "s_L %g, p (%g, %g, %g)", s, p.x, p.y, p.z);
        }

        /* Just below a portal edge or corner, on the line from the light's
           centre through it, 0.1 below the portal: the projected light
           (side 0.2 s < 0.3) is centred on the edge, so it straddles it. */
        static const double rim[][2] = { { 0.15, 0 }, { -0.15, 0 }, { 0, 0.15 }, { 0, -0.15 }, { 0.15, 0.15 } };
        for (size_t k = 0; k < sizeof rim / sizeof rim[0]; ++k) {
            struct vec3 c = vec3_make(0, 2.6, 0), e = vec3_make(rim[k][0], 2.2, rim[k][1]);
            struct vec3 p = vec3_madd(c, vec3_sub(e, c), 1.25);
            CHECK_MSG(antishadow_classify(&a, p) == REGION_ANTI_PENUMBRA, "s_L %g, p (%g, %g, %g)", s, p.x, p.y, p.z);
        }
        antishadow_free(&a);
    }
}

static void test_brute_force_fixed(void)
{
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    int total_compared = 0, total_disagree = 0;
    for (int i = 0; i < N_FIXED; ++i) {
        struct antishadow a;
        struct error err;
        if (!antishadow_build(&c[i].light, &c[i].portal, &a, &err)) {
            CHECK_MSG(false, "%s: %s", c[i].name, err.message);
            continue;
        }
        struct brute b;
        brute_init(&b, &c[i].light, &c[i].portal, 100 + (uint64_t)i);
        const int n = 20000;
        struct agreement g = agree(&a, &b, &c[i], n, 200 + (uint64_t)i);
        printf("  %-50s compared %5d skipped %3d disagree %d  (out %d umbra %d pen %d antumbra %d)\n", c[i].name,
               g.compared, g.skipped, g.disagreements, g.count[REGION_OUTSIDE], g.count[REGION_ANTI_UMBRA],
               g.count[REGION_ANTI_PENUMBRA], g.count[REGION_ANTI_ANTUMBRA]);
        CHECK(g.disagreements == 0);
        /* The comparison must be nearly exhaustive and see every region. */
        CHECK(g.skipped < n / 50);
        CHECK(g.count[REGION_OUTSIDE] > 100 && g.count[REGION_ANTI_UMBRA] > 50 && g.count[REGION_ANTI_PENUMBRA] > 100);
        if (c[i].expect_antumbra) CHECK(g.count[REGION_ANTI_ANTUMBRA] > 100);
        else CHECK(g.count[REGION_ANTI_ANTUMBRA] == 0);
        total_compared += g.compared;
        total_disagree += g.disagreements;
        antishadow_free(&a);
    }
    printf("  fixed configurations: %d points compared, %d disagreements\n", total_compared, total_disagree);
}

/* The random polygons' vertex counts: 3..8. Random angles with a minimum
   gap of 0.15 rad are rejection-sampled, which never ends for 32 vertices;
   the 32-gons are tested as regular polygons (test_round_portal). */
#define RANDOM_POLYGON_MAX 8

/* A random strictly convex polygon: n points at sorted random angles on an
   ellipse, in a random orientation. */
static struct polygon random_polygon(struct rng *r, struct vec3 centre, double size)
{
    int n = 3 + (int)(rng_uniform(r) * (RANDOM_POLYGON_MAX - 2));
    if (n > RANDOM_POLYGON_MAX) n = RANDOM_POLYGON_MAX;
    double ang[RANDOM_POLYGON_MAX] = { 0 };
    for (;;) {
        for (int i = 0; i < n; ++i) ang[i] = 2.0 * M_PI * rng_uniform(r);
        for (int i = 1; i < n; ++i)
            for (int j = i; j > 0 && ang[j] < ang[j - 1]; --j) {
                double t = ang[j];
                ang[j] = ang[j - 1];
                ang[j - 1] = t;
            }
        double gap = 2.0 * M_PI - ang[n - 1] + ang[0];
        for (int i = 1; i < n; ++i) gap = fmin(gap, ang[i] - ang[i - 1]);
        if (gap > 0.15) break;
    }
    struct vec3 axis = vec3_normalize(vec3_make(rng_uniform(r) - 0.5, rng_uniform(r) - 0.5, rng_uniform(r) - 0.5));
    struct frame f = frame_from_normal(axis);
    double rx = size * (0.5 + rng_uniform(r)), ry = size * (0.5 + rng_uniform(r));
    struct polygon p;
    p.n = n;
    for (int i = 0; i < n; ++i)
        p.v[i] = vec3_add(centre, vec3_add(vec3_scale(f.x, rx * cos(ang[i])), vec3_scale(f.y, ry * sin(ang[i]))));
    return p;
}

static void test_brute_force_random_pairs(void)
{
    /* Random pairs in any orientation, including portals that cross the
       light's plane (no anti-antumbra) and lights seen edge-on. */
    struct rng r;
    rng_seed(&r, 77, 0, 0);
    int configs = 0, compared = 0, skipped = 0, disagree = 0, with_antumbra = 0, count[4] = { 0, 0, 0, 0 };
    while (configs < 40) {
        struct polygon light = random_polygon(&r, vec3_make(0, 0, 0), 0.1 + 0.4 * rng_uniform(&r));
        struct vec3 dir =
            vec3_normalize(vec3_make(rng_uniform(&r) - 0.5, rng_uniform(&r) - 0.5, rng_uniform(&r) - 0.5));
        struct vec3 centre = vec3_scale(dir, 0.3 + 0.9 * rng_uniform(&r));
        struct polygon portal = random_polygon(&r, centre, 0.08 + 0.3 * rng_uniform(&r));
        if (rng_uniform(&r) < 0.5) portal = reversed(&portal);
        struct antishadow a;
        if (!antishadow_build(&light, &portal, &a, NULL)) continue;
        /* Keep a clearance so that the brute force's margins are meaningful. */
        double clearance = INFINITY;
        for (int i = 0; i < light.n; ++i) clearance = fmin(clearance, -plane_distance(&a.portal_plane, light.v[i]));
        if (clearance < 0.02) {
            antishadow_free(&a);
            continue;
        }
        with_antumbra += a.has_antumbra;
        struct pair_setup c;
        c.name = "random pair";
        c.light = light;
        c.portal = portal;
        /* The room: a cube around the pair; the focus: the side beyond the
           portal, close to it. */
        c.box_lo = vec3_make(-2.5, -2.5, -2.5);
        c.box_hi = vec3_make(2.5, 2.5, 2.5);
        struct vec3 fc = vec3_madd(centre, a.portal_plane.normal, 0.8);
        c.focus_lo = vec3_sub(fc, vec3_make(0.9, 0.9, 0.9));
        c.focus_hi = vec3_add(fc, vec3_make(0.9, 0.9, 0.9));
        struct vec3 nc = vec3_madd(centre, a.portal_plane.normal, 0.25);
        c.near_lo = vec3_sub(nc, vec3_make(0.3, 0.3, 0.3));
        c.near_hi = vec3_add(nc, vec3_make(0.3, 0.3, 0.3));
        c.axis = vec3_normalize(vec3_sub(polygon_centroid(&portal), polygon_centroid(&light)));
        struct brute b;
        brute_init(&b, &light, &portal, 300 + (uint64_t)configs);
        struct agreement g = agree(&a, &b, &c, 2000, 400 + (uint64_t)configs);
        compared += g.compared;
        skipped += g.skipped;
        disagree += g.disagreements;
        for (int k = 0; k < 4; ++k) count[k] += g.count[k];
        ++configs;
        antishadow_free(&a);
    }
    printf("  %d random pairs (%d with an anti-antumbra): compared %d skipped %d disagree %d"
           "  (out %d umbra %d pen %d antumbra %d)\n",
           configs, with_antumbra, compared, skipped, disagree, count[0], count[1], count[2], count[3]);
    CHECK(disagree == 0);
    CHECK(skipped < compared / 50);
    CHECK(count[REGION_ANTI_UMBRA] > 1000 && count[REGION_ANTI_PENUMBRA] > 1000 && count[REGION_ANTI_ANTUMBRA] > 50);
    CHECK(with_antumbra > 5 && with_antumbra < configs);
}

/* The visible polygon is the part of the portal whose rays reach the light:
   its solid angle is the light's in the anti-umbra and the portal's in the
   anti-antumbra; the clip without the region shortcut agrees; random points
   of it lie on the portal and lead to the light, and random portal points
   whose rays hit the light lie in it (and those that miss lie outside it). */
/* The checks above at `points` points of one setup; adds the points per
   region to checked and the rays traced to *rays. */
static void check_visible(const struct pair_setup *c, uint64_t seed, int points, int checked[4], int *rays)
{
    struct antishadow a;
    struct error err;
    if (!antishadow_build(&c->light, &c->portal, &a, &err)) {
        CHECK_MSG(false, "%s: %s", c->name, err.message);
        return;
    }
    struct brute b;
    brute_init(&b, &c->light, &c->portal, 500 + seed);
    struct rng r;
    rng_seed(&r, 600 + seed, 0, 0);
    int fails = 0;
    for (int k = 0; k < points; ++k) {
        struct vec3 p = setup_point(c, &b, &r, k);
        enum region reg = antishadow_classify(&a, p);
        struct polygon vis, clip;
        int n = antishadow_visible_polygon(&a, p, &vis);
        int n_clip = antishadow_visible_polygon_in(&a, p, REGION_ANTI_PENUMBRA, &clip);
        double om = n >= 3 ? polygon_solid_angle(&vis, p) : 0.0;
        double om_clip = n_clip >= 3 ? polygon_solid_angle(&clip, p) : 0.0;
        double om_light = polygon_solid_angle(&c->light, p), om_portal = polygon_solid_angle(&c->portal, p);
        ++checked[reg];
        int before = test_failures_;
        switch (reg) {
        case REGION_OUTSIDE:
            CHECK(n == 0);
            CHECK(om_clip <= 1e-9 * om_portal);
            break;
        case REGION_ANTI_UMBRA:
            CHECK_NEAR(om, om_light, 1e-9 * om_light);
            CHECK_NEAR(om_clip, om_light, 1e-9 * om_light);
            break;
        case REGION_ANTI_ANTUMBRA:
            CHECK_NEAR(om, om_portal, 1e-9 * om_portal);
            CHECK_NEAR(om_clip, om_portal, 1e-9 * om_portal);
            break;
        case REGION_ANTI_PENUMBRA:
            CHECK(om > 0.0 && om <= fmin(om_light, om_portal) * (1.0 + 1e-9));
            CHECK_NEAR(om_clip, om, 1e-12);
            break;
        case REGION_INSIDE: /* the strategies' class, never the classifier's */
            CHECK(reg != REGION_INSIDE);
            break;
        }
        /* Rays: points of the visible polygon lie on the portal and their
           rays from p hit the light. */
        struct flat vf;
        bool has_vis = n >= 3 && flat_init(&vf, &vis);
        for (int s = 0; has_vis && s < 16; ++s) {
            struct vec3 y = polygon_uniform(&vis, &r);
            CHECK(flat_inside(&b.portal_flat, y) >= -1e-9);
            CHECK(portal_point_margin(&b, p, y) >= -1e-9);
            double t;
            CHECK(polygon_intersect_ray(&c->light, p, vec3_sub(y, p), &t) || portal_point_margin(&b, p, y) < 1e-7);
            ++*rays;
        }
        /* Portal points: a ray that hits the light passes through the
           visible polygon; one that misses does not. */
        for (int s = 0; s < 16; ++s) {
            struct vec3 q = polygon_uniform(&c->portal, &r);
            double u = portal_point_margin(&b, p, q);
            if (beyond_distance(&b, p) <= 0.0) u = -INFINITY; /* the ray p -> q never goes on to the light */
            if (u > 1e-9) {
                CHECK(has_vis && flat_inside(&vf, q) >= -1e-9);
            } else if (u < -1e-9 && has_vis) {
                CHECK(flat_inside(&vf, q) <= 1e-9);
            }
            ++*rays;
        }
        if (test_failures_ != before && ++fails <= 3)
            fprintf(stderr, "  %s: p = (%.9g, %.9g, %.9g) region %d, %d vertices\n", c->name, p.x, p.y, p.z, (int)reg,
                    n);
    }
    antishadow_free(&a);
}

static void test_visible_polygon(void)
{
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    int checked[4] = { 0, 0, 0, 0 }, rays = 0;
    for (int i = 0; i < N_FIXED; ++i) check_visible(&c[i], (uint64_t)i, 600, checked, &rays);
    printf("  visible polygon at %d outside, %d umbra, %d penumbra, %d antumbra points; %d ray checks\n", checked[0],
           checked[1], checked[2], checked[3], rays);
    CHECK(checked[REGION_ANTI_UMBRA] > 100 && checked[REGION_ANTI_PENUMBRA] > 100 &&
          checked[REGION_ANTI_ANTUMBRA] > 100);
}

/* Every 32 / k-th vertex of a regular 32-gon: the inscribed regular k-gon. */
static struct polygon inscribed(const struct polygon *p, int k)
{
    struct polygon q;
    q.n = k;
    for (int i = 0; i < k; ++i) q.v[i] = p->v[i * (p->n / k)];
    return q;
}

/* Round lamps: a 32-gon light over a 32-gon opening (the most vertices
   POLYGON_INPUT_MAX allows), level and tilted. The classifier agrees with
   the brute force, the visible polygon passes check_visible's tests (solid
   angle of the light in the anti-umbra, of the portal in the anti-antumbra),
   and the regions nest as they must with the inscribed octagons that the
   8-vertex machinery handled: a smaller portal P8 inside P32 has the
   smaller anti-umbra and the larger outside and anti-antumbra, a smaller
   light L8 inside L32 the larger anti-umbra and the smaller anti-antumbra. */
static void test_round_32(void)
{
    struct polygon light = ngon(vec3_make(0, 2.6, 0), Z, X, 0.3, 32, 0.0); /* winding normal -y */
    struct polygon portal = ngon(vec3_make(0, 2.2, 0), X, Z, 0.17, 32, 0.05);
    struct pair_setup c[2];
    c[0] = setup_make("32-gon light over a 32-gon portal", light, portal, true);
    c[1] = setup_make("32-gon light, 32-gon portal tilted 20 deg", light,
                      rotated(&portal, vec3_make(0, 2.2, 0), X, 20.0 * M_PI / 180.0), true);
    int checked[4] = { 0, 0, 0, 0 }, rays = 0;
    for (int i = 0; i < 2; ++i) {
        struct antishadow a;
        struct error err = { { 0 } };
        bool ok = antishadow_build(&c[i].light, &c[i].portal, &a, &err);
        CHECK_MSG(ok, "%s: %s", c[i].name, err.message);
        if (!ok) continue;
        CHECK(a.n_umbra == 32 && a.has_antumbra && a.n_antumbra == 32);
        CHECK(a.n_separating >= 32 && a.n_separating <= 96);
        struct brute b;
        brute_init(&b, &c[i].light, &c[i].portal, 700 + (uint64_t)i);
        const int n = 20000;
        struct agreement g = agree(&a, &b, &c[i], n, 800 + (uint64_t)i);
        printf("  %-50s separating %2d compared %5d skipped %3d disagree %d  (out %d umbra %d pen %d antumbra %d)\n",
               c[i].name, a.n_separating, g.compared, g.skipped, g.disagreements, g.count[REGION_OUTSIDE],
               g.count[REGION_ANTI_UMBRA], g.count[REGION_ANTI_PENUMBRA], g.count[REGION_ANTI_ANTUMBRA]);
        CHECK(g.disagreements == 0);
        CHECK(g.skipped < n / 50);
        CHECK(g.count[REGION_OUTSIDE] > 100 && g.count[REGION_ANTI_UMBRA] > 50 && g.count[REGION_ANTI_PENUMBRA] > 100 &&
              g.count[REGION_ANTI_ANTUMBRA] > 100);
        check_visible(&c[i], 900 + (uint64_t)i, 600, checked, &rays);

        /* Nesting with the inscribed octagons. */
        struct polygon l8 = inscribed(&c[i].light, 8), p8 = inscribed(&c[i].portal, 8);
        struct antishadow a_p8, a_l8;
        CHECK(antishadow_build(&c[i].light, &p8, &a_p8, &err));
        CHECK(antishadow_build(&l8, &c[i].portal, &a_l8, &err));
        struct rng r;
        rng_seed(&r, 1000 + (uint64_t)i, 0, 0);
        int nested = 0;
        for (int k = 0; k < 20000; ++k) {
            struct vec3 p = setup_point(&c[i], &b, &r, k);
            enum region r32 = antishadow_classify(&a, p), rp8 = antishadow_classify(&a_p8, p),
                        rl8 = antishadow_classify(&a_l8, p);
            int before = test_failures_;
            if (rp8 == REGION_ANTI_UMBRA) CHECK(r32 == REGION_ANTI_UMBRA);
            if (r32 == REGION_OUTSIDE) CHECK(rp8 == REGION_OUTSIDE);
            if (r32 == REGION_ANTI_ANTUMBRA) CHECK(rp8 == REGION_ANTI_ANTUMBRA);
            if (r32 == REGION_ANTI_UMBRA) CHECK(rl8 == REGION_ANTI_UMBRA);
            if (rl8 == REGION_ANTI_ANTUMBRA) CHECK(r32 == REGION_ANTI_ANTUMBRA);
            if (rl8 == REGION_OUTSIDE) CHECK(r32 == REGION_OUTSIDE || r32 == REGION_ANTI_PENUMBRA);
            if (test_failures_ != before && ++nested <= 3)
                fprintf(stderr, "  %s: p = (%.9g, %.9g, %.9g): 32/32 %d, 32/8 %d, 8/32 %d\n", c[i].name, p.x, p.y, p.z,
                        (int)r32, (int)rp8, (int)rl8);
        }
        antishadow_free(&a);
        antishadow_free(&a_p8);
        antishadow_free(&a_l8);
    }
    printf("  32-gon visible polygon at %d outside, %d umbra, %d penumbra, %d antumbra points; %d ray checks\n",
           checked[0], checked[1], checked[2], checked[3], rays);
    CHECK(checked[REGION_ANTI_UMBRA] > 20 && checked[REGION_ANTI_PENUMBRA] > 100 &&
          checked[REGION_ANTI_ANTUMBRA] > 100);
}

/* The round lamp of the good catalogue (32-gon light and portal, the limit)
   loads with every vertex, and its pair builds; 33 vertices are refused at
   the list's file:line:column (tests/configs/bad/portal_33_vertices.yaml,
   light_33_vertices.yaml, checked by test_config's bad catalogue). */
static void test_round_config(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load("tests/configs/good/round_portal_32.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.n_lights == 1 && c.n_portals == 1);
    CHECK(c.lights[0].polygon.n == 32 && c.portals[0].polygon.n == 32);
    struct antishadow a;
    CHECK_MSG(antishadow_build(&c.lights[0].polygon, &c.portals[0].polygon, &a, &err), "%s", err.message);
    /* Straight below the opening, near it: the whole lamp is seen. */
    CHECK(antishadow_classify(&a, vec3_make(0, 1.7, 0)) == REGION_ANTI_UMBRA);
    antishadow_free(&a);
    config_free(&c);
    ok = config_load("tests/configs/bad/portal_33_vertices.yaml", NULL, 0, &c, &err);
    CHECK(!ok);
    CHECK_MSG(strstr(err.message, "portal_33_vertices.yaml:24:15: portal \"round\" has 33 vertices (expected 3 to 32)"),
              "%s", err.message);
}

static void test_build_errors(void)
{
    struct polygon light, portal;
    lampshade(0.6, &light, &portal);
    struct antishadow a;
    struct error err;

    /* Tilted 45 degrees about x, the 0.6 light reaches y = 2.6 -+ 0.21: it
       crosses the plane y = 2.4 of a raised portal. */
    struct polygon raised = square(vec3_make(0, 2.4, 0), X, Z, 0.3);
    struct polygon tilted = rotated(&light, vec3_make(0, 2.6, 0), X, M_PI / 4.0);
    err.message[0] = 0;
    CHECK(!antishadow_build(&tilted, &raised, &a, &err));
    CHECK_MSG(strstr(err.message, "crosses") != NULL, "%s", err.message);

    /* One light corner exactly on the portal plane. */
    struct polygon touching = light;
    touching.v[0].y = 2.2;
    touching.v[1].y = 2.4;
    touching.v[3].y = 2.4;
    touching.v[2].y = 2.6;
    CHECK(polygon_is_planar(&touching, 1e-9));
    err.message[0] = 0;
    CHECK(!antishadow_build(&touching, &portal, &a, &err));
    CHECK_MSG(strstr(err.message, "touches") != NULL, "%s", err.message);

    /* The light in the portal's plane. */
    struct polygon flat = square(vec3_make(1, 2.2, 0), X, Z, 0.3);
    err.message[0] = 0;
    CHECK(!antishadow_build(&flat, &portal, &a, &err));
    CHECK_MSG(strstr(err.message, "touches") != NULL, "%s", err.message);

    /* Degenerate inputs. */
    struct polygon collinear = { 3, { { 0, 2.6, 0 }, { 0.1, 2.6, 0 }, { 0.2, 2.6, 0 } } };
    err.message[0] = 0;
    CHECK(!antishadow_build(&collinear, &portal, &a, &err));
    CHECK(strstr(err.message, "light") != NULL);
    struct polygon too_many = ngon(vec3_make(0, 2.2, 0), X, Z, 0.2, POLYGON_INPUT_MAX + 1, 0.0);
    err.message[0] = 0;
    CHECK(!antishadow_build(&light, &too_many, &a, &err));
    CHECK(strstr(err.message, "portal") != NULL);
    struct polygon bowtie = portal;
    bowtie.v[1] = portal.v[2];
    bowtie.v[2] = portal.v[1];
    CHECK(!antishadow_build(&light, &bowtie, &a, &err));
    struct polygon nan_light = light;
    nan_light.v[2].x = NAN;
    CHECK(!antishadow_build(&nan_light, &portal, &a, &err));
    CHECK(antishadow_build(&light, &portal, &a, NULL));
    antishadow_free(&a);

    /* A light below its portal is fine: the regions mirror. */
    struct polygon below = square(vec3_make(0, 1.8, 0), X, Z, 0.6);
    CHECK(antishadow_build(&below, &portal, &a, &err));
    CHECK(antishadow_classify(&a, vec3_make(0, 4.4, 0)) == REGION_ANTI_ANTUMBRA);
    CHECK(antishadow_classify(&a, vec3_make(0, 0.0, 0)) == REGION_OUTSIDE);
    CHECK(antishadow_classify(&a, vec3_make(0, 2.3, 0)) == REGION_ANTI_UMBRA);
    CHECK(antishadow_classify(&a, vec3_make(NAN, 0, 0)) == REGION_OUTSIDE);
    antishadow_free(&a);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Cost of one classification (printed, not asserted), and of one visible
   polygon, on points of the focus box. */
static void test_timing(void)
{
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    static const int which[3] = { 3, 6, 8 };
    enum { N_POINTS = 4096, REPEAT = 100 };
    struct vec3 pts[N_POINTS];
    for (int w = 0; w < 3; ++w) {
        const struct pair_setup *cf = &c[which[w]];
        struct antishadow a;
        struct error err;
        CHECK(antishadow_build(&cf->light, &cf->portal, &a, &err));
        struct rng r;
        rng_seed(&r, 900, (uint64_t)w, 0);
        for (int i = 0; i < N_POINTS; ++i)
            pts[i] = i % 2 ? random_in_box(&r, cf->box_lo, cf->box_hi) : random_in_box(&r, cf->focus_lo, cf->focus_hi);
        unsigned sink = 0;
        double t0 = now_s();
        for (int k = 0; k < REPEAT; ++k)
            for (int i = 0; i < N_POINTS; ++i) sink += (unsigned)antishadow_classify(&a, pts[i]);
        double t1 = now_s();
        struct polygon vis;
        for (int i = 0; i < N_POINTS; ++i) sink += (unsigned)antishadow_visible_polygon(&a, pts[i], &vis);
        double t2 = now_s();
        printf("  %-50s classify %.1f ns, visible polygon %.0f ns (checksum %u)\n", cf->name,
               1e9 * (t1 - t0) / (REPEAT * N_POINTS), 1e9 * (t2 - t1) / N_POINTS, sink);
        antishadow_free(&a);
    }
}

/* The interval clip of box pairs (antishadow_box) against
   Sutherland-Hodgman, which the other pairs use: the lampshade pairs in
   every winding qualify, the tilted, turned, triangular and offset ones do
   not; in the anti-penumbra both give the same polygon (area, winding and
   solid angle from p to 1e-9, every vertex of one on the other). */
static void test_box_matches_clip(void)
{
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    int compared = 0;
    for (int i = 0; i < N_FIXED; ++i) {
        struct antishadow a, plain;
        struct error err;
        if (!antishadow_build(&c[i].light, &c[i].portal, &a, &err)) {
            CHECK_MSG(false, "%s: %s", c[i].name, err.message);
            continue;
        }
        CHECK_MSG(a.box.valid == (i < 5), "%s: box %d", c[i].name, a.box.valid);
        if (!a.box.valid) {
            antishadow_free(&a);
            continue;
        }
        plain = a; /* shares a's storage: only a is freed */
        plain.box.valid = false;
        struct brute b;
        brute_init(&b, &c[i].light, &c[i].portal, 700 + (uint64_t)i);
        struct rng r;
        rng_seed(&r, 800 + (uint64_t)i, 0, 0);
        int bad = 0;
        for (int k = 0; k < 4000; ++k) {
            struct vec3 p = setup_point(&c[i], &b, &r, k);
            if (antishadow_classify(&a, p) != REGION_ANTI_PENUMBRA) continue;
            struct polygon got, want;
            int n_got = antishadow_visible_polygon_in(&a, p, REGION_ANTI_PENUMBRA, &got);
            int n_want = antishadow_visible_polygon_in(&plain, p, REGION_ANTI_PENUMBRA, &want);
            double area = n_want >= 3 ? polygon_area(&want) : 0.0, size = polygon_size(&c[i].portal);
            if (n_want < 3 || area < 1e-9 * size * size) {
                /* A sliver Sutherland-Hodgman merges away: the box may keep it. */
                bad += n_got >= 3 && polygon_area(&got) > 1e-8 * size * size;
                continue;
            }
            ++compared;
            bool same = n_got == 4 && fabs(polygon_area(&got) - area) <= 1e-9 * area &&
                        vec3_dot(polygon_area_normal(&got), polygon_area_normal(&want)) > 0.0 &&
                        fabs(polygon_solid_angle(&got, p) - polygon_solid_angle(&want, p)) <=
                            1e-9 * polygon_solid_angle(&want, p);
            for (int v = 0; same && v < n_got; ++v) {
                double nearest = INFINITY;
                for (int w = 0; w < n_want; ++w) nearest = fmin(nearest, vec3_length(vec3_sub(got.v[v], want.v[w])));
                same = nearest <= 1e-9 * size;
            }
            if (!same && bad++ < 3)
                fprintf(stderr, "  %s: p (%.9g, %.9g, %.9g): box %d vertices, area %.17g vs %.17g\n", c[i].name, p.x,
                        p.y, p.z, n_got, n_got >= 3 ? polygon_area(&got) : 0.0, area);
        }
        CHECK_MSG(bad == 0, "%s: %d points differ", c[i].name, bad);
        antishadow_free(&a);
    }
    CHECK_MSG(compared > 1000, "only %d anti-penumbra points compared", compared);
}

/* A box rectangle reported simple (antishadow_visible_polygon_known) is one
   that simplification copies unchanged, bit for bit: that is what lets a
   portal strategy skip the scan (target_init_polygon_simple). Most
   anti-penumbra points qualify; a sliver, found by bisecting to the edge of
   the overlap, does not. */
static void test_box_simple_needs_no_simplifying(void)
{
    /* The margins over simplification's tolerances, for a rectangle of
       sides lo <= hi at the aspect limit: its corners' cross product over
       the squared diagonal is lo hi / (lo^2 + hi^2) >= aspect / 2, its
       shorter edge over the diagonal >= aspect / sqrt(2); each must stay at
       least 1e3 times the tolerance (a looser simplify fails here). */
    double aspect = ANTISHADOW_BOX_SIMPLE_ASPECT;
    CHECK(0.5 * aspect >= 1e3 * sqrt(TARGET_COLLINEAR_REL2));
    CHECK(aspect / sqrt(2.0) >= 1e3 * sqrt(TARGET_REPEATED_REL2));
    CHECK(ANTISHADOW_BOX_SIMPLE_ROUNDING >= 1e3 * DBL_EPSILON);
    struct pair_setup c[N_FIXED];
    fixed_setups(c);
    int simple_seen = 0, changed = 0;
    for (int i = 0; i < 5; ++i) {
        struct antishadow a;
        struct error err;
        if (!antishadow_build(&c[i].light, &c[i].portal, &a, &err) || !a.box.valid) {
            CHECK_MSG(false, "%s: no box pair", c[i].name);
            antishadow_free(&a);
            continue;
        }
        struct brute b;
        brute_init(&b, &c[i].light, &c[i].portal, 900 + (uint64_t)i);
        struct rng r;
        rng_seed(&r, 1000 + (uint64_t)i, 0, 0);
        for (int k = 0; k < 4000; ++k) {
            struct vec3 p = setup_point(&c[i], &b, &r, k);
            if (antishadow_classify(&a, p) != REGION_ANTI_PENUMBRA) continue;
            struct polygon vis;
            bool simple;
            int n = antishadow_visible_polygon_known(&a, p, REGION_ANTI_PENUMBRA, &vis, &simple);
            if (!simple) continue;
            ++simple_seen;
            struct target t;
            bool ok = n == 4 && target_init_polygon(&t, &vis) && t.polygon.n == vis.n &&
                      memcmp(t.polygon.v, vis.v, (size_t)vis.n * sizeof vis.v[0]) == 0;
            if (!ok && changed++ < 3)
                fprintf(stderr, "  %s: p (%.17g, %.17g, %.17g) simplified to %d vertices\n", c[i].name, p.x, p.y, p.z,
                        t.polygon.n);
        }
        /* From below the portal's centre (the whole overlap) to a point far
           to the side (none): the last point with an overlap sees a sliver. */
        struct vec3 in = vec3_make(0.0, 1.0, 0.0), out = vec3_make(40.0, 1.0, 0.0);
        struct polygon vis;
        bool simple;
        CHECK_MSG(antishadow_visible_polygon_known(&a, in, REGION_ANTI_PENUMBRA, &vis, &simple) == 4 && simple,
                  "%s: the overlap below the centre is not simple", c[i].name);
        CHECK(antishadow_visible_polygon_known(&a, out, REGION_ANTI_PENUMBRA, &vis, &simple) == 0 && !simple);
        for (int it = 0; it < 200; ++it) {
            struct vec3 mid = vec3_scale(vec3_add(in, out), 0.5);
            if (antishadow_visible_polygon_known(&a, mid, REGION_ANTI_PENUMBRA, &vis, &simple) == 4) in = mid;
            else out = mid;
        }
        CHECK_MSG(antishadow_visible_polygon_known(&a, in, REGION_ANTI_PENUMBRA, &vis, &simple) == 4 && !simple,
                  "%s: a sliver at x = %.17g is reported simple", c[i].name, in.x);
        antishadow_free(&a);
    }
    CHECK_MSG(changed == 0, "%d simple rectangles were changed by simplification", changed);
    CHECK_MSG(simple_seen > 1000, "only %d simple rectangles seen", simple_seen);
}

static const struct test_case antishadow_tests[] = {
    { "build_plane_counts", test_build_plane_counts },
    { "lampshade_hand_checked", test_lampshade_hand_checked },
    { "brute_force_fixed", test_brute_force_fixed },
    { "brute_force_random_pairs", test_brute_force_random_pairs },
    { "visible_polygon", test_visible_polygon },
    { "box_matches_clip", test_box_matches_clip },
    { "box_simple_needs_no_simplifying", test_box_simple_needs_no_simplifying },
    { "round_32", test_round_32 },
    { "round_config", test_round_config },
    { "build_errors", test_build_errors },
    { "timing", test_timing },
};
TEST_MAIN(antishadow_tests)

/* `portals: auto` (scene/portal_finder.h): the convex hull and the facet
   subtraction it is built on, then the proof that the found portals miss
   no path, from both ends of the segments, with a negative control that
   shows the tests see a gap; the lampshade's hole found exactly; renders
   with the found portals against the closed form and against `light`,
   with defensive 0 and no BSDF sampling (MIS off), so that a gap cannot
   hide behind MIS; robustness of the set to how a shade is meshed; the
   stated fallbacks; determinism. Monte Carlo with fixed seeds. */
#include <string.h>
#include <unistd.h>

#include "config/config.h"
#include "geometry/convex_hull.h"
#include "geometry/mesh_components.h"
#include "geometry/polygon_subtract.h"
#include "sampling/integrator.h"
#include "sampling/strategy.h"
#include "scene/portal_coverage.h"
#include "scene/scene.h"
#include "scene_util.h"
#include "direct_estimate.h"
#include "testlib.h"

/* ---- helpers */

/* The text of a scene file with its portals section replaced by
   `portals: auto` (the section runs to the next top-level key), and a
   relative include made absolute, written to a temporary file. */
static bool write_auto_copy(const char *path, char *out, size_t out_size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return false;
    static char text[1 << 16], edited[1 << 16];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    char *p = strstr(text, "\nportals:");
    if (!p) return false;
    char *end = p + 1;
    while ((end = strchr(end, '\n')) && (end[1] == ' ' || end[1] == '#' || end[1] == '\n' || end[1] == '-')) ++end;
    *p = '\0';
    char dir[512];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash) *slash = '\0';
    char cwd[512];
    if (!getcwd(cwd, sizeof cwd)) return false;
    char *inc = strstr(text, "\ninclude: ");
    if (inc) {
        char head[1 << 16];
        *inc = '\0';
        if (snprintf(head, sizeof head, "%s\ninclude: %s/%s/%s", text, cwd, dir, inc + 10) >= (int)sizeof head ||
            snprintf(edited, sizeof edited, "%s\nportals: auto\n%s", head, end ? end + 1 : "") >= (int)sizeof edited)
            return false;
    } else {
        if (snprintf(edited, sizeof edited, "%s\nportals: auto\n%s", text, end ? end + 1 : "") >= (int)sizeof edited)
            return false;
    }
    snprintf(out, out_size, "/tmp/portal-finder-%ld-%s", (long)getpid(), slash ? slash + 1 : path);
    FILE *g = fopen(out, "wb");
    if (!g) return false;
    fputs(edited, g);
    return fclose(g) == 0;
}

static bool load_auto(const char *path, const struct config_override *ov, int n_ov, struct config *cfg,
                      struct scene *sc)
{
    char tmp[600];
    if (!write_auto_copy(path, tmp, sizeof tmp)) {
        fprintf(stderr, "  cannot make the auto copy of %s\n", path);
        return false;
    }
    bool ok = test_scene_load(tmp, ov, n_ov, cfg, sc);
    remove(tmp);
    return ok;
}

/* The found portals of emitter e, copied. */
static int portals_of(const struct scene *sc, int e, struct polygon *out, int max)
{
    const struct light *l = &sc->lights[sc->emitters[e].first_light];
    int n = 0;
    for (int k = 0; k < l->n_portals && n < max; ++k)
        polygon_copy(&out[n++], &sc->portals[l->first_portal + k].target->polygon);
    return n;
}

/* Light side: rays until at least min_escaped escape (or max_rays). */
static struct portal_coverage light_side(const struct scene *sc, int e, const struct polygon *ports, int n_ports,
                                         long min_escaped, long max_rays, uint64_t seed)
{
    const struct auto_portal_report *rep = &sc->auto_portals[e];
    struct portal_coverage total;
    memset(&total, 0, sizeof total);
    for (uint64_t batch = 0; total.n_escaped < min_escaped && total.n_rays < max_rays; ++batch) {
        struct portal_coverage c;
        struct error err;
        if (!portal_finder_coverage(sc, e, rep->planes, rep->n_planes, ports, n_ports, 1 << 17, seed + batch, &c,
                                    &err)) {
            fprintf(stderr, "  %s\n", err.message);
            break;
        }
        total.n_rays += c.n_rays, total.n_escaped += c.n_escaped, total.n_missed += c.n_missed;
        total.n_portal += c.n_portal, total.n_through += c.n_through;
    }
    total.blocked_fraction = total.n_portal ? 1.0 - (double)total.n_through / (double)total.n_portal : 0.0;
    total.bound = total.n_escaped ? 3.0 / (double)total.n_escaped : INFINITY;
    return total;
}

static bool outside_hull(const struct auto_portal_report *rep, struct vec3 x)
{
    for (int k = 0; k < rep->n_planes; ++k)
        if (plane_distance(&rep->planes[k], x) > 0.0) return true;
    return false;
}

/* Receiver side: n segments from random points outside P (in the scene's
   box) to random points of the light; returns how many were unoccluded
   and crossed no portal (*n_open: how many were unoccluded). */
static long receiver_side(const struct scene *sc, int e, const struct polygon *ports, int n_ports, long n,
                          uint64_t seed, long *n_open)
{
    const struct auto_portal_report *rep = &sc->auto_portals[e];
    struct emission_sampler es;
    struct error err;
    if (!emission_sampler_init(&es, sc, e, &err)) return -1;
    struct rng r = rng_seeded(seed, 7, 0);
    long missed = 0;
    *n_open = 0;
    struct vec3 lo = sc->bounds_lo, hi = sc->bounds_hi;
    for (long i = 0; i < n; ++i) {
        struct vec3 x;
        /* Half the points anywhere in the scene, half near P. */
        bool near = i % 2;
        struct vec3 blo = near ? vec3_sub(rep->box_lo, vec3_scale(vec3_sub(rep->box_hi, rep->box_lo), 0.5)) : lo;
        struct vec3 bhi = near ? vec3_add(rep->box_hi, vec3_scale(vec3_sub(rep->box_hi, rep->box_lo), 0.5)) : hi;
        do {
            x = vec3_make(blo.x + rng_uniform(&r) * (bhi.x - blo.x), blo.y + rng_uniform(&r) * (bhi.y - blo.y),
                          blo.z + rng_uniform(&r) * (bhi.z - blo.z));
        } while (!outside_hull(rep, x));
        double u[EMISSION_UNIFORMS];
        for (int k = 0; k < EMISSION_UNIFORMS; ++k) u[k] = rng_uniform(&r);
        struct vec3 y, ny, d;
        emission_sample(&es, u, &y, &ny, &d);
        struct vec3 to_x = vec3_sub(x, y);
        double len = vec3_length(to_x);
        struct vec3 w = vec3_scale(to_x, 1.0 / len);
        const struct light *l = &sc->lights[sc->emitters[e].first_light];
        if (!l->two_sided && vec3_dot(w, ny) <= 0.0) continue; /* a one-sided light sends nothing that way */
        /* Traced from x (in free space) towards y, stopping just short of
           the light's plane: no offset at the light, whose step would
           carry a grazing ray through a nearby wall. */
        if (scene_occluded(sc, x, vec3_neg(w), len * (1.0 - 1e-6))) continue;
        ++*n_open;
        bool crosses = false;
        for (int k = 0; k < n_ports && !crosses; ++k) {
            double t;
            crosses = polygon_intersect_ray(&ports[k], y, w, &t) && t <= len;
        }
        missed += !crosses;
    }
    emission_sampler_free(&es);
    return missed;
}

/* ---- geometry */

static void test_hull_box(void)
{
    /* A unit cube's corners, each twice, its face centres and edge
       midpoints (coplanar points), and inner points. */
    struct vec3 pts[64];
    int n = 0;
    for (int rep = 0; rep < 2; ++rep)
        for (int i = 0; i < 8; ++i) pts[n++] = vec3_make(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    for (int a = 0; a < 3; ++a)
        for (int s = 0; s < 2; ++s) {
            double c[3] = { 0.5, 0.5, 0.5 };
            c[a] = s;
            pts[n++] = vec3_make(c[0], c[1], c[2]);
        }
    pts[n++] = vec3_make(0.5, 0, 0), pts[n++] = vec3_make(1, 0.5, 1), pts[n++] = vec3_make(0.3, 0.4, 0.6);
    struct convex_hull h;
    struct error err;
    CHECK(convex_hull_build(pts, n, &h, &err));
    CHECK_MSG(h.n_facets == 6, "%d facets", h.n_facets);
    double area = 0.0;
    for (int f = 0; f < h.n_facets; ++f) {
        struct polygon p;
        CHECK(convex_hull_facet_polygon(&h, pts, f, &p));
        CHECK_MSG(p.n == 4, "facet %d has %d corners", f, p.n);
        CHECK(polygon_check(&p) == POLYGON_DEFECT_NONE);
        /* Wound counter-clockwise from outside: along the outward normal. */
        CHECK(vec3_dot(polygon_normal(&p), h.facets[f].plane.normal) > 0.999);
        area += polygon_area(&p);
    }
    CHECK_NEAR(area, 6.0, 1e-12);
    convex_hull_free(&h);
    /* Degenerate sets: fewer than four points, coplanar, collinear. */
    struct vec3 flat[5] = { { 0, 0, 0 }, { 1, 0, 0 }, { 0, 1, 0 }, { 1, 1, 0 }, { 0.5, 0.5, 0 } };
    CHECK(!convex_hull_build(flat, 5, &h, &err) && strstr(err.message, "degenerate"));
    struct vec3 line[4] = { { 0, 0, 0 }, { 1, 1, 1 }, { 2, 2, 2 }, { 3, 3, 3 } };
    CHECK(!convex_hull_build(line, 4, &h, &err) && strstr(err.message, "degenerate"));
    CHECK(!convex_hull_build(line, 3, &h, &err));
}

static void test_hull_sphere_points(void)
{
    /* Random points on and in a sphere: every point inside every facet's
       plane, Euler's formula on the facets' corners. */
    enum { N = 3000 };
    static struct vec3 pts[N];
    struct rng r = rng_seeded(5, 0, 0);
    for (int i = 0; i < N; ++i) {
        double z = 2.0 * rng_uniform(&r) - 1.0, phi = 2.0 * M_PI * rng_uniform(&r), s = sqrt(1.0 - z * z);
        double rad = i % 3 ? 1.0 : rng_uniform(&r);
        pts[i] = vec3_make(rad * s * cos(phi) + 3.0, rad * s * sin(phi) - 2.0, rad * z);
    }
    struct convex_hull h;
    struct error err;
    CHECK(convex_hull_build(pts, N, &h, &err));
    int worst = 0;
    for (int f = 0; f < h.n_facets; ++f)
        for (int i = 0; i < N; ++i) worst += plane_distance(&h.facets[f].plane, pts[i]) > h.tol;
    CHECK_MSG(worst == 0, "%d point-facet pairs outside", worst);
    CHECK(h.n_facets > 100);
    convex_hull_free(&h);
}

/* The 2-D hull (convex_hull_2d): a square with inner and edge points has
   its four corners; nearly collinear points (a tilted line with rounding
   jitter, as a light seen edge-on gives) never yield more corners than
   points (the buffer holds n) nor a repeated corner. The second part
   overflowed with a turn test that was not antisymmetric. */
static void test_hull_2d(void)
{
    struct vec3 sq[7] = { { 0, 0, 0 },   { 1, 0, 0 },     { 1, 1, 0 },   { 0, 1, 0 },
                          { 0.5, 0, 0 }, { 0.5, 0.5, 0 }, { 0, 0.25, 0 } };
    int idx[7];
    CHECK(convex_hull_2d(sq, 7, vec3_make(0, 0, 1), 0.0, idx) == 4);
    struct rng r = rng_seeded(11, 0, 0);
    int worst = 0, repeats = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        int n = 3 + (int)(rng_uniform(&r) * 6.0);
        struct vec3 *pts = malloc(sizeof *pts * (size_t)n);
        int *out = malloc(sizeof *out * (size_t)n);
        struct vec3 o = vec3_make(rng_uniform(&r), rng_uniform(&r), rng_uniform(&r));
        struct vec3 d = vec3_normalize(vec3_make(rng_uniform(&r) - 0.5, rng_uniform(&r) - 0.5, 0.1 * rng_uniform(&r)));
        for (int i = 0; i < n; ++i) pts[i] = vec3_madd(o, d, 10.0 * rng_uniform(&r));
        struct vec3 nrm = vec3_normalize(vec3_make(0.05 * rng_uniform(&r), 0.05 * rng_uniform(&r), 1.0));
        int c = convex_hull_2d(pts, n, nrm, 0.0, out);
        if (c - n > worst) worst = c - n;
        for (int i = 0; i < c && i < n; ++i)
            for (int j = i + 1; j < c && j < n; ++j) repeats += out[i] == out[j];
        free(pts);
        free(out);
    }
    CHECK_MSG(worst <= 0, "%d more corners than points", worst);
    CHECK_MSG(repeats == 0, "%d repeated corners", repeats);
}

static void test_subtract_triangle(void)
{
    struct polygon sq = { 4, { { 0, 0, 0 }, { 2, 0, 0 }, { 2, 2, 0 }, { 0, 2, 0 } } };
    struct vec3 nz = vec3_make(0, 0, 1);
    struct vec3 t1[3] = { { 0, 0, 0 }, { 2, 0, 0 }, { 2, 2, 0 } }, t2[3] = { { 0, 0, 0 }, { 2, 2, 0 }, { 0, 2, 0 } };
    struct polygon out[3], out2[3];
    int n = polygon_subtract_triangle(&sq, nz, t1, 1e-15, out);
    double area = 0.0;
    for (int i = 0; i < n; ++i) area += polygon_area(&out[i]);
    CHECK_NEAR(area, 2.0, 1e-12);
    /* The rest covered by the other half (wound the other way): nothing left. */
    int left = 0;
    for (int i = 0; i < n; ++i) left += polygon_subtract_triangle(&out[i], nz, t2, 1e-15, out2);
    CHECK_MSG(left == 0, "%d pieces left", left);
    /* A small triangle inside: three pieces, area conserved, and the
       pieces merge back to nothing smaller than the square minus it. */
    struct vec3 t3[3] = { { 0.5, 0.5, 1e-12 }, { 1.5, 0.5, 0 }, { 1.0, 1.5, 0 } };
    n = polygon_subtract_triangle(&sq, nz, t3, 1e-15, out);
    area = 0.0;
    for (int i = 0; i < n; ++i) area += polygon_area(&out[i]);
    CHECK_NEAR(area, 4.0 - 0.5, 1e-9);
    CHECK(n == 3);
    /* Two halves of a square merge into it; two pieces whose union is not convex do not. */
    struct polygon a = { 4, { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 2, 0 }, { 0, 2, 0 } } };
    struct polygon b = { 4, { { 1, 0, 0 }, { 2, 0, 0 }, { 2, 2, 0 }, { 1, 2, 0 } } };
    struct polygon c = { 4, { { 1, 0, 0 }, { 2, 0, 0 }, { 2, 1, 0 }, { 1, 1, 0 } } }, m;
    CHECK(polygon_merge_convex(&a, &b, nz, 1e-12, 1e-9, POLYGON_INPUT_MAX, &m) && m.n == 4);
    CHECK_NEAR(polygon_area(&m), 4.0, 1e-12);
    CHECK(!polygon_merge_convex(&a, &c, nz, 1e-12, 1e-9, POLYGON_INPUT_MAX, &m));
}

/* ---- the shipped scenes */

static bool same_polygon(const struct polygon *a, const struct polygon *b, double tol)
{
    if (a->n != b->n) return false;
    for (int i = 0; i < a->n; ++i) {
        bool found = false;
        for (int j = 0; j < b->n && !found; ++j) found = vec3_length(vec3_sub(a->v[i], b->v[j])) <= tol;
        if (!found) return false;
    }
    return true;
}

/* The lampshade at several light sizes: one portal, the hole; no escaping
   ray misses it (rule-of-three bound below 1e-5 at 3e5 escapes). */
static void test_lampshade_hole_and_light_side(void)
{
    static const char *sizes[] = { "0.075", "0.3", "1.2" };
    for (int i = 0; i < 3; ++i) {
        struct config cfg;
        struct scene sc;
        struct config_override ov[] = { { "params.s_L", sizes[i] } };
        if (!load_auto("configs/scenes/lampshade.yaml", ov, 1, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        struct polygon hole = {
            4, { { -0.15, 2.2, -0.15 }, { 0.15, 2.2, -0.15 }, { 0.15, 2.2, 0.15 }, { -0.15, 2.2, 0.15 } }
        };
        struct polygon ports[8];
        int n = portals_of(&sc, 0, ports, 8);
        CHECK_MSG(n == 1 && same_polygon(&ports[0], &hole, 1e-12), "s_L=%s: %d portals", sizes[i], n);
        struct portal_coverage c = light_side(&sc, 0, ports, n, 300000, 1L << 23, 11);
        printf("  lampshade s_L=%s: %d portal, area %.4g, %ld/%ld escaped, missed %ld, bound %.3g, blocked %.4f\n",
               sizes[i], n, sc.auto_portals[0].area, c.n_escaped, c.n_rays, c.n_missed, c.bound, c.blocked_fraction);
        CHECK(c.n_missed == 0);
        CHECK_MSG(c.bound <= 1e-5, "bound %.3g", c.bound);
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* multi_lamp: each shaded lamp's portals are its hand-made ones, the
   ceiling panel gets none; light side and receiver side for each. */
static void test_multi_lamp_both_sides(void)
{
    struct config cfg, hand;
    struct scene sc;
    struct error err;
    if (!load_auto("configs/scenes/multi_lamp.yaml", NULL, 0, &cfg, &sc) ||
        !config_load("configs/scenes/multi_lamp.yaml", NULL, 0, &hand, &err)) {
        CHECK(false);
        return;
    }
    for (int e = 0; e < sc.n_emitters; ++e) {
        const struct auto_portal_report *rep = &sc.auto_portals[e];
        struct polygon ports[16];
        int n = portals_of(&sc, e, ports, 16), n_hand = 0;
        for (int k = 0; k < hand.n_portals; ++k) {
            if (hand.portals[k].light != e) continue;
            bool matched = false;
            for (int j = 0; j < n && !matched; ++j) matched = same_polygon(&ports[j], &hand.portals[k].polygon, 1e-9);
            CHECK_MSG(matched, "%s: hand portal %s not found", cfg.lights[e].name, hand.portals[k].name);
            ++n_hand;
        }
        CHECK_MSG(n == n_hand, "%s: %d portals found, %d by hand", cfg.lights[e].name, n, n_hand);
        if (!rep->enclosed) {
            CHECK(n_hand == 0 && !rep->warn);
            printf("  multi_lamp %s: %s\n", cfg.lights[e].name, rep->note);
            continue;
        }
        struct portal_coverage c = light_side(&sc, e, ports, n, 300000, 1L << 22, 21);
        long n_open = 0, missed = receiver_side(&sc, e, ports, n, 100000, 23, &n_open);
        printf("  multi_lamp %s: %d portal(s), area %.4g, light side %ld/%ld escaped, missed %ld, bound %.3g, "
               "blocked %.4f; receiver side %ld open segments, missed %ld\n",
               cfg.lights[e].name, n, rep->area, c.n_escaped, c.n_rays, c.n_missed, c.bound, c.blocked_fraction, n_open,
               missed);
        CHECK(c.n_missed == 0 && c.bound <= 1e-5);
        CHECK(missed == 0 && n_open > 1000);
    }
    scene_destroy(&sc);
    config_free(&cfg);
    config_free(&hand);
}

/* Little Lamp: the hull around the bulb is mostly open (the head is a
   curved shell), so auto gives it no portals, a stated fallback: the bulb
   is then sampled as `light` samples it. */
static void test_little_lamp_fallback(void)
{
    struct config cfg;
    struct scene sc;
    if (!load_auto("configs/scenes/little_lamp.yaml", NULL, 0, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    const struct auto_portal_report *rep = &sc.auto_portals[0];
    printf("  little_lamp: %s\n", rep->note);
    CHECK(rep->requested);
    CHECK(!rep->enclosed && sc.lights[0].n_portals == 0 && sc.n_portals == 0);
    scene_destroy(&sc);
    config_free(&cfg);
}

/* Negative control: without one found portal both sides see the gap. */
static void test_negative_control(void)
{
    struct config cfg;
    struct scene sc;
    if (!load_auto("configs/scenes/multi_lamp.yaml", NULL, 0, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    /* lamp_b (emitter 1): two openings; drop each in turn. */
    for (int drop = 0; drop < 2; ++drop) {
        struct polygon ports[4];
        int n = portals_of(&sc, 1, ports, 4);
        CHECK(n == 2);
        polygon_copy(&ports[drop], &ports[n - 1]);
        struct portal_coverage c = light_side(&sc, 1, ports, n - 1, 20000, 1L << 18, 31);
        long n_open = 0, missed = receiver_side(&sc, 1, ports, n - 1, 20000, 33, &n_open);
        printf("  without portal %d of lamp_b: light side missed %ld of %ld escaped, receiver side %ld of %ld\n", drop,
               c.n_missed, c.n_escaped, missed, n_open);
        CHECK(c.n_missed > 100);
        CHECK(missed > 100);
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

/* ---- renders */

static struct render_desc strict_desc(const struct config *cfg, enum strategy_kind k)
{
    struct render_desc rd = cfg->render;
    rd.integrator = INTEGRATOR_DIRECT;
    rd.mis = MIS_NONE; /* light sampling alone: no BSDF ray can fill a gap */
    rd.defensive = 0.0;
    rd.strategy = k;
    return rd;
}

/* Lampshade with auto portals, antishadow_exact: the closed form on the
   floor (the light seen through the found hole) and inside the shade (the
   light seen whole), within 5 standard errors. */
static void test_rendered_lampshade(void)
{
    static const struct {
        const char *s_l;
        struct vec3 p, n;
        bool inside;
    } cases[] = {
        { "0.6", { 0, 0, 0 }, { 0, 1, 0 }, false },         { "0.6", { -1.0, 0, 0.4 }, { 0, 1, 0 }, false },
        { "0.075", { 0.3, 0, -0.2 }, { 0, 1, 0 }, false },  { "1.2", { -1.6, 0, 1.2 }, { 0, 1, 0 }, false },
        { "0.6", { -0.35, 2.4, 0.05 }, { 1, 0, 0 }, true }, { "0.6", { 0.1, 2.2, 0.3 }, { 0, 1, 0 }, true },
        { "0.3", { -0.2, 2.3, 0.0 }, { 1, 0, 0 }, true },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        struct config cfg;
        struct scene sc;
        struct config_override ov[] = { { "params.s_L", cases[i].s_l } };
        if (!load_auto("configs/scenes/lampshade.yaml", ov, 1, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        int white = 0;
        const struct light *l = &sc.lights[0];
        struct vec3 p = cases[i].p, n = cases[i].n;
        double exact;
        if (cases[i].inside) {
            exact = cfg.materials[white].albedo.r / M_PI * l->radiance.r *
                    polygon_projected_solid_angle(&l->target.polygon, p, n);
        } else {
            struct polygon vis;
            exact =
                antishadow_visible_polygon(&sc.portals[0].antishadow, p, &vis) < 3
                    ? 0.0
                    : cfg.materials[white].albedo.r / M_PI * l->radiance.r * polygon_projected_solid_angle(&vis, p, n);
        }
        struct render_desc rd = strict_desc(&cfg, STRATEGY_ANTISHADOW_EXACT);
        struct estimate e = estimate_at(&sc, &rd, p, n, white, 20000, 41 + i);
        CHECK_MSG(fabs(e.mean - exact) <= 5.0 * e.se + 1e-12 * exact, "s_L=%s (%g, %g, %g): %.6g +- %.2g vs exact %.6g",
                  cases[i].s_l, p.x, p.y, p.z, e.mean, e.se, exact);
        if (exact > 0.0) CHECK(e.mean > 0.0);
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

/* multi_lamp with auto portals, antishadow_exact against `light`, point
   by point (z-test at 5 standard errors): floor, walls, under each shade,
   on the shades' inner and outer faces. */
static void test_rendered_multi_lamp(void)
{
    struct config cfg;
    struct scene sc;
    if (!load_auto("configs/scenes/multi_lamp.yaml", NULL, 0, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    static const struct {
        struct vec3 p, n;
    } pts[] = {
        { { -1.5, 0, -1.0 }, { 0, 1, 0 } },     { { 1.6, 0, -1.6 }, { 0, 1, 0 } },
        { { -1.6, 0, 1.4 }, { 0, 1, 0 } },      { { 0.0, 0, 1.0 }, { 0, 1, 0 } },
        { { 0.5, 0, 2.0 }, { 0, 1, 0 } },       { { -3, 1.5, -1.0 }, { 1, 0, 0 } },
        { { 0, 2.0, -3 }, { 0, 0, 1 } },        { { 1.6, 4, -1.6 }, { 0, -1, 0 } },
        { { -1.5, 2.6, -1.0 }, { 0, 1, 0 } },   { { -1.84, 2.8, -1.0 }, { 1, 0, 0 } },
        { { -1.86, 2.8, -1.0 }, { -1, 0, 0 } }, { { 1.6, 2.4, -1.6 }, { 0, 1, 0 } },
        { { -1.6, 2.0, 1.4 }, { 0, 1, 0 } },    { { 0.29, 2.9, 1.0 }, { -1, 0, 0 } },
    };
    int worst_i = -1;
    double worst_z = 0.0;
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; ++i) {
        struct render_desc ra = strict_desc(&cfg, STRATEGY_ANTISHADOW_EXACT), rl = strict_desc(&cfg, STRATEGY_LIGHT);
        struct estimate a = estimate_at(&sc, &ra, pts[i].p, pts[i].n, 0, 8000, 51 + i);
        struct estimate b = estimate_at(&sc, &rl, pts[i].p, pts[i].n, 0, 8000, 151 + i);
        double se = sqrt(a.se * a.se + b.se * b.se);
        double z = se > 0.0 ? fabs(a.mean - b.mean) / se : (a.mean == b.mean ? 0.0 : INFINITY);
        if (z > worst_z) worst_z = z, worst_i = (int)i;
        CHECK_MSG(z <= 5.0, "(%g, %g, %g): antishadow_exact %.6g +- %.2g, light %.6g +- %.2g", pts[i].p.x, pts[i].p.y,
                  pts[i].p.z, a.mean, a.se, b.mean, b.se);
    }
    printf("  multi_lamp: %zu points, largest z %.2f (point %d)\n", sizeof pts / sizeof pts[0], worst_z, worst_i);
    scene_destroy(&sc);
    config_free(&cfg);
}

/* ---- robustness and fallbacks */

/* A box shade with a square hole in its bottom around a light, meshed in
   several ways; the hole must come out (area s^2) and no escaping ray
   may miss the portals. */
static const char *shade_scene_head = "camera: {position: [0, 1, 6], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
                                      "film: {width: 8, height: 8}\n"
                                      "materials: {grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}}\n"
                                      "render: {spp: 1}\n";
/* The room around the shades: a floor far larger than a shade (shapes of
   more than half the scene's size are never taken as a shade). */
static const char *floor_shape =
    "  - {type: quad, material: grey, vertices: [[-20, -2, -20], [-20, -2, 20], [20, -2, 20], [20, -2, -20]]}\n";

static bool build_text(const char *text, struct config *cfg, struct scene *sc)
{
    return test_scene_load_string(text, strlen(text), "shade.yaml", cfg, sc);
}

/* The shade scene (floor, then shapes) around light, with `portals: auto`. */
static bool build_shade(const char *shapes, const char *light, struct config *cfg, struct scene *sc)
{
    static char text[1 << 16];
    snprintf(text, sizeof text, "%sshapes:\n%s%slights:\n%sportals: auto\n", shade_scene_head, floor_shape, shapes,
             light);
    return build_text(text, cfg, sc);
}

static void check_shade(const char *what, const char *shapes, const char *light, double hole_area, int expect_ports)
{
    struct config cfg;
    struct scene sc;
    if (!build_shade(shapes, light, &cfg, &sc)) {
        CHECK_MSG(false, "%s", what);
        return;
    }
    const struct auto_portal_report *rep = &sc.auto_portals[0];
    struct polygon ports[64];
    int n = portals_of(&sc, 0, ports, 64);
    if (expect_ports >= 0) CHECK_MSG(n == expect_ports, "%s: %d portals (%s)", what, n, rep->note);
    if (hole_area > 0.0) CHECK_MSG(fabs(rep->area - hole_area) <= 1e-9, "%s: area %.9g", what, rep->area);
    if (rep->enclosed) {
        struct portal_coverage c = light_side(&sc, 0, ports, n, 20000, 1L << 18, 61);
        long n_open, missed = receiver_side(&sc, 0, ports, n, 20000, 63, &n_open);
        CHECK_MSG(c.n_missed == 0 && missed == 0, "%s: missed %ld (light side), %ld (receiver side)", what, c.n_missed,
                  missed);
    }
    scene_destroy(&sc);
    config_free(&cfg);
}

static void test_robust_meshing(void)
{
    const char *light =
        "  - {name: bulb, vertices: [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]],"
        " radiance: [1, 1, 1], two_sided: true}\n";
    /* Welded: one mesh, shared vertices; bottom with a hole of 0.4 x 0.4. */
    const char *welded = "  - {type: mesh, material: grey,\n"
                         "     vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5],\n"
                         "                [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
                         "                [-0.2, 0, -0.2], [0.2, 0, -0.2], [0.2, 0, 0.2], [-0.2, 0, 0.2]],\n"
                         "     quads: [[4, 7, 6, 5], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7],\n"
                         "             [0, 8, 9, 1], [1, 9, 10, 2], [2, 10, 11, 3], [3, 11, 8, 0]]}\n";
    check_shade("welded quads", welded, light, 0.16, 1);
    /* The same surfaces as separate quads (unwelded), with the top split
       into triangles, a duplicate face and flipped windings. */
    const char *unwelded =
        "  - {type: quad, material: grey, vertices: [[-0.5, 1, -0.5], [-0.5, 1, 0.5], [0.5, 1, 0.5], [0.5, 1, -0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 1, -0.5], [-0.5, 1, "
        "-0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 1, -0.5], [-0.5, 1, "
        "-0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[0.5, 0, -0.5], [0.5, 0, 0.5], [0.5, 1, 0.5], [0.5, 1, -0.5]]}\n"
        "  - {type: mesh, material: grey, vertices: [[-0.5, 0, 0.5], [0.5, 0, 0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5], [0, "
        "0.5, 0.5]],\n"
        "     triangles: [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]}\n"
        "  - {type: quad, material: grey, vertices: [[-0.5, 0, -0.5], [-0.5, 1, -0.5], [-0.5, 1, 0.5], [-0.5, 0, "
        "0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[-0.5, 0, -0.5], [-0.2, 0, -0.2], [0.2, 0, -0.2], [0.5, 0, "
        "-0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[0.5, 0, -0.5], [0.2, 0, -0.2], [0.2, 0, 0.2], [0.5, 0, 0.5]]}\n"
        "  - {type: quad, material: grey, vertices: [[0.5, 0, 0.5], [0.2, 0, 0.2], [-0.2, 0, 0.2], [-0.5, 0, 0.5]]}\n"
        "  - {type: mesh, material: grey, vertices: [[-0.5, 0, 0.5], [-0.2, 0, 0.2], [-0.2, 0, -0.2], [-0.5, 0, -0.5], "
        "[-0.2, 0, 0]],\n"
        "     triangles: [[0, 1, 4], [0, 4, 3], [4, 2, 3]]}\n";
    check_shade("unwelded, split, duplicate, flipped", unwelded, light, 0.16, 1);
    /* Transformed (rotated and moved): the same shade. */
    char moved[4096];
    snprintf(moved, sizeof moved,
             "%.*s, transform: [{rotate: {axis: [1, 2, 0.5], angle: 30}}, {translate: [0.3, 1.2, -0.4]}]}\n",
             (int)(strlen(welded) - 2), welded);
    char moved_light[512];
    snprintf(moved_light, sizeof moved_light,
             "%.*s, transform: [{rotate: {axis: [1, 2, 0.5], angle: 30}}, {translate: [0.3, 1.2, -0.4]}]}\n",
             (int)(strlen(light) - 2), light);
    check_shade("transformed", moved, moved_light, 0.16, 1);
    /* A one-sided light facing up in the same shade: nothing it emits goes
       down, so no portal (the hole is behind it). */
    const char *up =
        "  - {name: bulb, vertices: [[-0.2, 0.5, -0.2], [-0.2, 0.5, 0.2], [0.2, 0.5, 0.2], [0.2, 0.5, -0.2]],"
        " radiance: [1, 1, 1]}\n";
    check_shade("one-sided, facing away from the hole", welded, up, 0.0, 0);
}

/* A lamp modelled as one mesh: the shade of test_robust_meshing and, in
   the same mesh but not connected to it, a stand beside it (a vertical
   panel). The hull of the whole mesh reaches out to the stand and leaves
   the gap between them open; the hull of the shade's piece alone gives
   the hole, as a shade of its own does. */
static void test_one_mesh_lamp(void)
{
    const char *light =
        "  - {name: bulb, vertices: [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]],"
        " radiance: [1, 1, 1], two_sided: true}\n";
    const char *lamp = "  - {type: mesh, material: grey,\n"
                       "     vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5],\n"
                       "                [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
                       "                [-0.2, 0, -0.2], [0.2, 0, -0.2], [0.2, 0, 0.2], [-0.2, 0, 0.2],\n"
                       "                [1.5, -1.5, -0.3], [1.5, -1.5, 0.3], [1.5, 1.2, 0.3], [1.5, 1.2, -0.3]],\n"
                       "     quads: [[4, 7, 6, 5], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7],\n"
                       "             [0, 8, 9, 1], [1, 9, 10, 2], [2, 10, 11, 3], [3, 11, 8, 0], [12, 13, 14, 15]]}\n";
    check_shade("shade and stand in one mesh", lamp, light, 0.16, 1);
    struct config cfg;
    struct scene sc;
    if (!build_shade(lamp, light, &cfg, &sc)) {
        CHECK(false);
        return;
    }
    const char *note = sc.auto_portals[0].note;
    CHECK_MSG(strstr(note, "1 portal(s) on the hull of 1 connected piece(s) of shapes") != NULL, "%s", note);
    scene_destroy(&sc);
    config_free(&cfg);
}

/* mesh_components: pieces by shared position, not by shared index. */
static void test_mesh_components(void)
{
    /* Two quads sharing an edge by position only (unwelded, as at a UV
       seam), a triangle apart, and a triangle sharing index 9 with it. */
    const struct vec3 v[] = { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0 },   { 0, 1, 0 }, { 1, 0, 0 },
                              { 2, 0, 0 }, { 2, 1, 0 }, { 1, 1, 0 },   { 5, 5, 5 }, { 6, 5, 5 },
                              { 5, 6, 5 }, { 7, 7, 7 }, { -0.0, 0, 0 } };
    const int quads[][4] = { { 0, 1, 2, 3 }, { 4, 5, 6, 7 } };
    const int tris[][3] = { { 8, 9, 10 }, { 9, 11, 10 }, { 12, 3, 2 } };
    int label[5];
    int n = mesh_components(v, 13, quads, 2, tris, 3, label);
    CHECK_MSG(n == 2, "%d pieces", n);
    CHECK(label[0] == 0 && label[1] == 0 && label[4] == 0); /* -0 and 0 are one position */
    CHECK(label[2] == 1 && label[3] == 1);
    /* Nothing: no faces, no pieces. */
    CHECK(mesh_components(v, 13, quads, 0, tris, 0, label) == 0);
}

/* A finely meshed shade: the box's bottom (with its hole) a 14 x 14 grid
   of triangle pairs less the 6 x 6 cells of the hole. The greedy merge of
   the bottom's many open pieces once accepted a 2-D hull that did not
   hold both pieces (an opening lost while the total area stayed right):
   579 of 6853 escaping rays crossed no portal. */
static void test_tessellated_shade(void)
{
    static char shapes[1 << 16];
    int n = snprintf(shapes, sizeof shapes,
                     "  - {type: mesh, material: grey,\n"
                     "     vertices: [[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
                     "                [-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5]],\n"
                     "     quads: [[0, 3, 2, 1], [4, 5, 1, 0], [5, 6, 2, 1], [6, 7, 3, 2], [7, 4, 0, 3]]}\n"
                     "  - {type: mesh, material: grey, vertices: [");
    const int g = 14;
    for (int i = 0; i <= g; ++i)
        for (int j = 0; j <= g; ++j)
            n += snprintf(shapes + n, sizeof shapes - (size_t)n, "%s[%.17g, 0, %.17g]", i || j ? ", " : "",
                          -0.5 + (double)i / g, -0.5 + (double)j / g);
    n += snprintf(shapes + n, sizeof shapes - (size_t)n, "],\n     triangles: [");
    bool first = true;
    for (int i = 0; i < g; ++i)
        for (int j = 0; j < g; ++j) {
            if (i >= 4 && i < 10 && j >= 4 && j < 10) continue; /* the hole */
            int a = i * (g + 1) + j, b = a + g + 1;
            n += snprintf(shapes + n, sizeof shapes - (size_t)n, "%s[%d, %d, %d], [%d, %d, %d]", first ? "" : ", ", a,
                          b, b + 1, a, b + 1, a + 1);
            first = false;
        }
    snprintf(shapes + n, sizeof shapes - (size_t)n, "]}\n");
    const char *light =
        "  - {name: bulb, vertices: [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]],"
        " radiance: [1, 1, 1], two_sided: true}\n";
    check_shade("tessellated bottom", shapes, light, (6.0 / 14) * (6.0 / 14), -1);
}

/* The edge test of open_region (geometry/facet_cover.c): a tessellated bottom
   with two holes far apart (one of them a single missing triangle), a
   duplicated triangle and a triangle wound the other way. The duplicate
   leaves its edges unbalanced, so they count as free and widen the region
   that is subtracted exactly; the holes must come out whole. */
static void test_edge_test_holes(void)
{
    static char shapes[1 << 16];
    int n = snprintf(shapes, sizeof shapes,
                     "  - {type: mesh, material: grey,\n"
                     "     vertices: [[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
                     "                [-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5]],\n"
                     "     quads: [[0, 3, 2, 1], [4, 5, 1, 0], [5, 6, 2, 1], [6, 7, 3, 2], [7, 4, 0, 3]]}\n"
                     "  - {type: mesh, material: grey, vertices: [");
    const int g = 10;
    for (int i = 0; i <= g; ++i)
        for (int j = 0; j <= g; ++j)
            n += snprintf(shapes + n, sizeof shapes - (size_t)n, "%s[%.17g, 0, %.17g]", i || j ? ", " : "",
                          -0.5 + (double)i / g, -0.5 + (double)j / g);
    n += snprintf(shapes + n, sizeof shapes - (size_t)n, "],\n     triangles: [");
    bool first = true;
    for (int i = 0; i < g; ++i)
        for (int j = 0; j < g; ++j) {
            if (i >= 1 && i < 3 && j >= 1 && j < 4) continue; /* a 2 x 3 hole */
            int a = i * (g + 1) + j, b = a + g + 1;
            bool drop_second = i == 7 && j == 6; /* a one-triangle hole */
            bool flip = i == 5 && j == 2, dup = i == 4 && j == 8;
            n += snprintf(shapes + n, sizeof shapes - (size_t)n, "%s[%d, %d, %d]", first ? "" : ", ", a,
                          flip ? b + 1 : b, flip ? b : b + 1);
            if (dup) n += snprintf(shapes + n, sizeof shapes - (size_t)n, ", [%d, %d, %d]", a, b, b + 1);
            if (!drop_second) n += snprintf(shapes + n, sizeof shapes - (size_t)n, ", [%d, %d, %d]", a, b + 1, a + 1);
            first = false;
        }
    snprintf(shapes + n, sizeof shapes - (size_t)n, "]}\n");
    const char *light =
        "  - {name: bulb, vertices: [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]],"
        " radiance: [1, 1, 1], two_sided: true}\n";
    check_shade("edge test, two holes", shapes, light, 0.2 * 0.3 + 0.5 * 0.1 * 0.1, -1);
}

/* A drum shade (open at both ends) of n_seg segments, radius r, from
   y = 0 to 1: an outer wall whose middle ring has a waist (inward by 2 to
   3 mm, alternately, so its quads are not planar), and, when `inner`, an
   inner wall 1 cm inside joined to it by flat rims. The hull's side
   facets then have no triangle in them: only the layer rule
   (layer_covers) can close them. `skip` >= 0 leaves out the outer wall's
   segment skip (both rings), a real hole when there is no inner wall. */
static int drum_shape(char *out, size_t size, int n_seg, double r, bool inner, int skip)
{
    int n = snprintf(out, size, "  - {type: mesh, material: grey, vertices: [");
    int walls = inner ? 2 : 1;
    for (int w = 0; w < walls; ++w)
        for (int ring = 0; ring < 3; ++ring)
            for (int k = 0; k < n_seg; ++k) {
                double a = 2.0 * M_PI * k / n_seg;
                double rr = w ? r - 0.01 : ring == 1 ? r - 0.002 - 0.001 * (k % 2) : r;
                n += snprintf(out + n, size - (size_t)n, "%s[%.17g, %.17g, %.17g]", w || ring || k ? ", " : "",
                              rr * cos(a), 0.5 * ring, rr * sin(a));
            }
    n += snprintf(out + n, size - (size_t)n, "],\n     triangles: [");
    bool first = true;
#define DRUM_V(w, ring, k) ((w)*3 * n_seg + (ring)*n_seg + ((k) % n_seg))
#define DRUM_QUAD(a, b, c, d)                                                                                          \
    do {                                                                                                               \
        n += snprintf(out + n, size - (size_t)n, "%s[%d, %d, %d], [%d, %d, %d]", first ? "" : ", ", a, b, c, a, c, d); \
        first = false;                                                                                                 \
    } while (0)
    for (int w = 0; w < walls; ++w)
        for (int ring = 0; ring < 2; ++ring)
            for (int k = 0; k < n_seg; ++k) {
                if (w == 0 && k == skip) continue;
                DRUM_QUAD(DRUM_V(w, ring, k), DRUM_V(w, ring, k + 1), DRUM_V(w, ring + 1, k + 1),
                          DRUM_V(w, ring + 1, k));
            }
    for (int k = 0; inner && k < n_seg; ++k) {
        DRUM_QUAD(DRUM_V(0, 0, k), DRUM_V(0, 0, k + 1), DRUM_V(1, 0, k + 1), DRUM_V(1, 0, k));
        DRUM_QUAD(DRUM_V(0, 2, k), DRUM_V(0, 2, k + 1), DRUM_V(1, 2, k + 1), DRUM_V(1, 2, k));
    }
#undef DRUM_QUAD
#undef DRUM_V
    n += snprintf(out + n, size - (size_t)n, "]}\n");
    return n;
}

/* The layer rule on drum shades, each checked for completeness from the
   light side (at least 3e5 escaping rays) and the receiver side. */
static void test_drum_layers(void)
{
    static char shapes[1 << 16];
    const int n_seg = 24;
    const double r = 0.5, ngon = 0.5 * n_seg * sin(2.0 * M_PI / n_seg);
    const char *light = "  - {name: bulb, vertices: [[-0.05, 0.5, -0.05], [0.05, 0.5, -0.05], [0.05, 0.5, 0.05],"
                        " [-0.05, 0.5, 0.05]], radiance: [1, 1, 1], two_sided: true}\n";
    static char text[1 << 17];
    for (int variant = 0; variant < 2; ++variant) {
        /* 0: inner and outer wall, rims: the two openings and nothing else.
           1: one wall with a segment missing (negative control of the
           watertight condition): that segment's facet stays a portal. */
        drum_shape(shapes, sizeof shapes, n_seg, r, variant == 0, variant == 0 ? -1 : 5);
        snprintf(text, sizeof text, "%sshapes:\n%s%slights:\n%sportals: auto\n", shade_scene_head, floor_shape, shapes,
                 light);
        struct config cfg;
        struct scene sc;
        if (!build_text(text, &cfg, &sc)) {
            CHECK_MSG(false, "drum variant %d", variant);
            continue;
        }
        const struct auto_portal_report *rep = &sc.auto_portals[0];
        struct polygon ports[64];
        int n = portals_of(&sc, 0, ports, 64);
        CHECK_MSG(rep->enclosed, "drum %d: %s", variant, rep->note);
        double caps = variant == 0 ? 2.0 * ngon * (r - 0.01) * (r - 0.01) : 2.0 * ngon * r * r;
        double hole = variant == 0 ? 0.0 : 2.0 * r * sin(M_PI / n_seg); /* the missing segment's facet */
        if (variant == 0) {
            CHECK_MSG(n == 2 && fabs(rep->area - caps) <= 1e-9, "drum 0: %d portals, area %.9g (caps %.9g)", n,
                      rep->area, caps);
        } else {
            CHECK_MSG(rep->area >= caps + hole - 1e-9, "drum 1: area %.9g < caps and hole %.9g", rep->area,
                      caps + hole);
            /* The missing segment's middle, seen from the light, is on a portal. */
            double a = 2.0 * M_PI * 5.5 / n_seg;
            struct vec3 o = vec3_make(0.0, 0.5, 0.0), d = vec3_make(cos(a), 0.0, sin(a));
            bool on = false;
            for (int k = 0; k < n && !on; ++k) {
                double t;
                on = polygon_intersect_ray(&ports[k], o, d, &t);
            }
            CHECK_MSG(on, "drum 1: the missing segment is on no portal");
        }
        if (rep->enclosed) {
            struct portal_coverage c = light_side(&sc, 0, ports, n, 300000, 1L << 22, 71);
            long n_open, missed = receiver_side(&sc, 0, ports, n, 20000, 73, &n_open);
            printf("  drum %d: %d portal(s), area %.6g, light side %ld/%ld escaped, missed %ld, bound %.3g, blocked "
                   "%.4f; receiver side %ld open segments, missed %ld\n",
                   variant, n, rep->area, c.n_escaped, c.n_rays, c.n_missed, c.bound, c.blocked_fraction, n_open,
                   missed);
            CHECK_MSG(c.n_escaped >= 300000 && c.n_missed == 0 && missed == 0,
                      "drum %d: %ld escaped, missed %ld (light side), %ld (receiver side)", variant, c.n_escaped,
                      c.n_missed, missed);
        }
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

static void test_fallbacks(void)
{
    const char *welded = "  - {type: mesh, material: grey,\n"
                         "     vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5],\n"
                         "                [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
                         "                [-0.2, 0, -0.2], [0.2, 0, -0.2], [0.2, 0, 0.2], [-0.2, 0, 0.2]],\n"
                         "     quads: [[4, 7, 6, 5], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7],\n"
                         "             [0, 8, 9, 1], [1, 9, 10, 2], [2, 10, 11, 3], [3, 11, 8, 0]]}\n";
    static const struct {
        const char *what, *light, *note;
        bool warn;
    } cases[] = {
        { "piercing",
          "  - {name: bulb, vertices: [[-0.8, 0.5, -0.2], [0.2, 0.5, -0.2], [0.2, 0.5, 0.2], [-0.8, 0.5, 0.2]], "
          "radiance: [1, 1, 1], two_sided: true}\n",
          "touches or pierces", true },
        { "touching the top",
          "  - {name: bulb, vertices: [[-0.2, 1, -0.2], [0.2, 1, -0.2], [0.2, 1, 0.2], [-0.2, 1, 0.2]], radiance: [1, "
          "1, 1]}\n",
          "touches or pierces", true },
        { "outside",
          "  - {name: bulb, vertices: [[2, 0.5, -0.2], [2, 0.5, 0.2], [2.4, 0.5, 0.2], [2.4, 0.5, -0.2]], radiance: "
          "[1, 1, 1], two_sided: true}\n",
          "no shape encloses it", false },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        static char text[1 << 14];
        snprintf(text, sizeof text, "%sshapes:\n%s%slights:\n%sportals: auto\n", shade_scene_head, floor_shape, welded,
                 cases[i].light);
        struct config cfg;
        struct scene sc;
        if (!build_text(text, &cfg, &sc)) {
            CHECK_MSG(false, "%s", cases[i].what);
            continue;
        }
        const struct auto_portal_report *rep = &sc.auto_portals[0];
        CHECK_MSG(!rep->enclosed && sc.n_portals == 0 && rep->warn == cases[i].warn && strstr(rep->note, cases[i].note),
                  "%s: %s", cases[i].what, rep->note);
        scene_destroy(&sc);
        config_free(&cfg);
    }
    /* Coplanar geometry only (a degenerate hull): no enclosure. */
    static char text[1 << 14];
    snprintf(text, sizeof text,
             "%sshapes:\n  - {type: quad, material: grey, vertices: [[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]]}\n"
             "  - {type: quad, material: grey, vertices: [[-9, -1, -9], [9, -1, -9], [9, -1, 9], [-9, -1, 9]]}\n"
             "lights:\n  - {name: l, vertices: [[-0.2, 0.5, -0.2], [0.2, 0.5, -0.2], [0.2, 0.5, 0.2], [-0.2, 0.5, "
             "0.2]], radiance: [1, 1, 1], two_sided: true}\n"
             "portals: auto\n",
             shade_scene_head);
    struct config cfg;
    struct scene sc;
    if (build_text(text, &cfg, &sc)) {
        CHECK(!sc.auto_portals[0].enclosed && sc.n_portals == 0);
        scene_destroy(&sc);
        config_free(&cfg);
    } else {
        CHECK(false);
    }
    /* Nested shades: a small closed-but-for-a-hole box inside the big one:
       the inner shade is the enclosure. */
    const char *inner = "  - {type: mesh, material: grey,\n"
                        "     vertices: [[-0.3, 0.3, -0.3], [0.3, 0.3, -0.3], [0.3, 0.3, 0.3], [-0.3, 0.3, 0.3],\n"
                        "                [-0.3, 0.8, -0.3], [0.3, 0.8, -0.3], [0.3, 0.8, 0.3], [-0.3, 0.8, 0.3],\n"
                        "                [-0.1, 0.3, -0.1], [0.1, 0.3, -0.1], [0.1, 0.3, 0.1], [-0.1, 0.3, 0.1]],\n"
                        "     quads: [[4, 7, 6, 5], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7],\n"
                        "             [0, 8, 9, 1], [1, 9, 10, 2], [2, 10, 11, 3], [3, 11, 8, 0]]}\n";
    char both[4096];
    snprintf(both, sizeof both, "%s%s", welded, inner);
    check_shade("nested shades", both,
                "  - {name: bulb, vertices: [[-0.1, 0.6, -0.1], [0.1, 0.6, -0.1], [0.1, 0.6, 0.1], [-0.1, 0.6, 0.1]],"
                " radiance: [1, 1, 1], two_sided: true}\n",
                0.04, 1);
}

/* Same scene, same portals bit for bit, whatever render.threads. */
static void test_deterministic(void)
{
    struct config a, b;
    struct scene sa, sb;
    struct config_override one[] = { { "render.threads", "1" } }, four[] = { { "render.threads", "4" } };
    if (!load_auto("configs/scenes/multi_lamp.yaml", one, 1, &a, &sa)) {
        CHECK(false);
        return;
    }
    if (!load_auto("configs/scenes/multi_lamp.yaml", four, 1, &b, &sb)) {
        CHECK(false);
        scene_destroy(&sa);
        config_free(&a);
        return;
    }
    CHECK(sa.n_portals == sb.n_portals);
    for (int i = 0; i < sa.n_portals && i < sb.n_portals; ++i) {
        const struct polygon *p = &sa.portals[i].target->polygon, *q = &sb.portals[i].target->polygon;
        CHECK(p->n == q->n && memcmp(p->v, q->v, sizeof p->v[0] * (size_t)p->n) == 0);
    }
    scene_destroy(&sa);
    scene_destroy(&sb);
    config_free(&a);
    config_free(&b);
}

/* The config: `portals: auto` and per-light entries load back from the
   effective YAML; without auto nothing is requested. */
static void test_config_round_trip(void)
{
    const char *text = "camera: {position: [0, 1, 6], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
                       "film: {width: 8, height: 8}\n"
                       "materials: {grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}}\n"
                       "render: {spp: 1}\n"
                       "lights:\n"
                       "  - {name: a, vertices: [[0, 2, 0], [1, 2, 0], [1, 2, 1]], radiance: [1, 1, 1]}\n"
                       "  - {name: b, vertices: [[0, 3, 0], [1, 3, 0], [1, 3, 1]], radiance: [1, 1, 1]}\n"
                       "portals:\n"
                       "  - {light: b, auto: true}\n"
                       "  - {name: pa, light: a, vertices: [[0, 1, 0], [1, 1, 1], [1, 1, 0]]}\n";
    struct config c, d;
    struct error err;
    CHECK(config_load_string(text, strlen(text), "t.yaml", NULL, 0, &c, &err));
    CHECK(!c.lights[0].auto_portals && c.lights[1].auto_portals && c.n_portals == 1 && !c.portals_auto);
    CHECK(strstr(c.effective_yaml, "auto: true") != NULL);
    CHECK(config_load_string(c.effective_yaml, strlen(c.effective_yaml), "e.yaml", NULL, 0, &d, &err));
    CHECK(d.hash == c.hash && d.lights[1].auto_portals && d.n_portals == 1);
    config_free(&c);
    config_free(&d);
}

static const struct test_case tests[] = {
    { "hull_box", test_hull_box },
    { "hull_sphere_points", test_hull_sphere_points },
    { "hull_2d", test_hull_2d },
    { "subtract_triangle", test_subtract_triangle },
    { "config_round_trip", test_config_round_trip },
    { "lampshade_hole_and_light_side", test_lampshade_hole_and_light_side },
    { "multi_lamp_both_sides", test_multi_lamp_both_sides },
    { "little_lamp_fallback", test_little_lamp_fallback },
    { "negative_control", test_negative_control },
    { "rendered_lampshade", test_rendered_lampshade },
    { "rendered_multi_lamp", test_rendered_multi_lamp },
    { "robust_meshing", test_robust_meshing },
    { "tessellated_shade", test_tessellated_shade },
    { "one_mesh_lamp", test_one_mesh_lamp },
    { "mesh_components", test_mesh_components },
    { "edge_test_holes", test_edge_test_holes },
    { "drum_layers", test_drum_layers },
    { "fallbacks", test_fallbacks },
    { "deterministic", test_deterministic },
};

TEST_MAIN(tests)

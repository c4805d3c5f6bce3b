/* libFuzzer target: `portals: auto` (scene/portal_finder.h) on random
   shades. The bytes build a shade around a light: a box or a prism (3 to 8
   sides), each face cut into a grid of cells of which some are holes, the
   rest quads or split into two triangles, welded into one mesh or written
   as separate shapes, some duplicated, some with flipped winding, all
   under a random rotation, scale and translation; the light is a quad
   inside it, one- or two-sided, tilted, sometimes large enough to pierce
   the shade. The scene is loaded as a user's config is (config_load_string,
   scene_create). Then either the light is enclosed and its portals are
   complete (the light side of the coverage test: of 4096 of the light's
   rays that leave the enclosure unoccluded, none crosses no portal; a
   closed shade has no portal and lets no ray out), or it got no portals
   and a note (a clean fallback). Anything else aborts: the fuzzer's finding. */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "config/config.h"
#include "scene/portal_coverage.h"
#include "scene/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The fuzz bytes as a stream of choices; zeros after the end. */
struct bytes {
    const uint8_t *p;
    size_t n, at;
};

static unsigned next_byte(struct bytes *b)
{
    return b->at < b->n ? b->p[b->at++] : 0u;
}

/* A value in [lo, hi] from one byte. */
static double next_range(struct bytes *b, double lo, double hi)
{
    return lo + (hi - lo) * (double)next_byte(b) / 255.0;
}

/* The growing YAML text. */
struct text {
    char *s;
    size_t n, cap;
    bool failed;
};

static void put(struct text *t, const char *fmt, ...)
{
    for (int tries = 0; tries < 2 && !t->failed; ++tries) {
        va_list ap;
        va_start(ap, fmt);
        /* No buffer yet: ask for the length only (NULL + 0 is undefined). */
        int m = vsnprintf(t->s ? t->s + t->n : NULL, t->cap - t->n, fmt, ap);
        va_end(ap);
        if (m < 0) break;
        if ((size_t)m < t->cap - t->n) {
            t->n += (size_t)m;
            return;
        }
        size_t cap = 2 * (t->cap + (size_t)m) + 1;
        char *s = realloc(t->s, cap);
        if (!s) break;
        t->s = s;
        t->cap = cap;
    }
    t->failed = true;
}

/* The random similarity: x -> scale * R x + shift. */
struct xform {
    double r[3][3], scale;
    struct vec3 shift;
};

static struct xform random_xform(struct bytes *b)
{
    struct xform x;
    struct vec3 axis = vec3_make(next_range(b, -1, 1), next_range(b, -1, 1), next_range(b, -1, 1));
    double len = vec3_length(axis), angle = next_range(b, 0, 2 * M_PI);
    axis = len > 1e-3 ? vec3_scale(axis, 1.0 / len) : vec3_make(0, 1, 0);
    double c = cos(angle), s = sin(angle), k = 1 - c;
    double ax = axis.x, ay = axis.y, az = axis.z;
    double r[3][3] = { { c + ax * ax * k, ax * ay * k - az * s, ax * az * k + ay * s },
                       { ay * ax * k + az * s, c + ay * ay * k, ay * az * k - ax * s },
                       { az * ax * k - ay * s, az * ay * k + ax * s, c + az * az * k } };
    memcpy(x.r, r, sizeof r);
    x.scale = pow(10.0, next_range(b, -1.5, 1.5));
    x.shift = vec3_make(next_range(b, -5, 5), next_range(b, -5, 5), next_range(b, -5, 5));
    return x;
}

static struct vec3 apply(const struct xform *x, struct vec3 p)
{
    struct vec3 q = vec3_make(x->r[0][0] * p.x + x->r[0][1] * p.y + x->r[0][2] * p.z,
                              x->r[1][0] * p.x + x->r[1][1] * p.y + x->r[1][2] * p.z,
                              x->r[2][0] * p.x + x->r[2][1] * p.y + x->r[2][2] * p.z);
    return vec3_add(vec3_scale(q, x->scale), x->shift);
}

static void put_point(struct text *t, const struct xform *x, struct vec3 p)
{
    struct vec3 q = apply(x, p);
    put(t, "[%.17g, %.17g, %.17g]", q.x, q.y, q.z);
}

/* One face of the shade: a convex quad (a, b, c, d) cut into g x g cells,
   or a triangle (a, b, c; d == c), one cell cut once. */
#define MAX_FACES 16
struct face {
    struct vec3 v[4];
};

/* The cells of every face, as shapes. A welded shade is one mesh per face
   (cells share the face's grid vertices); otherwise each cell is a shape. */
static void put_shade(struct text *t, struct bytes *b, const struct xform *x, const struct face *faces, int n_faces)
{
    bool welded = next_byte(b) & 1;
    for (int f = 0; f < n_faces; ++f) {
        const struct vec3 *v = faces[f].v;
        bool triangle = v[3].x == v[2].x && v[3].y == v[2].y && v[3].z == v[2].z;
        int g = triangle ? 1 : 1 + (int)(next_byte(b) % 3);
        struct vec3 grid[4][4];
        for (int i = 0; i <= g; ++i)
            for (int j = 0; j <= g; ++j) {
                double u = (double)i / g, w = (double)j / g;
                struct vec3 ab = vec3_add(vec3_scale(v[0], 1 - u), vec3_scale(v[1], u));
                struct vec3 dc = vec3_add(vec3_scale(v[3], 1 - u), vec3_scale(v[2], u));
                grid[i][j] = vec3_add(vec3_scale(ab, 1 - w), vec3_scale(dc, w));
            }
        if (welded) {
            put(t, "  - {type: mesh, material: grey, vertices: [");
            for (int i = 0; i <= g; ++i)
                for (int j = 0; j <= g; ++j) {
                    put(t, i || j ? ", " : "");
                    put_point(t, x, grid[i][j]);
                }
            put(t, "], triangles: [");
        }
        bool any = false;
        for (int i = 0; i < g; ++i)
            for (int j = 0; j < g; ++j) {
                unsigned c = next_byte(b);
                if ((c & 7) == 7) continue; /* a hole */
                int idx[4] = { i * (g + 1) + j, (i + 1) * (g + 1) + j, (i + 1) * (g + 1) + j + 1, i * (g + 1) + j + 1 };
                struct vec3 p[4] = { grid[i][j], grid[i + 1][j], grid[i + 1][j + 1], grid[i][j + 1] };
                bool flip = c & 8, split_other = (c & 16) && !triangle, dup = (c & 96) == 96;
                if (flip && !triangle) {
                    int ti = idx[1];
                    idx[1] = idx[3], idx[3] = ti;
                    struct vec3 tp = p[1];
                    p[1] = p[3], p[3] = tp;
                }
                int s0 = split_other ? 1 : 0;
                int tri[2][3] = { { s0, s0 + 1, (s0 + 2) % 4 }, { s0, (s0 + 2) % 4, (s0 + 3) % 4 } };
                for (int copy = 0; copy <= dup; ++copy) {
                    if (welded) {
                        for (int k = 0; k < 2 - triangle; ++k) {
                            put(t, "%s[%d, %d, %d]", any ? ", " : "", idx[tri[k][0]], idx[tri[k][1]], idx[tri[k][2]]);
                            any = true;
                        }
                    } else if ((c & 32) && !triangle) {
                        put(t, "  - {type: quad, material: grey, vertices: [");
                        for (int k = 0; k < 4; ++k) {
                            put(t, k ? ", " : "");
                            put_point(t, x, p[k]);
                        }
                        put(t, "]}\n");
                    } else {
                        for (int k = 0; k < 2 - triangle; ++k) {
                            put(t, "  - {type: mesh, material: grey, vertices: [");
                            for (int m = 0; m < 3; ++m) {
                                put(t, m ? ", " : "");
                                put_point(t, x, p[tri[k][m]]);
                            }
                            put(t, "], triangles: [[0, 1, 2]]}\n");
                        }
                    }
                }
            }
        if (welded && !any) put(t, "[0, 1, %d]", g + 2); /* a mesh needs a triangle: a cell half */
        if (welded) put(t, "]}\n");
    }
}

/* The distance from x to the segment a..b. */
static double segment_distance(struct vec3 x, struct vec3 a, struct vec3 b)
{
    struct vec3 ab = vec3_sub(b, a);
    double len2 = vec3_dot(ab, ab), s = len2 > 0.0 ? vec3_dot(vec3_sub(x, a), ab) / len2 : 0.0;
    return vec3_length(vec3_sub(x, vec3_madd(a, ab, fmax(0.0, fmin(1.0, s)))));
}

/* The light side of the coverage test, as portal_finder_coverage counts
   it (same rays, same tests), except for a miss that leaves P within
   Embree's float resolution of a portal's edge: there a covering triangle
   and the portal share the edge, and whether the ray slips between them is
   the float ray tracer's rounding (it would leak in any render), not a
   gap in the portals. Counts the other misses into *n_missed. */
static bool light_side(const struct scene *s, const struct auto_portal_report *rep, const struct polygon *ports,
                       int n_ports, long n_rays, long *n_escaped, long *n_missed, struct vec3 *miss)
{
    struct emission_sampler es;
    struct error err;
    if (!emission_sampler_init(&es, s, 0, &err)) return false;
    struct rng r = rng_seeded(0x5eed, 0, 0);
    for (long i = 0; i < n_rays; ++i) {
        double u[EMISSION_UNIFORMS];
        struct vec3 p, n, d;
        for (int k = 0; k < EMISSION_UNIFORMS; ++k) u[k] = rng_uniform(&r);
        emission_sample(&es, u, &p, &n, &d);
        double step = scene_offset_step(s, p, n, d), t_exit = INFINITY;
        for (int k = 0; k < rep->n_planes; ++k) {
            double c = vec3_dot(rep->planes[k].normal, d);
            if (c > 0.0) t_exit = fmin(t_exit, fmax(0.0, -plane_distance(&rep->planes[k], p)) / c);
        }
        t_exit -= step;
        struct vec3 o = vec3_madd(p, d, step);
        if (!isfinite(t_exit) || !(t_exit > scene_offset_height(s, o))) continue;
        bool on_portal = false;
        for (int k = 0; k < n_ports && !on_portal; ++k) {
            double t;
            on_portal = polygon_intersect_ray(&ports[k], o, d, &t);
        }
        struct hit h;
        struct vec3 x = vec3_madd(o, d, t_exit);
        if (scene_intersect(s, o, d, t_exit + scene_offset_height(s, x), &h)) continue;
        ++*n_escaped;
        if (on_portal) continue;
        double near = INFINITY, size = fmax(fabs(x.x), fmax(fabs(x.y), fabs(x.z)));
        for (int k = 0; k < n_ports; ++k)
            for (int e = 0; e < ports[k].n; ++e)
                near = fmin(near, segment_distance(x, ports[k].v[e], ports[k].v[(e + 1) % ports[k].n]));
        if (near <= 16.0 * FLT_EPSILON * size) continue;
        ++*n_missed;
        *miss = x;
    }
    emission_sampler_free(&es);
    return true;
}

/* Aborts with what went wrong. */
static void fail(const char *what, const char *yaml)
{
    fprintf(stderr, "fuzz_portals: %s\n--- scene ---\n%s\n", what, yaml);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct bytes b = { data, size, 0 };
    struct text t = { NULL, 0, 0, false };
    struct xform x = random_xform(&b);
    /* The shade in its own frame: a box of half sizes hx, hy, hz, or a
       prism of n sides of radius r and half height hy. */
    struct face faces[MAX_FACES];
    int n_faces = 0;
    double hy = next_range(&b, 0.3, 1.5), inner;
    if (next_byte(&b) & 1) {
        double hx = next_range(&b, 0.3, 1.5), hz = next_range(&b, 0.3, 1.5);
        struct vec3 c[8];
        for (int i = 0; i < 8; ++i) c[i] = vec3_make(i & 1 ? hx : -hx, i & 2 ? hy : -hy, i & 4 ? hz : -hz);
        const int q[6][4] = { { 0, 1, 3, 2 }, { 4, 6, 7, 5 }, { 0, 4, 5, 1 },
                              { 2, 3, 7, 6 }, { 0, 2, 6, 4 }, { 1, 5, 7, 3 } };
        for (int f = 0; f < 6; ++f)
            for (int k = 0; k < 4; ++k) faces[n_faces + f].v[k] = c[q[f][k]];
        n_faces = 6;
        inner = fmin(hx, fmin(hy, hz));
    } else {
        int n = 3 + (int)(next_byte(&b) % 6);
        double r = next_range(&b, 0.4, 1.5);
        struct vec3 ring[8];
        for (int i = 0; i < n; ++i) ring[i] = vec3_make(r * cos(2 * M_PI * i / n), 0, r * sin(2 * M_PI * i / n));
        for (int i = 0; i < n; ++i) {
            struct vec3 a = ring[i], c = ring[(i + 1) % n];
            faces[n_faces++] = (struct face){ { vec3_make(a.x, -hy, a.z), vec3_make(c.x, -hy, c.z),
                                                vec3_make(c.x, hy, c.z), vec3_make(a.x, hy, a.z) } };
        }
        /* The caps as fans of quads (a prism of 3..8 sides: each cap is
           (n - 2) / 2 quads, plus a triangle as a degenerate quad). */
        for (int cap = 0; cap < 2; ++cap) {
            double y = cap ? hy : -hy;
            for (int i = 1; i + 1 < n; i += 2) {
                struct vec3 p0 = vec3_make(ring[0].x, y, ring[0].z), p1 = vec3_make(ring[i].x, y, ring[i].z);
                struct vec3 p2 = vec3_make(ring[i + 1].x, y, ring[i + 1].z);
                struct vec3 p3 = i + 2 < n ? vec3_make(ring[i + 2].x, y, ring[i + 2].z) : p2;
                if (n_faces < MAX_FACES) faces[n_faces++] = (struct face){ { p0, p1, p2, p3 } };
            }
        }
        inner = fmin(hy, r * cos(M_PI / n));
    }
    /* The light: a tilted quad about a point near the centre; usually
       well inside, sometimes (a large size) through the shade. */
    double half = inner * (next_byte(&b) < 224 ? next_range(&b, 0.05, 0.45) : next_range(&b, 0.9, 2.0));
    struct vec3 centre = vec3_make(next_range(&b, -0.3, 0.3) * inner, next_range(&b, -0.3, 0.3) * inner,
                                   next_range(&b, -0.3, 0.3) * inner);
    struct xform tilt = random_xform(&b);
    tilt.scale = 1.0;
    tilt.shift = vec3_make(0, 0, 0);
    bool two_sided = next_byte(&b) & 1;
    put(&t, "camera: {position: [0, 0, 60], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 40}\n"
            "film: {width: 4, height: 4}\n"
            "materials: {grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}}\n"
            "render: {spp: 1, threads: 1}\n"
            "shapes:\n"
            "  - {type: quad, material: grey, vertices: [[-200, -40, -200], [-200, -40, 200], [200, -40, 200], "
            "[200, -40, -200]]}\n");
    /* The shade may stop short of closing the face list (a bottomless
       shade) when a byte says so. */
    int drop = next_byte(&b) % 8 == 0 ? 1 : 0;
    put_shade(&t, &b, &x, faces, n_faces - drop);
    put(&t, "lights:\n  - {name: bulb, radiance: [1, 1, 1], two_sided: %s, vertices: [", two_sided ? "true" : "false");
    const double corner[4][2] = { { -1, -1 }, { 1, -1 }, { 1, 1 }, { -1, 1 } };
    for (int k = 0; k < 4; ++k) {
        struct vec3 p = vec3_add(centre, apply(&tilt, vec3_make(half * corner[k][0], 0, half * corner[k][1])));
        put(&t, k ? ", " : "");
        put_point(&t, &x, p);
    }
    put(&t, "]}\nportals: auto\n");
    if (t.failed) {
        free(t.s);
        return 0;
    }
    struct config cfg;
    struct error err;
    if (!config_load_string(t.s, t.n, "fuzz.yaml", NULL, 0, &cfg, &err)) {
        /* Only the config loader's own refusals (e.g. a light too small to
           be a polygon after rounding): nothing to check here. */
        free(t.s);
        return 0;
    }
    struct scene sc;
    if (!scene_create(&cfg, &sc, &err)) {
        config_free(&cfg);
        free(t.s);
        return 0;
    }
    const struct auto_portal_report *rep = sc.auto_portals ? &sc.auto_portals[0] : NULL;
    if (!rep || !rep->requested) fail("the light's auto portals were not looked for", t.s);
    const struct light *l = &sc.lights[sc.emitters[0].first_light];
    if (!rep->enclosed) {
        /* The fallback: no portal, and a note saying why. */
        if (l->n_portals != 0 || !rep->note[0]) fail("a fallback with portals or without a note", t.s);
    } else {
        /* A closed shade leaves no portal: then no ray may escape. */
        if (l->n_portals != rep->n_portals) fail("the portals are not the ones reported", t.s);
        struct polygon *ports = malloc(sizeof *ports * (size_t)(l->n_portals + 1));
        if (!ports) abort();
        for (int k = 0; k < l->n_portals; ++k)
            polygon_copy(&ports[k], &sc.portals[l->first_portal + k].target->polygon);
        long n_escaped = 0, n_missed = 0;
        struct vec3 miss = vec3_make(0, 0, 0);
        if (!light_side(&sc, rep, ports, l->n_portals, 4096, &n_escaped, &n_missed, &miss)) abort();
        free(ports);
        if (n_missed != 0) {
            char what[900];
            snprintf(what, sizeof what,
                     "%ld of %ld escaping rays crossed no portal, one at (%.17g, %.17g, %.17g) (%d portals, %s)",
                     n_missed, n_escaped, miss.x, miss.y, miss.z, rep->n_portals, rep->note);
            fail(what, t.s);
        }
    }
    scene_destroy(&sc);
    config_free(&cfg);
    free(t.s);
    return 0;
}

#include "scene/portal_finder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/json_write.h"
#include "base/rng.h"
#include "config/config.h"
#include "geometry/convex_hull.h"
#include "geometry/polygon_subtract.h"

/* The seed of the finder's rays (a constant: the portals must not depend
   on render.seed, which a resumed or repeated run may change). */
#define FINDER_SEED 0x706f7274616c73ull
/* Light vertices must lie this far inside every facet of P, relative to
   P's size: well beyond the antishadow's own side test (1e-9). */
#define INSIDE_REL 1e-7
/* A triangle covers a facet when its vertices are within this distance of
   the facet's plane, relative to P's size. */
#define COVER_REL 1e-8
/* Pieces of a facet smaller than this (relative to P's size squared) are
   rounding debris of the subtraction, not openings. */
#define DEBRIS_REL 1e-12
/* Pieces per facet beyond which the greedy merge is skipped. */
#define MERGE_MAX 256

bool emission_sampler_init(struct emission_sampler *es, const struct scene *s, int emitter, struct error *err)
{
    const struct emitter *e = &s->emitters[emitter];
    es->scene = s;
    es->emitter = emitter;
    es->cdf = malloc(sizeof *es->cdf * (size_t)e->n_lights);
    if (!es->cdf) return error_set(err, "out of memory for the emission sampler");
    double sum = 0.0;
    for (int i = 0; i < e->n_lights; ++i) es->cdf[i] = sum += s->lights[e->first_light + i].target.area;
    for (int i = 0; i < e->n_lights; ++i) es->cdf[i] /= sum;
    return true;
}

void emission_sampler_free(struct emission_sampler *es)
{
    free(es->cdf);
    es->cdf = NULL;
}

void emission_sample(const struct emission_sampler *es, const double u[EMISSION_UNIFORMS], struct vec3 *p,
                     struct vec3 *n, struct vec3 *d)
{
    const struct scene *s = es->scene;
    const struct emitter *e = &s->emitters[es->emitter];
    int lo = 0, hi = e->n_lights - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (es->cdf[mid] > u[0]) hi = mid;
        else lo = mid + 1;
    }
    const struct light *l = &s->lights[e->first_light + lo];
    const struct polygon *poly = &l->target.polygon;
    /* A triangle of the fan by area, then a uniform point in it. */
    double r = u[1] * l->target.area, acc = 0.0;
    int k = 1;
    for (; k + 2 < poly->n; ++k) {
        acc += 0.5 * vec3_length(vec3_cross(vec3_sub(poly->v[k], poly->v[0]), vec3_sub(poly->v[k + 1], poly->v[0])));
        if (r < acc) break;
    }
    double su = sqrt(u[2]);
    double b0 = 1.0 - su, b1 = su * (1.0 - u[3]), b2 = su * u[3];
    *p = vec3_add(vec3_add(vec3_scale(poly->v[0], b0), vec3_scale(poly->v[k], b1)), vec3_scale(poly->v[k + 1], b2));
    struct vec3 normal = l->target.normal;
    if (l->two_sided && u[6] < 0.5) normal = vec3_neg(normal);
    /* Cosine-weighted (Malley): a uniform point of the unit disc lifted
       onto the hemisphere. */
    double radius = sqrt(u[4]), phi = 2.0 * M_PI * u[5];
    double x = radius * cos(phi), y = radius * sin(phi), z = sqrt(fmax(0.0, 1.0 - u[4]));
    struct frame f = frame_from_normal(normal);
    *n = normal;
    *d = vec3_normalize(frame_to_world(&f, vec3_make(x, y, z)));
}

/* The distance along d from p (inside P) to P's boundary. */
static double exit_distance(const struct plane *planes, int n, struct vec3 p, struct vec3 d)
{
    double t = INFINITY;
    for (int i = 0; i < n; ++i) {
        double c = vec3_dot(planes[i].normal, d);
        if (c > 0.0) t = fmin(t, fmax(0.0, -plane_distance(&planes[i], p)) / c);
    }
    return t;
}

static void draw_uniforms(struct rng *r, double u[EMISSION_UNIFORMS])
{
    for (int k = 0; k < EMISSION_UNIFORMS; ++k) u[k] = rng_uniform(r);
}

bool portal_finder_coverage(const struct scene *s, int emitter, const struct plane *planes, int n_planes,
                            const struct polygon *portals, int n_portals, long n_rays, uint64_t seed,
                            struct portal_coverage *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    struct emission_sampler es;
    if (!emission_sampler_init(&es, s, emitter, err)) return false;
    struct rng r = rng_seeded(seed, (uint64_t)emitter, 0);
    for (long i = 0; i < n_rays; ++i) {
        double u[EMISSION_UNIFORMS];
        struct vec3 p, n, d;
        draw_uniforms(&r, u);
        emission_sample(&es, u, &p, &n, &d);
        /* A grazing ray's offset origin can land beyond a wall close to
           the light (the step grows as 1 / cos): such a ray tests the
           offset, not the portals, and is not counted. */
        double step = scene_offset_step(s, p, n, d), t_exit = exit_distance(planes, n_planes, p, d) - step;
        struct vec3 o = vec3_madd(p, d, step);
        if (!isfinite(t_exit) || !(t_exit > 0.0)) continue;
        bool on_portal = false;
        for (int k = 0; k < n_portals && !on_portal; ++k) {
            double t;
            on_portal = polygon_intersect_ray(&portals[k], o, d, &t);
        }
        struct hit h;
        /* Blocked: a surface before P's boundary, or on it (a covering
           surface lies in P's facet): the test reaches slightly beyond. */
        double reach = t_exit + scene_offset_height(s, vec3_madd(o, d, t_exit));
        bool blocked = scene_intersect(s, o, d, reach, &h);
        ++out->n_rays;
        out->n_portal += on_portal;
        if (!blocked) {
            ++out->n_escaped;
            out->n_through += on_portal;
            out->n_missed += !on_portal;
        }
    }
    emission_sampler_free(&es);
    out->blocked_fraction = out->n_portal > 0 ? 1.0 - (double)out->n_through / (double)out->n_portal : 0.0;
    out->bound = out->n_escaped > 0 ? 3.0 / (double)out->n_escaped : INFINITY;
    return true;
}

int portal_finder_portals(const struct scene *s, int emitter, const struct polygon **out, int max)
{
    const struct light *l = &s->lights[s->emitters[emitter].first_light];
    int n = 0;
    for (int k = 0; k < l->n_portals && n < max; ++k) out[n++] = &s->portals[l->first_portal + k].target.polygon;
    return n;
}

/* A growing array of polygons. */
struct polys {
    int n, cap;
    struct polygon *p;
};

static bool polys_push(struct polys *ps, const struct polygon *p)
{
    if (ps->n == ps->cap) {
        int cap = ps->cap ? 2 * ps->cap : 16;
        struct polygon *q = realloc(ps->p, sizeof *q * (size_t)cap);
        if (!q) return false;
        ps->p = q;
        ps->cap = cap;
    }
    polygon_copy(&ps->p[ps->n++], p);
    return true;
}

/* The finder's state for one light. */
struct finder {
    struct scene *s;
    const struct config *cfg;
    int emitter;
    struct auto_portal_report *rep;
    struct vec3 *light_pts; /* every vertex of the emitter's lights */
    int n_light_pts;
};

struct candidate {
    int shape;
    double t_min;
};

static int compare_candidates(const void *a, const void *b)
{
    const struct candidate *p = a, *q = b;
    if (p->t_min != q->t_min) return p->t_min < q->t_min ? -1 : 1;
    return p->shape - q->shape;
}

/* The shapes the light's rays meet first, nearest first, without the
   room-sized ones. Returns the count (into *out, owned), -1 on memory. */
static int find_candidates(const struct finder *f, struct candidate **out)
{
    const struct scene *s = f->s;
    const struct config *cfg = f->cfg;
    double *t_min = malloc(sizeof *t_min * (size_t)(cfg->n_shapes > 0 ? cfg->n_shapes : 1));
    struct emission_sampler es;
    struct error err;
    if (!t_min || !emission_sampler_init(&es, s, f->emitter, &err)) {
        free(t_min);
        return -1;
    }
    for (int i = 0; i < cfg->n_shapes; ++i) t_min[i] = INFINITY;
    struct rng r = rng_seeded(FINDER_SEED, (uint64_t)f->emitter, 1);
    for (int i = 0; i < PORTAL_FINDER_RAYS; ++i) {
        double u[EMISSION_UNIFORMS];
        struct vec3 p, n, d;
        draw_uniforms(&r, u);
        emission_sample(&es, u, &p, &n, &d);
        struct hit h;
        int g;
        if (!scene_intersect_geometry(s, scene_offset_origin(s, p, n, d), d, INFINITY, &h, &g)) continue;
        int shape = s->geometries[g].shape;
        if (shape >= 0) t_min[shape] = fmin(t_min[shape], h.t);
    }
    emission_sampler_free(&es);
    struct candidate *c = malloc(sizeof *c * (size_t)(cfg->n_shapes > 0 ? cfg->n_shapes : 1));
    int n = 0;
    for (int i = 0; c && i < cfg->n_shapes; ++i) {
        if (!isfinite(t_min[i])) continue;
        const struct shape_desc *sh = &cfg->shapes[i];
        struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
        for (int v = 0; v < sh->n_vertices; ++v) {
            struct vec3 x = sh->vertices[v];
            lo = vec3_make(fmin(lo.x, x.x), fmin(lo.y, x.y), fmin(lo.z, x.z));
            hi = vec3_make(fmax(hi.x, x.x), fmax(hi.y, x.y), fmax(hi.z, x.z));
        }
        if (vec3_length(vec3_sub(hi, lo)) > PORTAL_FINDER_MAX_SHAPE_FRACTION * s->scale) continue;
        c[n++] = (struct candidate){ i, t_min[i] };
    }
    free(t_min);
    if (!c) return -1;
    qsort(c, (size_t)n, sizeof *c, compare_candidates);
    *out = c;
    return n;
}

/* How the light sits in the hull: the largest plane distance of a light
   vertex over the facets (negative: strictly inside by that much), and
   whether some vertex lies inside or on it. */
static double light_depth(const struct finder *f, const struct convex_hull *h, bool *some_inside)
{
    double worst = -INFINITY;
    *some_inside = false;
    for (int i = 0; i < f->n_light_pts; ++i) {
        double d = -INFINITY;
        for (int k = 0; k < h->n_facets; ++k) d = fmax(d, plane_distance(&h->facets[k].plane, f->light_pts[i]));
        worst = fmax(worst, d);
        if (d <= INSIDE_REL * h->size) *some_inside = true;
    }
    return worst;
}

/* The hull of the first k candidates' vertices, into points (room for
   all of them). */
static bool hull_of(const struct finder *f, const struct candidate *c, int k, struct vec3 *points, int *n_points,
                    struct convex_hull *h, struct error *err)
{
    int n = 0;
    for (int i = 0; i < k; ++i) {
        const struct shape_desc *sh = &f->cfg->shapes[c[i].shape];
        memcpy(points + n, sh->vertices, sizeof *points * (size_t)sh->n_vertices);
        n += sh->n_vertices;
    }
    *n_points = n;
    return convex_hull_build(points, n, h, err);
}

/* Pushes the fan of the convex polygon v[0..n) in chunks of at most
   POLYGON_INPUT_MAX corners. */
static bool push_fan(const struct vec3 *v, int n, struct polys *out)
{
    bool ok = true;
    for (int a = 1; ok && a + 1 < n; a += POLYGON_INPUT_MAX - 2) {
        struct polygon chunk;
        chunk.n = 0;
        chunk.v[chunk.n++] = v[0];
        for (int b = a; b < n && chunk.n < POLYGON_INPUT_MAX; ++b) chunk.v[chunk.n++] = v[b];
        if (chunk.n >= 3) ok = polys_push(out, &chunk);
        if (a + POLYGON_INPUT_MAX - 2 >= n - 1) break;
    }
    return ok;
}

/* An edge of a covering triangle, its ends in lexicographic order, and the
   side of the edge (seen along the facet's normal) its triangle lies on. */
struct cover_edge {
    struct vec3 a, b;
    int side;
};

static int compare_vec3(struct vec3 p, struct vec3 q)
{
    if (p.x != q.x) return p.x < q.x ? -1 : 1;
    if (p.y != q.y) return p.y < q.y ? -1 : 1;
    if (p.z != q.z) return p.z < q.z ? -1 : 1;
    return 0;
}

static int compare_cover_edges(const void *x, const void *y)
{
    const struct cover_edge *p = x, *q = y;
    int c = compare_vec3(p->a, q->a);
    return c ? c : compare_vec3(p->b, q->b);
}

static double orient2(struct vec3 a, struct vec3 b, struct vec3 c)
{
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

/* Where the open part of a facet can be, from the edges of the triangles
   lying in it (tris[sel[0..m)]), in O(m log m), so that the exact
   subtraction only runs there. Writes to *dom the convex region (its
   corners, <= cap) outside which every point of the facet is covered, and
   returns its corner count: 0 when the whole facet is covered, -1 when
   nothing is proven (the whole facet is the region).

   The argument. Seen along the facet's normal (2-D), let S be the
   triangles of positive area, and c(x) the number of them that hold x. An
   edge of S (its ends welded when bit-identical) has L triangles of S on
   its left and R on its right; it is balanced when L = R, free
   otherwise. Edges on the facet's outline are set aside. Along a path in
   the facet's interior that avoids the free edges (and the finitely many
   vertices and crossings), c changes only where the path crosses edges,
   and by the sum of R - L over the edges it crosses there, which is 0: so
   c is constant on every connected part of (facet interior) minus (free
   edges). The points within delta of the outline, delta the least
   distance of a free edge to it (the distance to a convex outline is
   concave, so a segment's is least at an end), form one connected band
   with no free edge in it; one point x0 of that band with c(x0) >= 1,
   off every edge, shows c >= 1 on the band. Then a part where c = 0 (a
   hole) avoids the band, so it is bounded by free edges only and lies in
   their convex hull. With no free edge, the facet is covered. Any
   condition unmet (a vertex beyond the outline, no such x0) proves
   nothing and the caller subtracts over the whole facet. Unwelded or
   T-junctioned meshes only make more edges free: a larger region, never a
   wrong one. */
static int open_region(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                       const int *sel, int m, struct vec3 *dom, int cap)
{
    const struct hull_facet *hf = &h->facets[fi];
    struct frame fr = frame_from_normal(hf->plane.normal);
    double tol = h->tol, eps = 100.0 * h->tol;
    int nf = hf->n;
    struct vec3 *fv = malloc(sizeof *fv * (size_t)nf);
    struct vec3 *ln = malloc(sizeof *ln * (size_t)nf); /* inward 2-D unit normal (x, y) and offset (z) */
    struct cover_edge *e = malloc(sizeof *e * (size_t)(3 * m + 1));
    struct vec3 *free_pts = malloc(sizeof *free_pts * (size_t)(6 * m + 1));
    int *idx = malloc(sizeof *idx * (size_t)(6 * m + 1));
    int result = -1;
    if (!fv || !ln || !e || !free_pts || !idx) goto done;
    struct vec3 c2 = vec3_make(0.0, 0.0, 0.0);
    for (int i = 0; i < nf; ++i) {
        fv[i] = frame_to_local(&fr, points[h->index[hf->first + i]]);
        fv[i].z = 0.0;
        c2 = vec3_madd(c2, fv[i], 1.0 / nf);
    }
    for (int i = 0; i < nf; ++i) {
        struct vec3 a = fv[i], b = fv[(i + 1) % nf];
        double len = hypot(b.x - a.x, b.y - a.y);
        if (!(len > 0.0)) goto done;
        struct vec3 n = vec3_make(-(b.y - a.y) / len, (b.x - a.x) / len, 0.0);
        if (n.x * (c2.x - a.x) + n.y * (c2.y - a.y) < 0.0) n = vec3_neg(n);
        n.z = n.x * a.x + n.y * a.y;
        ln[i] = n;
    }
#define LINE_D(i, p) (ln[i].x * (p).x + ln[i].y * (p).y - ln[i].z)
    int n_e = 0, n_s = 0;
    for (int t = 0; t < m; ++t) {
        struct vec3 q[3];
        for (int v = 0; v < 3; ++v) {
            q[v] = frame_to_local(&fr, tris[sel[t]][v]);
            for (int i = 0; i < nf; ++i)
                if (LINE_D(i, q[v]) < -tol) goto done; /* beyond the outline */
        }
        double area2 = orient2(q[0], q[1], q[2]);
        if (!(fabs(area2) > eps * eps)) continue; /* no area: not in S */
        ++n_s;
        for (int k = 0; k < 3; ++k) {
            struct vec3 a = tris[sel[t]][k], b = tris[sel[t]][(k + 1) % 3];
            struct vec3 qa = q[k], qb = q[(k + 1) % 3];
            bool outline = false;
            for (int i = 0; i < nf && !outline; ++i) outline = fabs(LINE_D(i, qa)) <= tol && fabs(LINE_D(i, qb)) <= tol;
            if (outline) continue;
            /* The triangle is left of a -> b when it winds positively. */
            int side = area2 > 0.0 ? 1 : -1;
            if (compare_vec3(a, b) > 0) {
                struct vec3 tmp = a;
                a = b, b = tmp, side = -side;
            }
            e[n_e++] = (struct cover_edge){ a, b, side };
        }
    }
    qsort(e, (size_t)n_e, sizeof *e, compare_cover_edges);
    int n_free = 0;
    double delta = INFINITY;
    for (int i = 0; i < n_e;) {
        int j = i, sum = 0;
        for (; j < n_e && compare_cover_edges(&e[i], &e[j]) == 0; ++j) sum += e[j].side;
        if (sum != 0) {
            free_pts[n_free++] = e[i].a;
            free_pts[n_free++] = e[i].b;
            for (int k = 0; k < 2; ++k) {
                struct vec3 q = frame_to_local(&fr, e[i].a);
                if (k) q = frame_to_local(&fr, e[i].b);
                for (int l = 0; l < nf; ++l) delta = fmin(delta, LINE_D(l, q));
            }
        }
        i = j;
    }
    if (n_s == 0 || !(delta > 4.0 * eps)) goto done;
    /* x0: from a corner of the facet towards its centre, closer to the
       outline than delta, off every edge of S. */
    bool proven = false;
    for (int v = 0; v < nf && !proven; ++v) {
        double reach = fmax(LINE_D(v, c2), LINE_D((v + nf - 1) % nf, c2));
        if (!(reach > 0.0)) continue;
        for (double frac = 0.5; frac > 0.01 && !proven; frac *= 0.37) {
            double t = fmin(0.5, frac * fmin(delta, reach) / reach);
            struct vec3 x0 = vec3_add(fv[v], vec3_scale(vec3_sub(c2, fv[v]), t));
            double dist = INFINITY;
            for (int i = 0; i < nf; ++i) dist = fmin(dist, LINE_D(i, x0));
            if (!(dist > eps && dist < delta)) continue;
            int count = 0;
            bool clear = true;
            for (int tt = 0; tt < m && clear; ++tt) {
                struct vec3 q[3];
                for (int k = 0; k < 3; ++k) q[k] = frame_to_local(&fr, tris[sel[tt]][k]);
                double area2 = orient2(q[0], q[1], q[2]);
                if (!(fabs(area2) > eps * eps)) continue;
                int inside = 0;
                for (int k = 0; k < 3 && clear; ++k) {
                    struct vec3 a = q[k], b = q[(k + 1) % 3];
                    double len = hypot(b.x - a.x, b.y - a.y);
                    double o = orient2(a, b, x0) / len * (area2 > 0.0 ? 1.0 : -1.0);
                    if (fabs(o) <= eps) clear = false; /* on an edge's line: try another x0 */
                    inside += o > 0.0;
                }
                count += inside == 3;
            }
            proven = clear && count >= 1;
        }
    }
    if (!proven) goto done;
    if (n_free == 0) {
        result = 0;
        goto done;
    }
    int c = convex_hull_2d(free_pts, n_free, hf->plane.normal, tol, idx);
    if (c < 3 || c > cap) goto done; /* (also on memory: proves nothing) */
    for (int i = 0; i < c; ++i) dom[i] = free_pts[idx[i]];
    result = c;
#undef LINE_D
done:
    free(fv);
    free(ln);
    free(e);
    free(free_pts);
    free(idx);
    return result;
}

/* One facet's uncovered part: its chunks minus every covering triangle,
   over the region open_region leaves (the whole facet when it proves
   nothing). */
static bool uncovered_part(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                           int n_tris, struct polys *out)
{
    const struct hull_facet *hf = &h->facets[fi];
    struct plane pl = hf->plane;
    double cover = COVER_REL * h->size, debris = DEBRIS_REL * h->size * h->size;
    struct polys cur = { 0, 0, NULL }, next = { 0, 0, NULL };
    int *sel = malloc(sizeof *sel * (size_t)(n_tris > 0 ? n_tris : 1));
    /* Room for the facet's corners or the free edges' ends (6 per triangle). */
    size_t n_fv = (size_t)hf->n + 6 * (size_t)n_tris + 1;
    struct vec3 *fv = malloc(sizeof *fv * n_fv);
    if (!sel || !fv) {
        free(sel);
        free(fv);
        return false;
    }
    int n_sel = 0;
    for (int t = 0; t < n_tris; ++t) {
        bool in_plane = true;
        for (int v = 0; v < 3 && in_plane; ++v) in_plane = fabs(plane_distance(&pl, tris[t][v])) <= cover;
        if (in_plane) sel[n_sel++] = t;
    }
    for (int i = 0; i < hf->n; ++i) fv[i] = points[h->index[hf->first + i]];
    bool ok = true;
    int n_dom = n_sel > 0 ? open_region(h, points, fi, tris, sel, n_sel, fv, (int)n_fv) : -1;
    if (n_dom < 0) ok = push_fan(fv, hf->n, &cur);
    else if (n_dom >= 3) ok = push_fan(fv, n_dom, &cur);
    free(fv);
    for (int s = 0; ok && s < n_sel && cur.n > 0; ++s) {
        const struct vec3 *tri = tris[sel[s]];
        /* A piece whose box the triangle's box (grown by the cover
           distance) misses keeps whole: what the subtraction would return,
           at the cost of a box test (a finely meshed shade puts thousands
           of triangles in one facet). */
        struct vec3 tlo = tri[0], thi = tri[0];
        for (int v = 1; v < 3; ++v) {
            tlo = vec3_make(fmin(tlo.x, tri[v].x), fmin(tlo.y, tri[v].y), fmin(tlo.z, tri[v].z));
            thi = vec3_make(fmax(thi.x, tri[v].x), fmax(thi.y, tri[v].y), fmax(thi.z, tri[v].z));
        }
        tlo = vec3_sub(tlo, vec3_make(cover, cover, cover));
        thi = vec3_add(thi, vec3_make(cover, cover, cover));
        next.n = 0;
        for (int k = 0; ok && k < cur.n; ++k) {
            struct polygon pieces[3];
            bool apart = true;
            for (int v = 0; v < cur.p[k].n && apart; ++v) {
                struct vec3 x = cur.p[k].v[v];
                apart = !(x.x >= tlo.x && x.x <= thi.x && x.y >= tlo.y && x.y <= thi.y && x.z >= tlo.z && x.z <= thi.z);
            }
            if (apart) {
                struct vec3 plo = cur.p[k].v[0], phi = plo;
                for (int v = 1; v < cur.p[k].n; ++v) {
                    struct vec3 x = cur.p[k].v[v];
                    plo = vec3_make(fmin(plo.x, x.x), fmin(plo.y, x.y), fmin(plo.z, x.z));
                    phi = vec3_make(fmax(phi.x, x.x), fmax(phi.y, x.y), fmax(phi.z, x.z));
                }
                apart =
                    plo.x > thi.x || plo.y > thi.y || plo.z > thi.z || phi.x < tlo.x || phi.y < tlo.y || phi.z < tlo.z;
            }
            if (apart) {
                ok = polys_push(&next, &cur.p[k]);
                continue;
            }
            if (cur.p[k].n > POLYGON_MAX - 3) {
                ok = polys_push(&next, &cur.p[k]);
                continue;
            }
            int m = polygon_subtract_triangle(&cur.p[k], pl.normal, tri, debris, pieces);
            for (int j = 0; ok && j < m; ++j) ok = polys_push(&next, &pieces[j]);
        }
        struct polys tmp = cur;
        cur = next;
        next = tmp;
    }
    /* Greedy merge of pieces whose union is convex. */
    for (bool merged = ok && cur.n <= MERGE_MAX; merged;) {
        merged = false;
        for (int i = 0; i < cur.n && !merged; ++i)
            for (int j = i + 1; j < cur.n && !merged; ++j) {
                struct polygon m;
                if (polygon_merge_convex(&cur.p[i], &cur.p[j], pl.normal, h->tol, 1e-9, POLYGON_INPUT_MAX, &m)) {
                    polygon_copy(&cur.p[i], &m);
                    polygon_copy(&cur.p[j], &cur.p[cur.n - 1]);
                    --cur.n;
                    merged = true;
                }
            }
    }
    for (int k = 0; ok && k < cur.n; ++k) ok = polys_push(out, &cur.p[k]);
    free(sel);
    free(cur.p);
    free(next.p);
    return ok;
}

/* The scene's shape triangles that touch the box lo..hi. */
static int gather_triangles(const struct config *cfg, struct vec3 lo, struct vec3 hi, struct vec3 (**out)[3])
{
    size_t cap = 0;
    for (int i = 0; i < cfg->n_shapes; ++i)
        cap += (size_t)cfg->shapes[i].n_triangles + 2 * (size_t)cfg->shapes[i].n_quads;
    struct vec3(*t)[3] = malloc(sizeof *t * (cap > 0 ? cap : 1));
    if (!t) return -1;
    int n = 0;
    for (int i = 0; i < cfg->n_shapes; ++i) {
        const struct shape_desc *sh = &cfg->shapes[i];
        for (int f = 0; f < sh->n_triangles + 2 * sh->n_quads; ++f) {
            struct vec3 v[3];
            if (f < sh->n_triangles) {
                for (int k = 0; k < 3; ++k) v[k] = sh->vertices[sh->triangles[f][k]];
            } else {
                const int *q = sh->quads[(f - sh->n_triangles) / 2];
                int second = (f - sh->n_triangles) % 2;
                v[0] = sh->vertices[q[0]];
                v[1] = sh->vertices[q[second ? 2 : 1]];
                v[2] = sh->vertices[q[second ? 3 : 2]];
            }
            bool out_box = false;
            out_box = out_box || (v[0].x < lo.x && v[1].x < lo.x && v[2].x < lo.x);
            out_box = out_box || (v[0].y < lo.y && v[1].y < lo.y && v[2].y < lo.y);
            out_box = out_box || (v[0].z < lo.z && v[1].z < lo.z && v[2].z < lo.z);
            out_box = out_box || (v[0].x > hi.x && v[1].x > hi.x && v[2].x > hi.x);
            out_box = out_box || (v[0].y > hi.y && v[1].y > hi.y && v[2].y > hi.y);
            out_box = out_box || (v[0].z > hi.z && v[1].z > hi.z && v[2].z > hi.z);
            if (out_box) continue;
            for (int k = 0; k < 3; ++k) t[n][k] = v[k];
            ++n;
        }
    }
    *out = t;
    return n;
}

/* Depths, relative to P's size, tried for the covering layer of a facet
   that no triangle lying in it covers (layer_covers), shallowest first. */
static const double LAYER_REL[] = { 1e-6, 1e-5, 1e-4, 1e-3, 3e-3, 1e-2 };

/* A triangle of a covering layer clipped to the layer's depth. */
struct layer_poly {
    int n;
    struct vec3 v[4];
};

/* Whether the surfaces just under facet fi cover it: no unblocked segment
   from the light leaves P through it. For a shade whose wall lies a little
   inside its hull (float vertices, a waist, non-planar quads, a rim
   standing proud of the wall), where no triangle lies in the facet itself.

   The argument (the margin d tan(theta_max), made exact). Seen
   along the facet's outward normal, let depth be the distance under the
   facet's plane, h > 0 the least depth of the light (of its vertices: it
   is in their convex hull) and d < h a layer depth; d' just above d. A
   segment from a light point l that leaves P at x on the facet runs,
   between depth d' and the plane, over the points x + t (f - x), t in
   [0, d' / h_l], f the foot of l on the plane: all in G, the convex hull
   of the facet's corners v and of v + (d' / h) (f - v) over the feet of
   the light's vertices (the facet grown towards the light's feet only).
   Let S be the triangles over G with no vertex above the plane, clipped
   to depth <= d (the clipped crossings computed from the edge's ends in
   a fixed order, so that welded neighbours still share their edges). An
   edge of S is odd when an odd number of pieces of S have it (ends
   welded when bit-identical). Conditions:
     (a) no odd edge below the plane meets the interior of G;
     (b) no odd edge lying in the plane enters the facet's interior;
     (c) at one point x0 of the facet off every edge of S, an odd number
         of pieces of S lie over x0.
   Then by (a) S has no mod-2 boundary where a path over the interior of
   G from depth d' up to x can meet it, so sweeping the segment's part
   (lower end at depth d', where S is not; upper end fixed at x) to the
   vertical segment at x keeps the parity of its crossings with S; the
   vertical one crosses S c(x) times, c(x) the pieces over x; by (a) and
   (b) no odd edge separates two points of the facet's interior, so c mod
   2 is the same all over it, and by (c) it is odd. Every such segment
   crosses S: it is blocked (every surface is opaque), and the facet needs
   no portal. A second layer within d (a shade's inner wall) makes c even
   and proves nothing at that d; the depths of LAYER_REL are tried in
   turn, each a separate proof. Missing, unwelded or T-junctioned
   triangles only make odd edges: a facet not proven stays open. The
   tests "interior" and "off every edge" use tolerances of P's size times
   1e-9 (tol) and 1e-7 (eps), as the rest of the finder does. */
static bool layer_covers(const struct finder *f, const struct convex_hull *h, const struct vec3 *points, int fi,
                         const struct vec3 (*tris)[3], int n_tris)
{
    const struct hull_facet *hf = &h->facets[fi];
    const struct plane *pl = &hf->plane;
    struct frame fr = frame_from_normal(pl->normal);
    double tol = h->tol, eps = 100.0 * h->tol;
    double h_min = INFINITY;
    for (int i = 0; i < f->n_light_pts; ++i) h_min = fmin(h_min, -plane_distance(pl, f->light_pts[i]));
    if (!(h_min > 0.0)) return false;
    int nf = hf->n, n_g_cap = nf * (f->n_light_pts + 1);
    struct vec3 *gp = malloc(sizeof *gp * (size_t)n_g_cap);
    int *gi = malloc(sizeof *gi * (size_t)n_g_cap);
    struct vec3 *ln = malloc(sizeof *ln * (size_t)n_g_cap);
    struct cover_edge *e = malloc(sizeof *e * (size_t)(3 * n_tris + 1));
    struct layer_poly *sp = malloc(sizeof *sp * (size_t)(n_tris + 1));
    struct vec3 *fl = malloc(sizeof *fl * (size_t)nf); /* the facet's inward 2-D edge lines */
    bool fl_ok = fl != NULL;
    for (int i = 0; fl_ok && i < nf; ++i) {
        struct vec3 a = frame_to_local(&fr, points[h->index[hf->first + i]]);
        struct vec3 b = frame_to_local(&fr, points[h->index[hf->first + (i + 1) % nf]]);
        struct vec3 m = frame_to_local(&fr, points[h->index[hf->first + (i + 2) % nf]]);
        double len = hypot(b.x - a.x, b.y - a.y);
        fl_ok = len > 0.0;
        struct vec3 nrm = vec3_make(-(b.y - a.y) / len, (b.x - a.x) / len, 0.0);
        if (nrm.x * (m.x - a.x) + nrm.y * (m.y - a.y) < 0.0) nrm = vec3_neg(nrm);
        nrm.z = nrm.x * a.x + nrm.y * a.y;
        fl[i] = nrm;
    }
#define FL_D(i, p) (fl[i].x * (p).x + fl[i].y * (p).y - fl[i].z)
    /* The corners of the light's feet on the plane (their 2-D hull). */
    struct vec3 *feet = malloc(sizeof *feet * (size_t)(f->n_light_pts + 1));
    int *fi2 = malloc(sizeof *fi2 * (size_t)(f->n_light_pts + 1)), n_feet = 0;
    if (feet && fi2) {
        for (int i = 0; i < f->n_light_pts; ++i)
            feet[i] = vec3_madd(f->light_pts[i], pl->normal, -plane_distance(pl, f->light_pts[i]));
        int nh = convex_hull_2d(feet, f->n_light_pts, pl->normal, 0.0, fi2);
        if (nh >= 3) {
            struct vec3 tmp[POLYGON_MAX];
            if (nh <= POLYGON_MAX) {
                for (int i = 0; i < nh; ++i) tmp[i] = feet[fi2[i]];
                for (int i = 0; i < nh; ++i) feet[i] = tmp[i];
                n_feet = nh;
            } else {
                n_feet = f->n_light_pts;
            }
        } else {
            n_feet = f->n_light_pts; /* a light seen edge-on: every foot */
        }
    }
    free(fi2);
    int *pre = malloc(sizeof *pre * (size_t)(n_tris + 1)), n_pre = 0;
    bool covered = false;
    /* The triangles within the deepest layer tried, once. */
    double d_last = fmin(LAYER_REL[sizeof LAYER_REL / sizeof LAYER_REL[0] - 1] * h->size, 0.5 * h_min);
    for (int t = 0; pre && t < n_tris; ++t) {
        double dmin = INFINITY;
        for (int k = 0; k < 3; ++k) dmin = fmin(dmin, -plane_distance(pl, tris[t][k]));
        if (dmin >= -tol && dmin <= d_last) pre[n_pre++] = t;
    }
    for (size_t li = 0; gp && gi && ln && e && sp && fl_ok && pre && feet && n_feet > 0 &&
                        li < sizeof LAYER_REL / sizeof LAYER_REL[0] && !covered;
         ++li) {
        double d = LAYER_REL[li] * h->size;
        if (!(d < 0.5 * h_min)) break;
        double dp = d + 2.0 * tol, tau = dp / h_min;
        /* G, in the facet's 2-D frame. */
        int n_g = 0;
        for (int v = 0; v < nf; ++v) {
            struct vec3 x = points[h->index[hf->first + v]];
            gp[n_g++] = x;
            for (int i = 0; i < n_feet; ++i) gp[n_g++] = vec3_add(x, vec3_scale(vec3_sub(feet[i], x), tau));
        }
        int c = convex_hull_2d(gp, n_g, pl->normal, 0.0, gi);
        if (c < 3) break;
        struct vec3 gc = vec3_make(0.0, 0.0, 0.0), g2[POLYGON_MAX];
        if (c > POLYGON_MAX) break;
        for (int i = 0; i < c; ++i) {
            g2[i] = frame_to_local(&fr, gp[gi[i]]);
            gc = vec3_add(gc, vec3_scale(g2[i], 1.0 / c));
        }
        bool okg = true;
        for (int i = 0; i < c && okg; ++i) {
            struct vec3 a = g2[i], b = g2[(i + 1) % c];
            double len = hypot(b.x - a.x, b.y - a.y);
            okg = len > 0.0;
            struct vec3 nrm = vec3_make(-(b.y - a.y) / len, (b.x - a.x) / len, 0.0);
            if (nrm.x * (gc.x - a.x) + nrm.y * (gc.y - a.y) < 0.0) nrm = vec3_neg(nrm);
            nrm.z = nrm.x * a.x + nrm.y * a.y;
            ln[i] = nrm; /* inward: >= 0 inside G */
        }
        if (!okg) break;
#define G_D(i, p) (ln[i].x * (p).x + ln[i].y * (p).y - ln[i].z)
        /* S: the triangles over G clipped to depth <= d (a triangle with a
           vertex above the plane is left out; one wholly deeper too). */
        int n_s = 0, n_e = 0;
        for (int pi = 0; pi < n_pre; ++pi) {
            int t = pre[pi];
            struct vec3 q[3];
            double dep[3];
            for (int k = 0; k < 3; ++k) {
                q[k] = frame_to_local(&fr, tris[t][k]);
                dep[k] = -plane_distance(pl, tris[t][k]);
            }
            bool outside = false;
            for (int i = 0; i < c && !outside; ++i)
                outside = G_D(i, q[0]) < -eps && G_D(i, q[1]) < -eps && G_D(i, q[2]) < -eps;
            if (outside || fmin(dep[0], fmin(dep[1], dep[2])) > d || fmin(dep[0], fmin(dep[1], dep[2])) < -tol)
                continue;
            struct layer_poly *lp = &sp[n_s];
            lp->n = 0;
            for (int k = 0; k < 3; ++k) {
                int k1 = (k + 1) % 3;
                if (dep[k] <= d) lp->v[lp->n++] = tris[t][k];
                if ((dep[k] <= d) != (dep[k1] <= d)) {
                    /* The crossing, from the edge's ends in a fixed order,
                       so that both triangles of an edge get the same bits. */
                    int lo = compare_vec3(tris[t][k], tris[t][k1]) < 0 ? k : k1, hi2 = lo == k ? k1 : k;
                    double w = (d - dep[lo]) / (dep[hi2] - dep[lo]);
                    lp->v[lp->n++] = vec3_add(tris[t][lo], vec3_scale(vec3_sub(tris[t][hi2], tris[t][lo]), w));
                }
            }
            if (lp->n >= 3) ++n_s;
        }
        for (int si = 0; si < n_s; ++si) {
            const struct layer_poly *lp = &sp[si];
            for (int k = 0; k < lp->n; ++k) {
                struct vec3 a = lp->v[k], b = lp->v[(k + 1) % lp->n];
                if (compare_vec3(a, b) > 0) {
                    struct vec3 tmp = a;
                    a = b, b = tmp;
                }
                e[n_e++] = (struct cover_edge){ a, b, 0 };
            }
        }
        qsort(e, (size_t)n_e, sizeof *e, compare_cover_edges);
        /* Odd edges: one below the plane must not meet G; one in the plane
           (within tol) must not enter the facet's interior. */
        bool odd_bad = false;
        for (int i = 0; i < n_e && !odd_bad;) {
            int j = i;
            while (j < n_e && compare_cover_edges(&e[i], &e[j]) == 0) ++j;
            if ((j - i) % 2) {
                struct vec3 a = frame_to_local(&fr, e[i].a), b = frame_to_local(&fr, e[i].b);
                bool in_plane = -plane_distance(pl, e[i].a) <= tol && -plane_distance(pl, e[i].b) <= tol;
                if (in_plane) {
                    bool harmless = false;
                    for (int k = 0; k < nf && !harmless; ++k) harmless = FL_D(k, a) <= eps && FL_D(k, b) <= eps;
                    odd_bad = !harmless;
                } else {
                    /* Its part deeper than G's boundary by more than tol:
                       what the paths below the plane can meet. */
                    double t0 = 0.0, t1 = 1.0;
                    for (int k = 0; k < c && t0 <= t1; ++k) {
                        double da = G_D(k, a) - tol, db = G_D(k, b) - tol;
                        if (da < 0.0 && db < 0.0) t1 = -1.0;
                        else if (da < 0.0) t0 = fmax(t0, da / (da - db));
                        else if (db < 0.0) t1 = fmin(t1, da / (da - db));
                    }
                    odd_bad = t0 < t1;
                }
            }
            i = j;
        }
        if (odd_bad || n_s == 0) continue; /* a deeper layer may close it */
        /* Parity at a point of the facet off every edge of S. */
        struct vec3 fc = vec3_make(0.0, 0.0, 0.0);
        for (int v = 0; v < nf; ++v) fc = vec3_add(fc, vec3_scale(points[h->index[hf->first + v]], 1.0 / nf));
        fc = frame_to_local(&fr, fc);
        for (int attempt = 0; attempt < 8 && !covered; ++attempt) {
            struct vec3 corner = frame_to_local(&fr, points[h->index[hf->first + attempt % nf]]);
            struct vec3 x0 = vec3_add(fc, vec3_scale(vec3_sub(corner, fc), 0.0125 * attempt + 0.0371 * (attempt % 3)));
            int count = 0;
            bool clear = true;
            for (int si = 0; si < n_s && clear; ++si) {
                const struct layer_poly *lp = &sp[si];
                struct vec3 q[4];
                for (int k = 0; k < lp->n; ++k) q[k] = frame_to_local(&fr, lp->v[k]);
                double area2 = 0.0;
                for (int k = 1; k + 1 < lp->n; ++k) area2 += orient2(q[0], q[k], q[k + 1]);
                /* A piece seen edge-on (a wall square to the facet) is over
                   no point off its edges, and x0 must be off them too. */
                bool flat = !(fabs(area2) > eps * eps);
                double sign = area2 > 0.0 ? 1.0 : -1.0;
                int inside = 0;
                for (int k = 0; k < lp->n && clear; ++k) {
                    struct vec3 a = q[k], b = q[(k + 1) % lp->n];
                    double len = hypot(b.x - a.x, b.y - a.y);
                    if (!(len > 0.0)) {
                        clear = hypot(x0.x - a.x, x0.y - a.y) > eps;
                        continue;
                    }
                    double o = orient2(a, b, x0) / len * sign;
                    if (fabs(o) <= eps) {
                        double s0 = (x0.x - a.x) * (b.x - a.x) + (x0.y - a.y) * (b.y - a.y);
                        if (s0 >= -eps * len && s0 <= len * len + eps * len) clear = false;
                    }
                    inside += o > eps;
                }
                count += !flat && inside == lp->n;
            }
            if (clear) {
                covered = count % 2 == 1;
                break; /* the parity is the same all over the facet: one clear point decides */
            }
        }
#undef FL_D
#undef G_D
    }
    free(gp);
    free(gi);
    free(ln);
    free(e);
    free(sp);
    free(fl);
    free(pre);
    free(feet);
    return covered;
}

/* The portals of P: every facet's uncovered part, clipped for a one-sided
   polygon light to the half-space it emits into (nothing it emits crosses
   the rest), split to at most POLYGON_INPUT_MAX corners. */
static bool portals_of_hull(const struct finder *f, const struct convex_hull *h, const struct vec3 *points,
                            struct polys *out, double *open_area, double *hull_area, bool *bad)
{
    *bad = false;
    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    for (int i = 0; i < h->n_index; ++i) {
        struct vec3 x = points[h->index[i]];
        lo = vec3_make(fmin(lo.x, x.x), fmin(lo.y, x.y), fmin(lo.z, x.z));
        hi = vec3_make(fmax(hi.x, x.x), fmax(hi.y, x.y), fmax(hi.z, x.z));
    }
    double g = COVER_REL * h->size * 10.0;
    lo = vec3_sub(lo, vec3_make(g, g, g));
    hi = vec3_add(hi, vec3_make(g, g, g));
    struct vec3(*tris)[3] = NULL;
    int n_tris = gather_triangles(f->cfg, lo, hi, &tris);
    if (n_tris < 0) return false;
    struct polys open = { 0, 0, NULL };
    bool ok = true;
    *hull_area = 0.0;
    for (int fi = 0; ok && fi < h->n_facets; ++fi) {
        const struct hull_facet *hf = &h->facets[fi];
        struct vec3 a = points[h->index[hf->first]];
        for (int k = 1; k + 1 < hf->n; ++k)
            *hull_area += 0.5 * vec3_length(vec3_cross(vec3_sub(points[h->index[hf->first + k]], a),
                                                       vec3_sub(points[h->index[hf->first + k + 1]], a)));
        int before = open.n;
        ok = uncovered_part(h, points, fi, (const struct vec3(*)[3])tris, n_tris, &open);
        if (ok && open.n > before && layer_covers(f, h, points, fi, (const struct vec3(*)[3])tris, n_tris))
            open.n = before;
    }
    free(tris);
    *open_area = 0.0;
    const struct emitter *e = &f->s->emitters[f->emitter];
    const struct light *l0 = &f->s->lights[e->first_light];
    bool clip = e->n_lights == 1 && !l0->two_sided;
    struct plane front = { l0->target.normal, vec3_dot(l0->target.normal, l0->target.polygon.v[0]) };
    for (int k = 0; ok && k < open.n; ++k) {
        struct polygon piece;
        *open_area += polygon_area(&open.p[k]);
        if (clip) {
            if (polygon_clip_plane(&open.p[k], &front, &piece) < 3) continue;
        } else {
            polygon_copy(&piece, &open.p[k]);
        }
        if (!(polygon_area(&piece) > DEBRIS_REL * h->size * h->size)) continue;
        /* Fans of at most POLYGON_INPUT_MAX corners. A chunk that is no
           valid portal (collinear corners or rounding left it not strictly
           convex) goes in as its fan's triangles; a triangle of no area
           (polygon_check: below 1e-10 of its diameter squared) covers no
           ray and is left out; any other defect would leave a gap, so the
           hull is refused (*bad). Nothing is dropped silently. */
        for (int a = 1; ok && a + 1 < piece.n; a += POLYGON_INPUT_MAX - 2) {
            struct polygon chunk;
            chunk.n = 0;
            chunk.v[chunk.n++] = piece.v[0];
            for (int b = a; b < piece.n && chunk.n < POLYGON_INPUT_MAX; ++b) chunk.v[chunk.n++] = piece.v[b];
            if (chunk.n >= 3 && polygon_check(&chunk) == POLYGON_DEFECT_NONE) {
                ok = polys_push(out, &chunk);
            } else {
                for (int b = 1; ok && b + 1 < chunk.n; ++b) {
                    struct polygon tri = { 3, { chunk.v[0], chunk.v[b], chunk.v[b + 1] } };
                    enum polygon_defect defect = polygon_check(&tri);
                    if (defect == POLYGON_DEFECT_NONE) ok = polys_push(out, &tri);
                    else if (defect != POLYGON_DEFECT_DEGENERATE) *bad = true;
                }
            }
            if (a + POLYGON_INPUT_MAX - 2 >= piece.n - 1) break;
        }
    }
    free(open.p);
    return ok;
}

/* Decides and applies the portals of one light. False only on memory. */
static bool find_for_light(struct finder *f, struct error *err)
{
    struct auto_portal_report *rep = f->rep;
    const char *name = f->cfg->lights[f->emitter].name;
    struct candidate *c = NULL;
    int n_c = find_candidates(f, &c);
    if (n_c < 0) return error_set(err, "out of memory finding the portals of light \"%s\"", name);
    size_t n_pts = 0;
    for (int i = 0; i < n_c; ++i) n_pts += (size_t)f->cfg->shapes[c[i].shape].n_vertices;
    struct vec3 *points = malloc(sizeof *points * (n_pts > 0 ? n_pts : 1));
    if (!points) {
        free(c);
        return error_set(err, "out of memory finding the portals of light \"%s\"", name);
    }
    struct convex_hull h = { 0 };
    int k = 0, n_points = 0;
    bool found = false, touches = false;
    for (k = 1; k <= n_c && !found; ++k) {
        struct error herr;
        if (!hull_of(f, c, k, points, &n_points, &h, &herr)) continue;
        bool some;
        double depth = light_depth(f, &h, &some);
        found = depth < -INSIDE_REL * h.size;
        touches = !found && some;
        if (!found) convex_hull_free(&h);
    }
    --k;
    if (!found) {
        if (touches) {
            rep->warn = true;
            snprintf(rep->note, sizeof rep->note,
                     "light \"%s\" touches or pierces the hull of the %d shape(s) around it: no portals "
                     "(sampled as `light` samples it)",
                     name, n_c);
        } else {
            snprintf(rep->note, sizeof rep->note, "light \"%s\": no shape encloses it: no portals", name);
        }
        free(points);
        free(c);
        return true;
    }
    struct polys ports = { 0, 0, NULL };
    double open_area = 0.0, hull_area = 0.0;
    bool bad = false;
    bool ok = portals_of_hull(f, &h, points, &ports, &open_area, &hull_area, &bad);
    /* The tightest of the hulls that add the next nearby shapes (met
       within twice the distance of the last one taken): the least open
       area. Each is complete; more shapes only make P fit them better. */
    double reach = 2.0 * c[k - 1].t_min;
    for (int more = k + 1; ok && more <= n_c && more <= k + PORTAL_FINDER_MAX_EXTRA && c[more - 1].t_min <= reach;
         ++more) {
        struct convex_hull h2;
        struct error herr;
        int n2;
        struct vec3 *points2 = malloc(sizeof *points2 * (n_pts > 0 ? n_pts : 1));
        if (!points2) {
            ok = false;
            break;
        }
        bool some;
        if (!hull_of(f, c, more, points2, &n2, &h2, &herr)) {
            free(points2);
            continue;
        }
        if (!(light_depth(f, &h2, &some) < -INSIDE_REL * h2.size)) {
            convex_hull_free(&h2);
            free(points2);
            continue;
        }
        struct polys ports2 = { 0, 0, NULL };
        double open2 = 0.0, hull2 = 0.0;
        bool bad2 = false;
        ok = portals_of_hull(f, &h2, points2, &ports2, &open2, &hull2, &bad2);
        if (ok && (bad || (!bad2 && open2 < open_area))) {
            convex_hull_free(&h);
            free(points);
            free(ports.p);
            h = h2, points = points2, ports = ports2, open_area = open2, hull_area = hull2, k = more, bad = bad2;
        } else {
            convex_hull_free(&h2);
            free(points2);
            free(ports2.p);
        }
    }
    /* Then the chosen shapes without one of them, while that leaves less
       open area and still holds the light strictly inside: a stand or a
       socket met first by the light's rays stretches the hull well beyond
       the shade (each such hull is complete as well). */
    struct candidate *set = ok ? malloc(sizeof *set * (size_t)n_c) : NULL,
                     *sub = ok ? malloc(sizeof *sub * (size_t)n_c) : NULL;
    if (ok && (!set || !sub)) ok = false;
    int n_set = k;
    if (ok) {
        /* The shapes of the hull chosen above: the first k candidates. */
        for (int i = 0; i < k; ++i) set[i] = c[i];
    }
    for (bool improved = ok; improved && n_set > 1;) {
        improved = false;
        for (int j = 0; ok && j < n_set && !improved; ++j) {
            int n_sub = 0;
            for (int i = 0; i < n_set; ++i)
                if (i != j) sub[n_sub++] = set[i];
            struct convex_hull h2;
            struct error herr;
            int n2;
            struct vec3 *points2 = malloc(sizeof *points2 * (n_pts > 0 ? n_pts : 1));
            if (!points2) {
                ok = false;
                break;
            }
            bool some;
            if (!hull_of(f, sub, n_sub, points2, &n2, &h2, &herr)) {
                free(points2);
                continue;
            }
            if (!(light_depth(f, &h2, &some) < -INSIDE_REL * h2.size)) {
                convex_hull_free(&h2);
                free(points2);
                continue;
            }
            struct polys ports2 = { 0, 0, NULL };
            double open2 = 0.0, hull2 = 0.0;
            bool bad2 = false;
            ok = portals_of_hull(f, &h2, points2, &ports2, &open2, &hull2, &bad2);
            if (ok && !bad2 && (bad || open2 < open_area)) {
                convex_hull_free(&h);
                free(points);
                free(ports.p);
                h = h2, points = points2, ports = ports2, open_area = open2, hull_area = hull2, bad = bad2;
                for (int i = 0; i < n_sub; ++i) set[i] = sub[i];
                n_set = k = n_sub;
                improved = true;
            } else {
                convex_hull_free(&h2);
                free(points2);
                free(ports2.p);
            }
        }
    }
    free(set);
    free(sub);
    if (!ok) {
        convex_hull_free(&h);
        free(points);
        free(c);
        free(ports.p);
        return error_set(err, "out of memory finding the portals of light \"%s\"", name);
    }
    rep->hull_area = hull_area;
    if (open_area > PORTAL_FINDER_MAX_OPEN_FRACTION * hull_area) {
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": the hull of the %d nearest shape(s) around it is %.0f%% open: no portals", name, k,
                 100.0 * open_area / hull_area);
    } else if (bad) {
        rep->warn = true;
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": an opening of the hull of the %d nearest shape(s) around it is no valid polygon: "
                 "no portals (sampled as `light` samples it)",
                 name, k);
    } else if (ports.n > PORTAL_FINDER_MAX_PORTALS) {
        rep->warn = true;
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": the hull of the %d nearest shape(s) around it leaves %d open pieces (more than %d): "
                 "no portals (sampled as `light` samples it)",
                 name, k, ports.n, PORTAL_FINDER_MAX_PORTALS);
    } else {
        struct error aerr = { { 0 } };
        if (!scene_add_portals(f->s, f->emitter, ports.p, ports.n, &aerr)) {
            rep->warn = true;
            snprintf(rep->note, sizeof rep->note, "light \"%s\": %.300s: no portals (sampled as `light` samples it)",
                     name, aerr.message);
        } else {
            rep->enclosed = true;
            rep->n_portals = ports.n;
            for (int i = 0; i < ports.n; ++i) rep->area += polygon_area(&ports.p[i]);
            rep->n_planes = h.n_facets;
            rep->planes = malloc(sizeof *rep->planes * (size_t)h.n_facets);
            ok = rep->planes != NULL;
            for (int i = 0; ok && i < h.n_facets; ++i) rep->planes[i] = h.facets[i].plane;
            rep->box_lo = vec3_make(INFINITY, INFINITY, INFINITY);
            rep->box_hi = vec3_neg(rep->box_lo);
            for (int i = 0; i < h.n_index; ++i) {
                struct vec3 x = points[h.index[i]];
                rep->box_lo = vec3_make(fmin(rep->box_lo.x, x.x), fmin(rep->box_lo.y, x.y), fmin(rep->box_lo.z, x.z));
                rep->box_hi = vec3_make(fmax(rep->box_hi.x, x.x), fmax(rep->box_hi.y, x.y), fmax(rep->box_hi.z, x.z));
            }
            snprintf(rep->note, sizeof rep->note, "light \"%s\": %d portal(s) on the hull of %d shape(s)", name,
                     ports.n, k);
        }
    }
    convex_hull_free(&h);
    free(points);
    free(c);
    free(ports.p);
    return ok || error_set(err, "out of memory finding the portals of light \"%s\"", name);
}

bool portal_finder_run(struct scene *s, const struct config *cfg, struct error *err)
{
    bool any = false;
    for (int i = 0; i < cfg->n_lights; ++i) any = any || cfg->lights[i].auto_portals;
    if (!any) return true;
    s->auto_portals = calloc((size_t)s->n_emitters, sizeof *s->auto_portals);
    if (!s->auto_portals) return error_set(err, "out of memory for the auto portals");
    for (int i = 0; i < cfg->n_lights; ++i) {
        if (!cfg->lights[i].auto_portals) continue;
        s->auto_portals[i].requested = true;
        const struct emitter *e = &s->emitters[i];
        struct finder f = { s, cfg, i, &s->auto_portals[i], NULL, 0 };
        f.light_pts = malloc(sizeof *f.light_pts * (size_t)e->n_lights * POLYGON_INPUT_MAX);
        if (!f.light_pts) return error_set(err, "out of memory for the auto portals");
        for (int m = 0; m < e->n_lights; ++m) {
            const struct polygon *p = &s->lights[e->first_light + m].target.polygon;
            for (int v = 0; v < p->n && v < POLYGON_INPUT_MAX; ++v) f.light_pts[f.n_light_pts++] = p->v[v];
        }
        /* Only the corners of the light points' convex hull matter (every
           use is a max or min of an affine or convex function over the
           light): a mesh bulb has thousands of vertices. */
        struct convex_hull lh;
        struct error lerr;
        if (f.n_light_pts > 64 && convex_hull_build(f.light_pts, f.n_light_pts, &lh, &lerr)) {
            int n_keep = 0;
            bool *used = calloc((size_t)f.n_light_pts, sizeof *used);
            struct vec3 *kept = malloc(sizeof *kept * (size_t)f.n_light_pts);
            if (used && kept) {
                for (int q = 0; q < lh.n_index; ++q) used[lh.index[q]] = true;
                for (int q = 0; q < f.n_light_pts; ++q)
                    if (used[q]) kept[n_keep++] = f.light_pts[q];
                free(f.light_pts);
                f.light_pts = kept, f.n_light_pts = n_keep, kept = NULL;
            }
            free(used);
            free(kept);
            convex_hull_free(&lh);
        }
        bool ok = find_for_light(&f, err);
        free(f.light_pts);
        if (!ok) return false;
    }
    return true;
}

/* The shortest of %.15g..%.17g that reads back to x: a frozen portal is
   the found one, bit for bit. */
static void write_exact(FILE *out, double x)
{
    char buf[40];
    for (int digits = 15; digits <= 17; ++digits) {
        snprintf(buf, sizeof buf, "%.*g", digits, x);
        if (strtod(buf, NULL) == x) break;
    }
    fputs(buf, out);
}

static void write_polygon(FILE *out, const struct polygon *p)
{
    fputs("[", out);
    for (int v = 0; v < p->n; ++v) {
        fputs(v ? ", [" : "[", out);
        write_exact(out, p->v[v].x);
        fputs(", ", out);
        write_exact(out, p->v[v].y);
        fputs(", ", out);
        write_exact(out, p->v[v].z);
        fputs("]", out);
    }
    fputs("]", out);
}

/* The coverage of emitter i's found portals: n_rays rays, fixed seed. */
static bool summary_coverage(const struct scene *s, int i, long n_rays, struct portal_coverage *cov, struct error *err)
{
    const struct auto_portal_report *rep = &s->auto_portals[i];
    const struct light *l = &s->lights[s->emitters[i].first_light];
    int n = l->n_portals;
    struct polygon *copy = malloc(sizeof *copy * (size_t)(n > 0 ? n : 1));
    if (!copy) return error_set(err, "out of memory");
    for (int k = 0; k < n; ++k) polygon_copy(&copy[k], &s->portals[l->first_portal + k].target.polygon);
    bool ok = portal_finder_coverage(s, i, rep->planes, rep->n_planes, copy, n, n_rays, FINDER_SEED + 1, cov, err);
    free(copy);
    return ok;
}

bool portal_finder_write_summary(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                                 struct error *err)
{
    if (!s->auto_portals) return true;
    fputs("# portals: auto found, per light (blocked: the fraction of the light's rays aimed through a portal\n"
          "# that something inside the enclosure stops; bound: 3/N over N escaping rays, none of which missed\n"
          "# the portals, bounds the escaping flux the portals could miss at 95% confidence):\n",
          out);
    for (int i = 0; i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->requested) continue;
        if (!rep->enclosed) {
            fprintf(out, "#   %s%s\n", rep->warn ? "warning: " : "", rep->note);
            continue;
        }
        struct portal_coverage cov;
        if (!summary_coverage(s, i, n_rays, &cov, err)) return false;
        fprintf(out,
                "#   %s: %d portal(s), area %.6g m^2 (%.1f%% of the enclosure's %.6g m^2), blocked %.4f, bound %.3g "
                "(%ld of %ld rays escaped, %ld missed)\n",
                cfg->lights[i].name, rep->n_portals, rep->area, 100.0 * rep->area / rep->hull_area, rep->hull_area,
                cov.blocked_fraction, cov.bound, cov.n_escaped, cov.n_rays, cov.n_missed);
    }
    fputs("# To freeze them, replace the auto entries by:\n# portals:\n", out);
    for (int i = 0; i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->enclosed) continue;
        const struct light *l = &s->lights[s->emitters[i].first_light];
        for (int k = 0; k < l->n_portals; ++k) {
            fprintf(out, "#   - {name: %s_auto%d, light: %s, vertices: ", cfg->lights[i].name, k, cfg->lights[i].name);
            write_polygon(out, &s->portals[l->first_portal + k].target.polygon);
            fputs("}\n", out);
        }
    }
    return true;
}

static void json_key_number(FILE *out, const char *key, double v)
{
    fprintf(out, ",\"%s\":", key);
    json_write_number(out, v);
}

bool portal_finder_write_json(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                              struct error *err)
{
    fputc('{', out);
    bool first = true;
    for (int i = 0; s->auto_portals && i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->requested) continue;
        if (!first) fputc(',', out);
        first = false;
        json_write_string(out, cfg->lights[i].name);
        fprintf(out, ":{\"enclosed\":%s,\"warning\":%s,\"note\":", rep->enclosed ? "true" : "false",
                rep->warn ? "true" : "false");
        json_write_string(out, rep->note);
        struct portal_coverage cov = { 0 };
        if (rep->enclosed && !summary_coverage(s, i, n_rays, &cov, err)) return false;
        fprintf(out, ",\"n_portals\":%d", rep->enclosed ? rep->n_portals : 0);
        json_key_number(out, "area", rep->enclosed ? rep->area : 0.0);
        json_key_number(out, "hull_area", rep->hull_area);
        if (rep->enclosed) {
            json_key_number(out, "blocked_fraction", cov.blocked_fraction);
            json_key_number(out, "bound", cov.bound);
            fprintf(out, ",\"n_rays\":%ld,\"n_escaped\":%ld,\"n_missed\":%ld", cov.n_rays, cov.n_escaped, cov.n_missed);
        }
        fputs(",\"portals\":[", out);
        const struct light *l = &s->lights[s->emitters[i].first_light];
        for (int k = 0; rep->enclosed && k < l->n_portals; ++k) {
            const struct polygon *p = &s->portals[l->first_portal + k].target.polygon;
            char name[CONFIG_NAME_MAX + 32];
            snprintf(name, sizeof name, "%s_auto%d", cfg->lights[i].name, k);
            fputs(k ? ",{\"name\":" : "{\"name\":", out);
            json_write_string(out, name);
            fputs(",\"light\":", out);
            json_write_string(out, cfg->lights[i].name);
            fputs(",\"vertices\":[", out);
            for (int v = 0; v < p->n; ++v) {
                fputs(v ? ",[" : "[", out);
                json_write_number(out, p->v[v].x);
                fputc(',', out);
                json_write_number(out, p->v[v].y);
                fputc(',', out);
                json_write_number(out, p->v[v].z);
                fputc(']', out);
            }
            fputs("]}", out);
        }
        fputs("]}", out);
    }
    fputc('}', out);
    return true;
}

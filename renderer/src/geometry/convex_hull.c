#include "geometry/convex_hull.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Quickhull (Barber, Dobkin and Huhdanpaa 1996) on triangles: each face
   keeps the points above it by more than tol (its outside set); the
   farthest of them replaces the faces it sees by a cone from their horizon.
   A point within tol of a face counts as on it, which absorbs duplicates
   and coplanar points; the faces that end up in one plane are merged
   afterwards into one polygon each (the 2D hull of their vertices). */

#define HULL_REL_TOL 1e-9

struct qh_face {
    int v[3];
    int nb[3]; /* nb[k]: the face across edge v[k] -> v[k + 1] */
    struct vec3 n;
    double d;
    int outside; /* first point of the outside set, -1 when empty */
    int visit;
    bool alive;
};

struct qh {
    const struct vec3 *pts;
    int n_pts;
    int *next; /* per point: the next of its outside set */
    struct qh_face *f;
    int n_f, cap_f;
    double tol;
};

static double face_dist(const struct qh_face *f, struct vec3 p)
{
    return vec3_dot(f->n, p) - f->d;
}

static int new_face(struct qh *q, int a, int b, int c)
{
    if (q->n_f == q->cap_f) {
        int cap = q->cap_f ? 2 * q->cap_f : 64;
        struct qh_face *f = realloc(q->f, sizeof *f * (size_t)cap);
        if (!f) return -1;
        q->f = f;
        q->cap_f = cap;
    }
    struct qh_face *f = &q->f[q->n_f];
    f->v[0] = a, f->v[1] = b, f->v[2] = c;
    f->nb[0] = f->nb[1] = f->nb[2] = -1;
    struct vec3 pa = q->pts[a];
    struct vec3 n = vec3_cross(vec3_sub(q->pts[b], pa), vec3_sub(q->pts[c], pa));
    double len = vec3_length(n);
    f->n = len > 0.0 ? vec3_scale(n, 1.0 / len) : vec3_make(0.0, 0.0, 0.0);
    f->d = vec3_dot(f->n, pa);
    f->outside = -1;
    f->visit = 0;
    f->alive = true;
    return q->n_f++;
}

/* Puts point i in the outside set of the face (among faces[0..n)) it is
   farthest above, if above any by more than tol. */
static void assign_point(struct qh *q, int i, const int *faces, int n)
{
    int best = -1;
    double best_d = q->tol;
    for (int k = 0; k < n; ++k) {
        double d = face_dist(&q->f[faces[k]], q->pts[i]);
        if (d > best_d) best_d = d, best = faces[k];
    }
    if (best < 0) return;
    q->next[i] = q->f[best].outside;
    q->f[best].outside = i;
}

static int edge_index(const struct qh_face *f, int a, int b)
{
    for (int k = 0; k < 3; ++k)
        if (f->v[k] == a && f->v[(k + 1) % 3] == b) return k;
    return -1;
}

/* The four extreme points of a volume, or false when the points span none. */
static bool initial_simplex(const struct qh *q, int out[4])
{
    const struct vec3 *p = q->pts;
    int ext[6] = { 0, 0, 0, 0, 0, 0 };
    for (int i = 1; i < q->n_pts; ++i) {
        if (p[i].x < p[ext[0]].x) ext[0] = i;
        if (p[i].x > p[ext[1]].x) ext[1] = i;
        if (p[i].y < p[ext[2]].y) ext[2] = i;
        if (p[i].y > p[ext[3]].y) ext[3] = i;
        if (p[i].z < p[ext[4]].z) ext[4] = i;
        if (p[i].z > p[ext[5]].z) ext[5] = i;
    }
    double best = -1.0;
    for (int a = 0; a < 6; ++a)
        for (int b = a + 1; b < 6; ++b) {
            double d = vec3_length2(vec3_sub(p[ext[a]], p[ext[b]]));
            if (d > best) best = d, out[0] = ext[a], out[1] = ext[b];
        }
    if (!(sqrt(best) > 10.0 * q->tol)) return false;
    struct vec3 axis = vec3_normalize(vec3_sub(p[out[1]], p[out[0]]));
    best = -1.0;
    for (int i = 0; i < q->n_pts; ++i) {
        struct vec3 r = vec3_sub(p[i], p[out[0]]);
        double d = vec3_length2(vec3_sub(r, vec3_scale(axis, vec3_dot(r, axis))));
        if (d > best) best = d, out[2] = i;
    }
    if (!(sqrt(best) > 10.0 * q->tol)) return false;
    struct vec3 n = vec3_normalize(vec3_cross(vec3_sub(p[out[1]], p[out[0]]), vec3_sub(p[out[2]], p[out[0]])));
    best = -1.0;
    for (int i = 0; i < q->n_pts; ++i) {
        double d = fabs(vec3_dot(n, vec3_sub(p[i], p[out[0]])));
        if (d > best) best = d, out[3] = i;
    }
    return best > 10.0 * q->tol;
}

/* The faces of the tetrahedron, outward, linked, with every point assigned. */
static bool start(struct qh *q, const int s[4])
{
    struct vec3 c = vec3_make(0.0, 0.0, 0.0);
    for (int k = 0; k < 4; ++k) c = vec3_add(c, vec3_scale(q->pts[s[k]], 0.25));
    static const int tri[4][3] = { { 0, 1, 2 }, { 0, 3, 1 }, { 1, 3, 2 }, { 2, 3, 0 } };
    int faces[4];
    for (int k = 0; k < 4; ++k) {
        int a = s[tri[k][0]], b = s[tri[k][1]], cc = s[tri[k][2]];
        struct vec3 n = vec3_cross(vec3_sub(q->pts[b], q->pts[a]), vec3_sub(q->pts[cc], q->pts[a]));
        if (vec3_dot(n, vec3_sub(q->pts[a], c)) < 0.0) {
            int t = b;
            b = cc;
            cc = t;
        }
        if ((faces[k] = new_face(q, a, b, cc)) < 0) return false;
    }
    for (int a = 0; a < 4; ++a)
        for (int e = 0; e < 3; ++e) {
            struct qh_face *f = &q->f[faces[a]];
            for (int b = 0; b < 4; ++b)
                if (b != a && edge_index(&q->f[faces[b]], f->v[(e + 1) % 3], f->v[e]) >= 0) f->nb[e] = faces[b];
        }
    for (int i = 0; i < q->n_pts; ++i)
        if (i != s[0] && i != s[1] && i != s[2] && i != s[3]) assign_point(q, i, faces, 4);
    return true;
}

struct horizon_edge {
    int a, b, across;
};

/* Adds the farthest point of face f's outside set: false on memory or a
   horizon that is not one loop (a numerical failure). */
static bool add_point(struct qh *q, int f, int stamp, int **vis, int *cap_vis, struct horizon_edge **hor, int *cap_hor,
                      int *start_of)
{
    int apex = -1;
    double far = -INFINITY;
    for (int i = q->f[f].outside; i >= 0; i = q->next[i]) {
        double d = face_dist(&q->f[f], q->pts[i]);
        if (d > far) far = d, apex = i;
    }
    struct vec3 p = q->pts[apex];
    int n_vis = 0, n_hor = 0;
    if (*cap_vis < q->n_f) {
        int *v = realloc(*vis, sizeof *v * (size_t)q->n_f);
        if (!v) return false;
        *vis = v, *cap_vis = q->n_f;
    }
    (*vis)[n_vis++] = f;
    q->f[f].visit = stamp;
    for (int k = 0; k < n_vis; ++k) {
        struct qh_face *cur = &q->f[(*vis)[k]];
        for (int e = 0; e < 3; ++e) {
            int g = cur->nb[e];
            if (g < 0) return false;
            if (q->f[g].visit == stamp) continue;
            if (face_dist(&q->f[g], p) > q->tol) {
                q->f[g].visit = stamp;
                (*vis)[n_vis++] = g;
                continue;
            }
            if (n_hor == *cap_hor) {
                int cap = *cap_hor ? 2 * *cap_hor : 64;
                struct horizon_edge *h = realloc(*hor, sizeof *h * (size_t)cap);
                if (!h) return false;
                *hor = h, *cap_hor = cap;
            }
            (*hor)[n_hor++] = (struct horizon_edge){ cur->v[e], cur->v[(e + 1) % 3], g };
        }
    }
    int first_new = q->n_f;
    for (int k = 0; k < n_hor; ++k) {
        struct horizon_edge h = (*hor)[k];
        if (start_of[h.a] >= 0) return false;
        int nf = new_face(q, h.a, h.b, apex);
        if (nf < 0) return false;
        start_of[h.a] = nf;
        q->f[nf].nb[0] = h.across;
        int e = edge_index(&q->f[h.across], h.b, h.a);
        if (e < 0) return false;
        q->f[h.across].nb[e] = nf;
    }
    bool ok = true;
    for (int k = first_new; k < q->n_f; ++k) {
        int g = start_of[q->f[k].v[1]];
        if (g < 0) ok = false;
        else q->f[k].nb[1] = g, q->f[g].nb[2] = k;
    }
    for (int k = first_new; k < q->n_f; ++k) start_of[q->f[k].v[0]] = -1;
    if (!ok) return false;
    int n_new = q->n_f - first_new;
    int *news = malloc(sizeof *news * (size_t)n_new);
    if (!news) return false;
    for (int k = 0; k < n_new; ++k) news[k] = first_new + k;
    for (int k = 0; k < n_vis; ++k) {
        struct qh_face *v = &q->f[(*vis)[k]];
        v->alive = false;
        for (int i = v->outside, next; i >= 0; i = next) {
            next = q->next[i];
            if (i != apex) assign_point(q, i, news, n_new);
        }
        v->outside = -1;
    }
    free(news);
    return true;
}

static int find_root(int *parent, int i)
{
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

struct proj {
    double x, y;
    int i;
};

static int compare_proj(const void *a, const void *b)
{
    const struct proj *p = a, *q = b;
    if (p->x != q->x) return p->x < q->x ? -1 : 1;
    if (p->y != q->y) return p->y < q->y ? -1 : 1;
    return p->i - q->i;
}

/* Distance of b from the line a -> c, positive when b lies to its right,
   that is when a -> b -> c turns left. The cross product is taken with the
   three points in sorted order and its sign set by the permutation, so
   that turn(c, b, a) is exactly -turn(a, b, c): the upper chain then never
   keeps a point that the lower chain kept as a left turn too (with the
   plain formula both can round positive for nearly collinear points, and
   the chain grew past n corners). */
static double turn(const struct proj *a, const struct proj *b, const struct proj *c)
{
    const struct proj *s[3] = { a, b, c };
    double sign = 1.0;
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2 - i; ++j)
            if (compare_proj(s[j], s[j + 1]) > 0) {
                const struct proj *t = s[j];
                s[j] = s[j + 1];
                s[j + 1] = t;
                sign = -sign;
            }
    double cr = (s[1]->x - s[0]->x) * (s[2]->y - s[0]->y) - (s[1]->y - s[0]->y) * (s[2]->x - s[0]->x);
    double len = hypot(c->x - a->x, c->y - a->y);
    return len > 0.0 ? sign * cr / len : 0.0;
}

int convex_hull_2d(const struct vec3 *points, int n, struct vec3 normal, double tol, int *out)
{
    if (n < 3) return 0;
    struct proj *p = malloc(sizeof *p * (size_t)n), *h = malloc(sizeof *h * (size_t)(2 * n + 1));
    int k = 0;
    if (p && h) {
        struct frame fr = frame_from_normal(normal);
        double m = 0.0;
        for (int i = 0; i < n; ++i) {
            struct vec3 l = frame_to_local(&fr, points[i]);
            p[i] = (struct proj){ l.x, l.y, i };
            m = fmax(m, fmax(fabs(l.x), fabs(l.y)));
        }
        /* Below the rounding noise of turn() the sign of a turn means
           nothing, and different triples of nearly collinear points then
           disagree: a point could stay in both chains (a repeated corner).
           Such points count as on the line. */
        double t = fmax(tol, 16.0 * DBL_EPSILON * m);
        if (!isfinite(m)) t = INFINITY; /* no finite hull: nothing kept */
        qsort(p, (size_t)n, sizeof *p, compare_proj);
        /* The chain keeps b only when a -> b -> c turns left with b more
           than t from the line a -> c. */
        for (int i = 0; i < n; ++i) {
            while (k >= 2 && turn(&h[k - 2], &h[k - 1], &p[i]) <= t) --k;
            h[k++] = p[i];
        }
        for (int i = n - 2, lower = k + 1; i >= 0; --i) {
            while (k >= lower && turn(&h[k - 2], &h[k - 1], &p[i]) <= t) --k;
            h[k++] = p[i];
        }
        --k; /* the first point again */
        /* A corner twice or more corners than points would mean the turns
           still disagreed: report no area, which every caller takes as
           "proves nothing". */
        unsigned char *seen = calloc((size_t)n, 1);
        bool ok = seen && k <= n;
        for (int i = 0; ok && i < k; ++i) {
            ok = !seen[h[i].i];
            seen[h[i].i] = 1;
        }
        free(seen);
        if (!ok) k = 0;
        for (int i = 0; i < k; ++i) out[i] = h[i].i;
    }
    free(p);
    free(h);
    return k >= 3 ? k : 0;
}

/* Merges the alive faces into planar groups and writes the facets. */
static bool write_facets(const struct qh *q, struct convex_hull *out)
{
    int n = q->n_f;
    int *parent = malloc(sizeof *parent * (size_t)n), *group = malloc(sizeof *group * (size_t)n);
    int *order = malloc(sizeof *order * (size_t)n), *first = malloc(sizeof *first * (size_t)(n + 1));
    int *pts = malloc(sizeof *pts * (size_t)(3 * n)), *hull = malloc(sizeof *hull * (size_t)(3 * n));
    struct vec3 *xyz = malloc(sizeof *xyz * (size_t)(3 * n));
    bool ok = parent && group && order && first && pts && hull && xyz;
    if (ok) {
        for (int i = 0; i < n; ++i) parent[i] = i;
        for (int i = 0; i < n; ++i) {
            const struct qh_face *f = &q->f[i];
            if (!f->alive) continue;
            for (int e = 0; e < 3; ++e) {
                const struct qh_face *g = &q->f[f->nb[e]];
                bool flat = true;
                for (int k = 0; k < 3; ++k)
                    flat = flat && fabs(face_dist(f, q->pts[g->v[k]])) <= q->tol &&
                           fabs(face_dist(g, q->pts[f->v[k]])) <= q->tol;
                if (flat && vec3_dot(f->n, g->n) > 0.0) {
                    int a = find_root(parent, i), b = find_root(parent, f->nb[e]);
                    if (a != b) parent[a < b ? b : a] = a < b ? a : b;
                }
            }
        }
        /* Groups numbered by their first face, faces bucketed by group. */
        int n_groups = 0;
        for (int i = 0; i < n; ++i) group[i] = -1;
        for (int i = 0; i < n; ++i)
            if (q->f[i].alive) {
                int r = find_root(parent, i);
                if (group[r] < 0) group[r] = n_groups++;
                group[i] = group[r];
            }
        memset(first, 0, sizeof *first * (size_t)(n_groups + 1));
        for (int i = 0; i < n; ++i)
            if (group[i] >= 0) ++first[group[i] + 1];
        for (int g = 0; g < n_groups; ++g) first[g + 1] += first[g];
        int *fill = hull; /* scratch until the corners are computed */
        memcpy(fill, first, sizeof *fill * (size_t)(n_groups + 1));
        for (int i = 0; i < n; ++i)
            if (group[i] >= 0) order[fill[group[i]]++] = i;
        out->facets = malloc(sizeof *out->facets * (size_t)(n_groups > 0 ? n_groups : 1));
        out->index = malloc(sizeof *out->index * (size_t)(3 * n > 0 ? 3 * n : 1));
        ok = out->facets && out->index;
        for (int g = 0; ok && g < n_groups; ++g) {
            struct vec3 nsum = vec3_make(0.0, 0.0, 0.0);
            int m = 0;
            for (int k = first[g]; k < first[g + 1]; ++k) {
                const struct qh_face *f = &q->f[order[k]];
                struct vec3 a = q->pts[f->v[0]];
                nsum = vec3_add(nsum, vec3_cross(vec3_sub(q->pts[f->v[1]], a), vec3_sub(q->pts[f->v[2]], a)));
                for (int v = 0; v < 3; ++v) {
                    bool seen = false;
                    for (int j = 0; j < m && !seen; ++j) seen = pts[j] == f->v[v];
                    if (!seen) pts[m++] = f->v[v];
                }
            }
            double len = vec3_length(nsum);
            if (!(len > 0.0)) continue;
            struct vec3 nn = vec3_scale(nsum, 1.0 / len);
            for (int j = 0; j < m; ++j) xyz[j] = q->pts[pts[j]];
            int c = convex_hull_2d(xyz, m, nn, q->tol, hull);
            if (c < 3) continue;
            struct hull_facet *hf = &out->facets[out->n_facets++];
            hf->plane.normal = nn;
            hf->plane.offset = -INFINITY;
            for (int j = 0; j < m; ++j) hf->plane.offset = fmax(hf->plane.offset, vec3_dot(nn, xyz[j]));
            hf->first = out->n_index;
            hf->n = c;
            for (int j = 0; j < c; ++j) out->index[out->n_index++] = pts[hull[j]];
        }
    }
    free(parent);
    free(group);
    free(order);
    free(first);
    free(pts);
    free(hull);
    free(xyz);
    return ok;
}

bool convex_hull_build(const struct vec3 *points, int n, struct convex_hull *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    for (int i = 0; i < n; ++i) {
        struct vec3 p = points[i];
        if (!isfinite(p.x) || !isfinite(p.y) || !isfinite(p.z))
            return error_set(err, "convex hull: point %d is not finite", i);
        lo = vec3_make(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
        hi = vec3_make(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
    }
    if (n < 4) return error_set(err, "convex hull of %d points: degenerate (expected 4 points spanning a volume)", n);
    struct qh q = { points, n, NULL, NULL, 0, 0, 0.0 };
    out->size = vec3_length(vec3_sub(hi, lo));
    q.tol = out->tol = HULL_REL_TOL * out->size;
    int s[4];
    if (!initial_simplex(&q, s))
        return error_set(err, "convex hull of %d points: degenerate (they are collinear or coplanar)", n);
    q.next = malloc(sizeof *q.next * (size_t)n);
    int *start_of = malloc(sizeof *start_of * (size_t)n);
    int *vis = NULL, cap_vis = 0, cap_hor = 0;
    struct horizon_edge *hor = NULL;
    bool ok = q.next && start_of && start(&q, s);
    if (!ok) error_set(err, "convex hull: out of memory");
    if (ok)
        for (int i = 0; i < n; ++i) start_of[i] = -1;
    for (int f = 0, stamp = 1; ok && f < q.n_f; ++f)
        while (ok && q.f[f].alive && q.f[f].outside >= 0) {
            ok = add_point(&q, f, stamp++, &vis, &cap_vis, &hor, &cap_hor, start_of);
            if (!ok) error_set(err, "convex hull of %d points: numerical failure (a horizon that is not one loop)", n);
        }
    if (ok && !write_facets(&q, out)) ok = error_set(err, "convex hull: out of memory");
    if (ok && out->n_facets < 4) ok = error_set(err, "convex hull of %d points: degenerate", n);
    free(q.next);
    free(q.f);
    free(start_of);
    free(vis);
    free(hor);
    if (!ok) {
        convex_hull_free(out);
        return false;
    }
    return true;
}

void convex_hull_free(struct convex_hull *h)
{
    free(h->facets);
    free(h->index);
    memset(h, 0, sizeof *h);
}

bool convex_hull_facet_polygon(const struct convex_hull *h, const struct vec3 *points, int f, struct polygon *out)
{
    const struct hull_facet *hf = &h->facets[f];
    if (hf->n > POLYGON_MAX) return false;
    out->n = hf->n;
    for (int i = 0; i < hf->n; ++i) out->v[i] = points[h->index[hf->first + i]];
    return true;
}

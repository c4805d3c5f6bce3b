/* facet_cover.c: a facet's uncovered part (facet_cover.h), by exact
   subtraction of the triangles lying in it, over the region that the
   edge argument of open_region leaves. */
#include "geometry/facet_cover.h"

#include <math.h>
#include <stdlib.h>

#include "base/fastmath.h"

#include "geometry/facet_edges.h"
#include "geometry/polygon_subtract.h"

/* Pieces per facet beyond which the greedy merge is skipped. */
#define MERGE_MAX 256

bool polygon_list_push(struct polygon_list *ps, const struct polygon *p)
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

/* Pushes the fan of the convex polygon v[0..n) in chunks of at most
   POLYGON_INPUT_MAX corners. */
static bool push_fan(const struct vec3 *v, int n, struct polygon_list *out)
{
    bool ok = true;
    for (int a = 1; ok && a + 1 < n; a += POLYGON_INPUT_MAX - 2) {
        struct polygon chunk;
        chunk.n = 0;
        chunk.v[chunk.n++] = v[0];
        for (int b = a; b < n && chunk.n < POLYGON_INPUT_MAX; ++b) chunk.v[chunk.n++] = v[b];
        if (chunk.n >= 3) ok = polygon_list_push(out, &chunk);
        if (a + POLYGON_INPUT_MAX - 2 >= n - 1) break;
    }
    return ok;
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
                for (int l = 0; l < nf; ++l) delta = fm_fmin(delta, LINE_D(l, q));
            }
        }
        i = j;
    }
    if (n_s == 0 || !(delta > 4.0 * eps)) goto done;
    /* x0: from a corner of the facet towards its centre, closer to the
       outline than delta, off every edge of S. */
    bool proven = false;
    for (int v = 0; v < nf && !proven; ++v) {
        double reach = fm_fmax(LINE_D(v, c2), LINE_D((v + nf - 1) % nf, c2));
        if (!(reach > 0.0)) continue;
        for (double frac = 0.5; frac > 0.01 && !proven; frac *= 0.37) {
            double t = fm_fmin(0.5, frac * fm_fmin(delta, reach) / reach);
            struct vec3 x0 = vec3_add(fv[v], vec3_scale(vec3_sub(c2, fv[v]), t));
            double dist = INFINITY;
            for (int i = 0; i < nf; ++i) dist = fm_fmin(dist, LINE_D(i, x0));
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
bool facet_uncovered_part(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                          int n_tris, struct polygon_list *out)
{
    const struct hull_facet *hf = &h->facets[fi];
    struct plane pl = hf->plane;
    double cover = FACET_COVER_REL * h->size, debris = FACET_DEBRIS_REL * h->size * h->size;
    struct polygon_list cur = { 0, 0, NULL }, next = { 0, 0, NULL };
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
            tlo = vec3_make(fm_fmin(tlo.x, tri[v].x), fm_fmin(tlo.y, tri[v].y), fm_fmin(tlo.z, tri[v].z));
            thi = vec3_make(fm_fmax(thi.x, tri[v].x), fm_fmax(thi.y, tri[v].y), fm_fmax(thi.z, tri[v].z));
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
                    plo = vec3_make(fm_fmin(plo.x, x.x), fm_fmin(plo.y, x.y), fm_fmin(plo.z, x.z));
                    phi = vec3_make(fm_fmax(phi.x, x.x), fm_fmax(phi.y, x.y), fm_fmax(phi.z, x.z));
                }
                apart =
                    plo.x > thi.x || plo.y > thi.y || plo.z > thi.z || phi.x < tlo.x || phi.y < tlo.y || phi.z < tlo.z;
            }
            if (apart) {
                ok = polygon_list_push(&next, &cur.p[k]);
                continue;
            }
            if (cur.p[k].n > POLYGON_MAX - 3) {
                ok = polygon_list_push(&next, &cur.p[k]);
                continue;
            }
            int m = polygon_subtract_triangle(&cur.p[k], pl.normal, tri, debris, pieces);
            for (int j = 0; ok && j < m; ++j) ok = polygon_list_push(&next, &pieces[j]);
        }
        struct polygon_list tmp = cur;
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
    for (int k = 0; ok && k < cur.n; ++k) ok = polygon_list_push(out, &cur.p[k]);
    free(sel);
    free(cur.p);
    free(next.p);
    return ok;
}

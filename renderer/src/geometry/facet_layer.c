/* facet_layer.c: whether a layer of surface just under a facet closes it
   (facet_cover.h), for a shade whose wall lies a little inside its hull. */
#include "geometry/facet_cover.h"

#include <math.h>
#include <stdlib.h>

#include "base/fastmath.h"

#include "geometry/facet_edges.h"

/* Depths, relative to P's size, tried for the covering layer of a facet
   that no triangle lying in it covers (facet_layer_covers), shallowest first. */
static const double LAYER_REL[] = { 1e-6, 1e-5, 1e-4, 1e-3, 3e-3, 1e-2 };

/* A triangle of a covering layer clipped to the layer's depth. */
struct layer_poly {
    int n;
    struct vec3 v[4];
};

void tri_spheres(const struct vec3 (*tris)[3], int n_tris, struct tri_sphere *out)
{
    for (int t = 0; t < n_tris; ++t) {
        struct vec3 c = vec3_scale(vec3_add(vec3_add(tris[t][0], tris[t][1]), tris[t][2]), 1.0 / 3.0);
        double r = 0.0;
        for (int k = 0; k < 3; ++k) r = fm_fmax(r, vec3_length(vec3_sub(tris[t][k], c)));
        /* Rounding of a plane distance is ~1e-16 of the coordinates'
           size: 1e-9 of it (and of r) leaves a wide margin. */
        out[t] = (struct tri_sphere){ c, r * (1.0 + 1e-9) + 1e-9 * (vec3_max_abs(c) + r) };
    }
}

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
   1e-9 (tol) and 1e-7 (eps), as the rest of the finder does (scene/portal_finder.c). */
bool facet_layer_covers(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                        const struct tri_sphere *spheres, int n_tris, const struct vec3 *light_pts, int n_light_pts)
{
    const struct hull_facet *hf = &h->facets[fi];
    const struct plane *pl = &hf->plane;
    struct frame fr = frame_from_normal(pl->normal);
    double tol = h->tol, eps = 100.0 * h->tol;
    double h_min = INFINITY;
    for (int i = 0; i < n_light_pts; ++i) h_min = fm_fmin(h_min, -plane_distance(pl, light_pts[i]));
    if (!(h_min > 0.0)) return false;
    int nf = hf->n, n_g_cap = nf * (n_light_pts + 1);
    struct vec3 *gp = malloc(sizeof *gp * (size_t)n_g_cap);
    int *gi = malloc(sizeof *gi * (size_t)n_g_cap);
    struct vec3 *ln = malloc(sizeof *ln * (size_t)n_g_cap);
    /* A triangle cut at depth d keeps up to four corners: four edges each. */
    struct cover_edge *e = malloc(sizeof *e * (size_t)(4 * n_tris + 1));
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
    struct vec3 *feet = malloc(sizeof *feet * (size_t)(n_light_pts + 1));
    int *fi2 = malloc(sizeof *fi2 * (size_t)(n_light_pts + 1)), n_feet = 0;
    if (feet && fi2) {
        for (int i = 0; i < n_light_pts; ++i)
            feet[i] = vec3_madd(light_pts[i], pl->normal, -plane_distance(pl, light_pts[i]));
        int nh = convex_hull_2d(feet, n_light_pts, pl->normal, 0.0, fi2);
        if (nh >= 3) {
            struct vec3 tmp[POLYGON_MAX];
            if (nh <= POLYGON_MAX) {
                for (int i = 0; i < nh; ++i) tmp[i] = feet[fi2[i]];
                for (int i = 0; i < nh; ++i) feet[i] = tmp[i];
                n_feet = nh;
            } else {
                n_feet = n_light_pts;
            }
        } else {
            n_feet = n_light_pts; /* a light seen edge-on: every foot */
        }
    }
    free(fi2);
    int *pre = malloc(sizeof *pre * (size_t)(n_tris + 1)), n_pre = 0;
    bool covered = false;
    /* The triangles within the deepest layer tried, once. */
    double d_last = fm_fmin(LAYER_REL[sizeof LAYER_REL / sizeof LAYER_REL[0] - 1] * h->size, 0.5 * h_min);
    for (int t = 0; pre && t < n_tris; ++t) {
        /* Every vertex is within the sphere's radius of its centre's
           depth: a sphere wholly above the plane (beyond tol) or wholly
           deeper than d_last holds no triangle the exact test keeps. */
        double dc = -plane_distance(pl, spheres[t].centre), r = spheres[t].radius;
        if (dc - r > d_last || dc + r < -tol) continue;
        double dmin = INFINITY;
        for (int k = 0; k < 3; ++k) dmin = fm_fmin(dmin, -plane_distance(pl, tris[t][k]));
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
            if (outside || fm_fmin(dep[0], fm_fmin(dep[1], dep[2])) > d ||
                fm_fmin(dep[0], fm_fmin(dep[1], dep[2])) < -tol)
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
                        else if (da < 0.0) t0 = fm_fmax(t0, da / (da - db));
                        else if (db < 0.0) t1 = fm_fmin(t1, da / (da - db));
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

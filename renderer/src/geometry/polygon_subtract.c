#include "geometry/polygon_subtract.h"

#include <math.h>

#include "geometry/convex_hull.h"

int polygon_subtract_triangle(const struct polygon *poly, struct vec3 normal, const struct vec3 t[3], double min_area,
                              struct polygon out[3])
{
    struct plane pl = polygon_plane(poly);
    struct vec3 q[3];
    for (int k = 0; k < 3; ++k) q[k] = vec3_madd(t[k], pl.normal, -plane_distance(&pl, t[k]));
    struct vec3 tn = vec3_cross(vec3_sub(q[1], q[0]), vec3_sub(q[2], q[0]));
    if (!(vec3_length(tn) > 0.0)) {
        polygon_copy(&out[0], poly);
        return 1;
    }
    /* Inward edge planes of the triangle, perpendicular to the polygon. */
    double sign = vec3_dot(tn, normal) >= 0.0 ? 1.0 : -1.0;
    struct plane inward[3];
    for (int k = 0; k < 3; ++k) {
        struct vec3 e = vec3_sub(q[(k + 1) % 3], q[k]);
        struct vec3 m = vec3_normalize(vec3_scale(vec3_cross(normal, e), sign));
        inward[k].normal = m;
        inward[k].offset = vec3_dot(m, q[k]);
    }
    int n_out = 0;
    struct polygon rest, tmp;
    polygon_copy(&rest, poly);
    for (int k = 0; k < 3 && rest.n >= 3; ++k) {
        struct plane outward = { vec3_neg(inward[k].normal), -inward[k].offset };
        if (polygon_clip_plane(&rest, &outward, &out[n_out]) >= 3 && polygon_area(&out[n_out]) > min_area) ++n_out;
        if (polygon_clip_plane(&rest, &inward[k], &tmp) < 3) break;
        polygon_copy(&rest, &tmp);
    }
    return n_out;
}

bool polygon_merge_convex(const struct polygon *a, const struct polygon *b, struct vec3 normal, double tol,
                          double rel_tol, int max_vertices, struct polygon *out)
{
    struct vec3 pts[2 * POLYGON_MAX];
    int idx[2 * POLYGON_MAX], n = 0;
    for (int i = 0; i < a->n; ++i) pts[n++] = a->v[i];
    for (int i = 0; i < b->n; ++i) pts[n++] = b->v[i];
    int c = convex_hull_2d(pts, n, normal, tol, idx);
    if (c < 3 || c > max_vertices || c > POLYGON_MAX) return false;
    struct polygon h;
    h.n = c;
    for (int i = 0; i < c; ++i) h.v[i] = pts[idx[i]];
    double sum = polygon_area(a) + polygon_area(b);
    /* The hull of the union holds the union: equal areas (within
       rel_tol) say it is the union. A smaller hull dropped a corner (the
       2-D hull's tolerance) or a and b overlap: no merge, since a merge
       must never lose area (a lost piece of an opening is a gap in the
       portals). */
    if (!(fabs(polygon_area(&h) - sum) <= sum * rel_tol)) return false;
    /* And it holds every corner of a and b (within tol of each edge). */
    struct vec3 hn = polygon_plane(&h).normal;
    double orient = vec3_dot(hn, normal) >= 0.0 ? 1.0 : -1.0;
    for (int i = 0; i < c; ++i) {
        struct vec3 p0 = h.v[i], e = vec3_sub(h.v[(i + 1) % c], p0);
        double len = vec3_length(e);
        if (!(len > 0.0)) return false;
        for (int k = 0; k < n; ++k)
            if (orient * vec3_dot(vec3_cross(e, vec3_sub(pts[k], p0)), normal) < -tol * len) return false;
    }
    polygon_copy(out, &h);
    return true;
}

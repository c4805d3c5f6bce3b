/* antishadow.c: antishadow planes of a light/portal pair, the region
   classifier and the visible part of the light (see antishadow.h).

   Notation: P the portal in its plane Pi, L the light, strictly on one side
   of Pi; p a point strictly beyond Pi. Every segment from p to a light point
   l crosses Pi exactly once, at x(l) = p + t (l - p) with
   t = d(p) / (d(p) - d(l)) in (0, 1) (d: distance to Pi, positive beyond).
   L' = x(L) is a convex polygon with vertices x(l_i).

   Anti-umbra (L' inside P). For a portal edge e = (a, b) and a light point l,
   x(l) lies on P's side of e iff p lies on P's side of the plane through e
   and l: both x(l) and p are on the segment from l (on that plane) through
   x(l) to p, so they share a side. The test is linear in l, so it holds for
   all of L iff it holds at the light vertices. In the cross-section along e
   (origin on e, axis u0 into P within Pi, axis u1 towards the light, where
   the light vertices sit at angles in (0, pi)), the plane through e and a
   vertex at angle theta keeps p (which is at an angle in (pi, 2 pi)) on P's
   side iff angle(p) > theta + pi: only the vertex of largest angle binds.
   Its plane has the whole light on P's side: the supporting plane of e.

   Anti-antumbra (P inside L'). A direction from p is in the cone over L iff
   it is on the light's side of every plane through p and a light edge. For a
   light edge f and a portal point q this is the sign of the volume
   (p, f, q), which is linear in q (so portal vertices suffice) and affine in
   p (a plane through f and q). Any point p that sees some of the light
   through the portal lies on P's side of the light's plane (q between p and
   l), so the sign convention is fixed there. In the cross-section along f
   (origin on f, u0 into L within L's plane, u1 the light's normal) the light
   is the ray at angle 0 and, with P strictly on the u1 > 0 side, the portal
   vertices sit at angles in (0, pi); the condition for q at angle alpha is
   angle(p) > alpha, so only the portal vertex of largest angle binds (the
   mirror case u1 < 0 takes the smallest). Its plane has portal and light on
   the same side: the supporting plane of f. It coincides with an anti-umbra
   plane (reversed) only when f is parallel to a portal edge, as for the
   paper's aligned rectangles; elsewhere the two sets differ. If the portal
   reaches the light's plane, a portal point q there sees along the ray p q
   only q itself, which is not on the light: the anti-antumbra is empty.

   Outside (L', P disjoint). The set of points beyond Pi that see some light
   through P is C = {(1 + u) x - u l : x in P, l in L, u > 0}, which is
   convex (a convex combination of two such points is again one, with
   u = the combined weight). A facet of C is a plane touching C along a 2D
   set, so it touches P and L with P, L on opposite sides, and its contact
   sets span a plane: an edge of one polygon with a vertex of the other. For a
   portal edge this is the vertex of smallest angle in the cross-section
   above (the separating plane of e); for a light edge it is an angular
   extreme of the portal seen from the edge's line with the light on the other
   side (zero, one or two per light edge). C is the intersection of the
   half-spaces beyond Pi and on P's side of these planes. */
#include "geometry/antishadow.h"

#include <stdlib.h>
#include <string.h>

#include "base/fastmath.h"

/* Clearance demanded between the light and the portal plane (and used to
   decide whether the portal reaches the light's plane), as a fraction of
   the pair's size. */
#define ANTISHADOW_SIDE_REL 1e-9
/* Two separating planes are the same (parallel aligned edges give each plane
   twice) when their normals and offsets agree to this. */
#define ANTISHADOW_SAME_REL 1e-9

static bool check_polygon(const struct polygon *poly, const char *what, struct error *err)
{
    if (poly->n < 3 || poly->n > POLYGON_INPUT_MAX)
        return error_set(err, "%s has %d vertices (expected 3 to %d)", what, poly->n, POLYGON_INPUT_MAX);
    for (int i = 0; i < poly->n; ++i) {
        struct vec3 v = poly->v[i];
        if (!isfinite(v.x) || !isfinite(v.y) || !isfinite(v.z))
            return error_set(err, "%s vertex %d is not finite", what, i);
    }
    switch (polygon_check(poly)) {
    case POLYGON_DEFECT_NONE:
        return true;
    case POLYGON_DEFECT_DEGENERATE:
    case POLYGON_DEFECT_NOT_PLANAR:
        return error_set(err, "%s is degenerate or not planar", what);
    case POLYGON_DEFECT_NOT_CONVEX:
        return error_set(err, "%s is not strictly convex", what);
    }
    return false;
}

/* Cross-section perpendicular to an edge: origin a on the edge, u0 and u1
   orthonormal and perpendicular to the edge. */
struct section {
    struct vec3 a, u0, u1;
};

/* Angle-ordered extremes of points in a cross-section, all within less than
   pi of each other as seen from the origin. */
struct extremes {
    double x_lo, y_lo, x_hi, y_hi; /* section coordinates of the extremes */
};

static void section_coords(const struct section *s, struct vec3 v, double *x, double *y)
{
    struct vec3 r = vec3_sub(v, s->a);
    *x = vec3_dot(r, s->u0);
    *y = vec3_dot(r, s->u1);
}

/* Finds the points of smallest and largest angle about the section origin.
   Angles are measured from the direction of the points' mean so that no
   wrap-around occurs. False when the points are not within an open
   half-plane through the origin (the edge's line meets or touches their
   convex hull): then no plane through the edge has them all on one side. */
static bool section_extremes(const struct section *s, const struct polygon *poly, double tol, struct extremes *ex)
{
    double x[POLYGON_INPUT_MAX], y[POLYGON_INPUT_MAX], cx = 0.0, cy = 0.0;
    for (int i = 0; i < poly->n; ++i) {
        section_coords(s, poly->v[i], &x[i], &y[i]);
        if (!(hypot(x[i], y[i]) > tol)) return false;
        cx += x[i];
        cy += y[i];
    }
    if (!(hypot(cx, cy) > tol)) return false;
    int lo = 0, hi = 0;
    double d_lo = INFINITY, d_hi = -INFINITY;
    for (int i = 0; i < poly->n; ++i) {
        double d = atan2(cx * y[i] - cy * x[i], cx * x[i] + cy * y[i]);
        if (d < d_lo) {
            d_lo = d;
            lo = i;
        }
        if (d > d_hi) {
            d_hi = d;
            hi = i;
        }
    }
    /* A hull around the origin spans at least pi of angle. */
    if (!(d_hi - d_lo < M_PI - 1e-9)) return false;
    ex->x_lo = x[lo];
    ex->y_lo = y[lo];
    ex->x_hi = x[hi];
    ex->y_hi = y[hi];
    return true;
}

/* The plane containing the section's edge and the point at (x, y), with unit
   normal (y u0 - x u1) / r times sign: its positive side holds u0 when
   sign * y > 0. */
static struct plane section_plane(const struct section *s, double x, double y, double sign)
{
    double r = hypot(x, y);
    struct plane pl;
    pl.normal = vec3_scale(vec3_sub(vec3_scale(s->u0, y), vec3_scale(s->u1, x)), sign / r);
    pl.offset = vec3_dot(pl.normal, s->a);
    return pl;
}

/* The pair's planes while they are found, in arrays of the largest size;
   antishadow_build then keeps what is used in one block. */
struct antishadow_parts {
    int n_separating, n_umbra, n_antumbra;
    struct plane separating[ANTISHADOW_SEPARATING_MAX];
    struct plane umbra[POLYGON_INPUT_MAX];
    struct plane antumbra[POLYGON_INPUT_MAX];
    struct clip_planes portal_clip;
};

static void add_separating(struct antishadow_parts *w, struct plane pl, double scale)
{
    for (int i = 0; i < w->n_separating; ++i) {
        const struct plane *q = &w->separating[i];
        if (vec3_dot(q->normal, pl.normal) > 1.0 - ANTISHADOW_SAME_REL &&
            fabs(q->offset - pl.offset) <= ANTISHADOW_SAME_REL * scale)
            return;
    }
    w->separating[w->n_separating++] = pl;
}

/* Moves the parts and copies of the polygons into one block owned by a. */
static bool keep_parts(struct antishadow *a, const struct antishadow_parts *w, const struct polygon *light,
                       const struct polygon *portal, struct error *err)
{
    size_t n_planes = (size_t)(w->n_separating + w->n_umbra + w->n_antumbra + w->portal_clip.n);
    size_t n_vertices = (size_t)(light->n + portal->n);
    /* Planes first: both types are doubles, so the vertices stay aligned. */
    char *block = malloc(n_planes * sizeof(struct plane) + n_vertices * sizeof(struct vec3));
    if (!block) return error_set(err, "out of memory for a light/portal pair");
    struct plane *planes = (struct plane *)(void *)block;
    struct vec3 *vertices = (struct vec3 *)(void *)(block + n_planes * sizeof(struct plane));
    a->separating = planes;
    memcpy(planes, w->separating, (size_t)w->n_separating * sizeof *planes);
    planes += w->n_separating;
    a->umbra = planes;
    memcpy(planes, w->umbra, (size_t)w->n_umbra * sizeof *planes);
    planes += w->n_umbra;
    a->antumbra = planes;
    memcpy(planes, w->antumbra, (size_t)w->n_antumbra * sizeof *planes);
    planes += w->n_antumbra;
    a->portal_clip = planes;
    memcpy(planes, w->portal_clip.plane, (size_t)w->portal_clip.n * sizeof *planes);
    a->n_separating = w->n_separating;
    a->n_umbra = w->n_umbra;
    a->n_antumbra = w->n_antumbra;
    a->n_portal_clip = w->portal_clip.n;
    memcpy(vertices, light->v, (size_t)light->n * sizeof *vertices);
    a->light = (struct antishadow_vertices){ light->n, vertices };
    memcpy(vertices + light->n, portal->v, (size_t)portal->n * sizeof *vertices);
    a->portal = (struct antishadow_vertices){ portal->n, vertices + light->n };
    a->storage = block;
    return true;
}

void antishadow_free(struct antishadow *a)
{
    free(a->storage);
    memset(a, 0, sizeof *a);
}

/* Section along the edge from poly->v[i] to its successor: u0 points into
   the polygon within its plane (cross(winding normal, edge) for either
   winding), u1 is the given unit normal. */
static struct section edge_section(const struct polygon *poly, int i, struct vec3 winding_normal, struct vec3 u1)
{
    struct section s;
    struct vec3 e = vec3_normalize(vec3_sub(poly->v[(i + 1) % poly->n], poly->v[i]));
    s.a = poly->v[i];
    s.u0 = vec3_normalize(vec3_cross(winding_normal, e));
    s.u1 = u1;
    return s;
}

/* Relative tolerance of the box test (antishadow_box): right angles,
   parallel planes and edges up to rounding of the input coordinates. */
#define ANTISHADOW_BOX_REL 1e-12

/* Fills a->box when the portal is a rectangle and the light a rectangle in
   a parallel plane with edges along the portal's; leaves it invalid
   otherwise. Needs a->portal_plane (oriented). */
static void box_build(struct antishadow *a, const struct polygon *light, const struct polygon *portal, double scale)
{
    struct antishadow_box *b = &a->box;
    b->valid = false;
    if (portal->n != 4 || light->n != 4) return;
    const struct vec3 *q = portal->v;
    struct vec3 e0 = vec3_sub(q[1], q[0]), e1 = vec3_sub(q[2], q[1]);
    double tol = ANTISHADOW_BOX_REL * scale;
    if (fabs(vec3_dot(e0, e1)) > tol * scale || vec3_length(vec3_sub(vec3_add(q[0], e1), q[3])) > tol) return;
    b->origin = q[0];
    b->len_u = vec3_length(e0);
    b->len_w = vec3_length(e1);
    b->u = vec3_scale(e0, 1.0 / b->len_u);
    b->w = vec3_scale(e1, 1.0 / b->len_w);
    double lu[4], lw[4], ld[4];
    for (int i = 0; i < 4; ++i) {
        struct vec3 r = vec3_sub(light->v[i], b->origin);
        lu[i] = vec3_dot(r, b->u);
        lw[i] = vec3_dot(r, b->w);
        ld[i] = plane_distance(&a->portal_plane, light->v[i]);
    }
    /* Parallel planes; each light edge along u or along w, alternating. */
    bool first_along_u = fabs(lw[1] - lw[0]) <= tol;
    for (int i = 0; i < 4; ++i) {
        int j = (i + 1) % 4;
        if (fabs(ld[i] - ld[0]) > tol) return;
        bool along_u = fabs(lw[j] - lw[i]) <= tol, along_w = fabs(lu[j] - lu[i]) <= tol;
        if (along_u == along_w || along_u != (first_along_u == (i % 2 == 0))) return;
    }
    b->lo_u = b->hi_u = lu[0];
    b->lo_w = b->hi_w = lw[0];
    for (int i = 1; i < 4; ++i) {
        b->lo_u = fmin(b->lo_u, lu[i]);
        b->hi_u = fmax(b->hi_u, lu[i]);
        b->lo_w = fmin(b->lo_w, lw[i]);
        b->hi_w = fmax(b->hi_w, lw[i]);
    }
    b->light_dist = 0.25 * (ld[0] + ld[1] + ld[2] + ld[3]);
    b->flip = vec3_dot(polygon_area_normal(light), vec3_cross(b->u, b->w)) < 0.0;
    b->valid = b->light_dist < 0.0;
}

bool antishadow_build(const struct polygon *light, const struct polygon *portal, struct antishadow *a,
                      struct error *err)
{
    if (!check_polygon(light, "light", err) || !check_polygon(portal, "portal", err)) return false;
    memset(a, 0, sizeof *a);
    struct antishadow_parts w;
    w.n_separating = w.n_umbra = w.n_antumbra = 0;
    polygon_clip_planes_init(portal, &w.portal_clip);

    struct vec3 c_light = polygon_centroid(light), c_portal = polygon_centroid(portal);
    double scale = polygon_size(light) + polygon_size(portal) + vec3_length(vec3_sub(c_light, c_portal));
    double tol = ANTISHADOW_SIDE_REL * scale;

    /* Orient the portal plane so that the light is on its negative side. */
    struct vec3 n_portal = polygon_normal(portal);
    a->portal_plane.normal = n_portal;
    a->portal_plane.offset = vec3_dot(n_portal, c_portal);
    double d_min = INFINITY, d_max = -INFINITY;
    for (int i = 0; i < light->n; ++i) {
        double d = plane_distance(&a->portal_plane, light->v[i]);
        d_min = fmin(d_min, d);
        d_max = fmax(d_max, d);
    }
    if (d_min < -tol && d_max > tol)
        return error_set(err,
                         "light crosses the portal's plane (its vertices lie %.6g to %.6g from it); it must be "
                         "strictly on one side",
                         d_min, d_max);
    if (!(d_max < -tol) && !(d_min > tol))
        return error_set(err,
                         "light touches the portal's plane (closest vertex %.3g from it); it must be strictly "
                         "on one side",
                         fabs(d_min) < fabs(d_max) ? d_min : d_max);
    if (d_min > tol) {
        a->portal_plane.normal = vec3_neg(a->portal_plane.normal);
        a->portal_plane.offset = -a->portal_plane.offset;
    }
    struct vec3 towards_light = vec3_neg(a->portal_plane.normal);

    /* Portal edges: light vertices lie at angles in (0, pi) of the section
       (u1 towards the light); the largest angle gives the supporting plane
       (anti-umbra), the smallest the separating plane. The normal
       (y u0 - x u1) / r keeps the portal's inside (u0) positive for both. */
    for (int j = 0; j < portal->n; ++j) {
        struct section s = edge_section(portal, j, n_portal, towards_light);
        double best_lo = INFINITY, best_hi = -INFINITY, x_lo = 0.0, y_lo = 0.0, x_hi = 0.0, y_hi = 0.0;
        for (int i = 0; i < light->n; ++i) {
            double x, y;
            section_coords(&s, light->v[i], &x, &y);
            double theta = atan2(y, x);
            if (theta < best_lo) {
                best_lo = theta;
                x_lo = x;
                y_lo = y;
            }
            if (theta > best_hi) {
                best_hi = theta;
                x_hi = x;
                y_hi = y;
            }
        }
        w.umbra[w.n_umbra++] = section_plane(&s, x_hi, y_hi, 1.0);
        add_separating(&w, section_plane(&s, x_lo, y_lo, 1.0), scale);
    }

    /* The anti-antumbra exists only if the portal lies strictly on one side
       of the light's plane; `side` is that side along the light's winding
       normal. */
    struct vec3 n_light = polygon_normal(light);
    struct plane light_plane = { n_light, vec3_dot(n_light, c_light) };
    double q_min = INFINITY, q_max = -INFINITY;
    for (int m = 0; m < portal->n; ++m) {
        double d = plane_distance(&light_plane, portal->v[m]);
        q_min = fmin(q_min, d);
        q_max = fmax(q_max, d);
    }
    double side = q_min > tol ? 1.0 : q_max < -tol ? -1.0 : 0.0;
    a->has_antumbra = side != 0.0;

    /* Light edges: the light is the ray at angle 0 of the section (u1 the
       light's normal). With n0 = (y u0 - x u1) / r, n0 . (q - a) is minus the
       2D cross product of the extreme's direction with q, so the portal lies
       on n0's negative side of the smallest-angle plane and on its positive
       side of the largest-angle plane. A plane is separating when the light's
       direction (1, 0), whose n0 component is y / r, falls on the other side. */
    for (int k = 0; k < light->n; ++k) {
        struct section s = edge_section(light, k, n_light, n_light);
        struct extremes ex;
        if (!section_extremes(&s, portal, tol, &ex)) continue;
        if (ex.y_lo >= 0.0) add_separating(&w, section_plane(&s, ex.x_lo, ex.y_lo, -1.0), scale);
        if (ex.y_hi <= 0.0) add_separating(&w, section_plane(&s, ex.x_hi, ex.y_hi, 1.0), scale);
        /* Supporting plane, positive on the side away from portal and light:
           the largest angle when the portal is on the u1 > 0 side, else the
           smallest (the mirror image). */
        if (side > 0.0) w.antumbra[w.n_antumbra++] = section_plane(&s, ex.x_hi, ex.y_hi, -1.0);
        else if (side < 0.0) w.antumbra[w.n_antumbra++] = section_plane(&s, ex.x_lo, ex.y_lo, 1.0);
    }
    /* Each light edge's line misses the portal when the portal is strictly
       on one side of the light's plane, so every edge gave its plane. */
    if (a->has_antumbra && w.n_antumbra != light->n) a->has_antumbra = false;
    box_build(a, light, portal, scale);
    return keep_parts(a, &w, light, portal, err);
}

enum region antishadow_classify(const struct antishadow *a, struct vec3 p)
{
    /* NaN fails the comparison and counts as outside. */
    if (!(plane_distance(&a->portal_plane, p) > 0.0)) return REGION_OUTSIDE;
    for (int i = 0; i < a->n_separating; ++i)
        if (plane_distance(&a->separating[i], p) < 0.0) return REGION_OUTSIDE;
    int i = 0;
    while (i < a->n_umbra && plane_distance(&a->umbra[i], p) >= 0.0) ++i;
    if (i == a->n_umbra) return REGION_ANTI_UMBRA;
    if (a->has_antumbra) {
        i = 0;
        while (i < a->n_antumbra && plane_distance(&a->antumbra[i], p) >= 0.0) ++i;
        if (i == a->n_antumbra) return REGION_ANTI_ANTUMBRA;
    }
    return REGION_ANTI_PENUMBRA;
}

/* L' = x(L): x(l) = l + s (p - l) with s = d(l) / (d(l) - d(p)) in (0, 1),
   which puts x(l) on the portal plane (d(x) = d(l) + s (d(p) - d(l)) = 0).
   0 vertices when p is not beyond the portal. */
static int project_light(const struct antishadow *a, struct vec3 p, struct polygon *out)
{
    double dp = plane_distance(&a->portal_plane, p);
    if (!(dp > 0.0)) {
        out->n = 0;
        return 0;
    }
    for (int i = 0; i < a->light.n; ++i) {
        struct vec3 l = a->light.v[i];
        double dl = plane_distance(&a->portal_plane, l); /* < 0 */
        double s = dl / (dl - dp);                       /* fraction of the way from l to p */
        out->v[i] = vec3_madd(l, vec3_sub(p, l), s);
    }
    out->n = a->light.n;
    return out->n;
}

/* The anti-penumbra's visible polygon for a box pair: the light's
   projection x(l) = (1 - s) l + s p (s the same for every vertex, the
   planes being parallel) is the light's rectangle scaled about p, so in the
   portal's frame its extent is the light's, scaled, and clipping it to the
   portal intersects intervals. The corners keep the light's winding, as
   Sutherland-Hodgman's output does. */
static int box_visible(const struct antishadow_box *b, const struct plane *portal_plane, struct vec3 p,
                       struct polygon *out, bool *simple)
{
    *simple = false;
    double dp = plane_distance(portal_plane, p);
    out->n = 0;
    if (!(dp > 0.0)) return 0;
    double s = b->light_dist / (b->light_dist - dp), t = 1.0 - s;
    struct vec3 r = vec3_sub(p, b->origin);
    double pu = s * vec3_dot(r, b->u), pw = s * vec3_dot(r, b->w);
    double u0 = fm_fmax(t * b->lo_u + pu, 0.0), u1 = fm_fmin(t * b->hi_u + pu, b->len_u);
    double w0 = fm_fmax(t * b->lo_w + pw, 0.0), w1 = fm_fmin(t * b->hi_w + pw, b->len_w);
    if (!(u1 > u0) || !(w1 > w0)) return 0;
    const double cu[4] = { u0, u1, u1, u0 }, cw[4] = { w0, w0, w1, w1 };
    for (int i = 0; i < 4; ++i) {
        int k = b->flip ? 3 - i : i;
        out->v[i] = vec3_add(b->origin, vec3_add(vec3_scale(b->u, cu[k]), vec3_scale(b->w, cw[k])));
    }
    out->n = 4;
    double lo = fm_fmin(u1 - u0, w1 - w0), hi = fm_fmax(u1 - u0, w1 - w0);
    double coords = vec3_max_abs(b->origin) + b->len_u + b->len_w;
    /* antishadow.h: ANTISHADOW_BOX_SIMPLE_ASPECT. */
    *simple = lo > ANTISHADOW_BOX_SIMPLE_ASPECT * hi && lo > ANTISHADOW_BOX_SIMPLE_ROUNDING * coords;
    return 4;
}

int antishadow_visible_polygon_in(const struct antishadow *a, struct vec3 p, enum region region, struct polygon *out)
{
    bool simple;
    return antishadow_visible_polygon_known(a, p, region, out, &simple);
}

int antishadow_visible_polygon_known(const struct antishadow *a, struct vec3 p, enum region region, struct polygon *out,
                                     bool *simple)
{
    *simple = false;
    switch (region) {
    case REGION_OUTSIDE:
    case REGION_INSIDE: /* the light's side: no direction crosses the portal */
        out->n = 0;
        return 0;
    case REGION_ANTI_UMBRA:
        return project_light(a, p, out);
    case REGION_ANTI_ANTUMBRA:
        out->n = a->portal.n;
        memcpy(out->v, a->portal.v, (size_t)a->portal.n * sizeof out->v[0]);
        return out->n;
    case REGION_ANTI_PENUMBRA: {
        if (a->box.valid) return box_visible(&a->box, &a->portal_plane, p, out, simple);
        struct polygon projected;
        if (project_light(a, p, &projected) == 0) {
            out->n = 0;
            return 0;
        }
        return polygon_clip_by_plane_list(&projected, a->portal_clip, a->n_portal_clip, out);
    }
    }
    out->n = 0;
    return 0;
}

int antishadow_visible_polygon(const struct antishadow *a, struct vec3 p, struct polygon *out)
{
    return antishadow_visible_polygon_in(a, p, antishadow_classify(a, p), out);
}

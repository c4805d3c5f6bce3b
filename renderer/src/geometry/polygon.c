/* polygon.c: convex planar polygons in 3D (see polygon.h). */
#include "geometry/polygon.h"

#include <float.h>

#include "base/fastmath.h"

/* Relative tolerances, as fractions of the polygon's size (bounding-box
   diagonal). Clipping snaps distances below POLYGON_SNAP_REL to the plane so
   that vertices on a clip edge are kept as they are and no sliver vertex is
   created next to them; vertices closer than POLYGON_DUP_REL are merged. */
#define POLYGON_SNAP_REL       1e-12
#define POLYGON_DUP_REL        1e-10
#define POLYGON_CONVEX_REL     1e-9
#define POLYGON_CONTAINS_REL   1e-9
#define POLYGON_DEGENERATE_REL 1e-12

double polygon_size(const struct polygon *poly)
{
    if (poly->n <= 0) return 0.0;
    struct vec3 lo = poly->v[0], hi = poly->v[0];
    for (int i = 1; i < poly->n; ++i) {
        struct vec3 p = poly->v[i];
        lo = vec3_make(fm_fmin(lo.x, p.x), fm_fmin(lo.y, p.y), fm_fmin(lo.z, p.z));
        hi = vec3_make(fm_fmax(hi.x, p.x), fm_fmax(hi.y, p.y), fm_fmax(hi.z, p.z));
    }
    return vec3_length(vec3_sub(hi, lo));
}

/* polygon_size and the largest coordinate magnitude in one pass over the
   vertices: clipping needs both for every plane. */
static void polygon_size_max_abs(const struct polygon *poly, double *size, double *max_abs)
{
    double m = 0.0;
    struct vec3 lo = poly->v[0], hi = poly->v[0];
    for (int i = 0; i < poly->n; ++i) {
        struct vec3 p = poly->v[i];
        m = fm_fmax(m, vec3_max_abs(p));
        lo = vec3_make(fm_fmin(lo.x, p.x), fm_fmin(lo.y, p.y), fm_fmin(lo.z, p.z));
        hi = vec3_make(fm_fmax(hi.x, p.x), fm_fmax(hi.y, p.y), fm_fmax(hi.z, p.z));
    }
    *size = vec3_length(vec3_sub(hi, lo));
    *max_abs = m;
}

/* The fan sum of cross(v_i - v_0, v_{i+1} - v_0) equals Newell's sum of
   cross(v_i, v_{i+1}) for any closed polygon (the translation terms cancel),
   but differences of nearby vertices keep their precision far from the
   origin. */
struct vec3 polygon_area_normal(const struct polygon *poly)
{
    struct vec3 n = vec3_make(0.0, 0.0, 0.0);
    for (int i = 1; i + 1 < poly->n; ++i) {
        struct vec3 a = vec3_sub(poly->v[i], poly->v[0]);
        struct vec3 b = vec3_sub(poly->v[i + 1], poly->v[0]);
        n = vec3_add(n, vec3_cross(a, b));
    }
    return n;
}

/* polygon_normal from the Newell normal n = polygon_area_normal(poly). */
static struct vec3 normal_from_area_normal(const struct polygon *poly, struct vec3 n)
{
    double len = vec3_length(n), size = polygon_size(poly);
    if (!(len > POLYGON_DEGENERATE_REL * size * size) || !isfinite(len)) return vec3_make(0.0, 0.0, 0.0);
    return vec3_scale(n, 1.0 / len);
}

struct vec3 polygon_normal(const struct polygon *poly)
{
    return normal_from_area_normal(poly, polygon_area_normal(poly));
}

void polygon_normal_area(const struct polygon *poly, struct vec3 *normal, double *area)
{
    struct vec3 n = polygon_area_normal(poly);
    *normal = normal_from_area_normal(poly, n);
    *area = 0.5 * vec3_length(n);
}

double polygon_area(const struct polygon *poly)
{
    return 0.5 * vec3_length(polygon_area_normal(poly));
}

/* Area centroid: fan triangles weighted by their area signed along the
   polygon's normal (exact for any simple planar polygon); the vertex mean
   when the polygon has no area. */
struct vec3 polygon_centroid(const struct polygon *poly)
{
    if (poly->n <= 0) return vec3_make(0.0, 0.0, 0.0);
    struct vec3 nrm = polygon_normal(poly);
    struct vec3 sum = vec3_make(0.0, 0.0, 0.0);
    double weight = 0.0;
    for (int i = 1; i + 1 < poly->n; ++i) {
        struct vec3 a = vec3_sub(poly->v[i], poly->v[0]);
        struct vec3 b = vec3_sub(poly->v[i + 1], poly->v[0]);
        double w = vec3_dot(vec3_cross(a, b), nrm);
        sum = vec3_madd(sum, vec3_add(a, b), w / 3.0);
        weight += w;
    }
    if (weight > 0.0) return vec3_madd(poly->v[0], sum, 1.0 / weight);
    struct vec3 mean = vec3_make(0.0, 0.0, 0.0);
    for (int i = 0; i < poly->n; ++i) mean = vec3_add(mean, vec3_sub(poly->v[i], poly->v[0]));
    return vec3_madd(poly->v[0], mean, 1.0 / poly->n);
}

struct plane polygon_plane(const struct polygon *poly)
{
    struct plane pl;
    pl.normal = polygon_normal(poly);
    pl.offset = vec3_dot(pl.normal, polygon_centroid(poly));
    return pl;
}

bool polygon_is_planar(const struct polygon *poly, double rel_tol)
{
    if (poly->n < 3 || poly->n > POLYGON_MAX) return false;
    struct plane pl = polygon_plane(poly);
    if (vec3_length2(pl.normal) == 0.0) return false;
    double tol = rel_tol * polygon_size(poly);
    for (int i = 0; i < poly->n; ++i)
        if (!(fabs(plane_distance(&pl, poly->v[i])) <= tol)) return false;
    return true;
}

/* Area at or below this times the squared diameter is degenerate. */
#define POLYGON_AREA_REL 1e-10

double polygon_diameter(const struct polygon *poly)
{
    double d2 = 0.0;
    for (int i = 0; i < poly->n; ++i)
        for (int j = i + 1; j < poly->n; ++j) {
            double l2 = vec3_length2(vec3_sub(poly->v[i], poly->v[j]));
            if (l2 > d2) d2 = l2;
        }
    return sqrt(d2);
}

enum polygon_defect polygon_check(const struct polygon *poly)
{
    double diam = polygon_diameter(poly);
    if (!(polygon_area(poly) > POLYGON_AREA_REL * diam * diam)) return POLYGON_DEFECT_DEGENERATE;
    if (!polygon_is_planar(poly, POLYGON_PLANARITY_TOLERANCE)) return POLYGON_DEFECT_NOT_PLANAR;
    if (!polygon_is_convex(poly)) return POLYGON_DEFECT_NOT_CONVEX;
    return POLYGON_DEFECT_NONE;
}

/* Why this implies polygon_check's verdict NONE, with d the longest edge
   (the diameter), |x| the largest coordinate and e = 2.2e-16:
   - area = |cross| / 2 >= 5e-3 d^2, far above POLYGON_AREA_REL d^2;
   - convexity: every edge is at least the height (>= 1e-2 d) and every
     vertex is at least the height from the opposite edge's line, against
     POLYGON_CONVEX_REL * size <= 1.8e-9 d;
   - planarity: three points are exactly planar; the computed distances
     err by about (normal error) * d + e |x|, where the normal's relative
     error is about 2 e |x| d / |cross| <= 200 e |x| / d, so by at most
     about 200 e |x| <= 4.4e-9 d, against POLYGON_PLANARITY_TOLERANCE *
     size >= 1e-6 d. */
bool polygon_triangle_is_sound(struct vec3 a, struct vec3 b, struct vec3 c)
{
    struct vec3 ab = vec3_sub(b, a), ac = vec3_sub(c, a), bc = vec3_sub(c, b);
    double d2 = fm_fmax(vec3_length2(ab), fm_fmax(vec3_length2(ac), vec3_length2(bc)));
    double m = fm_fmax(vec3_max_abs(a), fm_fmax(vec3_max_abs(b), vec3_max_abs(c)));
    /* Height over the longest edge >= 1e-2 d <=> |cross| >= 1e-2 d^2. */
    return vec3_length2(vec3_cross(ab, ac)) >= 1e-4 * d2 * d2 && m * m <= 1e10 * d2 && isfinite(m) && d2 > 0.0;
}

/* Every other vertex must lie strictly on the inner side of every edge (the
   side the winding normal turns to). This rejects collinear and repeated
   vertices, reflex corners, and self-intersecting or multiply wound polygons
   (a pentagram has all left turns but fails the edge test). O(n^2), n <= POLYGON_MAX. */
bool polygon_is_convex(const struct polygon *poly)
{
    int n = poly->n;
    if (n < 3 || n > POLYGON_MAX) return false;
    struct vec3 nrm = polygon_normal(poly);
    if (vec3_length2(nrm) == 0.0) return false;
    double tol = POLYGON_CONVEX_REL * polygon_size(poly);
    for (int i = 0; i < n; ++i) {
        struct vec3 a = poly->v[i], e = vec3_sub(poly->v[(i + 1) % n], a);
        double len = vec3_length(e);
        if (!(len > tol)) return false;
        for (int j = 0; j < n; ++j) {
            if (j == i || j == (i + 1) % n) continue;
            double side = vec3_dot(vec3_cross(e, vec3_sub(poly->v[j], a)), nrm) / len;
            if (!(side > tol)) return false;
        }
    }
    return true;
}

/* |a - b| <= tol, with the square root only where the squared length is
   too close to tol^2 to decide (the answer is the square root's, bit for
   bit: clipping runs for every light sample in an anti-penumbra). */
static bool within(struct vec3 a, struct vec3 b, double tol)
{
    double l2 = vec3_length2(vec3_sub(a, b));
    if (l2 > 4.0 * (tol * tol)) return false;
    return sqrt(l2) <= tol;
}

/* Removes consecutive (cyclically) vertices closer than tol, then, if the
   vertex count still exceeds POLYGON_MAX, drops the vertex whose triangle
   with its neighbours has the least area until it fits: the result shrinks
   by that sliver, which only happens for inputs beyond POLYGON_INPUT_MAX. */
static int polygon_finish(const struct vec3 *buf, int m, double tol, struct polygon *out)
{
    struct vec3 tmp[2 * POLYGON_MAX + 2];
    int k = 0;
    for (int i = 0; i < m; ++i) {
        if (k > 0 && within(buf[i], tmp[k - 1], tol)) continue;
        tmp[k++] = buf[i];
    }
    while (k > 1 && within(tmp[k - 1], tmp[0], tol)) --k;
    while (k > POLYGON_MAX) {
        int best = 0;
        double best_area = INFINITY;
        for (int i = 0; i < k; ++i) {
            struct vec3 prev = tmp[(i + k - 1) % k], next = tmp[(i + 1) % k];
            double area = vec3_length(vec3_cross(vec3_sub(tmp[i], prev), vec3_sub(next, tmp[i])));
            if (area < best_area) {
                best_area = area;
                best = i;
            }
        }
        for (int i = best; i + 1 < k; ++i) tmp[i] = tmp[i + 1];
        --k;
    }
    if (k < 3) k = 0;
    for (int i = 0; i < k; ++i) out->v[i] = tmp[i];
    out->n = k;
    return k;
}

/* The split of polygon_clip_plane, once the snapped distances d (n of
   them) put some vertex below the plane. */
static int clip_split(const struct polygon *in, const double *d, double size, struct polygon *out)
{
    int n = in->n;
    struct vec3 buf[2 * POLYGON_MAX + 2];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        int j = i + 1 < n ? i + 1 : 0;
        struct vec3 a = in->v[i], b = in->v[j];
        if (d[i] >= 0.0) buf[m++] = a;
        if ((d[i] > 0.0 && d[j] < 0.0) || (d[i] < 0.0 && d[j] > 0.0)) {
            /* Interpolate from the end point nearer the plane: the smaller
               step keeps the intersection closest to the exact one. */
            double t = d[i] / (d[i] - d[j]);
            buf[m++] = t <= 0.5 ? vec3_madd(a, vec3_sub(b, a), t) : vec3_madd(b, vec3_sub(a, b), 1.0 - t);
        }
    }
    return polygon_finish(buf, m, POLYGON_DUP_REL * size, out);
}

/* Sutherland-Hodgman for one plane. Distances within the snap tolerance
   count as exactly zero, so a vertex on the plane is emitted once as itself
   and an edge is split only where its end points lie strictly on opposite
   sides. Returns `in` itself when no vertex is below the plane (nothing to
   clip), else the clipped polygon written into *out (possibly empty); a
   caller that only reads the result is spared the copy. `in` and `out` may
   be the same polygon. */
static const struct polygon *clip_plane_view(const struct polygon *in, const struct plane *pl, struct polygon *out)
{
    int n = in->n;
    if (n < 3 || n > POLYGON_MAX) {
        out->n = 0;
        return out;
    }
    /* Snapping only moves distances within eps to zero, so a polygon with
       no vertex below the plane is kept whole whatever eps is: the common
       case (a horizon, most portal edges) needs no bounding box. */
    double d[POLYGON_MAX];
    bool all_in = true;
    for (int i = 0; i < n; ++i) {
        d[i] = plane_distance(pl, in->v[i]);
        if (d[i] < 0.0) all_in = false;
    }
    if (!all_in) {
        double size, max_abs;
        polygon_size_max_abs(in, &size, &max_abs);
        double eps =
            POLYGON_SNAP_REL * size + 4.0 * DBL_EPSILON * (max_abs * vec3_max_abs(pl->normal) + fabs(pl->offset));
        all_in = true;
        for (int i = 0; i < n; ++i) {
            if (fabs(d[i]) <= eps) d[i] = 0.0;
            if (d[i] < 0.0) all_in = false;
        }
        if (!all_in) {
            clip_split(in, d, size, out);
            return out;
        }
    }
    return in;
}

int polygon_clip_plane(const struct polygon *in, const struct plane *pl, struct polygon *out)
{
    const struct polygon *r = clip_plane_view(in, pl, out);
    if (r == in) polygon_copy(out, in);
    return out->n;
}

/* The clip polygon's edge planes point inwards: with its winding normal N,
   cross(N, edge) turns left of the edge, which is the inside for either
   winding because N follows the winding. The centroid check guards nearly
   degenerate clip polygons. */
void polygon_clip_planes_init(const struct polygon *clip, struct clip_planes *cp)
{
    cp->n = 0;
    struct vec3 nrm = polygon_normal(clip);
    if (clip->n < 3 || vec3_length2(nrm) == 0.0) return;
    struct vec3 c = polygon_centroid(clip);
    double tol = POLYGON_DUP_REL * polygon_size(clip);
    for (int i = 0; i < clip->n; ++i) {
        struct vec3 a = clip->v[i], e = vec3_sub(clip->v[(i + 1) % clip->n], a);
        if (!(vec3_length(e) > tol)) continue;
        struct plane pl;
        pl.normal = vec3_normalize(vec3_cross(nrm, e));
        pl.offset = vec3_dot(pl.normal, a);
        if (plane_distance(&pl, c) < 0.0) {
            pl.normal = vec3_neg(pl.normal);
            pl.offset = -pl.offset;
        }
        cp->plane[cp->n++] = pl;
    }
}

int polygon_clip_by_plane_list(const struct polygon *subject, const struct plane *planes, int n, struct polygon *out)
{
    if (subject->n < 3 || n == 0) {
        out->n = 0;
        return 0;
    }
    /* The first plane reads the subject, the others clip in place: no copy
       of the whole subject. */
    polygon_clip_plane(subject, &planes[0], out);
    for (int i = 1; i < n && out->n > 0; ++i) polygon_clip_plane(out, &planes[i], out);
    return out->n;
}

int polygon_clip_by_planes(const struct polygon *subject, const struct clip_planes *cp, struct polygon *out)
{
    return polygon_clip_by_plane_list(subject, cp->plane, cp->n, out);
}

int polygon_clip_convex(const struct polygon *subject, const struct polygon *clip, struct polygon *out)
{
    struct clip_planes cp;
    polygon_clip_planes_init(clip, &cp);
    return polygon_clip_by_planes(subject, &cp, out);
}

/* Inclusive of the boundary within POLYGON_CONTAINS_REL of the polygon's
   size, measured in the polygon's plane (the normal component of x - v_i is
   ignored). Valid for convex polygons of either winding. */
bool polygon_contains(const struct polygon *poly, struct vec3 x);

/* Inside test against the edges, given the (unnormalised) Newell normal.
   The tolerance scales with sqrt(|nrm|) = sqrt(2 area), a size measure that
   costs one square root instead of a bounding box per call (this runs for
   every light sample and every pdf evaluation). */
static bool contains_with_normal(const struct polygon *poly, struct vec3 nrm, struct vec3 x)
{
    int n = poly->n;
    double nrm_len2 = vec3_length2(nrm);
    if (n < 3 || nrm_len2 == 0.0) return false;
    double tol = POLYGON_CONTAINS_REL * sqrt(sqrt(nrm_len2));
    for (int i = 0; i < n; ++i) {
        struct vec3 a = poly->v[i], e = vec3_sub(poly->v[i + 1 < n ? i + 1 : 0], a);
        double s = vec3_dot(vec3_cross(e, vec3_sub(x, a)), nrm);
        /* s < -tol |e| |nrm|, compared squared to avoid two square roots. */
        if (s < 0.0 && s * s > tol * tol * vec3_length2(e) * nrm_len2) return false;
    }
    return true;
}

bool polygon_contains(const struct polygon *poly, struct vec3 x)
{
    return contains_with_normal(poly, polygon_area_normal(poly), x);
}

bool polygon_intersect_ray(const struct polygon *poly, struct vec3 o, struct vec3 d, double *t)
{
    struct vec3 nrm = polygon_area_normal(poly);
    double denom = vec3_dot(nrm, d);
    if (vec3_length2(nrm) == 0.0 || !(fabs(denom) > 1e-15 * vec3_length(d) * vec3_length(nrm))) return false;
    double tt = vec3_dot(nrm, vec3_sub(poly->v[0], o)) / denom;
    if (!(tt > 0.0) || !isfinite(tt)) return false;
    if (!contains_with_normal(poly, nrm, vec3_madd(o, d, tt))) return false;
    *t = tt;
    return true;
}

/* Van Oosterom and Strackee (1983): for the triangle a, b, c seen from the
   origin, tan(Omega / 2) = det[a b c] / (|a||b||c| + (a.b)|c| + (a.c)|b| +
   (b.c)|a|). The determinant is formed as a . ((b - a) x (c - a)) from the
   original vertex differences, which keeps it accurate when the triangle is
   small or far (the vectors from o are then nearly parallel). The fan sum is
   signed, so it is also right for non-convex fans. */
double polygon_solid_angle(const struct polygon *poly, struct vec3 o)
{
    if (poly->n < 3) return 0.0;
    struct vec3 a = vec3_sub(poly->v[0], o);
    double la = vec3_length(a), sum = 0.0;
    for (int i = 1; i + 1 < poly->n; ++i) {
        struct vec3 b = vec3_sub(poly->v[i], o), c = vec3_sub(poly->v[i + 1], o);
        double lb = vec3_length(b), lc = vec3_length(c);
        double num = vec3_dot(a, vec3_cross(vec3_sub(poly->v[i], poly->v[0]), vec3_sub(poly->v[i + 1], poly->v[0])));
        double den = la * lb * lc + vec3_dot(a, b) * lc + vec3_dot(a, c) * lb + vec3_dot(b, c) * la;
        sum += 2.0 * atan2(num, den);
    }
    return fabs(sum);
}

/* The edge angles of m edges seen from o, edge k running from a = v_k - o
   to b = v_{k+1} - o: theta_k = atan2(|a x b|, a . b), accurate for short
   and long edges alike, with a x b formed as c_k = a x (v_{k+1} - v_k), as
   vec3_cross forms it, and the weight w_k = -theta_k / |c_k| (0 for an
   edge through o). The minus sign takes the unit normal as b x a: for a
   polygon wound counter-clockwise as seen from o (its winding normal
   pointing back towards o), the vector irradiance Phi then points towards
   the polygon. The one-polygon and the many-polygon forms both use it, so
   that they agree bit for bit. The a and b arrays may overlap (a polygon's
   b is its a shifted by one): they are only read. */
FM_SIMD_CLONES static void edge_terms(const double *restrict xa, const double *restrict ya, const double *restrict za,
                                      const double *restrict xb, const double *restrict yb, const double *restrict zb,
                                      struct vec3 o, int m, double *restrict cx, double *restrict cy,
                                      double *restrict cz, double *restrict w)
{
#pragma omp simd
    for (int k = 0; k < m; ++k) {
        double ax = xa[k] - o.x, ay = ya[k] - o.y, az = za[k] - o.z;
        double bx = xb[k] - o.x, by = yb[k] - o.y, bz = zb[k] - o.z;
        double ex = xb[k] - xa[k], ey = yb[k] - ya[k], ez = zb[k] - za[k];
        double px = ay * ez - az * ey, py = az * ex - ax * ez, pz = ax * ey - ay * ex;
        double len = sqrt(px * px + py * py + pz * pz);
        double theta = fm_atan2(len, ax * bx + ay * by + az * bz);
        cx[k] = px;
        cy[k] = py;
        cz[k] = pz;
        w[k] = len > 0.0 ? -theta / len : 0.0;
    }
}

/* Edges per vectorised block of polygon_vector_irradiance. */
#define IRRADIANCE_BLOCK 8

FM_SIMD_CLONES struct vec3 polygon_vector_irradiance(const struct polygon *poly, struct vec3 o)
{
    struct vec3 phi = vec3_make(0.0, 0.0, 0.0);
    int n = poly->n;
    /* The edges' angles are independent: each block of edges computes
       them in one vectorised loop (fm_atan2 is straight-line arithmetic,
       within 3 ulp of libm's, whose call, with its rounding-mode save and
       restore, was a hot spot of antishadow_exact's profile on multi_lamp,
       where every candidate pair's irradiance weight runs this at every
       point),
       then sums them in edge order. */
    for (int b = 0; b < n; b += IRRADIANCE_BLOCK) {
        int m = n - b < IRRADIANCE_BLOCK ? n - b : IRRADIANCE_BLOCK;
        double x[IRRADIANCE_BLOCK + 1], y[IRRADIANCE_BLOCK + 1], z[IRRADIANCE_BLOCK + 1];
        for (int k = 0; k <= m; ++k) {
            struct vec3 v = poly->v[b + k < n ? b + k : 0];
            x[k] = v.x;
            y[k] = v.y;
            z[k] = v.z;
        }
        double cx[IRRADIANCE_BLOCK], cy[IRRADIANCE_BLOCK], cz[IRRADIANCE_BLOCK], w[IRRADIANCE_BLOCK];
        edge_terms(x, y, z, x + 1, y + 1, z + 1, o, m, cx, cy, cz, w);
        for (int k = 0; k < m; ++k)
            if (w[k] != 0.0) phi = vec3_madd(phi, vec3_make(cx[k], cy[k], cz[k]), w[k]);
    }
    return vec3_scale(phi, 1.0 / (2.0 * M_PI));
}

/* Lambert: the integral of dot(n, w) over the polygon's solid angle is
   pi * dot(n, Phi) (up to the winding sign) once the polygon lies in n's
   closed hemisphere, which the clip against the plane through o ensures.
   Edges in the horizon plane contribute nothing since their plane normal is
   orthogonal to n. */
double polygon_projected_solid_angle(const struct polygon *poly, struct vec3 o, struct vec3 n)
{
    struct plane horizon;
    horizon.normal = n;
    horizon.offset = vec3_dot(n, o);
    struct polygon above;
    if (polygon_clip_plane(poly, &horizon, &above) == 0) return 0.0;
    return M_PI * fabs(vec3_dot(n, polygon_vector_irradiance(&above, o)));
}

/* Edges per vectorised pass of polygon_projected_solid_angle_many; a
   polygon with more edges than this goes the one-polygon way. */
#define IRRADIANCE_MANY_EDGES 64

/* The edges gathered for one pass, and which polygon owns which run. */
struct edge_batch {
    int n_edges, n_polys;
    int out_index[IRRADIANCE_MANY_EDGES]; /* per gathered polygon: its slot in out */
    int first[IRRADIANCE_MANY_EDGES + 1]; /* per gathered polygon: its first edge */
    double xa[IRRADIANCE_MANY_EDGES], ya[IRRADIANCE_MANY_EDGES], za[IRRADIANCE_MANY_EDGES];
    double xb[IRRADIANCE_MANY_EDGES], yb[IRRADIANCE_MANY_EDGES], zb[IRRADIANCE_MANY_EDGES];
};

/* Runs the gathered edges and finishes each polygon as
   polygon_projected_solid_angle does: the edge terms summed in edge order,
   then pi |dot(n, Phi)|. */
static void edge_batch_flush(struct edge_batch *eb, struct vec3 o, struct vec3 n, double *out)
{
    double cx[IRRADIANCE_MANY_EDGES], cy[IRRADIANCE_MANY_EDGES], cz[IRRADIANCE_MANY_EDGES], w[IRRADIANCE_MANY_EDGES];
    /* Pad to whole vectors of 8 with empty edges (results unused), so that
       no edge runs in a scalar remainder loop. */
    int m = (eb->n_edges + 7) & ~7;
    for (int k = eb->n_edges; k < m; ++k) {
        eb->xa[k] = eb->ya[k] = eb->za[k] = 0.0;
        eb->xb[k] = eb->yb[k] = eb->zb[k] = 0.0;
    }
    edge_terms(eb->xa, eb->ya, eb->za, eb->xb, eb->yb, eb->zb, o, m, cx, cy, cz, w);
    eb->first[eb->n_polys] = eb->n_edges;
    for (int i = 0; i < eb->n_polys; ++i) {
        struct vec3 phi = vec3_make(0.0, 0.0, 0.0);
        for (int k = eb->first[i]; k < eb->first[i + 1]; ++k)
            if (w[k] != 0.0) phi = vec3_madd(phi, vec3_make(cx[k], cy[k], cz[k]), w[k]);
        phi = vec3_scale(phi, 1.0 / (2.0 * M_PI));
        out[eb->out_index[i]] = M_PI * fabs(vec3_dot(n, phi));
    }
    eb->n_edges = 0;
    eb->n_polys = 0;
}

void polygon_projected_solid_angle_many(const struct polygon *const *polys, int count, struct vec3 o, struct vec3 n,
                                        double *out)
{
    struct plane horizon;
    horizon.normal = n;
    horizon.offset = vec3_dot(n, o);
    struct edge_batch eb;
    eb.n_edges = 0;
    eb.n_polys = 0;
    for (int i = 0; i < count; ++i) {
        /* Most polygons are wholly above the horizon: read in place. */
        struct polygon clipped;
        const struct polygon *above = clip_plane_view(polys[i], &horizon, &clipped);
        int m = above->n;
        if (m == 0) {
            out[i] = 0.0;
            continue;
        }
        if (m > IRRADIANCE_MANY_EDGES - 8) {
            out[i] = M_PI * fabs(vec3_dot(n, polygon_vector_irradiance(above, o)));
            continue;
        }
        /* Room for m edges and the padding to a whole vector of 8. */
        if (eb.n_edges + m > IRRADIANCE_MANY_EDGES - 8) edge_batch_flush(&eb, o, n, out);
        eb.out_index[eb.n_polys] = i;
        eb.first[eb.n_polys++] = eb.n_edges;
        for (int k = 0; k < m; ++k) {
            struct vec3 a = above->v[k], b = above->v[k + 1 < m ? k + 1 : 0];
            eb.xa[eb.n_edges] = a.x;
            eb.ya[eb.n_edges] = a.y;
            eb.za[eb.n_edges] = a.z;
            eb.xb[eb.n_edges] = b.x;
            eb.yb[eb.n_edges] = b.y;
            eb.zb[eb.n_edges++] = b.z;
        }
    }
    if (eb.n_polys > 0) edge_batch_flush(&eb, o, n, out);
}

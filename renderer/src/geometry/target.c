#include "geometry/target.h"

#include "base/fastmath.h"
#include "geometry/spherical.h"

/* Below this height above the plane relative to the polygon's size (and
   below TARGET_MIN_SOLID_ANGLE, target.h), the spherical parametrisations
   lose precision; area sampling is then safe and nearly optimal (tiny or
   edge-on polygons). */
#define TARGET_MIN_REL_HEIGHT 1e-6

/* Drops vertices that repeat or lie on the segment between their
   neighbours (relative tolerance), preserving order. Writes only the
   vertices in use (a polygon is 2.3 KB; this runs per shading point). */
static void simplify(const struct polygon *in, struct polygon *out)
{
    double scale = 0.0;
    for (int i = 0; i < in->n; ++i) scale = fm_fmax(scale, vec3_length2(vec3_sub(in->v[i], in->v[0])));
    double tol2 = TARGET_COLLINEAR_REL2 * scale * scale + 1e-300;
    polygon_copy(out, in);
    int n = out->n;
    struct vec3 *v = out->v;
    bool changed = true;
    while (changed && n >= 3) {
        changed = false;
        for (int i = 0; i < n && n >= 3; ++i) {
            /* Neighbours by selects: two integer divisions a vertex (%)
               were a large share of this function's time. */
            struct vec3 a = v[i == 0 ? n - 1 : i - 1], b = v[i], c = v[i + 1 == n ? 0 : i + 1];
            struct vec3 cr = vec3_cross(vec3_sub(b, a), vec3_sub(c, b));
            if (vec3_length2(cr) <= tol2 || vec3_length2(vec3_sub(b, a)) <= TARGET_REPEATED_REL2 * scale) {
                for (int k = i; k + 1 < n; ++k) v[k] = v[k + 1];
                --n;
                changed = true;
                break;
            }
        }
    }
    out->n = n;
}

bool target_init_polygon(struct target *t, const struct polygon *poly)
{
    simplify(poly, &t->polygon);
    return t->polygon.n >= 3;
}

bool target_init_polygon_simple(struct target *t, const struct polygon *poly)
{
    polygon_copy(&t->polygon, poly);
    return t->polygon.n >= 3;
}

bool target_init(struct target *t, const struct polygon *poly)
{
    return target_init_polygon(t, poly) && target_finish(t);
}

bool target_finish(struct target *t)
{
    polygon_normal_area(&t->polygon, &t->normal, &t->area);
    if (!(t->area > 0.0)) return false;
    t->min_height = TARGET_MIN_REL_HEIGHT * sqrt(t->area);
    t->is_rectangle = false;
    if (t->polygon.n == 4) {
        const struct vec3 *v = t->polygon.v;
        struct vec3 e0 = vec3_sub(v[1], v[0]), e1 = vec3_sub(v[2], v[1]);
        struct vec3 e2 = vec3_sub(v[3], v[2]), e3 = vec3_sub(v[0], v[3]);
        double tol = 1e-9 * (vec3_length2(e0) + vec3_length2(e1));
        if (fabs(vec3_dot(e0, e1)) <= tol && vec3_length2(vec3_add(e0, e2)) <= tol &&
            vec3_length2(vec3_add(e1, e3)) <= tol)
            t->is_rectangle = sphrect_frame_init(&t->frame, v[0], e0, vec3_neg(e3));
    }
    return true;
}

void target_copy(struct target *dst, const struct target *src)
{
    polygon_copy(&dst->polygon, &src->polygon);
    dst->normal = src->normal;
    dst->area = src->area;
    dst->min_height = src->min_height;
    dst->is_rectangle = src->is_rectangle;
    dst->frame = src->frame;
}

/* Uniform point on a convex polygon: a fan triangle chosen by area, then a
   uniform point in it (square-root warp of the barycentrics). */
static struct vec3 sample_point(const struct target *t, double u_tri, double u, double v)
{
    const struct polygon *poly = &t->polygon;
    double goal = u_tri * t->area, acc = 0.0;
    int k = 1;
    for (; k < poly->n - 2; ++k) {
        double a =
            0.5 * vec3_length(vec3_cross(vec3_sub(poly->v[k], poly->v[0]), vec3_sub(poly->v[k + 1], poly->v[0])));
        if (acc + a > goal) break;
        acc += a;
    }
    double su = sqrt(u), b0 = 1.0 - su, b1 = v * su;
    return vec3_add(vec3_add(vec3_scale(poly->v[0], b0), vec3_scale(poly->v[k], b1)),
                    vec3_scale(poly->v[k + 1], 1.0 - b0 - b1));
}

static bool to_point(struct vec3 p, struct vec3 y, struct target_point *out)
{
    struct vec3 d = vec3_sub(y, p);
    double dist = vec3_length(d);
    if (!(dist > 0.0)) return false;
    out->y = y;
    out->dist = dist;
    out->wi = vec3_scale(d, 1.0 / dist);
    return true;
}

static double area_density(const struct target *t, struct vec3 wi, double dist)
{
    double cos_t = fabs(vec3_dot(wi, t->normal));
    if (!(cos_t > 0.0)) return 0.0;
    return dist * dist / (t->area * cos_t);
}

bool target_sample_area(const struct target *t, struct vec3 p, double u_tri, double u, double v,
                        struct target_point *out)
{
    if (!to_point(p, sample_point(t, u_tri, u, v), out)) return false;
    out->pdf_sa = area_density(t, out->wi, out->dist);
    return out->pdf_sa > 0.0 && isfinite(out->pdf_sa);
}

double target_pdf_area(const struct target *t, struct vec3 p, struct vec3 wi)
{
    double dist;
    if (!polygon_intersect_ray(&t->polygon, p, wi, &dist)) return 0.0;
    return area_density(t, wi, dist);
}

/* The decision shared by sampling and pdf: the solid angle subtended, or 0
   when area sampling must be used instead. */
static double usable_solid_angle(const struct target *t, struct vec3 p, struct sphrect *r, struct sphpoly *sp)
{
    if (!target_above_min_height(t, p)) return 0.0;
    double omega = 0.0;
    if (t->is_rectangle) {
        if (sphrect_init_frame(r, &t->frame, p)) omega = r->solid_angle;
    } else if (sphpoly_init(sp, &t->polygon, p)) {
        omega = sp->solid_angle;
    }
    return omega >= TARGET_MIN_SOLID_ANGLE ? omega : 0.0;
}

/* A spherical-rectangle sample as a target point, shared by the one-point
   and the many-point samplers. */
static bool rect_point(struct vec3 p, struct vec3 wi, double dist, double pdf, struct target_point *out)
{
    if (!(pdf > 0.0)) return false;
    out->wi = wi;
    out->dist = dist;
    out->y = vec3_madd(p, wi, dist);
    out->pdf_sa = pdf;
    return true;
}

bool target_sample_solid_angle(const struct target *t, struct vec3 p, double u_tri, double u, double v,
                               struct target_point *out)
{
    struct sphrect r;
    struct sphpoly sp;
    double omega = usable_solid_angle(t, p, &r, &sp);
    if (omega == 0.0) return target_sample_area(t, p, u_tri, u, v, out);
    if (t->is_rectangle) {
        double dist;
        bool by_area;
        struct vec3 wi = sphrect_sample_dir(&r, u, v, &dist);
        return rect_point(p, wi, dist, target_rect_lane_pdf(omega, dist, &by_area), out);
    }
    struct vec3 wi = sphpoly_sample(&sp, u_tri, u, v);
    double dist;
    /* The fan's directions lie inside the polygon up to rounding; a
       direction that grazes past an edge is dropped (measure zero). */
    if (!polygon_intersect_ray(&t->polygon, p, wi, &dist)) return false;
    out->wi = wi;
    out->dist = dist;
    out->y = vec3_madd(p, wi, dist);
    out->pdf_sa = 1.0 / omega;
    return true;
}

/* Lanes per call of sphrect_sample_many (stack arrays, no allocation). */
#define TARGET_MANY_CHUNK 64

void target_sample_solid_angle_many(const struct target *const *t, const struct vec3 *p, const double (*u)[3], int n,
                                    struct target_point *out, bool *ok)
{
    for (int b = 0; b < n; b += TARGET_MANY_CHUNK) {
        int m = n - b < TARGET_MANY_CHUNK ? n - b : TARGET_MANY_CHUNK;
        const struct sphrect_frame *frames[TARGET_MANY_CHUNK];
        struct vec3 o[TARGET_MANY_CHUNK], wi[TARGET_MANY_CHUNK];
        double uu[TARGET_MANY_CHUNK], vv[TARGET_MANY_CHUNK], dist[TARGET_MANY_CHUNK], omega[TARGET_MANY_CHUNK];
        int lane_of[TARGET_MANY_CHUNK], lanes = 0;
        for (int i = b; i < b + m; ++i) {
            /* The rectangles above their min_height go to the vectorised
               sampler, everything else the one-point way. */
            const struct target *ti = t[i];
            if (target_rect_lane(ti, p[i])) {
                frames[lanes] = &ti->frame;
                o[lanes] = p[i];
                uu[lanes] = u[i][1];
                vv[lanes] = u[i][2];
                lane_of[lanes++] = i;
            } else {
                ok[i] = target_sample_solid_angle(ti, p[i], u[i][0], u[i][1], u[i][2], &out[i]);
            }
        }
        sphrect_sample_many(frames, o, uu, vv, lanes, wi, dist, omega);
        for (int k = 0; k < lanes; ++k) {
            int i = lane_of[k];
            bool by_area;
            double pdf = target_rect_lane_pdf(omega[k], dist[k], &by_area);
            if (by_area) ok[i] = target_sample_area(t[i], p[i], u[i][0], u[i][1], u[i][2], &out[i]);
            else ok[i] = rect_point(p[i], wi[k], dist[k], pdf, &out[i]);
        }
    }
}

double target_pdf_solid_angle(const struct target *t, struct vec3 p, struct vec3 wi)
{
    double dist;
    if (!polygon_intersect_ray(&t->polygon, p, wi, &dist)) return 0.0;
    struct sphrect r;
    struct sphpoly sp;
    double omega = usable_solid_angle(t, p, &r, &sp);
    if (omega == 0.0) return area_density(t, wi, dist);
    return 1.0 / omega;
}

/* target.h: a convex planar polygon prepared for sampling directions from a
   shading point, by area or by solid angle, with the matching pdfs. Lights,
   portals and the clipped visible part of a light are all targets, so every
   strategy shares one sampling and one pdf code path per technique.
   It knows nothing of lights or portals as such, only the polygon it was
   built from. */
#ifndef TARGET_H
#define TARGET_H

#include <stdbool.h>

#include "geometry/polygon.h"
#include "geometry/spherical.h"
#include "base/vec.h"

/* What target_init_polygon's simplification drops, with size^2 the
   polygon's largest squared distance from its first vertex: a vertex whose
   two edges have a squared cross product below TARGET_COLLINEAR_REL2 size^4
   (collinear), or whose edge from the previous vertex has a squared length
   below TARGET_REPEATED_REL2 size^2 (repeated). */
#define TARGET_COLLINEAR_REL2 1e-20
#define TARGET_REPEATED_REL2  1e-24
/* Below this solid angle (sr) the spherical parametrisations lose
   precision: area sampling takes the point instead (target.c). */
#define TARGET_MIN_SOLID_ANGLE 1e-7

struct target {
    struct polygon polygon;
    struct vec3 normal; /* unit, by winding */
    double area;
    double min_height;          /* below this distance from the plane, area sampling */
    bool is_rectangle;          /* spherical-rectangle sampling applies */
    struct sphrect_frame frame; /* the rectangle's frame when is_rectangle */
};

/* Prepares poly (convex, planar, >= 3 vertices). Collinear and repeated
   vertices, as clipping leaves them, are removed first so that a clipped
   rectangle is recognised as one. False for a degenerate polygon. */
bool target_init(struct target *t, const struct polygon *poly);
/* target_init in two steps, for a caller that needs only the simplified
   polygon of most targets it makes (a portal strategy's pair weights) and
   prepares the others for sampling: target_init_polygon simplifies poly
   into t->polygon (false with fewer than 3 vertices left); target_finish
   then does the rest (false for a degenerate polygon). Together they are
   target_init. */
bool target_init_polygon(struct target *t, const struct polygon *poly);
/* target_init_polygon for a polygon known to have no collinear or repeated
   vertex (antishadow_visible_polygon_known), which simplification would
   copy unchanged: copied without the scan. */
bool target_init_polygon_simple(struct target *t, const struct polygon *poly);
bool target_finish(struct target *t);
/* *dst = *src, copying only the polygon's vertices in use. */
void target_copy(struct target *dst, const struct target *src);

/* A direction towards the target and the point where it meets the target. */
struct target_point {
    struct vec3 wi; /* unit, from p */
    struct vec3 y;  /* point on the target */
    double dist;    /* |y - p| */
    double pdf_sa;  /* solid-angle density of wi */
};

/* Uniform point by area; pdf dist^2 / (area |cos|). */
bool target_sample_area(const struct target *t, struct vec3 p, double u_tri, double u, double v,
                        struct target_point *out);
/* Density of wi under target_sample_area; 0 when wi misses the target. */
double target_pdf_area(const struct target *t, struct vec3 p, struct vec3 wi);

/* Uniform in solid angle (spherical rectangle or spherical-triangle fan);
   falls back to area sampling where solid-angle sampling is numerically
   unsafe; target_pdf_solid_angle takes the same decision. */
bool target_sample_solid_angle(const struct target *t, struct vec3 p, double u_tri, double u, double v,
                               struct target_point *out);
double target_pdf_solid_angle(const struct target *t, struct vec3 p, struct vec3 wi);
/* target_sample_solid_angle for n independent lanes (target t[i] from p[i]
   with the uniforms u[i]), out[i] and ok[i] as it would give them, bit for
   bit; the rectangles among them are sampled in vectorised batches. */
void target_sample_solid_angle_many(const struct target *const *t, const struct vec3 *p, const double (*u)[3], int n,
                                    struct target_point *out, bool *ok);

/* Whether p is far enough from the target's plane for solid-angle sampling
   (below min_height: area sampling). */
static inline bool target_above_min_height(const struct target *t, struct vec3 p)
{
    return !(fabs(vec3_dot(vec3_sub(p, t->polygon.v[0]), t->normal)) <= t->min_height);
}

/* The rectangle lanes of target_sample_solid_angle_many, for a caller that
   runs sphrect_sample_many on its own lanes (strategy_sample_many):
   target_rect_lane says whether t is sampled from p as a spherical
   rectangle, i.e. by sphrect_sample_many's lane (t->frame, p, u[1], u[2]);
   target_rect_lane_pdf turns that lane's solid angle and distance into the
   direction's density, as target_sample_solid_angle would give it, or
   returns 0 when the sample is dropped (*by_area false) or area sampling
   must take the lane instead (*by_area true). Inline: the light strategy
   asks it for every shading point. */
static inline bool target_rect_lane(const struct target *t, struct vec3 p)
{
    return t->is_rectangle && target_above_min_height(t, p);
}
static inline double target_rect_lane_pdf(double solid_angle, double dist, bool *by_area)
{
    /* usable_solid_angle's rule: too small a solid angle (or a refused
       rectangle, solid angle 0) samples by area; a sample needs a
       positive, finite distance. */
    *by_area = !(solid_angle >= TARGET_MIN_SOLID_ANGLE);
    if (*by_area || !(dist > 0.0) || !isfinite(dist)) return 0.0;
    return 1.0 / solid_angle;
}

#endif

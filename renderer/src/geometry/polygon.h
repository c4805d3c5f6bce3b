/* polygon.h: convex planar polygons in 3D: the shape of every area light and
   portal. Area, plane, validity checks, Sutherland-Hodgman clipping, ray
   intersection, solid angle and the Lambert/Arvo vector irradiance.
   Pure geometry: no rays against the scene, no lights, no random state. */
#ifndef POLYGON_H
#define POLYGON_H

#include <stdbool.h>

#include "base/vec.h"

/* Clipping a convex n-gon by a convex m-gon yields at most n + m vertices;
   lights and portals have at most POLYGON_INPUT_MAX so that a light clipped
   to a portal (64) and then to a horizon plane (65) fits. 32 vertices let a
   regular polygon fit a round opening to 0.5% of its radius. */
#define POLYGON_INPUT_MAX 32
#define POLYGON_MAX       96

/* Only v[0..n) is meaningful: the struct is 2.3 KB, so hot paths copy a
   polygon with polygon_copy (its n vertices), never by assignment. */
struct polygon {
    int n;
    struct vec3 v[POLYGON_MAX];
};

/* *dst = *src for the vertices in use (dst and src may be the same). */
static inline void polygon_copy(struct polygon *dst, const struct polygon *src)
{
    if (dst == src) return;
    dst->n = src->n;
    for (int i = 0; i < src->n; ++i) dst->v[i] = src->v[i];
}

/* Plane dot(normal, x) = offset, normal unit length. */
struct plane {
    struct vec3 normal;
    double offset;
};

static inline double plane_distance(const struct plane *pl, struct vec3 x)
{
    return vec3_dot(pl->normal, x) - pl->offset;
}

/* Newell's normal: length is twice the area, direction by right-hand winding. */
struct vec3 polygon_area_normal(const struct polygon *poly);
/* Unit normal by right-hand winding (zero vector when degenerate). */
struct vec3 polygon_normal(const struct polygon *poly);
double polygon_area(const struct polygon *poly);
/* polygon_normal and polygon_area from one Newell sum (the same bits). */
void polygon_normal_area(const struct polygon *poly, struct vec3 *normal, double *area);
struct vec3 polygon_centroid(const struct polygon *poly);
/* Diagonal of the bounding box: the size that relative tolerances scale with. */
double polygon_size(const struct polygon *poly);
/* The supporting plane, oriented by the winding. */
struct plane polygon_plane(const struct polygon *poly);

/* Input validity; tolerances are relative to the polygon's size. */
bool polygon_is_planar(const struct polygon *poly, double rel_tol);
/* Strictly convex in its plane, consistently wound, no repeated vertices. */
bool polygon_is_convex(const struct polygon *poly);

/* How far a vertex of a light, portal or face may lie from its polygon's
   plane, as a fraction of the polygon's size (polygon_check). Relative, so
   that a scene in millimetres validates like one in metres. */
#define POLYGON_PLANARITY_TOLERANCE 1e-6

/* What polygon_check finds wrong, the first in this order. */
enum polygon_defect {
    POLYGON_DEFECT_NONE,
    POLYGON_DEFECT_DEGENERATE, /* no area for its diameter (area <= 1e-10 diameter^2) */
    POLYGON_DEFECT_NOT_PLANAR, /* a vertex off the plane by more than POLYGON_PLANARITY_TOLERANCE */
    POLYGON_DEFECT_NOT_CONVEX  /* not strictly convex in its plane (polygon_is_convex) */
};
/* The one validity test of an input polygon (config and antishadow): non-zero
   area, planar and convex, all relative to its size. Callers turn the
   defect into their message. */
enum polygon_defect polygon_check(const struct polygon *poly);
/* A quick sufficient test that polygon_check finds no defect in the
   triangle a, b, c (one cross product instead of its O(n^2) walk): true
   when the triangle is finite, its height over its longest edge is at least
   1% of that edge, and no coordinate exceeds 1e5 times that edge (so that
   rounding stays far inside polygon_check's tolerances). False says
   nothing: ask polygon_check. For the loops over a mesh's triangles. */
bool polygon_triangle_is_sound(struct vec3 a, struct vec3 b, struct vec3 c);
/* The largest distance between two vertices (0 for fewer than two). */
double polygon_diameter(const struct polygon *poly);

/* Sutherland-Hodgman against one plane: keeps the part with
   plane_distance >= 0. Returns the number of output vertices (0 if empty). */
int polygon_clip_plane(const struct polygon *in, const struct plane *pl, struct polygon *out);
/* Clips `subject` by the convex `clip` polygon, both in (nearly) the same
   plane: keeps subject inside every edge of clip. Winding of clip may be
   either way. Returns the vertex count of `out` (0 when they do not overlap). */
int polygon_clip_convex(const struct polygon *subject, const struct polygon *clip, struct polygon *out);

/* The inward edge planes of a convex clip polygon (perpendicular to its
   plane), precomputed once when the same polygon clips many subjects. */
struct clip_planes {
    int n;
    struct plane plane[POLYGON_MAX];
};
void polygon_clip_planes_init(const struct polygon *clip, struct clip_planes *cp);
/* polygon_clip_convex with prepared planes. */
int polygon_clip_by_planes(const struct polygon *subject, const struct clip_planes *cp, struct polygon *out);
/* The same with the n planes stored elsewhere (an antishadow's block). */
int polygon_clip_by_plane_list(const struct polygon *subject, const struct plane *planes, int n, struct polygon *out);

/* Ray o + t d (d need not be unit) against the polygon: true with *t when the
   ray hits the polygon's interior at t > 0 (either side). */
bool polygon_intersect_ray(const struct polygon *poly, struct vec3 o, struct vec3 d, double *t);
/* Point-in-polygon for a point on (or projected onto) the polygon's plane. */
bool polygon_contains(const struct polygon *poly, struct vec3 x);

/* Solid angle subtended by the polygon from o, in steradians (>= 0). */
double polygon_solid_angle(const struct polygon *poly, struct vec3 o);
/* Lambert's vector irradiance (Arvo 1995): Phi = 1/(2 pi) sum_i theta_i u_i,
   with theta_i the angle subtended by edge i (from v_i to v_{i+1}) and u_i the
   unit normal of the plane through o and that edge, taken as
   u_i = normalize((v_{i+1} - o) x (v_i - o)). So for a polygon wound
   counter-clockwise as seen from o (its winding normal points back towards
   o) Phi points towards the polygon and dot(n, Phi) >= 0 for a receiver
   normal n facing it; the opposite winding flips Phi. Irradiance from a uniform emitter of radiance L at a receiver
   with normal n is E = pi * L * |dot(n, Phi)| when the whole polygon is above
   the receiver's horizon; this function does not clip to the horizon. */
struct vec3 polygon_vector_irradiance(const struct polygon *poly, struct vec3 o);
/* Cosine-weighted solid angle integral over the polygon seen from o with
   receiver normal n: integral of max(0, dot(n, w)) dw over directions w
   towards the polygon; clips the polygon to n's hemisphere first. Equals
   E / L for a uniform emitter. */
double polygon_projected_solid_angle(const struct polygon *poly, struct vec3 o, struct vec3 n);
/* polygon_projected_solid_angle of count polygons from the same o and n:
   out[i] is what it gives for polys[i], bit for bit. The edges of all the
   polygons go through one vectorised loop, so that their angles' long
   dependency chains overlap instead of running one short polygon at a
   time. */
void polygon_projected_solid_angle_many(const struct polygon *const *polys, int count, struct vec3 o, struct vec3 n,
                                        double *out);

#endif

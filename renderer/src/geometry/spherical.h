/* spherical.h: solid-angle sampling of planar shapes seen from a point:
   spherical rectangles (Urena, Fajardo, King 2013), spherical triangles
   (Arvo 1995), and convex polygons as fans of spherical triangles chosen by
   solid angle. Each sampler's pdf is 1 / solid angle inside the shape.
   Pure geometry and sampling of one shape: no lights, no scene, no random
   state. */
#ifndef SPHERICAL_H
#define SPHERICAL_H

#include <stdbool.h>

#include "geometry/polygon.h"
#include "base/vec.h"

/* A rectangle's own frame, independent of the viewpoint: corner s, unit
   edge directions x, y and normal z = x cross y, edge lengths. Prepared once
   per rectangle so that the per-point set-up below needs no normalisation. */
struct sphrect_frame {
    struct vec3 corner, x, y, z;
    double ex_len, ey_len;
};

/* False for a degenerate (zero or non-finite) edge; ex and ey must be
   perpendicular. */
bool sphrect_frame_init(struct sphrect_frame *f, struct vec3 s, struct vec3 ex, struct vec3 ey);

/* Spherical rectangle seen from o. Precomputation per shading point. */
struct sphrect {
    struct vec3 o, x, y, z;    /* local frame at o (z flipped towards o's side) */
    double z0, x0, y0, x1, y1; /* rectangle in that frame */
    double b0, b1;             /* Urena's constants */
    double one_minus_b0sq;     /* 1 - b0^2 = z0^2 / (z0^2 + y0^2) */
    double cos_k, sin_k;       /* Urena's k = 2 pi - g2 - g3, as cosine and sine */
    double solid_angle;
};

/* False when o lies (nearly) in the rectangle's plane or the solid angle is
   below 1e-12 sr, too small to sample robustly (callers then fall back to
   area sampling); o may be on either side. The mapping's positions carry a
   relative error of ~1e-16 / solid angle (1e-10 at 1e-6 sr). */
bool sphrect_init_frame(struct sphrect *r, const struct sphrect_frame *f, struct vec3 o);
/* The same from the corner s and the edge vectors ex, ey (perpendicular). */
bool sphrect_init(struct sphrect *r, struct vec3 o, struct vec3 s, struct vec3 ex, struct vec3 ey);
/* Point on the rectangle for (u, v) in [0,1)^2; the direction from o to it
   has solid-angle pdf 1 / r->solid_angle. */
struct vec3 sphrect_sample(const struct sphrect *r, double u, double v);
/* The same sample as the unit direction from o and the distance to the
   point: cheaper than forming the point and normalising. */
struct vec3 sphrect_sample_dir(const struct sphrect *r, double u, double v, double *dist);

/* The same sample for n independent lanes at once: lane i is the rectangle
   *frames[i] seen from o[i], sampled at (u[i], v[i]); it gives the direction
   wi[i], the distance dist[i] and solid_angle[i], which is 0 where
   sphrect_init_frame would refuse (wi and dist are then meaningless).
   Bit-identical to sphrect_init_frame + sphrect_sample_dir lane by lane, and
   vectorised (AVX-512, AVX2 or SSE2, chosen at load time). */
void sphrect_sample_many(const struct sphrect_frame *const *frames, const struct vec3 *o, const double *u,
                         const double *v, int n, struct vec3 *wi, double *dist, double *solid_angle);

/* Spherical triangle with unit vertex directions a, b, c. */
struct sphtri {
    struct vec3 a, b, c;
    double area;  /* solid angle */
    double alpha; /* interior angle at a */
    double sin_alpha, cos_alpha;
    double cos_c; /* cosine of the arc from a to b */
};

/* False for a degenerate triangle (area below 1e-16 sr). Either winding.
   The sampler stays accurate for tiny triangles (see spherical.c). */
bool sphtri_init(struct sphtri *t, struct vec3 a, struct vec3 b, struct vec3 c);
/* Unit direction for (u, v) in [0,1)^2, pdf 1 / t->area (Arvo 1995). */
struct vec3 sphtri_sample(const struct sphtri *t, double u, double v);

/* Convex polygon seen from o as a fan of spherical triangles; a triangle is
   chosen with probability proportional to its solid angle. */
struct sphpoly {
    int n; /* number of usable triangles */
    struct sphtri tri[POLYGON_MAX - 2];
    double cdf[POLYGON_MAX - 2]; /* normalised, cdf[n-1] == 1 */
    double solid_angle;
};

/* False when o is (nearly) in the polygon's plane or the polygon subtends
   less than 1e-12 sr. The polygon must be convex (the fan is taken from
   vertex 0); degenerate fan triangles are skipped. */
bool sphpoly_init(struct sphpoly *sp, const struct polygon *poly, struct vec3 o);
/* Unit direction from o; pdf 1 / sp->solid_angle. u_select picks a triangle
   with probability proportional to its solid angle, then (u, v) sample that
   triangle (Arvo's map, area-preserving in (u, v)); the three uniforms must
   be independent. */
struct vec3 sphpoly_sample(const struct sphpoly *sp, double u_select, double u, double v);

#endif

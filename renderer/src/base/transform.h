/* transform.h: affine transforms of points (the `transform:` of shapes,
   lights and portals): translate, scale, rotate, a general matrix, their
   composition, and the inverse transpose that normals follow. Pure math,
   no I/O. */
#ifndef TRANSFORM_H
#define TRANSFORM_H

#include <stdbool.h>

#include "base/vec.h"

/* x' = A x + t, stored as the top three rows of the 4x4 row-major matrix
   [A t; 0 0 0 1]. */
struct transform {
    double m[3][4];
};

/* A transform whose linear part has |det A| at most this fraction of the
   product of its row lengths (Hadamard's bound, 1 for a rotation) is
   singular: it flattens space, and with it the polygons it maps. */
#define TRANSFORM_SINGULAR_TOL 1e-12

struct transform transform_identity(void);
struct transform transform_translate(struct vec3 t);
/* Scale by s.x, s.y, s.z along the axes. */
struct transform transform_scale(struct vec3 s);
/* Right-handed rotation by angle_deg degrees about axis (any length > 0):
   seen from the tip of the axis, counter-clockwise. Multiples of 90 degrees
   are exact. False when the axis is zero or not finite. */
bool transform_rotate(struct vec3 axis, double angle_deg, struct transform *out);
/* From 16 numbers, row-major. False unless the last row is 0, 0, 0, 1
   (only affine transforms keep planar polygons planar and convex). */
bool transform_from_rows(const double rows[16], struct transform *out);

/* The transform that applies `first`, then `then`: then * first. */
struct transform transform_then(const struct transform *first, const struct transform *then);

static inline struct vec3 transform_point(const struct transform *t, struct vec3 p)
{
    const double(*m)[4] = t->m;
    return vec3_make(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                     m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                     m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]);
}

/* det A of the linear part: negative for a mirroring transform, which
   reverses the winding of the polygons it maps. */
double transform_det(const struct transform *t);
/* |det A| <= TRANSFORM_SINGULAR_TOL times the product of A's row lengths
   (or a row is zero, or something is not finite). */
bool transform_is_singular(const struct transform *t);
/* The unit normal of a surface with unit normal n after the transform:
   the inverse transpose of A applied to n, normalised (cofactor form, so
   no division by det). Zero for a singular transform. */
struct vec3 transform_normal(const struct transform *t, struct vec3 n);

#endif

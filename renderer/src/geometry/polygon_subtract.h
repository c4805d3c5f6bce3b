/* polygon_subtract.h: Boolean operations on coplanar convex polygons that
   the automatic portals need: the part of a convex polygon that a triangle
   does not cover, as convex pieces, and the merge of two pieces whose union
   is convex. Pure geometry. */
#ifndef POLYGON_SUBTRACT_H
#define POLYGON_SUBTRACT_H

#include <stdbool.h>

#include "base/vec.h"
#include "geometry/polygon.h"

/* The part of convex `poly` (normal `normal`, unit) not covered by the
   triangle t projected onto poly's plane, as at most three disjoint convex
   pieces written to out: piece k lies outside edge k of the triangle and
   inside its edges before k, so the pieces and the triangle tile poly with
   shared boundaries and no gap. Pieces of area at most min_area are left
   out (rounding debris). Returns the count; a degenerate triangle covers
   nothing (poly comes back whole). poly has at most POLYGON_MAX - 3
   vertices. */
int polygon_subtract_triangle(const struct polygon *poly, struct vec3 normal, const struct vec3 t[3], double min_area,
                              struct polygon out[3]);

/* The convex union of coplanar convex a and b, which must not overlap,
   when that union is convex (its convex hull has the area of a plus b
   within rel_tol, above or below, and holds every corner of both within
   tol) and has at most max_vertices corners once vertices within tol of
   the line of their neighbours are dropped. False otherwise: a merge never
   loses area. */
bool polygon_merge_convex(const struct polygon *a, const struct polygon *b, struct vec3 normal, double tol,
                          double rel_tol, int max_vertices, struct polygon *out);

#endif

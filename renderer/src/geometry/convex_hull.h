/* convex_hull.h: the convex hull of a 3D point set (quickhull), as convex
   planar facets: the triangles of the hull that lie in one plane are merged
   into one convex polygon, so that a box comes out as six quadrilaterals.
   Duplicate points, points on edges and faces, and nearly coplanar
   triangles are absorbed by one distance tolerance relative to the size of
   the set. Pure geometry: single-threaded, deterministic (the same points
   in the same order give the same facets, bit for bit). */
#ifndef CONVEX_HULL_H
#define CONVEX_HULL_H

#include <stdbool.h>

#include "base/error.h"
#include "base/vec.h"
#include "geometry/polygon.h"

/* One facet: a strictly convex polygon of input points, counter-clockwise
   seen from outside, and its plane with the outward unit normal; every
   input point lies at plane distance <= tol. */
struct hull_facet {
    struct plane plane;
    int first, n; /* its vertices: index[first .. first + n) (input point indices) */
};

struct convex_hull {
    int n_facets;
    struct hull_facet *facets; /* owned */
    int n_index;
    int *index;  /* owned */
    double tol;  /* the distance tolerance used: 1e-9 times the diagonal of the points' bounding box */
    double size; /* that diagonal */
};

/* The hull of points[0..n). Fails with a message when fewer than four
   points span a volume (all points collinear or coplanar within tol), on
   non-finite points, or out of memory; out is then left empty. */
bool convex_hull_build(const struct vec3 *points, int n, struct convex_hull *out, struct error *err);
void convex_hull_free(struct convex_hull *h);

/* The vertices of facet f as a polygon, when it has at most POLYGON_MAX. */
bool convex_hull_facet_polygon(const struct convex_hull *h, const struct vec3 *points, int f, struct polygon *out);

/* The 2D convex hull (Andrew's monotone chain) of points[0..n) seen along
   the unit normal: the indices of its corners, counter-clockwise about the
   normal, into out (room for n); points closer than tol to the line of
   their neighbours are dropped, so the result is strictly convex. Returns
   the count (< 3 when the points span no area). */
int convex_hull_2d(const struct vec3 *points, int n, struct vec3 normal, double tol, int *out);

#endif

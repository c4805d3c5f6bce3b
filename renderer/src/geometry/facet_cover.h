/* facet_cover.h: which parts of a convex hull's facet the surfaces around
   it leave open, for `portals: auto` (scene/portal_finder.h). Pure
   geometry over triangles, a hull and the light's points: the finder
   gathers the triangles and decides what the open parts become.

   Two proofs, both complete (a part is called covered only when every
   segment through it is blocked; anything unproven stays open):
   facet_uncovered_part subtracts the triangles lying in the facet
   (facet_cover.c), and facet_layer_covers shows that a layer of surface
   just under the facet closes it (facet_layer.c). Single-threaded and
   deterministic: the same input gives the same pieces, bit for bit. */
#ifndef FACET_COVER_H
#define FACET_COVER_H

#include <stdbool.h>

#include "base/vec.h"
#include "geometry/convex_hull.h"
#include "geometry/polygon.h"

/* A triangle covers a facet when its vertices are within this distance of
   the facet's plane, relative to P's size. */
#define FACET_COVER_REL 1e-8
/* Pieces of a facet smaller than this (relative to P's size squared) are
   rounding debris of the subtraction, not openings. */
#define FACET_DEBRIS_REL 1e-12

/* A growing array of polygons; { 0, 0, NULL } is empty, p is owned (free). */
struct polygon_list {
    int n, cap;
    struct polygon *p;
};
/* Appends a copy of *p. False on memory. */
bool polygon_list_push(struct polygon_list *ps, const struct polygon *p);

/* Facet fi of h (points: the hull's input points) minus every triangle of
   tris[0..n_tris) lying in its plane (within FACET_COVER_REL), appended to
   *out as convex pieces of at most POLYGON_INPUT_MAX corners. False only
   on memory. */
bool facet_uncovered_part(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                          int n_tris, struct polygon_list *out);

/* A sphere holding a triangle: a facet's scan for the triangles near its
   plane rejects a far one with one distance instead of three. */
struct tri_sphere {
    struct vec3 centre;
    double radius;
};
/* The spheres of tris[0..n_tris) into out[0..n_tris): centroids, and radii
   rounded up beyond any rounding of the distances they bound. */
void tri_spheres(const struct vec3 (*tris)[3], int n_tris, struct tri_sphere *out);

/* Whether the surfaces of tris[0..n_tris) just under facet fi of h cover
   it: no unblocked segment from a point of the convex hull of
   light_pts[0..n_light_pts) (strictly inside h) leaves h through it.
   spheres: tri_spheres of tris (they only skip triangles that cannot
   matter, so the answer is the same bit for bit). */
bool facet_layer_covers(const struct convex_hull *h, const struct vec3 *points, int fi, const struct vec3 (*tris)[3],
                        const struct tri_sphere *spheres, int n_tris, const struct vec3 *light_pts, int n_light_pts);

#endif

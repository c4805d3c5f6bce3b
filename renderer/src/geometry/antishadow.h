/* antishadow.h: the antishadow of one light/portal pair: the planes that cut
   space into outside / anti-umbra / anti-penumbra / anti-antumbra, the
   per-point classifier, and the part of the light seen through the portal.

   Exact for convex polygons (3..POLYGON_INPUT_MAX vertices) in any relative
   orientation. Derivation (see antishadow.c): for p beyond the portal, let
   L' be the light projected from p onto the portal plane (the points where
   the segments from p to the light cross it). Then
     anti-umbra      L' inside P    <=> p inside one supporting plane per
                                        portal edge (edge + light vertex);
     anti-antumbra   P inside L'    <=> p beyond one supporting plane per
                                        light edge (edge + portal vertex);
     outside         L', P disjoint <=> p outside some separating plane
                                        (edge of one + vertex of the other,
                                        light and portal on opposite sides),
   and every point on the light's side of the portal plane is outside.
   Pure geometry of one pair: it traces no rays and picks no sampling
   technique (strategy.c does). */
#ifndef ANTISHADOW_H
#define ANTISHADOW_H

#include <stdbool.h>

#include "base/error.h"
#include "geometry/polygon.h"
#include "base/vec.h"

/* The region classes of a point relative to one light: the antishadow's
   four, which antishadow_classify returns, and REGION_INSIDE, which it
   never returns: p lies on the light's side of every portal plane of its
   light, within the light's shade box (strategy.h decides it), where the
   light is reached directly, not through a portal. aov.h's classes begin
   with these five. */
enum region { REGION_OUTSIDE, REGION_ANTI_UMBRA, REGION_ANTI_PENUMBRA, REGION_ANTI_ANTUMBRA, REGION_INSIDE };

/* One separating plane per portal edge and at most two per light edge. */
#define ANTISHADOW_SEPARATING_MAX (3 * POLYGON_INPUT_MAX)

/* A rectangular portal and a light that is a rectangle in a parallel
   plane with its edges along the portal's (the lamps of the shipped
   scenes): seen from any point, the light projects onto the portal plane
   as a rectangle with the same edge directions, so clipping it to the
   portal is an intersection of intervals in the portal's frame. */
struct antishadow_box {
    bool valid;
    struct vec3 origin, u, w;      /* portal corner, unit edge directions */
    double len_u, len_w;           /* the portal is [0, len_u] x [0, len_w] */
    double lo_u, hi_u, lo_w, hi_w; /* the light's extent in the same frame */
    double light_dist;             /* the light plane's distance from the portal plane (< 0) */
    bool flip;                     /* the light winds clockwise about u x w */
};

/* The vertices of one of the pair's polygons (v[0..n), as given). */
struct antishadow_vertices {
    int n;
    const struct vec3 *v;
};

/* Every plane is oriented so that its positive side (plane_distance > 0) is
   the side of the region it bounds; distances are in scene units (metres).
   The planes and vertices live in one block sized to what the pair uses
   (`storage`), not in arrays of the largest size: a mesh light has a pair
   per triangle and portal, and arrays of the largest size made most of a
   large scene's memory (docs/performance.md). The struct may be moved (copied
   bitwise) but owns its block: one copy is freed, with antishadow_free. */
struct antishadow {
    struct plane portal_plane;                /* positive beyond the portal, away from the light */
    int n_separating;                         /* p outside if negative for any of them */
    int n_umbra;                              /* anti-umbra if positive for all (one per portal edge) */
    int n_antumbra;                           /* anti-antumbra if positive for all (one per light edge) */
    bool has_antumbra;                        /* false when the portal reaches the light's plane */
    const struct plane *separating;           /* n_separating */
    const struct plane *umbra;                /* n_umbra */
    const struct plane *antumbra;             /* n_antumbra */
    struct antishadow_vertices light, portal; /* copies of the inputs, as given */
    int n_portal_clip;
    const struct plane *portal_clip; /* the portal's inward edge planes, for clipping */
    struct antishadow_box box;       /* the anti-penumbra's clip as intervals, when box.valid */
    void *storage;                   /* owns the arrays above; NULL before a build and after a failed one */
};

/* Precomputes the planes of a light/portal pair (once, at scene load). Both
   polygons must be convex, planar, with 3..POLYGON_INPUT_MAX vertices and
   either winding; the light must lie strictly on one side of the portal's
   plane. False with a message otherwise. Only geometry counts here: a
   one-sided light facing away from its portal is still accepted. *a
   must hold no storage (new, or freed); on failure it holds none. */
bool antishadow_build(const struct polygon *light, const struct polygon *portal, struct antishadow *a,
                      struct error *err);
/* Releases what antishadow_build allocated (a zeroed or failed one holds
   nothing; freeing it is harmless) and leaves *a without storage. */
void antishadow_free(struct antishadow *a);

/* The region of point p (a few dot products, cheapest tests first). Points
   within rounding of a boundary may go either way. */
enum region antishadow_classify(const struct antishadow *a, struct vec3 p);

/* The part of the portal through which p sees the light: the light
   projected from p onto the portal plane (central projection through p),
   clipped to the portal. The directions from p through `out` are exactly the
   directions that reach the light through the portal. Returns the vertex
   count of `out` (0 when p is outside, including the light's side). */
int antishadow_visible_polygon(const struct antishadow *a, struct vec3 p, struct polygon *out);

/* Same, for a caller that already has region = antishadow_classify(a, p):
   the anti-umbra gives the projected light and the anti-antumbra the portal
   without clipping; only the anti-penumbra clips. */
int antishadow_visible_polygon_in(const struct antishadow *a, struct vec3 p, enum region region, struct polygon *out);
/* Same, and *simple tells whether `out` is known to have no collinear or
   repeated vertex (target.h: target_init_polygon_simple), which holds for
   the anti-penumbra's box rectangles that are not slivers: there it saves
   the scan that would find nothing to drop. A box rectangle is simple when
   its shorter side is above ANTISHADOW_BOX_SIMPLE_ASPECT times its longer
   one, far from target.h's TARGET_COLLINEAR_REL2 and TARGET_REPEATED_REL2
   (test_antishadow checks the margins), and above
   ANTISHADOW_BOX_SIMPLE_ROUNDING times the size of the portal's
   coordinates, so that the corners' rounding (~1e-16 of those) cannot
   bring it near them. */
#define ANTISHADOW_BOX_SIMPLE_ASPECT   1e-6
#define ANTISHADOW_BOX_SIMPLE_ROUNDING 1e-9
int antishadow_visible_polygon_known(const struct antishadow *a, struct vec3 p, enum region region, struct polygon *out,
                                     bool *simple);

#endif

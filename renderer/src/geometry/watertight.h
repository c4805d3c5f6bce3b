/* watertight.h: T-junction stitching of the ray-traced surfaces: each face
   whose edges carry vertices of other faces is re-emitted as a fan of
   triangles through those vertices, so that neighbouring faces share whole
   edges with identical endpoints (the only edges Embree's robust mode
   traces without cracks). The surfaces themselves do not change. */
#ifndef WATERTIGHT_H
#define WATERTIGHT_H

#include <stdbool.h>

#include "base/error.h"
#include "base/vec.h"

#define WATERTIGHT_FACE_MAX 4

/* A planar convex face: 3 or 4 vertices in winding order. */
struct watertight_face {
    int n;
    struct vec3 v[WATERTIGHT_FACE_MAX];
};

struct watertight_triangle {
    struct vec3 v[3]; /* in the winding of the face it comes from */
};

/* The stitched faces. A face that gained no vertex is left as it was (no
   triangles); a face that did is replaced by the triangles
   tris[first[f]] .. tris[first[f + 1] - 1], which cover exactly the face. */
struct watertight {
    int n_faces;
    int *first; /* n_faces + 1 entries */
    int n_triangles;
    struct watertight_triangle *tris;
    int n_inserted; /* vertices inserted into edges, over all faces */
};

/* A vertex counts as lying on an edge when it is within this distance,
   relative to the faces' bounding-box diagonal, of the edge's open segment
   (and farther than that from both ends): far above the rounding of
   double-precision configs (~1e-16), far below the float precision of the
   traced geometry (~6e-8), so a vertex this close is on the edge as far as
   Embree can tell, and inserting it moves no surface by a visible amount. */
#define WATERTIGHT_TOLERANCE 1e-9

/* Finds, for every edge of the n faces, the vertices of the faces that lie
   on its open segment, and re-emits each face that has any as a fan of
   triangles over its boundary with them (from a corner whose two edges
   gained nothing, otherwise from the face's centroid, so that no triangle
   is degenerate). O(V log V + total edge length / grid cell) with a grid
   over the vertex positions. False only when out of memory. */
bool watertight_stitch(const struct watertight_face *faces, int n, struct watertight *out, struct error *err);
void watertight_free(struct watertight *w);

/* True when face f was re-emitted as triangles. */
static inline bool watertight_changed(const struct watertight *w, int f)
{
    return w->first[f + 1] > w->first[f];
}

#endif

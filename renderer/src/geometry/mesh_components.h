/* mesh_components.h: the connected pieces of a polygon mesh. `portals:
   auto` (scene/portal_finder.c) builds its enclosure from the pieces the
   light's rays meet: a lamp modelled as one mesh holds its shade, arm and
   base, and the convex hull of the shade alone fits the shade, where the
   hull of the whole mesh reaches down to the base. */
#ifndef MESH_COMPONENTS_H
#define MESH_COMPONENTS_H

#include "base/vec.h"

/* Labels the faces of a mesh, its n_quads quads first, then its n_tris
   triangles (the scene's face order), with their connected component:
   label[f] in 0..count-1, numbered in the order of each component's first
   face. Faces that share a vertex position are connected, whether or not
   they share the vertex index: a mesh split at its normal or UV seams,
   as OBJ and PLY exports are, is one piece. Vertices that no face uses
   are ignored. Returns the count of components, -1 when out of memory. */
int mesh_components(const struct vec3 *verts, int n_verts, const int (*quads)[4], int n_quads, const int (*tris)[3],
                    int n_tris, int *label);

#endif

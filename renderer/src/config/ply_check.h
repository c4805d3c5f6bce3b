/* ply_check.h: the renderer's PLY reader (ASCII, binary little- and
   big-endian), from memory. Assimp is not used for PLY: 5.2.5's reader
   allocates whatever element count a header declares, crashes on a
   truncated binary body, loops forever on a header without end_header,
   silently replaces out-of-range face indices, and skips a 0x0a byte after
   end_header's line even in a binary body, then misreads every value and
   aborts the process on an assertion (a float whose first byte is 0x0a is
   valid; 0x0d, 0x20 and 0x09 it read right). ply_check walks the header
   and the body once, without building anything, and reports the first
   defect with its place (header or ASCII line, binary byte offset);
   ply_read does the same checks, then keeps the positions and
   triangulates the faces. */
#ifndef PLY_CHECK_H
#define PLY_CHECK_H

#include <stdbool.h>
#include <stddef.h>

#include "base/error.h"
#include "base/vec.h"

#define PLY_HEADER_MAX          65536 /* bytes up to and including end_header */
#define PLY_PROPERTIES_MAX      64    /* per element */
#define PLY_ELEMENTS_MAX        64
#define PLY_CONCAVE_CORNERS_MAX 256 /* of a face that is not convex (ear clipping is quadratic) */

struct ply_info {
    int n_vertices;        /* of the vertex element */
    int n_faces;           /* of the face element */
    long long n_triangles; /* sum over faces of (corners - 2) */
};

/* True when data[0..size) is a PLY file that ply_read can read: magic
   and format lines, known property types, a vertex element with scalar x,
   y, z, a face element with an integer vertex_indices (or vertex_index)
   list, every element present in full (no more, no less), finite vertex
   coordinates, faces of at least 3 corners with indices in range. False
   with err ("line 4: ...", "byte 1234: ...") otherwise. */
bool ply_check(const void *data, size_t size, struct ply_info *info, struct error *err);

struct ply_mesh {
    int n_vertices;
    struct vec3 *positions; /* owned; every vertex of the file, each coordinate rounded to float */
    int n_triangles;
    int (*triangles)[3]; /* owned; in face order, each in its face's winding */
};

/* ply_check's checks, then the mesh: vertex x, y, z of any scalar type
   (other properties and elements skipped), rounded to float as assimp
   did; every face cut into corners - 2 triangles (a triangle as it is, a
   convex face as a fan from its first corner, a concave one by ear
   clipping in its plane). Also false for no triangles, more than
   max_triangles, a coordinate beyond the float range, a concave face of
   more than PLY_CONCAVE_CORNERS_MAX corners; out is then empty. */
bool ply_read(const void *data, size_t size, long long max_triangles, struct ply_mesh *out, struct error *err);
void ply_mesh_free(struct ply_mesh *m);

#endif

/* ply_check.h: a structural check of a PLY file in memory (ASCII, binary
   little- and big-endian), run before assimp reads it. Assimp 5.2.5's PLY
   reader allocates whatever element count a header declares, crashes on a
   truncated binary body, loops forever on a header without end_header, and
   silently replaces out-of-range face indices; this check walks the header
   and the body once, without building anything, and reports the first
   defect with its place (header or ASCII line, binary byte offset). */
#ifndef PLY_CHECK_H
#define PLY_CHECK_H

#include <stdbool.h>
#include <stddef.h>

#include "base/error.h"

#define PLY_HEADER_MAX     65536 /* bytes up to and including end_header */
#define PLY_PROPERTIES_MAX 64    /* per element */
#define PLY_ELEMENTS_MAX   64

struct ply_info {
    int n_vertices;        /* of the vertex element */
    int n_faces;           /* of the face element */
    long long n_triangles; /* sum over faces of (corners - 2) */
};

/* True when data[0..size) is a PLY file that assimp can read safely: magic
   and format lines, known property types, a vertex element with scalar x,
   y, z, a face element with an integer vertex_indices (or vertex_index)
   list, every element present in full (no more, no less), finite vertex
   coordinates, faces of at least 3 corners with indices in range. False
   with err ("line 4: ...", "byte 1234: ...") otherwise. */
bool ply_check(const void *data, size_t size, struct ply_info *info, struct error *err);

#endif

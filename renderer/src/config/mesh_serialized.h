/* mesh_serialized.h: Mitsuba's `serialized` mesh format (zlib; the only
   file that includes zlib.h is mesh_serialized.c). A file holds one or
   more shapes, each a 4-byte header (format id 0x041C, version 3 or 4,
   little-endian uint16s) and a zlib stream: uint32 flags, the shape's
   NUL-terminated UTF-8 name (version 4 only), uint64 vertex and triangle
   counts, the positions, then normals, texture coordinates and colors when
   the flags say so, in single or double precision, then the indices
   (uint32; uint64 only beyond 2^32 vertices, which the limits below
   refuse). The file ends with a dictionary: each shape's byte offset
   (uint64 in version 4, uint32 in version 3), then the shape count
   (uint32). Written from Mitsuba's documentation of the format. */
#ifndef MESH_SERIALIZED_H
#define MESH_SERIALIZED_H

#include <stdbool.h>
#include <stddef.h>

#include "base/error.h"
#include "config/mesh_file.h"

#define MESH_SERIALIZED_ID       0x041C
#define MESH_SERIALIZED_NAME_MAX 4096 /* bytes of a shape's name, its NUL included */

/* One shape as the file stores it: positions widened to double exactly
   (single precision files) or as written (double), triangles checked
   against the vertex count. Nothing joined or dropped. */
struct mesh_serialized {
    int n_vertices;
    struct vec3 *positions; /* owned */
    int n_triangles;
    int (*triangles)[3]; /* owned; in the file's winding */
};

/* The number of shapes in data[0..size), after checking the file's header
   and its dictionary (every offset lands on a shape header of the file's
   version, before the dictionary). False with err ("byte 2: ...",
   "dictionary entry 3 (byte 120): ...") otherwise. */
bool mesh_serialized_count(const void *data, size_t size, int *n_shapes, struct error *err);

/* Reads shape `shape` (0-based) of data[0..size): the checks of
   mesh_serialized_count, then its stream: known precision flags, counts
   within the limits of mesh_file.h and within what the compressed bytes
   can hold, every value present (a truncated or corrupt stream, or counts
   larger than the data, is an error), nothing after the indices (counts
   smaller than the data), every index in range, every position finite,
   at least one triangle. Normals, texture coordinates and colors are read
   past. False with err naming the shape ("shape 2 (byte 96): ...");
   out is then empty. */
bool mesh_serialized_read(const void *data, size_t size, int shape, struct mesh_serialized *out, struct error *err);
void mesh_serialized_free(struct mesh_serialized *m);

#endif

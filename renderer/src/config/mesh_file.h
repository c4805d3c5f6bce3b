/* mesh_file.h: triangle meshes from OBJ files, read by assimp (the only
   file that includes its headers is mesh_file.c), from PLY files, read by
   ply_check.h, and from Mitsuba's serialized files (mesh_serialized.h). In: the file's bytes; out:
   vertices and triangles, or an error without a location (the config
   loader adds the file:line:column of the `file:` key). */
#ifndef MESH_FILE_H
#define MESH_FILE_H

#include <stdbool.h>
#include <stddef.h>

#include "base/error.h"
#include "base/vec.h"

enum mesh_format { MESH_FORMAT_OBJ, MESH_FORMAT_PLY, MESH_FORMAT_SERIALIZED };

/* Limits, so that counts fit the config's ints with room for the scene's
   stitching (watertight.c) and the file fits assimp's unsigned length. */
#define MESH_FILE_BYTES_MAX     ((size_t)1 << 31)
#define MESH_FILE_TRIANGLES_MAX (1 << 28)

/* The format a file name's extension names (.obj, .ply, .serialized, any
   case). False when it names none of them. */
bool mesh_format_from_path(const char *path, enum mesh_format *out);

struct mesh_data {
    int n_vertices;
    struct vec3 *vertices; /* owned; only those some triangle uses */
    int n_triangles;
    int (*triangles)[3]; /* owned; in the file's winding */
};

/* Reads a mesh from data[0..size) in the given format: every face
   triangulated (assimp's ear clipping for OBJ, ply_read's for PLY, so
   convex and concave polygons alike), identical vertices joined, every object and group of an OBJ file
   in one mesh; lines and points are skipped, materials, normals and texture
   coordinates ignored; zero-area triangles kept (config_scene.c drops a
   surface's). Checks what assimp does not: an empty file, a binary file as
   OBJ, a PLY file's structure (ply_check.h), vertices that are not finite,
   no triangles. Writes nothing to stdout or stderr. False with err
   ("line 4: ...", "byte 96: ...", "assimp: ...") otherwise; out is then
   empty. A serialized file gives its first shape, as mesh_file_parse_shape
   does with shape 0. */
bool mesh_file_parse(const void *data, size_t size, enum mesh_format format, struct mesh_data *out, struct error *err);

/* How many meshes mesh_file_parse_shape can read from the file: 1 for OBJ
   and PLY (unchecked: mesh_file_parse checks them), the dictionary's count
   for a serialized file (checked as mesh_serialized_count does). */
bool mesh_file_shape_count(const void *data, size_t size, enum mesh_format format, int *n_shapes, struct error *err);

/* Shape `shape` of the file (0 for OBJ and PLY, which hold one mesh): for
   a serialized file, mesh_serialized_read's checks, then the vertices
   joined and kept as mesh_file_parse does. */
bool mesh_file_parse_shape(const void *data, size_t size, enum mesh_format format, int shape, struct mesh_data *out,
                           struct error *err);
void mesh_data_free(struct mesh_data *m);

#endif

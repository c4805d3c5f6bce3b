/* libFuzzer target: the mesh loaders (mesh_file.c through assimp for OBJ,
   ply_check.c for PLY; mesh_serialized.c through zlib) must reject or accept any
   bytes, read as an OBJ file, as a PLY file and as every shape of a
   serialized file, without crashing or invoking undefined behaviour; what they
   accept must be a mesh the renderer can use: at least one triangle, every
   index in range, every vertex finite and used. mesh_file_parse reads from
   memory (assimp's aiImportFileFromMemory), so no temporary file is
   needed. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "config/mesh_file.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Aborts (the fuzzer's finding) when an accepted mesh breaks the contract
   of mesh_file.h. */
static void check_mesh(const struct mesh_data *m)
{
    if (m->n_triangles < 1 || m->n_vertices < 1 || !m->vertices || !m->triangles) abort();
    char *used = calloc((size_t)m->n_vertices, 1);
    if (!used) abort();
    for (int t = 0; t < m->n_triangles; ++t)
        for (int c = 0; c < 3; ++c) {
            int i = m->triangles[t][c];
            if (i < 0 || i >= m->n_vertices) abort();
            used[i] = 1;
        }
    for (int i = 0; i < m->n_vertices; ++i) {
        struct vec3 v = m->vertices[i];
        if (!used[i] || !isfinite(v.x) || !isfinite(v.y) || !isfinite(v.z)) abort();
    }
    free(used);
}

static void parse_one(const uint8_t *data, size_t size, enum mesh_format format, int shape)
{
    struct mesh_data m;
    struct error err;
    bool ok = mesh_file_parse_shape(data, size, format, shape, &m, &err);
    if (ok) check_mesh(&m);
    else if (m.vertices || m.triangles || m.n_vertices || m.n_triangles) abort(); /* out must be empty */
    mesh_data_free(&m);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    parse_one(data, size, MESH_FORMAT_OBJ, 0);
    parse_one(data, size, MESH_FORMAT_PLY, 0);
    /* Every shape the dictionary names (at most 8, to keep an input
       fast), and the first one past the end, which must be refused. */
    int n = 0;
    struct error err;
    if (!mesh_file_shape_count(data, size, MESH_FORMAT_SERIALIZED, &n, &err)) n = 0;
    for (int s = 0; s <= n && s <= 8; ++s) parse_one(data, size, MESH_FORMAT_SERIALIZED, s);
    return 0;
}

/* mesh_file.c: OBJ and PLY through assimp's C API, and the checks around
   it. Assimp's logger is process-global: none is attached, so assimp logs
   to its NullLogger and prints nothing (stdout is the renderer's JSON event
   stream; test_mesh_file.c checks it stays empty). Its last error message
   is global too (aiGetErrorString): it is read right after the failed call,
   and configs are loaded on one thread. */
#include "config/mesh_file.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "config/ply_check.h"

bool mesh_format_from_path(const char *path, enum mesh_format *out)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash) || strlen(dot) != 4) return false;
    char ext[5];
    for (int i = 0; i < 4; ++i) ext[i] = (char)tolower((unsigned char)dot[i]);
    ext[4] = '\0';
    if (!strcmp(ext, ".obj")) *out = MESH_FORMAT_OBJ;
    else if (!strcmp(ext, ".ply")) *out = MESH_FORMAT_PLY;
    else return false;
    return true;
}

void mesh_data_free(struct mesh_data *m)
{
    free(m->vertices);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

/* What assimp cannot be trusted with (see ply_check.h for PLY; an empty
   buffer trips an assertion that aborts the process). */
static bool precheck(const unsigned char *data, size_t size, enum mesh_format format, struct error *err)
{
    if (size == 0) return error_set(err, "empty file (expected a mesh)");
    if (size > MESH_FILE_BYTES_MAX) return error_set(err, "file larger than %zu bytes", MESH_FILE_BYTES_MAX);
    if (format == MESH_FORMAT_PLY) {
        struct ply_info info;
        return ply_check(data, size, &info, err);
    }
    if (size >= 4 && (!memcmp(data, "ply\n", 4) || !memcmp(data, "ply\r", 4)))
        return error_set(err, "line 1: a PLY file by its content (\"ply\"), not OBJ (expected a file named .ply)");
    const unsigned char *nul = memchr(data, '\0', size);
    if (nul)
        return error_set(err, "byte %zu: a NUL byte: not a text file (expected an OBJ file, which is text)",
                         (size_t)(nul - data));
    return true;
}

/* Identical vertices are joined here, not by assimp's
   aiProcess_JoinIdenticalVertices: aiApplyPostProcessing crashes (assimp
   5.2.5, inside aiReleaseImport) when its validation fails, as it does for
   an OBJ file with vertices but no faces, and its join is slower than one
   hash table for a 1M-triangle mesh. Positions are joined when their
   coordinates are equal as floats (-0 and +0 alike); NaN never reaches
   here (check_finite). */
struct vertex_table {
    size_t mask;   /* capacity - 1, a power of two minus one */
    int *slot;     /* output vertex index, or -1 when empty */
    uint32_t *key; /* 3 per slot: the coordinates' bits */
};

static uint32_t float_key(float f)
{
    uint32_t u;
    if (f == 0.0f) f = 0.0f; /* -0 joins +0 */
    memcpy(&u, &f, sizeof u);
    return u;
}

/* The slot of key k: an empty one or the one that holds it (linear probing
   from a multiplicative hash). */
static size_t table_find(const struct vertex_table *t, const uint32_t k[3])
{
    uint64_t h = ((uint64_t)k[0] * 0x9E3779B97F4A7C15u) ^ ((uint64_t)k[1] * 0xC2B2AE3D27D4EB4Fu) ^
                 ((uint64_t)k[2] * 0x165667B19E3779F9u);
    size_t i = (size_t)(h ^ (h >> 29)) & t->mask;
    while (t->slot[i] >= 0 && memcmp(&t->key[3 * i], k, 3 * sizeof k[0]) != 0) i = (i + 1) & t->mask;
    return i;
}

/* Triangles of the meshes of s, concatenated, with only the vertices they
   use (a point or line of an OBJ file keeps no vertex), identical positions
   joined. OBJ and PLY scenes have an identity node hierarchy, so the meshes
   are read as they are. Checks every index against its mesh: assimp's own
   validation is not run (see vertex_table). */
static bool collect(const struct aiScene *s, struct mesh_data *out, struct error *err)
{
    long long nt = 0, nv = 0;
    for (unsigned m = 0; m < s->mNumMeshes; ++m) {
        const struct aiMesh *mesh = s->mMeshes[m];
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const struct aiFace *face = &mesh->mFaces[f];
            unsigned k = face->mNumIndices;
            if (k > 3) return error_set(err, "assimp left a face of %u corners after triangulation", k);
            if (k != 3) continue;
            for (int c = 0; c < 3; ++c)
                if (face->mIndices[c] >= mesh->mNumVertices)
                    return error_set(err, "face %u of object %u has vertex index %u, out of range (expected 0 to %u)",
                                     f, m, face->mIndices[c], mesh->mNumVertices - 1);
            ++nt;
        }
        nv += mesh->mNumVertices;
    }
    if (nt == 0) return error_set(err, "no triangles (expected faces: OBJ f lines, or a PLY face element)");
    if (nt > MESH_FILE_TRIANGLES_MAX || nv > INT_MAX / 2)
        return error_set(err, "%lld triangles, %lld vertices (expected at most %d triangles)", nt, nv,
                         MESH_FILE_TRIANGLES_MAX);
    /* At most 3 nt vertices are used: the table stays at most half full. */
    long long used_max = nv < 3 * nt ? nv : 3 * nt;
    size_t cap = 16;
    while (cap < 2 * (size_t)used_max) cap *= 2;
    struct vertex_table t = { cap - 1, malloc(sizeof *t.slot * cap), malloc(sizeof *t.key * 3 * cap) };
    out->vertices = malloc(sizeof *out->vertices * (size_t)used_max);
    out->triangles = malloc(sizeof *out->triangles * (size_t)nt);
    int *remap = malloc(sizeof *remap * (size_t)nv);
    if (!out->vertices || !out->triangles || !remap || !t.slot || !t.key) {
        free(remap);
        free(t.slot);
        free(t.key);
        mesh_data_free(out);
        return error_set(err, "out of memory for %lld triangles", nt);
    }
    for (size_t i = 0; i < cap; ++i) t.slot[i] = -1;
    for (long long i = 0; i < nv; ++i) remap[i] = -1;
    int v_out = 0, t_out = 0;
    long long base = 0;
    for (unsigned m = 0; m < s->mNumMeshes; ++m) {
        const struct aiMesh *mesh = s->mMeshes[m];
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const struct aiFace *face = &mesh->mFaces[f];
            if (face->mNumIndices != 3) continue;
            for (int c = 0; c < 3; ++c) {
                unsigned idx = face->mIndices[c];
                int *r = &remap[base + idx];
                if (*r < 0) {
                    const struct aiVector3D *p = &mesh->mVertices[idx];
                    uint32_t k[3] = { float_key(p->x), float_key(p->y), float_key(p->z) };
                    size_t i = table_find(&t, k);
                    if (t.slot[i] < 0) {
                        t.slot[i] = v_out;
                        memcpy(&t.key[3 * i], k, sizeof k);
                        out->vertices[v_out++] = vec3_make(p->x, p->y, p->z);
                    }
                    *r = t.slot[i];
                }
                out->triangles[t_out][c] = *r;
            }
            ++t_out;
        }
        base += mesh->mNumVertices;
    }
    free(remap);
    free(t.slot);
    free(t.key);
    out->n_vertices = v_out;
    out->n_triangles = t_out;
    return true;
}

/* Before joining identical vertices: a NaN would otherwise merge with
   whatever it compares equal to by accident and vanish. */
static bool check_finite(const struct aiScene *s, struct error *err)
{
    for (unsigned m = 0; m < s->mNumMeshes; ++m) {
        const struct aiMesh *mesh = s->mMeshes[m];
        for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
            const struct aiVector3D *p = &mesh->mVertices[v];
            if (!isfinite(p->x) || !isfinite(p->y) || !isfinite(p->z))
                return error_set(err, "vertex %u of object %u is not finite (%g, %g, %g)", v, m, (double)p->x,
                                 (double)p->y, (double)p->z);
        }
    }
    return true;
}

/* The geometry statements of an OBJ file; every other line reaches assimp
   blanked (spaces, its newline kept, so line numbers hold). The renderer
   reads no materials, and assimp 5.2.5 writes through a null pointer on
   an MTL statement such as map_emissive once an mtllib it could not open
   has been named (found by make fuzz). */
static bool obj_keyword_kept(const char *line, size_t n)
{
    static const char *const kept[] = { "v", "vt", "vn", "vp", "f", "l", "p", "o", "g", "s" };
    while (n > 0 && (*line == ' ' || *line == '\t')) ++line, --n;
    size_t k = 0;
    while (k < n && line[k] != ' ' && line[k] != '\t' && line[k] != '\r') ++k;
    if (k == 0 || line[0] == '#') return true; /* blank or comment: harmless as it is */
    for (size_t i = 0; i < sizeof kept / sizeof kept[0]; ++i)
        if (strlen(kept[i]) == k && memcmp(kept[i], line, k) == 0) return true;
    return false;
}

/* A copy of an OBJ text with its non-geometry lines blanked (obj_keyword_kept). */
static char *obj_geometry_only(const unsigned char *data, size_t size)
{
    char *copy = malloc(size);
    if (!copy) return NULL;
    memcpy(copy, data, size);
    for (size_t start = 0; start < size;) {
        const char *nl = memchr(copy + start, '\n', size - start);
        size_t end = nl ? (size_t)(nl - copy) : size;
        if (!obj_keyword_kept(copy + start, end - start)) memset(copy + start, ' ', end - start);
        start = end + 1;
    }
    return copy;
}

bool mesh_file_parse(const void *data, size_t size, enum mesh_format format, struct mesh_data *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    if (!precheck(data, size, format, err)) return false;
    char *geometry = NULL;
    if (format == MESH_FORMAT_OBJ) {
        if (!(geometry = obj_geometry_only(data, size))) return error_set(err, "out of memory for %zu bytes", size);
        data = geometry;
    }
    /* Triangulate in the import, nothing else: the index checks and the
       join are collect's (no aiApplyPostProcessing, see vertex_table). No
       normals or smoothing: the renderer uses geometric normals. */
    const struct aiScene *s =
        aiImportFileFromMemory(data, (unsigned)size, aiProcess_Triangulate, format == MESH_FORMAT_OBJ ? "obj" : "ply");
    if (!s) {
        free(geometry);
        return error_set(err, "assimp: %s", aiGetErrorString());
    }
    bool ok =
        (s->mNumMeshes > 0 || error_set(err, "no triangles (expected faces: OBJ f lines, or a PLY face element)")) &&
        check_finite(s, err) && collect(s, out, err);
    aiReleaseImport(s);
    free(geometry);
    return ok;
}

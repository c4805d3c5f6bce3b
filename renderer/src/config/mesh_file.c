/* mesh_file.c: OBJ through assimp's C API, and the checks around it; PLY
   through the renderer's own reader (ply_check.c) and serialized files
   through mesh_serialized.c, both joined here as OBJ is. Assimp's logger is process-global: none is attached, so assimp logs
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

#include "config/mesh_serialized.h"
#include "config/ply_check.h"

bool mesh_format_from_path(const char *path, enum mesh_format *out)
{
    static const struct {
        const char *ext;
        enum mesh_format format;
    } known[] = { { ".obj", MESH_FORMAT_OBJ }, { ".ply", MESH_FORMAT_PLY }, { ".serialized", MESH_FORMAT_SERIALIZED } };
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash)) return false;
    for (size_t k = 0; k < sizeof known / sizeof known[0]; ++k) {
        const char *e = known[k].ext;
        size_t i = 0;
        while (e[i] && dot[i] && tolower((unsigned char)dot[i]) == e[i]) ++i;
        if (!e[i] && !dot[i]) {
            *out = known[k].format;
            return true;
        }
    }
    return false;
}

void mesh_data_free(struct mesh_data *m)
{
    free(m->vertices);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

/* What assimp cannot be trusted with (an empty buffer trips an assertion
   that aborts the process). */
static bool precheck(const unsigned char *data, size_t size, enum mesh_format format, struct error *err)
{
    if (size == 0) return error_set(err, "empty file (expected a mesh)");
    if (size > MESH_FILE_BYTES_MAX) return error_set(err, "file larger than %zu bytes", MESH_FILE_BYTES_MAX);
    if (format == MESH_FORMAT_PLY) return true; /* ply_read checks the rest */
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
    uint64_t *key; /* 3 per slot: the coordinates' bits as doubles */
};

/* Doubles hold assimp's floats exactly, so equal keys are equal floats
   there and equal doubles for a double-precision serialized file. */
static uint64_t coord_key(double d)
{
    uint64_t u;
    if (d == 0.0) d = 0.0; /* -0 joins +0 */
    memcpy(&u, &d, sizeof u);
    return u;
}

static void vertex_key(struct vec3 p, uint64_t k[3])
{
    k[0] = coord_key(p.x);
    k[1] = coord_key(p.y);
    k[2] = coord_key(p.z);
}

/* The slot of key k: an empty one or the one that holds it (linear probing
   from a multiplicative hash, folded so that the low bits see the high
   ones: a float's double has 29 zero low bits). */
static size_t table_find(const struct vertex_table *t, const uint64_t k[3])
{
    uint64_t h = (k[0] * 0x9E3779B97F4A7C15u) ^ (k[1] * 0xC2B2AE3D27D4EB4Fu) ^ (k[2] * 0x165667B19E3779F9u);
    h ^= h >> 32;
    h *= 0xD6E8FEB86659FD93u;
    h ^= h >> 29;
    size_t i = (size_t)h & t->mask;
    while (t->slot[i] >= 0 && memcmp(&t->key[3 * i], k, 3 * sizeof k[0]) != 0) i = (i + 1) & t->mask;
    return i;
}

/* A table for at most n keys, at most half full; false when out of memory. */
static bool table_init(struct vertex_table *t, long long n)
{
    size_t cap = 16;
    while (cap < 2 * (size_t)n) cap *= 2;
    t->mask = cap - 1;
    t->slot = malloc(sizeof *t->slot * cap);
    t->key = malloc(sizeof *t->key * 3 * cap);
    if (!t->slot || !t->key) return false;
    for (size_t i = 0; i < cap; ++i) t->slot[i] = -1;
    return true;
}

static void table_free(struct vertex_table *t)
{
    free(t->slot);
    free(t->key);
}

/* The output index of position p: the vertex already kept at the same
   position, or a new one appended to out. */
static int table_join(struct vertex_table *t, struct vec3 p, struct mesh_data *out)
{
    uint64_t k[3];
    vertex_key(p, k);
    size_t i = table_find(t, k);
    if (t->slot[i] < 0) {
        t->slot[i] = out->n_vertices;
        memcpy(&t->key[3 * i], k, sizeof k);
        out->vertices[out->n_vertices++] = p;
    }
    return t->slot[i];
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
    struct vertex_table t;
    bool table = table_init(&t, used_max);
    out->vertices = malloc(sizeof *out->vertices * (size_t)used_max);
    out->triangles = malloc(sizeof *out->triangles * (size_t)nt);
    int *remap = malloc(sizeof *remap * (size_t)nv);
    if (!out->vertices || !out->triangles || !remap || !table) {
        free(remap);
        table_free(&t);
        mesh_data_free(out);
        return error_set(err, "out of memory for %lld triangles", nt);
    }
    for (long long i = 0; i < nv; ++i) remap[i] = -1;
    int t_out = 0;
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
                    *r = table_join(&t, vec3_make(p->x, p->y, p->z), out);
                }
                out->triangles[t_out][c] = *r;
            }
            ++t_out;
        }
        base += mesh->mNumVertices;
    }
    free(remap);
    table_free(&t);
    out->n_triangles = t_out;
    return true;
}

/* Indexed triangles (a serialized shape, a PLY file) as a mesh_data: the
   vertices the triangles use, identical positions joined, as collect does
   for assimp's meshes (a serialized mesh splits a vertex wherever its
   normals or texture coordinates do). Every index is in range. */
static bool join_indexed(const struct vec3 *positions, int n_vertices, const int (*triangles)[3], int n_triangles,
                         struct mesh_data *out, struct error *err)
{
    long long used_max = n_vertices < 3LL * n_triangles ? n_vertices : 3LL * n_triangles;
    struct vertex_table t;
    bool table = table_init(&t, used_max);
    out->vertices = malloc(sizeof *out->vertices * (size_t)used_max);
    out->triangles = malloc(sizeof *out->triangles * (size_t)n_triangles);
    int *remap = malloc(sizeof *remap * ((size_t)n_vertices + 1));
    if (!out->vertices || !out->triangles || !remap || !table) {
        free(remap);
        table_free(&t);
        mesh_data_free(out);
        return error_set(err, "out of memory for %d triangles", n_triangles);
    }
    for (int i = 0; i < n_vertices; ++i) remap[i] = -1;
    for (int f = 0; f < n_triangles; ++f)
        for (int c = 0; c < 3; ++c) {
            int idx = triangles[f][c];
            if (remap[idx] < 0) remap[idx] = table_join(&t, positions[idx], out);
            out->triangles[f][c] = remap[idx];
        }
    free(remap);
    table_free(&t);
    out->n_triangles = n_triangles;
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

bool mesh_file_shape_count(const void *data, size_t size, enum mesh_format format, int *n_shapes, struct error *err)
{
    if (format == MESH_FORMAT_SERIALIZED) return mesh_serialized_count(data, size, n_shapes, err);
    *n_shapes = 1;
    return true;
}

bool mesh_file_parse(const void *data, size_t size, enum mesh_format format, struct mesh_data *out, struct error *err)
{
    return mesh_file_parse_shape(data, size, format, 0, out, err);
}

bool mesh_file_parse_shape(const void *data, size_t size, enum mesh_format format, int shape, struct mesh_data *out,
                           struct error *err)
{
    memset(out, 0, sizeof *out);
    if (format == MESH_FORMAT_SERIALIZED) {
        struct mesh_serialized raw;
        if (!mesh_serialized_read(data, size, shape, &raw, err)) return false;
        bool ok =
            join_indexed(raw.positions, raw.n_vertices, (const int(*)[3])raw.triangles, raw.n_triangles, out, err);
        mesh_serialized_free(&raw);
        return ok;
    }
    if (shape != 0)
        return error_set(err, "shape %d out of range (an %s file holds one mesh: expected 0)", shape,
                         format == MESH_FORMAT_OBJ ? "OBJ" : "PLY");
    if (!precheck(data, size, format, err)) return false;
    if (format == MESH_FORMAT_PLY) {
        struct ply_mesh ply;
        if (!ply_read(data, size, MESH_FILE_TRIANGLES_MAX, &ply, err)) return false;
        bool ok =
            join_indexed(ply.positions, ply.n_vertices, (const int(*)[3])ply.triangles, ply.n_triangles, out, err);
        ply_mesh_free(&ply);
        return ok;
    }
    char *geometry = NULL;
    if (format == MESH_FORMAT_OBJ) {
        if (!(geometry = obj_geometry_only(data, size))) return error_set(err, "out of memory for %zu bytes", size);
        data = geometry;
    }
    /* Triangulate in the import, nothing else: the index checks and the
       join are collect's (no aiApplyPostProcessing, see vertex_table). No
       normals or smoothing: the renderer uses geometric normals. */
    const struct aiScene *s = aiImportFileFromMemory(data, (unsigned)size, aiProcess_Triangulate, "obj");
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

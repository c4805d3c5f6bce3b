/* mesh_file.c: OBJ and PLY through assimp's C API, and the checks around
   it. Assimp's logger is process-global: none is attached, so assimp logs
   to its NullLogger and prints nothing (stdout is the renderer's JSON event
   stream; test_mesh_file.c checks it stays empty). Its last error message
   is global too (aiGetErrorString): it is read right after the failed call,
   and configs are loaded on one thread. */
#include "mesh_file.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ply_check.h"

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

/* Triangles of the meshes of s, concatenated, with only the vertices they
   use (a point or line of an OBJ file keeps no vertex). OBJ and PLY scenes
   have an identity node hierarchy, so the meshes are read as they are. */
static bool collect(const struct aiScene *s, struct mesh_data *out, struct error *err)
{
    long long nt = 0, nv = 0;
    for (unsigned m = 0; m < s->mNumMeshes; ++m) {
        const struct aiMesh *mesh = s->mMeshes[m];
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            unsigned k = mesh->mFaces[f].mNumIndices;
            if (k > 3) return error_set(err, "assimp left a face of %u corners after triangulation", k);
            nt += k == 3;
        }
        nv += mesh->mNumVertices;
    }
    if (nt == 0) return error_set(err, "no triangles (expected faces: OBJ f lines, or a PLY face element)");
    if (nt > MESH_FILE_TRIANGLES_MAX || nv > INT_MAX / 2)
        return error_set(err, "%lld triangles, %lld vertices (expected at most %d triangles)", nt, nv,
                         MESH_FILE_TRIANGLES_MAX);
    out->vertices = malloc(sizeof *out->vertices * (size_t)nv);
    out->triangles = malloc(sizeof *out->triangles * (size_t)nt);
    int *remap = malloc(sizeof *remap * (size_t)nv);
    if (!out->vertices || !out->triangles || !remap) {
        free(remap);
        mesh_data_free(out);
        return error_set(err, "out of memory for %lld triangles", nt);
    }
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
                /* ValidateDataStructure checked the range already. */
                int *slot = &remap[base + idx];
                if (*slot < 0) {
                    const struct aiVector3D *p = &mesh->mVertices[idx];
                    out->vertices[v_out] = vec3_make(p->x, p->y, p->z);
                    *slot = v_out++;
                }
                out->triangles[t_out][c] = *slot;
            }
            ++t_out;
        }
        base += mesh->mNumVertices;
    }
    free(remap);
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

bool mesh_file_parse(const void *data, size_t size, enum mesh_format format, struct mesh_data *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    if (!precheck(data, size, format, err)) return false;
    /* Triangulate in the import; validate (index ranges) and join after
       the checks of our own, which say more than assimp's validation.
       No normals or smoothing: the renderer uses geometric normals. */
    const struct aiScene *s =
        aiImportFileFromMemory(data, (unsigned)size, aiProcess_Triangulate, format == MESH_FORMAT_OBJ ? "obj" : "ply");
    if (!s) return error_set(err, "assimp: %s", aiGetErrorString());
    bool ok = s->mNumMeshes > 0 || error_set(err, "no triangles (expected faces: OBJ f lines, or a PLY face element)");
    ok = ok && check_finite(s, err);
    if (ok) {
        s = aiApplyPostProcessing(s, aiProcess_ValidateDataStructure | aiProcess_JoinIdenticalVertices);
        ok = s != NULL || error_set(err, "assimp: %s", aiGetErrorString());
    }
    ok = ok && collect(s, out, err);
    if (s) aiReleaseImport(s);
    return ok;
}

/* config_scene.c: the section loaders of what the image shows: camera,
   film, materials, shapes (quads, boxes and meshes, inline or from OBJ and
   PLY files, all kept as meshes), lights and portals, each with its
   transform applied, and the geometric checks on them (each polygon by
   polygon_check, after the transform; each portal on its light's emitting
   side). */
#define _XOPEN_SOURCE 700 /* realpath, for the absolute path of a mesh file */

#include "config/config_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "config/mesh_file.h"

enum shape_kind { SHAPE_QUAD, SHAPE_BOX, SHAPE_MESH };
static const char *const shape_kind_names[3] = { "quad", "box", "mesh" };

static const char *const camera_keys[] = { "position", "look_at", "up", "fov_y" };
static const char *const film_keys[] = { "width", "height" };
static const char *const diffuse_keys[] = { "type", "albedo" };
static const char *const ggx_keys[] = { "type", "albedo", "roughness" };
static const char *const quad_keys[] = { "name", "type", "material", "vertices", "transform" };
static const char *const box_keys[] = { "name", "type", "material", "min", "max", "transform" };
static const char *const mesh_keys[] = { "name", "type", "material", "vertices", "triangles", "quads", "transform" };
static const char *const mesh_file_keys[] = {
    "name", "type", "material", "file", "shape_index", "transform", "digest"
};
static const char *const digest_keys[] = { "fnv1a64", "bytes" };
static const char *const light_keys[] = { "name", "vertices", "radiance", "two_sided", "transform" };
static const char *const mesh_light_keys[] = { "name", "mesh", "radiance", "two_sided" };
static const char *const light_mesh_keys[] = { "file", "shape_index", "transform", "digest" };
static const char *const portal_keys[] = { "name", "light", "vertices", "transform", "auto" };
static const char *const auto_portal_keys[] = { "light", "auto" };

#define PARALLEL_TOL 1e-9 /* |sin| of the angle between up and the view direction */

#define FILM_SIZE_MAX 16384

/* A polygon's validity (polygon_check) as a message at the node. */
static bool check_polygon(struct loader *L, const yaml_node_t *n, const char *what, const struct polygon *poly)
{
    switch (polygon_check(poly)) {
    case POLYGON_DEFECT_NONE:
        return true;
    case POLYGON_DEFECT_DEGENERATE:
        return config_fail(L, n, "%s is degenerate (expected a polygon with non-zero area)", what);
    case POLYGON_DEFECT_NOT_PLANAR:
        return config_fail(L, n, "%s is not planar (expected every vertex within %g times its size of its plane)", what,
                           POLYGON_PLANARITY_TOLERANCE);
    case POLYGON_DEFECT_NOT_CONVEX:
        return config_fail(L, n, "%s is not convex (expected a convex polygon with its vertices in order)", what);
    }
    return false;
}

/* The polygon after the transform. The renderer keeps no normals: a
   polygon's normal is its winding's, so a mirroring transform (det < 0)
   also reverses the order after the first vertex, which keeps the winding
   normal along the inverse transpose of the old one (transform_normal),
   and a one-sided light emitting towards the same side of the surface. */
static void transform_polygon(const struct transform *t, struct polygon *p)
{
    for (int i = 0; i < p->n; ++i) p->v[i] = transform_point(t, p->v[i]);
    if (transform_det(t) < 0.0)
        for (int i = 1, j = p->n - 1; i < j; ++i, --j) {
            struct vec3 tmp = p->v[i];
            p->v[i] = p->v[j];
            p->v[j] = tmp;
        }
}

/* The same reversal for the faces of a mesh: k indices each. */
static void reverse_faces(int *faces, int n, int k)
{
    for (int f = 0; f < n; ++f)
        for (int i = 1, j = k - 1; i < j; ++i, --j) {
            int tmp = faces[f * k + i];
            faces[f * k + i] = faces[f * k + j];
            faces[f * k + j] = tmp;
        }
}

/* A polygon of min..max points, transformed by the transform of `map`
   (the mapping that holds the vertices n), then checked by check_polygon. */
static bool get_polygon(struct loader *L, const yaml_node_t *map, const yaml_node_t *n, const char *what, int min,
                        int max, struct polygon *out)
{
    char buf[64];
    memset(out, 0, sizeof *out);
    if (n->type != YAML_SEQUENCE_NODE)
        return config_fail(L, n, "expected a list of points [x, y, z], got %s",
                           config_describe_node(n, buf, sizeof buf));
    int count = config_seq_count(n);
    if (count < min || count > max) {
        if (min == max) return config_fail(L, n, "%s has %d vertices (expected %d)", what, count, min);
        return config_fail(L, n, "%s has %d vertices (expected %d to %d)", what, count, min, max);
    }
    for (int i = 0; i < count; ++i)
        if (!config_get_vec3(L, config_seq_item(L, n, i), &out->v[i])) return false;
    out->n = count;
    struct transform t;
    bool present;
    if (!config_get_transform(L, map, &t, &present)) return false;
    if (present) transform_polygon(&t, out);
    return check_polygon(L, n, what, out);
}

static bool load_camera(struct loader *L, const yaml_node_t *root, struct camera_desc *cam)
{
    yaml_node_t *map = config_need(L, root, "camera", "the top level"), *n, *look, *up;
    if (!map || !config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !config_check_keys(L, map, "camera", camera_keys, COUNT(camera_keys)))
        return false;
    if (!(n = config_need(L, map, "position", "camera")) || !config_get_vec3(L, n, &cam->position)) return false;
    if (!(look = config_need(L, map, "look_at", "camera")) || !config_get_vec3(L, look, &cam->look_at)) return false;
    if (!(up = config_need(L, map, "up", "camera")) || !config_get_vec3(L, up, &cam->up)) return false;
    if (!(n = config_need(L, map, "fov_y", "camera")) ||
        !config_get_number_in(L, n, 0.0, true, 180.0, true, &cam->fov_y_deg))
        return false;
    struct vec3 dir = vec3_sub(cam->look_at, cam->position);
    if (vec3_length(dir) == 0.0) return config_fail(L, look, "look_at equals position (expected a different point)");
    if (vec3_length(cam->up) == 0.0) return config_fail(L, up, "up is zero (expected a direction)");
    if (vec3_length(vec3_cross(vec3_normalize(dir), vec3_normalize(cam->up))) <= PARALLEL_TOL)
        return config_fail(L, up,
                           "up is parallel to the view direction (expected a direction not along look_at - "
                           "position)");
    return true;
}

static bool load_film(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map = config_need(L, root, "film", "the top level"), *n;
    if (!map || !config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !config_check_keys(L, map, "film", film_keys, COUNT(film_keys)))
        return false;
    if (!(n = config_need(L, map, "width", "film")) || !config_get_int(L, n, 1, FILM_SIZE_MAX, &c->width)) return false;
    if (!(n = config_need(L, map, "height", "film")) || !config_get_int(L, n, 1, FILM_SIZE_MAX, &c->height))
        return false;
    return true;
}

static bool load_material(struct loader *L, const yaml_node_t *key, const yaml_node_t *map, struct material_desc *m)
{
    if (!config_get_string(L, key, m->name, sizeof m->name)) return false;
    char where[CONFIG_NAME_MAX + 16];
    snprintf(where, sizeof where, "material \"%s\"", m->name);
    m->loc = config_loc_of(L, key);
    yaml_node_t *n;
    int kind = 0;
    if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping")) return false;
    if (!(n = config_need(L, map, "type", where)) || !config_get_enum(L, n, "material type", material_names, 2, &kind))
        return false;
    m->kind = (enum material_kind)kind;
    bool ggx = m->kind == MATERIAL_GGX;
    if (!config_check_keys(L, map, where, ggx ? ggx_keys : diffuse_keys, ggx ? COUNT(ggx_keys) : COUNT(diffuse_keys)))
        return false;
    if (!(n = config_need(L, map, "albedo", where)) || !config_get_rgb(L, n, 0.0, 1.0, &m->albedo)) return false;
    if (ggx && (!(n = config_need(L, map, "roughness", where)) ||
                !config_get_number_in(L, n, 0.001, false, 1.0, false, &m->roughness)))
        return false;
    return true;
}

static bool load_materials(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map;
    if (!config_get_optional(L, root, "materials", YAML_MAPPING_NODE, &map)) return false;
    if (!map) return true;
    if (!config_check_keys(L, map, "materials", NULL, 0)) return false;
    int n = config_map_count(map);
    if (n == 0) return true;
    c->materials = calloc((size_t)n, sizeof *c->materials);
    if (!c->materials) return error_set(L->err, "%s: out of memory", L->file);
    c->n_materials = n;
    for (int i = 0; i < n; ++i) {
        yaml_node_pair_t *p = &map->data.mapping.pairs.start[i];
        if (!load_material(L, config_node(L, p->key), config_node(L, p->value), &c->materials[i])) return false;
    }
    return true;
}

static bool shape_alloc(struct loader *L, struct shape_desc *s, int n_vertices, int n_triangles, int n_quads)
{
    s->vertices = calloc((size_t)n_vertices, sizeof *s->vertices);
    s->triangles = n_triangles ? calloc((size_t)n_triangles, sizeof *s->triangles) : NULL;
    s->quads = n_quads ? calloc((size_t)n_quads, sizeof *s->quads) : NULL;
    if (!s->vertices || (n_triangles && !s->triangles) || (n_quads && !s->quads))
        return error_set(L->err, "%s: out of memory", L->file);
    s->n_vertices = n_vertices;
    s->n_triangles = n_triangles;
    s->n_quads = n_quads;
    return true;
}

/* The same test for every face of every shape type, so that a shape written
   back as a mesh in effective_yaml validates again. */
static bool check_face(struct loader *L, const yaml_node_t *n, const char *what, const struct shape_desc *s,
                       const int *idx, int k)
{
    struct polygon poly; /* only v[0..k) is read */
    poly.n = k;
    for (int i = 0; i < k; ++i) poly.v[i] = s->vertices[idx[i]];
    return check_polygon(L, n, what, &poly);
}

/* Faces of a mesh: a sequence of k-index lists, indices in range. */
static bool get_faces(struct loader *L, const yaml_node_t *seq, const char *kind, int k, struct shape_desc *s,
                      int *faces)
{
    char buf[64], what[64];
    for (int f = 0; f < config_seq_count(seq); ++f) {
        const yaml_node_t *face = config_seq_item(L, seq, f);
        if (face->type != YAML_SEQUENCE_NODE)
            return config_fail(L, face, "expected a %s (%d vertex indices), got %s", kind, k,
                               config_describe_node(face, buf, sizeof buf));
        if (config_seq_count(face) != k)
            return config_fail(L, face, "expected a %s (%d vertex indices), got %d items", kind, k,
                               config_seq_count(face));
        for (int i = 0; i < k; ++i) {
            const yaml_node_t *item = config_seq_item(L, face, i);
            int index;
            if (!config_get_int(L, item, 0, INT_MAX, &index)) return false;
            if (index >= s->n_vertices)
                return config_fail(L, item, "vertex index %d out of range (expected 0 to %d: the mesh has %d vertices)",
                                   index, s->n_vertices - 1, s->n_vertices);
            faces[f * k + i] = index;
        }
        snprintf(what, sizeof what, "%s %d", kind, f);
        if (!check_face(L, face, what, s, &faces[f * k], k)) return false;
    }
    return true;
}

static bool load_mesh(struct loader *L, const yaml_node_t *map, const char *where, struct shape_desc *s)
{
    yaml_node_t *verts, *tris, *quads;
    if (!(verts = config_need(L, map, "vertices", where)) ||
        !config_expect_type(L, verts, YAML_SEQUENCE_NODE, "a sequence") ||
        !config_get_optional(L, map, "triangles", YAML_SEQUENCE_NODE, &tris) ||
        !config_get_optional(L, map, "quads", YAML_SEQUENCE_NODE, &quads))
        return false;
    int nv = config_seq_count(verts), nt = tris ? config_seq_count(tris) : 0, nq = quads ? config_seq_count(quads) : 0;
    if (nv < 3) return config_fail(L, verts, "%s has %d vertices (expected at least 3)", where, nv);
    if (nt + nq == 0) return config_fail(L, map, "%s has no faces (expected triangles, quads or both)", where);
    if (!shape_alloc(L, s, nv, nt, nq)) return false;
    for (int i = 0; i < nv; ++i)
        if (!config_get_vec3(L, config_seq_item(L, verts, i), &s->vertices[i])) return false;
    struct transform t;
    bool present;
    if (!config_get_transform(L, map, &t, &present)) return false;
    if (present)
        for (int i = 0; i < nv; ++i) s->vertices[i] = transform_point(&t, s->vertices[i]);
    if (!((!tris || get_faces(L, tris, "triangle", 3, s, &s->triangles[0][0])) &&
          (!quads || get_faces(L, quads, "quad", 4, s, &s->quads[0][0]))))
        return false;
    if (present && transform_det(&t) < 0.0) {
        if (nt) reverse_faces(&s->triangles[0][0], nt, 3);
        if (nq) reverse_faces(&s->quads[0][0], nq, 4);
    }
    return true;
}

/* Box corners by bits (x, y, z) of the index; faces wound counter-clockwise
   seen from outside. */
static bool load_box(struct loader *L, const yaml_node_t *map, const char *where, struct shape_desc *s)
{
    static const int faces[6][4] = { { 0, 4, 6, 2 }, { 1, 3, 7, 5 }, { 0, 1, 5, 4 },
                                     { 2, 6, 7, 3 }, { 0, 2, 3, 1 }, { 4, 5, 7, 6 } };
    yaml_node_t *nmin, *nmax;
    struct vec3 lo, hi;
    if (!(nmin = config_need(L, map, "min", where)) || !config_get_vec3(L, nmin, &lo) ||
        !(nmax = config_need(L, map, "max", where)) || !config_get_vec3(L, nmax, &hi))
        return false;
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z))
        return config_fail(L, nmax, "expected max > min on every axis, got min [%g, %g, %g] and max [%g, %g, %g]", lo.x,
                           lo.y, lo.z, hi.x, hi.y, hi.z);
    struct transform t;
    bool present;
    if (!config_get_transform(L, map, &t, &present)) return false;
    if (!shape_alloc(L, s, 8, 0, 6)) return false;
    for (int i = 0; i < 8; ++i) {
        s->vertices[i] = vec3_make(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
        if (present) s->vertices[i] = transform_point(&t, s->vertices[i]);
    }
    memcpy(s->quads, faces, sizeof faces);
    if (present && transform_det(&t) < 0.0) reverse_faces(&s->quads[0][0], 6, 4);
    char what[CONFIG_NAME_MAX + 48];
    for (int f = 0; f < 6; ++f) {
        snprintf(what, sizeof what, "%s face %d", where, f);
        if (!check_face(L, map, what, s, s->quads[f], 4)) return false;
    }
    return true;
}

static bool load_quad(struct loader *L, const yaml_node_t *map, const char *where, struct shape_desc *s)
{
    yaml_node_t *n;
    struct polygon poly;
    if (!(n = config_need(L, map, "vertices", where)) || !get_polygon(L, map, n, where, 4, 4, &poly)) return false;
    if (!shape_alloc(L, s, 4, 0, 1)) return false;
    for (int i = 0; i < 4; ++i) {
        s->vertices[i] = poly.v[i];
        s->quads[0][i] = i;
    }
    return true;
}

/* digest: {fnv1a64: "16 hex digits", bytes: N}, as the effective YAML
   writes it: when given, the file must still be the one it was made from. */
static bool check_digest(struct loader *L, const yaml_node_t *map, const char *name, uint64_t hash, size_t bytes)
{
    yaml_node_t *d, *h, *b;
    char hex[24], have[24];
    double n;
    if (!config_get_optional(L, map, "digest", YAML_MAPPING_NODE, &d)) return false;
    if (!d) return true;
    if (!config_check_keys(L, d, "digest", digest_keys, COUNT(digest_keys)) ||
        !(h = config_need(L, d, "fnv1a64", "digest")) || !config_get_string(L, h, hex, sizeof hex) ||
        !(b = config_need(L, d, "bytes", "digest")) ||
        !config_get_number_in(L, b, 0.0, false, 9007199254740992.0, false, &n))
        return false;
    snprintf(have, sizeof have, "%016" PRIx64, hash);
    if (strcmp(hex, have) != 0 || n != (double)bytes)
        return config_fail(L, d,
                           "mesh \"%s\" has changed: fnv1a64 %s and %zu bytes now, the config says %s and %.0f "
                           "(expected the file the config was made with)",
                           name, have, bytes, hex, n);
    return true;
}

/* Remembers a mesh file for config.files, once. */
static bool add_mesh_file(struct loader *L, const char *path)
{
    for (int i = 0; i < L->n_mesh_files; ++i)
        if (strcmp(L->mesh_files[i], path) == 0) return true;
    char **grown = realloc(L->mesh_files, (size_t)(L->n_mesh_files + 1) * sizeof *grown);
    if (!grown) return error_set(L->err, "%s: out of memory", L->file);
    L->mesh_files = grown;
    if (!(L->mesh_files[L->n_mesh_files] = strdup(path))) return error_set(L->err, "%s: out of memory", L->file);
    ++L->n_mesh_files;
    return true;
}

/* The mesh's triangles after the transform, each checked as an inline
   triangle is, then moved into s. */
/* Drops the triangles marked in drop (and the vertices only they used) from
   s, keeping the order of the others. */
static void drop_triangles(struct shape_desc *s, const unsigned char *drop, int *remap)
{
    int nt = 0, nv = 0;
    for (int i = 0; i < s->n_vertices; ++i) remap[i] = -1;
    for (int f = 0; f < s->n_triangles; ++f) {
        if (drop[f]) continue;
        for (int c = 0; c < 3; ++c) {
            int *r = &remap[s->triangles[f][c]];
            if (*r < 0) *r = nv++;
            s->triangles[nt][c] = *r;
        }
        ++nt;
    }
    for (int i = 0; i < s->n_vertices; ++i)
        if (remap[i] >= 0) s->vertices[remap[i]] = s->vertices[i]; /* remap[i] <= i: in place */
    s->n_triangles = nt;
    s->n_vertices = nv;
}

/* A file mesh into s, after its transform. A zero-area (degenerate)
   triangle of a surface is dropped, with one warning on stderr per mesh
   that says how many: it covers nothing, so the surface is the same, and
   real meshes hold them (the White Room's OBJ files have thousands); the
   effective YAML keeps file:, so a reload drops them again. A mesh light's
   is refused: each of its triangles is a light (light_init needs its
   normal and area) whose index the scene's messages and statistics name. A
   mesh whose every triangle is degenerate is refused too. */
static bool take_mesh(struct loader *L, const yaml_node_t *file, const char *name, const struct transform *t,
                      bool present, bool is_light, struct mesh_data *m, struct shape_desc *s)
{
    if (present) {
        for (int i = 0; i < m->n_vertices; ++i) m->vertices[i] = transform_point(t, m->vertices[i]);
        if (transform_det(t) < 0.0) reverse_faces(&m->triangles[0][0], m->n_triangles, 3);
    }
    s->vertices = m->vertices;
    s->n_vertices = m->n_vertices;
    s->triangles = m->triangles;
    s->n_triangles = m->n_triangles;
    memset(m, 0, sizeof *m);
    char what[CONFIG_PATH_MAX + 128];
    unsigned char *drop = NULL;
    int n_drop = 0, first_drop = -1;
    for (int f = 0; f < s->n_triangles; ++f) {
        /* The quick test passes nearly every triangle of a real mesh; the
           full check (and its message) only for the others. */
        const int *tri = s->triangles[f];
        if (polygon_triangle_is_sound(s->vertices[tri[0]], s->vertices[tri[1]], s->vertices[tri[2]])) continue;
        struct polygon poly = { 3, { s->vertices[tri[0]], s->vertices[tri[1]], s->vertices[tri[2]] } };
        if (!is_light && polygon_check(&poly) == POLYGON_DEFECT_DEGENERATE) {
            if (!drop && !(drop = calloc((size_t)s->n_triangles, 1))) {
                return error_set(L->err, "%s: out of memory", L->file);
            }
            drop[f] = 1;
            if (n_drop++ == 0) first_drop = f;
            continue;
        }
        snprintf(what, sizeof what, "mesh \"%s\": triangle %d (after triangulation)", name, f);
        if (!check_face(L, file, what, s, tri, 3)) {
            free(drop);
            return false;
        }
    }
    if (n_drop == 0) return true;
    if (n_drop == s->n_triangles) {
        free(drop);
        snprintf(what, sizeof what, "mesh \"%s\": every triangle (%d) is degenerate; triangle %d (after triangulation)",
                 name, n_drop, first_drop);
        return check_face(L, file, what, s, s->triangles[first_drop], 3);
    }
    int *remap = malloc(sizeof *remap * (size_t)s->n_vertices);
    if (!remap) {
        free(drop);
        return error_set(L->err, "%s: out of memory", L->file);
    }
    int n_before = s->n_triangles;
    drop_triangles(s, drop, remap);
    free(remap);
    free(drop);
    struct source_loc loc = config_loc_of(L, file);
    fprintf(stderr,
            "%s:%d:%d: warning: mesh \"%s\": dropped %d degenerate (zero-area) triangle%s of %d, the first "
            "triangle %d (after triangulation)\n",
            loc.file, loc.line, loc.column, name, n_drop, n_drop == 1 ? "" : "s", n_before, first_drop);
    return true;
}

/* A mesh from an OBJ, PLY or serialized file (mesh_file.h), its path
   relative to the folder of the config file that names it, as include:
   paths are; of a serialized file, the shape its shape_index names (0 when
   absent). */
static bool load_mesh_file(struct loader *L, const yaml_node_t *map, const yaml_node_t *file, bool is_light,
                           struct shape_desc *s, struct shape_file *sf)
{
    char name[CONFIG_PATH_MAX];
    struct transform t;
    bool present;
    enum mesh_format format;
    if (!config_get_string(L, file, name, sizeof name) || !config_get_transform(L, map, &t, &present)) return false;
    if (!mesh_format_from_path(name, &format)) {
        const char *dot = strrchr(name, '.'), *slash = strrchr(name, '/');
        bool ext = dot && (!slash || dot > slash);
        return config_fail(L, file,
                           "mesh \"%s\": unknown mesh format %s%.16s%s (expected a .obj, .ply or .serialized file)",
                           name, ext ? "\"" : "", ext ? dot : "(no extension)", ext ? "\"" : "");
    }
    int shape = 0;
    yaml_node_t *shape_node = config_map_get(L, map, "shape_index");
    if (shape_node && format != MESH_FORMAT_SERIALIZED)
        return config_fail(L, shape_node,
                           "mesh \"%s\": shape_index is for a .serialized file of several shapes (expected no "
                           "shape_index: an OBJ or PLY file holds one mesh)",
                           name);
    if (shape_node && !config_get_int(L, shape_node, 0, INT_MAX, &shape)) return false;
    if (name[0] != '/' && L->from_string)
        return config_fail(L, file,
                           "mesh \"%s\": a relative path in a config given as a string (expected an absolute path: "
                           "there is no folder to resolve it against)",
                           name);
    const char *parent = L->sources[config_source_of(L, file)].path, *slash = strrchr(parent, '/');
    size_t dir_len = name[0] == '/' || !slash ? 0 : (size_t)(slash - parent) + 1;
    char path[2 * CONFIG_PATH_MAX];
    snprintf(path, sizeof path, "%.*s%s", (int)dir_len, parent, name);

    char *text;
    size_t length;
    struct stat st;
    const char *why;
    if (!config_read_text(path, &text, &length, &st, &why))
        return config_fail(L, file,
                           "mesh \"%s\": cannot read %s: %s (expected an OBJ, PLY or serialized file; a relative "
                           "path is relative to the folder of the config file that names it)",
                           name, path, why);
    sf->fnv1a64 = config_fnv1a64(text, length);
    sf->bytes = length;
    sf->has_transform = present;
    sf->transform = t;
    sf->shape_index = format == MESH_FORMAT_SERIALIZED ? shape : -1;
    struct mesh_data m = { 0, NULL, 0, NULL };
    struct error merr = { "" };
    int n_shapes = 1;
    bool ok = check_digest(L, map, name, sf->fnv1a64, sf->bytes);
    ok = ok && (mesh_file_shape_count(text, length, format, &n_shapes, &merr) ||
                config_fail(L, file, "mesh \"%s\": %s", name, merr.message));
    /* shape < n_shapes when shape_index is absent (shape 0, n_shapes >= 1). */
    ok = ok &&
         (shape < n_shapes || config_fail(L, shape_node,
                                          "mesh \"%s\": shape_index %d is out of range (the file holds %d shape%s: "
                                          "expected 0 to %d)",
                                          name, shape, n_shapes, n_shapes == 1 ? "" : "s", n_shapes - 1));
    ok = ok && (mesh_file_parse_shape(text, length, format, shape, &m, &merr) ||
                config_fail(L, file, "mesh \"%s\": %s", name, merr.message));
    free(text);
    if (!ok) return false;
    ok = take_mesh(L, file, name, &t, present, is_light, &m, s);
    mesh_data_free(&m);
    if (!ok) return false;
    /* Absolute: the effective YAML is written into the output folder. */
    if (!(sf->path = realpath(path, NULL)))
        return config_fail(L, file, "mesh \"%s\": cannot resolve %s: %s", name, path, strerror(errno));
    return add_mesh_file(L, path);
}

static int find_material(const struct config *c, const char *name)
{
    for (int i = 0; i < c->n_materials; ++i)
        if (strcmp(c->materials[i].name, name) == 0) return i;
    return -1;
}

static bool load_shape(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct shape_desc *s = &c->shapes[index];
    char *name = L->shape_names[index];
    char where[CONFIG_NAME_MAX + 24];
    yaml_node_t *n;
    int kind = 0;
    s->loc = config_loc_of(L, map);
    if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping")) return false;
    if ((n = config_map_get(L, map, "name")) && !config_get_string(L, n, name, CONFIG_NAME_MAX)) return false;
    if (name[0]) snprintf(where, sizeof where, "shape %d (%s)", index, name);
    else snprintf(where, sizeof where, "shape %d", index);
    if (!(n = config_need(L, map, "type", where)) || !config_get_enum(L, n, "shape type", shape_kind_names, 3, &kind))
        return false;
    yaml_node_t *file = kind == SHAPE_MESH ? config_map_get(L, map, "file") : NULL;
    const char *const *keys = kind == SHAPE_QUAD  ? quad_keys
                              : kind == SHAPE_BOX ? box_keys
                              : file              ? mesh_file_keys
                                                  : mesh_keys;
    int n_keys = kind == SHAPE_QUAD  ? COUNT(quad_keys)
                 : kind == SHAPE_BOX ? COUNT(box_keys)
                 : file              ? COUNT(mesh_file_keys)
                                     : COUNT(mesh_keys);
    if (!config_check_keys(L, map, where, keys, n_keys)) return false;

    char material[CONFIG_NAME_MAX];
    if (!(n = config_need(L, map, "material", where)) || !config_get_string(L, n, material, sizeof material))
        return false;
    s->material = find_material(c, material);
    if (s->material < 0) {
        struct config_line list = { "", 0 };
        for (int i = 0; i < c->n_materials; ++i) config_line_add(&list, c->materials[i].name);
        return config_fail(L, n, "unknown material \"%s\" (expected one of: %s)", material,
                           c->n_materials ? list.s : "no materials are defined");
    }
    switch ((enum shape_kind)kind) {
    case SHAPE_QUAD:
        return load_quad(L, map, where, s);
    case SHAPE_BOX:
        return load_box(L, map, where, s);
    case SHAPE_MESH:
        return file ? load_mesh_file(L, map, file, false, s, &L->shape_files[index]) : load_mesh(L, map, where, s);
    }
    return false;
}

static bool load_shapes(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq;
    if (!config_get_optional(L, root, "shapes", YAML_SEQUENCE_NODE, &seq)) return false;
    int n = seq ? config_seq_count(seq) : 0;
    if (n == 0) return true;
    c->shapes = calloc((size_t)n, sizeof *c->shapes);
    L->shape_names = calloc((size_t)n, sizeof *L->shape_names);
    L->shape_files = calloc((size_t)n, sizeof *L->shape_files);
    if (!c->shapes || !L->shape_names || !L->shape_files) return error_set(L->err, "%s: out of memory", L->file);
    c->n_shapes = n;
    for (int i = 0; i < n; ++i)
        if (!load_shape(L, config_seq_item(L, seq, i), i, c)) return false;
    return true;
}

/* A mesh light's `mesh: {file, transform, digest}`: the triangles of an OBJ
   or PLY file, each one an emitter (config.h). */
static bool load_light_mesh(struct loader *L, const yaml_node_t *map, const char *where, int index,
                            struct light_desc *l)
{
    yaml_node_t *mesh = config_map_get(L, map, "mesh"), *file;
    char what[CONFIG_NAME_MAX + 24];
    snprintf(what, sizeof what, "%s mesh", where);
    if (!config_expect_type(L, mesh, YAML_MAPPING_NODE, "a mapping {file, transform}") ||
        !config_check_keys(L, mesh, what, light_mesh_keys, COUNT(light_mesh_keys)) ||
        !(file = config_need(L, mesh, "file", what)) ||
        !load_mesh_file(L, mesh, file, true, &l->mesh, &L->light_files[index]))
        return false;
    l->mesh.material = -1;
    l->mesh.loc = config_loc_of(L, mesh);
    return true;
}

static bool load_light(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct light_desc *l = &c->lights[index];
    char where[CONFIG_NAME_MAX + 16];
    yaml_node_t *name, *n;
    l->loc = config_loc_of(L, map);
    snprintf(where, sizeof where, "light %d", index);
    if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping")) return false;
    bool is_mesh = config_map_get(L, map, "mesh") != NULL;
    if (is_mesh && (n = config_map_get(L, map, "transform")))
        return config_fail(L, n, "%s: a mesh light's transform goes inside its mesh (expected mesh: {file, transform})",
                           where);
    if (!(is_mesh ? config_check_keys(L, map, where, mesh_light_keys, COUNT(mesh_light_keys))
                  : config_check_keys(L, map, where, light_keys, COUNT(light_keys))) ||
        !(name = config_need(L, map, "name", where)) || !config_get_string(L, name, l->name, sizeof l->name))
        return false;
    for (int i = 0; i < index; ++i)
        if (strcmp(c->lights[i].name, l->name) == 0)
            return config_fail(L, name, "duplicate light name \"%s\" (first at line %d, column %d)", l->name,
                               c->lights[i].loc.line, c->lights[i].loc.column);
    snprintf(where, sizeof where, "light \"%s\"", l->name);
    if (is_mesh) {
        if (!load_light_mesh(L, map, where, index, l)) return false;
    } else if (!(n = config_need(L, map, "vertices", where)) ||
               !get_polygon(L, map, n, where, 3, POLYGON_INPUT_MAX, &l->polygon)) {
        return false;
    }
    if (!(n = config_need(L, map, "radiance", where)) || !config_get_rgb(L, n, 0.0, INFINITY, &l->radiance))
        return false;
    if (rgb_is_black(l->radiance))
        return config_fail(L, n, "%s has zero radiance (expected a positive component)", where);
    l->two_sided = false;
    return !(n = config_map_get(L, map, "two_sided")) || config_get_bool(L, n, &l->two_sided);
}

static bool load_lights(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq;
    if (!config_get_optional(L, root, "lights", YAML_SEQUENCE_NODE, &seq)) return false;
    if (!seq || config_seq_count(seq) == 0)
        return config_fail(L, seq ? seq : root,
                           "scene has no lights (expected a lights sequence with at least one light)");
    int n = config_seq_count(seq);
    c->lights = calloc((size_t)n, sizeof *c->lights);
    L->light_files = calloc((size_t)n, sizeof *L->light_files);
    if (!c->lights || !L->light_files) return error_set(L->err, "%s: out of memory", L->file);
    c->n_lights = n;
    for (int i = 0; i < n; ++i)
        if (!load_light(L, config_seq_item(L, seq, i), i, c)) return false;
    return true;
}

/* A portal is useful only on the side its light emits to, and one lying in
   the light's own plane would pass no light at all. */
static bool check_portal_placement(struct loader *L, const yaml_node_t *n, const struct portal_desc *p,
                                   const struct light_desc *l)
{
    if (l->mesh.n_triangles > 0) {
        /* Each triangle becomes a light of this portal (antishadow.h): the
           whole mesh must lie strictly on one side of the portal's plane. */
        struct plane pp = polygon_plane(&p->polygon);
        double tol = POLYGON_PLANARITY_TOLERANCE * polygon_diameter(&p->polygon);
        int below = 0, above = 0;
        for (int i = 0; i < l->mesh.n_vertices; ++i) {
            double d = plane_distance(&pp, l->mesh.vertices[i]);
            below += d < -tol;
            above += d > tol;
        }
        if (below + above < l->mesh.n_vertices || (below && above))
            return config_fail(L, n,
                               "portal \"%s\" cuts its mesh light \"%s\": %d of its %d vertices lie on or across "
                               "the portal's plane (expected the whole mesh on one side of it)",
                               p->name, l->name,
                               below && above ? (below < above ? below : above) : l->mesh.n_vertices - below - above,
                               l->mesh.n_vertices);
        return true;
    }
    struct plane pl = polygon_plane(&l->polygon);
    double size = fmax(polygon_diameter(&l->polygon), polygon_diameter(&p->polygon));
    double tol = POLYGON_PLANARITY_TOLERANCE * size, dmin = INFINITY, dmax = -INFINITY;
    for (int i = 0; i < p->polygon.n; ++i) {
        double d = plane_distance(&pl, p->polygon.v[i]);
        dmin = fmin(dmin, d);
        dmax = fmax(dmax, d);
    }
    if (dmin >= -tol && dmax <= tol)
        return config_fail(L, n,
                           "portal \"%s\" is coplanar with its light \"%s\" (expected a portal off the light's plane)",
                           p->name, l->name);
    if (!l->two_sided && dmin < -tol)
        return config_fail(L, n,
                           "portal \"%s\" is behind its light \"%s\" (expected every vertex on the emitting side, "
                           "towards the light's normal)",
                           p->name, l->name);
    return true;
}

/* The light a portal entry names, into *light. */
static bool get_portal_light(struct loader *L, const yaml_node_t *n, const char *what, const struct config *c,
                             int *light)
{
    char name[CONFIG_NAME_MAX];
    if (!config_get_string(L, n, name, sizeof name)) return false;
    *light = -1;
    for (int i = 0; i < c->n_lights; ++i)
        if (strcmp(c->lights[i].name, name) == 0) *light = i;
    if (*light >= 0) return true;
    struct config_line list = { "", 0 };
    for (int i = 0; i < c->n_lights; ++i) config_line_add(&list, c->lights[i].name);
    return config_fail(L, n, "%s refers to unknown light \"%s\" (expected one of: %s)", what, name, list.s);
}

/* An entry {light: <name>, auto: true}: that light's portals are found
   from the geometry at scene build. */
static bool load_auto_portal(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    yaml_node_t *n = config_map_get(L, map, "auto");
    bool on = false;
    char where[48];
    snprintf(where, sizeof where, "portal %d (auto)", index);
    if (!config_get_bool(L, n, &on)) return false;
    if (!on)
        return config_fail(L, n,
                           "portal %d has auto: false (expected auto: true, or a hand-written portal with "
                           "vertices and no auto key)",
                           index);
    if (config_map_get(L, map, "vertices") || config_map_get(L, map, "name") || config_map_get(L, map, "transform"))
        if (!config_check_keys(L, map, "an auto portal entry {light: <name>, auto: true}", auto_portal_keys,
                               COUNT(auto_portal_keys)))
            return false;
    int light;
    if (!(n = config_need(L, map, "light", where)) || !get_portal_light(L, n, "auto portal entry", c, &light))
        return false;
    struct light_desc *l = &c->lights[light];
    for (int i = 0; i < c->n_portals; ++i)
        if (c->portals[i].light == light)
            return config_fail(L, map,
                               "light \"%s\" has auto portals and the hand-written portal \"%s\" (at line %d, "
                               "column %d) (expected either {light: %s, auto: true} or hand-written portals)",
                               l->name, c->portals[i].name, c->portals[i].loc.line, c->portals[i].loc.column, l->name);
    if (l->auto_portals)
        return config_fail(L, map, "light \"%s\" has auto portals twice (first at line %d, column %d)", l->name,
                           l->auto_loc.line, l->auto_loc.column);
    l->auto_portals = true;
    l->auto_loc = config_loc_of(L, map);
    return true;
}

static bool load_portal(struct loader *L, const yaml_node_t *map, struct portal_desc *p, int index, struct config *c)
{
    char where[CONFIG_NAME_MAX + 16];
    yaml_node_t *n, *verts;
    p->loc = config_loc_of(L, map);
    snprintf(where, sizeof where, "portal %d", index);
    snprintf(p->name, sizeof p->name, "portal%d", index);
    if ((n = config_map_get(L, map, "name")) && !config_get_string(L, n, p->name, sizeof p->name)) return false;
    for (const struct portal_desc *q = c->portals; q < p; ++q)
        if (strcmp(q->name, p->name) == 0)
            return config_fail(L, n ? n : map, "duplicate portal name \"%s\" (first at line %d, column %d)", p->name,
                               q->loc.line, q->loc.column);
    snprintf(where, sizeof where, "portal \"%s\"", p->name);
    char what[CONFIG_NAME_MAX + 16];
    snprintf(what, sizeof what, "portal \"%s\"", p->name);
    if (!(n = config_need(L, map, "light", where)) || !get_portal_light(L, n, what, c, &p->light)) return false;
    if (!(verts = config_need(L, map, "vertices", where)) ||
        !get_polygon(L, map, verts, where, 3, POLYGON_INPUT_MAX, &p->polygon))
        return false;
    return check_portal_placement(L, verts, p, &c->lights[p->light]);
}

/* `portals:` is a list of hand-written portals and {light: <name>, auto:
   true} entries, or the word `auto` for every light. */
static bool load_portals(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq = config_map_get(L, root, "portals");
    if (seq && config_is_null(seq)) seq = NULL;
    if (seq && seq->type == YAML_SCALAR_NODE && strcmp(config_text(seq), "auto") == 0) {
        c->portals_auto = true;
        for (int i = 0; i < c->n_lights; ++i) {
            c->lights[i].auto_portals = true;
            c->lights[i].auto_loc = config_loc_of(L, seq);
        }
        return true;
    }
    if (seq && seq->type != YAML_SEQUENCE_NODE) {
        char buf[64];
        return config_fail(L, seq,
                           "expected `auto` or a sequence of portals (hand-written {name, light, vertices} or "
                           "{light: <name>, auto: true}), got %s",
                           config_describe_node(seq, buf, sizeof buf));
    }
    int n = seq ? config_seq_count(seq) : 0;
    if (n == 0) return true;
    c->portals = calloc((size_t)n, sizeof *c->portals);
    if (!c->portals) return error_set(L->err, "%s: out of memory", L->file);
    for (int i = 0; i < n; ++i) {
        yaml_node_t *map = config_seq_item(L, seq, i);
        char where[32];
        snprintf(where, sizeof where, "portal %d", i);
        if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
            !config_check_keys(L, map, where, portal_keys, COUNT(portal_keys)))
            return false;
        if (config_map_get(L, map, "auto")) {
            if (!load_auto_portal(L, map, i, c)) return false;
            continue;
        }
        struct portal_desc *p = &c->portals[c->n_portals];
        if (!load_portal(L, map, p, i, c)) return false;
        const struct light_desc *l = &c->lights[p->light];
        if (l->auto_portals)
            return config_fail(L, map,
                               "portal \"%s\" is hand-written for light \"%s\", which has auto portals (at line %d, "
                               "column %d) (expected either {light: %s, auto: true} or hand-written portals)",
                               p->name, l->name, l->auto_loc.line, l->auto_loc.column, l->name);
        ++c->n_portals;
    }
    return true;
}

bool config_load_scene(struct loader *L, const yaml_node_t *root, struct config *c)
{
    return load_camera(L, root, &c->camera) && load_film(L, root, c) && load_materials(L, root, c) &&
           load_shapes(L, root, c) && load_lights(L, root, c) && load_portals(L, root, c);
}

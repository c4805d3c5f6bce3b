/* config.c: the public API of the config module (config_load,
   config_load_string, config_free) and the section loaders. */
#include "config.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "config_internal.h"

enum shape_kind { SHAPE_QUAD, SHAPE_BOX, SHAPE_MESH };
static const char *const shape_kind_names[3] = { "quad", "box", "mesh" };

static const char *const top_keys[] = { "include", "params", "camera",  "film",  "materials",
                                        "shapes",  "lights", "portals", "render" };
static const char *const camera_keys[] = { "position", "look_at", "up", "fov_y" };
static const char *const film_keys[] = { "width", "height" };
static const char *const diffuse_keys[] = { "type", "albedo" };
static const char *const ggx_keys[] = { "type", "albedo", "roughness" };
static const char *const quad_keys[] = { "name", "type", "material", "vertices" };
static const char *const box_keys[] = { "name", "type", "material", "min", "max" };
static const char *const mesh_keys[] = { "name", "type", "material", "vertices", "triangles", "quads" };
static const char *const light_keys[] = { "name", "vertices", "radiance", "two_sided" };
static const char *const portal_keys[] = { "name", "light", "vertices" };
static const char *const render_keys[] = { "integrator", "strategy", "mis",       "portal_weight", "defensive",
                                           "max_depth",  "rr_depth", "spp",       "time",          "snapshots",
                                           "seed",       "threads",  "output",    "aov",
                                           "resumable" };
static const char *const snapshot_keys[] = { "every", "doubling", "times", "every_spp", "doubling_spp", "spp" };
static const char *const aov_keys[] = { "region" };

#define PARALLEL_TOL 1e-9     /* |sin| of the angle between up and the view direction */

#define FILM_SIZE_MAX 16384
#define THREADS_MAX 256

/* A polygon's validity (polygon_check) as a message at the node. */
static bool check_polygon(struct loader *L, const yaml_node_t *n, const char *what, const struct polygon *poly)
{
    switch (polygon_check(poly)) {
    case POLYGON_DEFECT_NONE: return true;
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

/* A polygon of min..max points; checked by check_polygon. */
static bool get_polygon(struct loader *L, const yaml_node_t *n, const char *what, int min, int max,
                        struct polygon *out)
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
    return check_polygon(L, n, what, out);
}

static bool load_params(struct loader *L, const yaml_node_t *root)
{
    yaml_node_t *map;
    if (!config_get_optional(L, root, "params", YAML_MAPPING_NODE, &map)) return false;
    if (!map) return true;
    if (!config_check_keys(L, map, "params", NULL, 0)) return false;
    int n = config_map_count(map);
    L->params = calloc((size_t)n, sizeof *L->params);
    if (!L->params) return error_set(L->err, "%s: out of memory", L->file);
    for (int i = 0; i < n; ++i) {
        const yaml_node_t *key = config_node(L, map->data.mapping.pairs.start[i].key);
        const char *name = config_text(key);
        if (!expr_is_identifier(name))
            return config_fail(L, key,
                               "invalid param name \"%.64s\" (expected letters, digits and _, not starting "
                               "with a digit)",
                               name);
        if (expr_is_reserved(name))
            return config_fail(L, key,
                               "param name \"%s\" is reserved (expected a name other than pi, min, max, abs, "
                               "sqrt, sin, cos, tan)",
                               name);
        /* Params see only the ones before them, so definitions cannot loop. */
        double v;
        if (!config_get_number(L, config_node(L, map->data.mapping.pairs.start[i].value), "a number", &v)) return false;
        L->params[L->n_params].name = name;
        L->params[L->n_params].value = v;
        ++L->n_params;
    }
    return true;
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
        return config_fail(L, up, "up is parallel to the view direction (expected a direction not along look_at - "
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

static bool load_material(struct loader *L, const yaml_node_t *key, const yaml_node_t *map,
                          struct material_desc *m)
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
    struct polygon poly;
    memset(&poly, 0, sizeof poly);
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
    return (!tris || get_faces(L, tris, "triangle", 3, s, &s->triangles[0][0])) &&
           (!quads || get_faces(L, quads, "quad", 4, s, &s->quads[0][0]));
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
    if (!shape_alloc(L, s, 8, 0, 6)) return false;
    for (int i = 0; i < 8; ++i)
        s->vertices[i] = vec3_make(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    char what[CONFIG_NAME_MAX + 48];
    for (int f = 0; f < 6; ++f) {
        memcpy(s->quads[f], faces[f], sizeof faces[f]);
        snprintf(what, sizeof what, "%s face %d", where, f);
        if (!check_face(L, map, what, s, faces[f], 4)) return false;
    }
    return true;
}

static bool load_quad(struct loader *L, const yaml_node_t *map, const char *where, struct shape_desc *s)
{
    yaml_node_t *n;
    struct polygon poly;
    if (!(n = config_need(L, map, "vertices", where)) || !get_polygon(L, n, where, 4, 4, &poly)) return false;
    if (!shape_alloc(L, s, 4, 0, 1)) return false;
    for (int i = 0; i < 4; ++i) {
        s->vertices[i] = poly.v[i];
        s->quads[0][i] = i;
    }
    return true;
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
    if (name[0])
        snprintf(where, sizeof where, "shape %d (%s)", index, name);
    else
        snprintf(where, sizeof where, "shape %d", index);
    if (!(n = config_need(L, map, "type", where)) || !config_get_enum(L, n, "shape type", shape_kind_names, 3, &kind))
        return false;
    const char *const *keys = kind == SHAPE_QUAD ? quad_keys : kind == SHAPE_BOX ? box_keys : mesh_keys;
    int n_keys = kind == SHAPE_QUAD ? COUNT(quad_keys) : kind == SHAPE_BOX ? COUNT(box_keys) : COUNT(mesh_keys);
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
    case SHAPE_QUAD: return load_quad(L, map, where, s);
    case SHAPE_BOX: return load_box(L, map, where, s);
    case SHAPE_MESH: return load_mesh(L, map, where, s);
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
    if (!c->shapes || !L->shape_names) return error_set(L->err, "%s: out of memory", L->file);
    c->n_shapes = n;
    for (int i = 0; i < n; ++i)
        if (!load_shape(L, config_seq_item(L, seq, i), i, c)) return false;
    return true;
}

static bool load_light(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct light_desc *l = &c->lights[index];
    char where[CONFIG_NAME_MAX + 16];
    yaml_node_t *name, *n;
    l->loc = config_loc_of(L, map);
    snprintf(where, sizeof where, "light %d", index);
    if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !config_check_keys(L, map, where, light_keys, COUNT(light_keys)) ||
        !(name = config_need(L, map, "name", where)) || !config_get_string(L, name, l->name, sizeof l->name))
        return false;
    for (int i = 0; i < index; ++i)
        if (strcmp(c->lights[i].name, l->name) == 0)
            return config_fail(L, name, "duplicate light name \"%s\" (first at line %d, column %d)", l->name,
                               c->lights[i].loc.line, c->lights[i].loc.column);
    snprintf(where, sizeof where, "light \"%s\"", l->name);
    if (!(n = config_need(L, map, "vertices", where)) ||
        !get_polygon(L, n, where, 3, POLYGON_INPUT_MAX, &l->polygon) || !(n = config_need(L, map, "radiance", where)) ||
        !config_get_rgb(L, n, 0.0, INFINITY, &l->radiance))
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
    if (!c->lights) return error_set(L->err, "%s: out of memory", L->file);
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

static bool load_portal(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct portal_desc *p = &c->portals[index];
    char where[CONFIG_NAME_MAX + 16], light[CONFIG_NAME_MAX];
    yaml_node_t *n, *verts;
    p->loc = config_loc_of(L, map);
    snprintf(where, sizeof where, "portal %d", index);
    if (!config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !config_check_keys(L, map, where, portal_keys, COUNT(portal_keys)))
        return false;
    snprintf(p->name, sizeof p->name, "portal%d", index);
    if ((n = config_map_get(L, map, "name")) && !config_get_string(L, n, p->name, sizeof p->name)) return false;
    for (int i = 0; i < index; ++i)
        if (strcmp(c->portals[i].name, p->name) == 0)
            return config_fail(L, n ? n : map, "duplicate portal name \"%s\" (first at line %d, column %d)", p->name,
                               c->portals[i].loc.line, c->portals[i].loc.column);
    snprintf(where, sizeof where, "portal \"%s\"", p->name);
    if (!(n = config_need(L, map, "light", where)) || !config_get_string(L, n, light, sizeof light)) return false;
    p->light = -1;
    for (int i = 0; i < c->n_lights; ++i)
        if (strcmp(c->lights[i].name, light) == 0) p->light = i;
    if (p->light < 0) {
        struct config_line list = { "", 0 };
        for (int i = 0; i < c->n_lights; ++i) config_line_add(&list, c->lights[i].name);
        return config_fail(L, n, "portal \"%s\" refers to unknown light \"%s\" (expected one of: %s)", p->name, light,
                           list.s);
    }
    if (!(verts = config_need(L, map, "vertices", where)) ||
        !get_polygon(L, verts, where, 3, POLYGON_INPUT_MAX, &p->polygon))
        return false;
    return check_portal_placement(L, verts, p, &c->lights[p->light]);
}

static bool load_portals(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq;
    if (!config_get_optional(L, root, "portals", YAML_SEQUENCE_NODE, &seq)) return false;
    int n = seq ? config_seq_count(seq) : 0;
    if (n == 0) return true;
    c->portals = calloc((size_t)n, sizeof *c->portals);
    if (!c->portals) return error_set(L->err, "%s: out of memory", L->file);
    c->n_portals = n;
    for (int i = 0; i < n; ++i)
        if (!load_portal(L, config_seq_item(L, seq, i), i, c)) return false;
    return true;
}

/* Strictly increasing positive times, at most CONFIG_SCHEDULE_MAX. */
static bool get_times(struct loader *L, const yaml_node_t *seq, double *times, int *count)
{
    char buf[64];
    if (config_seq_count(seq) > CONFIG_SCHEDULE_MAX)
        return config_fail(L, seq, "too many snapshot times: %d (expected at most %d)", config_seq_count(seq),
                           CONFIG_SCHEDULE_MAX);
    for (int i = 0; i < config_seq_count(seq); ++i) {
        const yaml_node_t *item = config_seq_item(L, seq, i);
        if (!config_get_number_in(L, item, 0.0, true, INFINITY, false, &times[i])) return false;
        if (i > 0 && times[i] <= times[i - 1])
            return config_fail(L, item, "snapshot times must increase (expected a time > %g, got %s)", times[i - 1],
                               config_value_text(item, times[i], buf, sizeof buf));
    }
    *count = config_seq_count(seq);
    return true;
}

static bool get_spps(struct loader *L, const yaml_node_t *seq, int *spps, int *count)
{
    if (config_seq_count(seq) > CONFIG_SCHEDULE_MAX)
        return config_fail(L, seq, "too many snapshot spps: %d (expected at most %d)", config_seq_count(seq),
                           CONFIG_SCHEDULE_MAX);
    for (int i = 0; i < config_seq_count(seq); ++i) {
        const yaml_node_t *item = config_seq_item(L, seq, i);
        if (!config_get_int(L, item, 1, INT_MAX, &spps[i])) return false;
        if (i > 0 && spps[i] <= spps[i - 1])
            return config_fail(L, item, "snapshot spps must increase (expected more than %d, got %d)", spps[i - 1],
                               spps[i]);
    }
    *count = config_seq_count(seq);
    return true;
}

static bool load_snapshots(struct loader *L, const yaml_node_t *map, struct snapshot_schedule *s)
{
    yaml_node_t *n;
    if (!config_check_keys(L, map, "render.snapshots", snapshot_keys, COUNT(snapshot_keys))) return false;
    if ((n = config_map_get(L, map, "every")) && !config_get_number_in(L, n, 0.0, false, INFINITY, false, &s->every_s))
        return false;
    if ((n = config_map_get(L, map, "doubling")) &&
        !config_get_number_in(L, n, 0.0, false, INFINITY, false, &s->doubling_s))
        return false;
    if ((n = config_map_get(L, map, "every_spp")) && !config_get_int(L, n, 0, INT_MAX, &s->every_spp)) return false;
    if ((n = config_map_get(L, map, "doubling_spp")) && !config_get_int(L, n, 0, INT_MAX, &s->doubling_spp))
        return false;
    if (!config_get_optional(L, map, "times", YAML_SEQUENCE_NODE, &n) ||
        (n && !get_times(L, n, s->times_s, &s->n_times)))
        return false;
    if (!config_get_optional(L, map, "spp", YAML_SEQUENCE_NODE, &n) || (n && !get_spps(L, n, s->spps, &s->n_spps)))
        return false;
    return true;
}

static bool load_aov(struct loader *L, const yaml_node_t *map, struct render_desc *r)
{
    yaml_node_t *n;
    if (!config_check_keys(L, map, "render.aov", aov_keys, COUNT(aov_keys))) return false;
    if ((n = config_map_get(L, map, "region")) && !config_get_bool(L, n, &r->aov_region)) return false;
    return true;
}

/* The seed is read from its text when it is a literal: a double would lose
   the low bits of seeds above 2^53. */
static bool get_seed(struct loader *L, const yaml_node_t *n, uint64_t *out)
{
    char buf[64];
    const char *expected = "a non-negative integer below 2^64";
    if (n->type == YAML_SCALAR_NODE && n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE) {
        const char *s = config_text(n);
        size_t len = strspn(s, "0123456789");
        if (len > 0 && s[len] == '\0') {
            errno = 0;
            unsigned long long v = strtoull(s, NULL, 10);
            if (errno == ERANGE || v > UINT64_MAX) return config_fail(L, n, "expected %s, got %.40s", expected, s);
            *out = (uint64_t)v;
            return true;
        }
    }
    /* Expressions and other number spellings go through doubles: exact up to 2^53. */
    double v;
    if (!config_get_number(L, n, expected, &v)) return false;
    if (v != floor(v) || v < 0.0 || v > 9007199254740992.0)
        return config_fail(L, n, "expected %s, got %s", expected, config_value_text(n, v, buf, sizeof buf));
    *out = (uint64_t)v;
    return true;
}

static bool get_threads(struct loader *L, const yaml_node_t *n, int *out)
{
    char expected[64], buf[64];
    double v;
    if (n->type == YAML_SCALAR_NODE && strcmp(config_text(n), "auto") == 0) {
        *out = 0;
        return true;
    }
    snprintf(expected, sizeof expected, "\"auto\" or an integer in [1, %d]", THREADS_MAX);
    if (!config_get_number(L, n, expected, &v)) return false;
    if (v != floor(v) || v < 1 || v > THREADS_MAX)
        return config_fail(L, n, "expected %s, got %s", expected, config_value_text(n, v, buf, sizeof buf));
    *out = (int)v;
    return true;
}

static bool load_render(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map = config_need(L, root, "render", "the top level"), *n;
    struct render_desc *r = &c->render;
    int e;
    r->integrator = INTEGRATOR_DIRECT;
    r->strategy = STRATEGY_LIGHT;
    r->mis = MIS_POWER;
    r->portal_weight = PORTAL_WEIGHT_IRRADIANCE;
    r->defensive = 0.0;
    r->max_depth = 8;
    r->rr_depth = 3;
    r->seed = 1;
    r->threads = 0;
    r->aov_region = false;
    snprintf(r->output, sizeof r->output, "results/renders/out");
    if (!map || !config_expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !config_check_keys(L, map, "render", render_keys, COUNT(render_keys)))
        return false;
    if ((n = config_map_get(L, map, "integrator"))) {
        if (!config_get_enum(L, n, "integrator", integrator_names, 2, &e)) return false;
        r->integrator = (enum integrator_kind)e;
    }
    if ((n = config_map_get(L, map, "strategy"))) {
        if (!config_get_enum(L, n, "strategy", strategy_names, STRATEGY_COUNT, &e)) return false;
        r->strategy = (enum strategy_kind)e;
    }
    if ((n = config_map_get(L, map, "mis"))) {
        if (!config_get_enum(L, n, "mis", mis_names, 3, &e)) return false;
        r->mis = (enum mis_kind)e;
    }
    if ((n = config_map_get(L, map, "portal_weight"))) {
        if (!config_get_enum(L, n, "portal_weight", portal_weight_names, 3, &e)) return false;
        r->portal_weight = (enum portal_weight_kind)e;
    }
    if ((n = config_map_get(L, map, "defensive")) && !config_get_number_in(L, n, 0.0, false, 1.0, true, &r->defensive))
        return false;
    if ((n = config_map_get(L, map, "max_depth")) && !config_get_int(L, n, 1, INT_MAX, &r->max_depth)) return false;
    if ((n = config_map_get(L, map, "rr_depth")) && !config_get_int(L, n, 1, INT_MAX, &r->rr_depth)) return false;
    if ((n = config_map_get(L, map, "spp")) && !config_get_int(L, n, 0, INT_MAX, &r->spp)) return false;
    if ((n = config_map_get(L, map, "time")) && !config_get_number_in(L, n, 0.0, false, INFINITY, false, &r->time_s))
        return false;
    if (!config_get_optional(L, map, "snapshots", YAML_MAPPING_NODE, &n) || (n && !load_snapshots(L, n, &r->snapshots)))
        return false;
    if ((n = config_map_get(L, map, "seed")) && !get_seed(L, n, &r->seed)) return false;
    if ((n = config_map_get(L, map, "threads")) && !get_threads(L, n, &r->threads)) return false;
    if (!config_get_optional(L, map, "aov", YAML_MAPPING_NODE, &n) || (n && !load_aov(L, n, r))) return false;
    if ((n = config_map_get(L, map, "resumable")) && !config_get_bool(L, n, &r->resumable)) return false;
    if ((n = config_map_get(L, map, "output")) && !config_get_string(L, n, r->output, sizeof r->output)) return false;
    c->output_override = n ? config_override_of(L, n) : -1;
    if (c->output_override < 0) c->output_loc = config_loc_of(L, n ? n : map);
    if (r->spp == 0 && r->time_s == 0.0)
        return config_fail(L, map, "spp and time are both 0 (expected a sample limit, a time limit or both)");
    return true;
}

static bool load_sections(struct loader *L, struct config *c)
{
    const yaml_node_t *root = L->root ? config_node(L, L->root) : NULL;
    if (!root) return error_at(L->err, L->file, 1, 1, "empty document (expected a mapping with camera, film, lights "
                                                      "and render)");
    return config_expect_type(L, root, YAML_MAPPING_NODE, "a mapping at the top level") &&
           config_check_keys(L, root, "the top level", top_keys, COUNT(top_keys)) && load_params(L, root) &&
           load_camera(L, root, &c->camera) && load_film(L, root, c) && load_materials(L, root, c) &&
           load_shapes(L, root, c) && load_lights(L, root, c) && load_portals(L, root, c) &&
           load_render(L, root, c);
}

/* A load from text, named `name`; st identifies the file, NULL for a string. */
static bool load_text(const char *text, size_t length, const char *name, const struct stat *st,
                      const struct config_override *overrides, int n_overrides, struct config *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    struct loader L;
    memset(&L, 0, sizeof L);
    L.file = name;
    L.err = err;
    L.overrides = overrides;
    L.n_overrides = n_overrides > 0 ? n_overrides : 0;
    L.from_string = st == NULL;
    if (strlen(L.file) >= sizeof out->path) return error_set(err, "%.64s...: path too long", L.file);
    snprintf(out->path, sizeof out->path, "%s", L.file);

    L.sources = calloc(1, sizeof *L.sources);
    char *copy = strdup(name);
    if (!L.sources || !copy) {
        free(L.sources);
        free(copy);
        return error_set(err, "%s: out of memory", L.file);
    }
    struct source src = { copy, -1, 0, 0, st != NULL, st ? st->st_dev : 0, st ? st->st_ino : 0 };
    L.sources[0] = src;
    L.n_sources = 1;
    bool ok = true;
    if (L.n_overrides) {
        /* Each override marks at most a key and a value node, plus a key
           and a mapping it creates (add_override_mapping). */
        L.marks = calloc((size_t)L.n_overrides * 4, sizeof *L.marks);
        ok = L.marks != NULL || error_set(err, "%s: out of memory", L.file);
    }
    ok = ok && config_load_document(&L, text, length);
    for (int k = 0; ok && k < L.n_overrides; ++k) ok = config_apply_override(&L, k);
    ok = ok && load_sections(&L, out) && config_emit_effective(&L, out);
    if (ok) {
        /* The file names move to the config: the locations point at them. */
        out->files = malloc((size_t)L.n_sources * sizeof *out->files);
        ok = out->files != NULL || error_set(err, "%s: out of memory", L.file);
        for (int i = 0; ok && i < L.n_sources; ++i) {
            out->files[i] = L.sources[i].path;
            L.sources[i].path = NULL;
        }
        if (ok) out->n_files = L.n_sources;
    }

    if (L.have_doc) yaml_document_delete(&L.doc);
    for (int i = 0; i < L.n_sources; ++i) free(L.sources[i].path);
    free(L.sources);
    free(L.node_source);
    free(L.marks);
    free(L.params);
    free(L.shape_names);
    if (!ok) config_free(out);
    return ok;
}

bool config_load_string(const char *text, size_t length, const char *name,
                        const struct config_override *overrides, int n_overrides, struct config *out,
                        struct error *err)
{
    return load_text(text ? text : "", text ? length : 0, name ? name : "<string>", NULL, overrides, n_overrides,
                     out, err);
}

bool config_load(const char *path, const struct config_override *overrides, int n_overrides, struct config *out,
                 struct error *err)
{
    memset(out, 0, sizeof *out);
    char *text;
    size_t length;
    struct stat st;
    const char *why;
    if (!config_read_text(path, &text, &length, &st, &why)) return error_set(err, "%s: %s", path, why);
    bool ok = load_text(text, length, path, &st, overrides, n_overrides, out, err);
    free(text);
    return ok;
}

void config_free(struct config *c)
{
    if (!c) return;
    for (int i = 0; i < c->n_files; ++i) free(c->files[i]);
    free(c->files);
    for (int i = 0; i < c->n_shapes; ++i) {
        free(c->shapes[i].vertices);
        free(c->shapes[i].triangles);
        free(c->shapes[i].quads);
    }
    free(c->materials);
    free(c->shapes);
    free(c->lights);
    free(c->portals);
    free(c->effective_yaml);
    memset(c, 0, sizeof *c);
}

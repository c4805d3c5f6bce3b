/* config.c: the public API of the config module. config_load and
   config_load_string run one load from start to end: read and parse the
   file with its includes (config_include.c), apply the --set overrides
   (config_override.c), read the top level and the params here, then the
   sections (config_scene.c, config_render.c), and emit the effective YAML
   (config_emit.c). And config_free. */
#include "config/config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "config/config_internal.h"

static const char *const top_keys[] = { "include", "params", "camera",  "film",  "materials",
                                        "shapes",  "lights", "portals", "render" };

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

static bool load_sections(struct loader *L, struct config *c)
{
    const yaml_node_t *root = L->root ? config_node(L, L->root) : NULL;
    if (!root)
        return error_at(L->err, L->file, 1, 1,
                        "empty document (expected a mapping with camera, film, lights "
                        "and render)");
    return config_expect_type(L, root, YAML_MAPPING_NODE, "a mapping at the top level") &&
           config_check_keys(L, root, "the top level", top_keys, COUNT(top_keys)) && load_params(L, root) &&
           config_load_scene(L, root, c) && config_load_render(L, root, c);
}

/* The loader's params (names pointing into its document) copied into the
   config, which outlives the document: --print-config reports them. */
static bool keep_params(struct loader *L, struct config *c)
{
    if (!L->n_params) return true;
    c->params = calloc((size_t)L->n_params, sizeof *c->params);
    if (!c->params) return error_set(L->err, "%s: out of memory", L->file);
    for (int i = 0; i < L->n_params; ++i) {
        if (!(c->params[i].name = strdup(L->params[i].name))) return error_set(L->err, "%s: out of memory", L->file);
        c->params[i].value = L->params[i].value;
        c->n_params = i + 1;
    }
    return true;
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
        /* The file names move to the config: the locations point at them.
           The mesh files follow the YAML files, in shape order. */
        out->files = malloc((size_t)(L.n_sources + L.n_mesh_files) * sizeof *out->files);
        ok = out->files != NULL || error_set(err, "%s: out of memory", L.file);
        for (int i = 0; ok && i < L.n_sources; ++i) {
            out->files[i] = L.sources[i].path;
            L.sources[i].path = NULL;
        }
        for (int i = 0; ok && i < L.n_mesh_files; ++i) {
            out->files[L.n_sources + i] = L.mesh_files[i];
            L.mesh_files[i] = NULL;
        }
        if (ok) out->n_files = L.n_sources + L.n_mesh_files;
        ok = ok && keep_params(&L, out);
    }

    if (L.have_doc) yaml_document_delete(&L.doc);
    for (int i = 0; i < L.n_sources; ++i) free(L.sources[i].path);
    free(L.sources);
    free(L.node_source);
    free(L.marks);
    free(L.params);
    free(L.shape_names);
    for (int i = 0; L.shape_files && i < out->n_shapes; ++i) free(L.shape_files[i].path);
    free(L.shape_files);
    for (int i = 0; L.light_files && i < out->n_lights; ++i) free(L.light_files[i].path);
    free(L.light_files);
    for (int i = 0; i < L.n_mesh_files; ++i) free(L.mesh_files[i]);
    free(L.mesh_files);
    if (!ok) config_free(out);
    return ok;
}

bool config_load_string(const char *text, size_t length, const char *name, const struct config_override *overrides,
                        int n_overrides, struct config *out, struct error *err)
{
    return load_text(text ? text : "", text ? length : 0, name ? name : "<string>", NULL, overrides, n_overrides, out,
                     err);
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
    for (int i = 0; i < c->n_lights; ++i) {
        free(c->lights[i].mesh.vertices);
        free(c->lights[i].mesh.triangles);
    }
    free(c->lights);
    free(c->portals);
    free(c->effective_yaml);
    for (int i = 0; i < c->n_params; ++i) free(c->params[i].name);
    free(c->params);
    memset(c, 0, sizeof *c);
}

/* config_internal.h: private to the config module (config.c and
   config_*.c); nothing else includes it, and it is the only header that
   includes <yaml.h>, so libyaml stays inside the module. It owns the
   loader, the state of one load (the YAML document, the files it came
   from, the overrides and params), and declares what the module's files
   share:
     config_node.c     typed getters over YAML nodes, and the error reports
                       that name file:line:column (or the --set override)
     config_include.c  reading files, parsing, the include merge
     config_override.c --set overrides
     config_emit.c     the effective YAML and its hashes
     config_scene.c    the sections camera, film, materials, shapes, lights
                       and portals
     config_transform.c  the transform: key of shapes, lights and portals
     config_render.c   the render section
     config.c          the public API, the top level and params */
#ifndef CONFIG_INTERNAL_H
#define CONFIG_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>

#include <yaml.h>

#include "config/config.h"
#include "base/error.h"
#include "config/expr.h"
#include "base/transform.h"
#include "base/vec.h"

#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

/* --set values become nodes without a place in the file; errors in them name
   the override instead. */
struct override_mark {
    int node;
    int override;
};

/* A file read for the config: the loaded file (index 0) or an include. */
struct source {
    char *path;       /* owned; as opened: the includer's folder joined with the include */
    int parent;       /* the including source; -1 for the loaded file */
    int line, column; /* of the include entry in the parent, one-based */
    bool have_id;     /* dev and ino identify the file (not for strings) */
    dev_t dev;
    ino_t ino;
};

/* A shape read from a mesh file, as the effective YAML writes it back: the
   file (absolute, since config.yaml lives in another folder), the
   transform, and the digest of the bytes read, so that the config's hashes
   change with the file. */
struct shape_file {
    char *path;      /* owned; absolute; NULL for a shape without a file */
    int shape_index; /* of a serialized file; -1 for OBJ and PLY */
    bool has_transform;
    struct transform transform;
    uint64_t fnv1a64; /* of the file's bytes */
    size_t bytes;
};

/* The state of one load, from reading the file to emitting the effective YAML. */
struct loader {
    const char *file; /* the loaded file's name */
    struct error *err;
    yaml_document_t doc;
    bool have_doc;
    int root;         /* node id of the root in doc; 0 when the document is empty */
    bool from_string; /* no folder to resolve includes against */
    struct source *sources;
    int n_sources;
    /* Source of each node of doc (by id - 1), when doc was merged from an
       include tree; NULL when doc is the loaded file's own document. */
    int *node_source;
    int n_node_source, cap_node_source;
    long n_copied, n_merged;
    const struct config_override *overrides;
    int n_overrides;
    struct override_mark *marks;
    int n_marks;
    struct expr_var *params; /* names point into the document */
    int n_params;
    char (*shape_names)[CONFIG_NAME_MAX]; /* "" when unnamed; only for effective_yaml */
    struct shape_file *shape_files;       /* one per shape; only for effective_yaml */
    struct shape_file *light_files;       /* one per light (mesh lights); only for effective_yaml */
    char **mesh_files;                    /* owned: each mesh file once, as opened, in shape order */
    int n_mesh_files;
};

/* config_node.c: message lists, node access, reports, typed getters. */

/* A bounded string for lists in messages; truncates silently. */
struct config_line {
    char s[512];
    size_t n;
};

/* Appends str, after sep unless l is empty. */
void config_line_append(struct config_line *l, const char *sep, const char *str);
/* Appends str after ", ". */
void config_line_add(struct config_line *l, const char *str);

/* Nodes of L->doc by id, and the parts of scalars, sequences and mappings. */
static inline yaml_node_t *config_node(struct loader *L, int id)
{
    return yaml_document_get_node(&L->doc, id);
}

static inline const char *config_text(const yaml_node_t *n)
{
    return (const char *)n->data.scalar.value;
}

static inline int config_seq_count(const yaml_node_t *n)
{
    return (int)(n->data.sequence.items.top - n->data.sequence.items.start);
}

static inline yaml_node_t *config_seq_item(struct loader *L, const yaml_node_t *n, int i)
{
    return config_node(L, n->data.sequence.items.start[i]);
}

static inline int config_map_count(const yaml_node_t *n)
{
    return (int)(n->data.mapping.pairs.top - n->data.mapping.pairs.start);
}

/* A plain null scalar: empty, ~, null, Null or NULL. */
bool config_is_null(const yaml_node_t *n);
/* What the node is, for messages: "a mapping", "null", the quoted scalar
   (shortened, in buf)... */
const char *config_describe_node(const yaml_node_t *n, char *buf, size_t size);
/* The index of the --set override that made node n, or -1. */
int config_override_of(const struct loader *L, const yaml_node_t *n);
/* The source (index into L->sources) that node n came from. */
int config_source_of(const struct loader *L, const yaml_node_t *n);

/* Reports at line:column of source s: "file:line:column: ...", followed for
   an included file by the include entries that led to it. Returns false. */
bool config_report(struct loader *L, int s, int line, int column, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
/* Reports at the node (or the override that made it). Returns false. */
bool config_fail(struct loader *L, const yaml_node_t *n, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* Where the node is, for items that keep their location. */
struct source_loc config_loc_of(const struct loader *L, const yaml_node_t *n);

/* The typed getters: each checks the node and reports at it on failure. */
bool config_expect_type(struct loader *L, const yaml_node_t *n, yaml_node_type_t type, const char *expected);
/* Every key a unique scalar listed in allowed[] (any scalar when allowed is NULL). */
bool config_check_keys(struct loader *L, const yaml_node_t *map, const char *where, const char *const *allowed,
                       int n_allowed);
/* The value of `key` in the mapping, or NULL. */
yaml_node_t *config_map_get(struct loader *L, const yaml_node_t *map, const char *key);
/* A required key; NULL (reported at the mapping) when missing. */
yaml_node_t *config_need(struct loader *L, const yaml_node_t *map, const char *key, const char *where);
/* An optional mapping or sequence: *out is NULL when absent or null. */
bool config_get_optional(struct loader *L, const yaml_node_t *map, const char *key, yaml_node_type_t type,
                         yaml_node_t **out);
/* A YAML 1.2 core-schema float or decimal integer (no expressions, no error report). */
bool config_parse_literal(const char *s, double *out);
/* A number scalar as written when it is a literal, else v, for messages. */
const char *config_value_text(const yaml_node_t *n, double v, char *buf, size_t size);
/* A finite number, literal or "=expression" over the params; `expected` says
   what the caller wants, for the message. */
bool config_get_number(struct loader *L, const yaml_node_t *n, const char *expected, double *out);
/* A finite number in the range from lo to hi, each end open or closed. */
bool config_get_number_in(struct loader *L, const yaml_node_t *n, double lo, bool lo_open, double hi, bool hi_open,
                          double *out);
bool config_get_int(struct loader *L, const yaml_node_t *n, int lo, int hi, int *out);
bool config_get_bool(struct loader *L, const yaml_node_t *n, bool *out);
/* A non-empty string that fits in `size` bytes with its terminator. */
bool config_get_string(struct loader *L, const yaml_node_t *n, char *out, size_t size);
/* One of names[0..count), as its index; `what` names the kind for the message. */
bool config_get_enum(struct loader *L, const yaml_node_t *n, const char *what, const char *const *names, int count,
                     int *out);
/* [x, y, z], any finite numbers. */
bool config_get_vec3(struct loader *L, const yaml_node_t *n, struct vec3 *out);
/* [r, g, b], each in [lo, hi]. */
bool config_get_rgb(struct loader *L, const yaml_node_t *n, double lo, double hi, struct rgb *out);

/* config_include.c: the files. */
/* The whole of a file that is not a folder; false with *why (a strerror
   text or "out of memory") otherwise. */
bool config_read_text(const char *path, char **text, size_t *length, struct stat *st, const char **why);
/* Parses text, the loaded file (source 0), into L->doc and L->root: its
   own document, or the merged document of its include tree. False with
   L->err set. */
bool config_load_document(struct loader *L, const char *text, size_t length);

/* FNV-1a 64 of n bytes (the config hashes and the mesh files' digests). */
uint64_t config_fnv1a64(const void *data, size_t n);

/* config_transform.c: transform: [ops...] of the mapping map, composed in
   order (the first applied first). *present is false, and *out the
   identity, when the key is absent, null or an empty list. False with
   L->err at the operation (unknown op, wrong arity, zero rotation axis,
   singular or non-affine matrix) or the list (a singular composition). */
bool config_get_transform(struct loader *L, const yaml_node_t *map, struct transform *out, bool *present);

/* config_override.c: --set. */
/* Applies L->overrides[k] to L->doc: replaces the scalar its path names,
   or adds a missing last key of a mapping (and render.snapshots or
   render.aov when missing). False with L->err naming the override. */
bool config_apply_override(struct loader *L, int k);

/* config_emit.c: the effective YAML. */
/* Fills c->effective_yaml, c->hash and c->image_hash from the loaded c
   (and L->shape_names). False with L->err set when out of memory. */
bool config_emit_effective(struct loader *L, struct config *c);

/* The section loaders: each reads its keys of the top-level mapping root
   into c, reporting the first error. */
/* config_scene.c: camera, film, materials, shapes, lights, portals. */
bool config_load_scene(struct loader *L, const yaml_node_t *root, struct config *c);
/* config_render.c: render, with its defaults. */
bool config_load_render(struct loader *L, const yaml_node_t *root, struct config *c);

#endif

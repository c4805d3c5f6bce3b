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

#include <yaml.h>

#include "expr.h"

const char *const integrator_names[2] = { "direct", "path" };
const char *const strategy_names[STRATEGY_COUNT] = { "light_area", "light",      "portal",
                                                     "projection", "antishadow", "antishadow_exact" };
const char *const mis_names[3] = { "none", "balance", "power" };
const char *const portal_weight_names[3] = { "area", "distance", "irradiance" };
const char *const material_names[2] = { "diffuse", "ggx" };

enum shape_kind { SHAPE_QUAD, SHAPE_BOX, SHAPE_MESH };
static const char *const shape_kind_names[3] = { "quad", "box", "mesh" };

#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

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
const char *const config_snapshot_keys[CONFIG_SNAPSHOT_KEY_COUNT] = { "every",     "doubling",     "times",
                                                                    "every_spp", "doubling_spp", "spp" };
/* What each key counts in: render time (get_number_in) or passes (get_int, get_spps). */
const char *const config_snapshot_units[CONFIG_SNAPSHOT_KEY_COUNT] = { "s", "s", "s", "spp", "spp", "spp" };
static const char *const aov_keys[] = { "region" };
/* Optional mappings that --set creates when they are missing, so that
   `--set render.aov.region=true` works on a config without `aov:`. */
static const char *const override_mapping_paths[] = { "render.snapshots", "render.aov" };

/* Geometric tolerances, relative to the size (diameter) of each polygon so
   that a scene in millimetres validates like one in metres. */
#define PLANAR_REL_TOL 1e-6   /* max distance to the plane / diameter */
#define AREA_REL_TOL 1e-10    /* area / diameter^2 at or below this is degenerate */
#define PARALLEL_TOL 1e-9     /* |sin| of the angle between up and the view direction */

#define FILM_SIZE_MAX 16384
#define THREADS_MAX 256

/* Bounds on building the merged document of an include tree: nesting of
   copied nodes (the copy recurses), and nodes made by merging mappings
   relative to nodes copied (aliases to mappings could otherwise multiply
   the merged nodes exponentially). Real configs stay far below both. */
#define COPY_DEPTH_MAX 1000
#define MERGE_NODES_PER_COPY 16
#define MERGE_NODES_SLACK 4096

/* --set values become nodes without a place in the file; errors in them name
   the override instead. */
struct override_mark {
    int node;
    int override;
};

/* A file read for the config: the loaded file (index 0) or an include. */
struct source {
    char *path;             /* owned; as opened: the includer's folder joined with the include */
    int parent;             /* the including source; -1 for the loaded file */
    int line, column;       /* of the include entry in the parent, one-based */
    bool have_id;           /* dev and ino identify the file (not for strings) */
    dev_t dev;
    ino_t ino;
};

struct loader {
    const char *file;       /* the loaded file's name */
    struct error *err;
    yaml_document_t doc;
    bool have_doc;
    int root;               /* node id of the root in doc; 0 when the document is empty */
    bool from_string;       /* no folder to resolve includes against */
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
    struct expr_var *params;  /* names point into the document */
    int n_params;
    char (*shape_names)[CONFIG_NAME_MAX]; /* "" when unnamed; only for effective_yaml */
};

/* A bounded string for lists in messages; truncates silently. */
struct line {
    char s[512];
    size_t n;
};

/* Appends str, after sep unless l is empty. */
static void line_append(struct line *l, const char *sep, const char *str)
{
    if (l->n >= sizeof l->s - 1) return;
    int k = snprintf(l->s + l->n, sizeof l->s - l->n, "%s%s", l->n ? sep : "", str);
    if (k > 0) l->n += (size_t)k;
    if (l->n > sizeof l->s - 1) l->n = sizeof l->s - 1;
}

static void line_add(struct line *l, const char *str)
{
    line_append(l, ", ", str);
}

static const char *join_names(struct line *l, const char *const *names, int n)
{
    l->n = 0;
    l->s[0] = '\0';
    for (int i = 0; i < n; ++i) line_add(l, names[i]);
    return l->s;
}


static yaml_node_t *node_get(struct loader *L, int id)
{
    return yaml_document_get_node(&L->doc, id);
}

static const char *text_of(const yaml_node_t *n)
{
    return (const char *)n->data.scalar.value;
}

static int seq_count(const yaml_node_t *n)
{
    return (int)(n->data.sequence.items.top - n->data.sequence.items.start);
}

static yaml_node_t *seq_item(struct loader *L, const yaml_node_t *n, int i)
{
    return node_get(L, n->data.sequence.items.start[i]);
}

static int map_count(const yaml_node_t *n)
{
    return (int)(n->data.mapping.pairs.top - n->data.mapping.pairs.start);
}

static bool is_null(const yaml_node_t *n)
{
    if (n->type != YAML_SCALAR_NODE || n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE) return false;
    const char *s = text_of(n);
    return !strcmp(s, "") || !strcmp(s, "~") || !strcmp(s, "null") || !strcmp(s, "Null") || !strcmp(s, "NULL");
}

static const char *describe(const yaml_node_t *n, char *buf, size_t size)
{
    switch (n->type) {
    case YAML_MAPPING_NODE: return "a mapping";
    case YAML_SEQUENCE_NODE: return "a sequence";
    case YAML_SCALAR_NODE:
        if (is_null(n)) return "null";
        snprintf(buf, size, "\"%.40s%s\"", text_of(n), strlen(text_of(n)) > 40 ? "..." : "");
        return buf;
    case YAML_NO_NODE: break;
    }
    return "nothing";
}

static int override_of(const struct loader *L, const yaml_node_t *n)
{
    int id = (int)(n - L->doc.nodes.start) + 1;
    for (int i = L->n_marks - 1; i >= 0; --i)
        if (L->marks[i].node == id) return L->marks[i].override;
    return -1;
}

static int source_of(const struct loader *L, const yaml_node_t *n)
{
    if (!L->node_source) return 0;
    int id = (int)(n - L->doc.nodes.start) + 1;
    return id >= 1 && id <= L->n_node_source ? L->node_source[id - 1] : 0;
}

/* Reports at line:column of source s: "file:line:column: ...", followed for
   an included file by the include entries that led to it. */
static bool report(struct loader *L, int s, int line, int column, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

static bool report(struct loader *L, int s, int line, int column, const char *fmt, ...)
{
    char msg[ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* The include entries from the file up to the loaded one; a long chain
       keeps its two nearest links and the loaded file's. */
    int links[CONFIG_INCLUDE_DEPTH_MAX + 1], n = 0;
    for (int p = s; p > 0 && n <= CONFIG_INCLUDE_DEPTH_MAX; p = L->sources[p].parent) links[n++] = p;
    char chain[ERROR_MESSAGE_MAX] = "";
    size_t used = 0;
    for (int i = 0; i < n && used < sizeof chain; ++i) {
        if (n > 3 && i == 2) {
            used += (size_t)snprintf(chain + used, sizeof chain - used, ", ...");
            i = n - 1;
        }
        if (used >= sizeof chain) break;
        const struct source *src = &L->sources[links[i]];
        int k = snprintf(chain + used, sizeof chain - used, "%s %s:%d:%d", i ? ", from" : " (included from",
                         L->sources[src->parent].path, src->line, src->column);
        used += k > 0 ? (size_t)k : 0;
    }
    if (n && used < sizeof chain - 1) snprintf(chain + used, sizeof chain - used, ")");
    return error_at(L->err, L->sources[s].path, line, column, "%s%s", msg, chain);
}

/* Reports at the node: "file:line:column: ..." (libyaml marks are zero-based),
   or "--set path=value: ..." for a node that came from an override. */
static bool fail(struct loader *L, const yaml_node_t *n, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

static bool fail(struct loader *L, const yaml_node_t *n, const char *fmt, ...)
{
    char msg[ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    int k = override_of(L, n);
    if (k >= 0) return error_set(L->err, "--set %s=%s: %s", L->overrides[k].path, L->overrides[k].value, msg);
    return report(L, source_of(L, n), (int)n->start_mark.line + 1, (int)n->start_mark.column + 1, "%s", msg);
}

/* Where the node is, for items that keep their location. */
static struct source_loc loc_of(const struct loader *L, const yaml_node_t *n)
{
    struct source_loc loc = { (int)n->start_mark.line + 1, (int)n->start_mark.column + 1,
                              L->sources[source_of(L, n)].path };
    return loc;
}

static bool expect_type(struct loader *L, const yaml_node_t *n, yaml_node_type_t type, const char *expected)
{
    char buf[64];
    if (n->type == type && !is_null(n)) return true;
    return fail(L, n, "expected %s, got %s", expected, describe(n, buf, sizeof buf));
}

/* Every key a scalar, listed in allowed[] (unless allowed is NULL), and
   unique: pbrt-v4's rule that any key nothing reads is an error. */
static bool check_keys(struct loader *L, const yaml_node_t *map, const char *where, const char *const *allowed,
                       int n_allowed)
{
    yaml_node_pair_t *pairs = map->data.mapping.pairs.start;
    int n = map_count(map);
    for (int i = 0; i < n; ++i) {
        const yaml_node_t *key = node_get(L, pairs[i].key);
        char buf[64];
        if (key->type != YAML_SCALAR_NODE)
            return fail(L, key, "expected a string key in %s, got %s", where, describe(key, buf, sizeof buf));
        const char *name = text_of(key);
        if (allowed) {
            int j = 0;
            while (j < n_allowed && strcmp(name, allowed[j]) != 0) ++j;
            struct line list;
            if (j == n_allowed)
                return fail(L, key, "unknown key \"%.64s\" in %s (expected %s)", name, where,
                            join_names(&list, allowed, n_allowed));
        }
        for (int j = 0; j < i; ++j) {
            const yaml_node_t *other = node_get(L, pairs[j].key);
            if (other->type == YAML_SCALAR_NODE && strcmp(text_of(other), name) == 0)
                return fail(L, key, "duplicate key \"%.64s\" in %s (first at line %d, column %d)", name, where,
                            (int)other->start_mark.line + 1, (int)other->start_mark.column + 1);
        }
    }
    return true;
}

/* The value of `key` in the mapping, or NULL. */
static yaml_node_t *map_get(struct loader *L, const yaml_node_t *map, const char *key)
{
    yaml_node_pair_t *pairs = map->data.mapping.pairs.start;
    for (int i = 0; i < map_count(map); ++i) {
        const yaml_node_t *k = node_get(L, pairs[i].key);
        if (k->type == YAML_SCALAR_NODE && strcmp(text_of(k), key) == 0) return node_get(L, pairs[i].value);
    }
    return NULL;
}

/* A required key; reported at the enclosing mapping when missing. */
static yaml_node_t *need(struct loader *L, const yaml_node_t *map, const char *key, const char *where)
{
    yaml_node_t *v = map_get(L, map, key);
    if (!v) fail(L, map, "missing key \"%s\" in %s", key, where);
    return v;
}

/* An optional mapping or sequence: NULL when absent or null. */
static bool get_optional(struct loader *L, const yaml_node_t *map, const char *key, yaml_node_type_t type,
                         yaml_node_t **out)
{
    *out = map_get(L, map, key);
    if (*out && is_null(*out)) *out = NULL;
    if (!*out) return true;
    return expect_type(L, *out, type, type == YAML_MAPPING_NODE ? "a mapping" : "a sequence");
}


/* YAML 1.2 core-schema floats and decimal integers. The non-finite spellings
   are recognised too, so that they are rejected by name. */
static bool parse_literal(const char *s, double *out)
{
    const char *p = s;
    if (*p == '+' || *p == '-') ++p;
    if (!strcmp(p, ".inf") || !strcmp(p, ".Inf") || !strcmp(p, ".INF")) {
        *out = *s == '-' ? -INFINITY : INFINITY;
        return true;
    }
    if (!strcmp(s, ".nan") || !strcmp(s, ".NaN") || !strcmp(s, ".NAN")) {
        *out = NAN;
        return true;
    }
    bool digits = false;
    for (; isdigit((unsigned char)*p); ++p) digits = true;
    if (*p == '.')
        for (++p; isdigit((unsigned char)*p); ++p) digits = true;
    if (!digits) return false;
    if (*p == 'e' || *p == 'E') {
        ++p;
        if (*p == '+' || *p == '-') ++p;
        if (!isdigit((unsigned char)*p)) return false;
        while (isdigit((unsigned char)*p)) ++p;
    }
    if (*p) return false;
    *out = strtod(s, NULL);
    return true;
}

/* The value as written when it is a literal, else as evaluated. */
static const char *value_text(const yaml_node_t *n, double v, char *buf, size_t size)
{
    if (n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE && text_of(n)[0] != '=' && strlen(text_of(n)) < 40)
        return text_of(n);
    snprintf(buf, size, "%.10g", v);
    return buf;
}

/* A finite number: a plain YAML number or "=expression" over the params.
   `expected` describes what the caller wants, for messages. */
static bool get_number_as(struct loader *L, const yaml_node_t *n, const char *expected, double *out)
{
    char buf[64];
    if (n->type != YAML_SCALAR_NODE || is_null(n))
        return fail(L, n, "expected %s, got %s", expected, describe(n, buf, sizeof buf));
    const char *s = text_of(n);
    if (s[0] == '=') {
        struct error e;
        if (!expr_eval(s + 1, L->params, L->n_params, out, &e))
            return fail(L, n, "expression \"%.100s\": %s", s, e.message);
        return true;
    }
    if (n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE || !parse_literal(s, out))
        return fail(L, n, "expected %s, got %s", expected, describe(n, buf, sizeof buf));
    if (!isfinite(*out)) return fail(L, n, "expected a finite number, got %.40s", s);
    return true;
}

static void describe_range(char *buf, size_t size, double lo, bool lo_open, double hi, bool hi_open)
{
    if (isinf(lo) && isinf(hi))
        snprintf(buf, size, "a number");
    else if (isinf(hi))
        snprintf(buf, size, "a number %s %g", lo_open ? ">" : ">=", lo);
    else
        snprintf(buf, size, "a number in %c%g, %g%c", lo_open ? '(' : '[', lo, hi, hi_open ? ')' : ']');
}

static bool get_number_in(struct loader *L, const yaml_node_t *n, double lo, bool lo_open, double hi, bool hi_open,
                          double *out)
{
    char desc[96], buf[64];
    describe_range(desc, sizeof desc, lo, lo_open, hi, hi_open);
    if (!get_number_as(L, n, desc, out)) return false;
    double v = *out;
    if ((lo_open ? v <= lo : v < lo) || (hi_open ? v >= hi : v > hi))
        return fail(L, n, "expected %s, got %s", desc, value_text(n, v, buf, sizeof buf));
    return true;
}

static bool get_int(struct loader *L, const yaml_node_t *n, int lo, int hi, int *out)
{
    char desc[96], buf[64];
    if (lo == 0 && hi == INT_MAX)
        snprintf(desc, sizeof desc, "a non-negative integer");
    else if (lo == 1 && hi == INT_MAX)
        snprintf(desc, sizeof desc, "a positive integer");
    else
        snprintf(desc, sizeof desc, "an integer in [%d, %d]", lo, hi);
    double v;
    if (!get_number_as(L, n, desc, &v)) return false;
    if (v != floor(v) || v < lo || v > hi)
        return fail(L, n, "expected %s, got %s", desc, value_text(n, v, buf, sizeof buf));
    *out = (int)v;
    return true;
}

static bool get_bool(struct loader *L, const yaml_node_t *n, bool *out)
{
    char buf[64];
    if (n->type == YAML_SCALAR_NODE && n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE) {
        const char *s = text_of(n);
        bool yes = !strcmp(s, "true") || !strcmp(s, "True") || !strcmp(s, "TRUE");
        bool no = !strcmp(s, "false") || !strcmp(s, "False") || !strcmp(s, "FALSE");
        if (yes || no) {
            *out = yes;
            return true;
        }
    }
    return fail(L, n, "expected true or false, got %s", describe(n, buf, sizeof buf));
}

/* A non-empty string that fits in `size` bytes with its terminator. */
static bool get_string(struct loader *L, const yaml_node_t *n, char *out, size_t size)
{
    if (!expect_type(L, n, YAML_SCALAR_NODE, "a string")) return false;
    const char *s = text_of(n);
    size_t len = strlen(s);
    if (len != n->data.scalar.length) return fail(L, n, "string contains a NUL character");
    if (len >= size) return fail(L, n, "string too long (%zu bytes, expected at most %zu)", len, size - 1);
    memcpy(out, s, len + 1);
    return true;
}

static bool get_enum(struct loader *L, const yaml_node_t *n, const char *what, const char *const *names, int count,
                     int *out)
{
    if (!expect_type(L, n, YAML_SCALAR_NODE, "a string")) return false;
    for (int i = 0; i < count; ++i)
        if (strcmp(text_of(n), names[i]) == 0) {
            *out = i;
            return true;
        }
    struct line list;
    return fail(L, n, "unknown %s \"%.64s\" (expected one of: %s)", what, text_of(n), join_names(&list, names, count));
}

/* A sequence of three numbers in a range: points, colours. */
static bool get_triple(struct loader *L, const yaml_node_t *n, const char *form, double lo, bool lo_open, double hi,
                       bool hi_open, double out[3])
{
    char buf[64];
    if (n->type != YAML_SEQUENCE_NODE)
        return fail(L, n, "expected %s (3 numbers), got %s", form, describe(n, buf, sizeof buf));
    if (seq_count(n) != 3) return fail(L, n, "expected %s (3 numbers), got %d items", form, seq_count(n));
    for (int i = 0; i < 3; ++i)
        if (!get_number_in(L, seq_item(L, n, i), lo, lo_open, hi, hi_open, &out[i])) return false;
    return true;
}

static bool get_vec3(struct loader *L, const yaml_node_t *n, struct vec3 *out)
{
    double v[3];
    if (!get_triple(L, n, "[x, y, z]", -INFINITY, false, INFINITY, false, v)) return false;
    *out = vec3_make(v[0], v[1], v[2]);
    return true;
}

static bool get_rgb(struct loader *L, const yaml_node_t *n, double lo, double hi, struct rgb *out)
{
    double v[3];
    if (!get_triple(L, n, "[r, g, b]", lo, false, hi, false, v)) return false;
    *out = rgb_make(v[0], v[1], v[2]);
    return true;
}


static double points_diameter(const struct vec3 *v, int n)
{
    double d2 = 0.0;
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j) {
            double l2 = vec3_length2(vec3_sub(v[i], v[j]));
            if (l2 > d2) d2 = l2;
        }
    return sqrt(d2);
}

/* Non-zero area, planar and convex, all relative to the polygon's size. */
static bool check_polygon(struct loader *L, const yaml_node_t *n, const char *what, const struct polygon *poly)
{
    double diam = points_diameter(poly->v, poly->n);
    if (!(polygon_area(poly) > AREA_REL_TOL * diam * diam))
        return fail(L, n, "%s is degenerate (expected a polygon with non-zero area)", what);
    if (!polygon_is_planar(poly, PLANAR_REL_TOL))
        return fail(L, n, "%s is not planar (expected every vertex within %g times its size of its plane)", what,
                    PLANAR_REL_TOL);
    if (!polygon_is_convex(poly))
        return fail(L, n, "%s is not convex (expected a convex polygon with its vertices in order)", what);
    return true;
}

/* A polygon of min..max points; checked by check_polygon. */
static bool get_polygon(struct loader *L, const yaml_node_t *n, const char *what, int min, int max,
                        struct polygon *out)
{
    char buf[64];
    memset(out, 0, sizeof *out);
    if (n->type != YAML_SEQUENCE_NODE)
        return fail(L, n, "expected a list of points [x, y, z], got %s", describe(n, buf, sizeof buf));
    int count = seq_count(n);
    if (count < min || count > max) {
        if (min == max) return fail(L, n, "%s has %d vertices (expected %d)", what, count, min);
        return fail(L, n, "%s has %d vertices (expected %d to %d)", what, count, min, max);
    }
    for (int i = 0; i < count; ++i)
        if (!get_vec3(L, seq_item(L, n, i), &out->v[i])) return false;
    out->n = count;
    return check_polygon(L, n, what, out);
}


static bool load_params(struct loader *L, const yaml_node_t *root)
{
    yaml_node_t *map;
    if (!get_optional(L, root, "params", YAML_MAPPING_NODE, &map)) return false;
    if (!map) return true;
    if (!check_keys(L, map, "params", NULL, 0)) return false;
    int n = map_count(map);
    L->params = calloc((size_t)n, sizeof *L->params);
    if (!L->params) return error_set(L->err, "%s: out of memory", L->file);
    for (int i = 0; i < n; ++i) {
        const yaml_node_t *key = node_get(L, map->data.mapping.pairs.start[i].key);
        const char *name = text_of(key);
        if (!expr_is_identifier(name))
            return fail(L, key, "invalid param name \"%.64s\" (expected letters, digits and _, not starting "
                                "with a digit)", name);
        if (expr_is_reserved(name))
            return fail(L, key, "param name \"%s\" is reserved (expected a name other than pi, min, max, abs, "
                                "sqrt, sin, cos, tan)", name);
        /* Params see only the ones before them, so definitions cannot loop. */
        double v;
        if (!get_number_as(L, node_get(L, map->data.mapping.pairs.start[i].value), "a number", &v)) return false;
        L->params[L->n_params].name = name;
        L->params[L->n_params].value = v;
        ++L->n_params;
    }
    return true;
}

static bool load_camera(struct loader *L, const yaml_node_t *root, struct camera_desc *cam)
{
    yaml_node_t *map = need(L, root, "camera", "the top level"), *n, *look, *up;
    if (!map || !expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !check_keys(L, map, "camera", camera_keys, COUNT(camera_keys)))
        return false;
    if (!(n = need(L, map, "position", "camera")) || !get_vec3(L, n, &cam->position)) return false;
    if (!(look = need(L, map, "look_at", "camera")) || !get_vec3(L, look, &cam->look_at)) return false;
    if (!(up = need(L, map, "up", "camera")) || !get_vec3(L, up, &cam->up)) return false;
    if (!(n = need(L, map, "fov_y", "camera")) || !get_number_in(L, n, 0.0, true, 180.0, true, &cam->fov_y_deg))
        return false;
    struct vec3 dir = vec3_sub(cam->look_at, cam->position);
    if (vec3_length(dir) == 0.0) return fail(L, look, "look_at equals position (expected a different point)");
    if (vec3_length(cam->up) == 0.0) return fail(L, up, "up is zero (expected a direction)");
    if (vec3_length(vec3_cross(vec3_normalize(dir), vec3_normalize(cam->up))) <= PARALLEL_TOL)
        return fail(L, up, "up is parallel to the view direction (expected a direction not along look_at - "
                           "position)");
    return true;
}

static bool load_film(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map = need(L, root, "film", "the top level"), *n;
    if (!map || !expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !check_keys(L, map, "film", film_keys, COUNT(film_keys)))
        return false;
    if (!(n = need(L, map, "width", "film")) || !get_int(L, n, 1, FILM_SIZE_MAX, &c->width)) return false;
    if (!(n = need(L, map, "height", "film")) || !get_int(L, n, 1, FILM_SIZE_MAX, &c->height)) return false;
    return true;
}

static bool load_material(struct loader *L, const yaml_node_t *key, const yaml_node_t *map,
                          struct material_desc *m)
{
    if (!get_string(L, key, m->name, sizeof m->name)) return false;
    char where[CONFIG_NAME_MAX + 16];
    snprintf(where, sizeof where, "material \"%s\"", m->name);
    m->loc = loc_of(L, key);
    yaml_node_t *n;
    int kind = 0;
    if (!expect_type(L, map, YAML_MAPPING_NODE, "a mapping")) return false;
    if (!(n = need(L, map, "type", where)) || !get_enum(L, n, "material type", material_names, 2, &kind))
        return false;
    m->kind = (enum material_kind)kind;
    bool ggx = m->kind == MATERIAL_GGX;
    if (!check_keys(L, map, where, ggx ? ggx_keys : diffuse_keys, ggx ? COUNT(ggx_keys) : COUNT(diffuse_keys)))
        return false;
    if (!(n = need(L, map, "albedo", where)) || !get_rgb(L, n, 0.0, 1.0, &m->albedo)) return false;
    if (ggx && (!(n = need(L, map, "roughness", where)) || !get_number_in(L, n, 0.001, false, 1.0, false, &m->roughness)))
        return false;
    return true;
}

static bool load_materials(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map;
    if (!get_optional(L, root, "materials", YAML_MAPPING_NODE, &map)) return false;
    if (!map) return true;
    if (!check_keys(L, map, "materials", NULL, 0)) return false;
    int n = map_count(map);
    if (n == 0) return true;
    c->materials = calloc((size_t)n, sizeof *c->materials);
    if (!c->materials) return error_set(L->err, "%s: out of memory", L->file);
    c->n_materials = n;
    for (int i = 0; i < n; ++i) {
        yaml_node_pair_t *p = &map->data.mapping.pairs.start[i];
        if (!load_material(L, node_get(L, p->key), node_get(L, p->value), &c->materials[i])) return false;
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
    for (int f = 0; f < seq_count(seq); ++f) {
        const yaml_node_t *face = seq_item(L, seq, f);
        if (face->type != YAML_SEQUENCE_NODE)
            return fail(L, face, "expected a %s (%d vertex indices), got %s", kind, k, describe(face, buf, sizeof buf));
        if (seq_count(face) != k)
            return fail(L, face, "expected a %s (%d vertex indices), got %d items", kind, k, seq_count(face));
        for (int i = 0; i < k; ++i) {
            const yaml_node_t *item = seq_item(L, face, i);
            int index;
            if (!get_int(L, item, 0, INT_MAX, &index)) return false;
            if (index >= s->n_vertices)
                return fail(L, item, "vertex index %d out of range (expected 0 to %d: the mesh has %d vertices)",
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
    if (!(verts = need(L, map, "vertices", where)) || !expect_type(L, verts, YAML_SEQUENCE_NODE, "a sequence") ||
        !get_optional(L, map, "triangles", YAML_SEQUENCE_NODE, &tris) ||
        !get_optional(L, map, "quads", YAML_SEQUENCE_NODE, &quads))
        return false;
    int nv = seq_count(verts), nt = tris ? seq_count(tris) : 0, nq = quads ? seq_count(quads) : 0;
    if (nv < 3) return fail(L, verts, "%s has %d vertices (expected at least 3)", where, nv);
    if (nt + nq == 0) return fail(L, map, "%s has no faces (expected triangles, quads or both)", where);
    if (!shape_alloc(L, s, nv, nt, nq)) return false;
    for (int i = 0; i < nv; ++i)
        if (!get_vec3(L, seq_item(L, verts, i), &s->vertices[i])) return false;
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
    if (!(nmin = need(L, map, "min", where)) || !get_vec3(L, nmin, &lo) || !(nmax = need(L, map, "max", where)) ||
        !get_vec3(L, nmax, &hi))
        return false;
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z))
        return fail(L, nmax, "expected max > min on every axis, got min [%g, %g, %g] and max [%g, %g, %g]", lo.x,
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
    if (!(n = need(L, map, "vertices", where)) || !get_polygon(L, n, where, 4, 4, &poly)) return false;
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
    s->loc = loc_of(L, map);
    if (!expect_type(L, map, YAML_MAPPING_NODE, "a mapping")) return false;
    if ((n = map_get(L, map, "name")) && !get_string(L, n, name, CONFIG_NAME_MAX)) return false;
    if (name[0])
        snprintf(where, sizeof where, "shape %d (%s)", index, name);
    else
        snprintf(where, sizeof where, "shape %d", index);
    if (!(n = need(L, map, "type", where)) || !get_enum(L, n, "shape type", shape_kind_names, 3, &kind))
        return false;
    const char *const *keys = kind == SHAPE_QUAD ? quad_keys : kind == SHAPE_BOX ? box_keys : mesh_keys;
    int n_keys = kind == SHAPE_QUAD ? COUNT(quad_keys) : kind == SHAPE_BOX ? COUNT(box_keys) : COUNT(mesh_keys);
    if (!check_keys(L, map, where, keys, n_keys)) return false;

    char material[CONFIG_NAME_MAX];
    if (!(n = need(L, map, "material", where)) || !get_string(L, n, material, sizeof material)) return false;
    s->material = find_material(c, material);
    if (s->material < 0) {
        struct line list = { "", 0 };
        for (int i = 0; i < c->n_materials; ++i) line_add(&list, c->materials[i].name);
        return fail(L, n, "unknown material \"%s\" (expected one of: %s)", material,
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
    if (!get_optional(L, root, "shapes", YAML_SEQUENCE_NODE, &seq)) return false;
    int n = seq ? seq_count(seq) : 0;
    if (n == 0) return true;
    c->shapes = calloc((size_t)n, sizeof *c->shapes);
    L->shape_names = calloc((size_t)n, sizeof *L->shape_names);
    if (!c->shapes || !L->shape_names) return error_set(L->err, "%s: out of memory", L->file);
    c->n_shapes = n;
    for (int i = 0; i < n; ++i)
        if (!load_shape(L, seq_item(L, seq, i), i, c)) return false;
    return true;
}

static bool load_light(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct light_desc *l = &c->lights[index];
    char where[CONFIG_NAME_MAX + 16];
    yaml_node_t *name, *n;
    l->loc = loc_of(L, map);
    snprintf(where, sizeof where, "light %d", index);
    if (!expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !check_keys(L, map, where, light_keys, COUNT(light_keys)) || !(name = need(L, map, "name", where)) ||
        !get_string(L, name, l->name, sizeof l->name))
        return false;
    for (int i = 0; i < index; ++i)
        if (strcmp(c->lights[i].name, l->name) == 0)
            return fail(L, name, "duplicate light name \"%s\" (first at line %d, column %d)", l->name,
                        c->lights[i].loc.line, c->lights[i].loc.column);
    snprintf(where, sizeof where, "light \"%s\"", l->name);
    if (!(n = need(L, map, "vertices", where)) ||
        !get_polygon(L, n, where, 3, POLYGON_INPUT_MAX, &l->polygon) || !(n = need(L, map, "radiance", where)) ||
        !get_rgb(L, n, 0.0, INFINITY, &l->radiance))
        return false;
    if (rgb_is_black(l->radiance)) return fail(L, n, "%s has zero radiance (expected a positive component)", where);
    l->two_sided = false;
    return !(n = map_get(L, map, "two_sided")) || get_bool(L, n, &l->two_sided);
}

static bool load_lights(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq;
    if (!get_optional(L, root, "lights", YAML_SEQUENCE_NODE, &seq)) return false;
    if (!seq || seq_count(seq) == 0)
        return fail(L, seq ? seq : root, "scene has no lights (expected a lights sequence with at least one light)");
    int n = seq_count(seq);
    c->lights = calloc((size_t)n, sizeof *c->lights);
    if (!c->lights) return error_set(L->err, "%s: out of memory", L->file);
    c->n_lights = n;
    for (int i = 0; i < n; ++i)
        if (!load_light(L, seq_item(L, seq, i), i, c)) return false;
    return true;
}

/* A portal is useful only on the side its light emits to, and one lying in
   the light's own plane would pass no light at all. */
static bool check_portal_placement(struct loader *L, const yaml_node_t *n, const struct portal_desc *p,
                                   const struct light_desc *l)
{
    struct plane pl = polygon_plane(&l->polygon);
    double size = fmax(points_diameter(l->polygon.v, l->polygon.n), points_diameter(p->polygon.v, p->polygon.n));
    double tol = PLANAR_REL_TOL * size, dmin = INFINITY, dmax = -INFINITY;
    for (int i = 0; i < p->polygon.n; ++i) {
        double d = plane_distance(&pl, p->polygon.v[i]);
        dmin = fmin(dmin, d);
        dmax = fmax(dmax, d);
    }
    if (dmin >= -tol && dmax <= tol)
        return fail(L, n, "portal \"%s\" is coplanar with its light \"%s\" (expected a portal off the light's plane)",
                    p->name, l->name);
    if (!l->two_sided && dmin < -tol)
        return fail(L, n, "portal \"%s\" is behind its light \"%s\" (expected every vertex on the emitting side, "
                          "towards the light's normal)", p->name, l->name);
    return true;
}

static bool load_portal(struct loader *L, const yaml_node_t *map, int index, struct config *c)
{
    struct portal_desc *p = &c->portals[index];
    char where[CONFIG_NAME_MAX + 16], light[CONFIG_NAME_MAX];
    yaml_node_t *n, *verts;
    p->loc = loc_of(L, map);
    snprintf(where, sizeof where, "portal %d", index);
    if (!expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !check_keys(L, map, where, portal_keys, COUNT(portal_keys)))
        return false;
    snprintf(p->name, sizeof p->name, "portal%d", index);
    if ((n = map_get(L, map, "name")) && !get_string(L, n, p->name, sizeof p->name)) return false;
    for (int i = 0; i < index; ++i)
        if (strcmp(c->portals[i].name, p->name) == 0)
            return fail(L, n ? n : map, "duplicate portal name \"%s\" (first at line %d, column %d)", p->name,
                        c->portals[i].loc.line, c->portals[i].loc.column);
    snprintf(where, sizeof where, "portal \"%s\"", p->name);
    if (!(n = need(L, map, "light", where)) || !get_string(L, n, light, sizeof light)) return false;
    p->light = -1;
    for (int i = 0; i < c->n_lights; ++i)
        if (strcmp(c->lights[i].name, light) == 0) p->light = i;
    if (p->light < 0) {
        struct line list = { "", 0 };
        for (int i = 0; i < c->n_lights; ++i) line_add(&list, c->lights[i].name);
        return fail(L, n, "portal \"%s\" refers to unknown light \"%s\" (expected one of: %s)", p->name, light,
                    list.s);
    }
    if (!(verts = need(L, map, "vertices", where)) ||
        !get_polygon(L, verts, where, 3, POLYGON_INPUT_MAX, &p->polygon))
        return false;
    return check_portal_placement(L, verts, p, &c->lights[p->light]);
}

static bool load_portals(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *seq;
    if (!get_optional(L, root, "portals", YAML_SEQUENCE_NODE, &seq)) return false;
    int n = seq ? seq_count(seq) : 0;
    if (n == 0) return true;
    c->portals = calloc((size_t)n, sizeof *c->portals);
    if (!c->portals) return error_set(L->err, "%s: out of memory", L->file);
    c->n_portals = n;
    for (int i = 0; i < n; ++i)
        if (!load_portal(L, seq_item(L, seq, i), i, c)) return false;
    return true;
}

/* Strictly increasing positive times, at most CONFIG_SCHEDULE_MAX. */
static bool get_times(struct loader *L, const yaml_node_t *seq, double *times, int *count)
{
    char buf[64];
    if (seq_count(seq) > CONFIG_SCHEDULE_MAX)
        return fail(L, seq, "too many snapshot times: %d (expected at most %d)", seq_count(seq), CONFIG_SCHEDULE_MAX);
    for (int i = 0; i < seq_count(seq); ++i) {
        const yaml_node_t *item = seq_item(L, seq, i);
        if (!get_number_in(L, item, 0.0, true, INFINITY, false, &times[i])) return false;
        if (i > 0 && times[i] <= times[i - 1])
            return fail(L, item, "snapshot times must increase (expected a time > %g, got %s)", times[i - 1],
                        value_text(item, times[i], buf, sizeof buf));
    }
    *count = seq_count(seq);
    return true;
}

static bool get_spps(struct loader *L, const yaml_node_t *seq, int *spps, int *count)
{
    if (seq_count(seq) > CONFIG_SCHEDULE_MAX)
        return fail(L, seq, "too many snapshot spps: %d (expected at most %d)", seq_count(seq), CONFIG_SCHEDULE_MAX);
    for (int i = 0; i < seq_count(seq); ++i) {
        const yaml_node_t *item = seq_item(L, seq, i);
        if (!get_int(L, item, 1, INT_MAX, &spps[i])) return false;
        if (i > 0 && spps[i] <= spps[i - 1])
            return fail(L, item, "snapshot spps must increase (expected more than %d, got %d)", spps[i - 1], spps[i]);
    }
    *count = seq_count(seq);
    return true;
}

static bool load_snapshots(struct loader *L, const yaml_node_t *map, struct snapshot_schedule *s)
{
    yaml_node_t *n;
    if (!check_keys(L, map, "render.snapshots", config_snapshot_keys, CONFIG_SNAPSHOT_KEY_COUNT)) return false;
    if ((n = map_get(L, map, "every")) && !get_number_in(L, n, 0.0, false, INFINITY, false, &s->every_s)) return false;
    if ((n = map_get(L, map, "doubling")) && !get_number_in(L, n, 0.0, false, INFINITY, false, &s->doubling_s))
        return false;
    if ((n = map_get(L, map, "every_spp")) && !get_int(L, n, 0, INT_MAX, &s->every_spp)) return false;
    if ((n = map_get(L, map, "doubling_spp")) && !get_int(L, n, 0, INT_MAX, &s->doubling_spp)) return false;
    if (!get_optional(L, map, "times", YAML_SEQUENCE_NODE, &n) || (n && !get_times(L, n, s->times_s, &s->n_times)))
        return false;
    if (!get_optional(L, map, "spp", YAML_SEQUENCE_NODE, &n) || (n && !get_spps(L, n, s->spps, &s->n_spps)))
        return false;
    return true;
}

static bool load_aov(struct loader *L, const yaml_node_t *map, struct render_desc *r)
{
    yaml_node_t *n;
    if (!check_keys(L, map, "render.aov", aov_keys, COUNT(aov_keys))) return false;
    if ((n = map_get(L, map, "region")) && !get_bool(L, n, &r->aov_region)) return false;
    return true;
}

/* The seed is read from its text when it is a literal: a double would lose
   the low bits of seeds above 2^53. */
static bool get_seed(struct loader *L, const yaml_node_t *n, uint64_t *out)
{
    char buf[64];
    const char *expected = "a non-negative integer below 2^64";
    if (n->type == YAML_SCALAR_NODE && n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE) {
        const char *s = text_of(n);
        size_t len = strspn(s, "0123456789");
        if (len > 0 && s[len] == '\0') {
            errno = 0;
            unsigned long long v = strtoull(s, NULL, 10);
            if (errno == ERANGE || v > UINT64_MAX) return fail(L, n, "expected %s, got %.40s", expected, s);
            *out = (uint64_t)v;
            return true;
        }
    }
    /* Expressions and other number spellings go through doubles: exact up to 2^53. */
    double v;
    if (!get_number_as(L, n, expected, &v)) return false;
    if (v != floor(v) || v < 0.0 || v > 9007199254740992.0)
        return fail(L, n, "expected %s, got %s", expected, value_text(n, v, buf, sizeof buf));
    *out = (uint64_t)v;
    return true;
}

static bool get_threads(struct loader *L, const yaml_node_t *n, int *out)
{
    char expected[64], buf[64];
    double v;
    if (n->type == YAML_SCALAR_NODE && strcmp(text_of(n), "auto") == 0) {
        *out = 0;
        return true;
    }
    snprintf(expected, sizeof expected, "\"auto\" or an integer in [1, %d]", THREADS_MAX);
    if (!get_number_as(L, n, expected, &v)) return false;
    if (v != floor(v) || v < 1 || v > THREADS_MAX)
        return fail(L, n, "expected %s, got %s", expected, value_text(n, v, buf, sizeof buf));
    *out = (int)v;
    return true;
}

static bool load_render(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map = need(L, root, "render", "the top level"), *n;
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
    if (!map || !expect_type(L, map, YAML_MAPPING_NODE, "a mapping") ||
        !check_keys(L, map, "render", render_keys, COUNT(render_keys)))
        return false;
    if ((n = map_get(L, map, "integrator"))) {
        if (!get_enum(L, n, "integrator", integrator_names, 2, &e)) return false;
        r->integrator = (enum integrator_kind)e;
    }
    if ((n = map_get(L, map, "strategy"))) {
        if (!get_enum(L, n, "strategy", strategy_names, STRATEGY_COUNT, &e)) return false;
        r->strategy = (enum strategy_kind)e;
    }
    if ((n = map_get(L, map, "mis"))) {
        if (!get_enum(L, n, "mis", mis_names, 3, &e)) return false;
        r->mis = (enum mis_kind)e;
    }
    if ((n = map_get(L, map, "portal_weight"))) {
        if (!get_enum(L, n, "portal_weight", portal_weight_names, 3, &e)) return false;
        r->portal_weight = (enum portal_weight_kind)e;
    }
    if ((n = map_get(L, map, "defensive")) && !get_number_in(L, n, 0.0, false, 1.0, true, &r->defensive)) return false;
    if ((n = map_get(L, map, "max_depth")) && !get_int(L, n, 1, INT_MAX, &r->max_depth)) return false;
    if ((n = map_get(L, map, "rr_depth")) && !get_int(L, n, 1, INT_MAX, &r->rr_depth)) return false;
    if ((n = map_get(L, map, "spp")) && !get_int(L, n, 0, INT_MAX, &r->spp)) return false;
    if ((n = map_get(L, map, "time")) && !get_number_in(L, n, 0.0, false, INFINITY, false, &r->time_s)) return false;
    if (!get_optional(L, map, "snapshots", YAML_MAPPING_NODE, &n) || (n && !load_snapshots(L, n, &r->snapshots)))
        return false;
    if ((n = map_get(L, map, "seed")) && !get_seed(L, n, &r->seed)) return false;
    if ((n = map_get(L, map, "threads")) && !get_threads(L, n, &r->threads)) return false;
    if (!get_optional(L, map, "aov", YAML_MAPPING_NODE, &n) || (n && !load_aov(L, n, r))) return false;
    if ((n = map_get(L, map, "resumable")) && !get_bool(L, n, &r->resumable)) return false;
    if ((n = map_get(L, map, "output")) && !get_string(L, n, r->output, sizeof r->output)) return false;
    c->output_override = n ? override_of(L, n) : -1;
    if (c->output_override < 0) c->output_loc = loc_of(L, n ? n : map);
    if (r->spp == 0 && r->time_s == 0.0)
        return fail(L, map, "spp and time are both 0 (expected a sample limit, a time limit or both)");
    return true;
}

static bool load_sections(struct loader *L, struct config *c)
{
    const yaml_node_t *root = L->root ? node_get(L, L->root) : NULL;
    if (!root) return error_at(L->err, L->file, 1, 1, "empty document (expected a mapping with camera, film, lights "
                                                      "and render)");
    return expect_type(L, root, YAML_MAPPING_NODE, "a mapping at the top level") &&
           check_keys(L, root, "the top level", top_keys, COUNT(top_keys)) && load_params(L, root) &&
           load_camera(L, root, &c->camera) && load_film(L, root, c) && load_materials(L, root, c) &&
           load_shapes(L, root, c) && load_lights(L, root, c) && load_portals(L, root, c) &&
           load_render(L, root, c);
}


static bool mark_override(struct loader *L, int node, int k)
{
    L->marks[L->n_marks].node = node;
    L->marks[L->n_marks].override = k;
    ++L->n_marks;
    return true;
}

/* For override k, whose first `len` characters name the missing key `comp`
   of mapping `parent`: when that prefix is one of override_mapping_paths,
   adds comp as an empty mapping and sets *made to its node id (else 0). */
static bool add_override_mapping(struct loader *L, int k, int parent, const char *comp, size_t len, int *made)
{
    const char *path = L->overrides[k].path;
    *made = 0;
    for (int i = 0; i < COUNT(override_mapping_paths); ++i)
        if (strlen(override_mapping_paths[i]) == len && !strncmp(path, override_mapping_paths[i], len)) {
            int key = yaml_document_add_scalar(&L->doc, NULL, (yaml_char_t *)comp, -1, YAML_PLAIN_SCALAR_STYLE);
            int map = key ? yaml_document_add_mapping(&L->doc, NULL, YAML_FLOW_MAPPING_STYLE) : 0;
            if (!key || !map || !yaml_document_append_mapping_pair(&L->doc, parent, key, map))
                return error_set(L->err, "--set %s: out of memory", path);
            *made = map;
            return mark_override(L, key, k) && mark_override(L, map, k);
        }
    return true;
}

/* Walks the dot-separated path from the root and replaces (or, for a missing
   last key of a mapping, adds) the scalar it names. Nodes are re-fetched by
   id after each addition because adding may move the node array. */
static bool apply_override(struct loader *L, int k)
{
    const struct config_override *o = &L->overrides[k];
    if (!o->path || !o->value || !o->path[0]) return error_set(L->err, "--set: expected key.path=value");
    char path[CONFIG_PATH_MAX], where[CONFIG_PATH_MAX] = "the top level";
    if (strlen(o->path) >= sizeof path) return error_set(L->err, "--set %.64s...: path too long", o->path);
    memcpy(path, o->path, strlen(o->path) + 1);
    if (!L->root) return error_set(L->err, "--set %s: the document is empty", o->path);
    int cur = L->root;
    char *comp = path;
    for (;;) {
        char *dot = strchr(comp, '.');
        bool last = dot == NULL;
        if (dot) *dot = '\0';
        if (!comp[0]) return error_set(L->err, "--set %s: empty key in the path", o->path);
        yaml_node_t *node = node_get(L, cur);
        int *slot = NULL;
        if (node->type == YAML_MAPPING_NODE) {
            for (int i = 0; i < map_count(node) && !slot; ++i) {
                const yaml_node_t *key = node_get(L, node->data.mapping.pairs.start[i].key);
                if (key->type == YAML_SCALAR_NODE && strcmp(text_of(key), comp) == 0)
                    slot = &node->data.mapping.pairs.start[i].value;
            }
            if (!slot && !last) {
                int made = 0;
                if (!add_override_mapping(L, k, cur, comp, (size_t)(dot - path), &made)) return false;
                if (!made) return error_set(L->err, "--set %s: no key \"%s\" in %s", o->path, comp, where);
                cur = made;
                snprintf(where, sizeof where, "%.*s", (int)(dot - path), o->path);
                comp = dot + 1;
                continue;
            }
            if (!slot) {
                int key = yaml_document_add_scalar(&L->doc, NULL, (yaml_char_t *)comp, -1, YAML_PLAIN_SCALAR_STYLE);
                int value = key ? yaml_document_add_scalar(&L->doc, NULL, (yaml_char_t *)o->value, -1,
                                                           YAML_PLAIN_SCALAR_STYLE)
                                : 0;
                if (!key || !value || !yaml_document_append_mapping_pair(&L->doc, cur, key, value))
                    return error_set(L->err, "--set %s=%s: not valid UTF-8 (or out of memory)", o->path, o->value);
                return mark_override(L, key, k) && mark_override(L, value, k);
            }
        } else if (node->type == YAML_SEQUENCE_NODE) {
            size_t len = strspn(comp, "0123456789");
            if (len == 0 || comp[len] != '\0' || len > 9)
                return error_set(L->err, "--set %s: \"%s\" is not an index (%s is a sequence)", o->path, comp, where);
            int index = atoi(comp);
            if (index >= seq_count(node))
                return error_set(L->err, "--set %s: index %d out of range in %s (expected 0 to %d)", o->path, index,
                                 where, seq_count(node) - 1);
            slot = &node->data.sequence.items.start[index];
        } else {
            return error_set(L->err, "--set %s: %s is a scalar (expected a mapping or a sequence before \"%s\")",
                             o->path, where, comp);
        }
        const yaml_node_t *target = node_get(L, *slot);
        if (last) {
            if (target->type != YAML_SCALAR_NODE)
                return error_set(L->err, "--set %s: %s is a %s (only scalars can be overridden)", o->path, o->path,
                                 target->type == YAML_MAPPING_NODE ? "mapping" : "sequence");
            /* The slot lives in the parent's own item array, which adding a
               node does not move; the id is stored through it afterwards. */
            int value = yaml_document_add_scalar(&L->doc, NULL, (yaml_char_t *)o->value, -1, YAML_PLAIN_SCALAR_STYLE);
            if (!value) return error_set(L->err, "--set %s=%s: not valid UTF-8 (or out of memory)", o->path, o->value);
            *slot = value;
            return mark_override(L, value, k);
        }
        cur = *slot;
        /* `where` names the prefix walked so far, as the user wrote it. */
        snprintf(where, sizeof where, "%.*s", (int)(dot - path), o->path);
        comp = dot + 1;
    }
}


struct text {
    char *s;
    size_t len, cap;
    bool failed;
};

static void text_printf(struct text *t, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void text_printf(struct text *t, const char *fmt, ...)
{
    if (t->failed) return;
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (k < 0) {
        t->failed = true;
        return;
    }
    if (t->len + (size_t)k + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 4096;
        while (cap < t->len + (size_t)k + 1) cap *= 2;
        char *s = realloc(t->s, cap);
        if (!s) {
            t->failed = true;
            return;
        }
        t->s = s;
        t->cap = cap;
    }
    va_start(ap, fmt);
    vsnprintf(t->s + t->len, t->cap - t->len, fmt, ap);
    va_end(ap);
    t->len += (size_t)k;
}

/* The shortest of %.15g, %.16g, %.17g that reads back to the same double:
   %.17g always does, the shorter ones keep 0.6 from printing as
   0.59999999999999998. */
static void emit_number(struct text *t, double v)
{
    char buf[32];
    for (int digits = 15; digits <= 17; ++digits) {
        snprintf(buf, sizeof buf, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) break;
    }
    text_printf(t, "%s", buf);
}

static void emit_vec3(struct text *t, struct vec3 v)
{
    text_printf(t, "[");
    emit_number(t, v.x);
    text_printf(t, ", ");
    emit_number(t, v.y);
    text_printf(t, ", ");
    emit_number(t, v.z);
    text_printf(t, "]");
}

static void emit_rgb(struct text *t, struct rgb c)
{
    emit_vec3(t, vec3_make(c.r, c.g, c.b));
}

/* Decodes one UTF-8 sequence; returns its length (1 for a stray byte, which
   cannot occur: libyaml and yaml_document_add_scalar validate UTF-8). */
static int utf8_decode(const unsigned char *s, unsigned long *cp)
{
    int len = s[0] < 0x80 ? 1 : (s[0] & 0xE0) == 0xC0 ? 2 : (s[0] & 0xF0) == 0xE0 ? 3 : (s[0] & 0xF8) == 0xF0 ? 4 : 1;
    unsigned long c = len == 1 ? s[0] : s[0] & (0x7Fu >> len);
    for (int i = 1; i < len; ++i) {
        if ((s[i] & 0xC0) != 0x80) { /* also stops at the terminator */
            *cp = s[0];
            return 1;
        }
        c = (c << 6) | (s[i] & 0x3F);
    }
    *cp = c;
    return len;
}

/* A double-quoted YAML string. Escapes what libyaml would fold or refuse:
   controls, line and paragraph separators, the BOM and non-characters. */
static void emit_string(struct text *t, const char *s)
{
    text_printf(t, "\"");
    const unsigned char *p = (const unsigned char *)s;
    while (*p) {
        unsigned long c;
        int len = utf8_decode(p, &c);
        if (c == '"' || c == '\\')
            text_printf(t, "\\%c", (int)c);
        else if (c < 0x20 || (c >= 0x7F && c <= 0x9F))
            text_printf(t, "\\x%02lX", c);
        else if (c == 0x2028 || c == 0x2029 || c == 0xFEFF || c == 0xFFFE || c == 0xFFFF || (c >= 0xD800 && c <= 0xDFFF))
            text_printf(t, "\\u%04lX", c);
        else
            text_printf(t, "%.*s", len, (const char *)p);
        p += len;
    }
    text_printf(t, "\"");
}

static void emit_camera_film(struct text *t, const struct config *c)
{
    text_printf(t, "camera:\n  position: ");
    emit_vec3(t, c->camera.position);
    text_printf(t, "\n  look_at: ");
    emit_vec3(t, c->camera.look_at);
    text_printf(t, "\n  up: ");
    emit_vec3(t, c->camera.up);
    text_printf(t, "\n  fov_y: ");
    emit_number(t, c->camera.fov_y_deg);
    text_printf(t, "\nfilm:\n  width: %d\n  height: %d\n", c->width, c->height);
}

static void emit_materials(struct text *t, const struct config *c)
{
    text_printf(t, "materials:%s\n", c->n_materials ? "" : " {}");
    for (int i = 0; i < c->n_materials; ++i) {
        const struct material_desc *m = &c->materials[i];
        text_printf(t, "  ");
        emit_string(t, m->name);
        text_printf(t, ": {type: %s, albedo: ", material_names[m->kind]);
        emit_rgb(t, m->albedo);
        if (m->kind == MATERIAL_GGX) {
            text_printf(t, ", roughness: ");
            emit_number(t, m->roughness);
        }
        text_printf(t, "}\n");
    }
}

static void emit_shapes(struct text *t, const struct config *c, char (*names)[CONFIG_NAME_MAX])
{
    text_printf(t, "shapes:%s\n", c->n_shapes ? "" : " []");
    for (int i = 0; i < c->n_shapes; ++i) {
        const struct shape_desc *s = &c->shapes[i];
        text_printf(t, "  - ");
        if (names[i][0]) {
            text_printf(t, "name: ");
            emit_string(t, names[i]);
            text_printf(t, "\n    ");
        }
        text_printf(t, "type: mesh\n    material: ");
        emit_string(t, c->materials[s->material].name);
        text_printf(t, "\n    vertices:\n");
        for (int v = 0; v < s->n_vertices; ++v) {
            text_printf(t, "      - ");
            emit_vec3(t, s->vertices[v]);
            text_printf(t, "\n");
        }
        if (s->n_triangles) text_printf(t, "    triangles:\n");
        for (int f = 0; f < s->n_triangles; ++f)
            text_printf(t, "      - [%d, %d, %d]\n", s->triangles[f][0], s->triangles[f][1], s->triangles[f][2]);
        if (s->n_quads) text_printf(t, "    quads:\n");
        for (int f = 0; f < s->n_quads; ++f)
            text_printf(t, "      - [%d, %d, %d, %d]\n", s->quads[f][0], s->quads[f][1], s->quads[f][2], s->quads[f][3]);
    }
}

static void emit_polygon(struct text *t, const struct polygon *p)
{
    text_printf(t, "    vertices:\n");
    for (int v = 0; v < p->n; ++v) {
        text_printf(t, "      - ");
        emit_vec3(t, p->v[v]);
        text_printf(t, "\n");
    }
}

static void emit_lights_portals(struct text *t, const struct config *c)
{
    text_printf(t, "lights:\n");
    for (int i = 0; i < c->n_lights; ++i) {
        const struct light_desc *l = &c->lights[i];
        text_printf(t, "  - name: ");
        emit_string(t, l->name);
        text_printf(t, "\n");
        emit_polygon(t, &l->polygon);
        text_printf(t, "    radiance: ");
        emit_rgb(t, l->radiance);
        text_printf(t, "\n    two_sided: %s\n", l->two_sided ? "true" : "false");
    }
    text_printf(t, "portals:%s\n", c->n_portals ? "" : " []");
    for (int i = 0; i < c->n_portals; ++i) {
        const struct portal_desc *p = &c->portals[i];
        text_printf(t, "  - name: ");
        emit_string(t, p->name);
        text_printf(t, "\n    light: ");
        emit_string(t, c->lights[p->light].name);
        text_printf(t, "\n");
        emit_polygon(t, &p->polygon);
    }
}

static void emit_snapshots(struct text *t, const struct snapshot_schedule *s)
{
    const char *sep = "";
    text_printf(t, "\n  snapshots: {");
    if (s->every_s > 0.0) {
        text_printf(t, "every: ");
        emit_number(t, s->every_s);
        sep = ", ";
    }
    if (s->doubling_s > 0.0) {
        text_printf(t, "%sdoubling: ", sep);
        emit_number(t, s->doubling_s);
        sep = ", ";
    }
    if (s->n_times) {
        text_printf(t, "%stimes: [", sep);
        for (int i = 0; i < s->n_times; ++i) {
            text_printf(t, "%s", i ? ", " : "");
            emit_number(t, s->times_s[i]);
        }
        text_printf(t, "]");
        sep = ", ";
    }
    if (s->every_spp > 0) {
        text_printf(t, "%severy_spp: %d", sep, s->every_spp);
        sep = ", ";
    }
    if (s->doubling_spp > 0) {
        text_printf(t, "%sdoubling_spp: %d", sep, s->doubling_spp);
        sep = ", ";
    }
    if (s->n_spps) {
        text_printf(t, "%sspp: [", sep);
        for (int i = 0; i < s->n_spps; ++i) text_printf(t, "%s%d", i ? ", " : "", s->spps[i]);
        text_printf(t, "]");
    }
    text_printf(t, "}");
}

/* With `image_only`, the keys that only say how long, how often, on how
   many threads and where a render runs are left out: what remains decides
   the image of every pass. */
static void emit_render(struct text *t, const struct render_desc *r, bool image_only)
{
    text_printf(t, "render:\n  integrator: %s\n  strategy: %s\n  mis: %s\n  portal_weight: %s\n  defensive: ",
                integrator_names[r->integrator], strategy_names[r->strategy], mis_names[r->mis],
                portal_weight_names[r->portal_weight]);
    emit_number(t, r->defensive);
    text_printf(t, "\n  max_depth: %d\n  rr_depth: %d", r->max_depth, r->rr_depth);
    if (!image_only) {
        text_printf(t, "\n  spp: %d\n  time: ", r->spp);
        emit_number(t, r->time_s);
        emit_snapshots(t, &r->snapshots);
    }
    text_printf(t, "\n  seed: %" PRIu64, r->seed);
    if (!image_only) {
        text_printf(t, "\n  threads: ");
        if (r->threads == 0)
            text_printf(t, "auto");
        else
            text_printf(t, "%d", r->threads);
        text_printf(t, "\n  output: ");
        emit_string(t, r->output);
        text_printf(t, "\n  resumable: %s", r->resumable ? "true" : "false");
    }
    /* The AOV is part of the image: its channels and the film state's counts. */
    text_printf(t, "\n  aov: {region: %s}\n", r->aov_region ? "true" : "false");
}

/* FNV-1a, 64-bit. */
static uint64_t fnv1a64(const char *s, size_t n)
{
    uint64_t h = 14695981039346656037ull;
    for (size_t i = 0; i < n; ++i) {
        h ^= (unsigned char)s[i];
        h *= 1099511628211ull;
    }
    return h;
}

static void emit_yaml(struct text *t, struct loader *L, const struct config *c, bool image_only)
{
    text_printf(t, "# effective configuration (params substituted, overrides applied, defaults filled)\n");
    emit_camera_film(t, c);
    emit_materials(t, c);
    emit_shapes(t, c, L->shape_names);
    emit_lights_portals(t, c);
    emit_render(t, &c->render, image_only);
}

static bool emit_effective(struct loader *L, struct config *c)
{
    struct text t = { NULL, 0, 0, false }, image = { NULL, 0, 0, false };
    emit_yaml(&t, L, c, false);
    emit_yaml(&image, L, c, true);
    if (t.failed || image.failed) {
        free(t.s);
        free(image.s);
        return error_set(L->err, "%s: out of memory", L->file);
    }
    c->effective_yaml = t.s;
    c->hash = fnv1a64(t.s, t.len);
    c->image_hash = fnv1a64(image.s, image.len);
    free(image.s);
    return true;
}


/* libyaml reader errors carry a byte offset, not a mark. */
static void offset_to_mark(const char *text, size_t offset, int *line, int *column)
{
    *line = 1;
    *column = 1;
    for (size_t i = 0; i < offset && text[i]; ++i) {
        if (text[i] == '\n') {
            ++*line;
            *column = 1;
        } else if (((unsigned char)text[i] & 0xC0) != 0x80) {
            ++*column;
        }
    }
}

static bool parse_error(struct loader *L, int s, const yaml_parser_t *parser, const char *text)
{
    int line, column;
    const char *problem = parser->problem ? parser->problem : "invalid YAML";
    if (parser->error == YAML_MEMORY_ERROR) return error_set(L->err, "%s: out of memory", L->sources[s].path);
    if (parser->error == YAML_READER_ERROR) {
        offset_to_mark(text, parser->problem_offset, &line, &column);
        return report(L, s, line, column, "%s", parser->problem ? parser->problem : "unreadable input");
    }
    line = (int)parser->problem_mark.line + 1;
    column = (int)parser->problem_mark.column + 1;
    if (parser->context)
        return report(L, s, line, column, "%s (%s at line %d, column %d)", problem, parser->context,
                      (int)parser->context_mark.line + 1, (int)parser->context_mark.column + 1);
    return report(L, s, line, column, "%s", problem);
}

/* Parses the one document of source s into doc; on success the caller
   deletes doc. */
static bool parse_document(struct loader *L, int s, const char *text, size_t length, yaml_document_t *doc)
{
    yaml_parser_t parser;
    if (!yaml_parser_initialize(&parser)) return error_set(L->err, "%s: out of memory", L->sources[s].path);
    yaml_parser_set_input_string(&parser, (const unsigned char *)text, length);
    /* On failure yaml_parser_load deletes the document itself. */
    bool ok = yaml_parser_load(&parser, doc) != 0;
    if (!ok) {
        parse_error(L, s, &parser, text);
    } else {
        yaml_document_t next;
        if (!yaml_parser_load(&parser, &next)) {
            ok = parse_error(L, s, &parser, text);
        } else {
            const yaml_node_t *root = yaml_document_get_root_node(&next);
            if (root)
                ok = report(L, s, (int)root->start_mark.line + 1, (int)root->start_mark.column + 1,
                            "a second YAML document (expected exactly one)");
            yaml_document_delete(&next);
        }
        if (!ok) yaml_document_delete(doc);
    }
    yaml_parser_delete(&parser);
    return ok;
}

/* The whole of a file that is not a folder; on failure *why says what was
   wrong. */
static bool read_text(const char *path, char **text, size_t *length, struct stat *st, const char **why)
{
    *text = NULL;
    *length = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        *why = strerror(errno);
        return false;
    }
    /* Reading a folder would fail with EISDIR anyway; say so before. */
    if (fstat(fd, st) != 0 || S_ISDIR(st->st_mode)) {
        *why = strerror(S_ISDIR(st->st_mode) ? EISDIR : errno);
        close(fd);
        return false;
    }
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    *why = NULL;
    while (buf) {
        if (len == cap) {
            char *grown = cap <= SIZE_MAX / 2 ? realloc(buf, cap * 2) : NULL;
            if (!grown) break;
            buf = grown;
            cap *= 2;
        }
        ssize_t got = read(fd, buf + len, cap - len);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            *why = strerror(errno);
            break;
        }
        if (got == 0) {
            close(fd);
            *text = buf;
            *length = len;
            return true;
        }
        len += (size_t)got;
    }
    if (!*why) *why = "out of memory";
    free(buf);
    close(fd);
    return false;
}


/* Building the merged document of an include tree. Every node is copied
   into L->doc with its marks, and L->node_source remembers its file, so
   that messages name the file and position the value came from. */

static bool out_of_memory(struct loader *L)
{
    return error_set(L->err, "%s: out of memory", L->file);
}

/* Adds to L->doc a node like n (a scalar with its value, an empty sequence
   or mapping) with n's marks, from source s. n may be a node of L->doc:
   everything is read from it before the node array can move. Returns the
   new id, or 0. */
static int add_like(struct loader *L, const yaml_node_t *n, int s)
{
    yaml_node_t copy = *n; /* the strings it points to do not move */
    int id = 0;
    switch (copy.type) {
    case YAML_SCALAR_NODE:
        if (copy.data.scalar.length > INT_MAX) return out_of_memory(L);
        id = yaml_document_add_scalar(&L->doc, copy.tag, copy.data.scalar.value, (int)copy.data.scalar.length,
                                      copy.data.scalar.style);
        break;
    case YAML_SEQUENCE_NODE: id = yaml_document_add_sequence(&L->doc, copy.tag, copy.data.sequence.style); break;
    case YAML_MAPPING_NODE: id = yaml_document_add_mapping(&L->doc, copy.tag, copy.data.mapping.style); break;
    case YAML_NO_NODE: break;
    }
    if (!id) return out_of_memory(L);
    if (id > L->cap_node_source) {
        int cap = L->cap_node_source ? 2 * L->cap_node_source : 1024;
        while (cap < id) cap *= 2;
        int *grown = realloc(L->node_source, (size_t)cap * sizeof *grown);
        if (!grown) return out_of_memory(L);
        L->node_source = grown;
        L->cap_node_source = cap;
    }
    L->node_source[id - 1] = s;
    L->n_node_source = id;
    yaml_node_t *c = node_get(L, id);
    c->start_mark = copy.start_mark;
    c->end_mark = copy.end_mark;
    return id;
}

static bool is_include_key(const yaml_node_t *key)
{
    return key->type == YAML_SCALAR_NODE && strcmp(text_of(key), "include") == 0;
}

/* Copies node id of source s's document into L->doc, once per node (memo,
   by id - 1), so that aliases stay shared and cannot multiply; the top
   level (depth 0) leaves out its include key. Returns the copy's id, or 0. */
static int copy_node(struct loader *L, int s, yaml_document_t *doc, int id, int *memo, int depth)
{
    if (memo[id - 1]) return memo[id - 1];
    const yaml_node_t *n = yaml_document_get_node(doc, id);
    if (depth > COPY_DEPTH_MAX) {
        report(L, s, (int)n->start_mark.line + 1, (int)n->start_mark.column + 1,
               "nested more than %d levels deep (expected a flatter document)", COPY_DEPTH_MAX);
        return 0;
    }
    int c = add_like(L, n, s);
    if (!c) return 0;
    memo[id - 1] = c;
    ++L->n_copied;
    if (n->type == YAML_SEQUENCE_NODE) {
        for (const yaml_node_item_t *it = n->data.sequence.items.start; it < n->data.sequence.items.top; ++it) {
            int item = copy_node(L, s, doc, *it, memo, depth + 1);
            if (!item) return 0;
            if (!yaml_document_append_sequence_item(&L->doc, c, item)) return out_of_memory(L);
        }
    } else if (n->type == YAML_MAPPING_NODE) {
        for (const yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; ++p) {
            if (depth == 0 && is_include_key(yaml_document_get_node(doc, p->key))) continue;
            int key = copy_node(L, s, doc, p->key, memo, depth + 1);
            int value = key ? copy_node(L, s, doc, p->value, memo, depth + 1) : 0;
            if (!value) return 0;
            if (!yaml_document_append_mapping_pair(&L->doc, c, key, value)) return out_of_memory(L);
        }
    }
    return c;
}

/* Index of the pair of mapping `map` (in L->doc) whose key is the scalar
   `key`, or -1. */
static int find_key(struct loader *L, int map, const yaml_node_t *key)
{
    if (key->type != YAML_SCALAR_NODE) return -1;
    const yaml_node_t *m = node_get(L, map);
    for (int i = 0; i < map_count(m); ++i) {
        const yaml_node_t *k = node_get(L, m->data.mapping.pairs.start[i].key);
        if (k->type == YAML_SCALAR_NODE && strcmp(text_of(k), text_of(key)) == 0) return i;
    }
    return -1;
}

/* `over` merged onto `base`, both in L->doc: two mappings merge key by key
   (base's keys first, in its order, with over's value where over has the
   key, merged again when both values are mappings; then over's other keys,
   in its order); anything else is over, whole. Returns the result's id (a
   new mapping, or over itself), or 0. Each file's keys are unique
   (check_unique_keys), so a merged mapping has unique keys too. */
static int merge(struct loader *L, int base, int over, int depth)
{
    const yaml_node_t *b = node_get(L, base), *o = node_get(L, over);
    if (b->type != YAML_MAPPING_NODE || o->type != YAML_MAPPING_NODE) return over;
    if (depth > COPY_DEPTH_MAX) {
        fail(L, o, "mappings nested more than %d levels deep (expected a flatter document)", COPY_DEPTH_MAX);
        return 0;
    }
    if (L->n_merged >= MERGE_NODES_PER_COPY * L->n_copied + MERGE_NODES_SLACK) {
        fail(L, o, "merging the includes makes more than %ld mappings (expected fewer aliases of mappings)",
             L->n_merged);
        return 0;
    }
    int m = add_like(L, o, source_of(L, o));
    if (!m) return 0;
    ++L->n_merged;
    int n_base = map_count(node_get(L, base)), n_over = map_count(node_get(L, over));
    for (int i = 0; i < n_base; ++i) {
        yaml_node_pair_t p = node_get(L, base)->data.mapping.pairs.start[i];
        int j = find_key(L, over, node_get(L, p.key));
        if (j >= 0) {
            yaml_node_pair_t q = node_get(L, over)->data.mapping.pairs.start[j];
            /* The key as the including file wrote it: messages point there. */
            p.key = q.key;
            p.value = merge(L, p.value, q.value, depth + 1);
            if (!p.value) return 0;
        }
        if (!yaml_document_append_mapping_pair(&L->doc, m, p.key, p.value)) return out_of_memory(L);
    }
    for (int j = 0; j < n_over; ++j) {
        yaml_node_pair_t q = node_get(L, over)->data.mapping.pairs.start[j];
        if (find_key(L, base, node_get(L, q.key)) >= 0) continue;
        if (!yaml_document_append_mapping_pair(&L->doc, m, q.key, q.value)) return out_of_memory(L);
    }
    return m;
}

/* Every mapping of a file in an include tree has unique keys, checked
   before merging: a merged mapping keeps one value per key. */
static bool check_unique_keys(struct loader *L, int s, yaml_document_t *doc)
{
    for (const yaml_node_t *n = doc->nodes.start; n < doc->nodes.top; ++n) {
        if (n->type != YAML_MAPPING_NODE) continue;
        const yaml_node_pair_t *pairs = n->data.mapping.pairs.start;
        for (int i = 1; i < map_count(n); ++i) {
            const yaml_node_t *key = yaml_document_get_node(doc, pairs[i].key);
            if (key->type != YAML_SCALAR_NODE) continue;
            for (int j = 0; j < i; ++j) {
                const yaml_node_t *other = yaml_document_get_node(doc, pairs[j].key);
                if (other->type == YAML_SCALAR_NODE && strcmp(text_of(other), text_of(key)) == 0)
                    return report(L, s, (int)key->start_mark.line + 1, (int)key->start_mark.column + 1,
                                  "duplicate key \"%.64s\" (first at line %d, column %d)", text_of(key),
                                  (int)other->start_mark.line + 1, (int)other->start_mark.column + 1);
            }
        }
    }
    return true;
}

static int resolve(struct loader *L, int s, yaml_document_t *doc, int depth);

/* A path in an include entry: a string, not a number, boolean or null. */
static bool include_path_ok(struct loader *L, int s, const yaml_node_t *entry)
{
    int line = (int)entry->start_mark.line + 1, column = (int)entry->start_mark.column + 1;
    char buf[64];
    const char *expected = "expected a path (a string) or a list of paths";
    if (entry->type != YAML_SCALAR_NODE || is_null(entry))
        return report(L, s, line, column, "%s, got %s", expected, describe(entry, buf, sizeof buf));
    const char *name = text_of(entry);
    double number;
    bool boolean = !strcmp(name, "true") || !strcmp(name, "True") || !strcmp(name, "TRUE") ||
                   !strcmp(name, "false") || !strcmp(name, "False") || !strcmp(name, "FALSE");
    if (entry->data.scalar.style == YAML_PLAIN_SCALAR_STYLE && (boolean || parse_literal(name, &number)))
        return report(L, s, line, column, "%s, got %.40s (quote it if it is a file name)", expected, name);
    if (strlen(name) != entry->data.scalar.length) return report(L, s, line, column, "path contains a NUL character");
    if (!name[0]) return report(L, s, line, column, "%s, got an empty string", expected);
    return true;
}

/* Appends " -> path" (or the path first) to a chain of file names. */
static void chain_add(struct line *chain, const char *path)
{
    line_append(chain, " -> ", path);
}

/* Reads, parses and resolves the file named by include entry `entry` of
   source s (at include depth `depth`). Returns the id of its merged top
   level in L->doc, or 0. */
static int include_one(struct loader *L, int s, const yaml_node_t *entry, int depth)
{
    int line = (int)entry->start_mark.line + 1, column = (int)entry->start_mark.column + 1;
    if (!include_path_ok(L, s, entry)) return 0;
    const char *name = text_of(entry), *parent = L->sources[s].path, *slash = strrchr(parent, '/');
    /* Relative to the folder of the including file, as #include "..." is. */
    size_t dir_len = name[0] == '/' || !slash ? 0 : (size_t)(slash - parent) + 1, len = dir_len + strlen(name);
    if (len >= CONFIG_PATH_MAX) {
        report(L, s, line, column, "include \"%.64s...\": path too long (expected at most %d bytes)", name,
               CONFIG_PATH_MAX - 1);
        return 0;
    }
    char *path = malloc(len + 1);
    if (!path) return out_of_memory(L);
    memcpy(path, parent, dir_len);
    memcpy(path + dir_len, name, strlen(name) + 1);

    char *text;
    size_t length;
    struct stat st;
    const char *why;
    if (!read_text(path, &text, &length, &st, &why)) {
        report(L, s, line, column, "include \"%s\": cannot read %s: %s (expected a YAML file; a relative path is "
                                   "relative to the folder of the file that includes it)", name, path, why);
        free(path);
        return 0;
    }
    for (int p = s; p >= 0; p = L->sources[p].parent) {
        if (!L->sources[p].have_id || L->sources[p].dev != st.st_dev || L->sources[p].ino != st.st_ino) continue;
        int stack[CONFIG_INCLUDE_DEPTH_MAX + 1], n = 0;
        for (int q = s; n <= CONFIG_INCLUDE_DEPTH_MAX; q = L->sources[q].parent) {
            stack[n++] = q;
            if (q == p) break;
        }
        struct line chain = { "", 0 };
        while (n > 0) chain_add(&chain, L->sources[stack[--n]].path);
        chain_add(&chain, path);
        report(L, s, line, column, "include \"%s\": include cycle %s (expected files that do not include each "
                                   "other)", name, chain.s);
        free(path);
        free(text);
        return 0;
    }
    if (depth >= CONFIG_INCLUDE_DEPTH_MAX) {
        report(L, s, line, column, "include \"%s\": includes nested more than %d levels deep (expected at most %d)",
               name, CONFIG_INCLUDE_DEPTH_MAX, CONFIG_INCLUDE_DEPTH_MAX);
        free(path);
        free(text);
        return 0;
    }
    struct source *grown = realloc(L->sources, (size_t)(L->n_sources + 1) * sizeof *grown);
    if (!grown) {
        free(path);
        free(text);
        return out_of_memory(L);
    }
    L->sources = grown;
    int t = L->n_sources++;
    struct source src = { path, s, line, column, true, st.st_dev, st.st_ino };
    L->sources[t] = src;

    yaml_document_t doc;
    bool parsed = parse_document(L, t, text, length, &doc);
    free(text);
    if (!parsed) return 0;
    int r = resolve(L, t, &doc, depth + 1);
    yaml_document_delete(&doc);
    return r;
}

/* The merged top level of source s (whose document is doc, at include depth
   `depth`): its includes, in order, each merged over the previous ones,
   then the file itself merged over them. Returns its id in L->doc, or 0. */
static int resolve(struct loader *L, int s, yaml_document_t *doc, int depth)
{
    char buf[64];
    const yaml_node_t *root = yaml_document_get_root_node(doc), *inc = NULL;
    if (!root) {
        report(L, s, 1, 1, "empty document (expected a mapping of config keys)");
        return 0;
    }
    if (root->type != YAML_MAPPING_NODE) {
        report(L, s, (int)root->start_mark.line + 1, (int)root->start_mark.column + 1,
               "expected a mapping at the top level, got %s", describe(root, buf, sizeof buf));
        return 0;
    }
    if (!check_unique_keys(L, s, doc)) return 0;
    for (const yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top; ++p)
        if (is_include_key(yaml_document_get_node(doc, p->key))) inc = yaml_document_get_node(doc, p->value);
    int merged = 0;
    if (inc && !is_null(inc)) {
        if (inc->type == YAML_MAPPING_NODE) {
            report(L, s, (int)inc->start_mark.line + 1, (int)inc->start_mark.column + 1,
                   "expected a path (a string) or a list of paths, got a mapping");
            return 0;
        }
        bool list = inc->type == YAML_SEQUENCE_NODE;
        int count = list ? seq_count(inc) : 1;
        for (int i = 0; i < count; ++i) {
            const yaml_node_t *entry = list ? yaml_document_get_node(doc, inc->data.sequence.items.start[i]) : inc;
            int r = include_one(L, s, entry, depth);
            if (!r) return 0;
            merged = merged ? merge(L, merged, r, 0) : r;
            if (!merged) return 0;
        }
    }
    int *memo = calloc((size_t)(doc->nodes.top - doc->nodes.start), sizeof *memo);
    if (!memo) return out_of_memory(L);
    int self = copy_node(L, s, doc, (int)(root - doc->nodes.start) + 1, memo, 0);
    free(memo);
    if (!self) return 0;
    return merged ? merge(L, merged, self, 0) : self;
}

/* Source 0's document as L->doc: its own, or the merged document of its
   include tree. */
static bool load_document(struct loader *L, const char *text, size_t length)
{
    yaml_document_t doc;
    if (!parse_document(L, 0, text, length, &doc)) return false;
    const yaml_node_t *root = yaml_document_get_root_node(&doc), *include_key = NULL;
    if (root && root->type == YAML_MAPPING_NODE)
        for (const yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top; ++p) {
            const yaml_node_t *key = yaml_document_get_node(&doc, p->key);
            if (is_include_key(key)) include_key = key;
        }
    if (!include_key) {
        L->doc = doc;
        L->have_doc = true;
        L->root = root ? 1 : 0;
        return true;
    }
    bool ok;
    if (L->from_string) {
        ok = report(L, 0, (int)include_key->start_mark.line + 1, (int)include_key->start_mark.column + 1,
                    "include is not available for a config given as a string (expected a config file: includes "
                    "are relative to its folder)");
    } else {
        ok = yaml_document_initialize(&L->doc, NULL, NULL, NULL, 1, 1) || out_of_memory(L);
        L->have_doc = ok;
        ok = ok && (L->root = resolve(L, 0, &doc, 0)) != 0;
    }
    yaml_document_delete(&doc);
    return ok;
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
    ok = ok && load_document(&L, text, length);
    for (int k = 0; ok && k < L.n_overrides; ++k) ok = apply_override(&L, k);
    ok = ok && load_sections(&L, out) && emit_effective(&L, out);
    if (ok) {
        /* The file names move to the config: the locations point at them. */
        out->files = malloc((size_t)L.n_sources * sizeof *out->files);
        ok = out->files != NULL || error_set(err, "%s: out of memory", L.file);
        for (int i = 0; ok && i < L.n_sources; ++i) {
            out->files[i] = L.sources[i].path;
            L.sources[i].path = NULL;
        }
        if (ok) out->n_files = L.n_sources;
        ok = ok && keep_params(&L, out);
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
    if (!read_text(path, &text, &length, &st, &why)) return error_set(err, "%s: %s", path, why);
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
    for (int i = 0; i < c->n_params; ++i) free(c->params[i].name);
    free(c->params);
    memset(c, 0, sizeof *c);
}

/* config_node.c: typed getters over the nodes of a config's YAML
   document (numbers and expressions, integers, booleans, strings, enums,
   vectors, colours, key checks) and the reports that name the
   file:line:column of a node, or the --set override that made it. */
#include "config/config_internal.h"

#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Appends str, after sep unless l is empty. */
void config_line_append(struct config_line *l, const char *sep, const char *str)
{
    if (l->n >= sizeof l->s - 1) return;
    int k = snprintf(l->s + l->n, sizeof l->s - l->n, "%s%s", l->n ? sep : "", str);
    if (k > 0) l->n += (size_t)k;
    if (l->n > sizeof l->s - 1) l->n = sizeof l->s - 1;
}

void config_line_add(struct config_line *l, const char *str)
{
    config_line_append(l, ", ", str);
}

static const char *join_names(struct config_line *l, const char *const *names, int n)
{
    l->n = 0;
    l->s[0] = '\0';
    for (int i = 0; i < n; ++i) config_line_add(l, names[i]);
    return l->s;
}

bool config_is_null(const yaml_node_t *n)
{
    if (n->type != YAML_SCALAR_NODE || n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE) return false;
    const char *s = config_text(n);
    return !strcmp(s, "") || !strcmp(s, "~") || !strcmp(s, "null") || !strcmp(s, "Null") || !strcmp(s, "NULL");
}

const char *config_describe_node(const yaml_node_t *n, char *buf, size_t size)
{
    switch (n->type) {
    case YAML_MAPPING_NODE:
        return "a mapping";
    case YAML_SEQUENCE_NODE:
        return "a sequence";
    case YAML_SCALAR_NODE:
        if (config_is_null(n)) return "null";
        snprintf(buf, size, "\"%.40s%s\"", config_text(n), strlen(config_text(n)) > 40 ? "..." : "");
        return buf;
    case YAML_NO_NODE:
        break;
    }
    return "nothing";
}

int config_override_of(const struct loader *L, const yaml_node_t *n)
{
    int id = (int)(n - L->doc.nodes.start) + 1;
    for (int i = L->n_marks - 1; i >= 0; --i)
        if (L->marks[i].node == id) return L->marks[i].override;
    return -1;
}

int config_source_of(const struct loader *L, const yaml_node_t *n)
{
    if (!L->node_source) return 0;
    int id = (int)(n - L->doc.nodes.start) + 1;
    return id >= 1 && id <= L->n_node_source ? L->node_source[id - 1] : 0;
}

bool config_report(struct loader *L, int s, int line, int column, const char *fmt, ...)
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

bool config_fail(struct loader *L, const yaml_node_t *n, const char *fmt, ...)
{
    char msg[ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    int k = config_override_of(L, n);
    if (k >= 0) return error_set(L->err, "--set %s=%s: %s", L->overrides[k].path, L->overrides[k].value, msg);
    return config_report(L, config_source_of(L, n), (int)n->start_mark.line + 1, (int)n->start_mark.column + 1, "%s",
                         msg);
}

/* Where the node is, for items that keep their location. */
struct source_loc config_loc_of(const struct loader *L, const yaml_node_t *n)
{
    struct source_loc loc = { (int)n->start_mark.line + 1, (int)n->start_mark.column + 1,
                              L->sources[config_source_of(L, n)].path };
    return loc;
}

bool config_expect_type(struct loader *L, const yaml_node_t *n, yaml_node_type_t type, const char *expected)
{
    char buf[64];
    if (n->type == type && !config_is_null(n)) return true;
    return config_fail(L, n, "expected %s, got %s", expected, config_describe_node(n, buf, sizeof buf));
}

/* Every key a scalar, listed in allowed[] (unless allowed is NULL), and
   unique: pbrt-v4's rule that any key nothing reads is an error. */
bool config_check_keys(struct loader *L, const yaml_node_t *map, const char *where, const char *const *allowed,
                       int n_allowed)
{
    yaml_node_pair_t *pairs = map->data.mapping.pairs.start;
    int n = config_map_count(map);
    for (int i = 0; i < n; ++i) {
        const yaml_node_t *key = config_node(L, pairs[i].key);
        char buf[64];
        if (key->type != YAML_SCALAR_NODE)
            return config_fail(L, key, "expected a string key in %s, got %s", where,
                               config_describe_node(key, buf, sizeof buf));
        const char *name = config_text(key);
        if (allowed) {
            int j = 0;
            while (j < n_allowed && strcmp(name, allowed[j]) != 0) ++j;
            struct config_line list;
            if (j == n_allowed)
                return config_fail(L, key, "unknown key \"%.64s\" in %s (expected %s)", name, where,
                                   join_names(&list, allowed, n_allowed));
        }
        for (int j = 0; j < i; ++j) {
            const yaml_node_t *other = config_node(L, pairs[j].key);
            if (other->type == YAML_SCALAR_NODE && strcmp(config_text(other), name) == 0)
                return config_fail(L, key, "duplicate key \"%.64s\" in %s (first at line %d, column %d)", name, where,
                                   (int)other->start_mark.line + 1, (int)other->start_mark.column + 1);
        }
    }
    return true;
}

/* The value of `key` in the mapping, or NULL. */
yaml_node_t *config_map_get(struct loader *L, const yaml_node_t *map, const char *key)
{
    yaml_node_pair_t *pairs = map->data.mapping.pairs.start;
    for (int i = 0; i < config_map_count(map); ++i) {
        const yaml_node_t *k = config_node(L, pairs[i].key);
        if (k->type == YAML_SCALAR_NODE && strcmp(config_text(k), key) == 0) return config_node(L, pairs[i].value);
    }
    return NULL;
}

/* A required key; reported at the enclosing mapping when missing. */
yaml_node_t *config_need(struct loader *L, const yaml_node_t *map, const char *key, const char *where)
{
    yaml_node_t *v = config_map_get(L, map, key);
    if (!v) config_fail(L, map, "missing key \"%s\" in %s", key, where);
    return v;
}

/* An optional mapping or sequence: NULL when absent or null. */
bool config_get_optional(struct loader *L, const yaml_node_t *map, const char *key, yaml_node_type_t type,
                         yaml_node_t **out)
{
    *out = config_map_get(L, map, key);
    if (*out && config_is_null(*out)) *out = NULL;
    if (!*out) return true;
    return config_expect_type(L, *out, type, type == YAML_MAPPING_NODE ? "a mapping" : "a sequence");
}

/* YAML 1.2 core-schema floats and decimal integers. The non-finite spellings
   are recognised too, so that they are rejected by name. */
bool config_parse_literal(const char *s, double *out)
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
const char *config_value_text(const yaml_node_t *n, double v, char *buf, size_t size)
{
    if (n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE && config_text(n)[0] != '=' && strlen(config_text(n)) < 40)
        return config_text(n);
    snprintf(buf, size, "%.10g", v);
    return buf;
}

/* A finite number: a plain YAML number or "=expression" over the params.
   `expected` describes what the caller wants, for messages. */
bool config_get_number(struct loader *L, const yaml_node_t *n, const char *expected, double *out)
{
    char buf[64];
    if (n->type != YAML_SCALAR_NODE || config_is_null(n))
        return config_fail(L, n, "expected %s, got %s", expected, config_describe_node(n, buf, sizeof buf));
    const char *s = config_text(n);
    if (s[0] == '=') {
        struct error e;
        if (!expr_eval(s + 1, L->params, L->n_params, out, &e))
            return config_fail(L, n, "expression \"%.100s\": %s", s, e.message);
        return true;
    }
    if (n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE || !config_parse_literal(s, out))
        return config_fail(L, n, "expected %s, got %s", expected, config_describe_node(n, buf, sizeof buf));
    if (!isfinite(*out)) return config_fail(L, n, "expected a finite number, got %.40s", s);
    return true;
}

static void describe_range(char *buf, size_t size, double lo, bool lo_open, double hi, bool hi_open)
{
    if (isinf(lo) && isinf(hi)) snprintf(buf, size, "a number");
    else if (isinf(hi)) snprintf(buf, size, "a number %s %g", lo_open ? ">" : ">=", lo);
    else snprintf(buf, size, "a number in %c%g, %g%c", lo_open ? '(' : '[', lo, hi, hi_open ? ')' : ']');
}

bool config_get_number_in(struct loader *L, const yaml_node_t *n, double lo, bool lo_open, double hi, bool hi_open,
                          double *out)
{
    char desc[96], buf[64];
    describe_range(desc, sizeof desc, lo, lo_open, hi, hi_open);
    if (!config_get_number(L, n, desc, out)) return false;
    double v = *out;
    if ((lo_open ? v <= lo : v < lo) || (hi_open ? v >= hi : v > hi))
        return config_fail(L, n, "expected %s, got %s", desc, config_value_text(n, v, buf, sizeof buf));
    return true;
}

bool config_get_int(struct loader *L, const yaml_node_t *n, int lo, int hi, int *out)
{
    char desc[96], buf[64];
    if (lo == 0 && hi == INT_MAX) snprintf(desc, sizeof desc, "a non-negative integer");
    else if (lo == 1 && hi == INT_MAX) snprintf(desc, sizeof desc, "a positive integer");
    else snprintf(desc, sizeof desc, "an integer in [%d, %d]", lo, hi);
    double v;
    if (!config_get_number(L, n, desc, &v)) return false;
    if (v != floor(v) || v < lo || v > hi)
        return config_fail(L, n, "expected %s, got %s", desc, config_value_text(n, v, buf, sizeof buf));
    *out = (int)v;
    return true;
}

bool config_get_bool(struct loader *L, const yaml_node_t *n, bool *out)
{
    char buf[64];
    if (n->type == YAML_SCALAR_NODE && n->data.scalar.style == YAML_PLAIN_SCALAR_STYLE) {
        const char *s = config_text(n);
        bool yes = !strcmp(s, "true") || !strcmp(s, "True") || !strcmp(s, "TRUE");
        bool no = !strcmp(s, "false") || !strcmp(s, "False") || !strcmp(s, "FALSE");
        if (yes || no) {
            *out = yes;
            return true;
        }
    }
    return config_fail(L, n, "expected true or false, got %s", config_describe_node(n, buf, sizeof buf));
}

/* A non-empty string that fits in `size` bytes with its terminator. */
bool config_get_string(struct loader *L, const yaml_node_t *n, char *out, size_t size)
{
    if (!config_expect_type(L, n, YAML_SCALAR_NODE, "a string")) return false;
    const char *s = config_text(n);
    size_t len = strlen(s);
    if (len != n->data.scalar.length) return config_fail(L, n, "string contains a NUL character");
    if (len >= size) return config_fail(L, n, "string too long (%zu bytes, expected at most %zu)", len, size - 1);
    memcpy(out, s, len + 1);
    return true;
}

bool config_get_enum(struct loader *L, const yaml_node_t *n, const char *what, const char *const *names, int count,
                     int *out)
{
    if (!config_expect_type(L, n, YAML_SCALAR_NODE, "a string")) return false;
    for (int i = 0; i < count; ++i)
        if (strcmp(config_text(n), names[i]) == 0) {
            *out = i;
            return true;
        }
    struct config_line list;
    return config_fail(L, n, "unknown %s \"%.64s\" (expected one of: %s)", what, config_text(n),
                       join_names(&list, names, count));
}

/* A sequence of three numbers in a range: points, colours. */
static bool get_triple(struct loader *L, const yaml_node_t *n, const char *form, double lo, bool lo_open, double hi,
                       bool hi_open, double out[3])
{
    char buf[64];
    if (n->type != YAML_SEQUENCE_NODE)
        return config_fail(L, n, "expected %s (3 numbers), got %s", form, config_describe_node(n, buf, sizeof buf));
    if (config_seq_count(n) != 3)
        return config_fail(L, n, "expected %s (3 numbers), got %d items", form, config_seq_count(n));
    for (int i = 0; i < 3; ++i)
        if (!config_get_number_in(L, config_seq_item(L, n, i), lo, lo_open, hi, hi_open, &out[i])) return false;
    return true;
}

bool config_get_vec3(struct loader *L, const yaml_node_t *n, struct vec3 *out)
{
    double v[3];
    if (!get_triple(L, n, "[x, y, z]", -INFINITY, false, INFINITY, false, v)) return false;
    *out = vec3_make(v[0], v[1], v[2]);
    return true;
}

bool config_get_rgb(struct loader *L, const yaml_node_t *n, double lo, double hi, struct rgb *out)
{
    double v[3];
    if (!get_triple(L, n, "[r, g, b]", lo, false, hi, false, v)) return false;
    *out = rgb_make(v[0], v[1], v[2]);
    return true;
}

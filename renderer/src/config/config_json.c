/* config_json.c: part of the config module (one of the files allowed to
   include <yaml.h>): the effective configuration as JSON, for
   `render --print-config --format json`. It converts the effective YAML
   text itself rather than struct config, so that the JSON has exactly the
   keys and values of the config.yaml a render writes. */
#include "config/config.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <yaml.h>

#include "base/json_write.h"

/* The effective YAML nests four levels; anything deeper is not one. */
#define JSON_DEPTH_MAX 64

static bool text_is(const char *s, const char *const *spellings, int n)
{
    for (int i = 0; i < n; ++i)
        if (!strcmp(s, spellings[i])) return true;
    return false;
}

/* True for the JSON number grammar: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)? */
static bool is_json_number(const char *s)
{
    if (*s == '-') ++s;
    if (*s == '0') ++s;
    else if (*s >= '1' && *s <= '9')
        while (*s >= '0' && *s <= '9') ++s;
    else return false;
    if (*s == '.') {
        if (!(*++s >= '0' && *s <= '9')) return false;
        while (*s >= '0' && *s <= '9') ++s;
    }
    if (*s == 'e' || *s == 'E') {
        ++s;
        if (*s == '+' || *s == '-') ++s;
        if (!(*s >= '0' && *s <= '9')) return false;
        while (*s >= '0' && *s <= '9') ++s;
    }
    return *s == '\0';
}

/* A plain scalar that reads as a finite decimal number (the loader's
   numbers: no hex, no inf or nan, which strtod would also take). */
static bool plain_number(const char *s, double *v)
{
    if (!*s || strspn(s, "0123456789+-.eE") != strlen(s)) return false;
    char *end;
    *v = strtod(s, &end);
    return *end == '\0' && isfinite(*v);
}

static void write_scalar(const yaml_node_t *n, FILE *out)
{
    const char *s = (const char *)n->data.scalar.value;
    size_t len = n->data.scalar.length;
    if (n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE) {
        json_write_string_n(out, s, len);
        return;
    }
    /* The YAML 1.2 core schema's spellings. */
    static const char *const trues[] = { "true", "True", "TRUE" }, *const falses[] = { "false", "False", "FALSE" },
                             *const nulls[] = { "null", "Null", "NULL", "~", "" };
    double v;
    if (text_is(s, trues, 3)) fputs("true", out);
    else if (text_is(s, falses, 3)) fputs("false", out);
    else if (text_is(s, nulls, 5)) fputs("null", out);
    else if (plain_number(s, &v) && is_json_number(s)) fputs(s, out);
    else if (plain_number(s, &v)) json_write_number(out, v);
    else json_write_string_n(out, s, len);
}

static bool write_node(yaml_document_t *doc, int id, int depth, FILE *out, struct error *err)
{
    yaml_node_t *n = yaml_document_get_node(doc, id);
    if (!n) return error_set(err, "effective configuration: missing node %d", id);
    if (depth > JSON_DEPTH_MAX)
        return error_set(err, "effective configuration: nested deeper than %d levels at line %d", JSON_DEPTH_MAX,
                         (int)n->start_mark.line + 1);
    switch (n->type) {
    case YAML_NO_NODE:
        fputs("null", out);
        return true;
    case YAML_SCALAR_NODE:
        write_scalar(n, out);
        return true;
    case YAML_SEQUENCE_NODE:
        fputc('[', out);
        for (yaml_node_item_t *it = n->data.sequence.items.start; it < n->data.sequence.items.top; ++it) {
            if (it != n->data.sequence.items.start) fputc(',', out);
            if (!write_node(doc, *it, depth + 1, out, err)) return false;
        }
        fputc(']', out);
        return true;
    case YAML_MAPPING_NODE:
        fputc('{', out);
        for (yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; ++p) {
            yaml_node_t *k = yaml_document_get_node(doc, p->key);
            if (!k || k->type != YAML_SCALAR_NODE)
                return error_set(err, "effective configuration: a key that is not a scalar at line %d",
                                 (int)n->start_mark.line + 1);
            if (p != n->data.mapping.pairs.start) fputc(',', out);
            json_write_string_n(out, (const char *)k->data.scalar.value, k->data.scalar.length);
            fputc(':', out);
            if (!write_node(doc, p->value, depth + 1, out, err)) return false;
        }
        fputc('}', out);
        return true;
    }
    return error_set(err, "effective configuration: unknown node type");
}

bool config_write_json(const struct config *c, FILE *out, struct error *err)
{
    if (!c->effective_yaml) return error_set(err, "%s: no effective configuration", c->path);
    yaml_parser_t parser;
    yaml_document_t doc;
    if (!yaml_parser_initialize(&parser)) return error_set(err, "%s: out of memory", c->path);
    yaml_parser_set_input_string(&parser, (const unsigned char *)c->effective_yaml, strlen(c->effective_yaml));
    bool ok = yaml_parser_load(&parser, &doc);
    if (!ok) {
        error_set(err, "%s: effective configuration: %s at line %d", c->path,
                  parser.problem ? parser.problem : "cannot parse", (int)parser.problem_mark.line + 1);
        yaml_parser_delete(&parser);
        return false;
    }
    yaml_parser_delete(&parser);
    yaml_node_t *root = yaml_document_get_root_node(&doc);
    if (root) {
        struct error why;
        ok = write_node(&doc, 1, 0, out, &why) || error_set(err, "%s: %s", c->path, why.message);
    } else {
        fputs("null", out);
    }
    yaml_document_delete(&doc);
    return ok;
}

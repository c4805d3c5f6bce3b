/* config_override.c: `--set key.path=value` overrides, applied to the
   (merged) YAML document before the sections are read, each new node
   marked with its override so that errors in it name the override. */
#include "config/config_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Optional mappings that --set creates when they are missing, so that
   `--set render.aov.region=true` works on a config without `aov:`. */
static const char *const override_mapping_paths[] = { "render.snapshots", "render.aov" };

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
bool config_apply_override(struct loader *L, int k)
{
    const struct config_override *o = &L->overrides[k];
    if (!o->path || !o->value || !o->path[0]) return error_set(L->err, "--set: expected key.path=value");
    char path[CONFIG_PATH_MAX], where[CONFIG_PATH_MAX] = "the top level";
    if (strlen(o->path) >= sizeof path) return error_set(L->err, "--set %.64s...: path too long", o->path);
    memcpy(path, o->path, strlen(o->path) + 1);
    if (!L->root) return error_set(L->err, "--set %s: the document is empty", o->path);
    /* Includes are merged when the file is read, before any override: an
       override of `include` would be ignored, so it is refused. */
    if (!strcmp(o->path, "include") || !strncmp(o->path, "include.", 8))
        return error_set(L->err, "--set %s: includes are read with the file; an override cannot add one", o->path);
    int cur = L->root;
    char *comp = path;
    for (;;) {
        char *dot = strchr(comp, '.');
        bool last = dot == NULL;
        if (dot) *dot = '\0';
        if (!comp[0]) return error_set(L->err, "--set %s: empty key in the path", o->path);
        yaml_node_t *node = config_node(L, cur);
        int *slot = NULL;
        if (node->type == YAML_MAPPING_NODE) {
            for (int i = 0; i < config_map_count(node) && !slot; ++i) {
                const yaml_node_t *key = config_node(L, node->data.mapping.pairs.start[i].key);
                if (key->type == YAML_SCALAR_NODE && strcmp(config_text(key), comp) == 0)
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
                int value =
                    key ? yaml_document_add_scalar(&L->doc, NULL, (yaml_char_t *)o->value, -1, YAML_PLAIN_SCALAR_STYLE)
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
            if (index >= config_seq_count(node))
                return error_set(L->err, "--set %s: index %d out of range in %s (expected 0 to %d)", o->path, index,
                                 where, config_seq_count(node) - 1);
            slot = &node->data.sequence.items.start[index];
        } else {
            return error_set(L->err, "--set %s: %s is a scalar (expected a mapping or a sequence before \"%s\")",
                             o->path, where, comp);
        }
        const yaml_node_t *target = config_node(L, *slot);
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

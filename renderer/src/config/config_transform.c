/* config_transform.c: the `transform:` key of shapes, lights and portals:
   a list of operations (translate, scale, rotate, matrix) applied to the
   points in order, composed into one affine transform (transform.h). */
#include "config/config_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *const transform_ops[] = { "translate", "scale", "rotate", "matrix" };
static const char *const rotate_keys[] = { "axis", "angle" };

static bool fail_singular(struct loader *L, const yaml_node_t *n, const char *what)
{
    return config_fail(L, n, "%s is singular (expected an invertible transform: it would flatten the geometry)", what);
}

static bool get_scale(struct loader *L, const yaml_node_t *n, struct transform *out)
{
    struct vec3 s;
    if (n->type == YAML_SEQUENCE_NODE) {
        if (!config_get_vec3(L, n, &s)) return false;
    } else {
        double k;
        if (!config_get_number(L, n, "a scale factor or [x, y, z]", &k)) return false;
        s = vec3_make(k, k, k);
    }
    *out = transform_scale(s);
    return !transform_is_singular(out) || fail_singular(L, n, "scale");
}

static bool get_rotate(struct loader *L, const yaml_node_t *n, struct transform *out)
{
    yaml_node_t *axis, *angle;
    struct vec3 k;
    double deg;
    if (!config_expect_type(L, n, YAML_MAPPING_NODE, "a mapping {axis: [x, y, z], angle: degrees}") ||
        !config_check_keys(L, n, "rotate", rotate_keys, COUNT(rotate_keys)) ||
        !(axis = config_need(L, n, "axis", "rotate")) || !config_get_vec3(L, axis, &k) ||
        !(angle = config_need(L, n, "angle", "rotate")) || !config_get_number(L, angle, "an angle in degrees", &deg))
        return false;
    if (!transform_rotate(k, deg, out)) return config_fail(L, axis, "rotation axis is zero (expected a direction)");
    return true;
}

static bool get_matrix(struct loader *L, const yaml_node_t *n, struct transform *out)
{
    char buf[64];
    if (n->type != YAML_SEQUENCE_NODE)
        return config_fail(L, n, "expected a matrix (16 numbers, row-major), got %s",
                           config_describe_node(n, buf, sizeof buf));
    if (config_seq_count(n) != 16)
        return config_fail(L, n, "expected a matrix (16 numbers, row-major), got %d items", config_seq_count(n));
    double rows[16];
    for (int i = 0; i < 16; ++i)
        if (!config_get_number(L, config_seq_item(L, n, i), "a number", &rows[i])) return false;
    if (!transform_from_rows(rows, out))
        return config_fail(L, n, "matrix is not affine (expected the last row to be 0, 0, 0, 1), got [%g, %g, %g, %g]",
                           rows[12], rows[13], rows[14], rows[15]);
    return !transform_is_singular(out) || fail_singular(L, n, "matrix");
}

/* One item of the list: a mapping with exactly one operation. */
static bool get_op(struct loader *L, const yaml_node_t *item, struct transform *out)
{
    char buf[64];
    if (item->type != YAML_MAPPING_NODE || config_map_count(item) != 1)
        return config_fail(L, item,
                           "expected one operation per item ({translate: ...}, {scale: ...}, {rotate: ...} or "
                           "{matrix: ...}), got %s",
                           item->type == YAML_MAPPING_NODE && config_map_count(item) > 1
                               ? "several keys"
                               : config_describe_node(item, buf, sizeof buf));
    yaml_node_t *key = config_node(L, item->data.mapping.pairs.start[0].key);
    yaml_node_t *value = config_node(L, item->data.mapping.pairs.start[0].value);
    int op;
    if (!config_get_enum(L, key, "transform operation", transform_ops, COUNT(transform_ops), &op)) return false;
    switch (op) {
    case 0: {
        struct vec3 t;
        if (!config_get_vec3(L, value, &t)) return false;
        *out = transform_translate(t);
        return true;
    }
    case 1:
        return get_scale(L, value, out);
    case 2:
        return get_rotate(L, value, out);
    case 3:
        return get_matrix(L, value, out);
    }
    return false;
}

bool config_get_transform(struct loader *L, const yaml_node_t *map, struct transform *out, bool *present)
{
    yaml_node_t *seq;
    *present = false;
    *out = transform_identity();
    if (!config_get_optional(L, map, "transform", YAML_SEQUENCE_NODE, &seq)) return false;
    if (!seq || config_seq_count(seq) == 0) return true;
    /* The first operation as it is, so that one {matrix: ...} (what the
       effective YAML writes) reads back bit for bit. */
    for (int i = 0; i < config_seq_count(seq); ++i) {
        struct transform op;
        if (!get_op(L, config_seq_item(L, seq, i), &op)) return false;
        *out = i == 0 ? op : transform_then(out, &op);
    }
    if (transform_is_singular(out)) return fail_singular(L, seq, "transform");
    *present = true;
    return true;
}

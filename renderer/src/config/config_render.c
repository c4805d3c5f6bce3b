/* config_render.c: the section loader of how the image is rendered:
   the render mapping (integrator, strategy, MIS, sampler, limits, snapshot
   schedule, seed, threads, output, AOV) and its defaults. */
#include "config/config_internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const render_keys[] = { "integrator", "strategy", "mis", "portal_weight", "defensive", "max_depth",
                                           "rr_depth",   "sampler",  "spp", "time",          "snapshots", "seed",
                                           "threads",    "output",   "aov", "resumable" };
const char *const config_snapshot_keys[CONFIG_SNAPSHOT_KEY_COUNT] = { "every",     "doubling",     "times",
                                                                      "every_spp", "doubling_spp", "spp" };
/* What each key counts in: render time (config_get_number_in) or passes (config_get_int, get_spps). */
const char *const config_snapshot_units[CONFIG_SNAPSHOT_KEY_COUNT] = { "s", "s", "s", "spp", "spp", "spp" };
static const char *const aov_keys[] = { "region" };

#define THREADS_MAX 256

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
    if (!config_check_keys(L, map, "render.snapshots", config_snapshot_keys, CONFIG_SNAPSHOT_KEY_COUNT)) return false;
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

bool config_load_render(struct loader *L, const yaml_node_t *root, struct config *c)
{
    yaml_node_t *map = config_need(L, root, "render", "the top level"), *n;
    struct render_desc *r = &c->render;
    int e;
    r->integrator = INTEGRATOR_DIRECT;
    r->strategy = STRATEGY_LIGHT;
    r->mis = MIS_POWER;
    r->portal_weight = PORTAL_WEIGHT_IRRADIANCE;
    r->sampler = SAMPLER_INDEPENDENT;
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
        if (!config_get_enum(L, n, "portal_weight", portal_weight_names, PORTAL_WEIGHT_COUNT, &e)) return false;
        r->portal_weight = (enum portal_weight_kind)e;
    }
    if ((n = config_map_get(L, map, "sampler"))) {
        if (!config_get_enum(L, n, "sampler", sampler_names, SAMPLER_COUNT, &e)) return false;
        r->sampler = (enum sampler_kind)e;
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

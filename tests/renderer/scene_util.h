/* scene_util.h: loading a config and building its scene in a test, with
   the loader's message on stderr on failure. */
#ifndef SCENE_UTIL_H
#define SCENE_UTIL_H

#include <stdio.h>

#include "config/config.h"
#include "scene/scene.h"

/* The scene of a loaded config; on failure the config is freed. */
static inline bool test_scene_build(struct config *cfg, struct scene *sc)
{
    struct error err;
    if (!scene_create(cfg, sc, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        config_free(cfg);
        return false;
    }
    return true;
}

static inline bool test_scene_load(const char *path, const struct config_override *ov, int n_ov, struct config *cfg,
                                   struct scene *sc)
{
    struct error err;
    if (!config_load(path, ov, n_ov, cfg, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        return false;
    }
    return test_scene_build(cfg, sc);
}

/* test_scene_load for a config given as text (name: what messages call it). */
static inline bool test_scene_load_string(const char *text, size_t length, const char *name, struct config *cfg,
                                          struct scene *sc)
{
    struct error err;
    if (!config_load_string(text, length, name, NULL, 0, cfg, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        return false;
    }
    return test_scene_build(cfg, sc);
}

/* True when anything blocks the segment from `from` to `to` (scene_occluded
   along it). Both ends are expected to be clear of the surfaces they lie
   on already: use scene_offset_origin at each end (towards the other end). */
static inline bool test_segment_occluded(const struct scene *s, struct vec3 from, struct vec3 to)
{
    struct vec3 d = vec3_sub(to, from);
    double len = vec3_length(d);
    if (!(len > 0.0)) return false;
    return scene_occluded(s, from, vec3_scale(d, 1.0 / len), len);
}

#endif

/* scene_util.h: loading a config and building its scene in a test, with
   the loader's message on stderr on failure. */
#ifndef SCENE_UTIL_H
#define SCENE_UTIL_H

#include <stdio.h>

#include "config.h"
#include "scene.h"

static inline bool test_scene_load(const char *path, const struct config_override *ov, int n_ov, struct config *cfg,
                                   struct scene *sc)
{
    struct error err;
    if (!config_load(path, ov, n_ov, cfg, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        return false;
    }
    if (!scene_create(cfg, sc, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        config_free(cfg);
        return false;
    }
    return true;
}

#endif

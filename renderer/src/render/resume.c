#include "render/resume.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

bool resume_override_allowed(const char *path)
{
    static const char *const exact[] = { "render.spp", "render.time", "render.threads", "render.resumable" };
    for (size_t i = 0; i < sizeof exact / sizeof exact[0]; ++i)
        if (!strcmp(path, exact[i])) return true;
    return !strncmp(path, "render.snapshots.", strlen("render.snapshots."));
}

/* The state against the config it is to continue. */
static bool check_match(const char *state_path, const char *config_path, const struct config *cfg,
                        const struct film_state *st, struct error *err)
{
    const char *why = "config.yaml was edited, or the state is from another render";
    if (st->film.width != cfg->width || st->film.height != cfg->height)
        return error_set(err, "%s: the state is %dx%d but %s is %dx%d (%s)", state_path, st->film.width,
                         st->film.height, config_path, cfg->width, cfg->height, why);
    if (st->seed != cfg->render.seed)
        return error_set(err, "%s: the state has seed %" PRIu64 " but %s has seed %" PRIu64 " (%s)", state_path,
                         st->seed, config_path, cfg->render.seed, why);
    if (st->sampler != cfg->render.sampler)
        return error_set(err, "%s: the state was rendered with sampler %s but %s has sampler %s (%s)", state_path,
                         sampler_names[st->sampler], config_path, sampler_names[cfg->render.sampler], why);
    if (st->image_hash != cfg->image_hash)
        return error_set(err,
                         "%s: the state was rendered with another image configuration than %s (image hash "
                         "%016" PRIx64 ", config %016" PRIx64 ": %s)",
                         state_path, config_path, st->image_hash, cfg->image_hash, why);
    return true;
}

/* The limits are totals: each set one must leave something to render. */
static bool check_limits(const char *dir, const struct config *cfg, const struct film_state *st, struct error *err)
{
    const struct render_desc *rd = &cfg->render;
    if (rd->spp > 0 && rd->spp <= st->film.passes)
        return error_set(err,
                         "--resume %s: render.spp %d is not above the %" PRId64 " passes already done (the limit is "
                         "the total: give a larger --spp)",
                         dir, rd->spp, st->film.passes);
    if (rd->time_s > 0.0 && rd->time_s <= st->render_time_s)
        return error_set(err,
                         "--resume %s: render.time %g s is not above the %.3f s already rendered (the limit is the "
                         "total: give a larger --time, or --time 0)",
                         dir, rd->time_s, st->render_time_s);
    return true;
}

bool resume_load(const char *dir, const struct config_override *overrides, int n_overrides, struct config *cfg,
                 struct film_state *st, struct error *err)
{
    memset(cfg, 0, sizeof *cfg);
    memset(st, 0, sizeof *st);
    struct stat sb;
    if (stat(dir, &sb) != 0) return error_set(err, "--resume %s: %s", dir, strerror(errno));
    if (!S_ISDIR(sb.st_mode)) return error_set(err, "--resume %s: not a folder", dir);
    size_t len = strlen(dir) + 32;
    char *config_path = malloc(len), *state_path = malloc(len);
    struct config_override *ov = malloc(((size_t)n_overrides + 1) * sizeof *ov);
    bool ok = (config_path && state_path && ov) || error_set(err, "--resume %s: out of memory", dir);
    if (ok) {
        snprintf(config_path, len, "%s/config.yaml", dir);
        snprintf(state_path, len, "%s/final.state", dir);
        if (stat(config_path, &sb) != 0)
            ok = error_set(err, "--resume %s: %s: %s (expected the output folder of a render)", dir, config_path,
                           strerror(errno));
    }
    if (ok) {
        for (int i = 0; i < n_overrides; ++i) ov[i] = overrides[i];
        ov[n_overrides].path = "render.output";
        ov[n_overrides].value = dir;
        ok = config_load(config_path, ov, n_overrides + 1, cfg, err);
    }
    if (ok && stat(state_path, &sb) != 0 && errno == ENOENT)
        ok = error_set(err,
                       "--resume %s: %s is missing: only a render made with render.resumable: true (--resumable) "
                       "can be resumed",
                       dir, state_path);
    ok = ok && film_state_read(state_path, st, err) && check_match(state_path, config_path, cfg, st, err) &&
         check_limits(dir, cfg, st, err);
    if (!ok) {
        config_free(cfg);
        film_state_free(st);
    }
    free(config_path);
    free(state_path);
    free(ov);
    return ok;
}

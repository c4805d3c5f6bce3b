/* resume.h: `render --resume DIR`: the effective config and the film state
   an earlier render left in DIR, checked to belong together, and which
   settings a continued render may change. Reads only: nothing in DIR is
   touched here. */
#ifndef RESUME_H
#define RESUME_H

#include <stdbool.h>

#include "config/config.h"
#include "base/error.h"
#include "render/film_state.h"

/* The keys a resumed render may override: those that say how long, how
   often, on how many threads (render.spp, render.time, render.threads,
   render.snapshots.*, render.resumable). Everything else would change the
   image of a pass. */
bool resume_override_allowed(const char *path);
#define RESUME_ALLOWED_KEYS "render.spp, render.time, render.threads, render.snapshots.* and render.resumable"

/* Loads DIR/config.yaml with the overrides (callers check them with
   resume_override_allowed first) and render.output = dir, then
   DIR/final.state, and checks that they belong together (size, seed,
   image hash) and that the limits (totals) leave passes to render. On
   failure cfg and st are left empty and err says what is missing or
   wrong and, where it helps, what to do. */
bool resume_load(const char *dir, const struct config_override *overrides, int n_overrides, struct config *cfg,
                 struct film_state *st, struct error *err);

#endif

/* render.h: the progressive render loop: worker threads render whole passes
   (one sample per pixel each), the main thread keeps render time, schedules
   snapshots, and a writer thread writes them off the render threads. */
#ifndef RENDER_H
#define RENDER_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "config.h"
#include "error.h"
#include "integrator.h"
#include "scene.h"

struct render_result {
    int64_t spp;                 /* completed passes */
    double time_s;               /* render time, snapshot I/O excluded */
    int snapshots;               /* timed snapshots written (final excluded) */
    bool interrupted;            /* stopped by SIGINT/SIGTERM */
    uint64_t nonfinite_samples;
    struct integrator_stats stats;
};

/* Installs SIGINT/SIGTERM handlers that ask a running render to stop after
   its current pass and write its final snapshot. */
void render_catch_signals(void);

/* Renders cfg (scene already built) into cfg->render.output, which must
   exist. JSON progress lines go to `json` (one object per line). False on a
   runtime failure (e.g. a snapshot could not be written). */
bool render_run(const struct config *cfg, const struct scene *scene, FILE *json, struct render_result *result,
                struct error *err);

#endif

/* render.h: the progressive render loop: worker threads render whole passes
   (one sample per pixel each), the main thread keeps render time and takes
   the snapshots that fall due (snapshot_schedule.h), a writer thread writes
   them off the render threads (snapshot_writer.h), and progress goes out as
   JSON lines (render_events.h). It reads no environment variable: the test
   hooks come in with the options. */
#ifndef RENDER_H
#define RENDER_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "config/config.h"
#include "base/error.h"
#include "render/film_state.h"
#include "sampling/integrator.h"
#include "sampling/integrator_stats.h"
#include "render/render_events.h"
#include "scene/scene.h"

/* Results are cumulative: a resumed render counts the passes, time,
   snapshots and rays of the runs before it. */
struct render_result {
    int64_t spp;      /* completed passes */
    double time_s;    /* render time, snapshot I/O excluded */
    int snapshots;    /* timed snapshots written (final excluded) */
    bool interrupted; /* stopped by SIGINT/SIGTERM */
    uint64_t nonfinite_samples;
    struct integrator_stats stats;
    struct render_timers timers; /* for the benchmarks: CPU and pause times */
};

/* Installs SIGINT/SIGTERM handlers that ask a running render to stop after
   its current pass and write its final snapshot. */
void render_catch_signals(void);

/* Test hooks, which main.c reads from the environment:
   PORTAL_LIGHTS_FAULT_NONFINITE=N turns about one sample in N into a NaN;
   PORTAL_LIGHTS_FAULT_BIAS=STRATEGY:FACTOR multiplies every sample's
   radiance by FACTOR when the render's strategy is STRATEGY (a
   deliberately biased estimator). All zero: no faults. */
struct render_faults {
    int64_t nonfinite_every; /* 0: off */
    bool bias;               /* PORTAL_LIGHTS_FAULT_BIAS is set */
    enum strategy_kind bias_strategy;
    double bias_factor; /* finite, >= 0 */
};

/* Parses the two hooks' values (NULL: the variable is unset); fails with a
   message naming the variable when the bias is malformed (an unknown
   strategy, a factor that is not a finite number >= 0). */
bool render_faults_parse(const char *nonfinite, const char *bias, struct render_faults *out, struct error *err);

/* What render_run renders, and how. */
struct render_options {
    const struct config *cfg;
    const struct scene *scene; /* built from cfg */
    /* NULL for a fresh render. Otherwise the render continues from that
       state: its film moves into the render (start->film is left empty;
       the caller still frees start), passes go on from start->film.passes,
       and time, counters and snapshot numbering continue from it; its size
       must be cfg's. */
    struct film_state *start;
    FILE *json;                  /* JSON event lines (render_events.h) */
    struct render_faults faults; /* test hooks; zeroed for none */
};

/* Renders opt->cfg into cfg->render.output, which must exist. With
   cfg->render.resumable, final.state is written (atomically, before
   final.exr is renamed into place); without it a final.state left by an
   earlier render is removed. False on a runtime failure (e.g. a snapshot
   could not be written); result holds what was done either way. */
bool render_run(const struct render_options *opt, struct render_result *result, struct error *err);

#endif

/* render_events.h: the JSON event lines a render writes (one object per
   line, the protocol the harness reads): `start`, one `snapshot` per timed
   snapshot, `final`. Owns their exact text, one function per event kind;
   each writes one whole line and flushes it. It must not decide when an
   event happens, nor read the film, the clocks or the threads: callers
   pass in what the line says. */
#ifndef RENDER_EVENTS_H
#define RENDER_EVENTS_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "config/config.h"
#include "render/film.h"
#include "sampling/integrator_stats.h"

/* The kinds of line, the value of their "event" field; `render --describe`
   lists them. */
enum render_event { RENDER_EVENT_START, RENDER_EVENT_SNAPSHOT, RENDER_EVENT_FINAL };
#define RENDER_EVENT_COUNT 3

/* "start", "snapshot", "final", indexed by enum render_event. */
extern const char *const render_event_names[RENDER_EVENT_COUNT];

/* What a render cost beyond its render time, for the benchmarks; the
   `final` line and a resumable state carry them. Cumulative over resumed
   runs, like every counter of a render. */
struct render_timers {
    double render_cpu_s;     /* CPU time the render threads spent in passes */
    double snapshot_cpu_s;   /* CPU time timed snapshots took (writer thread and copies) */
    double snapshot_pause_s; /* wall time the render threads were paused for snapshot copies */
};

/* {"event":"start","out":...,"width":..,"height":..,"strategy":..,
   "integrator":..,"seed":..,"config_hash":"16 hex digits",
   "renderer_version":..,"threads":..,"spp_target":..,"time_target_s":..,
   "resumed_from_spp":..} for a render of cfg on `threads` threads that
   starts after resumed_from_spp passes (0 for a fresh render). */
void render_event_start(FILE *f, const struct config *cfg, int threads, int64_t resumed_from_spp);

/* {"event":"snapshot","index":..,"path":..,"time_s":..,"spp":..,"rays":..,
   "nonfinite":..} once snapshot number `index` (from 1) is at `path`. */
void render_event_snapshot(FILE *f, int index, const char *path, const struct snapshot_info *info);

/* {"event":"final","path":..,"time_s":..,"spp":..,"rays":..,"nonfinite":..,
   "interrupted":..,"shadow_rays":..,"shadow_blocked":..,"light_samples":..,
   "light_missed":..,"render_cpu_s":..,"snapshot_cpu_s":..,
   "snapshot_pause_s":..} once the final image is at `path`. */
void render_event_final(FILE *f, const char *path, const struct snapshot_info *info, bool interrupted,
                        const struct integrator_stats *stats, const struct render_timers *timers);

#endif

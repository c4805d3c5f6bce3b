/* film_state.h: the exact state of a render between two passes (the film's
   double accumulators, passes, render time, counters), as a versioned,
   checksummed binary file, so that a later run can continue the render and
   end with the bits an uninterrupted one would have.

   Layout, version 2, every number in the host's byte order (little-endian
   on every target this renderer builds for; a file moved to a big-endian
   host fails at the version check):

     magic "PLFSTATE" (8 bytes), u32 version (2), u32 header bytes (124)
     header: i32 width, i32 height, i64 passes, f64 render_time_s,
             f64 render_cpu_s, f64 snapshot_cpu_s, f64 snapshot_pause_s,
             u64 rays, shadow_rays, shadow_blocked, light_samples,
             light_missed, u64 nonfinite_samples, i32 snapshots,
             u32 array count, u64 seed, u64 image_hash,
             u32 sampler (enum sampler_kind)
     arrays, each: u32 name length (1..63), the name (no terminator),
             u32 element type (1: f64, 2: u32), u64 element count,
             u64 byte count, the elements (row-major, per pixel)
     u64 FNV-1a 64 of every byte before it

   The arrays are "mean" (3 f64 per pixel), "m2" (3 f64 per pixel) and
   "count" (1 u32 per pixel), and "region_count" with the region AOV.
   Version 1 is version 2 without the sampler (120 header bytes); it reads
   as the independent sampler, the only one there was. */
#ifndef FILM_STATE_H
#define FILM_STATE_H

#include <stdbool.h>
#include <stdint.h>

#include "base/error.h"
#include "render/film.h"
#include "sampling/integrator_stats.h"
#include "base/kinds.h"

#define FILM_STATE_VERSION 2

struct film_state {
    struct film film;        /* accumulators and passes done */
    double render_time_s;    /* render clock so far (passes only) */
    double render_cpu_s;     /* render threads' CPU time so far */
    double snapshot_cpu_s;   /* CPU time timed snapshots took so far */
    double snapshot_pause_s; /* wall time paused for snapshot copies so far */
    struct integrator_stats stats;
    uint64_t nonfinite_samples; /* samples dropped so far */
    int snapshots;              /* timed snapshots written so far */
    uint64_t seed;
    uint64_t image_hash; /* config.image_hash of the render */
    /* render.sampler: the passes a resume adds draw the same sequence (the
       image hash covers it too; this says which one in a message). */
    enum sampler_kind sampler;
};

/* Writes s to "path.tmp-<pid>", fsyncs it and renames it to `path`, so a
   reader never sees a partial file; on failure the previous file at `path`
   is untouched, nothing is left at the temporary name, and err names the
   path and the cause. */
bool film_state_write(const char *path, const struct film_state *s, struct error *err);

/* Reads a state written by film_state_write; s->film is allocated here
   (free with film_state_free). Fails, with s left zeroed and err naming the
   path, on a missing or unreadable file, a wrong magic or version, a
   truncated or damaged file (checksum), an absurd size, or a state that
   lacks an array the film needs. Arrays the film does not know are
   skipped (their bytes still count for the checksum). */
bool film_state_read(const char *path, struct film_state *s, struct error *err);

/* Frees s->film; safe on a zeroed or freed state. */
void film_state_free(struct film_state *s);

#endif

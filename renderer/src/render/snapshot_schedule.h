/* snapshot_schedule.h: when a render's timed snapshots fall due, given the
   config's schedule (struct snapshot_schedule in config.h: every, doubling
   and listed times; every, doubling and listed sample counts), the render
   clock and the passes done. Owns the cursor through the schedule. Pure and
   deterministic: it must not read clocks, write files, or see the film or
   the threads; the render loop passes the time in and takes the snapshot. */
#ifndef SNAPSHOT_SCHEDULE_H
#define SNAPSHOT_SCHEDULE_H

#include <stdbool.h>
#include <stdint.h>

#include "config/config.h"

/* The next due point of each part of a schedule. A snapshot is taken at
   the first pass boundary at or after a due point. */
struct snapshot_cursor {
    const struct snapshot_schedule *schedule;
    double next_every_s;       /* render time; INFINITY when off */
    double next_doubling_s;    /* render time; INFINITY when off */
    int next_time;             /* index of the next of schedule->times_s */
    int next_spp_list;         /* index of the next of schedule->spps */
    int64_t next_every_spp;    /* passes; INT64_MAX when off */
    int64_t next_doubling_spp; /* passes; INT64_MAX when off */
};

/* A cursor at the start of a render (0 s, 0 spp). The schedule must
   outlive it; its lists ascend (config_load checks that). */
void snapshot_schedule_start(struct snapshot_cursor *c, const struct snapshot_schedule *schedule);

/* Whether a snapshot is due at a pass boundary after elapsed_s seconds of
   render time and spp passes: whether any part of the schedule has a due
   point at or before them. Advances every part past them, so that points
   passed together (coincident times, a slow pass, a time and a sample
   count at once) give one snapshot, and a point never gives two. */
bool snapshot_schedule_due(struct snapshot_cursor *c, double elapsed_s, int64_t spp);

/* The earliest render time (s) of a due point still ahead; INFINITY when
   no part of the schedule counts time (or all have passed). */
double snapshot_schedule_next_s(const struct snapshot_cursor *c);

/* The smallest sample count of a due point still ahead; INT64_MAX when no
   part of the schedule counts samples (or all have passed). */
int64_t snapshot_schedule_next_spp(const struct snapshot_cursor *c);

#endif

/* snapshot_schedule.c: the cursor through a snapshot schedule (see
   snapshot_schedule.h). */
#include "render/snapshot_schedule.h"

#include <math.h>

void snapshot_schedule_start(struct snapshot_cursor *c, const struct snapshot_schedule *schedule)
{
    c->schedule = schedule;
    c->next_every_s = schedule->every_s > 0.0 ? schedule->every_s : INFINITY;
    c->next_doubling_s = schedule->doubling_s > 0.0 ? schedule->doubling_s : INFINITY;
    c->next_time = 0;
    c->next_spp_list = 0;
    c->next_every_spp = schedule->every_spp > 0 ? schedule->every_spp : INT64_MAX;
    c->next_doubling_spp = schedule->doubling_spp > 0 ? schedule->doubling_spp : INT64_MAX;
}

bool snapshot_schedule_due(struct snapshot_cursor *c, double elapsed_s, int64_t spp)
{
    const struct snapshot_schedule *sch = c->schedule;
    double t = elapsed_s;
    bool due = false;
    if (t >= c->next_every_s) {
        due = true;
        while (c->next_every_s <= t) c->next_every_s += sch->every_s;
    }
    if (t >= c->next_doubling_s) {
        due = true;
        while (c->next_doubling_s <= t) c->next_doubling_s *= 2.0;
    }
    while (c->next_time < sch->n_times && t >= sch->times_s[c->next_time]) {
        due = true;
        ++c->next_time;
    }
    if (spp >= c->next_every_spp) {
        due = true;
        while (c->next_every_spp <= spp) c->next_every_spp += sch->every_spp;
    }
    if (spp >= c->next_doubling_spp) {
        due = true;
        /* Saturates instead of overflowing: INT64_MAX is never reached. */
        while (c->next_doubling_spp <= spp)
            c->next_doubling_spp = c->next_doubling_spp > INT64_MAX / 2 ? INT64_MAX : 2 * c->next_doubling_spp;
    }
    while (c->next_spp_list < sch->n_spps && spp >= sch->spps[c->next_spp_list]) {
        due = true;
        ++c->next_spp_list;
    }
    return due;
}

double snapshot_schedule_next_s(const struct snapshot_cursor *c)
{
    const struct snapshot_schedule *sch = c->schedule;
    double next = c->next_every_s < c->next_doubling_s ? c->next_every_s : c->next_doubling_s;
    if (c->next_time < sch->n_times && sch->times_s[c->next_time] < next) next = sch->times_s[c->next_time];
    return next;
}

int64_t snapshot_schedule_next_spp(const struct snapshot_cursor *c)
{
    const struct snapshot_schedule *sch = c->schedule;
    int64_t next = c->next_every_spp < c->next_doubling_spp ? c->next_every_spp : c->next_doubling_spp;
    if (c->next_spp_list < sch->n_spps && sch->spps[c->next_spp_list] < next) next = sch->spps[c->next_spp_list];
    return next;
}

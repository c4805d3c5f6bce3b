/* render_events.c: the text of the JSON event lines (see render_events.h). */
#include "render/render_events.h"

#include "base/json_write.h"
#include "base/version.h"

const char *const render_event_names[RENDER_EVENT_COUNT] = {
    [RENDER_EVENT_START] = "start",
    [RENDER_EVENT_SNAPSHOT] = "snapshot",
    [RENDER_EVENT_FINAL] = "final",
};

/* The fields a snapshot and the final image share, without the closing brace. */
static void image_fields(FILE *f, const char *event, int index, const char *path, const struct snapshot_info *info)
{
    fprintf(f, "{\"event\":\"%s\",", event);
    if (index > 0) fprintf(f, "\"index\":%d,", index);
    fputs("\"path\":", f);
    json_write_string(f, path);
    fprintf(f, ",\"time_s\":%.6f,\"spp\":%lld,\"rays\":%llu,\"nonfinite\":%llu", info->render_time_s,
            (long long)info->spp, (unsigned long long)info->rays, (unsigned long long)info->nonfinite_samples);
}

void render_event_start(FILE *f, const struct config *cfg, int threads, int64_t resumed_from_spp)
{
    const struct render_desc *rd = &cfg->render;
    fprintf(f, "{\"event\":\"%s\",\"out\":", render_event_names[RENDER_EVENT_START]);
    json_write_string(f, rd->output);
    fprintf(f,
            ",\"width\":%d,\"height\":%d,\"strategy\":\"%s\",\"integrator\":\"%s\",\"seed\":%llu,"
            "\"config_hash\":\"%016llx\",\"renderer_version\":\"%s\",\"threads\":%d,"
            "\"spp_target\":%d,\"time_target_s\":%g,\"resumed_from_spp\":%lld}\n",
            cfg->width, cfg->height, strategy_names[rd->strategy], integrator_names[rd->integrator],
            (unsigned long long)rd->seed, (unsigned long long)cfg->hash, RENDERER_VERSION, threads, rd->spp, rd->time_s,
            (long long)resumed_from_spp);
    fflush(f);
}

void render_event_snapshot(FILE *f, int index, const char *path, const struct snapshot_info *info)
{
    image_fields(f, render_event_names[RENDER_EVENT_SNAPSHOT], index, path, info);
    fputs("}\n", f);
    fflush(f);
}

void render_event_final(FILE *f, const char *path, const struct snapshot_info *info, bool interrupted,
                        const struct integrator_stats *stats, const struct render_timers *timers)
{
    image_fields(f, render_event_names[RENDER_EVENT_FINAL], 0, path, info);
    fprintf(f,
            ",\"interrupted\":%s,\"shadow_rays\":%llu,\"shadow_blocked\":%llu,"
            "\"light_samples\":%llu,\"light_missed\":%llu,\"render_cpu_s\":%.6f,"
            "\"snapshot_cpu_s\":%.6f,\"snapshot_pause_s\":%.6f}\n",
            interrupted ? "true" : "false", (unsigned long long)stats->shadow_rays,
            (unsigned long long)stats->shadow_blocked, (unsigned long long)stats->light_samples,
            (unsigned long long)stats->light_missed, timers->render_cpu_s, timers->snapshot_cpu_s,
            timers->snapshot_pause_s);
    fflush(f);
}

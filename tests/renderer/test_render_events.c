/* test_render_events.c: the exact text of the JSON event lines
   (render_events.h) that the harness parses: field names, order, number
   formats, string escapes, one line each. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/render_events.h"
#include "testlib.h"
#include "base/version.h"

/* What one event function wrote, as a string (free it). */
struct capture {
    char *text;
    size_t size;
    FILE *f;
};

static FILE *capture_open(struct capture *c)
{
    c->text = NULL;
    c->size = 0;
    c->f = open_memstream(&c->text, &c->size);
    return c->f;
}

static char *capture_close(struct capture *c)
{
    fclose(c->f);
    return c->text;
}

static void check_text(const char *what, char *got, const char *want)
{
    CHECK_MSG(got && !strcmp(got, want), "%s:\n    got  %s\n    want %s", what, got ? got : "(null)", want);
    free(got);
}

static struct snapshot_info sample_info(void)
{
    struct snapshot_info info;
    memset(&info, 0, sizeof info);
    info.render_time_s = 1.5;
    info.spp = 8;
    info.rays = 12345;
    info.nonfinite_samples = 2;
    return info;
}

static void test_start(void)
{
    static struct config cfg; /* large: not on the stack */
    memset(&cfg, 0, sizeof cfg);
    cfg.width = 64;
    cfg.height = 32;
    cfg.hash = 0xdeadbeefull;
    cfg.render.strategy = STRATEGY_ANTISHADOW_EXACT;
    cfg.render.integrator = INTEGRATOR_PATH;
    cfg.render.seed = 7;
    cfg.render.spp = 16;
    cfg.render.time_s = 2.5;
    /* A quote, a backslash and a control character must be escaped. */
    strcpy(cfg.render.output, "out/a\"b\\c\001");
    struct capture c;
    CHECK(capture_open(&c));
    render_event_start(c.f, &cfg, 3, 4);
    check_text("start", capture_close(&c),
               "{\"event\":\"start\",\"out\":\"out/a\\\"b\\\\c\\u0001\",\"width\":64,\"height\":32,"
               "\"strategy\":\"antishadow_exact\",\"integrator\":\"path\",\"seed\":7,"
               "\"config_hash\":\"00000000deadbeef\",\"renderer_version\":\"" RENDERER_VERSION "\","
               "\"threads\":3,\"spp_target\":16,\"time_target_s\":2.5,\"resumed_from_spp\":4}\n");
}

static void test_snapshot(void)
{
    struct snapshot_info info = sample_info();
    struct capture c;
    CHECK(capture_open(&c));
    render_event_snapshot(c.f, 3, "dir/snapshot_0003.exr", &info);
    check_text("snapshot", capture_close(&c),
               "{\"event\":\"snapshot\",\"index\":3,\"path\":\"dir/snapshot_0003.exr\",\"time_s\":1.500000,"
               "\"spp\":8,\"rays\":12345,\"nonfinite\":2}\n");
}

static void test_final(void)
{
    struct snapshot_info info = sample_info();
    struct integrator_stats stats = { 12345, 1, 2, 3, 4 };
    struct render_timers timers = { 0.25, 0.125, 0.0625 };
    struct capture c;
    CHECK(capture_open(&c));
    render_event_final(c.f, "dir/final.exr", &info, true, &stats, &timers);
    check_text("final", capture_close(&c),
               "{\"event\":\"final\",\"path\":\"dir/final.exr\",\"time_s\":1.500000,\"spp\":8,\"rays\":12345,"
               "\"nonfinite\":2,\"interrupted\":true,\"shadow_rays\":1,\"shadow_blocked\":2,"
               "\"light_samples\":3,\"light_missed\":4,\"render_cpu_s\":0.250000,"
               "\"snapshot_cpu_s\":0.125000,\"snapshot_pause_s\":0.062500}\n");
    CHECK(capture_open(&c));
    render_event_final(c.f, "f.exr", &info, false, &stats, &timers);
    char *text = capture_close(&c);
    CHECK(text && strstr(text, "\"interrupted\":false,"));
    free(text);
}

static const struct test_case tests[] = {
    { "start", test_start },
    { "snapshot", test_snapshot },
    { "final", test_final },
};

TEST_MAIN(tests)

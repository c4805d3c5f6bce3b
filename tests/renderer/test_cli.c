/* The command line as a user and the harness see it: exit codes, messages,
   the output folder, the JSON stream, and SIGTERM/SIGINT handling. Runs the
   `render` binary that sits next to this test's folder. */
#include "cli_util.h"
#include "film.h"
#include "testlib.h"

static void test_help_and_version(void)
{
    struct run r;
    char *a1[] = { NULL, "--help", NULL };
    run_render(a1, 0, 0, &r);
    CHECK(r.status == 0);
    CHECK(strstr(r.out, "usage: render CONFIG") && strstr(r.out, "--strategy"));
    char *a2[] = { NULL, "--version", NULL };
    run_render(a2, 0, 0, &r);
    CHECK(r.status == 0 && strstr(r.out, "render "));
}

static void test_usage_errors(void)
{
    struct run r;
    char *a1[] = { NULL, "configs/scenes/lampshade.yaml", "--bogus", NULL };
    run_render(a1, 0, 0, &r);
    CHECK(r.status == 2 && strstr(r.err, "unknown option --bogus"));
    char *a2[] = { NULL, NULL };
    run_render(a2, 0, 0, &r);
    CHECK(r.status == 2);
    char *a3[] = { NULL, "configs/scenes/lampshade.yaml", "--set", "novalue", NULL };
    run_render(a3, 0, 0, &r);
    CHECK(r.status == 2 && strstr(r.err, "--set needs KEY.PATH=VALUE"));
    char *a4[] = { NULL, "configs/scenes/does_not_exist.yaml", NULL };
    run_render(a4, 0, 0, &r);
    CHECK(r.status == 2 && strstr(r.err, "does_not_exist.yaml"));
}

/* A config error: exit 2, file:line:column on stderr, nothing written. */
static void test_config_error_writes_nothing(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    char out[600];
    snprintf(out, sizeof out, "%s/never", dir);
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", out, "--set", "render.strategy=prtal", NULL };
    run_render(a, 0, 0, &r);
    CHECK(r.status == 2);
    CHECK_MSG(strstr(r.err, "--set render.strategy=prtal") != NULL, "stderr: %s", r.err);
    CHECK(!exists(out));
    char *b[] = { NULL, "tests/configs/bad/unknown_key_camera.yaml", "--out", out, NULL };
    run_render(b, 0, 0, &r);
    CHECK_MSG(r.status == 2 && strstr(r.err, "bad/unknown_key_camera.yaml:"), "status %d, stderr: %s", r.status, r.err);
    CHECK(!exists(out));
    remove_tree(dir);
}

/* A small render: JSON lines, files, exit 0. */
static void test_render_outputs(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", dir, "--spp", "6", "--threads", "2",
                  "--set", "film.width=24", "--set", "film.height=16", "--set", "render.snapshots.every_spp=2",
                  "--quiet", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
    int lines = 0, snaps = 0, finals = 0, starts = 0;
    for (char *line = r.out; *line;) {
        char *nl = strchr(line, '\n');
        if (!nl) break;
        *nl = '\0';
        ++lines;
        CHECK(line[0] == '{' && nl[-1] == '}');
        starts += strstr(line, "\"event\":\"start\"") != NULL;
        snaps += strstr(line, "\"event\":\"snapshot\"") != NULL;
        finals += strstr(line, "\"event\":\"final\"") != NULL && strstr(line, "\"spp\":6");
        line = nl + 1;
    }
    CHECK(starts == 1 && finals == 1);
    CHECK_MSG(snaps == 3, "%d snapshots (expected at spp 2, 4, 6)", snaps);
    char path[700];
    const char *files[] = { "config.yaml", "final.exr", "snapshot_0001.exr", "snapshot_0003.exr" };
    for (int i = 0; i < 4; ++i) {
        snprintf(path, sizeof path, "%s/%s", dir, files[i]);
        CHECK_MSG(exists(path), "missing %s", path);
    }
    struct film_image img = { 0 };
    struct snapshot_read meta = { { 0 }, NULL };
    struct error err;
    snprintf(path, sizeof path, "%s/final.exr", dir);
    CHECK(film_read_exr(path, &img, &meta, &err));
    CHECK(img.width == 24 && img.height == 16 && meta.info.spp == 6);
    CHECK(meta.info.strategy && !strcmp(meta.info.strategy, "light"));
    film_image_free(&img);
    free(meta.storage);
    /* The effective config renders again as it is. */
    char cfg[700], dir2[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir2);
    snprintf(cfg, sizeof cfg, "%s/config.yaml", dir);
    char *b[] = { NULL, cfg, "--out", dir2, "--quiet", NULL };
    run_render(b, 0, 0, &r);
    CHECK_MSG(r.status == 0, "re-render of config.yaml: %s", r.err);
    remove_tree(dir2);
    remove_tree(dir);
}

/* SIGTERM and SIGINT: the current pass ends, final.exr is written, exit 3. */
static void test_signals(void)
{
    int sigs[] = { SIGTERM, SIGINT };
    for (int i = 0; i < 2; ++i) {
        char dir[] = "/tmp/portal-cli-XXXXXX";
        make_tmpdir(dir);
        struct run r;
        char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", dir, "--spp", "0", "--time", "60",
                      "--threads", "2", "--set", "film.width=64", "--set", "film.height=64", "--quiet", NULL };
        run_render(a, 0.8, sigs[i], &r);
        CHECK_MSG(r.status == 3, "signal %d: status %d: %s", sigs[i], r.status, r.err);
        CHECK(strstr(r.out, "\"event\":\"final\"") && strstr(r.out, "\"interrupted\":true"));
        char path[600];
        snprintf(path, sizeof path, "%s/final.exr", dir);
        struct film_image img = { 0 };
        struct snapshot_read meta = { { 0 }, NULL };
        struct error err;
        CHECK_MSG(film_read_exr(path, &img, &meta, &err), "final.exr after signal %d", sigs[i]);
        CHECK(meta.info.spp > 0);
        film_image_free(&img);
        free(meta.storage);
        remove_tree(dir);
    }
}

/* An output folder that cannot be created: runtime error, exit 1. */
static void test_unwritable_output(void)
{
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", "/proc/portal-lights-test", "--spp", "1",
                  "--set", "film.width=8", "--set", "film.height=8", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 1 && strstr(r.err, "/proc/portal-lights-test"), "status %d: %s", r.status, r.err);
}

/* Non-finite samples (provoked by the renderer's fault hook) are dropped and
   counted: the count reaches the JSON stream and the EXR header, and no
   NaN reaches the image. */
static void test_nonfinite_dropped(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", dir, "--spp", "8", "--set", "film.width=16",
                  "--set", "film.height=16", "--quiet", NULL };
    setenv("PORTAL_LIGHTS_FAULT_NONFINITE", "20", 1);
    run_render(a, 0, 0, &r);
    unsetenv("PORTAL_LIGHTS_FAULT_NONFINITE");
    CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
    const char *fin = strstr(r.out, "\"event\":\"final\"");
    const char *nf = fin ? strstr(fin, "\"nonfinite\":") : NULL;
    long count = nf ? strtol(nf + 12, NULL, 10) : 0;
    /* 2048 samples, about 1 in 20 poisoned. */
    CHECK_MSG(count > 40 && count < 200, "nonfinite count %ld", count);
    CHECK(strstr(r.err, "non-finite samples dropped") != NULL);
    char path[600];
    snprintf(path, sizeof path, "%s/final.exr", dir);
    struct film_image img = { 0 };
    struct snapshot_read meta = { { 0 }, NULL };
    struct error err;
    CHECK(film_read_exr(path, &img, &meta, &err));
    CHECK(meta.info.nonfinite_samples == (uint64_t)count);
    int bad = 0;
    for (int i = 0; i < 3 * img.width * img.height; ++i) bad += !isfinite(img.rgb[i]) || !isfinite(img.variance[i]);
    CHECK(bad == 0);
    film_image_free(&img);
    free(meta.storage);
    remove_tree(dir);
}

static const struct test_case tests[] = {
    { "nonfinite_dropped", test_nonfinite_dropped },
    { "help_and_version", test_help_and_version },
    { "usage_errors", test_usage_errors },
    { "config_error_writes_nothing", test_config_error_writes_nothing },
    { "render_outputs", test_render_outputs },
    { "signals", test_signals },
    { "unwritable_output", test_unwritable_output },
};
TEST_MAIN(tests)

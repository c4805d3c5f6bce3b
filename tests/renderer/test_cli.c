/* The command line as a user and the harness see it: exit codes, messages,
   the output folder, the JSON stream, and SIGTERM/SIGINT handling. Runs the
   `render` binary that sits next to this test's folder. */
#include <dirent.h>

#include "cli_util.h"
#include "render/film.h"
#include "exr_read.h"
#include "testlib.h"

static void test_help_and_version(void)
{
    struct run r;
    char *a1[] = { NULL, "--help", NULL };
    run_render(a1, 0, 0, &r);
    CHECK(r.status == 0);
    CHECK(strstr(r.out, "usage: render CONFIG") && strstr(r.out, "--strategy"));
    CHECK(strstr(r.out, "render --resume DIR") && strstr(r.out, "--resumable"));
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
    char *a[] = { NULL,        "configs/scenes/lampshade.yaml",
                  "--out",     dir,
                  "--spp",     "6",
                  "--threads", "2",
                  "--set",     "film.width=24",
                  "--set",     "film.height=16",
                  "--set",     "render.snapshots.every_spp=2",
                  "--quiet",   NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
    int lines = 0, snaps = 0, finals = 0, starts = 0;
    double render_cpu_s = -1.0, time_s = -1.0, snapshot_cpu_s = -1.0, snapshot_pause_s = -1.0;
    for (char *line = r.out; *line;) {
        char *nl = strchr(line, '\n');
        if (!nl) break;
        *nl = '\0';
        ++lines;
        CHECK(line[0] == '{' && nl[-1] == '}');
        starts += strstr(line, "\"event\":\"start\"") != NULL;
        snaps += strstr(line, "\"event\":\"snapshot\"") != NULL;
        finals += strstr(line, "\"event\":\"final\"") != NULL && strstr(line, "\"spp\":6");
        if (strstr(line, "\"event\":\"final\"")) {
            const char *c = strstr(line, "\"render_cpu_s\":"), *t = strstr(line, "\"time_s\":");
            if (c) sscanf(c + strlen("\"render_cpu_s\":"), "%lf", &render_cpu_s);
            if (t) sscanf(t + strlen("\"time_s\":"), "%lf", &time_s);
            const char *sc = strstr(line, "\"snapshot_cpu_s\":"), *sp = strstr(line, "\"snapshot_pause_s\":");
            if (sc) sscanf(sc + strlen("\"snapshot_cpu_s\":"), "%lf", &snapshot_cpu_s);
            if (sp) sscanf(sp + strlen("\"snapshot_pause_s\":"), "%lf", &snapshot_pause_s);
        }
        line = nl + 1;
    }
    CHECK(starts == 1 && finals == 1);
    /* The render threads' CPU time: some, and no more than two threads can
       spend in the render time (plus the clocks' granularity). */
    CHECK_MSG(render_cpu_s > 0.0 && time_s > 0.0 && render_cpu_s <= 2.0 * time_s + 0.002, "render_cpu_s %g, time_s %g",
              render_cpu_s, time_s);
    /* Three snapshots were written: they took some CPU, and some pause. */
    CHECK_MSG(snapshot_cpu_s > 0.0 && snapshot_pause_s > 0.0, "snapshot_cpu_s %g, snapshot_pause_s %g", snapshot_cpu_s,
              snapshot_pause_s);
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
        char *a[] = { NULL,        "configs/scenes/lampshade.yaml",
                      "--out",     dir,
                      "--spp",     "0",
                      "--time",    "60",
                      "--threads", "2",
                      "--set",     "film.width=64",
                      "--set",     "film.height=64",
                      "--quiet",   NULL };
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

/* An output folder that cannot be created is a config error (exit 2) that
   names the option that set it; nothing is written. */
static void test_unwritable_output(void)
{
    struct run r;
    char *a[] = { NULL,    "configs/scenes/lampshade.yaml",
                  "--out", "/proc/portal-lights-test",
                  "--spp", "1",
                  "--set", "film.width=8",
                  "--set", "film.height=8",
                  NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 2 && strstr(r.err, "--out /proc/portal-lights-test: output folder cannot be created: No such "
                                             "file or directory (expected a folder that can be created and written)"),
              "status %d: %s", r.status, r.err);
    CHECK(r.out[0] == '\0');
    char *b[] = { NULL, "configs/scenes/lampshade.yaml", "--set", "render.output=/proc/portal-lights-test/x", NULL };
    run_render(b, 0, 0, &r);
    CHECK_MSG(r.status == 2 && strstr(r.err, "--set render.output=/proc/portal-lights-test/x: output folder cannot be "
                                             "created: /proc/portal-lights-test: No such file or directory"),
              "status %d: %s", r.status, r.err);
}

/* Folders made on the way to one that cannot be made are removed again:
   here the last name is longer than a file name may be. */
static void test_output_rollback(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    char out[900], first[700];
    snprintf(first, sizeof first, "%s/a", dir);
    int n = snprintf(out, sizeof out, "%s/a/b/", dir);
    for (int i = 0; i < 300; ++i) out[n++] = 'x';
    out[n] = '\0';
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", out, "--quiet", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 2 && strncmp(r.err, "--out ", 6) == 0 && strstr(r.err, "File name too long"), "status %d: %s",
              r.status, r.err);
    CHECK_MSG(!exists(first), "%s was left behind", first);
    CHECK(exists(dir));
    /* Permissions stop only non-root users: an existing folder that cannot
       be written, and one in which no folder can be made. */
    if (geteuid() != 0) {
        char ro[700], sub[720];
        snprintf(ro, sizeof ro, "%s/ro", dir);
        snprintf(sub, sizeof sub, "%s/ro/sub", dir);
        CHECK(mkdir(ro, 0555) == 0);
        char *b[] = { NULL, "configs/scenes/lampshade.yaml", "--out", ro, "--quiet", NULL };
        run_render(b, 0, 0, &r);
        CHECK_MSG(r.status == 2 && strstr(r.err, "output folder cannot be written: config.yaml.tmp-") &&
                      strstr(r.err, "Permission denied"),
                  "%s", r.err);
        char *c[] = { NULL, "configs/scenes/lampshade.yaml", "--out", sub, "--quiet", NULL };
        run_render(c, 0, 0, &r);
        CHECK_MSG(r.status == 2 && strstr(r.err, "Permission denied") && !exists(sub), "%s", r.err);
        chmod(ro, 0755);
    } else {
        printf("  unwritable output folders by permission: not checked as root\n");
    }
    remove_tree(dir);
}

/* The bad configs marked "# stage: output": valid configs whose output
   folder cannot be made. Exit 2, the expected message (with the location of
   render.output), nothing on stdout, and no folder on the way made. */
static void test_bad_output_catalogue(void)
{
    DIR *d = opendir("tests/configs/bad");
    int n = 0;
    CHECK(d != NULL);
    for (struct dirent *e; d && (e = readdir(d)) != NULL;) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".yaml")) continue;
        char path[600], expect[1100], line[1100], out[1100] = "";
        snprintf(path, sizeof path, "tests/configs/bad/%s", e->d_name);
        FILE *f = fopen(path, "r");
        bool output_stage = f && fgets(expect, sizeof expect, f) && fgets(line, sizeof line, f) &&
                            strncmp(line, "# stage: output", 15) == 0;
        while (output_stage && fgets(line, sizeof line, f))
            if (strncmp(line, "  output: ", 10) == 0) snprintf(out, sizeof out, "%s", line + 10);
        if (f) fclose(f);
        if (!output_stage) continue;
        ++n;
        expect[strcspn(expect, "\n")] = '\0';
        out[strcspn(out, "\n")] = '\0';
        CHECK_MSG(out[0] != '\0', "%s: no render.output line", path);
        /* Which folders on the way exist before and after. */
        bool before[64], after[64];
        int k = 0;
        for (char *p = out + 1; *p && k < 64; ++p)
            if (*p == '/' || !p[1]) {
                char c = p[1];
                p[1] = '\0';
                before[k++] = exists(out);
                p[1] = c;
            }
        struct run r;
        char *a[] = { NULL, path, "--quiet", NULL };
        run_render(a, 0, 0, &r);
        CHECK_MSG(r.status == 2, "%s: status %d", path, r.status);
        CHECK_MSG(strstr(r.err, expect + 10) != NULL, "\n    got:      %s    expected: %s", r.err, expect + 10);
        CHECK(r.out[0] == '\0');
        k = 0;
        for (char *p = out + 1; *p && k < 64; ++p)
            if (*p == '/' || !p[1]) {
                char c = p[1];
                p[1] = '\0';
                after[k] = exists(out);
                CHECK_MSG(after[k] == before[k], "%s: %s %s", path, out, after[k] ? "was made" : "vanished");
                ++k;
                p[1] = c;
            }
    }
    if (d) closedir(d);
    CHECK_MSG(n >= 3, "only %d output-stage bad configs", n);
    printf("  %d bad output folders\n", n);
}

/* Non-finite samples (provoked by the renderer's fault hook) are dropped and
   counted: the count reaches the JSON stream and the EXR header, and no
   NaN reaches the image. */
static void test_nonfinite_dropped(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL,      "configs/scenes/lampshade.yaml",
                  "--out",   dir,
                  "--spp",   "8",
                  "--set",   "film.width=16",
                  "--set",   "film.height=16",
                  "--quiet", NULL };
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

/* A 16x16 lampshade of 4 passes with PORTAL_LIGHTS_FAULT_BIAS=bias (unset
   when NULL); img holds final.exr. */
static bool render_biased(const char *bias, struct film_image *img)
{
    char dir[] = "/tmp/portal-cli-XXXXXX", path[600];
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL,      "configs/scenes/lampshade.yaml",
                  "--out",   dir,
                  "--spp",   "4",
                  "--set",   "film.width=16",
                  "--set",   "film.height=16",
                  "--quiet", NULL };
    if (bias) setenv("PORTAL_LIGHTS_FAULT_BIAS", bias, 1);
    run_render(a, 0, 0, &r);
    unsetenv("PORTAL_LIGHTS_FAULT_BIAS");
    CHECK_MSG(r.status == 0, "bias %s: status %d: %s", bias ? bias : "(none)", r.status, r.err);
    struct snapshot_read meta = { { 0 }, NULL };
    struct error err;
    snprintf(path, sizeof path, "%s/final.exr", dir);
    bool ok = r.status == 0 && film_read_exr(path, img, &meta, &err);
    free(meta.storage);
    remove_tree(dir);
    return ok;
}

/* PORTAL_LIGHTS_FAULT_BIAS=STRATEGY:FACTOR: every sample of that strategy
   times FACTOR (here 2: the mean doubles, the variance of the mean
   quadruples, pixel by pixel); another strategy's render is untouched, bit
   for bit; a malformed value is exit 2 with nothing written. */
static void test_fault_bias(void)
{
    struct film_image plain = { 0 }, doubled = { 0 }, other = { 0 };
    if (render_biased(NULL, &plain) && render_biased("light:2", &doubled) && render_biased("portal:2", &other)) {
        size_t n = 3 * (size_t)plain.width * (size_t)plain.height;
        int off = 0, nonzero = 0;
        for (size_t i = 0; i < n; ++i) {
            double want = 2.0 * plain.rgb[i], var = 4.0 * plain.variance[i];
            off += fabs(doubled.rgb[i] - want) > 1e-6 * fabs(want) + 1e-30;
            off += fabs(doubled.variance[i] - var) > 1e-6 * var + 1e-30;
            nonzero += plain.rgb[i] > 0.0f;
        }
        CHECK_MSG(off == 0, "%d of %zu values are not twice (mean) or four times (variance) the unbiased ones", off, n);
        CHECK_MSG(nonzero > (int)n / 32, "only %d of %zu values lit", nonzero, n);
        CHECK(memcmp(plain.rgb, other.rgb, n * sizeof(float)) == 0);
        CHECK(memcmp(plain.variance, other.variance, n * sizeof(float)) == 0);
    }
    film_image_free(&plain);
    film_image_free(&doubled);
    film_image_free(&other);

    const char *bad[] = { "light", "light:", "light:abc", "prtal:2", ":2", "light:-1", "light:inf", "light:2x" };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        char dir[] = "/tmp/portal-cli-XXXXXX", out[600];
        make_tmpdir(dir);
        snprintf(out, sizeof out, "%s/never", dir);
        struct run r;
        char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", out, "--spp", "1", "--quiet", NULL };
        setenv("PORTAL_LIGHTS_FAULT_BIAS", bad[k], 1);
        run_render(a, 0, 0, &r);
        unsetenv("PORTAL_LIGHTS_FAULT_BIAS");
        CHECK_MSG(r.status == 2 && strstr(r.err, "PORTAL_LIGHTS_FAULT_BIAS=") &&
                      strstr(r.err, "expected STRATEGY:FACTOR"),
                  "%s: status %d: %s", bad[k], r.status, r.err);
        CHECK_MSG(!exists(out) && r.out[0] == '\0', "%s: something was written", bad[k]);
        remove_tree(dir);
    }
}

/* render.snapshots.doubling_spp: snapshots at 1, 2, 4, 8, 16 spp of a
   20-spp render (early snapshots for the harness's error-over-time
   curves), and the key survives into the effective config. */
static void test_doubling_spp(void)
{
    char dir[] = "/tmp/portal-cli-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL,        "configs/scenes/lampshade.yaml",
                  "--out",     dir,
                  "--spp",     "20",
                  "--threads", "2",
                  "--set",     "film.width=16",
                  "--set",     "film.height=16",
                  "--set",     "render.snapshots.doubling_spp=1",
                  "--quiet",   NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
    const int expected[] = { 1, 2, 4, 8, 16 };
    int n = 0;
    for (const char *line = r.out; (line = strstr(line, "\"event\":\"snapshot\"")); ++line) {
        const char *spp = strstr(line, "\"spp\":");
        int v = spp ? atoi(spp + strlen("\"spp\":")) : -1;
        CHECK_MSG(n < 5 && v == expected[n], "snapshot %d at spp %d", n + 1, v);
        ++n;
    }
    CHECK_MSG(n == 5, "%d snapshots (expected at spp 1, 2, 4, 8, 16)", n);
    char path[512], text[8192] = { 0 };
    snprintf(path, sizeof path, "%s/config.yaml", dir);
    FILE *f = fopen(path, "r");
    size_t len = f ? fread(text, 1, sizeof text - 1, f) : 0;
    if (f) fclose(f);
    CHECK_MSG(len > 0 && strstr(text, "doubling_spp: 1"), "config.yaml: %s", text);
    remove_tree(dir);
}

static const struct test_case tests[] = {
    { "doubling_spp", test_doubling_spp },
    { "nonfinite_dropped", test_nonfinite_dropped },
    { "fault_bias", test_fault_bias },
    { "help_and_version", test_help_and_version },
    { "usage_errors", test_usage_errors },
    { "config_error_writes_nothing", test_config_error_writes_nothing },
    { "render_outputs", test_render_outputs },
    { "signals", test_signals },
    { "unwritable_output", test_unwritable_output },
    { "output_rollback", test_output_rollback },
    { "bad_output_catalogue", test_bad_output_catalogue },
};
TEST_MAIN(tests)

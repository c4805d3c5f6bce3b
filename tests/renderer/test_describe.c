/* `render --describe`: one JSON object whose lists are the renderer's own
   tables, in their order, and whose promises hold: every strategy listed
   renders, every EXR channel and attribute listed is in the files, every
   AOV channel listed is written with render.aov.region=true, every JSON
   event printed is listed. EXR headers are read here without OpenEXR. */
#include <stdint.h>

#include "render/aov.h"
#include "cli_util.h"
#include "config/config.h"
#include "cli/exit_code.h"
#include "render/film.h"
#include "json_util.h"
#include "render/render_events.h"
#include "sampling/sampler.h"
#include "testlib.h"
#include "base/version.h"

#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

/* Runs `render --describe` and parses it; false (with a failed check) when
   it does not give one well-formed object on one line. */
static bool describe(struct jval *d)
{
    struct run r;
    char *a[] = { NULL, "--describe", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
    size_t n = strlen(r.out);
    CHECK_MSG(n > 2 && r.out[n - 1] == '\n' && strchr(r.out, '\n') == r.out + n - 1, "not one line: %s", r.out);
    CHECK(r.err[0] == '\0');
    char why[200];
    bool ok = json_parse(r.out, d, why);
    CHECK_MSG(ok, "%s in %s", why, r.out);
    CHECK(ok && d->type == J_OBJECT);
    return ok && d->type == J_OBJECT;
}

static void test_describe_lists_the_tables(void)
{
    struct jval d;
    if (!describe(&d)) return;
    static const char *const keys[] = { "program",    "version",      "strategies",     "integrators",
                                        "materials",  "mis",          "portal_weights", "samplers",
                                        "aov",        "exr_channels", "exr_attributes", "snapshot_keys",
                                        "exit_codes", "json_events" };
    CHECK_MSG(d.n == COUNT(keys), "%d keys", d.n);
    for (int i = 0; i < d.n && i < COUNT(keys); ++i) CHECK_MSG(!strcmp(d.keys[i], keys[i]), "key %d: %s", i, d.keys[i]);
    const struct jval *v = json_get(&d, "program");
    CHECK(v && v->type == J_STRING && !strcmp(v->text, "render"));
    v = json_get(&d, "version");
    CHECK(v && v->type == J_STRING && !strcmp(v->text, RENDERER_VERSION));
    CHECK(json_is_names(json_get(&d, "strategies"), NULL, strategy_names, STRATEGY_COUNT));
    CHECK(json_is_names(json_get(&d, "integrators"), NULL, integrator_names, COUNT(integrator_names)));
    CHECK(json_is_names(json_get(&d, "materials"), NULL, material_names, COUNT(material_names)));
    CHECK(json_is_names(json_get(&d, "mis"), NULL, mis_names, COUNT(mis_names)));
    CHECK(json_is_names(json_get(&d, "portal_weights"), NULL, portal_weight_names, COUNT(portal_weight_names)));
    CHECK(json_is_names(json_get(&d, "samplers"), NULL, sampler_names, SAMPLER_COUNT));
    const struct jval *aov = json_get(&d, "aov");
    CHECK(aov && aov->type == J_OBJECT && aov->n == 1);
    CHECK(json_is_names(json_get(aov, "region"), "region.", aov_region_names, AOV_REGION_COUNT));
    CHECK(json_is_names(json_get(&d, "exr_channels"), NULL, film_channel_names, FILM_CHANNEL_COUNT));
    CHECK(json_is_names(json_get(&d, "exr_attributes"), NULL, film_attribute_names, FILM_ATTRIBUTE_COUNT));
    CHECK(json_is_names(json_get(&d, "json_events"), NULL, render_event_names, RENDER_EVENT_COUNT));
    /* The spellings the harness is written against, pinned once here. */
    static const char *const strategies[] = { "light_area", "light",      "portal",
                                              "projection", "antishadow", "antishadow_exact" };
    CHECK(json_is_names(json_get(&d, "strategies"), NULL, strategies, COUNT(strategies)));

    const struct jval *sk = json_get(&d, "snapshot_keys");
    CHECK(sk && sk->type == J_OBJECT && sk->n == CONFIG_SNAPSHOT_KEY_COUNT);
    for (int i = 0; sk && i < sk->n && i < CONFIG_SNAPSHOT_KEY_COUNT; ++i) {
        CHECK(!strcmp(sk->keys[i], config_snapshot_keys[i]));
        CHECK(sk->items[i].type == J_STRING && !strcmp(sk->items[i].text, config_snapshot_units[i]));
        CHECK(!strcmp(sk->items[i].text, "s") || !strcmp(sk->items[i].text, "spp"));
    }
    const struct jval *ec = json_get(&d, "exit_codes");
    CHECK(ec && ec->type == J_OBJECT && ec->n == EXIT_CODE_COUNT);
    static const struct {
        const char *name;
        int code;
    } codes[] = {
        { "done", EXIT_DONE }, { "runtime", EXIT_RUNTIME }, { "usage", EXIT_USAGE }, { "interrupted", EXIT_INTERRUPTED }
    };
    for (int i = 0; i < COUNT(codes); ++i) {
        const struct jval *c = json_get(ec, codes[i].name);
        CHECK_MSG(c && c->type == J_NUMBER && c->number == codes[i].code &&
                      !strcmp(exit_code_names[codes[i].code], codes[i].name),
                  "exit code %s", codes[i].name);
    }
    jfree(&d);
}

static void test_describe_takes_no_arguments(void)
{
    struct run r;
    char *a[] = { NULL, "--describe", "configs/scenes/lampshade.yaml", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_USAGE && strstr(r.err, "--describe") && !r.out[0], "status %d: %s", r.status, r.err);
}

/* The attribute and channel names of an EXR header (single part), read from
   the bytes: name\0 type\0 size value; a chlist value is a list of
   name\0 + 16 bytes, closed by \0. */
struct exr_names {
    int n_attrs, n_channels;
    char attrs[64][64];
    char channels[64][64];
};

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static bool exr_parse_names(const unsigned char *b, size_t n, struct exr_names *out)
{
    if (n < 8 || le32(b) != 20000630u) return false;
    size_t i = 8;
    while (i < n && b[i] != 0) {
        const char *name = (const char *)b + i;
        int name_len = (int)strnlen(name, n - i);
        i += (size_t)name_len + 1;
        const char *type = (const char *)b + i;
        if (i >= n) return false;
        i += strnlen(type, n - i) + 1;
        if (i + 4 > n) return false;
        uint32_t size = le32(b + i);
        i += 4;
        if (i + size > n || out->n_attrs == 64) return false;
        snprintf(out->attrs[out->n_attrs++], 64, "%.*s", name_len, name);
        if (!strcmp(type, "chlist")) {
            size_t j = i;
            while (j < i + size && b[j] != 0 && out->n_channels < 64) {
                int len = (int)strnlen((const char *)b + j, i + size - j);
                snprintf(out->channels[out->n_channels++], 64, "%.*s", len, (const char *)b + j);
                j += (size_t)len + 1 + 16;
            }
        }
        i += size;
    }
    return i < n;
}

static bool exr_read_names(const char *path, struct exr_names *out)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "rb");
    if (!f) return false;
    size_t cap = 1 << 16; /* the header is at the start, far shorter */
    unsigned char *b = malloc(cap);
    size_t n = b ? fread(b, 1, cap, f) : 0;
    fclose(f);
    bool ok = exr_parse_names(b, n, out);
    free(b);
    return ok;
}

static bool has_name(char (*list)[64], int n, const char *name)
{
    for (int i = 0; i < n; ++i)
        if (!strcmp(list[i], name)) return true;
    return false;
}

/* Every "event" of the JSON lines in out is one of the listed events;
   returns how many lines there were. */
static int check_events(char *out, const struct jval *events)
{
    int lines = 0;
    for (char *line = out; *line;) {
        char *nl = strchr(line, '\n');
        if (!nl) break;
        *nl = '\0';
        ++lines;
        struct jval v;
        char why[200];
        bool ok = json_parse(line, &v, why);
        CHECK_MSG(ok, "%s in %s", why, line);
        const struct jval *e = ok ? json_get(&v, "event") : NULL;
        bool listed = false;
        for (int i = 0; e && e->type == J_STRING && i < events->n; ++i)
            listed |= !strcmp(events->items[i].text, e->text);
        CHECK_MSG(!ok || listed, "event not listed by --describe: %s", line);
        if (ok) jfree(&v);
        line = nl + 1;
    }
    return lines;
}

/* Each strategy listed is accepted by --strategy and renders; its EXR has
   every channel and attribute listed and its JSON events are listed. */
static void test_every_listed_strategy_renders(void)
{
    struct jval d;
    if (!describe(&d)) return;
    const struct jval *strategies = json_get(&d, "strategies"), *channels = json_get(&d, "exr_channels"),
                      *attrs = json_get(&d, "exr_attributes"), *events = json_get(&d, "json_events");
    CHECK(strategies && channels && attrs && events);
    if (!strategies || !channels || !attrs || !events) {
        jfree(&d);
        return;
    }
    for (int s = 0; s < strategies->n; ++s) {
        char dir[] = "/tmp/portal-describe-XXXXXX";
        make_tmpdir(dir);
        struct run r;
        char *a[] = { NULL,         "configs/scenes/lampshade.yaml",
                      "--out",      dir,
                      "--strategy", strategies->items[s].text,
                      "--spp",      "2",
                      "--set",      "film.width=12",
                      "--set",      "film.height=8",
                      "--set",      "render.snapshots.every_spp=1",
                      "--threads",  "1",
                      "--quiet",    NULL };
        run_render(a, 0, 0, &r);
        CHECK_MSG(r.status == EXIT_DONE, "--strategy %s: status %d: %s", strategies->items[s].text, r.status, r.err);
        CHECK_MSG(check_events(r.out, events) == 4, "--strategy %s: not start, 2 snapshots, final",
                  strategies->items[s].text);
        const char *files[] = { "final.exr", "snapshot_0001.exr" };
        for (int k = 0; k < 2; ++k) {
            char path[600];
            snprintf(path, sizeof path, "%s/%s", dir, files[k]);
            struct exr_names names;
            bool read = exr_read_names(path, &names);
            CHECK_MSG(read, "cannot read the header of %s", path);
            for (int i = 0; read && i < channels->n; ++i)
                CHECK_MSG(has_name(names.channels, names.n_channels, channels->items[i].text), "%s: no channel %s",
                          path, channels->items[i].text);
            for (int i = 0; read && i < attrs->n; ++i)
                CHECK_MSG(has_name(names.attrs, names.n_attrs, attrs->items[i].text), "%s: no attribute %s", path,
                          attrs->items[i].text);
            /* Nothing but the listed channels without the AOV. */
            CHECK_MSG(!read || names.n_channels == channels->n, "%s: %d channels", path, names.n_channels);
        }
        remove_tree(dir);
    }
    jfree(&d);
}

/* With render.aov.region=true the EXR has exactly the listed channels: the
   snapshot channels and the AOV's. */
static void test_listed_aov_channels_are_written(void)
{
    struct jval d;
    if (!describe(&d)) return;
    const struct jval *aov = json_get(json_get(&d, "aov"), "region"), *channels = json_get(&d, "exr_channels");
    CHECK(aov && aov->type == J_ARRAY && aov->n > 0 && channels);
    char dir[] = "/tmp/portal-describe-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL,      "configs/scenes/lampshade.yaml",
                  "--out",   dir,
                  "--spp",   "1",
                  "--set",   "film.width=12",
                  "--set",   "film.height=8",
                  "--set",   "render.aov.region=true",
                  "--quiet", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_DONE, "status %d: %s", r.status, r.err);
    char path[600];
    snprintf(path, sizeof path, "%s/final.exr", dir);
    struct exr_names names;
    bool read = exr_read_names(path, &names);
    CHECK_MSG(read, "cannot read the header of %s", path);
    for (int i = 0; read && aov && i < aov->n; ++i)
        CHECK_MSG(has_name(names.channels, names.n_channels, aov->items[i].text), "no channel %s", aov->items[i].text);
    CHECK(!read || !aov || !channels || names.n_channels == aov->n + channels->n);
    CHECK(!read || has_name(names.attrs, names.n_attrs, FILM_ATTR_AOV_REGION_CLASSES));
    remove_tree(dir);
    jfree(&d);
}

/* The test reader itself: what it must refuse. */
static void test_json_reader_is_strict(void)
{
    static const char *const bad[] = { "",
                                       "{",
                                       "{\"a\":1,}",
                                       "[1,]",
                                       "{\"a\":1,\"a\":2}",
                                       "\"\x01\"",
                                       "\"\\x\"",
                                       "\"\\ud800\"",
                                       "01",
                                       "1.",
                                       "{} {}",
                                       "[\"a\" \"b\"]",
                                       "tru",
                                       "\"abc",
                                       "\"\\" };
    for (int i = 0; i < COUNT(bad); ++i) {
        struct jval v;
        CHECK_MSG(!json_parse(bad[i], &v, NULL), "accepted %s", bad[i]);
    }
    struct jval v;
    CHECK(json_parse(" {\"a\": [1, -2.5e3, true, null, \"\\u00e9\\ud83d\\ude00\\\"\"]}\n", &v, NULL));
    const struct jval *a = json_get(&v, "a");
    CHECK(a && a->n == 5 && a->items[1].number == -2500.0 && a->items[2].boolean && a->items[3].type == J_NULL);
    CHECK(a && !strcmp(a->items[4].text, "\xc3\xa9\xf0\x9f\x98\x80\""));
    jfree(&v);
}

static const struct test_case describe_tests[] = {
    { "json_reader_is_strict", test_json_reader_is_strict },
    { "describe_lists_the_tables", test_describe_lists_the_tables },
    { "describe_takes_no_arguments", test_describe_takes_no_arguments },
    { "every_listed_strategy_renders", test_every_listed_strategy_renders },
    { "listed_aov_channels_are_written", test_listed_aov_channels_are_written },
};

TEST_MAIN(describe_tests)

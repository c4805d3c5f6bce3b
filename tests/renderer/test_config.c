/* Tests of the YAML config loader: the canonical scene, --set overrides, the
   effective YAML round trip and its hash, the expression language, and the
   catalogues of good and bad configs in tests/configs/ (each bad file names
   the exact message it must produce in its first line). */
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include "config/config.h"
#include "config/expr.h"
#include "testlib.h"

#define LAMPSHADE   "configs/scenes/lampshade.yaml"
#define GOOD_DIR    "tests/configs/good"
#define BAD_DIR     "tests/configs/bad"
#define FUZZ_DIR    "tests/configs/fuzz"
#define COUNT_OF(a) ((int)(sizeof(a) / sizeof((a)[0])))

static bool is_zeroed(const struct config *c)
{
    static const struct config zero;
    return memcmp(c, &zero, sizeof zero) == 0;
}

static bool vec3_eq(struct vec3 a, struct vec3 b)
{
    return a.x == b.x && a.y == b.y && a.z == b.z;
}
static bool rgb_eq(struct rgb a, struct rgb b)
{
    return a.r == b.r && a.g == b.g && a.b == b.b;
}

static bool polygon_eq(const struct polygon *a, const struct polygon *b)
{
    if (a->n != b->n) return false;
    for (int i = 0; i < a->n; ++i)
        if (!vec3_eq(a->v[i], b->v[i])) return false;
    return true;
}

/* Field by field, bit-exact; locations and the file name are allowed to differ. */
static bool config_same(const struct config *a, const struct config *b)
{
    if (a->width != b->width || a->height != b->height) return false;
    if (!vec3_eq(a->camera.position, b->camera.position) || !vec3_eq(a->camera.look_at, b->camera.look_at) ||
        !vec3_eq(a->camera.up, b->camera.up) || a->camera.fov_y_deg != b->camera.fov_y_deg)
        return false;
    if (a->n_materials != b->n_materials || a->n_shapes != b->n_shapes || a->n_lights != b->n_lights ||
        a->n_portals != b->n_portals)
        return false;
    for (int i = 0; i < a->n_materials; ++i) {
        const struct material_desc *x = &a->materials[i], *y = &b->materials[i];
        if (strcmp(x->name, y->name) || x->kind != y->kind || !rgb_eq(x->albedo, y->albedo) ||
            (x->kind == MATERIAL_GGX && x->roughness != y->roughness))
            return false;
    }
    for (int i = 0; i < a->n_shapes; ++i) {
        const struct shape_desc *x = &a->shapes[i], *y = &b->shapes[i];
        if (x->material != y->material || x->n_vertices != y->n_vertices || x->n_triangles != y->n_triangles ||
            x->n_quads != y->n_quads)
            return false;
        for (int v = 0; v < x->n_vertices; ++v)
            if (!vec3_eq(x->vertices[v], y->vertices[v])) return false;
        if (x->n_triangles && memcmp(x->triangles, y->triangles, (size_t)x->n_triangles * sizeof *x->triangles))
            return false;
        if (x->n_quads && memcmp(x->quads, y->quads, (size_t)x->n_quads * sizeof *x->quads)) return false;
    }
    for (int i = 0; i < a->n_lights; ++i) {
        const struct light_desc *x = &a->lights[i], *y = &b->lights[i];
        if (strcmp(x->name, y->name) || !polygon_eq(&x->polygon, &y->polygon) || !rgb_eq(x->radiance, y->radiance) ||
            x->two_sided != y->two_sided)
            return false;
    }
    for (int i = 0; i < a->n_portals; ++i) {
        const struct portal_desc *x = &a->portals[i], *y = &b->portals[i];
        if (strcmp(x->name, y->name) || x->light != y->light || !polygon_eq(&x->polygon, &y->polygon)) return false;
    }
    const struct render_desc *r = &a->render, *s = &b->render;
    if (r->integrator != s->integrator || r->strategy != s->strategy || r->mis != s->mis ||
        r->portal_weight != s->portal_weight || r->defensive != s->defensive || r->max_depth != s->max_depth ||
        r->rr_depth != s->rr_depth || r->spp != s->spp || r->time_s != s->time_s || r->seed != s->seed ||
        r->threads != s->threads || strcmp(r->output, s->output))
        return false;
    const struct snapshot_schedule *p = &r->snapshots, *q = &s->snapshots;
    if (p->every_s != q->every_s || p->doubling_s != q->doubling_s || p->n_times != q->n_times ||
        p->every_spp != q->every_spp || p->n_spps != q->n_spps)
        return false;
    for (int i = 0; i < p->n_times; ++i)
        if (p->times_s[i] != q->times_s[i]) return false;
    for (int i = 0; i < p->n_spps; ++i)
        if (p->spps[i] != q->spps[i]) return false;
    return true;
}

static uint64_t fnv1a64(const char *s)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (; *s; ++s) h = (h ^ (unsigned char)*s) * 0x100000001b3ull;
    return h;
}

/* Loads c's effective YAML back and checks it gives the same config, the same
   text and the same hash. */
static void check_round_trip(const struct config *c, const char *label)
{
    struct config back;
    struct error err = { "" };
    bool ok = config_load_string(c->effective_yaml, strlen(c->effective_yaml), "effective", NULL, 0, &back, &err);
    CHECK_MSG(ok, "%s: effective YAML does not load: %s", label, err.message);
    if (!ok) return;
    CHECK_MSG(config_same(c, &back), "%s: reloaded config differs", label);
    CHECK_MSG(strcmp(c->effective_yaml, back.effective_yaml) == 0, "%s: effective YAML differs after reload", label);
    CHECK(c->hash == back.hash);
    CHECK(c->hash == fnv1a64(c->effective_yaml));
    config_free(&back);
}

static void test_lampshade_defaults(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load(LAMPSHADE, NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(strcmp(c.path, LAMPSHADE) == 0);
    CHECK(c.width == 256 && c.height == 256);
    CHECK(vec3_eq(c.camera.position, vec3_make(0, 2, 8)) && vec3_eq(c.camera.look_at, vec3_make(0, 1.5, 0)));
    CHECK(c.camera.fov_y_deg == 45.0);
    CHECK(c.n_materials == 3 && strcmp(c.materials[1].name, "red") == 0);
    CHECK(rgb_eq(c.materials[1].albedo, rgb_make(0.63, 0.065, 0.05)) && c.materials[1].kind == MATERIAL_DIFFUSE);

    CHECK(c.n_shapes == 15);
    CHECK(c.shapes[3].material == 1 && c.shapes[4].material == 2 && c.shapes[0].material == 0);
    CHECK(c.shapes[0].n_vertices == 4 && c.shapes[0].n_quads == 1 && c.shapes[0].n_triangles == 0);
    /* The box: 8 corners, 6 faces. */
    CHECK(c.shapes[5].n_vertices == 8 && c.shapes[5].n_quads == 6 && c.shapes[5].n_triangles == 0);
    /* shade_left's first vertex is (-a, 2.2, -a) with a = max(0.6, 0.3) / 2 + 0.05. */
    CHECK_NEAR(c.shapes[6].vertices[0].x, -0.35, 1e-15);
    CHECK_NEAR(c.shapes[6].vertices[0].z, -0.35, 1e-15);
    CHECK(c.shapes[6].vertices[0].y == 2.2);
    /* shade_bottom_left's inner edge at -h = -s_P / 2. */
    CHECK_NEAR(c.shapes[13].vertices[1].x, -0.15, 1e-15);

    CHECK(c.n_lights == 1);
    const struct light_desc *l = &c.lights[0];
    CHECK(strcmp(l->name, "lamp") == 0 && !l->two_sided && l->polygon.n == 4);
    CHECK_NEAR(l->polygon.v[0].x, -0.3, 1e-15);
    CHECK_NEAR(l->polygon.v[2].z, 0.3, 1e-15);
    CHECK(l->polygon.v[1].y == 2.6);
    double k = (0.5 / 0.6) * (0.5 / 0.6);
    CHECK_NEAR(l->radiance.r, 40 * k, 1e-12);
    CHECK_NEAR(l->radiance.g, 34 * k, 1e-12);
    CHECK_NEAR(l->radiance.b, 24 * k, 1e-12);
    /* One-sided, emitting downwards: the winding must give a -y normal. */
    CHECK_NEAR(polygon_normal(&l->polygon).y, -1.0, 1e-12);
    CHECK_NEAR(polygon_area(&l->polygon), 0.36, 1e-12);

    CHECK(c.n_portals == 1 && c.portals[0].light == 0 && strcmp(c.portals[0].name, "opening") == 0);
    CHECK_NEAR(c.portals[0].polygon.v[0].x, -0.15, 1e-15);
    CHECK(c.portals[0].polygon.v[0].y == 2.2);

    const struct render_desc *r = &c.render;
    CHECK(r->integrator == INTEGRATOR_DIRECT && r->strategy == STRATEGY_LIGHT && r->mis == MIS_POWER);
    CHECK(r->portal_weight == PORTAL_WEIGHT_IRRADIANCE && r->defensive == 0.0);
    CHECK(r->max_depth == 8 && r->rr_depth == 3 && r->spp == 64 && r->time_s == 0.0);
    CHECK(r->snapshots.every_s == 0.5 && r->snapshots.n_times == 0 && r->snapshots.doubling_s == 0.0);
    CHECK(r->seed == 1 && r->threads == 0 && strcmp(r->output, "results/renders/lampshade") == 0);
    CHECK(c.effective_yaml != NULL && c.hash == fnv1a64(c.effective_yaml));
    config_free(&c);
    CHECK(is_zeroed(&c));
}

/* The ratio sweep: s_L = 1.2 moves the light, scales its radiance by
   (0.5 / s_L)^2 and widens the shade to a = 1.2 / 2 + 0.05. */
static void test_lampshade_sweep_override(void)
{
    struct config_override o = { "params.s_L", "1.2" };
    struct config c;
    struct error err = { "" };
    bool ok = config_load(LAMPSHADE, &o, 1, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK_NEAR(c.lights[0].polygon.v[0].x, -0.6, 1e-15);
    CHECK_NEAR(c.lights[0].polygon.v[2].x, 0.6, 1e-15);
    CHECK_NEAR(c.lights[0].radiance.r, 40 * (0.5 / 1.2) * (0.5 / 1.2), 1e-12);
    CHECK_NEAR(c.lights[0].radiance.b, 24 * (0.5 / 1.2) * (0.5 / 1.2), 1e-12);
    CHECK_NEAR(c.shapes[6].vertices[0].x, -0.65, 1e-15);
    CHECK_NEAR(c.portals[0].polygon.v[0].x, -0.15, 1e-15);
    /* Light power s_L^2 * L stays the same across the sweep. */
    CHECK_NEAR(polygon_area(&c.lights[0].polygon) * c.lights[0].radiance.r, 0.36 * 40 * (0.5 / 0.6) * (0.5 / 0.6),
               1e-12);
    check_round_trip(&c, "s_L=1.2");
    config_free(&c);
}

static void test_overrides_apply(void)
{
    const struct config_override o[] = {
        { "camera.position.1", "3" }, /* a sequence item */
        { "render.spp", "1" },
        { "render.spp", "128" },          /* the later one wins */
        { "render.time", "5" },           /* absent: added */
        { "shapes.3.material", "white" }, /* index, then key */
        { "lights.0.two_sided", "true" },
        { "render.strategy", "portal" },
        { "render.output", "123" },   /* a plain scalar read as a string */
        { "params.s_P", "=0.2 * 2" }, /* an expression */
        { "render.snapshots.every", "2" },
        { "render.snapshots.every_spp", "8" },
        { "portals.0.name", "hole" },
        { "render.seed", "18446744073709551615" },
        { "render.threads", "8" },
        { "film.width", "=2^7" },
    };
    struct config c;
    struct error err = { "" };
    bool ok = config_load(LAMPSHADE, o, COUNT_OF(o), &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.camera.position.y == 3.0 && c.camera.position.z == 8.0);
    CHECK(c.render.spp == 128 && c.render.time_s == 5.0);
    CHECK(c.shapes[3].material == 0);
    CHECK(c.lights[0].two_sided);
    CHECK(c.render.strategy == STRATEGY_PORTAL);
    CHECK(strcmp(c.render.output, "123") == 0);
    CHECK_NEAR(c.portals[0].polygon.v[0].x, -0.2, 1e-15);
    CHECK_NEAR(c.shapes[6].vertices[0].x, -0.35, 1e-15); /* a = max(0.6, 0.4) / 2 + 0.05 */
    CHECK(c.render.snapshots.every_s == 2.0 && c.render.snapshots.every_spp == 8);
    CHECK(strcmp(c.portals[0].name, "hole") == 0);
    CHECK(c.render.seed == UINT64_MAX);
    CHECK(c.render.threads == 8);
    CHECK(c.width == 128 && c.height == 256);
    check_round_trip(&c, "overrides");
    config_free(&c);
}

/* render.aov: off by default and in the effective YAML either way; --set
   creates the mapping when the file has none. */
static void test_aov_key(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load(LAMPSHADE, NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(!c.render.aov_region);
    CHECK(strstr(c.effective_yaml, "\n  aov: {region: false}\n") != NULL);
    config_free(&c);
    const struct config_override on[] = { { "render.aov.region", "true" } };
    ok = config_load(LAMPSHADE, on, 1, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.render.aov_region);
    CHECK(strstr(c.effective_yaml, "\n  aov: {region: true}\n") != NULL);
    check_round_trip(&c, "aov");
    config_free(&c);
}

static void test_override_errors(void)
{
    static const struct {
        const char *path, *value, *expect;
    } cases[] = {
        { "camera.pos.1", "0", "--set camera.pos.1: no key \"pos\" in camera" },
        { "nothing.x", "0", "--set nothing.x: no key \"nothing\" in the top level" },
        { "shapes.99.material", "white",
          "--set shapes.99.material: index 99 out of range in shapes (expected 0 to 14)" },
        { "shapes.x.material", "white", "--set shapes.x.material: \"x\" is not an index (shapes is a sequence)" },
        { "camera.position", "1",
          "--set camera.position: camera.position is a sequence (only scalars can be overridden)" },
        { "camera", "1", "--set camera: camera is a mapping (only scalars can be overridden)" },
        { "camera.fov_y.x", "1", "--set camera.fov_y.x: camera.fov_y is a scalar" },
        { "camera..x", "1", "--set camera..x: empty key in the path" },
        /* Includes are merged before overrides: one cannot add a file. */
        { "include", "/etc/passwd", "--set include: includes are read with the file; an override cannot add one" },
        { "render.spp", "abc", "--set render.spp=abc: expected a non-negative integer, got \"abc\"" },
        { "render.spp", "-3", "--set render.spp=-3: expected a non-negative integer, got -3" },
        { "render.tme", "5", "--set render.tme=5: unknown key \"tme\" in render (expected integrator," },
        /* render.aov is created when missing, then checked like the file's. */
        { "render.aov.regon", "true",
          "--set render.aov.regon=true: unknown key \"regon\" in render.aov (expected region)" },
        { "render.aov.region", "3", "--set render.aov.region=3: expected true or false, got \"3\"" },
        { "render.aov", "true", "--set render.aov=true: expected a mapping, got \"true\"" },
        { "render.aovs.region", "true", "--set render.aovs.region: no key \"aovs\" in render" },
        { "render.strategy", "prtal",
          "--set render.strategy=prtal: unknown strategy \"prtal\" (expected one of: light_area, light, portal, "
          "projection, antishadow, antishadow_exact)" },
        { "lights.0.two_sided", "yes", "--set lights.0.two_sided=yes: expected true or false, got \"yes\"" },
        { "params.s_L", "=s_Q",
          "--set params.s_L==s_Q: expression \"=s_Q\": unknown name \"s_Q\" (expected one of: pi)" },
        { "params.h", "=s_Q",
          "--set params.h==s_Q: expression \"=s_Q\": unknown name \"s_Q\" (expected one of: s_L, s_P, a, pi)" },
        { "camera.fov_y", ".nan", "--set camera.fov_y=.nan: expected a finite number, got .nan" },
        { "render.output", "\xff", "--set render.output=\xff: not valid UTF-8" },
        /* An override can make a value in the file fail: reported in the file. */
        { "params.s_L", "0",
          "lampshade.yaml:71:15: light \"lamp\" is degenerate (expected a polygon with non-zero area)" },
        { "lights.0.vertices.0.1", "2.7", "lampshade.yaml:71:15: light \"lamp\" is not planar" },
        { "render.spp", "0", "lampshade.yaml:83:3: spp and time are both 0" },
        { "portals.0.light", "lmp", "portal \"opening\" refers to unknown light \"lmp\" (expected one of: lamp)" },
    };
    for (int i = 0; i < COUNT_OF(cases); ++i) {
        struct config_override o = { cases[i].path, cases[i].value };
        struct config c;
        struct error err = { "" };
        bool ok = config_load(LAMPSHADE, &o, 1, &c, &err);
        CHECK_MSG(!ok, "--set %s=%s loaded", cases[i].path, cases[i].value);
        CHECK_MSG(strstr(err.message, cases[i].expect) != NULL, "got: %s\n    expected: %s", err.message,
                  cases[i].expect);
        CHECK(is_zeroed(&c));
        if (ok) config_free(&c);
    }
    struct config_override missing = { NULL, "1" };
    struct config c;
    struct error err = { "" };
    CHECK(!config_load(LAMPSHADE, &missing, 1, &c, &err) && strstr(err.message, "--set") != NULL);
}

static void test_effective_round_trip_and_hash(void)
{
    struct config a, b, c;
    struct error err = { "" };
    bool ok = config_load(LAMPSHADE, NULL, 0, &a, &err) && config_load(LAMPSHADE, NULL, 0, &b, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    check_round_trip(&a, "lampshade");
    CHECK(a.hash == b.hash && strcmp(a.effective_yaml, b.effective_yaml) == 0);
    /* Params are substituted, defaults are filled in. */
    CHECK(strstr(a.effective_yaml, "\nparams:") == NULL && strchr(a.effective_yaml, '=') == NULL);
    CHECK(strstr(a.effective_yaml, "portal_weight: irradiance") != NULL);
    CHECK(strstr(a.effective_yaml, "rr_depth: 3") != NULL);

    /* The smallest change to any value changes the hash: one ulp of fov_y. */
    static const struct config_override changes[][1] = {
        { { "render.spp", "65" } },
        { { "camera.fov_y", "45.000000000000007" } },
        { { "params.s_L", "0.6000000000000001" } },
        { { "shapes.0.material", "red" } },
        { { "render.seed", "2" } },
        { { "render.defensive", "0.1" } },
    };
    for (int i = 0; i < COUNT_OF(changes); ++i) {
        ok = config_load(LAMPSHADE, changes[i], 1, &c, &err);
        CHECK_MSG(ok, "%s", err.message);
        if (!ok) continue;
        CHECK_MSG(c.hash != a.hash, "--set %s=%s kept the hash", changes[i][0].path, changes[i][0].value);
        check_round_trip(&c, changes[i][0].path);
        config_free(&c);
    }
    ok = config_load(LAMPSHADE, changes[1], 1, &c, &err);
    CHECK(ok && c.camera.fov_y_deg == nextafter(45.0, 90.0));
    if (ok) config_free(&c);

    /* Overriding a value with the value it already has keeps the hash. */
    struct config_override same = { "params.s_L", "=1.2 / 2" };
    ok = config_load(LAMPSHADE, &same, 1, &c, &err);
    CHECK(ok && c.hash == a.hash);
    if (ok) config_free(&c);
    config_free(&a);
    config_free(&b);
}

static int compare_names(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Sorted *.yaml names in dir; returns the count (names freed by the caller). */
static int list_yaml(const char *dir, char **names, int max)
{
    DIR *d = opendir(dir);
    int n = 0;
    if (!d) return 0;
    for (struct dirent *e; (e = readdir(d)) != NULL && n < max;) {
        size_t len = strlen(e->d_name);
        if (len > 5 && strcmp(e->d_name + len - 5, ".yaml") == 0) {
            names[n] = malloc(len + 1);
            memcpy(names[n], e->d_name, len + 1);
            ++n;
        }
    }
    closedir(d);
    qsort(names, (size_t)n, sizeof *names, compare_names);
    return n;
}

static void test_bad_catalogue(void)
{
    char *names[512];
    int n = list_yaml(BAD_DIR, names, 512);
    int n_output = 0;
    CHECK_MSG(n >= 45, "only %d bad configs", n);
    for (int i = 0; i < n; ++i) {
        char path[512], line[ERROR_MESSAGE_MAX];
        snprintf(path, sizeof path, "%s/%s", BAD_DIR, names[i]);
        FILE *f = fopen(path, "r");
        bool have = f && fgets(line, sizeof line, f) && strncmp(line, "# expect: ", 10) == 0;
        /* "# stage: output" on the second line: the config is valid, its
           output folder is not; test_cli.c runs the renderer on it. */
        char second[128];
        bool output_stage = have && fgets(second, sizeof second, f) && strncmp(second, "# stage: output", 15) == 0;
        if (f) fclose(f);
        CHECK_MSG(have, "%s: no \"# expect: \" first line", path);
        if (have && output_stage) {
            struct config c;
            struct error err = { "" };
            bool ok = config_load(path, NULL, 0, &c, &err);
            CHECK_MSG(ok, "%s (stage: output) does not load: %s", path, err.message);
            if (ok) config_free(&c);
            ++n_output;
        } else if (have) {
            line[strcspn(line, "\n")] = '\0';
            const char *expect = line + 10;
            char location[300];
            snprintf(location, sizeof location, "bad/%s:", names[i]);
            /* The location, or (for an error in an included file) the
               include entry that led there. */
            CHECK_MSG(strstr(expect, location) != NULL, "%s: expectation must name %s", path, location);
            struct config c;
            struct error err = { "" };
            bool ok = config_load(path, NULL, 0, &c, &err);
            CHECK_MSG(!ok, "%s loaded", path);
            CHECK_MSG(strstr(err.message, expect) != NULL, "\n    got:      %s\n    expected: %s", err.message, expect);
            CHECK_MSG(is_zeroed(&c), "%s: config not left empty", path);
            if (ok) config_free(&c);
        }
        free(names[i]);
    }
    printf("  %d bad configs, %d of them for the output folder (test_cli)\n", n, n_output);
}

static void test_good_catalogue(void)
{
    char *names[128];
    int n = list_yaml(GOOD_DIR, names, 128);
    CHECK_MSG(n >= 6, "only %d good configs", n);
    for (int i = 0; i < n; ++i) {
        char path[512];
        snprintf(path, sizeof path, "%s/%s", GOOD_DIR, names[i]);
        struct config c;
        struct error err = { "" };
        bool ok = config_load(path, NULL, 0, &c, &err);
        CHECK_MSG(ok, "%s: %s", path, err.message);
        if (ok) {
            check_round_trip(&c, path);
            config_free(&c);
        }
        free(names[i]);
    }
}

/* Spot checks of values only the good files exercise. */
static void test_good_values(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load(GOOD_DIR "/render_all_fields.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        const struct render_desc *r = &c.render;
        CHECK(c.width == 32 && c.height == 16 && c.camera.fov_y_deg == 45.0);
        CHECK(vec3_eq(c.camera.position, vec3_make(0, 1, 5)));
        CHECK(r->integrator == INTEGRATOR_PATH && r->strategy == STRATEGY_ANTISHADOW && r->mis == MIS_NONE);
        CHECK(r->portal_weight == PORTAL_WEIGHT_DISTANCE && r->defensive == 0.25);
        CHECK(r->max_depth == 12 && r->rr_depth == 5 && r->spp == 0 && r->time_s == 2.5);
        CHECK(r->snapshots.every_s == 1.0 && r->snapshots.doubling_s == 0.125 && r->snapshots.every_spp == 16);
        CHECK(r->snapshots.n_times == 3 && r->snapshots.times_s[2] == 2.0);
        CHECK(r->snapshots.n_spps == 3 && r->snapshots.spps[2] == 64);
        CHECK(r->seed == UINT64_MAX && r->threads == 4);
        CHECK(strcmp(r->output, "results/renders/all fields \"quoted\"") == 0);
        CHECK(r->aov_region);
        CHECK(strstr(c.effective_yaml, "\n  aov: {region: true}\n") != NULL);
        CHECK(c.n_shapes == 0 && c.n_materials == 0 && c.shapes == NULL);
        config_free(&c);
    }
    ok = config_load(GOOD_DIR "/pentagon_tilted_portal.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        const struct polygon *p = &c.lights[0].polygon;
        CHECK(p->n == 5);
        /* Area of a regular pentagon of circumradius r: (5/2) r^2 sin(72 deg). */
        CHECK_NEAR(polygon_area(p), 2.5 * 0.16 * sin(2 * M_PI / 5), 1e-12);
        CHECK_NEAR(polygon_normal(p).y, -1.0, 1e-12);
        CHECK(c.portals[0].light == 0 && c.render.strategy == STRATEGY_ANTISHADOW_EXACT);
        config_free(&c);
    }
    ok = config_load(GOOD_DIR "/triangle_light.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(c.lights[0].polygon.n == 3 && strcmp(c.portals[0].name, "portal0") == 0);
        config_free(&c);
    }
    ok = config_load(GOOD_DIR "/mesh_scene.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(c.n_shapes == 3 && c.shapes[0].n_quads == 1 && c.shapes[0].n_triangles == 1);
        CHECK(c.shapes[1].n_triangles == 4 && c.shapes[1].quads == NULL);
        CHECK(c.shapes[0].triangles[0][1] == 4 && c.shapes[0].quads[0][3] == 1);
        config_free(&c);
    }
}

/* A light whose last vertex is lifted out of the plane by eps times the
   light's size, in a scene scaled by `scale`. */
static bool load_scaled_light(double scale, double eps, struct error *err)
{
    char text[1024];
    snprintf(text, sizeof text,
             "params: {k: %.17g, e: %.17g}\n"
             "camera: {position: [0, 0, \"=5*k\"], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 30}\n"
             "film: {width: 1, height: 1}\n"
             "lights:\n"
             "  - name: l\n"
             "    vertices: [[0, 0, 0], [\"=k\", 0, 0], [\"=k\", \"=k\", 0], [0, \"=k\", \"=e * k\"]]\n"
             "    radiance: [1, 1, 1]\n"
             "render: {spp: 1}\n",
             scale, eps);
    struct config c;
    bool ok = config_load_string(text, strlen(text), "scaled", NULL, 0, &c, err);
    if (ok) config_free(&c);
    return ok;
}

/* Tolerances are relative: the verdict does not depend on the units. */
static void test_tolerances_are_relative(void)
{
    static const double scales[] = { 1e-3, 1.0, 1e3 };
    for (int i = 0; i < 3; ++i) {
        struct error err = { "" };
        CHECK_MSG(load_scaled_light(scales[i], 0.0, &err), "scale %g: %s", scales[i], err.message);
        CHECK_MSG(load_scaled_light(scales[i], 1e-9, &err), "scale %g: %s", scales[i], err.message);
        CHECK(!load_scaled_light(scales[i], 1e-4, &err) && strstr(err.message, "is not planar") != NULL);
    }
}

static void test_load_string_and_files(void)
{
    const char *text = "camera: {position: [0, 0, 1], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 30}\n"
                       "film: {width: 1, height: 1}\n"
                       "lights: [{name: a, vertices: [[0, 0, 0], [1, 0, 0], [0, 1, 0]], radiance: [1, 1, 1]}]\n"
                       "render: {spp: 1, seed: 12345678901234567890}\n";
    struct config c;
    struct error err = { "" };
    bool ok = config_load_string(text, strlen(text), "memory", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(c.render.seed == 12345678901234567890ull); /* above 2^53: read exactly */
        CHECK(strcmp(c.path, "memory") == 0 && c.n_portals == 0 && c.portals == NULL);
        check_round_trip(&c, "memory");
        config_free(&c);
    }
    /* Only `length` bytes are read: the text is cut before "render". */
    ok = config_load_string(text, (size_t)(strstr(text, "render") - text), "cut", NULL, 0, &c, &err);
    CHECK(!ok && strstr(err.message, "cut:1:1: missing key \"render\" in the top level") != NULL);

    ok = config_load("tests/configs/no_such_file.yaml", NULL, 0, &c, &err);
    CHECK(!ok && strstr(err.message, "tests/configs/no_such_file.yaml: No such file or directory") != NULL);
    CHECK(is_zeroed(&c));

    /* Invalid UTF-8 in the file is a reader error with a position. */
    const char bad[] = "camera: {position: [0, 0, 1]}\nfilm: \xff\n";
    ok = config_load_string(bad, sizeof bad - 1, "bytes", NULL, 0, &c, &err);
    CHECK_MSG(!ok && strstr(err.message, "bytes:2:7: invalid") != NULL, "%s", err.message);

    config_free(&c); /* freeing an empty config is harmless */
    CHECK(is_zeroed(&c));
}

/* include: the merged result of good/include_merge.yaml (two includes, one
   of them nested) equals the same config written out by hand, and every
   item keeps the file it came from. */
static void test_include_merge(void)
{
    struct config c, e;
    struct error err = { "" };
    bool ok = config_load(GOOD_DIR "/include_merge.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    ok = config_load(GOOD_DIR "/include_merge_expected.yaml", NULL, 0, &e, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(config_same(&c, &e));
        CHECK_MSG(strcmp(c.effective_yaml, e.effective_yaml) == 0, "merged:\n%s\nexpected:\n%s", c.effective_yaml,
                  e.effective_yaml);
        CHECK(c.hash == e.hash);
        config_free(&e);
    }
    CHECK(strstr(c.effective_yaml, "include:") == NULL);
    /* Load order: the file, then its includes depth first. */
    static const char *const order[] = { "good/include_merge.yaml", "include/mid.yaml", "include/base_room.yaml",
                                         "include/render_quick.yaml" };
    CHECK(c.n_files == 4 && strcmp(c.files[0], c.path) == 0);
    for (int i = 0; i < c.n_files && i < 4; ++i)
        CHECK_MSG(strstr(c.files[i], order[i]) != NULL, "file %d: %s", i, c.files[i]);
    CHECK(strcmp(c.files[2], GOOD_DIR "/include/base_room.yaml") == 0);
    /* Where each item was defined: the file and position that won. */
    CHECK(c.n_materials == 3 && strstr(c.materials[0].loc.file, "base_room.yaml") && c.materials[0].loc.line == 9);
    CHECK(strstr(c.materials[1].loc.file, "mid.yaml") && c.materials[1].loc.line == 5);
    CHECK(strstr(c.materials[2].loc.file, "mid.yaml") && c.materials[2].loc.line == 6);
    CHECK(strstr(c.lights[0].loc.file, "base_room.yaml") && c.lights[0].loc.line == 14);
    CHECK(c.shapes[1].loc.file == c.files[0] && c.shapes[1].loc.line == 10);
    CHECK(c.output_override == -1 && c.output_loc.file == c.files[0] && c.output_loc.line == 15 &&
          c.output_loc.column == 11);
    config_free(&c);
    CHECK(is_zeroed(&c));
}

/* The canonical scene included whole and partly overridden equals the
   scene with the same values given as --set overrides. */
static void test_include_lampshade(void)
{
    static const struct config_override o[] = {
        { "params.s_L", "1.2" },
        { "film.width", "64" },
        { "render.strategy", "antishadow" },
        { "render.spp", "16" },
        { "render.snapshots.every_spp", "4" },
        { "render.output", "results/renders/lampshade_include" },
    };
    struct config c, e;
    struct error err = { "" };
    bool ok = config_load(GOOD_DIR "/include_lampshade.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    ok = config_load(LAMPSHADE, o, COUNT_OF(o), &e, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(config_same(&c, &e));
        CHECK(strcmp(c.effective_yaml, e.effective_yaml) == 0 && c.hash == e.hash);
        CHECK(c.render.snapshots.every_s == 0.5 && c.render.snapshots.every_spp == 4 && c.height == 256);
        config_free(&e);
    }
    CHECK(c.n_files == 2 && strcmp(c.files[1], GOOD_DIR "/../../../configs/scenes/lampshade.yaml") == 0);
    config_free(&c);
}

/* --set applies to the merged result, whichever file a value came from;
   an error that an override causes in an included value names that file
   and the include chain. */
static void test_include_overrides(void)
{
    const struct config_override o[] = {
        { "camera.position.1", "3" }, /* camera.position is only in base_room.yaml */
        { "params.y", "2.5" },        /* a param of base_room.yaml that only it uses */
        { "materials.red.albedo.0", "0.25" },
    };
    struct config c;
    struct error err = { "" };
    bool ok = config_load(GOOD_DIR "/include_merge.yaml", o, COUNT_OF(o), &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(c.camera.position.y == 3.0 && c.camera.fov_y_deg == 30.0);
        CHECK(c.lights[0].polygon.v[0].y == 2.5 && c.lights[0].polygon.v[1].x == 0.25);
        CHECK(c.materials[1].albedo.r == 0.25 && c.materials[1].albedo.g == 0.1);
        check_round_trip(&c, "include + overrides");
        config_free(&c);
    }
    struct config_override zero = { "params.size", "0" };
    ok = config_load(GOOD_DIR "/include_merge.yaml", &zero, 1, &c, &err);
    CHECK(!ok);
    CHECK_MSG(strstr(err.message, GOOD_DIR "/include/base_room.yaml:15:15: light \"sky\" is degenerate") &&
                  strstr(err.message, "(included from " GOOD_DIR "/include/mid.yaml:3:10, from " GOOD_DIR
                                      "/include_merge.yaml:5:11)"),
              "got: %s", err.message);
    struct config_override bad = { "render.integrator", "pth" };
    ok = config_load(GOOD_DIR "/include_merge.yaml", &bad, 1, &c, &err);
    CHECK(!ok && strncmp(err.message, "--set render.integrator=pth: unknown integrator", 47) == 0);
}

static bool write_text(const char *dir, const char *name, const char *text)
{
    char path[600];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) return false;
    bool ok = fputs(text, f) >= 0;
    return (fclose(f) == 0) && ok;
}

/* Includes found through the file system: a diamond (two files include the
   same one) is not a cycle, a cycle through another spelling of a path is
   one, an unreadable file is an error at the include entry, and a config
   given as a string cannot include. */
static void test_include_files(void)
{
    char dir[] = "/tmp/portal-include-XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK_MSG(false, "mkdtemp: %s", strerror(errno));
        return;
    }
    static const char room[] =
        "camera: {position: [0, 1, 5], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
        "film: {width: 4, height: 4}\n"
        "lights: [{name: sky, vertices: [[-1, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]], radiance: [1, 1, 1]}]\n"
        "render: {spp: 1}\n";
    char path[700];
    CHECK(write_text(dir, "d.yaml", room));
    CHECK(write_text(dir, "b.yaml", "include: d.yaml\nfilm: {width: 8}\n"));
    CHECK(write_text(dir, "c.yaml", "include: ./d.yaml\nfilm: {height: 2}\n"));
    CHECK(write_text(dir, "a.yaml", "include: [b.yaml, c.yaml]\n"));
    CHECK(write_text(dir, "loop.yaml", "include: ./loop.yaml\n"));
    CHECK(write_text(dir, "secret.yaml", room));
    CHECK(write_text(dir, "uses_secret.yaml", "include: secret.yaml\n"));
    CHECK(write_text(dir, "uses_mem.yaml", "include: /proc/self/mem\n"));
    struct config c;
    struct error err = { "" };
    snprintf(path, sizeof path, "%s/a.yaml", dir);
    bool ok = config_load(path, NULL, 0, &c, &err);
    CHECK_MSG(ok, "diamond: %s", err.message);
    if (ok) {
        /* c.yaml re-includes d.yaml, whose width 4 then wins over b.yaml's 8. */
        CHECK(c.width == 4 && c.height == 2 && c.n_files == 5);
        config_free(&c);
    }
    snprintf(path, sizeof path, "%s/loop.yaml", dir);
    CHECK(!config_load(path, NULL, 0, &c, &err));
    CHECK_MSG(strstr(err.message, "loop.yaml:1:10: include \"./loop.yaml\": include cycle"), "%s", err.message);

    /* Permissions do not stop root: then only the message is not checked. */
    snprintf(path, sizeof path, "%s/secret.yaml", dir);
    CHECK(chmod(path, 0) == 0);
    snprintf(path, sizeof path, "%s/uses_secret.yaml", dir);
    ok = config_load(path, NULL, 0, &c, &err);
    if (geteuid() != 0) {
        CHECK_MSG(!ok && strstr(err.message, "uses_secret.yaml:1:10: include \"secret.yaml\": cannot read") &&
                      strstr(err.message, "Permission denied"),
                  "%s", err.message);
    } else {
        printf("  include of a chmod 000 file: not checked as root (it loads)\n");
        if (ok) config_free(&c);
    }
    /* A file that opens but cannot be read, even by root: reading
       /proc/self/mem at offset 0 fails with EIO. */
    snprintf(path, sizeof path, "%s/uses_mem.yaml", dir);
    CHECK(!config_load(path, NULL, 0, &c, &err));
    CHECK_MSG(strstr(err.message, "uses_mem.yaml:1:10: include \"/proc/self/mem\": cannot read /proc/self/mem: "
                                  "Input/output error"),
              "%s", err.message);
    CHECK(is_zeroed(&c));

    /* Aliases of mappings, 40 levels each doubling the paths: copying keeps
       them shared, and merging two such trees stops at a bound instead of
       making 2^40 mappings. */
    static char bomb[8192];
    int len = snprintf(bomb, sizeof bomb, "params:\n  x0: &a0 {k: 1}\n");
    for (int i = 1; i <= 40; ++i)
        len += snprintf(bomb + len, sizeof bomb - (size_t)len, "  x%d: &a%d {p: *a%d, q: *a%d}\n", i, i, i - 1, i - 1);
    CHECK(write_text(dir, "bomb.yaml", bomb));
    CHECK(write_text(dir, "bomb_base.yaml", bomb));
    snprintf(bomb + len, sizeof bomb - (size_t)len, "include: bomb_base.yaml\n");
    CHECK(write_text(dir, "bomb_over.yaml", bomb));
    snprintf(path, sizeof path, "%s/bomb_over.yaml", dir);
    CHECK(!config_load(path, NULL, 0, &c, &err));
    CHECK_MSG(strstr(err.message, "bomb_over.yaml:") && strstr(err.message, "merging the includes makes more than"),
              "%s", err.message);
    CHECK(write_text(dir, "bomb_top.yaml", "include: bomb.yaml\n"));
    snprintf(path, sizeof path, "%s/bomb_top.yaml", dir);
    CHECK(!config_load(path, NULL, 0, &c, &err));
    CHECK_MSG(strstr(err.message, "bomb.yaml:2:7: expected a number, got a mapping (included from"), "%s", err.message);

    const char text[] = "# a comment\ninclude: d.yaml\n";
    CHECK(!config_load_string(text, strlen(text), "memory", NULL, 0, &c, &err));
    CHECK_MSG(strstr(err.message, "memory:2:1: include is not available for a config given as a string"), "%s",
              err.message);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0);
}

/* Inputs the fuzzer once crashed on (tests/configs/fuzz/): each must load or
   fail cleanly, and what loads must round-trip. */
static void test_fuzz_regressions(void)
{
    DIR *d = opendir(FUZZ_DIR);
    int n = 0;
    if (!d) return;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (e->d_name[0] == '.') continue;
        char path[512];
        snprintf(path, sizeof path, "%s/%s", FUZZ_DIR, e->d_name);
        FILE *f = fopen(path, "rb");
        if (!f) continue;
        static char text[1 << 16];
        size_t len = fread(text, 1, sizeof text, f);
        fclose(f);
        struct config c;
        struct error err = { "" };
        if (config_load_string(text, len, e->d_name, NULL, 0, &c, &err)) {
            check_round_trip(&c, path);
            config_free(&c);
        } else {
            CHECK_MSG(err.message[0] != '\0' && is_zeroed(&c), "%s: failed without a message", path);
        }
        ++n;
    }
    closedir(d);
    printf("  %d fuzz regression inputs\n", n);
}

static void test_expressions(void)
{
    const struct expr_var vars[] = { { "a", 2.0 }, { "b_2", 3.0 } };
    static const struct {
        const char *text;
        double value;
    } ok_cases[] = {
        { "1 + 2 * 3", 7.0 },    { "(1 + 2) * 3", 9.0 },    { "2 ^ 3 ^ 2", 512.0 }, /* right-assoc */
        { "-2 ^ 2", -4.0 },      { "2 ^ -1", 0.5 },         { "a * b_2 - 1", 5.0 },
        { "8 / 4 / 2", 1.0 },    { "1 - 2 - 3", -4.0 },     { "--a", 2.0 },
        { "min(3, a, 7)", 2.0 }, { "max(1, b_2)", 3.0 },    { "abs(-a)", 2.0 },
        { "sqrt(16)", 4.0 },     { "cos(pi)", -1.0 },       { "sin(0)", 0.0 },
        { "tan(0)", 0.0 },       { ".5e1 + 1.5E-1", 5.15 }, { " 7 ", 7.0 },
    };
    for (int i = 0; i < COUNT_OF(ok_cases); ++i) {
        double v = NAN;
        struct error err = { "" };
        bool ok = expr_eval(ok_cases[i].text, vars, 2, &v, &err);
        CHECK_MSG(ok, "%s: %s", ok_cases[i].text, err.message);
        CHECK_NEAR(v, ok_cases[i].value, 1e-15 * fabs(ok_cases[i].value) + 1e-15);
    }
    static const struct {
        const char *text, *expect;
    } bad_cases[] = {
        { "c + 1", "unknown name \"c\" (expected one of: a, b_2, pi)" },
        { "1 +", "unexpected end of expression" },
        { "1 + * 2", "syntax error at \"* 2\"" },
        { "(1", "expected \")\"" },
        { "1 2", "syntax error at \"2\" (expected an operator or the end)" },
        { "1 / 0", "division by zero" },
        { "1 / (a - 2)", "division by zero" },
        { "10 ^ 400", "power is not finite" },
        { "1e400", "number is not finite" },
        { "sqrt(-1)", "sqrt of a negative number" },
        { "min(1)", "min takes at least 2 arguments, got 1" },
        { "abs(1, 2)", "abs takes 1 argument, got 2" },
        { "foo(1)", "unknown function \"foo\"" },
        { "sqrt 4", "expected \"(\" after a function name" },
        { "", "unexpected end of expression" },
        { "1e", "expected an exponent" },
        { "inf", "unknown name \"inf\"" },
        { "((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((1))))))))))))))))))))))"
          "))))))))))))))))))))))))))))))))))))))))))))))",
          "nested too deeply" },
    };
    for (int i = 0; i < COUNT_OF(bad_cases); ++i) {
        double v = 0.0;
        struct error err = { "" };
        CHECK_MSG(!expr_eval(bad_cases[i].text, vars, 2, &v, &err), "\"%s\" evaluated", bad_cases[i].text);
        CHECK_MSG(strstr(err.message, bad_cases[i].expect) != NULL, "\"%s\": got %s", bad_cases[i].text, err.message);
    }
    /* A long chain of powers recurses too; it must be bounded as well. */
    char chain[400] = "2";
    for (int i = 0; i < 100; ++i) strcat(chain, "^1");
    double v;
    struct error err;
    CHECK(!expr_eval(chain, vars, 2, &v, &err) && strstr(err.message, "nested too deeply") != NULL);
    CHECK(expr_is_identifier("s_L") && expr_is_identifier("_x1") && !expr_is_identifier("1x") &&
          !expr_is_identifier("s-L") && !expr_is_identifier(""));
    CHECK(expr_is_reserved("pi") && expr_is_reserved("sqrt") && !expr_is_reserved("s_L"));
}

/* Not named `tests`: TEST_MAIN's parameter of that name would shadow it. */
static const struct test_case config_tests[] = {
    { "lampshade_defaults", test_lampshade_defaults },
    { "lampshade_sweep_override", test_lampshade_sweep_override },
    { "overrides_apply", test_overrides_apply },
    { "override_errors", test_override_errors },
    { "effective_round_trip_and_hash", test_effective_round_trip_and_hash },
    { "bad_catalogue", test_bad_catalogue },
    { "aov_key", test_aov_key },
    { "good_catalogue", test_good_catalogue },
    { "good_values", test_good_values },
    { "tolerances_are_relative", test_tolerances_are_relative },
    { "load_string_and_files", test_load_string_and_files },
    { "expressions", test_expressions },
    { "include_merge", test_include_merge },
    { "include_lampshade", test_include_lampshade },
    { "include_overrides", test_include_overrides },
    { "include_files", test_include_files },
    { "fuzz_regressions", test_fuzz_regressions },
};
TEST_MAIN(config_tests)

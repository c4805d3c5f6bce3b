/* `render --print-config`: the configuration a render would use, printed
   instead of rendered. The YAML is the config.yaml a render writes, byte
   for byte; the JSON holds the same tree, the params, the files and the
   hashes (checked against config_load in this process); every config error
   is reported exactly as a render reports it; nothing is created. */
#include <dirent.h>
#include <inttypes.h>

#include "cli_util.h"
#include "config/config.h"
#include "cli/exit_code.h"
#include "json_util.h"
#include "scene/portal_report.h"
#include "testlib.h"

#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        s = NULL;
    }
    if (s) s[n] = '\0';
    fclose(f);
    return s;
}

/* argv for a render of lampshade with overrides into out, with `extra`
   (NULL-terminated, at most 4) appended. */
#define LAMPSHADE_ARGS(out)                                                                                            \
    "configs/scenes/lampshade.yaml", "--set", "params.s_L=1.2", "--strategy", "antishadow", "--spp", "2", "--out",     \
        out, "--set", "film.width=8", "--set", "film.height=6", "--set", "render.snapshots.doubling_spp=1",            \
        "--threads", "1", "--quiet"

/* The overrides of LAMPSHADE_ARGS, for config_load in this process. */
static void lampshade_overrides(struct config_override ov[8], const char *out)
{
    const struct config_override o[8] = {
        { "params.s_L", "1.2" },
        { "render.strategy", "antishadow" },
        { "render.spp", "2" },
        { "render.output", out },
        { "film.width", "8" },
        { "film.height", "6" },
        { "render.snapshots.doubling_spp", "1" },
        { "render.threads", "1" },
    };
    memcpy(ov, o, sizeof o);
}

static void test_yaml_is_the_rendered_config_yaml(void)
{
    char dir[] = "/tmp/portal-print-XXXXXX";
    make_tmpdir(dir);
    struct run r, p;
    char *a[] = { NULL, LAMPSHADE_ARGS(dir), NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_DONE, "status %d: %s", r.status, r.err);
    char path[600];
    snprintf(path, sizeof path, "%s/config.yaml", dir);
    char *written = slurp(path);
    CHECK(written != NULL);
    char *b[] = { NULL, "--print-config", LAMPSHADE_ARGS(dir), NULL };
    run_render(b, 0, 0, &p);
    CHECK_MSG(p.status == EXIT_DONE, "status %d: %s", p.status, p.err);
    CHECK_MSG(written && !strcmp(p.out, written), "--print-config:\n%s\nconfig.yaml:\n%s", p.out, written);
    CHECK(!p.err[0]);
    /* --format yaml is the default, said out loud. */
    char *c[] = { NULL, "--print-config", LAMPSHADE_ARGS(dir), "--format", "yaml", NULL };
    run_render(c, 0, 0, &r);
    CHECK(r.status == EXIT_DONE && written && !strcmp(r.out, written));
    free(written);
    remove_tree(dir);
}

/* The output folder, and its parent, are not created, in either format. */
static void test_nothing_is_created(void)
{
    char dir[] = "/tmp/portal-print-XXXXXX";
    make_tmpdir(dir);
    char out[600];
    snprintf(out, sizeof out, "%s/parent/never", dir);
    const char *formats[] = { "yaml", "json" };
    for (int i = 0; i < 2; ++i) {
        struct run r;
        char *a[] = { NULL, "--print-config", LAMPSHADE_ARGS(out), "--format", (char *)formats[i], NULL };
        run_render(a, 0, 0, &r);
        CHECK_MSG(r.status == EXIT_DONE, "%s: status %d: %s", formats[i], r.status, r.err);
        CHECK(strstr(r.out, out) != NULL);
        snprintf(out, sizeof out, "%s/parent", dir);
        CHECK_MSG(!exists(out), "%s: %s was created", formats[i], out);
        snprintf(out, sizeof out, "%s/parent/never", dir);
    }
    DIR *d = opendir(dir);
    int entries = 0;
    for (struct dirent *e; d && (e = readdir(d));) entries += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d) closedir(d);
    CHECK(entries == 0);
    remove_tree(dir);
}

static bool is_hex16(const struct jval *v, uint64_t want)
{
    char buf[24];
    snprintf(buf, sizeof buf, "%016" PRIx64, want);
    return v && v->type == J_STRING && !strcmp(v->text, buf);
}

/* Runs --print-config --format json with args and parses the one line. */
static bool print_json(char **argv, struct jval *v)
{
    struct run r;
    run_render(argv, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_DONE, "status %d: %s", r.status, r.err);
    size_t n = strlen(r.out);
    CHECK_MSG(n > 0 && r.out[n - 1] == '\n' && strchr(r.out, '\n') == r.out + n - 1, "not one line: %s", r.out);
    char why[200];
    bool ok = r.status == EXIT_DONE && json_parse(r.out, v, why);
    CHECK_MSG(ok, "%s in %s", why, r.out);
    return ok;
}

static void test_json_has_the_config_params_files_and_hashes(void)
{
    const char *out = "/tmp/portal-print-never-made";
    char *a[] = { NULL, "--print-config", LAMPSHADE_ARGS((char *)out), "--format", "json", NULL };
    struct jval v;
    if (!print_json(a, &v)) return;
    static const char *const keys[] = { "config", "params", "files", "hash", "image_hash" };
    CHECK(v.type == J_OBJECT && v.n == COUNT(keys));
    for (int i = 0; i < v.n && i < COUNT(keys); ++i) CHECK(!strcmp(v.keys[i], keys[i]));

    struct config cfg;
    struct config_override ov[8];
    struct error err;
    lampshade_overrides(ov, out);
    bool loaded = config_load("configs/scenes/lampshade.yaml", ov, 8, &cfg, &err);
    CHECK_MSG(loaded, "%s", err.message);
    if (!loaded) {
        jfree(&v);
        return;
    }
    CHECK(is_hex16(json_get(&v, "hash"), cfg.hash));
    CHECK(is_hex16(json_get(&v, "image_hash"), cfg.image_hash));
    /* Params after the override, evaluated, in file order. */
    const struct jval *params = json_get(&v, "params");
    static const char *const names[] = { "s_L", "s_P", "a", "h" };
    const double values[] = { 1.2, 0.3, 1.2 / 2 + 0.05, 0.3 / 2 };
    CHECK(params && params->type == J_OBJECT && params->n == 4 && cfg.n_params == 4);
    for (int i = 0; params && i < params->n && i < 4; ++i) {
        CHECK(!strcmp(params->keys[i], names[i]) && !strcmp(cfg.params[i].name, names[i]));
        CHECK_MSG(params->items[i].type == J_NUMBER && same_bits(params->items[i].number, cfg.params[i].value),
                  "%s = %s", names[i], params->items[i].text ? params->items[i].text : "?");
        CHECK(same_bits(cfg.params[i].value, values[i]));
    }
    const struct jval *files = json_get(&v, "files");
    CHECK(files && files->type == J_ARRAY && files->n == 1 && !strcmp(files->items[0].text, cfg.files[0]));
    /* The tree: the sections of the effective YAML, typed. */
    const struct jval *c = json_get(&v, "config");
    static const char *const sections[] = { "camera", "film", "materials", "shapes", "lights", "portals", "render" };
    CHECK(c && c->type == J_OBJECT && c->n == COUNT(sections));
    for (int i = 0; c && i < c->n && i < COUNT(sections); ++i) CHECK(!strcmp(c->keys[i], sections[i]));
    const struct jval *film = json_get(c, "film"), *render = json_get(c, "render");
    CHECK(json_get(film, "width") && json_get(film, "width")->number == 8 && json_get(film, "height")->number == 6);
    CHECK(json_get(render, "strategy") && !strcmp(json_get(render, "strategy")->text, "antishadow"));
    CHECK(json_get(render, "output") && !strcmp(json_get(render, "output")->text, out));
    CHECK(json_get(render, "resumable") && json_get(render, "resumable")->type == J_BOOL);
    CHECK(json_get(render, "threads") && json_get(render, "threads")->number == 1);
    const struct jval *shapes = json_get(c, "shapes");
    CHECK(shapes && shapes->type == J_ARRAY && shapes->n == cfg.n_shapes);
    const struct jval *lights = json_get(c, "lights");
    const struct jval *radiance = lights && lights->n == 1 ? json_get(&lights->items[0], "radiance") : NULL;
    CHECK(radiance && radiance->n == 3);
    for (int k = 0; radiance && k < 3; ++k) {
        double want = k == 0 ? cfg.lights[0].radiance.r : k == 1 ? cfg.lights[0].radiance.g : cfg.lights[0].radiance.b;
        CHECK_MSG(same_bits(radiance->items[k].number, want), "radiance %d: %s", k, radiance->items[k].text);
    }
    config_free(&cfg);
    jfree(&v);

    /* No params: an empty object. */
    char *b[] = { NULL, "--print-config", "tests/configs/good/minimal.yaml", "--format", "json", NULL };
    if (print_json(b, &v)) {
        const struct jval *p = json_get(&v, "params");
        CHECK(p && p->type == J_OBJECT && p->n == 0);
        jfree(&v);
    }
}

/* Every included file, in load order, as config_load has them. */
static void test_json_lists_the_included_files(void)
{
    const char *configs[] = { "tests/configs/good/include_lampshade.yaml", "tests/configs/good/include_merge.yaml" };
    for (int i = 0; i < 2; ++i) {
        char *a[] = { NULL, "--print-config", (char *)configs[i], "--format", "json", NULL };
        struct jval v;
        if (!print_json(a, &v)) continue;
        struct config cfg;
        struct error err;
        if (!config_load(configs[i], NULL, 0, &cfg, &err)) {
            CHECK_MSG(false, "%s", err.message);
            jfree(&v);
            continue;
        }
        const struct jval *files = json_get(&v, "files");
        CHECK_MSG(files && files->type == J_ARRAY && files->n == cfg.n_files && cfg.n_files >= 2, "%s: %d files",
                  configs[i], cfg.n_files);
        for (int k = 0; files && k < files->n && k < cfg.n_files; ++k)
            CHECK_MSG(!strcmp(files->items[k].text, cfg.files[k]), "%s vs %s", files->items[k].text, cfg.files[k]);
        CHECK(files && files->n > 0 && !strcmp(files->items[0].text, configs[i]));
        config_free(&cfg);
        jfree(&v);
    }
}

/* Every bad config fails under --print-config exactly as under a render:
   same status, same stderr, nothing on stdout, nothing created. The
   output_* configs are about the folder, which --print-config never makes. */
static void test_errors_are_a_renders_errors(void)
{
    char dir[] = "/tmp/portal-print-XXXXXX";
    make_tmpdir(dir);
    char out[600];
    snprintf(out, sizeof out, "%s/never", dir);
    DIR *d = opendir("tests/configs/bad");
    CHECK(d != NULL);
    int checked = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        size_t n = strlen(e->d_name);
        if (n < 6 || strcmp(e->d_name + n - 5, ".yaml") || !strncmp(e->d_name, "output_", 7)) continue;
        char path[400];
        snprintf(path, sizeof path, "tests/configs/bad/%s", e->d_name);
        struct run r, p;
        char *a[] = { NULL, path, "--out", out, "--quiet", NULL };
        run_render(a, 0, 0, &r);
        char *b[] = { NULL, "--print-config", path, "--out", out, "--format", "json", NULL };
        run_render(b, 0, 0, &p);
        CHECK_MSG(r.status == EXIT_USAGE && p.status == EXIT_USAGE, "%s: status %d (render) and %d (print)", path,
                  r.status, p.status);
        CHECK_MSG(!strcmp(r.err, p.err), "%s: render said\n%s--print-config said\n%s", path, r.err, p.err);
        CHECK_MSG(!p.out[0], "%s: stdout %s", path, p.out);
        /* The file's place, or the override (--out) that cannot apply. */
        CHECK_MSG(strstr(p.err, e->d_name) || strstr(p.err, "--set render.output"), "%s: %s", path, p.err);
        CHECK(!exists(out));
        ++checked;
    }
    if (d) closedir(d);
    CHECK_MSG(checked > 100, "%d bad configs", checked);
    /* A bad --set names the override; a bad value in a file its place. */
    struct run r;
    char *a[] = { NULL, "--print-config", LAMPSHADE_ARGS(out), "--set", "render.strategy=prtal", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_USAGE && strstr(r.err, "--set render.strategy=prtal") && !r.out[0], "%d: %s", r.status,
              r.err);
    char *b[] = { NULL, "--print-config", "tests/configs/bad/unknown_key_camera.yaml", NULL };
    run_render(b, 0, 0, &r);
    int line = 0, column = 0;
    const char *at = strstr(r.err, "unknown_key_camera.yaml:");
    CHECK_MSG(r.status == EXIT_USAGE && at && sscanf(at, "unknown_key_camera.yaml:%d:%d:", &line, &column) == 2 &&
                  line > 0 && column > 0 && !r.out[0],
              "%d: %s", r.status, r.err);
    CHECK(!exists(out));
    remove_tree(dir);
}

static void test_usage_errors(void)
{
    struct run r;
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--format", "json", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_USAGE && strstr(r.err, "--format") && !r.out[0], "%d: %s", r.status, r.err);
    char *b[] = { NULL, "--print-config", "--resume", "/tmp/portal-print-none", NULL };
    run_render(b, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_USAGE && strstr(r.err, "--print-config") && !r.out[0], "%d: %s", r.status, r.err);
    char *c[] = { NULL, "--print-config", "configs/scenes/lampshade.yaml", "--format", "toml", NULL };
    run_render(c, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_USAGE && strstr(r.err, "toml") && !r.out[0], "%d: %s", r.status, r.err);
    char *d[] = { NULL, "--print-config", NULL };
    run_render(d, 0, 0, &r);
    CHECK(r.status == EXIT_USAGE && !r.out[0]);
    char *e[] = { NULL, "--help", NULL };
    run_render(e, 0, 0, &r);
    CHECK(strstr(r.out, "--print-config") && strstr(r.out, "--format yaml|json") && strstr(r.out, "--describe"));
}

/* Names with a quote, a backslash, a tab, non-ASCII letters and a
   character beyond the BMP survive YAML -> JSON: the output is
   well-formed and decodes to the same bytes as config_load has them. */
static void test_json_escapes_names(void)
{
    char dir[] = "/tmp/portal-print-XXXXXX";
    make_tmpdir(dir);
    char path[600];
    snprintf(path, sizeof path, "%s/odd.yaml", dir);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) return;
    /* The material: q"b\t<TAB>é😀; the shape: a\\b/ü. */
    fputs("camera: {position: [0, 1, 5], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
          "film: {width: 4, height: 4}\n"
          "materials:\n"
          "  \"q\\\"b\\\\t\\t\xc3\xa9\xf0\x9f\x98\x80\": {type: diffuse, albedo: [0.5, 0.5, 0.5]}\n"
          "shapes:\n"
          "  - {name: 'a\\b/\xc3\xbc', type: quad, material: \"q\\\"b\\\\t\\t\xc3\xa9\xf0\x9f\x98\x80\",\n"
          "     vertices: [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]}\n"
          "lights:\n"
          "  - {name: sky, vertices: [[-0.5, 2, -0.5], [0.5, 2, -0.5], [0.5, 2, 0.5], [-0.5, 2, 0.5]],\n"
          "     radiance: [1, 1, 1]}\n"
          "render: {spp: 1, output: \"out \\\"dir\\\"\"}\n",
          f);
    fclose(f);
    const char *material = "q\"b\\t\t\xc3\xa9\xf0\x9f\x98\x80", *shape = "a\\b/\xc3\xbc";
    struct config cfg;
    struct error err;
    bool loaded = config_load(path, NULL, 0, &cfg, &err);
    CHECK_MSG(loaded, "%s", err.message);
    CHECK(loaded && cfg.n_materials == 1 && !strcmp(cfg.materials[0].name, material));
    if (loaded) config_free(&cfg);

    struct run r;
    char *a[] = { NULL, "--print-config", path, "--format", "json", NULL };
    run_render(a, 0, 0, &r);
    CHECK_MSG(r.status == EXIT_DONE, "%d: %s", r.status, r.err);
    /* ASCII only, no raw control character. */
    bool ascii = true;
    for (const unsigned char *p = (const unsigned char *)r.out; *p; ++p)
        ascii &= (*p >= 0x20 && *p < 0x7F) || *p == '\n';
    CHECK(ascii);
    struct jval v;
    char why[200];
    bool ok = json_parse(r.out, &v, why);
    CHECK_MSG(ok, "%s in %s", why, r.out);
    if (ok) {
        const struct jval *c = json_get(&v, "config"), *materials = json_get(c, "materials");
        CHECK(materials && materials->n == 1 && !strcmp(materials->keys[0], material));
        const struct jval *shapes = json_get(c, "shapes");
        const struct jval *name = shapes && shapes->n == 1 ? json_get(&shapes->items[0], "name") : NULL;
        const struct jval *mat = shapes && shapes->n == 1 ? json_get(&shapes->items[0], "material") : NULL;
        CHECK(name && name->type == J_STRING && !strcmp(name->text, shape));
        CHECK(mat && mat->type == J_STRING && !strcmp(mat->text, material));
        const struct jval *output = json_get(json_get(c, "render"), "output");
        CHECK(output && !strcmp(output->text, "out \"dir\""));
        jfree(&v);
    }
    /* And the YAML form loads back to the same names. */
    char *b[] = { NULL, "--print-config", path, NULL };
    run_render(b, 0, 0, &r);
    CHECK(r.status == EXIT_DONE);
    loaded = config_load_string(r.out, strlen(r.out), "printed", NULL, 0, &cfg, &err);
    CHECK_MSG(loaded, "%s", err.message);
    CHECK(loaded && !strcmp(cfg.materials[0].name, material));
    if (loaded) config_free(&cfg);
    remove_tree(dir);
}

/* `portals: auto`: --print-config adds what the finder found, per light,
   as YAML comments after the config (a summary line, then the portals as
   ordinary entries that load back as hand portals) and as the JSON member
   "auto_portals"; the same text whatever --threads. */
static const char auto_scene[] =
    "camera: {position: [0, 1, 6], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
    "film: {width: 8, height: 8}\n"
    "materials: {grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}}\n"
    "render: {spp: 1}\n"
    "shapes:\n"
    "  - {type: quad, material: grey, vertices: [[-20, -2, -20], [-20, -2, 20], [20, -2, 20], [20, -2, -20]]}\n"
    "  - {type: mesh, material: grey,\n"
    "     vertices: [[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5],\n"
    "                [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5],\n"
    "                [-0.2, 0, -0.2], [0.2, 0, -0.2], [0.2, 0, 0.2], [-0.2, 0, 0.2]],\n"
    "     quads: [[4, 7, 6, 5], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7],\n"
    "             [0, 8, 9, 1], [1, 9, 10, 2], [2, 10, 11, 3], [3, 11, 8, 0]]}\n"
    "lights:\n"
    "  - {name: bulb, vertices: [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]],\n"
    "     radiance: [1, 1, 1], two_sided: true}\n"
    "  - {name: sky, vertices: [[-1, 5, -1], [1, 5, -1], [1, 5, 1], [-1, 5, 1]], radiance: [1, 1, 1]}\n"
    "portals: auto\n";

static void test_auto_portals_found(void)
{
    char dir[] = "/tmp/portal-print-auto-XXXXXX";
    make_tmpdir(dir);
    char path[600];
    snprintf(path, sizeof path, "%s/shade.yaml", dir);
    FILE *f = fopen(path, "w");
    CHECK(f && fputs(auto_scene, f) >= 0 && fclose(f) == 0);
    struct run y1, y2;
    char *a[] = { NULL, "--print-config", path, "--threads", "1", NULL };
    char *b[] = { NULL, "--print-config", path, "--threads", "2", NULL };
    run_render(a, 0, 0, &y1);
    run_render(b, 0, 0, &y2);
    CHECK_MSG(y1.status == EXIT_DONE && y2.status == EXIT_DONE, "status %d, %d: %s", y1.status, y2.status, y1.err);
    const char *s1 = strstr(y1.out, "# portals: auto found"), *s2 = strstr(y2.out, "# portals: auto found");
    CHECK(s1 && s2 && !strcmp(s1, s2));
    if (!s1) {
        remove_tree(dir);
        return;
    }
    /* The summary: bulb's one portal (the 0.4 x 0.4 hole), nothing missed;
       sky: enclosed by nothing. */
    CHECK_MSG(strstr(s1, "#   bulb: 1 portal(s), area 0.16 m^2") && strstr(s1, " 0 missed)"), "%s", s1);
    CHECK_MSG(strstr(s1, "light \"sky\": no shape encloses it"), "%s", s1);
    /* The count goes on until 300,000 rays escaped (a bound of 1e-5, the
       goal) or 32 batches were cast (portal_report.h): this box's 0.16 m^2
       hole lets 2.8% of the rays out, so it stops at the cap. */
    const char *b1 = strstr(s1, "bound ");
    double bound = b1 ? strtod(b1 + 6, NULL) : 1.0;
    long escaped = 0, rays = 0;
    const char *open = b1 ? strchr(b1, '(') : NULL, *of = open ? strstr(open, " of ") : NULL;
    if (open) escaped = strtol(open + 1, NULL, 10);
    if (of) rays = strtol(of + 4, NULL, 10);
    bool goal = escaped >= PORTAL_FINDER_SUMMARY_ESCAPED && bound <= 1e-5;
    bool capped = rays == PORTAL_FINDER_SUMMARY_MAX_BATCHES * PORTAL_FINDER_SUMMARY_RAYS;
    CHECK_MSG(goal != capped && escaped > 100000 && fabs(bound - 3.0 / (double)escaped) <= 1e-3 * bound,
              "bound %g over %ld escaped of %ld rays", bound, escaped, rays);
    /* Frozen: the comment lines after "# portals:" uncommented in place of
       `portals: auto` load as hand portals, the found ones bit for bit. */
    static char frozen[1 << 15];
    const char *entries = strstr(s1, "# portals:\n");
    int n = snprintf(frozen, sizeof frozen, "%.*sportals:\n", (int)(strstr(auto_scene, "portals: auto") - auto_scene),
                     auto_scene);
    for (const char *l = entries ? strchr(entries, '\n') + 1 : ""; *l == '#'; l = strchr(l, '\n') + 1)
        n += snprintf(frozen + n, sizeof frozen - (size_t)n, "%.*s", (int)(strchr(l, '\n') + 1 - (l + 1)), l + 1);
    struct config cfg;
    struct error err;
    bool loaded = config_load_string(frozen, strlen(frozen), "frozen.yaml", NULL, 0, &cfg, &err);
    CHECK_MSG(loaded, "%s\n%s", err.message, frozen);
    if (loaded) {
        CHECK(cfg.n_portals == 1 && !cfg.lights[0].auto_portals && !strcmp(cfg.portals[0].name, "bulb_auto0"));
        config_free(&cfg);
    }
    /* JSON: the same numbers per light, and the vertices exactly. */
    struct jval v;
    char *c[] = { NULL, "--print-config", path, "--format", "json", NULL };
    if (print_json(c, &v)) {
        const struct jval *ap = json_get(&v, "auto_portals"), *bulb = json_get(ap, "bulb"), *sky = json_get(ap, "sky");
        CHECK(bulb && sky && json_get(bulb, "n_portals") && json_get(bulb, "n_portals")->number == 1);
        CHECK(bulb && json_get(bulb, "n_missed") && json_get(bulb, "n_missed")->number == 0);
        CHECK(bulb && json_get(bulb, "n_escaped") && json_get(bulb, "n_escaped")->number > 1000);
        CHECK(bulb && json_get(bulb, "bound") && json_get(bulb, "bound")->number < 3e-3);
        CHECK(bulb && json_get(bulb, "blocked_fraction") && json_get(bulb, "blocked_fraction")->number == 0);
        CHECK(bulb && json_get(bulb, "area") && fabs(json_get(bulb, "area")->number - 0.16) < 1e-9);
        const struct jval *ports = bulb ? json_get(bulb, "portals") : NULL;
        CHECK(ports && ports->n == 1 && json_get(&ports->items[0], "vertices")->n == 4);
        CHECK(sky && json_get(sky, "enclosed")->type == J_BOOL && json_get(sky, "n_portals")->number == 0);
        jfree(&v);
    }
    /* Without auto there is no member and no comment. */
    struct run r;
    char *d[] = { NULL, "--print-config", "configs/scenes/lampshade.yaml", "--format", "json", NULL };
    if (print_json(d, &v)) {
        CHECK(json_get(&v, "auto_portals") == NULL);
        jfree(&v);
    }
    char *e[] = { NULL, "--print-config", "configs/scenes/lampshade.yaml", NULL };
    run_render(e, 0, 0, &r);
    CHECK(r.status == EXIT_DONE && !strstr(r.out, "auto found"));
    remove_tree(dir);
}

static const struct test_case print_config_tests[] = {
    { "yaml_is_the_rendered_config_yaml", test_yaml_is_the_rendered_config_yaml },
    { "nothing_is_created", test_nothing_is_created },
    { "json_has_the_config_params_files_and_hashes", test_json_has_the_config_params_files_and_hashes },
    { "json_lists_the_included_files", test_json_lists_the_included_files },
    { "errors_are_a_renders_errors", test_errors_are_a_renders_errors },
    { "usage_errors", test_usage_errors },
    { "json_escapes_names", test_json_escapes_names },
    { "auto_portals_found", test_auto_portals_found },
};

TEST_MAIN(print_config_tests)

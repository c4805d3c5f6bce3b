/* main.c: the command line: arguments -> config -> scene -> render -> exit
   status. The only place that prints diagnostics or chooses an exit code:
   0 done, 1 runtime error, 2 usage or config error, 3 interrupted. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "config.h"
#include "render.h"
#include "scene.h"
#include "version.h"

enum exit_code { EXIT_DONE = 0, EXIT_RUNTIME = 1, EXIT_USAGE = 2, EXIT_INTERRUPTED = 3 };

static const char usage[] =
    "usage: render CONFIG [options]\n"
    "\n"
    "Renders the scene described by the YAML file CONFIG progressively, writing\n"
    "timed OpenEXR snapshots and DIR/final.exr, and one JSON line per snapshot on\n"
    "stdout.\n"
    "\n"
    "options (each overrides the config's value):\n"
    "  --set KEY.PATH=VALUE  override any scalar of the config, e.g.\n"
    "                        --set params.s_L=0.15  --set camera.position.1=2.5\n"
    "                        --set render.aov.region=true (region.* AOV channels)\n"
    "  --out DIR             output folder (render.output); created if missing\n"
    "  --spp N               stop after N samples per pixel (render.spp; 0 = no limit)\n"
    "  --time SECONDS        stop after this render time (render.time; 0 = no limit)\n"
    "  --seed N              random seed (render.seed)\n"
    "  --threads N|auto      render threads (render.threads)\n"
    "  --strategy NAME       light_area | light | portal | projection | antishadow |\n"
    "                        antishadow_exact (render.strategy)\n"
    "  --integrator NAME     direct | path (render.integrator)\n"
    "  --quiet               no progress messages on stderr\n"
    "  --help, --version\n"
    "\n"
    "exit status: 0 done, 1 runtime error, 2 usage or config error, including an\n"
    "output folder that cannot be created or written (nothing is written), 3\n"
    "interrupted by SIGINT/SIGTERM (final.exr holds the passes done).\n";

/* The folders make_dirs created, deepest last, so that a failure can
   remove them again. */
struct made_dirs {
    char path[CONFIG_PATH_MAX];
    int n;
    size_t ends[CONFIG_PATH_MAX / 2]; /* length of each created prefix of path */
};

/* Creates dir and its parents (mkdir -p), recording what it created. The
   message completes "output folder X ...". */
static bool make_dirs(const char *dir, struct made_dirs *made, struct error *err)
{
    char *buf = made->path;
    made->n = 0;
    if (!dir[0]) return error_set(err, "cannot be created: the path is empty");
    if (snprintf(buf, sizeof made->path, "%s", dir) >= (int)sizeof made->path)
        return error_set(err, "cannot be created: the path is too long");
    for (char *p = buf + 1;; ++p) {
        if (*p == '/' || *p == '\0') {
            char c = *p;
            *p = '\0';
            if (mkdir(buf, 0777) == 0)
                made->ends[made->n++] = (size_t)(p - buf);
            else if (errno != EEXIST && c == '\0')
                return error_set(err, "cannot be created: %s", strerror(errno));
            else if (errno != EEXIST)
                return error_set(err, "cannot be created: %s: %s", buf, strerror(errno));
            *p = c;
            if (c == '\0') break;
        }
    }
    struct stat st;
    if (stat(dir, &st) != 0) return error_set(err, "cannot be created: %s", strerror(errno));
    if (!S_ISDIR(st.st_mode)) return error_set(err, "cannot be created: it exists and is not a folder");
    return true;
}

static void unmake_dirs(struct made_dirs *made)
{
    while (made->n > 0) {
        made->path[made->ends[--made->n]] = '\0';
        rmdir(made->path);
    }
}

/* DIR/config.yaml: the effective configuration, written atomically. The
   message completes "output folder X ...". */
static bool write_effective_config(const struct config *cfg, struct error *err)
{
    char path[CONFIG_PATH_MAX + 32], tmp[CONFIG_PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/config.yaml", cfg->render.output);
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) return error_set(err, "cannot be written: %s: %s", strrchr(tmp, '/') + 1, strerror(errno));
    size_t len = strlen(cfg->effective_yaml);
    bool ok = fwrite(cfg->effective_yaml, 1, len, f) == len;
    ok = (fflush(f) == 0) && ok;
    ok = (fsync(fileno(f)) == 0) && ok;
    int saved = errno;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path) != 0) {
        if (ok) saved = errno;
        unlink(tmp);
        return error_set(err, "cannot be written: config.yaml: %s", strerror(saved));
    }
    return true;
}

/* The output folder, made and proven writable (config.yaml is its first
   file) before anything renders. A folder that cannot be made or written is
   a config error: reported where render.output was set, with every folder
   made on the way removed again, so that nothing is left behind. */
static bool prepare_output(const struct config *cfg, const struct config_override *ov, const char *const *ov_flag,
                           struct error *err)
{
    struct made_dirs made;
    struct error why;
    if (make_dirs(cfg->render.output, &made, &why) && write_effective_config(cfg, &why)) return true;
    unmake_dirs(&made);
    const char *out = cfg->render.output, *expected = "expected a folder that can be created and written";
    int k = cfg->output_override;
    if (k >= 0 && ov_flag[k])
        return error_set(err, "%s %s: output folder %s (%s)", ov_flag[k], ov[k].value, why.message, expected);
    if (k >= 0)
        return error_set(err, "--set %s=%s: output folder %s (%s)", ov[k].path, ov[k].value, why.message, expected);
    return error_at(err, cfg->output_loc.file, cfg->output_loc.line, cfg->output_loc.column,
                    "output folder \"%s\" %s (%s)", out, why.message, expected);
}

int main(int argc, char **argv)
{
    const char *config_path = NULL;
    bool quiet = false;
    struct config_override *ov = calloc((size_t)argc, sizeof *ov);
    const char **ov_flag = calloc((size_t)argc, sizeof *ov_flag); /* the shorthand that set it, or NULL */
    char **owned = calloc((size_t)argc, sizeof *owned);
    int n_ov = 0;
    int status = EXIT_USAGE;
    if (!ov || !ov_flag || !owned) {
        fprintf(stderr, "render: out of memory\n");
        return EXIT_RUNTIME;
    }

    static const struct { const char *flag, *key; } shorthands[] = {
        { "--out", "render.output" },       { "--spp", "render.spp" },
        { "--time", "render.time" },        { "--seed", "render.seed" },
        { "--threads", "render.threads" },  { "--strategy", "render.strategy" },
        { "--integrator", "render.integrator" },
    };
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(usage, stdout);
            status = EXIT_DONE;
            goto done;
        }
        if (!strcmp(a, "--version")) {
            printf("render %s\n", RENDERER_VERSION);
            status = EXIT_DONE;
            goto done;
        }
        if (!strcmp(a, "--quiet")) {
            quiet = true;
            continue;
        }
        if (!strcmp(a, "--set")) {
            if (i + 1 >= argc || !strchr(argv[i + 1], '=') || argv[i + 1][0] == '=') {
                fprintf(stderr, "render: --set needs KEY.PATH=VALUE\n%s", usage);
                goto done;
            }
            char *kv = owned[n_ov] = strdup(argv[++i]);
            if (!kv) goto oom;
            char *eq = strchr(kv, '=');
            *eq = '\0';
            ov[n_ov].path = kv;
            ov[n_ov].value = eq + 1;
            ++n_ov;
            continue;
        }
        bool matched = false;
        for (size_t k = 0; k < sizeof shorthands / sizeof shorthands[0]; ++k) {
            if (strcmp(a, shorthands[k].flag)) continue;
            if (i + 1 >= argc) {
                fprintf(stderr, "render: %s needs a value\n%s", a, usage);
                goto done;
            }
            ov[n_ov].path = shorthands[k].key;
            ov[n_ov].value = argv[++i];
            ov_flag[n_ov] = shorthands[k].flag;
            ++n_ov;
            matched = true;
        }
        if (matched) continue;
        if (a[0] == '-') {
            fprintf(stderr, "render: unknown option %s\n%s", a, usage);
            goto done;
        }
        if (config_path) {
            fprintf(stderr, "render: more than one CONFIG (%s and %s)\n%s", config_path, a, usage);
            goto done;
        }
        config_path = a;
    }
    if (!config_path) {
        fputs(usage, stderr);
        goto done;
    }

    struct error err = { { 0 } };
    struct config cfg;
    if (!config_load(config_path, ov, n_ov, &cfg, &err)) {
        fprintf(stderr, "%s\n", err.message);
        goto done;
    }
    struct scene scene;
    if (!scene_create(&cfg, &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
        config_free(&cfg);
        goto done;
    }
    if (!prepare_output(&cfg, ov, ov_flag, &err)) {
        fprintf(stderr, "%s\n", err.message);
    } else {
        status = EXIT_RUNTIME;
        struct render_result res;
        render_catch_signals();
        if (!quiet)
            fprintf(stderr, "render: %s, %dx%d, %s/%s, output %s\n", config_path, cfg.width, cfg.height,
                    integrator_names[cfg.render.integrator], strategy_names[cfg.render.strategy], cfg.render.output);
        if (render_run(&cfg, &scene, stdout, &res, &err)) {
            status = res.interrupted ? EXIT_INTERRUPTED : EXIT_DONE;
            if (!quiet) {
                double secs = res.time_s > 0.0 ? res.time_s : 1e-9;
                fprintf(stderr, "render: %lld spp in %.3f s: %.3g samples/s, %.3g rays/s%s\n", (long long)res.spp,
                        res.time_s, (double)res.spp * cfg.width * cfg.height / secs, (double)res.stats.rays / secs,
                        res.interrupted ? " (interrupted)" : "");
            }
            if (res.nonfinite_samples)
                fprintf(stderr, "render: warning: %llu non-finite samples dropped\n",
                        (unsigned long long)res.nonfinite_samples);
        } else {
            fprintf(stderr, "render: %s\n", err.message);
        }
    }
    scene_destroy(&scene);
    config_free(&cfg);
    goto done;
oom:
    fprintf(stderr, "render: out of memory\n");
    status = EXIT_RUNTIME;
done:
    for (int i = 0; i < argc; ++i) free(owned[i]);
    free(owned);
    free(ov_flag);
    free(ov);
    return status;
}

/* main.c: the command line: arguments -> config -> scene -> render -> exit
   status. The only place that prints diagnostics or chooses an exit code:
   0 done, 1 runtime error, 2 usage or config error, 3 interrupted. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "config/config.h"
#include "cli/describe.h"
#include "cli/exit_code.h"
#include "config/print_config.h"
#include "render/render.h"
#include "render/resume.h"
#include "scene/scene.h"
#include "base/version.h"

static const char usage[] = "usage: render CONFIG [options]\n"
                            "       render --resume DIR [--spp N] [--time S] [--threads N|auto] [--quiet]\n"
                            "       render --print-config CONFIG [options] [--format yaml|json]\n"
                            "       render --describe\n"
                            "\n"
                            "Renders the scene described by the YAML file CONFIG progressively, writing\n"
                            "timed OpenEXR snapshots and DIR/final.exr, and one JSON line per snapshot on\n"
                            "stdout. --resume continues the render in DIR (made with --resumable) with the\n"
                            "passes it did not draw, to the same bits as one uninterrupted render; --spp\n"
                            "and --time are then totals, and only render.spp, render.time, render.threads,\n"
                            "render.snapshots.* and render.resumable may be overridden.\n"
                            "\n"
                            "--print-config loads CONFIG as a render would (includes, params, overrides,\n"
                            "defaults, every check, same messages and exit status) and prints the\n"
                            "effective configuration instead of rendering: YAML (the config.yaml a render\n"
                            "writes) or, with --format json, one JSON object {config, params, files,\n"
                            "hash, image_hash}; nothing is created, render.output is not touched.\n"
                            "\n"
                            "--describe prints the renderer's contract as one JSON object (strategies,\n"
                            "integrators, materials, AOV and EXR channels, EXR attributes, snapshot\n"
                            "keys, exit codes, JSON events), read from the tables the renderer uses.\n"
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
                            "  --strategy NAME       light sampling strategy (render.strategy; the names:\n"
                            "                        render --describe)\n"
                            "  --integrator NAME     direct or path (render.integrator)\n"
                            "  --resumable           also write DIR/final.state, so that --resume can\n"
                            "                        continue the render (render.resumable=true)\n"
                            "  --resume DIR          continue the render in DIR (no CONFIG)\n"
                            "  --quiet               no progress messages on stderr\n"
                            "  --print-config        print the effective configuration, do not render\n"
                            "  --format yaml|json    the form of --print-config (default yaml)\n"
                            "  --describe            print the contract as JSON (no other arguments)\n"
                            "  --help, --version\n"
                            "\n"
                            "exit status: 0 done, 1 runtime error, 2 usage or config error, including an\n"
                            "output folder that cannot be created or written, a malformed fault hook, and\n"
                            "a --resume that cannot continue (nothing is written or changed), 3\n"
                            "interrupted by SIGINT/SIGTERM (final.exr, and final.state if resumable, hold\n"
                            "the passes done).\n";

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
            if (mkdir(buf, 0777) == 0) made->ends[made->n++] = (size_t)(p - buf);
            else if (errno != EEXIST && c == '\0') return error_set(err, "cannot be created: %s", strerror(errno));
            else if (errno != EEXIST) return error_set(err, "cannot be created: %s: %s", buf, strerror(errno));
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

/* Renders into the prepared output folder and reports; returns the exit
   status. `start`: the state to continue, NULL for a fresh render. */
static int render_and_report(const struct config *cfg, const struct scene *scene, struct film_state *start,
                             const struct render_faults *faults, bool quiet)
{
    struct error err = { { 0 } };
    struct render_result res;
    render_catch_signals();
    if (!quiet && start)
        fprintf(stderr, "render: resuming %s at %lld spp, %dx%d, %s/%s\n", cfg->render.output,
                (long long)start->film.passes, cfg->width, cfg->height, integrator_names[cfg->render.integrator],
                strategy_names[cfg->render.strategy]);
    else if (!quiet)
        fprintf(stderr, "render: %s, %dx%d, %s/%s, output %s\n", cfg->path, cfg->width, cfg->height,
                integrator_names[cfg->render.integrator], strategy_names[cfg->render.strategy], cfg->render.output);
    struct render_options opt = { cfg, scene, start, stdout, *faults };
    if (!render_run(&opt, &res, &err)) {
        fprintf(stderr, "render: %s\n", err.message);
        return EXIT_RUNTIME;
    }
    if (!quiet) {
        double secs = res.time_s > 0.0 ? res.time_s : 1e-9;
        fprintf(stderr, "render: %lld spp in %.3f s: %.3g samples/s, %.3g rays/s%s\n", (long long)res.spp, res.time_s,
                (double)res.spp * cfg->width * cfg->height / secs, (double)res.stats.rays / secs,
                res.interrupted ? " (interrupted)" : "");
    }
    if (res.nonfinite_samples)
        fprintf(stderr, "render: warning: %llu non-finite samples dropped\n",
                (unsigned long long)res.nonfinite_samples);
    return res.interrupted ? EXIT_INTERRUPTED : EXIT_DONE;
}

int main(int argc, char **argv)
{
    const char *config_path = NULL, *resume_dir = NULL;
    bool quiet = false, describe = false, print_config = false;
    const char *format_name = NULL;
    enum print_config_format format = PRINT_CONFIG_YAML;
    struct config_override *ov = calloc((size_t)argc, sizeof *ov);
    const char **ov_flag = calloc((size_t)argc, sizeof *ov_flag); /* the shorthand that set it, or NULL */
    char **owned = calloc((size_t)argc, sizeof *owned);
    int n_ov = 0;
    int status = EXIT_USAGE;
    if (!ov || !ov_flag || !owned) {
        fprintf(stderr, "render: out of memory\n");
        return EXIT_RUNTIME;
    }

    static const struct {
        const char *flag, *key;
    } shorthands[] = {
        { "--out", "render.output" },
        { "--spp", "render.spp" },
        { "--time", "render.time" },
        { "--seed", "render.seed" },
        { "--threads", "render.threads" },
        { "--strategy", "render.strategy" },
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
        if (!strcmp(a, "--describe")) {
            describe = true;
            continue;
        }
        if (!strcmp(a, "--print-config")) {
            print_config = true;
            continue;
        }
        if (!strcmp(a, "--format")) {
            if (i + 1 >= argc) {
                fprintf(stderr, "render: --format needs yaml or json\n%s", usage);
                goto done;
            }
            format_name = argv[++i];
            int k = 0;
            while (k < PRINT_CONFIG_FORMAT_COUNT && strcmp(format_name, print_config_format_names[k])) ++k;
            if (k == PRINT_CONFIG_FORMAT_COUNT) {
                fprintf(stderr, "render: unknown --format %s (expected yaml or json)\n%s", format_name, usage);
                goto done;
            }
            format = (enum print_config_format)k;
            continue;
        }
        if (!strcmp(a, "--quiet")) {
            quiet = true;
            continue;
        }
        if (!strcmp(a, "--resumable")) {
            ov[n_ov].path = "render.resumable";
            ov[n_ov].value = "true";
            ov_flag[n_ov] = a;
            ++n_ov;
            continue;
        }
        if (!strcmp(a, "--resume")) {
            if (i + 1 >= argc) {
                fprintf(stderr, "render: --resume needs a folder\n%s", usage);
                goto done;
            }
            if (resume_dir) {
                fprintf(stderr, "render: more than one --resume (%s and %s)\n%s", resume_dir, argv[i + 1], usage);
                goto done;
            }
            resume_dir = argv[++i];
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
    if (describe && argc != 2) {
        fprintf(stderr, "render: --describe takes no other arguments\n%s", usage);
        goto done;
    }
    if (describe) {
        describe_write(stdout);
        status = fflush(stdout) == 0 && !ferror(stdout) ? EXIT_DONE : EXIT_RUNTIME;
        if (status != EXIT_DONE) fprintf(stderr, "render: --describe: cannot write to stdout\n");
        goto done;
    }
    if (format_name && !print_config) {
        fprintf(stderr, "render: --format %s is for --print-config only\n%s", format_name, usage);
        goto done;
    }
    if (print_config && resume_dir) {
        fprintf(stderr, "render: --print-config takes a CONFIG, not --resume %s\n%s", resume_dir, usage);
        goto done;
    }
    if (resume_dir && config_path) {
        fprintf(stderr, "render: --resume %s takes no CONFIG (it continues %s/config.yaml), got %s\n%s", resume_dir,
                resume_dir, config_path, usage);
        goto done;
    }
    if (!resume_dir && !config_path) {
        fputs(usage, stderr);
        goto done;
    }
    for (int k = 0; resume_dir && k < n_ov; ++k) {
        if (resume_override_allowed(ov[k].path)) continue;
        if (ov_flag[k])
            fprintf(stderr, "render: --resume: %s (%s) cannot be changed when resuming (only %s can)\n", ov_flag[k],
                    ov[k].path, RESUME_ALLOWED_KEYS);
        else
            fprintf(stderr, "render: --resume: --set %s cannot be changed when resuming (only %s can)\n", ov[k].path,
                    RESUME_ALLOWED_KEYS);
        goto done;
    }

    struct error err = { { 0 } };
    struct render_faults faults;
    struct config cfg;
    struct film_state start;
    /* The test hooks: read here, so that the library never reads the environment. */
    if (!print_config && !render_faults_parse(getenv("PORTAL_LIGHTS_FAULT_NONFINITE"),
                                              getenv("PORTAL_LIGHTS_FAULT_BIAS"), &faults, &err)) {
        fprintf(stderr, "render: %s\n", err.message);
        goto done;
    }
    bool loaded = resume_dir ? resume_load(resume_dir, ov, n_ov, &cfg, &start, &err)
                             : config_load(config_path, ov, n_ov, &cfg, &err);
    if (!loaded) {
        fprintf(stderr, "%s%s\n", resume_dir ? "render: " : "", err.message);
        goto done;
    }
    struct scene scene;
    if (!scene_create(&cfg, &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
    } else {
        /* A resume rewrites config.yaml with the new totals only now that
           everything has been checked. --print-config has checked all a
           render checks before it makes the output folder, and stops. */
        bool ready =
            print_config || (resume_dir ? write_effective_config(&cfg, &err) : prepare_output(&cfg, ov, ov_flag, &err));
        if (print_config) {
            status = print_config_write(&cfg, format, stdout, &err) ? EXIT_DONE : EXIT_RUNTIME;
            if (status != EXIT_DONE) fprintf(stderr, "render: --print-config: %s\n", err.message);
        } else if (!ready && resume_dir)
            fprintf(stderr, "render: --resume %s: output folder %s\n", resume_dir, err.message);
        else if (!ready) fprintf(stderr, "%s\n", err.message);
        else status = render_and_report(&cfg, &scene, resume_dir ? &start : NULL, &faults, quiet);
        scene_destroy(&scene);
    }
    if (resume_dir) film_state_free(&start);
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

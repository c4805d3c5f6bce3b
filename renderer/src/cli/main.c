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
#include "cli/args.h"
#include "cli/describe.h"
#include "cli/exit_code.h"
#include "config/print_config.h"
#include "render/render.h"
#include "render/resume.h"
#include "scene/portal_report.h"
#include "scene/scene.h"
#include "base/version.h"

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

/* render --print-config: the config, and what `portals: auto` found
   (portal_report.h: YAML comments after the config, or the JSON member
   "auto_portals"), both made in memory before anything is written. */
static bool print_config_and_portals(const struct config *cfg, const struct scene *scene,
                                     enum print_config_format format, struct error *err)
{
    if (!scene->auto_portals) return print_config_write(cfg, format, stdout, err);
    char *text = NULL;
    size_t len = 0;
    FILE *mem = open_memstream(&text, &len);
    if (!mem) return error_set(err, "out of memory for the auto portals");
    bool ok = format == PRINT_CONFIG_JSON
                  ? portal_finder_write_json(scene, cfg, PORTAL_FINDER_SUMMARY_RAYS, mem, err)
                  : portal_finder_write_summary(scene, cfg, PORTAL_FINDER_SUMMARY_RAYS, mem, err);
    ok = (fclose(mem) == 0 || error_set(err, "out of memory for the auto portals")) && ok;
    ok = ok && print_config_write_extra(cfg, format, "auto_portals", text, text, stdout, err);
    free(text);
    return ok;
}

/* Loads the config (or the state to resume), builds the scene and renders
   or prints the configuration; returns the exit status. */
static int run(const struct args *a)
{
    struct error err = { { 0 } };
    struct render_faults faults;
    struct config cfg;
    struct film_state start;
    bool print_config = a->action == ARGS_PRINT_CONFIG;
    const char *resume_dir = a->resume_dir;
    int status = EXIT_USAGE;
    /* The test hooks: read here, so that the library never reads the environment. */
    if (!print_config && !render_faults_parse(getenv("PORTAL_LIGHTS_FAULT_NONFINITE"),
                                              getenv("PORTAL_LIGHTS_FAULT_BIAS"), &faults, &err)) {
        fprintf(stderr, "render: %s\n", err.message);
        return status;
    }
    bool loaded = resume_dir ? resume_load(resume_dir, a->ov, a->n_ov, &cfg, &start, &err)
                             : config_load(a->config_path, a->ov, a->n_ov, &cfg, &err);
    if (!loaded) {
        fprintf(stderr, "%s%s\n", resume_dir ? "render: " : "", err.message);
        return status;
    }
    struct scene scene;
    if (!scene_create(&cfg, &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
    } else {
        /* A resume rewrites config.yaml with the new totals only now that
           everything has been checked. --print-config has checked all a
           render checks before it makes the output folder, and stops. */
        bool ready = print_config ||
                     (resume_dir ? write_effective_config(&cfg, &err) : prepare_output(&cfg, a->ov, a->ov_flag, &err));
        if (print_config) {
            status = print_config_and_portals(&cfg, &scene, a->format, &err) ? EXIT_DONE : EXIT_RUNTIME;
            if (status != EXIT_DONE) fprintf(stderr, "render: --print-config: %s\n", err.message);
        } else if (!ready && resume_dir)
            fprintf(stderr, "render: --resume %s: output folder %s\n", resume_dir, err.message);
        else if (!ready) fprintf(stderr, "%s\n", err.message);
        else status = render_and_report(&cfg, &scene, resume_dir ? &start : NULL, &faults, a->quiet);
        scene_destroy(&scene);
    }
    if (resume_dir) film_state_free(&start);
    config_free(&cfg);
    return status;
}

int main(int argc, char **argv)
{
    struct args a;
    struct error err;
    int status = EXIT_USAGE;
    switch (args_parse(argc, argv, &a, &err)) {
    case ARGS_NO_MEMORY:
        fprintf(stderr, "render: out of memory\n");
        status = EXIT_RUNTIME;
        break;
    case ARGS_USAGE:
        if (err.message[0]) fprintf(stderr, "render: %s\n", err.message);
        fputs(args_usage, stderr);
        break;
    case ARGS_OK:
        switch (a.action) {
        case ARGS_HELP:
            fputs(args_usage, stdout);
            status = EXIT_DONE;
            break;
        case ARGS_VERSION:
            printf("render %s\n", RENDERER_VERSION);
            status = EXIT_DONE;
            break;
        case ARGS_DESCRIBE:
            describe_write(stdout);
            status = fflush(stdout) == 0 && !ferror(stdout) ? EXIT_DONE : EXIT_RUNTIME;
            if (status != EXIT_DONE) fprintf(stderr, "render: --describe: cannot write to stdout\n");
            break;
        case ARGS_RENDER:
        case ARGS_PRINT_CONFIG:
            if (a.resume_dir && !args_check_resume(&a, &err)) fprintf(stderr, "render: %s\n", err.message);
            else status = run(&a);
            break;
        }
        break;
    }
    args_free(&a);
    return status;
}

/* args.c: the render command's arguments: options, shorthands for config
   keys, and the combinations that make no sense, each a usage error. */
#include <stdlib.h>
#include <string.h>

#include "cli/args.h"
#include "render/resume.h"

const char args_usage[] = "usage: render CONFIG [options]\n"
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
                          "With `portals: auto`, what the finder found follows, per light: the portals,\n"
                          "their area, blocked fraction and coverage bound 3/N (rays cast until\n"
                          "N = 300000 escaped: a bound of 1e-5), as YAML comments ending in\n"
                          "`portals:` entries to freeze, or as the JSON member auto_portals (one\n"
                          "batch of 131072 rays).\n"
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

/* The options that set one config key each. */
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

static void add_override(struct args *a, const char *path, const char *value, const char *flag)
{
    a->ov[a->n_ov].path = path;
    a->ov[a->n_ov].value = value;
    a->ov_flag[a->n_ov] = flag;
    ++a->n_ov;
}

/* One option that takes no value or whose value follows it; *i moves past
   what it read. Returns ARGS_OK with *matched false when `opt` is none of
   them. */
static enum args_status parse_option(int argc, char **argv, int *i, struct args *a, const char **format_name,
                                     bool *describe, bool *print_config, bool *matched, struct error *err)
{
    const char *opt = argv[*i];
    bool has_value = *i + 1 < argc;
    *matched = true;
    if (!strcmp(opt, "--describe")) *describe = true;
    else if (!strcmp(opt, "--print-config")) *print_config = true;
    else if (!strcmp(opt, "--quiet")) a->quiet = true;
    else if (!strcmp(opt, "--resumable")) add_override(a, "render.resumable", "true", opt);
    else if (!strcmp(opt, "--format")) {
        if (!has_value) return error_set(err, "--format needs yaml or json"), ARGS_USAGE;
        *format_name = argv[++*i];
        int k = 0;
        while (k < PRINT_CONFIG_FORMAT_COUNT && strcmp(*format_name, print_config_format_names[k])) ++k;
        if (k == PRINT_CONFIG_FORMAT_COUNT)
            return error_set(err, "unknown --format %s (expected yaml or json)", *format_name), ARGS_USAGE;
        a->format = (enum print_config_format)k;
    } else if (!strcmp(opt, "--resume")) {
        if (!has_value) return error_set(err, "--resume needs a folder"), ARGS_USAGE;
        if (a->resume_dir)
            return error_set(err, "more than one --resume (%s and %s)", a->resume_dir, argv[*i + 1]), ARGS_USAGE;
        a->resume_dir = argv[++*i];
    } else if (!strcmp(opt, "--set")) {
        if (!has_value || !strchr(argv[*i + 1], '=') || argv[*i + 1][0] == '=')
            return error_set(err, "--set needs KEY.PATH=VALUE"), ARGS_USAGE;
        char *kv = a->owned[a->n_owned] = strdup(argv[++*i]);
        if (!kv) return ARGS_NO_MEMORY;
        ++a->n_owned;
        char *eq = strchr(kv, '=');
        *eq = '\0';
        add_override(a, kv, eq + 1, NULL);
    } else {
        *matched = false;
        for (size_t k = 0; k < sizeof shorthands / sizeof shorthands[0]; ++k) {
            if (strcmp(opt, shorthands[k].flag)) continue;
            if (!has_value) return error_set(err, "%s needs a value", opt), ARGS_USAGE;
            add_override(a, shorthands[k].key, argv[++*i], shorthands[k].flag);
            *matched = true;
            break;
        }
    }
    return ARGS_OK;
}

enum args_status args_parse(int argc, char **argv, struct args *a, struct error *err)
{
    *a = (struct args){ .action = ARGS_RENDER, .format = PRINT_CONFIG_YAML };
    err->message[0] = '\0';
    a->ov = calloc((size_t)argc, sizeof *a->ov);
    a->ov_flag = calloc((size_t)argc, sizeof *a->ov_flag);
    a->owned = calloc((size_t)argc, sizeof *a->owned);
    if (!a->ov || !a->ov_flag || !a->owned) return ARGS_NO_MEMORY;

    const char *format_name = NULL;
    bool describe = false, print_config = false;
    for (int i = 1; i < argc; ++i) {
        const char *arg = argv[i];
        if (!strcmp(arg, "--help") || !strcmp(arg, "-h")) {
            a->action = ARGS_HELP;
            return ARGS_OK;
        }
        if (!strcmp(arg, "--version")) {
            a->action = ARGS_VERSION;
            return ARGS_OK;
        }
        bool matched;
        enum args_status st = parse_option(argc, argv, &i, a, &format_name, &describe, &print_config, &matched, err);
        if (st != ARGS_OK) return st;
        if (matched) continue;
        if (arg[0] == '-') return error_set(err, "unknown option %s", arg), ARGS_USAGE;
        if (a->config_path) return error_set(err, "more than one CONFIG (%s and %s)", a->config_path, arg), ARGS_USAGE;
        a->config_path = arg;
    }
    if (describe && argc != 2) return error_set(err, "--describe takes no other arguments"), ARGS_USAGE;
    if (describe) {
        a->action = ARGS_DESCRIBE;
        return ARGS_OK;
    }
    if (format_name && !print_config)
        return error_set(err, "--format %s is for --print-config only", format_name), ARGS_USAGE;
    if (print_config && a->resume_dir)
        return error_set(err, "--print-config takes a CONFIG, not --resume %s", a->resume_dir), ARGS_USAGE;
    if (a->resume_dir && a->config_path)
        return error_set(err, "--resume %s takes no CONFIG (it continues %s/config.yaml), got %s", a->resume_dir,
                         a->resume_dir, a->config_path),
               ARGS_USAGE;
    if (!a->resume_dir && !a->config_path) return ARGS_USAGE;
    if (print_config) a->action = ARGS_PRINT_CONFIG;
    return ARGS_OK;
}

bool args_check_resume(const struct args *a, struct error *err)
{
    for (int k = 0; k < a->n_ov; ++k) {
        if (resume_override_allowed(a->ov[k].path)) continue;
        if (a->ov_flag[k])
            return error_set(err, "--resume: %s (%s) cannot be changed when resuming (only %s can)", a->ov_flag[k],
                             a->ov[k].path, RESUME_ALLOWED_KEYS);
        return error_set(err, "--resume: --set %s cannot be changed when resuming (only %s can)", a->ov[k].path,
                         RESUME_ALLOWED_KEYS);
    }
    return true;
}

void args_free(struct args *a)
{
    for (int i = 0; i < a->n_owned; ++i) free(a->owned[i]);
    free(a->owned);
    free(a->ov_flag);
    free(a->ov);
    *a = (struct args){ 0 };
}

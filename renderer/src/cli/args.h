/* args.h: the render command's arguments, parsed into what main does and
   the config overrides it passes on. Nothing here prints: main reports. */
#ifndef ARGS_H
#define ARGS_H

#include <stdbool.h>

#include "base/error.h"
#include "config/config.h"
#include "config/print_config.h"

/* The text of --help, and the tail of every usage error. */
extern const char args_usage[];

/* What the command line asks for, the first of help and version winning. */
enum args_action { ARGS_RENDER, ARGS_HELP, ARGS_VERSION, ARGS_DESCRIBE, ARGS_PRINT_CONFIG };

/* The parsed command line. Strings point into argv, except the --set
   overrides, which own a copy (args_free releases them). */
struct args {
    enum args_action action;
    const char *config_path; /* CONFIG, or NULL with resume_dir */
    const char *resume_dir;  /* --resume DIR, or NULL */
    bool quiet;
    enum print_config_format format;
    struct config_override *ov; /* every override, in command-line order */
    const char **ov_flag;       /* the shorthand that set ov[k] (--out...), or NULL for --set */
    int n_ov;
    char **owned; /* the --set copies */
    int n_owned;
};

enum args_status {
    ARGS_OK,
    ARGS_USAGE,    /* a usage error: err holds the message, or is empty when only the usage applies */
    ARGS_NO_MEMORY /* out of memory */
};

/* Parses argv[1..argc-1] into a. After any status, args_free(a) releases
   what a holds. ARGS_HELP and ARGS_VERSION stop the parse where they stand,
   so that an option before them may still be a usage error. */
enum args_status args_parse(int argc, char **argv, struct args *a, struct error *err);

/* A --resume may change only RESUME_ALLOWED_KEYS: false, with the message
   naming the first override that it may not, otherwise. */
bool args_check_resume(const struct args *a, struct error *err);

void args_free(struct args *a);

#endif

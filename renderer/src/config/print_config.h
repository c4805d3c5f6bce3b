/* print_config.h: `render --print-config`: a loaded configuration as YAML
   (the config.yaml a render writes, byte for byte) or as one JSON object
   with its params, files and hashes, for tools that must not re-implement
   the include merge, the params or the defaults. */
#ifndef PRINT_CONFIG_H
#define PRINT_CONFIG_H

#include <stdbool.h>
#include <stdio.h>

#include "config/config.h"
#include "base/error.h"

enum print_config_format { PRINT_CONFIG_YAML, PRINT_CONFIG_JSON };
#define PRINT_CONFIG_FORMAT_COUNT 2

/* "yaml", "json": the values of --format, indexed by the enum. */
extern const char *const print_config_format_names[PRINT_CONFIG_FORMAT_COUNT];

/* Writes c to out: PRINT_CONFIG_YAML its effective_yaml verbatim,
   PRINT_CONFIG_JSON one line {"config": <config_write_json>, "params":
   {name: value...}, "files": [c->files...], "hash": "<16 hex digits>",
   "image_hash": "<16 hex digits>"}. All or nothing: the text is made in
   memory first, so that a failure (memory, or writing to out) leaves at
   most a failed write behind and err says which. */
bool print_config_write(const struct config *c, enum print_config_format format, FILE *out, struct error *err);

/* As print_config_write, with what the scene build found added (render
   --print-config passes the auto portals, scene/portal_finder.h): for
   PRINT_CONFIG_YAML, extra_yaml (comment lines) after the config; for
   PRINT_CONFIG_JSON, one more member "<extra_key>": extra_json (a JSON
   value). NULL for nothing. */
bool print_config_write_extra(const struct config *c, enum print_config_format format, const char *extra_key,
                              const char *extra_json, const char *extra_yaml, FILE *out, struct error *err);

#endif

#include "config/print_config.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "base/json_write.h"

const char *const print_config_format_names[PRINT_CONFIG_FORMAT_COUNT] = {
    [PRINT_CONFIG_YAML] = "yaml",
    [PRINT_CONFIG_JSON] = "json",
};

static bool write_json(const struct config *c, const char *extra_key, const char *extra, FILE *f, struct error *err)
{
    fputs("{\"config\":", f);
    if (!config_write_json(c, f, err)) return false;
    fputs(",\"params\":{", f);
    for (int i = 0; i < c->n_params; ++i) {
        if (i) fputc(',', f);
        json_write_string(f, c->params[i].name);
        fputc(':', f);
        json_write_number(f, c->params[i].value);
    }
    fputs("},\"files\":[", f);
    for (int i = 0; i < c->n_files; ++i) {
        if (i) fputc(',', f);
        json_write_string(f, c->files[i]);
    }
    fputc(']', f);
    if (extra_key && extra) {
        fputc(',', f);
        json_write_string(f, extra_key);
        fputc(':', f);
        fputs(extra, f);
    }
    fprintf(f, ",\"hash\":\"%016" PRIx64 "\",\"image_hash\":\"%016" PRIx64 "\"}\n", c->hash, c->image_hash);
    return true;
}

bool print_config_write(const struct config *c, enum print_config_format format, FILE *out, struct error *err)
{
    return print_config_write_extra(c, format, NULL, NULL, NULL, out, err);
}

bool print_config_write_extra(const struct config *c, enum print_config_format format, const char *extra_key,
                              const char *extra_json, const char *extra_yaml, FILE *out, struct error *err)
{
    char *text = NULL;
    size_t len = 0;
    switch (format) {
    case PRINT_CONFIG_YAML:
        text = c->effective_yaml;
        len = strlen(text);
        break;
    case PRINT_CONFIG_JSON: {
        FILE *mem = open_memstream(&text, &len);
        if (!mem) return error_set(err, "out of memory for the JSON of %s", c->path);
        bool ok = write_json(c, extra_key, extra_json, mem, err);
        ok = (fclose(mem) == 0 || error_set(err, "out of memory for the JSON of %s", c->path)) && ok;
        if (!ok) {
            free(text);
            return false;
        }
        break;
    }
    }
    size_t extra_len = format == PRINT_CONFIG_YAML && extra_yaml ? strlen(extra_yaml) : 0;
    bool ok = fwrite(text, 1, len, out) == len &&
              fwrite(extra_yaml ? extra_yaml : "", 1, extra_len, out) == extra_len && fflush(out) == 0;
    if (text != c->effective_yaml) free(text);
    return ok || error_set(err, "cannot write the configuration to the output stream");
}

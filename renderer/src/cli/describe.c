#include "cli/describe.h"

#include <stdbool.h>

#include "render/aov.h"
#include "config/config.h"
#include "cli/exit_code.h"
#include "render/film.h"
#include "base/json_write.h"
#include "render/render_events.h"
#include "base/kinds.h"
#include "base/version.h"

/* Sizes of the name tables as declared, so that a new entry shows up here
   without an edit. */
#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

static void key(FILE *out, const char *name, bool first)
{
    if (!first) fputc(',', out);
    json_write_string(out, name);
    fputc(':', out);
}

static void names(FILE *out, const char *name, const char *const *list, int n)
{
    key(out, name, false);
    json_write_names(out, NULL, list, n);
}

void describe_write(FILE *out)
{
    fputc('{', out);
    key(out, "program", true);
    json_write_string(out, "render");
    key(out, "version", false);
    json_write_string(out, RENDERER_VERSION);
    names(out, "strategies", strategy_names, COUNT(strategy_names));
    names(out, "integrators", integrator_names, COUNT(integrator_names));
    names(out, "materials", material_names, COUNT(material_names));
    names(out, "mis", mis_names, COUNT(mis_names));
    names(out, "portal_weights", portal_weight_names, COUNT(portal_weight_names));
    names(out, "samplers", sampler_names, COUNT(sampler_names));

    key(out, "aov", false);
    fputc('{', out);
    key(out, "region", true);
    json_write_names(out, FILM_REGION_PREFIX, aov_region_names, COUNT(aov_region_names));
    fputc('}', out);

    names(out, "exr_channels", film_channel_names, COUNT(film_channel_names));
    names(out, "exr_attributes", film_attribute_names, COUNT(film_attribute_names));

    key(out, "snapshot_keys", false);
    fputc('{', out);
    for (int i = 0; i < COUNT(config_snapshot_keys); ++i) {
        key(out, config_snapshot_keys[i], i == 0);
        json_write_string(out, config_snapshot_units[i]);
    }
    fputc('}', out);

    key(out, "exit_codes", false);
    fputc('{', out);
    for (int i = 0; i < COUNT(exit_code_names); ++i) {
        key(out, exit_code_names[i], i == 0);
        fprintf(out, "%d", i);
    }
    fputc('}', out);

    names(out, "json_events", render_event_names, COUNT(render_event_names));
    fputs("}\n", out);
}

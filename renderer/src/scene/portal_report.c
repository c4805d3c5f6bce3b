#include "scene/portal_report.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/json_write.h"
#include "config/config.h"
#include "scene/portal_coverage.h"
#include "scene/portal_finder.h"

/* The shortest of %.15g..%.17g that reads back to x: a frozen portal is
   the found one, bit for bit. */
static void write_exact(FILE *out, double x)
{
    char buf[40];
    for (int digits = 15; digits <= 17; ++digits) {
        snprintf(buf, sizeof buf, "%.*g", digits, x);
        if (strtod(buf, NULL) == x) break;
    }
    fputs(buf, out);
}

static void write_polygon(FILE *out, const struct polygon *p)
{
    fputs("[", out);
    for (int v = 0; v < p->n; ++v) {
        fputs(v ? ", [" : "[", out);
        write_exact(out, p->v[v].x);
        fputs(", ", out);
        write_exact(out, p->v[v].y);
        fputs(", ", out);
        write_exact(out, p->v[v].z);
        fputs("]", out);
    }
    fputs("]", out);
}

/* The coverage of emitter i's found portals: batches of n_rays rays (fixed
   seeds) until PORTAL_FINDER_SUMMARY_ESCAPED rays escaped or max_batches
   batches were cast. */
static bool summary_coverage(const struct scene *s, int i, long n_rays, int max_batches, struct portal_coverage *cov,
                             struct error *err)
{
    const struct auto_portal_report *rep = &s->auto_portals[i];
    const struct light *l = &s->lights[s->emitters[i].first_light];
    int n = l->n_portals;
    struct polygon *copy = malloc(sizeof *copy * (size_t)(n > 0 ? n : 1));
    if (!copy) return error_set(err, "out of memory");
    for (int k = 0; k < n; ++k) polygon_copy(&copy[k], &s->portals[l->first_portal + k].target->polygon);
    memset(cov, 0, sizeof *cov);
    bool ok = true;
    for (int batch = 0; ok && batch < max_batches && cov->n_escaped < PORTAL_FINDER_SUMMARY_ESCAPED; ++batch) {
        struct portal_coverage c;
        ok = portal_finder_coverage(s, i, rep->planes, rep->n_planes, copy, n, n_rays,
                                    PORTAL_FINDER_SEED + 1 + (uint64_t)batch, &c, err);
        cov->n_rays += c.n_rays, cov->n_escaped += c.n_escaped, cov->n_missed += c.n_missed;
        cov->n_portal += c.n_portal, cov->n_through += c.n_through;
    }
    cov->blocked_fraction = cov->n_portal ? 1.0 - (double)cov->n_through / (double)cov->n_portal : 0.0;
    cov->bound = cov->n_escaped ? 3.0 / (double)cov->n_escaped : INFINITY;
    free(copy);
    return ok;
}

bool portal_finder_write_summary(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                                 struct error *err)
{
    if (!s->auto_portals) return true;
    fputs("# portals: auto found, per light (blocked: the fraction of the light's rays aimed through a portal\n"
          "# that something inside the enclosure stops; bound: 3/N over N escaping rays, none of which missed\n"
          "# the portals, bounds the escaping flux the portals could miss at 95% confidence):\n",
          out);
    for (int i = 0; i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->requested) continue;
        if (!rep->enclosed) {
            fprintf(out, "#   %s%s\n", rep->warn ? "warning: " : "", rep->note);
            continue;
        }
        struct portal_coverage cov;
        if (!summary_coverage(s, i, n_rays, PORTAL_FINDER_SUMMARY_MAX_BATCHES, &cov, err)) return false;
        fprintf(out,
                "#   %s: %d portal(s), area %.6g m^2 (%.1f%% of the enclosure's %.6g m^2), blocked %.4f, bound %.3g "
                "(%ld of %ld rays escaped, %ld missed)\n",
                cfg->lights[i].name, rep->n_portals, rep->area, 100.0 * rep->area / rep->hull_area, rep->hull_area,
                cov.blocked_fraction, cov.bound, cov.n_escaped, cov.n_rays, cov.n_missed);
    }
    fputs("# To freeze them, replace the auto entries by:\n# portals:\n", out);
    for (int i = 0; i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->enclosed) continue;
        const struct light *l = &s->lights[s->emitters[i].first_light];
        for (int k = 0; k < l->n_portals; ++k) {
            fprintf(out, "#   - {name: %s_auto%d, light: %s, vertices: ", cfg->lights[i].name, k, cfg->lights[i].name);
            write_polygon(out, &s->portals[l->first_portal + k].target->polygon);
            fputs("}\n", out);
        }
    }
    return true;
}

static void json_key_number(FILE *out, const char *key, double v)
{
    fprintf(out, ",\"%s\":", key);
    json_write_number(out, v);
}

bool portal_finder_write_json(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                              struct error *err)
{
    fputc('{', out);
    bool first = true;
    for (int i = 0; s->auto_portals && i < s->n_emitters; ++i) {
        const struct auto_portal_report *rep = &s->auto_portals[i];
        if (!rep->requested) continue;
        if (!first) fputc(',', out);
        first = false;
        json_write_string(out, cfg->lights[i].name);
        fprintf(out, ":{\"enclosed\":%s,\"warning\":%s,\"note\":", rep->enclosed ? "true" : "false",
                rep->warn ? "true" : "false");
        json_write_string(out, rep->note);
        struct portal_coverage cov = { 0 };
        if (rep->enclosed && !summary_coverage(s, i, n_rays, 1, &cov, err)) return false;
        fprintf(out, ",\"n_portals\":%d", rep->enclosed ? rep->n_portals : 0);
        json_key_number(out, "area", rep->enclosed ? rep->area : 0.0);
        json_key_number(out, "hull_area", rep->hull_area);
        if (rep->enclosed) {
            json_key_number(out, "blocked_fraction", cov.blocked_fraction);
            json_key_number(out, "bound", cov.bound);
            fprintf(out, ",\"n_rays\":%ld,\"n_escaped\":%ld,\"n_missed\":%ld", cov.n_rays, cov.n_escaped, cov.n_missed);
        }
        fputs(",\"portals\":[", out);
        const struct light *l = &s->lights[s->emitters[i].first_light];
        for (int k = 0; rep->enclosed && k < l->n_portals; ++k) {
            const struct polygon *p = &s->portals[l->first_portal + k].target->polygon;
            char name[CONFIG_NAME_MAX + 32];
            snprintf(name, sizeof name, "%s_auto%d", cfg->lights[i].name, k);
            fputs(k ? ",{\"name\":" : "{\"name\":", out);
            json_write_string(out, name);
            fputs(",\"light\":", out);
            json_write_string(out, cfg->lights[i].name);
            fputs(",\"vertices\":[", out);
            for (int v = 0; v < p->n; ++v) {
                fputs(v ? ",[" : "[", out);
                json_write_number(out, p->v[v].x);
                fputc(',', out);
                json_write_number(out, p->v[v].y);
                fputc(',', out);
                json_write_number(out, p->v[v].z);
                fputc(']', out);
            }
            fputs("]}", out);
        }
        fputs("]}", out);
    }
    fputc('}', out);
    return true;
}

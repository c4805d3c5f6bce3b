/* config_emit.c: the effective YAML of a loaded config (params
   substituted, overrides applied, defaults filled, every shape a mesh),
   canonical so that it loads back to the same config, and its two
   FNV-1a hashes: of the whole text, and of the part that decides the
   image of a pass. */
#include "config/config_internal.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct text {
    char *s;
    size_t len, cap;
    bool failed;
};

static void text_printf(struct text *t, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void text_printf(struct text *t, const char *fmt, ...)
{
    if (t->failed) return;
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (k < 0) {
        t->failed = true;
        return;
    }
    if (t->len + (size_t)k + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 4096;
        while (cap < t->len + (size_t)k + 1) cap *= 2;
        char *s = realloc(t->s, cap);
        if (!s) {
            t->failed = true;
            return;
        }
        t->s = s;
        t->cap = cap;
    }
    va_start(ap, fmt);
    vsnprintf(t->s + t->len, t->cap - t->len, fmt, ap);
    va_end(ap);
    t->len += (size_t)k;
}

/* The shortest of %.15g, %.16g, %.17g that reads back to the same double:
   %.17g always does, the shorter ones keep 0.6 from printing as
   0.59999999999999998. */
static void emit_number(struct text *t, double v)
{
    char buf[32];
    for (int digits = 15; digits <= 17; ++digits) {
        snprintf(buf, sizeof buf, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) break;
    }
    text_printf(t, "%s", buf);
}

static void emit_vec3(struct text *t, struct vec3 v)
{
    text_printf(t, "[");
    emit_number(t, v.x);
    text_printf(t, ", ");
    emit_number(t, v.y);
    text_printf(t, ", ");
    emit_number(t, v.z);
    text_printf(t, "]");
}

static void emit_rgb(struct text *t, struct rgb c)
{
    emit_vec3(t, vec3_make(c.r, c.g, c.b));
}

/* Decodes one UTF-8 sequence; returns its length (1 for a stray byte, which
   cannot occur: libyaml and yaml_document_add_scalar validate UTF-8). */
static int utf8_decode(const unsigned char *s, unsigned long *cp)
{
    int len = s[0] < 0x80 ? 1 : (s[0] & 0xE0) == 0xC0 ? 2 : (s[0] & 0xF0) == 0xE0 ? 3 : (s[0] & 0xF8) == 0xF0 ? 4 : 1;
    unsigned long c = len == 1 ? s[0] : s[0] & (0x7Fu >> len);
    for (int i = 1; i < len; ++i) {
        if ((s[i] & 0xC0) != 0x80) { /* also stops at the terminator */
            *cp = s[0];
            return 1;
        }
        c = (c << 6) | (s[i] & 0x3F);
    }
    *cp = c;
    return len;
}

/* A double-quoted YAML string. Escapes what libyaml would fold or refuse:
   controls, line and paragraph separators, the BOM and non-characters. */
static void emit_string(struct text *t, const char *s)
{
    text_printf(t, "\"");
    const unsigned char *p = (const unsigned char *)s;
    while (*p) {
        unsigned long c;
        int len = utf8_decode(p, &c);
        if (c == '"' || c == '\\') text_printf(t, "\\%c", (int)c);
        else if (c < 0x20 || (c >= 0x7F && c <= 0x9F)) text_printf(t, "\\x%02lX", c);
        else if (c == 0x2028 || c == 0x2029 || c == 0xFEFF || c == 0xFFFE || c == 0xFFFF ||
                 (c >= 0xD800 && c <= 0xDFFF))
            text_printf(t, "\\u%04lX", c);
        else text_printf(t, "%.*s", len, (const char *)p);
        p += len;
    }
    text_printf(t, "\"");
}

static void emit_camera_film(struct text *t, const struct config *c)
{
    text_printf(t, "camera:\n  position: ");
    emit_vec3(t, c->camera.position);
    text_printf(t, "\n  look_at: ");
    emit_vec3(t, c->camera.look_at);
    text_printf(t, "\n  up: ");
    emit_vec3(t, c->camera.up);
    text_printf(t, "\n  fov_y: ");
    emit_number(t, c->camera.fov_y_deg);
    text_printf(t, "\nfilm:\n  width: %d\n  height: %d\n", c->width, c->height);
}

static void emit_materials(struct text *t, const struct config *c)
{
    text_printf(t, "materials:%s\n", c->n_materials ? "" : " {}");
    for (int i = 0; i < c->n_materials; ++i) {
        const struct material_desc *m = &c->materials[i];
        text_printf(t, "  ");
        emit_string(t, m->name);
        text_printf(t, ": {type: %s, albedo: ", material_names[m->kind]);
        emit_rgb(t, m->albedo);
        if (m->kind == MATERIAL_GGX) {
            text_printf(t, ", roughness: ");
            emit_number(t, m->roughness);
        }
        text_printf(t, "}\n");
    }
}

/* A mesh from a file stays a reference to it: its absolute path, the
   transform as one matrix (the composition the loader applied, bit for
   bit), and the digest of the bytes read, so that both hashes change when
   the file does and a reload checks that it has not. The image hash leaves
   the path out: the digest says what the image depends on, and a copy of the
   scene elsewhere (a Dask worker's folder, a moved project) must resume the
   same film. */
static void emit_shape_file(struct text *t, const struct shape_file *f, const char *indent, bool image_only)
{
    if (!image_only) {
        text_printf(t, "\n%sfile: ", indent);
        emit_string(t, f->path);
    }
    /* In the image hash too: another shape is another image. */
    if (f->shape_index >= 0) text_printf(t, "\n%sshape_index: %d", indent, f->shape_index);
    if (f->has_transform) {
        text_printf(t, "\n%stransform: [{matrix: [", indent);
        for (int i = 0; i < 16; ++i) {
            text_printf(t, "%s", i ? ", " : "");
            emit_number(t, i < 12 ? f->transform.m[i / 4][i % 4] : i == 15 ? 1.0 : 0.0);
        }
        text_printf(t, "]}]");
    }
    text_printf(t, "\n%sdigest: {fnv1a64: \"%016" PRIx64 "\", bytes: %zu}\n", indent, f->fnv1a64, f->bytes);
}

static void emit_shapes(struct text *t, const struct config *c, char (*names)[CONFIG_NAME_MAX],
                        const struct shape_file *files, bool image_only)
{
    text_printf(t, "shapes:%s\n", c->n_shapes ? "" : " []");
    for (int i = 0; i < c->n_shapes; ++i) {
        const struct shape_desc *s = &c->shapes[i];
        text_printf(t, "  - ");
        if (names[i][0]) {
            text_printf(t, "name: ");
            emit_string(t, names[i]);
            text_printf(t, "\n    ");
        }
        text_printf(t, "type: mesh\n    material: ");
        emit_string(t, c->materials[s->material].name);
        if (files[i].path) {
            emit_shape_file(t, &files[i], "    ", image_only);
            continue;
        }
        text_printf(t, "\n    vertices:\n");
        for (int v = 0; v < s->n_vertices; ++v) {
            text_printf(t, "      - ");
            emit_vec3(t, s->vertices[v]);
            text_printf(t, "\n");
        }
        if (s->n_triangles) text_printf(t, "    triangles:\n");
        for (int f = 0; f < s->n_triangles; ++f)
            text_printf(t, "      - [%d, %d, %d]\n", s->triangles[f][0], s->triangles[f][1], s->triangles[f][2]);
        if (s->n_quads) text_printf(t, "    quads:\n");
        for (int f = 0; f < s->n_quads; ++f)
            text_printf(t, "      - [%d, %d, %d, %d]\n", s->quads[f][0], s->quads[f][1], s->quads[f][2],
                        s->quads[f][3]);
    }
}

static void emit_polygon(struct text *t, const struct polygon *p)
{
    text_printf(t, "    vertices:\n");
    for (int v = 0; v < p->n; ++v) {
        text_printf(t, "      - ");
        emit_vec3(t, p->v[v]);
        text_printf(t, "\n");
    }
}

static void emit_lights_portals(struct text *t, const struct config *c, const struct shape_file *light_files,
                                bool image_only)
{
    text_printf(t, "lights:\n");
    for (int i = 0; i < c->n_lights; ++i) {
        const struct light_desc *l = &c->lights[i];
        text_printf(t, "  - name: ");
        emit_string(t, l->name);
        if (l->mesh.n_triangles > 0) {
            text_printf(t, "\n    mesh:");
            emit_shape_file(t, &light_files[i], "      ", image_only);
        } else {
            text_printf(t, "\n");
            emit_polygon(t, &l->polygon);
        }
        text_printf(t, "    radiance: ");
        emit_rgb(t, l->radiance);
        text_printf(t, "\n    two_sided: %s\n", l->two_sided ? "true" : "false");
    }
    int n_auto = 0;
    for (int i = 0; i < c->n_lights; ++i) n_auto += c->lights[i].auto_portals;
    if (c->portals_auto) {
        text_printf(t, "portals: auto\n");
        return;
    }
    text_printf(t, "portals:%s\n", c->n_portals + n_auto ? "" : " []");
    for (int i = 0; i < c->n_lights; ++i)
        if (c->lights[i].auto_portals) {
            text_printf(t, "  - light: ");
            emit_string(t, c->lights[i].name);
            text_printf(t, "\n    auto: true\n");
        }
    for (int i = 0; i < c->n_portals; ++i) {
        const struct portal_desc *p = &c->portals[i];
        text_printf(t, "  - name: ");
        emit_string(t, p->name);
        text_printf(t, "\n    light: ");
        emit_string(t, c->lights[p->light].name);
        text_printf(t, "\n");
        emit_polygon(t, &p->polygon);
    }
}

static void emit_snapshots(struct text *t, const struct snapshot_schedule *s)
{
    const char *sep = "";
    text_printf(t, "\n  snapshots: {");
    if (s->every_s > 0.0) {
        text_printf(t, "every: ");
        emit_number(t, s->every_s);
        sep = ", ";
    }
    if (s->doubling_s > 0.0) {
        text_printf(t, "%sdoubling: ", sep);
        emit_number(t, s->doubling_s);
        sep = ", ";
    }
    if (s->n_times) {
        text_printf(t, "%stimes: [", sep);
        for (int i = 0; i < s->n_times; ++i) {
            text_printf(t, "%s", i ? ", " : "");
            emit_number(t, s->times_s[i]);
        }
        text_printf(t, "]");
        sep = ", ";
    }
    if (s->every_spp > 0) {
        text_printf(t, "%severy_spp: %d", sep, s->every_spp);
        sep = ", ";
    }
    if (s->doubling_spp > 0) {
        text_printf(t, "%sdoubling_spp: %d", sep, s->doubling_spp);
        sep = ", ";
    }
    if (s->n_spps) {
        text_printf(t, "%sspp: [", sep);
        for (int i = 0; i < s->n_spps; ++i) text_printf(t, "%s%d", i ? ", " : "", s->spps[i]);
        text_printf(t, "]");
    }
    text_printf(t, "}");
}

/* With `image_only`, the keys that only say how long, how often, on how
   many threads and where a render runs are left out: what remains decides
   the image of every pass. */
static void emit_render(struct text *t, const struct render_desc *r, bool image_only)
{
    text_printf(t, "render:\n  integrator: %s\n  strategy: %s\n  mis: %s\n  portal_weight: %s\n  defensive: ",
                integrator_names[r->integrator], strategy_names[r->strategy], mis_names[r->mis],
                portal_weight_names[r->portal_weight]);
    emit_number(t, r->defensive);
    text_printf(t, "\n  max_depth: %d\n  rr_depth: %d\n  sampler: %s", r->max_depth, r->rr_depth,
                sampler_names[r->sampler]);
    if (!image_only) {
        text_printf(t, "\n  spp: %d\n  time: ", r->spp);
        emit_number(t, r->time_s);
        emit_snapshots(t, &r->snapshots);
    }
    text_printf(t, "\n  seed: %" PRIu64, r->seed);
    if (!image_only) {
        text_printf(t, "\n  threads: ");
        if (r->threads == 0) text_printf(t, "auto");
        else text_printf(t, "%d", r->threads);
        text_printf(t, "\n  output: ");
        emit_string(t, r->output);
        text_printf(t, "\n  resumable: %s", r->resumable ? "true" : "false");
    }
    /* The AOV is part of the image: its channels and the film state's counts. */
    text_printf(t, "\n  aov: {region: %s}\n", r->aov_region ? "true" : "false");
}

/* FNV-1a, 64-bit. */
uint64_t config_fnv1a64(const void *data, size_t n)
{
    const unsigned char *s = data;
    uint64_t h = 14695981039346656037ull;
    for (size_t i = 0; i < n; ++i) {
        h ^= s[i];
        h *= 1099511628211ull;
    }
    return h;
}

static void emit_yaml(struct text *t, struct loader *L, const struct config *c, bool image_only)
{
    text_printf(t, "# effective configuration (params substituted, overrides applied, defaults filled)\n");
    emit_camera_film(t, c);
    emit_materials(t, c);
    emit_shapes(t, c, L->shape_names, L->shape_files, image_only);
    emit_lights_portals(t, c, L->light_files, image_only);
    emit_render(t, &c->render, image_only);
}

bool config_emit_effective(struct loader *L, struct config *c)
{
    struct text t = { NULL, 0, 0, false }, image = { NULL, 0, 0, false };
    emit_yaml(&t, L, c, false);
    emit_yaml(&image, L, c, true);
    if (t.failed || image.failed) {
        free(t.s);
        free(image.s);
        return error_set(L->err, "%s: out of memory", L->file);
    }
    c->effective_yaml = t.s;
    c->hash = config_fnv1a64(t.s, t.len);
    c->image_hash = config_fnv1a64(image.s, image.len);
    free(image.s);
    return true;
}

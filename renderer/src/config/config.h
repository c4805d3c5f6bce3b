/* config.h: the validated description of a scene and a render, as read from
   one YAML file (and the files it includes) plus command-line overrides.
   Plain data: no Embree, no I/O beyond reading the files. Every error names
   file:line:column. */
#ifndef CONFIG_H
#define CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "base/kinds.h"
#include "geometry/polygon.h"
#include "base/vec.h"

#define CONFIG_NAME_MAX          64
#define CONFIG_PATH_MAX          1024
#define CONFIG_SCHEDULE_MAX      256
#define CONFIG_INCLUDE_DEPTH_MAX 16 /* include: nesting levels below the loaded file */

struct source_loc {
    int line, column; /* one-based, of the YAML node that defined the item */
    const char *file; /* the file it is in (one of config.files) */
};

struct material_desc {
    char name[CONFIG_NAME_MAX];
    enum material_kind kind;
    struct rgb albedo; /* diffuse reflectance, or GGX specular colour */
    double roughness;  /* GGX alpha (0, 1]; unused for diffuse */
    struct source_loc loc;
};

/* Every shape is reduced to an indexed mesh of quads and triangles. Surfaces
   are two-sided. */
struct shape_desc {
    int material; /* index into config.materials */
    int n_vertices;
    struct vec3 *vertices; /* owned */
    int n_triangles;
    int (*triangles)[3]; /* owned, may be NULL */
    int n_quads;
    int (*quads)[4]; /* owned, may be NULL; planar convex */
    struct source_loc loc;
};

/* Uniform emitter on a convex planar polygon, or on every triangle of a
   mesh (a mesh light). One-sided lights emit towards the side of
   polygon_normal(&polygon), or of each triangle's winding (counter-clockwise
   as seen from the lit side). Lights reflect nothing. */
struct light_desc {
    char name[CONFIG_NAME_MAX];
    struct polygon polygon; /* 3..POLYGON_INPUT_MAX vertices; n = 0 for a mesh light */
    struct shape_desc mesh; /* a mesh light's triangles (owned, material -1); n_triangles = 0 otherwise */
    struct rgb radiance;
    bool two_sided;
    struct source_loc loc;
    /* `portals: auto`, or a `{light: <name>, auto: true}` entry: the scene
       finds this light's portals (scene/portal_finder.h); auto_loc is where
       it was asked for. Never together with hand-written portals. */
    bool auto_portals;
    struct source_loc auto_loc;
};

/* An opening through which every path of its light leaves (not geometry). */
struct portal_desc {
    char name[CONFIG_NAME_MAX];
    int light;              /* index into config.lights */
    struct polygon polygon; /* 3..POLYGON_INPUT_MAX vertices */
    struct source_loc loc;
};

struct camera_desc {
    struct vec3 position, look_at, up;
    double fov_y_deg; /* vertical field of view, (0, 180) */
};

/* When to write snapshots; any combination; the final one is always written. */
struct snapshot_schedule {
    double every_s;    /* 0: off */
    double doubling_s; /* first time, then 2x, 4x...; 0: off */
    int n_times;
    double times_s[CONFIG_SCHEDULE_MAX];
    int every_spp;    /* 0: off */
    int doubling_spp; /* first spp, then 2x, 4x...; 0: off (a scalar, so --set reaches it) */
    int n_spps;
    int spps[CONFIG_SCHEDULE_MAX];
};

struct render_desc {
    enum integrator_kind integrator;
    enum strategy_kind strategy;
    enum mis_kind mis;
    enum portal_weight_kind portal_weight;
    enum sampler_kind sampler; /* where the random numbers come from (sampler.h) */
    double defensive;          /* [0, 1): fraction of plain light sampling */
    int max_depth;             /* path: >= 1 bounces; direct ignores it */
    int rr_depth;              /* path: Russian roulette from this depth */
    int spp;                   /* 0: no sample limit */
    double time_s;             /* 0: no time limit; at least one is set */
    struct snapshot_schedule snapshots;
    uint64_t seed;
    int threads; /* 0: auto (number of online CPUs) */
    char output[CONFIG_PATH_MAX];
    bool aov_region; /* render.aov.region: per-pixel antishadow region classes (aov.h) */
    bool resumable;  /* also write output/final.state (film_state.h) */
};

/* The keys of render.snapshots, and the unit each counts in ("s" of render
   time or "spp" passes), as the loader checks them. */
#define CONFIG_SNAPSHOT_KEY_COUNT 6
extern const char *const config_snapshot_keys[CONFIG_SNAPSHOT_KEY_COUNT];
extern const char *const config_snapshot_units[CONFIG_SNAPSHOT_KEY_COUNT];

/* One entry of `params:`, after overrides, evaluated. */
struct config_param {
    char *name; /* owned */
    double value;
};

struct config {
    char path[CONFIG_PATH_MAX]; /* the file it came from */
    int n_files;
    char **files; /* owned: path, then every included file in load order */
    int width, height;
    struct camera_desc camera;
    int n_materials;
    struct material_desc *materials;
    int n_shapes;
    struct shape_desc *shapes;
    int n_lights;
    struct light_desc *lights;
    int n_portals;
    struct portal_desc *portals;
    bool portals_auto; /* `portals: auto`: every light's auto_portals */
    struct render_desc render;
    /* Canonical YAML of the effective configuration (params substituted,
       overrides applied, defaults filled); loads back to the same config. */
    char *effective_yaml;
    uint64_t hash; /* FNV-1a 64 of effective_yaml */
    /* FNV-1a 64 of the effective YAML without the keys that do not change
       the image of a pass (render.spp, time, snapshots, threads, output,
       resumable): a resumed render must match the state's. */
    uint64_t image_hash;
    /* Where render.output was set, for messages about the folder: the value
       in a file (output_override < 0; the render mapping when the default
       applies), or the index of the --set override that set it. */
    struct source_loc output_loc;
    int output_override;
    /* The params in file order: effective_yaml has them substituted, so
       this is the only record of their values (render --print-config). */
    int n_params;
    struct config_param *params; /* owned */
};

/* One --set key.path=value. Paths are dot-separated mapping keys and
   sequence indices (e.g. "params.s_L", "camera.position.1", "lights.0.two_sided"). */
struct config_override {
    const char *path;
    const char *value;
};

/* Reads, validates and fills `out`. On failure `out` is left empty (nothing to
   free) and err holds "file:line:column: what was wrong (expected ...)".
   A top-level `include: path` or `include: [paths]` (relative to the folder
   of the file that names them) loads those files first, in order, each
   merged over the previous ones, then merges the file itself over them:
   mappings merge key by key (the including file wins), sequences and
   scalars are replaced whole. Overrides apply to the merged result. */
bool config_load(const char *path, const struct config_override *overrides, int n_overrides, struct config *out,
                 struct error *err);
/* Same from memory; `name` is used as the file name in messages. There is no
   folder to resolve includes against: `include:` is an error. */
bool config_load_string(const char *text, size_t length, const char *name, const struct config_override *overrides,
                        int n_overrides, struct config *out, struct error *err);
void config_free(struct config *c);

/* Writes the effective configuration (c->effective_yaml) as one JSON value:
   mappings become objects in key order, sequences arrays, plain scalars
   that read as finite decimal numbers JSON numbers (their text when it is
   valid JSON, else the shortest round-tripping %.17g form), true/false
   and null/~/empty (YAML 1.2 core spellings) booleans and null, quoted
   and other scalars strings (config_json.c). Fails only when the text
   does not parse (it always does for a loaded config) or on memory;
   out may then hold part of the value. */
bool config_write_json(const struct config *c, FILE *out, struct error *err);

#endif

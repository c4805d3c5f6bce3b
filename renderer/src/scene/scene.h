/* scene.h: the render-ready scene: materials, lights, portals and the Embree
   acceleration structure for closest-hit and occlusion queries. Embree types
   stay inside scene.c. */
#ifndef SCENE_H
#define SCENE_H

#include <stdbool.h>
#include <stdint.h>

#include "geometry/antishadow.h"
#include "scene/bsdf.h"
#include "base/error.h"
#include "base/fastmath.h"
#include "scene/light.h"
#include "scene/ray_stream.h"
#include "base/vec.h"

struct config; /* config.h */

/* One portal of a light, with its antishadow precomputed at load. */
struct portal {
    int light;
    /* The opening's polygon, area, normal: one per portal of an emitter,
       which every light of the emitter shares (scene.target_blocks). */
    const struct target *target;
    struct vec3 centroid;
    struct antishadow antishadow;
};

/* A light as the config names it: one polygon light, or a mesh light whose
   every triangle is a light of its own (lights first_light.. first_light +
   n_lights - 1, in the mesh's order). Each of its lights holds its own pair
   with each of the emitter's portals (as many as lights[first_light].n_portals),
   in the same order, with the antishadow of that light and that portal and
   the portal's target, which the pairs of the portal share; a
   portal therefore has the index lights[l].first_portal + k in every light
   l of the emitter. */
struct emitter {
    int first_light, n_lights;
    double power;    /* sum of its lights' */
    void *rtc_scene; /* a mesh light's triangles alone (RTCScene), NULL for a polygon light */
};

/* What a geometry stands for: a surface with a material, or a light. */
struct geometry_info {
    int material;        /* -1 for lights */
    int light;           /* -1 for surfaces; the first light of a mesh light */
    bool light_per_prim; /* a mesh light: primitive k is light `light + k` */
    int shape;           /* index into config.shapes, -1 for lights */
    int *prim_face;      /* a shape's: the shape's face (its quads, then its triangles) of each primitive; owned */
};

/* The light a hit on primitive prim of geometry g found, -1 for a surface. */
static inline int geometry_light(const struct geometry_info *g, unsigned prim)
{
    return g->light < 0 ? -1 : g->light + (g->light_per_prim ? (int)prim : 0);
}

/* What `portals: auto` found for one config light (portal_finder.h): the
   enclosure P, a convex hull strictly around the light, and its portals,
   which are the emitter's portals in the scene. */
struct auto_portal_report {
    bool requested; /* the config asked for auto portals */
    bool enclosed;  /* P was found and its portals added */
    int n_portals;
    double area;                /* of the portals, m^2 */
    double hull_area;           /* of P's boundary */
    int n_planes;               /* P's facets' planes, outward normals */
    struct plane *planes;       /* owned */
    struct vec3 box_lo, box_hi; /* P's bounding box */
    bool warn;                  /* note is a warning (a stated fallback), not just information */
    char note[640];             /* what was decided and why, one line */
};

struct scene {
    int n_materials;
    struct material *materials;
    int n_lights;
    struct light *lights;
    int n_emitters;
    struct emitter *emitters; /* one per config light; lights[i].emitter */
    int n_portals;
    struct portal *portals; /* grouped by light: light.first_portal.. */
    /* The portals' targets, in blocks that never move (the config's
       portals, then one block per emitter's found portals); owned. */
    int n_target_blocks;
    struct target **target_blocks;
    int n_geometries;
    struct geometry_info *geometries; /* indexed by Embree geomID */
    struct vec3 bounds_lo, bounds_hi; /* of all geometry and lights */
    double scale;                     /* bounding-box diagonal, for ray offsets */
    void *device;                     /* RTCDevice */
    void *rtc_scene;                  /* RTCScene, committed */
    /* The lights' geometries alone, under the same geometry IDs (RTCScene):
       what scene_first_light looks for before it traces anything else. */
    void *rtc_lights;
    /* The same lights as planes (light_hit.h), which scene_first_light
       tests instead when they are a few polygons; NULL otherwise. */
    struct light_hit_set *light_hits;
    /* Per emitter, what `portals: auto` found (requested false for lights
       without it). */
    struct auto_portal_report *auto_portals;
};

struct hit {
    double t;
    struct vec3 p;
    struct vec3 ng; /* unit geometric normal, winding-oriented */
    int material;   /* -1 when a light was hit */
    int light;      /* -1 when a surface was hit */
};

struct watertight_face; /* watertight.h */

/* The faces of every shape of cfg, in shape order, each shape's quads then
   its triangles: what scene_create gives watertight_stitch (the mesh-load
   bench times the stitching alone with it). *out is the caller's to free. */
bool scene_collect_faces(const struct config *cfg, struct watertight_face **out, int *n_out, struct error *err);

/* Builds Embree geometry for every shape and light; precomputes portals. */
bool scene_create(const struct config *cfg, struct scene *out, struct error *err);
void scene_destroy(struct scene *s);

/* Adds n portals (3..POLYGON_INPUT_MAX vertices, convex, planar) to every
   light of emitter `emitter`, which must have none yet, with their
   antishadows. On failure (a portal the antishadow rejects, memory) the
   scene is unchanged and err says why. */
bool scene_add_portals(struct scene *s, int emitter, const struct polygon *portals, int n, struct error *err);

/* scene_intersect that also gives the index (into s->geometries) of the
   geometry hit and, on a shape, the shape's face hit (its quads, then its
   triangles; -1 on a light), for the portal finder. */
bool scene_intersect_geometry(const struct scene *s, struct vec3 o, struct vec3 d, double tmax, struct hit *h,
                              int *geometry, int *face);

/* Closest hit along o + t d, t in (0, tmax) (d unit). False on a miss. */
bool scene_intersect(const struct scene *s, struct vec3 o, struct vec3 d, double tmax, struct hit *h);
/* Closest hits of the n rays o + t d[i], t > 0 (d[i] unit), rays from one
   point such as the camera rays of a film row. They are traced as a
   coherent stream, which Embree traces as packets: well above the single-
   ray rate for camera rays (`make bench`, raw limit), through `rays`, a
   stream with room for n rays. found[i] tells whether ray i hit; hits[i]
   is then set, as scene_intersect(s, o, d[i], INFINITY, ...) gives it, bit
   for bit. */
void scene_intersect_coherent(const struct scene *s, struct vec3 o, const struct vec3 *d, int n,
                              struct ray_stream *rays, struct hit *hits, bool *found);
/* The light that the ray o + t d, t in (0, tmax), hits first; -1 when it
   hits a surface first or nothing (the MIS ray of direct lighting, which
   counts only where it reaches a light). Most such rays reach no light,
   so the ray is first tested against the lights alone (as planes,
   light_hit.h, where they are a few polygons; else through their own
   Embree scene); only when it meets
   one, at distance t, is the rest of the scene asked whether anything
   blocks (0, t - step), the step scene_offset_step takes at a light end,
   as a shadow ray towards that point would be. */
int scene_first_light(const struct scene *s, struct vec3 o, struct vec3 d, double tmax);
/* The first n rays of a stream, traced incoherently (rays from many
   points, such as the shadow or BSDF rays of a film row), one Embree call
   for all. Occlusion: afterwards ray_stream_blocked(s, i) tells whether an
   active ray i was blocked. */
void scene_occluded_stream(const struct scene *s, struct ray_stream *rays, int n, bool coherent);
/* scene_occluded_stream for rays that converge on a few lights: the active
   ones, ordered by group (the emitter they go to), are copied into packed
   and traced as a coherent stream, and each one's result is written back
   into rays. order (n ints) is scratch. */
void scene_occluded_grouped(const struct scene *s, struct ray_stream *rays, int n, const int *group,
                            struct ray_stream *packed, int *order);
/* Closest hits: light[i] = the light ray i hits first, -1 when it hits a
   surface first or nothing (scene_first_light for each ray) or is
   inactive. */
void scene_first_light_stream(const struct scene *s, struct ray_stream *rays, int n, int *light);
/* Closest hits of the first n rays of a stream, traced incoherently (the
   bounce rays of a film row's paths): ray i must be o[i] + t d[i] as
   ray_stream_set stores it, and then found[i] and hits[i] are what
   scene_intersect(s, o[i], d[i], tmax, ...) gives, bit for bit. */
void scene_intersect_stream(const struct scene *s, struct ray_stream *rays, int n, const struct vec3 *o,
                            const struct vec3 *d, struct hit *hits, bool *found);
/* A ray still to trace: o + t d for t in (0, tmax). */
struct scene_ray {
    struct vec3 o, d;
    double tmax;
};

/* The light of emitter `emitter` that the ray o + t d (t > 0, d unit)
   meets first, ignoring everything else in the scene, with its distance;
   -1 when it misses the emitter. O(log n) in a mesh light's triangles. */
int scene_emitter_hit(const struct scene *s, int emitter, struct vec3 o, struct vec3 d, double *dist);

/* True when anything blocks o + t d for t in (0, tmax). */
bool scene_occluded(const struct scene *s, struct vec3 o, struct vec3 d, double tmax);

/* The distance scene_offset_origin moves p along d. A shadow ray along a
   sampled unit direction wi to a point at distance dist spans
   (step at p, dist - step at the far end) without renormalising wi.
   Float geometry (Embree) has a relative error of ~1e-7 in coordinates, so
   a ray must start clear of the surface it leaves. Moving the origin along
   d itself (not along the normal) keeps the ray on the exact line that was
   sampled: a normal offset shifts where a long grazing segment crosses a
   distant opening and clips it against the opening's rim. The step is
   chosen so the height above the surface is at least eps. Inline, with
   selects, so that the vectorised set-up loops (shading.c) can use it. */
FM_INLINE double scene_offset_height_scaled(double scale, struct vec3 p)
{
    return 1e-5 * scale + 1e-6 * vec3_max_abs(p);
}
FM_INLINE double scene_offset_step_scaled(double scale, struct vec3 p, struct vec3 ng, struct vec3 d)
{
    double eps = scene_offset_height_scaled(scale, p);
    double cos_n = fabs(vec3_dot(ng, d));
    return eps / (cos_n > 1e-3 ? cos_n : 1e-3);
}
/* The height above its surface at p that scene_offset_step clears. */
static inline double scene_offset_height(const struct scene *s, struct vec3 p)
{
    return scene_offset_height_scaled(s->scale, p);
}
static inline double scene_offset_step(const struct scene *s, struct vec3 p, struct vec3 ng, struct vec3 d)
{
    return scene_offset_step_scaled(s->scale, p, ng, d);
}
/* Origin for a ray leaving surface point p (geometric normal ng) along the
   unit direction d: moved along d itself until it clears the surface, so the
   ray stays on the line that was sampled and does not re-hit its surface. */
static inline struct vec3 scene_offset_origin(const struct scene *s, struct vec3 p, struct vec3 ng, struct vec3 d)
{
    return vec3_madd(p, d, scene_offset_step(s, p, ng, d));
}

#endif

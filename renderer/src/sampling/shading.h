/* shading.h: a shading point and the two rays direct lighting sends from
   it: the shadow ray towards a light sample (next-event estimation) and the
   BSDF-sampled ray that counts where it reaches a light, each weighted
   against the other by MIS. Each ray is set up, traced and resolved in
   separate steps so that a film row can do every step for all its points
   in turn (integrator_radiance_row); the set-up of a whole row is
   vectorised for Lambertian surfaces (shading_setup_many).
   It chooses no light (strategy.h) and writes no film. */
#ifndef SHADING_H
#define SHADING_H

#include <stdbool.h>
#include <stdint.h>

#include "scene/bsdf.h"
#include "sampling/integrator_stats.h"
#include "sampling/mis.h"
#include "scene/scene.h"
#include "sampling/strategy.h"
#include "base/kinds.h"
#include "base/vec.h"

/* The shading context of a surface hit: side, frame, ray origin. */
struct vertex {
    const struct material *m;
    struct vec3 n; /* geometric normal on the side of wo */
    struct frame frame;
    struct vec3 wo_local;
    struct vec3 p; /* the surface point */
};

/* m, n and p of a vertex: what every kind of vertex needs. Two-sided
   surfaces: n is the side wo leaves from. */
static inline void vertex_orient(const struct scene *sc, struct vec3 p, struct vec3 ng, int material, struct vec3 wo,
                                 struct vertex *v)
{
    v->m = &sc->materials[material];
    v->n = vec3_dot(ng, wo) > 0.0 ? ng : vec3_neg(ng);
    v->p = p;
}

/* False when wo lies in the surface's plane (nothing is reflected). */
bool vertex_init(const struct scene *sc, struct vec3 p, struct vec3 ng, int material, struct vec3 wo, struct vertex *v);
/* The same for shading_setup_many, which reads only m, n and p of a
   Lambertian point (its lanes build the frame from n): there the frame and
   wo_local are left unset, saving a division and twelve stores a point.
   Inline: a film row calls it for every pixel. */
static inline bool vertex_init_lanes(const struct scene *sc, struct vec3 p, struct vec3 ng, int material,
                                     struct vec3 wo, struct vertex *v)
{
    if (sc->materials[material].kind != MATERIAL_DIFFUSE) return vertex_init(sc, p, ng, material, wo, v);
    vertex_orient(sc, p, ng, material, wo, v);
    /* wo_local.z: the frame's z axis is n itself. */
    return vec3_dot(wo, v->n) > 0.0;
}

/* A shadow ray still to trace and what the sample delivers if the ray is
   not blocked. The set-up functions below count the rays they prepare in
   their struct integrator_stats. */
struct shadow_query {
    struct scene_ray ray;
    bool trace; /* a segment to test (else: delivered unless value is black) */
    struct rgb value;
};

/* Next-event estimation at v from a drawn light sample (ok: the strategy
   produced one), up to the shadow ray. */
void shadow_setup(const struct scene *sc, enum mis_kind mis, const struct vertex *v, bool ok,
                  const struct light_sample *ls, struct integrator_stats *stats, struct shadow_query *q);

/* A BSDF-sampled ray still to trace; it counts only where it reaches a light. */
struct bsdf_query {
    struct scene_ray ray;
    bool trace;
    struct rgb weight; /* f cos / pdf */
    double pdf;
};

/* Samples v's BSDF with the uniforms u: the ray leaving v (o offset off the
   surface, tmax infinite), its weight and density. Lambertian points take a
   cosine-distributed direction in the frame of n alone, whose weight is the
   albedo itself. It counts no ray: direct lighting traces every such ray,
   the path integrator only those that survive Russian roulette. */
void bsdf_setup(const struct scene *sc, const struct vertex *v, const double u[2], struct bsdf_query *q);

/* shadow_setup for the n points of a row and, unless ub is NULL,
   bsdf_setup with uniforms ub; the same results, bit for bit, and the same
   counts. Lambertian points go through vectorised loops, others one at a
   time. Point k's rays go to ray k of the streams instead (inactive where
   a query traces nothing), for one Embree call each (scene_occluded_stream,
   scene_first_light_stream); the streams need room for n rays. The queries
   then hold what resolving needs: trace and value (shadow; its ray fields
   are unset), and all of the BSDF query (with its ray). As bsdf_setup, it
   counts the shadow rays but not the BSDF rays. */
void shading_setup_many(const struct scene *sc, enum mis_kind mis, const struct vertex *v, const bool *ok,
                        const struct light_sample *ls, const double (*ub)[2], int n, struct integrator_stats *stats,
                        struct shadow_query *shadow, struct ray_stream *shadow_rays, struct bsdf_query *bsdf,
                        struct ray_stream *bsdf_rays);

#endif

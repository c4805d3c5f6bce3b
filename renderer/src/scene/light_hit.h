/* light_hit.h: which of a few polygon lights a ray meets first, by a plane
   and an edge test per light instead of a trace of the lights' Embree scene.

   Direct lighting asks it of every BSDF sample (scene_first_light_stream):
   the ray counts only where a light is the first thing it meets, so the
   lights alone are looked at first and the whole scene is traced only for
   the segment in front of the light met. Through Embree that first look
   was a noticeable part of a camera sample on the lampshade (an Embree
   call has a fixed cost even for a scene of one quad; docs/performance.md
   has the profile). For a handful of convex polygons, a vectorised loop
   over the row's rays, light by light, is several times cheaper.

   The answer is the closest light whose plane the ray crosses in
   [tnear, tfar] inside the polygon, both faces (as Embree's triangles
   count them; light_emitted is black from the back of a one-sided light).
   It is computed in double from the float ray Embree would have traced,
   against the lights' double polygons: Embree's float triangles agree
   with it up to the rounding of the float vertices, i.e. on rays that pass
   within about 1e-7 of a light's rim. Scenes with a mesh light or with
   more lights or edges than below keep the Embree trace. */
#ifndef LIGHT_HIT_H
#define LIGHT_HIT_H

#include <stdbool.h>

#include "scene/light.h"

/* Beyond these, the Embree trace of the lights' BVH costs less than a test
   of every light per ray. */
#define LIGHT_HIT_MAX_LIGHTS 16
#define LIGHT_HIT_MAX_EDGES  64

/* Lights 0..n_lights of a scene as planes and inward edge planes: a point
   x of light l's plane is inside its polygon when
   m_e . x >= mc_e for every edge e of first_edge[l]..first_edge[l + 1]. */
struct light_hit_set {
    int n_lights;
    int first_edge[LIGHT_HIT_MAX_LIGHTS + 1];
    double nx[LIGHT_HIT_MAX_LIGHTS], ny[LIGHT_HIT_MAX_LIGHTS], nz[LIGHT_HIT_MAX_LIGHTS];
    double nc[LIGHT_HIT_MAX_LIGHTS]; /* n . x on the plane */
    double mx[LIGHT_HIT_MAX_EDGES], my[LIGHT_HIT_MAX_EDGES], mz[LIGHT_HIT_MAX_EDGES], mc[LIGHT_HIT_MAX_EDGES];
};

/* Fills set from the n polygon lights; false when they are too many or
   have too many edges in all (the caller then traces Embree's scene). */
bool light_hit_set_init(struct light_hit_set *set, const struct light *lights, int n);

/* For each of the n rays o + t d (float arrays, as a ray stream holds
   them), the light met first for t in [tnear, tfar], and its distance;
   light[i] = -1 where none is met (an inactive ray, tnear > tfar, meets
   none). */
void light_hit_many(const struct light_hit_set *set, const float *ox, const float *oy, const float *oz, const float *dx,
                    const float *dy, const float *dz, const float *tnear, const float *tfar, int n, int *light,
                    double *t);

#endif

/* aov.h: the region AOV: the antishadow region class of each sample's
   primary (camera) hit, so that the harness can measure error per region.
   The class depends only on the hit and the scene, never on the render's
   strategy or on random numbers, so every strategy gets the same map. */
#ifndef AOV_H
#define AOV_H

#include <stdbool.h>

#include "geometry/antishadow.h"
#include "base/error.h"
#include "scene/scene.h"
#include "sampling/strategy.h"
#include "base/vec.h"

/* The classes, in the order of the EXR channels region.<name>: the five of
   enum region (antishadow.h), the same values, then two classes of camera
   rays that hit no surface point. */
enum aov_region {
    AOV_REGION_OUTSIDE = REGION_OUTSIDE, /* no light reaches the point through any portal */
    AOV_REGION_ANTI_UMBRA = REGION_ANTI_UMBRA,
    AOV_REGION_ANTI_PENUMBRA = REGION_ANTI_PENUMBRA,
    AOV_REGION_ANTI_ANTUMBRA = REGION_ANTI_ANTUMBRA,
    AOV_REGION_INSIDE = REGION_INSIDE, /* inside the shade of the dominant light */
    AOV_REGION_EMITTER,                /* the camera ray hits a light */
    AOV_REGION_MISS                    /* the camera ray leaves the scene */
};
#define AOV_REGION_COUNT 7

/* "outside", "anti_umbra", ..., indexed by enum aov_region. */
extern const char *const aov_region_names[AOV_REGION_COUNT];

/* What classification needs of the scene, built once per render. */
struct aov_classifier {
    /* An antishadow strategy with the irradiance heuristic: its pairs,
       shade boxes and pair BVH, whatever strategy the render uses. */
    struct strategy pairs;
};

bool aov_classifier_init(struct aov_classifier *c, const struct scene *sc, struct error *err);
void aov_classifier_free(struct aov_classifier *c);

/* Per-thread room for the candidate pairs of a point. */
struct aov_scratch {
    int *cand;
};
bool aov_scratch_init(const struct aov_classifier *c, struct aov_scratch *scratch, struct error *err);
/* Safe on a zeroed or freed scratch. */
void aov_scratch_free(struct aov_scratch *scratch);

/* The class of surface point p with unit normal n on the receiving side:
   that of the component (light/portal pair, or light without portals)
   with the largest luminance-weighted unoccluded irradiance at p
   (strategy_pair_irradiance; ties go to the first pair in scene order).
   Its antishadow region, or AOV_REGION_INSIDE when p is inside that
   light's shade, or AOV_REGION_ANTI_UMBRA for a light without portals
   (the whole light is seen); AOV_REGION_OUTSIDE when no component gives
   anything, or the scene has no lights. */
enum aov_region aov_classify_point(const struct aov_classifier *c, struct aov_scratch *scratch, struct vec3 p,
                                   struct vec3 n);

/* The class of a camera ray with unit direction d and first hit h (NULL
   for a miss): AOV_REGION_MISS, AOV_REGION_EMITTER for a light (either
   side: the integrators end the path there), else aov_classify_point at the
   hit with the normal on the camera's side. */
enum aov_region aov_classify_hit(const struct aov_classifier *c, struct aov_scratch *scratch, struct vec3 d,
                                 const struct hit *h);

/* aov_classify_hit for the n camera rays of a film row (found[x]: hit
   hits[x]), into cls[x]. */
void aov_classify_row(const struct aov_classifier *c, struct aov_scratch *scratch, const struct vec3 *d,
                      const struct hit *hits, const bool *found, int n, unsigned char *cls);

#endif

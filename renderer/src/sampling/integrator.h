/* integrator.h: radiance along a camera ray: `direct` (emission plus direct
   lighting at the first hit) and `path` (unidirectional path tracing with
   next-event estimation and Russian roulette), both combining the light
   strategy with BSDF sampling by multiple importance sampling.
   It owns no threads and no film: render.c drives it row by row. */
#ifndef INTEGRATOR_H
#define INTEGRATOR_H

#include <stdint.h>

#include "base/kinds.h"
#include "sampling/sampler.h"
#include "scene/scene.h"
#include "sampling/shading.h"
#include "sampling/strategy.h"

struct render_desc; /* config.h */

struct integrator {
    enum integrator_kind kind;
    enum mis_kind mis;
    int max_depth;
    int rr_depth;
    const struct scene *scene;
    const struct strategy *strategy;
};

void integrator_init(struct integrator *it, const struct render_desc *rd, const struct scene *scene,
                     const struct strategy *strategy);

/* One sample of the radiance that direct lighting reflects towards wo from
   surface point p (geometric normal ng, either side), material m: next-event
   estimation plus BSDF sampling, combined by MIS. This is the `direct`
   integrator's estimator at its first hit. */
struct rgb integrator_direct_at(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 p,
                                struct vec3 ng, int material, struct vec3 wo, struct sampler *smp,
                                struct integrator_stats *stats);

/* Radiance arriving at the camera along o + t d (d unit), the camera ray
   traced already (a row at a time, see scene_intersect_coherent): first is
   its hit, NULL for a miss. Counts the camera ray in stats. */
struct rgb integrator_radiance_from(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 o,
                                    struct vec3 d, const struct hit *first, struct sampler *smp,
                                    struct integrator_stats *stats);

/* Workspace for one film row of up to n shading points
   (integrator_radiance_row); one per render thread. NULL (and err set)
   when out of memory. */
struct integrator_row;
struct integrator_row *integrator_row_create(int n, struct error *err);
/* Safe on NULL. */
void integrator_row_destroy(struct integrator_row *row);

/* integrator_radiance_from for the n camera rays of one film row, with
   directions d[x] (n at most the size row was created for), their first
   hits already traced (found[x]: hit hits[x]; where the rays start is in
   the hits); out[x] is the same, bit for bit. Direct lighting sets up and traces the row's shadow
   and BSDF rays together, and with a strategy_batches strategy draws the
   row's light samples together too (strategy_sample_many). */
void integrator_radiance_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                             const struct vec3 *d, const struct hit *hits, const bool *found, int n,
                             struct sampler *smp, struct rgb *out, struct integrator_stats *stats);

#endif

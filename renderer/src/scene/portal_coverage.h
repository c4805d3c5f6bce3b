/* portal_coverage.h: the light side of `portals: auto`
   (scene/portal_finder.h): sampling what a light emits, and counting
   whether the rays that leave an enclosure cross it on its portals. Used
   by the finder, by render --print-config (portal_report.h) and by the
   tests. Single-threaded, with the seeds given: the same counts bit for
   bit. */
#ifndef PORTAL_COVERAGE_H
#define PORTAL_COVERAGE_H

#include <stdbool.h>
#include <stdint.h>

#include "base/error.h"
#include "geometry/polygon.h"
#include "scene/scene.h"

/* Samples points and emitted directions of one emitter: a point uniform
   by area over its lights, a direction cosine-distributed about the
   normal of its emitting side (for a two-sided light, either side with
   probability 1/2). */
struct emission_sampler {
    const struct scene *scene;
    int emitter;
    double *cdf; /* per light of the emitter, by area (owned) */
};
bool emission_sampler_init(struct emission_sampler *es, const struct scene *s, int emitter, struct error *err);
void emission_sampler_free(struct emission_sampler *es);
/* From EMISSION_UNIFORMS uniforms in [0, 1): the point *p, its light's
   unit normal on the emitting side *n, and the unit direction *d. */
#define EMISSION_UNIFORMS 7
void emission_sample(const struct emission_sampler *es, const double u[EMISSION_UNIFORMS], struct vec3 *p,
                     struct vec3 *n, struct vec3 *d);

/* The light side of the coverage test. Of n_rays rays from the emitter
   (emission_sample, seeded by seed), those that leave the convex P
   (given by its outward facet planes) unoccluded must all cross P's
   boundary on one of the portals. */
struct portal_coverage {
    long n_rays;
    long n_escaped; /* reached P's boundary with nothing in the way: they carry the light out */
    long n_missed;  /* of those, crossed it on no portal: must be 0 */
    long n_portal;  /* crossed P's boundary on a portal, blocked on the way or not */
    long n_through; /* of those, reached it unblocked */
    /* The blocked fraction, 1 - n_through / n_portal: of the light's rays
       aimed through a portal, the fraction that something inside P stops
       first, i.e. the portal samples that a render wastes. */
    double blocked_fraction;
    /* 3 / n_escaped: with no miss in n_escaped trials, the fraction of the
       escaping flux that crosses no portal is below it at 95% confidence
       (rule of three). */
    double bound;
};
bool portal_finder_coverage(const struct scene *s, int emitter, const struct plane *planes, int n_planes,
                            const struct polygon *portals, int n_portals, long n_rays, uint64_t seed,
                            struct portal_coverage *out, struct error *err);

/* The portals of emitter e as the scene holds them (its first light's). */
int portal_finder_portals(const struct scene *s, int emitter, const struct polygon **out, int max);

#endif

/* portal_finder.h: `portals: auto`: the portals of a light inside a shade,
   found from the geometry when the scene is built, so that every path of
   every run sees the same portals.

   The construction is complete by design. P is the convex hull of the
   shapes around the light (the shapes that rays from the light meet first,
   nearest first, until their hull holds the light strictly inside, then
   without any of them whose removal leaves less open area); every part of
   P's boundary that no opaque surface lying in it covers becomes a
   portal, except whole facets that a layer of surface just under them
   provably closes (layer_covers in portal_finder.c). A segment from a point of the light (inside P) to a point
   outside P crosses P's boundary exactly once; if nothing blocks it, it
   crosses where no surface lies, which is on a portal. That holds for any
   convex P that strictly contains the light: the choice of shapes only
   decides how tight the portals are. Points inside P are inside the
   light's shade for the strategies (strategy.h), which sample the light
   itself there.

   Single-threaded, with fixed seeds: the same scene gives the same portals
   bit for bit whatever render.threads. */
#ifndef PORTAL_FINDER_H
#define PORTAL_FINDER_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "geometry/polygon.h"
#include "scene/scene.h"

struct config; /* config.h */

/* Rays cast from each light to find the shapes around it. */
#define PORTAL_FINDER_RAYS 8192
/* A shape whose bounding box is larger than this fraction of the scene's
   is a room, a floor or a wall, never a shade: it is not considered. */
#define PORTAL_FINDER_MAX_SHAPE_FRACTION 0.5
/* An enclosure whose uncovered boundary is more than this fraction of its
   area is no shade: its light gets no portals. */
#define PORTAL_FINDER_MAX_OPEN_FRACTION 0.75
/* More portals than this cost every shading point more than they save (a
   curved shell's hull leaves a sliver between each hull facet and the
   surface under it): the light gets none, with a warning. */
#define PORTAL_FINDER_MAX_PORTALS 64
/* Shapes beyond the first hull that holds the light tried for a tighter
   one (the nearby ones only). */
#define PORTAL_FINDER_MAX_EXTRA 16

/* Finds the portals of every light of cfg with auto_portals and adds them
   to s (scene_add_portals), filling s->auto_portals. A light that nothing
   encloses gets no portal and a note; a light that touches or pierces the
   hull around it, or whose portals the antishadow rejects, gets no portal
   and a warning (report.warn): it is then sampled as `light` samples it,
   which is unbiased. Fails only on memory or an Embree error. */
bool portal_finder_run(struct scene *s, const struct config *cfg, struct error *err);

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

/* Writes what `portals: auto` found as YAML comments, for render
   --print-config: per light a summary line (portals, their area, the
   blocked fraction and the coverage bound from n_rays rays), then the
   found portals as ordinary `portals:` entries that a user can paste into
   a config in place of the auto entries. Nothing when no light asked for
   auto portals. */
bool portal_finder_write_summary(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                                 struct error *err);

/* The same as one JSON object, for render --print-config --format json:
   {"<light>": {"enclosed", "warning", "note", "n_portals", "area",
   "hull_area", "blocked_fraction", "bound", "n_rays", "n_escaped",
   "n_missed" (these five only when enclosed), "portals": [{"name",
   "light", "vertices"}...]}...} over the lights that asked for auto
   portals ({} when none did). */
bool portal_finder_write_json(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                              struct error *err);

/* The rays of the coverage count that render --print-config makes per
   light with auto portals (fixed seed, single-threaded: the same numbers
   whatever render.threads). 2^17 keeps it well under a second on the
   shipped scenes; with every ray escaping the bound is 2.3e-5, so the
   1e-5 goal needs test_portal_finder's longer counts. */
#define PORTAL_FINDER_SUMMARY_RAYS 131072L

#endif

/* light.h: uniform area lights on convex planar polygons: emission and the
   quantities light selection needs. Sampling goes through the light's
   target (target.h).
   It has no sampling code of its own (target.h) and never sees Embree. */
#ifndef LIGHT_H
#define LIGHT_H

#include <stdbool.h>

#include "geometry/target.h"
#include "base/vec.h"

struct light {
    struct target target; /* polygon, normal (emitting side), area */
    struct vec3 centroid; /* of the polygon: the per-point weights measure from it */
    struct rgb radiance;  /* W / (m^2 sr) per channel */
    bool two_sided;
    double power;                /* luminance flux: pi * area * Y(radiance) * sides */
    int first_portal, n_portals; /* range in scene.portals */
    int emitter;                 /* index in scene.emitters */
};

/* Fills the light; false when the polygon is degenerate. */
bool light_init(struct light *l, const struct polygon *poly, struct rgb radiance, bool two_sided);

/* Radiance leaving the light towards w_out (unit, pointing away from it);
   black from the back of a one-sided light. Inline: every light sample
   and every camera or BSDF ray that meets a light asks. */
static inline struct rgb light_emitted(const struct light *l, struct vec3 w_out)
{
    if (l->two_sided || vec3_dot(w_out, l->target.normal) > 0.0) return l->radiance;
    return rgb_make(0.0, 0.0, 0.0);
}

/* Relative margin of light_culled: a plane distance h counts as clearly
   negative when h < 0 and h^2 > LIGHT_CULL_MARGIN2 |d|^2, d the vector
   it was measured along. Within that, a sampled direction's rounding
   (~1e-16 relative) could still deliver something, so those points are
   left to sampling. */
#define LIGHT_CULL_MARGIN2 1e-18

static inline bool light_clearly_below(double h, struct vec3 d)
{
    return h < 0.0 && h * h > LIGHT_CULL_MARGIN2 * vec3_dot(d, d);
}

/* Whether l delivers nothing to point p, whose receiving side has unit
   normal n (zero: it receives from every side), whatever the direction:
   p lies clearly behind a one-sided light's plane (light_emitted is black
   towards it), or every vertex of the light lies clearly below p's
   horizon (no direction to the light has a positive cosine at p). The
   light-only strategies draw no sample of such a light, nor do the pairs
   that pick a mesh light's triangle (strategy.c): the sample's value was
   exactly zero and no ray was traced for it, but it was drawn, which on
   the lampshade was a large share of the `light` strategy's samples (the
   ceiling, the upper walls; docs/performance.md). */
static inline bool light_culled(const struct light *l, struct vec3 p, struct vec3 n)
{
    const struct polygon *poly = &l->target.polygon;
    struct vec3 to_p = vec3_sub(p, poly->v[0]);
    if (!l->two_sided && light_clearly_below(vec3_dot(to_p, l->target.normal), to_p)) return true;
    if (vec3_dot(n, n) == 0.0) return false;
    for (int j = 0; j < poly->n; ++j) {
        struct vec3 d = vec3_sub(poly->v[j], p);
        if (!light_clearly_below(vec3_dot(d, n), d)) return false;
    }
    return true;
}

#endif

/* light.h: uniform area lights on convex planar polygons: emission and the
   quantities light selection needs. Sampling goes through the light's
   target (target.h).
   It has no sampling code of its own (target.h) and never sees Embree. */
#ifndef LIGHT_H
#define LIGHT_H

#include <stdbool.h>

#include "target.h"
#include "vec.h"

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

#endif

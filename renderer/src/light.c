#include "light.h"

bool light_init(struct light *l, const struct polygon *poly, struct rgb radiance, bool two_sided)
{
    if (!target_init(&l->target, poly)) return false;
    l->radiance = radiance;
    l->two_sided = two_sided;
    l->power = M_PI * l->target.area * rgb_luminance(radiance) * (two_sided ? 2.0 : 1.0);
    l->first_portal = l->n_portals = 0;
    return true;
}

struct rgb light_emitted(const struct light *l, struct vec3 w_out)
{
    if (l->two_sided || vec3_dot(w_out, l->target.normal) > 0.0) return l->radiance;
    return rgb_make(0.0, 0.0, 0.0);
}

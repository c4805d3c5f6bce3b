#include "scene/light.h"

bool light_init(struct light *l, const struct polygon *poly, struct rgb radiance, bool two_sided)
{
    if (!target_init(&l->target, poly)) return false;
    l->centroid = polygon_centroid(&l->target.polygon);
    l->radiance = radiance;
    l->two_sided = two_sided;
    l->power = M_PI * l->target.area * rgb_luminance(radiance) * (two_sided ? 2.0 : 1.0);
    l->first_portal = l->n_portals = 0;
    return true;
}

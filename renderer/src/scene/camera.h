/* camera.h: pinhole camera with a vertical field of view; pixel (0, 0) is at
   the top left; box-filtered pixels are sampled by jittering inside them.
   It keeps no film and no random state: callers pass the jitter. */
#ifndef CAMERA_H
#define CAMERA_H

#include "base/vec.h"

struct camera_desc; /* config.h */

struct camera {
    struct vec3 origin;
    struct vec3 forward, right, up; /* unit */
    double tan_half_fov;
    int width, height;
    /* Film plane at distance 1: the (unnormalised) direction through film
       position (px, py) is top_left + px * dx + py * dy. */
    struct vec3 top_left, dx, dy;
};

void camera_init(struct camera *c, const struct camera_desc *d, int width, int height);
/* Unit direction through film position (px, py) in pixels (continuous).
   Inline so that a loop over a film row vectorises. */
static inline struct vec3 camera_ray(const struct camera *c, double px, double py)
{
    return vec3_normalize(vec3_add(c->top_left, vec3_add(vec3_scale(c->dx, px), vec3_scale(c->dy, py))));
}

#endif

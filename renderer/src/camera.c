#include "camera.h"

void camera_init(struct camera *c, const struct camera_desc *d, int width, int height)
{
    c->origin = d->position;
    c->forward = vec3_normalize(vec3_sub(d->look_at, d->position));
    c->right = vec3_normalize(vec3_cross(c->forward, d->up));
    c->up = vec3_cross(c->right, c->forward);
    c->tan_half_fov = tan(0.5 * d->fov_y_deg * M_PI / 180.0);
    c->width = width;
    c->height = height;
}

struct vec3 camera_ray(const struct camera *c, double px, double py)
{
    /* Square pixels: the vertical extent spans the field of view. */
    double aspect = (double)c->width / (double)c->height;
    double sx = (2.0 * px / c->width - 1.0) * aspect * c->tan_half_fov;
    double sy = (1.0 - 2.0 * py / c->height) * c->tan_half_fov;
    return vec3_normalize(vec3_add(c->forward, vec3_add(vec3_scale(c->right, sx), vec3_scale(c->up, sy))));
}

#include "scene/camera.h"

#include "config/config.h"

void camera_init(struct camera *c, const struct camera_desc *d, int width, int height)
{
    c->origin = d->position;
    c->forward = vec3_normalize(vec3_sub(d->look_at, d->position));
    c->right = vec3_normalize(vec3_cross(c->forward, d->up));
    c->up = vec3_cross(c->right, c->forward);
    c->tan_half_fov = tan(0.5 * d->fov_y_deg * M_PI / 180.0);
    c->width = width;
    c->height = height;
    /* Square pixels: the vertical extent spans the field of view. */
    double half_h = c->tan_half_fov, half_w = half_h * (double)width / (double)height;
    c->top_left = vec3_add(c->forward, vec3_add(vec3_scale(c->right, -half_w), vec3_scale(c->up, half_h)));
    c->dx = vec3_scale(c->right, 2.0 * half_w / width);
    c->dy = vec3_scale(c->up, -2.0 * half_h / height);
}

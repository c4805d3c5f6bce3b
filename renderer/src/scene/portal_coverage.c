#include "scene/portal_coverage.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"

bool emission_sampler_init(struct emission_sampler *es, const struct scene *s, int emitter, struct error *err)
{
    const struct emitter *e = &s->emitters[emitter];
    es->scene = s;
    es->emitter = emitter;
    es->cdf = malloc(sizeof *es->cdf * (size_t)e->n_lights);
    if (!es->cdf) return error_set(err, "out of memory for the emission sampler");
    double sum = 0.0;
    for (int i = 0; i < e->n_lights; ++i) es->cdf[i] = sum += s->lights[e->first_light + i].target.area;
    for (int i = 0; i < e->n_lights; ++i) es->cdf[i] /= sum;
    return true;
}

void emission_sampler_free(struct emission_sampler *es)
{
    free(es->cdf);
    es->cdf = NULL;
}

void emission_sample(const struct emission_sampler *es, const double u[EMISSION_UNIFORMS], struct vec3 *p,
                     struct vec3 *n, struct vec3 *d)
{
    const struct scene *s = es->scene;
    const struct emitter *e = &s->emitters[es->emitter];
    int lo = 0, hi = e->n_lights - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (es->cdf[mid] > u[0]) hi = mid;
        else lo = mid + 1;
    }
    const struct light *l = &s->lights[e->first_light + lo];
    const struct polygon *poly = &l->target.polygon;
    /* A triangle of the fan by area, then a uniform point in it. */
    double r = u[1] * l->target.area, acc = 0.0;
    int k = 1;
    for (; k + 2 < poly->n; ++k) {
        acc += 0.5 * vec3_length(vec3_cross(vec3_sub(poly->v[k], poly->v[0]), vec3_sub(poly->v[k + 1], poly->v[0])));
        if (r < acc) break;
    }
    double su = sqrt(u[2]);
    double b0 = 1.0 - su, b1 = su * (1.0 - u[3]), b2 = su * u[3];
    *p = vec3_add(vec3_add(vec3_scale(poly->v[0], b0), vec3_scale(poly->v[k], b1)), vec3_scale(poly->v[k + 1], b2));
    struct vec3 normal = l->target.normal;
    if (l->two_sided && u[6] < 0.5) normal = vec3_neg(normal);
    /* Cosine-weighted (Malley): a uniform point of the unit disc lifted
       onto the hemisphere. */
    double radius = sqrt(u[4]), phi = 2.0 * M_PI * u[5];
    double x = radius * cos(phi), y = radius * sin(phi), z = sqrt(fmax(0.0, 1.0 - u[4]));
    struct frame f = frame_from_normal(normal);
    *n = normal;
    *d = vec3_normalize(frame_to_world(&f, vec3_make(x, y, z)));
}

/* The distance along d from p (inside P) to P's boundary. */
static double exit_distance(const struct plane *planes, int n, struct vec3 p, struct vec3 d)
{
    double t = INFINITY;
    for (int i = 0; i < n; ++i) {
        double c = vec3_dot(planes[i].normal, d);
        if (c > 0.0) t = fmin(t, fmax(0.0, -plane_distance(&planes[i], p)) / c);
    }
    return t;
}

static void draw_uniforms(struct rng *r, double u[EMISSION_UNIFORMS])
{
    for (int k = 0; k < EMISSION_UNIFORMS; ++k) u[k] = rng_uniform(r);
}

bool portal_finder_coverage(const struct scene *s, int emitter, const struct plane *planes, int n_planes,
                            const struct polygon *portals, int n_portals, long n_rays, uint64_t seed,
                            struct portal_coverage *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    struct emission_sampler es;
    if (!emission_sampler_init(&es, s, emitter, err)) return false;
    struct rng r = rng_seeded(seed, (uint64_t)emitter, 0);
    for (long i = 0; i < n_rays; ++i) {
        double u[EMISSION_UNIFORMS];
        struct vec3 p, n, d;
        draw_uniforms(&r, u);
        emission_sample(&es, u, &p, &n, &d);
        /* A grazing ray's offset origin can land beyond a wall close to
           the light (the step grows as 1 / cos), or within the float
           resolution of the wall, where whether Embree sees the wall is
           rounding: such a ray tests the offset, not the portals, and is
           not counted. So the origin must lie inside P by more than the
           height the offset clears above a surface. */
        double step = scene_offset_step(s, p, n, d), t_exit = exit_distance(planes, n_planes, p, d) - step;
        struct vec3 o = vec3_madd(p, d, step);
        if (!isfinite(t_exit) || !(t_exit > scene_offset_height(s, o))) continue;
        bool on_portal = false;
        for (int k = 0; k < n_portals && !on_portal; ++k) {
            double t;
            on_portal = polygon_intersect_ray(&portals[k], o, d, &t);
        }
        struct hit h;
        /* Blocked: a surface before P's boundary, or on it (a covering
           surface lies in P's facet): the test reaches slightly beyond. */
        double reach = t_exit + scene_offset_height(s, vec3_madd(o, d, t_exit));
        bool blocked = scene_intersect(s, o, d, reach, &h);
        ++out->n_rays;
        out->n_portal += on_portal;
        if (!blocked) {
            ++out->n_escaped;
            out->n_through += on_portal;
            out->n_missed += !on_portal;
        }
    }
    emission_sampler_free(&es);
    out->blocked_fraction = out->n_portal > 0 ? 1.0 - (double)out->n_through / (double)out->n_portal : 0.0;
    out->bound = out->n_escaped > 0 ? 3.0 / (double)out->n_escaped : INFINITY;
    return true;
}

int portal_finder_portals(const struct scene *s, int emitter, const struct polygon **out, int max)
{
    const struct light *l = &s->lights[s->emitters[emitter].first_light];
    int n = 0;
    for (int k = 0; k < l->n_portals && n < max; ++k) out[n++] = &s->portals[l->first_portal + k].target->polygon;
    return n;
}

/* strategy_batch.c: sampling many points at once, with the same decisions
   from the same numbers as strategy_sample one point at a time: the light
   strategy's spherical rectangles together, and the portal strategies'
   samples left waiting by strategy_sample_begin. */
#include <stddef.h>

#include "sampling/strategy_internal.h"

/* Points per batch (stack arrays, no allocation). */
#define STRATEGY_MANY_CHUNK 64

void strategy_sample_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4], int n,
                          struct light_sample *out, bool *ok)
{
    if (s->kind != STRATEGY_LIGHT) {
        for (int i = 0; i < n; ++i) ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
        return;
    }
    /* strategy_sample's light-only branch, lane by lane: the light by
       power, then target_sample_solid_angle. The lanes it samples as
       spherical rectangles go to sphrect_sample_many together and are
       finished here; the others (and the rectangle lanes that area
       sampling must take) go the one-point way, which takes the same
       decisions from the same numbers. */
    for (int b = 0; b < n; b += STRATEGY_MANY_CHUNK) {
        int m = n - b < STRATEGY_MANY_CHUNK ? n - b : STRATEGY_MANY_CHUNK, lanes = 0;
        const struct sphrect_frame *frames[STRATEGY_MANY_CHUNK];
        struct vec3 o[STRATEGY_MANY_CHUNK], wi[STRATEGY_MANY_CHUNK];
        double uu[STRATEGY_MANY_CHUNK], vv[STRATEGY_MANY_CHUNK], dist[STRATEGY_MANY_CHUNK], omega[STRATEGY_MANY_CHUNK];
        int lane_of[STRATEGY_MANY_CHUNK], light_of[STRATEGY_MANY_CHUNK];
        for (int i = b; i < b + m; ++i) {
            int light = alias_sample(&s->power, u[i][0], NULL);
            const struct target *t = &s->scene->lights[light].target;
            /* strategy_sample culls as sample_at does; the rectangle lanes
               are culled here, once. */
            if (!target_rect_lane(t, pts[i].p)) {
                ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
                continue;
            }
            if (strategy_light_only_culls(s, light, &pts[i])) {
                ok[i] = false;
                continue;
            }
            frames[lanes] = &t->frame;
            o[lanes] = pts[i].p;
            uu[lanes] = u[i][2];
            vv[lanes] = u[i][3];
            light_of[lanes] = light;
            lane_of[lanes++] = i;
        }
        sphrect_sample_many(frames, o, uu, vv, lanes, wi, dist, omega);
        for (int k = 0; k < lanes; ++k) {
            int i = lane_of[k];
            bool by_area;
            double pdf = target_rect_lane_pdf(omega[k], dist[k], &by_area);
            if (by_area) {
                ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
                continue;
            }
            ok[i] = pdf > 0.0;
            if (ok[i]) strategy_finish_light_only(s, light_of[k], wi[k], dist[k], pdf, &out[i]);
        }
    }
}

void strategy_sample_finish_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4],
                                 const struct strategy_pending *pend, int n, struct light_sample *out, bool *ok)
{
    for (int b = 0; b < n; b += STRATEGY_MANY_CHUNK) {
        int end = n - b < STRATEGY_MANY_CHUNK ? n : b + STRATEGY_MANY_CHUNK, m = 0;
        const struct target *t[STRATEGY_MANY_CHUNK];
        struct vec3 p[STRATEGY_MANY_CHUNK];
        double uu[STRATEGY_MANY_CHUNK][3];
        int lane[STRATEGY_MANY_CHUNK];
        struct target_point tp[STRATEGY_MANY_CHUNK];
        bool got[STRATEGY_MANY_CHUNK];
        for (int i = b; i < end; ++i) {
            if (!pend[i].waiting) continue;
            /* strategy_sample's technique_sample: the same target, point
               and uniforms. */
            t[m] = pend[i].target;
            p[m] = pts[i].p;
            for (int j = 0; j < 3; ++j) uu[m][j] = u[i][j + 1];
            lane[m++] = i;
        }
        target_sample_solid_angle_many(t, p, (const double(*)[3])uu, m, tp, got);
        for (int k = 0; k < m; ++k) {
            int i = lane[k];
            ok[i] = got[k];
            if (got[k])
                strategy_finish_sample(s, &pts[i], &s->pairs[pend[i].index], pend[i].index, &tp[k], 1.0, pend[i].sel,
                                       &out[i]);
        }
    }
}

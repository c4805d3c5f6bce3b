/* ray_stream.h: rays traced together by one Embree call, stored as arrays of
   floats, one array per component (Embree's SOA stream layout, rtcOccludedNp
   and rtcIntersectNp). A vectorised loop can then write a row's rays
   straight from its registers, and tracing them costs one call instead of a
   call, a context and a double-to-float conversion per ray (`make bench`:
   the renderer's per-ray wrappers traced the raw ray mix slower than
   Embree alone; docs/performance.md). scene.c traces a stream (scene_occluded_stream,
   scene_first_light_stream); the types here stay free of Embree's.
   It holds rays; tracing them is scene.c's job, the only place Embree is
   seen. */
#ifndef RAY_STREAM_H
#define RAY_STREAM_H

#include <math.h>
#include <stdbool.h>

#include "base/error.h"
#include "base/vec.h"

/* Ray i is o + t d for t in (tnear[i], tfar[i]). A ray with tnear > tfar is
   inactive: Embree skips it and leaves it as it is. */
struct ray_stream {
    float *ox, *oy, *oz, *dx, *dy, *dz, *tnear, *tfar;
    /* Embree's other components: time, mask, id and flags are set once at
       creation; the hit fields are written by closest-hit tracing
       (geom_id is reset before each trace). */
    float *time;
    unsigned *mask, *id, *flags;
    float *ng_x, *ng_y, *ng_z, *u, *v;
    unsigned *prim_id, *geom_id, *inst_id;
};

/* Room for cap rays (rounded up to whole vectors); false (err set) when
   out of memory. */
bool ray_stream_init(struct ray_stream *s, int cap, struct error *err);
void ray_stream_free(struct ray_stream *s);

/* The float end of the segment: rays without an end (tmax infinite or
   beyond float range) go to infinity. The same conversion as the one-ray
   wrappers (scene.c), so a ray traced either way is the same ray. */
static inline float ray_stream_tfar(double tmax)
{
    return tmax < 3.0e38 ? (float)tmax : INFINITY;
}

/* The segment (tnear, tfar) of a ray that is traced up to tmax, or of an
   inactive one: (1, 0). Its tfar is 0 because an occlusion trace sets tfar
   to -inf for blocked rays only, so an inactive ray reads as clear.
   Selects, so that vectorised loops (shading.c) write them too. */
static inline float ray_stream_tnear_for(bool active)
{
    return active ? 0.0f : 1.0f;
}
static inline float ray_stream_tfar_for(bool active, double tmax)
{
    return active ? ray_stream_tfar(tmax) : 0.0f;
}

/* Sets ray i to o + t d, t in (0, tmax). */
static inline void ray_stream_set(struct ray_stream *s, int i, struct vec3 o, struct vec3 d, double tmax)
{
    s->ox[i] = (float)o.x, s->oy[i] = (float)o.y, s->oz[i] = (float)o.z;
    s->dx[i] = (float)d.x, s->dy[i] = (float)d.y, s->dz[i] = (float)d.z;
    s->tnear[i] = ray_stream_tnear_for(true);
    s->tfar[i] = ray_stream_tfar_for(true, tmax);
}

/* Ray `from`'s segment (origin, direction, tnear, tfar) into ray `to`,
   as a set of rays is compacted. */
static inline void ray_stream_move(struct ray_stream *s, int from, int to)
{
    s->ox[to] = s->ox[from], s->oy[to] = s->oy[from], s->oz[to] = s->oz[from];
    s->dx[to] = s->dx[from], s->dy[to] = s->dy[from], s->dz[to] = s->dz[from];
    s->tnear[to] = s->tnear[from];
    s->tfar[to] = s->tfar[from];
}

/* Marks ray i as not to be traced. */
static inline void ray_stream_skip(struct ray_stream *s, int i)
{
    s->tnear[i] = ray_stream_tnear_for(false);
    s->tfar[i] = ray_stream_tfar_for(false, 0.0);
}

/* Whether ray i is to be traced (ray_stream_skip makes tnear > tfar). */
static inline bool ray_stream_active(const struct ray_stream *s, int i)
{
    return s->tnear[i] <= s->tfar[i];
}

/* Ray i of src into slot j of dst, as it is. */
static inline void ray_stream_copy(struct ray_stream *dst, int j, const struct ray_stream *src, int i)
{
    dst->ox[j] = src->ox[i], dst->oy[j] = src->oy[i], dst->oz[j] = src->oz[i];
    dst->dx[j] = src->dx[i], dst->dy[j] = src->dy[i], dst->dz[j] = src->dz[i];
    dst->tnear[j] = src->tnear[i];
    dst->tfar[j] = src->tfar[i];
}

/* After scene_occluded_stream: whether ray i was blocked. */
static inline bool ray_stream_blocked(const struct ray_stream *s, int i)
{
    return s->tfar[i] < 0.0f;
}

#endif

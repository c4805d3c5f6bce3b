/* ray_stream.c: the arrays of a ray stream, carved from one aligned block. */
#include "scene/ray_stream.h"

#include <stdlib.h>
#include <string.h>

/* Arrays per stream: 14 of floats (origin, direction, tnear, tfar, time,
   hit normal, u, v) and 6 of unsigned (mask, id, flags, primitive,
   geometry, instance), all 4 bytes an element. */
#define RAY_STREAM_ARRAYS 20
/* Elements per array rounded up to a multiple of this, so that every array
   starts on a 64-byte line (Embree asks for 16 bytes). */
#define RAY_STREAM_ROUND 16

bool ray_stream_init(struct ray_stream *s, int cap, struct error *err)
{
    memset(s, 0, sizeof *s);
    size_t n = ((size_t)(cap > 0 ? cap : 1) + RAY_STREAM_ROUND - 1) / RAY_STREAM_ROUND * RAY_STREAM_ROUND;
    void *block = NULL;
    if (posix_memalign(&block, 64, RAY_STREAM_ARRAYS * n * sizeof(float)) != 0)
        return error_set(err, "out of memory for a stream of %d rays", cap);
    /* Rays that are never set are zero, not garbage, should Embree look
       at an inactive ray's components. */
    memset(block, 0, RAY_STREAM_ARRAYS * n * sizeof(float));
    float *f = block;
    float **floats[] = { &s->ox,   &s->oy,   &s->oz,   &s->dx,   &s->dy,   &s->dz, &s->tnear,
                         &s->tfar, &s->time, &s->ng_x, &s->ng_y, &s->ng_z, &s->u,  &s->v };
    unsigned **uints[] = { &s->mask, &s->id, &s->flags, &s->prim_id, &s->geom_id, &s->inst_id };
    size_t nf = sizeof floats / sizeof floats[0], nu = sizeof uints / sizeof uints[0];
    for (size_t k = 0; k < nf; ++k) *floats[k] = f + k * n;
    for (size_t k = 0; k < nu; ++k) *uints[k] = (unsigned *)(f + (nf + k) * n);
    /* What every ray of the renderer has: no motion blur (time 0), every
       geometry visible, no ray flags (0); inactive until set. */
    for (size_t i = 0; i < n; ++i) {
        s->mask[i] = ~0u;
        s->id[i] = (unsigned)i;
        ray_stream_skip(s, (int)i);
    }
    return true;
}

void ray_stream_free(struct ray_stream *s)
{
    /* ox is the start of the block. */
    free(s->ox);
    memset(s, 0, sizeof *s);
}

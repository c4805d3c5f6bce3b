/* sampler.h: where a pixel sample's random numbers come from
   (`render.sampler`). Each draw names what it is for (camera jitter, a
   light sample, a BSDF sample, Russian roulette) and at which bounce, so
   that a low-discrepancy sampler can give each its own stratified
   dimensions:

   - independent: a PCG32 stream per (seed, pixel, pass) (rng.h), drawn in
     call order whatever the purpose: camera jitter 2, then per bounce the
     light sample 4, the BSDF sample 2, roulette 1;
   - sobol: an Owen-scrambled Sobol sequence, progressive in the pass
     (the sample index within the pixel is the pass number) and scrambled
     per pixel by a hash of (seed, pixel).

   Sobol's dimensions are allocated by padding (Burley 2020, sec. 4; the
   scheme of pbrt-v4's PaddedSobol and ZSobol samplers): each purpose at
   each bounce is a block that draws Sobol dimensions 0..n-1 (n <= 4) of
   its own randomly shuffled copy of the sequence, with its own
   scrambles. Within a block the points are a scrambled Sobol net: the
   camera jitter and the light sample's point are (0,2)-sequences in 2D,
   every power-of-two prefix of the passes one point per elementary
   interval; between blocks the sample orders are independent random
   nested permutations, so bounces and purposes do not correlate. Padding
   needs no more dimensions than a block has, so every bounce of every
   path is stratified this way and nothing falls back to independent
   numbers. Blocks: camera 0; at bounce b, light 1 + 3b, BSDF 2 + 3b,
   roulette 3 + 3b.

   The light sample's four numbers are u[0] (which light or light/portal
   pair), u[1] (which triangle of a polygon fan), u[2], u[3] (the point):
   the point takes dimensions 0 and 1, the pair choice 2, the triangle 3. */
#ifndef SAMPLER_H
#define SAMPLER_H

#include <stdint.h>

#include "base/rng.h"
#include "base/kinds.h"

/* One pixel sample's source of numbers; a value its caller owns. */
struct sampler {
    /* independent: the stream every draw comes from; sobol: unused by the
       draws, a distinct state per (pixel, pass) for the fault hook. */
    struct rng rng;
    enum sampler_kind kind;
    uint32_t index;          /* sobol: the sample index (the pass, mod 2^32) */
    uint32_t index_reversed; /* its bits reversed */
    uint64_t pixel_key;      /* sobol: hash of (seed, pixel) */
};

/* The sample of pass `pass` of pixel `pixel` (y * width + x). */
void sampler_start(struct sampler *s, enum sampler_kind kind, uint64_t seed, uint64_t pixel, int64_t pass);

/* An independent sampler over an existing stream (tests and tools that
   seed their own). */
static inline struct sampler sampler_of_rng(struct rng r)
{
    struct sampler s;
    s.rng = r;
    s.kind = SAMPLER_INDEPENDENT;
    s.index = 0;
    s.index_reversed = 0;
    s.pixel_key = 0;
    return s;
}

/* Each draw returns uniforms in [0, 1). depth is the bounce (0 at the
   camera ray's hit). */
void sampler_camera(struct sampler *s, double u[2]);
void sampler_light(struct sampler *s, int depth, double u[4]);
void sampler_bsdf(struct sampler *s, int depth, double u[2]);
/* sampler_light(&smp[pixel[k]], depth, u[k]) and then, unless ub is NULL,
   sampler_bsdf(&smp[pixel[k]], depth, ub[k]) for k < n: the same numbers,
   bit for bit, and the same sampler states. Independent streams advance
   together in vectorised loops (a film row's shading points draw this way
   once they are known). */
void sampler_light_bsdf_many(struct sampler *smp, const int *pixel, int n, int depth, double (*u)[4], double (*ub)[2]);
double sampler_roulette(struct sampler *s, int depth);

/* The numbers of Sobol block `block` for sample `index` of the pixel with
   key pixel_key: n <= 4 fractions in 0.32 fixed point (for the tests). */
void sampler_sobol_block(uint64_t pixel_key, uint32_t block, uint32_t index, int n, uint32_t out[4]);

/* The pixel key of the sobol sampler for (seed, pixel). */
uint64_t sampler_pixel_key(uint64_t seed, uint64_t pixel);

#endif

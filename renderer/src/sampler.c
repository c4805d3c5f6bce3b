/* sampler.c: the draws of each sampler (see sampler.h). */
#include "sampler.h"

#include "sobol.h"

/* Block numbers (sampler.h). */
#define BLOCK_CAMERA 0u
static uint32_t block_light(int depth)
{
    return 1u + 3u * (uint32_t)depth;
}

/* Keys of one block's seeds are pixel_key + (block * 8 + slot) * KEY_STEP:
   slot 0 shuffles the sample order, slot 1 + d scrambles dimension d. The
   step is odd, so distinct (block, slot) give distinct keys, and the hash
   decorrelates neighbours. */
#define KEY_STEP 0xd1342543de82ef95ull

uint64_t sampler_pixel_key(uint64_t seed, uint64_t pixel)
{
    return rng_mix64(seed ^ rng_mix64(pixel * 0x9fb21c651e98df25ull + 0x5851f42d4c957f2dull));
}

void sampler_start(struct sampler *s, enum sampler_kind kind, uint64_t seed, uint64_t pixel, int64_t pass)
{
    s->rng = rng_seeded(seed, pixel, (uint64_t)pass);
    s->kind = kind;
    s->index = (uint32_t)pass;
    s->pixel_key = kind == SAMPLER_SOBOL ? sampler_pixel_key(seed, pixel) : 0;
}

void sampler_sobol_block(uint64_t pixel_key, uint32_t block, uint32_t index, int n, uint32_t out[4])
{
    uint64_t key = pixel_key + (uint64_t)block * 8u * KEY_STEP;
    /* Owen-scrambling the index (bit-reversed) permutes every aligned run
       of 2^k indices within itself: the first 2^k passes still draw one
       aligned run of the sequence, a net, in a random order of the block's
       own (Burley 2020, sec. 4). */
    uint32_t i = sobol_owen_scramble(index, sobol_hash(key));
    for (int d = 0; d < n; ++d)
        out[d] = sobol_owen_scramble(sobol_point(i, d), sobol_hash(key + (uint64_t)(d + 1) * KEY_STEP));
}

static double fraction(uint32_t x)
{
    return (double)x * 0x1.0p-32;
}

void sampler_camera(struct sampler *s, double u[2])
{
    switch (s->kind) {
    case SAMPLER_INDEPENDENT:
        u[0] = rng_uniform(&s->rng);
        u[1] = rng_uniform(&s->rng);
        return;
    case SAMPLER_SOBOL: {
        uint32_t x[4];
        sampler_sobol_block(s->pixel_key, BLOCK_CAMERA, s->index, 2, x);
        u[0] = fraction(x[0]);
        u[1] = fraction(x[1]);
        return;
    }
    }
}

void sampler_light(struct sampler *s, int depth, double u[4])
{
    switch (s->kind) {
    case SAMPLER_INDEPENDENT:
        for (int k = 0; k < 4; ++k) u[k] = rng_uniform(&s->rng);
        return;
    case SAMPLER_SOBOL: {
        uint32_t x[4];
        sampler_sobol_block(s->pixel_key, block_light(depth), s->index, 4, x);
        /* The point on the light or portal gets the (0,2)-sequence. */
        u[2] = fraction(x[0]);
        u[3] = fraction(x[1]);
        u[0] = fraction(x[2]);
        u[1] = fraction(x[3]);
        return;
    }
    }
}

void sampler_bsdf(struct sampler *s, int depth, double u[2])
{
    switch (s->kind) {
    case SAMPLER_INDEPENDENT:
        u[0] = rng_uniform(&s->rng);
        u[1] = rng_uniform(&s->rng);
        return;
    case SAMPLER_SOBOL: {
        uint32_t x[4];
        sampler_sobol_block(s->pixel_key, block_light(depth) + 1u, s->index, 2, x);
        u[0] = fraction(x[0]);
        u[1] = fraction(x[1]);
        return;
    }
    }
}

double sampler_roulette(struct sampler *s, int depth)
{
    switch (s->kind) {
    case SAMPLER_INDEPENDENT:
        return rng_uniform(&s->rng);
    case SAMPLER_SOBOL: {
        uint32_t x[4];
        sampler_sobol_block(s->pixel_key, block_light(depth) + 2u, s->index, 1, x);
        return fraction(x[0]);
    }
    }
    return 0.0;
}

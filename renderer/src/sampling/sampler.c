/* sampler.c: the draws of each sampler (see sampler.h). */
#include "sampling/sampler.h"

#include <stdbool.h>

#include "base/fastmath.h"
#include "sampling/sobol.h"

/* Block numbers (sampler.h). */
#define BLOCK_CAMERA 0u
static uint32_t block_light(int depth)
{
    return 1u + 3u * (uint32_t)depth;
}

/* The seeds of block b are the halves of rng_mix64(pixel_key + (4 b + j)
   KEY_STEP), j = 0, 1, 2: the sample order's, then one per dimension. The
   step is odd, so distinct (block, j) give distinct keys, and the hash
   decorrelates neighbours. */
#define KEY_STEP 0xd1342543de82ef95ull

uint64_t sampler_pixel_key(uint64_t seed, uint64_t pixel)
{
    return rng_mix64(seed ^ rng_mix64(pixel * 0x9fb21c651e98df25ull + 0x5851f42d4c957f2dull));
}

void sampler_start(struct sampler *s, enum sampler_kind kind, uint64_t seed, uint64_t pixel, int64_t pass)
{
    s->kind = kind;
    s->index = (uint32_t)pass;
    s->index_reversed = sobol_reverse_bits(s->index);
    switch (kind) {
    case SAMPLER_INDEPENDENT:
        s->rng = rng_seeded(seed, pixel, (uint64_t)pass);
        s->pixel_key = 0;
        return;
    case SAMPLER_SOBOL:
        s->pixel_key = sampler_pixel_key(seed, pixel);
        /* Unused by the draws; distinct per (pixel, pass) for the fault
           hook, which hashes it. */
        s->rng.state = s->pixel_key + (uint64_t)pass * KEY_STEP;
        s->rng.inc = 1;
        return;
    }
}

/* sampler_sobol_block with the sample index bit-reversed. */
static void sobol_block(uint64_t pixel_key, uint32_t block, uint32_t index_reversed, int n, uint32_t out[4])
{
    uint64_t key = pixel_key + (uint64_t)block * 4u * KEY_STEP;
    uint32_t seeds[6];
    for (int j = 0; 2 * j < n + 1; ++j) {
        uint64_t h = rng_mix64(key + (uint64_t)j * KEY_STEP);
        seeds[2 * j] = (uint32_t)h;
        seeds[2 * j + 1] = (uint32_t)(h >> 32);
    }
    /* Owen-scrambling the index (bit-reversed) permutes every aligned run
       of 2^k indices within itself, so the first 2^k passes draw one
       aligned run of the sequence, a net, in an order of the block's own
       (Burley 2020, sec. 4). The run is [c, c + 2^k) with c the high bits
       of the scrambled 0; xor-ing them away maps it onto [0, 2^k): the
       points then differ by a digital shift, which the Owen scrambles
       below absorb (a shift is one of their permutations), and the index
       keeps only k bits, so the matrix products take k steps. */
    uint32_t r = sobol_owen_reversed(index_reversed, seeds[0]) ^ sobol_owen_reversed(0, seeds[0]);
    for (int d = 0; d < n; ++d)
        out[d] = sobol_reverse_bits(sobol_owen_reversed(sobol_point_reversed(r, d), seeds[d + 1]));
}

void sampler_sobol_block(uint64_t pixel_key, uint32_t block, uint32_t index, int n, uint32_t out[4])
{
    sobol_block(pixel_key, block, sobol_reverse_bits(index), n, out);
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
        sobol_block(s->pixel_key, BLOCK_CAMERA, s->index_reversed, 2, x);
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
        sobol_block(s->pixel_key, block_light(depth), s->index_reversed, 4, x);
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
        sobol_block(s->pixel_key, block_light(depth) + 1u, s->index_reversed, 2, x);
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
        sobol_block(s->pixel_key, block_light(depth) + 2u, s->index_reversed, 1, x);
        return fraction(x[0]);
    }
    }
    return 0.0;
}

/* Streams per batch of sampler_light_bsdf_many (stack arrays). */
#define DRAW_CHUNK 64

/* Each of the n streams (state[k], inc[k]) draws `per` uniforms, into
   out[j][k]; the states advance. One loop over the streams per draw, so
   that the chains of multiplies of different streams run side by side. */
FM_SIMD_CLONES static void draw_streams(uint64_t *restrict state, const uint64_t *restrict inc, int n, int per,
                                        double out[6][DRAW_CHUNK])
{
    for (int j = 0; j < per; ++j) {
#pragma omp simd
        for (int k = 0; k < n; ++k) {
            struct rng_draw d = rng_draw(state[k], inc[k]);
            state[k] = d.state;
            out[j][k] = d.u;
        }
    }
}

void sampler_light_bsdf_many(struct sampler *smp, const int *pixel, int n, int depth, double (*u)[4], double (*ub)[2])
{
    int per = ub ? 6 : 4;
    for (int b = 0; b < n; b += DRAW_CHUNK) {
        int m = n - b < DRAW_CHUNK ? n - b : DRAW_CHUNK;
        bool independent = true;
        for (int k = 0; k < m; ++k) independent = independent && smp[pixel[b + k]].kind == SAMPLER_INDEPENDENT;
        if (!independent) {
            for (int k = 0; k < m; ++k) {
                sampler_light(&smp[pixel[b + k]], depth, u[b + k]);
                if (ub) sampler_bsdf(&smp[pixel[b + k]], depth, ub[b + k]);
            }
            continue;
        }
        uint64_t state[DRAW_CHUNK], inc[DRAW_CHUNK];
        for (int k = 0; k < m; ++k) {
            state[k] = smp[pixel[b + k]].rng.state;
            inc[k] = smp[pixel[b + k]].rng.inc;
        }
        double out[6][DRAW_CHUNK];
        draw_streams(state, inc, m, per, out);
        for (int k = 0; k < m; ++k) {
            smp[pixel[b + k]].rng.state = state[k];
            for (int j = 0; j < 4; ++j) u[b + k][j] = out[j][k];
            if (ub) ub[b + k][0] = out[4][k], ub[b + k][1] = out[5][k];
        }
    }
}

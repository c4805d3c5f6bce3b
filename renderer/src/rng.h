/* rng.h: per-sample random streams. Each (seed, pixel, sample index) triple
   seeds its own PCG32 stream through a hash, so an image rendered to a fixed
   sample count is bit-identical whatever the number or schedule of threads. */
#ifndef RNG_H
#define RNG_H

#include <stdint.h>

struct rng {
    uint64_t state;
    uint64_t inc;
};

/* SplitMix64 finaliser: a bijective 64-bit mix used to decorrelate seeds. */
static inline uint64_t rng_mix64(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static inline uint32_t rng_next_u32(struct rng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ull + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31u));
}

/* Stream for one (seed, pixel, sample): state and increment both depend on
   all three, so neighbouring pixels and passes never share a sequence. */
static inline void rng_seed(struct rng *r, uint64_t seed, uint64_t pixel, uint64_t sample)
{
    uint64_t a = rng_mix64(seed ^ rng_mix64(pixel * 0x2545f4914f6cdd1dull + sample));
    uint64_t b = rng_mix64(a ^ 0xda942042e4dd58b5ull ^ sample);
    r->state = 0;
    r->inc = (b << 1u) | 1u;
    rng_next_u32(r);
    r->state += a;
    rng_next_u32(r);
}

/* Uniform double in [0, 1): 53 bits from two draws. */
static inline double rng_uniform(struct rng *r)
{
    uint64_t hi = rng_next_u32(r), lo = rng_next_u32(r);
    return (double)(((hi << 32) | lo) >> 11) * 0x1.0p-53;
}

#endif

/* rng.h: per-sample random streams. Each (seed, pixel, sample index) triple
   seeds its own PCG32 stream through a hash, so an image rendered to a fixed
   sample count is bit-identical whatever the number or schedule of threads.
   No global state: every stream is a value its caller owns. */
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

/* The generator as functions of values (no pointers), so that loops over
   many streams vectorise; the pointer API below is written with them. */
#define RNG_MULT 6364136223846793005ull

/* PCG32's output for the state before a step (XSH RR). */
static inline uint32_t rng_output(uint64_t old)
{
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31u));
}

/* One uniform and the state after it. */
struct rng_draw {
    double u;
    uint64_t state;
};

/* Uniform double in [0, 1): 53 bits from two steps. The 53-bit integer is
   converted as a signed one (same value, and the instruction exists in
   more vector instruction sets than the unsigned conversion). */
static inline struct rng_draw rng_draw(uint64_t state, uint64_t inc)
{
    uint64_t s1 = state * RNG_MULT + inc;
    uint64_t hi = rng_output(state), lo = rng_output(s1);
    struct rng_draw d;
    d.state = s1 * RNG_MULT + inc;
    d.u = (double)(int64_t)(((hi << 32) | lo) >> 11) * 0x1.0p-53;
    return d;
}

/* Stream for one (seed, pixel, sample): state and increment both depend on
   all three, so neighbouring pixels and passes never share a sequence. */
static inline struct rng rng_seeded(uint64_t seed, uint64_t pixel, uint64_t sample)
{
    uint64_t a = rng_mix64(seed ^ rng_mix64(pixel * 0x2545f4914f6cdd1dull + sample));
    uint64_t b = rng_mix64(a ^ 0xda942042e4dd58b5ull ^ sample);
    struct rng r;
    r.inc = (b << 1u) | 1u;
    /* PCG's seeding: a step from state 0 (giving inc), add the seed, step. */
    r.state = (r.inc + a) * RNG_MULT + r.inc;
    return r;
}

static inline uint32_t rng_next_u32(struct rng *r)
{
    uint64_t old = r->state;
    r->state = old * RNG_MULT + r->inc;
    return rng_output(old);
}

static inline void rng_seed(struct rng *r, uint64_t seed, uint64_t pixel, uint64_t sample)
{
    *r = rng_seeded(seed, pixel, sample);
}

/* Uniform double in [0, 1): 53 bits from two draws. */
static inline double rng_uniform(struct rng *r)
{
    struct rng_draw d = rng_draw(r->state, r->inc);
    r->state = d.state;
    return d.u;
}

#endif

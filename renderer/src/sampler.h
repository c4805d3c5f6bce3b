/* sampler.h: the sample generators a render can draw its random numbers
   from. Today there is one, "independent": a PCG32 stream per (seed, pixel,
   sample index) (rng.h). This table is where a future `render.sampler`
   config key would take its names from, as render.strategy takes them from
   strategy_names; `render --describe` lists it.
   It holds names only; the numbers come from rng.h. */
#ifndef SAMPLER_H
#define SAMPLER_H

enum sampler_kind { SAMPLER_INDEPENDENT };
#define SAMPLER_COUNT 1

/* Names as a config would write them, indexed by enum sampler_kind. */
extern const char *const sampler_names[SAMPLER_COUNT];

#endif

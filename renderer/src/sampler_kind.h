/* sampler_kind.h: the names of the samplers a config can choose
   (`render.sampler`, see sampler.h). A header of its own so that config.h
   and the config loader need neither the random streams nor Sobol. */
#ifndef SAMPLER_KIND_H
#define SAMPLER_KIND_H

enum sampler_kind { SAMPLER_INDEPENDENT, SAMPLER_SOBOL };
#define SAMPLER_COUNT 2

/* Names as written in configs, indexed by enum sampler_kind. */
extern const char *const sampler_names[SAMPLER_COUNT];

#endif

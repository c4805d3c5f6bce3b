/* sampler_kind.c: the config names of the samplers (see sampler_kind.h);
   apart from sampler.c so that the config module links without it. */
#include "sampler_kind.h"

const char *const sampler_names[SAMPLER_COUNT] = { [SAMPLER_INDEPENDENT] = "independent", [SAMPLER_SOBOL] = "sobol" };

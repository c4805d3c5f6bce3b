#include "sampler.h"

const char *const sampler_names[SAMPLER_COUNT] = { [SAMPLER_INDEPENDENT] = "independent" };

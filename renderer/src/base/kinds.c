/* kinds.c: the config names of every kind in kinds.h, in one table. */
#include "base/kinds.h"

const char *const integrator_names[2] = { "direct", "path" };
const char *const material_names[2] = { "diffuse", "ggx" };
const char *const sampler_names[SAMPLER_COUNT] = { [SAMPLER_INDEPENDENT] = "independent", [SAMPLER_SOBOL] = "sobol" };
const char *const strategy_names[STRATEGY_COUNT] = { "light_area", "light",      "portal",
                                                     "projection", "antishadow", "antishadow_exact" };
const char *const mis_names[3] = { "none", "balance", "power" };
const char *const portal_weight_names[PORTAL_WEIGHT_COUNT] = { "area", "distance", "irradiance",
                                                               "irradiance_estimate" };

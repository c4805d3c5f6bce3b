/* strategy_kind.c: the config names of the strategy, MIS and portal weight
   kinds (see strategy_kind.h); apart from strategy.c so that the config
   module links without the scene. */
#include "strategy_kind.h"

const char *const strategy_names[STRATEGY_COUNT] = { "light_area", "light",      "portal",
                                                     "projection", "antishadow", "antishadow_exact" };
const char *const mis_names[3] = { "none", "balance", "power" };
const char *const portal_weight_names[PORTAL_WEIGHT_COUNT] = { "area", "distance", "irradiance",
                                                               "irradiance_estimate" };

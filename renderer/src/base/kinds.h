/* kinds.h: the closed sets a config names, one enum each, with the names as
   written in configs. One table for the words the config module, the
   contract (`render --describe`) and the code that dispatches on them all
   share. Apart from the modules that implement the kinds (integrator.h,
   bsdf.h, sampler.h, strategy.h) because those bring the scene, the random
   streams or the BSDF code with them, and the config module links without
   any of that. */
#ifndef KINDS_H
#define KINDS_H

/* The integrators (`render.integrator`). */
enum integrator_kind { INTEGRATOR_DIRECT, INTEGRATOR_PATH };

/* The reflection models a material can have. */
enum material_kind { MATERIAL_DIFFUSE, MATERIAL_GGX };

/* The samplers (`render.sampler`, see sampler.h). */
enum sampler_kind { SAMPLER_INDEPENDENT, SAMPLER_SOBOL };
#define SAMPLER_COUNT 2

/* The light-sampling choices: the strategy, how its samples combine with
   BSDF sampling (MIS) and how a shading point weights its (light, portal)
   pairs. */
enum strategy_kind {
    STRATEGY_LIGHT_AREA,
    STRATEGY_LIGHT,
    STRATEGY_PORTAL,
    STRATEGY_PROJECTION,
    STRATEGY_ANTISHADOW,
    STRATEGY_ANTISHADOW_EXACT
};
#define STRATEGY_COUNT 6

/* MIS_NONE: light sampling only (no BSDF-sampled direct light). */
enum mis_kind { MIS_NONE, MIS_BALANCE, MIS_POWER };

/* How a shading point distributes light samples over (light, portal) pairs. */
enum portal_weight_kind {
    PORTAL_WEIGHT_AREA,
    PORTAL_WEIGHT_DISTANCE,
    PORTAL_WEIGHT_IRRADIANCE,
    PORTAL_WEIGHT_IRRADIANCE_ESTIMATE
};
#define PORTAL_WEIGHT_COUNT 4

/* Names as written in configs, indexed by the enums above. */
extern const char *const integrator_names[2];
extern const char *const material_names[2];
extern const char *const sampler_names[SAMPLER_COUNT];
extern const char *const strategy_names[STRATEGY_COUNT];
extern const char *const mis_names[3];
extern const char *const portal_weight_names[PORTAL_WEIGHT_COUNT];

#endif

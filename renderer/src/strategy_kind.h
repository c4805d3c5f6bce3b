/* strategy_kind.h: the names of the light-sampling choices a config makes:
   the strategy, how its samples combine with BSDF sampling (MIS) and how a
   shading point weights its (light, portal) pairs. A header of its own, not
   strategy.h, because config.h needs these words and strategy.h brings the
   scene (and the Embree-backed queries) with it. */
#ifndef STRATEGY_KIND_H
#define STRATEGY_KIND_H

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
extern const char *const strategy_names[STRATEGY_COUNT];
extern const char *const mis_names[3];
extern const char *const portal_weight_names[PORTAL_WEIGHT_COUNT];

#endif

/* strategy_internal.h: what the strategy's files share and nobody else
   sees: the small rules inlined on every path, the visible-part cache's
   states, and the functions one file makes for another (strategy.c builds
   and samples, strategy_weights.c weighs and culls, strategy_batch.c
   samples many points at once). */
#ifndef STRATEGY_INTERNAL_H
#define STRATEGY_INTERNAL_H

#include "sampling/strategy.h"

/* The states of a pair's visible part in a point's scratch (vis_state). */
enum { VIS_UNKNOWN, VIS_EMPTY, VIS_POLYGON, VIS_READY };

/* The antishadow strategies classify; `portal` and `projection` are the
   plain techniques of the paper and must not benefit from classification. */
static inline bool strategy_kind_classifies(enum strategy_kind k)
{
    return k == STRATEGY_ANTISHADOW || k == STRATEGY_ANTISHADOW_EXACT;
}

/* Whether a sample of the pair first picks one of its emitter's lights by
   power: for a mesh light's pairs, but with the plain `portal` strategy,
   which samples the portal and goes on to whichever triangle it meets
   (scene_emitter_hit), as it goes on to the light behind for a polygon. */
static inline bool strategy_picks_member(const struct strategy *s, const struct strategy_pair *pair)
{
    return s->scene->emitters[pair->emitter].n_lights > 1 && s->kind != STRATEGY_PORTAL;
}

/* The member of pair `pair` for light `light` of its emitter: that light with
   the same portal (by position in its range). */
static inline struct strategy_pair strategy_member_of(const struct scene *sc, const struct strategy_pair *pair,
                                                      int light)
{
    struct strategy_pair m = { light, pair->portal, pair->emitter };
    if (pair->portal >= 0)
        m.portal = sc->lights[light].first_portal + (pair->portal - sc->lights[pair->light].first_portal);
    return m;
}

/* Whether a light-only strategy (light, light_area) draws nothing at pt
   when it picks `light` (light_culled): no sample, and a density of zero
   in every direction towards it. The portal strategies' defensive light
   sampling is left as it was (their densities are mixtures). */
static inline bool strategy_light_only_culls(const struct strategy *s, int light, const struct strategy_point *pt)
{
    return !strategy_kind_uses_portals(s->kind) && light_culled(&s->scene->lights[light], pt->p, pt->n);
}

/* strategy_finish_sample for a light-only strategy (light, light_area): the light
   sampled was picked by power with probability power.prob[light] and the
   direction wi, at distance dist, with density pdf_sa on it. */
static inline void strategy_finish_light_only(const struct strategy *s, int light, struct vec3 wi, double dist,
                                              double pdf_sa, struct light_sample *out)
{
    out->wi = wi;
    out->light = light;
    out->dist = dist;
    out->radiance = light_emitted(&s->scene->lights[light], vec3_neg(wi));
    out->pdf_sa = s->power.prob[light] * pdf_sa;
}

/* The visible part of pair i's light through its portal from the prepared
   point as a finished target, cached per point; NULL when nothing is
   visible (strategy_weights.c). */
const struct target *strategy_visible_target(const struct strategy *s, const struct strategy_point *pt, int i);

/* The visible part of a mesh light's member pair from the prepared point,
   into `storage`, not cached; NULL when nothing is visible
   (strategy_weights.c). */
const struct target *strategy_member_visible(const struct strategy *s, const struct strategy_point *pt,
                                             const struct strategy_pair *member, enum region region,
                                             struct target *storage);

/* The light sample from a technique's target point and its density under
   the whole strategy (strategy.c says more). */
void strategy_finish_sample(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                            int index, const struct target_point *tp, double pick, double known_sel,
                            struct light_sample *out);

#endif

/* integrator_stats.h: the ray and sample counters a render thread keeps
   while it shades, summed across threads and carried in a resumable state.
   Plain counters: no dependency on the scene, the shading code or the
   film, so that the state and the render loop can hold them without
   seeing how they are counted (shading.h and integrator.h count them). */
#ifndef INTEGRATOR_STATS_H
#define INTEGRATOR_STATS_H

#include <stdint.h>

struct integrator_stats {
    uint64_t rays;           /* all rays traced */
    uint64_t shadow_rays;    /* occlusion rays towards a sampled light point */
    uint64_t shadow_blocked; /* ...of which were occluded */
    uint64_t light_samples;  /* next-event samples that produced a direction */
    uint64_t light_missed;   /* ...whose direction missed the light (no ray traced) */
};

/* a += b, counter by counter. */
static inline void integrator_stats_add(struct integrator_stats *a, const struct integrator_stats *b)
{
    a->rays += b->rays;
    a->shadow_rays += b->shadow_rays;
    a->shadow_blocked += b->shadow_blocked;
    a->light_samples += b->light_samples;
    a->light_missed += b->light_missed;
}

#endif

/* direct_estimate.h: a point estimate of direct lighting for tests that
   compare the integrator with closed forms or with another strategy at
   chosen surface points (test_closed_form.c, test_portal_finder.c). */
#ifndef DIRECT_ESTIMATE_H
#define DIRECT_ESTIMATE_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "base/rng.h"
#include "sampling/integrator.h"
#include "sampling/sampler.h"
#include "sampling/strategy.h"
#include "scene/scene.h"

struct estimate {
    double mean, se;
};

/* Mean and standard error of the red channel of n direct-lighting samples
   at surface point p with normal ng, seen along the normal. NaNs when the
   strategy cannot be set up (the message goes to stderr). */
static inline struct estimate estimate_at(const struct scene *sc, const struct render_desc *rd, struct vec3 p,
                                          struct vec3 ng, int material, int n, uint64_t seed)
{
    struct strategy s;
    struct strategy_scratch scratch;
    struct error err;
    struct estimate e = { NAN, NAN };
    if (!strategy_init(&s, sc, rd, &err) || !strategy_scratch_init(&s, &scratch, &err)) {
        fprintf(stderr, "  %s\n", err.message);
        return e;
    }
    struct integrator it;
    integrator_init(&it, rd, sc, &s);
    struct integrator_stats stats;
    memset(&stats, 0, sizeof stats);
    double mean = 0.0, m2 = 0.0;
    for (int i = 0; i < n; ++i) {
        struct sampler r = sampler_of_rng(rng_seeded(seed, 0, (uint64_t)i));
        struct rgb c = integrator_direct_at(&it, &scratch, p, ng, material, ng, &r, &stats);
        double d = c.r - mean;
        mean += d / (i + 1);
        m2 += d * (c.r - mean);
    }
    e.mean = mean;
    e.se = sqrt(m2 / (n - 1) / n);
    strategy_scratch_free(&scratch);
    strategy_free(&s);
    return e;
}

#endif

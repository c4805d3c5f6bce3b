#include "render/aov.h"

#include <stdlib.h>

#include "config/config.h"

const char *const aov_region_names[AOV_REGION_COUNT] = {
    "outside", "anti_umbra", "anti_penumbra", "anti_antumbra", "inside", "emitter", "miss",
};

bool aov_classifier_init(struct aov_classifier *c, const struct scene *sc, struct error *err)
{
    /* Only these three fields are read by strategy_init. The irradiance
       heuristic is what the AOV ranks by, and the antishadow strategy's
       pairs and BVH are what it needs, whatever the render samples with. */
    struct render_desc rd = { 0 };
    rd.strategy = STRATEGY_ANTISHADOW;
    rd.portal_weight = PORTAL_WEIGHT_IRRADIANCE;
    rd.defensive = 0.0;
    return strategy_init(&c->pairs, sc, &rd, err);
}

void aov_classifier_free(struct aov_classifier *c)
{
    strategy_free(&c->pairs);
}

bool aov_scratch_init(const struct aov_classifier *c, struct aov_scratch *scratch, struct error *err)
{
    int n = c->pairs.n_pairs > 0 ? c->pairs.n_pairs : 1;
    scratch->cand = malloc(sizeof *scratch->cand * (size_t)n);
    if (!scratch->cand) return error_set(err, "out of memory for %d light/portal pairs", n);
    return true;
}

void aov_scratch_free(struct aov_scratch *scratch)
{
    free(scratch->cand);
    scratch->cand = NULL;
}

enum aov_region aov_classify_point(const struct aov_classifier *c, struct aov_scratch *scratch, struct vec3 p,
                                   struct vec3 n)
{
    const struct strategy *s = &c->pairs;
    /* Pairs outside the BVH's candidates light nothing at p (their boxes
       bound everything they light), so they cannot win. */
    int n_cand = s->n_pairs > 0 ? strategy_candidates(s, strategy_sided_point(s, p, n), scratch->cand) : 0;
    double best = 0.0;
    int best_pair = -1;
    enum aov_region cls = AOV_REGION_OUTSIDE;
    for (int k = 0; k < n_cand; ++k) {
        int i = scratch->cand[k];
        enum region region;
        double e = strategy_pair_irradiance(s, i, p, n, &region);
        if (!(e > 0.0) || !isfinite(e)) continue;
        /* The BVH lists candidates in its own order: among equal pairs the
           first in scene order wins, so the class is a function of p. */
        if (e > best || (e == best && i < best_pair)) {
            best = e;
            best_pair = i;
            cls = (enum aov_region)region; /* the same values */
        }
    }
    return cls;
}

enum aov_region aov_classify_hit(const struct aov_classifier *c, struct aov_scratch *scratch, struct vec3 d,
                                 const struct hit *h)
{
    if (!h) return AOV_REGION_MISS;
    if (h->light >= 0) return AOV_REGION_EMITTER;
    /* The side the camera sees, as vertex_orient picks it for shading. */
    struct vec3 n = vec3_dot(h->ng, d) < 0.0 ? h->ng : vec3_neg(h->ng);
    return aov_classify_point(c, scratch, h->p, n);
}

void aov_classify_row(const struct aov_classifier *c, struct aov_scratch *scratch, const struct vec3 *d,
                      const struct hit *hits, const bool *found, int n, unsigned char *cls)
{
    for (int x = 0; x < n; ++x) cls[x] = (unsigned char)aov_classify_hit(c, scratch, d[x], found[x] ? &hits[x] : NULL);
}

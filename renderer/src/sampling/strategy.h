/* strategy.h: light-sampling strategies for next-event estimation: which
   light (and which of its portals) a shading point samples, with which
   technique, and the solid-angle pdf of any direction under the same rules,
   so that every strategy combines with BSDF sampling by MIS.

   A strategy is a mixture over "pairs" (a light with one of its portals, or
   a light alone). The `light` and `light_area` strategies pick lights by
   power from a global table; the portal strategies weight pairs per shading
   point (strategy_prepare) and then sample the pair's technique, which for
   the antishadow strategies depends on the point's region.
   It traces no rays: the integrator traces the shadow ray a strategy
   samples. */
#ifndef STRATEGY_H
#define STRATEGY_H

#include <stdbool.h>

#include "sampling/alias.h"
#include "base/error.h"
#include "geometry/pair_bvh.h"
#include "scene/scene.h"
#include "base/kinds.h"
#include "base/vec.h"

struct render_desc; /* config.h */

enum technique {
    TECHNIQUE_NONE,         /* no direction can reach the light through this pair */
    TECHNIQUE_LIGHT_AREA,   /* uniform area on the light */
    TECHNIQUE_LIGHT_SOLID,  /* uniform solid angle of the light */
    TECHNIQUE_PORTAL_AREA,  /* uniform area on the portal, continue to the light */
    TECHNIQUE_PORTAL_SOLID, /* uniform solid angle of the portal */
    TECHNIQUE_VISIBLE_AREA, /* uniform area on the light's projection clipped to the portal */
    TECHNIQUE_VISIBLE_SOLID /* uniform solid angle of that clipped projection */
};

/* A pair of an emitter (scene.h) and one of its portals. For a polygon
   light, `light` is its light; for a mesh light, `light` and `portal` name
   the first triangle's light and portal copy, and a sample first picks a
   triangle by power (its "member" pair: the same portal of that triangle). */
struct strategy_pair {
    int light;
    int portal; /* -1: the light alone */
    int emitter;
};

/* A portal's outline as arrays, for a vectorised loop over its edges:
   vertices 0..n-1, then vertex 0 repeated up to index n_edges (a whole
   number of SIMD blocks), so that edge k runs from k to k + 1 for every
   k < n_edges, the closing edge included, and the padding edges are of
   zero length. */
struct portal_outline {
    int n_edges;
    double *x, *y, *z; /* n_edges + 1 each */
};

struct strategy {
    enum strategy_kind kind;
    enum portal_weight_kind weight;
    double defensive; /* probability of plain `light` sampling */
    const struct scene *scene;
    struct alias_table power; /* lights by power */
    int n_pairs;
    struct strategy_pair *pairs;
    int *first_pair;                /* per emitter: index of its first pair */
    struct alias_table *members;    /* per emitter: its lights by power (n = 0 for a polygon light) */
    struct vec3 *centre;            /* per emitter: area-weighted centroid (the distance heuristic) */
    double *reach;                  /* per emitter: radius of the sphere about centre that holds it */
    bool use_bvh;                   /* antishadow strategies: candidates from the BVH */
    struct aabb *shade;             /* per emitter: where a point counts as inside its shade */
    struct plane *portal_plane;     /* per pair with a portal: that portal's plane (on_light_side) */
    struct pair_bvh bvh;            /* over the pairs' lit regions */
    struct portal_outline *outline; /* per pair: its portal's, for a mesh light's portal pairs (else empty) */
};

bool strategy_init(struct strategy *s, const struct scene *scene, const struct render_desc *rd, struct error *err);
void strategy_free(struct strategy *s);

/* Per-thread scratch that strategy_prepare fills (one slot per pair). The
   visible part of each pair's light is computed at most once per shading
   point, when a weight, a sample or a pdf first needs it. */
struct strategy_scratch {
    int n_cand;               /* pairs that may light the point */
    int *cand;                /* their indices */
    int *cand_pos;            /* per pair: position in cand, or -1 */
    double *cdf;              /* cumulative weights of the candidates */
    unsigned char *region;    /* enum region per pair (candidates only) */
    unsigned char *vis_state; /* VIS_UNKNOWN, VIS_EMPTY, VIS_POLYGON or VIS_READY */
    struct target *vis;       /* the clipped projection: its polygon from VIS_POLYGON, all of it when VIS_READY */
    /* strategy_prepare_pairs' weights left to finish together: the polygon,
       the candidate's position, the projected solid angle. */
    const struct polygon **defer_poly;
    int *defer_cand;
    double *defer_value;
};
bool strategy_scratch_init(const struct strategy *s, struct strategy_scratch *scratch, struct error *err);
void strategy_scratch_free(struct strategy_scratch *scratch);

/* A shading point with its pair distribution, prepared once and used for
   both sampling and pdf evaluation there. */
struct strategy_point {
    struct vec3 p;     /* world position (offset origin for rays) */
    struct vec3 n;     /* unit normal of the receiving side, or zero */
    struct vec3 sided; /* where its regions are decided (portal strategies: strategy_sided_point) */
    double total;      /* sum of pair weights (portal strategies) */
    struct strategy_scratch *scratch;
};

/* Whether a strategy of kind k samples through portals (and so keeps
   per-point state in the scratch). */
static inline bool strategy_kind_uses_portals(enum strategy_kind k)
{
    switch (k) {
    case STRATEGY_LIGHT_AREA:
    case STRATEGY_LIGHT:
        return false;
    case STRATEGY_PORTAL:
    case STRATEGY_PROJECTION:
    case STRATEGY_ANTISHADOW:
    case STRATEGY_ANTISHADOW_EXACT:
        return true;
    }
    return false;
}

/* True when strategy_prepare keeps nothing in the scratch (the light-only
   strategies), so that many points can be prepared first and sampled
   together with strategy_sample_many. */
static inline bool strategy_batches(const struct strategy *s)
{
    return !strategy_kind_uses_portals(s->kind);
}

/* The point at which the portal strategies decide the regions of a
   shading point p with normal n (unit on the side the path arrives from,
   or zero): p lifted off its surface along n by the height a ray leaving p
   clears (scene_offset_height). A surface in a portal's plane, as a shade's
   bottom plate around its opening, is hit up to ~1e-7 above or below that
   plane (Embree's distances are floats): decided at p, the plate's inner
   face was outside the shade half the time, its lamp never sampled there,
   and every BSDF ray from it that reached the lamp counted with MIS weight
   1, a firefly of the lamp's whole radiance under path tracing. A zero
   normal keeps p. Directions and densities are still those from p. */
struct vec3 strategy_sided_point(const struct strategy *s, struct vec3 p, struct vec3 n);

/* True when no light of the scene can deliver anything to point p, whose
   receiving side has unit normal n (zero: every side), whatever the
   direction: every polygon light is culled there (light_culled: behind a
   one-sided light, or below p's horizon) and every mesh light's bounding
   sphere lies clearly below the horizon. Then neither a light sample nor
   a BSDF ray of direct lighting can reach an emitting face from p, and
   the direct integrator skips the point: its value is exactly zero. On
   the lampshade that is a large share of the camera's points (the
   ceiling, the upper walls). Scenes with more than
   STRATEGY_UNLIT_MAX_EMITTERS emitters are not tested (false), a bound on
   what the test may cost a lit point (docs/performance.md has both
   measurements).
   Independent of the strategy's kind. *hint is the emitter to
   test first; a lit point leaves there the emitter that lights it, so
   that a film row's next point, most often on the same surface, is
   decided by one test (out-of-range values are taken as 0). */
#define STRATEGY_UNLIT_MAX_EMITTERS 16
bool strategy_point_unlit(const struct strategy *s, struct vec3 p, struct vec3 n, int *hint);

/* The portal strategies' part of strategy_prepare: pt->sided, and the
   candidate pairs found there with their weights at pt->p, into
   pt->scratch. p and n are pt->p and pt->n, passed in registers: read
   back from pt right after strategy_prepare stored them, they can straddle
   two of its stores, which the processor cannot forward (a stall that
   showed in antishadow_exact's profile). */
void strategy_prepare_pairs(const struct strategy *s, struct strategy_point *pt, struct vec3 p, struct vec3 n);

/* The pairs that may light p, into out (room for s->n_pairs): those the
   pair BVH finds for the antishadow strategies, all pairs otherwise.
   Returns how many. */
int strategy_candidates(const struct strategy *s, struct vec3 p, int *out);

/* The `irradiance` heuristic's weight of pair i at p (receiving normal n,
   unit, or zero for a point that receives from every side), with the
   antishadow strategies' classification and without their lone-pair
   shortcut: the luminance of the light's radiance times the projected solid
   angle (unoccluded irradiance per unit radiance) of what p sees of the
   light through the pair's portal; of the whole light for a light without
   portals, and for the first pair of a light whose shade contains p. Zero
   when the pair cannot light p. *region gets the pair's region, REGION_INSIDE
   inside the light's shade (REGION_ANTI_UMBRA for a light without
   portals, which p sees whole). Needs a strategy whose pairs include the
   portals (strategy_kind_uses_portals); s->weight is not read. */
double strategy_pair_irradiance(const struct strategy *s, int i, struct vec3 p, struct vec3 n, enum region *region);

/* Inline: a film row prepares every shading point, and for the light-only
   strategies this is all there is to it. */
static inline void strategy_prepare(const struct strategy *s, struct strategy_scratch *scratch, struct vec3 p,
                                    struct vec3 n, struct strategy_point *pt)
{
    pt->p = p;
    pt->n = n;
    pt->scratch = scratch;
    pt->total = 0.0;
    if (!strategy_batches(s)) strategy_prepare_pairs(s, pt, p, n);
}

struct light_sample {
    struct vec3 wi;      /* unit */
    double pdf_sa;       /* density of wi under the whole strategy */
    int light;           /* light reached along wi, -1 when wi misses every target light */
    double dist;         /* distance to the point on that light */
    struct rgb radiance; /* emitted towards p (black from the back) */
};

/* Samples with four uniforms. False when the strategy produced nothing
   (no pair has weight). A sample with light == -1 is a direction that does
   not reach the light (portal sampling): it contributes zero. */
bool strategy_sample(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                     struct light_sample *out);

/* strategy_sample at n points: ok[i] and out[i] are what strategy_sample
   would give for pts[i] and u[i], bit for bit. The `light` strategy
   samples its rectangles in vectorised batches; the others call
   strategy_sample point by point. Only for strategy_batches strategies (the
   points' scratch is not read). */
void strategy_sample_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4], int n,
                          struct light_sample *out, bool *ok);
/* A portal strategy's sample left waiting by strategy_sample_begin. */
struct strategy_pending {
    bool waiting;
    int index;                   /* the pair */
    const struct target *target; /* a light's or a portal's own (outlives the scratch), or `visible` */
    double sel;                  /* the pair's probability at the point */
    struct target visible;       /* a copy of the point's visible rectangle, which the scratch does not keep */
};

/* strategy_sample in two steps, so that a row's portal-strategy samples of
   rectangles (the light's, the portal's or a visible part that is one,
   copied into pend; of an emitter with one pair), which do not live in the
   scratch) are drawn together in vectorised batches. begin is called right
   after strategy_prepare: it returns what strategy_sample would, or leaves
   the sample waiting (pend->waiting, return false); then
   strategy_sample_finish_many, once for the n points, sets ok[i] and out[i]
   of the waiting ones to what strategy_sample would have given, bit for
   bit. The points' scratch is not read by the finish. */
bool strategy_sample_begin(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                           struct light_sample *out, struct strategy_pending *pend);
void strategy_sample_finish_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4],
                                 const struct strategy_pending *pend, int n, struct light_sample *out, bool *ok);
/* Density with which strategy_sample generates wi, given that wi reaches
   light `light` (the first light along wi). */
double strategy_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi);

/* The technique a pair uses at a point in `region`. Inside the light's
   shade (REGION_INSIDE) the antishadow strategies sample the light itself;
   the first pair of the light carries it. */
enum technique strategy_technique(const struct strategy *s, const struct strategy_pair *pair, enum region region);

#endif

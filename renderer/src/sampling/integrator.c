#include "sampling/integrator.h"

#include <stdlib.h>

#include "scene/bsdf.h"
#include "base/fastmath.h"
#include "config/config.h"

void integrator_init(struct integrator *it, const struct render_desc *rd, const struct scene *scene,
                     const struct strategy *strategy)
{
    it->kind = rd->integrator;
    it->mis = rd->mis;
    it->max_depth = rd->integrator == INTEGRATOR_DIRECT ? 1 : rd->max_depth;
    it->rr_depth = rd->rr_depth;
    it->scene = scene;
    it->strategy = strategy;
}

/* The shadow and BSDF rays are set up (shading.c), traced and resolved in
   three steps so that a film row can do each step for all its pixels in
   turn (see direct_row). */
static bool shadow_trace(const struct integrator *it, const struct shadow_query *q)
{
    return q->trace && scene_occluded(it->scene, q->ray.o, q->ray.d, q->ray.tmax);
}

static struct rgb shadow_resolve(const struct shadow_query *q, bool occluded, struct integrator_stats *stats)
{
    if (!occluded) return q->value;
    ++stats->shadow_blocked;
    return rgb_make(0.0, 0.0, 0.0);
}

/* Next-event estimation's contribution at vertex v from a drawn light
   sample: one shadow ray, weighted against BSDF sampling. */
static struct rgb direct_from_sample(const struct integrator *it, const struct vertex *v, bool ok,
                                     const struct light_sample *ls, struct integrator_stats *stats)
{
    struct shadow_query q;
    shadow_setup(it->scene, it->mis, v, ok, ls, stats, &q);
    return shadow_resolve(&q, shadow_trace(it, &q), stats);
}

/* Next-event estimation at a surface point of bounce `depth`: one
   strategy sample. */
static struct rgb sample_direct(const struct integrator *it, const struct strategy_point *sp, const struct vertex *v,
                                int depth, struct sampler *smp, struct integrator_stats *stats)
{
    double u[4];
    sampler_light(smp, depth, u);
    struct light_sample ls;
    bool ok = strategy_sample(it->strategy, sp, u, &ls);
    return direct_from_sample(it, v, ok, &ls, stats);
}

/* Emission found by a BSDF-sampled ray, weighted against the strategy.
   With `reprepare` set, sp's scratch has since served other points (a row
   prepares each point in turn): sp is prepared again in it, from the same
   point and normal, so that the pdf is the one it would have been. */
static struct rgb bsdf_hit_light(const struct integrator *it, struct strategy_point *sp,
                                 struct strategy_scratch *reprepare, int light, struct vec3 d, double bsdf_pdf_value)
{
    struct rgb le = light_emitted(&it->scene->lights[light], vec3_neg(d));
    if (it->mis == MIS_NONE || rgb_is_black(le)) return rgb_make(0.0, 0.0, 0.0);
    if (reprepare) strategy_prepare(it->strategy, reprepare, sp->p, sp->n, sp);
    double pdf_light = strategy_pdf(it->strategy, sp, light, d);
    return rgb_scale(le, mis_weight(it->mis, bsdf_pdf_value, pdf_light));
}

static int bsdf_trace(const struct integrator *it, const struct bsdf_query *q)
{
    return q->trace ? scene_first_light(it->scene, q->ray.o, q->ray.d, q->ray.tmax) : -1;
}

static struct rgb bsdf_resolve(const struct integrator *it, struct strategy_point *sp,
                               struct strategy_scratch *reprepare, const struct bsdf_query *q, int light)
{
    if (light < 0) return rgb_make(0.0, 0.0, 0.0);
    return rgb_mul(q->weight, bsdf_hit_light(it, sp, reprepare, light, q->ray.d, q->pdf));
}

static struct rgb bsdf_mis(const struct integrator *it, struct strategy_point *sp, const struct vertex *v,
                           struct sampler *smp, struct integrator_stats *stats)
{
    double u[2];
    sampler_bsdf(smp, 0, u);
    struct bsdf_query q;
    bsdf_setup(it->scene, v, u, &q);
    if (q.trace) ++stats->rays;
    return bsdf_resolve(it, sp, NULL, &q, bsdf_trace(it, &q));
}

/* What a path's ray that reached light `light` along d adds, before its
   throughput: the emission itself for the camera ray (depth 0), else the
   emission weighted against the strategy (bsdf_hit_light). */
static struct rgb light_reached(const struct integrator *it, struct strategy_point *sp,
                                struct strategy_scratch *reprepare, int depth, int light, struct vec3 d,
                                double bsdf_pdf_prev)
{
    if (depth == 0) return light_emitted(&it->scene->lights[light], vec3_neg(d));
    return bsdf_hit_light(it, sp, reprepare, light, d, bsdf_pdf_prev);
}

/* Russian roulette after the BSDF sample of bounce `depth`: false when the
   path ends, else beta is rescaled for the survivors. */
static bool roulette_survives(const struct integrator *it, struct rgb *beta, struct sampler *smp, int depth)
{
    if (depth + 1 < it->rr_depth) return true;
    double q = fm_fmax(0.05, 1.0 - rgb_max(*beta));
    if (sampler_roulette(smp, depth) < q) return false;
    *beta = rgb_scale(*beta, 1.0 / (1.0 - q));
    return true;
}

struct rgb integrator_direct_at(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 p,
                                struct vec3 ng, int material, struct vec3 wo, struct sampler *smp,
                                struct integrator_stats *stats)
{
    struct rgb L = rgb_make(0.0, 0.0, 0.0);
    struct vertex v;
    if (!vertex_init(it->scene, p, ng, material, wo, &v)) return L;
    int hint = 0;
    if (strategy_point_unlit(it->strategy, p, v.n, &hint)) return L;
    struct strategy_point sp;
    strategy_prepare(it->strategy, scratch, p, v.n, &sp);
    L = sample_direct(it, &sp, &v, 0, smp, stats);
    if (it->mis == MIS_NONE) return L;
    return rgb_add(L, bsdf_mis(it, &sp, &v, smp, stats));
}

struct rgb integrator_radiance_from(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 o,
                                    struct vec3 d, const struct hit *first, struct sampler *smp,
                                    struct integrator_stats *stats)
{
    const struct scene *sc = it->scene;
    struct rgb L = rgb_make(0.0, 0.0, 0.0), beta = rgb_make(1.0, 1.0, 1.0);
    struct strategy_point sp;
    double bsdf_pdf_prev = 0.0;
    struct vec3 ray_o = o, ray_d = d;

    for (int depth = 0;; ++depth) {
        struct hit h;
        ++stats->rays;
        if (depth == 0) {
            if (!first) break;
            h = *first;
        } else if (!scene_intersect(sc, ray_o, ray_d, INFINITY, &h)) {
            break;
        }
        if (h.light >= 0) {
            /* Lights emit and reflect nothing. Seen directly: full weight;
               reached by BSDF sampling: weighted against the strategy. */
            L = rgb_add(L, rgb_mul(beta, light_reached(it, &sp, NULL, depth, h.light, ray_d, bsdf_pdf_prev)));
            break;
        }
        if (depth >= it->max_depth) break;
        if (it->kind == INTEGRATOR_DIRECT) {
            L = rgb_add(L, integrator_direct_at(it, scratch, h.p, h.ng, h.material, vec3_neg(ray_d), smp, stats));
            break;
        }

        struct vertex v;
        if (!vertex_init(sc, h.p, h.ng, h.material, vec3_neg(ray_d), &v)) break;
        strategy_prepare(it->strategy, scratch, h.p, v.n, &sp);
        L = rgb_add(L, rgb_mul(beta, sample_direct(it, &sp, &v, depth, smp, stats)));

        /* Continue by BSDF sampling (the ray direct lighting's MIS would
           trace); the same direction gathers direct light at the next
           vertex, weighted by MIS (or not at all without MIS). */
        struct bsdf_query bq;
        double ub[2];
        sampler_bsdf(smp, depth, ub);
        bsdf_setup(sc, &v, ub, &bq);
        if (!bq.trace) break;
        beta = rgb_mul(beta, bq.weight);
        bsdf_pdf_prev = bq.pdf;
        ray_d = bq.ray.d;
        ray_o = bq.ray.o;
        if (!roulette_survives(it, &beta, smp, depth)) break;
    }
    return L;
}

/* One path of a film row in flight (path_row): what integrator_radiance_from
   keeps from one bounce to the next. */
struct path_lane {
    int pixel;
    struct rgb beta;      /* throughput up to the ray's next hit */
    double bsdf_pdf_prev; /* the density with which d was sampled */
    struct vec3 d;        /* the ray's direction (its origin: integrator_row's ray_o) */
    /* The vertex d left from (p and n of its strategy_point), prepared
       again where d reaches a light, for MIS: kept whole, the point was
       most of what path_row copied as paths moved. */
    struct vec3 prev_p, prev_n;
};

/* One film row of shading points in flight (direct_row, path_row). */
struct integrator_row {
    struct vertex *v;
    struct strategy_point *sp;
    double (*u)[4];  /* light sample uniforms */
    double (*ub)[2]; /* BSDF sample uniforms */
    struct light_sample *ls;
    struct strategy_pending *pend;
    bool *ok;
    struct shadow_query *shadow;
    struct bsdf_query *bsdf;
    struct ray_stream shadow_rays, bsdf_rays, packed_rays;
    int *group, *order; /* scene_occluded_grouped's keys and scratch */
    int *light;
    int *pixel;
    struct path_lane *paths;
    struct vec3 *ray_o, *ray_d; /* path_row's bounce rays, in double (ray k: path k's), */
    struct hit *hit;            /* and what path k's ray met */
    bool *found;
};

struct integrator_row *integrator_row_create(int n, struct error *err)
{
    struct integrator_row *row = calloc(1, sizeof *row);
    if (!row) {
        error_set(err, "out of memory for a row of %d shading points", n);
        return NULL;
    }
    size_t m = n > 0 ? (size_t)n : 1;
    row->v = malloc(m * sizeof *row->v);
    row->sp = malloc(m * sizeof *row->sp);
    row->u = malloc(m * sizeof *row->u);
    row->ub = malloc(m * sizeof *row->ub);
    row->ls = malloc(m * sizeof *row->ls);
    row->pend = malloc(m * sizeof *row->pend);
    row->ok = malloc(m * sizeof *row->ok);
    row->shadow = malloc(m * sizeof *row->shadow);
    row->bsdf = malloc(m * sizeof *row->bsdf);
    row->light = malloc(m * sizeof *row->light);
    row->pixel = malloc(m * sizeof *row->pixel);
    row->paths = malloc(m * sizeof *row->paths);
    row->ray_o = malloc(m * sizeof *row->ray_o);
    row->ray_d = malloc(m * sizeof *row->ray_d);
    row->hit = malloc(m * sizeof *row->hit);
    row->found = malloc(m * sizeof *row->found);
    row->group = malloc(m * sizeof *row->group);
    row->order = malloc(m * sizeof *row->order);
    if (row->v && row->sp && row->u && row->ub && row->ls && row->pend && row->ok && row->shadow && row->bsdf &&
        row->light && row->pixel && row->paths && row->ray_o && row->ray_d && row->hit && row->found && row->group &&
        row->order && ray_stream_init(&row->shadow_rays, (int)m, err) &&
        ray_stream_init(&row->bsdf_rays, (int)m, err) && ray_stream_init(&row->packed_rays, (int)m, err))
        return row;
    integrator_row_destroy(row);
    error_set(err, "out of memory for a row of %d shading points", n);
    return NULL;
}

void integrator_row_destroy(struct integrator_row *row)
{
    if (!row) return;
    free(row->v);
    free(row->sp);
    free(row->u);
    free(row->ub);
    free(row->ls);
    free(row->pend);
    free(row->ok);
    free(row->shadow);
    free(row->bsdf);
    ray_stream_free(&row->shadow_rays);
    ray_stream_free(&row->bsdf_rays);
    ray_stream_free(&row->packed_rays);
    free(row->group);
    free(row->order);
    free(row->light);
    free(row->pixel);
    free(row->paths);
    free(row->ray_o);
    free(row->ray_d);
    free(row->hit);
    free(row->found);
    free(row);
}

/* The row's shadow rays, one Embree call. Those of camera vertices (a
   film row's neighbouring points) converge on the lights they sample:
   grouped by emitter, they are traced as a coherent stream (Embree's
   packets); those of later bounces start from scattered points and go as
   they are. */
static void trace_shadows(const struct scene *sc, struct integrator_row *row, int lanes, bool converge)
{
    if (!converge) {
        scene_occluded_stream(sc, &row->shadow_rays, lanes, false);
        return;
    }
    for (int k = 0; k < lanes; ++k)
        row->group[k] = row->ok[k] && row->ls[k].light >= 0 ? sc->lights[row->ls[k].light].emitter : 0;
    scene_occluded_grouped(sc, &row->shadow_rays, lanes, row->group, &row->packed_rays, row->order);
}

/* The portal strategies keep a point's pair distribution in the one
   scratch: each point is prepared and its sample begun before the next
   point is prepared (its uniforms are drawn already). */
static void begin_samples(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                          int lanes)
{
    for (int k = 0; k < lanes; ++k) {
        strategy_prepare(it->strategy, scratch, row->v[k].p, row->v[k].n, &row->sp[k]);
        row->ok[k] = strategy_sample_begin(it->strategy, &row->sp[k], row->u[k], &row->ls[k], &row->pend[k]);
    }
}

/* Direct lighting a row at a time, one step for every shading point before
   the next: shading points and their uniforms; all light samples at once
   (vectorised); shadow and BSDF ray set-up, into ray streams; the streams,
   one Embree call each; the sums. Apart from
   the batched sampler this lets the processor overlap the long dependency
   chains of neighbouring pixels, which ray tracing calls in between would
   otherwise serialise. Each pixel draws its uniforms in the same order as
   integrator_direct_at and goes through the same functions, so the result
   is the same, bit for bit.
   The portal strategies keep a point's pair distribution in the one
   scratch, so each point is sampled as soon as it is prepared, but for
   the samples of a whole light or portal rectangle, which wait and are
   drawn together (strategy_sample_begin); the rare BSDF ray that reaches
   a light prepares its point again for the pdf (bsdf_hit_light), which
   costs less than a scratch per point. */
static void direct_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                       const struct vec3 *d, const struct hit *hits, const bool *found, int n, struct sampler *smp,
                       struct rgb *out, struct integrator_stats *stats)
{
    const struct scene *sc = it->scene;
    bool mis = it->mis != MIS_NONE, batches = strategy_batches(it->strategy);
    int lanes = 0, unlit_hint = 0;
    for (int x = 0; x < n; ++x) {
        out[x] = rgb_make(0.0, 0.0, 0.0);
        ++stats->rays;
        if (!found[x]) continue;
        const struct hit *h = &hits[x];
        if (h->light >= 0) {
            out[x] = light_emitted(&sc->lights[h->light], vec3_neg(d[x]));
            continue;
        }
        if (it->max_depth < 1) continue;
        struct vertex *v = &row->v[lanes];
        if (!vertex_init_lanes(sc, h->p, h->ng, h->material, vec3_neg(d[x]), v)) continue;
        /* As integrator_direct_at: nothing can light it. Its numbers are
           not drawn either: its stream has no later use in this pass. */
        if (strategy_point_unlit(it->strategy, h->p, v->n, &unlit_hint)) continue;
        if (batches) strategy_prepare(it->strategy, scratch, h->p, v->n, &row->sp[lanes]);
        row->pixel[lanes++] = x;
    }
    /* Every point's numbers, drawn together (each pixel its own stream, in
       the order of integrator_direct_at). */
    sampler_light_bsdf_many(smp, row->pixel, lanes, 0, row->u, mis ? row->ub : NULL);
    if (batches) {
        strategy_sample_many(it->strategy, row->sp, (const double(*)[4])row->u, lanes, row->ls, row->ok);
    } else {
        begin_samples(it, row, scratch, lanes);
        strategy_sample_finish_many(it->strategy, row->sp, (const double(*)[4])row->u, row->pend, lanes, row->ls,
                                    row->ok);
    }
    shading_setup_many(sc, it->mis, row->v, row->ok, row->ls, mis ? (const double(*)[2])row->ub : NULL, lanes, stats,
                       row->shadow, &row->shadow_rays, row->bsdf, &row->bsdf_rays);
    trace_shadows(sc, row, lanes, true);
    if (mis) scene_first_light_stream(sc, &row->bsdf_rays, lanes, row->light);
    for (int k = 0; k < lanes; ++k) {
        struct rgb L = shadow_resolve(&row->shadow[k], ray_stream_blocked(&row->shadow_rays, k), stats);
        if (mis) {
            stats->rays += row->bsdf[k].trace;
            L = rgb_add(L, bsdf_resolve(it, &row->sp[k], batches ? NULL : scratch, &row->bsdf[k], row->light[k]));
        }
        out[row->pixel[k]] = L;
    }
}

/* The path integrator a row at a time (a wavefront): each bounce of all the
   row's live paths is one step, as in direct_row: their vertices and light
   samples (a strategy_batches strategy draws them together), the set-up of
   the shadow rays and of the BSDF samples in vectorised loops
   (shading_setup_many) and one Embree stream for the shadow rays, then
   each path's Russian roulette, and one stream for the next rays. Paths
   that end leave the set, which stays packed. Each path draws its uniforms
   in the order integrator_radiance_from does and goes through the same
   arithmetic, so out[x] is the same, bit for bit. As in direct_row, a
   point's pair distribution lives in the one scratch: a path whose BSDF
   ray reaches a light prepares its previous vertex again for the pdf. */
static void path_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                     const struct vec3 *d, const struct hit *hits, const bool *found, int n, struct sampler *smp,
                     struct rgb *out, struct integrator_stats *stats)
{
    const struct scene *sc = it->scene;
    bool batches = strategy_batches(it->strategy);
    struct path_lane *paths = row->paths;
    int live = 0;
    for (int x = 0; x < n; ++x) {
        out[x] = rgb_make(0.0, 0.0, 0.0);
        struct path_lane *pl = &paths[live++];
        pl->pixel = x;
        pl->beta = rgb_make(1.0, 1.0, 1.0);
        pl->bsdf_pdf_prev = 0.0;
        pl->d = d[x];
    }
    for (int depth = 0; live > 0; ++depth) {
        /* What path k's ray met: the camera ray's (path k is pixel k at
           depth 0), then the bounce's. */
        const struct hit *hit = hits;
        const bool *met = found;
        if (depth > 0) {
            /* The live paths' rays, left in place by the last bounce. */
            scene_intersect_stream(sc, &row->bsdf_rays, live, row->ray_o, row->ray_d, row->hit, row->found);
            hit = row->hit;
            met = row->found;
        }
        /* The vertices, packed: vertex k is path k's from here on. */
        int lanes = 0;
        for (int k = 0; k < live; ++k) {
            struct path_lane *pl = &paths[k];
            ++stats->rays;
            if (!met[k]) continue;
            const struct hit *h = &hit[k];
            if (h->light >= 0) {
                struct rgb *L = &out[pl->pixel];
                struct strategy_point sp; /* prepared by bsdf_hit_light, if it needs it */
                sp.p = pl->prev_p;
                sp.n = pl->prev_n;
                *L = rgb_add(
                    *L, rgb_mul(pl->beta, light_reached(it, &sp, scratch, depth, h->light, pl->d, pl->bsdf_pdf_prev)));
                continue;
            }
            if (depth >= it->max_depth) continue;
            struct vertex *v = &row->v[lanes];
            if (!vertex_init_lanes(sc, h->p, h->ng, h->material, vec3_neg(pl->d), v)) continue;
            if (batches) strategy_prepare(it->strategy, scratch, h->p, v->n, &row->sp[lanes]);
            row->pixel[lanes] = pl->pixel;
            if (lanes != k) paths[lanes] = *pl;
            ++lanes;
        }
        sampler_light_bsdf_many(smp, row->pixel, lanes, depth, row->u, row->ub);
        if (batches) {
            strategy_sample_many(it->strategy, row->sp, (const double(*)[4])row->u, lanes, row->ls, row->ok);
        } else {
            begin_samples(it, row, scratch, lanes);
            strategy_sample_finish_many(it->strategy, row->sp, (const double(*)[4])row->u, row->pend, lanes, row->ls,
                                        row->ok);
        }
        /* The shadow rays and the BSDF samples (the rays in bsdf_rays are
           traced at the next bounce, for the paths that go on). */
        shading_setup_many(sc, it->mis, row->v, row->ok, row->ls, (const double(*)[2])row->ub, lanes, stats,
                           row->shadow, &row->shadow_rays, row->bsdf, &row->bsdf_rays);
        trace_shadows(sc, row, lanes, depth == 0);
        /* Each path's next ray, by BSDF sampling; the paths that go on stay
           packed, and so do their rays (path k's is ray k). */
        live = 0;
        for (int k = 0; k < lanes; ++k) {
            struct path_lane *pl = &paths[k];
            const struct bsdf_query *bq = &row->bsdf[k];
            struct rgb *L = &out[pl->pixel];
            *L = rgb_add(*L, rgb_mul(pl->beta,
                                     shadow_resolve(&row->shadow[k], ray_stream_blocked(&row->shadow_rays, k), stats)));
            if (!bq->trace) continue;
            pl->beta = rgb_mul(pl->beta, bq->weight);
            pl->bsdf_pdf_prev = bq->pdf;
            pl->d = bq->ray.d;
            pl->prev_p = row->sp[k].p;
            pl->prev_n = row->sp[k].n;
            if (!roulette_survives(it, &pl->beta, &smp[pl->pixel], depth)) continue;
            row->ray_o[live] = bq->ray.o;
            row->ray_d[live] = bq->ray.d;
            if (live != k) {
                paths[live] = *pl;
                ray_stream_move(&row->bsdf_rays, k, live);
            }
            ++live;
        }
    }
}

void integrator_radiance_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                             const struct vec3 *d, const struct hit *hits, const bool *found, int n,
                             struct sampler *smp, struct rgb *out, struct integrator_stats *stats)
{
    if (it->kind == INTEGRATOR_DIRECT) {
        direct_row(it, row, scratch, d, hits, found, n, smp, out, stats);
        return;
    }
    path_row(it, row, scratch, d, hits, found, n, smp, out, stats);
}

#include "integrator.h"

#include <stdlib.h>

#include "bsdf.h"

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

/* MIS weight of technique a against b (one sample each). */
static double mis_weight(enum mis_kind mis, double pdf_a, double pdf_b)
{
    switch (mis) {
    case MIS_NONE:
        return 1.0;
    case MIS_BALANCE:
        return pdf_a / (pdf_a + pdf_b);
    case MIS_POWER:
        /* Squares overflow only for absurd pdfs; the ratio form avoids it. */
        if (pdf_a >= pdf_b) {
            double r = pdf_b / pdf_a;
            return 1.0 / (1.0 + r * r);
        } else {
            double r = pdf_a / pdf_b;
            return r * r / (1.0 + r * r);
        }
    }
    return 1.0;
}

/* The shading context of a surface hit: side, frame, ray origin. */
struct vertex {
    const struct material *m;
    struct vec3 n;           /* geometric normal on the side of wo */
    struct frame frame;
    struct vec3 wo_local;
    struct vec3 p;           /* the surface point */
};

static bool vertex_init(const struct scene *sc, struct vec3 p, struct vec3 ng, int material, struct vec3 wo,
                        struct vertex *v)
{
    v->m = &sc->materials[material];
    /* Two-sided surfaces: shade the side wo leaves from. */
    v->n = vec3_dot(ng, wo) > 0.0 ? ng : vec3_neg(ng);
    v->frame = frame_from_normal(v->n);
    v->wo_local = frame_to_local(&v->frame, wo);
    v->p = p;
    return v->wo_local.z > 0.0;
}

/* Next-event estimation's contribution at vertex v from a drawn light
   sample (ok: the strategy produced one): one shadow ray, weighted against
   BSDF sampling. */
static struct rgb direct_from_sample(const struct integrator *it, const struct strategy_point *sp,
                                     const struct vertex *v, bool ok, const struct light_sample *ls,
                                     struct integrator_stats *stats)
{
    struct rgb black = rgb_make(0.0, 0.0, 0.0);
    if (!ok) return black;
    ++stats->light_samples;
    if (ls->light < 0) {
        ++stats->light_missed;
        return black;
    }
    if (rgb_is_black(ls->radiance) || !(ls->pdf_sa > 0.0)) return black;
    struct vec3 wi_local = frame_to_local(&v->frame, ls->wi);
    if (wi_local.z <= 0.0) return black;
    struct rgb f = bsdf_eval(v->m, v->wo_local, wi_local);
    if (rgb_is_black(f)) return black;
    ++stats->rays;
    ++stats->shadow_rays;
    /* Both ends of the shadow segment are moved along it until they clear
       their surfaces: a relative shortening alone leaves the end within
       float precision of the light's plane for points just below it. */
    const struct scene *sc = it->scene;
    double t0 = scene_offset_step(sc, sp->p, sp->n, ls->wi);
    struct vec3 y = vec3_madd(sp->p, ls->wi, ls->dist);
    double t1 = ls->dist - scene_offset_step(sc, y, sc->lights[ls->light].target.normal, ls->wi);
    if (t1 > t0 && scene_occluded(sc, vec3_madd(sp->p, ls->wi, t0), ls->wi, t1 - t0)) {
        ++stats->shadow_blocked;
        return black;
    }
    double w = it->mis == MIS_NONE ? 1.0 : mis_weight(it->mis, ls->pdf_sa, bsdf_pdf(v->m, v->wo_local, wi_local));
    return rgb_scale(rgb_mul(f, ls->radiance), wi_local.z * w / ls->pdf_sa);
}

/* The four uniforms of one strategy sample. */
static void draw_light_uniforms(struct rng *rng, double u[4])
{
    for (int k = 0; k < 4; ++k) u[k] = rng_uniform(rng);
}

/* Next-event estimation at a surface point: one strategy sample. */
static struct rgb sample_direct(const struct integrator *it, const struct strategy_point *sp, const struct vertex *v,
                                struct rng *rng, struct integrator_stats *stats)
{
    double u[4];
    draw_light_uniforms(rng, u);
    struct light_sample ls;
    bool ok = strategy_sample(it->strategy, sp, u, &ls);
    return direct_from_sample(it, sp, v, ok, &ls, stats);
}

/* Emission found by a BSDF-sampled ray, weighted against the strategy. */
static struct rgb bsdf_hit_light(const struct integrator *it, const struct strategy_point *sp, int light,
                                 struct vec3 d, double bsdf_pdf_value)
{
    struct rgb le = light_emitted(&it->scene->lights[light], vec3_neg(d));
    if (it->mis == MIS_NONE || rgb_is_black(le)) return rgb_make(0.0, 0.0, 0.0);
    double pdf_light = strategy_pdf(it->strategy, sp, light, d);
    return rgb_scale(le, mis_weight(it->mis, bsdf_pdf_value, pdf_light));
}

/* The BSDF-sampling half of direct lighting at v: one BSDF ray, counted
   only where it reaches a light, weighted against the strategy. */
static struct rgb bsdf_mis(const struct integrator *it, const struct strategy_point *sp, const struct vertex *v,
                           struct rng *rng, struct integrator_stats *stats)
{
    struct rgb black = rgb_make(0.0, 0.0, 0.0);
    struct bsdf_sample bs;
    if (!bsdf_sample(v->m, v->wo_local, rng_uniform(rng), rng_uniform(rng), &bs)) return black;
    struct vec3 d = frame_to_world(&v->frame, bs.wi);
    ++stats->rays;
    int light = scene_first_light(it->scene, scene_offset_origin(it->scene, v->p, v->n, d), d, INFINITY);
    if (light < 0) return black;
    return rgb_mul(rgb_scale(bs.f, bs.wi.z / bs.pdf), bsdf_hit_light(it, sp, light, d, bs.pdf));
}

struct rgb integrator_direct_at(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 p,
                                struct vec3 ng, int material, struct vec3 wo, struct rng *rng,
                                struct integrator_stats *stats)
{
    struct rgb L = rgb_make(0.0, 0.0, 0.0);
    struct vertex v;
    if (!vertex_init(it->scene, p, ng, material, wo, &v)) return L;
    struct strategy_point sp;
    strategy_prepare(it->strategy, scratch, p, v.n, &sp);
    L = sample_direct(it, &sp, &v, rng, stats);
    if (it->mis == MIS_NONE) return L;
    return rgb_add(L, bsdf_mis(it, &sp, &v, rng, stats));
}

struct rgb integrator_radiance_from(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 o,
                                    struct vec3 d, const struct hit *first, struct rng *rng,
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
            if (depth == 0) L = rgb_add(L, light_emitted(&sc->lights[h.light], vec3_neg(ray_d)));
            else L = rgb_add(L, rgb_mul(beta, bsdf_hit_light(it, &sp, h.light, ray_d, bsdf_pdf_prev)));
            break;
        }
        if (depth >= it->max_depth) break;
        if (it->kind == INTEGRATOR_DIRECT) {
            L = rgb_add(L, integrator_direct_at(it, scratch, h.p, h.ng, h.material, vec3_neg(ray_d), rng, stats));
            break;
        }

        struct vertex v;
        if (!vertex_init(sc, h.p, h.ng, h.material, vec3_neg(ray_d), &v)) break;
        strategy_prepare(it->strategy, scratch, h.p, v.n, &sp);
        L = rgb_add(L, rgb_mul(beta, sample_direct(it, &sp, &v, rng, stats)));

        /* Continue by BSDF sampling; the same direction gathers direct light
           at the next vertex, weighted by MIS (or not at all without MIS). */
        struct bsdf_sample bs;
        if (!bsdf_sample(v.m, v.wo_local, rng_uniform(rng), rng_uniform(rng), &bs)) break;
        beta = rgb_mul(beta, rgb_scale(bs.f, bs.wi.z / bs.pdf));
        bsdf_pdf_prev = bs.pdf;
        ray_d = frame_to_world(&v.frame, bs.wi);
        ray_o = scene_offset_origin(sc, v.p, v.n, ray_d);

        if (depth + 1 >= it->rr_depth) {
            double q = fmax(0.05, 1.0 - rgb_max(beta));
            if (rng_uniform(rng) < q) break;
            beta = rgb_scale(beta, 1.0 / (1.0 - q));
        }
    }
    return L;
}

struct rgb integrator_radiance(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 o,
                               struct vec3 d, struct rng *rng, struct integrator_stats *stats)
{
    struct hit h;
    bool found = scene_intersect(it->scene, o, d, INFINITY, &h);
    return integrator_radiance_from(it, scratch, o, d, found ? &h : NULL, rng, stats);
}

bool integrator_row_init(struct integrator_row *row, int n, struct error *err)
{
    size_t m = n > 0 ? (size_t)n : 1;
    row->v = malloc(m * sizeof *row->v);
    row->sp = malloc(m * sizeof *row->sp);
    row->u = malloc(m * sizeof *row->u);
    row->ls = malloc(m * sizeof *row->ls);
    row->ok = malloc(m * sizeof *row->ok);
    row->pixel = malloc(m * sizeof *row->pixel);
    if (row->v && row->sp && row->u && row->ls && row->ok && row->pixel) return true;
    integrator_row_free(row);
    return error_set(err, "out of memory for a row of %d shading points", n);
}

void integrator_row_free(struct integrator_row *row)
{
    free(row->v);
    free(row->sp);
    free(row->u);
    free(row->ls);
    free(row->ok);
    free(row->pixel);
    *row = (struct integrator_row){ NULL, NULL, NULL, NULL, NULL, NULL };
}

/* Direct lighting a row at a time, in three sweeps: shading points and
   their uniforms, all light samples at once, then shadow and BSDF rays.
   Each pixel draws its uniforms in the same order as integrator_direct_at,
   so the result is the same, bit for bit. */
static void direct_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                       const struct vec3 *d, const struct hit *hits, const bool *found, int n, struct rng *rng,
                       struct rgb *out, struct integrator_stats *stats)
{
    const struct scene *sc = it->scene;
    int lanes = 0;
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
        if (!vertex_init(sc, h->p, h->ng, h->material, vec3_neg(d[x]), v)) continue;
        strategy_prepare(it->strategy, scratch, h->p, v->n, &row->sp[lanes]);
        draw_light_uniforms(&rng[x], row->u[lanes]);
        row->pixel[lanes++] = x;
    }
    strategy_sample_many(it->strategy, row->sp, (const double(*)[4])row->u, lanes, row->ls, row->ok);
    for (int k = 0; k < lanes; ++k) {
        int x = row->pixel[k];
        struct rgb L = direct_from_sample(it, &row->sp[k], &row->v[k], row->ok[k], &row->ls[k], stats);
        if (it->mis != MIS_NONE) L = rgb_add(L, bsdf_mis(it, &row->sp[k], &row->v[k], &rng[x], stats));
        out[x] = L;
    }
}

void integrator_radiance_row(const struct integrator *it, struct integrator_row *row, struct strategy_scratch *scratch,
                             struct vec3 o, const struct vec3 *d, const struct hit *hits, const bool *found, int n,
                             struct rng *rng, struct rgb *out, struct integrator_stats *stats)
{
    if (it->kind == INTEGRATOR_DIRECT && strategy_batches(it->strategy)) {
        direct_row(it, row, scratch, d, hits, found, n, rng, out, stats);
        return;
    }
    for (int x = 0; x < n; ++x)
        out[x] = integrator_radiance_from(it, scratch, o, d[x], found[x] ? &hits[x] : NULL, &rng[x], stats);
}

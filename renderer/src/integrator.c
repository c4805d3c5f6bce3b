#include "integrator.h"

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

/* Next-event estimation at a surface point: one strategy sample, one shadow
   ray, weighted against BSDF sampling. */
static struct rgb sample_direct(const struct integrator *it, const struct strategy_point *sp, const struct material *m,
                                const struct frame *fr, struct vec3 wo_local, struct vec3 origin, struct rng *rng,
                                struct integrator_stats *stats)
{
    struct rgb black = rgb_make(0.0, 0.0, 0.0);
    double u[4] = { rng_uniform(rng), rng_uniform(rng), rng_uniform(rng), rng_uniform(rng) };
    struct light_sample ls;
    if (!strategy_sample(it->strategy, sp, u, &ls)) return black;
    ++stats->light_samples;
    if (ls.light < 0) {
        ++stats->light_missed;
        return black;
    }
    if (rgb_is_black(ls.radiance) || !(ls.pdf_sa > 0.0)) return black;
    struct vec3 wi_local = frame_to_local(fr, ls.wi);
    if (wi_local.z <= 0.0) return black;
    struct rgb f = bsdf_eval(m, wo_local, wi_local);
    if (rgb_is_black(f)) return black;
    ++stats->rays;
    ++stats->shadow_rays;
    if (scene_segment_occluded(it->scene, origin, vec3_madd(sp->p, ls.wi, ls.dist))) {
        ++stats->shadow_blocked;
        return black;
    }
    double w = it->mis == MIS_NONE ? 1.0 : mis_weight(it->mis, ls.pdf_sa, bsdf_pdf(m, wo_local, wi_local));
    return rgb_scale(rgb_mul(f, ls.radiance), wi_local.z * w / ls.pdf_sa);
}

struct rgb integrator_radiance(const struct integrator *it, struct strategy_scratch *scratch, struct vec3 o,
                               struct vec3 d, struct rng *rng, struct integrator_stats *stats)
{
    const struct scene *sc = it->scene;
    struct rgb L = rgb_make(0.0, 0.0, 0.0), beta = rgb_make(1.0, 1.0, 1.0);
    struct strategy_point sp;
    double bsdf_pdf_prev = 0.0;
    struct vec3 ray_o = o, ray_d = d;

    for (int depth = 0;; ++depth) {
        struct hit h;
        ++stats->rays;
        if (!scene_intersect(sc, ray_o, ray_d, INFINITY, &h)) break;

        if (h.light >= 0) {
            /* Lights emit and reflect nothing. Seen directly: full weight;
               reached by BSDF sampling: weighted against the strategy. */
            struct rgb le = light_emitted(&sc->lights[h.light], vec3_neg(ray_d));
            if (depth == 0) {
                L = rgb_add(L, rgb_mul(beta, le));
            } else if (it->mis != MIS_NONE && !rgb_is_black(le)) {
                double pdf_light = strategy_pdf(it->strategy, &sp, h.light, ray_d);
                double w = mis_weight(it->mis, bsdf_pdf_prev, pdf_light);
                L = rgb_add(L, rgb_scale(rgb_mul(beta, le), w));
            }
            break;
        }
        if (depth >= it->max_depth) break;

        const struct material *m = &sc->materials[h.material];
        /* Two-sided surfaces: shade the side the ray arrives from. */
        struct vec3 n = vec3_dot(h.ng, ray_d) < 0.0 ? h.ng : vec3_neg(h.ng);
        struct frame fr = frame_from_normal(n);
        struct vec3 wo_local = frame_to_local(&fr, vec3_neg(ray_d));
        if (wo_local.z <= 0.0) break;
        struct vec3 origin = scene_offset_origin(sc, h.p, n, n);

        strategy_prepare(it->strategy, scratch, h.p, n, &sp);
        L = rgb_add(L, rgb_mul(beta, sample_direct(it, &sp, m, &fr, wo_local, origin, rng, stats)));

        /* Continue by BSDF sampling: this direction also gathers direct light
           (MIS) at the next vertex. Without MIS, direct light comes from the
           strategy alone, so the path still continues for indirect light. */
        if (it->kind == INTEGRATOR_DIRECT && it->mis == MIS_NONE) break;
        struct bsdf_sample bs;
        if (!bsdf_sample(m, wo_local, rng_uniform(rng), rng_uniform(rng), &bs)) break;
        beta = rgb_mul(beta, rgb_scale(bs.f, bs.wi.z / bs.pdf));
        bsdf_pdf_prev = bs.pdf;
        ray_d = frame_to_world(&fr, bs.wi);
        ray_o = origin;

        if (depth + 1 >= it->rr_depth && it->kind == INTEGRATOR_PATH) {
            double q = fmax(0.05, 1.0 - rgb_max(beta));
            if (rng_uniform(rng) < q) break;
            beta = rgb_scale(beta, 1.0 / (1.0 - q));
        }
    }
    return L;
}

/* shading.c: shading points and the set-up of direct lighting's shadow and
   BSDF rays, one point at a time or a row at a time (see shading.h). */
#include "sampling/shading.h"

#include "base/fastmath.h"
#include "sampling/mis.h"

bool vertex_init(const struct scene *sc, struct vec3 p, struct vec3 ng, int material, struct vec3 wo, struct vertex *v)
{
    vertex_orient(sc, p, ng, material, wo, v);
    v->frame = frame_from_normal(v->n);
    v->wo_local = frame_to_local(&v->frame, wo);
    return v->wo_local.z > 0.0;
}

/* ---- Lambertian lanes ------------------------------------------------------
   The set-up of both rays at a Lambertian point, written as straight-line
   functions of scalars (selects, no branches) so that the loop over a row's
   points vectorises; the one-point functions below call the same code, so
   the two paths agree bit for bit. Flags are doubles (0 or 1): the
   vectoriser handles a lane of doubles better than a mix with bools. */

struct shadow_lane {
    double ox, oy, oz, tmax; /* the shadow segment (direction: wi) */
    double r, g, b;          /* delivered unless blocked */
    double counted;          /* a ray was set up (counted even if too short to trace) */
    double trace;
};

/* The shadow ray towards a light sample (unit wi, distance dist, density
   pdf_sa, radiance le, the light's normal nl) at point p with normal n on
   wo's side, where the BSDF is f, cos_i = wi . n and BSDF sampling would
   pick wi with density pdf_b; its value f le cos w / pdf_sa with the MIS
   weight w against BSDF sampling. Both ends of the segment are moved along
   it until they clear their surfaces: a relative shortening alone leaves
   the end within float precision of the light's plane for points just
   below it.
   w / pdf_sa is mis_ratio's num / den (mis.h): one division for every
   MIS kind, and no NaN for an infinite density. */
FM_INLINE struct shadow_lane shadow_lane(double scale, enum mis_kind mis, struct rgb f, double cos_i, double pdf_b,
                                         struct vec3 n, struct vec3 p, struct vec3 wi, double dist, double pdf_sa,
                                         struct rgb le, struct vec3 nl)
{
    struct shadow_lane out;
    /* Nested selects of doubles: combining the comparisons as bools defeats
       GCC's vectoriser (mask conversions). */
    double valid = pdf_sa > 0.0 ? 1.0 : 0.0;
    valid = cos_i > 0.0 ? valid : 0.0;
    valid = le.r != 0.0 || le.g != 0.0 || le.b != 0.0 ? valid : 0.0;
    valid = f.r != 0.0 || f.g != 0.0 || f.b != 0.0 ? valid : 0.0;
    double t0 = scene_offset_step_scaled(scale, p, n, wi);
    double t1 = dist - scene_offset_step_scaled(scale, vec3_madd(p, wi, dist), nl, wi);
    struct vec3 o = vec3_madd(p, wi, t0);
    out.ox = o.x;
    out.oy = o.y;
    out.oz = o.z;
    out.tmax = t1 - t0;
    out.counted = valid;
    out.trace = t1 > t0 ? valid : 0.0;
    struct mis_ratio w = mis_ratio(mis, pdf_sa, pdf_b);
    double k = valid != 0.0 ? cos_i * w.num / w.den : 0.0;
    out.r = f.r * le.r * k;
    out.g = f.g * le.g * k;
    out.b = f.b * le.b * k;
    return out;
}

/* shadow_lane at a Lambertian point: f = albedo / pi, pdf_b = cos / pi. */
FM_INLINE struct shadow_lane lambert_shadow_lane(double scale, enum mis_kind mis, struct rgb albedo, struct vec3 n,
                                                 struct vec3 p, struct vec3 wi, double dist, double pdf_sa,
                                                 struct rgb le, struct vec3 nl)
{
    double cos_i = vec3_dot(wi, n);
    return shadow_lane(scale, mis, bsdf_lambert_f(albedo), cos_i, bsdf_lambert_pdf(cos_i), n, p, wi, dist, pdf_sa, le,
                       nl);
}

struct bsdf_lane {
    double ox, oy, oz, dx, dy, dz;
    double pdf;
    double trace;
};

/* A cosine-distributed ray from p (normal n on wo's side). Its weight
   f cos / pdf is the albedo itself, taken as such (not as a quotient). */
FM_INLINE struct bsdf_lane lambert_bsdf_lane(double scale, struct vec3 n, struct vec3 p, double u0, double u1)
{
    struct bsdf_lane out;
    struct vec3 wl = bsdf_lambert_dir(u0, u1);
    struct frame fr = frame_from_normal(n);
    struct vec3 d = frame_to_world(&fr, wl);
    struct vec3 o = vec3_madd(p, d, scene_offset_step_scaled(scale, p, n, d));
    out.ox = o.x;
    out.oy = o.y;
    out.oz = o.z;
    out.dx = d.x;
    out.dy = d.y;
    out.dz = d.z;
    out.pdf = bsdf_lambert_pdf(wl.z);
    /* pdf > 0 implies wl.z > 0 (and wl.z >= 2^-26.5 keeps pdf from underflowing). */
    out.trace = out.pdf > 0.0 ? 1.0 : 0.0;
    return out;
}

/* A query from a lane; the ray itself only with_ray (the row keeps its
   rays in streams, see shading_setup_many). */
FM_INLINE void shadow_from_lane(const struct shadow_lane *l, struct vec3 wi, bool with_ray,
                                struct integrator_stats *stats, struct shadow_query *q)
{
    if (l->counted != 0.0) {
        ++stats->rays;
        ++stats->shadow_rays;
    }
    q->trace = l->trace != 0.0;
    if (with_ray) {
        q->ray.o = vec3_make(l->ox, l->oy, l->oz);
        q->ray.d = wi;
        q->ray.tmax = l->tmax;
    }
    q->value = rgb_make(l->r, l->g, l->b);
}

/* The same for the BSDF ray, with the whole ray: the path integrator goes
   on along it, direct lighting weighs the light it reaches by the
   strategy's density in its direction. */
FM_INLINE void bsdf_from_lane(const struct bsdf_lane *l, const struct material *m, struct bsdf_query *q)
{
    q->trace = l->trace != 0.0;
    if (!q->trace) return;
    q->ray.o = vec3_make(l->ox, l->oy, l->oz);
    q->ray.d = vec3_make(l->dx, l->dy, l->dz);
    q->ray.tmax = INFINITY;
    q->weight = m->albedo;
    q->pdf = l->pdf;
}

/* ---- one point ------------------------------------------------------------ */

void shadow_setup(const struct scene *sc, enum mis_kind mis, const struct vertex *v, bool ok,
                  const struct light_sample *ls, struct integrator_stats *stats, struct shadow_query *q)
{
    q->trace = false;
    q->value = rgb_make(0.0, 0.0, 0.0);
    if (!ok) return;
    ++stats->light_samples;
    if (ls->light < 0) {
        ++stats->light_missed;
        return;
    }
    struct vec3 nl = sc->lights[ls->light].target.normal;
    /* Lambertian points exactly as the vectorised row computes them. */
    if (v->m->kind == MATERIAL_DIFFUSE) {
        struct shadow_lane l = lambert_shadow_lane(sc->scale, mis, v->m->albedo, v->n, v->p, ls->wi, ls->dist,
                                                   ls->pdf_sa, ls->radiance, nl);
        shadow_from_lane(&l, ls->wi, true, stats, q);
        return;
    }
    /* Any other BSDF: the same shadow ray, with its own f and pdf. */
    struct vec3 wi_local = frame_to_local(&v->frame, ls->wi);
    struct shadow_lane l =
        shadow_lane(sc->scale, mis, bsdf_eval(v->m, v->wo_local, wi_local), wi_local.z,
                    bsdf_pdf(v->m, v->wo_local, wi_local), v->n, v->p, ls->wi, ls->dist, ls->pdf_sa, ls->radiance, nl);
    shadow_from_lane(&l, ls->wi, true, stats, q);
}

void bsdf_setup(const struct scene *sc, const struct vertex *v, const double u[2], struct bsdf_query *q)
{
    if (v->m->kind == MATERIAL_DIFFUSE) {
        struct bsdf_lane l = lambert_bsdf_lane(sc->scale, v->n, v->p, u[0], u[1]);
        bsdf_from_lane(&l, v->m, q);
        return;
    }
    struct bsdf_sample bs;
    q->trace = bsdf_sample(v->m, v->wo_local, u[0], u[1], &bs);
    if (!q->trace) return;
    q->ray.d = frame_to_world(&v->frame, bs.wi);
    q->ray.o = scene_offset_origin(sc, v->p, v->n, q->ray.d);
    q->ray.tmax = INFINITY;
    q->weight = rgb_scale(bs.f, bs.wi.z / bs.pdf);
    q->pdf = bs.pdf;
}

/* ---- a row ---------------------------------------------------------------- */

/* Points per block: gathered into arrays of scalars, run through the
   vectorised loops (one point per SIMD slot), scattered back. */
#define LANE_BLOCK 16

/* Inputs of a block, one row per scalar. */
enum {
    IN_AR,
    IN_AG,
    IN_AB,
    IN_NX,
    IN_NY,
    IN_NZ,
    IN_PX,
    IN_PY,
    IN_PZ,
    IN_WX,
    IN_WY,
    IN_WZ,
    IN_DIST,
    IN_PDF,
    IN_LR,
    IN_LG,
    IN_LB,
    IN_NLX,
    IN_NLY,
    IN_NLZ,
    IN_U0,
    IN_U1,
    IN_COUNT
};
/* Outputs: the fields of shadow_lane and bsdf_lane, in order. */
enum { SO_OX, SO_OY, SO_OZ, SO_TMAX, SO_R, SO_G, SO_B, SO_COUNTED, SO_TRACE, SO_COUNT };
enum { BO_OX, BO_OY, BO_OZ, BO_DX, BO_DY, BO_DZ, BO_PDF, BO_TRACE, BO_COUNT };

/* The two halves of a block, lambert_shadow_lane and lambert_bsdf_lane for
   each lane, are separate loops: one loop with both is too big for GCC's
   vectoriser. Results go to arrays of scalars, not to arrays of lane
   structs, whose strided stores GCC does not vectorise. */
FM_INLINE void shadow_block(double scale, enum mis_kind mis, double in[IN_COUNT][LANE_BLOCK],
                            double so[SO_COUNT][LANE_BLOCK])
{
#pragma omp simd
    for (int i = 0; i < LANE_BLOCK; ++i) {
        struct shadow_lane l = lambert_shadow_lane(
            scale, mis, rgb_make(in[IN_AR][i], in[IN_AG][i], in[IN_AB][i]),
            vec3_make(in[IN_NX][i], in[IN_NY][i], in[IN_NZ][i]), vec3_make(in[IN_PX][i], in[IN_PY][i], in[IN_PZ][i]),
            vec3_make(in[IN_WX][i], in[IN_WY][i], in[IN_WZ][i]), in[IN_DIST][i], in[IN_PDF][i],
            rgb_make(in[IN_LR][i], in[IN_LG][i], in[IN_LB][i]), vec3_make(in[IN_NLX][i], in[IN_NLY][i], in[IN_NLZ][i]));
        so[SO_OX][i] = l.ox;
        so[SO_OY][i] = l.oy;
        so[SO_OZ][i] = l.oz;
        so[SO_TMAX][i] = l.tmax;
        so[SO_R][i] = l.r;
        so[SO_G][i] = l.g;
        so[SO_B][i] = l.b;
        so[SO_COUNTED][i] = l.counted;
        so[SO_TRACE][i] = l.trace;
    }
}

FM_INLINE void bsdf_block(double scale, double in[IN_COUNT][LANE_BLOCK], double bo[BO_COUNT][LANE_BLOCK])
{
#pragma omp simd
    for (int i = 0; i < LANE_BLOCK; ++i) {
        struct bsdf_lane l =
            lambert_bsdf_lane(scale, vec3_make(in[IN_NX][i], in[IN_NY][i], in[IN_NZ][i]),
                              vec3_make(in[IN_PX][i], in[IN_PY][i], in[IN_PZ][i]), in[IN_U0][i], in[IN_U1][i]);
        bo[BO_OX][i] = l.ox;
        bo[BO_OY][i] = l.oy;
        bo[BO_OZ][i] = l.oz;
        bo[BO_DX][i] = l.dx;
        bo[BO_DY][i] = l.dy;
        bo[BO_DZ][i] = l.dz;
        bo[BO_PDF][i] = l.pdf;
        bo[BO_TRACE][i] = l.trace;
    }
}

/* A block's rays into the streams at lanes b..b+LANE_BLOCK-1 (the
   streams have room: their arrays are rounded up to whole blocks), as
   ray_stream_set converts them. Lanes that trace nothing are inactive. */
FM_INLINE void shadow_stream_block(double in[IN_COUNT][LANE_BLOCK], double so[SO_COUNT][LANE_BLOCK],
                                   struct ray_stream *r, int b)
{
#pragma omp simd
    for (int i = 0; i < LANE_BLOCK; ++i) {
        bool trace = so[SO_TRACE][i] != 0.0;
        r->ox[b + i] = (float)so[SO_OX][i];
        r->oy[b + i] = (float)so[SO_OY][i];
        r->oz[b + i] = (float)so[SO_OZ][i];
        r->dx[b + i] = (float)in[IN_WX][i];
        r->dy[b + i] = (float)in[IN_WY][i];
        r->dz[b + i] = (float)in[IN_WZ][i];
        r->tnear[b + i] = ray_stream_tnear_for(trace);
        r->tfar[b + i] = ray_stream_tfar_for(trace, so[SO_TMAX][i]);
    }
}

FM_INLINE void bsdf_stream_block(double bo[BO_COUNT][LANE_BLOCK], struct ray_stream *r, int b)
{
#pragma omp simd
    for (int i = 0; i < LANE_BLOCK; ++i) {
        bool trace = bo[BO_TRACE][i] != 0.0;
        r->ox[b + i] = (float)bo[BO_OX][i];
        r->oy[b + i] = (float)bo[BO_OY][i];
        r->oz[b + i] = (float)bo[BO_OZ][i];
        r->dx[b + i] = (float)bo[BO_DX][i];
        r->dy[b + i] = (float)bo[BO_DY][i];
        r->dz[b + i] = (float)bo[BO_DZ][i];
        r->tnear[b + i] = ray_stream_tnear_for(trace);
        r->tfar[b + i] = ray_stream_tfar_for(trace, INFINITY);
    }
}

/* A query's ray into a stream (the points that take the one-point path). */
static void stream_from_query(struct ray_stream *r, int k, bool trace, const struct scene_ray *ray)
{
    if (trace) ray_stream_set(r, k, ray->o, ray->d, ray->tmax);
    else ray_stream_skip(r, k);
}

FM_SIMD_CLONES
void shading_setup_many(const struct scene *sc, enum mis_kind mis, const struct vertex *v, const bool *ok,
                        const struct light_sample *ls, const double (*ub)[2], int n, struct integrator_stats *stats,
                        struct shadow_query *shadow, struct ray_stream *shadow_rays, struct bsdf_query *bsdf,
                        struct ray_stream *bsdf_rays)
{
    const double scale = sc->scale;
    /* The lanes' counts, added to stats at the end: increments through the
       pointer, which GCC pairs into one 16-byte add, stall on the 8-byte
       stores of the other counts (store forwarding fails). */
    struct integrator_stats c = { 0 };
    for (int b = 0; b < n; b += LANE_BLOCK) {
        int m = n - b < LANE_BLOCK ? n - b : LANE_BLOCK;
        double in[IN_COUNT][LANE_BLOCK];
        for (int i = 0; i < LANE_BLOCK; ++i) {
            /* Idle lanes repeat lane 0 so that they compute finite values. */
            int k = b + (i < m ? i : 0);
            const struct light_sample *l = &ls[k];
            /* A lane without a light sample gets a harmless stand-in; only
               its bsdf half is used. Stored field by field: a local array
               of the fields copied in a loop costs as much again. */
            bool has = ok[k] && l->light >= 0;
            struct vec3 wi = has ? l->wi : v[k].n, nl = has ? sc->lights[l->light].target.normal : v[k].n;
            struct rgb le = has ? l->radiance : rgb_make(0.0, 0.0, 0.0);
            in[IN_AR][i] = v[k].m->albedo.r;
            in[IN_AG][i] = v[k].m->albedo.g;
            in[IN_AB][i] = v[k].m->albedo.b;
            in[IN_NX][i] = v[k].n.x;
            in[IN_NY][i] = v[k].n.y;
            in[IN_NZ][i] = v[k].n.z;
            in[IN_PX][i] = v[k].p.x;
            in[IN_PY][i] = v[k].p.y;
            in[IN_PZ][i] = v[k].p.z;
            in[IN_WX][i] = wi.x;
            in[IN_WY][i] = wi.y;
            in[IN_WZ][i] = wi.z;
            in[IN_DIST][i] = has ? l->dist : 1.0;
            in[IN_PDF][i] = has ? l->pdf_sa : 1.0;
            in[IN_LR][i] = le.r;
            in[IN_LG][i] = le.g;
            in[IN_LB][i] = le.b;
            in[IN_NLX][i] = nl.x;
            in[IN_NLY][i] = nl.y;
            in[IN_NLZ][i] = nl.z;
            in[IN_U0][i] = ub ? ub[k][0] : 0.0;
            in[IN_U1][i] = ub ? ub[k][1] : 0.0;
        }
        double so[SO_COUNT][LANE_BLOCK], bo[BO_COUNT][LANE_BLOCK];
        /* mis as a constant in each copy: a select on a loop-invariant
           enum is not vectorised. */
        switch (mis) {
        case MIS_NONE:
            shadow_block(scale, MIS_NONE, in, so);
            break;
        case MIS_BALANCE:
            shadow_block(scale, MIS_BALANCE, in, so);
            break;
        case MIS_POWER:
            shadow_block(scale, MIS_POWER, in, so);
            break;
        }
        shadow_stream_block(in, so, shadow_rays, b);
        if (ub) {
            bsdf_block(scale, in, bo);
            bsdf_stream_block(bo, bsdf_rays, b);
        }
        for (int i = 0; i < m; ++i) {
            int k = b + i;
            if (v[k].m->kind != MATERIAL_DIFFUSE) {
                shadow_setup(sc, mis, &v[k], ok[k], &ls[k], stats, &shadow[k]);
                stream_from_query(shadow_rays, k, shadow[k].trace, &shadow[k].ray);
                if (ub) {
                    bsdf_setup(sc, &v[k], ub[k], &bsdf[k]);
                    stream_from_query(bsdf_rays, k, bsdf[k].trace, &bsdf[k].ray);
                }
                continue;
            }
            /* The counting and early outs of shadow_setup. */
            shadow[k].trace = false;
            shadow[k].value = rgb_make(0.0, 0.0, 0.0);
            if (ok[k]) {
                ++c.light_samples;
                if (ls[k].light < 0) ++c.light_missed;
                else {
                    struct shadow_lane l = { so[SO_OX][i], so[SO_OY][i], so[SO_OZ][i],      so[SO_TMAX][i], so[SO_R][i],
                                             so[SO_G][i],  so[SO_B][i],  so[SO_COUNTED][i], so[SO_TRACE][i] };
                    shadow_from_lane(&l, ls[k].wi, false, &c, &shadow[k]);
                }
            }
            if (ub) {
                struct bsdf_lane l = { bo[BO_OX][i], bo[BO_OY][i], bo[BO_OZ][i],  bo[BO_DX][i],
                                       bo[BO_DY][i], bo[BO_DZ][i], bo[BO_PDF][i], bo[BO_TRACE][i] };
                bsdf_from_lane(&l, v[k].m, &bsdf[k]);
            }
        }
    }
    stats->rays += c.rays;
    stats->shadow_rays += c.shadow_rays;
    stats->light_samples += c.light_samples;
    stats->light_missed += c.light_missed;
}

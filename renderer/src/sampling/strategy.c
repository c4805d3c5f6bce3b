/* strategy.c: a strategy's pairs and per-emitter tables, its lifetime, and
   sampling with the density of what it samples: technique choice, the
   techniques' pdfs and the mixture over pairs. Weights and culling are in
   strategy_weights.c, batched sampling in strategy_batch.c. */
#include "sampling/strategy.h"

#include <stdlib.h>

#include "config/config.h"
#include "sampling/strategy_internal.h"

/* The box in which an emitter with portals counts a point as inside its
   shade: the bounding box of its lights and its portals, grown on every
   side by its own diagonal. A shade wraps its lamp closely; without a
   bound, every point between the portal and light planes of a lamp (the
   outside of other shades, walls at that height) would sample that lamp
   through its shade. */
static struct aabb shade_box(const struct scene *sc, const struct emitter *e)
{
    struct aabb b = { vec3_make(INFINITY, INFINITY, INFINITY), vec3_make(-INFINITY, -INFINITY, -INFINITY) };
    const struct light *first = &sc->lights[e->first_light];
    for (int i = 0; i < e->n_lights + first->n_portals; ++i) {
        const struct polygon *poly = i < e->n_lights
                                         ? &sc->lights[e->first_light + i].target.polygon
                                         : &sc->portals[first->first_portal + i - e->n_lights].target->polygon;
        for (int v = 0; v < poly->n; ++v) {
            struct vec3 x = poly->v[v];
            b.lo = vec3_make(fmin(b.lo.x, x.x), fmin(b.lo.y, x.y), fmin(b.lo.z, x.z));
            b.hi = vec3_make(fmax(b.hi.x, x.x), fmax(b.hi.y, x.y), fmax(b.hi.z, x.z));
        }
    }
    double grow = vec3_length(vec3_sub(b.hi, b.lo));
    b.lo = vec3_sub(b.lo, vec3_make(grow, grow, grow));
    b.hi = vec3_add(b.hi, vec3_make(grow, grow, grow));
    /* Auto portals lie on a convex hull P around the light (portal_finder.h)
       and every point inside P must count as inside: a shade's inner face
       sees the light directly, not through a portal. */
    const struct auto_portal_report *ap = sc->auto_portals ? &sc->auto_portals[first->emitter] : NULL;
    if (ap && ap->enclosed) {
        b.lo = vec3_make(fmin(b.lo.x, ap->box_lo.x), fmin(b.lo.y, ap->box_lo.y), fmin(b.lo.z, ap->box_lo.z));
        b.hi = vec3_make(fmax(b.hi.x, ap->box_hi.x), fmax(b.hi.y, ap->box_hi.y), fmax(b.hi.z, ap->box_hi.z));
    }
    return b;
}

static struct aabb aabb_union(struct aabb a, struct aabb b)
{
    return (struct aabb){ vec3_make(fmin(a.lo.x, b.lo.x), fmin(a.lo.y, b.lo.y), fmin(a.lo.z, b.lo.z)),
                          vec3_make(fmax(a.hi.x, b.hi.x), fmax(a.hi.y, b.hi.y), fmax(a.hi.z, b.hi.z)) };
}

/* The box of the part of the scene box that a light/portal pair can light
   (see build_bvh); false when it lights nothing. */
static bool member_box(const struct scene *sc, const struct strategy_pair *m, struct aabb scene_box, struct aabb *box)
{
    struct plane planes[1 + ANTISHADOW_SEPARATING_MAX];
    int n = 0;
    if (m->portal >= 0) {
        const struct antishadow *a = &sc->portals[m->portal].antishadow;
        planes[n++] = a->portal_plane;
        for (int k = 0; k < a->n_separating; ++k) planes[n++] = a->separating[k];
    } else if (!sc->lights[m->light].two_sided) {
        const struct target *t = &sc->lights[m->light].target;
        planes[n++] = (struct plane){ t->normal, vec3_dot(t->normal, t->polygon.v[0]) };
    }
    *box = (struct aabb){ vec3_make(INFINITY, INFINITY, INFINITY), vec3_make(-INFINITY, -INFINITY, -INFINITY) };
    return aabb_of_region(planes, n, scene_box, box);
}

/* The region each pair can light, as a box: a portal's anti-penumbra (the
   portal plane and the separating planes), a one-sided light's front half
   space, a two-sided light's whole scene; all within the scene's bounds,
   padded so that points on the bounding surfaces stay inside. A mesh
   light's pair takes the union over its triangles, so that a point finds
   the pair once, whatever the number of triangles. */
static bool build_bvh(struct strategy *s, struct error *err)
{
    const struct scene *sc = s->scene;
    double pad = 1e-3 * sc->scale + 1e-9;
    struct aabb scene_box = { vec3_sub(sc->bounds_lo, vec3_make(pad, pad, pad)),
                              vec3_add(sc->bounds_hi, vec3_make(pad, pad, pad)) };
    struct aabb *boxes = malloc(sizeof *boxes * (size_t)s->n_pairs);
    if (!boxes) return error_set(err, "out of memory for %d light/portal pairs", s->n_pairs);
    for (int i = 0; i < s->n_pairs; ++i) {
        const struct strategy_pair *pair = &s->pairs[i];
        const struct emitter *e = &sc->emitters[pair->emitter];
        struct aabb box;
        bool any = false;
        for (int k = 0; k < e->n_lights; ++k) {
            struct strategy_pair m = strategy_member_of(sc, pair, e->first_light + k);
            struct aabb b;
            if (!member_box(sc, &m, scene_box, &b)) continue;
            box = any ? aabb_union(box, b) : b;
            any = true;
        }
        const struct light *l = &sc->lights[pair->light];
        if (pair->portal >= 0 && pair->portal == l->first_portal) {
            /* The first pair also lights the light's side of all its portals. */
            struct plane side[POLYGON_INPUT_MAX + 1];
            int m = 0;
            for (int k = l->first_portal; k < l->first_portal + l->n_portals && m < POLYGON_INPUT_MAX; ++k) {
                struct plane q = sc->portals[k].antishadow.portal_plane;
                side[m++] = (struct plane){ vec3_neg(q.normal), -q.offset };
            }
            if (!l->two_sided && e->n_lights == 1)
                side[m++] = (struct plane){ l->target.normal, vec3_dot(l->target.normal, l->target.polygon.v[0]) };
            struct aabb inside, shade = s->shade[pair->emitter];
            shade.lo = vec3_make(fmax(shade.lo.x, scene_box.lo.x), fmax(shade.lo.y, scene_box.lo.y),
                                 fmax(shade.lo.z, scene_box.lo.z));
            shade.hi = vec3_make(fmin(shade.hi.x, scene_box.hi.x), fmin(shade.hi.y, scene_box.hi.y),
                                 fmin(shade.hi.z, scene_box.hi.z));
            if (aabb_of_region(side, m, shade, &inside)) {
                box = any ? aabb_union(box, inside) : inside;
                any = true;
            }
        }
        if (any) {
            boxes[i].lo = vec3_sub(box.lo, vec3_make(pad, pad, pad));
            boxes[i].hi = vec3_add(box.hi, vec3_make(pad, pad, pad));
        } else {
            boxes[i] = (struct aabb){ vec3_make(1, 1, 1), vec3_make(-1, -1, -1) }; /* lights nothing */
        }
    }
    bool ok = pair_bvh_build(&s->bvh, boxes, s->n_pairs, err);
    free(boxes);
    return ok;
}

/* Per emitter: the alias table of a mesh light's triangles by power, and
   the area-weighted centroid. */
static bool build_emitters(struct strategy *s, struct error *err)
{
    const struct scene *sc = s->scene;
    int n = sc->n_emitters > 0 ? sc->n_emitters : 1;
    s->members = calloc((size_t)n, sizeof *s->members);
    s->centre = calloc((size_t)n, sizeof *s->centre);
    s->reach = calloc((size_t)n, sizeof *s->reach);
    s->shade = malloc(sizeof *s->shade * (size_t)n);
    s->portal_plane = malloc(sizeof *s->portal_plane * (size_t)(s->n_pairs > 0 ? s->n_pairs : 1));
    if (!s->members || !s->centre || !s->reach || !s->shade || !s->portal_plane)
        return error_set(err, "out of memory for %d lights", sc->n_emitters);
    /* The planes on_light_side tests, in one small array: reached through
       the lights and portals, each test touched a separate part of
       structs of several kilobytes. */
    for (int i = 0; i < s->n_pairs; ++i)
        if (s->pairs[i].portal >= 0) s->portal_plane[i] = sc->portals[s->pairs[i].portal].antishadow.portal_plane;
    for (int i = 0; i < sc->n_emitters; ++i) {
        const struct emitter *e = &sc->emitters[i];
        s->shade[i] = shade_box(sc, e);
        struct vec3 c = vec3_make(0.0, 0.0, 0.0);
        double area = 0.0;
        for (int k = 0; k < e->n_lights; ++k) {
            const struct light *l = &sc->lights[e->first_light + k];
            c = vec3_madd(c, l->centroid, l->target.area);
            area += l->target.area;
        }
        s->centre[i] = vec3_scale(c, 1.0 / area);
        for (int k = 0; k < e->n_lights; ++k) {
            const struct polygon *poly = &sc->lights[e->first_light + k].target.polygon;
            for (int v = 0; v < poly->n; ++v)
                s->reach[i] = fmax(s->reach[i], vec3_length(vec3_sub(poly->v[v], s->centre[i])));
        }
        if (e->n_lights == 1) continue;
        double *power = malloc(sizeof *power * (size_t)e->n_lights);
        if (!power) return error_set(err, "out of memory for %d lights", e->n_lights);
        for (int k = 0; k < e->n_lights; ++k) power[k] = sc->lights[e->first_light + k].power;
        bool ok = alias_build(&s->members[i], power, e->n_lights, err);
        free(power);
        if (!ok) return false;
    }
    return true;
}

/* Edges of a portal outline per SIMD block (AVX-512: 8 doubles). */
#define OUTLINE_BLOCK 8

/* The outline of each mesh light's portal pair (mesh_pair_bound's loop). */
static bool build_outlines(struct strategy *s, struct error *err)
{
    const struct scene *sc = s->scene;
    s->outline = calloc((size_t)(s->n_pairs > 0 ? s->n_pairs : 1), sizeof *s->outline);
    if (!s->outline) return error_set(err, "out of memory for %d light/portal pairs", s->n_pairs);
    for (int i = 0; i < s->n_pairs; ++i) {
        const struct strategy_pair *pair = &s->pairs[i];
        if (pair->portal < 0 || sc->emitters[pair->emitter].n_lights == 1) continue;
        const struct polygon *q = &sc->portals[pair->portal].target->polygon;
        struct portal_outline *o = &s->outline[i];
        o->n_edges = (q->n + OUTLINE_BLOCK - 1) / OUTLINE_BLOCK * OUTLINE_BLOCK;
        double *xyz = malloc(sizeof *xyz * 3 * (size_t)(o->n_edges + 1));
        if (!xyz) return error_set(err, "out of memory for a portal of %d vertices", q->n);
        o->x = xyz;
        o->y = xyz + o->n_edges + 1;
        o->z = xyz + 2 * (o->n_edges + 1);
        for (int k = 0; k <= o->n_edges; ++k) {
            struct vec3 v = q->v[k < q->n ? k : 0];
            o->x[k] = v.x;
            o->y[k] = v.y;
            o->z[k] = v.z;
        }
    }
    return true;
}

bool strategy_init(struct strategy *s, const struct scene *scene, const struct render_desc *rd, struct error *err)
{
    s->kind = rd->strategy;
    s->weight = rd->portal_weight;
    s->defensive = strategy_kind_uses_portals(rd->strategy) ? rd->defensive : 0.0;
    s->scene = scene;
    s->pairs = NULL;
    s->first_pair = NULL;
    s->members = NULL;
    s->centre = NULL;
    s->reach = NULL;
    s->n_pairs = 0;
    s->use_bvh = false;
    s->shade = NULL;
    s->portal_plane = NULL;
    s->bvh = (struct pair_bvh){ 0 };
    s->outline = NULL;
    double *power = malloc(sizeof *power * (size_t)scene->n_lights);
    if (!power) return error_set(err, "out of memory for %d lights", scene->n_lights);
    for (int i = 0; i < scene->n_lights; ++i) power[i] = scene->lights[i].power;
    bool ok = alias_build(&s->power, power, scene->n_lights, err);
    free(power);
    if (!ok) return false;

    int n = 0;
    for (int i = 0; i < scene->n_emitters; ++i) {
        int np = strategy_kind_uses_portals(s->kind) ? scene->lights[scene->emitters[i].first_light].n_portals : 0;
        n += np > 0 ? np : 1;
    }
    s->pairs = malloc(sizeof *s->pairs * (size_t)n);
    s->first_pair = malloc(sizeof *s->first_pair * (size_t)(scene->n_emitters + 1));
    if (!s->pairs || !s->first_pair) {
        strategy_free(s);
        return error_set(err, "out of memory for %d light/portal pairs", n);
    }
    for (int i = 0; i < scene->n_emitters; ++i) {
        int first = scene->emitters[i].first_light;
        const struct light *l = &scene->lights[first];
        s->first_pair[i] = s->n_pairs;
        if (strategy_kind_uses_portals(s->kind) && l->n_portals > 0) {
            for (int k = 0; k < l->n_portals; ++k)
                s->pairs[s->n_pairs++] = (struct strategy_pair){ first, l->first_portal + k, i };
        } else {
            s->pairs[s->n_pairs++] = (struct strategy_pair){ first, -1, i };
        }
    }
    s->first_pair[scene->n_emitters] = s->n_pairs;
    if (!build_emitters(s, err) || !build_outlines(s, err)) {
        strategy_free(s);
        return false;
    }
    s->use_bvh = strategy_kind_classifies(s->kind);
    if (s->use_bvh && !build_bvh(s, err)) {
        strategy_free(s); /* on failure nothing is left to free, as above */
        return false;
    }
    return true;
}

void strategy_free(struct strategy *s)
{
    alias_free(&s->power);
    pair_bvh_free(&s->bvh);
    for (int i = 0; s->members && i < s->scene->n_emitters; ++i) alias_free(&s->members[i]);
    free(s->members);
    free(s->centre);
    free(s->reach);
    free(s->shade);
    free(s->portal_plane);
    s->members = NULL;
    s->centre = NULL;
    s->reach = NULL;
    s->shade = NULL;
    s->portal_plane = NULL;
    for (int i = 0; s->outline && i < s->n_pairs; ++i) free(s->outline[i].x);
    free(s->outline);
    s->outline = NULL;
    free(s->pairs);
    free(s->first_pair);
    s->pairs = NULL;
    s->first_pair = NULL;
    s->n_pairs = 0;
    s->use_bvh = false;
    s->bvh = (struct pair_bvh){ 0 };
}

bool strategy_scratch_init(const struct strategy *s, struct strategy_scratch *scratch, struct error *err)
{
    size_t n = (size_t)s->n_pairs;
    scratch->n_cand = 0;
    scratch->cand = malloc(sizeof *scratch->cand * n);
    scratch->cand_pos = malloc(sizeof *scratch->cand_pos * n);
    scratch->cdf = malloc(sizeof *scratch->cdf * n);
    scratch->region = malloc(n);
    scratch->vis_state = calloc(n, 1);
    scratch->vis = malloc(sizeof *scratch->vis * n);
    scratch->defer_poly = malloc(sizeof *scratch->defer_poly * n);
    scratch->defer_cand = malloc(sizeof *scratch->defer_cand * n);
    scratch->defer_value = malloc(sizeof *scratch->defer_value * n);
    if (!scratch->cand || !scratch->cand_pos || !scratch->cdf || !scratch->region || !scratch->vis_state ||
        !scratch->vis || !scratch->defer_poly || !scratch->defer_cand || !scratch->defer_value) {
        strategy_scratch_free(scratch);
        return error_set(err, "out of memory for strategy scratch");
    }
    for (size_t i = 0; i < n; ++i) scratch->cand_pos[i] = -1;
    return true;
}

void strategy_scratch_free(struct strategy_scratch *scratch)
{
    free(scratch->cand);
    free(scratch->cand_pos);
    free(scratch->cdf);
    free(scratch->region);
    free(scratch->vis_state);
    free(scratch->vis);
    free(scratch->defer_poly);
    free(scratch->defer_cand);
    free(scratch->defer_value);
    scratch->defer_poly = NULL;
    scratch->defer_cand = NULL;
    scratch->defer_value = NULL;
    scratch->cand = NULL;
    scratch->cand_pos = NULL;
    scratch->cdf = NULL;
    scratch->region = NULL;
    scratch->vis_state = NULL;
    scratch->vis = NULL;
}

enum technique strategy_technique(const struct strategy *s, const struct strategy_pair *pair, enum region region)
{
    switch (s->kind) {
    case STRATEGY_LIGHT_AREA:
        return TECHNIQUE_LIGHT_AREA;
    case STRATEGY_LIGHT:
        return TECHNIQUE_LIGHT_SOLID;
    case STRATEGY_PORTAL:
        return pair->portal < 0 ? TECHNIQUE_LIGHT_SOLID : TECHNIQUE_PORTAL_AREA;
    case STRATEGY_PROJECTION:
        return pair->portal < 0 ? TECHNIQUE_LIGHT_SOLID : TECHNIQUE_VISIBLE_AREA;
    case STRATEGY_ANTISHADOW:
    case STRATEGY_ANTISHADOW_EXACT: {
        if (pair->portal < 0) return TECHNIQUE_LIGHT_SOLID;
        bool exact = s->kind == STRATEGY_ANTISHADOW_EXACT;
        switch (region) {
        case REGION_OUTSIDE:
            return TECHNIQUE_NONE;
        case REGION_ANTI_UMBRA:
        case REGION_INSIDE:
            return TECHNIQUE_LIGHT_SOLID;
        case REGION_ANTI_ANTUMBRA:
            return exact ? TECHNIQUE_PORTAL_SOLID : TECHNIQUE_PORTAL_AREA;
        case REGION_ANTI_PENUMBRA:
            return exact ? TECHNIQUE_VISIBLE_SOLID : TECHNIQUE_VISIBLE_AREA;
        }
        return TECHNIQUE_NONE;
    }
    }
    return TECHNIQUE_NONE;
}

/* The visible target of a pair's technique: the cached one of pair
   `pair_index`, or for a mesh light's member (member_vis set) one made
   into member_vis. */
static const struct target *technique_visible(const struct strategy *s, const struct strategy_point *pt,
                                              const struct strategy_pair *pair, int pair_index, enum region region,
                                              struct target *member_vis)
{
    return member_vis ? strategy_member_visible(s, pt, pair, region, member_vis)
                      : strategy_visible_target(s, pt, pair_index);
}

/* Density of wi under one pair's technique (0 when it cannot produce wi);
   pair_index is -1 for the defensive light-only pair. For a mesh light's
   member, member_vis is room for its visible target (NULL otherwise). */
static double technique_pdf(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                            int pair_index, enum technique t, enum region region, struct target *member_vis,
                            struct vec3 wi)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[pair->light];
    struct vec3 p = pt->p;
    const struct target *vis;
    switch (t) {
    case TECHNIQUE_NONE:
        return 0.0;
    case TECHNIQUE_LIGHT_AREA:
        return target_pdf_area(&l->target, p, wi);
    case TECHNIQUE_LIGHT_SOLID:
        return target_pdf_solid_angle(&l->target, p, wi);
    case TECHNIQUE_PORTAL_AREA:
        return target_pdf_area(sc->portals[pair->portal].target, p, wi);
    case TECHNIQUE_PORTAL_SOLID:
        return target_pdf_solid_angle(sc->portals[pair->portal].target, p, wi);
    case TECHNIQUE_VISIBLE_AREA:
        vis = technique_visible(s, pt, pair, pair_index, region, member_vis);
        return vis ? target_pdf_area(vis, p, wi) : 0.0;
    case TECHNIQUE_VISIBLE_SOLID:
        vis = technique_visible(s, pt, pair, pair_index, region, member_vis);
        return vis ? target_pdf_solid_angle(vis, p, wi) : 0.0;
    }
    return 0.0;
}

static bool technique_sample(const struct strategy *s, const struct strategy_point *pt,
                             const struct strategy_pair *pair, int pair_index, enum technique t, enum region region,
                             struct target *member_vis, const double u[3], struct target_point *tp)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[pair->light];
    struct vec3 p = pt->p;
    const struct target *vis;
    switch (t) {
    case TECHNIQUE_NONE:
        return false;
    case TECHNIQUE_LIGHT_AREA:
        return target_sample_area(&l->target, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_LIGHT_SOLID:
        return target_sample_solid_angle(&l->target, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_PORTAL_AREA:
        return target_sample_area(sc->portals[pair->portal].target, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_PORTAL_SOLID:
        return target_sample_solid_angle(sc->portals[pair->portal].target, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_VISIBLE_AREA:
        vis = technique_visible(s, pt, pair, pair_index, region, member_vis);
        return vis && target_sample_area(vis, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_VISIBLE_SOLID:
        vis = technique_visible(s, pt, pair, pair_index, region, member_vis);
        return vis && target_sample_solid_angle(vis, p, u[0], u[1], u[2], tp);
    }
    return false;
}

static enum region region_of(const struct strategy_point *pt, int pair)
{
    return pt->scratch ? (enum region)pt->scratch->region[pair] : REGION_ANTI_PENUMBRA;
}

/* The region of a mesh light's member pair at the point: its pair's when
   that is REGION_INSIDE or the strategy does not classify, else the
   member's own antishadow's. */
static enum region member_region(const struct strategy *s, const struct strategy_point *pt, int pair_index,
                                 const struct strategy_pair *member)
{
    enum region r = region_of(pt, pair_index);
    /* REGION_ANTI_UMBRA here is mesh_pair_bound's: every triangle's too. */
    if (r == REGION_INSIDE || r == REGION_ANTI_UMBRA || !strategy_kind_classifies(s->kind) || member->portal < 0)
        return r;
    return antishadow_classify(&s->scene->portals[member->portal].antishadow, pt->sided);
}

static double pair_probability(const struct strategy_point *pt, int i)
{
    int k = pt->scratch->cand_pos[i];
    if (k < 0) return 0.0;
    double lo = k > 0 ? pt->scratch->cdf[k - 1] : 0.0;
    return (pt->scratch->cdf[k] - lo) / pt->total;
}

/* Mixture density of wi reaching `light`: the defensive light-sampling
   share plus every pair of that light's emitter that could have produced
   wi (for a mesh light, through its member for that light, picked with the
   light's share of the emitter's power). The density of pair `known` (if
   >= 0) is already known to be known_pdf (the member's pick included),
   and its probability at the point to be known_sel when that is >= 0 (a
   waiting sample's, whose scratch has served other points since). */
static double mixture_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi,
                          int known, double known_pdf, double known_sel)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[light];
    const struct emitter *e = &sc->emitters[l->emitter];
    double pdf = 0.0;
    if (s->defensive > 0.0) pdf += s->defensive * s->power.prob[light] * target_pdf_solid_angle(&l->target, pt->p, wi);
    if (pt->total > 0.0) {
        double mix = 0.0, pick = e->n_lights > 1 ? s->members[l->emitter].prob[light - e->first_light] : 1.0;
        /* sample_at draws nothing for a member culled at pt. */
        bool member_culled = e->n_lights > 1 && light_culled(l, pt->p, pt->n);
        for (int i = s->first_pair[l->emitter]; i < s->first_pair[l->emitter + 1]; ++i) {
            double sel = i == known && known_sel >= 0.0 ? known_sel : pair_probability(pt, i);
            if (sel <= 0.0) continue;
            if (i == known) {
                mix += sel * known_pdf;
                continue;
            }
            if (!strategy_picks_member(s, &s->pairs[i])) {
                enum region r = region_of(pt, i);
                enum technique t = strategy_technique(s, &s->pairs[i], r);
                mix += sel * technique_pdf(s, pt, &s->pairs[i], i, t, r, NULL, wi);
                continue;
            }
            if (member_culled) continue;
            struct strategy_pair m = strategy_member_of(sc, &s->pairs[i], light);
            enum region r = member_region(s, pt, i, &m);
            struct target vis;
            mix += sel * (pick * technique_pdf(s, pt, &m, i, strategy_technique(s, &m, r), r, &vis, wi));
        }
        pdf += (1.0 - s->defensive) * mix;
    }
    return pdf;
}

double strategy_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi)
{
    if (!strategy_kind_uses_portals(s->kind)) {
        if (strategy_light_only_culls(s, light, pt)) return 0.0;
        const struct light *l = &s->scene->lights[light];
        double sel = s->power.prob[light];
        return sel * (s->kind == STRATEGY_LIGHT_AREA ? target_pdf_area(&l->target, pt->p, wi)
                                                     : target_pdf_solid_angle(&l->target, pt->p, wi));
    }
    return mixture_pdf(s, pt, light, wi, -1, 0.0, -1.0);
}

/* First index whose cdf exceeds x (cdf non-decreasing, x < cdf[n-1]). */
static int cdf_find(const double *cdf, int n, double x)
{
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (cdf[mid] > x) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* The light sample from a technique's target point: the light it reaches
   and its density under the whole strategy. `pick` is the probability with
   which the pair's light was picked within its emitter (1 but for a mesh
   light's member); known_sel the pair's probability when known (mixture_pdf),
   else -1. */
void strategy_finish_sample(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                            int index, const struct target_point *tp, double pick, double known_sel,
                            struct light_sample *out)
{
    const struct scene *sc = s->scene;
    /* A light-only strategy samples its lights alone (sample_at's
       light-only pair, portal -1); the rest is the portal strategies'. */
    if (!strategy_kind_uses_portals(s->kind)) {
        strategy_finish_light_only(s, pair->light, tp->wi, tp->dist, tp->pdf_sa, out);
        return;
    }
    out->wi = tp->wi;
    const struct light *l = &sc->lights[pair->light];
    if (pair->portal < 0) {
        out->light = pair->light;
        out->dist = tp->dist;
    } else {
        /* Through the portal: the direction counts only if it goes on to
           meet the light (always, up to rounding, for the exact techniques). */
        double dist;
        if (sc->emitters[pair->emitter].n_lights > 1 && s->kind == STRATEGY_PORTAL) {
            out->light = scene_emitter_hit(sc, pair->emitter, pt->p, tp->wi, &dist);
            out->dist = out->light >= 0 ? dist : 0.0;
        } else if (polygon_intersect_ray(&l->target.polygon, pt->p, tp->wi, &dist)) {
            out->light = pair->light;
            out->dist = dist;
        } else {
            out->light = -1;
            out->dist = 0.0;
        }
    }
    if (out->light < 0) {
        out->pdf_sa = tp->pdf_sa;
        out->radiance = rgb_make(0.0, 0.0, 0.0);
        return;
    }
    out->radiance = light_emitted(&sc->lights[out->light], vec3_neg(tp->wi));
    /* A mixture must add every other way of producing the same direction. */
    if (index >= 0) out->pdf_sa = mixture_pdf(s, pt, out->light, tp->wi, index, pick * tp->pdf_sa, known_sel);
    else out->pdf_sa = mixture_pdf(s, pt, out->light, tp->wi, -1, 0.0, -1.0);
}

/* The target a portal strategy's sample may leave waiting
   (strategy_sample_begin), or NULL: a rectangle sampled by solid angle, of
   a pair that is its emitter's only one, so that the sample's density
   needs no other pair's. The light's own or the portal's outlive the
   point's scratch; a visible part that is a rectangle (a box pair's,
   polygon.c) is copied into pend, which is what the wait costs. */
static const struct target *waiting_target(const struct strategy *s, const struct strategy_point *pt,
                                           const struct strategy_pair *pair, int index, enum technique t,
                                           enum region region, const struct target *member_vis,
                                           struct strategy_pending *pend)
{
    if (index < 0 || member_vis || s->first_pair[pair->emitter + 1] - s->first_pair[pair->emitter] != 1) return NULL;
    const struct target *target = NULL;
    if (t == TECHNIQUE_LIGHT_SOLID) target = &s->scene->lights[pair->light].target;
    else if (t == TECHNIQUE_PORTAL_SOLID) target = s->scene->portals[pair->portal].target;
    else if (t == TECHNIQUE_VISIBLE_SOLID) {
        const struct target *vis = technique_visible(s, pt, pair, index, region, NULL);
        if (!vis || !vis->is_rectangle) return NULL;
        target_copy(&pend->visible, vis);
        return &pend->visible;
    }
    return target && target->is_rectangle ? target : NULL;
}

/* strategy_sample, or with pend set, strategy_sample_begin. */
static bool sample_at(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                      struct light_sample *out, struct strategy_pending *pend)
{
    double u0 = u[0], pick = 1.0;
    struct strategy_pair light_only, member;
    const struct strategy_pair *pair;
    enum technique t;
    enum region region = REGION_ANTI_PENUMBRA;
    struct target member_vis;
    struct target *vis = NULL;
    int index = -1;
    if (pend) pend->waiting = false;

    if (strategy_kind_uses_portals(s->kind) && u0 >= s->defensive) {
        /* Rescale u0 to [0,1) and pick a pair by the point's weights. */
        if (!(pt->total > 0.0)) return false;
        u0 = (u0 - s->defensive) / (1.0 - s->defensive);
        const double *cdf = pt->scratch->cdf;
        int k = cdf_find(cdf, pt->scratch->n_cand, u0 * pt->total);
        index = pt->scratch->cand[k];
        pair = &s->pairs[index];
        region = region_of(pt, index);
        if (strategy_picks_member(s, pair)) {
            /* A triangle by power, with what is left of u0 within the pair. */
            double lo = k > 0 ? cdf[k - 1] : 0.0, um = (u0 * pt->total - lo) / (cdf[k] - lo);
            um = um >= 0.0 ? (um < 1.0 ? um : 0x1.fffffffffffffp-1) : 0.0;
            const struct alias_table *members = &s->members[pair->emitter];
            int m = alias_sample(members, um, NULL);
            pick = members->prob[m];
            member = strategy_member_of(s->scene, pair, s->scene->emitters[pair->emitter].first_light + m);
            /* A triangle that can deliver nothing here (light_culled: most
               often one facing away) is not sampled; mixture_pdf gives it
               no density either. */
            if (light_culled(&s->scene->lights[member.light], pt->p, pt->n)) return false;
            pair = &member;
            region = member_region(s, pt, index, &member);
            vis = &member_vis;
        }
        t = strategy_technique(s, pair, region);
    } else {
        if (strategy_kind_uses_portals(s->kind)) u0 = u0 / s->defensive;
        light_only.light = alias_sample(&s->power, u0, NULL);
        if (strategy_light_only_culls(s, light_only.light, pt)) return false;
        light_only.portal = -1;
        light_only.emitter = s->scene->lights[light_only.light].emitter;
        pair = &light_only;
        t = s->kind == STRATEGY_LIGHT_AREA ? TECHNIQUE_LIGHT_AREA : TECHNIQUE_LIGHT_SOLID;
    }

    if (pend) {
        pend->target = waiting_target(s, pt, pair, index, t, region, vis, pend);
        pend->waiting = pend->target != NULL;
        if (pend->waiting) {
            pend->index = index;
            pend->sel = pair_probability(pt, index);
            return false;
        }
    }
    struct target_point tp;
    if (!technique_sample(s, pt, pair, index, t, region, vis, u + 1, &tp)) return false;
    strategy_finish_sample(s, pt, pair, index, &tp, pick, -1.0, out);
    return true;
}

bool strategy_sample(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                     struct light_sample *out)
{
    return sample_at(s, pt, u, out, NULL);
}

bool strategy_sample_begin(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                           struct light_sample *out, struct strategy_pending *pend)
{
    return sample_at(s, pt, u, out, pend);
}

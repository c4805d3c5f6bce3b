#include "sampling/strategy.h"

#include <stdlib.h>
#include <string.h>

#include "config/config.h"
#include "base/fastmath.h"

/* The antishadow strategies classify; `portal` and `projection` are the
   plain techniques of the paper and must not benefit from classification. */
static bool classifies(enum strategy_kind k)
{
    return k == STRATEGY_ANTISHADOW || k == STRATEGY_ANTISHADOW_EXACT;
}

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
                                         : &sc->portals[first->first_portal + i - e->n_lights].target.polygon;
        for (int v = 0; v < poly->n; ++v) {
            struct vec3 x = poly->v[v];
            b.lo = vec3_make(fmin(b.lo.x, x.x), fmin(b.lo.y, x.y), fmin(b.lo.z, x.z));
            b.hi = vec3_make(fmax(b.hi.x, x.x), fmax(b.hi.y, x.y), fmax(b.hi.z, x.z));
        }
    }
    double grow = vec3_length(vec3_sub(b.hi, b.lo));
    b.lo = vec3_sub(b.lo, vec3_make(grow, grow, grow));
    b.hi = vec3_add(b.hi, vec3_make(grow, grow, grow));
    return b;
}

static struct aabb aabb_union(struct aabb a, struct aabb b)
{
    return (struct aabb){ vec3_make(fmin(a.lo.x, b.lo.x), fmin(a.lo.y, b.lo.y), fmin(a.lo.z, b.lo.z)),
                          vec3_make(fmax(a.hi.x, b.hi.x), fmax(a.hi.y, b.hi.y), fmax(a.hi.z, b.hi.z)) };
}

/* Whether a sample of the pair first picks one of its emitter's lights by
   power: for a mesh light's pairs, but with the plain `portal` strategy,
   which samples the portal and goes on to whichever triangle it meets
   (scene_emitter_hit), as it goes on to the light behind for a polygon. */
static bool picks_member(const struct strategy *s, const struct strategy_pair *pair)
{
    return s->scene->emitters[pair->emitter].n_lights > 1 && s->kind != STRATEGY_PORTAL;
}

/* The member of pair `pair` for light `light` of its emitter: that light with
   the same portal (by position in its range). */
static struct strategy_pair member_of(const struct scene *sc, const struct strategy_pair *pair, int light)
{
    struct strategy_pair m = { light, pair->portal, pair->emitter };
    if (pair->portal >= 0)
        m.portal = sc->lights[light].first_portal + (pair->portal - sc->lights[pair->light].first_portal);
    return m;
}

/* The region each pair can light, as a box: a portal's anti-penumbra (the
   portal plane and the separating planes), a one-sided light's front half
   space, a two-sided light's whole scene; all within the scene's bounds,
   padded so that points on the bounding surfaces stay inside. */
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
            struct strategy_pair m = member_of(sc, pair, e->first_light + k);
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
        const struct polygon *q = &sc->portals[pair->portal].target.polygon;
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
    s->use_bvh = classifies(s->kind);
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

enum { VIS_UNKNOWN, VIS_EMPTY, VIS_POLYGON, VIS_READY };

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

/* The visible part of pair i's light through its portal from the prepared
   point, as a simplified polygon; NULL when nothing is visible. Cached per
   point: a weight needs only this, a sample or a pdf its target. */
static const struct polygon *visible_polygon(const struct strategy *s, const struct strategy_point *pt, int i)
{
    struct strategy_scratch *sc = pt->scratch;
    if (sc->vis_state[i] == VIS_UNKNOWN) {
        const struct strategy_pair *pair = &s->pairs[i];
        struct polygon vis;
        const struct antishadow *a = &s->scene->portals[pair->portal].antishadow;
        /* Once classified, the anti-umbra and anti-antumbra need no clipping
           (and a box rectangle no simplification). */
        bool simple = false;
        int n = classifies(s->kind)
                    ? antishadow_visible_polygon_known(a, pt->p, (enum region)sc->region[i], &vis, &simple)
                    : antishadow_visible_polygon(a, pt->p, &vis);
        bool ok =
            n >= 3 && (simple ? target_init_polygon_simple(&sc->vis[i], &vis) : target_init_polygon(&sc->vis[i], &vis));
        sc->vis_state[i] = ok ? VIS_POLYGON : VIS_EMPTY;
    }
    return sc->vis_state[i] == VIS_EMPTY ? NULL : &sc->vis[i].polygon;
}

/* The same as a target, finished when first asked for: at a point with
   several candidates most are only weighed (its normal, area and
   rectangle frame were a third of the cost of making the target). */
static const struct target *visible_target(const struct strategy *s, const struct strategy_point *pt, int i)
{
    struct strategy_scratch *sc = pt->scratch;
    if (!visible_polygon(s, pt, i)) return NULL;
    if (sc->vis_state[i] == VIS_POLYGON) sc->vis_state[i] = target_finish(&sc->vis[i]) ? VIS_READY : VIS_EMPTY;
    return sc->vis_state[i] == VIS_READY ? &sc->vis[i] : NULL;
}

/* The visible part of a mesh light's member pair (one triangle and the
   portal) from the prepared point, into `storage`; NULL when nothing is
   visible. Not cached: a member is used by one sample or one pdf. */
static const struct target *member_visible(const struct strategy *s, const struct strategy_point *pt,
                                           const struct strategy_pair *member, enum region region,
                                           struct target *storage)
{
    struct polygon vis;
    const struct antishadow *a = &s->scene->portals[member->portal].antishadow;
    int n = classifies(s->kind) ? antishadow_visible_polygon_in(a, pt->p, region, &vis)
                                : antishadow_visible_polygon(a, pt->p, &vis);
    return n >= 3 && target_init(storage, &vis) ? storage : NULL;
}

/* A pair's weight, or with poly set its `irradiance` form left to finish:
   scale times the projected solid angle of poly from the point, so that a
   point's candidates compute those together
   (polygon_projected_solid_angle_many): their edge angles were a third of
   antishadow_exact's time on multi_lamp, one short polygon at a time. */
struct weight_term {
    double value;
    double scale;
    const struct polygon *poly;
};

static struct weight_term weight_value(double value)
{
    return (struct weight_term){ value, 0.0, NULL };
}

/* lum times the projected solid angle (cosine-weighted when n is set) of a
   polygon: the unoccluded irradiance it delivers to p for a radiance of
   luminance lum. The cosine-weighted one is left to finish. */
static struct weight_term irradiance_term(double lum, const struct polygon *poly, struct vec3 p, struct vec3 n)
{
    if (vec3_length2(n) > 0.0) return (struct weight_term){ 0.0, lum, poly };
    return weight_value(lum * polygon_solid_angle(poly, p));
}

/* A weight term finished one at a time. */
static double weight_finish(struct weight_term t, struct vec3 p, struct vec3 n)
{
    return t.poly ? t.scale * polygon_projected_solid_angle(t.poly, p, n) : t.value;
}

/* True when p is inside the emitter's shade: on the light's side of every
   one of its portals' planes and within its shade box. The emitter's pairs
   are its first light's portals, in order, when it has any (strategy_init). */
static bool on_light_side(const struct strategy *s, int emitter, struct vec3 p)
{
    int first = s->first_pair[emitter], end = s->first_pair[emitter + 1];
    if (s->pairs[first].portal < 0) return false;
    for (int k = first; k < end; ++k)
        if (plane_distance(&s->portal_plane[k], p) > 0.0) return false;
    return aabb_contains(&s->shade[emitter], p);
}

/* True when some vertex of poly is strictly above the plane through p with
   normal n (always, when n is zero). */
static bool above_horizon(const struct polygon *poly, struct vec3 p, struct vec3 n)
{
    if (vec3_length2(n) == 0.0) return true;
    for (int i = 0; i < poly->n; ++i)
        if (vec3_dot(n, vec3_sub(poly->v[i], p)) > 0.0) return true;
    return false;
}

/* The solid angle of a planar polygon (area, unit normal, centroid c) from
   p as a small polygon's, area |cos| / d^2 from its centroid, capped at a
   hemisphere: O(1) in its vertices, and close where the polygon is small
   against its distance, which is where most of a room's points see a lamp. */
static double small_solid_angle(const struct target *t, struct vec3 c, struct vec3 p)
{
    struct vec3 d = vec3_sub(c, p);
    double d2 = fm_fmax(vec3_length2(d), 1e-12);
    double sa = t->area * fabs(vec3_dot(d, t->normal)) / (d2 * sqrt(d2));
    return fm_fmin(sa, 2.0 * M_PI);
}

/* The lowest receiver cosine an `irradiance_estimate` uses: the cosine is
   taken at the polygon's centroid, which may lie below the horizon while
   part of the polygon rises above it. Any positive weight keeps the
   estimator unbiased; zero is only for a polygon wholly below. */
#define ESTIMATE_MIN_COSINE 0.05

/* small_solid_angle times the receiver's cosine towards the centroid
   (with n set; clamped below by ESTIMATE_MIN_COSINE), 0 when the polygon
   is wholly below the horizon. */
static double small_projected_solid_angle(const struct target *t, struct vec3 c, struct vec3 p, struct vec3 n)
{
    if (!above_horizon(&t->polygon, p, n)) return 0.0;
    double sa = small_solid_angle(t, c, p);
    if (vec3_length2(n) == 0.0) return sa;
    double cos_r = vec3_dot(n, vec3_normalize(vec3_sub(c, p)));
    return sa * fm_fmax(cos_r, ESTIMATE_MIN_COSINE);
}

/* Weight of a light sampled by itself (no portal): facing test, then the
   heuristic on the light's own polygon. */
static struct weight_term light_weight_term(const struct light *l, enum portal_weight_kind heuristic, struct vec3 p,
                                            struct vec3 n)
{
    struct vec3 to_p = vec3_sub(p, l->target.polygon.v[0]);
    if (!l->two_sided && vec3_dot(to_p, l->target.normal) <= 0.0) return weight_value(0.0);
    switch (heuristic) {
    case PORTAL_WEIGHT_AREA:
        return weight_value(l->power);
    case PORTAL_WEIGHT_DISTANCE: {
        struct vec3 c = polygon_centroid(&l->target.polygon);
        return weight_value(l->power / fm_fmax(vec3_length2(vec3_sub(c, p)), 1e-12));
    }
    case PORTAL_WEIGHT_IRRADIANCE:
        return irradiance_term(rgb_luminance(l->radiance), &l->target.polygon, p, n);
    case PORTAL_WEIGHT_IRRADIANCE_ESTIMATE:
        return weight_value(rgb_luminance(l->radiance) * small_projected_solid_angle(&l->target, l->centroid, p, n));
    }
    return weight_value(0.0);
}

static double light_weight(const struct light *l, enum portal_weight_kind heuristic, struct vec3 p, struct vec3 n)
{
    return weight_finish(light_weight_term(l, heuristic, p, n), p, n);
}

/* light_weight for an emitter. A mesh light's is O(1) in its triangles: its
   power for `area`; power / d^2 from its centroid for `distance`; and for
   `irradiance` power / (pi d^2), the irradiance of a small emitter facing p
   without the cosines (an estimate, not the exact sum over triangles,
   which would make every point's cost linear in the triangles). */
static struct weight_term emitter_weight_term(const struct strategy *s, int emitter, enum portal_weight_kind heuristic,
                                              struct vec3 p, struct vec3 n)
{
    const struct emitter *e = &s->scene->emitters[emitter];
    if (e->n_lights == 1) return light_weight_term(&s->scene->lights[e->first_light], heuristic, p, n);
    double d2 = fm_fmax(vec3_length2(vec3_sub(s->centre[emitter], p)), 1e-12);
    switch (heuristic) {
    case PORTAL_WEIGHT_AREA:
        return weight_value(e->power);
    case PORTAL_WEIGHT_DISTANCE:
        return weight_value(e->power / d2);
    case PORTAL_WEIGHT_IRRADIANCE:
    case PORTAL_WEIGHT_IRRADIANCE_ESTIMATE:
        return weight_value(e->power / (M_PI * d2));
    }
    return weight_value(0.0);
}

static double emitter_weight(const struct strategy *s, int emitter, enum portal_weight_kind heuristic, struct vec3 p,
                             struct vec3 n)
{
    return weight_finish(emitter_weight_term(s, emitter, heuristic, p, n), p, n);
}

/* What the plane through p and the edge from a to b (offsets from p) says
   about a sphere about p + pc of radius^2 r2, with pq towards the portal's
   inside: EDGE_OUTSIDE that it lies wholly outside the plane (so outside
   the portal's antishadow), 0 wholly inside or that the edge says nothing
   (p on its line), 1 that the plane cuts it. The verdicts are summed, and
   sums of these small integers are exact in any order: a sum of at least
   EDGE_OUTSIDE means some edge put the sphere outside. m = a x b as
   vec3_cross forms it, written out: the vectoriser takes no struct
   values. */
#define EDGE_OUTSIDE (2.0 * POLYGON_MAX)

FM_INLINE double edge_verdict(double ax, double ay, double az, double bx, double by, double bz, struct vec3 pc,
                              struct vec3 pq, double r2)
{
    double mx = ay * bz - az * by, my = az * bx - ax * bz, mz = ax * by - ay * bx;
    double len2 = mx * mx + my * my + mz * mz;
    double dc = mx * pc.x + my * pc.y + mz * pc.z;
    double sd = mx * pq.x + my * pq.y + mz * pq.z < 0.0 ? -dc : dc, rl2 = r2 * len2;
    bool beyond = sd * sd >= rl2; /* |d| >= r */
    return !(len2 > 0.0) ? 0.0 : beyond ? (sd <= 0.0 ? EDGE_OUTSIDE : 0.0) : 1.0;
}

/* What the bounding sphere of a mesh light tells of its pair at p (beyond
   the portal's plane): REGION_OUTSIDE when the sphere lies wholly outside
   one edge plane of the portal as seen from p (no triangle can be seen
   through the portal), REGION_ANTI_UMBRA when its cone from p lies inside
   every one (every triangle is seen whole), REGION_ANTI_PENUMBRA when it
   cannot tell. O(portal edges), and it decides everywhere but near the
   anti-penumbra. Every shading point of a portal strategy runs it for each
   of its mesh light's pairs (the Little Lamp: two 32-gons), so the planes
   are not normalised: the centre's signed distance d = s / |m| from the
   plane with normal m is compared with the radius r as s against r |m|,
   squared, with no square root or division (it was 23% of
   antishadow_exact's time there). */
FM_SIMD_CLONES static enum region mesh_pair_bound(const struct strategy *s, int i, struct vec3 p)
{
    const struct strategy_pair *pair = &s->pairs[i];
    const struct portal *pt = &s->scene->portals[pair->portal];
    if (plane_distance(&pt->antishadow.portal_plane, p) <= 0.0) return REGION_OUTSIDE;
    struct vec3 pc = vec3_sub(s->centre[pair->emitter], p), pq = vec3_sub(pt->centroid, p);
    double r2 = s->reach[pair->emitter] * s->reach[pair->emitter];
    const struct portal_outline *o = &s->outline[i];
    const double *x = o->x, *y = o->y, *z = o->z;
    /* Every edge's verdict summed in one vectorised loop over whole SIMD
       blocks, with no early exit: which edge finds p outside does not
       matter, only whether one does. (Over the polygon's vertices, the
       closing edge and the remainder went one by one, and a maximum taken
       after the loop was a chain of dependent scalar steps: together more
       than the vector loop.) */
    double sum = 0.0;
#pragma omp simd reduction(+ : sum)
    for (int k = 0; k < o->n_edges; ++k)
        sum += edge_verdict(x[k] - p.x, y[k] - p.y, z[k] - p.z, x[k + 1] - p.x, y[k + 1] - p.y, z[k + 1] - p.z, pc, pq,
                            r2);
    return sum >= EDGE_OUTSIDE ? REGION_OUTSIDE : sum > 0.0 ? REGION_ANTI_PENUMBRA : REGION_ANTI_UMBRA;
}

/* The region of a mesh light's pair at p, exactly: mesh_pair_bound where
   it decides, else its triangles' common region, the anti-penumbra when
   they differ. */
static enum region mesh_pair_region(const struct strategy *s, int i, struct vec3 p)
{
    const struct strategy_pair *pair = &s->pairs[i];
    enum region bound = mesh_pair_bound(s, i, p);
    if (bound != REGION_ANTI_PENUMBRA) return bound;
    const struct scene *sc = s->scene;
    const struct emitter *e = &sc->emitters[pair->emitter];
    enum region common = REGION_INSIDE; /* none yet */
    for (int k = 0; k < e->n_lights; ++k) {
        struct strategy_pair m = member_of(sc, pair, e->first_light + k);
        enum region r_k = antishadow_classify(&sc->portals[m.portal].antishadow, p);
        if (common == REGION_INSIDE) common = r_k;
        else if (r_k != common) return REGION_ANTI_PENUMBRA;
    }
    return common;
}

/* The `irradiance` weight of a mesh light's portal pair: the radiance
   times the portal's solid angle as a small polygon's (small_solid_angle),
   as if the light filled the portal (pair_weight says why). */
static double mesh_portal_irradiance(const struct strategy *s, const struct strategy_pair *pair, struct vec3 p)
{
    const struct portal *pt = &s->scene->portals[pair->portal];
    return rgb_luminance(s->scene->lights[pair->light].radiance) * small_solid_angle(&pt->target, pt->centroid, p);
}

/* The `irradiance_estimate` weight of a polygon light's portal pair in a
   known region: what the `irradiance` weight computes exactly from the
   clipped visible polygon, estimated in O(1) from the light (anti-umbra:
   all of it is seen), the portal (anti-antumbra: all of it is filled) or
   the smaller of the two (anti-penumbra: the visible part is within both).
   A point then clips and prepares only the pair it samples, instead of
   every candidate: on multi_lamp those were a third of antishadow_exact's
   time. */
static double pair_irradiance_estimate(const struct strategy *s, const struct strategy_pair *pair, enum region region,
                                       struct vec3 p, struct vec3 n)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[pair->light];
    const struct portal *pt = &sc->portals[pair->portal];
    double light =
        region == REGION_ANTI_ANTUMBRA ? INFINITY : small_projected_solid_angle(&l->target, l->centroid, p, n);
    double portal =
        region == REGION_ANTI_UMBRA ? INFINITY : small_projected_solid_angle(&pt->target, pt->centroid, p, n);
    return rgb_luminance(l->radiance) * fm_fmin(light, portal);
}

/* Weight of pair i at the point under the strategy's heuristic; sets the
   pair's region. A mesh light's pair is classified as a whole by its
   bounding sphere (mesh_pair_bound): no weight where no triangle can be
   seen through the portal, and where the sphere cannot tell, its
   triangles are classified one by one when a sample or a pdf picks one. */
static struct weight_term pair_weight(const struct strategy *s, const struct strategy_point *ptp, int i)
{
    const struct scene *sc = s->scene;
    const struct strategy_pair *pair = &s->pairs[i];
    struct vec3 p = ptp->p, n = ptp->n, sided = ptp->sided;
    unsigned char *region = &ptp->scratch->region[i];
    const struct light *l = &sc->lights[pair->light];
    const struct emitter *e = &sc->emitters[pair->emitter];
    bool classify = classifies(s->kind), mesh = e->n_lights > 1;
    /* The plain portal techniques use the seed heuristic (area) and no
       classification, as in the original method. */
    enum portal_weight_kind heuristic = classify ? s->weight : PORTAL_WEIGHT_AREA;
    *region = REGION_ANTI_PENUMBRA;

    if (pair->portal < 0) return emitter_weight_term(s, pair->emitter, heuristic, p, n);

    const struct portal *pt = &sc->portals[pair->portal];
    if (classify) {
        if (on_light_side(s, pair->emitter, sided)) {
            /* Only the light's first pair samples it there, and only if some
               of the light is above the receiver's horizon: the outside of
               the shade and the underside of its opening face away. (A mesh
               light is not tested: its triangles below the horizon only
               waste their samples.) */
            *region = REGION_INSIDE;
            if (pair->portal != l->first_portal || (!mesh && !above_horizon(&l->target.polygon, p, n)))
                return weight_value(0.0);
            return s->n_pairs == 1 ? weight_value(1.0) : emitter_weight_term(s, pair->emitter, heuristic, p, n);
        }
        *region = (unsigned char)(mesh ? mesh_pair_bound(s, i, sided) : antishadow_classify(&pt->antishadow, sided));
        if (*region == REGION_OUTSIDE) return weight_value(0.0);
        /* A lone pair needs no weight beyond "can light p". */
        if (s->n_pairs == 1) return weight_value(1.0);
    }
    switch (heuristic) {
    case PORTAL_WEIGHT_AREA: {
        double sum = 0.0;
        for (int k = 0; k < l->n_portals; ++k) sum += sc->portals[l->first_portal + k].target.area;
        return weight_value(e->power * pt->target.area / sum);
    }
    case PORTAL_WEIGHT_DISTANCE: {
        /* Each portal's share of its light falls off as area / distance^2. */
        double sum = 0.0, mine = 0.0;
        for (int k = 0; k < l->n_portals; ++k) {
            const struct portal *q = &sc->portals[l->first_portal + k];
            double w = q->target.area / fm_fmax(vec3_length2(vec3_sub(q->centroid, p)), 1e-12);
            sum += w;
            if (l->first_portal + k == pair->portal) mine = w;
        }
        return weight_value(sum > 0.0 ? e->power * mine / sum : 0.0);
    }
    case PORTAL_WEIGHT_IRRADIANCE: {
        /* A mesh light: as if the light filled the portal, and with the
           portal's solid angle taken as a small polygon's, area |cos| / d^2
           (capped at a hemisphere), so that the weight is O(1) in the
           portal's vertices too: the exact projected solid angle of a
           32-gon cost more than the sample it weighs (measured on the Little
           Lamp at 16 spp: antishadow_exact 2.4-2.7x the CPU time of light,
           1.3-1.4x with this). */
        if (mesh) return weight_value(mesh_portal_irradiance(s, pair, p));
        const struct polygon *vis = visible_polygon(s, ptp, i);
        return vis ? irradiance_term(rgb_luminance(l->radiance), vis, p, n) : weight_value(0.0);
    }
    case PORTAL_WEIGHT_IRRADIANCE_ESTIMATE:
        if (mesh) return weight_value(mesh_portal_irradiance(s, pair, p));
        return weight_value(pair_irradiance_estimate(s, pair, (enum region) * region, p, n));
    }
    return weight_value(0.0);
}

/* strategy_pair_irradiance for one light/portal pair (a polygon light's
   pair, or one member of a mesh light's). */
static double member_irradiance(const struct strategy *s, const struct strategy_pair *m, struct vec3 p, struct vec3 n,
                                enum region *region)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[m->light];
    if (m->portal < 0) {
        *region = REGION_ANTI_UMBRA; /* nothing stands between p and the light's own polygon */
        return light_weight(l, PORTAL_WEIGHT_IRRADIANCE, p, n);
    }
    /* The same cases as pair_weight's, in the same order, minus its lone-pair
       shortcut (weight 1): a caller comparing pairs needs the irradiance. */
    struct vec3 sided = strategy_sided_point(s, p, n);
    if (on_light_side(s, m->emitter, sided)) {
        *region = REGION_INSIDE;
        if (m->portal != l->first_portal || !above_horizon(&l->target.polygon, p, n)) return 0.0;
        return light_weight(l, PORTAL_WEIGHT_IRRADIANCE, p, n);
    }
    const struct antishadow *a = &sc->portals[m->portal].antishadow;
    enum region r = antishadow_classify(a, sided);
    *region = r;
    if (r == REGION_OUTSIDE) return 0.0;
    struct polygon vis;
    if (antishadow_visible_polygon_in(a, p, r, &vis) < 3) return 0.0;
    return weight_finish(irradiance_term(rgb_luminance(l->radiance), &vis, p, n), p, n);
}

/* A mesh light's pair: its region (mesh_pair_region, or REGION_INSIDE) and
   the O(1) estimate of its irradiance that its sampling weight uses
   (pair_weight's `irradiance` case): the region AOV needs the region
   exactly and only a ranking of the pairs. */
double strategy_pair_irradiance(const struct strategy *s, int i, struct vec3 p, struct vec3 n, enum region *region)
{
    const struct strategy_pair *pair = &s->pairs[i];
    const struct emitter *e = &s->scene->emitters[pair->emitter];
    if (e->n_lights == 1) return member_irradiance(s, pair, p, n, region);
    if (pair->portal < 0) {
        *region = REGION_ANTI_UMBRA;
        return emitter_weight(s, pair->emitter, PORTAL_WEIGHT_IRRADIANCE, p, n);
    }
    const struct light *l = &s->scene->lights[pair->light];
    struct vec3 sided = strategy_sided_point(s, p, n);
    if (on_light_side(s, pair->emitter, sided)) {
        *region = REGION_INSIDE;
        return pair->portal == l->first_portal ? emitter_weight(s, pair->emitter, PORTAL_WEIGHT_IRRADIANCE, p, n) : 0.0;
    }
    *region = mesh_pair_region(s, i, sided);
    return *region == REGION_OUTSIDE ? 0.0 : mesh_portal_irradiance(s, pair, p);
}

int strategy_candidates(const struct strategy *s, struct vec3 p, int *out)
{
    if (s->use_bvh) return pair_bvh_query(&s->bvh, p, out);
    for (int i = 0; i < s->n_pairs; ++i) out[i] = i;
    return s->n_pairs;
}

/* Whether exactly one of the n weights (or scales of weights left to
   finish) is positive. */
static bool single_live(const double *w, int n)
{
    int live = 0;
    for (int k = 0; k < n; ++k) live += w[k] > 0.0;
    return live == 1;
}

/* Whether emitter e can deliver nothing to p (strategy_point_unlit). */
static bool emitter_culled(const struct strategy *s, int e, struct vec3 p, struct vec3 n)
{
    const struct scene *sc = s->scene;
    const struct emitter *em = &sc->emitters[e];
    if (em->n_lights == 1) return light_culled(&sc->lights[em->first_light], p, n);
    /* A mesh light: every point of it lies within reach of centre. */
    struct vec3 d = vec3_sub(s->centre[e], p);
    return vec3_dot(n, n) > 0.0 && light_clearly_below(vec3_dot(d, n) + s->reach[e], d);
}

bool strategy_point_unlit(const struct strategy *s, struct vec3 p, struct vec3 n, int *hint)
{
    int count = s->scene->n_emitters;
    if (count == 0) return true;
    if (count > STRATEGY_UNLIT_MAX_EMITTERS) return false;
    int first = *hint >= 0 && *hint < count ? *hint : 0, e = first;
    do {
        if (!emitter_culled(s, e, p, n)) {
            *hint = e;
            return false;
        }
        e = e + 1 < count ? e + 1 : 0;
    } while (e != first);
    return true;
}

struct vec3 strategy_sided_point(const struct strategy *s, struct vec3 p, struct vec3 n)
{
    return vec3_madd(p, n, scene_offset_height(s->scene, p));
}

void strategy_prepare_pairs(const struct strategy *s, struct strategy_point *pt, struct vec3 p, struct vec3 n)
{
    struct strategy_scratch *scratch = pt->scratch;
    pt->sided = strategy_sided_point(s, p, n);
    /* Forget the previous point's candidates (only those were touched). */
    for (int k = 0; k < scratch->n_cand; ++k) {
        scratch->cand_pos[scratch->cand[k]] = -1;
        scratch->vis_state[scratch->cand[k]] = VIS_UNKNOWN;
    }
    scratch->n_cand = strategy_candidates(s, pt->sided, scratch->cand);
    /* cdf holds each candidate's weight first, or the scale of a weight
       left to finish; those finish together. */
    int n_defer = 0;
    for (int k = 0; k < scratch->n_cand; ++k) {
        int i = scratch->cand[k];
        scratch->cand_pos[i] = k;
        struct weight_term t = pair_weight(s, pt, i);
        if (t.poly) {
            scratch->defer_poly[n_defer] = t.poly;
            scratch->defer_cand[n_defer++] = k;
            scratch->cdf[k] = t.scale;
        } else {
            scratch->cdf[k] = t.value;
        }
    }
    /* A weight only matters against others: a point with one candidate
       that can have weight picks it with probability 1 whatever the
       weight, so its projected solid angle (the costly part: horizon clip
       and an angle per edge) is left out. Only whether it is zero counts:
       it is where no vertex of the polygon rises above the horizon (the
       normal is not zero: irradiance_term defers only then). */
    if (n_defer == 1 && single_live(scratch->cdf, scratch->n_cand)) {
        if (!above_horizon(scratch->defer_poly[0], p, n)) scratch->cdf[scratch->defer_cand[0]] = 0.0;
        n_defer = 0;
    }
    if (n_defer > 0) {
        polygon_projected_solid_angle_many(scratch->defer_poly, n_defer, p, n, scratch->defer_value);
        for (int j = 0; j < n_defer; ++j) scratch->cdf[scratch->defer_cand[j]] *= scratch->defer_value[j];
    }
    double acc = 0.0;
    for (int k = 0; k < scratch->n_cand; ++k) {
        double w = scratch->cdf[k];
        if (!(w > 0.0) || !isfinite(w)) w = 0.0;
        acc += w;
        scratch->cdf[k] = acc;
    }
    pt->total = acc;
}

/* The visible target of a pair's technique: the cached one of pair
   `pair_index`, or for a mesh light's member (member_vis set) one made
   into member_vis. */
static const struct target *technique_visible(const struct strategy *s, const struct strategy_point *pt,
                                              const struct strategy_pair *pair, int pair_index, enum region region,
                                              struct target *member_vis)
{
    return member_vis ? member_visible(s, pt, pair, region, member_vis) : visible_target(s, pt, pair_index);
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
        return target_pdf_area(&sc->portals[pair->portal].target, p, wi);
    case TECHNIQUE_PORTAL_SOLID:
        return target_pdf_solid_angle(&sc->portals[pair->portal].target, p, wi);
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
        return target_sample_area(&sc->portals[pair->portal].target, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_PORTAL_SOLID:
        return target_sample_solid_angle(&sc->portals[pair->portal].target, p, u[0], u[1], u[2], tp);
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
    if (r == REGION_INSIDE || r == REGION_ANTI_UMBRA || !classifies(s->kind) || member->portal < 0) return r;
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
            if (!picks_member(s, &s->pairs[i])) {
                enum region r = region_of(pt, i);
                enum technique t = strategy_technique(s, &s->pairs[i], r);
                mix += sel * technique_pdf(s, pt, &s->pairs[i], i, t, r, NULL, wi);
                continue;
            }
            if (member_culled) continue;
            struct strategy_pair m = member_of(sc, &s->pairs[i], light);
            enum region r = member_region(s, pt, i, &m);
            struct target vis;
            mix += sel * (pick * technique_pdf(s, pt, &m, i, strategy_technique(s, &m, r), r, &vis, wi));
        }
        pdf += (1.0 - s->defensive) * mix;
    }
    return pdf;
}

/* Whether a light-only strategy (light, light_area) draws nothing at pt
   when it picks `light` (light_culled): no sample, and a density of zero
   in every direction towards it. The portal strategies' defensive light
   sampling is left as it was (their densities are mixtures). */
static inline bool light_only_culls(const struct strategy *s, int light, const struct strategy_point *pt)
{
    return !strategy_kind_uses_portals(s->kind) && light_culled(&s->scene->lights[light], pt->p, pt->n);
}

double strategy_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi)
{
    if (!strategy_kind_uses_portals(s->kind)) {
        if (light_only_culls(s, light, pt)) return 0.0;
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

/* finish_sample for a light-only strategy (light, light_area): the light
   sampled was picked by power with probability power.prob[light] and the
   direction wi, at distance dist, with density pdf_sa on it. */
static inline void finish_light_only(const struct strategy *s, int light, struct vec3 wi, double dist, double pdf_sa,
                                     struct light_sample *out)
{
    out->wi = wi;
    out->light = light;
    out->dist = dist;
    out->radiance = light_emitted(&s->scene->lights[light], vec3_neg(wi));
    out->pdf_sa = s->power.prob[light] * pdf_sa;
}

/* The light sample from a technique's target point: the light it reaches
   and its density under the whole strategy. `pick` is the probability with
   which the pair's light was picked within its emitter (1 but for a mesh
   light's member); known_sel the pair's probability when known (mixture_pdf),
   else -1. */
static void finish_sample(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                          int index, const struct target_point *tp, double pick, double known_sel,
                          struct light_sample *out)
{
    const struct scene *sc = s->scene;
    /* A light-only strategy samples its lights alone (sample_at's
       light-only pair, portal -1); the rest is the portal strategies'. */
    if (!strategy_kind_uses_portals(s->kind)) {
        finish_light_only(s, pair->light, tp->wi, tp->dist, tp->pdf_sa, out);
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
    else if (t == TECHNIQUE_PORTAL_SOLID) target = &s->scene->portals[pair->portal].target;
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
        if (picks_member(s, pair)) {
            /* A triangle by power, with what is left of u0 within the pair. */
            double lo = k > 0 ? cdf[k - 1] : 0.0, um = (u0 * pt->total - lo) / (cdf[k] - lo);
            um = um >= 0.0 ? (um < 1.0 ? um : 0x1.fffffffffffffp-1) : 0.0;
            const struct alias_table *members = &s->members[pair->emitter];
            int m = alias_sample(members, um, NULL);
            pick = members->prob[m];
            member = member_of(s->scene, pair, s->scene->emitters[pair->emitter].first_light + m);
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
        if (light_only_culls(s, light_only.light, pt)) return false;
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
    finish_sample(s, pt, pair, index, &tp, pick, -1.0, out);
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

/* Points per batch (stack arrays, no allocation). */
#define STRATEGY_MANY_CHUNK 64

void strategy_sample_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4], int n,
                          struct light_sample *out, bool *ok)
{
    if (s->kind != STRATEGY_LIGHT) {
        for (int i = 0; i < n; ++i) ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
        return;
    }
    /* strategy_sample's light-only branch, lane by lane: the light by
       power, then target_sample_solid_angle. The lanes it samples as
       spherical rectangles go to sphrect_sample_many together and are
       finished here; the others (and the rectangle lanes that area
       sampling must take) go the one-point way, which takes the same
       decisions from the same numbers. */
    for (int b = 0; b < n; b += STRATEGY_MANY_CHUNK) {
        int m = n - b < STRATEGY_MANY_CHUNK ? n - b : STRATEGY_MANY_CHUNK, lanes = 0;
        const struct sphrect_frame *frames[STRATEGY_MANY_CHUNK];
        struct vec3 o[STRATEGY_MANY_CHUNK], wi[STRATEGY_MANY_CHUNK];
        double uu[STRATEGY_MANY_CHUNK], vv[STRATEGY_MANY_CHUNK], dist[STRATEGY_MANY_CHUNK], omega[STRATEGY_MANY_CHUNK];
        int lane_of[STRATEGY_MANY_CHUNK], light_of[STRATEGY_MANY_CHUNK];
        for (int i = b; i < b + m; ++i) {
            int light = alias_sample(&s->power, u[i][0], NULL);
            const struct target *t = &s->scene->lights[light].target;
            /* strategy_sample culls as sample_at does; the rectangle lanes
               are culled here, once. */
            if (!target_rect_lane(t, pts[i].p)) {
                ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
                continue;
            }
            if (light_only_culls(s, light, &pts[i])) {
                ok[i] = false;
                continue;
            }
            frames[lanes] = &t->frame;
            o[lanes] = pts[i].p;
            uu[lanes] = u[i][2];
            vv[lanes] = u[i][3];
            light_of[lanes] = light;
            lane_of[lanes++] = i;
        }
        sphrect_sample_many(frames, o, uu, vv, lanes, wi, dist, omega);
        for (int k = 0; k < lanes; ++k) {
            int i = lane_of[k];
            bool by_area;
            double pdf = target_rect_lane_pdf(omega[k], dist[k], &by_area);
            if (by_area) {
                ok[i] = strategy_sample(s, &pts[i], u[i], &out[i]);
                continue;
            }
            ok[i] = pdf > 0.0;
            if (ok[i]) finish_light_only(s, light_of[k], wi[k], dist[k], pdf, &out[i]);
        }
    }
}

void strategy_sample_finish_many(const struct strategy *s, const struct strategy_point *pts, const double (*u)[4],
                                 const struct strategy_pending *pend, int n, struct light_sample *out, bool *ok)
{
    for (int b = 0; b < n; b += STRATEGY_MANY_CHUNK) {
        int end = n - b < STRATEGY_MANY_CHUNK ? n : b + STRATEGY_MANY_CHUNK, m = 0;
        const struct target *t[STRATEGY_MANY_CHUNK];
        struct vec3 p[STRATEGY_MANY_CHUNK];
        double uu[STRATEGY_MANY_CHUNK][3];
        int lane[STRATEGY_MANY_CHUNK];
        struct target_point tp[STRATEGY_MANY_CHUNK];
        bool got[STRATEGY_MANY_CHUNK];
        for (int i = b; i < end; ++i) {
            if (!pend[i].waiting) continue;
            /* strategy_sample's technique_sample: the same target, point
               and uniforms. */
            t[m] = pend[i].target;
            p[m] = pts[i].p;
            for (int j = 0; j < 3; ++j) uu[m][j] = u[i][j + 1];
            lane[m++] = i;
        }
        target_sample_solid_angle_many(t, p, (const double(*)[3])uu, m, tp, got);
        for (int k = 0; k < m; ++k) {
            int i = lane[k];
            ok[i] = got[k];
            if (got[k])
                finish_sample(s, &pts[i], &s->pairs[pend[i].index], pend[i].index, &tp[k], 1.0, pend[i].sel, &out[i]);
        }
    }
}

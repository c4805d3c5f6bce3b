#include "strategy.h"

#include <stdlib.h>
#include <string.h>

#include "config.h"

/* The antishadow strategies classify; `portal` and `projection` are the
   plain techniques of the paper and must not benefit from classification. */
static bool classifies(enum strategy_kind k)
{
    return k == STRATEGY_ANTISHADOW || k == STRATEGY_ANTISHADOW_EXACT;
}

/* The box in which a light with portals counts a point as inside its shade:
   the bounding box of the light and its portals, grown on every side by its
   own diagonal. A shade wraps its lamp closely; without a bound, every
   point between the portal and light planes of a lamp (the outside of other
   shades, walls at that height) would sample that lamp through its shade. */
static struct aabb shade_box(const struct scene *sc, const struct light *l)
{
    struct aabb b = { vec3_make(INFINITY, INFINITY, INFINITY), vec3_make(-INFINITY, -INFINITY, -INFINITY) };
    const struct polygon *polys[1 + 64];
    int n = 0;
    polys[n++] = &l->target.polygon;
    for (int k = l->first_portal; k < l->first_portal + l->n_portals && n < 65; ++k)
        polys[n++] = &sc->portals[k].target.polygon;
    for (int i = 0; i < n; ++i)
        for (int v = 0; v < polys[i]->n; ++v) {
            struct vec3 x = polys[i]->v[v];
            b.lo = vec3_make(fmin(b.lo.x, x.x), fmin(b.lo.y, x.y), fmin(b.lo.z, x.z));
            b.hi = vec3_make(fmax(b.hi.x, x.x), fmax(b.hi.y, x.y), fmax(b.hi.z, x.z));
        }
    double grow = vec3_length(vec3_sub(b.hi, b.lo));
    b.lo = vec3_sub(b.lo, vec3_make(grow, grow, grow));
    b.hi = vec3_add(b.hi, vec3_make(grow, grow, grow));
    return b;
}

/* The region each pair can light, as a box: a portal's anti-penumbra (the
   portal plane and the separating planes), a one-sided light's front half
   space, a two-sided light's whole scene; all within the scene's bounds,
   padded so that points on the bounding surfaces stay inside. */
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
        struct plane planes[1 + ANTISHADOW_SEPARATING_MAX];
        int n = 0;
        if (pair->portal >= 0) {
            const struct antishadow *a = &sc->portals[pair->portal].antishadow;
            planes[n++] = a->portal_plane;
            for (int k = 0; k < a->n_separating; ++k) planes[n++] = a->separating[k];
        } else if (!sc->lights[pair->light].two_sided) {
            const struct target *t = &sc->lights[pair->light].target;
            planes[n++] = (struct plane){ t->normal, vec3_dot(t->normal, t->polygon.v[0]) };
        }
        struct aabb box = { vec3_make(INFINITY, INFINITY, INFINITY), vec3_make(-INFINITY, -INFINITY, -INFINITY) };
        bool any = aabb_of_region(planes, n, scene_box, &box);
        const struct light *l = &sc->lights[pair->light];
        if (pair->portal >= 0 && pair->portal == l->first_portal) {
            /* The first pair also lights the light's side of all its portals. */
            struct plane side[POLYGON_INPUT_MAX + 1];
            int m = 0;
            for (int k = l->first_portal; k < l->first_portal + l->n_portals && m < POLYGON_INPUT_MAX; ++k) {
                struct plane q = sc->portals[k].antishadow.portal_plane;
                side[m++] = (struct plane){ vec3_neg(q.normal), -q.offset };
            }
            if (!l->two_sided)
                side[m++] = (struct plane){ l->target.normal, vec3_dot(l->target.normal, l->target.polygon.v[0]) };
            struct aabb inside, shade = s->shade[pair->light];
            shade.lo = vec3_make(fmax(shade.lo.x, scene_box.lo.x), fmax(shade.lo.y, scene_box.lo.y),
                                 fmax(shade.lo.z, scene_box.lo.z));
            shade.hi = vec3_make(fmin(shade.hi.x, scene_box.hi.x), fmin(shade.hi.y, scene_box.hi.y),
                                 fmin(shade.hi.z, scene_box.hi.z));
            if (aabb_of_region(side, m, shade, &inside)) {
                box = any ? (struct aabb){ vec3_make(fmin(box.lo.x, inside.lo.x), fmin(box.lo.y, inside.lo.y),
                                                     fmin(box.lo.z, inside.lo.z)),
                                           vec3_make(fmax(box.hi.x, inside.hi.x), fmax(box.hi.y, inside.hi.y),
                                                     fmax(box.hi.z, inside.hi.z)) }
                          : inside;
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

bool strategy_init(struct strategy *s, const struct scene *scene, const struct render_desc *rd, struct error *err)
{
    s->kind = rd->strategy;
    s->weight = rd->portal_weight;
    s->defensive = strategy_kind_uses_portals(rd->strategy) ? rd->defensive : 0.0;
    s->scene = scene;
    s->pairs = NULL;
    s->first_pair = NULL;
    s->n_pairs = 0;
    s->use_bvh = false;
    s->shade = NULL;
    s->bvh = (struct pair_bvh){ 0, NULL, NULL, NULL };
    double *power = malloc(sizeof *power * (size_t)scene->n_lights);
    if (!power) return error_set(err, "out of memory for %d lights", scene->n_lights);
    for (int i = 0; i < scene->n_lights; ++i) power[i] = scene->lights[i].power;
    bool ok = alias_build(&s->power, power, scene->n_lights, err);
    free(power);
    if (!ok) return false;

    int n = 0;
    for (int i = 0; i < scene->n_lights; ++i) {
        int np = strategy_kind_uses_portals(s->kind) ? scene->lights[i].n_portals : 0;
        n += np > 0 ? np : 1;
    }
    s->pairs = malloc(sizeof *s->pairs * (size_t)n);
    s->first_pair = malloc(sizeof *s->first_pair * (size_t)(scene->n_lights + 1));
    if (!s->pairs || !s->first_pair) {
        strategy_free(s);
        return error_set(err, "out of memory for %d light/portal pairs", n);
    }
    for (int i = 0; i < scene->n_lights; ++i) {
        const struct light *l = &scene->lights[i];
        s->first_pair[i] = s->n_pairs;
        if (strategy_kind_uses_portals(s->kind) && l->n_portals > 0) {
            for (int k = 0; k < l->n_portals; ++k)
                s->pairs[s->n_pairs++] = (struct strategy_pair){ i, l->first_portal + k };
        } else {
            s->pairs[s->n_pairs++] = (struct strategy_pair){ i, -1 };
        }
    }
    s->first_pair[scene->n_lights] = s->n_pairs;
    s->shade = malloc(sizeof *s->shade * (size_t)(scene->n_lights > 0 ? scene->n_lights : 1));
    if (!s->shade) {
        strategy_free(s);
        return error_set(err, "out of memory for %d lights", scene->n_lights);
    }
    for (int i = 0; i < scene->n_lights; ++i) s->shade[i] = shade_box(scene, &scene->lights[i]);
    s->use_bvh = classifies(s->kind);
    return s->use_bvh ? build_bvh(s, err) : true;
}

void strategy_free(struct strategy *s)
{
    alias_free(&s->power);
    pair_bvh_free(&s->bvh);
    free(s->shade);
    s->shade = NULL;
    free(s->pairs);
    free(s->first_pair);
    s->pairs = NULL;
    s->first_pair = NULL;
    s->n_pairs = 0;
    s->use_bvh = false;
    s->bvh = (struct pair_bvh){ 0, NULL, NULL, NULL };
}

enum { VIS_UNKNOWN, VIS_EMPTY, VIS_READY };

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
    if (!scratch->cand || !scratch->cand_pos || !scratch->cdf || !scratch->region || !scratch->vis_state ||
        !scratch->vis) {
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
   point, as a target; NULL when nothing is visible. Cached per point. */
static const struct target *visible_target(const struct strategy *s, const struct strategy_point *pt, int i)
{
    struct strategy_scratch *sc = pt->scratch;
    if (sc->vis_state[i] == VIS_UNKNOWN) {
        const struct strategy_pair *pair = &s->pairs[i];
        struct polygon vis;
        const struct antishadow *a = &s->scene->portals[pair->portal].antishadow;
        /* Once classified, the anti-umbra and anti-antumbra need no clipping. */
        int n = classifies(s->kind) ? antishadow_visible_polygon_in(a, pt->p, (enum region)sc->region[i], &vis)
                                    : antishadow_visible_polygon(a, pt->p, &vis);
        bool ok = n >= 3 && target_init(&sc->vis[i], &vis);
        sc->vis_state[i] = ok ? VIS_READY : VIS_EMPTY;
    }
    return sc->vis_state[i] == VIS_READY ? &sc->vis[i] : NULL;
}

/* Projected solid angle (cosine-weighted when n is set) of a polygon: the
   unoccluded irradiance per unit radiance it delivers to p. */
static double irradiance_factor(const struct polygon *poly, struct vec3 p, struct vec3 n)
{
    if (vec3_length2(n) > 0.0) return polygon_projected_solid_angle(poly, p, n);
    return polygon_solid_angle(poly, p);
}

/* True when p is inside the light's shade: on the light's side of every one
   of its portals' planes and within its shade box. */
static bool on_light_side(const struct strategy *s, const struct light *l, struct vec3 p)
{
    const struct scene *sc = s->scene;
    if (l->n_portals == 0) return false;
    for (int k = l->first_portal; k < l->first_portal + l->n_portals; ++k)
        if (plane_distance(&sc->portals[k].antishadow.portal_plane, p) > 0.0) return false;
    return aabb_contains(&s->shade[l - sc->lights], p);
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

/* Weight of a light sampled by itself (no portal): facing test, then the
   heuristic on the light's own polygon. */
static double light_weight(const struct light *l, enum portal_weight_kind heuristic, struct vec3 p, struct vec3 n)
{
    struct vec3 to_p = vec3_sub(p, l->target.polygon.v[0]);
    if (!l->two_sided && vec3_dot(to_p, l->target.normal) <= 0.0) return 0.0;
    switch (heuristic) {
    case PORTAL_WEIGHT_AREA:
        return l->power;
    case PORTAL_WEIGHT_DISTANCE: {
        struct vec3 c = polygon_centroid(&l->target.polygon);
        return l->power / fmax(vec3_length2(vec3_sub(c, p)), 1e-12);
    }
    case PORTAL_WEIGHT_IRRADIANCE:
        return rgb_luminance(l->radiance) * irradiance_factor(&l->target.polygon, p, n);
    }
    return 0.0;
}

/* Weight of pair i at the point under the strategy's heuristic; sets the
   pair's region. */
static double pair_weight(const struct strategy *s, const struct strategy_point *ptp, int i)
{
    const struct scene *sc = s->scene;
    const struct strategy_pair *pair = &s->pairs[i];
    struct vec3 p = ptp->p, n = ptp->n;
    unsigned char *region = &ptp->scratch->region[i];
    const struct light *l = &sc->lights[pair->light];
    bool classify = classifies(s->kind);
    /* The plain portal techniques use the seed heuristic (area) and no
       classification, as in the original method. */
    enum portal_weight_kind heuristic = classify ? s->weight : PORTAL_WEIGHT_AREA;
    *region = REGION_ANTI_PENUMBRA;

    if (pair->portal < 0) return light_weight(l, heuristic, p, n);

    const struct portal *pt = &sc->portals[pair->portal];
    if (classify) {
        if (on_light_side(s, l, p)) {
            /* Only the light's first pair samples it there, and only if some
               of the light is above the receiver's horizon: the outside of
               the shade and the underside of its opening face away. */
            *region = REGION_INSIDE;
            if (pair->portal != l->first_portal || !above_horizon(&l->target.polygon, p, n)) return 0.0;
            return s->n_pairs == 1 ? 1.0 : light_weight(l, heuristic, p, n);
        }
        *region = (unsigned char)antishadow_classify(&pt->antishadow, p);
        if (*region == REGION_OUTSIDE) return 0.0;
        /* A lone pair needs no weight beyond "can light p". */
        if (s->n_pairs == 1) return 1.0;
    }
    switch (heuristic) {
    case PORTAL_WEIGHT_AREA: {
        double sum = 0.0;
        for (int k = 0; k < l->n_portals; ++k) sum += sc->portals[l->first_portal + k].target.area;
        return l->power * pt->target.area / sum;
    }
    case PORTAL_WEIGHT_DISTANCE: {
        /* Each portal's share of its light falls off as area / distance^2. */
        double sum = 0.0, mine = 0.0;
        for (int k = 0; k < l->n_portals; ++k) {
            const struct portal *q = &sc->portals[l->first_portal + k];
            double w = q->target.area / fmax(vec3_length2(vec3_sub(q->centroid, p)), 1e-12);
            sum += w;
            if (l->first_portal + k == pair->portal) mine = w;
        }
        return sum > 0.0 ? l->power * mine / sum : 0.0;
    }
    case PORTAL_WEIGHT_IRRADIANCE: {
        const struct target *vis = visible_target(s, ptp, i);
        return vis ? rgb_luminance(l->radiance) * irradiance_factor(&vis->polygon, p, n) : 0.0;
    }
    }
    return 0.0;
}

double strategy_pair_irradiance(const struct strategy *s, int i, struct vec3 p, struct vec3 n, enum region *region)
{
    const struct scene *sc = s->scene;
    const struct strategy_pair *pair = &s->pairs[i];
    const struct light *l = &sc->lights[pair->light];
    if (pair->portal < 0) {
        *region = REGION_ANTI_UMBRA; /* nothing stands between p and the light's own polygon */
        return light_weight(l, PORTAL_WEIGHT_IRRADIANCE, p, n);
    }
    /* The same cases as pair_weight's, in the same order, minus its lone-pair
       shortcut (weight 1): a caller comparing pairs needs the irradiance. */
    if (on_light_side(s, l, p)) {
        *region = REGION_INSIDE;
        if (pair->portal != l->first_portal || !above_horizon(&l->target.polygon, p, n)) return 0.0;
        return light_weight(l, PORTAL_WEIGHT_IRRADIANCE, p, n);
    }
    const struct antishadow *a = &sc->portals[pair->portal].antishadow;
    enum region r = antishadow_classify(a, p);
    *region = r;
    if (r == REGION_OUTSIDE) return 0.0;
    struct polygon vis;
    if (antishadow_visible_polygon_in(a, p, r, &vis) < 3) return 0.0;
    return rgb_luminance(l->radiance) * irradiance_factor(&vis, p, n);
}

int strategy_candidates(const struct strategy *s, struct vec3 p, int *out)
{
    if (s->use_bvh) return pair_bvh_query(&s->bvh, p, out);
    for (int i = 0; i < s->n_pairs; ++i) out[i] = i;
    return s->n_pairs;
}

void strategy_prepare_pairs(const struct strategy *s, struct strategy_point *pt)
{
    struct strategy_scratch *scratch = pt->scratch;
    struct vec3 p = pt->p;
    /* Forget the previous point's candidates (only those were touched). */
    for (int k = 0; k < scratch->n_cand; ++k) {
        scratch->cand_pos[scratch->cand[k]] = -1;
        scratch->vis_state[scratch->cand[k]] = VIS_UNKNOWN;
    }
    scratch->n_cand = strategy_candidates(s, p, scratch->cand);
    double acc = 0.0;
    for (int k = 0; k < scratch->n_cand; ++k) {
        int i = scratch->cand[k];
        scratch->cand_pos[i] = k;
        double w = pair_weight(s, pt, i);
        if (!(w > 0.0) || !isfinite(w)) w = 0.0;
        acc += w;
        scratch->cdf[k] = acc;
    }
    pt->total = acc;
}

/* Density of wi under one pair's technique (0 when it cannot produce wi);
   pair_index is -1 for the defensive light-only pair. */
static double technique_pdf(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                            int pair_index, enum technique t, struct vec3 wi)
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
        vis = visible_target(s, pt, pair_index);
        return vis ? target_pdf_area(vis, p, wi) : 0.0;
    case TECHNIQUE_VISIBLE_SOLID:
        vis = visible_target(s, pt, pair_index);
        return vis ? target_pdf_solid_angle(vis, p, wi) : 0.0;
    }
    return 0.0;
}

static bool technique_sample(const struct strategy *s, const struct strategy_point *pt,
                             const struct strategy_pair *pair, int pair_index, enum technique t, const double u[3],
                             struct target_point *tp)
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
        vis = visible_target(s, pt, pair_index);
        return vis && target_sample_area(vis, p, u[0], u[1], u[2], tp);
    case TECHNIQUE_VISIBLE_SOLID:
        vis = visible_target(s, pt, pair_index);
        return vis && target_sample_solid_angle(vis, p, u[0], u[1], u[2], tp);
    }
    return false;
}

static enum region region_of(const struct strategy_point *pt, int pair)
{
    return pt->scratch ? (enum region)pt->scratch->region[pair] : REGION_ANTI_PENUMBRA;
}

static double pair_probability(const struct strategy_point *pt, int i)
{
    int k = pt->scratch->cand_pos[i];
    if (k < 0) return 0.0;
    double lo = k > 0 ? pt->scratch->cdf[k - 1] : 0.0;
    return (pt->scratch->cdf[k] - lo) / pt->total;
}

/* Mixture density of wi reaching `light`: the defensive light-sampling
   share plus every pair of that light that could have produced wi. The
   density of pair `known` (if >= 0) is already known to be known_pdf. */
static double mixture_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi,
                          int known, double known_pdf)
{
    const struct light *l = &s->scene->lights[light];
    double pdf = 0.0;
    if (s->defensive > 0.0) pdf += s->defensive * s->power.prob[light] * target_pdf_solid_angle(&l->target, pt->p, wi);
    if (pt->total > 0.0) {
        double mix = 0.0;
        for (int i = s->first_pair[light]; i < s->first_pair[light + 1]; ++i) {
            double sel = pair_probability(pt, i);
            if (sel <= 0.0) continue;
            if (i == known) {
                mix += sel * known_pdf;
                continue;
            }
            enum technique t = strategy_technique(s, &s->pairs[i], region_of(pt, i));
            mix += sel * technique_pdf(s, pt, &s->pairs[i], i, t, wi);
        }
        pdf += (1.0 - s->defensive) * mix;
    }
    return pdf;
}

double strategy_pdf(const struct strategy *s, const struct strategy_point *pt, int light, struct vec3 wi)
{
    if (!strategy_kind_uses_portals(s->kind)) {
        const struct light *l = &s->scene->lights[light];
        double sel = s->power.prob[light];
        return sel * (s->kind == STRATEGY_LIGHT_AREA ? target_pdf_area(&l->target, pt->p, wi)
                                                     : target_pdf_solid_angle(&l->target, pt->p, wi));
    }
    return mixture_pdf(s, pt, light, wi, -1, 0.0);
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
   and its density under the whole strategy. */
static void finish_sample(const struct strategy *s, const struct strategy_point *pt, const struct strategy_pair *pair,
                          int index, const struct target_point *tp, struct light_sample *out)
{
    const struct scene *sc = s->scene;
    out->wi = tp->wi;
    const struct light *l = &sc->lights[pair->light];
    if (pair->portal < 0) {
        out->light = pair->light;
        out->dist = tp->dist;
    } else {
        /* Through the portal: the direction counts only if it goes on to
           meet the light (always, up to rounding, for the exact techniques). */
        double dist;
        if (polygon_intersect_ray(&l->target.polygon, pt->p, tp->wi, &dist)) {
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
    out->radiance = light_emitted(l, vec3_neg(tp->wi));
    /* Light-only strategies know their density already; mixtures must add
       every other way of producing the same direction. */
    if (!strategy_kind_uses_portals(s->kind)) out->pdf_sa = s->power.prob[pair->light] * tp->pdf_sa;
    else if (index >= 0) out->pdf_sa = mixture_pdf(s, pt, out->light, tp->wi, index, tp->pdf_sa);
    else out->pdf_sa = mixture_pdf(s, pt, out->light, tp->wi, -1, 0.0);
}

bool strategy_sample(const struct strategy *s, const struct strategy_point *pt, const double u[4],
                     struct light_sample *out)
{
    double u0 = u[0];
    struct strategy_pair light_only;
    const struct strategy_pair *pair;
    enum technique t;
    int index = -1;

    if (strategy_kind_uses_portals(s->kind) && u0 >= s->defensive) {
        /* Rescale u0 to [0,1) and pick a pair by the point's weights. */
        if (!(pt->total > 0.0)) return false;
        u0 = (u0 - s->defensive) / (1.0 - s->defensive);
        index = pt->scratch->cand[cdf_find(pt->scratch->cdf, pt->scratch->n_cand, u0 * pt->total)];
        pair = &s->pairs[index];
        t = strategy_technique(s, pair, region_of(pt, index));
    } else {
        if (strategy_kind_uses_portals(s->kind)) u0 = u0 / s->defensive;
        light_only.light = alias_sample(&s->power, u0, NULL);
        light_only.portal = -1;
        pair = &light_only;
        t = s->kind == STRATEGY_LIGHT_AREA ? TECHNIQUE_LIGHT_AREA : TECHNIQUE_LIGHT_SOLID;
    }

    struct target_point tp;
    if (!technique_sample(s, pt, pair, index, t, u + 1, &tp)) return false;
    finish_sample(s, pt, pair, index, &tp, out);
    return true;
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
    for (int b = 0; b < n; b += STRATEGY_MANY_CHUNK) {
        int m = n - b < STRATEGY_MANY_CHUNK ? n - b : STRATEGY_MANY_CHUNK;
        const struct target *t[STRATEGY_MANY_CHUNK];
        struct vec3 p[STRATEGY_MANY_CHUNK];
        double uu[STRATEGY_MANY_CHUNK][3];
        struct strategy_pair pairs[STRATEGY_MANY_CHUNK];
        struct target_point tp[STRATEGY_MANY_CHUNK];
        for (int k = 0; k < m; ++k) {
            /* strategy_sample's light-only branch, technique by technique. */
            pairs[k] = (struct strategy_pair){ alias_sample(&s->power, u[b + k][0], NULL), -1 };
            t[k] = &s->scene->lights[pairs[k].light].target;
            p[k] = pts[b + k].p;
            for (int j = 0; j < 3; ++j) uu[k][j] = u[b + k][j + 1];
        }
        target_sample_solid_angle_many(t, p, (const double(*)[3])uu, m, tp, ok + b);
        for (int k = 0; k < m; ++k)
            if (ok[b + k]) finish_sample(s, &pts[b + k], &pairs[k], -1, &tp[k], &out[b + k]);
    }
}

/* strategy_weights.c: a shading point's pairs and their weights: the
   visible-part cache, the heuristics (area, distance, irradiance and its
   estimate), the mesh lights' bounding-sphere classification, culling of
   points no emitter can light, and strategy_prepare_pairs, which turns the
   weights into the point's cdf. */
#include <math.h>
#include <stddef.h>

#include "base/fastmath.h"
#include "sampling/strategy_internal.h"

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
        int n = strategy_kind_classifies(s->kind)
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
   rectangle frame were a large part of the cost of making the target). */
const struct target *strategy_visible_target(const struct strategy *s, const struct strategy_point *pt, int i)
{
    struct strategy_scratch *sc = pt->scratch;
    if (!visible_polygon(s, pt, i)) return NULL;
    if (sc->vis_state[i] == VIS_POLYGON) sc->vis_state[i] = target_finish(&sc->vis[i]) ? VIS_READY : VIS_EMPTY;
    return sc->vis_state[i] == VIS_READY ? &sc->vis[i] : NULL;
}

/* The visible part of a mesh light's member pair (one triangle and the
   portal) from the prepared point, into `storage`; NULL when nothing is
   visible. Not cached: a member is used by one sample or one pdf. */
const struct target *strategy_member_visible(const struct strategy *s, const struct strategy_point *pt,
                                             const struct strategy_pair *member, enum region region,
                                             struct target *storage)
{
    struct polygon vis;
    const struct antishadow *a = &s->scene->portals[member->portal].antishadow;
    int n = strategy_kind_classifies(s->kind) ? antishadow_visible_polygon_in(a, pt->p, region, &vis)
                                              : antishadow_visible_polygon(a, pt->p, &vis);
    return n >= 3 && target_init(storage, &vis) ? storage : NULL;
}

/* A pair's weight, or with poly set its `irradiance` form left to finish:
   scale times the projected solid angle of poly from the point, so that a
   point's candidates compute those together
   (polygon_projected_solid_angle_many): their edge angles were a large
   share of antishadow_exact's time on multi_lamp, one short polygon at a
   time. */
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
   squared, with no square root or division (it was a large share of
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
        struct strategy_pair m = strategy_member_of(sc, pair, e->first_light + k);
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
    return rgb_luminance(s->scene->lights[pair->light].radiance) * small_solid_angle(pt->target, pt->centroid, p);
}

/* The `irradiance_estimate` weight of a polygon light's portal pair in a
   known region: what the `irradiance` weight computes exactly from the
   clipped visible polygon, estimated in O(1) from the light (anti-umbra:
   all of it is seen), the portal (anti-antumbra: all of it is filled) or
   the smaller of the two (anti-penumbra: the visible part is within both).
   A point then clips and prepares only the pair it samples, instead of
   every candidate: on multi_lamp those were a large share of
   antishadow_exact's time. */
static double pair_irradiance_estimate(const struct strategy *s, const struct strategy_pair *pair, enum region region,
                                       struct vec3 p, struct vec3 n)
{
    const struct scene *sc = s->scene;
    const struct light *l = &sc->lights[pair->light];
    const struct portal *pt = &sc->portals[pair->portal];
    double light =
        region == REGION_ANTI_ANTUMBRA ? INFINITY : small_projected_solid_angle(&l->target, l->centroid, p, n);
    double portal =
        region == REGION_ANTI_UMBRA ? INFINITY : small_projected_solid_angle(pt->target, pt->centroid, p, n);
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
    bool classify = strategy_kind_classifies(s->kind), mesh = e->n_lights > 1;
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
        for (int k = 0; k < l->n_portals; ++k) sum += sc->portals[l->first_portal + k].target->area;
        return weight_value(e->power * pt->target->area / sum);
    }
    case PORTAL_WEIGHT_DISTANCE: {
        /* Each portal's share of its light falls off as area / distance^2. */
        double sum = 0.0, mine = 0.0;
        for (int k = 0; k < l->n_portals; ++k) {
            const struct portal *q = &sc->portals[l->first_portal + k];
            double w = q->target->area / fm_fmax(vec3_length2(vec3_sub(q->centroid, p)), 1e-12);
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
           Lamp; docs/performance.md). */
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

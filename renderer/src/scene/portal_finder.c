#include "scene/portal_finder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "config/config.h"
#include "geometry/convex_hull.h"
#include "geometry/facet_cover.h"
#include "geometry/mesh_components.h"
#include "scene/portal_coverage.h"

/* Light vertices must lie this far inside every facet of P, relative to
   P's size: well beyond the antishadow's own side test (1e-9). */
#define INSIDE_REL 1e-7

/* The finder's state for one light. */
struct finder {
    struct scene *s;
    const struct config *cfg;
    int emitter;
    struct auto_portal_report *rep;
    struct vec3 *light_pts; /* every vertex of the emitter's lights */
    int n_light_pts;
};

/* A candidate for the enclosure: a shape, or one connected piece of a
   shape (geometry/mesh_components.h), with the nearest distance at which
   the light's rays met it and the vertices of its faces (owned). */
struct candidate {
    int shape;
    int piece; /* -1: the whole shape */
    double t_min;
    struct vec3 *verts;
    int n_verts;
};

/* A list of candidates, nearest first; { 0, NULL } is empty. */
struct candidates {
    int n;
    struct candidate *c;
};

static void candidates_free(struct candidates *cs)
{
    for (int i = 0; i < cs->n; ++i) free(cs->c[i].verts);
    free(cs->c);
    *cs = (struct candidates){ 0, NULL };
}

static int compare_candidates(const void *a, const void *b)
{
    const struct candidate *p = a, *q = b;
    if (p->t_min != q->t_min) return p->t_min < q->t_min ? -1 : 1;
    if (p->shape != q->shape) return p->shape - q->shape;
    return p->piece - q->piece;
}

/* Where the light's rays met one shape: the nearest distance overall and
   per connected piece (label: the piece of each face; computed at the
   shape's first hit). */
struct shape_hits {
    double t_min;
    int *label;
    int n_pieces;
    double *piece_t;
};

/* Appends the candidate of shape `shape`'s piece `piece` (-1: the whole
   shape, every vertex) met at t, unless it is room-sized. False on memory. */
static bool push_candidate(const struct finder *f, struct candidates *cs, int shape, int piece, const int *label,
                           double t)
{
    const struct shape_desc *sh = &f->cfg->shapes[shape];
    struct vec3 *v = malloc(sizeof *v * (size_t)(sh->n_vertices > 0 ? sh->n_vertices : 1));
    if (!v) return false;
    int n = 0;
    if (piece < 0) {
        memcpy(v, sh->vertices, sizeof *v * (size_t)sh->n_vertices);
        n = sh->n_vertices;
    } else {
        /* Every vertex of the piece's faces, once (a vertex index belongs
           to one piece: the faces that share it are connected). */
        char *taken = calloc((size_t)(sh->n_vertices > 0 ? sh->n_vertices : 1), 1);
        if (!taken) {
            free(v);
            return false;
        }
        for (int face = 0; face < sh->n_quads + sh->n_triangles; ++face) {
            if (label[face] != piece) continue;
            const int *idx = face < sh->n_quads ? sh->quads[face] : sh->triangles[face - sh->n_quads];
            for (int k = 0; k < (face < sh->n_quads ? 4 : 3); ++k)
                if (!taken[idx[k]]) taken[idx[k]] = 1, v[n++] = sh->vertices[idx[k]];
        }
        free(taken);
    }
    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    for (int i = 0; i < n; ++i) {
        lo = vec3_make(fmin(lo.x, v[i].x), fmin(lo.y, v[i].y), fmin(lo.z, v[i].z));
        hi = vec3_make(fmax(hi.x, v[i].x), fmax(hi.y, v[i].y), fmax(hi.z, v[i].z));
    }
    if (n == 0 || vec3_length(vec3_sub(hi, lo)) > PORTAL_FINDER_MAX_SHAPE_FRACTION * f->s->scale) {
        free(v);
        return true;
    }
    struct candidate *grown = realloc(cs->c, sizeof *grown * (size_t)(cs->n + 1));
    if (!grown) {
        free(v);
        return false;
    }
    cs->c = grown;
    cs->c[cs->n++] = (struct candidate){ shape, piece, t, v, n };
    return true;
}

/* The candidates the light's rays meet first, nearest first, without the
   room-sized ones: by shape into *shapes, and by connected piece into
   *pieces (the same list when no shape met has more than one piece).
   False on memory or an Embree error. */
static bool find_candidates(const struct finder *f, struct candidates *shapes, struct candidates *pieces)
{
    const struct scene *s = f->s;
    const struct config *cfg = f->cfg;
    struct shape_hits *hits = calloc((size_t)(cfg->n_shapes > 0 ? cfg->n_shapes : 1), sizeof *hits);
    struct emission_sampler es;
    struct error err;
    if (!hits || !emission_sampler_init(&es, s, f->emitter, &err)) {
        free(hits);
        return false;
    }
    bool ok = true;
    for (int i = 0; i < cfg->n_shapes; ++i) hits[i].t_min = INFINITY;
    struct rng r = rng_seeded(PORTAL_FINDER_SEED, (uint64_t)f->emitter, 1);
    for (int i = 0; ok && i < PORTAL_FINDER_RAYS; ++i) {
        double u[EMISSION_UNIFORMS];
        struct vec3 p, n, d;
        for (int j = 0; j < EMISSION_UNIFORMS; ++j) u[j] = rng_uniform(&r);
        emission_sample(&es, u, &p, &n, &d);
        struct hit h;
        int g, face;
        if (!scene_intersect_geometry(s, scene_offset_origin(s, p, n, d), d, INFINITY, &h, &g, &face)) continue;
        int shape = s->geometries[g].shape;
        if (shape < 0 || face < 0) continue;
        struct shape_hits *sh = &hits[shape];
        sh->t_min = fmin(sh->t_min, h.t);
        if (!sh->label) {
            const struct shape_desc *d0 = &cfg->shapes[shape];
            sh->label = malloc(sizeof *sh->label * (size_t)(d0->n_quads + d0->n_triangles + 1));
            sh->n_pieces = sh->label
                               ? mesh_components(d0->vertices, d0->n_vertices, (const int(*)[4])d0->quads, d0->n_quads,
                                                 (const int(*)[3])d0->triangles, d0->n_triangles, sh->label)
                               : -1;
            sh->piece_t = sh->n_pieces > 0 ? malloc(sizeof *sh->piece_t * (size_t)sh->n_pieces) : NULL;
            ok = sh->piece_t != NULL;
            for (int k = 0; ok && k < sh->n_pieces; ++k) sh->piece_t[k] = INFINITY;
        }
        if (ok) sh->piece_t[sh->label[face]] = fmin(sh->piece_t[sh->label[face]], h.t);
    }
    emission_sampler_free(&es);
    *shapes = *pieces = (struct candidates){ 0, NULL };
    bool split = false;
    for (int i = 0; ok && i < cfg->n_shapes; ++i) {
        if (!isfinite(hits[i].t_min)) continue;
        ok = push_candidate(f, shapes, i, -1, NULL, hits[i].t_min);
        if (hits[i].n_pieces == 1) {
            ok = ok && push_candidate(f, pieces, i, -1, NULL, hits[i].t_min);
            continue;
        }
        split = true;
        for (int k = 0; ok && k < hits[i].n_pieces; ++k)
            if (isfinite(hits[i].piece_t[k])) ok = push_candidate(f, pieces, i, k, hits[i].label, hits[i].piece_t[k]);
    }
    for (int i = 0; i < cfg->n_shapes; ++i) free(hits[i].label), free(hits[i].piece_t);
    free(hits);
    if (!ok || !split) candidates_free(pieces);
    if (!ok) {
        candidates_free(shapes);
        return false;
    }
    /* (No ray hit anything: no candidates, and qsort must not see NULL.) */
    if (shapes->n > 1) qsort(shapes->c, (size_t)shapes->n, sizeof *shapes->c, compare_candidates);
    if (pieces->c && pieces->n > 1) qsort(pieces->c, (size_t)pieces->n, sizeof *pieces->c, compare_candidates);
    return true;
}

/* How the light sits in the hull: the largest plane distance of a light
   vertex over the facets (negative: strictly inside by that much), and
   whether some vertex lies inside or on it. */
static double light_depth(const struct finder *f, const struct convex_hull *h, bool *some_inside)
{
    double worst = -INFINITY;
    *some_inside = false;
    for (int i = 0; i < f->n_light_pts; ++i) {
        double d = -INFINITY;
        for (int k = 0; k < h->n_facets; ++k) d = fmax(d, plane_distance(&h->facets[k].plane, f->light_pts[i]));
        worst = fmax(worst, d);
        if (d <= INSIDE_REL * h->size) *some_inside = true;
    }
    return worst;
}

/* The hull of the first k candidates' vertices, into points (room for
   all of them). */
static bool hull_of(const struct finder *f, const struct candidate *c, int k, struct vec3 *points, int *n_points,
                    struct convex_hull *h, struct error *err)
{
    (void)f;
    int n = 0;
    for (int i = 0; i < k; ++i) {
        memcpy(points + n, c[i].verts, sizeof *points * (size_t)c[i].n_verts);
        n += c[i].n_verts;
    }
    *n_points = n;
    return convex_hull_build(points, n, h, err);
}

/* The scene's shape triangles that touch the box lo..hi. */
static int gather_triangles(const struct config *cfg, struct vec3 lo, struct vec3 hi, struct vec3 (**out)[3])
{
    size_t cap = 0;
    for (int i = 0; i < cfg->n_shapes; ++i)
        cap += (size_t)cfg->shapes[i].n_triangles + 2 * (size_t)cfg->shapes[i].n_quads;
    struct vec3(*t)[3] = malloc(sizeof *t * (cap > 0 ? cap : 1));
    if (!t) return -1;
    int n = 0;
    for (int i = 0; i < cfg->n_shapes; ++i) {
        const struct shape_desc *sh = &cfg->shapes[i];
        for (int f = 0; f < sh->n_triangles + 2 * sh->n_quads; ++f) {
            struct vec3 v[3];
            if (f < sh->n_triangles) {
                for (int k = 0; k < 3; ++k) v[k] = sh->vertices[sh->triangles[f][k]];
            } else {
                const int *q = sh->quads[(f - sh->n_triangles) / 2];
                int second = (f - sh->n_triangles) % 2;
                v[0] = sh->vertices[q[0]];
                v[1] = sh->vertices[q[second ? 2 : 1]];
                v[2] = sh->vertices[q[second ? 3 : 2]];
            }
            bool out_box = false;
            out_box = out_box || (v[0].x < lo.x && v[1].x < lo.x && v[2].x < lo.x);
            out_box = out_box || (v[0].y < lo.y && v[1].y < lo.y && v[2].y < lo.y);
            out_box = out_box || (v[0].z < lo.z && v[1].z < lo.z && v[2].z < lo.z);
            out_box = out_box || (v[0].x > hi.x && v[1].x > hi.x && v[2].x > hi.x);
            out_box = out_box || (v[0].y > hi.y && v[1].y > hi.y && v[2].y > hi.y);
            out_box = out_box || (v[0].z > hi.z && v[1].z > hi.z && v[2].z > hi.z);
            if (out_box) continue;
            for (int k = 0; k < 3; ++k) t[n][k] = v[k];
            ++n;
        }
    }
    *out = t;
    return n;
}

/* The portals of P: every facet's uncovered part, clipped for a one-sided
   polygon light to the half-space it emits into (nothing it emits crosses
   the rest), split to at most POLYGON_INPUT_MAX corners. It stops early,
   with *open_area at least stop_at and no portals, once the open area of
   the facets so far reaches stop_at: a caller that keeps a hull only for
   less open area than stop_at has its answer then (the areas are summed in
   the same order as the full sum, so the partial sum is no larger). */
static bool portals_of_hull(const struct finder *f, const struct convex_hull *h, const struct vec3 *points,
                            double stop_at, struct polygon_list *out, double *open_area, double *hull_area, bool *bad)
{
    *bad = false;
    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    for (int i = 0; i < h->n_index; ++i) {
        struct vec3 x = points[h->index[i]];
        lo = vec3_make(fmin(lo.x, x.x), fmin(lo.y, x.y), fmin(lo.z, x.z));
        hi = vec3_make(fmax(hi.x, x.x), fmax(hi.y, x.y), fmax(hi.z, x.z));
    }
    double g = FACET_COVER_REL * h->size * 10.0;
    lo = vec3_sub(lo, vec3_make(g, g, g));
    hi = vec3_add(hi, vec3_make(g, g, g));
    struct vec3(*tris)[3] = NULL;
    int n_tris = gather_triangles(f->cfg, lo, hi, &tris);
    if (n_tris < 0) return false;
    struct tri_sphere *spheres = malloc(sizeof *spheres * (size_t)(n_tris > 0 ? n_tris : 1));
    if (!spheres) {
        free(tris);
        return false;
    }
    tri_spheres((const struct vec3(*)[3])tris, n_tris, spheres);
    struct polygon_list open = { 0, 0, NULL };
    bool ok = true;
    *hull_area = 0.0;
    double partial = 0.0;
    for (int fi = 0; ok && fi < h->n_facets; ++fi) {
        const struct hull_facet *hf = &h->facets[fi];
        struct vec3 a = points[h->index[hf->first]];
        for (int k = 1; k + 1 < hf->n; ++k)
            *hull_area += 0.5 * vec3_length(vec3_cross(vec3_sub(points[h->index[hf->first + k]], a),
                                                       vec3_sub(points[h->index[hf->first + k + 1]], a)));
        int before = open.n;
        ok = facet_uncovered_part(h, points, fi, (const struct vec3(*)[3])tris, n_tris, &open);
        if (ok && open.n > before &&
            facet_layer_covers(h, points, fi, (const struct vec3(*)[3])tris, spheres, n_tris, f->light_pts,
                               f->n_light_pts))
            open.n = before;
        for (int k = before; ok && k < open.n; ++k) partial += polygon_area(&open.p[k]);
        if (ok && partial >= stop_at) {
            free(tris);
            free(spheres);
            free(open.p);
            *open_area = partial;
            return true;
        }
    }
    free(tris);
    free(spheres);
    *open_area = 0.0;
    const struct emitter *e = &f->s->emitters[f->emitter];
    const struct light *l0 = &f->s->lights[e->first_light];
    bool clip = e->n_lights == 1 && !l0->two_sided;
    struct plane front = { l0->target.normal, vec3_dot(l0->target.normal, l0->target.polygon.v[0]) };
    for (int k = 0; ok && k < open.n; ++k) {
        struct polygon piece;
        *open_area += polygon_area(&open.p[k]);
        if (clip) {
            if (polygon_clip_plane(&open.p[k], &front, &piece) < 3) continue;
        } else {
            polygon_copy(&piece, &open.p[k]);
        }
        if (!(polygon_area(&piece) > FACET_DEBRIS_REL * h->size * h->size)) continue;
        /* Fans of at most POLYGON_INPUT_MAX corners. A chunk that is no
           valid portal (collinear corners or rounding left it not strictly
           convex) goes in as its fan's triangles; a triangle of no area
           (polygon_check: below 1e-10 of its diameter squared) covers no
           ray and is left out; any other defect would leave a gap, so the
           hull is refused (*bad). Nothing is dropped silently. */
        for (int a = 1; ok && a + 1 < piece.n; a += POLYGON_INPUT_MAX - 2) {
            struct polygon chunk;
            chunk.n = 0;
            chunk.v[chunk.n++] = piece.v[0];
            for (int b = a; b < piece.n && chunk.n < POLYGON_INPUT_MAX; ++b) chunk.v[chunk.n++] = piece.v[b];
            if (chunk.n >= 3 && polygon_check(&chunk) == POLYGON_DEFECT_NONE) {
                ok = polygon_list_push(out, &chunk);
            } else {
                for (int b = 1; ok && b + 1 < chunk.n; ++b) {
                    struct polygon tri = { 3, { chunk.v[0], chunk.v[b], chunk.v[b + 1] } };
                    enum polygon_defect defect = polygon_check(&tri);
                    if (defect == POLYGON_DEFECT_NONE) ok = polygon_list_push(out, &tri);
                    else if (defect != POLYGON_DEFECT_DEGENERATE) *bad = true;
                }
            }
            if (a + POLYGON_INPUT_MAX - 2 >= piece.n - 1) break;
        }
    }
    free(open.p);
    return ok;
}

/* A hull of candidate shapes with its points and portals (all owned). */
struct choice {
    struct convex_hull h;
    struct vec3 *points;
    struct polygon_list ports;
    double open_area, hull_area;
    bool bad; /* an opening is no valid polygon (portals_of_hull) */
};

static void choice_free(struct choice *ch)
{
    convex_hull_free(&ch->h);
    free(ch->points);
    free(ch->ports.p);
}

/* Tries the hull of the candidates c[0..n) (n_pts: room for their
   vertices) in place of *best. It is taken when it holds the light
   strictly inside and its portals are better: valid over invalid, or less
   open area; with bad_ok, also an invalid set over an invalid one.
   Returns whether it was taken; sets *ok to false on memory. */
static bool try_hull(const struct finder *f, const struct candidate *c, int n, size_t n_pts, bool bad_ok,
                     struct choice *best, bool *ok)
{
    struct choice ch = { .points = malloc(sizeof *ch.points * (n_pts > 0 ? n_pts : 1)) };
    if (!ch.points) {
        *ok = false;
        return false;
    }
    struct error herr;
    int n_points;
    bool some;
    if (!hull_of(f, c, n, ch.points, &n_points, &ch.h, &herr)) {
        free(ch.points);
        return false;
    }
    if (!(light_depth(f, &ch.h, &some) < -INSIDE_REL * ch.h.size)) {
        convex_hull_free(&ch.h);
        free(ch.points);
        return false;
    }
    /* Only a valid set with less open area can replace a valid best. */
    double stop_at = best->bad ? INFINITY : best->open_area;
    *ok = portals_of_hull(f, &ch.h, ch.points, stop_at, &ch.ports, &ch.open_area, &ch.hull_area, &ch.bad);
    bool better = ch.bad ? bad_ok && best->bad : best->bad || ch.open_area < best->open_area;
    if (*ok && better) {
        choice_free(best);
        *best = ch;
        return true;
    }
    choice_free(&ch);
    return false;
}

/* The enclosure built from one candidate list, into *best (owned) with
   *k, the count of candidates it is the hull of. *found false: no hull of
   them holds the light strictly inside (*touches: one holds it on its
   boundary or pierces it). False only on memory. */
static bool choose(const struct finder *f, const struct candidates *cs, struct choice *best, int *k_out, bool *found,
                   bool *touches)
{
    const struct candidate *c = cs->c;
    int n_c = cs->n;
    size_t n_pts = 0;
    for (int i = 0; i < n_c; ++i) n_pts += (size_t)c[i].n_verts;
    *best = (struct choice){ .points = malloc(sizeof *best->points * (n_pts > 0 ? n_pts : 1)) };
    *found = *touches = false;
    if (!best->points) return false;
    int k = 0, n_points = 0;
    for (k = 1; k <= n_c && !*found; ++k) {
        struct error herr;
        if (!hull_of(f, c, k, best->points, &n_points, &best->h, &herr)) continue;
        bool some;
        double depth = light_depth(f, &best->h, &some);
        *found = depth < -INSIDE_REL * best->h.size;
        *touches = !*found && some;
        if (!*found) convex_hull_free(&best->h);
    }
    --k;
    *k_out = k;
    if (!*found) return true;
    bool ok = portals_of_hull(f, &best->h, best->points, INFINITY, &best->ports, &best->open_area, &best->hull_area,
                              &best->bad);
    /* The tightest of the hulls that add the next nearby candidates (met
       within twice the distance of the last one taken): the least open
       area. Each is complete; more candidates only make P fit them better. */
    double reach = 2.0 * c[k - 1].t_min;
    for (int more = k + 1; ok && more <= n_c && more <= k + PORTAL_FINDER_MAX_EXTRA && c[more - 1].t_min <= reach;
         ++more)
        if (try_hull(f, c, more, n_pts, true, best, &ok)) k = more;
    /* Then the chosen candidates without one of them, while that leaves
       less open area and still holds the light strictly inside: a stand or
       a socket met first by the light's rays stretches the hull well
       beyond the shade (each such hull is complete as well). */
    struct candidate *set = ok ? malloc(sizeof *set * (size_t)n_c) : NULL,
                     *sub = ok ? malloc(sizeof *sub * (size_t)n_c) : NULL;
    if (ok && (!set || !sub)) ok = false;
    int n_set = k;
    if (ok) {
        /* The candidates of the hull chosen above: the first k. */
        for (int i = 0; i < k; ++i) set[i] = c[i];
    }
    for (bool improved = ok; improved && n_set > 1;) {
        improved = false;
        for (int j = 0; ok && j < n_set && !improved; ++j) {
            int n_sub = 0;
            for (int i = 0; i < n_set; ++i)
                if (i != j) sub[n_sub++] = set[i];
            if (try_hull(f, sub, n_sub, n_pts, false, best, &ok)) {
                for (int i = 0; i < n_sub; ++i) set[i] = sub[i];
                n_set = k = n_sub;
                improved = true;
            }
        }
    }
    free(set);
    free(sub);
    *k_out = k;
    return ok;
}

/* Whether the portals of an enclosure can be used as they are (else the
   light gets none: find_for_light says why). */
static bool usable(const struct choice *ch)
{
    return !ch->bad && ch->open_area <= PORTAL_FINDER_MAX_OPEN_FRACTION * ch->hull_area &&
           ch->ports.n <= PORTAL_FINDER_MAX_PORTALS;
}

/* Decides and applies the portals of one light. False only on memory. */
static bool find_for_light(struct finder *f, struct error *err)
{
    struct auto_portal_report *rep = f->rep;
    const char *name = f->cfg->lights[f->emitter].name;
    struct candidates shapes, pieces;
    if (!find_candidates(f, &shapes, &pieces))
        return error_set(err, "out of memory finding the portals of light \"%s\"", name);
    struct choice best;
    int k = 0;
    bool found, touches;
    bool ok = choose(f, &shapes, &best, &k, &found, &touches);
    /* By connected pieces too, when a shape met has several (a lamp
       modelled as one mesh): kept when its portals are usable and leave
       less open area. Bounded: the choice costs hulls in the square of
       the candidates it keeps. */
    const char *unit = "shape(s)";
    if (ok && pieces.n > 0 && pieces.n <= PORTAL_FINDER_MAX_PIECES) {
        struct choice alt;
        int k_alt = 0;
        bool found_alt, touches_alt;
        ok = choose(f, &pieces, &alt, &k_alt, &found_alt, &touches_alt);
        if (ok && found_alt && usable(&alt) && (!found || !usable(&best) || alt.open_area < best.open_area)) {
            choice_free(&best);
            best = alt;
            k = k_alt;
            found = true;
            unit = "connected piece(s) of shapes";
        } else {
            choice_free(&alt);
        }
    }
    int n_c = shapes.n;
    candidates_free(&shapes);
    candidates_free(&pieces);
    if (!ok) {
        choice_free(&best);
        return error_set(err, "out of memory finding the portals of light \"%s\"", name);
    }
    if (!found) {
        if (touches) {
            rep->warn = true;
            snprintf(rep->note, sizeof rep->note,
                     "light \"%s\" touches or pierces the hull of the %d shape(s) around it: no portals "
                     "(sampled as `light` samples it)",
                     name, n_c);
        } else {
            snprintf(rep->note, sizeof rep->note, "light \"%s\": no shape encloses it: no portals", name);
        }
        choice_free(&best);
        return true;
    }
    const struct convex_hull *h = &best.h;
    const struct polygon_list *ports = &best.ports;
    double open_area = best.open_area, hull_area = best.hull_area;
    rep->hull_area = hull_area;
    if (open_area > PORTAL_FINDER_MAX_OPEN_FRACTION * hull_area) {
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": the hull of the %d nearest %s around it is %.0f%% open: no portals", name, k, unit,
                 100.0 * open_area / hull_area);
    } else if (best.bad) {
        rep->warn = true;
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": an opening of the hull of the %d nearest %s around it is no valid polygon: "
                 "no portals (sampled as `light` samples it)",
                 name, k, unit);
    } else if (ports->n > PORTAL_FINDER_MAX_PORTALS) {
        rep->warn = true;
        snprintf(rep->note, sizeof rep->note,
                 "light \"%s\": the hull of the %d nearest %s around it leaves %d open pieces (more than %d): "
                 "no portals (sampled as `light` samples it)",
                 name, k, unit, ports->n, PORTAL_FINDER_MAX_PORTALS);
    } else {
        struct error aerr = { { 0 } };
        if (!scene_add_portals(f->s, f->emitter, ports->p, ports->n, &aerr)) {
            rep->warn = true;
            snprintf(rep->note, sizeof rep->note, "light \"%s\": %.300s: no portals (sampled as `light` samples it)",
                     name, aerr.message);
        } else {
            rep->enclosed = true;
            rep->n_portals = ports->n;
            for (int i = 0; i < ports->n; ++i) rep->area += polygon_area(&ports->p[i]);
            rep->n_planes = h->n_facets;
            rep->planes = malloc(sizeof *rep->planes * (size_t)h->n_facets);
            ok = rep->planes != NULL;
            for (int i = 0; ok && i < h->n_facets; ++i) rep->planes[i] = h->facets[i].plane;
            rep->box_lo = vec3_make(INFINITY, INFINITY, INFINITY);
            rep->box_hi = vec3_neg(rep->box_lo);
            for (int i = 0; i < h->n_index; ++i) {
                struct vec3 x = best.points[h->index[i]];
                rep->box_lo = vec3_make(fmin(rep->box_lo.x, x.x), fmin(rep->box_lo.y, x.y), fmin(rep->box_lo.z, x.z));
                rep->box_hi = vec3_make(fmax(rep->box_hi.x, x.x), fmax(rep->box_hi.y, x.y), fmax(rep->box_hi.z, x.z));
            }
            snprintf(rep->note, sizeof rep->note, "light \"%s\": %d portal(s) on the hull of %d %s", name, ports->n, k,
                     unit);
        }
    }
    choice_free(&best);
    return ok || error_set(err, "out of memory finding the portals of light \"%s\"", name);
}

bool portal_finder_run(struct scene *s, const struct config *cfg, struct error *err)
{
    bool any = false;
    for (int i = 0; i < cfg->n_lights; ++i) any = any || cfg->lights[i].auto_portals;
    if (!any) return true;
    s->auto_portals = calloc((size_t)s->n_emitters, sizeof *s->auto_portals);
    if (!s->auto_portals) return error_set(err, "out of memory for the auto portals");
    for (int i = 0; i < cfg->n_lights; ++i) {
        if (!cfg->lights[i].auto_portals) continue;
        s->auto_portals[i].requested = true;
        const struct emitter *e = &s->emitters[i];
        struct finder f = { s, cfg, i, &s->auto_portals[i], NULL, 0 };
        f.light_pts = malloc(sizeof *f.light_pts * (size_t)e->n_lights * POLYGON_INPUT_MAX);
        if (!f.light_pts) return error_set(err, "out of memory for the auto portals");
        for (int m = 0; m < e->n_lights; ++m) {
            const struct polygon *p = &s->lights[e->first_light + m].target.polygon;
            for (int v = 0; v < p->n && v < POLYGON_INPUT_MAX; ++v) f.light_pts[f.n_light_pts++] = p->v[v];
        }
        /* Only the corners of the light points' convex hull matter (every
           use is a max or min of an affine or convex function over the
           light): a mesh bulb has thousands of vertices. */
        struct convex_hull lh;
        struct error lerr;
        if (f.n_light_pts > 64 && convex_hull_build(f.light_pts, f.n_light_pts, &lh, &lerr)) {
            int n_keep = 0;
            bool *used = calloc((size_t)f.n_light_pts, sizeof *used);
            struct vec3 *kept = malloc(sizeof *kept * (size_t)f.n_light_pts);
            if (used && kept) {
                for (int q = 0; q < lh.n_index; ++q) used[lh.index[q]] = true;
                for (int q = 0; q < f.n_light_pts; ++q)
                    if (used[q]) kept[n_keep++] = f.light_pts[q];
                free(f.light_pts);
                f.light_pts = kept, f.n_light_pts = n_keep, kept = NULL;
            }
            free(used);
            free(kept);
            convex_hull_free(&lh);
        }
        bool ok = find_for_light(&f, err);
        free(f.light_pts);
        if (!ok) return false;
    }
    return true;
}

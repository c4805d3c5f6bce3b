/* test_ray_stream.c: tracing a ray stream (scene_occluded_stream,
   scene_first_light_stream, scene_intersect_stream and
   scene_intersect_coherent, one Embree call for many rays) against the
   one-ray wrappers (scene_occluded, scene_first_light, scene_intersect) on the lampshade
   scene: the same answer for every ray, inactive rays left out (clear, no
   light), rays of every kind among them (blocked and clear segments, rays
   that reach the light, hit a surface first or leave the scene). */
#include <math.h>
#include <string.h>

#include "geometry/polygon.h"
#include "base/rng.h"
#include "scene/scene.h"
#include "scene_util.h"
#include "testlib.h"

#define SCENE "configs/scenes/lampshade.yaml"

enum { N_RAYS = 4099 };

struct fixture {
    struct config cfg;
    struct scene sc;
    struct scene_ray rays[N_RAYS];
    bool active[N_RAYS];
};

static double uniform(struct rng *r, double lo, double hi)
{
    return lo + (hi - lo) * rng_uniform(r);
}

/* A point of the light's polygon (a random vertex pulled towards another
   and towards the first: inside, the polygon being convex). */
static struct vec3 light_point(const struct light *l, struct rng *r)
{
    const struct polygon *poly = &l->target.polygon;
    int a = (int)(rng_uniform(r) * poly->n) % poly->n, b = (a + 1) % poly->n;
    struct vec3 p = vec3_add(poly->v[a], vec3_scale(vec3_sub(poly->v[b], poly->v[a]), rng_uniform(r)));
    return vec3_add(p, vec3_scale(vec3_sub(poly->v[(a + 2) % poly->n], p), uniform(r, 0.01, 0.99)));
}

/* Rays from random points of the scene's box: half towards a point of the
   light (segments ending just before it, or unbounded), half in random
   directions; one in ten inactive. */
static bool fixture_init_scene(struct fixture *f, const char *scene, uint64_t seed)
{
    if (!test_scene_load(scene, NULL, 0, &f->cfg, &f->sc)) return false;
    struct rng r;
    rng_seed(&r, seed, 0, 0);
    struct vec3 lo = f->sc.bounds_lo, hi = f->sc.bounds_hi;
    for (int i = 0; i < N_RAYS; ++i) {
        struct vec3 o = vec3_make(uniform(&r, lo.x, hi.x), uniform(&r, lo.y, hi.y), uniform(&r, lo.z, hi.z));
        struct scene_ray *ray = &f->rays[i];
        ray->o = o;
        if (rng_uniform(&r) < 0.5) {
            const struct light *l = &f->sc.lights[(int)(rng_uniform(&r) * f->sc.n_lights) % f->sc.n_lights];
            struct vec3 lp = light_point(l, &r);
            /* Half of them from near the light's emitting side, where most
               reach it; from the rest of the room the shade blocks most. */
            if (rng_uniform(&r) < 0.5) {
                struct vec3 w = vec3_make(uniform(&r, -1, 1), uniform(&r, -1, 1), uniform(&r, -1, 1));
                if (vec3_dot(w, l->target.normal) < 0.0) w = vec3_neg(w);
                o = ray->o = vec3_madd(lp, w, uniform(&r, 0.02, 0.3));
            }
            struct vec3 to = vec3_sub(lp, o);
            double dist = vec3_length(to);
            ray->d = vec3_scale(to, 1.0 / dist);
            ray->tmax = rng_uniform(&r) < 0.5 ? dist * (1.0 - 1e-4) : INFINITY;
        } else {
            double z = uniform(&r, -1.0, 1.0), phi = uniform(&r, 0.0, 2.0 * M_PI), s = sqrt(1.0 - z * z);
            ray->d = vec3_make(s * cos(phi), s * sin(phi), z);
            ray->tmax = rng_uniform(&r) < 0.5 ? uniform(&r, 0.0, 3.0) : INFINITY;
        }
        f->active[i] = rng_uniform(&r) >= 0.1;
    }
    return true;
}

static bool fixture_init(struct fixture *f, uint64_t seed)
{
    return fixture_init_scene(f, SCENE, seed);
}

static void fixture_free(struct fixture *f)
{
    scene_destroy(&f->sc);
    config_free(&f->cfg);
}

static void fill(struct ray_stream *s, const struct fixture *f, int n)
{
    for (int i = 0; i < n; ++i) {
        if (f->active[i]) ray_stream_set(s, i, f->rays[i].o, f->rays[i].d, f->rays[i].tmax);
        else ray_stream_skip(s, i);
    }
}

static void test_occluded_matches_one(void)
{
    static struct fixture f;
    if (!fixture_init(&f, 3)) {
        CHECK(false);
        return;
    }
    struct ray_stream s;
    CHECK(ray_stream_init(&s, N_RAYS, NULL));
    long blocked = 0, clear = 0, differ = 0;
    /* A whole stream, a stream shorter than one vector, and none. */
    const int sizes[] = { N_RAYS, 5, 0 };
    for (int si = 0; si < 3; ++si) {
        int n = sizes[si];
        fill(&s, &f, n);
        scene_occluded_stream(&f.sc, &s, n, false);
        for (int i = 0; i < n; ++i) {
            const struct scene_ray *ray = &f.rays[i];
            bool want = f.active[i] && scene_occluded(&f.sc, ray->o, ray->d, ray->tmax);
            differ += ray_stream_blocked(&s, i) != want;
            if (f.active[i] && n == N_RAYS) {
                blocked += want;
                clear += !want;
            }
        }
    }
    fprintf(stderr, "  %ld blocked, %ld clear\n", blocked, clear);
    CHECK_MSG(differ == 0, "%ld rays differ", differ);
    CHECK(blocked > 500 && clear > 500);
    ray_stream_free(&s);
    fixture_free(&f);
}

/* scene_occluded_grouped (the rays ordered by group, traced as a coherent
   stream, results written back in place) gives each ray the answer of the
   one-ray query: with many groups (more than the function folds them
   into, so that groups share a slot), with rays already in group order,
   and with no rays. Inactive rays stay unblocked. */
static void test_occluded_grouped_matches_one(void)
{
    static struct fixture f;
    if (!fixture_init(&f, 7)) {
        CHECK(false);
        return;
    }
    struct ray_stream s, packed;
    CHECK(ray_stream_init(&s, N_RAYS, NULL));
    CHECK(ray_stream_init(&packed, N_RAYS, NULL));
    static int group[N_RAYS], order[N_RAYS];
    struct rng r;
    rng_seed(&r, 9, 0, 0);
    long differ = 0, blocked = 0;
    /* Shuffled groups 0..39; the same sorted (the in-order path); a single
       group; a stream shorter than one vector; none. */
    const int sizes[] = { N_RAYS, N_RAYS, N_RAYS, 5, 0 };
    for (int si = 0; si < 5; ++si) {
        int n = sizes[si];
        for (int i = 0; i < n; ++i)
            group[i] = si == 1 ? i * 16 / N_RAYS : si == 2 ? 3 : (int)(rng_uniform(&r) * 40.0) % 40;
        fill(&s, &f, n);
        scene_occluded_grouped(&f.sc, &s, n, group, &packed, order);
        for (int i = 0; i < n; ++i) {
            const struct scene_ray *ray = &f.rays[i];
            bool want = f.active[i] && scene_occluded(&f.sc, ray->o, ray->d, ray->tmax);
            differ += ray_stream_blocked(&s, i) != want;
            if (n == N_RAYS) blocked += want;
            /* The ray itself is unchanged but for tfar (blocked: -inf). */
            if (f.active[i])
                differ += s.ox[i] != (float)ray->o.x || s.dz[i] != (float)ray->d.z ||
                          (!want && s.tfar[i] != ray_stream_tfar(ray->tmax));
        }
    }
    fprintf(stderr, "  %ld blocked over the three full streams\n", blocked);
    CHECK_MSG(differ == 0, "%ld rays differ", differ);
    CHECK(blocked > 1500);
    ray_stream_free(&packed);
    ray_stream_free(&s);
    fixture_free(&f);
}

static void test_first_light_matches_one(void)
{
    static struct fixture f;
    if (!fixture_init(&f, 5)) {
        CHECK(false);
        return;
    }
    struct ray_stream s;
    CHECK(ray_stream_init(&s, N_RAYS, NULL));
    static int light[N_RAYS];
    long reach = 0, surface_or_none = 0, differ = 0;
    const int sizes[] = { N_RAYS, 5, 0 };
    for (int si = 0; si < 3; ++si) {
        int n = sizes[si];
        fill(&s, &f, n);
        for (int i = 0; i < n; ++i) light[i] = 1234;
        scene_first_light_stream(&f.sc, &s, n, light);
        for (int i = 0; i < n; ++i) {
            const struct scene_ray *ray = &f.rays[i];
            int want = f.active[i] ? scene_first_light(&f.sc, ray->o, ray->d, ray->tmax) : -1;
            differ += light[i] != want;
            if (f.active[i] && n == N_RAYS) {
                reach += want >= 0;
                surface_or_none += want < 0;
            }
        }
    }
    /* The same stream again with rays that leave the scene (from outside
       its box, pointing away): all miss, also where the rays before hit
       the light (no hit is left over from the trace before). */
    fill(&s, &f, N_RAYS);
    scene_first_light_stream(&f.sc, &s, N_RAYS, light);
    long misses = 0;
    struct vec3 centre = vec3_scale(vec3_add(f.sc.bounds_lo, f.sc.bounds_hi), 0.5);
    double radius = vec3_length(vec3_sub(f.sc.bounds_hi, f.sc.bounds_lo));
    for (int i = 0; i < N_RAYS; ++i) {
        struct vec3 d = vec3_normalize(vec3_sub(f.rays[i].o, centre));
        ray_stream_set(&s, i, vec3_madd(centre, d, radius), d, INFINITY);
    }
    scene_first_light_stream(&f.sc, &s, N_RAYS, light);
    for (int i = 0; i < N_RAYS; ++i) misses += light[i] == -1;
    CHECK_MSG(misses == N_RAYS, "%ld of %d rays leaving the scene hit a light", N_RAYS - misses, (int)N_RAYS);
    fprintf(stderr, "  %ld reach the light, %ld do not\n", reach, surface_or_none);
    CHECK_MSG(differ == 0, "%ld rays differ", differ);
    CHECK(reach > 200 && surface_or_none > 500);
    ray_stream_free(&s);
    fixture_free(&f);
}

/* Whether Embree's float arithmetic may decide ray o + t d, t in
   (0, tmax), either way at light l: its exact (double) crossing of the
   light's plane lies within float rounding of the segment's end or of the
   polygon's rim. A float coordinate of the ray is off by up to ~2e-7 here
   (6e-8 relative, coordinates below 4), which moves the crossing by that
   over the cosine with the plane; 1e-6 leaves five times that. */
static bool ambiguous_at(const struct light *l, struct vec3 o, struct vec3 d, double tmax)
{
    double t, cos = fabs(vec3_dot(d, l->target.normal));
    if (!polygon_intersect_ray(&l->target.polygon, o, d, &t)) {
        /* Missed: ambiguous only if the plane is crossed near the rim. */
        double den = vec3_dot(d, l->target.normal);
        if (den == 0.0) return false;
        t = vec3_dot(vec3_sub(l->target.polygon.v[0], o), l->target.normal) / den;
        if (!(t > 0.0)) return false;
    }
    double tol = 1e-6 / (cos > 1e-6 ? cos : 1e-6);
    if (fabs(t - tmax) <= tol) return true;
    struct vec3 x = vec3_madd(o, d, t);
    const struct polygon *poly = &l->target.polygon;
    for (int k = 0; k < poly->n; ++k) {
        struct vec3 a = poly->v[k], e = vec3_sub(poly->v[(k + 1) % poly->n], a);
        double along = vec3_dot(vec3_sub(x, a), e) / vec3_length2(e);
        along = along < 0.0 ? 0.0 : along > 1.0 ? 1.0 : along;
        if (vec3_length(vec3_sub(x, vec3_madd(a, e, along))) <= tol) return true;
    }
    return false;
}

/* scene_first_light looks at the lights alone (as planes, light_hit.h, or
   through their own Embree scene for a mesh light) and then traces the
   segment before the light it met: the same answer as the closest hit of
   the whole scene (what it stands for), on the lampshade, the room of
   several lamps and a lamp whose bulb is a mesh light. The planes are
   exact where Embree rounds the ray to floats: only rays that float
   rounding may decide either way (ambiguous_at) may differ, and they are
   rare. */
static void test_first_light_is_closest_hit(void)
{
    const char *scenes[] = { SCENE, "configs/scenes/multi_lamp.yaml", "configs/scenes/little_lamp.yaml" };
    for (int k = 0; k < 3; ++k) {
        static struct fixture f;
        if (!fixture_init_scene(&f, scenes[k], 11 + (uint64_t)k)) {
            CHECK(false);
            return;
        }
        long reach = 0, differ = 0, unexplained = 0;
        for (int i = 0; i < N_RAYS; ++i) {
            const struct scene_ray *ray = &f.rays[i];
            struct hit h;
            int want = scene_intersect(&f.sc, ray->o, ray->d, ray->tmax, &h) ? h.light : -1;
            int got = scene_first_light(&f.sc, ray->o, ray->d, ray->tmax);
            reach += want >= 0;
            if (got == want) continue;
            ++differ;
            bool explained = false;
            for (int l = 0; l < f.sc.n_lights && !explained; ++l)
                explained = (l == got || l == want) && ambiguous_at(&f.sc.lights[l], ray->o, ray->d, ray->tmax);
            unexplained += !explained;
        }
        fprintf(stderr, "  %s: %ld of %d rays reach a light first, %ld decided within float rounding differ\n",
                scenes[k], reach, (int)N_RAYS, differ);
        CHECK_MSG(unexplained == 0, "%s: %ld rays differ beyond float rounding", scenes[k], unexplained);
        CHECK_MSG(differ <= N_RAYS / 1000, "%s: %ld rays differ", scenes[k], differ);
        CHECK(reach > 200);
        fixture_free(&f);
    }
}

/* Whether two hits are the same, bit for bit (every field the renderer
   reads). */
static bool same_hit(const struct hit *a, const struct hit *b)
{
    return memcmp(&a->t, &b->t, sizeof a->t) == 0 && memcmp(&a->p, &b->p, sizeof a->p) == 0 &&
           memcmp(&a->ng, &b->ng, sizeof a->ng) == 0 && a->material == b->material && a->light == b->light;
}

/* The closest hits of a stream (scene_intersect_stream: the path
   integrator's bounce rays) and of rays from one point
   (scene_intersect_coherent: a film row's camera rays) are those of
   scene_intersect, ray by ray and bit for bit (their points and normals
   are computed in vectorised blocks, the one-ray hit one at a time), and
   misses are misses. Sizes that fill no whole block or chunk, one ray,
   and none. */
static void test_intersect_matches_one(void)
{
    static struct fixture f;
    static struct vec3 o[N_RAYS], d[N_RAYS];
    static struct hit hits[N_RAYS];
    static bool found[N_RAYS];
    if (!fixture_init(&f, 5)) {
        CHECK(false);
        return;
    }
    struct ray_stream s;
    CHECK(ray_stream_init(&s, N_RAYS, NULL));
    long hit_light = 0, hit_surface = 0, missed = 0, differ = 0;
    const int sizes[] = { N_RAYS, 300, 17, 1, 0 };
    for (int si = 0; si < 5; ++si) {
        int n = sizes[si];
        /* As the path integrator traces them: active, unbounded. */
        for (int i = 0; i < n; ++i) {
            o[i] = f.rays[i].o;
            d[i] = f.rays[i].d;
            ray_stream_set(&s, i, o[i], d[i], INFINITY);
        }
        scene_intersect_stream(&f.sc, &s, n, o, d, hits, found);
        for (int i = 0; i < n; ++i) {
            struct hit want;
            bool want_found = scene_intersect(&f.sc, o[i], d[i], INFINITY, &want);
            differ += found[i] != want_found || (want_found && !same_hit(&hits[i], &want));
            if (n == N_RAYS) {
                hit_light += want_found && want.light >= 0;
                hit_surface += want_found && want.light < 0;
                missed += !want_found;
            }
        }
        /* From one point: the fixture's first origin, its directions. */
        scene_intersect_coherent(&f.sc, o[0], d, n, &s, hits, found);
        for (int i = 0; i < n; ++i) {
            struct hit want;
            bool want_found = scene_intersect(&f.sc, o[0], d[i], INFINITY, &want);
            differ += found[i] != want_found || (want_found && !same_hit(&hits[i], &want));
        }
    }
    fprintf(stderr, "  %ld rays hit a light, %ld a surface, %ld nothing\n", hit_light, hit_surface, missed);
    CHECK_MSG(differ == 0, "%ld hits differ", differ);
    CHECK(hit_light > 200 && hit_surface > 1000);
    ray_stream_free(&s);
    fixture_free(&f);
}

static const struct test_case tests[] = {
    { "first_light_is_closest_hit", test_first_light_is_closest_hit },
    { "occluded_matches_one", test_occluded_matches_one },
    { "occluded_grouped_matches_one", test_occluded_grouped_matches_one },
    { "first_light_matches_one", test_first_light_matches_one },
    { "intersect_matches_one", test_intersect_matches_one },
};

TEST_MAIN(tests)

/* test_light_hit.c: the first polygon light along a ray by planes
   (light_hit.c) against the one-polygon ray test (polygon_intersect_ray)
   on random convex lights and rays, its segment and inactive-ray rules,
   its limits, and which scenes use it. */
#include <math.h>

#include "scene/light_hit.h"
#include "geometry/polygon.h"
#include "polygon_util.h"
#include "base/rng.h"
#include "scene_util.h"
#include "testlib.h"

enum { N_LIGHTS = 6, N_RAYS = 20000 };

static double uniform(struct rng *r, double lo, double hi)
{
    return lo + (hi - lo) * rng_uniform(r);
}

/* A regular n-gon of radius rad about c in the plane spanned by the unit
   vectors a and b (counter-clockwise about a x b). */
static struct polygon ngon(int n, struct vec3 c, struct vec3 a, struct vec3 b, double rad)
{
    struct polygon p;
    p.n = n;
    for (int k = 0; k < n; ++k) {
        double phi = 2.0 * M_PI * k / n;
        p.v[k] = vec3_add(c, vec3_add(vec3_scale(a, rad * cos(phi)), vec3_scale(b, rad * sin(phi))));
    }
    return p;
}

static struct vec3 random_unit(struct rng *r)
{
    double z = uniform(r, -1.0, 1.0), phi = uniform(r, 0.0, 2.0 * M_PI), s = sqrt(1.0 - z * z);
    return vec3_make(s * cos(phi), s * sin(phi), z);
}

/* N_LIGHTS random n-gons (3 to 10 vertices) in [-1, 1]^3, in random
   orientations. */
static void random_lights(struct rng *r, struct light *lights)
{
    for (int l = 0; l < N_LIGHTS; ++l) {
        struct vec3 nrm = random_unit(r);
        struct vec3 a = vec3_normalize(vec3_cross(nrm, fabs(nrm.x) < 0.9 ? vec3_make(1, 0, 0) : vec3_make(0, 1, 0)));
        struct vec3 b = vec3_cross(nrm, a);
        struct vec3 c = vec3_make(uniform(r, -1, 1), uniform(r, -1, 1), uniform(r, -1, 1));
        struct polygon p = ngon(3 + (int)(rng_uniform(r) * 8), c, a, b, uniform(r, 0.1, 0.6));
        bool ok = light_init(&lights[l], &p, rgb_make(1, 1, 1), false);
        CHECK(ok);
    }
}

/* Rays from random points towards random points of the box or of a light
   (both faces), a third of them bounded before the point they aim at: the
   light found and its distance are those of the nearest light that
   polygon_intersect_ray meets within the segment, on the float ray. Only
   a crossing within 1e-9 of a rim (where polygon_intersect_ray's tolerance
   and the exact edge planes may disagree) is allowed to differ. */
static void test_matches_polygon_test(void)
{
    struct rng r;
    rng_seed(&r, 5, 0, 0);
    struct light lights[N_LIGHTS];
    random_lights(&r, lights);
    struct light_hit_set set;
    CHECK(light_hit_set_init(&set, lights, N_LIGHTS));
    static float ox[N_RAYS], oy[N_RAYS], oz[N_RAYS], dx[N_RAYS], dy[N_RAYS], dz[N_RAYS], tn[N_RAYS], tf[N_RAYS];
    static int got[N_RAYS];
    static double got_t[N_RAYS];
    for (int i = 0; i < N_RAYS; ++i) {
        struct vec3 o = vec3_make(uniform(&r, -1.5, 1.5), uniform(&r, -1.5, 1.5), uniform(&r, -1.5, 1.5));
        struct vec3 to = rng_uniform(&r) < 0.5
                             ? lights[i % N_LIGHTS].centroid
                             : vec3_make(uniform(&r, -1.5, 1.5), uniform(&r, -1.5, 1.5), uniform(&r, -1.5, 1.5));
        to = vec3_add(to, vec3_scale(random_unit(&r), uniform(&r, 0.0, 0.4)));
        double dist = vec3_length(vec3_sub(to, o));
        struct vec3 d = vec3_scale(vec3_sub(to, o), 1.0 / dist);
        ox[i] = (float)o.x, oy[i] = (float)o.y, oz[i] = (float)o.z;
        dx[i] = (float)d.x, dy[i] = (float)d.y, dz[i] = (float)d.z;
        tn[i] = 0.0f;
        tf[i] = rng_uniform(&r) < 0.33 ? (float)(dist * uniform(&r, 0.2, 1.0)) : INFINITY;
    }
    light_hit_many(&set, ox, oy, oz, dx, dy, dz, tn, tf, N_RAYS, got, got_t);
    long hits = 0, bad = 0, near_rim = 0;
    for (int i = 0; i < N_RAYS; ++i) {
        struct vec3 o = vec3_make(ox[i], oy[i], oz[i]), d = vec3_make(dx[i], dy[i], dz[i]);
        int want = -1;
        double want_t = INFINITY;
        bool at_rim = false;
        for (int l = 0; l < N_LIGHTS; ++l) {
            double t;
            if (polygon_intersect_ray(&lights[l].target.polygon, o, d, &t) && t <= tf[i] && t < want_t)
                want = l, want_t = t;
            /* Any crossing of a plane near its rim may go either way. */
            double den = vec3_dot(d, lights[l].target.normal);
            double tp = vec3_dot(vec3_sub(lights[l].target.polygon.v[0], o), lights[l].target.normal) / den;
            if (tp > 0.0 && test_rim_distance(&lights[l].target.polygon, vec3_madd(o, d, tp)) < 1e-9) at_rim = true;
        }
        hits += want >= 0;
        if (at_rim) {
            ++near_rim;
            continue;
        }
        bad += got[i] != want || (want >= 0 && !(fabs(got_t[i] - want_t) <= 1e-12 * (1.0 + want_t)));
    }
    fprintf(stderr, "  %ld of %d rays meet a light, %ld cross a plane within 1e-9 of its rim\n", hits, (int)N_RAYS,
            near_rim);
    CHECK_MSG(bad == 0, "%ld rays differ", bad);
    CHECK(hits > N_RAYS / 10);
    CHECK(near_rim < 10);
}

/* The segment is [tnear, tfar]; an inactive ray (tnear > tfar) meets
   nothing; both faces count. One square at z = 0 facing +z. */
static void test_segment_and_faces(void)
{
    struct polygon p = ngon(4, vec3_make(0, 0, 0), vec3_make(1, 0, 0), vec3_make(0, 1, 0), 1.0);
    struct light l;
    CHECK(light_init(&l, &p, rgb_make(1, 1, 1), false));
    struct light_hit_set set;
    CHECK(light_hit_set_init(&set, &l, 1));
    /* From z = 2 down (front face) and from z = -2 up (back face), with
       segments ending before the light, at it, after it; then inactive. */
    float ox[8] = { 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f, 0.1f }, oy[8] = { 0 };
    float oz[8] = { 2, 2, 2, -2, -2, -2, 2, 2 };
    float dx[8] = { 0 }, dy[8] = { 0 }, dz[8] = { -1, -1, -1, 1, 1, 1, -1, -1 };
    float tn[8] = { 0, 0, 0, 0, 0, 0, 1, 2.5f }, tf[8] = { 1.5f, 2, INFINITY, 1.5f, 2, INFINITY, 0, 3 };
    int want[8] = { -1, 0, 0, -1, 0, 0, -1, -1 };
    int got[8];
    double t[8];
    light_hit_many(&set, ox, oy, oz, dx, dy, dz, tn, tf, 8, got, t);
    for (int i = 0; i < 8; ++i) {
        CHECK_MSG(got[i] == want[i], "ray %d: light %d, want %d", i, got[i], want[i]);
        if (want[i] == 0) CHECK_NEAR(t[i], 2.0, 1e-15);
    }
}

/* More lights or edges than the limits: refused, so that the scene keeps
   Embree's trace. */
static void test_limits(void)
{
    static struct light lights[LIGHT_HIT_MAX_LIGHTS + 1];
    for (int l = 0; l <= LIGHT_HIT_MAX_LIGHTS; ++l) {
        struct polygon p = ngon(3, vec3_make(3.0 * l, 0, 0), vec3_make(1, 0, 0), vec3_make(0, 1, 0), 1.0);
        CHECK(light_init(&lights[l], &p, rgb_make(1, 1, 1), false));
    }
    struct light_hit_set set;
    CHECK(light_hit_set_init(&set, lights, LIGHT_HIT_MAX_LIGHTS));
    CHECK(!light_hit_set_init(&set, lights, LIGHT_HIT_MAX_LIGHTS + 1));
    for (int l = 0; l < 3; ++l) {
        struct polygon p =
            ngon(POLYGON_INPUT_MAX, vec3_make(3.0 * l, 0, 0), vec3_make(1, 0, 0), vec3_make(0, 1, 0), 1.0);
        CHECK(light_init(&lights[l], &p, rgb_make(1, 1, 1), false));
    }
    CHECK(light_hit_set_init(&set, lights, 2));  /* 64 edges */
    CHECK(!light_hit_set_init(&set, lights, 3)); /* 96 */
}

/* The scenes of polygon lights use the planes, a scene with a mesh light
   Embree's trace of its lights. */
static void test_which_scenes(void)
{
    const char *scenes[] = { "configs/scenes/lampshade.yaml", "configs/scenes/multi_lamp.yaml",
                             "configs/scenes/little_lamp.yaml" };
    bool want[] = { true, true, false };
    for (int k = 0; k < 3; ++k) {
        struct config cfg;
        struct scene sc;
        if (!test_scene_load(scenes[k], NULL, 0, &cfg, &sc)) {
            CHECK(false);
            continue;
        }
        CHECK_MSG((sc.light_hits != NULL) == want[k], "%s: planes %d", scenes[k], sc.light_hits != NULL);
        if (sc.light_hits) CHECK(sc.light_hits->n_lights == sc.n_lights);
        scene_destroy(&sc);
        config_free(&cfg);
    }
}

static const struct test_case tests[] = {
    { "matches_polygon_test", test_matches_polygon_test },
    { "segment_and_faces", test_segment_and_faces },
    { "limits", test_limits },
    { "which_scenes", test_which_scenes },
};

TEST_MAIN(tests)

/* test_transform.c: the affine transforms of `transform:` against closed
   forms: composition order, right-handed rotation, the inverse transpose
   of normals, singular matrices. */
#include "geometry/polygon.h"
#include "testlib.h"
#include "base/transform.h"

static void check_vec(struct vec3 a, struct vec3 b, double tol)
{
    CHECK_NEAR(a.x, b.x, tol);
    CHECK_NEAR(a.y, b.y, tol);
    CHECK_NEAR(a.z, b.z, tol);
}

/* Rodrigues' formula on a vector, the closed form of a rotation. */
static struct vec3 rodrigues(struct vec3 v, struct vec3 k, double deg)
{
    double a = deg * M_PI / 180.0;
    k = vec3_normalize(k);
    return vec3_add(vec3_add(vec3_scale(v, cos(a)), vec3_scale(vec3_cross(k, v), sin(a))),
                    vec3_scale(k, vec3_dot(k, v) * (1.0 - cos(a))));
}

/* [{scale: 2}, {rotate: {axis: [0, 1, 0], angle: -30}}, {translate: [1, 2, 3]}]
   scales first and translates last. */
static void test_composition_order(void)
{
    struct transform s = transform_scale(vec3_make(2, 2, 2)), r, t = transform_translate(vec3_make(1, 2, 3));
    CHECK(transform_rotate(vec3_make(0, 1, 0), -30, &r));
    struct transform sr = transform_then(&s, &r), srt = transform_then(&sr, &t);
    struct vec3 p = vec3_make(0.3, -1.2, 0.7);
    struct vec3 expect = vec3_add(rodrigues(vec3_scale(p, 2.0), vec3_make(0, 1, 0), -30), vec3_make(1, 2, 3));
    check_vec(transform_point(&srt, p), expect, 1e-14);
    /* The other order differs: translating first moves the point, then scales the move. */
    struct transform ts = transform_then(&t, &s);
    check_vec(transform_point(&ts, p), vec3_scale(vec3_add(p, vec3_make(1, 2, 3)), 2.0), 1e-15);
    /* Associativity of transform_then. */
    struct transform rt = transform_then(&r, &t), s_rt = transform_then(&s, &rt);
    check_vec(transform_point(&s_rt, p), expect, 1e-14);
    /* The identity is exact. */
    struct transform id = transform_identity();
    struct vec3 q = transform_point(&id, p);
    CHECK(q.x == p.x && q.y == p.y && q.z == p.z);
}

static void test_rotation_handedness(void)
{
    struct transform r;
    /* A quarter turn about +z takes +x to +y (right-handed), exactly. */
    CHECK(transform_rotate(vec3_make(0, 0, 1), 90, &r));
    struct vec3 y = transform_point(&r, vec3_make(1, 0, 0));
    CHECK(y.x == 0.0 && y.y == 1.0 && y.z == 0.0);
    /* About +x: +y to +z; about +y: +z to +x. */
    CHECK(transform_rotate(vec3_make(2, 0, 0), 90, &r));
    struct vec3 z = transform_point(&r, vec3_make(0, 1, 0));
    CHECK(z.x == 0.0 && z.y == 0.0 && z.z == 1.0);
    CHECK(transform_rotate(vec3_make(0, 0.5, 0), 90, &r));
    struct vec3 x = transform_point(&r, vec3_make(0, 0, 1));
    CHECK(x.x == 1.0 && x.y == 0.0 && x.z == 0.0);
    /* -90 is 270: exact too. */
    CHECK(transform_rotate(vec3_make(0, 0, 1), -90, &r));
    struct vec3 m = transform_point(&r, vec3_make(1, 0, 0));
    CHECK(m.x == 0.0 && m.y == -1.0 && m.z == 0.0);
    /* Closed form about z: (x cos a - y sin a, x sin a + y cos a, z). */
    double a = 37.5, c = cos(a * M_PI / 180), s = sin(a * M_PI / 180);
    CHECK(transform_rotate(vec3_make(0, 0, 3), a, &r));
    check_vec(transform_point(&r, vec3_make(0.4, -0.9, 2)), vec3_make(0.4 * c + 0.9 * s, 0.4 * s - 0.9 * c, 2), 1e-15);
    /* Any axis, against Rodrigues' vector form; a rotation is orthonormal. */
    struct vec3 k = vec3_make(0.3, -0.5, 0.81), v = vec3_make(1.1, 0.2, -0.7);
    CHECK(transform_rotate(k, -123.0, &r));
    check_vec(transform_point(&r, v), rodrigues(v, k, -123.0), 1e-14);
    CHECK_NEAR(transform_det(&r), 1.0, 1e-14);
    CHECK(!transform_is_singular(&r));
    /* The axis itself stays put. */
    check_vec(transform_point(&r, k), k, 1e-15);
    CHECK(!transform_rotate(vec3_make(0, 0, 0), 10, &r));
    CHECK(!transform_rotate(vec3_make(NAN, 0, 1), 10, &r));
}

/* A polygon's normal follows the inverse transpose, for any invertible
   transform: the winding normal of the mapped points (reversed when det <
   0, as the config loader reverses them) equals transform_normal. */
static void test_inverse_transpose(void)
{
    const double rows[16] = { 2, 0.5, 0, 1, 0, 1, 0.3, -2, 0.2, 0, 0.5, 3, 0, 0, 0, 1 };
    struct transform shear, mirror = transform_scale(vec3_make(1, -1, 1)), r, rm;
    CHECK(transform_from_rows(rows, &shear));
    CHECK(transform_rotate(vec3_make(1, 1, 0), 50, &r));
    rm = transform_then(&mirror, &shear);
    const struct transform *cases[] = { &shear, &mirror, &r, &rm };
    struct polygon p;
    p.n = 4;
    p.v[0] = vec3_make(0, 0, 0), p.v[1] = vec3_make(1, 0, 0), p.v[2] = vec3_make(1, 1, 0), p.v[3] = vec3_make(0, 1, 0);
    struct vec3 n = polygon_normal(&p); /* +z */
    for (int c = 0; c < 4; ++c) {
        const struct transform *t = cases[c];
        struct polygon q;
        q.n = 4;
        for (int i = 0; i < 4; ++i) q.v[i] = transform_point(t, p.v[i]);
        if (transform_det(t) < 0.0) {
            struct vec3 tmp = q.v[1];
            q.v[1] = q.v[3];
            q.v[3] = tmp;
        }
        struct vec3 tn = transform_normal(t, n);
        check_vec(polygon_normal(&q), tn, 1e-14);
        /* Perpendicular to every mapped tangent. */
        CHECK_NEAR(vec3_dot(tn, vec3_sub(q.v[2], q.v[0])), 0.0, 1e-14);
        CHECK_NEAR(vec3_length(tn), 1.0, 1e-15);
    }
    CHECK(transform_det(&mirror) == -1.0);
    check_vec(transform_normal(&mirror, vec3_make(0, -1, 0)), vec3_make(0, 1, 0), 0.0);
}

static void test_singular(void)
{
    struct transform t = transform_scale(vec3_make(1, 0, 1));
    CHECK(transform_is_singular(&t));
    const double rank2[16] = { 1, 2, 3, 0, 2, 4, 6, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
    CHECK(transform_from_rows(rank2, &t));
    CHECK(transform_is_singular(&t));
    /* Nearly dependent rows, beyond the tolerance. */
    const double near[16] = { 1, 0, 0, 0, 1, 1e-14, 0, 0, 0, 0, 1, 5, 0, 0, 0, 1 };
    CHECK(transform_from_rows(near, &t));
    CHECK(transform_is_singular(&t));
    /* Tiny but well-conditioned: not singular (the tolerance is relative). */
    t = transform_scale(vec3_make(1e-9, 1e-9, 1e-9));
    CHECK(!transform_is_singular(&t));
    t = transform_scale(vec3_make(-2, 3, 0.5));
    CHECK(!transform_is_singular(&t) && transform_det(&t) == -3.0);
    check_vec(transform_normal(&t, vec3_make(1, 0, 0)), vec3_make(-1, 0, 0), 0.0);
    t = transform_translate(vec3_make(1, 2, 3));
    CHECK(!transform_is_singular(&t));
    /* Not affine: the last row must be 0, 0, 0, 1. */
    const double projective[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0 };
    CHECK(!transform_from_rows(projective, &t));
    struct transform zero = transform_scale(vec3_make(0, 0, 0));
    struct vec3 zn = transform_normal(&zero, vec3_make(0, 0, 1));
    CHECK(zn.x == 0.0 && zn.y == 0.0 && zn.z == 0.0);
}

static const struct test_case tests[] = {
    { "composition_order", test_composition_order },
    { "rotation_handedness", test_rotation_handedness },
    { "inverse_transpose", test_inverse_transpose },
    { "singular", test_singular },
};

TEST_MAIN(tests)

/* test_polygon.c: polygon geometry against closed forms: area, normal,
   centroid, validity checks, clipping, ray hits, solid angle, vector
   irradiance and projected solid angle. */
#include <float.h>
#include <stdint.h>
#include <string.h>

#include "geometry/polygon.h"
#include "testlib.h"

static struct polygon poly_make(int n, const double (*xyz)[3])
{
    struct polygon p;
    p.n = n;
    for (int i = 0; i < n; ++i) p.v[i] = vec3_make(xyz[i][0], xyz[i][1], xyz[i][2]);
    return p;
}

/* Axis-aligned rectangle [x0, x1] x [y0, y1] at height z, counter-clockwise
   seen from +z (normal +z) unless flip. */
static struct polygon rect_xy(double x0, double x1, double y0, double y1, double z, int flip)
{
    double v[4][3] = { { x0, y0, z }, { x1, y0, z }, { x1, y1, z }, { x0, y1, z } };
    struct polygon p = poly_make(4, (const double(*)[3])v);
    if (flip) {
        struct vec3 t = p.v[1];
        p.v[1] = p.v[3];
        p.v[3] = t;
    }
    return p;
}

static struct polygon regular_ngon(int n, double radius, double phase)
{
    struct polygon p;
    p.n = n;
    for (int i = 0; i < n; ++i) {
        double a = phase + 2.0 * M_PI * i / n;
        p.v[i] = vec3_make(radius * cos(a), radius * sin(a), 0.0);
    }
    return p;
}

/* Maps a polygon by x -> origin + R x with R a fixed rotation, so that tests
   do not depend on axis alignment. */
static struct vec3 rotate(struct vec3 x)
{
    /* Rotation from an orthonormal basis built of a unit axis. */
    struct frame f = frame_from_normal(vec3_normalize(vec3_make(0.3, -0.5, 0.81)));
    return frame_to_world(&f, x);
}

static struct polygon poly_transform(const struct polygon *in, struct vec3 origin)
{
    struct polygon p = *in;
    for (int i = 0; i < p.n; ++i) p.v[i] = vec3_add(origin, rotate(in->v[i]));
    return p;
}

static void test_area_normal_centroid(void)
{
    struct polygon sq = rect_xy(0, 1, 0, 1, 0, 0);
    CHECK_NEAR(polygon_area(&sq), 1.0, 1e-15);
    struct vec3 n = polygon_normal(&sq);
    CHECK_NEAR(n.z, 1.0, 1e-15);
    struct polygon cw = rect_xy(0, 1, 0, 1, 0, 1);
    CHECK_NEAR(polygon_normal(&cw).z, -1.0, 1e-15);
    CHECK_NEAR(vec3_length(polygon_area_normal(&sq)), 2.0, 1e-15);
    struct vec3 c = polygon_centroid(&sq);
    CHECK_NEAR(c.x, 0.5, 1e-15);
    CHECK_NEAR(c.y, 0.5, 1e-15);

    /* Regular hexagon of circumradius r: area 3 sqrt(3) / 2 r^2. */
    struct polygon hex = regular_ngon(6, 2.0, 0.3);
    CHECK_NEAR(polygon_area(&hex), 3.0 * sqrt(3.0) / 2.0 * 4.0, 1e-13);

    /* Trapezoid (0,0) (4,0) (3,2) (1,2): area 6, centroid (2, 8/9): the area
       centroid, not the vertex mean (2, 1). */
    const double tz[4][3] = { { 0, 0, 0 }, { 4, 0, 0 }, { 3, 2, 0 }, { 1, 2, 0 } };
    struct polygon trap = poly_make(4, tz);
    CHECK_NEAR(polygon_area(&trap), 6.0, 1e-14);
    c = polygon_centroid(&trap);
    CHECK_NEAR(c.x, 2.0, 1e-14);
    CHECK_NEAR(c.y, 8.0 / 9.0, 1e-14);

    /* Far from the origin, rotated: the same numbers to relative 1e-9. */
    struct vec3 far = vec3_make(1e5, -3e5, 2e5);
    struct polygon tf = poly_transform(&trap, far);
    CHECK_NEAR(polygon_area(&tf), 6.0, 6e-9);
    struct vec3 cf = vec3_sub(polygon_centroid(&tf), vec3_add(far, rotate(vec3_make(2.0, 8.0 / 9.0, 0.0))));
    CHECK(vec3_length(cf) < 1e-9 * 3e5);
    struct vec3 nf = polygon_normal(&tf), nz = rotate(vec3_make(0, 0, 1));
    CHECK_NEAR(vec3_dot(nf, nz), 1.0, 1e-12);
    struct plane pl = polygon_plane(&tf);
    for (int i = 0; i < tf.n; ++i) CHECK(fabs(plane_distance(&pl, tf.v[i])) < 1e-9);

    /* Degenerate: collinear points have a zero normal. */
    const double line[3][3] = { { 0, 0, 0 }, { 1, 1, 1 }, { 2, 2, 2 } };
    struct polygon deg = poly_make(3, line);
    CHECK(vec3_length(polygon_normal(&deg)) == 0.0);
}

static void test_planar_convex(void)
{
    struct polygon sq = rect_xy(0, 1, 0, 1, 0, 0), cw = rect_xy(0, 1, 0, 1, 0, 1);
    CHECK(polygon_is_planar(&sq, 1e-9) && polygon_is_convex(&sq));
    CHECK(polygon_is_planar(&cw, 1e-9) && polygon_is_convex(&cw));
    struct polygon hex = regular_ngon(8, 1.0, 0.1);
    hex = poly_transform(&hex, vec3_make(3, 2, 1));
    CHECK(polygon_is_planar(&hex, 1e-9) && polygon_is_convex(&hex));
    const double tri[3][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 0, 1, 0 } };
    struct polygon t = poly_make(3, tri);
    CHECK(polygon_is_planar(&t, 1e-9) && polygon_is_convex(&t));

    /* Dart: reflex corner at (0.5, 1). */
    const double dart[4][3] = { { 0, 0, 0 }, { 2, 1, 0 }, { 0, 2, 0 }, { 0.5, 1, 0 } };
    struct polygon d = poly_make(4, dart);
    CHECK(polygon_is_planar(&d, 1e-9));
    CHECK(!polygon_is_convex(&d));
    /* Bow-ties: symmetric (zero net area) and lopsided. */
    const double bow[4][3] = { { 0, 0, 0 }, { 1, 1, 0 }, { 1, 0, 0 }, { 0, 1, 0 } };
    struct polygon b = poly_make(4, bow);
    CHECK(!polygon_is_convex(&b));
    const double bow2[4][3] = { { 0, 0, 0 }, { 3, 2, 0 }, { 3, 0, 0 }, { 0, 1, 0 } };
    b = poly_make(4, bow2);
    CHECK(!polygon_is_convex(&b));
    /* Pentagram: every turn is to the left, but it winds twice. */
    struct polygon star;
    star.n = 5;
    for (int i = 0; i < 5; ++i) star.v[i] = vec3_make(cos(4.0 * M_PI * i / 5), sin(4.0 * M_PI * i / 5), 0);
    CHECK(polygon_is_planar(&star, 1e-9));
    CHECK(!polygon_is_convex(&star));
    /* Collinear vertex, repeated vertex. */
    const double col[5][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 2, 0, 0 }, { 2, 2, 0 }, { 0, 2, 0 } };
    struct polygon cl = poly_make(5, col);
    CHECK(!polygon_is_convex(&cl));
    const double rep[5][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0 }, { 0, 1, 0 } };
    struct polygon rp = poly_make(5, rep);
    CHECK(!polygon_is_convex(&rp));
    /* Non-planar quad: one corner lifted by 10% of the size; a lift of
       1e-12 passes at a tolerance of 1e-9. */
    const double np[4][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0.1 }, { 0, 1, 0 } };
    struct polygon q = poly_make(4, np);
    CHECK(!polygon_is_planar(&q, 1e-6));
    q.v[2].z = 1e-12;
    CHECK(polygon_is_planar(&q, 1e-9));
    /* Too few vertices. */
    struct polygon two = sq;
    two.n = 2;
    CHECK(!polygon_is_planar(&two, 1e-9) && !polygon_is_convex(&two));
}

/* polygon_check: the first defect in the order degenerate, not planar, not
   convex; tolerances relative to the size, so scale does not matter. */
static void test_check(void)
{
    struct polygon sq = rect_xy(0, 1, 0, 1, 0, 0);
    CHECK_NEAR(polygon_diameter(&sq), sqrt(2.0), 1e-15);
    CHECK(polygon_check(&sq) == POLYGON_DEFECT_NONE);
    struct polygon oct = regular_ngon(8, 1.0, 0.1);
    oct = poly_transform(&oct, vec3_make(3, 2, 1));
    CHECK(polygon_check(&oct) == POLYGON_DEFECT_NONE);
    const double scales[] = { 1e-3, 1.0, 1e3 };
    for (int k = 0; k < 3; ++k) {
        /* Planar: a lift of a tenth of the tolerance passes, ten times it fails. */
        const double np[4][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0 }, { 0, 1, 0 } };
        struct polygon q = poly_make(4, np);
        for (int i = 0; i < 4; ++i) q.v[i] = vec3_scale(q.v[i], scales[k]);
        q.v[2].z = 0.1 * POLYGON_PLANARITY_TOLERANCE * scales[k];
        CHECK(polygon_check(&q) == POLYGON_DEFECT_NONE);
        q.v[2].z = 10.0 * POLYGON_PLANARITY_TOLERANCE * scales[k];
        CHECK(polygon_check(&q) == POLYGON_DEFECT_NOT_PLANAR);
        q.v[2].z = 0.1 * scales[k];
        CHECK(polygon_check(&q) == POLYGON_DEFECT_NOT_PLANAR);
    }
    /* Not convex: a dart (reflex corner), a lopsided bow-tie. */
    const double dart[4][3] = { { 0, 0, 0 }, { 2, 1, 0 }, { 0, 2, 0 }, { 0.5, 1, 0 } };
    struct polygon d = poly_make(4, dart);
    CHECK(polygon_check(&d) == POLYGON_DEFECT_NOT_CONVEX);
    const double bow2[4][3] = { { 0, 0, 0 }, { 3, 2, 0 }, { 3, 0, 0 }, { 0, 1, 0 } };
    struct polygon b = poly_make(4, bow2);
    CHECK(polygon_check(&b) == POLYGON_DEFECT_NOT_CONVEX);
    /* Degenerate, reported before the planarity it also fails: collinear
       points, a sliver of height 1e-11 of its length, one repeated point,
       and a symmetric bow-tie (zero net area). */
    const double line[3][3] = { { 0, 0, 0 }, { 1, 1, 1 }, { 2, 2, 2 } };
    struct polygon deg = poly_make(3, line);
    CHECK(polygon_check(&deg) == POLYGON_DEFECT_DEGENERATE);
    const double sliver[3][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 0.5, 1e-11, 0 } };
    deg = poly_make(3, sliver);
    CHECK(polygon_check(&deg) == POLYGON_DEFECT_DEGENERATE);
    const double point[3][3] = { { 1, 2, 3 }, { 1, 2, 3 }, { 1, 2, 3 } };
    deg = poly_make(3, point);
    CHECK(polygon_check(&deg) == POLYGON_DEFECT_DEGENERATE);
    CHECK(polygon_diameter(&deg) == 0.0);
    const double bow[4][3] = { { 0, 0, 0 }, { 1, 1, 0 }, { 1, 0, 0 }, { 0, 1, 0 } };
    deg = poly_make(4, bow);
    CHECK(polygon_check(&deg) == POLYGON_DEFECT_DEGENERATE);
}

static bool all_inside(const struct polygon *p, const struct polygon *a, const struct polygon *b)
{
    for (int i = 0; i < p->n; ++i)
        if (!polygon_contains(a, p->v[i]) || !polygon_contains(b, p->v[i])) return false;
    return true;
}

static void test_clip_convex(void)
{
    struct polygon a = rect_xy(0, 2, 0, 2, 0, 0), b = rect_xy(1, 3, 1, 3, 0, 0), out;
    /* Overlap: the unit square [1,2]^2, for both windings of the clip. */
    for (int flip = 0; flip < 2; ++flip) {
        b = rect_xy(1, 3, 1, 3, 0, flip);
        CHECK(polygon_clip_convex(&a, &b, &out) == 4);
        CHECK_NEAR(polygon_area(&out), 1.0, 1e-14);
        CHECK(all_inside(&out, &a, &b));
        CHECK(polygon_is_convex(&out));
    }
    /* Containment both ways. */
    struct polygon small = rect_xy(0.5, 1.0, 0.25, 1.5, 0, 1);
    CHECK(polygon_clip_convex(&small, &a, &out) == 4);
    CHECK_NEAR(polygon_area(&out), 0.625, 1e-14);
    CHECK(polygon_clip_convex(&a, &small, &out) == 4);
    CHECK_NEAR(polygon_area(&out), 0.625, 1e-14);
    /* Identical squares: the square itself, no duplicate vertices. */
    CHECK(polygon_clip_convex(&a, &a, &out) == 4);
    CHECK_NEAR(polygon_area(&out), 4.0, 1e-14);
    /* Disjoint, touching along an edge, touching at a corner: empty. */
    b = rect_xy(3, 4, 0, 2, 0, 0);
    CHECK(polygon_clip_convex(&a, &b, &out) == 0 && out.n == 0);
    b = rect_xy(2, 4, 0, 2, 0, 0);
    CHECK(polygon_clip_convex(&a, &b, &out) == 0);
    b = rect_xy(2, 4, 2, 4, 0, 1);
    CHECK(polygon_clip_convex(&a, &b, &out) == 0);
    /* Square [-1,1]^2 by the diamond |x| + |y| <= 1.5: an octagon of area
       4 - 4 * 0.5^2 / 2 = 3.5. */
    struct polygon sq = rect_xy(-1, 1, -1, 1, 0, 0);
    const double dm[4][3] = { { 1.5, 0, 0 }, { 0, 1.5, 0 }, { -1.5, 0, 0 }, { 0, -1.5, 0 } };
    struct polygon diamond = poly_make(4, dm);
    CHECK(polygon_clip_convex(&sq, &diamond, &out) == 8);
    CHECK_NEAR(polygon_area(&out), 3.5, 1e-14);
    CHECK(polygon_is_convex(&out));
    /* Two octagons rotated by 22.5 degrees: 16 vertices, area in between. */
    struct polygon o1 = regular_ngon(8, 1.0, 0.0), o2 = regular_ngon(8, 1.0, M_PI / 8);
    o1 = poly_transform(&o1, vec3_make(5, 6, 7));
    o2 = poly_transform(&o2, vec3_make(5, 6, 7));
    CHECK(polygon_clip_convex(&o1, &o2, &out) == 16);
    CHECK(polygon_is_convex(&out) && polygon_is_planar(&out, 1e-12));
    CHECK(polygon_area(&out) < polygon_area(&o1) && polygon_area(&out) > 0.9 * polygon_area(&o1));
    /* A subject vertex exactly on a clip edge stays one vertex. */
    const double tr[3][3] = { { 1, 1, 0 }, { 3, 1, 0 }, { 3, 3, 0 } };
    struct polygon tri = poly_make(3, tr);
    CHECK(polygon_clip_convex(&tri, &a, &out) == 3);
    CHECK_NEAR(polygon_area(&out), 0.5, 1e-14);
}

static void test_clip_plane(void)
{
    struct polygon sq = rect_xy(0, 1, 0, 1, 0, 0), out;
    struct plane pl = { vec3_make(1, 0, 0), 0.25 };
    CHECK(polygon_clip_plane(&sq, &pl, &out) == 4);
    CHECK_NEAR(polygon_area(&out), 0.75, 1e-15);
    for (int i = 0; i < out.n; ++i) CHECK(out.v[i].x >= 0.25);
    /* Through two opposite corners: a triangle, corners kept as they are. */
    pl.normal = vec3_normalize(vec3_make(1, -1, 0));
    pl.offset = 0.0;
    CHECK(polygon_clip_plane(&sq, &pl, &out) == 3);
    CHECK_NEAR(polygon_area(&out), 0.5, 1e-15);
    /* Fully inside, fully outside, touching one corner, in place. */
    pl.normal = vec3_make(0, 0, 1);
    pl.offset = -1.0;
    CHECK(polygon_clip_plane(&sq, &pl, &out) == 4);
    pl.offset = 1.0;
    CHECK(polygon_clip_plane(&sq, &pl, &out) == 0);
    pl.normal = vec3_normalize(vec3_make(1, 1, 0));
    pl.offset = sqrt(2.0);
    CHECK(polygon_clip_plane(&sq, &pl, &out) == 0);
    pl.offset = 0.5 * sqrt(2.0);
    struct polygon inplace = sq;
    CHECK(polygon_clip_plane(&inplace, &pl, &inplace) == 3);
    CHECK_NEAR(polygon_area(&inplace), 0.5, 1e-15);
    /* Tilted plane on a rotated square away from the origin. */
    struct polygon t = poly_transform(&sq, vec3_make(10, -20, 30));
    pl.normal = rotate(vec3_make(0, 1, 0));
    pl.offset = vec3_dot(pl.normal, vec3_add(vec3_make(10, -20, 30), rotate(vec3_make(0, 0.4, 0))));
    CHECK(polygon_clip_plane(&t, &pl, &out) == 4);
    CHECK_NEAR(polygon_area(&out), 0.6, 1e-12);
    /* Near-duplicates are merged: a plane 5e-11 inside the hypotenuse of a
       unit right triangle cuts the legs 5e-11 from the corners it keeps;
       what remains is a sliver with no area worth a polygon. A plane 1e-13
       off the corners snaps to them: the triangle is kept unchanged. */
    const double rt[3][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 0, 1, 0 } };
    struct polygon tri = poly_make(3, rt);
    pl.normal = vec3_normalize(vec3_make(1, 1, 0));
    pl.offset = (1.0 - 5e-11) / sqrt(2.0);
    CHECK(polygon_clip_plane(&tri, &pl, &out) == 0);
    pl.offset = 1e-13;
    pl.normal = vec3_make(1, 0, 0);
    CHECK(polygon_clip_plane(&tri, &pl, &out) == 3);
    /* A POLYGON_MAX-gon (96) losing one corner would need 97 vertices:
       capped at POLYGON_MAX by dropping the least significant vertex. */
    struct polygon big = regular_ngon(POLYGON_MAX, 1.0, 0.0);
    pl.normal = vec3_make(-1, 0, 0);
    pl.offset = -0.999;
    CHECK(polygon_clip_plane(&big, &pl, &out) == POLYGON_MAX);
    /* The corner cut off loses 3.05e-5; dropping the least-area vertex (one
       of the two new ones) 3.49e-5 more, of an area of 3.1. */
    double lost = polygon_area(&big) - polygon_area(&out);
    CHECK(lost > 6.4e-5 && lost < 6.7e-5);
    CHECK(polygon_is_convex(&out));
}

/* The largest clip the renderer makes: a light of POLYGON_INPUT_MAX (32)
   vertices clipped to a portal of 32 (the anti-penumbra's visible polygon),
   then to a horizon plane (polygon_projected_solid_angle). Two regular
   32-gons turned by half a step meet in a regular 64-gon (every edge of
   each cuts a corner of the other), whose area is closed-form; a horizon
   that cuts off one of its corners adds one vertex: 65. */
static void test_clip_32_by_32(void)
{
    int n = POLYGON_INPUT_MAX;
    struct polygon a = regular_ngon(n, 1.0, 0.0), b = regular_ngon(n, 1.0, M_PI / n), out;
    CHECK(polygon_clip_convex(&a, &b, &out) == 2 * n);
    CHECK(polygon_is_convex(&out));
    /* The 64-gon's inradius is the 32-gons' apothem cos(pi / 32), so its
       area is 64 tan(pi / 64) cos^2(pi / 32). */
    double inr = cos(M_PI / n);
    CHECK_NEAR(polygon_area(&out), 2 * n * tan(M_PI / (2 * n)) * inr * inr, 1e-12);
    /* Its neighbours lie at cos(2 pi / 64) = 0.995 of a corner's distance
       along that corner's direction. */
    struct vec3 corner = out.v[0];
    struct plane cut = { vec3_neg(vec3_normalize(corner)), -0.999 * vec3_length(corner) };
    struct polygon above;
    CHECK(polygon_clip_plane(&out, &cut, &above) == 2 * n + 1);
    CHECK(2 * n + 1 <= POLYGON_MAX);
    CHECK(polygon_is_convex(&above));
    CHECK(polygon_area(&above) < polygon_area(&out) && polygon_area(&above) > 0.9999 * polygon_area(&out));
    /* polygon_copy copies the vertices in use, also onto itself. */
    struct polygon copy;
    polygon_copy(&copy, &above);
    CHECK(copy.n == above.n && memcmp(copy.v, above.v, sizeof copy.v[0] * (size_t)copy.n) == 0);
    polygon_copy(&copy, &copy);
    CHECK(copy.n == above.n);
}

/* polygon_triangle_is_sound is sufficient for polygon_check: over random
   triangles of every shape (slivers, needles, tiny and far from the
   origin, collinear, repeated vertices), whenever it says yes,
   polygon_check finds no defect; and it says yes for ordinary triangles. */
static void test_triangle_is_sound(void)
{
    uint64_t state = 0x9E3779B97F4A7C15u;
    int sound = 0, agreed_bad = 0, fallback = 0, n = 200000;
    for (int i = 0; i < n; ++i) {
        double u[10];
        for (int k = 0; k < 10; ++k) {
            state = state * 6364136223846793005u + 1442695040888963407u;
            u[k] = (double)(state >> 11) * 0x1.0p-53;
        }
        /* Scale 1e-6..1e2, offset up to 1e8, flatness 1e-12..1. */
        double scale = pow(10.0, -6.0 + 8.0 * u[0]), off = pow(10.0, 8.0 * u[1]) * (u[2] - 0.5);
        double flat = pow(10.0, -12.0 * u[3]);
        struct vec3 o = vec3_make(off, -0.7 * off, 0.3 * off);
        struct polygon t;
        t.n = 3;
        t.v[0] = vec3_add(o, rotate(vec3_make(0, 0, 0)));
        t.v[1] = vec3_add(o, rotate(vec3_make(scale * u[4], scale * flat * (u[5] - 0.5), 0)));
        t.v[2] = vec3_add(o, rotate(vec3_make(scale * u[6], scale * flat * (u[7] - 0.5) + scale * flat, 0)));
        if (i % 50 == 0) t.v[2] = t.v[1]; /* a repeated vertex */
        bool quick = polygon_triangle_is_sound(t.v[0], t.v[1], t.v[2]);
        enum polygon_defect d = polygon_check(&t);
        CHECK_MSG(!quick || d == POLYGON_DEFECT_NONE, "triangle %d: quick yes, polygon_check %d", i, (int)d);
        sound += quick;
        agreed_bad += !quick && d != POLYGON_DEFECT_NONE;
        fallback += !quick && d == POLYGON_DEFECT_NONE;
    }
    /* Most of these triangles are extreme on purpose (far, flat or tiny):
       the quick test leaves them to polygon_check. */
    printf("  %d random triangles: %d sound by the quick test, %d left to polygon_check and valid, %d invalid\n", n,
           sound, fallback, agreed_bad);
    CHECK(sound > n / 20 && agreed_bad > n / 10);
    struct vec3 a = vec3_make(0, 0, 0), b = vec3_make(1, 0, 0), c = vec3_make(0, 1, 0);
    CHECK(polygon_triangle_is_sound(a, b, c));
    CHECK(!polygon_triangle_is_sound(a, b, b));
    CHECK(!polygon_triangle_is_sound(a, b, vec3_make(0.5, 1e-3, 0))); /* height 0.1% of the edge */
    CHECK(!polygon_triangle_is_sound(a, b, vec3_make(NAN, 1, 0)));
    CHECK(!polygon_triangle_is_sound(vec3_make(1e6, 0, 0), vec3_make(1e6 + 1e-3, 0, 0), vec3_make(1e6, 1e-3, 0)));
}

static void test_intersect_contains(void)
{
    struct polygon sq = rect_xy(-1, 1, -1, 1, 0, 0);
    sq = poly_transform(&sq, vec3_make(1, 2, 3));
    struct vec3 c = vec3_make(1, 2, 3), z = rotate(vec3_make(0, 0, 1)), x = rotate(vec3_make(1, 0, 0));
    double t = 0.0;
    /* From either side, with a non-unit direction. */
    CHECK(polygon_intersect_ray(&sq, vec3_madd(c, z, 2.0), vec3_scale(z, -4.0), &t));
    CHECK_NEAR(t, 0.5, 1e-14);
    CHECK(polygon_intersect_ray(&sq, vec3_madd(c, z, -3.0), vec3_add(z, vec3_scale(x, 0.2)), &t));
    CHECK_NEAR(t, 3.0, 1e-14);
    /* Misses: beyond the edge, pointing away, parallel. */
    CHECK(!polygon_intersect_ray(&sq, vec3_madd(c, z, 2.0), vec3_add(vec3_neg(z), x), &t));
    CHECK(!polygon_intersect_ray(&sq, vec3_madd(c, z, 2.0), z, &t));
    CHECK(!polygon_intersect_ray(&sq, vec3_madd(c, z, 2.0), x, &t));
    CHECK(polygon_contains(&sq, vec3_madd(c, x, 0.999)));
    CHECK(polygon_contains(&sq, vec3_madd(c, x, 1.0)));
    CHECK(!polygon_contains(&sq, vec3_madd(c, x, 1.001)));
}

/* Solid angle of [x0,x1] x [y0,y1] in the plane z = h seen from the origin:
   the integral of h / r^3 over the rectangle, whose antiderivative is
   F(x, y) = atan(x y / (h sqrt(x^2 + y^2 + h^2))) (odd in x and in y). */
static double rect_f(double x, double y, double h)
{
    return atan(x * y / (h * sqrt(x * x + y * y + h * h)));
}

static double rect_solid_angle(double x0, double x1, double y0, double y1, double h)
{
    return rect_f(x1, y1, h) - rect_f(x0, y1, h) - rect_f(x1, y0, h) + rect_f(x0, y0, h);
}

/* Projected solid angle of the same rectangle for the receiver normal +z:
   the integral of h^2 / r^4, i.e. pi times the form factor from a
   differential area to a parallel rectangle with one corner above it,
   G(x, y) = 1/2 [X / sqrt(1 + X^2) atan(Y / sqrt(1 + X^2)) + (X <-> Y)],
   X = x / h, Y = y / h, again odd in x and y. */
static double rect_g(double x, double y, double h)
{
    double a = x / h, b = y / h, sa = sqrt(1.0 + a * a), sb = sqrt(1.0 + b * b);
    return 0.5 * (a / sa * atan(b / sa) + b / sb * atan(a / sb));
}

static double rect_projected(double x0, double x1, double y0, double y1, double h)
{
    return rect_g(x1, y1, h) - rect_g(x0, y1, h) - rect_g(x1, y0, h) + rect_g(x0, y0, h);
}

static void test_solid_angle(void)
{
    struct vec3 o = vec3_make(0, 0, 0);
    /* Square of side s centred on the axis at distance h: the rectangle
       formula with x, y = +-s/2 gives 4 atan(s^2 / (2 h sqrt(s^2 + 4 h^2)))
       = 4 asin(s^2 / (s^2 + 4 h^2)). */
    const double cases[][2] = { { 1, 1 }, { 2, 0.1 }, { 1, 1e4 }, { 1e-3, 1 }, { 3, 0.5 } };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        double s = cases[i][0], h = cases[i][1];
        double expect = 4.0 * asin(s * s / (s * s + 4.0 * h * h));
        for (int flip = 0; flip < 2; ++flip) {
            struct polygon sq = rect_xy(-s / 2, s / 2, -s / 2, s / 2, h, flip);
            CHECK_NEAR(polygon_solid_angle(&sq, o), expect, 1e-12 * expect);
            /* Seen from the other side, and rotated away from the axes. */
            struct polygon r = poly_transform(&sq, vec3_make(0.5, 0.25, -2.0));
            CHECK_NEAR(polygon_solid_angle(&r, vec3_add(vec3_make(0.5, 0.25, -2.0), rotate(vec3_make(0, 0, 2 * h)))),
                       expect, 1e-11 * expect);
        }
    }
    /* A huge square fills the hemisphere. The closed form in atan form
       (asin is ill-conditioned near 1): 4 F(s/2, s/2) = 2 pi - 1.13e-7 for
       side 1e8 at h = 1. The fan triangles then graze o's plane: Van
       Oosterom-Strackee's denominator cancels to ~4 / s^2 (scaled to unit
       vectors) against a numerator ~3 / s, so its absolute error is about
       eps |a||b||c| / det ~ eps s / 3 per triangle; twice that in the angle,
       two triangles: ~1.3 eps s, bounded here by 4 eps s. */
    for (double s = 1e2; s <= 1e8; s *= 100.0) {
        double e = 4.0 * rect_f(s / 2, s / 2, 1.0);
        struct polygon huge = rect_xy(-s / 2, s / 2, -s / 2, s / 2, 1.0, 0);
        CHECK_NEAR(polygon_solid_angle(&huge, o), e, 4.0 * DBL_EPSILON * s + 1e-14);
        CHECK_NEAR(polygon_solid_angle(&huge, o), 2.0 * M_PI, 12.0 / s);
    }
    /* Off-axis rectangles, including ones entirely to one side of o. */
    const double rects[][5] = { { 0.2, 1.3, -0.4, 0.7, 0.9 }, { 1.5, 2.5, 2.0, 2.2, 0.3 }, { -3, -2, 1, 4, 0.05 } };
    for (size_t i = 0; i < sizeof rects / sizeof rects[0]; ++i) {
        const double *q = rects[i];
        struct polygon r = rect_xy(q[0], q[1], q[2], q[3], q[4], (int)i & 1);
        double e = rect_solid_angle(q[0], q[1], q[2], q[3], q[4]);
        CHECK_NEAR(polygon_solid_angle(&r, o), e, 1e-12 * e);
    }
    /* The triangle (1,0,0) (0,1,0) (0,0,1) covers an octant: pi / 2. */
    const double oct[3][3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } };
    struct polygon t = poly_make(3, oct);
    CHECK_NEAR(polygon_solid_angle(&t, o), 0.5 * M_PI, 1e-14);
    /* o in the plane, outside the polygon: zero. */
    struct polygon sq = rect_xy(1, 2, 1, 2, 0, 0);
    CHECK_NEAR(polygon_solid_angle(&sq, o), 0.0, 1e-15);
}

static void test_vector_irradiance(void)
{
    struct vec3 o = vec3_make(0, 0, 0), up = vec3_make(0, 0, 1);
    /* flip = 1 winds the square clockwise seen from +z, i.e.
       counter-clockwise seen from o below it: Phi then points up, to it. */
    struct polygon ccw = rect_xy(-1, 1, -1, 1, 1.0, 1), cw = rect_xy(-1, 1, -1, 1, 1.0, 0);
    struct vec3 phi = polygon_vector_irradiance(&ccw, o);
    CHECK(vec3_dot(up, phi) > 0.0);
    CHECK(vec3_dot(up, polygon_vector_irradiance(&cw, o)) < 0.0);
    CHECK_NEAR(phi.x, 0.0, 1e-15);
    CHECK_NEAR(phi.y, 0.0, 1e-15);
    /* Centred square of side 2a at height h: 4 A / sqrt(1 + A^2) atan(A / sqrt(1 + A^2)), A = a / h. */
    const double cases[][2] = { { 1, 1 }, { 0.5, 3 }, { 2, 0.01 }, { 1e-3, 10 } };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        double a = cases[i][0], h = cases[i][1], aa = a / h, sa = sqrt(1.0 + aa * aa);
        double expect = 4.0 * aa / sa * atan(aa / sa);
        struct polygon sq = rect_xy(-a, a, -a, a, h, (int)i & 1);
        double tol = 1e-12 * expect;
        CHECK_NEAR(M_PI * fabs(vec3_dot(up, polygon_vector_irradiance(&sq, o))), expect, tol);
        CHECK_NEAR(polygon_projected_solid_angle(&sq, o, up), expect, tol);
        CHECK_NEAR(rect_projected(-a, a, -a, a, h), expect, tol);
        /* Rotated frame, o displaced. */
        struct vec3 base = vec3_make(-1, 2, 0.5);
        struct polygon r = poly_transform(&sq, base);
        CHECK_NEAR(polygon_projected_solid_angle(&r, base, rotate(up)), expect, 1e-11 * expect);
    }
    /* Off-axis parallel rectangles. */
    const double rects[][5] = { { 0.2, 1.3, -0.4, 0.7, 0.9 }, { 1.5, 2.5, 2.0, 2.2, 0.3 }, { -3, -2, 1, 4, 0.05 } };
    for (size_t i = 0; i < sizeof rects / sizeof rects[0]; ++i) {
        const double *q = rects[i];
        struct polygon r = rect_xy(q[0], q[1], q[2], q[3], q[4], 0);
        double e = rect_projected(q[0], q[1], q[2], q[3], q[4]);
        CHECK_NEAR(polygon_projected_solid_angle(&r, o, up), e, 1e-12 * e + 1e-15);
    }
    /* A huge square overhead: the whole cosine lobe, pi. */
    struct polygon huge = rect_xy(-1e8, 1e8, -1e8, 1e8, 1.0, 0);
    CHECK_NEAR(polygon_projected_solid_angle(&huge, o, up), M_PI, 1e-7);
    /* Below the horizon or facing away: nothing. */
    CHECK_NEAR(polygon_projected_solid_angle(&ccw, o, vec3_neg(up)), 0.0, 0.0);
    struct polygon low = rect_xy(-1, 1, -1, 1, -0.5, 0);
    CHECK_NEAR(polygon_projected_solid_angle(&low, o, up), 0.0, 0.0);
}

static double psa_integrand(struct vec3 x, struct vec3 o, struct vec3 n, struct vec3 pn)
{
    struct vec3 w = vec3_sub(x, o);
    double r2 = vec3_length2(w), r = sqrt(r2);
    return fmax(0.0, vec3_dot(n, w) / r) * fabs(vec3_dot(pn, w) / r) / r2;
}

/* Integral over the polygon's area of cos(receiver) cos(polygon) / r^2,
   midpoint rule on m^2 sub-triangles of each fan triangle. */
static double psa_quadrature(const struct polygon *p, struct vec3 o, struct vec3 n, int m)
{
    struct vec3 pn = polygon_normal(p);
    double sum = 0.0;
    for (int k = 1; k + 1 < p->n; ++k) {
        struct vec3 e1 = vec3_scale(vec3_sub(p->v[k], p->v[0]), 1.0 / m);
        struct vec3 e2 = vec3_scale(vec3_sub(p->v[k + 1], p->v[0]), 1.0 / m);
        double da = 0.5 * vec3_length(vec3_cross(e1, e2)), tri = 0.0;
        for (int i = 0; i < m; ++i) {
            for (int j = 0; i + j < m; ++j) {
                struct vec3 up = vec3_madd(vec3_madd(p->v[0], e1, i + 1.0 / 3.0), e2, j + 1.0 / 3.0);
                tri += psa_integrand(up, o, n, pn);
                if (i + j + 2 <= m) {
                    struct vec3 dn = vec3_madd(vec3_madd(p->v[0], e1, i + 2.0 / 3.0), e2, j + 2.0 / 3.0);
                    tri += psa_integrand(dn, o, n, pn);
                }
            }
        }
        sum += tri * da;
    }
    return sum;
}

/* Tilted polygons partly below the receiver's horizon against quadrature;
   the tolerance is the difference between m and 2m sub-divisions (about 3x
   the error of the finer one for this second-order rule). */
static void test_projected_solid_angle_numeric(void)
{
    struct polygon sq = rect_xy(-1, 1, -1, 1, 0, 0), hex = regular_ngon(6, 0.8, 0.2);
    const double tri_v[3][3] = { { 0, 0, 0 }, { 1.5, 0.2, 0 }, { 0.3, 1.1, 0 } };
    struct polygon tri = poly_make(3, tri_v);
    struct {
        const struct polygon *shape;
        struct vec3 at, o, n;
        double min_value;
        bool straddles; /* partly below the receiver's horizon */
    } cases[] = {
        { &sq, vec3_make(0.3, 0.2, 0.5), vec3_make(0, 0, 0), vec3_make(0, 0.2, 1), 0.05, true },
        { &hex, vec3_make(1, -1, 0.1), vec3_make(0.2, -0.3, -0.4), vec3_make(0.78, 0.73, 0.05), 0.05, true },
        { &tri, vec3_make(0, 0, 2), vec3_make(0.1, 0.1, 0.1), vec3_make(-0.2, 0.1, 1), 0.05, false },
        { &sq, vec3_make(3, 0, 1), vec3_make(0, 0, 0), vec3_make(1.6, 0, -2.8), 0.01, true },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        struct polygon p = poly_transform(cases[i].shape, cases[i].at);
        struct vec3 n = vec3_normalize(cases[i].n), o = cases[i].o;
        int below = 0;
        for (int k = 0; k < p.n; ++k) below += vec3_dot(n, vec3_sub(p.v[k], o)) < 0.0;
        CHECK(cases[i].straddles ? below > 0 && below < p.n : below == 0);
        double coarse = psa_quadrature(&p, o, n, 256), fine = psa_quadrature(&p, o, n, 512);
        double tol = fabs(fine - coarse);
        double got = polygon_projected_solid_angle(&p, o, n);
        CHECK_MSG(fabs(got - fine) <= tol, "case %zu: %.12g vs quadrature %.12g (tol %.3g)", i, got, fine, tol);
        CHECK(tol < 1e-4 * fine && fine > cases[i].min_value);
        CHECK(got <= polygon_solid_angle(&p, o) && got <= M_PI);
    }
}

/* polygon_projected_solid_angle_many gives polygon_projected_solid_angle's
   bits for each polygon: polygons of 3 to POLYGON_MAX vertices (the large
   ones beyond a batch), above, straddling and below the horizon, enough of
   them that the edges fill several batches. */
static void test_projected_solid_angle_many(void)
{
    enum { COUNT = 40 };
    static struct polygon polys[COUNT];
    const struct polygon *ptr[COUNT];
    struct vec3 o = vec3_make(0.1, -0.2, 0.05), n = vec3_normalize(vec3_make(0.2, 0.1, 1.0));
    for (int i = 0; i < COUNT; ++i) {
        int sides = i % 9 == 8 ? POLYGON_MAX - i % 3 : 3 + i % 7;
        struct polygon base = regular_ngon(sides, 0.3 + 0.05 * i, 0.1 * i);
        /* Heights from below the horizon to above it. */
        struct vec3 at = vec3_make(0.4 * cos(i), 0.4 * sin(i), -0.6 + 0.04 * i);
        polys[i] = poly_transform(&base, at);
        ptr[i] = &polys[i];
    }
    double out[COUNT];
    int zero = 0, positive = 0;
    for (int count = 1; count <= COUNT; count += 13) {
        polygon_projected_solid_angle_many(ptr, count, o, n, out);
        for (int i = 0; i < count; ++i) {
            double one = polygon_projected_solid_angle(ptr[i], o, n);
            CHECK_MSG(memcmp(&one, &out[i], sizeof one) == 0, "polygon %d of %d: %.17g vs %.17g", i, count, out[i],
                      one);
            zero += one == 0.0;
            positive += one > 0.0;
        }
    }
    CHECK(zero > 0 && positive > 0);
}

static const struct test_case polygon_tests[] = {
    { "area_normal_centroid", test_area_normal_centroid },
    { "planar_convex", test_planar_convex },
    { "check", test_check },
    { "clip_convex", test_clip_convex },
    { "clip_plane", test_clip_plane },
    { "clip_32_by_32", test_clip_32_by_32 },
    { "triangle_is_sound", test_triangle_is_sound },
    { "intersect_contains", test_intersect_contains },
    { "solid_angle", test_solid_angle },
    { "vector_irradiance", test_vector_irradiance },
    { "projected_solid_angle_numeric", test_projected_solid_angle_numeric },
    { "projected_solid_angle_many", test_projected_solid_angle_many },
};

TEST_MAIN(polygon_tests)

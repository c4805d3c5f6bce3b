/* transform.c: affine transforms of points and normals. */
#include "base/transform.h"

#include <math.h>
#include <string.h>

struct transform transform_identity(void)
{
    struct transform t;
    memset(&t, 0, sizeof t);
    t.m[0][0] = t.m[1][1] = t.m[2][2] = 1.0;
    return t;
}

struct transform transform_translate(struct vec3 v)
{
    struct transform t = transform_identity();
    t.m[0][3] = v.x;
    t.m[1][3] = v.y;
    t.m[2][3] = v.z;
    return t;
}

struct transform transform_scale(struct vec3 s)
{
    struct transform t = transform_identity();
    t.m[0][0] = s.x;
    t.m[1][1] = s.y;
    t.m[2][2] = s.z;
    return t;
}

/* sin and cos of an angle in degrees, exact at multiples of 90 degrees, so
   that a quarter turn maps axis-aligned geometry onto axis-aligned
   geometry (cos(M_PI / 2) is 6e-17, not 0). */
static void sincos_deg(double deg, double *s, double *c)
{
    double r = fmod(deg, 360.0);
    if (r < 0.0) r += 360.0;
    if (r == 0.0 || r == 90.0 || r == 180.0 || r == 270.0) {
        int q = (int)(r / 90.0);
        static const double sin_q[4] = { 0.0, 1.0, 0.0, -1.0 }, cos_q[4] = { 1.0, 0.0, -1.0, 0.0 };
        *s = sin_q[q];
        *c = cos_q[q];
        return;
    }
    double a = deg * (M_PI / 180.0);
    *s = sin(a);
    *c = cos(a);
}

/* Rodrigues: R = c I + s [k]x + (1 - c) k k^T for the unit axis k. */
bool transform_rotate(struct vec3 axis, double angle_deg, struct transform *out)
{
    double len = vec3_length(axis);
    if (!(len > 0.0) || !isfinite(len) || !isfinite(angle_deg)) return false;
    struct vec3 k = vec3_scale(axis, 1.0 / len);
    double s, c;
    sincos_deg(angle_deg, &s, &c);
    double d = 1.0 - c;
    struct transform t = transform_identity();
    t.m[0][0] = c + d * k.x * k.x;
    t.m[0][1] = d * k.x * k.y - s * k.z;
    t.m[0][2] = d * k.x * k.z + s * k.y;
    t.m[1][0] = d * k.y * k.x + s * k.z;
    t.m[1][1] = c + d * k.y * k.y;
    t.m[1][2] = d * k.y * k.z - s * k.x;
    t.m[2][0] = d * k.z * k.x - s * k.y;
    t.m[2][1] = d * k.z * k.y + s * k.x;
    t.m[2][2] = c + d * k.z * k.z;
    *out = t;
    return true;
}

bool transform_from_rows(const double rows[16], struct transform *out)
{
    if (rows[12] != 0.0 || rows[13] != 0.0 || rows[14] != 0.0 || rows[15] != 1.0) return false;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) out->m[i][j] = rows[4 * i + j];
    return true;
}

struct transform transform_then(const struct transform *first, const struct transform *then)
{
    const double(*a)[4] = then->m, (*b)[4] = first->m;
    struct transform t;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) t.m[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        t.m[i][3] = a[i][0] * b[0][3] + a[i][1] * b[1][3] + a[i][2] * b[2][3] + a[i][3];
    }
    return t;
}

/* Row i of the cofactor matrix of A: cof(A) = det(A) A^-T. */
static struct vec3 cofactor_row(const struct transform *t, int i)
{
    const double(*m)[4] = t->m;
    struct vec3 r1 = vec3_make(m[(i + 1) % 3][0], m[(i + 1) % 3][1], m[(i + 1) % 3][2]);
    struct vec3 r2 = vec3_make(m[(i + 2) % 3][0], m[(i + 2) % 3][1], m[(i + 2) % 3][2]);
    return vec3_cross(r1, r2);
}

double transform_det(const struct transform *t)
{
    const double(*m)[4] = t->m;
    return vec3_dot(vec3_make(m[0][0], m[0][1], m[0][2]), cofactor_row(t, 0));
}

bool transform_is_singular(const struct transform *t)
{
    double bound = 1.0;
    for (int i = 0; i < 3; ++i) {
        double len = vec3_length(vec3_make(t->m[i][0], t->m[i][1], t->m[i][2]));
        if (!(len > 0.0) || !isfinite(len)) return true;
        bound *= len;
    }
    for (int i = 0; i < 3; ++i)
        if (!isfinite(t->m[i][3])) return true;
    double det = transform_det(t);
    return !isfinite(det) || !isfinite(bound) || !(fabs(det) > TRANSFORM_SINGULAR_TOL * bound);
}

struct vec3 transform_normal(const struct transform *t, struct vec3 n)
{
    if (transform_is_singular(t)) return vec3_make(0.0, 0.0, 0.0);
    /* A^-T n = cof(A) n / det: the sign of det keeps the direction. */
    struct vec3 c =
        vec3_make(vec3_dot(cofactor_row(t, 0), n), vec3_dot(cofactor_row(t, 1), n), vec3_dot(cofactor_row(t, 2), n));
    return vec3_normalize(transform_det(t) < 0.0 ? vec3_neg(c) : c);
}

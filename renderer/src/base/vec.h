/* vec.h: double-precision 3-vectors, RGB triples and orthonormal frames.
   Geometry runs in double so that classification and spherical sampling stay
   robust near region boundaries; only Embree's ray structs are float. */
#ifndef VEC_H
#define VEC_H

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

struct vec3 {
    double x, y, z;
};
struct rgb {
    double r, g, b;
};

static inline struct vec3 vec3_make(double x, double y, double z)
{
    struct vec3 v = { x, y, z };
    return v;
}
static inline struct vec3 vec3_add(struct vec3 a, struct vec3 b)
{
    return vec3_make(a.x + b.x, a.y + b.y, a.z + b.z);
}
static inline struct vec3 vec3_sub(struct vec3 a, struct vec3 b)
{
    return vec3_make(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline struct vec3 vec3_scale(struct vec3 a, double s)
{
    return vec3_make(a.x * s, a.y * s, a.z * s);
}
static inline struct vec3 vec3_neg(struct vec3 a)
{
    return vec3_make(-a.x, -a.y, -a.z);
}
/* a + b * s, the ray-point idiom. */
static inline struct vec3 vec3_madd(struct vec3 a, struct vec3 b, double s)
{
    return vec3_make(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s);
}
static inline double vec3_dot(struct vec3 a, struct vec3 b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline struct vec3 vec3_cross(struct vec3 a, struct vec3 b)
{
    return vec3_make(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double vec3_length2(struct vec3 a)
{
    return vec3_dot(a, a);
}
static inline double vec3_length(struct vec3 a)
{
    return sqrt(vec3_dot(a, a));
}
static inline struct vec3 vec3_normalize(struct vec3 a)
{
    double l = vec3_length(a);
    return l > 0.0 ? vec3_scale(a, 1.0 / l) : a;
}
static inline double vec3_max_abs(struct vec3 a)
{
    double m = fabs(a.x);
    if (fabs(a.y) > m) m = fabs(a.y);
    if (fabs(a.z) > m) m = fabs(a.z);
    return m;
}

static inline struct rgb rgb_make(double r, double g, double b)
{
    struct rgb c = { r, g, b };
    return c;
}
static inline struct rgb rgb_add(struct rgb a, struct rgb b)
{
    return rgb_make(a.r + b.r, a.g + b.g, a.b + b.b);
}
static inline struct rgb rgb_mul(struct rgb a, struct rgb b)
{
    return rgb_make(a.r * b.r, a.g * b.g, a.b * b.b);
}
static inline struct rgb rgb_scale(struct rgb a, double s)
{
    return rgb_make(a.r * s, a.g * s, a.b * s);
}
static inline double rgb_max(struct rgb a)
{
    return a.r > a.g ? (a.r > a.b ? a.r : a.b) : (a.g > a.b ? a.g : a.b);
}
static inline double rgb_luminance(struct rgb a)
{
    return 0.2126 * a.r + 0.7152 * a.g + 0.0722 * a.b;
}
static inline int rgb_is_black(struct rgb a)
{
    return a.r == 0.0 && a.g == 0.0 && a.b == 0.0;
}
static inline int rgb_is_finite(struct rgb a)
{
    return isfinite(a.r) && isfinite(a.g) && isfinite(a.b);
}

/* Orthonormal frame whose z axis is n (Duff et al. 2017, branchless). */
struct frame {
    struct vec3 x, y, z;
};

static inline struct frame frame_from_normal(struct vec3 n)
{
    struct frame f;
    double sign = copysign(1.0, n.z);
    double a = -1.0 / (sign + n.z);
    double b = n.x * n.y * a;
    f.x = vec3_make(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.y = vec3_make(b, sign + n.y * n.y * a, -n.y);
    f.z = n;
    return f;
}
static inline struct vec3 frame_to_local(const struct frame *f, struct vec3 v)
{
    return vec3_make(vec3_dot(v, f->x), vec3_dot(v, f->y), vec3_dot(v, f->z));
}
static inline struct vec3 frame_to_world(const struct frame *f, struct vec3 v)
{
    return vec3_add(vec3_add(vec3_scale(f->x, v.x), vec3_scale(f->y, v.y)), vec3_scale(f->z, v.z));
}

#endif

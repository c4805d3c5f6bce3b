/* spherical.c: solid-angle sampling of rectangles, triangles and convex
   polygons seen from a point (see spherical.h). */
#include "geometry/spherical.h"

#include "base/fastmath.h"

/* Below this solid angle (sr) the rectangle and polygon samplers refuse:
   sphrect's mapping loses about 1e-16 / Omega of the rectangle's size in
   position (see sphrect_sample), i.e. 1e-4 here. */
#define SPHERICAL_MIN_SOLID_ANGLE 1e-12
/* A fan triangle below this solid angle is skipped; sphtri itself stays
   accurate far below it (see sphtri_sample). */
#define SPHTRI_MIN_AREA 1e-16
/* o counts as in the plane when closer than this fraction of the shape's size. */
#define SPHERICAL_PLANE_REL 1e-12

FM_INLINE double clamp(double x, double lo, double hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

bool sphrect_frame_init(struct sphrect_frame *f, struct vec3 s, struct vec3 ex, struct vec3 ey)
{
    double exl = vec3_length(ex), eyl = vec3_length(ey);
    if (!(exl > 0.0) || !(eyl > 0.0) || !isfinite(exl) || !isfinite(eyl)) return false;
    f->corner = s;
    f->ex_len = exl;
    f->ey_len = eyl;
    f->x = vec3_scale(ex, 1.0 / exl);
    f->y = vec3_scale(ey, 1.0 / eyl);
    f->z = vec3_cross(f->x, f->y);
    return true;
}

/* Urena, Fajardo, King 2013, section 3 and algorithm 1. In the local frame
   (x along ex, y along ey, z towards o's side flipped so that the rectangle
   lies at z = z0 < 0) the corners are v00 = (x0, y0, z0) ... v11 = (x1, y1, z0).
   The unit normals of the planes through o and each edge have the closed
   forms n0 ~ (0, z0, -y0), n1 ~ (-z0, 0, x1), n2 ~ (0, -z0, y1),
   n3 ~ (z0, 0, -x0); we use them instead of normalised cross products.
   The interior angle between consecutive edge planes, g_i = acos(-n_i . n_{i+1}),
   is atan2(|z0| |v|, +-x y) at the shared corner v = (x, y, z0), with
   |(|z0| |v|, x y)| = sqrt(z0^2 + x^2) sqrt(z0^2 + y^2).
   The sampler only needs sin and cos of au = u S + k (k = 2 pi - g2 - g3),
   so k is kept as its cosine and sine, found from those of g2 and g3 by the
   angle-sum formulas without any inverse trigonometric function:
       cos k =  cos(g2 + g3) = -(x0^2 y0 y1 + z0^2 l00 l01) / m,
       sin k = -sin(g2 + g3) = |z0| x0 (y0 l01 - y1 l00) / m,
       m = (z0^2 + x0^2) sqrt(z0^2 + y0^2) sqrt(z0^2 + y1^2),
   with l_ij = |v_ij|; both are accurate to ~1e-16 absolute, as the angles
   themselves were. The paper's solid angle S = g0 + g1 + g2 + g3 - 2 pi
   cancels badly for small rectangles; we compute it instead as the sum of
   two Van Oosterom-Strackee triangles (v00, v10, v11) and (v00, v11, v01),
   whose determinants are exactly z0 |ex| |ey| each (the edges are axis-
   aligned locally), merged into one atan2 by the tangent-sum formula
   (valid because S / 2 < pi), after scaling every term by 1 / (l00 l10 l11)
   so that no product can overflow.
   rect_constants computes these per-point constants from the rectangle in
   the local frame; sphrect_init_frame and sphrect_sample_many share it. */
FM_INLINE void rect_constants(double z0, double x0, double y0, double exl, double eyl, struct sphrect *r)
{
    double x1 = x0 + exl, y1 = y0 + eyl;
    r->z0 = z0;
    r->x0 = x0;
    r->y0 = y0;
    r->x1 = x1;
    r->y1 = y1;

    double z0sq = z0 * z0, az0 = -z0;
    double l00 = sqrt(x0 * x0 + y0 * y0 + z0sq), l10 = sqrt(x1 * x1 + y0 * y0 + z0sq);
    double l01 = sqrt(x0 * x0 + y1 * y1 + z0sq), l11 = sqrt(x1 * x1 + y1 * y1 + z0sq);
    double ry0 = sqrt(z0sq + y0 * y0), ry1 = sqrt(z0sq + y1 * y1);
    /* Divisions dominate the cost (vectorised, they are the bottleneck), so
       one reciprocal serves all: 1 / (a b) with a = (z0^2 + x0^2) ry0 ry1
       (for m and, times z0^2 + x0^2, for 1 / (ry0 ry1)) and b = l00 l10 l11
       (the scale below). a b has degree 7 in the lengths: finite for
       lengths between 1e-40 and 1e40, beyond float geometry's reach. */
    double zx0 = z0sq + x0 * x0, a = zx0 * ry0 * ry1, bl = l00 * l10 * l11;
    double inv_ab = 1.0 / (a * bl);
    double m = bl * inv_ab, inv_ry01 = zx0 * m;
    r->b0 = -y0 * ry1 * inv_ry01;                                   /* n0.z = -y0 / ry0 */
    r->b1 = y1 * ry0 * inv_ry01;                                    /* n2.z = y1 / ry1 */
    r->one_minus_b0sq = z0sq * (ry1 * inv_ry01) * (ry1 * inv_ry01); /* z0^2 / ry0^2 */
    r->cos_k = -(x0 * x0 * y0 * y1 + z0sq * l00 * l01) * m;
    r->sin_k = az0 * x0 * (y0 * l01 - y1 * l00) * m;

    /* Van Oosterom-Strackee with a = v00, b = v10, c = v11 and a = v00,
       b = v11, c = v01; dot products written out in local coordinates. */
    double sc = a * inv_ab; /* 1 / (l00 l10 l11) */
    double det = az0 * exl * eyl * sc;
    double d_a10 = x0 * x1 + y0 * y0 + z0sq, d_a11 = x0 * x1 + y0 * y1 + z0sq;
    double d_1011 = x1 * x1 + y0 * y1 + z0sq, d_a01 = x0 * x0 + y0 * y1 + z0sq;
    double d_1101 = x1 * x0 + y1 * y1 + z0sq;
    double den1 = (l00 * l10 * l11 + d_a10 * l11 + d_a11 * l10 + d_1011 * l00) * sc;
    double den2 = (l00 * l11 * l01 + d_a11 * l01 + d_a01 * l11 + d_1101 * l00) * sc;
    r->solid_angle = 2.0 * fm_atan2(det * (den1 + den2), den1 * den2 - det * det);
}

/* The local frame at o: z flipped towards o's side so that the rectangle
   lies at z0 < 0. Returns whether o is clear of the plane (see below). */
FM_INLINE bool rect_local(const struct sphrect_frame *f, struct vec3 o, struct sphrect *r)
{
    r->o = o;
    r->x = f->x;
    r->y = f->y;
    struct vec3 d = vec3_sub(f->corner, o);
    double z0 = vec3_dot(d, f->z);
    bool flip = z0 > 0.0;
    r->z = flip ? vec3_neg(f->z) : f->z;
    z0 = flip ? -z0 : z0;
    rect_constants(z0, vec3_dot(d, f->x), vec3_dot(d, f->y), f->ex_len, f->ey_len, r);
    double size = f->ex_len > f->ey_len ? f->ex_len : f->ey_len;
    return -z0 > SPHERICAL_PLANE_REL * size;
}

FM_INLINE bool rect_usable(const struct sphrect *r)
{
    /* Also false for NaN; infinity is out of reach (S <= 2 pi). */
    return (r->solid_angle > SPHERICAL_MIN_SOLID_ANGLE) & (r->solid_angle <= 4.0 * M_PI);
}

/* The set-up of Urena et al. (see rect_constants) at o. */
bool sphrect_init_frame(struct sphrect *r, const struct sphrect_frame *f, struct vec3 o)
{
    return rect_local(f, o, r) && rect_usable(r);
}

bool sphrect_init(struct sphrect *r, struct vec3 o, struct vec3 s, struct vec3 ex, struct vec3 ey)
{
    struct sphrect_frame f;
    return sphrect_frame_init(&f, s, ex, ey) && sphrect_init_frame(r, &f, o);
}

/* Algorithm 1 of the paper. u fixes the sub-rectangle [x0, xu] whose solid
   angle is u * S: its area au = u S + k determines the cosine cu of the angle
   between the edge plane at xu and the x axis,
       cu = sgn(fu) / sqrt(fu^2 + b0^2),  fu = (cos(au) b0 - b1) / sin(au),
   rewritten without the quotient fu as cu = sgn(n) s / q with s = sin(au),
   n = cos(au) b0 - b1, q = sqrt(n^2 + b0^2 s^2), so that
       xu = -cu z0 / sqrt(1 - cu^2) = -sgn(n) s z0 / sqrt(n^2 - s^2 (1 - b0^2)),
   where 1 - b0^2 = z0^2 / (z0^2 + y0^2) is formed without cancellation.
   v is then uniform in h = cos of the elevation along that edge line,
   i.e. in solid angle.
   Guards: h is clamped into [-1, 1] and xu into the rectangle; a zero
   root is the limit xu -> +-inf. For tiny solid angles au is close to pi
   and sin(au) carries an absolute error of about 1e-16, i.e. xu moves by
   ~1e-16 / S of the rectangle's width; init refuses S < 1e-12 for that
   reason. Written with selects, not branches, so that it vectorises. */
FM_INLINE struct vec3 rect_warp(const struct sphrect *r, double u, double v, double *dist)
{
    double z0 = r->z0, z0sq = z0 * z0;
    double su, cu_;
    fm_sincos(u * r->solid_angle, &su, &cu_);
    double s = su * r->cos_k + cu_ * r->sin_k;
    double c = cu_ * r->cos_k - su * r->sin_k;
    double n = c * r->b0 - r->b1;
    double num = (n > 0.0 ? -s : s) * z0;
    double den2 = n * n - s * s * r->one_minus_b0sq;
    double xu = den2 > 0.0 ? num / sqrt(den2) : (num > 0.0 ? r->x1 : r->x0);
    xu = clamp(xu, r->x0, r->x1);

    /* h is the y component of the unit direction itself: the direction is
       (xu / d sin, h, z0 / d sin) with sin = sqrt(1 - h^2), d = |(xu, z0)|,
       and the point lies at distance d / sin. */
    double dd = xu * xu + z0sq;
    /* h0 = y0 / r0, h1 = y1 / r1 with r_i = sqrt(dd + y_i^2), in one
       division; likewise below (d = sqrt(dd), sin = sqrt(1 - h^2)): the
       direction's scale sin / d and the distance d / sin both come from
       1 / (d sin) = 1 / sqrt(dd (1 - h^2)). */
    double r0 = sqrt(dd + r->y0 * r->y0), r1 = sqrt(dd + r->y1 * r->y1);
    double inv_r01 = 1.0 / (r0 * r1);
    double h0 = r->y0 * r1 * inv_r01, h1 = r->y1 * r0 * inv_r01;
    double hv = clamp(h0 + v * (h1 - h0), -1.0, 1.0);
    double sin2 = (1.0 - hv) * (1.0 + hv), p2 = dd * sin2;
    /* Rounding may put h on a pole, which only a point at infinity along y
       reaches: the rectangle's edge (xu, y0 or y1, z0) is taken instead. */
    bool pole = !(p2 > 1e-280);
    double qy = hv > 0.0 ? r->y1 : r->y0;
    double p = sqrt(pole ? dd + qy * qy : p2), inv_p = 1.0 / p;
    double f = pole ? inv_p : sin2 * inv_p;
    struct vec3 local = vec3_make(xu * f, pole ? qy * inv_p : hv, z0 * f);
    *dist = pole ? p : dd * inv_p;
    return vec3_add(vec3_add(vec3_scale(r->x, local.x), vec3_scale(r->y, local.y)), vec3_scale(r->z, local.z));
}

struct vec3 sphrect_sample_dir(const struct sphrect *r, double u, double v, double *dist)
{
    return rect_warp(r, u, v, dist);
}

/* sphrect_sample_many runs each lane in two stages, each a loop over a
   block of lanes: the per-point constants (rect_local, rect_constants),
   then the warp. Both are chains of divisions and square roots; split,
   each iteration is short enough for the processor to overlap
   neighbouring ones (measured faster than one loop doing both; see
   docs/performance.md). The stages read and write arrays of scalars indexed by
   lane, so that the loops have no local whose address is taken (OpenMP
   would turn those into per-lane arrays and defeat the vectoriser). */
enum {
    RF_CX,
    RF_CY,
    RF_CZ,
    RF_XX,
    RF_XY,
    RF_XZ,
    RF_YX,
    RF_YY,
    RF_YZ,
    RF_ZX,
    RF_ZY,
    RF_ZZ,
    RF_EXL,
    RF_EYL,
    RF_OX,
    RF_OY,
    RF_OZ,
    RF_U,
    RF_V,
    RF_COUNT
};
/* The sphrect fields stage one hands to stage two (o, x and y are inputs). */
enum {
    RS_ZX,
    RS_ZY,
    RS_ZZ,
    RS_Z0,
    RS_X0,
    RS_Y0,
    RS_X1,
    RS_Y1,
    RS_B0,
    RS_B1,
    RS_OMB,
    RS_COSK,
    RS_SINK,
    RS_SA,
    RS_COUNT
};

/* Lanes per block: enough iterations for the stages to overlap. */
#define RECT_BLOCK 64

FM_INLINE void rect_stage1(const double in[RF_COUNT][RECT_BLOCK], double st[RS_COUNT][RECT_BLOCK], int i)
{
    struct sphrect_frame f = { { in[RF_CX][i], in[RF_CY][i], in[RF_CZ][i] },
                               { in[RF_XX][i], in[RF_XY][i], in[RF_XZ][i] },
                               { in[RF_YX][i], in[RF_YY][i], in[RF_YZ][i] },
                               { in[RF_ZX][i], in[RF_ZY][i], in[RF_ZZ][i] },
                               in[RF_EXL][i],
                               in[RF_EYL][i] };
    struct sphrect r;
    /* Both evaluated (no branch), so that the loop vectorises. */
    bool in_front = rect_local(&f, vec3_make(in[RF_OX][i], in[RF_OY][i], in[RF_OZ][i]), &r), usable = rect_usable(&r);
    bool ok = in_front & usable;
    st[RS_ZX][i] = r.z.x;
    st[RS_ZY][i] = r.z.y;
    st[RS_ZZ][i] = r.z.z;
    st[RS_Z0][i] = r.z0;
    st[RS_X0][i] = r.x0;
    st[RS_Y0][i] = r.y0;
    st[RS_X1][i] = r.x1;
    st[RS_Y1][i] = r.y1;
    st[RS_B0][i] = r.b0;
    st[RS_B1][i] = r.b1;
    st[RS_OMB][i] = r.one_minus_b0sq;
    st[RS_COSK][i] = r.cos_k;
    st[RS_SINK][i] = r.sin_k;
    st[RS_SA][i] = ok ? r.solid_angle : 0.0;
}

FM_INLINE struct vec3 rect_stage2(const double in[RF_COUNT][RECT_BLOCK], const double st[RS_COUNT][RECT_BLOCK], int i,
                                  double *dist)
{
    struct sphrect r;
    r.o = vec3_make(in[RF_OX][i], in[RF_OY][i], in[RF_OZ][i]);
    r.x = vec3_make(in[RF_XX][i], in[RF_XY][i], in[RF_XZ][i]);
    r.y = vec3_make(in[RF_YX][i], in[RF_YY][i], in[RF_YZ][i]);
    r.z = vec3_make(st[RS_ZX][i], st[RS_ZY][i], st[RS_ZZ][i]);
    r.z0 = st[RS_Z0][i];
    r.x0 = st[RS_X0][i];
    r.y0 = st[RS_Y0][i];
    r.x1 = st[RS_X1][i];
    r.y1 = st[RS_Y1][i];
    r.b0 = st[RS_B0][i];
    r.b1 = st[RS_B1][i];
    r.one_minus_b0sq = st[RS_OMB][i];
    r.cos_k = st[RS_COSK][i];
    r.sin_k = st[RS_SINK][i];
    r.solid_angle = st[RS_SA][i];
    return rect_warp(&r, in[RF_U][i], in[RF_V][i], dist);
}

/* Lanes are processed in blocks: gathered into local arrays of scalars,
   run through the stages' vectorised loops (one lane per SIMD slot), and
   scattered back. The gathers are marked `omp simd` too: at -O2 GCC only
   vectorises a loop without the pragma when no remainder is left over
   ("very cheap" cost model), and gathered lane by lane with scalar
   stores they cost as much as a stage (docs/performance.md has the
   cycles). */
FM_SIMD_CLONES
void sphrect_sample_many(const struct sphrect_frame *const *frames, const struct vec3 *o, const double *u,
                         const double *v, int n, struct vec3 *wi, double *dist, double *solid_angle)
{
    for (int b = 0; b < n; b += RECT_BLOCK) {
        int m = n - b < RECT_BLOCK ? n - b : RECT_BLOCK;
        /* Lanes computed: m rounded up to a whole number of AVX-512 vectors. */
        int mv = (m + 7) & ~7;
        double in[RF_COUNT][RECT_BLOCK], st[RS_COUNT][RECT_BLOCK], out[4][RECT_BLOCK];
#pragma omp simd
        for (int i = 0; i < m; ++i) {
            in[RF_OX][i] = o[b + i].x;
            in[RF_OY][i] = o[b + i].y;
            in[RF_OZ][i] = o[b + i].z;
            in[RF_U][i] = u[b + i];
            in[RF_V][i] = v[b + i];
        }
        /* Idle lanes repeat lane 0 so that they compute finite values. */
        for (int i = m; i < mv; ++i)
            for (int j = RF_OX; j < RF_COUNT; ++j) in[j][i] = in[j][0];
        /* Usually every lane has the same rectangle (one light): its frame
           is then broadcast (vector stores) instead of gathered lane by lane
           (the stores of a lane-by-lane gather cost as much as a stage). */
        bool shared = true;
        for (int i = 1; i < m; ++i) shared &= frames[b + i] == frames[b];
        for (int i = 0; i < (shared ? 1 : mv); ++i) {
            const struct sphrect_frame *f = frames[b + (i < m ? i : 0)];
            const double fields[RF_OX] = {
                f->corner.x, f->corner.y, f->corner.z, f->x.x, f->x.y, f->x.z,    f->y.x,
                f->y.y,      f->y.z,      f->z.x,      f->z.y, f->z.z, f->ex_len, f->ey_len
            };
            for (int j = 0; j < RF_OX; ++j) in[j][i] = fields[j];
        }
        if (shared)
            for (int j = 0; j < RF_OX; ++j) {
                double x = in[j][0];
#pragma omp simd
                for (int i = 1; i < mv; ++i) in[j][i] = x;
            }
#pragma omp simd
        for (int i = 0; i < mv; ++i) rect_stage1((const double(*)[RECT_BLOCK])in, st, i);
#pragma omp simd
        for (int i = 0; i < mv; ++i) {
            double d;
            struct vec3 w = rect_stage2((const double(*)[RECT_BLOCK])in, (const double(*)[RECT_BLOCK])st, i, &d);
            out[0][i] = w.x;
            out[1][i] = w.y;
            out[2][i] = w.z;
            out[3][i] = d;
        }
        for (int i = 0; i < m; ++i) {
            wi[b + i] = vec3_make(out[0][i], out[1][i], out[2][i]);
            dist[b + i] = out[3][i];
            solid_angle[b + i] = st[RS_SA][i];
        }
    }
}

struct vec3 sphrect_sample(const struct sphrect *r, double u, double v)
{
    double dist;
    struct vec3 w = sphrect_sample_dir(r, u, v, &dist);
    return vec3_madd(r->o, w, dist);
}

/* Tangent at the unit vector p towards q, of length sin(arc), formed from the
   difference q - p so that it stays accurate for nearby points. */
static struct vec3 sph_tangent(struct vec3 p, struct vec3 q)
{
    struct vec3 dq = vec3_sub(q, p);
    return vec3_sub(dq, vec3_scale(p, vec3_dot(dq, p)));
}

/* Area: Van Oosterom-Strackee, tan(A/2) = |det[a b c]| / (1 + a.b + b.c + c.a)
   for unit vectors, with det = a . ((b - a) x (c - a)). The angle alpha at a
   is between the tangents towards b and c, again from differences. */
bool sphtri_init(struct sphtri *t, struct vec3 a, struct vec3 b, struct vec3 c)
{
    a = vec3_normalize(a);
    b = vec3_normalize(b);
    c = vec3_normalize(c);
    t->a = a;
    t->b = b;
    t->c = c;
    struct vec3 tb = sph_tangent(a, b), tc = sph_tangent(a, c);
    t->alpha = atan2(vec3_length(vec3_cross(tb, tc)), vec3_dot(tb, tc));
    t->sin_alpha = sin(t->alpha);
    t->cos_alpha = cos(t->alpha);
    t->cos_c = vec3_dot(a, b);
    double det = fabs(vec3_dot(a, vec3_cross(vec3_sub(b, a), vec3_sub(c, a))));
    double den = 1.0 + vec3_dot(a, b) + vec3_dot(b, c) + vec3_dot(c, a);
    t->area = 2.0 * atan2(det, den);
    return t->area > SPHTRI_MIN_AREA && isfinite(t->area) && t->sin_alpha > 0.0;
}

/* Arvo 1995 picks the point c' on the arc from a to c such that the triangle
   (a, b, c') has area A' = u * A, then samples the arc from b to c' with
   cos(theta) uniform in [b.c', 1]. Arvo solves for cos(b') (b' = arc a c')
   with a ratio of differences that both vanish as the triangle shrinks
   (cos(A' - alpha) - cos(alpha), ...), so c' loses about 1e-16 / b'^2 of its
   position. We use instead the excess formula for two sides and their
   included angle, tan(A'/2) = tan(b'/2) tan(c/2) sin(alpha) /
   (1 + tan(b'/2) tan(c/2) cos(alpha)), solved for tan(b'/2):
       tan(b'/2) = sin(A'/2) / (tan(c/2) sin(alpha - A'/2)),
   a quotient of products without cancellation (A' < A < 2 alpha holds in
   every spherical triangle, so the denominator is positive), with
   tan(c/2) = |a - b| / |a + b|. The second step uses 1 - b.c' = |c' - b|^2/2
   and sin(theta) = sqrt((1 - z)(1 + z)) for the same reason. */
struct vec3 sphtri_sample(const struct sphtri *t, double u, double v)
{
    double half = 0.5 * u * t->area;
    double tan_half_c = vec3_length(vec3_sub(t->a, t->b)) / vec3_length(vec3_add(t->a, t->b));
    struct vec3 tac = vec3_normalize(sph_tangent(t->a, t->c));
    double den = tan_half_c * sin(t->alpha - half);
    struct vec3 cp;
    if (den > 0.0) {
        double x = sin(half) / den, cos_b, sin_b;
        /* cos b' = (1 - x^2)/(1 + x^2), sin b' = 2x/(1 + x^2); in 1/x above 1. */
        if (x <= 1.0) {
            cos_b = (1.0 - x * x) / (1.0 + x * x);
            sin_b = 2.0 * x / (1.0 + x * x);
        } else {
            double y = 1.0 / x;
            cos_b = (y * y - 1.0) / (y * y + 1.0);
            sin_b = 2.0 * y / (y * y + 1.0);
        }
        cp = vec3_add(vec3_scale(t->a, cos_b), vec3_scale(tac, sin_b));
    } else {
        cp = t->c;
    }
    struct vec3 d = vec3_sub(cp, t->b);
    double one_minus_z = v * 0.5 * vec3_length2(d);
    double sin_theta = sqrt(fm_fmax(0.0, one_minus_z * (2.0 - one_minus_z)));
    struct vec3 tangent = vec3_normalize(sph_tangent(t->b, cp));
    struct vec3 w = vec3_add(vec3_scale(t->b, 1.0 - one_minus_z), vec3_scale(tangent, sin_theta));
    return vec3_normalize(w);
}

bool sphpoly_init(struct sphpoly *sp, const struct polygon *poly, struct vec3 o)
{
    sp->n = 0;
    sp->solid_angle = 0.0;
    if (poly->n < 3 || poly->n > POLYGON_MAX) return false;
    struct plane pl = polygon_plane(poly);
    if (vec3_length2(pl.normal) == 0.0) return false;
    double size = 0.0;
    for (int i = 1; i < poly->n; ++i) size = fm_fmax(size, vec3_length(vec3_sub(poly->v[i], poly->v[0])));
    if (!(fabs(plane_distance(&pl, o)) > SPHERICAL_PLANE_REL * size)) return false;

    struct vec3 w[POLYGON_MAX];
    for (int i = 0; i < poly->n; ++i) w[i] = vec3_normalize(vec3_sub(poly->v[i], o));
    double total = 0.0;
    for (int i = 1; i + 1 < poly->n; ++i) {
        struct sphtri *t = &sp->tri[sp->n];
        if (!sphtri_init(t, w[0], w[i], w[i + 1])) continue;
        total += t->area;
        sp->cdf[sp->n++] = total;
    }
    if (sp->n == 0 || !(total > SPHERICAL_MIN_SOLID_ANGLE)) {
        sp->n = 0;
        return false;
    }
    for (int i = 0; i < sp->n; ++i) sp->cdf[i] /= total;
    sp->cdf[sp->n - 1] = 1.0;
    sp->solid_angle = total;
    return true;
}

struct vec3 sphpoly_sample(const struct sphpoly *sp, double u_select, double u, double v)
{
    int i = 0;
    while (i + 1 < sp->n && u_select >= sp->cdf[i]) ++i;
    return sphtri_sample(&sp->tri[i], u, v);
}

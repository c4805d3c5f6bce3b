#include "scene/bsdf.h"

#include "base/fastmath.h"

static double ggx_d(double alpha, struct vec3 h)
{
    double a2 = alpha * alpha;
    double t = h.x * h.x / a2 + h.y * h.y / a2 + h.z * h.z;
    return 1.0 / (M_PI * a2 * t * t);
}

/* Smith Lambda for GGX (isotropic). */
static double ggx_lambda(double alpha, struct vec3 w)
{
    double cos2 = w.z * w.z;
    if (cos2 <= 0.0) return INFINITY;
    double tan2 = (1.0 - cos2) / cos2;
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}

static struct rgb schlick(struct rgb f0, double cos_theta)
{
    double m = 1.0 - cos_theta, m5 = m * m * m * m * m;
    return rgb_make(f0.r + (1.0 - f0.r) * m5, f0.g + (1.0 - f0.g) * m5, f0.b + (1.0 - f0.b) * m5);
}

struct rgb bsdf_eval(const struct material *m, struct vec3 wo, struct vec3 wi)
{
    if (wo.z <= 0.0 || wi.z <= 0.0) return rgb_make(0.0, 0.0, 0.0);
    switch (m->kind) {
    case MATERIAL_DIFFUSE:
        return bsdf_lambert_f(m->albedo);
    case MATERIAL_GGX: {
        struct vec3 h = vec3_normalize(vec3_add(wo, wi));
        double d = ggx_d(m->roughness, h);
        /* Height-correlated Smith G2 = 1 / (1 + Lambda(wo) + Lambda(wi)). */
        double g2 = 1.0 / (1.0 + ggx_lambda(m->roughness, wo) + ggx_lambda(m->roughness, wi));
        struct rgb f = schlick(m->albedo, vec3_dot(wi, h));
        return rgb_scale(f, d * g2 / (4.0 * wo.z * wi.z));
    }
    }
    return rgb_make(0.0, 0.0, 0.0);
}

double bsdf_pdf(const struct material *m, struct vec3 wo, struct vec3 wi)
{
    if (wo.z <= 0.0 || wi.z <= 0.0) return 0.0;
    switch (m->kind) {
    case MATERIAL_DIFFUSE:
        return bsdf_lambert_pdf(wi.z);
    case MATERIAL_GGX: {
        /* Visible-normal sampling: pdf(h) = G1(wo) max(0, wo.h) D(h) / wo.z,
           and the reflection Jacobian 1 / (4 wo.h) gives G1(wo) D(h) / (4 wo.z). */
        struct vec3 h = vec3_normalize(vec3_add(wo, wi));
        double g1 = 1.0 / (1.0 + ggx_lambda(m->roughness, wo));
        return g1 * ggx_d(m->roughness, h) / (4.0 * wo.z);
    }
    }
    return 0.0;
}

/* Heitz 2018, "Sampling the GGX Distribution of Visible Normals". */
static struct vec3 ggx_sample_visible_normal(double alpha, struct vec3 wo, double u, double v)
{
    struct vec3 vh = vec3_normalize(vec3_make(alpha * wo.x, alpha * wo.y, wo.z));
    double lensq = vh.x * vh.x + vh.y * vh.y;
    struct vec3 t1 =
        lensq > 0.0 ? vec3_scale(vec3_make(-vh.y, vh.x, 0.0), 1.0 / sqrt(lensq)) : vec3_make(1.0, 0.0, 0.0);
    struct vec3 t2 = vec3_cross(vh, t1);
    double r = sqrt(u), sin_phi, cos_phi;
    fm_sincos(2.0 * M_PI * v, &sin_phi, &cos_phi);
    double p1 = r * cos_phi, p2 = r * sin_phi;
    double s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(fm_fmax(0.0, 1.0 - p1 * p1)) + s * p2;
    struct vec3 nh = vec3_add(vec3_add(vec3_scale(t1, p1), vec3_scale(t2, p2)),
                              vec3_scale(vh, sqrt(fm_fmax(0.0, 1.0 - p1 * p1 - p2 * p2))));
    return vec3_normalize(vec3_make(alpha * nh.x, alpha * nh.y, fm_fmax(1e-9, nh.z)));
}

bool bsdf_sample(const struct material *m, struct vec3 wo, double u, double v, struct bsdf_sample *out)
{
    if (wo.z <= 0.0) return false;
    switch (m->kind) {
    case MATERIAL_DIFFUSE:
        out->wi = bsdf_lambert_dir(u, v);
        break;
    case MATERIAL_GGX: {
        struct vec3 h = ggx_sample_visible_normal(m->roughness, wo, u, v);
        out->wi = vec3_sub(vec3_scale(h, 2.0 * vec3_dot(wo, h)), wo);
        break;
    }
    }
    if (out->wi.z <= 0.0) return false;
    out->f = bsdf_eval(m, wo, out->wi);
    out->pdf = bsdf_pdf(m, wo, out->wi);
    return out->pdf > 0.0;
}

/* bsdf.h: the two reflection models: Lambertian and GGX microfacet
   reflection (Smith height-correlated shadowing, Schlick Fresnel with the
   albedo as F0), sampled by cosine and by visible normals (Heitz 2018).
   Directions are unit vectors in the local shading frame (z = normal, the
   side of the outgoing direction).
   Local to one surface point: it traces no rays, knows no lights, and keeps
   no random state (callers pass the numbers). */
#ifndef BSDF_H
#define BSDF_H

#include <stdbool.h>

#include "base/fastmath.h"
#include "base/kinds.h"
#include "base/vec.h"

struct material {
    enum material_kind kind;
    struct rgb albedo; /* diffuse reflectance, or GGX F0 */
    double roughness;  /* GGX alpha */
};

/* f(wo, wi); zero when either lies below the surface. */
struct rgb bsdf_eval(const struct material *m, struct vec3 wo, struct vec3 wi);
/* Solid-angle density with which bsdf_sample picks wi. */
double bsdf_pdf(const struct material *m, struct vec3 wo, struct vec3 wi);

struct bsdf_sample {
    struct vec3 wi;
    struct rgb f; /* bsdf_eval(wo, wi) */
    double pdf;   /* bsdf_pdf(wo, wi) */
};
/* The Lambertian BSDF's cosine-distributed direction (local frame) from two
   uniforms, by Malley's method (the disk is sampled in polar coordinates).
   Inline, without branches, for the vectorised set-up (shading.c). */
FM_INLINE struct vec3 bsdf_lambert_dir(double u, double v)
{
    double r = sqrt(u), sin_phi, cos_phi;
    fm_sincos(2.0 * M_PI * v, &sin_phi, &cos_phi);
    double z2 = 1.0 - u;
    return vec3_make(r * cos_phi, r * sin_phi, sqrt(z2 > 0.0 ? z2 : 0.0));
}

/* The Lambertian BSDF, f = albedo / pi, and the density of
   bsdf_lambert_dir, cos / pi (cos: the direction's local z), for callers
   that have the cosine already. Inline: the vectorised lanes (shading.c)
   call them for every point. */
FM_INLINE struct rgb bsdf_lambert_f(struct rgb albedo)
{
    return rgb_scale(albedo, 1.0 / M_PI);
}
FM_INLINE double bsdf_lambert_pdf(double cos_theta)
{
    return cos_theta * (1.0 / M_PI);
}

/* False when no valid direction was produced (below the surface). */
bool bsdf_sample(const struct material *m, struct vec3 wo, double u, double v, struct bsdf_sample *out);

#endif

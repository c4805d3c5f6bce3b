/* bsdf.h: the two reflection models: Lambertian and GGX microfacet
   reflection (Smith height-correlated shadowing, Schlick Fresnel with the
   albedo as F0), sampled by cosine and by visible normals (Heitz 2018).
   Directions are unit vectors in the local shading frame (z = normal, the
   side of the outgoing direction). */
#ifndef BSDF_H
#define BSDF_H

#include <stdbool.h>

#include "config.h"
#include "vec.h"

struct material {
    enum material_kind kind;
    struct rgb albedo;   /* diffuse reflectance, or GGX F0 */
    double roughness;    /* GGX alpha */
};

/* f(wo, wi); zero when either lies below the surface. */
struct rgb bsdf_eval(const struct material *m, struct vec3 wo, struct vec3 wi);
/* Solid-angle density with which bsdf_sample picks wi. */
double bsdf_pdf(const struct material *m, struct vec3 wo, struct vec3 wi);

struct bsdf_sample {
    struct vec3 wi;
    struct rgb f;      /* bsdf_eval(wo, wi) */
    double pdf;        /* bsdf_pdf(wo, wi) */
};
/* False when no valid direction was produced (below the surface). */
bool bsdf_sample(const struct material *m, struct vec3 wo, double u, double v, struct bsdf_sample *out);

#endif

/* material_kind.h: the names of the reflection models a material can have.
   A header of its own, not bsdf.h, so that config.h can name the kind
   without the BSDF code and its inline math. */
#ifndef MATERIAL_KIND_H
#define MATERIAL_KIND_H

enum material_kind { MATERIAL_DIFFUSE, MATERIAL_GGX };

/* Names as written in configs, indexed by enum material_kind. */
extern const char *const material_names[2];

#endif

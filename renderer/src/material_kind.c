/* material_kind.c: the config names of the material kinds (see
   material_kind.h); apart from bsdf.c so that the config module links
   without the BSDF code. */
#include "material_kind.h"

const char *const material_names[2] = { "diffuse", "ggx" };

/* integrator_kind.c: the config names of the integrators (see
   integrator_kind.h); apart from integrator.c so that the config module
   links without the scene. */
#include "integrator_kind.h"

const char *const integrator_names[2] = { "direct", "path" };

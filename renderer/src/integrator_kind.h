/* integrator_kind.h: the names of the integrators a config can choose. A
   header of its own, not integrator.h, because config.h needs the word and
   integrator.h brings the scene, the strategies and shading with it. */
#ifndef INTEGRATOR_KIND_H
#define INTEGRATOR_KIND_H

enum integrator_kind { INTEGRATOR_DIRECT, INTEGRATOR_PATH };

/* Names as written in configs, indexed by enum integrator_kind. */
extern const char *const integrator_names[2];

#endif

/* version.h: the renderer's version, stamped into every snapshot; bump it
   whenever a change can alter images, so harness caches are invalidated. */
#ifndef VERSION_H
#define VERSION_H
#define RENDERER_VERSION "0.12.1"
#endif

/* exr_read.h: test support: reads back an EXR that film_write_exr wrote. */
#ifndef EXR_READ_H
#define EXR_READ_H

#include <stdbool.h>

#include "base/error.h"
#include "render/film.h"

/* Reads back what film_write_exr wrote: channels are found by name, img is
   allocated here (free with film_image_free), with a region layer when the
   file has the region channels (all of them and aov_region_classes as
   written, else an error). Strings in `info` point into `storage`, which
   the caller frees with free(). On failure (missing file, not an EXR,
   missing channel or attribute, damaged data) img and meta are left zeroed
   and err names the path. */
struct snapshot_read {
    struct snapshot_info info;
    char *storage;
};
bool film_read_exr(const char *path, struct film_image *img, struct snapshot_read *meta, struct error *err);

#endif

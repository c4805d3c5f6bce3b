/* film.h: per-pixel accumulation of radiance samples (running mean and
   second moment, Welford) and the OpenEXR snapshot format: R, G, B of the
   mean and variance.R/G/B of the mean, plus the optional region AOV
   (aov.h) as per-class fractions, written atomically.
   It never samples or traces: it stores what the render passes in. */
#ifndef FILM_H
#define FILM_H

#include <stdbool.h>
#include <stdint.h>

#include "render/aov.h"
#include "base/error.h"
#include "base/vec.h"

/* Accumulator. Every progressive pass adds exactly one sample to each pixel,
   so all pixels share the sample count `passes`; rows are owned by one thread
   within a pass, so no locking is needed. */
struct film {
    int width, height;
    double *mean;           /* 3 per pixel, row-major, row 0 at the top */
    double *m2;             /* 3 per pixel: sum of squared deviations */
    uint32_t *count;        /* 1 per pixel: samples accumulated (a non-finite
                          sample is dropped, so a pixel may lag `passes`) */
    int64_t passes;         /* completed passes */
    uint32_t *region_count; /* AOV_REGION_COUNT per pixel (film_enable_regions),
                          NULL when the region AOV is off: the pixel's accepted
                          samples per primary-hit class, so they sum to count */
};

/* Largest accepted image: each side at most FILM_MAX_SIDE pixels and at most
   FILM_MAX_PIXELS pixels in all (a film of that size holds 3 GiB of doubles).
   Larger requests fail with a message instead of an allocation attempt. */
#define FILM_MAX_SIDE   65536
#define FILM_MAX_PIXELS ((int64_t)1 << 27)

/* Whether a width x height film or image is within those bounds; false with
   "<what> size WxH ..." in err otherwise. */
bool film_check_size(int width, int height, const char *what, struct error *err);

/* Allocates a zeroed width x height film; fails on non-positive or absurd
   sizes and on allocation failure. */
bool film_init(struct film *f, int width, int height, struct error *err);
void film_free(struct film *f);
/* Allocates the zeroed region AOV counts of an initialised film. */
bool film_enable_regions(struct film *f, struct error *err);
/* Counts one accepted sample of pixel (x, y) in class cls (enum
   aov_region); the film must have region counts. */
static inline void film_add_region(struct film *f, int x, int y, int cls)
{
    ++f->region_count[((int64_t)y * f->width + x) * AOV_REGION_COUNT + cls];
}
/* Welford's update of one pixel's mean m and second moment s with sample
   c, inv = 1 / (its count after this sample). */
static inline void film_welford(double *m, double *s, struct rgb c, double inv)
{
    double v[3] = { c.r, c.g, c.b };
    for (int k = 0; k < 3; ++k) {
        double d = v[k] - m[k];
        m[k] += d * inv;
        s[k] += d * (v[k] - m[k]);
    }
}

/* Adds one sample to pixel (x, y) (Welford's update with the pixel's own
   count). Callers drop non-finite samples instead of adding them. */
static inline void film_add(struct film *f, int x, int y, struct rgb c)
{
    int64_t p = (int64_t)y * f->width + x;
    film_welford(f->mean + 3 * p, f->m2 + 3 * p, c, 1.0 / (double)(++f->count[p]));
}

/* film_add for pixels (0, y) .. (n - 1, y) with the samples c[x]: the
   same sums, bit for bit, with the reciprocals of the counts formed first
   in a vectorised loop (the division by each pixel's count would otherwise
   sit in one dependency chain per pixel, run one after the other). */
void film_add_row(struct film *f, int y, const struct rgb *c, int n);

/* A snapshot: float images ready to write. */
struct film_image {
    int width, height;
    float *rgb;      /* 3 per pixel: running mean */
    float *variance; /* 3 per pixel: variance of the mean (sigma^2 / n) */
    float *region;   /* AOV_REGION_COUNT per pixel: the fraction of the pixel's
                          samples in each class (0 for a pixel without samples),
                          or NULL when the image has no region AOV */
};

/* Same size rules as film_init; film_image_free is safe on a zeroed or freed image. */
bool film_image_alloc(struct film_image *img, int width, int height, struct error *err);
void film_image_free(struct film_image *img);
/* Adds the region AOV layer to an allocated image. */
bool film_image_enable_regions(struct film_image *img, struct error *err);
/* Copies the film's state after n = `f->passes` passes into img (same size).
   variance = m2 / (n (n - 1)), the unbiased sample variance over n; for
   n < 2 it is unknown and written as 0 (never NaN or Inf): readers must look
   at spp before trusting it. Doubles beyond the float range are clamped to
   +-FLT_MAX; a NaN that overflowing accumulation could produce becomes 0 in
   the mean and FLT_MAX in the variance, so no NaN is ever written. When img
   has a region layer (then f has region counts), region = count of the
   class / count of the pixel. */
void film_snapshot(const struct film *f, struct film_image *img);

/* The float channels every snapshot has, as film_write_exr names them:
   index k < 3 is the mean's R, G, B, k >= 3 the variance of channel k - 3. */
#define FILM_CHANNEL_COUNT 6
extern const char *const film_channel_names[FILM_CHANNEL_COUNT];
/* The region AOV's channels are FILM_REGION_PREFIX + aov_region_names[k]. */
#define FILM_REGION_PREFIX "region."

/* The header attributes every snapshot has, indexed by enum film_attribute
   (film_write_exr below gives their types). */
enum film_attribute {
    FILM_ATTR_RENDER_TIME_S,
    FILM_ATTR_SPP,
    FILM_ATTR_STRATEGY,
    FILM_ATTR_INTEGRATOR,
    FILM_ATTR_SAMPLER,
    FILM_ATTR_SEED,
    FILM_ATTR_CONFIG_HASH,
    FILM_ATTR_RENDERER_VERSION,
    FILM_ATTR_RAYS,
    FILM_ATTR_NONFINITE_SAMPLES
};
#define FILM_ATTRIBUTE_COUNT 10
extern const char *const film_attribute_names[FILM_ATTRIBUTE_COUNT];
/* The attribute only an image with the region AOV has. */
#define FILM_ATTR_AOV_REGION_CLASSES "aov_region_classes"

/* Header attributes of a snapshot. */
struct snapshot_info {
    double render_time_s; /* rendering only, snapshot I/O excluded */
    int64_t spp;
    const char *strategy;
    const char *integrator;
    const char *sampler; /* render.sampler */
    uint64_t seed;
    uint64_t config_hash;
    const char *renderer_version;
    uint64_t rays;              /* rays traced so far */
    uint64_t nonfinite_samples; /* samples dropped for NaN/Inf */
    bool compress;              /* ZIPS when true; none for timed snapshots,
                                      where zlib costs most of a frame's write
                                      and gains little on noisy floats */
};

/* Writes an EXR (ZIPS: zlib, one scanline per chunk; float channels B, G,
   R, variance.B/G/R; scanline, increasing Y, data window = display window
   = (0,0)-(w-1,h-1)) to "path.tmp-<pid>" then fsyncs and renames it to
   `path`, so a reader never sees a partial file. On failure (including a
   full disk) the previous file at `path`, if any, is untouched, nothing is
   left at the temporary name and err names the path and the cause. One
   writer per path at a time (the temporary name is per process).
   Header attributes: render_time_s (double), spp (int, saturated),
   strategy, integrator, sampler, seed (string, decimal), config_hash (string,
   16 hex digits), renderer_version (string), rays (double),
   nonfinite_samples (double). NULL strings are written as "". An image
   with a region layer adds the float channels region.<name> for every name
   of aov_region_names and the string attribute aov_region_classes (those
   names in order, space-separated). */
bool film_write_exr(const char *path, const struct film_image *img, const struct snapshot_info *info,
                    struct error *err);

#endif

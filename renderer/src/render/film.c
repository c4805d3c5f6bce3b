/* film.c: the film's accumulation (running mean and variance per pixel,
   the region counts) and its snapshots into images. The EXR file is
   film_exr.c's. */
#include "render/film.h"

#include "base/fastmath.h"

#include <assert.h>
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

bool film_check_size(int width, int height, const char *what, struct error *err)
{
    if (width <= 0 || height <= 0)
        return error_set(err, "%s size %dx%d: width and height must be positive", what, width, height);
    if (width > FILM_MAX_SIDE || height > FILM_MAX_SIDE || (int64_t)width * height > FILM_MAX_PIXELS)
        return error_set(err, "%s size %dx%d is too large (at most %d per side and %" PRId64 " pixels)", what, width,
                         height, FILM_MAX_SIDE, FILM_MAX_PIXELS);
    return true;
}

bool film_init(struct film *f, int width, int height, struct error *err)
{
    memset(f, 0, sizeof *f);
    if (!film_check_size(width, height, "film", err)) return false;
    size_t n = 3 * (size_t)width * (size_t)height;
    f->mean = calloc(n, sizeof *f->mean);
    f->m2 = calloc(n, sizeof *f->m2);
    f->count = calloc(n / 3, sizeof *f->count);
    if (!f->mean || !f->m2 || !f->count) {
        film_free(f);
        return error_set(err, "film %dx%d: cannot allocate %zu MiB", width, height,
                         (2 * n * sizeof(double) + n / 3 * sizeof(uint32_t)) >> 20);
    }
    f->width = width;
    f->height = height;
    return true;
}

/* Pixels per block of film_add_row: the reciprocals of their counts are
   formed first, in a loop of divisions that vectorises. */
#define ADD_BLOCK 64

FM_SIMD_CLONES
void film_add_row(struct film *f, int y, const struct rgb *c, int n)
{
    int64_t p0 = (int64_t)y * f->width;
    double *mean = f->mean + 3 * p0, *m2 = f->m2 + 3 * p0;
    uint32_t *count = f->count + p0;
    for (int b = 0; b < n; b += ADD_BLOCK) {
        int m = n - b < ADD_BLOCK ? n - b : ADD_BLOCK;
        double inv[ADD_BLOCK];
#pragma omp simd
        for (int i = 0; i < m; ++i) inv[i] = 1.0 / (double)(count[b + i] + 1u);
        for (int i = 0; i < m; ++i) {
            int x = b + i;
            film_welford(mean + 3 * x, m2 + 3 * x, c[x], inv[i]);
            ++count[x];
        }
    }
}

bool film_enable_regions(struct film *f, struct error *err)
{
    size_t n = (size_t)AOV_REGION_COUNT * (size_t)f->width * (size_t)f->height;
    free(f->region_count);
    f->region_count = calloc(n, sizeof *f->region_count);
    if (!f->region_count)
        return error_set(err, "film %dx%d: cannot allocate %zu MiB for the region AOV", f->width, f->height,
                         (n * sizeof(uint32_t)) >> 20);
    return true;
}

void film_free(struct film *f)
{
    free(f->mean);
    free(f->m2);
    free(f->count);
    free(f->region_count);
    memset(f, 0, sizeof *f);
}

bool film_image_alloc(struct film_image *img, int width, int height, struct error *err)
{
    memset(img, 0, sizeof *img);
    if (!film_check_size(width, height, "image", err)) return false;
    size_t n = 3 * (size_t)width * (size_t)height;
    img->rgb = malloc(n * sizeof *img->rgb);
    img->variance = malloc(n * sizeof *img->variance);
    if (!img->rgb || !img->variance) {
        film_image_free(img);
        return error_set(err, "image %dx%d: cannot allocate %zu MiB", width, height, (2 * n * sizeof(float)) >> 20);
    }
    img->width = width;
    img->height = height;
    return true;
}

bool film_image_enable_regions(struct film_image *img, struct error *err)
{
    size_t n = (size_t)AOV_REGION_COUNT * (size_t)img->width * (size_t)img->height;
    free(img->region);
    img->region = malloc(n * sizeof *img->region);
    if (!img->region)
        return error_set(err, "image %dx%d: cannot allocate %zu MiB for the region AOV", img->width, img->height,
                         (n * sizeof(float)) >> 20);
    return true;
}

void film_image_free(struct film_image *img)
{
    free(img->rgb);
    free(img->variance);
    free(img->region);
    memset(img, 0, sizeof *img);
}

/* Converting a double outside the float range is undefined behaviour in C
   (C99 6.3.1.5), and the files must never hold NaN: clamp instead. */
static float narrow_mean(double x)
{
    if (isnan(x)) return 0.0f;
    if (x > FLT_MAX) return FLT_MAX;
    if (x < -FLT_MAX) return -FLT_MAX;
    return (float)x;
}

/* m2 can come out a rounding error below 0 (the Welford update adds
   d * (v - m_new), whose factors can disagree in sign by one ulp); a NaN
   means the accumulation overflowed, so the honest variance is "huge". */
static float narrow_variance(double v)
{
    if (isnan(v) || v > FLT_MAX) return FLT_MAX;
    if (v <= 0.0) return 0.0f;
    return (float)v;
}

void film_snapshot(const struct film *f, struct film_image *img)
{
    assert(img->width == f->width && img->height == f->height);
    size_t pixels = (size_t)f->width * (size_t)f->height;
    for (size_t p = 0; p < pixels; ++p) {
        /* Variance of the mean of n samples: the unbiased sample variance
           m2 / (n - 1), divided by n. Unknown below two samples: 0 by contract. */
        double n = (double)f->count[p];
        double scale = n >= 2.0 ? 1.0 / (n * (n - 1.0)) : 0.0;
        for (size_t k = 3 * p; k < 3 * p + 3; ++k) {
            img->rgb[k] = narrow_mean(f->mean[k]);
            img->variance[k] = n >= 2.0 ? narrow_variance(f->m2[k] * scale) : 0.0f;
        }
    }
    if (!img->region) return;
    assert(f->region_count);
    for (size_t p = 0; p < pixels; ++p) {
        /* The counts sum to count[p]: dropped samples are in neither. */
        double inv = f->count[p] > 0 ? 1.0 / (double)f->count[p] : 0.0;
        for (size_t k = AOV_REGION_COUNT * p; k < AOV_REGION_COUNT * (p + 1); ++k)
            img->region[k] = (float)((double)f->region_count[k] * inv);
    }
}

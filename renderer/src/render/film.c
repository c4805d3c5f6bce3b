#include "render/film.h"

#include "base/fastmath.h"

#include <OpenEXR/openexr.h>

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

/* Compression of the pixel chunks. Snapshots are rewritten every fraction
   of a second, so speed matters more than size. Float radiance has random
   low mantissa bytes that neither the ZIP byte split and predictor (made
   for 16-bit halves) nor deflate can model: zlib gains only ~3% on noisy
   pixels (~30% on black or constant areas) and takes ~90% of the write
   time whatever the level. Measured on this machine (2 cores, idle), a
   noisy 256x256 / 1024x1024 snapshot, fsync included: ZIP level 1
   44 / 740 ms, ZIPS level 1 40 / 580 ms, ZIP level 6 48 / 815 ms, NONE
   3.5 / 48 ms. ZIPS (one scanline per chunk) is the fastest zlib variant
   and level 1 the fastest level at the same ratio. */
#define FILM_EXR_COMPRESSION EXR_COMPRESSION_ZIPS
#define FILM_ZIP_LEVEL       1

/* Channel names as stored; the file keeps them sorted, so readers map by
   name. Index k < 3 is rgb[k], k >= 3 is variance[k - 3]. */
const char *const film_channel_names[FILM_CHANNEL_COUNT] = {
    "R", "G", "B", "variance.R", "variance.G", "variance.B",
};

const char *const film_attribute_names[FILM_ATTRIBUTE_COUNT] = {
    [FILM_ATTR_RENDER_TIME_S] = "render_time_s",
    [FILM_ATTR_SPP] = "spp",
    [FILM_ATTR_STRATEGY] = "strategy",
    [FILM_ATTR_INTEGRATOR] = "integrator",
    [FILM_ATTR_SAMPLER] = "sampler",
    [FILM_ATTR_SEED] = "seed",
    [FILM_ATTR_CONFIG_HASH] = "config_hash",
    [FILM_ATTR_RENDERER_VERSION] = "renderer_version",
    [FILM_ATTR_RAYS] = "rays",
    [FILM_ATTR_NONFINITE_SAMPLES] = "nonfinite_samples",
};
#define ATTR(k) film_attribute_names[FILM_ATTR_##k]

#define REGION_PREFIX     FILM_REGION_PREFIX
#define REGION_PREFIX_LEN (sizeof REGION_PREFIX - 1)

/* Where channel `name` lives in img: its first float, with *per_pixel
   floats from one pixel to the next; NULL for a channel img does not hold. */
static float *channel_data(const struct film_image *img, const char *name, size_t len, int *per_pixel)
{
    for (int k = 0; k < FILM_CHANNEL_COUNT; ++k)
        if (len == strlen(film_channel_names[k]) && !memcmp(name, film_channel_names[k], len)) {
            *per_pixel = 3;
            return k < 3 ? img->rgb + k : img->variance + (k - 3);
        }
    if (!img->region || len <= REGION_PREFIX_LEN || memcmp(name, REGION_PREFIX, REGION_PREFIX_LEN)) return NULL;
    for (int k = 0; k < AOV_REGION_COUNT; ++k)
        if (len - REGION_PREFIX_LEN == strlen(aov_region_names[k]) &&
            !memcmp(name + REGION_PREFIX_LEN, aov_region_names[k], len - REGION_PREFIX_LEN)) {
            *per_pixel = AOV_REGION_COUNT;
            return img->region + k;
        }
    return NULL;
}

/* The aov_region_classes attribute: the class names in order. */
static void region_classes(char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < AOV_REGION_COUNT && used < size; ++k)
        used += (size_t)snprintf(buf + used, size - used, "%s%s", k ? " " : "", aov_region_names[k]);
}
#define REGION_CLASSES_MAX 128

static bool check_size(int width, int height, const char *what, struct error *err)
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
    if (!check_size(width, height, "film", err)) return false;
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
    if (!check_size(width, height, "image", err)) return false;
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

/* Our own file stream for the OpenEXR context: the library's default stream
   ignores the result of close() and never fsyncs, so a full disk could go
   unnoticed. Every failed write is remembered here with its errno. */
struct exr_stream {
    int fd;
    int error;    /* errno of the first failed read or write; 0 if none */
    int64_t size; /* file size, for reading */
};

static int64_t stream_write(exr_const_context_t ctxt, void *user, const void *buffer, uint64_t size, uint64_t offset,
                            exr_stream_error_func_ptr_t error_cb)
{
    struct exr_stream *s = user;
    const unsigned char *p = buffer;
    uint64_t done = 0;
    (void)ctxt;
    (void)error_cb;
    while (done < size) {
        ssize_t n = pwrite(s->fd, p + done, (size_t)(size - done), (off_t)(offset + done));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            if (!s->error) s->error = n < 0 ? errno : EIO;
            return -1;
        }
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t stream_read(exr_const_context_t ctxt, void *user, void *buffer, uint64_t size, uint64_t offset,
                           exr_stream_error_func_ptr_t error_cb)
{
    struct exr_stream *s = user;
    unsigned char *p = buffer;
    uint64_t done = 0;
    (void)ctxt;
    (void)error_cb;
    while (done < size) {
        ssize_t n = pread(s->fd, p + done, (size_t)(size - done), (off_t)(offset + done));
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            if (!s->error) s->error = errno;
            return -1;
        }
        if (n == 0) break; /* end of file: the library judges the short read */
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t stream_size(exr_const_context_t ctxt, void *user)
{
    (void)ctxt;
    return ((struct exr_stream *)user)->size;
}

/* Nothing below main prints, so the library's default handler (which writes
   to stderr) is replaced. The handler cannot reach our stream safely (asking
   the context for its user data from inside a locked call could deadlock),
   so errors are reported from the result codes and the stream's errno. */
static void exr_quiet(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    (void)code;
    (void)msg;
}

static exr_context_initializer_t exr_init_for(struct exr_stream *s)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_quiet;
    init.user_data = s;
    init.write_fn = stream_write;
    init.read_fn = stream_read;
    init.size_fn = stream_size;
    init.zip_level = FILM_ZIP_LEVEL;
    return init;
}

/* Formats the failure of an OpenEXR call: an I/O error the stream saw is the
   real cause and wins over the library's generic code. */
static bool exr_fail(struct error *err, const char *path, const char *call, exr_result_t rc, const struct exr_stream *s)
{
    if (s->error) return error_set(err, "%s: %s: %s", path, call, strerror(s->error));
    return error_set(err, "%s: %s: %s", path, call, exr_get_default_error_message(rc));
}

/* OpenEXRCore 3.1.5 keeps zlib's output when it is exactly as long as the
   raw chunk, but every reader takes a chunk whose packed size equals its
   raw size to be stored uncompressed, so such a chunk reads back as garbage
   (AcademySoftwareFoundation/openexr#2306, reported on 3.4.7, fixed since).
   Noisy float rows hit this every few dozen chunks. This wrapper around the
   library's compressor stores the raw bytes in that case, as the format
   requires for chunks that do not shrink. */
struct compress_hook {
    exr_result_t (*inner)(exr_encode_pipeline_t *enc);
};

static exr_result_t compress_unambiguous(exr_encode_pipeline_t *enc)
{
    const struct compress_hook *hook = enc->encoding_user_data;
    exr_result_t rc = hook->inner(enc);
    if (rc == EXR_ERR_SUCCESS && enc->compressed_bytes >= enc->packed_bytes &&
        enc->compressed_buffer != enc->packed_buffer) {
        if (enc->compressed_alloc_size < enc->packed_bytes) return EXR_ERR_OUT_OF_MEMORY;
        memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
        enc->compressed_bytes = enc->packed_bytes;
    }
    return rc;
}

/* Header definition and pixel chunks, into an open context. */
static bool write_exr_content(exr_context_t ctx, const char *path, const struct film_image *img,
                              const struct snapshot_info *info, struct exr_stream *s, struct error *err)
{
    exr_result_t rc;
    int part = 0;
    if ((rc = exr_add_part(ctx, "", EXR_STORAGE_SCANLINE, &part))) return exr_fail(err, path, "exr_add_part", rc, s);
    if ((rc = exr_initialize_required_attr_simple(ctx, part, img->width, img->height,
                                                  info->compress ? FILM_EXR_COMPRESSION : EXR_COMPRESSION_NONE)))
        return exr_fail(err, path, "exr_initialize_required_attr_simple", rc, s);
    for (int k = 0; k < FILM_CHANNEL_COUNT; ++k)
        if ((rc = exr_add_channel(ctx, part, film_channel_names[k], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1)))
            return exr_fail(err, path, "exr_add_channel", rc, s);
    char classes[REGION_CLASSES_MAX];
    for (int k = 0; img->region && k < AOV_REGION_COUNT; ++k) {
        char name[REGION_PREFIX_LEN + 32];
        snprintf(name, sizeof name, REGION_PREFIX "%s", aov_region_names[k]);
        /* Fractions: linear, not perceptual, as far as a viewer cares. */
        if ((rc = exr_add_channel(ctx, part, name, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1)))
            return exr_fail(err, path, "exr_add_channel", rc, s);
    }
    if (img->region) {
        region_classes(classes, sizeof classes);
        if ((rc = exr_attr_set_string(ctx, part, FILM_ATTR_AOV_REGION_CLASSES, classes)))
            return exr_fail(err, path, "exr_attr_set", rc, s);
    }

    char seed[24], hash[24];
    snprintf(seed, sizeof seed, "%" PRIu64, info->seed);
    snprintf(hash, sizeof hash, "%016" PRIx64, info->config_hash);
    /* An EXR int is 32-bit: saturate rather than wrap. */
    int32_t spp = info->spp > INT32_MAX ? INT32_MAX : info->spp < 0 ? 0 : (int32_t)info->spp;
    if ((rc = exr_attr_set_double(ctx, part, ATTR(RENDER_TIME_S), info->render_time_s)) ||
        (rc = exr_attr_set_int(ctx, part, ATTR(SPP), spp)) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(STRATEGY), info->strategy ? info->strategy : "")) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(INTEGRATOR), info->integrator ? info->integrator : "")) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(SAMPLER), info->sampler ? info->sampler : "")) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(SEED), seed)) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(CONFIG_HASH), hash)) ||
        (rc = exr_attr_set_string(ctx, part, ATTR(RENDERER_VERSION),
                                  info->renderer_version ? info->renderer_version : "")) ||
        (rc = exr_attr_set_double(ctx, part, ATTR(RAYS), (double)info->rays)) ||
        (rc = exr_attr_set_double(ctx, part, ATTR(NONFINITE_SAMPLES), (double)info->nonfinite_samples)))
        return exr_fail(err, path, "exr_attr_set", rc, s);
    if ((rc = exr_write_header(ctx))) return exr_fail(err, path, "exr_write_header", rc, s);

    int32_t lines = 0;
    if ((rc = exr_get_scanlines_per_chunk(ctx, part, &lines)))
        return exr_fail(err, path, "exr_get_scanlines_per_chunk", rc, s);
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    struct compress_hook hook = { NULL };
    bool ok = true;
    for (int y = 0; ok && y < img->height; y += lines) {
        exr_chunk_info_t chunk;
        const char *call = "exr_write_scanline_chunk_info";
        rc = exr_write_scanline_chunk_info(ctx, part, y, &chunk);
        if (!rc) {
            call = y == 0 ? "exr_encoding_initialize" : "exr_encoding_update";
            rc = y == 0 ? exr_encoding_initialize(ctx, part, &chunk, &enc)
                        : exr_encoding_update(ctx, part, &chunk, &enc);
        }
        if (!rc) {
            /* The pipeline lists channels sorted by name: match by name and
               point each at its interleaved component of rows y onward. */
            for (int c = 0; c < enc.channel_count; ++c) {
                exr_coding_channel_info_t *ch = &enc.channels[c];
                int per_pixel = 0;
                const float *base = channel_data(img, ch->channel_name, strlen(ch->channel_name), &per_pixel);
                assert(base);
                size_t row = (size_t)per_pixel * (size_t)img->width;
                ch->encode_from_ptr = (const uint8_t *)(base + (size_t)chunk.start_y * row);
                ch->user_pixel_stride = per_pixel * (int32_t)sizeof(float);
                ch->user_line_stride = (int32_t)(row * sizeof(float));
                ch->user_bytes_per_element = (int16_t)sizeof(float);
                ch->user_data_type = EXR_PIXEL_FLOAT;
            }
            call = "exr_encoding_choose_default_routines";
            if (y == 0 && !(rc = exr_encoding_choose_default_routines(ctx, part, &enc)) && enc.compress_fn) {
                hook.inner = enc.compress_fn;
                enc.compress_fn = compress_unambiguous;
                enc.encoding_user_data = &hook;
            }
        }
        if (!rc) {
            call = "exr_encoding_run";
            rc = exr_encoding_run(ctx, part, &enc);
        }
        if (rc) ok = exr_fail(err, path, call, rc, s);
    }
    exr_encoding_destroy(ctx, &enc);
    return ok;
}

bool film_write_exr(const char *path, const struct film_image *img, const struct snapshot_info *info, struct error *err)
{
    if (!img || !img->rgb || !img->variance || !info) return error_set(err, "%s: nothing to write", path);
    if (!check_size(img->width, img->height, "image", err)) return false;

    size_t tmp_len = strlen(path) + 32;
    char *tmp = malloc(tmp_len);
    if (!tmp) return error_set(err, "%s: out of memory", path);
    snprintf(tmp, tmp_len, "%s.tmp-%ld", path, (long)getpid());

    struct exr_stream s = { -1, 0, 0 };
    s.fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (s.fd < 0) {
        error_set(err, "%s: cannot create %s: %s", path, tmp, strerror(errno));
        free(tmp);
        return false;
    }

    exr_context_initializer_t init = exr_init_for(&s);
    exr_context_t ctx = NULL;
    exr_result_t rc = exr_start_write(&ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
    bool ok = rc ? exr_fail(err, path, "exr_start_write", rc, &s) : write_exr_content(ctx, path, img, info, &s, err);
    if (ctx) {
        /* exr_finish flushes what is left (the chunk offset table); any write
           it makes goes through stream_write, so s.error catches it. */
        rc = exr_finish(&ctx);
        if (ok && (rc || s.error)) ok = exr_fail(err, path, "exr_finish", rc, &s);
    }
    /* fsync before rename: otherwise a crash could leave the new name
       pointing at a file whose data never reached the disk. */
    if (ok && fsync(s.fd) != 0) ok = error_set(err, "%s: fsync %s: %s", path, tmp, strerror(errno));
    if (close(s.fd) != 0 && ok) ok = error_set(err, "%s: close %s: %s", path, tmp, strerror(errno));
    if (ok && rename(tmp, path) != 0) ok = error_set(err, "%s: rename from %s: %s", path, tmp, strerror(errno));
    if (!ok) unlink(tmp);
    free(tmp);
    return ok;
}

/* Header attributes, copied out of the context. */
static bool read_exr_info(exr_const_context_t ctx, const char *path, struct snapshot_read *meta, struct error *err)
{
    const char *const string_names[3] = { ATTR(STRATEGY), ATTR(INTEGRATOR), ATTR(RENDERER_VERSION) };
    exr_result_t rc;
    const char *name = ATTR(RENDER_TIME_S);
    double rays = 0, nonfinite = 0;
    int32_t spp = 0;
    if ((rc = exr_attr_get_double(ctx, 0, name, &meta->info.render_time_s)) ||
        (rc = exr_attr_get_int(ctx, 0, name = ATTR(SPP), &spp)) ||
        (rc = exr_attr_get_double(ctx, 0, name = ATTR(RAYS), &rays)) ||
        (rc = exr_attr_get_double(ctx, 0, name = ATTR(NONFINITE_SAMPLES), &nonfinite)))
        return error_set(err, "%s: attribute %s: %s", path, name, exr_get_default_error_message(rc));
    meta->info.spp = spp;
    /* Counts were stored as doubles: exact up to 2^53, far beyond any run. */
    meta->info.rays = rays > 0 ? (uint64_t)rays : 0;
    meta->info.nonfinite_samples = nonfinite > 0 ? (uint64_t)nonfinite : 0;

    const char *text[3];
    int32_t len[3];
    size_t total = 0;
    for (int i = 0; i < 3; ++i) {
        if ((rc = exr_attr_get_string(ctx, 0, string_names[i], &len[i], &text[i])))
            return error_set(err, "%s: attribute %s: %s", path, string_names[i], exr_get_default_error_message(rc));
        total += (size_t)len[i] + 1;
    }
    meta->storage = malloc(total);
    if (!meta->storage) return error_set(err, "%s: out of memory", path);
    /* The library's strings are not NUL-terminated: copy with the length. */
    char *dst = meta->storage;
    const char **fields[3] = { &meta->info.strategy, &meta->info.integrator, &meta->info.renderer_version };
    for (int i = 0; i < 3; ++i) {
        memcpy(dst, text[i], (size_t)len[i]);
        dst[len[i]] = '\0';
        *fields[i] = dst;
        dst += len[i] + 1;
    }

    /* seed: decimal; config_hash: exactly 16 hex digits. */
    char buf[24];
    const char *str;
    int32_t n;
    if ((rc = exr_attr_get_string(ctx, 0, ATTR(SEED), &n, &str)))
        return error_set(err, "%s: attribute seed: %s", path, exr_get_default_error_message(rc));
    bool good = n > 0 && n < 21;
    for (int i = 0; good && i < n; ++i) good = str[i] >= '0' && str[i] <= '9';
    if (good) {
        memcpy(buf, str, (size_t)n);
        buf[n] = '\0';
        errno = 0;
        meta->info.seed = strtoull(buf, NULL, 10);
        good = errno == 0;
    }
    if (!good) return error_set(err, "%s: attribute seed is not a 64-bit decimal number", path);
    if ((rc = exr_attr_get_string(ctx, 0, ATTR(CONFIG_HASH), &n, &str)))
        return error_set(err, "%s: attribute config_hash: %s", path, exr_get_default_error_message(rc));
    good = n == 16;
    for (int i = 0; good && i < n; ++i)
        good = (str[i] >= '0' && str[i] <= '9') || (str[i] >= 'a' && str[i] <= 'f') || (str[i] >= 'A' && str[i] <= 'F');
    if (!good) return error_set(err, "%s: attribute config_hash is not 16 hex digits", path);
    memcpy(buf, str, 16);
    buf[16] = '\0';
    meta->info.config_hash = strtoull(buf, NULL, 16);
    return true;
}

/* Pixels of part 0 into img (allocated here). */
static bool read_exr_pixels(exr_const_context_t ctx, const char *path, struct film_image *img, struct exr_stream *s,
                            struct error *err)
{
    exr_result_t rc;
    exr_storage_t storage;
    if ((rc = exr_get_storage(ctx, 0, &storage))) return exr_fail(err, path, "exr_get_storage", rc, s);
    if (storage != EXR_STORAGE_SCANLINE) return error_set(err, "%s: not a scanline image", path);
    exr_attr_box2i_t dw;
    if ((rc = exr_get_data_window(ctx, 0, &dw))) return exr_fail(err, path, "exr_get_data_window", rc, s);
    int64_t width = (int64_t)dw.max.x - dw.min.x + 1, height = (int64_t)dw.max.y - dw.min.y + 1;
    if (width > FILM_MAX_SIDE || height > FILM_MAX_SIDE)
        return error_set(err, "%s: data window %" PRId64 "x%" PRId64 " is too large", path, width, height);

    const exr_attr_chlist_t *chlist;
    if ((rc = exr_get_channels(ctx, 0, &chlist))) return exr_fail(err, path, "exr_get_channels", rc, s);
    /* The six radiance channels, then the region AOV's: all or none. */
    char wanted[FILM_CHANNEL_COUNT + AOV_REGION_COUNT][REGION_PREFIX_LEN + 32];
    bool have[FILM_CHANNEL_COUNT + AOV_REGION_COUNT];
    int n_regions = 0;
    for (int k = 0; k < FILM_CHANNEL_COUNT + AOV_REGION_COUNT; ++k) {
        if (k < FILM_CHANNEL_COUNT) snprintf(wanted[k], sizeof wanted[k], "%s", film_channel_names[k]);
        else snprintf(wanted[k], sizeof wanted[k], REGION_PREFIX "%s", aov_region_names[k - FILM_CHANNEL_COUNT]);
        const exr_attr_chlist_entry_t *e = NULL;
        for (int c = 0; c < chlist->num_channels && !e; ++c) {
            const exr_attr_string_t *nm = &chlist->entries[c].name;
            if ((size_t)nm->length == strlen(wanted[k]) && !memcmp(nm->str, wanted[k], (size_t)nm->length))
                e = &chlist->entries[c];
        }
        have[k] = e != NULL;
        if (!e && k < FILM_CHANNEL_COUNT) return error_set(err, "%s: missing channel %s", path, wanted[k]);
        if (e && (e->pixel_type != EXR_PIXEL_FLOAT || e->x_sampling != 1 || e->y_sampling != 1))
            return error_set(err, "%s: channel %s is not a full-resolution 32-bit float channel", path, wanted[k]);
        n_regions += k >= FILM_CHANNEL_COUNT && e;
    }
    for (int k = FILM_CHANNEL_COUNT; n_regions > 0 && k < FILM_CHANNEL_COUNT + AOV_REGION_COUNT; ++k)
        if (!have[k])
            return error_set(err, "%s: missing channel %s (the file has other region channels)", path, wanted[k]);
    if (n_regions > 0) {
        /* The channels are found by name; the attribute must still agree,
           or the file was written with other classes. */
        char classes[REGION_CLASSES_MAX];
        const char *str;
        int32_t len;
        region_classes(classes, sizeof classes);
        if ((rc = exr_attr_get_string(ctx, 0, FILM_ATTR_AOV_REGION_CLASSES, &len, &str)))
            return error_set(err, "%s: attribute aov_region_classes: %s", path, exr_get_default_error_message(rc));
        if ((size_t)len != strlen(classes) || memcmp(str, classes, (size_t)len))
            return error_set(err, "%s: attribute aov_region_classes is \"%.*s\" (expected \"%s\")", path,
                             len > 200 ? 200 : (int)len, str, classes);
    }
    if (!film_image_alloc(img, (int)width, (int)height, err) ||
        (n_regions > 0 && !film_image_enable_regions(img, err))) {
        char inner[ERROR_MESSAGE_MAX];
        snprintf(inner, sizeof inner, "%s", err ? err->message : "");
        film_image_free(img);
        return error_set(err, "%s: %s", path, inner);
    }

    int32_t lines = 0;
    if ((rc = exr_get_scanlines_per_chunk(ctx, 0, &lines)))
        return exr_fail(err, path, "exr_get_scanlines_per_chunk", rc, s);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    bool ok = true;
    for (int64_t y = dw.min.y; ok && y <= dw.max.y; y += lines) {
        exr_chunk_info_t chunk;
        const char *call = "exr_read_scanline_chunk_info";
        rc = exr_read_scanline_chunk_info(ctx, 0, (int)y, &chunk);
        bool first = y == dw.min.y;
        if (!rc) {
            call = first ? "exr_decoding_initialize" : "exr_decoding_update";
            rc = first ? exr_decoding_initialize(ctx, 0, &chunk, &dec) : exr_decoding_update(ctx, 0, &chunk, &dec);
        }
        if (!rc) {
            for (int c = 0; c < dec.channel_count; ++c) {
                exr_coding_channel_info_t *ch = &dec.channels[c];
                int per_pixel = 0;
                float *base = channel_data(img, ch->channel_name, strlen(ch->channel_name), &per_pixel);
                if (!base) {
                    ch->decode_to_ptr = NULL; /* a channel we do not use: skipped */
                    continue;
                }
                size_t row = (size_t)per_pixel * (size_t)width;
                ch->decode_to_ptr = (uint8_t *)(base + (size_t)(chunk.start_y - dw.min.y) * row);
                ch->user_pixel_stride = per_pixel * (int32_t)sizeof(float);
                ch->user_line_stride = (int32_t)(row * sizeof(float));
                ch->user_bytes_per_element = (int16_t)sizeof(float);
                ch->user_data_type = EXR_PIXEL_FLOAT;
            }
            call = "exr_decoding_choose_default_routines";
            rc = first ? exr_decoding_choose_default_routines(ctx, 0, &dec) : EXR_ERR_SUCCESS;
        }
        if (!rc) {
            call = "exr_decoding_run";
            rc = exr_decoding_run(ctx, 0, &dec);
        }
        if (rc) ok = exr_fail(err, path, call, rc, s);
    }
    exr_decoding_destroy(ctx, &dec);
    if (!ok) film_image_free(img);
    return ok;
}

bool film_read_exr(const char *path, struct film_image *img, struct snapshot_read *meta, struct error *err)
{
    memset(img, 0, sizeof *img);
    memset(meta, 0, sizeof *meta);
    struct exr_stream s = { -1, 0, 0 };
    s.fd = open(path, O_RDONLY | O_CLOEXEC);
    if (s.fd < 0) return error_set(err, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(s.fd, &st) != 0) {
        error_set(err, "%s: cannot stat: %s", path, strerror(errno));
        close(s.fd);
        return false;
    }
    s.size = (int64_t)st.st_size;

    /* Check the magic number first, so that "not an EXR" reads as such
       rather than as a generic header error. */
    static const unsigned char magic[4] = { 0x76, 0x2f, 0x31, 0x01 };
    unsigned char head[4];
    if (stream_read(NULL, &s, head, 4, 0, NULL) != 4 || memcmp(head, magic, 4)) {
        if (s.error) error_set(err, "%s: cannot read: %s", path, strerror(s.error));
        else error_set(err, "%s: not an OpenEXR file (bad magic number)", path);
        close(s.fd);
        return false;
    }

    exr_context_initializer_t init = exr_init_for(&s);
    exr_context_t ctx = NULL;
    exr_result_t rc = exr_start_read(&ctx, path, &init);
    bool ok = rc ? exr_fail(err, path, "invalid OpenEXR header", rc, &s)
                 : read_exr_pixels(ctx, path, img, &s, err) && read_exr_info(ctx, path, meta, err);
    if (ctx) exr_finish(&ctx);
    close(s.fd);
    if (!ok) {
        film_image_free(img);
        free(meta->storage);
        memset(meta, 0, sizeof *meta);
    }
    return ok;
}

/* film_exr.c: film images into OpenEXR files (the only OpenEXR code of
   the renderer): channels, attributes, compression, and a write that is
   atomic and reports every I/O error. */
#include "render/film.h"

#include <OpenEXR/openexr.h>

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

/* Compression of the pixel chunks. Snapshots are rewritten every fraction
   of a second, so speed matters more than size. Float radiance has random
   low mantissa bytes that neither the ZIP byte split and predictor (made
   for 16-bit halves) nor deflate can model: zlib gains little on noisy
   pixels (more on black or constant areas) and takes most of the write
   time whatever the level (docs/performance.md has the timings). ZIPS
   (one scanline per chunk) is the fastest zlib variant and level 1 the
   fastest level at the same ratio. */
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

/* Our own file stream for the OpenEXR context: the library's default stream
   ignores the result of close() and never fsyncs, so a full disk could go
   unnoticed. Every failed write is remembered here with its errno. */
struct exr_stream {
    int fd;
    int error; /* errno of the first failed write; 0 if none */
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
    if (!film_check_size(img->width, img->height, "image", err)) return false;

    size_t tmp_len = strlen(path) + 32;
    char *tmp = malloc(tmp_len);
    if (!tmp) return error_set(err, "%s: out of memory", path);
    snprintf(tmp, tmp_len, "%s.tmp-%ld", path, (long)getpid());

    struct exr_stream s = { -1, 0 };
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

/* exr_read.c: reads back what film_write_exr writes, for the tests: its
   own stream and channel map, so that a test of the writer does not share
   the writer's code. The renderer itself never reads an EXR. */
#include "exr_read.h"

#include <OpenEXR/openexr.h>

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#define ATTR(k) film_attribute_names[FILM_ATTR_##k]

#define REGION_PREFIX     FILM_REGION_PREFIX
#define REGION_PREFIX_LEN (sizeof REGION_PREFIX - 1)

/* A read-only file stream for the OpenEXR context, remembering the errno of
   a failed read. */
struct exr_stream {
    int fd;
    int error;    /* errno of the first failed read; 0 if none */
    int64_t size; /* file size, for reading */
};

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
    init.read_fn = stream_read;
    init.size_fn = stream_size;
    return init;
}

/* Formats the failure of an OpenEXR call: an I/O error the stream saw is the
   real cause and wins over the library's generic code. */
static bool exr_fail(struct error *err, const char *path, const char *call, exr_result_t rc, const struct exr_stream *s)
{
    if (s->error) return error_set(err, "%s: %s: %s", path, call, strerror(s->error));
    return error_set(err, "%s: %s: %s", path, call, exr_get_default_error_message(rc));
}

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

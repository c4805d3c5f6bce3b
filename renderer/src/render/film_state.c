#include "render/film_state.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

static const char state_magic[8] = { 'P', 'L', 'F', 'S', 'T', 'A', 'T', 'E' };
#define STATE_HEADER_BYTES    124u
#define STATE_HEADER_BYTES_V1 120u
#define STATE_NAME_MAX        63u
#define STATE_ARRAYS_MAX      16

enum state_type { STATE_F64 = 1, STATE_U32 = 2 };

static size_t type_size(uint32_t type)
{
    return type == STATE_F64 ? sizeof(double) : type == STATE_U32 ? sizeof(uint32_t) : 0;
}

/* One per-pixel accumulator of the film. */
struct state_array {
    const char *name;
    enum state_type type;
    size_t per_pixel;
    void *data;
};

/* Every per-pixel accumulator of struct film, one line each. Adding an
   accumulator to the film is adding its line here: writers then store it,
   and readers refuse a state without it. */
/* The region AOV's counts (film.region_count), saved when the film has them. */
#define REGION_COUNT_ARRAY "region_count"

static int film_arrays(const struct film *f, struct state_array out[STATE_ARRAYS_MAX])
{
    int n = 0;
    out[n++] = (struct state_array){ "mean", STATE_F64, 3, f->mean };
    out[n++] = (struct state_array){ "m2", STATE_F64, 3, f->m2 };
    out[n++] = (struct state_array){ "count", STATE_U32, 1, f->count };
    if (f->region_count)
        out[n++] = (struct state_array){ REGION_COUNT_ARRAY, STATE_U32, AOV_REGION_COUNT, f->region_count };
    return n;
}

/* FNV-1a 64, continued over consecutive pieces of the file. */
#define FNV_OFFSET 14695981039346656037ull
static uint64_t fnv1a64_update(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

/* ---- writing ---------------------------------------------------------- */

/* Small fields are gathered in `buf`; arrays go straight from the film. */
struct state_writer {
    int fd;
    int error; /* errno of the first failed write; 0 if none */
    uint64_t hash;
    unsigned char buf[256];
    size_t len;
};

static void write_raw(struct state_writer *w, const void *data, size_t n)
{
    const unsigned char *p = data;
    while (n > 0 && !w->error) {
        ssize_t k = write(w->fd, p, n);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) {
            w->error = k < 0 ? errno : EIO;
            return;
        }
        p += k;
        n -= (size_t)k;
    }
}

static void flush_buf(struct state_writer *w)
{
    write_raw(w, w->buf, w->len);
    w->len = 0;
}

/* Appends n bytes (hashed). */
static void put(struct state_writer *w, const void *data, size_t n)
{
    w->hash = fnv1a64_update(w->hash, data, n);
    if (w->len + n > sizeof w->buf) flush_buf(w);
    if (n > sizeof w->buf) {
        write_raw(w, data, n);
        return;
    }
    memcpy(w->buf + w->len, data, n);
    w->len += n;
}

static void put_u32(struct state_writer *w, uint32_t v)
{
    put(w, &v, sizeof v);
}
static void put_i32(struct state_writer *w, int32_t v)
{
    put(w, &v, sizeof v);
}
static void put_u64(struct state_writer *w, uint64_t v)
{
    put(w, &v, sizeof v);
}
static void put_i64(struct state_writer *w, int64_t v)
{
    put(w, &v, sizeof v);
}
static void put_f64(struct state_writer *w, double v)
{
    put(w, &v, sizeof v);
}

static void write_content(struct state_writer *w, const struct film_state *s)
{
    const struct film *f = &s->film;
    struct state_array arrays[STATE_ARRAYS_MAX];
    int n = film_arrays(f, arrays);
    size_t pixels = (size_t)f->width * (size_t)f->height;

    put(w, state_magic, sizeof state_magic);
    put_u32(w, FILM_STATE_VERSION);
    put_u32(w, STATE_HEADER_BYTES);
    put_i32(w, f->width);
    put_i32(w, f->height);
    put_i64(w, f->passes);
    put_f64(w, s->render_time_s);
    put_f64(w, s->render_cpu_s);
    put_f64(w, s->snapshot_cpu_s);
    put_f64(w, s->snapshot_pause_s);
    put_u64(w, s->stats.rays);
    put_u64(w, s->stats.shadow_rays);
    put_u64(w, s->stats.shadow_blocked);
    put_u64(w, s->stats.light_samples);
    put_u64(w, s->stats.light_missed);
    put_u64(w, s->nonfinite_samples);
    put_i32(w, s->snapshots);
    put_u32(w, (uint32_t)n);
    put_u64(w, s->seed);
    put_u64(w, s->image_hash);
    put_u32(w, (uint32_t)s->sampler);
    for (int i = 0; i < n; ++i) {
        const struct state_array *a = &arrays[i];
        uint64_t count = (uint64_t)(a->per_pixel * pixels);
        put_u32(w, (uint32_t)strlen(a->name));
        put(w, a->name, strlen(a->name));
        put_u32(w, a->type);
        put_u64(w, count);
        put_u64(w, count * type_size(a->type));
        put(w, a->data, (size_t)count * type_size(a->type));
    }
    uint64_t sum = w->hash;
    put(w, &sum, sizeof sum);
    flush_buf(w);
}

bool film_state_write(const char *path, const struct film_state *s, struct error *err)
{
    const struct film *f = &s->film;
    if (!f->mean || !f->m2 || !f->count || f->width <= 0 || f->height <= 0)
        return error_set(err, "%s: no film to write", path);
    size_t tmp_len = strlen(path) + 32;
    char *tmp = malloc(tmp_len);
    if (!tmp) return error_set(err, "%s: out of memory", path);
    snprintf(tmp, tmp_len, "%s.tmp-%ld", path, (long)getpid());

    struct state_writer *w = calloc(1, sizeof *w);
    if (!w) {
        free(tmp);
        return error_set(err, "%s: out of memory", path);
    }
    w->hash = FNV_OFFSET;
    w->fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    bool ok = w->fd >= 0 || error_set(err, "%s: cannot create %s: %s", path, tmp, strerror(errno));
    if (ok) {
        write_content(w, s);
        if (w->error) ok = error_set(err, "%s: write %s: %s", path, tmp, strerror(w->error));
        /* fsync before rename: otherwise a crash could leave the new name
           pointing at a file whose data never reached the disk. */
        if (ok && fsync(w->fd) != 0) ok = error_set(err, "%s: fsync %s: %s", path, tmp, strerror(errno));
        if (close(w->fd) != 0 && ok) ok = error_set(err, "%s: close %s: %s", path, tmp, strerror(errno));
        if (ok && rename(tmp, path) != 0) ok = error_set(err, "%s: rename from %s: %s", path, tmp, strerror(errno));
        if (!ok) unlink(tmp);
    }
    free(w);
    free(tmp);
    return ok;
}

/* ---- reading ---------------------------------------------------------- */

struct state_reader {
    int fd;
    const char *path;
    uint64_t hash;
    uint64_t left; /* bytes of the file not read yet */
    uint64_t size;
};

/* Reads exactly n bytes (hashed). */
static bool get(struct state_reader *r, void *data, size_t n, struct error *err)
{
    if (n > r->left)
        return error_set(err, "%s: truncated (%" PRIu64 " bytes; the state ends before its checksum)", r->path,
                         r->size);
    unsigned char *p = data;
    size_t done = 0;
    while (done < n) {
        ssize_t k = read(r->fd, p + done, n - done);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) return error_set(err, "%s: cannot read: %s", r->path, strerror(errno));
        if (k == 0) return error_set(err, "%s: truncated while reading", r->path);
        done += (size_t)k;
    }
    r->left -= n;
    r->hash = fnv1a64_update(r->hash, data, n);
    return true;
}

static bool get_u32(struct state_reader *r, uint32_t *v, struct error *err)
{
    return get(r, v, sizeof *v, err);
}
static bool get_i32(struct state_reader *r, int32_t *v, struct error *err)
{
    return get(r, v, sizeof *v, err);
}
static bool get_u64(struct state_reader *r, uint64_t *v, struct error *err)
{
    return get(r, v, sizeof *v, err);
}
static bool get_i64(struct state_reader *r, int64_t *v, struct error *err)
{
    return get(r, v, sizeof *v, err);
}
static bool get_f64(struct state_reader *r, double *v, struct error *err)
{
    return get(r, v, sizeof *v, err);
}

/* The bytes of an array this film does not hold: read for the checksum. */
static bool skip(struct state_reader *r, uint64_t n, struct error *err)
{
    unsigned char buf[4096];
    while (n > 0) {
        size_t k = n < sizeof buf ? (size_t)n : sizeof buf;
        if (!get(r, buf, k, err)) return false;
        n -= k;
    }
    return true;
}

static bool read_header(struct state_reader *r, struct film_state *s, uint32_t *n_arrays, struct error *err)
{
    char magic[8];
    uint32_t version, header_bytes;
    if (!get(r, magic, sizeof magic, err)) return false;
    if (memcmp(magic, state_magic, sizeof magic))
        return error_set(err, "%s: not a render state file (bad magic number)", r->path);
    if (!get_u32(r, &version, err) || !get_u32(r, &header_bytes, err)) return false;
    if (version != FILM_STATE_VERSION && version != 1)
        return error_set(err, "%s: state format version %" PRIu32 " (this renderer reads versions 1 to %d)", r->path,
                         version, FILM_STATE_VERSION);
    uint32_t expect_bytes = version == 1 ? STATE_HEADER_BYTES_V1 : STATE_HEADER_BYTES;
    if (header_bytes != expect_bytes)
        return error_set(err, "%s: header of %" PRIu32 " bytes (expected %" PRIu32 "): damaged", r->path, header_bytes,
                         expect_bytes);
    int32_t width, height;
    int64_t passes;
    if (!get_i32(r, &width, err) || !get_i32(r, &height, err) || !get_i64(r, &passes, err) ||
        !get_f64(r, &s->render_time_s, err) || !get_f64(r, &s->render_cpu_s, err) ||
        !get_f64(r, &s->snapshot_cpu_s, err) || !get_f64(r, &s->snapshot_pause_s, err) ||
        !get_u64(r, &s->stats.rays, err) || !get_u64(r, &s->stats.shadow_rays, err) ||
        !get_u64(r, &s->stats.shadow_blocked, err) || !get_u64(r, &s->stats.light_samples, err) ||
        !get_u64(r, &s->stats.light_missed, err) || !get_u64(r, &s->nonfinite_samples, err) ||
        !get_i32(r, &s->snapshots, err) || !get_u32(r, n_arrays, err) || !get_u64(r, &s->seed, err) ||
        !get_u64(r, &s->image_hash, err))
        return false;
    /* Version 1 states predate render.sampler: they are independent. */
    uint32_t sampler = SAMPLER_INDEPENDENT;
    if (version >= 2 && !get_u32(r, &sampler, err)) return false;
    if (sampler >= SAMPLER_COUNT) return error_set(err, "%s: unknown sampler %" PRIu32 ": damaged", r->path, sampler);
    s->sampler = (enum sampler_kind)sampler;
    if (passes < 0 || s->snapshots < 0 || *n_arrays > STATE_ARRAYS_MAX || !isfinite(s->render_time_s) ||
        s->render_time_s < 0.0)
        return error_set(err, "%s: header values out of range: damaged", r->path);
    struct error why;
    if (!film_init(&s->film, width, height, &why)) return error_set(err, "%s: %s", r->path, why.message);
    s->film.passes = passes;
    return true;
}

/* One array: into the film if it is one of its accumulators (type and
   size checked), skipped otherwise. `seen` marks the film's arrays read. */
static bool read_array(struct state_reader *r, struct film *film, struct state_array *want, int *n_wanted, bool *seen,
                       size_t pixels, struct error *err)
{
    int n_want = *n_wanted;
    uint32_t len, type;
    uint64_t count, bytes;
    char name[STATE_NAME_MAX + 1];
    if (!get_u32(r, &len, err)) return false;
    if (len == 0 || len > STATE_NAME_MAX)
        return error_set(err, "%s: array name of %" PRIu32 " bytes: damaged", r->path, len);
    if (!get(r, name, len, err)) return false;
    name[len] = '\0';
    if (!get_u32(r, &type, err) || !get_u64(r, &count, err) || !get_u64(r, &bytes, err)) return false;
    if (!type_size(type) || bytes / type_size(type) != count || bytes % type_size(type))
        return error_set(err, "%s: array %s: type %" PRIu32 ", %" PRIu64 " elements in %" PRIu64 " bytes: damaged",
                         r->path, name, type, count, bytes);
    if (bytes > r->left)
        return error_set(err, "%s: truncated (%" PRIu64 " bytes; array %s needs %" PRIu64 " more)", r->path, r->size,
                         name, bytes - r->left);
    int k = 0;
    while (k < n_want && strcmp(want[k].name, name)) ++k;
    if (k == n_want && !film->region_count && !strcmp(name, REGION_COUNT_ARRAY)) {
        /* The region AOV's counts are there only when the render had the
           AOV on (as its config says, which the image hash checks): the
           film gets them when the state has them. */
        struct error why;
        if (!film_enable_regions(film, &why)) return error_set(err, "%s: %s", r->path, why.message);
        *n_wanted = n_want = film_arrays(film, want);
        k = 0;
        while (k < n_want && strcmp(want[k].name, name)) ++k;
    }
    if (k == n_want) return skip(r, bytes, err);
    if (seen[k]) return error_set(err, "%s: array %s appears twice: damaged", r->path, name);
    seen[k] = true;
    if (type != want[k].type || count != (uint64_t)(want[k].per_pixel * pixels))
        return error_set(err, "%s: array %s has %" PRIu64 " elements of type %" PRIu32 " (expected %zu of type %d)",
                         r->path, name, count, type, want[k].per_pixel * pixels, (int)want[k].type);
    return get(r, want[k].data, (size_t)bytes, err);
}

static bool read_content(struct state_reader *r, struct film_state *s, struct error *err)
{
    uint32_t n_arrays;
    if (!read_header(r, s, &n_arrays, err)) return false;
    struct state_array want[STATE_ARRAYS_MAX];
    bool seen[STATE_ARRAYS_MAX] = { false };
    int n_want = film_arrays(&s->film, want);
    size_t pixels = (size_t)s->film.width * (size_t)s->film.height;
    for (uint32_t i = 0; i < n_arrays; ++i)
        if (!read_array(r, &s->film, want, &n_want, seen, pixels, err)) return false;
    uint64_t expected = r->hash, stored;
    if (!get_u64(r, &stored, err)) return false;
    if (stored != expected) return error_set(err, "%s: checksum mismatch: the state is damaged", r->path);
    if (r->left) return error_set(err, "%s: %" PRIu64 " bytes after the checksum: damaged", r->path, r->left);
    /* Only after the checksum: a damaged list of arrays reads as damage,
       not as a missing array. */
    for (int k = 0; k < n_want; ++k)
        if (!seen[k])
            return error_set(err, "%s: the state has no array \"%s\", which this renderer's film needs", r->path,
                             want[k].name);
    return true;
}

bool film_state_read(const char *path, struct film_state *s, struct error *err)
{
    memset(s, 0, sizeof *s);
    struct state_reader r = { -1, path, FNV_OFFSET, 0, 0 };
    r.fd = open(path, O_RDONLY | O_CLOEXEC);
    if (r.fd < 0) return error_set(err, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    bool ok = fstat(r.fd, &st) == 0 || error_set(err, "%s: cannot stat: %s", path, strerror(errno));
    if (ok && !S_ISREG(st.st_mode)) ok = error_set(err, "%s: not a regular file", path);
    if (ok) {
        r.size = r.left = (uint64_t)st.st_size;
        ok = read_content(&r, s, err);
    }
    close(r.fd);
    if (!ok) film_state_free(s);
    return ok;
}

void film_state_free(struct film_state *s)
{
    film_free(&s->film);
    memset(s, 0, sizeof *s);
}

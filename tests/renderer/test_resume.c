/* Resuming a render: the state file (round trip, damage, truncation,
   missing arrays), the image hash of configs, and `render --resume` end to
   end: a render continued from its state, once or twice, on other thread
   counts, equals the uninterrupted render bit for bit; every refusal exits
   2 and leaves the folder as it was. */
#include <dirent.h>

#include "cli_util.h"
#include "config/config.h"
#include "render/film.h"
#include "exr_read.h"
#include "render/film_state.h"
#include "testlib.h"

/* ---- the state file --------------------------------------------------- */

static void fill_state(struct film_state *s, int w, int h)
{
    memset(s, 0, sizeof *s);
    struct error err;
    CHECK(film_init(&s->film, w, h, &err));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            film_add(&s->film, x, y, rgb_make(0.1 * x + 1e-17 * y, 1.0 / (3.0 + y), -0.5 * x * y));
    s->film.count[1] = 7; /* a pixel whose count lags or leads: kept as it is */
    s->film.passes = 5;
    s->render_time_s = 1.0 / 3.0;
    s->render_cpu_s = 0.7;
    s->snapshot_cpu_s = 0.01;
    s->snapshot_pause_s = 0.002;
    s->stats.rays = 123456789012ull;
    s->stats.shadow_rays = 11;
    s->stats.shadow_blocked = 12;
    s->stats.light_samples = 13;
    s->stats.light_missed = 14;
    s->nonfinite_samples = 3;
    s->snapshots = 4;
    s->seed = 18446744073709551615ull;
    s->image_hash = 0x0123456789abcdefull;
}

static bool same_memory(const void *a, const void *b, size_t n)
{
    return memcmp(a, b, n) == 0;
}

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

static void write_bytes(const char *path, const unsigned char *data, long n)
{
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(data, 1, (size_t)n, f) == (size_t)n);
    if (f) fclose(f);
}

/* The file's bytes plus a terminating NUL (so text can be searched). */
static unsigned char *read_bytes(const char *path, long *n)
{
    *n = file_size(path);
    unsigned char *data = calloc(*n > 0 ? (size_t)*n + 1 : 1, 1);
    FILE *f = fopen(path, "rb");
    if (!f || !data || fread(data, 1, (size_t)*n, f) != (size_t)*n) *n = -1;
    if (f) fclose(f);
    return data;
}

static void test_state_round_trip(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", path[64];
    make_tmpdir(dir);
    snprintf(path, sizeof path, "%s/final.state", dir);
    struct film_state a, b;
    struct error err;
    fill_state(&a, 5, 3);
    CHECK_MSG(film_state_write(path, &a, &err), "%s", err.message);
    CHECK_MSG(film_state_read(path, &b, &err), "%s", err.message);
    size_t px = 15;
    CHECK(b.film.width == 5 && b.film.height == 3 && b.film.passes == 5);
    CHECK(same_memory(a.film.mean, b.film.mean, 3 * px * sizeof(double)));
    CHECK(same_memory(a.film.m2, b.film.m2, 3 * px * sizeof(double)));
    CHECK(same_memory(a.film.count, b.film.count, px * sizeof(uint32_t)));
    CHECK(same_bits(a.render_time_s, b.render_time_s) && same_bits(a.render_cpu_s, b.render_cpu_s));
    CHECK(same_bits(a.snapshot_cpu_s, b.snapshot_cpu_s) && same_bits(a.snapshot_pause_s, b.snapshot_pause_s));
    CHECK(same_memory(&a.stats, &b.stats, sizeof a.stats));
    CHECK(b.nonfinite_samples == 3 && b.snapshots == 4 && b.seed == a.seed && b.image_hash == a.image_hash);
    /* magic, version, header, three arrays, checksum */
    long expect = 16 + 124 + (4 + 4 + 4 + 8 + 8 + 3 * 15 * 8) + (4 + 2 + 4 + 8 + 8 + 3 * 15 * 8) +
                  (4 + 5 + 4 + 8 + 8 + 15 * 4) + 8;
    CHECK_MSG(file_size(path) == expect, "size %ld, expected %ld", file_size(path), expect);
    /* Nothing left at a temporary name. */
    DIR *d = opendir(dir);
    int entries = 0;
    for (struct dirent *e; d && (e = readdir(d));) entries += e->d_name[0] != '.';
    if (d) closedir(d);
    CHECK(entries == 1);
    film_state_free(&a);
    film_state_free(&b);
    film_state_free(&b); /* safe twice */
    remove_tree(dir);
}

/* Every flipped byte, every truncation: refused, with a message, and the
   state left empty. */
static void test_state_damage_detected(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", path[64];
    make_tmpdir(dir);
    snprintf(path, sizeof path, "%s/final.state", dir);
    struct film_state a, b;
    struct error err;
    fill_state(&a, 3, 2);
    CHECK(film_state_write(path, &a, &err));
    long n;
    unsigned char *good = read_bytes(path, &n);
    CHECK(n > 0);
    int accepted = 0, checksum_msgs = 0;
    for (long i = 0; i < n; ++i) {
        good[i] ^= 0x10;
        write_bytes(path, good, n);
        good[i] ^= 0x10;
        err.message[0] = '\0';
        if (film_state_read(path, &b, &err)) ++accepted;
        checksum_msgs += strstr(err.message, "checksum mismatch") != NULL;
        CHECK(b.film.mean == NULL && b.film.passes == 0);
        CHECK(strncmp(err.message, path, strlen(path)) == 0);
    }
    CHECK_MSG(accepted == 0, "%d damaged files accepted", accepted);
    CHECK_MSG(checksum_msgs > n / 2, "only %d of %ld flips reported as checksum mismatches", checksum_msgs, n);
    int truncated_ok = 0;
    for (long k = 0; k < n; ++k) {
        write_bytes(path, good, k);
        if (film_state_read(path, &b, &err)) ++truncated_ok;
        CHECK_MSG(strstr(err.message, "truncated") || strstr(err.message, "bad magic"), "length %ld: %s", k,
                  err.message);
    }
    CHECK_MSG(truncated_ok == 0, "%d truncated files accepted", truncated_ok);
    /* Bytes after the checksum. */
    unsigned char *longer = malloc((size_t)n + 1);
    memcpy(longer, good, (size_t)n);
    longer[n] = 0;
    write_bytes(path, longer, n + 1);
    CHECK(!film_state_read(path, &b, &err) && strstr(err.message, "after the checksum"));
    free(longer);
    /* A file that is not a state; a missing one. */
    const char *other = "v/1\001 not a state file at all";
    write_bytes(path, (const unsigned char *)other, (long)strlen(other));
    CHECK(!film_state_read(path, &b, &err) && strstr(err.message, "not a render state file"));
    unlink(path);
    CHECK(!film_state_read(path, &b, &err) && strstr(err.message, "cannot open"));
    free(good);
    film_state_free(&a);
    remove_tree(dir);
}

/* FNV-1a 64 as the format defines it, to forge files with a valid checksum. */
static uint64_t fnv(const unsigned char *p, size_t n)
{
    uint64_t h = 14695981039346656037ull;
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

/* A well-formed state without the "count" array (renamed), and one with
   an array the film does not know: the first is refused by name, the
   second read. */
static void test_state_named_arrays(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", path[64];
    make_tmpdir(dir);
    snprintf(path, sizeof path, "%s/final.state", dir);
    struct film_state a, b;
    struct error err;
    fill_state(&a, 2, 2);
    CHECK(film_state_write(path, &a, &err));
    long n;
    unsigned char *bytes = read_bytes(path, &n);
    /* The last array is "count": its name sits after the two f64 arrays. */
    long at = 16 + 124 + (4 + 4 + 4 + 8 + 8 + 3 * 4 * 8) + (4 + 2 + 4 + 8 + 8 + 3 * 4 * 8);
    CHECK(n > at + 9 && memcmp(bytes + at, "\005\000\000\000count", 9) == 0);
    memcpy(bytes + at + 4, "cuont", 5);
    uint64_t sum = fnv(bytes, (size_t)n - 8);
    memcpy(bytes + n - 8, &sum, 8);
    write_bytes(path, bytes, n);
    CHECK(!film_state_read(path, &b, &err));
    CHECK_MSG(strstr(err.message, "no array \"count\""), "%s", err.message);
    /* Add one: array count 4, "cuont" kept as an unknown, "count" appended. */
    size_t extra = 4 + 5 + 4 + 8 + 8 + 4 * 4;
    unsigned char *more = malloc((size_t)n + extra);
    memcpy(more, bytes, (size_t)n - 8);
    unsigned char *p = more + n - 8;
    uint32_t len = 5, type = 2, four = 4;
    uint64_t count = 4, nbytes = 16;
    memcpy(p, &len, 4), p += 4;
    memcpy(p, "count", 5), p += 5;
    memcpy(p, &type, 4), p += 4;
    memcpy(p, &count, 8), p += 8;
    memcpy(p, &nbytes, 8), p += 8;
    memcpy(p, a.film.count, 16), p += 16;
    memcpy(more + 16 + 100, &four, 4); /* the array count, after `snapshots` */
    sum = fnv(more, (size_t)(p - more));
    memcpy(p, &sum, 8);
    write_bytes(path, more, (long)(p - more) + 8);
    CHECK_MSG(film_state_read(path, &b, &err), "%s", err.message);
    CHECK(b.film.count && same_memory(b.film.count, a.film.count, 16));
    film_state_free(&b);
    free(more);
    free(bytes);
    film_state_free(&a);
    remove_tree(dir);
}

/* The image hash ignores how long, how often, where and on how many
   threads; it follows everything else. */
static void test_image_hash(void)
{
    const char *scene = "configs/scenes/lampshade.yaml";
    struct config base, other;
    struct error err;
    CHECK_MSG(config_load(scene, NULL, 0, &base, &err), "%s", err.message);
    struct config_override same[] = { { "render.spp", "99" },         { "render.time", "3" },
                                      { "render.threads", "3" },      { "render.output", "/tmp/elsewhere" },
                                      { "render.resumable", "true" }, { "render.snapshots.every_spp", "2" } };
    CHECK(config_load(scene, same, 6, &other, &err));
    CHECK(other.image_hash == base.image_hash && other.hash != base.hash && other.render.resumable);
    config_free(&other);
    const char *const changes[][2] = {
        { "render.seed", "2" }, { "film.width", "17" }, { "render.strategy", "portal" }, { "params.s_L", "1.2" }
    };
    for (int i = 0; i < 4; ++i) {
        struct config_override o = { changes[i][0], changes[i][1] };
        CHECK(config_load(scene, &o, 1, &other, &err));
        CHECK_MSG(other.image_hash != base.image_hash, "%s does not change the image hash", changes[i][0]);
        config_free(&other);
    }
    config_free(&base);
}

/* ---- render --resume ------------------------------------------------- */

#define SCENE "configs/scenes/lampshade.yaml"

/* Runs the renderer with the NULL-terminated words of `args` (at most 40). */
static void run_words(const char *const *args, struct run *r)
{
    char *argv[48];
    int n = 1;
    for (; args[n - 1] && n < 47; ++n) argv[n] = (char *)args[n - 1];
    argv[n] = NULL;
    run_render(argv, 0, 0, r);
}

/* A fresh render of the 32x32 lampshade into dir with `extra` words. */
static bool render_fresh(const char *dir, const char *spp, const char *threads, const char *const *extra, struct run *r)
{
    const char *args[40] = { SCENE,   "--out",         dir,     "--spp",          spp,      "--threads", threads,
                             "--set", "film.width=32", "--set", "film.height=32", "--quiet" };
    int n = 12;
    for (int i = 0; extra && extra[i] && n < 39; ++i) args[n++] = extra[i];
    args[n] = NULL;
    run_words(args, r);
    CHECK_MSG(r->status == 0, "fresh render into %s: status %d: %s", dir, r->status, r->err);
    return r->status == 0;
}

static bool resume(const char *dir, const char *spp, const char *threads, struct run *r)
{
    const char *args[] = { "--resume", dir, "--spp", spp, "--threads", threads, "--quiet", NULL };
    run_words(args, r);
    CHECK_MSG(r->status == 0, "resume of %s to %s spp: status %d: %s", dir, spp, r->status, r->err);
    return r->status == 0;
}

struct final {
    struct film_image img;
    struct snapshot_read meta;
};

static bool read_final(const char *dir, const char *name, struct final *f)
{
    char path[512];
    struct error err;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    bool ok = film_read_exr(path, &f->img, &f->meta, &err);
    CHECK_MSG(ok, "%s", err.message);
    return ok;
}

static void final_free(struct final *f)
{
    film_image_free(&f->img);
    free(f->meta.storage);
}

/* Every float of R, G, B, variance.*, the region AOV (when there is one)
   and the spp header. */
static bool same_image(const struct final *a, const struct final *b)
{
    size_t n = 3 * (size_t)a->img.width * (size_t)a->img.height;
    size_t n_region = AOV_REGION_COUNT * (size_t)a->img.width * (size_t)a->img.height;
    return a->img.width == b->img.width && a->img.height == b->img.height && a->meta.info.spp == b->meta.info.spp &&
           same_memory(a->img.rgb, b->img.rgb, n * sizeof(float)) &&
           same_memory(a->img.variance, b->img.variance, n * sizeof(float)) &&
           (a->img.region != NULL) == (b->img.region != NULL) &&
           (!a->img.region || same_memory(a->img.region, b->img.region, n_region * sizeof(float)));
}

/* The `final` JSON line's value of "key" (a number), or -1. */
static double json_final(const char *out, const char *key)
{
    const char *fin = strstr(out, "\"event\":\"final\"");
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *v = fin ? strstr(fin, pat) : NULL;
    return v ? strtod(v + strlen(pat), NULL) : -1.0;
}

/* Compares dir/final.exr with a fresh render of `spp` passes with `extra`
   words (3 threads) in its own folder. */
static void check_equals_fresh(const char *dir, const char *spp, const char *const *extra, const struct run *resumed)
{
    char ref[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(ref);
    struct run r;
    struct final a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    if (render_fresh(ref, spp, "3", extra, &r) && read_final(dir, "final.exr", &a) &&
        read_final(ref, "final.exr", &b)) {
        CHECK_MSG(same_image(&a, &b), "%s: resumed image differs from a fresh render of %s spp (spp %lld vs %lld)", dir,
                  spp, (long long)a.meta.info.spp, (long long)b.meta.info.spp);
        CHECK(a.meta.info.spp == atoll(spp));
        CHECK(a.meta.info.rays == b.meta.info.rays && a.meta.info.nonfinite_samples == b.meta.info.nonfinite_samples);
        if (resumed) {
            CHECK(json_final(resumed->out, "rays") == json_final(r.out, "rays"));
            CHECK(json_final(resumed->out, "shadow_rays") == json_final(r.out, "shadow_rays"));
            CHECK(json_final(resumed->out, "nonfinite") == json_final(r.out, "nonfinite"));
        }
    }
    final_free(&a);
    final_free(&b);
    remove_tree(ref);
}

/* (a) 8 passes on one thread, resumed to 20 on two: the bits of an
   uninterrupted 20-pass render (on three); config.yaml says 20 now. */
static void test_resume_bit_identical(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(dir);
    const char *extra[] = { "--resumable", NULL };
    struct run r;
    if (render_fresh(dir, "8", "1", extra, &r)) {
        CHECK(strstr(r.out, "\"resumed_from_spp\":0}"));
        if (resume(dir, "20", "2", &r)) {
            CHECK_MSG(strstr(r.out, "\"resumed_from_spp\":8}"), "%s", r.out);
            CHECK(json_final(r.out, "spp") == 20);
            check_equals_fresh(dir, "20", NULL, &r);
            char path[600];
            snprintf(path, sizeof path, "%s/config.yaml", dir);
            long n;
            unsigned char *text = read_bytes(path, &n);
            CHECK(n > 0 && strstr((char *)text, "\n  spp: 20\n") && strstr((char *)text, "\n  resumable: true\n"));
            free(text);
        }
    }
    remove_tree(dir);
}

/* (b) 5 -> 11 -> 20 passes on 1, 2, 3 threads. */
static void test_resume_twice(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(dir);
    const char *extra[] = { "--resumable", NULL };
    struct run r;
    if (render_fresh(dir, "5", "1", extra, &r) && resume(dir, "11", "2", &r)) {
        CHECK(strstr(r.out, "\"resumed_from_spp\":5}"));
        if (resume(dir, "20", "3", &r)) {
            CHECK(strstr(r.out, "\"resumed_from_spp\":11}"));
            check_equals_fresh(dir, "20", NULL, &r);
        }
    }
    remove_tree(dir);
}

/* (c) the path integrator and the antishadow_exact strategy; (d) a render
   with non-finite samples dropped (per-pixel counts that lag), also with
   the region AOV, whose counts the state carries too. */
static void test_resume_integrators_and_faults(void)
{
    const char *path[] = { "--integrator", "path", NULL };
    const char *exact[] = { "--strategy", "antishadow_exact", NULL };
    const char *plain[] = { NULL };
    const char *aov[] = { "--set", "render.aov.region=true", NULL };
    const char *const *variants[] = { path, exact, plain, aov };
    for (int v = 0; v < 4; ++v) {
        if (v >= 2) setenv("PORTAL_LIGHTS_FAULT_NONFINITE", "7", 1);
        char dir[] = "/tmp/portal-resume-XXXXXX";
        make_tmpdir(dir);
        const char *extra[6] = { "--resumable" };
        for (int i = 0; variants[v][i]; ++i) extra[i + 1] = variants[v][i];
        struct run r;
        if (render_fresh(dir, "7", "1", extra, &r) && resume(dir, "16", "2", &r)) {
            if (v >= 2) CHECK_MSG(json_final(r.out, "nonfinite") > 100, "nonfinite %g", json_final(r.out, "nonfinite"));
            if (v == 3) {
                struct final f;
                memset(&f, 0, sizeof f);
                if (read_final(dir, "final.exr", &f)) CHECK_MSG(f.img.region != NULL, "resumed AOV render without AOV");
                final_free(&f);
            }
            check_equals_fresh(dir, "16", variants[v], &r);
        }
        remove_tree(dir);
        unsetenv("PORTAL_LIGHTS_FAULT_NONFINITE");
    }
}

/* Every file of a folder, to prove that a refusal changed nothing. */
struct folder {
    int n;
    char names[16][256];
    unsigned char *bytes[16];
    long sizes[16];
};

static void folder_read(const char *dir, struct folder *f)
{
    memset(f, 0, sizeof *f);
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d)) && f->n < 16;) {
        if (e->d_name[0] == '.') continue;
        char path[600];
        snprintf(f->names[f->n], sizeof f->names[0], "%s", e->d_name);
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        f->bytes[f->n] = read_bytes(path, &f->sizes[f->n]);
        ++f->n;
    }
    if (d) closedir(d);
}

static void folder_free(struct folder *f)
{
    for (int i = 0; i < f->n; ++i) free(f->bytes[i]);
    f->n = 0;
}

static bool folder_same(const struct folder *a, const struct folder *b)
{
    if (a->n != b->n) return false;
    for (int i = 0; i < a->n; ++i) {
        int j = 0;
        while (j < b->n && strcmp(a->names[i], b->names[j])) ++j;
        if (j == b->n || a->sizes[i] != b->sizes[j] || !same_memory(a->bytes[i], b->bytes[j], (size_t)a->sizes[i]))
            return false;
    }
    return true;
}

/* Runs the words, which must be refused: exit 2, `message` on stderr,
   nothing on stdout, dir unchanged. */
static void check_refused(const char *dir, const char *const *args, const char *message)
{
    struct folder before, after;
    folder_read(dir, &before);
    struct run r;
    run_words(args, &r);
    folder_read(dir, &after);
    CHECK_MSG(r.status == 2 && strstr(r.err, message), "%s %s ...: status %d, expected \"%s\" in: %s", args[0],
              args[1] ? args[1] : "", r.status, message, r.err);
    CHECK_MSG(r.out[0] == '\0', "stdout: %s", r.out);
    CHECK_MSG(folder_same(&before, &after), "%s changed", dir);
    folder_free(&before);
    folder_free(&after);
}

static void write_text(const char *path, const char *text)
{
    write_bytes(path, (const unsigned char *)text, (long)strlen(text));
}

/* Replaces the first `from` in dir/config.yaml by `to`. */
static void edit_config(const char *dir, const char *from, const char *to)
{
    char path[600], *text;
    long n;
    snprintf(path, sizeof path, "%s/config.yaml", dir);
    text = (char *)read_bytes(path, &n);
    char *at = n > 0 ? strstr(text, from) : NULL;
    CHECK_MSG(at != NULL, "no \"%s\" in %s", from, path);
    if (at) {
        char *edited = malloc((size_t)n + strlen(to) + 1);
        size_t head = (size_t)(at - text);
        memcpy(edited, text, head);
        snprintf(edited + head, (size_t)n + strlen(to) + 1 - head, "%s%s", to, at + strlen(from));
        write_text(path, edited);
        free(edited);
    }
    free(text);
}

/* (e) every refusal: exit 2, a message that says what is wrong, DIR as it
   was. */
/* (f) the sobol sampler: its sample index is the pass, so a resumed render
   draws the points an uninterrupted one would (path tracing: every
   bounce's blocks; 5 -> 11 -> 19 passes on 1, 2, 3 threads, crossing the
   powers of two where the nets close). */
static void test_resume_sobol(void)
{
    const char *sobol[] = { "--set", "render.sampler=sobol", "--integrator", "path", NULL };
    char dir[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(dir);
    const char *extra[] = { "--resumable", sobol[0], sobol[1], sobol[2], sobol[3], NULL };
    struct run r;
    if (render_fresh(dir, "5", "1", extra, &r) && resume(dir, "11", "2", &r) && resume(dir, "19", "3", &r)) {
        check_equals_fresh(dir, "19", sobol, &r);
        struct film_state st;
        struct error err;
        char path[600];
        snprintf(path, sizeof path, "%s/final.state", dir);
        CHECK_MSG(film_state_read(path, &st, &err), "%s", err.message);
        CHECK(st.sampler == SAMPLER_SOBOL && st.film.passes == 19);
        film_state_free(&st);
    }
    remove_tree(dir);
}

/* A version 1 state (before render.sampler) reads as the independent
   sampler it was rendered with. */
static void test_state_version1(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", path[64];
    make_tmpdir(dir);
    snprintf(path, sizeof path, "%s/final.state", dir);
    struct film_state a, b;
    struct error err;
    fill_state(&a, 3, 2);
    a.sampler = SAMPLER_SOBOL;
    CHECK(film_state_write(path, &a, &err));
    long n;
    unsigned char *bytes = read_bytes(path, &n);
    /* Version 1: version 1, header 120, no sampler after image_hash. */
    unsigned char *v1 = malloc((size_t)n);
    uint32_t one = 1, bytes120 = 120;
    memcpy(v1, bytes, 16 + 120);
    memcpy(v1 + 8, &one, 4);
    memcpy(v1 + 12, &bytes120, 4);
    memcpy(v1 + 16 + 120, bytes + 16 + 124, (size_t)n - (16 + 124) - 8);
    long m = n - 4;
    uint64_t sum = fnv(v1, (size_t)m - 8);
    memcpy(v1 + m - 8, &sum, 8);
    write_bytes(path, v1, m);
    CHECK_MSG(film_state_read(path, &b, &err), "%s", err.message);
    CHECK(b.sampler == SAMPLER_INDEPENDENT && b.seed == a.seed && b.image_hash == a.image_hash);
    CHECK(b.film.mean && same_memory(b.film.mean, a.film.mean, 3 * 6 * sizeof(double)));
    film_state_free(&b);
    /* A sampler this renderer does not know: damaged. */
    uint32_t nine = 9;
    memcpy(bytes + 16 + 120, &nine, 4);
    sum = fnv(bytes, (size_t)n - 8);
    memcpy(bytes + n - 8, &sum, 8);
    write_bytes(path, bytes, n);
    CHECK(!film_state_read(path, &b, &err));
    CHECK_MSG(strstr(err.message, "unknown sampler 9"), "%s", err.message);
    free(v1);
    free(bytes);
    film_state_free(&a);
    remove_tree(dir);
}

static void test_resume_refusals(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", plain[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(dir);
    make_tmpdir(plain);
    const char *extra[] = { "--resumable", NULL };
    struct run r;
    if (!render_fresh(dir, "8", "1", extra, &r) || !render_fresh(plain, "8", "1", NULL, &r)) goto out;
    char state[600], saved[600], missing[600];
    snprintf(state, sizeof state, "%s/final.state", dir);
    snprintf(saved, sizeof saved, "%s.saved", plain);
    snprintf(missing, sizeof missing, "%s/nothing-here", dir);

    const char *with_config[] = { SCENE, "--resume", dir, "--spp", "20", NULL };
    check_refused(dir, with_config, "takes no CONFIG");
    const char *seed[] = { "--resume", dir, "--spp", "20", "--seed", "3", NULL };
    check_refused(dir, seed, "--seed (render.seed) cannot be changed when resuming");
    const char *out[] = { "--resume", dir, "--out", plain, NULL };
    check_refused(dir, out, "--out (render.output) cannot be changed");
    const char *film[] = { "--resume", dir, "--set", "film.width=16", NULL };
    check_refused(dir, film, "--set film.width cannot be changed when resuming (only render.spp, render.time");
    const char *strategy[] = { "--resume", dir, "--set", "render.strategy=portal", NULL };
    check_refused(dir, strategy, "render.strategy cannot be changed");
    const char *nodir[] = { "--resume", missing, "--spp", "20", NULL };
    check_refused(dir, nodir, "No such file or directory");
    const char *noarg[] = { "--resume", NULL };
    check_refused(dir, noarg, "--resume needs a folder");

    /* A folder without config.yaml: the state alone is not enough. */
    char lone[] = "/tmp/portal-resume-XXXXXX", lone_state[600];
    make_tmpdir(lone);
    snprintf(lone_state, sizeof lone_state, "%s/final.state", lone);
    long n;
    unsigned char *good = read_bytes(state, &n);
    write_bytes(lone_state, good, n);
    const char *noconfig[] = { "--resume", lone, "--spp", "20", NULL };
    check_refused(lone, noconfig, "config.yaml: No such file or directory (expected the output folder of a render)");
    remove_tree(lone);

    /* A render made without --resumable. */
    const char *nostate[] = { "--resume", plain, "--spp", "20", NULL };
    check_refused(plain, nostate,
                  "final.state is missing: only a render made with render.resumable: true "
                  "(--resumable) can be resumed");

    /* Limits that leave nothing to render (they are totals). */
    const char *same_spp[] = { "--resume", dir, "--spp", "8", NULL };
    check_refused(dir, same_spp, "render.spp 8 is not above the 8 passes already done");
    const char *less_spp[] = { "--resume", dir, "--spp", "5", NULL };
    check_refused(dir, less_spp, "render.spp 5 is not above the 8 passes already done");
    const char *no_spp[] = { "--resume", dir, NULL };
    check_refused(dir, no_spp, "render.spp 8 is not above the 8 passes already done");
    const char *tiny_time[] = { "--resume", dir, "--spp", "0", "--time", "0.0000001", NULL };
    check_refused(dir, tiny_time, "render.time 1e-07 s is not above the");

    /* A malformed fault hook, a bad override value. */
    setenv("PORTAL_LIGHTS_FAULT_BIAS", "light", 1);
    const char *biased[] = { "--resume", dir, "--spp", "20", NULL };
    check_refused(dir, biased, "PORTAL_LIGHTS_FAULT_BIAS=light: expected STRATEGY:FACTOR");
    unsetenv("PORTAL_LIGHTS_FAULT_BIAS");
    const char *bad_spp[] = { "--resume", dir, "--spp", "lots", NULL };
    check_refused(dir, bad_spp, "render.spp=lots: expected a non-negative integer");

    /* Damaged states: truncated, one byte flipped. */
    write_bytes(state, good, n / 2);
    const char *go[] = { "--resume", dir, "--spp", "20", NULL };
    check_refused(dir, go, "truncated");
    good[n / 2] ^= 1;
    write_bytes(state, good, n);
    check_refused(dir, go, "checksum mismatch: the state is damaged");
    good[n / 2] ^= 1;
    write_bytes(state, good, n);

    /* config.yaml edited: another size, another seed, another strategy. */
    char config[600];
    snprintf(config, sizeof config, "%s/config.yaml", dir);
    long config_n;
    unsigned char *config_text = read_bytes(config, &config_n);
    edit_config(dir, "width: 32", "width: 16");
    check_refused(dir, go, "the state is 32x32 but");
    write_bytes(config, config_text, config_n);
    edit_config(dir, "seed: 1\n", "seed: 2\n");
    check_refused(dir, go, "the state has seed 1 but");
    write_bytes(config, config_text, config_n);
    edit_config(dir, "strategy: light\n", "strategy: portal\n");
    check_refused(dir, go, "the state was rendered with another image configuration than");
    write_bytes(config, config_text, config_n);
    edit_config(dir, "sampler: independent\n", "sampler: sobol\n");
    check_refused(dir, go, "the state was rendered with sampler independent but");
    write_bytes(config, config_text, config_n);
    free(config_text);

    /* After all that, the folder still resumes. */
    if (resume(dir, "12", "2", &r)) check_equals_fresh(dir, "12", NULL, &r);
    free(good);
out:
    remove_tree(dir);
    remove_tree(plain);
}

/* A render without render.resumable into a folder that holds a state
   removes it: a final.exr is never newer than the state beside it. */
static void test_stale_state_removed(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", state[600];
    make_tmpdir(dir);
    snprintf(state, sizeof state, "%s/final.state", dir);
    const char *extra[] = { "--resumable", NULL };
    struct run r;
    if (render_fresh(dir, "4", "1", extra, &r)) {
        CHECK(exists(state));
        render_fresh(dir, "6", "2", NULL, &r);
        CHECK(!exists(state));
        const char *go[] = { "--resume", dir, "--spp", "20", NULL };
        check_refused(dir, go, "final.state is missing");
    }
    remove_tree(dir);
}

/* (g) Snapshots of the resumed part continue the numbering and the
   schedule (every 2 passes: 2, 4, 6, then 8, 10), with cumulative spp and
   time in headers and JSON. */
static void test_resume_snapshots(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX";
    make_tmpdir(dir);
    const char *extra[] = { "--resumable", "--set", "render.snapshots.every_spp=2", NULL };
    struct run r;
    if (render_fresh(dir, "6", "1", extra, &r)) {
        double first_time = json_final(r.out, "time_s");
        CHECK(strstr(r.out, "\"index\":3,") && !strstr(r.out, "\"index\":4,"));
        if (resume(dir, "10", "2", &r)) {
            CHECK_MSG(strstr(r.out, "{\"event\":\"snapshot\",\"index\":4,") &&
                          strstr(r.out, "{\"event\":\"snapshot\",\"index\":5,") && !strstr(r.out, "\"index\":6,") &&
                          !strstr(r.out, "\"index\":1,"),
                      "%s", r.out);
            CHECK(json_final(r.out, "time_s") > first_time);
            struct final a, b;
            memset(&a, 0, sizeof a);
            memset(&b, 0, sizeof b);
            if (read_final(dir, "snapshot_0004.exr", &a) && read_final(dir, "snapshot_0005.exr", &b)) {
                CHECK_MSG(a.meta.info.spp == 8 && b.meta.info.spp == 10, "spp %lld, %lld", (long long)a.meta.info.spp,
                          (long long)b.meta.info.spp);
                CHECK(a.meta.info.render_time_s >= first_time &&
                      b.meta.info.render_time_s >= a.meta.info.render_time_s);
            }
            final_free(&a);
            final_free(&b);
            char path[600];
            snprintf(path, sizeof path, "%s/snapshot_0006.exr", dir);
            CHECK(!exists(path));
        }
    }
    remove_tree(dir);
}

/* A resumed render stopped by SIGTERM leaves a final.exr and final.state
   that resume again, to the bits of an uninterrupted render. */
static void test_resume_interrupted(void)
{
    char dir[] = "/tmp/portal-resume-XXXXXX", state[600];
    make_tmpdir(dir);
    snprintf(state, sizeof state, "%s/final.state", dir);
    const char *extra[] = { "--resumable", NULL };
    struct run r;
    if (render_fresh(dir, "3", "1", extra, &r)) {
        char *argv[] = { NULL, "--resume", dir, "--spp", "0", "--time", "60", "--threads", "2", "--quiet", NULL };
        run_render(argv, 0.8, SIGTERM, &r);
        CHECK_MSG(r.status == 3, "status %d: %s", r.status, r.err);
        CHECK(strstr(r.out, "\"interrupted\":true"));
        struct film_state st;
        struct error err;
        CHECK_MSG(film_state_read(state, &st, &err), "%s", err.message);
        long long passes = st.film.passes;
        film_state_free(&st);
        struct final fin;
        memset(&fin, 0, sizeof fin);
        if (read_final(dir, "final.exr", &fin)) CHECK(fin.meta.info.spp == passes);
        final_free(&fin);
        CHECK_MSG(passes > 3, "%lld passes", passes);
        char total[32];
        snprintf(total, sizeof total, "%lld", passes + 2);
        const char *args[] = { "--resume", dir, "--spp", total, "--time", "0", "--quiet", NULL };
        run_words(args, &r);
        CHECK_MSG(r.status == 0, "status %d: %s", r.status, r.err);
        if (r.status == 0) check_equals_fresh(dir, total, NULL, &r);
    }
    remove_tree(dir);
}

static const struct test_case tests[] = {
    { "state_round_trip", test_state_round_trip },
    { "state_damage_detected", test_state_damage_detected },
    { "state_named_arrays", test_state_named_arrays },
    { "image_hash", test_image_hash },
    { "resume_bit_identical", test_resume_bit_identical },
    { "resume_twice", test_resume_twice },
    { "resume_integrators_and_faults", test_resume_integrators_and_faults },
    { "resume_refusals", test_resume_refusals },
    { "resume_sobol", test_resume_sobol },
    { "state_version1", test_state_version1 },
    { "stale_state_removed", test_stale_state_removed },
    { "resume_snapshots", test_resume_snapshots },
    { "resume_interrupted", test_resume_interrupted },
};
TEST_MAIN(tests)

/* Tests of film.c: Welford accumulation against a two-pass reference, the
   variance-of-the-mean snapshot, the EXR round trip and its failure modes
   (missing directory, full disk, damaged files). */
#include "render/film.h"
#include "exr_read.h"
#include "base/rng.h"
#include "testlib.h"

#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <signal.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

/* A fresh scratch directory per test, removed (with its files) afterwards. */
static void scratch_make(char *dir, size_t size)
{
    snprintf(dir, size, "/tmp/test_film-XXXXXX");
    if (!mkdtemp(dir)) {
        fprintf(stderr, "mkdtemp: %s\n", strerror(errno));
        abort();
    }
}

/* Number of entries in dir (besides . and ..); with `tmp_only`, only
   names containing ".tmp-". */
static int dir_count(const char *dir, int tmp_only)
{
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        if (!tmp_only || strstr(e->d_name, ".tmp-")) ++n;
    }
    closedir(d);
    return n;
}

static void scratch_remove(const char *dir)
{
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *e;
        char path[512];
        while ((e = readdir(d))) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
        closedir(d);
    }
    rmdir(dir);
}

/* Whole file into a malloc'd buffer; NULL if unreadable. */
static unsigned char *file_slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc(n > 0 ? (size_t)n : 1);
    *size = fread(buf, 1, (size_t)n, f);
    fclose(f);
    if (*size != (size_t)n) {
        free(buf);
        return NULL;
    }
    return buf;
}

static bool file_spit(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f) return false;
    bool ok = fwrite(data, 1, size, f) == size;
    return fclose(f) == 0 && ok;
}

static const struct snapshot_info test_info = {
    .render_time_s = 12.375,
    .spp = 4096,
    .strategy = "antishadow_exact",
    .integrator = "direct",
    .seed = UINT64_MAX,
    .config_hash = 0x0123456789abcdefull,
    .renderer_version = "portal-lights 0.1.0 (test)",
    .rays = (1ull << 53),
    .nonfinite_samples = 7,
    .compress = true,
};

/* Random floats over many binades, both signs, including extremes, zero,
   negative zero and a subnormal: the file must keep every bit. */
static float random_float(struct rng *r)
{
    uint32_t u = rng_next_u32(r);
    switch (u % 16) {
    case 0:
        return FLT_MAX;
    case 1:
        return -FLT_MAX;
    case 2:
        return -0.0f;
    case 3:
        return 1e-40f;
    case 4:
        return (float)(1e30 * (rng_uniform(r) - 0.5));
    default:
        break;
    }
    double mag = ldexp(rng_uniform(r), (int)(u >> 8) % 80 - 40);
    return (float)((u & 0x10) ? -mag : mag);
}

static void image_fill_random(struct film_image *img, uint64_t seed)
{
    struct rng r;
    rng_seed(&r, seed, 0, 0);
    size_t n = 3 * (size_t)img->width * (size_t)img->height;
    for (size_t i = 0; i < n; ++i) {
        img->rgb[i] = random_float(&r);
        img->variance[i] = random_float(&r);
    }
}

static bool images_equal_bits(const struct film_image *a, const struct film_image *b)
{
    if (a->width != b->width || a->height != b->height) return false;
    size_t bytes = 3 * (size_t)a->width * (size_t)a->height * sizeof(float);
    return !memcmp(a->rgb, b->rgb, bytes) && !memcmp(a->variance, b->variance, bytes);
}

/* Independent check of the file layout, without OpenEXR: walks the header
   of a single-part scanline file to its chunk offset table, and checks every
   chunk whose packed size equals its raw size (which readers take to be
   stored uncompressed) against the raw layout built here: per scanline,
   channels in name order B, G, R, variance.B/G/R, little-endian floats.
   This also pins the channel naming, which a write/read round trip through
   the same mapping could not. Returns the number of raw chunks, or -1. */
static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int exr_check_raw_chunks(const char *path, const struct film_image *img, int *chunks_out)
{
    size_t n = 0;
    unsigned char *b = file_slurp(path, &n);
    if (!b || n < 8 || le32(b) != 20000630u) { /* the EXR magic number */
        free(b);
        return -1;
    }
    int compression = -1;
    size_t i = 8;
    while (i < n && b[i] != 0) {
        const char *name = (const char *)b + i;
        i += strnlen(name, n - i) + 1;
        if (i >= n) break;
        i += strnlen((const char *)b + i, n - i) + 1; /* type name */
        if (i + 4 > n) break;
        uint32_t size = le32(b + i);
        i += 4;
        if (!strcmp(name, "compression") && size == 1 && i < n) compression = b[i];
        i += size;
    }
    ++i; /* the header's closing NUL */
    /* NO_COMPRESSION, RLE and ZIPS: 1 line per chunk; ZIP: 16. */
    int lines = compression == 3 ? 16 : compression >= 0 && compression <= 2 ? 1 : 0;
    if (i > n || !lines) {
        free(b);
        return -1;
    }
    int w = img->width, h = img->height, count = (h + lines - 1) / lines, raw = 0;
    size_t row_bytes = (size_t)w * 6 * sizeof(float);
    unsigned char *expect = malloc(row_bytes * (size_t)lines);
    static const int order[6] = { 2, 1, 0, 5, 4, 3 }; /* B G R vB vG vR */
    for (int c = 0; c < count && raw >= 0; ++c) {
        if (i + 8 * (size_t)(c + 1) > n) {
            raw = -1;
            break;
        }
        uint64_t off = (uint64_t)le32(b + i + 8 * (size_t)c) | (uint64_t)le32(b + i + 8 * (size_t)c + 4) << 32;
        if (off + 8 > n) {
            raw = -1;
            break;
        }
        int y0 = (int)le32(b + off), nl = h - y0 < lines ? h - y0 : lines;
        uint32_t packed = le32(b + off + 4);
        if (y0 != c * lines || off + 8 + packed > n || packed > row_bytes * (size_t)nl) {
            raw = -1;
            break;
        }
        if (packed < row_bytes * (size_t)nl) continue; /* compressed */
        unsigned char *q = expect;
        for (int y = y0; y < y0 + nl; ++y)
            for (int k = 0; k < 6; ++k)
                for (int x = 0; x < w; ++x) {
                    int j = order[k];
                    size_t at = 3 * ((size_t)y * (size_t)w + (size_t)x) + (size_t)(j % 3);
                    float v = j < 3 ? img->rgb[at] : img->variance[at];
                    memcpy(q, &v, sizeof v); /* x86: the host is little-endian like the file */
                    q += sizeof v;
                }
        if (memcmp(b + off + 8, expect, packed)) {
            fprintf(stderr, "  %s: raw-sized chunk at line %d is not the raw pixels\n", path, y0);
            raw = -1;
            break;
        }
        ++raw;
    }
    free(expect);
    free(b);
    *chunks_out = count;
    return raw;
}

static void check_info_equal(const struct snapshot_info *got, const struct snapshot_info *want)
{
    CHECK(got->render_time_s == want->render_time_s);
    CHECK(got->spp == want->spp);
    CHECK(!strcmp(got->strategy, want->strategy));
    CHECK(!strcmp(got->integrator, want->integrator));
    CHECK(got->seed == want->seed);
    CHECK(got->config_hash == want->config_hash);
    CHECK(!strcmp(got->renderer_version, want->renderer_version));
    CHECK(got->rays == want->rays);
    CHECK(got->nonfinite_samples == want->nonfinite_samples);
}

static void test_sizes_are_checked(void)
{
    static const int bad[][2] = {
        { 0, 10 }, { 10, 0 }, { -3, 5 }, { FILM_MAX_SIDE + 1, 1 }, { 20000, 20000 },
    };
    struct error err;
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        struct film f;
        struct film_image img;
        char size[64];
        snprintf(size, sizeof size, "%dx%d", bad[i][0], bad[i][1]);
        err.message[0] = '\0';
        CHECK(!film_init(&f, bad[i][0], bad[i][1], &err));
        CHECK_MSG(strstr(err.message, size), "\"%s\" lacks %s", err.message, size);
        film_free(&f); /* safe after a failed init */
        err.message[0] = '\0';
        CHECK(!film_image_alloc(&img, bad[i][0], bad[i][1], &err));
        CHECK_MSG(strstr(err.message, size), "\"%s\" lacks %s", err.message, size);
        film_image_free(&img);
    }
    struct film f;
    CHECK(film_init(&f, 3, 2, &err));
    CHECK(f.width == 3 && f.height == 2 && f.passes == 0);
    for (int i = 0; i < 18; ++i) CHECK(f.mean[i] == 0.0 && f.m2[i] == 0.0);
    film_free(&f);
    film_free(&f); /* idempotent */
}

/* film_add over many passes against a two-pass mean and sum of squared
   deviations in long double. Per pixel the data are offset + scale * u with
   offsets up to 1e3 times the spread, where the naive sum-of-squares
   formula would lose everything. Welford's rounding error: the running mean
   drifts by at most ~n eps |mean| over n updates, and each deviation term
   then errs by that drift relative to sigma, so
   |m2 - m2_exact| <= 4 n eps (1 + |mean| / sigma) m2 and
   |mean - mean_exact| <= 2 n eps max|v|. */
static void test_welford_matches_two_pass(void)
{
    enum { W = 6, H = 5, N = 300 };
    static const double offsets[] = { 0.0, 1.0, -50.0, 1e3, 3e-7 };
    static const double scales[] = { 1.0, 1e-3, 10.0, 1.0, 1e-9 };
    struct film f;
    struct error err;
    CHECK(film_init(&f, W, H, &err));
    double *samples = malloc(sizeof(double) * W * H * 3 * N);
    for (int64_t pass = 0; pass < N; ++pass) {
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                int pixel = y * W + x;
                struct rng r;
                rng_seed(&r, 99, (uint64_t)pixel, (uint64_t)pass);
                double v[3];
                for (int k = 0; k < 3; ++k) {
                    int c = (pixel + k) % 5;
                    /* exponential draws: skewed like radiance samples */
                    v[k] = offsets[c] + scales[c] * -log(1.0 - rng_uniform(&r));
                    samples[((size_t)pixel * 3 + (size_t)k) * N + (size_t)pass] = v[k];
                }
                film_add(&f, x, y, rgb_make(v[0], v[1], v[2]));
            }
        f.passes = pass + 1;
    }
    const double eps = DBL_EPSILON;
    for (int i = 0; i < W * H * 3; ++i) {
        const double *s = samples + (size_t)i * N;
        long double sum = 0, ss = 0, vmax = 0;
        for (int j = 0; j < N; ++j) {
            sum += s[j];
            if (fabsl(s[j]) > vmax) vmax = fabsl(s[j]);
        }
        long double mean = sum / N;
        for (int j = 0; j < N; ++j) ss += (s[j] - mean) * (s[j] - mean);
        double sigma = sqrt((double)(ss / (N - 1)));
        CHECK_NEAR(f.mean[i], (double)mean, 2.0 * N * eps * (double)vmax);
        CHECK_NEAR(f.m2[i], (double)ss, 4.0 * N * eps * (1.0 + fabs((double)mean) / sigma) * (double)ss);
    }

    /* The snapshot divides by n (n - 1): the sample variance over n. */
    struct film_image img;
    CHECK(film_image_alloc(&img, W, H, &err));
    film_snapshot(&f, &img);
    for (int i = 0; i < W * H * 3; ++i) {
        double want = f.m2[i] / ((double)N * (N - 1));
        CHECK_NEAR(img.variance[i], want, 1.2e-7 * want);
        CHECK_NEAR(img.rgb[i], f.mean[i], 1.2e-7 * fabs(f.mean[i]));
    }
    film_image_free(&img);
    free(samples);
    film_free(&f);
}

/* Hand-checked case: samples 1..5 give mean 3, m2 = 10 and variance of the
   mean 10 / (5 * 4) = 0.5; before two passes the variance is 0. */
static void test_snapshot_variance_of_mean(void)
{
    struct film f;
    struct film_image img;
    struct error err;
    CHECK(film_init(&f, 2, 1, &err));
    CHECK(film_image_alloc(&img, 2, 1, &err));
    film_snapshot(&f, &img); /* n = 0 */
    for (int i = 0; i < 6; ++i) CHECK(img.rgb[i] == 0.0f && img.variance[i] == 0.0f);
    for (int64_t pass = 0; pass < 5; ++pass) {
        double v = (double)(pass + 1);
        film_add(&f, 0, 0, rgb_make(v, 2 * v, -v));
        film_add(&f, 1, 0, rgb_make(7.0, 0.0, 1e20));
        f.passes = pass + 1;
        film_snapshot(&f, &img);
        if (pass == 0) {
            CHECK(img.rgb[0] == 1.0f && img.rgb[1] == 2.0f && img.rgb[2] == -1.0f);
            for (int i = 0; i < 6; ++i) CHECK(img.variance[i] == 0.0f); /* n = 1 */
        }
    }
    CHECK(img.rgb[0] == 3.0f && img.rgb[1] == 6.0f && img.rgb[2] == -3.0f);
    CHECK(img.variance[0] == 0.5f && img.variance[1] == 2.0f && img.variance[2] == 0.5f);
    CHECK(img.rgb[3] == 7.0f && img.rgb[4] == 0.0f && img.rgb[5] == 1e20f);
    CHECK(img.variance[3] == 0.0f && img.variance[4] == 0.0f && img.variance[5] == 0.0f);
    film_image_free(&img);
    film_free(&f);
}

/* Samples of +-1e308 overflow the double accumulators to Inf and NaN; the
   snapshot must still hold only finite floats (clamped), never NaN. */
static void test_snapshot_never_writes_nonfinite(void)
{
    struct film f;
    struct film_image img;
    struct error err;
    CHECK(film_init(&f, 1, 1, &err));
    CHECK(film_image_alloc(&img, 1, 1, &err));
    for (int64_t pass = 0; pass < 6; ++pass) {
        double v = (pass % 2 ? -1e308 : 1e308);
        film_add(&f, 0, 0, rgb_make(v, 1e300 * (double)pass, 3e38));
        f.passes = pass + 1;
        film_snapshot(&f, &img);
        for (int k = 0; k < 3; ++k) {
            CHECK_MSG(isfinite(img.rgb[k]), "pass %d rgb[%d] = %g", (int)pass, k, img.rgb[k]);
            CHECK_MSG(isfinite(img.variance[k]) && img.variance[k] >= 0.0f, "pass %d variance[%d] = %g", (int)pass, k,
                      img.variance[k]);
        }
    }
    CHECK(isnan(f.mean[0]) || isinf(f.m2[0])); /* the case was really provoked */
    CHECK(img.rgb[1] == FLT_MAX);
    film_image_free(&img);
    film_free(&f);
}

/* Write then read: every bit of every channel and every attribute survives,
   for sizes that are and are not multiples of the 16-line ZIP chunk. The
   file stores channels sorted (B, G, R, ...): a reader mapping by index
   would swap R and B and fail here. */
static void test_exr_round_trip(void)
{
    static const int sizes[][2] = { { 37, 23 }, { 1, 1 }, { 64, 32 }, { 5, 17 } };
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/round trip.exr", dir);
    for (size_t t = 0; t < sizeof sizes / sizeof sizes[0]; ++t) {
        struct film_image img, back;
        struct snapshot_read meta;
        struct error err;
        CHECK(film_image_alloc(&img, sizes[t][0], sizes[t][1], &err));
        image_fill_random(&img, 7 + t);
        struct snapshot_info info = test_info;
        info.seed = t == 1 ? 0 : test_info.seed;
        info.integrator = t == 2 ? "" : test_info.integrator;
        info.compress = t != 3; /* timed snapshots are written uncompressed */
        bool wrote = film_write_exr(path, &img, &info, &err);
        CHECK_MSG(wrote, "%s", err.message);
        bool read = wrote && film_read_exr(path, &back, &meta, &err);
        CHECK_MSG(read, "%s", err.message);
        if (read) {
            CHECK_MSG(images_equal_bits(&img, &back), "%dx%d image differs", sizes[t][0], sizes[t][1]);
            check_info_equal(&meta.info, &info);
            film_image_free(&back);
            free(meta.storage);
        }
        film_image_free(&img);
    }
    CHECK(dir_count(dir, 1) == 0);
    scratch_remove(dir);
}

/* Chunks whose zlib output is exactly as long as the raw data must be
   stored raw (OpenEXRCore 3.1.5 stored the zlib bytes, which readers then
   decode as raw garbage). Ties need nearly incompressible data:
   - random_float rows, seed 22, 64 wide: with ZIPS (one line per chunk)
     rows 4, 23, 32 and 33 tie under this machine's zlib;
   - random bits with c zero floats at the start of 16-row block c: the
     compressed size sweeps down through the raw size, and with ZIP (16 lines
     per chunk) block 12 ties.
   Another zlib may move the ties (the test then only gets weaker). The raw
   chunks of the second image also pin the channel layout. */
static void test_exr_chunks_are_unambiguous(void)
{
    enum { W = 64, BLOCKS = 40, H = 16 * BLOCKS };
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/tie.exr", dir);
    struct film_image img, back;
    struct snapshot_read meta;
    struct error err;
    CHECK(film_image_alloc(&img, W, H, &err));
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 0) {
            image_fill_random(&img, 22);
        } else {
            struct rng r;
            rng_seed(&r, 5, 0, 0);
            for (size_t i = 0; i < 3 * (size_t)W * H; ++i) {
                uint32_t u[2] = { rng_next_u32(&r), rng_next_u32(&r) };
                for (int k = 0; k < 2; ++k)
                    if ((u[k] & 0x7f800000u) == 0x7f800000u) u[k] &= ~0x00800000u; /* no NaN/Inf */
                memcpy(&img.rgb[i], &u[0], 4);
                memcpy(&img.variance[i], &u[1], 4);
            }
            for (int c = 0; c < BLOCKS; ++c)
                for (int z = 0; z < c; ++z) {
                    img.rgb[(size_t)c * 16 * 3 * W + (size_t)z] = 0.0f;
                    img.variance[(size_t)c * 16 * 3 * W + (size_t)z] = 0.0f;
                }
        }
        CHECK(film_write_exr(path, &img, &test_info, &err));
        int chunks = 0, raw = exr_check_raw_chunks(path, &img, &chunks);
        CHECK_MSG(raw >= 0, "pass %d: bad file layout", pass);
        if (pass == 1) CHECK_MSG(raw >= 10, "only %d of %d chunks raw", raw, chunks);
        if (film_read_exr(path, &back, &meta, &err)) {
            CHECK_MSG(images_equal_bits(&img, &back), "pass %d: pixels differ", pass);
            film_image_free(&back);
            free(meta.storage);
        } else {
            CHECK_MSG(false, "%s", err.message);
        }
    }
    film_image_free(&img);
    scratch_remove(dir);
}

/* spp is a 32-bit int in the file: larger counts saturate, never wrap. */
static void test_exr_spp_saturates(void)
{
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/spp.exr", dir);
    struct film_image img, back;
    struct snapshot_read meta;
    struct error err;
    CHECK(film_image_alloc(&img, 2, 2, &err));
    image_fill_random(&img, 3);
    struct snapshot_info info = test_info;
    info.spp = (int64_t)1 << 40;
    CHECK(film_write_exr(path, &img, &info, &err));
    if (film_read_exr(path, &back, &meta, &err)) {
        CHECK(meta.info.spp == INT32_MAX);
        film_image_free(&back);
        free(meta.storage);
    } else {
        CHECK_MSG(false, "%s", err.message);
    }
    film_image_free(&img);
    scratch_remove(dir);
}

static void test_exr_write_into_missing_directory(void)
{
    char dir[64], path[160];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/no/such/dir/out.exr", dir);
    struct film_image img;
    struct error err = { "" };
    CHECK(film_image_alloc(&img, 4, 4, &err));
    image_fill_random(&img, 1);
    CHECK(!film_write_exr(path, &img, &test_info, &err));
    CHECK_MSG(strstr(err.message, path), "\"%s\" lacks the path", err.message);
    CHECK_MSG(strstr(err.message, strerror(ENOENT)), "\"%s\" lacks the cause", err.message);
    CHECK(dir_count(dir, 0) == 0);
    film_image_free(&img);
    scratch_remove(dir);
}

static void test_exr_write_replaces_existing_file(void)
{
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/snap.exr", dir);
    CHECK(file_spit(path, "old junk", 8));
    struct film_image a, b, back;
    struct snapshot_read meta;
    struct error err;
    CHECK(film_image_alloc(&a, 9, 20, &err));
    CHECK(film_image_alloc(&b, 9, 20, &err));
    image_fill_random(&a, 11);
    image_fill_random(&b, 12);
    struct snapshot_info info = test_info;
    info.spp = 1;
    CHECK(film_write_exr(path, &a, &info, &err));
    info.spp = 2;
    CHECK(film_write_exr(path, &b, &info, &err));
    if (film_read_exr(path, &back, &meta, &err)) {
        CHECK(images_equal_bits(&back, &b));
        CHECK(meta.info.spp == 2);
        film_image_free(&back);
        free(meta.storage);
    } else {
        CHECK_MSG(false, "%s", err.message);
    }
    CHECK(dir_count(dir, 0) == 1);
    film_image_free(&a);
    film_image_free(&b);
    scratch_remove(dir);
}

/* Child side of the full-disk test: with RLIMIT_FSIZE = limit and SIGXFSZ
   ignored, writes beyond the limit fail with EFBIG as on a full disk.
   Exit status 0: the write failed with a message naming the path and the
   cause; 1: it claimed success; 2: the message was wrong. */
static void full_disk_child(const char *path, const struct film_image *img, rlim_t limit)
{
    signal(SIGXFSZ, SIG_IGN);
    struct rlimit rl = { limit, limit };
    if (setrlimit(RLIMIT_FSIZE, &rl) != 0) _exit(3);
    struct error err = { "" };
    if (film_write_exr(path, img, &test_info, &err)) _exit(1);
    if (!strstr(err.message, path) || !strstr(err.message, strerror(EFBIG))) {
        fprintf(stderr, "  unexpected message: %s\n", err.message);
        _exit(2);
    }
    _exit(0);
}

/* A write that runs out of space fails, leaves the previous snapshot at
   path byte for byte, and leaves no temporary file. Limits cover a failure
   while writing the header, the first chunks and the very last chunk. */
static void test_exr_full_disk_keeps_old_file(void)
{
    char dir[64], path[128], probe[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/snap.exr", dir);
    snprintf(probe, sizeof probe, "%s/probe.exr", dir);
    struct film_image old, img;
    struct error err;
    CHECK(film_image_alloc(&old, 8, 8, &err));
    CHECK(film_image_alloc(&img, 64, 48, &err));
    image_fill_random(&old, 21);
    image_fill_random(&img, 22);
    CHECK(film_write_exr(path, &old, &test_info, &err));
    CHECK(film_write_exr(probe, &img, &test_info, &err));
    /* The old file's bytes live on the stack: a forked child that exits
       early would otherwise show them to valgrind as a leak. */
    unsigned char old_bytes[16384];
    size_t old_size = 0, full_size = 0;
    unsigned char *slurped = file_slurp(path, &old_size);
    CHECK(slurped && old_size <= sizeof old_bytes);
    if (slurped && old_size <= sizeof old_bytes) memcpy(old_bytes, slurped, old_size);
    free(slurped);
    unsigned char *probe_bytes = file_slurp(probe, &full_size);
    free(probe_bytes);
    unlink(probe);
    CHECK(full_size > 4096);

    const rlim_t limits[] = { 0, 200, 4096, (rlim_t)full_size - 1 };
    for (size_t i = 0; i < sizeof limits / sizeof limits[0]; ++i) {
        fflush(NULL);
        pid_t pid = fork();
        if (pid == 0) full_disk_child(path, &img, limits[i]);
        int status = -1;
        CHECK(pid > 0 && waitpid(pid, &status, 0) == pid);
        CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "limit %lu: child status %d", (unsigned long)limits[i],
                  status);
        size_t now_size = 0;
        unsigned char *now_bytes = file_slurp(path, &now_size);
        CHECK_MSG(now_bytes && now_size == old_size && !memcmp(now_bytes, old_bytes, old_size),
                  "limit %lu: old file changed", (unsigned long)limits[i]);
        free(now_bytes);
        CHECK(dir_count(dir, 1) == 0);
    }

    /* Control: with room to spare the same child-side write succeeds. */
    pid_t pid = fork();
    if (pid == 0) {
        struct rlimit rl = { (rlim_t)full_size, (rlim_t)full_size };
        if (setrlimit(RLIMIT_FSIZE, &rl) != 0) _exit(3);
        _exit(film_write_exr(path, &img, &test_info, NULL) ? 0 : 1);
    }
    int status = -1;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    struct film_image back;
    struct snapshot_read meta;
    if (film_read_exr(path, &back, &meta, &err)) {
        CHECK(images_equal_bits(&back, &img));
        film_image_free(&back);
        free(meta.storage);
    } else {
        CHECK_MSG(false, "%s", err.message);
    }
    film_image_free(&old);
    film_image_free(&img);
    scratch_remove(dir);
}

/* Reading fails cleanly, naming the path: missing file, not an EXR,
   a truncated EXR, and an EXR without one of the channels. */
static void test_exr_read_errors(void)
{
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    struct film_image img, back;
    struct snapshot_read meta;
    struct error err;

    snprintf(path, sizeof path, "%s/missing.exr", dir);
    CHECK(!film_read_exr(path, &back, &meta, &err));
    CHECK_MSG(strstr(err.message, path) && strstr(err.message, strerror(ENOENT)), "%s", err.message);
    CHECK(back.rgb == NULL && meta.storage == NULL);

    snprintf(path, sizeof path, "%s/text.exr", dir);
    CHECK(file_spit(path, "P3\n1 1\n255\n0 0 0\n", 17));
    CHECK(!film_read_exr(path, &back, &meta, &err));
    CHECK_MSG(strstr(err.message, path) && strstr(err.message, "not an OpenEXR"), "%s", err.message);

    CHECK(film_image_alloc(&img, 40, 40, &err));
    image_fill_random(&img, 5);
    snprintf(path, sizeof path, "%s/good.exr", dir);
    CHECK(film_write_exr(path, &img, &test_info, &err));
    size_t size = 0;
    unsigned char *bytes = file_slurp(path, &size);
    CHECK(bytes != NULL);
    if (bytes) {
        for (size_t cut = 3; cut < size; cut = cut * 2 + 1) {
            snprintf(path, sizeof path, "%s/cut.exr", dir);
            CHECK(file_spit(path, bytes, cut));
            CHECK_MSG(!film_read_exr(path, &back, &meta, &err), "truncated at %zu read fine", cut);
            CHECK_MSG(strstr(err.message, path), "%s", err.message);
            CHECK(back.rgb == NULL && meta.storage == NULL);
        }
        /* Renaming "variance.G" to "variance.H" in the header keeps the
           channel list sorted and valid, but the channel is gone. */
        unsigned char *hit = NULL;
        for (size_t i = 0; i + 11 <= size && !hit; ++i)
            if (!memcmp(bytes + i, "variance.G", 11)) hit = bytes + i;
        CHECK(hit != NULL);
        if (hit) {
            hit[9] = 'H';
            snprintf(path, sizeof path, "%s/renamed.exr", dir);
            CHECK(file_spit(path, bytes, size));
            CHECK(!film_read_exr(path, &back, &meta, &err));
            CHECK_MSG(strstr(err.message, path) && strstr(err.message, "missing channel variance.G"), "%s",
                      err.message);
        }
        free(bytes);
    }
    film_image_free(&img);
    scratch_remove(dir);
}

/* A pixel that lost samples (non-finite, dropped by the caller) uses its own
   count: its variance of the mean is m2 / (n (n - 1)) with its n. */
static void test_per_pixel_count(void)
{
    struct film f;
    struct film_image img;
    struct error err;
    CHECK(film_init(&f, 2, 1, &err) && film_image_alloc(&img, 2, 1, &err));
    const double v[] = { 1.0, 2.0, 4.0, 8.0 };
    for (int i = 0; i < 4; ++i) {
        film_add(&f, 0, 0, rgb_make(v[i], v[i], v[i]));
        if (i != 2) film_add(&f, 1, 0, rgb_make(v[i], v[i], v[i])); /* pixel 1 lost one sample */
    }
    f.passes = 4;
    film_snapshot(&f, &img);
    CHECK(f.count[0] == 4 && f.count[1] == 3);
    CHECK_NEAR(img.rgb[0], 15.0 / 4.0, 1e-6);
    CHECK_NEAR(img.rgb[3], 11.0 / 3.0, 1e-6);
    /* Sample variances: {1,2,4,8}: 9.5833; {1,2,8}: 14.3333. */
    CHECK_NEAR(img.variance[0], (115.0 / 12.0) / 4.0, 1e-5);
    CHECK_NEAR(img.variance[3], (43.0 / 3.0) / 3.0, 1e-5);
    film_image_free(&img);
    film_free(&f);
}

/* film_add_row is film_add for each pixel of the row, bit for bit, also on
   pixels whose counts differ (samples dropped earlier) and rows longer than
   one block of its reciprocals; other rows are untouched. */
static void test_add_row_matches_add(void)
{
    enum { W = 150, H = 3 };
    struct film a, b;
    struct error err;
    CHECK(film_init(&a, W, H, &err) && film_init(&b, W, H, &err));
    struct rng r;
    rng_seed(&r, 5, 0, 0);
    struct rgb c[W];
    for (int pass = 0; pass < 20; ++pass) {
        for (int x = 0; x < W; ++x) c[x] = rgb_make(rng_uniform(&r) * 10.0, rng_uniform(&r), rng_uniform(&r) * 1e-3);
        for (int x = 0; x < W; ++x) film_add(&a, x, 1, c[x]);
        film_add_row(&b, 1, c, W);
        /* Uneven counts: some pixels get an extra sample in some passes. */
        for (int x = pass; x < W; x += 7) {
            film_add(&a, x, 1, c[x]);
            film_add(&b, x, 1, c[x]);
        }
    }
    int differ = 0;
    for (int i = 0; i < 3 * W * H; ++i) differ += !same_bits(a.mean[i], b.mean[i]) + !same_bits(a.m2[i], b.m2[i]);
    for (int i = 0; i < W * H; ++i) differ += a.count[i] != b.count[i];
    CHECK_MSG(differ == 0, "%d values differ", differ);
    CHECK(b.count[0] == 0 && b.count[2 * W] == 0 && b.count[W] > 20);
    film_free(&a);
    film_free(&b);
}

/* The region AOV's layer: fractions of each pixel's samples per class
   (0 without samples), through the EXR and back bit for bit with its
   attribute; a file without the layer still reads, without it. */
static void test_exr_region_round_trip(void)
{
    char dir[64], path[128];
    scratch_make(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/regions.exr", dir);
    struct film f;
    struct film_image img, back;
    struct snapshot_read meta;
    struct error err;
    const int w = 5, h = 19; /* odd sizes: one chunk of 16 lines and a short one */
    CHECK(film_init(&f, w, h, &err) && film_enable_regions(&f, &err));
    CHECK(film_image_alloc(&img, w, h, &err) && film_image_enable_regions(&img, &err));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            int samples = (x + y) % 4; /* pixel (0, 0) keeps 0 samples */
            for (int i = 0; i < samples; ++i) {
                film_add(&f, x, y, rgb_make(x, y, i));
                film_add_region(&f, x, y, (x * 3 + y + i * (y % 3)) % AOV_REGION_COUNT);
            }
        }
    film_snapshot(&f, &img);
    for (int p = 0; p < w * h; ++p) {
        double sum = 0.0;
        for (int k = 0; k < AOV_REGION_COUNT; ++k) {
            float want = f.count[p] ? (float)((double)f.region_count[AOV_REGION_COUNT * p + k] / f.count[p]) : 0.0f;
            CHECK(img.region[AOV_REGION_COUNT * p + k] == want);
            sum += img.region[AOV_REGION_COUNT * p + k];
        }
        CHECK_MSG(f.count[p] ? fabs(sum - 1.0) < 1e-6 : sum == 0.0, "pixel %d: fractions sum to %g", p, sum);
    }
    /* Pixel (1, 0): one sample, class 3. */
    CHECK(img.region[AOV_REGION_COUNT * 1 + 3] == 1.0f);
    for (int c = 0; c < 2; ++c) {
        struct snapshot_info info = test_info;
        info.compress = c == 0;
        bool wrote = film_write_exr(path, &img, &info, &err);
        CHECK_MSG(wrote, "%s", err.message);
        bool read = wrote && film_read_exr(path, &back, &meta, &err);
        CHECK_MSG(read, "%s", err.message);
        if (!read) continue;
        CHECK(images_equal_bits(&img, &back));
        CHECK(back.region && !memcmp(back.region, img.region, sizeof(float) * AOV_REGION_COUNT * w * h));
        check_info_equal(&meta.info, &info);
        film_image_free(&back);
        free(meta.storage);
    }
    /* The channel names and the attribute, as bytes in the header. */
    size_t size = 0;
    unsigned char *bytes = file_slurp(path, &size);
    const char *want[] = { "region.outside",
                           "region.anti_umbra",
                           "region.anti_penumbra",
                           "region.anti_antumbra",
                           "region.inside",
                           "region.emitter",
                           "region.miss",
                           "aov_region_classes",
                           "outside anti_umbra anti_penumbra anti_antumbra inside emitter miss" };
    for (size_t i = 0; bytes && i < sizeof want / sizeof want[0]; ++i) {
        bool found = false;
        for (size_t o = 0; !found && o + strlen(want[i]) <= size; ++o)
            found = !memcmp(bytes + o, want[i], strlen(want[i]));
        CHECK_MSG(found, "no \"%s\" in the file", want[i]);
    }
    free(bytes);
    /* Without the layer: no region channels written, none read. */
    film_image_free(&img);
    CHECK(film_image_alloc(&img, w, h, &err));
    film_snapshot(&f, &img);
    CHECK(film_write_exr(path, &img, &test_info, &err));
    if (film_read_exr(path, &back, &meta, &err)) {
        CHECK(back.region == NULL);
        CHECK(images_equal_bits(&img, &back));
        film_image_free(&back);
        free(meta.storage);
    } else {
        CHECK_MSG(false, "%s", err.message);
    }
    bytes = file_slurp(path, &size);
    for (size_t o = 0; bytes && o + 7 <= size; ++o) CHECK(memcmp(bytes + o, "region.", 7) != 0);
    free(bytes);
    film_image_free(&img);
    film_free(&f);
    scratch_remove(dir);
}

static const struct test_case film_tests[] = {
    { "exr_region_round_trip", test_exr_region_round_trip },
    { "add_row_matches_add", test_add_row_matches_add },
    { "per_pixel_count", test_per_pixel_count },
    { "sizes_are_checked", test_sizes_are_checked },
    { "welford_matches_two_pass", test_welford_matches_two_pass },
    { "snapshot_variance_of_mean", test_snapshot_variance_of_mean },
    { "snapshot_never_writes_nonfinite", test_snapshot_never_writes_nonfinite },
    { "exr_round_trip", test_exr_round_trip },
    { "exr_chunks_are_unambiguous", test_exr_chunks_are_unambiguous },
    { "exr_spp_saturates", test_exr_spp_saturates },
    { "exr_write_into_missing_directory", test_exr_write_into_missing_directory },
    { "exr_write_replaces_existing_file", test_exr_write_replaces_existing_file },
    { "exr_full_disk_keeps_old_file", test_exr_full_disk_keeps_old_file },
    { "exr_read_errors", test_exr_read_errors },
};
TEST_MAIN(film_tests)

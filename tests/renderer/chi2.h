/* chi2.h: a header-only chi-square goodness-of-fit test of a direction
   sampler against its claimed solid-angle pdf, for the C tests.

   Usage:
       struct chi2_config cfg;
       chi2_config_init(&cfg, axis, cap_angle);   (or chi2_config_cap: below)
       cfg.samples = 200000; cfg.seed = 7; cfg.significance = 0.01 / n_tests;
       double p;
       char report[512];
       bool ok = chi2_test(&cfg, my_sample, my_pdf, &my_ctx, &p, report, sizeof report);

   Binning. Directions are binned in a cap of half-angle cfg.cap_angle around
   cfg.frame.z: theta_bins rings equal in cos(theta) times phi_bins sectors
   equal in phi (phi measured from frame.x towards frame.y), so every cap bin
   has the same solid angle and a small light gets fine bins when the cap is
   fitted to it. Two more cells: every direction outside the cap, and the
   sampler's failures (it returned false).

   Expected counts. N times the integral of the pdf over each bin. Each bin
   is split into sub x sub cells uniform in theta and phi (so that cells stay
   compact near the axis), each cell's exact solid angle times its pdf. A
   cell is checked on its 3 x 3 lattice of corners, edge midpoints and centre:
   when the centre value times the area disagrees by more than 0.1% with the
   sum over its four quarters of the mean of their corners, the cell is split
   in 2 x 2, recursively down to max_depth levels, where that quarter-corner
   estimate is kept. Cells next to a split cell are split once too, which
   catches a shape's corner poking into a cell between lattice points. With
   the defaults (8 x 8 cells, depth 3) a shape's outline is resolved to 1/64
   of a bin: the bias of a bin on the outline is ~0.1/64 of its mass, far
   below the statistical error; a piece of the pdf narrower than 1/8 of a bin
   that misses every lattice point is lost (fit the cap, or raise sub, for
   slivers). The region outside the cap is integrated the same way on 8 x 16
   bins uniform in theta. The expected failure count is N (1 - integral of
   the pdf over the sphere): a sampler may fail exactly as often as its pdf is
   defective. An integral above 1 + CHI2_NORM_TOL fails the test outright.

   Statistic. Cells with expected counts below 5 are pooled, smallest first,
   until the pool reaches 5; chi^2 = sum (observed - expected)^2 / expected
   over the remaining cells and the pool, with (cells - 1) degrees of freedom,
   and p = Q(dof / 2, chi^2 / 2), the regularised upper incomplete gamma
   function (chi2_gamma_q). The test passes when p >= cfg.significance (use
   0.01 / number of tests in the file: Bonferroni) and the pdf is normalised.
   A sampled direction that is not finite fails the test. */
#ifndef CHI2_H
#define CHI2_H

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "rng.h"
#include "vec.h"

/* Draws one direction from three uniforms in [0, 1); returns false when the
   sampler fails (that counts as a failure, not as a direction). dir need not
   be unit length. */
typedef bool (*chi2_sample_fn)(void *ctx, double u1, double u2, double u3, struct vec3 *dir);
/* Solid-angle density (1/sr) of the unit direction dir. */
typedef double (*chi2_pdf_fn)(void *ctx, struct vec3 dir);

struct chi2_config {
    struct frame frame;  /* cap axis is frame.z; phi starts at frame.x */
    double cap_angle;    /* half-angle of the cap in radians, (0, pi] */
    int theta_bins;      /* rings, equal in cos(theta) */
    int phi_bins;        /* sectors, equal in phi */
    long samples;
    uint64_t seed;
    double significance; /* reject when p < significance */
    int sub;             /* integration cells per bin side */
    int max_depth;       /* adaptive splits of a cell */
};

#define CHI2_NORM_TOL 1e-3
#define CHI2_MIN_EXPECTED 5.0
#define CHI2_MAX_RINGS 1024

/* Defaults: 20 x 40 bins, 200000 samples, seed 1, significance 0.01,
   8 x 8 integration cells per bin, depth 3. */
static inline void chi2_config_init(struct chi2_config *cfg, struct vec3 axis, double cap_angle)
{
    cfg->frame = frame_from_normal(vec3_normalize(axis));
    cfg->cap_angle = cap_angle;
    cfg->theta_bins = 20;
    cfg->phi_bins = 40;
    cfg->samples = 200000;
    cfg->seed = 1;
    cfg->significance = 0.01;
    cfg->sub = 8;
    cfg->max_depth = 3;
}

/* Fits the cap to a convex spherical shape given by its n unit vertex
   directions: axis along their normalised mean, half-angle 5% (plus 1e-9 rad)
   beyond the farthest vertex. A convex spherical polygon lies inside any cap
   of half-angle <= pi/2 that holds its vertices; beyond that the cap is
   widened to the whole sphere. */
static inline void chi2_config_cap(struct chi2_config *cfg, const struct vec3 *dirs, int n)
{
    struct vec3 mean = vec3_make(0.0, 0.0, 0.0);
    for (int i = 0; i < n; ++i) mean = vec3_add(mean, vec3_normalize(dirs[i]));
    struct vec3 axis = vec3_normalize(mean);
    double angle = 0.0;
    for (int i = 0; i < n; ++i) {
        struct vec3 d = vec3_normalize(dirs[i]);
        angle = fmax(angle, atan2(vec3_length(vec3_cross(axis, d)), vec3_dot(axis, d)));
    }
    angle = angle * 1.05 + 1e-9;
    cfg->frame = frame_from_normal(axis);
    cfg->cap_angle = angle > 0.5 * M_PI ? M_PI : angle;
}

/* Regularised upper incomplete gamma Q(a, x) = Gamma(a, x) / Gamma(a), for
   a > 0, x >= 0. With the prefactor f = x^a e^-x / Gamma(a):
   for x < a + 1 the series P = f sum_{n>=0} x^n / (a (a+1) ... (a+n))
   converges fast and Q = 1 - P; otherwise the continued fraction
   Q = f / (x + 1 - a - 1 (1 - a) / (x + 3 - a - 2 (2 - a) / (x + 5 - a - ...)))
   evaluated with the modified Lentz method. */
static inline double chi2_gamma_q(double a, double x)
{
    if (!(a > 0.0) || !(x >= 0.0)) return NAN;
    if (x == 0.0) return 1.0;
    double log_f = -x + a * log(x) - lgamma(a);
    if (x < a + 1.0) {
        double term = 1.0 / a, sum = term;
        for (int n = 1; n < 100000; ++n) {
            term *= x / (a + n);
            sum += term;
            if (fabs(term) < fabs(sum) * 1e-16) break;
        }
        double q = 1.0 - sum * exp(log_f);
        return q < 0.0 ? 0.0 : q;
    }
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 100000; ++i) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (fabs(d) < tiny) d = tiny;
        c = b + an / c;
        if (fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        double delta = d * c;
        h *= delta;
        if (fabs(delta - 1.0) < 1e-16) break;
    }
    return exp(log_f) * h;
}

struct chi2_cell_ {
    double expected;
    long observed;
};

static inline int chi2_cell_compare_(const void *pa, const void *pb)
{
    double a = ((const struct chi2_cell_ *)pa)->expected, b = ((const struct chi2_cell_ *)pb)->expected;
    return (a > b) - (a < b);
}

struct chi2_integrand_ {
    const struct chi2_config *cfg;
    chi2_pdf_fn pdf;
    void *ctx;
};

static inline double chi2_pdf_at_(const struct chi2_integrand_ *f, double theta, double phi)
{
    double st = sin(theta);
    struct vec3 local = vec3_make(st * cos(phi), st * sin(phi), cos(theta));
    return f->pdf(f->ctx, frame_to_world(&f->cfg->frame, local));
}

/* Solid angle of theta in [th0, th1], phi in [ph0, ph1]:
   (cos th0 - cos th1) (ph1 - ph0), the difference of cosines written as a
   product so that it keeps its precision in tiny caps. */
static inline double chi2_cell_area_(double th0, double th1, double ph0, double ph1)
{
    return 2.0 * sin(0.5 * (th0 + th1)) * sin(0.5 * (th1 - th0)) * (ph1 - ph0);
}

/* Integral of the pdf over one cell (see the top of this file). *split
   reports whether the cell was subdivided; force subdivides it regardless. */
static inline double chi2_cell_(const struct chi2_integrand_ *f, double th0, double th1, double ph0, double ph1,
                                int depth, bool force, bool *split)
{
    double th[3] = { th0, 0.5 * (th0 + th1), th1 }, ph[3] = { ph0, 0.5 * (ph0 + ph1), ph1 };
    double v[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) v[i][j] = chi2_pdf_at_(f, th[i], ph[j]);
    double coarse = v[1][1] * chi2_cell_area_(th0, th1, ph0, ph1), fine = 0.0;
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j)
            fine += 0.25 * (v[i][j] + v[i + 1][j] + v[i][j + 1] + v[i + 1][j + 1]) *
                    chi2_cell_area_(th[i], th[i + 1], ph[j], ph[j + 1]);
    *split = false;
    if (!force && fabs(coarse - fine) <= 1e-3 * fmax(fabs(coarse), fabs(fine))) return fine;
    if (depth >= f->cfg->max_depth) return fine;
    *split = true;
    double sum = 0.0;
    bool ignored;
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) sum += chi2_cell_(f, th[i], th[i + 1], ph[j], ph[j + 1], depth + 1, false, &ignored);
    return sum;
}

/* Masses of the nr x ns bins between the theta boundaries theta[0..nr] and
   ns equal phi sectors: sub x sub cells per bin, then a second pass splits
   the unsplit neighbours (8-neighbourhood, phi wrapping) of split cells. */
static inline bool chi2_masses_(const struct chi2_integrand_ *f, const double *theta, int nr, int ns, double *mass)
{
    int sub = f->cfg->sub, rows = nr * sub, cols = ns * sub;
    double *val = malloc((size_t)rows * (size_t)cols * sizeof *val);
    unsigned char *split = calloc((size_t)rows * (size_t)cols, 1);
    if (!val || !split) {
        free(val);
        free(split);
        return false;
    }
    for (int pass = 0; pass < 2; ++pass) {
        for (int r = 0; r < rows; ++r) {
            int ring = r / sub, k = r % sub;
            double th0 = theta[ring] + (theta[ring + 1] - theta[ring]) * k / sub;
            double th1 = theta[ring] + (theta[ring + 1] - theta[ring]) * (k + 1) / sub;
            for (int c = 0; c < cols; ++c) {
                size_t at = (size_t)r * (size_t)cols + (size_t)c;
                bool force = false;
                if (pass == 1) {
                    if (split[at]) continue;
                    for (int dr = -1; dr <= 1 && !force; ++dr)
                        for (int dc = -1; dc <= 1 && !force; ++dc) {
                            int rr = r + dr, cc = (c + dc + cols) % cols;
                            if (rr >= 0 && rr < rows && split[(size_t)rr * (size_t)cols + (size_t)cc] == 1) force = true;
                        }
                    if (!force) continue;
                }
                bool did = false;
                val[at] = chi2_cell_(f, th0, th1, 2.0 * M_PI * c / cols, 2.0 * M_PI * (c + 1) / cols, 0, force, &did);
                /* 2 marks cells split in the second pass: they do not spread. */
                if (did) split[at] = (unsigned char)(pass == 0 ? 1 : 2);
            }
        }
    }
    for (int b = 0; b < nr * ns; ++b) mass[b] = 0.0;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) mass[(r / sub) * ns + c / sub] += val[(size_t)r * (size_t)cols + (size_t)c];
    free(val);
    free(split);
    return true;
}

/* Runs the test (see the top of this file). *p_value receives p (0 when the
   test fails for another reason); report, if not NULL, a one-line summary.
   Returns true when the sampler passes. */
static inline bool chi2_test(const struct chi2_config *cfg, chi2_sample_fn sample, chi2_pdf_fn pdf, void *ctx,
                             double *p_value, char *report, size_t report_len)
{
    int nt = cfg->theta_bins, np = cfg->phi_bins, nbins = nt * np;
    double cap_t = 2.0 * pow(sin(0.5 * cfg->cap_angle), 2.0); /* 1 - cos(cap) */
    *p_value = 0.0;
    if (nt < 1 || nt > CHI2_MAX_RINGS || np < 1 || cfg->sub < 1 || cfg->max_depth < 0 || cfg->samples < 1 ||
        !(cfg->cap_angle > 0.0) || !(cfg->cap_angle <= M_PI)) {
        if (report && report_len) snprintf(report, report_len, "chi2: invalid configuration");
        return false;
    }
    struct chi2_cell_ *cells = calloc((size_t)nbins + 2, sizeof *cells);
    if (!cells) {
        if (report && report_len) snprintf(report, report_len, "chi2: out of memory");
        return false;
    }

    /* Expected probabilities: the cap's rings are equal in 1 - cos(theta),
       i.e. theta_i = 2 asin(sqrt(t_i / 2)); outside, 8 rings uniform in
       theta by 16 sectors. */
    struct chi2_integrand_ f = { cfg, pdf, ctx };
    double theta[CHI2_MAX_RINGS + 1], out_theta[9], out_bins[8 * 16];
    for (int i = 0; i <= nt; ++i) theta[i] = 2.0 * asin(sqrt(0.5 * cap_t * i / nt));
    theta[nt] = cfg->cap_angle;
    double *bins = malloc((size_t)nbins * sizeof *bins);
    bool ok_alloc = bins && chi2_masses_(&f, theta, nt, np, bins);
    double cap_mass = 0.0, out_mass = 0.0;
    if (ok_alloc && cfg->cap_angle < M_PI) {
        for (int i = 0; i <= 8; ++i) out_theta[i] = cfg->cap_angle + (M_PI - cfg->cap_angle) * i / 8.0;
        ok_alloc = chi2_masses_(&f, out_theta, 8, 16, out_bins);
        for (int b = 0; ok_alloc && b < 8 * 16; ++b) out_mass += out_bins[b];
    }
    if (!ok_alloc) {
        free(bins);
        free(cells);
        if (report && report_len) snprintf(report, report_len, "chi2: out of memory");
        return false;
    }
    for (int b = 0; b < nbins; ++b) {
        cells[b].expected = bins[b];
        cap_mass += bins[b];
    }
    free(bins);
    double total = cap_mass + out_mass;
    cells[nbins].expected = out_mass;
    cells[nbins + 1].expected = fmax(0.0, 1.0 - total);

    /* Observed counts. */
    struct rng rng;
    rng_seed(&rng, cfg->seed, 0, 0);
    long invalid = 0;
    for (long s = 0; s < cfg->samples; ++s) {
        double u1 = rng_uniform(&rng), u2 = rng_uniform(&rng), u3 = rng_uniform(&rng);
        struct vec3 dir;
        if (!sample(ctx, u1, u2, u3, &dir)) {
            ++cells[nbins + 1].observed;
            continue;
        }
        double len = vec3_length(dir);
        if (!(len > 0.0) || !isfinite(len)) {
            ++invalid;
            continue;
        }
        struct vec3 w = frame_to_local(&cfg->frame, vec3_scale(dir, 1.0 / len));
        /* 1 - cos(theta) without cancellation near the axis. */
        double t = w.z > 0.0 ? (w.x * w.x + w.y * w.y) / (1.0 + w.z) : 1.0 - w.z;
        if (t > cap_t) {
            ++cells[nbins].observed;
            continue;
        }
        double phi = atan2(w.y, w.x);
        if (phi < 0.0) phi += 2.0 * M_PI;
        int i = (int)(t / cap_t * nt), j = (int)(phi / (2.0 * M_PI) * np);
        i = i < 0 ? 0 : (i >= nt ? nt - 1 : i);
        j = j < 0 ? 0 : (j >= np ? np - 1 : j);
        ++cells[i * np + j].observed;
    }

    /* Pool the smallest cells into one of at least CHI2_MIN_EXPECTED. */
    long zero_pdf_hits = 0;
    for (int c = 0; c < nbins + 2; ++c) {
        if (cells[c].expected == 0.0) zero_pdf_hits += cells[c].observed;
        cells[c].expected *= (double)cfg->samples;
    }
    qsort(cells, (size_t)nbins + 2, sizeof *cells, chi2_cell_compare_);
    double pool_exp = 0.0, stat = 0.0;
    long pool_obs = 0;
    int c = 0, pooled = 0;
    while (c < nbins + 2 && pool_exp < CHI2_MIN_EXPECTED) {
        pool_exp += cells[c].expected;
        pool_obs += cells[c].observed;
        ++c;
        ++pooled;
    }
    int kept = 0;
    for (; c < nbins + 2; ++c, ++kept) {
        double diff = (double)cells[c].observed - cells[c].expected;
        stat += diff * diff / cells[c].expected;
    }
    if (pool_exp > 0.0) {
        double diff = (double)pool_obs - pool_exp;
        stat += diff * diff / pool_exp;
        ++kept;
    } else if (pool_obs > 0) {
        stat = INFINITY;
    }
    int dof = kept - 1;
    double p = dof > 0 ? chi2_gamma_q(0.5 * dof, 0.5 * stat) : (stat == 0.0 ? 1.0 : 0.0);
    if (isinf(stat)) p = 0.0;
    bool normalized = total <= 1.0 + CHI2_NORM_TOL;
    bool ok = normalized && invalid == 0 && p >= cfg->significance;
    *p_value = p;
    if (report && report_len) {
        snprintf(report, report_len,
                 "chi2 = %.1f, dof = %d, p = %.3g (%s %.3g); N = %ld, %d cells (%d pooled); "
                 "pdf integral %.6f (cap %.6f)%s; in zero-pdf cells %ld, invalid %ld",
                 stat, dof, p, p >= cfg->significance ? ">=" : "<", cfg->significance, cfg->samples, nbins + 2,
                 pooled, total, cap_mass, normalized ? "" : " > 1: pdf not normalised", zero_pdf_hits, invalid);
    }
    free(cells);
    return ok;
}

#endif

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
   is split into sub x sub cells uniform in theta and phi (compact near the
   axis too). A cell is first checked on a 3 x 3 lattice (corners, edge
   midpoints, centre; shared between neighbours): when its centre value times
   its exact solid angle agrees to 0.1% with the sum over its quarters of the
   mean of their corners, that sum is its integral. Otherwise (the cell holds
   an edge of the pdf) it is resolved on `fine` points of a Fibonacci lattice
   (see chi2_cell_fine_). Then a flood fill resolves the neighbours
   (8-neighbourhood, phi wrapping) of resolved cells, and keeps spreading
   from those where the fine points show what the coarse lattice missed: this
   follows thin tips of a shape (the acute corners of a grazing rectangle,
   slivers) and corners poking between lattice points. With the defaults
   (8 x 8 cells of 233 points) an outline is resolved to ~1/120 of a bin.
   What escapes: the part of a tip narrower than the point spacing w (area
   ~ w^2 / (2 tan(angle))), and features that no lattice point
   of any cell touches; fit the cap to the shape (chi2_config_cap) or raise
   sub/fine for extreme slivers. The region outside the cap is integrated the
   same way on 8 x 16 bins uniform in theta. The expected failure count is
   N (1 - integral of the pdf over the sphere): a sampler may fail exactly as
   often as its pdf is defective. An integral above 1 + CHI2_NORM_TOL fails
   the test outright.

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

#include "base/rng.h"
#include "base/vec.h"

/* Draws one direction from three uniforms in [0, 1); returns false when the
   sampler fails (that counts as a failure, not as a direction). dir need not
   be unit length. */
typedef bool (*chi2_sample_fn)(void *ctx, double u1, double u2, double u3, struct vec3 *dir);
/* Solid-angle density (1/sr) of the unit direction dir. */
typedef double (*chi2_pdf_fn)(void *ctx, struct vec3 dir);

struct chi2_config {
    struct frame frame; /* cap axis is frame.z; phi starts at frame.x */
    double cap_angle;   /* half-angle of the cap in radians, (0, pi] */
    int theta_bins;     /* rings, equal in cos(theta) */
    int phi_bins;       /* sectors, equal in phi */
    long samples;
    uint64_t seed;
    double significance; /* reject when p < significance */
    int sub;             /* integration cells per bin side */
    int fine;            /* points in a cell that holds an edge (Fibonacci) */
};

#define CHI2_NORM_TOL     1e-3
#define CHI2_MIN_EXPECTED 5.0
#define CHI2_MAX_RINGS    1024

/* Defaults: 20 x 40 bins, 200000 samples, seed 1, significance 0.01,
   8 x 8 integration cells per bin, 233 points per resolved cell. */
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
    cfg->fine = 233;
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
    if (!(vec3_length(mean) > 1e-6 * n)) {
        /* Directions that nearly cancel span about a hemisphere or more. */
        cfg->frame = frame_from_normal(vec3_make(0.0, 0.0, 1.0));
        cfg->cap_angle = M_PI;
        return;
    }
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

static inline double chi2_pdf_sc_(const struct chi2_integrand_ *f, double sin_th, double cos_th, double sin_ph,
                                  double cos_ph)
{
    struct vec3 local = vec3_make(sin_th * cos_ph, sin_th * sin_ph, cos_th);
    return f->pdf(f->ctx, frame_to_world(&f->cfg->frame, local));
}

static inline double chi2_pdf_at_(const struct chi2_integrand_ *f, double theta, double phi)
{
    return chi2_pdf_sc_(f, sin(theta), cos(theta), sin(phi), cos(phi));
}

/* Solid angle of theta in [th0, th1], phi in [ph0, ph1]:
   (cos th0 - cos th1) (ph1 - ph0), the difference of cosines written as a
   product so that it keeps its precision in tiny caps. */
static inline double chi2_cell_area_(double th0, double th1, double ph0, double ph1)
{
    return 2.0 * sin(0.5 * (th0 + th1)) * sin(0.5 * (th1 - th0)) * (ph1 - ph0);
}

static inline bool chi2_differ_(double a, double b)
{
    return fabs(a - b) > 1e-3 * fmax(fabs(a), fabs(b));
}

/* Integral over a cell from a (k+1) x (k+1) lattice of pdf values v (rows
   along theta): each of the k x k sub-cells gets the mean of its corners
   times its exact solid angle. */
static inline double chi2_lattice_sum_(const double *v, int k, double th0, double th1, double ph0, double ph1)
{
    double sum = 0.0;
    for (int i = 0; i < k; ++i) {
        double ta = th0 + (th1 - th0) * i / k, tb = th0 + (th1 - th0) * (i + 1) / k;
        double row = 0.0;
        for (int j = 0; j < k; ++j)
            row +=
                v[i * (k + 1) + j] + v[(i + 1) * (k + 1) + j] + v[i * (k + 1) + j + 1] + v[(i + 1) * (k + 1) + j + 1];
        sum += 0.25 * row * chi2_cell_area_(ta, tb, ph0, ph0 + (ph1 - ph0) / k);
    }
    return sum;
}

/* A cell resolved on a Fibonacci lattice of `fine` points: point i at
   ((i + 1/2) / M, frac((i F' + 1/2) / M)) in the cell's (theta, phi) square,
   with M = fine and F' the previous Fibonacci number. Unlike a square grid it
   has no rows or columns for a shape's edge to run along (an edge along
   theta or phi would bias a grid by up to half a row). Each point weighs
   sin(theta) (the measure), normalised to the cell's exact solid angle. */
static inline double chi2_cell_fine_(const struct chi2_integrand_ *f, double th0, double th1, double ph0, double ph1)
{
    int m = f->cfg->fine, a = 1, b = 1;
    while (a + b <= m) {
        int c = a + b;
        a = b;
        b = c;
    }
    /* m is rounded down to the Fibonacci number b; a precedes it. */
    double sum = 0.0, wsum = 0.0;
    for (int i = 0; i < b; ++i) {
        double x = (i + 0.5) / b, y = fmod((double)i * a + 0.5, (double)b) / b;
        double th = th0 + (th1 - th0) * x, w = sin(th);
        sum += w * chi2_pdf_at_(f, th, ph0 + (ph1 - ph0) * y);
        wsum += w;
    }
    return wsum > 0.0 ? sum / wsum * chi2_cell_area_(th0, th1, ph0, ph1) : 0.0;
}

/* Masses of the nr x ns bins between the theta boundaries theta[0..nr] and
   ns equal phi sectors (see the top of this file). */
static inline bool chi2_masses_(const struct chi2_integrand_ *f, const double *theta, int nr, int ns, double *mass)
{
    int sub = f->cfg->sub, rows = nr * sub, cols = ns * sub;
    size_t ncell = (size_t)rows * (size_t)cols, lrows = 2 * (size_t)rows + 1, lcols = 2 * (size_t)cols;
    double *val = malloc(ncell * sizeof *val), *coarse_est = malloc(ncell * sizeof *coarse_est);
    double *lat = malloc(lrows * lcols * sizeof *lat);
    double *th = malloc(lrows * sizeof *th), *trig = malloc(2 * lcols * sizeof *trig);
    unsigned char *state = calloc(ncell, 1); /* 0 coarse, 1 resolved and spreading, 2 resolved */
    size_t *queue = malloc(ncell * sizeof *queue);
    bool ok = val && coarse_est && lat && th && trig && state && queue;
    if (ok) {
        /* theta of lattice row a: cell r = a / 2 spans a ring's sub-th part. */
        for (size_t a = 0; a < lrows; ++a) {
            int r = (int)(a / 2) < rows ? (int)(a / 2) : rows - 1, ring = r / sub, q = r % sub;
            double half = (a == lrows - 1) ? 1.0 : (double)(a % 2) * 0.5;
            double step = (theta[ring + 1] - theta[ring]) / sub;
            th[a] = theta[ring] + step * (q + half);
        }
        /* The lattice's phi columns are shared by all rows. */
        for (size_t b = 0; b < lcols; ++b) {
            trig[2 * b] = sin(M_PI * (double)b / (double)cols);
            trig[2 * b + 1] = cos(M_PI * (double)b / (double)cols);
        }
        for (size_t a = 0; a < lrows; ++a) {
            double st = sin(th[a]), ct = cos(th[a]);
            for (size_t b = 0; b < lcols; ++b)
                lat[a * lcols + b] = chi2_pdf_sc_(f, st, ct, trig[2 * b], trig[2 * b + 1]);
        }
        size_t head = 0, tail = 0;
        for (size_t r = 0; r < (size_t)rows; ++r) {
            for (size_t c = 0; c < (size_t)cols; ++c) {
                double v[9], ph0 = 2.0 * M_PI * (double)c / cols, ph1 = 2.0 * M_PI * (double)(c + 1) / cols;
                for (size_t i = 0; i < 3; ++i)
                    for (size_t j = 0; j < 3; ++j) v[i * 3 + j] = lat[(2 * r + i) * lcols + (2 * c + j) % lcols];
                size_t at = r * (size_t)cols + c;
                double coarse = v[4] * chi2_cell_area_(th[2 * r], th[2 * r + 2], ph0, ph1);
                coarse_est[at] = chi2_lattice_sum_(v, 2, th[2 * r], th[2 * r + 2], ph0, ph1);
                val[at] = coarse_est[at];
                if (chi2_differ_(coarse, coarse_est[at])) {
                    val[at] = chi2_cell_fine_(f, th[2 * r], th[2 * r + 2], ph0, ph1);
                    state[at] = 1;
                    queue[tail++] = at;
                }
            }
        }
        while (head < tail) {
            size_t at = queue[head++], r = at / (size_t)cols, c = at % (size_t)cols;
            for (int dr = -1; dr <= 1; ++dr) {
                for (int dc = -1; dc <= 1; ++dc) {
                    long rr = (long)r + dr;
                    if (rr < 0 || rr >= rows) continue;
                    size_t cc = (c + (size_t)cols + (size_t)(long)dc) % (size_t)cols,
                           nb = (size_t)rr * (size_t)cols + cc;
                    if (state[nb]) continue;
                    double ph0 = 2.0 * M_PI * (double)cc / cols, ph1 = 2.0 * M_PI * (double)(cc + 1) / cols;
                    val[nb] = chi2_cell_fine_(f, th[2 * rr], th[2 * rr + 2], ph0, ph1);
                    state[nb] = 2;
                    if (chi2_differ_(val[nb], coarse_est[nb])) {
                        state[nb] = 1;
                        queue[tail++] = nb;
                    }
                }
            }
        }
        for (int b = 0; b < nr * ns; ++b) mass[b] = 0.0;
        for (size_t r = 0; r < (size_t)rows; ++r)
            for (size_t c = 0; c < (size_t)cols; ++c)
                mass[(r / sub) * (size_t)ns + c / sub] += val[r * (size_t)cols + c];
    }
    free(val);
    free(coarse_est);
    free(lat);
    free(th);
    free(trig);
    free(state);
    free(queue);
    return ok;
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
    if (nt < 1 || nt > CHI2_MAX_RINGS || np < 1 || cfg->sub < 1 || cfg->fine < 3 || cfg->samples < 1 ||
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
                 stat, dof, p, p >= cfg->significance ? ">=" : "<", cfg->significance, cfg->samples, nbins + 2, pooled,
                 total, cap_mass, normalized ? "" : " > 1: pdf not normalised", zero_pdf_hits, invalid);
    }
    free(cells);
    return ok;
}

#endif

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

   Expected counts. N times the integral of the pdf over each bin, computed
   by an adaptive midpoint rule in (1 - cos(theta), phi), where the measure is
   exactly d(omega) = d(1 - cos theta) d(phi): a cell is evaluated on a 4x4
   grid and split in 2x2 while its values differ by more than 1% and the
   depth is below cfg.max_depth. For pdfs that are piecewise constant (uniform
   solid-angle samplers) this resolves a shape's outline to 1/(4 * 2^depth) of
   a bin; a feature smaller than the 4x4 grid of a bin (a corner poking into
   it) can be missed, which biases that bin's expectation slightly. The
   outside region (1 - cos theta in [1 - cos(cap), 2]) is integrated the same
   way on 8 x 16 cells. The expected failure count is N (1 - integral of the
   pdf over the sphere): a sampler may fail exactly as often as its pdf is
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
    int max_depth;       /* adaptive integration depth per bin */
};

#define CHI2_NORM_TOL 1e-3
#define CHI2_MIN_EXPECTED 5.0

/* Defaults: 20 x 40 bins, 200000 samples, seed 1, significance 0.01,
   depth 5. */
static inline void chi2_config_init(struct chi2_config *cfg, struct vec3 axis, double cap_angle)
{
    cfg->frame = frame_from_normal(vec3_normalize(axis));
    cfg->cap_angle = cap_angle;
    cfg->theta_bins = 20;
    cfg->phi_bins = 40;
    cfg->samples = 200000;
    cfg->seed = 1;
    cfg->significance = 0.01;
    cfg->max_depth = 5;
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

/* Integral of the pdf over t = 1 - cos(theta) in [t0, t1], phi in [p0, p1]. */
static inline double chi2_integrate_(const struct chi2_config *cfg, chi2_pdf_fn pdf, void *ctx, double t0,
                                     double t1, double p0, double p1, int depth)
{
    double f[16], lo = INFINITY, hi = -INFINITY, sum = 0.0;
    for (int i = 0; i < 4; ++i) {
        double t = t0 + (t1 - t0) * (i + 0.5) / 4.0;
        double s = sqrt(fmax(0.0, t * (2.0 - t)));
        for (int j = 0; j < 4; ++j) {
            double phi = p0 + (p1 - p0) * (j + 0.5) / 4.0;
            struct vec3 local = vec3_make(s * cos(phi), s * sin(phi), 1.0 - t);
            double v = pdf(ctx, frame_to_world(&cfg->frame, local));
            f[4 * i + j] = v;
            lo = fmin(lo, v);
            hi = fmax(hi, v);
            sum += v;
        }
    }
    if (depth >= cfg->max_depth || hi - lo <= 0.01 * fabs(hi)) return sum / 16.0 * (t1 - t0) * (p1 - p0);
    double tm = 0.5 * (t0 + t1), pm = 0.5 * (p0 + p1);
    return chi2_integrate_(cfg, pdf, ctx, t0, tm, p0, pm, depth + 1) +
           chi2_integrate_(cfg, pdf, ctx, t0, tm, pm, p1, depth + 1) +
           chi2_integrate_(cfg, pdf, ctx, tm, t1, p0, pm, depth + 1) +
           chi2_integrate_(cfg, pdf, ctx, tm, t1, pm, p1, depth + 1);
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
    if (nt < 1 || np < 1 || cfg->samples < 1 || !(cfg->cap_angle > 0.0) || !(cfg->cap_angle <= M_PI)) {
        if (report && report_len) snprintf(report, report_len, "chi2: invalid configuration");
        return false;
    }
    struct chi2_cell_ *cells = calloc((size_t)nbins + 2, sizeof *cells);
    if (!cells) {
        if (report && report_len) snprintf(report, report_len, "chi2: out of memory");
        return false;
    }

    /* Expected probabilities. */
    double cap_mass = 0.0, out_mass = 0.0;
    for (int i = 0; i < nt; ++i) {
        for (int j = 0; j < np; ++j) {
            double m = chi2_integrate_(cfg, pdf, ctx, cap_t * i / nt, cap_t * (i + 1) / nt, 2.0 * M_PI * j / np,
                                       2.0 * M_PI * (j + 1) / np, 0);
            cells[i * np + j].expected = m;
            cap_mass += m;
        }
    }
    if (cap_t < 2.0) {
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 16; ++j)
                out_mass += chi2_integrate_(cfg, pdf, ctx, cap_t + (2.0 - cap_t) * i / 8.0,
                                            cap_t + (2.0 - cap_t) * (i + 1) / 8.0, 2.0 * M_PI * j / 16.0,
                                            2.0 * M_PI * (j + 1) / 16.0, 0);
    }
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

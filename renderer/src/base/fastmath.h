/* fastmath.h: sine, cosine and atan2 as straight-line arithmetic, so that
   loops over many shading points that call them vectorise (libm's versions
   are opaque calls with branches), and so that the one-point and the
   many-point samplers built on them give bit-identical results.

   Only +, -, *, /, fabs and comparisons feeding selects are used, and the
   project compiles in ISO C mode (no contraction into fused multiply-adds),
   so every lane of every instruction set rounds exactly alike.

   Accuracy, measured against libm in tests/renderer/test_fastmath.c:
   fm_sincos within 2 ulp on |x| <= 1000, except near the zeros of sin and
   cos, where the reduction's error is absolute (below 2e-23; 5e5 ulp of
   sin(pi) = 1.2e-16), and within 2.3e-16 absolute up to |x| = 2^20, beyond
   which the reduction is no longer exact; fm_atan2 within 3 ulp unless
   both arguments are below ~1e-300 (the samplers never get there). Signed
   zeros are not honoured: fm_atan2(-0, -1) is +pi, libm's -pi. */
#ifndef FASTMATH_H
#define FASTMATH_H

#include <math.h>

/* Runtime dispatch for the vectorised loops: GCC compiles the marked
   function once per instruction set and picks the widest the CPU has when
   the program loads. x86-64-v4 is AVX-512 F, BW, CD, DQ and VL (DQ gives
   the 64-bit multiplies and conversions of the random streams). Results
   are the same on every instruction set: ISO C mode (-std=c99) contracts
   no multiply-add into an FMA. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define FM_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define FM_SIMD_CLONES
#endif

/* Straight-line helpers called inside vectorised loops must be inlined
   there: an out-of-line call stops the vectoriser. */
#if defined(__GNUC__)
#define FM_INLINE static inline __attribute__((always_inline))
#else
#define FM_INLINE static inline
#endif

/* Round to the nearest integer by the 1.5 * 2^52 trick: plain arithmetic
   (no rounding instruction is needed on the baseline instruction set),
   exact for |x| < 2^51 in round-to-nearest mode. */
FM_INLINE double fm_round(double x)
{
    const double magic = 6755399441055744.0; /* 1.5 * 2^52 */
    return (x + magic) - magic;
}

/* sin and cos of x. x is reduced by q = round(x / (pi/2)) with pi/2 split in
   two (Cody and Waite: the first part has 33 significant bits, so q times it
   is exact for |q| < 2^20), leaving |r| <= pi/4 where the Taylor series up to
   r^17 (sine) and r^18 (cosine) are accurate to 1e-19. */
FM_INLINE void fm_sincos(double x, double *s, double *c)
{
    const double pio2_hi = 1.57079632673412561417e+00;
    const double pio2_lo = 6.07710050650619224932e-11;
    double q = fm_round(x * 0.63661977236758134308);
    double r = (x - q * pio2_hi) - q * pio2_lo;
    double r2 = r * r;
    double ps = -1.0 / 355687428096000.0; /* -1/17! */
    ps = ps * r2 + 1.0 / 1307674368000.0; /*  1/15! */
    ps = ps * r2 - 1.0 / 6227020800.0;    /* -1/13! */
    ps = ps * r2 + 1.0 / 39916800.0;      /*  1/11! */
    ps = ps * r2 - 1.0 / 362880.0;        /* -1/9!  */
    ps = ps * r2 + 1.0 / 5040.0;          /*  1/7!  */
    ps = ps * r2 - 1.0 / 120.0;           /* -1/5!  */
    ps = ps * r2 + 1.0 / 6.0;             /*  1/3!  */
    double sr = r - r * r2 * ps;
    double pc = 1.0 / 6402373705728000.0;  /*  1/18! */
    pc = pc * r2 - 1.0 / 20922789888000.0; /* -1/16! */
    pc = pc * r2 + 1.0 / 87178291200.0;    /*  1/14! */
    pc = pc * r2 - 1.0 / 479001600.0;      /* -1/12! */
    pc = pc * r2 + 1.0 / 3628800.0;        /*  1/10! */
    pc = pc * r2 - 1.0 / 40320.0;          /* -1/8!  */
    pc = pc * r2 + 1.0 / 720.0;            /*  1/6!  */
    pc = pc * r2 - 1.0 / 24.0;             /* -1/4!  */
    double cr = 1.0 - 0.5 * r2 - r2 * r2 * pc;
    /* Quadrant m = q mod 4, found without integers: (q - 1.5) / 4 rounds to
       floor(q / 4) for integer q. */
    double m = q - 4.0 * fm_round((q - 1.5) * 0.25);
    int odd = (m == 1.0) | (m == 3.0);
    double sv = odd ? cr : sr, cv = odd ? sr : cr;
    *s = m >= 2.0 ? -sv : sv;
    *c = ((m == 1.0) | (m == 2.0)) ? -cv : cv;
}

/* atan2(y, x) in [-pi, pi]. With a = min(|x|, |y|) / max(|x|, |y|) in [0, 1],
   atan a = c + atan t for the centre c in {0, pi/8, pi/4} nearest to atan a
   and t = (a - tan c) / (1 + a tan c), |t| <= tan(pi/16) ~ 0.199, where the
   series up to t^23 is accurate to 3e-18; t is formed in one division
   directly from |x| and |y|. Then the octant is undone. atan2(0, 0) = 0. */
FM_INLINE double fm_atan2(double y, double x)
{
    const double tan_pi_16 = 0.19891236737965800691;
    const double tan_pi_8 = 0.41421356237309504880;
    const double tan_3pi_16 = 0.66817863791929891999;
    double ax = fabs(x), ay = fabs(y);
    int swap = ay > ax;
    double n = swap ? ax : ay, d = swap ? ay : ax; /* a = n / d */
    int mid = n > tan_pi_16 * d, high = n > tan_3pi_16 * d;
    double tc = high ? 1.0 : (mid ? tan_pi_8 : 0.0);
    double c = high ? 0.78539816339744830962 : (mid ? 0.39269908169872415481 : 0.0);
    double den = d + n * tc;
    double t = (n - d * tc) / (den > 0.0 ? den : 1.0);
    double t2 = t * t;
    double p = -1.0 / 23.0;
    p = p * t2 + 1.0 / 21.0;
    p = p * t2 - 1.0 / 19.0;
    p = p * t2 + 1.0 / 17.0;
    p = p * t2 - 1.0 / 15.0;
    p = p * t2 + 1.0 / 13.0;
    p = p * t2 - 1.0 / 11.0;
    p = p * t2 + 1.0 / 9.0;
    p = p * t2 - 1.0 / 7.0;
    p = p * t2 + 1.0 / 5.0;
    p = p * t2 - 1.0 / 3.0;
    double a = c + (t + t * t2 * p);
    a = swap ? 1.57079632679489661923 - a : a;
    a = x < 0.0 ? 3.14159265358979323846 - a : a;
    return y < 0.0 ? -a : a;
}

/* fmin and fmax as glibc gives them (a NaN argument yields the other one;
   of two equal values the second, which for +0 and -0 C leaves open), but
   inline: without -ffinite-math-only GCC calls libm for fmin and fmax, and
   polygon bounding boxes on the per-sample path made those calls a
   visible share of a portal strategy's profile (docs/performance.md). */
FM_INLINE double fm_fmin(double a, double b)
{
    return (a < b || b != b) ? a : b;
}
FM_INLINE double fm_fmax(double a, double b)
{
    return (a > b || b != b) ? a : b;
}

#endif

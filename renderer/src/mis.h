/* mis.h: the multiple importance sampling weight of one sample of
   technique a against one of technique b (the balance and power
   heuristics of Veach 1997, or none), the one home of the heuristics:
   mis_ratio for estimators divided by pdf_a (the vectorised shadow rays),
   mis_weight for the weight itself. Pure arithmetic on densities: it must
   not see rays, BSDFs, strategies or the scene. */
#ifndef MIS_H
#define MIS_H

#include "strategy_kind.h"
#include "fastmath.h"

/* pdf_a is clamped to this before any square: an infinite density (a
   direction grazing an area-sampled light) then weighs ~1e-150 instead of
   exactly 0, and no square overflows into a NaN. */
#define MIS_PDF_MAX 1e150

/* w_a / pdf_a = num / den, with one division for every kind:
   1 / pa (none), 1 / (pa + pb) (balance), pa / (pa^2 + pb^2) (power).
   Selects, no branches, so that a loop over lanes vectorises; an estimator
   f L cos / pdf_a weighted by w_a is f L cos num / den. */
struct mis_ratio {
    double num, den;
};

FM_INLINE struct mis_ratio mis_ratio(enum mis_kind mis, double pdf_a, double pdf_b)
{
    struct mis_ratio r;
    double pa = pdf_a < MIS_PDF_MAX ? pdf_a : MIS_PDF_MAX, pb = pdf_b;
    r.num = mis == MIS_POWER ? pa : 1.0;
    r.den = mis == MIS_NONE ? pa : (mis == MIS_BALANCE ? pa + pb : pa * pa + pb * pb);
    return r;
}

/* The weight w_a itself, in [0, 1] (1 for MIS_NONE): pdf_a num / den of
   mis_ratio, written as a ratio of the smaller density to the larger so
   that an infinite density gives 1 or 0, never NaN. Used where the weight
   multiplies an estimate that is not divided by pdf_a (a BSDF-sampled ray
   that reaches a light). It is the same weight as mis_ratio's up to
   rounding, kept in this form because pdf_a num / den changes the last
   bits of the render's double accumulators (final.state) at a fixed seed. */
static inline double mis_weight(enum mis_kind mis, double pdf_a, double pdf_b)
{
    switch (mis) {
    case MIS_NONE:
        return 1.0;
    case MIS_BALANCE:
        if (pdf_a >= pdf_b) return 1.0 / (1.0 + pdf_b / pdf_a);
        return pdf_a / pdf_b / (1.0 + pdf_a / pdf_b);
    case MIS_POWER:
        /* Squares overflow only for absurd pdfs; the ratio form avoids it. */
        if (pdf_a >= pdf_b) {
            double r = pdf_b / pdf_a;
            return 1.0 / (1.0 + r * r);
        } else {
            double r = pdf_a / pdf_b;
            return r * r / (1.0 + r * r);
        }
    }
    return 1.0;
}

#endif

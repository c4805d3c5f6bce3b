/* mis.h: the multiple importance sampling weight of one sample of
   technique a against one of technique b (the balance and power
   heuristics of Veach 1997, or none), the one home of the heuristics, in
   one algebraic form: mis_ratio for estimators divided by pdf_a (the
   vectorised shadow rays), mis_weight for the weight itself. Pure arithmetic on densities: it must
   not see rays, BSDFs, strategies or the scene. */
#ifndef MIS_H
#define MIS_H

#include "base/kinds.h"
#include "base/fastmath.h"

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
   mis_ratio, the same form, for an estimate that is not divided by pdf_a
   (a BSDF-sampled ray that reaches a light). */
static inline double mis_weight(enum mis_kind mis, double pdf_a, double pdf_b)
{
    if (mis == MIS_NONE) return 1.0;
    struct mis_ratio r = mis_ratio(mis, pdf_a, pdf_b);
    double pa = pdf_a < MIS_PDF_MAX ? pdf_a : MIS_PDF_MAX;
    return pa * r.num / r.den;
}

#endif

/* test_mis.c: the MIS heuristics of mis.h. Both forms are one weight:
   mis_weight and pdf_a num / den of mis_ratio agree to rounding; the
   weights of the two techniques sum to one; infinite densities give the
   limits (1 or 0, or ~1e-150 in the ratio form), never NaN. */
#include <math.h>

#include "sampling/mis.h"
#include "base/rng.h"
#include "testlib.h"

static const enum mis_kind heuristics[] = { MIS_BALANCE, MIS_POWER };

/* Densities over many orders of magnitude, as lights near and far give. */
static double random_pdf(struct rng *r)
{
    return pow(10.0, 12.0 * rng_uniform(r) - 6.0);
}

static void test_forms_agree(void)
{
    struct rng r;
    rng_seed(&r, 14, 2, 0);
    int bad = 0;
    for (int i = 0; i < 100000; ++i) {
        double pa = random_pdf(&r), pb = random_pdf(&r);
        for (int k = 0; k < 2; ++k) {
            struct mis_ratio q = mis_ratio(heuristics[k], pa, pb);
            double w = mis_weight(heuristics[k], pa, pb), w_ratio = pa * q.num / q.den;
            bad += !(fabs(w - w_ratio) <= 1e-15 * (w > 1e-300 ? w : 1e-300) + 1e-300);
        }
    }
    CHECK_MSG(bad == 0, "%d weights differ beyond rounding", bad);
}

static void test_weights_sum_to_one(void)
{
    struct rng r;
    rng_seed(&r, 14, 3, 0);
    int bad = 0;
    for (int i = 0; i < 100000; ++i) {
        double pa = random_pdf(&r), pb = random_pdf(&r);
        for (int k = 0; k < 2; ++k) {
            double wa = mis_weight(heuristics[k], pa, pb), wb = mis_weight(heuristics[k], pb, pa);
            bad += !(fabs(wa + wb - 1.0) <= 4e-16) || !(wa >= 0.0 && wa <= 1.0);
        }
    }
    CHECK_MSG(bad == 0, "%d pairs of weights do not sum to one", bad);
    /* Equal densities split evenly. */
    CHECK(mis_weight(MIS_BALANCE, 3.0, 3.0) == 0.5);
    CHECK(mis_weight(MIS_POWER, 3.0, 3.0) == 0.5);
}

static void test_none(void)
{
    CHECK(mis_weight(MIS_NONE, 0.25, 4.0) == 1.0);
    CHECK(mis_weight(MIS_NONE, INFINITY, 4.0) == 1.0);
    struct mis_ratio q = mis_ratio(MIS_NONE, 0.25, 4.0);
    CHECK(q.num / q.den == 4.0); /* w / pdf_a = 1 / pdf_a */
}

static void test_infinite_densities(void)
{
    for (int k = 0; k < 2; ++k) {
        enum mis_kind m = heuristics[k];
        CHECK(mis_weight(m, INFINITY, 2.0) == 1.0);
        CHECK(mis_weight(m, 2.0, INFINITY) == 0.0);
        CHECK(mis_weight(m, 0.0, 2.0) == 0.0);
        /* The ratio form clamps pdf_a: a finite, tiny w / pdf_a. */
        struct mis_ratio q = mis_ratio(m, INFINITY, 2.0);
        double w_over_pdf = q.num / q.den;
        CHECK(isfinite(w_over_pdf) && w_over_pdf > 0.0 && w_over_pdf <= 1.0001 / MIS_PDF_MAX);
        q = mis_ratio(m, 2.0, INFINITY);
        CHECK(q.num / q.den == 0.0);
    }
}

static const struct test_case tests[] = {
    { "forms_agree", test_forms_agree },
    { "weights_sum_to_one", test_weights_sum_to_one },
    { "none", test_none },
    { "infinite_densities", test_infinite_densities },
};

TEST_MAIN(tests)

#include "sampling/alias.h"

#include <math.h>
#include <stdlib.h>

bool alias_build(struct alias_table *t, const double *weights, int n, struct error *err)
{
    double sum = 0.0;
    t->n = 0;
    t->prob = t->accept = NULL;
    t->alias = NULL;
    if (n <= 0) return error_set(err, "alias table needs at least one entry");
    for (int i = 0; i < n; ++i) {
        if (!(weights[i] >= 0.0) || !isfinite(weights[i]))
            return error_set(err, "alias table weight %d is %g (expected finite >= 0)", i, weights[i]);
        sum += weights[i];
    }
    if (!(sum > 0.0)) return error_set(err, "alias table weights sum to zero");

    t->prob = malloc(sizeof *t->prob * (size_t)n);
    t->accept = malloc(sizeof *t->accept * (size_t)n);
    t->alias = malloc(sizeof *t->alias * (size_t)n);
    int *small = malloc(sizeof *small * (size_t)n), *large = malloc(sizeof *large * (size_t)n);
    if (!t->prob || !t->accept || !t->alias || !small || !large) {
        free(small);
        free(large);
        alias_free(t);
        return error_set(err, "out of memory building an alias table of %d entries", n);
    }
    /* Vose's method: scaled weights split into under- and over-full bins;
       each under-full bin is topped up by one over-full bin. */
    int ns = 0, nl = 0;
    for (int i = 0; i < n; ++i) {
        t->prob[i] = weights[i] / sum;
        t->accept[i] = t->prob[i] * n;
        t->alias[i] = i;
        if (t->accept[i] < 1.0) small[ns++] = i;
        else large[nl++] = i;
    }
    while (ns > 0 && nl > 0) {
        int s = small[--ns], l = large[nl - 1];
        t->alias[s] = l;
        t->accept[l] -= 1.0 - t->accept[s];
        if (t->accept[l] < 1.0) {
            --nl;
            small[ns++] = l;
        }
    }
    /* Leftovers are full bins up to rounding. */
    while (nl > 0) t->accept[large[--nl]] = 1.0;
    while (ns > 0) t->accept[small[--ns]] = 1.0;
    free(small);
    free(large);
    t->n = n;
    return true;
}

void alias_free(struct alias_table *t)
{
    free(t->prob);
    free(t->accept);
    free(t->alias);
    t->prob = t->accept = NULL;
    t->alias = NULL;
    t->n = 0;
}

/* alias.h: Walker/Vose alias tables: O(1) sampling of a discrete
   distribution, used for light selection by power.
   It knows nothing of lights: it takes weights and returns indices. */
#ifndef ALIAS_H
#define ALIAS_H

#include <stdbool.h>

#include "base/error.h"

struct alias_table {
    int n;
    double *prob;   /* normalised probabilities p_i (sum 1) */
    double *accept; /* acceptance threshold of bin i */
    int *alias;     /* alias of bin i */
};

/* Builds from non-negative weights with a positive sum. */
bool alias_build(struct alias_table *t, const double *weights, int n, struct error *err);
void alias_free(struct alias_table *t);
/* Index for u in [0,1); *u_reuse (optional) receives a fresh uniform in [0,1)
   recovered from u's leftover bits, so the caller needs no extra draw.
   Inline: light sampling calls it once per sample. */
static inline int alias_sample(const struct alias_table *t, double u, double *u_reuse)
{
    double x = u * t->n;
    int i = (int)x;
    if (i >= t->n) i = t->n - 1;
    double f = x - i; /* uniform in [0,1) given i */
    if (f < t->accept[i]) {
        if (u_reuse) *u_reuse = t->accept[i] > 0.0 ? f / t->accept[i] : 0.0;
        return i;
    }
    if (u_reuse) *u_reuse = (f - t->accept[i]) / (1.0 - t->accept[i]);
    return t->alias[i];
}

#endif

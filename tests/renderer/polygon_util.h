/* polygon_util.h: what tests measure polygons with, beside polygon.h. */
#ifndef POLYGON_UTIL_H
#define POLYGON_UTIL_H

#include <math.h>

#include "geometry/polygon.h"

/* The distance from x to the polygon's rim (its nearest edge segment): how
   close a ray's crossing came to where two tests may rightly disagree. */
static inline double test_rim_distance(const struct polygon *poly, struct vec3 x)
{
    double best = INFINITY;
    for (int k = 0; k < poly->n; ++k) {
        struct vec3 a = poly->v[k], e = vec3_sub(poly->v[(k + 1) % poly->n], a);
        double along = vec3_dot(vec3_sub(x, a), e) / vec3_length2(e);
        along = along < 0.0 ? 0.0 : along > 1.0 ? 1.0 : along;
        double d = vec3_length(vec3_sub(x, vec3_madd(a, e, along)));
        best = d < best ? d : best;
    }
    return best;
}

#endif

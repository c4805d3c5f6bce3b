/* facet_edges.h: the edge bookkeeping that facet_cover.c and
   facet_layer.c share (facet_cover.h): edges welded when their ends are
   bit-identical, and the 2-D orientation in a facet's frame. Internal to
   those two files. */
#ifndef FACET_EDGES_H
#define FACET_EDGES_H

#include "base/vec.h"

/* An edge of a covering triangle, its ends in lexicographic order, and the
   side of the edge (seen along the facet's normal) its triangle lies on. */
struct cover_edge {
    struct vec3 a, b;
    int side;
};

static inline int compare_vec3(struct vec3 p, struct vec3 q)
{
    if (p.x != q.x) return p.x < q.x ? -1 : 1;
    if (p.y != q.y) return p.y < q.y ? -1 : 1;
    if (p.z != q.z) return p.z < q.z ? -1 : 1;
    return 0;
}

static inline int compare_cover_edges(const void *x, const void *y)
{
    const struct cover_edge *p = x, *q = y;
    int c = compare_vec3(p->a, q->a);
    return c ? c : compare_vec3(p->b, q->b);
}

static inline double orient2(struct vec3 a, struct vec3 b, struct vec3 c)
{
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

#endif

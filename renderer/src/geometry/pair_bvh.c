#include "geometry/pair_bvh.h"

#include <stdlib.h>

/* A square on the plane, large enough to cover the box. */
static void plane_polygon(const struct plane *pl, struct aabb box, struct polygon *out)
{
    struct vec3 c = vec3_scale(vec3_add(box.lo, box.hi), 0.5);
    double r = 2.0 * vec3_length(vec3_sub(box.hi, box.lo)) + 1.0;
    struct vec3 o = vec3_madd(c, pl->normal, -plane_distance(pl, c));
    struct frame f = frame_from_normal(pl->normal);
    out->n = 4;
    out->v[0] = vec3_add(o, vec3_add(vec3_scale(f.x, -r), vec3_scale(f.y, -r)));
    out->v[1] = vec3_add(o, vec3_add(vec3_scale(f.x, r), vec3_scale(f.y, -r)));
    out->v[2] = vec3_add(o, vec3_add(vec3_scale(f.x, r), vec3_scale(f.y, r)));
    out->v[3] = vec3_add(o, vec3_add(vec3_scale(f.x, -r), vec3_scale(f.y, r)));
}

#define REGION_PLANES_MAX 64

bool aabb_of_region(const struct plane *planes, int n, struct aabb box, struct aabb *out)
{
    struct plane all[REGION_PLANES_MAX + 6];
    int m = 0;
    for (int i = 0; i < n && m < REGION_PLANES_MAX; ++i) all[m++] = planes[i];
    /* The box as six inward planes. */
    const double lo[3] = { box.lo.x, box.lo.y, box.lo.z }, hi[3] = { box.hi.x, box.hi.y, box.hi.z };
    for (int a = 0; a < 3; ++a) {
        struct vec3 e = vec3_make(a == 0, a == 1, a == 2);
        all[m++] = (struct plane){ e, lo[a] };
        all[m++] = (struct plane){ vec3_neg(e), -hi[a] };
    }
    bool any = false;
    struct aabb acc = { vec3_make(INFINITY, INFINITY, INFINITY), vec3_make(-INFINITY, -INFINITY, -INFINITY) };
    for (int i = 0; i < m; ++i) {
        struct polygon poly, tmp;
        plane_polygon(&all[i], box, &poly);
        for (int j = 0; j < m && poly.n >= 3; ++j) {
            if (j == i) continue;
            polygon_clip_plane(&poly, &all[j], &tmp);
            poly = tmp;
        }
        for (int k = 0; k < poly.n; ++k) {
            struct vec3 v = poly.v[k];
            acc.lo = vec3_make(fmin(acc.lo.x, v.x), fmin(acc.lo.y, v.y), fmin(acc.lo.z, v.z));
            acc.hi = vec3_make(fmax(acc.hi.x, v.x), fmax(acc.hi.y, v.y), fmax(acc.hi.z, v.z));
            any = true;
        }
    }
    *out = acc;
    return any;
}

static struct aabb aabb_union(struct aabb a, struct aabb b)
{
    struct aabb r = { vec3_make(fmin(a.lo.x, b.lo.x), fmin(a.lo.y, b.lo.y), fmin(a.lo.z, b.lo.z)),
                      vec3_make(fmax(a.hi.x, b.hi.x), fmax(a.hi.y, b.hi.y), fmax(a.hi.z, b.hi.z)) };
    return r;
}

static double axis_of(struct vec3 v, int a)
{
    return a == 0 ? v.x : a == 1 ? v.y : v.z;
}

struct build_ctx {
    struct pair_bvh *b;
    const struct aabb *boxes;
};

/* Median split on the longest axis of the centroids; leaves of <= 4 items. */
static void build_node(struct build_ctx *c, int node, int first, int count)
{
    struct pair_bvh *b = c->b;
    struct aabb box = c->boxes[b->items[first]], cent;
    struct vec3 m0 = vec3_scale(vec3_add(box.lo, box.hi), 0.5);
    cent.lo = cent.hi = m0;
    for (int i = first; i < first + count; ++i) {
        struct aabb bi = c->boxes[b->items[i]];
        struct vec3 m = vec3_scale(vec3_add(bi.lo, bi.hi), 0.5);
        box = aabb_union(box, bi);
        cent = aabb_union(cent, (struct aabb){ m, m });
    }
    b->nodes[node].box = box;
    if (count <= 4) {
        b->nodes[node].first = first;
        b->nodes[node].count = count;
        return;
    }
    struct vec3 ext = vec3_sub(cent.hi, cent.lo);
    int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
    /* Partial selection sort around the median (n is small: scene load). */
    int half = count / 2;
    for (int i = first; i < first + half; ++i) {
        int best = i;
        for (int j = i + 1; j < first + count; ++j) {
            struct aabb bj = c->boxes[b->items[j]], bb = c->boxes[b->items[best]];
            if (axis_of(bj.lo, axis) + axis_of(bj.hi, axis) < axis_of(bb.lo, axis) + axis_of(bb.hi, axis)) best = j;
        }
        int t = b->items[i];
        b->items[i] = b->items[best];
        b->items[best] = t;
    }
    int left = b->n_nodes;
    b->n_nodes += 2;
    b->nodes[node].first = left;
    b->nodes[node].count = 0;
    build_node(c, left, first, half);
    build_node(c, left + 1, first + half, count - half);
}

/* The tree's items in the order pair_bvh_query_tree's traversal visits them
   (depth first, the right child popped first), for the flat search: a node
   whose box misses p holds no item whose box contains p (its box is their
   union), so the flat search over this order, keeping the boxes that
   contain p, finds what the traversal finds, in the same order. */
static void flatten(struct pair_bvh *b)
{
    int stack[64], top = 0;
    b->n_flat = 0;
    stack[top++] = 0;
    while (top > 0) {
        const struct pair_bvh_node *nd = &b->nodes[stack[--top]];
        if (nd->count > 0) {
            for (int i = nd->first; i < nd->first + nd->count; ++i) {
                b->flat_items[b->n_flat] = b->items[i];
                b->flat_boxes[b->n_flat++] = b->boxes[b->items[i]];
            }
            continue;
        }
        stack[top++] = nd->first;
        stack[top++] = nd->first + 1;
    }
}

bool pair_bvh_build(struct pair_bvh *b, const struct aabb *boxes, int n, struct error *err)
{
    b->n_nodes = 0;
    b->n_flat = 0;
    b->nodes = malloc(sizeof *b->nodes * (size_t)(2 * (n > 0 ? n : 1)));
    b->items = malloc(sizeof *b->items * (size_t)(n > 0 ? n : 1));
    b->boxes = malloc(sizeof *b->boxes * (size_t)(n > 0 ? n : 1));
    b->flat_items = malloc(sizeof *b->flat_items * (size_t)(n > 0 ? n : 1));
    b->flat_boxes = malloc(sizeof *b->flat_boxes * (size_t)(n > 0 ? n : 1));
    if (!b->nodes || !b->items || !b->boxes || !b->flat_items || !b->flat_boxes) {
        pair_bvh_free(b);
        return error_set(err, "out of memory for a hierarchy of %d light/portal pairs", n);
    }
    int m = 0;
    for (int i = 0; i < n; ++i) b->boxes[i] = boxes[i];
    for (int i = 0; i < n; ++i)
        if (boxes[i].lo.x <= boxes[i].hi.x && boxes[i].lo.y <= boxes[i].hi.y && boxes[i].lo.z <= boxes[i].hi.z)
            b->items[m++] = i;
    b->n_nodes = 1;
    if (m == 0) {
        b->nodes[0].box = (struct aabb){ vec3_make(1, 1, 1), vec3_make(-1, -1, -1) };
        b->nodes[0].first = 0;
        b->nodes[0].count = 0;
        return true;
    }
    struct build_ctx c = { b, boxes };
    build_node(&c, 0, 0, m);
    if (m <= PAIR_BVH_FLAT_MAX) flatten(b);
    return true;
}

void pair_bvh_free(struct pair_bvh *b)
{
    free(b->nodes);
    free(b->items);
    free(b->boxes);
    free(b->flat_items);
    free(b->flat_boxes);
    b->nodes = NULL;
    b->items = NULL;
    b->boxes = NULL;
    b->flat_items = NULL;
    b->flat_boxes = NULL;
    b->n_nodes = 0;
    b->n_flat = 0;
}

int pair_bvh_query_tree(const struct pair_bvh *b, struct vec3 p, int *out)
{
    int stack[64], top = 0, found = 0;
    if (b->n_nodes == 0 || !aabb_contains(&b->nodes[0].box, p)) return 0;
    stack[top++] = 0;
    while (top > 0) {
        const struct pair_bvh_node *nd = &b->nodes[stack[--top]];
        if (nd->count > 0) {
            for (int i = nd->first; i < nd->first + nd->count; ++i)
                if (aabb_contains(&b->boxes[b->items[i]], p)) out[found++] = b->items[i];
            continue;
        }
        for (int c = nd->first; c <= nd->first + 1; ++c)
            if (aabb_contains(&b->nodes[c].box, p) && top < 64) stack[top++] = c;
    }
    return found;
}

int pair_bvh_query(const struct pair_bvh *b, struct vec3 p, int *out)
{
    if (b->n_flat == 0) return pair_bvh_query_tree(b, p, out);
    int found = 0;
    for (int i = 0; i < b->n_flat; ++i)
        if (aabb_contains(&b->flat_boxes[i], p)) out[found++] = b->flat_items[i];
    return found;
}

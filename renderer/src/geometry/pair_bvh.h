/* pair_bvh.h: a bounding volume hierarchy over the parts of space that each
   light/portal pair can light (a portal's anti-penumbra, a light's lit half
   space, each clipped to the scene's bounds), so that a shading point finds
   the pairs that may reach it in O(log n + k) instead of testing them all.
   It only culls: the exact classification stays in antishadow.c and
   strategy.c, and it never sees the scene's geometry. */
#ifndef PAIR_BVH_H
#define PAIR_BVH_H

#include <stdbool.h>

#include "base/aabb.h"
#include "base/error.h"
#include "geometry/polygon.h"
#include "base/vec.h"

/* Bounding box of the convex region {x in box : plane_distance(p_i, x) >= 0
   for all i}; false when the region is empty. Found by clipping a polygon on
   each bounding plane by all the others: the region's vertices lie on them. */
bool aabb_of_region(const struct plane *planes, int n, struct aabb box, struct aabb *out);

struct pair_bvh_node {
    struct aabb box;
    int first; /* leaf: first index into items; inner: left child (right = left + 1) */
    int count; /* leaf: number of items; inner: 0 */
};

/* At most this many items are searched as a flat list rather than the
   tree: the traversal's stack and node tests cost more than testing a few
   boxes (measured on multi_lamp's few pairs; docs/performance.md). */
#define PAIR_BVH_FLAT_MAX 16

struct pair_bvh {
    int n_nodes;
    struct pair_bvh_node *nodes;
    int *items;         /* pair indices, grouped by leaf */
    struct aabb *boxes; /* each item's own box, by item index */
    /* With at most PAIR_BVH_FLAT_MAX items: the items in the order the
       tree's traversal meets them, and their boxes (n_flat = 0 otherwise),
       so that the flat search returns what the tree's would, in its order. */
    int n_flat;
    int *flat_items;
    struct aabb *flat_boxes;
};

/* Builds over n boxes (item i has box boxes[i]; an empty box, lo > hi, is
   never returned). */
bool pair_bvh_build(struct pair_bvh *b, const struct aabb *boxes, int n, struct error *err);
void pair_bvh_free(struct pair_bvh *b);
/* Writes the items whose box contains p into out (capacity: n items) and
   returns how many: by the flat search when there is one, else by
   pair_bvh_query_tree, which finds the same items in the same order. */
int pair_bvh_query(const struct pair_bvh *b, struct vec3 p, int *out);
/* The same by traversing the tree, whatever the number of items (the flat
   search's reference). */
int pair_bvh_query_tree(const struct pair_bvh *b, struct vec3 p, int *out);

#endif

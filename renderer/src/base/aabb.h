/* aabb.h: axis-aligned bounding boxes, closed on every side. An empty box
   has lo > hi on some axis and contains nothing. */
#ifndef AABB_H
#define AABB_H

#include <stdbool.h>

#include "base/vec.h"

struct aabb {
    struct vec3 lo, hi;
};

static inline bool aabb_contains(const struct aabb *box, struct vec3 p)
{
    return p.x >= box->lo.x && p.x <= box->hi.x && p.y >= box->lo.y && p.y <= box->hi.y && p.z >= box->lo.z &&
           p.z <= box->hi.z;
}

#endif

/* test_pair_bvh.c: the hierarchy over the pairs' lit regions. A query must
   return every item whose box holds the point, once, and no other; with
   few items (the flat search) it must also return them in the order the
   tree's traversal would, since a point's candidate order fixes which
   pair a uniform picks and images must not change with the search. */
#include "geometry/pair_bvh.h"
#include "base/rng.h"
#include "testlib.h"

enum { MAX_ITEMS = 64 };

/* Random boxes in [-1, 1]^3, some of them empty (lo > hi). */
static void random_boxes(struct rng *r, int n, struct aabb *boxes)
{
    for (int i = 0; i < n; ++i) {
        double c[3], h[3];
        for (int a = 0; a < 3; ++a) {
            c[a] = 2.0 * rng_uniform(r) - 1.0;
            h[a] = 0.05 + 0.6 * rng_uniform(r);
        }
        boxes[i].lo = vec3_make(c[0] - h[0], c[1] - h[1], c[2] - h[2]);
        boxes[i].hi = vec3_make(c[0] + h[0], c[1] + h[1], c[2] + h[2]);
        if (i % 7 == 3) { /* empty: lights nothing */
            struct vec3 t = boxes[i].lo;
            boxes[i].lo = boxes[i].hi;
            boxes[i].hi = t;
        }
    }
}

static void check_counts(int n, const struct aabb *boxes, struct vec3 p, const int *got, int n_got, int *missing)
{
    int seen[MAX_ITEMS] = { 0 };
    for (int k = 0; k < n_got; ++k) {
        CHECK(got[k] >= 0 && got[k] < n);
        if (got[k] >= 0 && got[k] < n) ++seen[got[k]];
    }
    for (int i = 0; i < n; ++i) {
        bool empty = boxes[i].lo.x > boxes[i].hi.x;
        bool holds = !empty && aabb_contains(&boxes[i], p);
        if (seen[i] != (holds ? 1 : 0)) ++*missing;
    }
}

static void test_query_finds_exactly_the_boxes(void)
{
    static const int sizes[] = { 1, 2, 5, 6, 16, 17, 40, 64 };
    struct rng r;
    rng_seed(&r, 4242, 0, 0);
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; ++s) {
        int n = sizes[s];
        struct aabb boxes[MAX_ITEMS];
        random_boxes(&r, n, boxes);
        struct pair_bvh b;
        struct error err;
        CHECK(pair_bvh_build(&b, boxes, n, &err));
        int nonempty = 0;
        for (int i = 0; i < n; ++i) nonempty += boxes[i].lo.x <= boxes[i].hi.x;
        /* The flat search is used exactly up to its limit. */
        CHECK_MSG(b.n_flat == (nonempty <= PAIR_BVH_FLAT_MAX ? nonempty : 0), "n %d: n_flat %d of %d items", n,
                  b.n_flat, nonempty);
        int wrong = 0, order = 0, hits = 0;
        for (int t = 0; t < 2000; ++t) {
            struct vec3 p =
                vec3_make(2.4 * rng_uniform(&r) - 1.2, 2.4 * rng_uniform(&r) - 1.2, 2.4 * rng_uniform(&r) - 1.2);
            int got[MAX_ITEMS], want[MAX_ITEMS];
            int n_got = pair_bvh_query(&b, p, got), n_want = pair_bvh_query_tree(&b, p, want);
            hits += n_got;
            check_counts(n, boxes, p, got, n_got, &wrong);
            if (n_got != n_want || memcmp(got, want, sizeof got[0] * (size_t)n_got) != 0) ++order;
        }
        CHECK_MSG(wrong == 0, "n %d: %d items found a wrong number of times", n, wrong);
        CHECK_MSG(order == 0, "n %d: %d queries differ from the tree's traversal", n, order);
        CHECK_MSG(hits > 0, "n %d: no query found anything (the test says nothing)", n);
        pair_bvh_free(&b);
    }
}

static void test_no_items(void)
{
    struct aabb empty = { vec3_make(1, 1, 1), vec3_make(-1, -1, -1) };
    struct pair_bvh b;
    struct error err;
    CHECK(pair_bvh_build(&b, &empty, 1, &err));
    int out[1];
    CHECK(pair_bvh_query(&b, vec3_make(0, 0, 0), out) == 0);
    pair_bvh_free(&b);
    CHECK(pair_bvh_build(&b, NULL, 0, &err));
    CHECK(pair_bvh_query(&b, vec3_make(0, 0, 0), out) == 0);
    pair_bvh_free(&b);
}

static const struct test_case pair_bvh_tests[] = {
    { "query_finds_exactly_the_boxes", test_query_finds_exactly_the_boxes },
    { "no_items", test_no_items },
};

TEST_MAIN(pair_bvh_tests)

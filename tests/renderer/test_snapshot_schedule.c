/* test_snapshot_schedule.c: when snapshots fall due (snapshot_schedule.h),
   for each kind of schedule alone and combined: the first point, points
   passed by one slow pass (one snapshot, not several), coincident points
   of two kinds (one snapshot), the cumulative schedule of a resumed
   render, and the saturation of doubling sample counts near INT64_MAX.
   Time and spp are given, never read: every case is exact. */
#include <limits.h>
#include <math.h>
#include <string.h>

#include "render/snapshot_schedule.h"
#include "testlib.h"

static struct snapshot_schedule none(void)
{
    struct snapshot_schedule s;
    memset(&s, 0, sizeof s);
    return s;
}

static void test_off(void)
{
    struct snapshot_schedule s = none();
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(!snapshot_schedule_due(&c, 0.0, 0));
    CHECK(!snapshot_schedule_due(&c, 1e9, INT64_MAX - 1));
    CHECK(snapshot_schedule_next_s(&c) == INFINITY);
    CHECK(snapshot_schedule_next_spp(&c) == INT64_MAX);
}

static void test_every(void)
{
    struct snapshot_schedule s = none();
    s.every_s = 0.5;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_s(&c) == 0.5);
    CHECK(snapshot_schedule_next_spp(&c) == INT64_MAX);
    CHECK(!snapshot_schedule_due(&c, 0.49, 1));
    CHECK(snapshot_schedule_due(&c, 0.5, 2)); /* at the point itself */
    CHECK(snapshot_schedule_next_s(&c) == 1.0);
    CHECK(!snapshot_schedule_due(&c, 0.9, 3));
    /* One slow pass over three points: one snapshot, then the next point after it. */
    CHECK(snapshot_schedule_due(&c, 2.2, 4));
    CHECK(snapshot_schedule_next_s(&c) == 2.5);
    CHECK(!snapshot_schedule_due(&c, 2.3, 5));
}

static void test_doubling(void)
{
    struct snapshot_schedule s = none();
    s.doubling_s = 0.25;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(!snapshot_schedule_due(&c, 0.2, 1));
    CHECK(snapshot_schedule_due(&c, 0.25, 2));
    CHECK(snapshot_schedule_next_s(&c) == 0.5);
    CHECK(!snapshot_schedule_due(&c, 0.3, 3));
    CHECK(snapshot_schedule_due(&c, 0.6, 4));
    CHECK(snapshot_schedule_next_s(&c) == 1.0);
    CHECK(snapshot_schedule_due(&c, 3.0, 5)); /* passes 1 and 2 at once */
    CHECK(snapshot_schedule_next_s(&c) == 4.0);
}

static void test_times(void)
{
    struct snapshot_schedule s = none();
    s.n_times = 3;
    s.times_s[0] = 0.1;
    s.times_s[1] = 0.2;
    s.times_s[2] = 0.3;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_s(&c) == 0.1);
    CHECK(!snapshot_schedule_due(&c, 0.05, 1));
    CHECK(snapshot_schedule_due(&c, 0.25, 2)); /* 0.1 and 0.2 together: one */
    CHECK(snapshot_schedule_next_s(&c) == 0.3);
    CHECK(!snapshot_schedule_due(&c, 0.29, 3));
    CHECK(snapshot_schedule_due(&c, 0.3, 4));
    CHECK(snapshot_schedule_next_s(&c) == INFINITY);
    CHECK(!snapshot_schedule_due(&c, 100.0, 5));
}

static void test_every_spp(void)
{
    struct snapshot_schedule s = none();
    s.every_spp = 4;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_spp(&c) == 4);
    CHECK(snapshot_schedule_next_s(&c) == INFINITY);
    int64_t due[12] = { 0 };
    for (int64_t spp = 1; spp <= 12; ++spp) due[spp - 1] = snapshot_schedule_due(&c, 0.0, spp);
    for (int64_t spp = 1; spp <= 12; ++spp) CHECK_MSG(due[spp - 1] == (spp % 4 == 0), "spp %lld", (long long)spp);
    CHECK(snapshot_schedule_next_spp(&c) == 16);
}

static void test_doubling_spp(void)
{
    struct snapshot_schedule s = none();
    s.doubling_spp = 1;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    /* The first pass already: the early points of an error curve. */
    int n = 0;
    for (int64_t spp = 1; spp <= 64; ++spp) {
        bool d = snapshot_schedule_due(&c, 0.0, spp);
        CHECK_MSG(d == ((spp & (spp - 1)) == 0), "spp %lld", (long long)spp);
        n += d;
    }
    CHECK(n == 7); /* 1, 2, 4, ..., 64 */
    CHECK(snapshot_schedule_next_spp(&c) == 128);
}

static void test_spps(void)
{
    struct snapshot_schedule s = none();
    s.n_spps = 2;
    s.spps[0] = 3;
    s.spps[1] = 7;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_spp(&c) == 3);
    CHECK(!snapshot_schedule_due(&c, 0.0, 2));
    CHECK(snapshot_schedule_due(&c, 0.0, 3));
    CHECK(snapshot_schedule_next_spp(&c) == 7);
    CHECK(!snapshot_schedule_due(&c, 0.0, 6));
    CHECK(snapshot_schedule_due(&c, 0.0, 7));
    CHECK(snapshot_schedule_next_spp(&c) == INT64_MAX);
    CHECK(!snapshot_schedule_due(&c, 0.0, 8));
}

/* Coincident points of different kinds give one snapshot, and every kind
   moves past them. */
static void test_coincident(void)
{
    struct snapshot_schedule s = none();
    s.every_s = 1.0;
    s.n_times = 1;
    s.times_s[0] = 1.0;
    s.every_spp = 4;
    s.doubling_spp = 2;
    s.n_spps = 1;
    s.spps[0] = 4;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_s(&c) == 1.0);
    CHECK(snapshot_schedule_next_spp(&c) == 2);
    CHECK(snapshot_schedule_due(&c, 0.1, 2)); /* doubling_spp's first */
    CHECK(!snapshot_schedule_due(&c, 0.2, 3));
    CHECK(snapshot_schedule_due(&c, 0.3, 4)); /* every_spp, doubling_spp and the list at once */
    CHECK(snapshot_schedule_next_spp(&c) == 8);
    CHECK(!snapshot_schedule_due(&c, 0.9, 5));
    CHECK(snapshot_schedule_due(&c, 1.0, 6)); /* every and the time list at once */
    CHECK(snapshot_schedule_next_s(&c) == 2.0);
    CHECK(!snapshot_schedule_due(&c, 1.5, 7));
    CHECK(snapshot_schedule_due(&c, 1.6, 8)); /* by sample count alone */
    CHECK(snapshot_schedule_next_s(&c) == 2.0 && snapshot_schedule_next_spp(&c) == 12);
}

/* Time and sample schedules together: either kind makes a snapshot due. */
static void test_time_and_spp(void)
{
    struct snapshot_schedule s = none();
    s.doubling_s = 0.5;
    s.every_spp = 3;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(!snapshot_schedule_due(&c, 0.1, 1));
    CHECK(snapshot_schedule_due(&c, 0.4, 3)); /* spp */
    CHECK(snapshot_schedule_due(&c, 0.6, 4)); /* time */
    CHECK(!snapshot_schedule_due(&c, 0.8, 5));
    CHECK(snapshot_schedule_next_s(&c) == 1.0 && snapshot_schedule_next_spp(&c) == 6);
}

/* A resumed render calls due once with its saved progress: what fell due
   before is consumed, and the schedule goes on from there. */
static void test_resumed(void)
{
    struct snapshot_schedule s = none();
    s.every_spp = 4;
    s.every_s = 1.0;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    snapshot_schedule_due(&c, 2.5, 10);
    CHECK(snapshot_schedule_next_spp(&c) == 12);
    CHECK(snapshot_schedule_next_s(&c) == 3.0);
    CHECK(!snapshot_schedule_due(&c, 2.7, 11));
    CHECK(snapshot_schedule_due(&c, 2.9, 12));
}

/* Doubling sample counts saturate at INT64_MAX instead of overflowing
   (the sanitizer build would stop on a signed overflow). */
static void test_spp_limit(void)
{
    struct snapshot_schedule s = none();
    s.doubling_spp = INT_MAX;
    s.every_spp = INT_MAX;
    struct snapshot_cursor c;
    snapshot_schedule_start(&c, &s);
    CHECK(snapshot_schedule_next_spp(&c) == INT_MAX);
    CHECK(!snapshot_schedule_due(&c, 0.0, (int64_t)INT_MAX - 1));
    CHECK(snapshot_schedule_due(&c, 0.0, INT_MAX));
    CHECK(snapshot_schedule_next_spp(&c) == 2 * (int64_t)INT_MAX);
    struct snapshot_schedule d = none();
    d.doubling_spp = INT_MAX;
    snapshot_schedule_start(&c, &d);
    CHECK(snapshot_schedule_due(&c, 0.0, INT64_MAX / 2 + 1));
    CHECK(snapshot_schedule_next_spp(&c) == (int64_t)INT_MAX << 32); /* the last doubling that fits */
    snapshot_schedule_start(&c, &d);
    CHECK(snapshot_schedule_due(&c, 0.0, INT64_MAX - 1));
    CHECK(snapshot_schedule_next_spp(&c) == INT64_MAX);
    CHECK(!snapshot_schedule_due(&c, 0.0, INT64_MAX - 1));
}

static const struct test_case tests[] = {
    { "off", test_off },         { "every", test_every },           { "doubling", test_doubling },
    { "times", test_times },     { "every_spp", test_every_spp },   { "doubling_spp", test_doubling_spp },
    { "spps", test_spps },       { "coincident", test_coincident }, { "time_and_spp", test_time_and_spp },
    { "resumed", test_resumed }, { "spp_limit", test_spp_limit },
};

TEST_MAIN(tests)

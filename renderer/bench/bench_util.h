/* bench_util.h: clocks, medians and argument helpers shared by the C
   micro-benchmarks (raw_embree.c, micro.c). Header-only: each benchmark is
   one translation unit linked against librender.a. */
#ifndef BENCH_UTIL_H
#define BENCH_UTIL_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "config/config.h"
#include "base/timing.h"

/* The clocks are the renderer's own (timing.h): timing_now_s for wall time,
   timing_thread_cpu_s for the calling thread's CPU time, which on a shared
   machine excludes the time the thread spent descheduled, so per-call
   costs stay comparable when other work competes for the cores. */

static int bench_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of v[0..n) (sorts v in place). */
static inline double bench_median(double *v, int n)
{
    if (n <= 0) return 0.0;
    qsort(v, (size_t)n, sizeof *v, bench_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Command-line overrides in the renderer's --set KEY=VALUE form. */
struct bench_overrides {
    int n;
    struct config_override items[32];
    char text[32][256];
};

/* Consumes "--set KEY=VALUE" at argv[*i]; true when it did. Exits on a
   malformed or excess override (benchmark programs may exit: they are mains). */
static inline int bench_take_set(struct bench_overrides *ov, int argc, char **argv, int *i)
{
    if (strcmp(argv[*i], "--set") != 0) return 0;
    if (*i + 1 >= argc || ov->n >= 32 || !strchr(argv[*i + 1], '=')) {
        fprintf(stderr, "%s: --set needs KEY=VALUE (at most 32)\n", argv[0]);
        exit(2);
    }
    char *kv = ov->text[ov->n];
    snprintf(kv, sizeof ov->text[0], "%s", argv[++*i]);
    char *eq = strchr(kv, '=');
    *eq = '\0';
    ov->items[ov->n].path = kv;
    ov->items[ov->n].value = eq + 1;
    ++ov->n;
    return 1;
}

#endif

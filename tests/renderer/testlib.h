/* testlib.h: a minimal test runner. Each test file lists its tests in one
   table and ends with TEST_MAIN(table); the runner prints one line per test
   and a closing "N passed, N failed" line. An argument runs only the tests
   whose name contains it; one that matches no test is an error (exit 2). */
#ifndef TESTLIB_H
#define TESTLIB_H

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct test_case {
    const char *name;
    void (*run)(void);
};

extern int test_failures_; /* failures within the running test */

/* Bit-for-bit equality of doubles: a differing sign of zero or NaN payload
   counts as a difference. */
static inline bool same_bits(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            fprintf(stderr, "  %s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond);                                 \
            ++test_failures_;                                                                                          \
        }                                                                                                              \
    } while (0)

#define CHECK_MSG(cond, ...)                                                                                           \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            fprintf(stderr, "  %s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond);                                 \
            fprintf(stderr, __VA_ARGS__);                                                                              \
            fputc('\n', stderr);                                                                                       \
            ++test_failures_;                                                                                          \
        }                                                                                                              \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                                                          \
    do {                                                                                                               \
        double a_ = (a), b_ = (b), t_ = (tol);                                                                         \
        if (!(fabs(a_ - b_) <= t_)) {                                                                                  \
            fprintf(stderr, "  %s:%d: |%s - %s| = |%.9g - %.9g| = %.3g > %.3g\n", __FILE__, __LINE__, #a, #b, a_, b_,  \
                    fabs(a_ - b_), t_);                                                                                \
            ++test_failures_;                                                                                          \
        }                                                                                                              \
    } while (0)

int test_main(const struct test_case *cases, int n, int argc, char **argv);

#define TEST_MAIN(table)                                                                                               \
    int test_failures_ = 0;                                                                                            \
    int main(int argc, char **argv)                                                                                    \
    {                                                                                                                  \
        return test_main(table, (int)(sizeof(table) / sizeof((table)[0])), argc, argv);                                \
    }                                                                                                                  \
    int test_main(const struct test_case *cases, int n, int argc, char **argv)                                         \
    {                                                                                                                  \
        int passed = 0, failed = 0;                                                                                    \
        for (int i = 0; i < n; ++i) {                                                                                  \
            if (argc > 1 && !strstr(cases[i].name, argv[1])) continue;                                                 \
            test_failures_ = 0;                                                                                        \
            cases[i].run();                                                                                            \
            if (test_failures_) {                                                                                      \
                ++failed;                                                                                              \
                printf("FAIL %s\n", cases[i].name);                                                                    \
            } else {                                                                                                   \
                ++passed;                                                                                              \
                printf("ok   %s\n", cases[i].name);                                                                    \
            }                                                                                                          \
            fflush(stdout);                                                                                            \
        }                                                                                                              \
        printf("%d passed, %d failed\n", passed, failed);                                                              \
        if (argc > 1 && passed + failed == 0) {                                                                        \
            /* A filter that runs nothing must not pass for a green run. */                                            \
            fprintf(stderr, "%s: no test matches \"%s\"; tests:", argv[0], argv[1]);                                   \
            for (int i = 0; i < n; ++i) fprintf(stderr, " %s", cases[i].name);                                         \
            fputc('\n', stderr);                                                                                       \
            return 2;                                                                                                  \
        }                                                                                                              \
        return failed ? 1 : 0;                                                                                         \
    }

#endif

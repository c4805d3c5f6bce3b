/* timing.h: the two clocks the render loop and the snapshot writer read:
   monotonic wall time and the calling thread's CPU time, in seconds. Owns
   nothing else; the schedule of snapshots must not read them
   (snapshot_schedule.h takes the time as an argument). */
#ifndef TIMING_H
#define TIMING_H

#include <time.h>

/* Monotonic wall time, from an arbitrary origin. */
static inline double timing_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the calling thread: what a worker spends rendering, whatever
   else runs on the machine or in the process (the Embree builder's
   threads, the EXR writer); 0 when the clock is not available. */
static inline double timing_thread_cpu_s(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#endif

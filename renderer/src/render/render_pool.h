/* render_pool.h: the render threads, private to the render layer: each
   takes whole film rows of a pass in turn, renders them into the film and
   waits for the next pass. Pixels are seeded per (pixel, pass), so which
   thread renders a row never changes its bits. */
#ifndef RENDER_POOL_H
#define RENDER_POOL_H

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

#include "base/error.h"
#include "config/config.h"
#include "render/aov.h"
#include "render/film.h"
#include "sampling/integrator.h"
#include "sampling/sampler.h"
#include "sampling/strategy.h"
#include "scene/camera.h"
#include "scene/ray_stream.h"

/* Shared between the main thread and the workers; guarded by `lock`. */
struct pass_control {
    pthread_mutex_t lock;
    pthread_cond_t start, done;
    int64_t generation; /* incremented to start a pass */
    int next_row;
    int active; /* workers still in the current pass */
    bool quit;
    int64_t pass;                  /* index of the pass being rendered */
    bool faults;                   /* test hooks: one of the two below is on */
    int64_t fault_nonfinite_every; /* test hook: poison ~1 sample in N (0: off) */
    bool fault_biased;             /* test hook: every sample times fault_bias */
    double fault_bias;
    uint64_t nonfinite;
    struct integrator_stats stats;
    double cpu_s; /* CPU time the workers spent rendering passes (not spinning between them) */
};

struct worker {
    pthread_t thread;
    struct pass_control *pc;
    const struct config *cfg;
    const struct camera *camera;
    const struct integrator *integrator;
    struct film *film;
    struct strategy_scratch scratch;
    /* One film row in flight: each pixel's sampler, camera ray and its
       hit, so that the row's camera rays are traced as one stream. */
    struct sampler *row_smp;
    struct vec3 *row_dir;
    struct ray_stream row_rays; /* the camera rays, as Embree traces them */
    struct hit *row_hit;
    bool *row_found;
    struct rgb *row_color;
    struct integrator_row *row;
    /* The region AOV (NULL when off): its classifier, and the row's classes. */
    const struct aov_classifier *aov;
    struct aov_scratch aov_scratch;
    unsigned char *row_class;
};

/* Starts n_threads render threads, each a copy of proto with its own
   scratch and row buffers; stops at the first failure, with *started the
   threads running (render_pool_stop joins them). */
bool render_pool_start(struct pass_control *pc, struct worker **out, int *started, int n_threads,
                       const struct worker *proto, const struct strategy *strategy, struct error *err);
/* Renders pass `pass` on the n started threads; returns when it is done. */
void render_pool_run_pass(struct pass_control *pc, int64_t pass, int n);
/* Stops and joins the started threads and frees the workers. */
void render_pool_stop(struct pass_control *pc, struct worker *workers, int started);

#endif

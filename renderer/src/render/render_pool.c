/* render_pool.c: the render threads (render_pool.h): a worker's row
   buffers, one film row from camera rays to the film, and the pool's
   start, passes and stop. */
#include "render/render_pool.h"

#include "base/fastmath.h"

#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include "base/rng.h"
#include "base/timing.h"

static bool worker_alloc_row(struct worker *w, int width, struct error *err)
{
    size_t n = (size_t)width;
    w->row_smp = malloc(n * sizeof *w->row_smp);
    w->row_dir = malloc(n * sizeof *w->row_dir);
    w->row_hit = malloc(n * sizeof *w->row_hit);
    w->row_found = malloc(n * sizeof *w->row_found);
    w->row_color = malloc(n * sizeof *w->row_color);
    if (!w->row_smp || !w->row_dir || !w->row_hit || !w->row_found || !w->row_color)
        return error_set(err, "out of memory for a film row of %d pixels", width);
    if (!ray_stream_init(&w->row_rays, width, err)) return false;
    w->row = integrator_row_create(width, err);
    if (!w->row) return false;
    if (!w->aov) return true;
    w->row_class = malloc(n * sizeof *w->row_class);
    if (!w->row_class) return error_set(err, "out of memory for a film row of %d pixels", width);
    return aov_scratch_init(w->aov, &w->aov_scratch, err);
}

static void worker_free(struct worker *w)
{
    strategy_scratch_free(&w->scratch);
    free(w->row_smp);
    free(w->row_dir);
    ray_stream_free(&w->row_rays);
    free(w->row_hit);
    free(w->row_found);
    free(w->row_color);
    integrator_row_destroy(w->row);
    w->row = NULL;
    free(w->row_class);
    w->row_class = NULL;
    aov_scratch_free(&w->aov_scratch);
}

/* Seeds the random stream of each pixel of film row y and draws its camera
   ray. One stream per (pixel, pass): pixels never depend on which thread
   rendered them, so fixed-spp renders are bit-identical. A vectorised loop:
   the hash chains of neighbouring pixels run side by side. The independent
   sampler's jitter, as sampler_camera would draw it. */
FM_SIMD_CLONES static void camera_row(const struct camera *c, uint64_t seed, int y, int64_t pass, int width,
                                      struct sampler *smp, struct vec3 *dir)
{
    uint64_t first = (uint64_t)y * (uint64_t)width;
#pragma omp simd
    for (int x = 0; x < width; ++x) {
        struct rng r = rng_seeded(seed, first + (uint64_t)x, (uint64_t)pass);
        struct rng_draw jx = rng_draw(r.state, r.inc), jy = rng_draw(jx.state, r.inc);
        smp[x].rng.state = jy.state;
        smp[x].rng.inc = r.inc;
        smp[x].kind = SAMPLER_INDEPENDENT;
        smp[x].index = (uint32_t)pass;
        smp[x].index_reversed = 0;
        smp[x].pixel_key = 0;
        dir[x] = camera_ray(c, x + jx.u, y + jy.u);
    }
}

/* camera_row for any other sampler, one pixel at a time. */
static void camera_row_sampled(const struct camera *c, enum sampler_kind kind, uint64_t seed, int y, int64_t pass,
                               int width, struct sampler *smp, struct vec3 *dir)
{
    uint64_t first = (uint64_t)y * (uint64_t)width;
    for (int x = 0; x < width; ++x) {
        double u[2];
        sampler_start(&smp[x], kind, seed, first + (uint64_t)x, pass);
        sampler_camera(&smp[x], u);
        dir[x] = camera_ray(c, x + u[0], y + u[1]);
    }
}

/* The test hooks on a row's samples: every sample times fault_bias, then
   about one in fault_nonfinite_every poisoned, chosen by its pixel's
   random state. */
static void inject_faults(const struct pass_control *pc, const struct sampler *smp, struct rgb *color, int width)
{
    if (pc->fault_biased)
        for (int x = 0; x < width; ++x) color[x] = rgb_scale(color[x], pc->fault_bias);
    for (int x = 0; pc->fault_nonfinite_every > 0 && x < width; ++x)
        if (rng_mix64(smp[x].rng.state) % (uint64_t)pc->fault_nonfinite_every == 0) color[x].g = NAN;
}

static void render_row(struct worker *w, int y, int64_t pass, struct integrator_stats *stats, uint64_t *nonfinite)
{
    const struct config *cfg = w->cfg;
    if (cfg->render.sampler == SAMPLER_INDEPENDENT)
        camera_row(w->camera, cfg->render.seed, y, pass, cfg->width, w->row_smp, w->row_dir);
    else
        camera_row_sampled(w->camera, cfg->render.sampler, cfg->render.seed, y, pass, cfg->width, w->row_smp,
                           w->row_dir);
    scene_intersect_coherent(w->integrator->scene, w->camera->origin, w->row_dir, cfg->width, &w->row_rays, w->row_hit,
                             w->row_found);
    integrator_radiance_row(w->integrator, w->row, &w->scratch, w->row_dir, w->row_hit, w->row_found, cfg->width,
                            w->row_smp, w->row_color, stats);
    /* The test hooks cost one branch per row when off. */
    if (w->pc->faults) inject_faults(w->pc, w->row_smp, w->row_color, cfg->width);
    int dropped = 0;
    for (int x = 0; x < cfg->width; ++x) dropped += !rgb_is_finite(w->row_color[x]);
    if (w->aov) {
        /* From the camera hits alone: no random numbers, no film state, so
           the radiance channels are the same bits with the AOV on or off.
           A dropped sample is dropped here too, so that the classes of a
           pixel sum to its sample count. */
        aov_classify_row(w->aov, &w->aov_scratch, w->row_dir, w->row_hit, w->row_found, cfg->width, w->row_class);
        for (int x = 0; x < cfg->width; ++x)
            if (rgb_is_finite(w->row_color[x])) film_add_region(w->film, x, y, w->row_class[x]);
    }
    /* A NaN/Inf sample would poison the pixel forever: it is dropped (the
       pixel keeps its own sample count) and counted, and the count is
       reported in the JSON stream and the EXR header. */
    if (dropped == 0) {
        film_add_row(w->film, y, w->row_color, cfg->width);
        return;
    }
    *nonfinite += (uint64_t)dropped;
    for (int x = 0; x < cfg->width; ++x)
        if (rgb_is_finite(w->row_color[x])) film_add(w->film, x, y, w->row_color[x]);
}

/* How long a worker that finished its part of a pass keeps its core busy
   waiting for the next pass before it sleeps. On a virtual machine a core
   left idle halts, and waking it again cost every pass and worker a
   visible part of a lampshade render at 2 threads; spinning, the wait is
   far shorter (docs/performance.md). Longer than the end of a pass
   usually takes (the
   last rows, the main thread's turn), short enough not to matter to other
   processes between renders. */
#define POOL_SPIN_S 2e-3

/* Waits, without sleeping, until the pass generation moves on from `seen`
   or the pool quits, or POOL_SPIN_S passes. It yields the processor as it
   goes: the main thread must get a core to start the next pass, and the
   last worker of a pass spins too. */
static void pool_spin(const struct pass_control *pc, int64_t seen)
{
    double t0 = timing_now_s();
    while (__atomic_load_n(&pc->generation, __ATOMIC_ACQUIRE) == seen &&
           !__atomic_load_n(&pc->quit, __ATOMIC_ACQUIRE)) {
        sched_yield();
        if (timing_now_s() - t0 > POOL_SPIN_S) return;
    }
}

static void *worker_main(void *arg)
{
    struct worker *w = arg;
    struct pass_control *pc = w->pc;
    /* Denormals are never needed here, and each operation on one is far
       slower than on a normal number. */
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    int64_t seen = 0;
    pthread_mutex_lock(&pc->lock);
    for (;;) {
        if (pc->generation == seen && !pc->quit) {
            pthread_mutex_unlock(&pc->lock);
            pool_spin(pc, seen);
            pthread_mutex_lock(&pc->lock);
        }
        while (pc->generation == seen && !pc->quit) pthread_cond_wait(&pc->start, &pc->lock);
        if (pc->quit) break;
        seen = pc->generation;
        int64_t pass = pc->pass;
        struct integrator_stats stats = { 0, 0, 0, 0, 0 };
        uint64_t nonfinite = 0;
        /* The pass's CPU time alone: a spin before it may overlap the main
           thread's snapshot pause, which is not render time. */
        double cpu0 = timing_thread_cpu_s();
        for (;;) {
            int y = pc->next_row < w->cfg->height ? pc->next_row++ : -1;
            if (y < 0) break;
            pthread_mutex_unlock(&pc->lock);
            render_row(w, y, pass, &stats, &nonfinite);
            pthread_mutex_lock(&pc->lock);
        }
        integrator_stats_add(&pc->stats, &stats);
        pc->nonfinite += nonfinite;
        pc->cpu_s += timing_thread_cpu_s() - cpu0;
        if (--pc->active == 0) pthread_cond_signal(&pc->done);
    }
    pthread_mutex_unlock(&pc->lock);
    return NULL;
}

/* Starts the render threads, each with its own scratch and row buffers;
   stops at the first failure (pool_stop joins those started). */
bool render_pool_start(struct pass_control *pc, struct worker **out, int *started, int n_threads,
                       const struct worker *proto, const struct strategy *strategy, struct error *err)
{
    struct worker *workers = *out = calloc((size_t)n_threads, sizeof *workers);
    if (!workers) return error_set(err, "out of memory for %d threads", n_threads);
    for (int i = 0; i < n_threads; ++i) {
        struct worker *w = &workers[i];
        *w = *proto;
        w->pc = pc;
        if (!strategy_scratch_init(strategy, &w->scratch, err) || !worker_alloc_row(w, proto->cfg->width, err)) {
            worker_free(w);
            return false;
        }
        if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
            worker_free(w);
            return error_set(err, "cannot start render thread %d", i);
        }
        ++*started;
    }
    return true;
}

/* Renders pass `pass` on the n started threads; returns when it is done. */
void render_pool_run_pass(struct pass_control *pc, int64_t pass, int n)
{
    pthread_mutex_lock(&pc->lock);
    pc->pass = pass;
    pc->next_row = 0;
    pc->active = n;
    __atomic_store_n(&pc->generation, pc->generation + 1, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&pc->start);
    while (pc->active > 0) pthread_cond_wait(&pc->done, &pc->lock);
    pthread_mutex_unlock(&pc->lock);
}

void render_pool_stop(struct pass_control *pc, struct worker *workers, int started)
{
    pthread_mutex_lock(&pc->lock);
    __atomic_store_n(&pc->quit, true, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&pc->start);
    pthread_mutex_unlock(&pc->lock);
    for (int i = 0; i < started; ++i) {
        pthread_join(workers[i].thread, NULL);
        worker_free(&workers[i]);
    }
    free(workers);
}

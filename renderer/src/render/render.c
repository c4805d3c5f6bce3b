/* render.c: the render loop, its thread pool and the final image (see
   render.h). */
#include "render/render.h"

#include "base/fastmath.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include "render/aov.h"
#include "scene/camera.h"
#include "render/film.h"
#include "render/render_events.h"
#include "base/rng.h"
#include "sampling/sampler.h"
#include "render/snapshot_schedule.h"
#include "render/snapshot_writer.h"
#include "sampling/strategy.h"
#include "base/timing.h"
#include "base/version.h"

/* The one piece of process-wide state: set by the signal handler, read by
   the render loop between passes. */
static volatile sig_atomic_t interrupt_requested = 0;

static void on_signal(int sig)
{
    (void)sig;
    interrupt_requested = 1;
}

void render_catch_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

/* ---- passes ------------------------------------------------------------ */

/* Shared between the main thread and the workers; guarded by `lock`. */
struct pass_control {
    pthread_mutex_t lock;
    pthread_cond_t start, done;
    int64_t generation; /* incremented to start a pass */
    int next_row;
    int active; /* workers still in the current pass */
    bool quit;
    int64_t pass;                  /* index of the pass being rendered */
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
    if (w->pc->fault_biased)
        for (int x = 0; x < cfg->width; ++x) w->row_color[x] = rgb_scale(w->row_color[x], w->pc->fault_bias);
    int dropped = 0;
    for (int x = 0; x < cfg->width; ++x) {
        struct rgb *c = &w->row_color[x];
        if (w->pc->fault_nonfinite_every > 0 &&
            rng_mix64(w->row_smp[x].rng.state) % (uint64_t)w->pc->fault_nonfinite_every == 0)
            c->g = NAN;
        dropped += !rgb_is_finite(*c);
    }
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
   left idle halts, and waking it again took 0.04-0.6 ms per pass and
   worker, 1-7% of a 128-spp lampshade render at 2 threads; spinning, the
   wait is below 0.03 ms. Longer than the end of a pass usually takes (the
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
    /* Denormals are never needed here and cost ~100x per operation. */
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
static bool pool_start(struct pass_control *pc, struct worker **out, int *started, int n_threads,
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
static void pool_run_pass(struct pass_control *pc, int64_t pass, int n)
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

static void pool_stop(struct pass_control *pc, struct worker *workers, int started)
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

static int thread_count(const struct render_desc *rd)
{
    if (rd->threads > 0) return rd->threads;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

/* ---- test hooks ------------------------------------------------------------ */

bool render_faults_parse(const char *nonfinite, const char *bias, struct render_faults *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    out->bias_factor = 1.0;
    if (nonfinite) out->nonfinite_every = atoll(nonfinite);
    if (!bias) return true;
    const char *colon = strchr(bias, ':');
    int k = 0;
    while (colon && k < STRATEGY_COUNT &&
           (strlen(strategy_names[k]) != (size_t)(colon - bias) ||
            strncmp(strategy_names[k], bias, (size_t)(colon - bias))))
        ++k;
    char *end = NULL;
    errno = 0;
    double factor = colon ? strtod(colon + 1, &end) : 0.0;
    if (!colon || k == STRATEGY_COUNT || end == colon + 1 || *end || errno || !isfinite(factor) || factor < 0.0)
        return error_set(err,
                         "PORTAL_LIGHTS_FAULT_BIAS=%s: expected STRATEGY:FACTOR (a strategy name such as light, and "
                         "a finite number >= 0)",
                         bias);
    out->bias = true;
    out->bias_strategy = (enum strategy_kind)k;
    out->bias_factor = factor;
    return true;
}

/* ---- the render -------------------------------------------------------------- */

/* What the render has done so far, beyond the film and the workers'
   counters: restored from a state when resuming, saved in it at the end. */
struct progress {
    int64_t pass;     /* passes done */
    double elapsed;   /* render clock */
    double last_pass; /* duration of the latest pass (0 before one) */
    int snapshots;    /* timed snapshots written */
    /* What the snapshot schedule costs the main thread: wall time with the
       render threads paused, and CPU time (the writer's is wr.cpu_s). */
    double pause_s, pause_cpu_s;
    bool interrupted;
};

/* Everything one render_run owns. */
struct render {
    const struct config *cfg;
    struct strategy strategy;
    struct integrator integrator;
    struct camera camera;
    struct film film;
    struct aov_classifier aov;
    bool have_aov;
    struct snapshot_writer wr;
    struct pass_control pc;
    struct worker *workers;
    int started; /* render threads running */
    struct progress pr;
};

/* The strategy, integrator, camera and film (the state's, when resuming).
   On failure nothing is left to free. */
static bool render_init(struct render *r, const struct render_options *opt, struct error *err)
{
    const struct config *cfg = opt->cfg;
    memset(r, 0, sizeof *r);
    r->cfg = cfg;
    if (!strategy_init(&r->strategy, opt->scene, &cfg->render, err)) return false;
    integrator_init(&r->integrator, &cfg->render, opt->scene, &r->strategy);
    camera_init(&r->camera, &cfg->camera, cfg->width, cfg->height);
    if (opt->start) {
        r->film = opt->start->film;
        memset(&opt->start->film, 0, sizeof opt->start->film);
    } else if (!film_init(&r->film, cfg->width, cfg->height, err)) {
        strategy_free(&r->strategy);
        return false;
    }
    return true;
}

/* `film` has been moved out of st already. */
static void progress_restore(struct progress *pr, struct pass_control *pc, const struct film_state *st,
                             const struct film *film)
{
    pr->pass = film->passes;
    pr->elapsed = st->render_time_s;
    pr->snapshots = st->snapshots;
    pr->pause_s = st->snapshot_pause_s;
    pr->pause_cpu_s = st->snapshot_cpu_s;
    pc->stats = st->stats;
    pc->nonfinite = st->nonfinite_samples;
    pc->cpu_s = st->render_cpu_s;
}

/* The writer's image, the region AOV, the pass control with the fault
   hooks, and the progress of a resumed render. render_free undoes it,
   whether it succeeded or not. */
static bool render_prepare(struct render *r, const struct render_options *opt, struct error *err)
{
    const struct render_desc *rd = &r->cfg->render;
    bool ok = snapshot_writer_init(&r->wr, r->cfg->width, r->cfg->height, rd->aov_region, opt->json, err);
    if (ok && rd->aov_region) {
        ok = aov_classifier_init(&r->aov, opt->scene, err);
        r->have_aov = ok;
        /* A resumed film brings its counts along (film_state.c). */
        ok = ok && (r->film.region_count || film_enable_regions(&r->film, err));
    } else if (ok && r->film.region_count) {
        ok = error_set(err, "the resumed state has region AOV counts, but render.aov.region is off");
    }
    struct pass_control *pc = &r->pc;
    /* Fault injection for tests: non-finite samples, to prove they never
       reach an image; a biased strategy, to prove the harness notices. */
    pc->fault_nonfinite_every = opt->faults.nonfinite_every;
    pc->fault_biased = opt->faults.bias && opt->faults.bias_strategy == rd->strategy;
    pc->fault_bias = opt->faults.bias_factor;
    if (opt->start) progress_restore(&r->pr, pc, opt->start, &r->film);
    pthread_mutex_init(&pc->lock, NULL);
    pthread_cond_init(&pc->start, NULL);
    pthread_cond_init(&pc->done, NULL);
    return ok;
}

static void render_free(struct render *r)
{
    pthread_mutex_destroy(&r->pc.lock);
    pthread_cond_destroy(&r->pc.start);
    pthread_cond_destroy(&r->pc.done);
    snapshot_writer_free(&r->wr);
    film_free(&r->film);
    if (r->have_aov) aov_classifier_free(&r->aov);
    strategy_free(&r->strategy);
}

static void fill_info(struct snapshot_info *info, const struct config *cfg, double t, int64_t spp,
                      const struct pass_control *pc)
{
    info->render_time_s = t;
    info->spp = spp;
    info->strategy = strategy_names[cfg->render.strategy];
    info->integrator = integrator_names[cfg->render.integrator];
    info->sampler = sampler_names[cfg->render.sampler];
    info->seed = cfg->render.seed;
    info->config_hash = cfg->hash;
    info->renderer_version = RENDERER_VERSION;
    info->rays = pc->stats.rays;
    info->nonfinite_samples = pc->nonfinite;
    info->compress = false;
}

/* Whether to stop before another pass; notes an interrupt. */
static bool render_should_stop(const struct render_desc *rd, struct progress *pr)
{
    if (rd->spp > 0 && pr->pass >= rd->spp) return true;
    /* Stop when another pass would end nearer past the limit than before it. */
    if (rd->time_s > 0.0 && pr->elapsed + 0.5 * pr->last_pass >= rd->time_s) return true;
    if (interrupt_requested) pr->interrupted = true;
    return pr->interrupted;
}

/* Hands a copy of the film to the writer. Waiting for the writer and
   copying happen between passes, outside the render clock. False when an
   earlier snapshot could not be written (the render stops). */
static bool render_snapshot(struct render *r)
{
    double w0 = timing_now_s(), c0 = timing_thread_cpu_s();
    struct snapshot_info info;
    fill_info(&info, r->cfg, r->pr.elapsed, r->pr.pass, &r->pc);
    if (!snapshot_writer_submit(&r->wr, &r->film, &info, r->cfg->render.output, r->pr.snapshots + 1)) return false;
    ++r->pr.snapshots;
    r->pr.pause_s += timing_now_s() - w0;
    r->pr.pause_cpu_s += timing_thread_cpu_s() - c0;
    return true;
}

/* Passes until a limit, an interrupt or a failed snapshot. */
static void render_passes(struct render *r, bool resumed)
{
    const struct render_desc *rd = &r->cfg->render;
    struct progress *pr = &r->pr;
    struct snapshot_cursor schedule;
    snapshot_schedule_start(&schedule, &rd->snapshots);
    /* The schedule is cumulative: what fell due before the state was saved
       was taken (or skipped) then. */
    if (resumed) snapshot_schedule_due(&schedule, pr->elapsed, pr->pass);
    while (!render_should_stop(rd, pr)) {
        double t0 = timing_now_s();
        pool_run_pass(&r->pc, pr->pass, r->started);
        pr->last_pass = timing_now_s() - t0;
        pr->elapsed += pr->last_pass;
        r->film.passes = ++pr->pass;
        if (snapshot_schedule_due(&schedule, pr->elapsed, pr->pass) && !render_snapshot(r)) break;
    }
}

static struct render_timers render_timers_of(const struct render *r)
{
    struct render_timers t;
    t.render_cpu_s = r->pc.cpu_s;
    t.snapshot_cpu_s = r->wr.cpu_s + r->pr.pause_cpu_s;
    t.snapshot_pause_s = r->pr.pause_s;
    return t;
}

/* DIR/final.state when the render is resumable, written before final.exr
   is renamed into place (so a final.exr is never newer than its state);
   otherwise a state an earlier render left is removed, for the same
   reason. */
static bool write_final_state(const struct render *r, struct error *err)
{
    const struct config *cfg = r->cfg;
    char path[CONFIG_PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/final.state", cfg->render.output);
    if (!cfg->render.resumable) {
        if (unlink(path) != 0 && errno != ENOENT)
            return error_set(err, "%s: cannot remove the state of an earlier render: %s", path, strerror(errno));
        return true;
    }
    struct render_timers timers = render_timers_of(r);
    struct film_state st;
    memset(&st, 0, sizeof st);
    st.film = r->film;
    st.render_time_s = r->pr.elapsed;
    st.render_cpu_s = timers.render_cpu_s;
    st.snapshot_cpu_s = timers.snapshot_cpu_s;
    st.snapshot_pause_s = timers.snapshot_pause_s;
    st.stats = r->pc.stats;
    st.nonfinite_samples = r->pc.nonfinite;
    st.snapshots = r->pr.snapshots;
    st.seed = cfg->render.seed;
    st.image_hash = cfg->image_hash;
    st.sampler = cfg->render.sampler;
    return film_state_write(path, &st, err);
}

/* The final snapshot (and state), always, from the main thread once the
   writer has stopped (its image is free), and the `final` JSON line. */
static bool write_final(struct render *r, FILE *json, struct error *err)
{
    struct snapshot_info info;
    char path[CONFIG_PATH_MAX + 64];
    film_snapshot(&r->film, &r->wr.image);
    fill_info(&info, r->cfg, r->pr.elapsed, r->pr.pass, &r->pc);
    info.compress = true;
    snprintf(path, sizeof path, "%s/final.exr", r->cfg->render.output);
    if (!write_final_state(r, err) || !film_write_exr(path, &r->wr.image, &info, err)) return false;
    struct render_timers timers = render_timers_of(r);
    render_event_final(json, path, &info, r->pr.interrupted, &r->pc.stats, &timers);
    return true;
}

bool render_run(const struct render_options *opt, struct render_result *result, struct error *err)
{
    const struct config *cfg = opt->cfg;
    const struct film_state *start = opt->start;
    memset(result, 0, sizeof *result);
    if (start && (start->film.width != cfg->width || start->film.height != cfg->height || !start->film.mean))
        return error_set(err, "the state to resume is %dx%d, the config %dx%d", start->film.width, start->film.height,
                         cfg->width, cfg->height);
    struct render r;
    if (!render_init(&r, opt, err)) return false;
    bool ok = render_prepare(&r, opt, err);
    int n_threads = thread_count(&cfg->render);
    struct worker proto = {
        .cfg = cfg, .camera = &r.camera, .integrator = &r.integrator, .film = &r.film, .aov = r.have_aov ? &r.aov : NULL
    };
    ok = ok && pool_start(&r.pc, &r.workers, &r.started, n_threads, &proto, &r.strategy, err) &&
         snapshot_writer_start(&r.wr, err);
    if (ok) {
        render_event_start(opt->json, cfg, n_threads, r.pr.pass);
        render_passes(&r, start != NULL);
    }
    pool_stop(&r.pc, r.workers, r.started);
    if (!snapshot_writer_stop(&r.wr, err)) ok = false;
    if (ok) ok = write_final(&r, opt->json, err);

    result->spp = r.pr.pass;
    result->time_s = r.pr.elapsed;
    result->snapshots = r.pr.snapshots;
    result->interrupted = r.pr.interrupted;
    result->nonfinite_samples = r.pc.nonfinite;
    result->stats = r.pc.stats;
    result->timers = render_timers_of(&r);
    render_free(&r);
    return ok;
}

/* render.c: a render's lifecycle (see render.h): set-up, the progressive
   loop, snapshots, the final image and state. The threads that render the
   passes are render_pool.c's. */
#include "render/render.h"
#include "render/render_pool.h"

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
    pc->faults = pc->fault_nonfinite_every > 0 || pc->fault_biased;
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
        render_pool_run_pass(&r->pc, pr->pass, r->started);
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
    ok = ok && render_pool_start(&r.pc, &r.workers, &r.started, n_threads, &proto, &r.strategy, err) &&
         snapshot_writer_start(&r.wr, err);
    if (ok) {
        render_event_start(opt->json, cfg, n_threads, r.pr.pass);
        render_passes(&r, start != NULL);
    }
    render_pool_stop(&r.pc, r.workers, r.started);
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

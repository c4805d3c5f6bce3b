#include "render.h"

#include "fastmath.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include "aov.h"
#include "camera.h"
#include "film.h"
#include "render_event.h"
#include "rng.h"
#include "strategy.h"
#include "version.h"

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

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- passes ------------------------------------------------------------ */

/* Shared between the main thread and the workers; guarded by `lock`. */
struct pass_control {
    pthread_mutex_t lock;
    pthread_cond_t start, done;
    int64_t generation;       /* incremented to start a pass */
    int next_row;
    int active;               /* workers still in the current pass */
    bool quit;
    int64_t pass;             /* index of the pass being rendered */
    int64_t fault_nonfinite_every; /* test hook: poison ~1 sample in N (0: off) */
    bool fault_biased;        /* test hook: every sample times fault_bias */
    double fault_bias;
    uint64_t nonfinite;
    struct integrator_stats stats;
    double cpu_s;             /* CPU time the workers spent rendering passes */
};

struct worker {
    pthread_t thread;
    struct pass_control *pc;
    const struct config *cfg;
    const struct camera *camera;
    const struct integrator *integrator;
    struct film *film;
    struct strategy_scratch scratch;
    /* One film row in flight: each pixel's random stream, camera ray and
       its hit, so that the row's camera rays are traced as one stream. */
    struct rng *row_rng;
    struct vec3 *row_dir;
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
    w->row_rng = malloc(n * sizeof *w->row_rng);
    w->row_dir = malloc(n * sizeof *w->row_dir);
    w->row_hit = malloc(n * sizeof *w->row_hit);
    w->row_found = malloc(n * sizeof *w->row_found);
    w->row_color = malloc(n * sizeof *w->row_color);
    if (!w->row_rng || !w->row_dir || !w->row_hit || !w->row_found || !w->row_color)
        return error_set(err, "out of memory for a film row of %d pixels", width);
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
    free(w->row_rng);
    free(w->row_dir);
    free(w->row_hit);
    free(w->row_found);
    free(w->row_color);
    integrator_row_destroy(w->row);
    w->row = NULL;
    free(w->row_class);
    w->row_class = NULL;
    aov_scratch_free(&w->aov_scratch);
}

static void stats_add(struct integrator_stats *a, const struct integrator_stats *b)
{
    a->rays += b->rays;
    a->shadow_rays += b->shadow_rays;
    a->shadow_blocked += b->shadow_blocked;
    a->light_samples += b->light_samples;
    a->light_missed += b->light_missed;
}

/* Seeds the random stream of each pixel of film row y and draws its camera
   ray. One stream per (pixel, pass): pixels never depend on which thread
   rendered them, so fixed-spp renders are bit-identical. A vectorised loop:
   the hash chains of neighbouring pixels run side by side. */
FM_SIMD_CLONES static void camera_row(const struct camera *c, uint64_t seed, int y, int64_t pass, int width,
                                      struct rng *rng, struct vec3 *dir)
{
    uint64_t first = (uint64_t)y * (uint64_t)width;
#pragma omp simd
    for (int x = 0; x < width; ++x) {
        struct rng r = rng_seeded(seed, first + (uint64_t)x, (uint64_t)pass);
        struct rng_draw jx = rng_draw(r.state, r.inc), jy = rng_draw(jx.state, r.inc);
        rng[x].state = jy.state;
        rng[x].inc = r.inc;
        dir[x] = camera_ray(c, x + jx.u, y + jy.u);
    }
}

static void render_row(struct worker *w, int y, int64_t pass, struct integrator_stats *stats, uint64_t *nonfinite)
{
    const struct config *cfg = w->cfg;
    camera_row(w->camera, cfg->render.seed, y, pass, cfg->width, w->row_rng, w->row_dir);
    scene_intersect_coherent(w->integrator->scene, w->camera->origin, w->row_dir, cfg->width, w->row_hit,
                             w->row_found);
    integrator_radiance_row(w->integrator, w->row, &w->scratch, w->camera->origin, w->row_dir, w->row_hit,
                            w->row_found, cfg->width, w->row_rng, w->row_color, stats);
    if (w->pc->fault_biased)
        for (int x = 0; x < cfg->width; ++x) w->row_color[x] = rgb_scale(w->row_color[x], w->pc->fault_bias);
    int dropped = 0;
    for (int x = 0; x < cfg->width; ++x) {
        struct rgb *c = &w->row_color[x];
        if (w->pc->fault_nonfinite_every > 0 &&
            rng_mix64(w->row_rng[x].state) % (uint64_t)w->pc->fault_nonfinite_every == 0)
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

/* CPU time of the calling thread: what a worker spends rendering,
   whatever else runs on the machine or in the process (the Embree
   builder's threads, the EXR writer). */
static double thread_cpu_s(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
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
        while (pc->generation == seen && !pc->quit) pthread_cond_wait(&pc->start, &pc->lock);
        if (pc->quit) break;
        seen = pc->generation;
        int64_t pass = pc->pass;
        struct integrator_stats stats = { 0, 0, 0, 0, 0 };
        uint64_t nonfinite = 0;
        double cpu0 = thread_cpu_s();
        for (;;) {
            int y = pc->next_row < w->cfg->height ? pc->next_row++ : -1;
            if (y < 0) break;
            pthread_mutex_unlock(&pc->lock);
            render_row(w, y, pass, &stats, &nonfinite);
            pthread_mutex_lock(&pc->lock);
        }
        stats_add(&pc->stats, &stats);
        pc->nonfinite += nonfinite;
        pc->cpu_s += thread_cpu_s() - cpu0;
        if (--pc->active == 0) pthread_cond_signal(&pc->done);
    }
    pthread_mutex_unlock(&pc->lock);
    return NULL;
}

/* ---- snapshots ----------------------------------------------------------- */

/* Next due time or sample count of each schedule; a snapshot is taken at the
   first pass boundary at or after it. */
struct schedule_state {
    const struct snapshot_schedule *sch;
    double next_every, next_doubling;
    int next_time, next_spp_list;
    int64_t next_every_spp, next_doubling_spp;
};

static void schedule_init(struct schedule_state *s, const struct snapshot_schedule *sch)
{
    s->sch = sch;
    s->next_every = sch->every_s > 0.0 ? sch->every_s : INFINITY;
    s->next_doubling = sch->doubling_s > 0.0 ? sch->doubling_s : INFINITY;
    s->next_time = 0;
    s->next_spp_list = 0;
    s->next_every_spp = sch->every_spp > 0 ? sch->every_spp : INT64_MAX;
    s->next_doubling_spp = sch->doubling_spp > 0 ? sch->doubling_spp : INT64_MAX;
}

/* True if a snapshot is due at (t, spp); advances every schedule past it. */
static bool schedule_due(struct schedule_state *s, double t, int64_t spp)
{
    const struct snapshot_schedule *sch = s->sch;
    bool due = false;
    if (t >= s->next_every) {
        due = true;
        while (s->next_every <= t) s->next_every += sch->every_s;
    }
    if (t >= s->next_doubling) {
        due = true;
        while (s->next_doubling <= t) s->next_doubling *= 2.0;
    }
    while (s->next_time < sch->n_times && t >= sch->times_s[s->next_time]) {
        due = true;
        ++s->next_time;
    }
    if (spp >= s->next_every_spp) {
        due = true;
        while (s->next_every_spp <= spp) s->next_every_spp += sch->every_spp;
    }
    if (spp >= s->next_doubling_spp) {
        due = true;
        /* Saturates instead of overflowing: INT64_MAX is never reached. */
        while (s->next_doubling_spp <= spp) s->next_doubling_spp = s->next_doubling_spp > INT64_MAX / 2
                                                                       ? INT64_MAX : 2 * s->next_doubling_spp;
    }
    while (s->next_spp_list < sch->n_spps && spp >= sch->spps[s->next_spp_list]) {
        due = true;
        ++s->next_spp_list;
    }
    return due;
}

/* Writes snapshots on its own thread so render threads never wait for I/O;
   holds one pending image at a time. */
struct writer {
    pthread_t thread;
    pthread_mutex_t lock;
    pthread_cond_t cond;
    bool busy, quit, failed;
    struct error err;
    FILE *json;
    struct film_image image;
    struct snapshot_info info;
    char path[CONFIG_PATH_MAX + 64];
    int index;
    double cpu_s;              /* CPU time spent writing snapshots */
};

static void json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; ++s) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(f, "\\%c", c);
        else if (c < 0x20) fprintf(f, "\\u%04x", c);
        else fputc(c, f);
    }
    fputc('"', f);
}

static void json_snapshot(FILE *f, const char *event, int index, const char *path, const struct snapshot_info *info)
{
    fprintf(f, "{\"event\":\"%s\",", event);
    if (index > 0) fprintf(f, "\"index\":%d,", index);
    fputs("\"path\":", f);
    json_string(f, path);
    fprintf(f, ",\"time_s\":%.6f,\"spp\":%lld,\"rays\":%llu,\"nonfinite\":%llu", info->render_time_s,
            (long long)info->spp, (unsigned long long)info->rays, (unsigned long long)info->nonfinite_samples);
}

static void *writer_main(void *arg)
{
    struct writer *w = arg;
    pthread_mutex_lock(&w->lock);
    for (;;) {
        while (!w->busy && !w->quit) pthread_cond_wait(&w->cond, &w->lock);
        if (!w->busy && w->quit) break;
        pthread_mutex_unlock(&w->lock);
        double cpu0 = thread_cpu_s();
        struct error err;
        bool ok = film_write_exr(w->path, &w->image, &w->info, &err);
        if (ok) {
            json_snapshot(w->json, render_event_names[RENDER_EVENT_SNAPSHOT], w->index, w->path, &w->info);
            fputs("}\n", w->json);
            fflush(w->json);
        }
        double cpu = thread_cpu_s() - cpu0;
        pthread_mutex_lock(&w->lock);
        w->cpu_s += cpu;
        if (!ok && !w->failed) {
            w->failed = true;
            w->err = err;
        }
        w->busy = false;
        pthread_cond_broadcast(&w->cond);
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

static void writer_wait_idle(struct writer *w)
{
    pthread_mutex_lock(&w->lock);
    while (w->busy) pthread_cond_wait(&w->cond, &w->lock);
    pthread_mutex_unlock(&w->lock);
}

/* ---- test hooks ------------------------------------------------------------ */

bool render_faults_from_env(struct render_faults *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    out->bias_factor = 1.0;
    const char *nonfinite = getenv("PORTAL_LIGHTS_FAULT_NONFINITE");
    if (nonfinite) out->nonfinite_every = atoll(nonfinite);
    const char *bias = getenv("PORTAL_LIGHTS_FAULT_BIAS");
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

/* ---- the loop -------------------------------------------------------------- */

static int thread_count(const struct render_desc *rd)
{
    if (rd->threads > 0) return rd->threads;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

static void fill_info(struct snapshot_info *info, const struct config *cfg, double t, int64_t spp,
                      const struct pass_control *pc)
{
    info->render_time_s = t;
    info->spp = spp;
    info->strategy = strategy_names[cfg->render.strategy];
    info->integrator = integrator_names[cfg->render.integrator];
    info->seed = cfg->render.seed;
    info->config_hash = cfg->hash;
    info->renderer_version = RENDERER_VERSION;
    info->rays = pc->stats.rays;
    info->nonfinite_samples = pc->nonfinite;
    info->compress = false;
}

/* What the render has done so far, beyond the film and the workers'
   counters: restored from a state when resuming, saved in it at the end. */
struct progress {
    int64_t pass;              /* passes done */
    double elapsed;            /* render clock */
    double last_pass;          /* duration of the latest pass (0 before one) */
    int snapshots;             /* timed snapshots written */
    /* What the snapshot schedule costs the main thread: wall time with the
       render threads paused, and CPU time (the writer's is wr.cpu_s). */
    double pause_s, pause_cpu_s;
    bool interrupted;
};

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

/* DIR/final.state when the render is resumable, written before final.exr
   is renamed into place (so a final.exr is never newer than its state);
   otherwise a state an earlier render left is removed, for the same
   reason. */
static bool write_final_state(const struct config *cfg, const struct film *film, const struct pass_control *pc,
                              const struct writer *wr, const struct progress *pr, struct error *err)
{
    char path[CONFIG_PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/final.state", cfg->render.output);
    if (!cfg->render.resumable) {
        if (unlink(path) != 0 && errno != ENOENT)
            return error_set(err, "%s: cannot remove the state of an earlier render: %s", path, strerror(errno));
        return true;
    }
    struct film_state st;
    memset(&st, 0, sizeof st);
    st.film = *film;
    st.render_time_s = pr->elapsed;
    st.render_cpu_s = pc->cpu_s;
    st.snapshot_cpu_s = wr->cpu_s + pr->pause_cpu_s;
    st.snapshot_pause_s = pr->pause_s;
    st.stats = pc->stats;
    st.nonfinite_samples = pc->nonfinite;
    st.snapshots = pr->snapshots;
    st.seed = cfg->render.seed;
    st.image_hash = cfg->image_hash;
    return film_state_write(path, &st, err);
}

/* The final snapshot (and state), always, from the main thread, and the
   `final` JSON line. */
static bool write_final(const struct config *cfg, const struct film *film, const struct pass_control *pc,
                        struct writer *wr, const struct progress *pr, FILE *json, struct error *err)
{
    struct snapshot_info info;
    char path[CONFIG_PATH_MAX + 64];
    film_snapshot(film, &wr->image);
    fill_info(&info, cfg, pr->elapsed, pr->pass, pc);
    info.compress = true;
    snprintf(path, sizeof path, "%s/final.exr", cfg->render.output);
    if (!write_final_state(cfg, film, pc, wr, pr, err) || !film_write_exr(path, &wr->image, &info, err)) return false;
    json_snapshot(json, render_event_names[RENDER_EVENT_FINAL], 0, path, &info);
    fprintf(json, ",\"interrupted\":%s,\"shadow_rays\":%llu,\"shadow_blocked\":%llu,"
                  "\"light_samples\":%llu,\"light_missed\":%llu,\"render_cpu_s\":%.6f,"
                  "\"snapshot_cpu_s\":%.6f,\"snapshot_pause_s\":%.6f}\n",
            pr->interrupted ? "true" : "false", (unsigned long long)pc->stats.shadow_rays,
            (unsigned long long)pc->stats.shadow_blocked, (unsigned long long)pc->stats.light_samples,
            (unsigned long long)pc->stats.light_missed, pc->cpu_s, wr->cpu_s + pr->pause_cpu_s, pr->pause_s);
    fflush(json);
    return true;
}

bool render_run(const struct config *cfg, const struct scene *scene, struct film_state *start, FILE *json,
                struct render_result *result, struct error *err)
{
    const struct render_desc *rd = &cfg->render;
    memset(result, 0, sizeof *result);
    struct render_faults faults;
    if (!render_faults_from_env(&faults, err)) return false;
    if (start && (start->film.width != cfg->width || start->film.height != cfg->height || !start->film.mean))
        return error_set(err, "the state to resume is %dx%d, the config %dx%d", start->film.width,
                         start->film.height, cfg->width, cfg->height);
    struct strategy strategy;
    if (!strategy_init(&strategy, scene, rd, err)) return false;
    struct integrator integrator;
    integrator_init(&integrator, rd, scene, &strategy);
    struct camera camera;
    camera_init(&camera, &cfg->camera, cfg->width, cfg->height);
    struct film film;
    if (start) {
        film = start->film;
        memset(&start->film, 0, sizeof start->film);
    } else if (!film_init(&film, cfg->width, cfg->height, err)) {
        strategy_free(&strategy);
        return false;
    }
    struct aov_classifier aov;
    bool have_aov = false;

    struct writer wr;
    memset(&wr, 0, sizeof wr);
    wr.json = json;
    bool ok = film_image_alloc(&wr.image, cfg->width, cfg->height, err);
    if (ok && rd->aov_region) {
        ok = aov_classifier_init(&aov, scene, err);
        have_aov = ok;
        /* A resumed film brings its counts along (film_state.c). */
        ok = ok && (film.region_count || film_enable_regions(&film, err)) &&
             film_image_enable_regions(&wr.image, err);
    } else if (ok && film.region_count) {
        ok = error_set(err, "the resumed state has region AOV counts, but render.aov.region is off");
    }

    int n_threads = thread_count(rd);
    struct pass_control pc;
    memset(&pc, 0, sizeof pc);
    /* Fault injection for tests: non-finite samples, to prove they never
       reach an image; a biased strategy, to prove the harness notices. */
    pc.fault_nonfinite_every = faults.nonfinite_every;
    pc.fault_biased = faults.bias && faults.bias_strategy == rd->strategy;
    pc.fault_bias = faults.bias_factor;
    struct progress pr;
    memset(&pr, 0, sizeof pr);
    if (start) progress_restore(&pr, &pc, start, &film);
    pthread_mutex_init(&pc.lock, NULL);
    pthread_cond_init(&pc.start, NULL);
    pthread_cond_init(&pc.done, NULL);
    pthread_mutex_init(&wr.lock, NULL);
    pthread_cond_init(&wr.cond, NULL);
    struct worker *workers = calloc((size_t)n_threads, sizeof *workers);
    int started = 0;
    bool writer_started = false;
    if (ok && !workers) ok = error_set(err, "out of memory for %d threads", n_threads);
    for (int i = 0; ok && i < n_threads; ++i) {
        struct worker *w = &workers[i];
        w->pc = &pc;
        w->cfg = cfg;
        w->camera = &camera;
        w->integrator = &integrator;
        w->film = &film;
        w->aov = have_aov ? &aov : NULL;
        if (!strategy_scratch_init(&strategy, &w->scratch, err) || !worker_alloc_row(w, cfg->width, err)) {
            worker_free(w);
            ok = false;
        } else if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
            worker_free(w);
            ok = error_set(err, "cannot start render thread %d", i);
        } else ++started;
    }
    if (ok) {
        if (pthread_create(&wr.thread, NULL, writer_main, &wr) != 0) ok = error_set(err, "cannot start the writer thread");
        else writer_started = true;
    }

    if (ok) {
        fprintf(json, "{\"event\":\"%s\",\"out\":", render_event_names[RENDER_EVENT_START]);
        json_string(json, rd->output);
        fprintf(json, ",\"width\":%d,\"height\":%d,\"strategy\":\"%s\",\"integrator\":\"%s\",\"seed\":%llu,"
                      "\"config_hash\":\"%016llx\",\"renderer_version\":\"%s\",\"threads\":%d,"
                      "\"spp_target\":%d,\"time_target_s\":%g,\"resumed_from_spp\":%lld}\n",
                cfg->width, cfg->height, strategy_names[rd->strategy], integrator_names[rd->integrator],
                (unsigned long long)rd->seed, (unsigned long long)cfg->hash, RENDERER_VERSION, n_threads, rd->spp,
                rd->time_s, (long long)pr.pass);
        fflush(json);
    }

    struct schedule_state sched;
    schedule_init(&sched, &rd->snapshots);
    /* The schedule is cumulative: what fell due before the state was saved
       was taken (or skipped) then. */
    if (start) schedule_due(&sched, pr.elapsed, pr.pass);
    while (ok) {
        if (rd->spp > 0 && pr.pass >= rd->spp) break;
        /* Stop when another pass would end nearer past the limit than before it. */
        if (rd->time_s > 0.0 && pr.elapsed + 0.5 * pr.last_pass >= rd->time_s) break;
        if (interrupt_requested) {
            pr.interrupted = true;
            break;
        }
        double t0 = now_s();
        pthread_mutex_lock(&pc.lock);
        pc.pass = pr.pass;
        pc.next_row = 0;
        pc.active = started;
        ++pc.generation;
        pthread_cond_broadcast(&pc.start);
        while (pc.active > 0) pthread_cond_wait(&pc.done, &pc.lock);
        pthread_mutex_unlock(&pc.lock);
        pr.last_pass = now_s() - t0;
        pr.elapsed += pr.last_pass;
        film.passes = ++pr.pass;

        if (schedule_due(&sched, pr.elapsed, pr.pass)) {
            /* Waiting for the writer and copying the film happen between
               passes, outside the render clock. */
            double w0 = now_s(), c0 = thread_cpu_s();
            writer_wait_idle(&wr);
            pthread_mutex_lock(&wr.lock);
            if (wr.failed) {
                pthread_mutex_unlock(&wr.lock);
                break;
            }
            film_snapshot(&film, &wr.image);
            fill_info(&wr.info, cfg, pr.elapsed, pr.pass, &pc);
            wr.index = ++pr.snapshots;
            snprintf(wr.path, sizeof wr.path, "%s/snapshot_%04d.exr", rd->output, wr.index);
            wr.busy = true;
            pthread_cond_broadcast(&wr.cond);
            pthread_mutex_unlock(&wr.lock);
            pr.pause_s += now_s() - w0;
            pr.pause_cpu_s += thread_cpu_s() - c0;
        }
    }

    /* Stop the workers. */
    pthread_mutex_lock(&pc.lock);
    pc.quit = true;
    pthread_cond_broadcast(&pc.start);
    pthread_mutex_unlock(&pc.lock);
    for (int i = 0; i < started; ++i) {
        pthread_join(workers[i].thread, NULL);
        worker_free(&workers[i]);
    }
    if (writer_started) {
        writer_wait_idle(&wr);
        pthread_mutex_lock(&wr.lock);
        wr.quit = true;
        pthread_cond_broadcast(&wr.cond);
        pthread_mutex_unlock(&wr.lock);
        pthread_join(wr.thread, NULL);
        if (wr.failed) ok = error_set(err, "%s", wr.err.message);
    }

    if (ok) ok = write_final(cfg, &film, &pc, &wr, &pr, json, err);

    result->spp = pr.pass;
    result->time_s = pr.elapsed;
    result->snapshots = pr.snapshots;
    result->interrupted = pr.interrupted;
    result->nonfinite_samples = pc.nonfinite;
    result->stats = pc.stats;
    free(workers);
    pthread_mutex_destroy(&pc.lock);
    pthread_cond_destroy(&pc.start);
    pthread_cond_destroy(&pc.done);
    pthread_mutex_destroy(&wr.lock);
    pthread_cond_destroy(&wr.cond);
    film_image_free(&wr.image);
    film_free(&film);
    if (have_aov) aov_classifier_free(&aov);
    strategy_free(&strategy);
    return ok;
}

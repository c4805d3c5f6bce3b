/* snapshot_writer.c: the snapshot writer thread (see snapshot_writer.h). */
#include "render/snapshot_writer.h"

#include <string.h>

#include "render/render_events.h"
#include "base/timing.h"

bool snapshot_writer_init(struct snapshot_writer *w, int width, int height, bool regions, FILE *json, struct error *err)
{
    memset(w, 0, sizeof *w);
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->cond, NULL);
    w->json = json;
    return film_image_alloc(&w->image, width, height, err) && (!regions || film_image_enable_regions(&w->image, err));
}

static void *writer_main(void *arg)
{
    struct snapshot_writer *w = arg;
    pthread_mutex_lock(&w->lock);
    for (;;) {
        while (!w->busy && !w->quit) pthread_cond_wait(&w->cond, &w->lock);
        if (!w->busy && w->quit) break;
        pthread_mutex_unlock(&w->lock);
        double cpu0 = timing_thread_cpu_s();
        struct error err;
        bool ok = film_write_exr(w->path, &w->image, &w->info, &err);
        if (ok) render_event_snapshot(w->json, w->index, w->path, &w->info);
        double cpu = timing_thread_cpu_s() - cpu0;
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

bool snapshot_writer_start(struct snapshot_writer *w, struct error *err)
{
    if (pthread_create(&w->thread, NULL, writer_main, w) != 0) return error_set(err, "cannot start the writer thread");
    w->started = true;
    return true;
}

static void wait_idle(struct snapshot_writer *w)
{
    pthread_mutex_lock(&w->lock);
    while (w->busy) pthread_cond_wait(&w->cond, &w->lock);
    pthread_mutex_unlock(&w->lock);
}

bool snapshot_writer_submit(struct snapshot_writer *w, const struct film *film, const struct snapshot_info *info,
                            const char *dir, int index)
{
    wait_idle(w);
    pthread_mutex_lock(&w->lock);
    if (w->failed) {
        pthread_mutex_unlock(&w->lock);
        return false;
    }
    film_snapshot(film, &w->image);
    w->info = *info;
    w->index = index;
    snprintf(w->path, sizeof w->path, "%s/snapshot_%04d.exr", dir, index);
    w->busy = true;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return true;
}

bool snapshot_writer_stop(struct snapshot_writer *w, struct error *err)
{
    if (!w->started) return true;
    wait_idle(w);
    pthread_mutex_lock(&w->lock);
    w->quit = true;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    pthread_join(w->thread, NULL);
    w->started = false;
    if (w->failed) return error_set(err, "%s", w->err.message);
    return true;
}

void snapshot_writer_free(struct snapshot_writer *w)
{
    pthread_mutex_destroy(&w->lock);
    pthread_cond_destroy(&w->cond);
    film_image_free(&w->image);
}

/* snapshot_writer.h: the thread that writes timed snapshots, so that the
   render threads never wait for I/O. Owns that thread, its one pending
   image and the `snapshot` event lines it writes once a file is in place.
   It must not decide when a snapshot is due (snapshot_schedule.h) and
   touches the film only to copy it, between passes, in
   snapshot_writer_submit. */
#ifndef SNAPSHOT_WRITER_H
#define SNAPSHOT_WRITER_H

#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>

#include "config/config.h"
#include "base/error.h"
#include "render/film.h"

/* Fields below `lock` are shared with the thread; read them only once it
   has stopped (snapshot_writer_stop). */
struct snapshot_writer {
    pthread_t thread;
    bool started;
    pthread_mutex_t lock;
    pthread_cond_t cond;
    bool busy, quit, failed;
    struct error err; /* the first failure */
    FILE *json;
    struct film_image image; /* the pending snapshot; free for the caller once stopped */
    struct snapshot_info info;
    char path[CONFIG_PATH_MAX + 64];
    int index;
    double cpu_s; /* CPU time spent writing snapshots */
};

/* An idle writer (no thread yet) with a width x height image, with the
   region AOV layer when `regions`; `snapshot` lines go to json. False
   when out of memory; snapshot_writer_free is safe either way. */
bool snapshot_writer_init(struct snapshot_writer *w, int width, int height, bool regions, FILE *json,
                          struct error *err);

/* Starts the thread. */
bool snapshot_writer_start(struct snapshot_writer *w, struct error *err);

/* Waits until the previous snapshot is written, then copies the film
   (film_snapshot) and hands it to the thread, to be written as
   DIR/snapshot_NNNN.exr (NNNN = index) with the header `info`. False, with
   nothing handed over, when an earlier snapshot could not be written
   (snapshot_writer_stop reports why). */
bool snapshot_writer_submit(struct snapshot_writer *w, const struct film *film, const struct snapshot_info *info,
                            const char *dir, int index);

/* Waits for the pending snapshot and stops the thread (nothing when it was
   never started). False, with the message of the first failed write in
   err, when a snapshot could not be written. */
bool snapshot_writer_stop(struct snapshot_writer *w, struct error *err);

/* Frees the image and the lock; after snapshot_writer_stop. */
void snapshot_writer_free(struct snapshot_writer *w);

#endif

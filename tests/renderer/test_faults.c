/* Faults while rendering: a full disk, an output folder that vanishes, and
   kills (SIGKILL, SIGTERM) at random moments. Whatever happens, every EXR in
   the output folder opens and no temporary file is left behind for a file
   that was completed; errors exit non-zero with a message. */
#include <dirent.h>

#include "cli_util.h"
#include "render/film.h"
#include "exr_read.h"
#include "base/rng.h"
#include "testlib.h"

/* Every *.exr in dir reads back; returns how many, or -1 on a bad one. */
static int check_exrs(const char *dir, int *tmp_files)
{
    DIR *d = opendir(dir);
    if (!d) return 0;
    int good = 0;
    *tmp_files = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strstr(e->d_name, ".tmp-")) ++*tmp_files;
        size_t len = strlen(e->d_name);
        if (len < 4 || strcmp(e->d_name + len - 4, ".exr")) continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct film_image img = { 0 };
        struct snapshot_read meta = { { 0 }, NULL };
        struct error err;
        if (!film_read_exr(path, &img, &meta, &err)) {
            fprintf(stderr, "  unreadable snapshot: %s\n", err.message);
            good = -1000000;
        } else {
            ++good;
        }
        film_image_free(&img);
        free(meta.storage);
    }
    closedir(d);
    return good;
}

/* A disk that fills up: the file-size limit lets a few snapshots through,
   then writes fail with EFBIG. Exit 1, a message naming the file, every
   file that exists is complete, no temporary left. */
static void test_full_disk(void)
{
    char dir[] = "/tmp/portal-fault-XXXXXX";
    make_tmpdir(dir);
    struct run r;
    char *a[] = { NULL,        "configs/scenes/lampshade.yaml",
                  "--out",     dir,
                  "--spp",     "40",
                  "--threads", "2",
                  "--set",     "film.width=48",
                  "--set",     "film.height=48",
                  "--set",     "render.snapshots.every_spp=4",
                  "--quiet",   NULL };
    /* 48 x 48 x 6 floats = 55 kB per uncompressed snapshot. */
    run_render_limited(a, 0, 0, 40000, &r);
    CHECK_MSG(r.status == 1, "status %d: %s", r.status, r.err);
    CHECK_MSG(strstr(r.err, "File too large") != NULL, "stderr: %s", r.err);
    int tmp = 0, n = check_exrs(dir, &tmp);
    CHECK_MSG(n >= 0 && tmp == 0, "%d readable snapshots, %d temporaries", n, tmp);
    remove_tree(dir);
}

/* The output folder is deleted while the renderer runs. */
static void test_vanished_output(void)
{
    char dir[] = "/tmp/portal-fault-XXXXXX";
    make_tmpdir(dir);
    char out[600];
    snprintf(out, sizeof out, "%s/out", dir);
    if (!render_bin[0]) find_binary();
    int fo = open("/dev/null", O_WRONLY);
    char err_path[] = "/tmp/portal-fault-err-XXXXXX";
    int fe = mkstemp(err_path);
    pid_t pid = fork();
    if (pid == 0) {
        dup2(fo, 1);
        dup2(fe, 2);
        execl(render_bin, render_bin, "configs/scenes/lampshade.yaml", "--out", out, "--spp", "0", "--time", "20",
              "--set", "film.width=32", "--set", "film.height=32", "--set", "render.snapshots.every=0.1", "--quiet",
              (char *)NULL);
        _exit(127);
    }
    struct timespec ts = { 0, 600000000 };
    nanosleep(&ts, NULL);
    /* Renamed away in one step (a recursive delete races with new files). */
    char gone[700];
    snprintf(gone, sizeof gone, "%s/gone", dir);
    CHECK(rename(out, gone) == 0);
    int st;
    waitpid(pid, &st, 0);
    char err[4096];
    lseek(fe, 0, SEEK_SET);
    read_all(fe, err, sizeof err);
    close(fo), close(fe);
    unlink(err_path);
    CHECK_MSG(WIFEXITED(st) && WEXITSTATUS(st) == 1, "status %d, stderr: %s", st, err);
    CHECK_MSG(strstr(err, out) != NULL, "stderr does not name the folder: %s", err);
    remove_tree(dir);
}

/* Kill loops. Each run renders the lampshade and is killed at a random
   moment: SIGKILL, SIGTERM, or SIGTERM then SIGKILL a few milliseconds
   later (which lands in the final write that SIGTERM starts). Afterwards
   every EXR in the folder must open. After SIGTERM alone, final.exr must
   exist and open, with no temporary left, and the exit status is 3 (or 0
   if the render had finished), unless the signal came before the renderer
   had installed its handler (status 128 + SIGTERM, no "start" event).
   PORTAL_LIGHTS_KILL_ITERATIONS sets the number of runs of each loop
   (`make stress`). */

enum kill_kind { KILL_TERM, KILL_KILL, KILL_TERM_THEN_KILL };

struct kill_counts {
    int runs, by_kind[3];
    int early;        /* SIGTERM before the signal handler: default action */
    int exrs;         /* EXR files opened */
    int unreadable;   /* must stay 0 */
    int finals;       /* readable final.exr after SIGTERM (alone or followed by SIGKILL) */
    int mid_snapshot; /* kills that left a snapshot temporary: caught writing one */
    int mid_final;    /* kills that left final.exr's temporary: caught writing it */
};

/* One loop: argv (argv[0] and the --out value filled in here, at index
   out_arg), kill moments uniform in [t_min, t_max] seconds, kinds cycling
   through the first n_kinds of enum kill_kind. */
struct kill_loop {
    const char *name;
    char **argv;
    int out_arg;
    double t_min, t_max;
    int n_kinds;
};

/* A temporary of a file named prefix... is left in dir: its writer was
   killed between creating it and renaming it. */
static bool has_temporary(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    bool found = false;
    for (struct dirent *e; d && !found && (e = readdir(d));)
        found = strncmp(e->d_name, prefix, strlen(prefix)) == 0 && strstr(e->d_name, ".tmp-") != NULL;
    if (d) closedir(d);
    return found;
}

static void kill_loop_run(const struct kill_loop *loop, int iterations, uint64_t seed, struct kill_counts *k)
{
    static const int first_signal[3] = { SIGTERM, SIGKILL, SIGTERM };
    struct rng rng;
    rng_seed(&rng, seed, 0, 0);
    memset(k, 0, sizeof *k);
    for (int i = 0; i < iterations; ++i) {
        char dir[] = "/tmp/portal-fault-XXXXXX";
        make_tmpdir(dir);
        loop->argv[loop->out_arg] = dir;
        enum kill_kind kind = (enum kill_kind)(i % loop->n_kinds);
        double when = loop->t_min + (loop->t_max - loop->t_min) * rng_uniform(&rng);
        double gap = 0.02 * rng_uniform(&rng);
        struct run r;
        struct run_opts o = { when, first_signal[kind], gap, kind == KILL_TERM_THEN_KILL ? SIGKILL : 0, 0 };
        run_render_opts(loop->argv, &o, &r);
        ++k->runs;
        ++k->by_kind[kind];
        int tmp = 0, n = check_exrs(dir, &tmp);
        if (n < 0) {
            ++k->unreadable;
            fprintf(stderr, "  %s run %d: unreadable EXR after signal at %.3f s\n", loop->name, i, when);
        } else {
            k->exrs += n;
        }
        k->mid_snapshot += has_temporary(dir, "snapshot_");
        k->mid_final += has_temporary(dir, "final.exr");
        char path[600];
        snprintf(path, sizeof path, "%s/final.exr", dir);
        bool started = strstr(r.out, "\"event\":\"start\"") != NULL;
        bool early = r.status == 128 + SIGTERM && !started;
        k->early += early && kind != KILL_KILL;
        switch (kind) {
        case KILL_TERM:
            if (early) break;
            CHECK_MSG(r.status == 3 || r.status == 0, "%s: SIGTERM at %.3f s: status %d: %s", loop->name, when,
                      r.status, r.err);
            CHECK_MSG(exists(path), "%s: SIGTERM at %.3f s: no final.exr", loop->name, when);
            CHECK_MSG(tmp == 0, "%s: SIGTERM at %.3f s: %d temporaries left", loop->name, when, tmp);
            k->finals += exists(path);
            break;
        case KILL_KILL:
            CHECK_MSG(r.status == 128 + SIGKILL || r.status == 0, "%s: SIGKILL at %.3f s: status %d", loop->name, when,
                      r.status);
            break;
        case KILL_TERM_THEN_KILL:
            CHECK_MSG(r.status == 128 + SIGKILL || r.status == 3 || r.status == 0 || early,
                      "%s: SIGTERM at %.3f s then SIGKILL: status %d: %s", loop->name, when, r.status, r.err);
            k->finals += exists(path);
            break;
        }
        remove_tree(dir);
    }
    CHECK_MSG(k->unreadable == 0, "%s: %d of %d runs left an unreadable EXR", loop->name, k->unreadable, k->runs);
    printf("  %s: %d runs (%d SIGTERM, %d SIGKILL, %d SIGTERM then SIGKILL; %d before the handler), %d EXRs "
           "opened, %d unreadable, %d final.exr after SIGTERM, killed writing: %d snapshots, %d finals\n",
           loop->name, k->runs, k->by_kind[KILL_TERM], k->by_kind[KILL_KILL], k->by_kind[KILL_TERM_THEN_KILL], k->early,
           k->exrs, k->unreadable, k->finals, k->mid_snapshot, k->mid_final);
}

static int kill_iterations(int default_count)
{
    const char *env = getenv("PORTAL_LIGHTS_KILL_ITERATIONS");
    int n = env ? atoi(env) : 0;
    return n > 0 ? n : default_count;
}

/* A time-limited render with a snapshot every 50 ms, killed in its first
   0.65 s: half SIGKILL, half SIGTERM. */
static void test_kill_loop(void)
{
    char *a[] = { NULL,      "configs/scenes/lampshade.yaml",
                  "--out",   NULL,
                  "--spp",   "0",
                  "--time",  "3",
                  "--set",   "film.width=40",
                  "--set",   "film.height=40",
                  "--set",   "render.snapshots.every=0.05",
                  "--quiet", NULL };
    struct kill_loop loop = { "kill loop", a, 3, 0.05, 0.65, 2 };
    struct kill_counts k;
    kill_loop_run(&loop, kill_iterations(24), 2024, &k);
    CHECK(k.by_kind[KILL_TERM] == 0 || k.finals > 0);
}

/* A short render that writes a snapshot after every pass and is killed at
   any moment of its life, from start-up to the final write (moments up to
   1.2 times its measured duration): SIGKILL, SIGTERM, and SIGTERM then
   SIGKILL, so that kills land inside snapshot and final writes, between
   the temporary file and its rename. */
static void test_kill_loop_writes(void)
{
    char *a[] = { NULL,        "configs/scenes/lampshade.yaml",
                  "--out",     NULL,
                  "--spp",     "24",
                  "--threads", "2",
                  "--set",     "film.width=96",
                  "--set",     "film.height=96",
                  "--set",     "render.snapshots.every_spp=1",
                  "--quiet",   NULL };
    /* The duration of an undisturbed run. */
    char dir[] = "/tmp/portal-fault-XXXXXX";
    make_tmpdir(dir);
    a[3] = dir;
    struct timespec t0, t1;
    struct run r;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    run_render(a, 0, 0, &r);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double duration = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    int tmp = 0;
    CHECK_MSG(r.status == 0 && check_exrs(dir, &tmp) == 25 && tmp == 0, "undisturbed run: status %d: %s", r.status,
              r.err);
    remove_tree(dir);
    struct kill_loop loop = { "kill loop (writes)", a, 3, 0.0, 1.2 * duration, 3 };
    struct kill_counts k;
    printf("  undisturbed run: %.3f s\n", duration);
    kill_loop_run(&loop, kill_iterations(9), 2025, &k);
}

static const struct test_case tests[] = {
    { "full_disk", test_full_disk },
    { "vanished_output", test_vanished_output },
    { "kill_loop", test_kill_loop },
    { "kill_loop_writes", test_kill_loop_writes },
};
TEST_MAIN(tests)

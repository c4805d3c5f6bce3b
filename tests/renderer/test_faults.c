/* Faults while rendering: a full disk, an output folder that vanishes, and
   kills (SIGKILL, SIGTERM) at random moments. Whatever happens, every EXR in
   the output folder opens and no temporary file is left behind for a file
   that was completed; errors exit non-zero with a message. */
#include <dirent.h>

#include "cli_util.h"
#include "film.h"
#include "rng.h"
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
    char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", dir, "--spp", "40", "--threads", "2",
                  "--set", "film.width=48", "--set", "film.height=48", "--set", "render.snapshots.every_spp=4",
                  "--quiet", NULL };
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

/* Kills at random moments: after SIGKILL every snapshot present opens;
   after SIGTERM, final.exr exists and opens, and the exit status is 3 (or
   0 if the render had already finished). */
static void test_kill_loop(void)
{
    struct rng rng;
    rng_seed(&rng, 2024, 0, 0);
    int iterations = 24, bad = 0, finals = 0;
    for (int i = 0; i < iterations; ++i) {
        char dir[] = "/tmp/portal-fault-XXXXXX";
        make_tmpdir(dir);
        struct run r;
        char *a[] = { NULL, "configs/scenes/lampshade.yaml", "--out", dir, "--spp", "0", "--time", "3",
                      "--set", "film.width=40", "--set", "film.height=40", "--set", "render.snapshots.every=0.05",
                      "--quiet", NULL };
        int sig = i % 2 ? SIGKILL : SIGTERM;
        double when = 0.05 + 0.6 * rng_uniform(&rng);
        run_render(a, when, sig, &r);
        int tmp = 0, n = check_exrs(dir, &tmp);
        if (n < 0) ++bad;
        if (sig == SIGTERM) {
            char path[600];
            snprintf(path, sizeof path, "%s/final.exr", dir);
            bool ok_status = r.status == 3 || r.status == 0;
            CHECK_MSG(ok_status, "SIGTERM at %.2f s: status %d: %s", when, r.status, r.err);
            CHECK_MSG(exists(path), "SIGTERM at %.2f s: no final.exr", when);
            finals += exists(path);
            CHECK_MSG(tmp == 0, "SIGTERM at %.2f s: %d temporaries left", when, tmp);
        } else {
            CHECK_MSG(r.status == 128 + SIGKILL, "SIGKILL: status %d", r.status);
        }
        remove_tree(dir);
    }
    CHECK_MSG(bad == 0, "%d of %d runs left an unreadable snapshot", bad, iterations);
    printf("  kill loop: %d runs (half SIGKILL, half SIGTERM), %d final snapshots after SIGTERM, %d unreadable\n",
           iterations, finals, bad);
}

static const struct test_case tests[] = {
    { "full_disk", test_full_disk },
    { "vanished_output", test_vanished_output },
    { "kill_loop", test_kill_loop },
};
TEST_MAIN(tests)

/* cli_util.h: running the `render` binary from C tests: the binary next to
   the test's folder, captured stdout/stderr, exit status, optional signal
   after a delay, temporary folders. */
#ifndef CLI_UTIL_H
#define CLI_UTIL_H

#include <errno.h>
#include <stdbool.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static char render_bin[PATH_MAX];

static inline void find_binary(void)
{
    char self[PATH_MAX - 16];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return;
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    if (slash) *slash = '\0';
    slash = strrchr(self, '/'); /* .../build/tests -> .../build */
    if (slash) *slash = '\0';
    snprintf(render_bin, sizeof render_bin, "%s/render", self);
}

struct run {
    int status;      /* exit code, or 128 + signal */
    char out[65536]; /* stdout */
    char err[8192];  /* stderr */
};

static inline void read_all(int fd, char *buf, size_t cap)
{
    size_t len = 0;
    ssize_t n;
    while (len + 1 < cap && (n = read(fd, buf + len, cap - 1 - len)) > 0) len += (size_t)n;
    buf[len] = '\0';
}

/* How to run the renderer: signal sig1 after t1 seconds and, if sig2,
   sig2 t2 seconds later (no signal when sig1 is 0); a positive fsize_limit
   caps the size of files the renderer may write (a full disk). */
struct run_opts {
    double t1;
    int sig1;
    double t2;
    int sig2;
    long fsize_limit;
};

static inline void sleep_s(double t)
{
    struct timespec ts = { (time_t)t, (long)((t - (time_t)t) * 1e9) };
    nanosleep(&ts, NULL);
}

/* Runs the renderer with argv (NULL-terminated, argv[0] ignored). */
static inline void run_render_opts(char **argv, const struct run_opts *o, struct run *r)
{
    if (!render_bin[0]) find_binary();
    argv[0] = render_bin;
    char out_path[] = "/tmp/portal-cli-out-XXXXXX", err_path[] = "/tmp/portal-cli-err-XXXXXX";
    int fo = mkstemp(out_path), fe = mkstemp(err_path);
    pid_t pid = fork();
    if (pid == 0) {
        dup2(fo, 1);
        dup2(fe, 2);
        if (o->fsize_limit > 0) {
            struct rlimit rl = { (rlim_t)o->fsize_limit, (rlim_t)o->fsize_limit };
            signal(SIGXFSZ, SIG_IGN); /* writes then fail with EFBIG */
            setrlimit(RLIMIT_FSIZE, &rl);
        }
        execv(render_bin, argv);
        _exit(127);
    }
    if (o->sig1) {
        sleep_s(o->t1);
        kill(pid, o->sig1);
        if (o->sig2) {
            sleep_s(o->t2);
            kill(pid, o->sig2);
        }
    }
    int st = 0;
    waitpid(pid, &st, 0);
    r->status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
    lseek(fo, 0, SEEK_SET);
    lseek(fe, 0, SEEK_SET);
    read_all(fo, r->out, sizeof r->out);
    read_all(fe, r->err, sizeof r->err);
    close(fo), close(fe);
    unlink(out_path), unlink(err_path);
}

/* The same with at most one signal (sig after signal_after_s seconds, none
   when sig is 0) and a file-size limit. */
static inline void run_render_limited(char **argv, double signal_after_s, int sig, long fsize_limit, struct run *r)
{
    struct run_opts o = { signal_after_s, sig, 0.0, 0, fsize_limit };
    run_render_opts(argv, &o, r);
}

static inline bool exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static inline void make_tmpdir(char *dir) /* dir: "/tmp/...XXXXXX" */
{
    if (!mkdtemp(dir)) dir[0] = '\0';
}

static inline void remove_tree(const char *dir)
{
    char cmd[PATH_MAX + 16];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "  could not remove %s\n", dir);
}

static inline void run_render(char **argv, double signal_after_s, int sig, struct run *r)
{
    run_render_limited(argv, signal_after_s, sig, 0, r);
}

#endif

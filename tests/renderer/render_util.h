/* render_util.h: helpers for end-to-end tests: render a config with
   overrides into a fresh temporary folder and read the final image back. */
#ifndef RENDER_UTIL_H
#define RENDER_UTIL_H

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "config/config.h"
#include "render/film.h"
#include "exr_read.h"
#include "render/render.h"
#include "scene/scene.h"

/* Renders `path` with the overrides plus render.output = a new temporary
   folder; fills img with final.exr. Prints the error and returns false on
   failure. */
static inline bool render_to_image(const char *path, const struct config_override *extra, int n_extra,
                                   struct film_image *img, struct render_result *res)
{
    char dir[] = "/tmp/portal-test-XXXXXX";
    if (!mkdtemp(dir)) return false;
    struct config_override ov[32];
    int n = 0;
    for (int i = 0; i < n_extra && n < 31; ++i) ov[n++] = extra[i];
    ov[n].path = "render.output";
    ov[n].value = dir;
    ++n;
    struct error err = { { 0 } };
    struct config cfg;
    struct scene scene;
    struct snapshot_read meta = { { 0 }, NULL };
    bool ok = config_load(path, ov, n, &cfg, &err);
    if (ok) {
        ok = scene_create(&cfg, &scene, &err);
        if (ok) {
            FILE *json = fopen("/dev/null", "w");
            struct render_result local;
            /* The fault hooks from the environment, as the CLI reads them. */
            struct render_options opt = { &cfg, &scene, NULL, json, { 0, false, STRATEGY_LIGHT_AREA, 1.0 } };
            ok = json && render_faults_parse(getenv("PORTAL_LIGHTS_FAULT_NONFINITE"),
                                             getenv("PORTAL_LIGHTS_FAULT_BIAS"), &opt.faults, &err);
            ok = ok && render_run(&opt, res ? res : &local, &err);
            if (json) fclose(json);
            scene_destroy(&scene);
        }
        config_free(&cfg);
    }
    char file[sizeof dir + 32];
    if (ok) {
        snprintf(file, sizeof file, "%s/final.exr", dir);
        ok = film_read_exr(file, img, &meta, &err);
        free(meta.storage);
    }
    if (!ok) fprintf(stderr, "  render_to_image(%s): %s\n", path, err.message);
    /* Clean the folder: snapshots, final, config. */
    char cmd[sizeof dir + 16];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0) fprintf(stderr, "  could not remove %s\n", dir);
    return ok;
}

/* Largest |z| over square blocks of side `block` between two images, with
   z = (mean_a - mean_b) / sqrt(var_a + var_b) of the block averages, using
   the images' own variance layers. Blocks with no variance are compared
   exactly (z = 0 if equal, +inf otherwise). */
static inline double images_max_block_z(const struct film_image *a, const struct film_image *b, int block)
{
    double worst = 0.0;
    for (int by = 0; by + block <= a->height; by += block)
        for (int bx = 0; bx + block <= a->width; bx += block)
            for (int c = 0; c < 3; ++c) {
                double ma = 0, mb = 0, va = 0, vb = 0;
                int n = block * block;
                for (int y = by; y < by + block; ++y)
                    for (int x = bx; x < bx + block; ++x) {
                        int i = 3 * (y * a->width + x) + c;
                        ma += a->rgb[i], mb += b->rgb[i];
                        va += a->variance[i], vb += b->variance[i];
                    }
                ma /= n, mb /= n, va /= (double)n * n, vb /= (double)n * n;
                double z = va + vb > 0 ? fabs(ma - mb) / sqrt(va + vb) : (ma == mb ? 0.0 : INFINITY);
                if (z > worst) worst = z;
            }
    return worst;
}

#endif

/* relMSE of a against b (mean over pixels and channels of
   (a - b)^2 / (b^2 + 0.01)) and the bound it stays below when both are
   unbiased: its expectation sum (var_a + var_b) / d plus `k` standard
   deviations, with Var[(a - b)^2] = 2 (var_a + var_b)^2 for Gaussian pixel
   errors. */
static inline void images_relmse(const struct film_image *a, const struct film_image *b, double k, double *relmse,
                                 double *bound)
{
    size_t n = (size_t)3 * a->width * a->height;
    double sum = 0.0, expect = 0.0, var = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double d = (double)b->rgb[i] * b->rgb[i] + 0.01;
        double e = (double)a->rgb[i] - b->rgb[i];
        double v = ((double)a->variance[i] + b->variance[i]) / d;
        sum += e * e / d;
        expect += v;
        var += 2.0 * v * v;
    }
    *relmse = sum / n;
    *bound = (expect + k * sqrt(var)) / n;
}

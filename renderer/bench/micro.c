/* micro.c: per-call cost of the portal machinery against one shadow ray, at
   random floor points of a scene with one light/portal pair (the lampshade).

   Cells (each timed in a tight loop over precomputed points, repeated
   round-robin, median reported in ns per call of thread CPU time):
     shadow_ray          scene_occluded from the point to a uniform point on
                         the light (offset origin, shortened segment: what
                         the renderer traces per light sample)
     classify            antishadow_classify
     visible_polygon     antishadow_visible_polygon
     visible_target      target_init + target_sample_solid_angle of the
                         visible polygon (points where it is not empty)
     prepare.S           strategy_prepare for strategy S
     prepare_sample.S    strategy_prepare + strategy_sample
     prepare_pdf.S       strategy_prepare + strategy_pdf of a direction to a
                         uniform point on the light (what MIS asks when a
                         BSDF ray hits the light)
     prepare_sample_many.S  the same as prepare_sample.S through
                         strategy_sample_many over all points at once (what
                         the direct integrator does per film row), for the
                         strategies that batch (light, light_area)
   where S is each strategy with the config's render.portal_weight, and
   antishadow_exact@W with each other weight W (the weight decides how much
   strategy_prepare computes per pair),
   over two point sets: "floor" (uniform over the floor square) and
   "antishadow" (floor points whose region is not outside).

   Then, under "ngon", the cost against the vertex count: the first portal
   ("portal"), or the portal and its light ("light_portal"), replaced by a
   regular n-gon of the same area, centroid, plane and winding, n = 8, 16,
   32 (POLYGON_INPUT_MAX), with the cells classify and
   prepare_sample.antishadow_exact over the same two point sets of that
   scene. Prints one JSON object on stdout. */
#include <stdint.h>

#include "geometry/antishadow.h"
#include "bench_util.h"
#include "config/config.h"
#include "base/rng.h"
#include "scene/scene.h"
#include "sampling/strategy.h"
#include "geometry/target.h"

#define N_POINTS   4096
#define N_VARIANTS (STRATEGY_COUNT + 2)

struct point_set {
    const char *name;
    int n;
    struct vec3 p[N_POINTS];
    double u[N_POINTS][4];
    struct vec3 shadow_o[N_POINTS], shadow_d[N_POINTS];
    double shadow_tmax[N_POINTS];
    struct vec3 wi_light[N_POINTS]; /* towards a uniform point on the light */
    int n_vis;                      /* points with a visible polygon */
    struct polygon vis[N_POINTS];
    int vis_point[N_POINTS];
    int regions[4];
};

enum cell_kind {
    CELL_SHADOW,
    CELL_CLASSIFY,
    CELL_VISIBLE_POLYGON,
    CELL_VISIBLE_TARGET,
    CELL_PREPARE,
    CELL_PREPARE_SAMPLE,
    CELL_PREPARE_PDF,
    CELL_PREPARE_SAMPLE_MANY
};
static const char *const cell_names[] = { "shadow_ray", "classify",       "visible_polygon", "visible_target",
                                          "prepare",    "prepare_sample", "prepare_pdf",     "prepare_sample_many" };

struct cell {
    enum cell_kind kind;
    int strategy;  /* for the strategy cells */
    double ns[64]; /* per rep */
    double wall_ns[64];
};

static struct vec3 light_point(const struct polygon *poly, struct rng *rng)
{
    /* Fan triangle by area, then uniform in it. */
    double areas[POLYGON_MAX], total = 0.0;
    for (int k = 0; k + 2 < poly->n; ++k) {
        areas[k] =
            0.5 * vec3_length(vec3_cross(vec3_sub(poly->v[k + 1], poly->v[0]), vec3_sub(poly->v[k + 2], poly->v[0])));
        total += areas[k];
    }
    double x = rng_uniform(rng) * total;
    int k = 0;
    while (k + 3 < poly->n && x >= areas[k]) x -= areas[k++];
    double su = sqrt(rng_uniform(rng)), b1 = rng_uniform(rng) * su, b0 = 1.0 - su;
    return vec3_add(vec3_add(vec3_scale(poly->v[0], b0), vec3_scale(poly->v[k + 1], b1)),
                    vec3_scale(poly->v[k + 2], 1.0 - b0 - b1));
}

/* Floor points (y = floor_y, x and z in [lo, hi]); inside_only keeps those
   whose region is not outside. */
static void make_points(struct point_set *ps, const char *name, const struct scene *sc, double lo, double hi,
                        bool inside_only)
{
    const struct antishadow *a = &sc->portals[0].antishadow;
    const struct light *l = &sc->lights[sc->portals[0].light];
    struct rng rng;
    rng_seed(&rng, 777, inside_only, 0);
    ps->name = name;
    ps->n = 0;
    ps->n_vis = 0;
    memset(ps->regions, 0, sizeof ps->regions);
    struct vec3 up = vec3_make(0.0, 1.0, 0.0);
    for (long tries = 0; ps->n < N_POINTS && tries < 100000000L; ++tries) {
        struct vec3 p = vec3_make(lo + (hi - lo) * rng_uniform(&rng), 0.0, lo + (hi - lo) * rng_uniform(&rng));
        enum region r = antishadow_classify(a, p);
        if (inside_only && r == REGION_OUTSIDE) continue;
        int i = ps->n++;
        ps->p[i] = p;
        ++ps->regions[r];
        for (int k = 0; k < 4; ++k) ps->u[i][k] = rng_uniform(&rng);
        struct vec3 y = light_point(&l->target.polygon, &rng);
        struct vec3 wi = vec3_normalize(vec3_sub(y, p));
        ps->wi_light[i] = wi;
        ps->shadow_o[i] = scene_offset_origin(sc, p, up, wi);
        ps->shadow_d[i] = wi;
        ps->shadow_tmax[i] =
            vec3_length(vec3_sub(y, ps->shadow_o[i])) * (1.0 - 1e-4) /* shadow rays stop short of the light */;
        struct polygon vis;
        if (antishadow_visible_polygon(a, p, &vis) >= 3) {
            ps->vis[ps->n_vis] = vis;
            ps->vis_point[ps->n_vis++] = i;
        }
    }
}

/* Runs one cell over the whole set once; returns the number of calls and
   adds to *sink so nothing is optimised away. */
static int run_cell(const struct cell *c, const struct point_set *ps, const struct scene *sc,
                    struct strategy *strategies, struct strategy_scratch *scratches, double *sink)
{
    const struct antishadow *a = &sc->portals[0].antishadow;
    struct vec3 up = vec3_make(0.0, 1.0, 0.0);
    double acc = 0.0;
    int calls = 0;
    switch (c->kind) {
    case CELL_SHADOW:
        for (int i = 0; i < ps->n; ++i) acc += scene_occluded(sc, ps->shadow_o[i], ps->shadow_d[i], ps->shadow_tmax[i]);
        calls = ps->n;
        break;
    case CELL_CLASSIFY:
        for (int i = 0; i < ps->n; ++i) acc += antishadow_classify(a, ps->p[i]);
        calls = ps->n;
        break;
    case CELL_VISIBLE_POLYGON:
        for (int i = 0; i < ps->n; ++i) {
            struct polygon vis;
            acc += antishadow_visible_polygon(a, ps->p[i], &vis);
        }
        calls = ps->n;
        break;
    case CELL_VISIBLE_TARGET:
        for (int j = 0; j < ps->n_vis; ++j) {
            int i = ps->vis_point[j];
            struct target t;
            struct target_point tp;
            if (target_init(&t, &ps->vis[j]) &&
                target_sample_solid_angle(&t, ps->p[i], ps->u[i][1], ps->u[i][2], ps->u[i][3], &tp))
                acc += tp.pdf_sa;
        }
        calls = ps->n_vis;
        break;
    case CELL_PREPARE:
    case CELL_PREPARE_SAMPLE:
    case CELL_PREPARE_PDF: {
        const struct strategy *s = &strategies[c->strategy];
        struct strategy_scratch *scr = &scratches[c->strategy];
        for (int i = 0; i < ps->n; ++i) {
            struct strategy_point pt;
            strategy_prepare(s, scr, ps->p[i], up, &pt);
            acc += pt.total;
            if (c->kind == CELL_PREPARE_SAMPLE) {
                struct light_sample ls;
                if (strategy_sample(s, &pt, ps->u[i], &ls)) acc += ls.pdf_sa;
            } else if (c->kind == CELL_PREPARE_PDF) {
                acc += strategy_pdf(s, &pt, sc->portals[0].light, ps->wi_light[i]);
            }
        }
        calls = ps->n;
        break;
    }
    case CELL_PREPARE_SAMPLE_MANY: {
        const struct strategy *s = &strategies[c->strategy];
        static struct strategy_point pts[N_POINTS];
        static struct light_sample ls[N_POINTS];
        static bool ok[N_POINTS];
        for (int i = 0; i < ps->n; ++i) strategy_prepare(s, &scratches[c->strategy], ps->p[i], up, &pts[i]);
        strategy_sample_many(s, pts, (const double(*)[4])ps->u, ps->n, ls, ok);
        for (int i = 0; i < ps->n; ++i)
            if (ok[i]) acc += ls[i].pdf_sa;
        calls = ps->n;
        break;
    }
    }
    *sink += acc;
    return calls;
}

/* Times one cell over one set: reps rounds of at least min_ms each;
   fills cl->ns and cl->wall_ns. */
static void time_cell(struct cell *cl, const struct point_set *ps, const struct scene *sc, struct strategy *strategies,
                      struct strategy_scratch *scratches, int r, double min_ms, double *sink)
{
    long calls = 0;
    double c0 = timing_thread_cpu_s(), w0 = timing_now_s(), c1 = c0;
    do {
        calls += run_cell(cl, ps, sc, strategies, scratches, sink);
        c1 = timing_thread_cpu_s();
    } while ((c1 - c0) * 1e3 < min_ms && calls < 100000000L);
    double w1 = timing_now_s();
    cl->ns[r] = calls ? (c1 - c0) * 1e9 / (double)calls : 0.0;
    cl->wall_ns[r] = calls ? (w1 - w0) * 1e9 / (double)calls : 0.0;
}

/* A regular n-gon with the area, centroid, plane and winding of poly (its
   first vertex towards poly's first vertex). */
static struct polygon ngon_like(const struct polygon *poly, int n)
{
    struct vec3 c = polygon_centroid(poly), nrm = polygon_normal(poly);
    double r = sqrt(2.0 * polygon_area(poly) / (n * sin(2.0 * M_PI / n)));
    struct vec3 d = vec3_sub(poly->v[0], c);
    struct vec3 u = vec3_normalize(vec3_sub(d, vec3_scale(nrm, vec3_dot(d, nrm))));
    struct vec3 w = vec3_cross(nrm, u); /* u, w, nrm right-handed: counter-clockwise about nrm */
    struct polygon out;
    out.n = n;
    for (int i = 0; i < n; ++i) {
        double a = 2.0 * M_PI * i / n;
        out.v[i] = vec3_add(c, vec3_add(vec3_scale(u, r * cos(a)), vec3_scale(w, r * sin(a))));
    }
    return out;
}

static const int ngon_counts[] = { 8, 16, 32 };
static const char *const ngon_variants[] = { "portal", "light_portal" };
#define N_NGON (3 * 2)

/* The two cells of one n-gon scene, per point set. */
struct ngon_result {
    int n, variant;
    int points[2], regions[2][4];
    struct cell classify[2], sample[2];
};

/* Builds the n-gon variant of cfg's first pair and times its cells. False
   with a message when the scene cannot be built. */
static bool ngon_run(const struct config *cfg, int n, int variant, double lo, double hi, int reps, double min_ms,
                     struct ngon_result *res, double *sink, struct error *err)
{
    static struct point_set sets[2];
    struct config c = *cfg;
    struct portal_desc *portals = malloc(sizeof *portals * (size_t)cfg->n_portals);
    struct light_desc *lights = malloc(sizeof *lights * (size_t)cfg->n_lights);
    if (!portals || !lights) {
        free(portals);
        free(lights);
        return error_set(err, "out of memory");
    }
    memcpy(portals, cfg->portals, sizeof *portals * (size_t)cfg->n_portals);
    memcpy(lights, cfg->lights, sizeof *lights * (size_t)cfg->n_lights);
    portals[0].polygon = ngon_like(&cfg->portals[0].polygon, n);
    if (variant == 1) lights[portals[0].light].polygon = ngon_like(&cfg->lights[portals[0].light].polygon, n);
    c.portals = portals;
    c.lights = lights;
    struct scene sc;
    struct strategy st;
    struct strategy_scratch scr;
    struct render_desc rd = cfg->render;
    rd.strategy = STRATEGY_ANTISHADOW_EXACT;
    bool ok = scene_create(&c, &sc, err);
    if (ok && !(strategy_init(&st, &sc, &rd, err) && strategy_scratch_init(&st, &scr, err))) {
        scene_destroy(&sc);
        ok = false;
    }
    if (ok) {
        res->n = n;
        res->variant = variant;
        make_points(&sets[0], "floor", &sc, lo, hi, false);
        make_points(&sets[1], "antishadow", &sc, lo, hi, true);
        for (int s = 0; s < 2; ++s) {
            res->points[s] = sets[s].n;
            memcpy(res->regions[s], sets[s].regions, sizeof res->regions[s]);
            res->classify[s] = (struct cell){ .kind = CELL_CLASSIFY };
            res->sample[s] = (struct cell){ .kind = CELL_PREPARE_SAMPLE, .strategy = 0 };
            run_cell(&res->classify[s], &sets[s], &sc, &st, &scr, sink); /* warm-up */
            run_cell(&res->sample[s], &sets[s], &sc, &st, &scr, sink);
        }
        for (int r = 0; r < reps; ++r)
            for (int s = 0; s < 2; ++s) {
                time_cell(&res->classify[s], &sets[s], &sc, &st, &scr, r, min_ms, sink);
                time_cell(&res->sample[s], &sets[s], &sc, &st, &scr, r, min_ms, sink);
            }
        strategy_scratch_free(&scr);
        strategy_free(&st);
        scene_destroy(&sc);
    }
    free(portals);
    free(lights);
    return ok;
}

static void usage(const char *argv0)
{
    fprintf(stderr,
            "usage: %s CONFIG [--set KEY=VALUE]... [--reps R] [--min-ms MS] [--floor LO HI]\n"
            "Times portal classification, projection and sampling against shadow rays at floor\n"
            "points (y = 0, x and z in [LO, HI], default -3 3) of a scene whose first portal is\n"
            "the one studied; prints one JSON object on stdout.\n",
            argv0);
}

int main(int argc, char **argv)
{
    const char *path = NULL;
    struct bench_overrides ov = { 0 };
    int reps = 7;
    double min_ms = 20.0, lo = -3.0, hi = 3.0;
    for (int i = 1; i < argc; ++i) {
        if (bench_take_set(&ov, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--min-ms") && i + 1 < argc) min_ms = atof(argv[++i]);
        else if (!strcmp(argv[i], "--floor") && i + 2 < argc) lo = atof(argv[++i]), hi = atof(argv[++i]);
        else if (argv[i][0] != '-' && !path) path = argv[i];
        else {
            usage(argv[0]);
            return 2;
        }
    }
    if (!path || reps < 1 || reps > 64 || !(min_ms > 0.0) || !(hi > lo)) {
        usage(argv[0]);
        return 2;
    }
    struct error err = { { 0 } };
    struct config cfg;
    if (!config_load(path, ov.items, ov.n, &cfg, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 2;
    }
    struct scene sc;
    if (!scene_create(&cfg, &sc, &err)) {
        fprintf(stderr, "%s\n", err.message);
        config_free(&cfg);
        return 2;
    }
    if (sc.n_portals < 1) {
        fprintf(stderr, "micro: %s has no portal\n", path);
        return 2;
    }

    /* Every strategy with the config's portal weight, then antishadow_exact
       with each other weight (the weight decides what strategy_prepare computes). */
    struct strategy strategies[N_VARIANTS];
    struct strategy_scratch scratches[N_VARIANTS];
    char variant_names[N_VARIANTS][64];
    int n_variants = 0;
    for (int k = 0; k < STRATEGY_COUNT + 3; ++k) {
        struct render_desc rd = cfg.render;
        if (k < STRATEGY_COUNT) {
            rd.strategy = (enum strategy_kind)k;
            snprintf(variant_names[n_variants], sizeof variant_names[0], "%s", strategy_names[k]);
        } else {
            rd.strategy = STRATEGY_ANTISHADOW_EXACT;
            rd.portal_weight = (enum portal_weight_kind)(k - STRATEGY_COUNT);
            if (rd.portal_weight == cfg.render.portal_weight) continue;
            snprintf(variant_names[n_variants], sizeof variant_names[0], "%s@%s",
                     strategy_names[STRATEGY_ANTISHADOW_EXACT], portal_weight_names[rd.portal_weight]);
        }
        int k_out = n_variants++;
        if (!strategy_init(&strategies[k_out], &sc, &rd, &err) ||
            !strategy_scratch_init(&strategies[k_out], &scratches[k_out], &err)) {
            fprintf(stderr, "micro: %s\n", err.message);
            return 1;
        }
    }

    static struct point_set sets[2];
    make_points(&sets[0], "floor", &sc, lo, hi, false);
    make_points(&sets[1], "antishadow", &sc, lo, hi, true);
    fprintf(stderr, "micro: %d floor points (%d with a visible polygon), %d antishadow points\n", sets[0].n,
            sets[0].n_vis, sets[1].n);

    static struct cell cells[2][4 + 4 * N_VARIANTS];
    int n_cells = 0;
    for (int s = 0; s < 2; ++s) {
        int n = 0;
        cells[s][n++] = (struct cell){ .kind = CELL_SHADOW };
        cells[s][n++] = (struct cell){ .kind = CELL_CLASSIFY };
        cells[s][n++] = (struct cell){ .kind = CELL_VISIBLE_POLYGON };
        cells[s][n++] = (struct cell){ .kind = CELL_VISIBLE_TARGET };
        for (int k = 0; k < n_variants; ++k) {
            cells[s][n++] = (struct cell){ .kind = CELL_PREPARE, .strategy = k };
            cells[s][n++] = (struct cell){ .kind = CELL_PREPARE_SAMPLE, .strategy = k };
            cells[s][n++] = (struct cell){ .kind = CELL_PREPARE_PDF, .strategy = k };
            if (strategy_batches(&strategies[k]))
                cells[s][n++] = (struct cell){ .kind = CELL_PREPARE_SAMPLE_MANY, .strategy = k };
        }
        n_cells = n;
    }

    double sink = 0.0;
    /* Warm-up: every cell once per set. */
    for (int s = 0; s < 2; ++s)
        for (int c = 0; c < n_cells; ++c) run_cell(&cells[s][c], &sets[s], &sc, strategies, scratches, &sink);
    for (int r = 0; r < reps; ++r) {
        fprintf(stderr, "micro: round %d/%d\n", r + 1, reps);
        for (int s = 0; s < 2; ++s)
            for (int c = 0; c < n_cells; ++c) {
                time_cell(&cells[s][c], &sets[s], &sc, strategies, scratches, r, min_ms, &sink);
            }
    }
    static struct ngon_result ngon[N_NGON];
    for (int k = 0; k < N_NGON; ++k) {
        int n = ngon_counts[k / 2], variant = k % 2;
        fprintf(stderr, "micro: %d-gon %s\n", n, ngon_variants[variant]);
        if (!ngon_run(&cfg, n, variant, lo, hi, reps, min_ms, &ngon[k], &sink, &err)) {
            fprintf(stderr, "micro: %d-gon %s: %s\n", n, ngon_variants[variant], err.message);
            return 1;
        }
    }

    printf("{\"config\":\"%s\",\"portal_weight\":\"%s\",\"reps\":%d,\"min_ms\":%g,\"floor\":[%g,%g],"
           "\"clock\":\"thread CPU time\",\"sets\":{",
           path, portal_weight_names[cfg.render.portal_weight], reps, min_ms, lo, hi);
    for (int s = 0; s < 2; ++s) {
        const struct point_set *ps = &sets[s];
        printf("%s\"%s\":{\"points\":%d,\"visible_points\":%d,\"regions\":{\"outside\":%d,\"anti_umbra\":%d,"
               "\"anti_penumbra\":%d,\"anti_antumbra\":%d},\"cells\":{",
               s ? "," : "", ps->name, ps->n, ps->n_vis, ps->regions[REGION_OUTSIDE], ps->regions[REGION_ANTI_UMBRA],
               ps->regions[REGION_ANTI_PENUMBRA], ps->regions[REGION_ANTI_ANTUMBRA]);
        for (int c = 0; c < n_cells; ++c) {
            struct cell *cl = &cells[s][c];
            char name[96];
            if (cl->kind >= CELL_PREPARE)
                snprintf(name, sizeof name, "%s.%s", cell_names[cl->kind], variant_names[cl->strategy]);
            else snprintf(name, sizeof name, "%s", cell_names[cl->kind]);
            printf("%s\"%s\":{\"ns\":[", c ? "," : "", name);
            for (int r = 0; r < reps; ++r) printf("%s%.2f", r ? "," : "", cl->ns[r]);
            printf("],\"wall_ns\":[");
            for (int r = 0; r < reps; ++r) printf("%s%.2f", r ? "," : "", cl->wall_ns[r]);
            double med = bench_median(cl->ns, reps), medw = bench_median(cl->wall_ns, reps);
            printf("],\"median_ns\":%.3f,\"median_wall_ns\":%.3f}", med, medw);
        }
        printf("}}");
    }
    printf("},\"ngon\":[");
    for (int k = 0; k < N_NGON; ++k) {
        struct ngon_result *g = &ngon[k];
        printf("%s{\"n\":%d,\"variant\":\"%s\",\"sets\":{", k ? "," : "", g->n, ngon_variants[g->variant]);
        for (int s = 0; s < 2; ++s)
            printf("%s\"%s\":{\"points\":%d,\"regions\":{\"outside\":%d,\"anti_umbra\":%d,\"anti_penumbra\":%d,"
                   "\"anti_antumbra\":%d},\"classify_ns\":%.3f,\"prepare_sample_ns\":%.3f}",
                   s ? "," : "", sets[s].name, g->points[s], g->regions[s][REGION_OUTSIDE],
                   g->regions[s][REGION_ANTI_UMBRA], g->regions[s][REGION_ANTI_PENUMBRA],
                   g->regions[s][REGION_ANTI_ANTUMBRA], bench_median(g->classify[s].ns, reps),
                   bench_median(g->sample[s].ns, reps));
        printf("}}");
    }
    printf("],\"sink\":%g}\n", sink != sink ? 0.0 : 1.0);

    for (int k = 0; k < n_variants; ++k) {
        strategy_scratch_free(&scratches[k]);
        strategy_free(&strategies[k]);
    }
    scene_destroy(&sc);
    config_free(&cfg);
    return 0;
}

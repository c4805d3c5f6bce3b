/* scan.c: from one floor point of the lampshade (s_L = 1.2), rays aimed
   across each edge line of the bottom plate at y = 2.2, in steps of 1e-9:
   which of them reach the light with the antishadow_exact strategy's pdf 0.
   Prints, per line, how many aims leak and the band of offsets that does.
   Usage: scan [config [px py pz]] */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>

#include "config/config.h"
#include "scene/scene.h"
#include "sampling/shading.h"
#include "sampling/strategy.h"

int main(int argc, char **argv)
{
    struct vec3 p = vec3_make(0.058881601, 0.000000140, 1.671687595);
    const char *path = argc > 1 ? argv[1] : "configs/scenes/lampshade.yaml";
    if (argc > 4) p = vec3_make(atof(argv[2]), atof(argv[3]), atof(argv[4]));
    struct config_override ov[] = { { "params.s_L", "1.2" }, { "render.strategy", "antishadow_exact" } };
    struct config cfg;
    struct scene sc;
    struct error err;
    if (!config_load(path, ov, 2, &cfg, &err) || !scene_create(&cfg, &sc, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    struct strategy st;
    struct strategy_scratch scr;
    if (!strategy_init(&st, &sc, &cfg.render, &err) || !strategy_scratch_init(&st, &scr, &err)) return 1;
    struct vec3 n = vec3_make(0, 1, 0);
    struct strategy_point sp;
    strategy_prepare(&st, &scr, p, n, &sp);
    const double a = 0.65, h = 0.15;
    /* Lines: a fixed coordinate (x or z) at value c, the other running over [lo, hi]. */
    struct {
        const char *name;
        int fixed_is_x;
        double c, lo, hi;
    } lines[] = {
        { "z=-h, x in [-a,-h]  T: bottom_back | bottom_left", 0, -h, -a, -h },
        { "z=-h, x in [h,a]    T: bottom_back | bottom_right", 0, -h, h, a },
        { "z=+h, x in [-a,-h]  T: bottom_front | bottom_left", 0, h, -a, -h },
        { "z=+h, x in [h,a]    T: bottom_front | bottom_right", 0, h, h, a },
        { "z=-h, x in [-h,h]   hole edge (bottom_back)", 0, -h, -h, h },
        { "z=+h, x in [-h,h]   hole edge (bottom_front)", 0, h, -h, h },
        { "x=-h, z in [-h,h]   hole edge (bottom_left)", 1, -h, -h, h },
        { "x=+h, z in [-h,h]   hole edge (bottom_right)", 1, h, -h, h },
        { "x=-a, z in [-a,a]   rim: shade_left | plates", 1, -a, -a, a },
        { "x=+a, z in [-a,a]   rim: shade_right | plates", 1, a, -a, a },
        { "z=+a, x in [-a,a]   rim: shade_front | bottom_front", 0, a, -a, a },
        { "diagonal of bottom_back's quad, x in [-a,-h] (shared edge)", 0, 0, -a + 0.01, -h - 0.01 },
        { "x=-h diag? interior z in [-a,-h] x=-0.4 (control, plate interior)", 1, -0.4, -a + 0.01, -h - 0.01 },
    };
    const int n_along = 200, n_off = 4001;
    const double step = 1e-9;
    struct integrator_stats stats = { 0 };
    (void)stats;
    for (size_t li = 0; li < sizeof lines / sizeof lines[0]; ++li) {
        long leaks = 0, light_in_portal = 0, blocked = 0, aims = 0;
        double off_min = INFINITY, off_max = -INFINITY;
        for (int i = 0; i < n_along; ++i) {
            double s = lines[li].lo + (lines[li].hi - lines[li].lo) * (i + 0.5) / n_along;
            for (int j = 0; j < n_off; ++j) {
                double off = (j - n_off / 2) * step;
                struct vec3 tgt;
                if (li == 11) {
                    /* Diagonal v1 = (a, -a) to v3 = (-a, -h) of shade_bottom_back: z(x) = -a + (a - x) (a - h) / (2 a). */
                    tgt = vec3_make(s, 2.2, -a + (a - s) * (a - h) / (2 * a) + off);
                } else {
                    tgt = lines[li].fixed_is_x ? vec3_make(lines[li].c + off, 2.2, s)
                                               : vec3_make(s, 2.2, lines[li].c + off);
                }
                struct vec3 d = vec3_normalize(vec3_sub(tgt, p));
                struct vec3 o = scene_offset_origin(&sc, p, n, d);
                ++aims;
                int l = scene_first_light(&sc, o, d, INFINITY);
                if (l < 0) {
                    ++blocked;
                    continue;
                }
                double pdf = strategy_pdf(&st, &sp, l, d);
                if (pdf > 0.0) {
                    ++light_in_portal;
                    continue;
                }
                ++leaks;
                off_min = fmin(off_min, off);
                off_max = fmax(off_max, off);
            }
        }
        printf("%-70s aims %ld: blocked %ld, light pdf>0 %ld, LEAK (light, pdf 0) %ld", lines[li].name, aims, blocked,
               light_in_portal, leaks);
        if (leaks)
            printf("  offsets [%.3g, %.3g], mean leak width %.3g", off_min, off_max, (double)leaks / n_along * step);
        printf("\n");
    }
    return 0;
}

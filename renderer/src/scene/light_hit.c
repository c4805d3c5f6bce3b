/* light_hit.c: the first polygon light along a ray, analytically (see
   light_hit.h). */
#include "scene/light_hit.h"

#include <math.h>

#include "base/fastmath.h"

bool light_hit_set_init(struct light_hit_set *set, const struct light *lights, int n)
{
    set->n_lights = 0;
    if (n > LIGHT_HIT_MAX_LIGHTS) return false;
    int edges = 0;
    for (int l = 0; l < n; ++l) edges += lights[l].target.polygon.n;
    if (edges > LIGHT_HIT_MAX_EDGES) return false;
    edges = 0;
    for (int l = 0; l < n; ++l) {
        const struct polygon *poly = &lights[l].target.polygon;
        struct vec3 nrm = lights[l].target.normal;
        set->nx[l] = nrm.x, set->ny[l] = nrm.y, set->nz[l] = nrm.z;
        set->nc[l] = vec3_dot(nrm, poly->v[0]);
        set->first_edge[l] = edges;
        /* The winding runs counter-clockwise about the normal (target.h),
           so n x (v[k+1] - v[k]) points into the polygon. */
        for (int k = 0; k < poly->n; ++k, ++edges) {
            struct vec3 a = poly->v[k], b = poly->v[(k + 1) % poly->n];
            struct vec3 m = vec3_cross(nrm, vec3_sub(b, a));
            set->mx[edges] = m.x, set->my[edges] = m.y, set->mz[edges] = m.z;
            set->mc[edges] = vec3_dot(m, a);
        }
    }
    set->first_edge[n] = edges;
    set->n_lights = n;
    return true;
}

/* Rays per block: the block's best distances and lights stay in the cache
   while every light is tested against them. */
#define HIT_BLOCK 64

/* Light l against the m rays of a block: where it is met inside
   [tnear, tfar], inside its polygon and nearer than the block's best so
   far, it becomes the best. Three kinds of loops over the rays, each
   vectorised: the plane, one per edge (a loop over the edges inside a
   ray's would not vectorise), and the choice. */
FM_SIMD_CLONES
static void test_light(const struct light_hit_set *set, int l, const float *ox, const float *oy, const float *oz,
                       const float *dx, const float *dy, const float *dz, const float *tnear, const float *tfar, int m,
                       double *best_t, int *best_l)
{
    double nx = set->nx[l], ny = set->ny[l], nz = set->nz[l], nc = set->nc[l];
    double t[HIT_BLOCK], hx[HIT_BLOCK], hy[HIT_BLOCK], hz[HIT_BLOCK];
    int ok[HIT_BLOCK];
#pragma omp simd
    for (int i = 0; i < m; ++i) {
        double px = ox[i], py = oy[i], pz = oz[i], qx = dx[i], qy = dy[i], qz = dz[i];
        double den = nx * qx + ny * qy + nz * qz;
        /* den = 0 gives an infinite or NaN t, which no test below passes. */
        double ti = (nc - (nx * px + ny * py + nz * pz)) / den;
        ok[i] = (ti >= (double)tnear[i]) & (ti <= (double)tfar[i]) & (ti < best_t[i]);
        t[i] = ti;
        hx[i] = px + ti * qx, hy[i] = py + ti * qy, hz[i] = pz + ti * qz;
    }
    for (int e = set->first_edge[l]; e < set->first_edge[l + 1]; ++e) {
        double mx = set->mx[e], my = set->my[e], mz = set->mz[e], mc = set->mc[e];
#pragma omp simd
        for (int i = 0; i < m; ++i) ok[i] &= mx * hx[i] + my * hy[i] + mz * hz[i] >= mc;
    }
#pragma omp simd
    for (int i = 0; i < m; ++i) {
        best_t[i] = ok[i] ? t[i] : best_t[i];
        best_l[i] = ok[i] ? l : best_l[i];
    }
}

void light_hit_many(const struct light_hit_set *set, const float *ox, const float *oy, const float *oz, const float *dx,
                    const float *dy, const float *dz, const float *tnear, const float *tfar, int n, int *light,
                    double *t)
{
    for (int i0 = 0; i0 < n; i0 += HIT_BLOCK) {
        int m = n - i0 < HIT_BLOCK ? n - i0 : HIT_BLOCK;
        for (int i = 0; i < m; ++i) t[i0 + i] = INFINITY, light[i0 + i] = -1;
        for (int l = 0; l < set->n_lights; ++l)
            test_light(set, l, ox + i0, oy + i0, oz + i0, dx + i0, dy + i0, dz + i0, tnear + i0, tfar + i0, m, t + i0,
                       light + i0);
    }
}

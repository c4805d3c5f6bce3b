#include "geometry/mesh_components.h"

#include <stdlib.h>

struct keyed {
    struct vec3 p;
    int index;
};

/* Lexicographic on (x, y, z), then the index: equal positions end up
   adjacent, in a deterministic order. */
static int compare_keyed(const void *a, const void *b)
{
    const struct keyed *u = a, *v = b;
    if (u->p.x != v->p.x) return u->p.x < v->p.x ? -1 : 1;
    if (u->p.y != v->p.y) return u->p.y < v->p.y ? -1 : 1;
    if (u->p.z != v->p.z) return u->p.z < v->p.z ? -1 : 1;
    return u->index - v->index;
}

/* Union-find root with path halving. */
static int root_of(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

static void join(int *parent, int a, int b)
{
    a = root_of(parent, a);
    b = root_of(parent, b);
    if (a != b) parent[a < b ? b : a] = a < b ? a : b;
}

int mesh_components(const struct vec3 *verts, int n_verts, const int (*quads)[4], int n_quads, const int (*tris)[3],
                    int n_tris, int *label)
{
    size_t nv = n_verts > 0 ? (size_t)n_verts : 1;
    struct keyed *sorted = malloc(sizeof *sorted * nv);
    int *parent = malloc(sizeof *parent * nv);
    int *numbered = malloc(sizeof *numbered * nv);
    if (!sorted || !parent || !numbered) {
        free(sorted);
        free(parent);
        free(numbered);
        return -1;
    }
    /* Welded by position: each vertex starts joined to the first vertex of
       its position. */
    for (int i = 0; i < n_verts; ++i) sorted[i] = (struct keyed){ verts[i], i };
    qsort(sorted, (size_t)n_verts, sizeof *sorted, compare_keyed);
    for (int i = 0; i < n_verts; ++i) parent[i] = i;
    for (int i = 1; i < n_verts; ++i) {
        const struct vec3 a = sorted[i - 1].p, b = sorted[i].p;
        if (a.x == b.x && a.y == b.y && a.z == b.z) join(parent, sorted[i - 1].index, sorted[i].index);
    }
    for (int q = 0; q < n_quads; ++q)
        for (int k = 1; k < 4; ++k) join(parent, quads[q][0], quads[q][k]);
    for (int t = 0; t < n_tris; ++t)
        for (int k = 1; k < 3; ++k) join(parent, tris[t][0], tris[t][k]);
    for (int i = 0; i < n_verts; ++i) numbered[i] = -1;
    int count = 0;
    for (int f = 0; f < n_quads + n_tris; ++f) {
        int r = root_of(parent, f < n_quads ? quads[f][0] : tris[f - n_quads][0]);
        if (numbered[r] < 0) numbered[r] = count++;
        label[f] = numbered[r];
    }
    free(sorted);
    free(parent);
    free(numbered);
    return count;
}

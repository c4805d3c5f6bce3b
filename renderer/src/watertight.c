#include "watertight.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Why this exists: the lampshade's bottom plate is four quads around the
   hole, and the corners of the side quads lie on the long edges of the
   front and back ones (T-junctions). Embree's robust mode is watertight
   only across edges whose endpoints are identical, so rays slipped through
   those lines: tools/firefly/scan.c counted 1209 to 1985 leaking aims per
   line out of 800 200 (a band ~1e-8 wide), and one such BSDF ray, reaching
   the lamp where the portal strategies' pdf is 0, made the firefly of
   pixel (130, 204) (tools/firefly/README.md). After stitching: 0. */

/* Grid cells per axis at most 2^21, so that a cell's key packs into 64
   bits; the cell size grows when the scene would need more. */
#define GRID_BITS 21
#define GRID_MAX  ((int64_t)1 << GRID_BITS)

static int cmp_vec3(const void *pa, const void *pb)
{
    const struct vec3 *a = pa, *b = pb;
    if (a->x != b->x) return a->x < b->x ? -1 : 1;
    if (a->y != b->y) return a->y < b->y ? -1 : 1;
    if (a->z != b->z) return a->z < b->z ? -1 : 1;
    return 0;
}

struct cell_entry {
    uint64_t key;
    int point;
};

static int cmp_entry(const void *pa, const void *pb)
{
    const struct cell_entry *a = pa, *b = pb;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return (a->point > b->point) - (a->point < b->point);
}

/* A uniform grid over the distinct vertex positions, stored as entries
   sorted by cell key (no hash table needed: a cell is a binary search). A
   point is entered in every cell its tolerance box touches, so a query only
   has to visit the cells the edge itself passes through. */
struct grid {
    struct vec3 lo;
    double cell;
    int n_points;
    struct vec3 *points;
    int n_entries;
    struct cell_entry *entries;
};

static int64_t cell_coord(double x, double lo, double cell)
{
    double c = floor((x - lo) / cell);
    if (!(c >= 0.0)) return 0;
    return c >= (double)(GRID_MAX - 1) ? GRID_MAX - 1 : (int64_t)c;
}

static uint64_t cell_key(int64_t ix, int64_t iy, int64_t iz)
{
    return (uint64_t)ix | (uint64_t)iy << GRID_BITS | (uint64_t)iz << (2 * GRID_BITS);
}

/* Index of the first entry with key >= k. */
static int grid_lower_bound(const struct grid *g, uint64_t k)
{
    int lo = 0, hi = g->n_entries;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (g->entries[mid].key < k) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static bool grid_build(const struct watertight_face *faces, int n, double *eps_out, struct grid *g, struct error *err)
{
    memset(g, 0, sizeof *g);
    size_t n_corners = 0;
    for (int f = 0; f < n; ++f) n_corners += (size_t)faces[f].n;
    g->points = malloc(sizeof *g->points * (n_corners > 0 ? n_corners : 1));
    if (!g->points) return error_set(err, "out of memory stitching %d faces", n);
    double edge_sum = 0.0;
    size_t k = 0;
    for (int f = 0; f < n; ++f)
        for (int i = 0; i < faces[f].n; ++i) {
            g->points[k++] = faces[f].v[i];
            edge_sum += vec3_length(vec3_sub(faces[f].v[(i + 1) % faces[f].n], faces[f].v[i]));
        }
    qsort(g->points, n_corners, sizeof *g->points, cmp_vec3);
    size_t u = 0;
    for (size_t i = 0; i < n_corners; ++i)
        if (u == 0 || cmp_vec3(&g->points[u - 1], &g->points[i]) != 0) g->points[u++] = g->points[i];
    g->n_points = (int)u;

    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    for (int i = 0; i < g->n_points; ++i) {
        struct vec3 p = g->points[i];
        lo = vec3_make(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
        hi = vec3_make(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
    }
    double scale = g->n_points > 0 ? vec3_length(vec3_sub(hi, lo)) : 1.0;
    if (!(scale > 0.0) || !isfinite(scale)) scale = 1.0;
    double eps = WATERTIGHT_TOLERANCE * scale;
    /* Cells about as large as the mean edge: a surface mesh then has a few
       vertices per cell, and an edge crosses about one cell per its length
       over the mean, so the total work is linear in the edges. */
    double cell = n_corners > 0 ? edge_sum / (double)n_corners : 1.0;
    double extent = fmax(hi.x - lo.x, fmax(hi.y - lo.y, hi.z - lo.z));
    if (!(cell >= extent / (double)(GRID_MAX / 2))) cell = extent / (double)(GRID_MAX / 2);
    if (!(cell > 0.0) || !isfinite(cell)) cell = scale;
    g->lo = vec3_make(lo.x - eps, lo.y - eps, lo.z - eps);
    g->cell = cell;

    g->entries = malloc(sizeof *g->entries * (size_t)8 * (u > 0 ? u : 1));
    if (!g->entries) return error_set(err, "out of memory stitching %d faces", n);
    int m = 0;
    for (int i = 0; i < g->n_points; ++i) {
        struct vec3 p = g->points[i];
        int64_t x0 = cell_coord(p.x - eps, g->lo.x, cell), x1 = cell_coord(p.x + eps, g->lo.x, cell);
        int64_t y0 = cell_coord(p.y - eps, g->lo.y, cell), y1 = cell_coord(p.y + eps, g->lo.y, cell);
        int64_t z0 = cell_coord(p.z - eps, g->lo.z, cell), z1 = cell_coord(p.z + eps, g->lo.z, cell);
        /* eps is far below a cell, so the box touches at most 2 cells per axis. */
        for (int64_t z = z0; z <= z1 && z <= z0 + 1; ++z)
            for (int64_t y = y0; y <= y1 && y <= y0 + 1; ++y)
                for (int64_t x = x0; x <= x1 && x <= x0 + 1; ++x)
                    g->entries[m++] = (struct cell_entry){ cell_key(x, y, z), i };
    }
    g->n_entries = m;
    qsort(g->entries, (size_t)m, sizeof *g->entries, cmp_entry);
    *eps_out = eps;
    return true;
}

static void grid_free(struct grid *g)
{
    free(g->points);
    free(g->entries);
}

/* A vertex found on an edge: where along it (0..1), and which point. */
struct on_edge {
    double t;
    int point;
};

static int cmp_on_edge(const void *pa, const void *pb)
{
    const struct on_edge *a = pa, *b = pb;
    if (a->t != b->t) return a->t < b->t ? -1 : 1;
    return (a->point > b->point) - (a->point < b->point);
}

/* A growable array of on_edge. */
struct on_edge_list {
    int n, cap;
    struct on_edge *items;
};

static bool list_push(struct on_edge_list *l, struct on_edge e, struct error *err)
{
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 16;
        struct on_edge *items = realloc(l->items, sizeof *items * (size_t)cap);
        if (!items) return error_set(err, "out of memory stitching faces");
        l->items = items, l->cap = cap;
    }
    l->items[l->n++] = e;
    return true;
}

/* Appends to l, sorted along the edge, the distinct points within eps of the
   open segment a..b and farther than eps from both ends. The segment is
   walked in pieces no longer than a cell, and each piece visits the cells
   of its bounding box. */
static bool edge_find(const struct grid *g, double eps, struct vec3 a, struct vec3 b, struct on_edge_list *l,
                      struct error *err)
{
    struct vec3 d = vec3_sub(b, a);
    double len2 = vec3_length2(d), len = sqrt(len2);
    l->n = 0;
    if (!(len > 2.0 * eps)) return true;
    double steps_d = ceil(len / g->cell);
    int steps = steps_d < 1.0 ? 1 : steps_d > 4.0 * (double)GRID_MAX ? (int)(4 * GRID_MAX) : (int)steps_d;
    for (int s = 0; s < steps; ++s) {
        struct vec3 p0 = vec3_madd(a, d, (double)s / steps), p1 = vec3_madd(a, d, (double)(s + 1) / steps);
        int64_t x0 = cell_coord(fmin(p0.x, p1.x), g->lo.x, g->cell),
                x1 = cell_coord(fmax(p0.x, p1.x), g->lo.x, g->cell);
        int64_t y0 = cell_coord(fmin(p0.y, p1.y), g->lo.y, g->cell),
                y1 = cell_coord(fmax(p0.y, p1.y), g->lo.y, g->cell);
        int64_t z0 = cell_coord(fmin(p0.z, p1.z), g->lo.z, g->cell),
                z1 = cell_coord(fmax(p0.z, p1.z), g->lo.z, g->cell);
        for (int64_t z = z0; z <= z1; ++z)
            for (int64_t y = y0; y <= y1; ++y)
                for (int64_t x = x0; x <= x1; ++x) {
                    uint64_t key = cell_key(x, y, z);
                    for (int e = grid_lower_bound(g, key); e < g->n_entries && g->entries[e].key == key; ++e) {
                        struct vec3 p = g->points[g->entries[e].point];
                        struct vec3 ap = vec3_sub(p, a);
                        double t = vec3_dot(ap, d) / len2;
                        double along = t * len;
                        if (!(along > eps && along < len - eps)) continue;
                        if (vec3_length(vec3_sub(ap, vec3_scale(d, t))) > eps) continue;
                        if (!list_push(l, (struct on_edge){ t, g->entries[e].point }, err)) return false;
                    }
                }
    }
    /* A point near a cell boundary is found from several cells. */
    if (l->n > 1) qsort(l->items, (size_t)l->n, sizeof *l->items, cmp_on_edge);
    int u = 0;
    for (int i = 0; i < l->n; ++i) {
        bool seen = false;
        for (int j = u - 1; j >= 0 && l->items[j].t == l->items[i].t; --j)
            seen |= l->items[j].point == l->items[i].point;
        if (!seen) l->items[u++] = l->items[i];
    }
    l->n = u;
    return true;
}

static bool tris_push(struct watertight *w, int *cap, struct vec3 a, struct vec3 b, struct vec3 c, struct error *err)
{
    if (w->n_triangles == *cap) {
        int ncap = *cap ? 2 * *cap : 16;
        struct watertight_triangle *t = realloc(w->tris, sizeof *t * (size_t)ncap);
        if (!t) return error_set(err, "out of memory stitching faces");
        w->tris = t, *cap = ncap;
    }
    w->tris[w->n_triangles++] = (struct watertight_triangle){ { a, b, c } };
    return true;
}

/* Triangles over the boundary loop[0..m) of face f (corners and inserted
   vertices in winding order; corner_at[i] = loop index of corner i). A fan
   from a corner whose two edges gained nothing has no degenerate triangle
   (the convex face's other edges do not pass through that corner); when
   every corner has an edge that gained vertices, the fan is from the
   centroid, which is strictly inside. Each boundary piece is then an edge
   of exactly one triangle, and every triangle keeps the face's winding. */
static bool fan_emit(const struct watertight_face *f, const struct vec3 *loop, int m, const int *corner_at,
                     struct watertight *w, int *cap, struct error *err)
{
    for (int i = 0; i < f->n; ++i) {
        int prev = (i + f->n - 1) % f->n, next = (i + 1) % f->n;
        int gained_in = (corner_at[i] - corner_at[prev] + m) % m - 1;
        int gained_out = (corner_at[next] - corner_at[i] + m) % m - 1;
        if (gained_in != 0 || gained_out != 0) continue;
        for (int j = 1; j + 1 < m; ++j)
            if (!tris_push(w, cap, loop[corner_at[i]], loop[(corner_at[i] + j) % m], loop[(corner_at[i] + j + 1) % m],
                           err))
                return false;
        return true;
    }
    struct vec3 c = vec3_make(0.0, 0.0, 0.0);
    for (int i = 0; i < f->n; ++i) c = vec3_add(c, f->v[i]);
    c = vec3_scale(c, 1.0 / f->n);
    for (int j = 0; j < m; ++j)
        if (!tris_push(w, cap, c, loop[j], loop[(j + 1) % m], err)) return false;
    return true;
}

bool watertight_stitch(const struct watertight_face *faces, int n, struct watertight *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    out->n_faces = n;
    out->first = calloc((size_t)n + 1, sizeof *out->first);
    if (!out->first) return error_set(err, "out of memory stitching %d faces", n);
    struct grid g;
    double eps = 0.0;
    struct on_edge_list edge = { 0, 0, NULL };
    struct vec3 *loop = NULL;
    int loop_cap = 0, tri_cap = 0;
    bool ok = grid_build(faces, n, &eps, &g, err);
    for (int f = 0; ok && f < n; ++f) {
        const struct watertight_face *fc = &faces[f];
        int m = 0, corner_at[WATERTIGHT_FACE_MAX];
        for (int i = 0; ok && i < fc->n; ++i) {
            ok = edge_find(&g, eps, fc->v[i], fc->v[(i + 1) % fc->n], &edge, err);
            if (!ok) break;
            if (m + 1 + edge.n > loop_cap) {
                int cap = 2 * (m + 1 + edge.n);
                struct vec3 *nl = realloc(loop, sizeof *nl * (size_t)cap);
                if (!nl) {
                    ok = error_set(err, "out of memory stitching %d faces", n);
                    break;
                }
                loop = nl, loop_cap = cap;
            }
            corner_at[i] = m;
            loop[m++] = fc->v[i];
            for (int k = 0; k < edge.n; ++k) loop[m++] = g.points[edge.items[k].point];
        }
        if (ok && m > fc->n) {
            out->n_inserted += m - fc->n;
            ok = fan_emit(fc, loop, m, corner_at, out, &tri_cap, err);
        }
        out->first[f + 1] = out->n_triangles;
    }
    free(loop);
    free(edge.items);
    grid_free(&g);
    if (!ok) watertight_free(out);
    return ok;
}

void watertight_free(struct watertight *w)
{
    free(w->first);
    free(w->tris);
    memset(w, 0, sizeof *w);
}

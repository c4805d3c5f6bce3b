#include "geometry/watertight.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Why this exists: the lampshade's bottom plate is four quads around the
   hole, and the corners of the side quads lie on the long edges of the
   front and back ones (T-junctions). Embree's robust mode is watertight
   only across edges whose endpoints are identical, so rays slipped through
   those lines (tools/firefly/scan.c counts the leaking aims of each line;
   docs/performance.md has the counts), and one such BSDF ray, reaching
   the lamp where the portal strategies' pdf is 0, made the firefly of
   pixel (130, 204) (tools/firefly/README.md). After stitching none leak. */

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

/* Hash of 64 bits (the finaliser of MurmurHash3): cell keys and vertex
   bits are far from uniform, the table's slots must not be. */
static uint64_t mix64(uint64_t h)
{
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    h *= 0xc4ceb9fe1a85ec53ull;
    h ^= h >> 33;
    return h;
}

/* The smallest power of two >= 2 n (open addressing stays under half full). */
static size_t table_size(size_t n)
{
    size_t size = 16;
    while (size < 2 * n) size *= 2;
    return size;
}

static uint64_t double_bits(double x)
{
    uint64_t u;
    x += 0.0; /* -0 and +0 compare equal (cmp_vec3), so they must hash alike */
    memcpy(&u, &x, sizeof u);
    return u;
}

/* The distinct positions of corners[0..n) (equal under cmp_vec3), each the
   first of its kind in corner order, sorted by cmp_vec3: what a stable
   sort of all corners followed by keeping the first of each run gives, but
   sorting only the distinct ones (a mesh's corners repeat each vertex about
   six times). Returns their count, or -1 when out of memory. */
static int unique_sorted(const struct vec3 *corners, size_t n, struct vec3 *out)
{
    size_t size = table_size(n);
    int *slot = malloc(sizeof *slot * size);
    if (!slot) return -1;
    memset(slot, 0xff, sizeof *slot * size); /* -1: empty */
    int u = 0;
    for (size_t i = 0; i < n; ++i) {
        struct vec3 p = corners[i];
        uint64_t h = mix64(double_bits(p.x) ^ mix64(double_bits(p.y) ^ mix64(double_bits(p.z))));
        size_t k = (size_t)h & (size - 1);
        while (slot[k] >= 0 && cmp_vec3(&out[slot[k]], &p) != 0) k = (k + 1) & (size - 1);
        if (slot[k] < 0) {
            slot[k] = u;
            out[u++] = p;
        }
    }
    free(slot);
    qsort(out, (size_t)u, sizeof *out, cmp_vec3);
    return u;
}

/* A point entered in a cell, with its position: a cell's candidates are
   then contiguous in memory (one cache miss per cell, not per point). */
struct cell_point {
    struct vec3 p;
    int point;
};

/* One occupied grid cell: its points are cell_points[start .. start +
   count), in increasing point order. */
struct cell_slot {
    uint64_t key; /* CELL_EMPTY when the slot is free */
    int start, count;
};

#define CELL_EMPTY UINT64_MAX /* cell keys use 3 * GRID_BITS < 64 bits */

/* A uniform grid over the distinct vertex positions, as a hash table from
   cell to the points in it (one probe per visited cell). A point is entered
   in every cell its tolerance box touches, so a query only has to visit the
   cells the edge itself passes through. */
struct grid {
    struct vec3 lo;
    double cell, inv_cell;
    int n_points;
    struct vec3 *points;
    size_t n_slots; /* a power of two */
    struct cell_slot *slots;
    struct cell_point *cell_points;
};

/* The cell of coordinate x, given 1 / cell size: any mapping that is
   monotonic in x finds every point (a point and a segment piece within eps
   of it share a cell on each axis), and the exact distance test decides. */
static int64_t cell_coord(double x, double lo, double inv_cell)
{
    double c = floor((x - lo) * inv_cell);
    if (!(c >= 0.0)) return 0;
    return c >= (double)(GRID_MAX - 1) ? GRID_MAX - 1 : (int64_t)c;
}

static uint64_t cell_key(int64_t ix, int64_t iy, int64_t iz)
{
    return (uint64_t)ix | (uint64_t)iy << GRID_BITS | (uint64_t)iz << (2 * GRID_BITS);
}

/* The slot of cell `key`: its own, or the free one where it would go. */
static struct cell_slot *grid_slot(const struct grid *g, uint64_t key)
{
    size_t k = (size_t)mix64(key) & (g->n_slots - 1);
    while (g->slots[k].key != CELL_EMPTY && g->slots[k].key != key) k = (k + 1) & (g->n_slots - 1);
    return &g->slots[k];
}

/* The last cells looked up, direct-mapped by position: neighbouring faces
   (a mesh's faces come in surface order) visit the same cells, which then
   cost no probe of the table, whose slots are scattered by the hash. */
#define CELL_CACHE 256

struct cell_cache {
    uint64_t key[CELL_CACHE];
    const struct cell_slot *slot[CELL_CACHE];
};

static const struct cell_slot *grid_cached(const struct grid *g, struct cell_cache *cache, int64_t x, int64_t y,
                                           int64_t z)
{
    uint64_t key = cell_key(x, y, z);
    size_t i = (size_t)(x + 17 * y + 31 * z) & (CELL_CACHE - 1);
    if (cache->key[i] != key) {
        cache->key[i] = key;
        cache->slot[i] = grid_slot(g, key);
    }
    return cache->slot[i];
}

/* The cells point i's tolerance box touches, at most 2 per axis (eps is far
   below a cell); returns how many were written to keys. */
static int point_cells(const struct grid *g, double eps, int i, uint64_t keys[8])
{
    struct vec3 p = g->points[i];
    double inv = g->inv_cell;
    int64_t x0 = cell_coord(p.x - eps, g->lo.x, inv), x1 = cell_coord(p.x + eps, g->lo.x, inv);
    int64_t y0 = cell_coord(p.y - eps, g->lo.y, inv), y1 = cell_coord(p.y + eps, g->lo.y, inv);
    int64_t z0 = cell_coord(p.z - eps, g->lo.z, inv), z1 = cell_coord(p.z + eps, g->lo.z, inv);
    int m = 0;
    for (int64_t z = z0; z <= z1 && z <= z0 + 1; ++z)
        for (int64_t y = y0; y <= y1 && y <= y0 + 1; ++y)
            for (int64_t x = x0; x <= x1 && x <= x0 + 1; ++x) keys[m++] = cell_key(x, y, z);
    return m;
}

static bool grid_build(const struct watertight_face *faces, int n, double *eps_out, struct grid *g, struct error *err)
{
    memset(g, 0, sizeof *g);
    size_t n_corners = 0;
    for (int f = 0; f < n; ++f) n_corners += (size_t)faces[f].n;
    struct vec3 *corners = malloc(sizeof *corners * (n_corners > 0 ? n_corners : 1));
    g->points = malloc(sizeof *g->points * (n_corners > 0 ? n_corners : 1));
    if (!corners || !g->points) {
        free(corners);
        return error_set(err, "out of memory stitching %d faces", n);
    }
    double edge_sum = 0.0;
    size_t k = 0;
    for (int f = 0; f < n; ++f)
        for (int i = 0; i < faces[f].n; ++i) {
            corners[k++] = faces[f].v[i];
            edge_sum += vec3_length(vec3_sub(faces[f].v[(i + 1) % faces[f].n], faces[f].v[i]));
        }
    g->n_points = unique_sorted(corners, n_corners, g->points);
    free(corners);
    if (g->n_points < 0) return error_set(err, "out of memory stitching %d faces", n);

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
    g->inv_cell = 1.0 / cell;

    /* Count the points per cell, lay the cells out one after the other,
       then fill them in point order. The table has room for every (point,
       cell) pair, so it stays at most half full. */
    uint64_t keys[8];
    size_t m = 0;
    for (int i = 0; i < g->n_points; ++i) m += (size_t)point_cells(g, eps, i, keys);
    if (m > (size_t)INT_MAX) return error_set(err, "too many vertices stitching %d faces", n);
    g->n_slots = table_size(m);
    g->slots = malloc(sizeof *g->slots * g->n_slots);
    g->cell_points = malloc(sizeof *g->cell_points * (m > 0 ? m : 1));
    if (!g->slots || !g->cell_points) return error_set(err, "out of memory stitching %d faces", n);
    for (size_t s = 0; s < g->n_slots; ++s) g->slots[s] = (struct cell_slot){ CELL_EMPTY, 0, 0 };
    for (int i = 0; i < g->n_points; ++i) {
        int nk = point_cells(g, eps, i, keys);
        for (int j = 0; j < nk; ++j) {
            struct cell_slot *c = grid_slot(g, keys[j]);
            c->key = keys[j];
            ++c->count;
        }
    }
    int start = 0;
    for (size_t s = 0; s < g->n_slots; ++s) {
        g->slots[s].start = start;
        start += g->slots[s].count;
        g->slots[s].count = 0;
    }
    for (int i = 0; i < g->n_points; ++i) {
        int nk = point_cells(g, eps, i, keys);
        for (int j = 0; j < nk; ++j) {
            struct cell_slot *c = grid_slot(g, keys[j]);
            g->cell_points[c->start + c->count++] = (struct cell_point){ g->points[i], i };
        }
    }
    *eps_out = eps;
    return true;
}

static void grid_free(struct grid *g)
{
    free(g->points);
    free(g->slots);
    free(g->cell_points);
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
static bool edge_find(const struct grid *g, struct cell_cache *cache, double eps, struct vec3 a, struct vec3 b,
                      struct on_edge_list *l, struct error *err)
{
    struct vec3 d = vec3_sub(b, a);
    double len2 = vec3_length2(d), len = sqrt(len2);
    l->n = 0;
    if (!(len > 2.0 * eps)) return true;
    double steps_d = ceil(len / g->cell);
    int steps = steps_d < 1.0 ? 1 : steps_d > 4.0 * (double)GRID_MAX ? (int)(4 * GRID_MAX) : (int)steps_d;
    for (int s = 0; s < steps; ++s) {
        struct vec3 p0 = vec3_madd(a, d, (double)s / steps), p1 = vec3_madd(a, d, (double)(s + 1) / steps);
        int64_t x0 = cell_coord(fmin(p0.x, p1.x), g->lo.x, g->inv_cell),
                x1 = cell_coord(fmax(p0.x, p1.x), g->lo.x, g->inv_cell);
        int64_t y0 = cell_coord(fmin(p0.y, p1.y), g->lo.y, g->inv_cell),
                y1 = cell_coord(fmax(p0.y, p1.y), g->lo.y, g->inv_cell);
        int64_t z0 = cell_coord(fmin(p0.z, p1.z), g->lo.z, g->inv_cell),
                z1 = cell_coord(fmax(p0.z, p1.z), g->lo.z, g->inv_cell);
        for (int64_t z = z0; z <= z1; ++z)
            for (int64_t y = y0; y <= y1; ++y)
                for (int64_t x = x0; x <= x1; ++x) {
                    const struct cell_slot *c = grid_cached(g, cache, x, y, z);
                    for (int e = c->start; e < c->start + c->count; ++e) {
                        int point = g->cell_points[e].point;
                        struct vec3 p = g->cell_points[e].p;
                        struct vec3 ap = vec3_sub(p, a);
                        double t = vec3_dot(ap, d) / len2;
                        double along = t * len;
                        if (!(along > eps && along < len - eps)) continue;
                        if (vec3_length(vec3_sub(ap, vec3_scale(d, t))) > eps) continue;
                        if (!list_push(l, (struct on_edge){ t, point }, err)) return false;
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
    struct cell_cache *cache = malloc(sizeof *cache);
    if (!cache) {
        free(out->first);
        out->first = NULL;
        return error_set(err, "out of memory stitching %d faces", n);
    }
    for (int i = 0; i < CELL_CACHE; ++i) cache->key[i] = CELL_EMPTY;
    bool ok = grid_build(faces, n, &eps, &g, err);
    for (int f = 0; ok && f < n; ++f) {
        const struct watertight_face *fc = &faces[f];
        int m = 0, corner_at[WATERTIGHT_FACE_MAX];
        for (int i = 0; ok && i < fc->n; ++i) {
            ok = edge_find(&g, cache, eps, fc->v[i], fc->v[(i + 1) % fc->n], &edge, err);
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
    free(cache);
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

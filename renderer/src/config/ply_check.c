/* ply_check.c: the renderer's own PLY reader (see ply_check.h for why):
   one pass checks the file without building anything, a second one stores
   the positions and the faces' corners, then each face is triangulated. */
#include "config/ply_check.h"

#include <ctype.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum ply_format { PLY_ASCII, PLY_BINARY_LE, PLY_BINARY_BE };

enum ply_type { T_INT8, T_UINT8, T_INT16, T_UINT16, T_INT32, T_UINT32, T_FLOAT32, T_FLOAT64 };

static const struct {
    const char *name, *alias;
    int size;
} ply_types[8] = {
    { "char", "int8", 1 }, { "uchar", "uint8", 1 }, { "short", "int16", 2 },   { "ushort", "uint16", 2 },
    { "int", "int32", 4 }, { "uint", "uint32", 4 }, { "float", "float32", 4 }, { "double", "float64", 8 },
};

enum ply_role { ROLE_NONE, ROLE_COORD, ROLE_INDICES };

struct ply_property {
    bool list;
    enum ply_type type;       /* of a scalar, or of a list's items */
    enum ply_type count_type; /* of a list's count */
    enum ply_role role;
    int axis; /* of a coordinate: 0, 1, 2 for x, y, z */
};

struct ply_element {
    char name[32];
    long long count;
    int n_props;
    struct ply_property props[PLY_PROPERTIES_MAX];
    int line; /* of its header line */
};

struct ply_header {
    enum ply_format format;
    int n_elements;
    struct ply_element elements[PLY_ELEMENTS_MAX];
    size_t body;      /* offset of the first byte after end_header's line */
    int body_line;    /* line number of that byte */
    int vertex, face; /* element indices, -1 when absent */
};

static bool is_float(enum ply_type t)
{
    return t == T_FLOAT32 || t == T_FLOAT64;
}

static bool find_type(const char *s, enum ply_type *out)
{
    for (int i = 0; i < 8; ++i)
        if (!strcmp(s, ply_types[i].name) || !strcmp(s, ply_types[i].alias)) {
            *out = (enum ply_type)i;
            return true;
        }
    return false;
}

/* Splits a line (NUL-terminated, modified) into at most max tokens. */
static int tokenize(char *line, char **tok, int max)
{
    int n = 0;
    for (char *p = line; *p;) {
        while (*p == ' ' || *p == '\t') ++p;
        if (!*p) break;
        if (n == max) return max + 1;
        tok[n++] = p;
        while (*p && *p != ' ' && *p != '\t') ++p;
        if (*p) *p++ = '\0';
    }
    return n;
}

/* A decimal count in [0, LLONG_MAX / 2]; false for anything else. */
static bool parse_count(const char *s, long long *out)
{
    long long v = 0;
    if (!*s) return false;
    for (; *s; ++s) {
        if (!isdigit((unsigned char)*s)) return false;
        if (v > (LLONG_MAX / 2 - 9) / 10) return false;
        v = 10 * v + (*s - '0');
    }
    *out = v;
    return true;
}

static bool add_property(struct ply_header *h, char **tok, int n, int line, struct error *err)
{
    if (h->n_elements == 0) return error_set(err, "line %d: a property before any element", line);
    struct ply_element *e = &h->elements[h->n_elements - 1];
    if (e->n_props == PLY_PROPERTIES_MAX)
        return error_set(err, "line %d: element %s has more than %d properties", line, e->name, PLY_PROPERTIES_MAX);
    struct ply_property *p = &e->props[e->n_props];
    memset(p, 0, sizeof *p);
    const char *name;
    if (n == 5 && !strcmp(tok[1], "list")) {
        p->list = true;
        if (!find_type(tok[2], &p->count_type) || !find_type(tok[3], &p->type))
            return error_set(err,
                             "line %d: unknown property type in \"list %s %s\" (expected char, uchar, short, "
                             "ushort, int, uint, float, double)",
                             line, tok[2], tok[3]);
        if (is_float(p->count_type))
            return error_set(err, "line %d: list count type %s is not an integer type", line, tok[2]);
        name = tok[4];
    } else if (n == 3) {
        if (!find_type(tok[1], &p->type))
            return error_set(err,
                             "line %d: unknown property type \"%.32s\" (expected char, uchar, short, ushort, "
                             "int, uint, float, double)",
                             line, tok[1]);
        name = tok[2];
    } else {
        return error_set(err, "line %d: expected \"property TYPE NAME\" or \"property list COUNT_TYPE TYPE NAME\"",
                         line);
    }
    if (!strcmp(e->name, "vertex") && (!strcmp(name, "x") || !strcmp(name, "y") || !strcmp(name, "z"))) {
        if (p->list) return error_set(err, "line %d: vertex coordinate %s is a list (expected a number)", line, name);
        p->role = ROLE_COORD;
        p->axis = name[0] - 'x';
    }
    if (!strcmp(e->name, "face") && (!strcmp(name, "vertex_indices") || !strcmp(name, "vertex_index"))) {
        if (!p->list || is_float(p->type))
            return error_set(err, "line %d: face property %s is not a list of integers", line, name);
        p->role = ROLE_INDICES;
    }
    ++e->n_props;
    return true;
}

static bool add_element(struct ply_header *h, char **tok, int n, int line, struct error *err)
{
    if (n != 3) return error_set(err, "line %d: expected \"element NAME COUNT\"", line);
    if (h->n_elements == PLY_ELEMENTS_MAX)
        return error_set(err, "line %d: more than %d elements", line, PLY_ELEMENTS_MAX);
    struct ply_element *e = &h->elements[h->n_elements];
    memset(e, 0, sizeof *e);
    if (strlen(tok[1]) >= sizeof e->name) return error_set(err, "line %d: element name too long", line);
    strcpy(e->name, tok[1]);
    e->line = line;
    if (!parse_count(tok[2], &e->count))
        return error_set(err, "line %d: element %s count \"%.32s\" is not a count", line, e->name, tok[2]);
    if (e->count > INT_MAX)
        return error_set(err, "line %d: element %s declares %lld elements (expected at most %d)", line, e->name,
                         e->count, INT_MAX);
    if (!strcmp(e->name, "tristrips"))
        return error_set(err, "line %d: element tristrips is not supported (expected a face element)", line);
    int *slot = !strcmp(e->name, "vertex") ? &h->vertex : !strcmp(e->name, "face") ? &h->face : NULL;
    if (slot && *slot >= 0) return error_set(err, "line %d: a second %s element", line, e->name);
    if (slot) *slot = h->n_elements;
    ++h->n_elements;
    return true;
}

/* The checks that need the whole header. */
static bool check_semantics(const struct ply_header *h, struct error *err)
{
    for (int i = 0; i < h->n_elements; ++i)
        if (h->elements[i].n_props == 0)
            return error_set(err, "line %d: element %s has no properties", h->elements[i].line, h->elements[i].name);
    if (h->vertex < 0) return error_set(err, "no vertex element in the header");
    if (h->face < 0)
        return error_set(err, "no face element in the header (expected faces: points alone are no surface)");
    const struct ply_element *v = &h->elements[h->vertex], *f = &h->elements[h->face];
    int coords = 0, lists = 0;
    for (int i = 0; i < v->n_props; ++i) coords += v->props[i].role == ROLE_COORD;
    for (int i = 0; i < f->n_props; ++i) lists += f->props[i].role == ROLE_INDICES;
    if (coords != 3) return error_set(err, "line %d: element vertex needs properties x, y and z, once each", v->line);
    if (lists != 1) return error_set(err, "line %d: element face needs one vertex_indices list", f->line);
    return true;
}

static bool parse_header(const char *data, size_t size, struct ply_header *h, struct error *err)
{
    memset(h, 0, sizeof *h);
    h->vertex = h->face = -1;
    size_t pos = 0;
    int line = 0;
    bool have_format = false;
    char buf[512], *tok[8];
    for (;;) {
        if (pos >= size) return error_set(err, "line %d: the file ends in the header (expected end_header)", line + 1);
        if (pos >= PLY_HEADER_MAX)
            return error_set(err, "no end_header in the first %d bytes (expected a PLY header)", PLY_HEADER_MAX);
        const char *nl = memchr(data + pos, '\n', size - pos);
        size_t len = nl ? (size_t)(nl - (data + pos)) : size - pos;
        ++line;
        if (len && data[pos + len - 1] == '\r') --len;
        if (len >= sizeof buf)
            return error_set(err, "line %d: header line longer than %zu bytes", line, sizeof buf - 1);
        if (memchr(data + pos, '\0', len)) return error_set(err, "line %d: a NUL byte in the header", line);
        memcpy(buf, data + pos, len);
        buf[len] = '\0';
        pos = nl ? (size_t)(nl - data) + 1 : size;
        if (line == 1) {
            if (strcmp(buf, "ply") && strcmp(buf, "PLY"))
                return error_set(err, "line 1: not a PLY file (expected the line \"ply\")");
            continue;
        }
        int n = tokenize(buf, tok, 6);
        if (n == 0) continue;
        if (!strcmp(tok[0], "comment") || !strcmp(tok[0], "obj_info")) continue;
        if (line == 2 || !have_format) {
            if (strcmp(tok[0], "format") || n != 3 || strncmp(tok[2], "1.", 2))
                return error_set(err, "line %d: expected \"format ascii|binary_little_endian|binary_big_endian 1.0\"",
                                 line);
            if (!strcmp(tok[1], "ascii")) h->format = PLY_ASCII;
            else if (!strcmp(tok[1], "binary_little_endian")) h->format = PLY_BINARY_LE;
            else if (!strcmp(tok[1], "binary_big_endian")) h->format = PLY_BINARY_BE;
            else
                return error_set(err,
                                 "line %d: unknown format \"%.32s\" (expected ascii, binary_little_endian, "
                                 "binary_big_endian)",
                                 line, tok[1]);
            have_format = true;
        } else if (!strcmp(tok[0], "element")) {
            if (!add_element(h, tok, n, line, err)) return false;
        } else if (!strcmp(tok[0], "property")) {
            if (!add_property(h, tok, n, line, err)) return false;
        } else if (!strcmp(tok[0], "end_header") && n == 1) {
            if (!nl) return error_set(err, "line %d: no line break after end_header", line);
            h->body = pos;
            h->body_line = line + 1;
            return check_semantics(h, err);
        } else {
            return error_set(err, "line %d: unknown header line \"%.32s\"", line, tok[0]);
        }
    }
}

/* The least each element takes in the body: catches a count that the file
   cannot hold before walking (an element of 10^9 vertices in 100 bytes). */
static bool check_sizes(const struct ply_header *h, size_t size, struct error *err)
{
    uint64_t need = 0, have = size - h->body;
    for (int i = 0; i < h->n_elements; ++i) {
        const struct ply_element *e = &h->elements[i];
        uint64_t each = 0;
        for (int k = 0; k < e->n_props; ++k) {
            const struct ply_property *p = &e->props[k];
            /* ASCII: a digit and a separator per value. */
            each += h->format == PLY_ASCII ? 2u : (uint64_t)ply_types[p->list ? p->count_type : p->type].size;
        }
        need += each * (uint64_t)e->count;
        if (need > have + 1)
            return error_set(err,
                             "line %d: element %s declares %lld elements, which take at least %llu bytes, but "
                             "the file has %llu bytes after the header",
                             e->line, e->name, e->count, (unsigned long long)(each * (uint64_t)e->count),
                             (unsigned long long)have);
    }
    return true;
}

/* Where the second pass puts what the mesh needs (NULL in the first). */
struct ply_store {
    struct vec3 *positions; /* one per vertex */
    int *face_n;            /* corners of each face */
    int *corners;           /* every face's vertex indices, in order */
    long long n_corners;
};

/* A coordinate as the float the renderer reads (as assimp did): false when
   it is beyond the float range. The range test comes first: converting a
   larger double to float is undefined behaviour in C99. */
static bool coord_float(double v, double *out)
{
    if (!(fabs(v) <= (double)FLT_MAX)) return false;
    *out = (double)(float)v;
    return true;
}

static void set_axis(struct vec3 *p, int axis, double v)
{
    if (axis == 0) p->x = v;
    else if (axis == 1) p->y = v;
    else p->z = v;
}

/* Binary body. */
struct reader {
    const unsigned char *p;
    size_t pos, size;
    bool big_endian;
};

static bool read_value(struct reader *r, enum ply_type t, double *out)
{
    int n = ply_types[t].size;
    if (r->size - r->pos < (size_t)n) return false;
    unsigned char b[8];
    for (int i = 0; i < n; ++i) b[i] = r->p[r->pos + (r->big_endian ? (size_t)(n - 1 - i) : (size_t)i)];
    r->pos += (size_t)n;
    uint64_t u = 0;
    for (int i = n - 1; i >= 0; --i) u = (u << 8) | b[i];
    switch (t) {
    case T_INT8:
        *out = (double)(int8_t)u;
        break;
    case T_UINT8:
        *out = (double)(uint8_t)u;
        break;
    case T_INT16:
        *out = (double)(int16_t)u;
        break;
    case T_UINT16:
        *out = (double)(uint16_t)u;
        break;
    case T_INT32:
        *out = (double)(int32_t)u;
        break;
    case T_UINT32:
        *out = (double)(uint32_t)u;
        break;
    case T_FLOAT32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *out = f;
        break;
    }
    case T_FLOAT64:
        memcpy(out, &u, sizeof *out);
        break;
    }
    return true;
}

/* What every body format checks in a face's index list. */
static bool check_face(long long count, long long i, const char *where, long long at, struct ply_info *info,
                       struct error *err)
{
    if (count < 3)
        return error_set(err, "%s %lld: face %lld has %lld corners (expected at least 3)", where, at, i, count);
    info->n_triangles += count - 2;
    if (info->n_triangles > INT_MAX / 4)
        return error_set(err, "%s %lld: more than %d triangles", where, at, INT_MAX / 4);
    return true;
}

static bool check_index(double v, int n_vertices, long long i, const char *where, long long at, struct error *err)
{
    if (!(v >= 0.0 && v < (double)n_vertices))
        return error_set(err, "%s %lld: face %lld has vertex index %.0f, out of range (expected 0 to %d)", where, at, i,
                         v, n_vertices - 1);
    return true;
}

static bool walk_binary(const struct ply_header *h, const void *data, size_t size, struct ply_info *info,
                        struct ply_store *st, struct error *err)
{
    struct reader r = { data, h->body, size, h->format == PLY_BINARY_BE };
    int nv = (int)h->elements[h->vertex].count;
    for (int e = 0; e < h->n_elements; ++e) {
        const struct ply_element *el = &h->elements[e];
        for (long long i = 0; i < el->count; ++i) {
            size_t start = r.pos;
            for (int k = 0; k < el->n_props; ++k) {
                const struct ply_property *p = &el->props[k];
                double v;
                if (!p->list) {
                    if (!read_value(&r, p->type, &v)) goto truncated;
                    if (p->role != ROLE_COORD) continue;
                    double f;
                    if (!isfinite(v))
                        return error_set(err, "byte %zu: vertex %lld has a coordinate that is not finite", start, i);
                    if (!coord_float(v, &f))
                        return error_set(err, "byte %zu: vertex %lld has coordinate %g, beyond the float range", start,
                                         i, v);
                    if (st) set_axis(&st->positions[i], p->axis, f);
                    continue;
                }
                double count;
                if (!read_value(&r, p->count_type, &count)) goto truncated;
                if (count < 0) return error_set(err, "byte %zu: %s %lld has a negative list count", start, el->name, i);
                if (p->role == ROLE_INDICES && !check_face((long long)count, i, "byte", (long long)start, info, err))
                    return false;
                if (st && p->role == ROLE_INDICES) st->face_n[i] = (int)count;
                size_t item = (size_t)ply_types[p->type].size;
                if ((size_t)count > (r.size - r.pos) / item) goto truncated;
                if (p->role != ROLE_INDICES) {
                    r.pos += (size_t)count * item;
                    continue;
                }
                for (long long c = 0; c < (long long)count; ++c) {
                    read_value(&r, p->type, &v);
                    if (!check_index(v, nv, i, "byte", (long long)start, err)) return false;
                    if (st) st->corners[st->n_corners++] = (int)v;
                }
            }
            continue;
        truncated:
            return error_set(err, "byte %zu: the file ends inside %s %lld (of %lld): truncated", start, el->name, i,
                             el->count);
        }
    }
    if (r.pos != size)
        return error_set(err, "byte %zu: %zu bytes after the last element (expected the file to end there)", r.pos,
                         size - r.pos);
    return true;
}

/* ASCII numbers: decimal only, as assimp's own reader parses them (no hex,
   no inf or nan); integers for integer types. */
static bool ascii_number(const char *s, bool integer, double *out)
{
    const char *p = s;
    if (*p == '+' || *p == '-') ++p;
    bool digits = false;
    for (; isdigit((unsigned char)*p); ++p) digits = true;
    if (!integer) {
        if (*p == '.')
            for (++p; isdigit((unsigned char)*p); ++p) digits = true;
        if (digits && (*p == 'e' || *p == 'E')) {
            ++p;
            if (*p == '+' || *p == '-') ++p;
            if (!isdigit((unsigned char)*p)) return false;
            while (isdigit((unsigned char)*p)) ++p;
        }
    }
    if (!digits || *p) return false;
    *out = strtod(s, NULL);
    return isfinite(*out);
}

static bool walk_ascii(const struct ply_header *h, const char *data, size_t size, struct ply_info *info,
                       struct ply_store *st, struct error *err)
{
    size_t pos = h->body;
    int line = h->body_line - 1, nv = (int)h->elements[h->vertex].count;
    for (int e = 0; e < h->n_elements; ++e) {
        const struct ply_element *el = &h->elements[e];
        for (long long i = 0; i < el->count; ++i) {
            if (pos >= size)
                return error_set(err, "line %d: the file ends before %s %lld (of %lld): truncated", line + 1, el->name,
                                 i, el->count);
            const char *nl = memchr(data + pos, '\n', size - pos);
            const char *s = data + pos, *end = nl ? nl : data + size;
            pos = nl ? (size_t)(nl - data) + 1 : size;
            ++line;
            int k = 0;
            long long list_left = -1; /* items left of the list being read */
            const struct ply_property *p = NULL;
            while (s < end) {
                while (s < end && (*s == ' ' || *s == '\t' || *s == '\r')) ++s;
                if (s == end) break;
                const char *t = s;
                while (s < end && *s != ' ' && *s != '\t' && *s != '\r') ++s;
                char tok[64];
                size_t len = (size_t)(s - t);
                if (len >= sizeof tok) return error_set(err, "line %d: a value longer than 63 characters", line);
                memcpy(tok, t, len);
                tok[len] = '\0';
                if (list_left < 0 && k == el->n_props)
                    return error_set(err, "line %d: more values than the %d properties of %s", line, el->n_props,
                                     el->name);
                if (list_left < 0) p = &el->props[k];
                bool count_value = p->list && list_left < 0;
                enum ply_type type = count_value ? p->count_type : p->type;
                double v;
                if (!ascii_number(tok, !is_float(type), &v))
                    return error_set(err, "line %d: \"%s\" is not %s", line, tok,
                                     is_float(type) ? "a finite decimal number" : "an integer");
                if (count_value) {
                    if (v < 0) return error_set(err, "line %d: negative list count %s", line, tok);
                    if (p->role == ROLE_INDICES && !check_face((long long)v, i, "line", line, info, err)) return false;
                    if (st && p->role == ROLE_INDICES) st->face_n[i] = (int)v;
                    list_left = (long long)v;
                } else if (p->list) {
                    if (p->role == ROLE_INDICES && !check_index(v, nv, i, "line", line, err)) return false;
                    if (st && p->role == ROLE_INDICES) st->corners[st->n_corners++] = (int)v;
                    --list_left;
                } else if (p->role == ROLE_COORD) {
                    /* Straight to float (strtof rounds once), as assimp read them. */
                    float f = strtof(tok, NULL);
                    if (!isfinite(f))
                        return error_set(err, "line %d: vertex %lld has coordinate %s, beyond the float range", line, i,
                                         tok);
                    if (st) set_axis(&st->positions[i], p->axis, (double)f);
                }
                if (!p->list || list_left == 0) {
                    list_left = -1;
                    ++k;
                }
            }
            if (k < el->n_props || list_left >= 0)
                return error_set(err, "line %d: %s %lld has fewer values than its %d properties", line, el->name, i,
                                 el->n_props);
        }
    }
    for (; pos < size; ++pos) {
        if (data[pos] == '\n') ++line;
        else if (data[pos] != ' ' && data[pos] != '\t' && data[pos] != '\r')
            return error_set(err, "line %d: data after the last element (expected the file to end)", line + 1);
    }
    return true;
}

static bool walk(const struct ply_header *h, const void *data, size_t size, struct ply_info *info, struct ply_store *st,
                 struct error *err)
{
    memset(info, 0, sizeof *info);
    bool ok =
        h->format == PLY_ASCII ? walk_ascii(h, data, size, info, st, err) : walk_binary(h, data, size, info, st, err);
    if (ok) {
        info->n_vertices = (int)h->elements[h->vertex].count;
        info->n_faces = (int)h->elements[h->face].count;
    }
    return ok;
}

bool ply_check(const void *data, size_t size, struct ply_info *info, struct error *err)
{
    memset(info, 0, sizeof *info);
    struct ply_header *h = malloc(sizeof *h);
    if (!h) return error_set(err, "out of memory");
    bool ok = parse_header(data, size, h, err) && check_sizes(h, size, err) && walk(h, data, size, info, NULL, err);
    free(h);
    return ok;
}

/* Triangulation of one face: n - 2 triangles in the face's winding. */

/* Twice the signed area of 2D triangle a, b, c (positive counter-clockwise). */
static double cross2(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether p lies in the closed triangle a, b, c (counter-clockwise), other
   than at one of its corners. */
static bool in_triangle(const double *p, const double *a, const double *b, const double *c)
{
    if ((p[0] == a[0] && p[1] == a[1]) || (p[0] == b[0] && p[1] == b[1]) || (p[0] == c[0] && p[1] == c[1]))
        return false;
    return cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0;
}

struct tri_work {
    double (*uv)[2];
    int *prev, *next;
    int cap;
};

/* Face idx[0..n) into tris[0..n-2). A convex face (every corner turning
   the same way in the plane of its Newell normal) is a fan from its first
   corner; a concave one is cut by ear clipping in that plane, the ears
   tried in order from corner 1, so that a convex face gives the same fan;
   when no ear is found (a self-intersecting or degenerate face) the corner
   at hand is cut anyway, so every face gives n - 2 triangles. A face with
   no plane (collinear corners) is a fan. Zero-area triangles are the
   caller's (config_scene.c drops them). */
static bool triangulate(const struct vec3 *pos, const int *idx, int n, long long face, struct tri_work *w,
                        int (*tris)[3], struct error *err)
{
    int t = 0;
    if (n > 3) {
        struct vec3 nrm = { 0.0, 0.0, 0.0 };
        for (int i = 0; i < n; ++i) {
            struct vec3 a = pos[idx[i]], b = pos[idx[(i + 1) % n]];
            nrm.x += (a.y - b.y) * (a.z + b.z);
            nrm.y += (a.z - b.z) * (a.x + b.x);
            nrm.z += (a.x - b.x) * (a.y + b.y);
        }
        double ax = fabs(nrm.x), ay = fabs(nrm.y), az = fabs(nrm.z);
        int k = ax >= ay && ax >= az ? 0 : ay >= az ? 1 : 2; /* the axis dropped */
        double sign = (k == 0 ? nrm.x : k == 1 ? nrm.y : nrm.z) < 0.0 ? -1.0 : 1.0;
        bool flat = !(fmax(ax, fmax(ay, az)) > 0.0);
        if (!flat && n > w->cap) {
            free(w->uv);
            free(w->prev);
            free(w->next);
            w->cap = n;
            w->uv = malloc(sizeof *w->uv * (size_t)n);
            w->prev = malloc(sizeof *w->prev * (size_t)n);
            w->next = malloc(sizeof *w->next * (size_t)n);
            if (!w->uv || !w->prev || !w->next) {
                w->cap = 0;
                return error_set(err, "out of memory for face %lld of %d corners", face, n);
            }
        }
        bool convex = true;
        if (!flat) {
            /* Counter-clockwise in (u, v) for a face along its normal. */
            for (int i = 0; i < n; ++i) {
                struct vec3 p = pos[idx[i]];
                double u = k == 0 ? p.y : k == 1 ? p.z : p.x, v = k == 0 ? p.z : k == 1 ? p.x : p.y;
                w->uv[i][0] = u;
                w->uv[i][1] = sign * v;
            }
            for (int i = 0; i < n && convex; ++i)
                convex = cross2(w->uv[(i + n - 1) % n], w->uv[i], w->uv[(i + 1) % n]) >= 0.0;
        }
        if (!flat && !convex) {
            if (n > PLY_CONCAVE_CORNERS_MAX)
                return error_set(err,
                                 "face %lld is a concave polygon of %d corners (expected at most %d for a "
                                 "concave face)",
                                 face, n, PLY_CONCAVE_CORNERS_MAX);
            for (int i = 0; i < n; ++i) {
                w->prev[i] = (i + n - 1) % n;
                w->next[i] = (i + 1) % n;
            }
            int left = n, c = 1, misses = 0;
            while (left > 3) {
                int a = w->prev[c], b = w->next[c];
                bool ear = cross2(w->uv[a], w->uv[c], w->uv[b]) > 0.0;
                for (int r = w->next[b]; ear && r != a; r = w->next[r])
                    ear = !in_triangle(w->uv[r], w->uv[a], w->uv[c], w->uv[b]);
                if (!ear && ++misses <= left) {
                    c = b;
                    continue;
                }
                tris[t][0] = idx[a];
                tris[t][1] = idx[c];
                tris[t][2] = idx[b];
                ++t;
                w->next[a] = b;
                w->prev[b] = a;
                --left;
                misses = 0;
                c = b;
            }
            tris[t][0] = idx[w->prev[c]];
            tris[t][1] = idx[c];
            tris[t][2] = idx[w->next[c]];
            return true;
        }
    }
    for (int i = 1; i + 1 < n; ++i, ++t) {
        tris[t][0] = idx[0];
        tris[t][1] = idx[i];
        tris[t][2] = idx[i + 1];
    }
    return true;
}

void ply_mesh_free(struct ply_mesh *m)
{
    free(m->positions);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

bool ply_read(const void *data, size_t size, long long max_triangles, struct ply_mesh *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    struct ply_info info;
    struct ply_header *h = malloc(sizeof *h);
    if (!h) return error_set(err, "out of memory");
    bool ok = parse_header(data, size, h, err) && check_sizes(h, size, err) && walk(h, data, size, &info, NULL, err);
    if (ok && info.n_triangles == 0)
        ok = error_set(err, "no triangles (expected faces: OBJ f lines, or a PLY face element)");
    if (ok && info.n_triangles > max_triangles)
        ok = error_set(err, "%lld triangles (expected at most %lld)", info.n_triangles, max_triangles);
    struct ply_store st = { NULL, NULL, NULL, 0 };
    struct tri_work w = { NULL, NULL, NULL, 0 };
    if (ok) {
        /* n_triangles <= INT_MAX / 4 (check_face): the corners fit an int count. */
        long long n_corners = info.n_triangles + 2LL * info.n_faces;
        st.positions = calloc((size_t)info.n_vertices + 1, sizeof *st.positions);
        st.face_n = malloc(sizeof *st.face_n * ((size_t)info.n_faces + 1));
        st.corners = malloc(sizeof *st.corners * (size_t)n_corners);
        out->triangles = malloc(sizeof *out->triangles * (size_t)info.n_triangles);
        if (!st.positions || !st.face_n || !st.corners || !out->triangles)
            ok = error_set(err, "out of memory for %lld triangles", info.n_triangles);
        /* The second walk stores what the first one checked. */
        ok = ok && walk(h, data, size, &info, &st, err);
    }
    long long c = 0;
    int t = 0;
    for (long long f = 0; ok && f < info.n_faces; ++f) {
        int n = st.face_n[f];
        ok = triangulate(st.positions, &st.corners[c], n, f, &w, &out->triangles[t], err);
        c += n;
        t += n - 2;
    }
    free(w.uv);
    free(w.prev);
    free(w.next);
    free(st.face_n);
    free(st.corners);
    free(h);
    if (!ok) {
        free(st.positions);
        ply_mesh_free(out);
        return false;
    }
    out->positions = st.positions;
    out->n_vertices = info.n_vertices;
    out->n_triangles = t;
    return true;
}

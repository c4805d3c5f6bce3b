/* mesh_serialized.c: Mitsuba's serialized meshes (see mesh_serialized.h
   for the layout), inflated with zlib a piece at a time: each field is
   read as the stream yields it, so that a count is checked before anything
   is allocated for it and memory follows the counts, never a guess at the
   inflated size. Every value is little-endian; it is assembled from bytes,
   so the host's byte order does not matter. */
#include "config/mesh_serialized.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

enum serialized_flag {
    FLAG_NORMALS = 0x0001,
    FLAG_TEXCOORDS = 0x0002,
    FLAG_COLORS = 0x0008,
    FLAG_SINGLE = 0x1000,
    FLAG_DOUBLE = 0x2000,
};

/* Deflate codes a 258-byte match in as little as one bit once its code
   table is set up, so a stream inflates to at most about 1032 times its
   size (zlib's technical notes); the slack covers the table and the
   header. A count that needs more bytes than this bound is a lie found
   before anything is allocated for it. */
#define INFLATE_RATIO_MAX 1032
#define INFLATE_SLACK     1024

static uint32_t u16le(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8;
}

static uint32_t u32le(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t u64le(const unsigned char *p)
{
    return (uint64_t)u32le(p) | (uint64_t)u32le(p + 4) << 32;
}

static double f32le(const unsigned char *p)
{
    uint32_t u = u32le(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static double f64le(const unsigned char *p)
{
    uint64_t u = u64le(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* The file's header and dictionary. */
struct layout {
    unsigned version;
    uint32_t n_shapes;
    size_t entry_bytes; /* of one dictionary offset: 8 (version 4) or 4 */
    size_t dictionary;  /* its first byte: the end of the shapes' data */
};

static uint64_t layout_offset(const unsigned char *d, const struct layout *lay, uint32_t i)
{
    const unsigned char *p = d + lay->dictionary + (size_t)i * lay->entry_bytes;
    return lay->entry_bytes == 8 ? u64le(p) : u32le(p);
}

/* The header at byte 0, the shape count at the end, and every dictionary
   entry: an offset to a shape header of the file's version, with at least
   one byte of stream after it, before the dictionary. */
static bool layout_read(const unsigned char *d, size_t size, struct layout *lay, struct error *err)
{
    if (size == 0) return error_set(err, "empty file (expected a Mitsuba serialized mesh)");
    if (size > MESH_FILE_BYTES_MAX) return error_set(err, "file larger than %zu bytes", MESH_FILE_BYTES_MAX);
    if (size < 8)
        return error_set(err, "a file of %zu bytes (expected at least a 4-byte header and a 4-byte shape count)", size);
    uint32_t id = u16le(d);
    if (id != MESH_SERIALIZED_ID)
        return error_set(err, "byte 0: format id 0x%04X (expected 0x%04X: not a Mitsuba serialized mesh)", (unsigned)id,
                         MESH_SERIALIZED_ID);
    lay->version = u16le(d + 2);
    if (lay->version != 3 && lay->version != 4)
        return error_set(err, "byte 2: version %u (expected 3 or 4)", lay->version);
    lay->entry_bytes = lay->version == 4 ? 8 : 4;
    lay->n_shapes = u32le(d + size - 4);
    if (lay->n_shapes == 0) return error_set(err, "byte %zu: shape count 0 (expected at least one shape)", size - 4);
    uint64_t dict_bytes = (uint64_t)lay->n_shapes * lay->entry_bytes;
    if (dict_bytes > size - 8)
        return error_set(err,
                         "byte %zu: shape count %u, whose dictionary of %llu bytes does not fit in the file of %zu "
                         "bytes (truncated, or not the end of a serialized mesh)",
                         size - 4, (unsigned)lay->n_shapes, (unsigned long long)dict_bytes, size);
    lay->dictionary = size - 4 - (size_t)dict_bytes;
    for (uint32_t i = 0; i < lay->n_shapes; ++i) {
        uint64_t off = layout_offset(d, lay, i);
        size_t at = lay->dictionary + (size_t)i * lay->entry_bytes;
        if (lay->dictionary < 5 || off > lay->dictionary - 5)
            return error_set(err,
                             "dictionary entry %u (byte %zu): offset %llu is outside the shapes' data (expected at "
                             "most %zu, before the dictionary at byte %zu)",
                             (unsigned)i, at, (unsigned long long)off, lay->dictionary < 5 ? 0 : lay->dictionary - 5,
                             lay->dictionary);
        uint32_t sid = u16le(d + off), sver = u16le(d + off + 2);
        if (sid != MESH_SERIALIZED_ID || sver != lay->version)
            return error_set(err,
                             "dictionary entry %u (byte %zu): offset %llu holds id 0x%04X, version %u (expected a "
                             "shape header: id 0x%04X, version %u)",
                             (unsigned)i, at, (unsigned long long)off, (unsigned)sid, (unsigned)sver,
                             MESH_SERIALIZED_ID, lay->version);
    }
    return true;
}

bool mesh_serialized_count(const void *data, size_t size, int *n_shapes, struct error *err)
{
    struct layout lay = { 0, 0, 0, 0 };
    if (!layout_read(data, size, &lay, err)) return false;
    /* At least 5 bytes a shape (layout_read), so the count fits an int. */
    *n_shapes = (int)lay.n_shapes;
    return true;
}

/* One shape's zlib stream, inflated on demand. */
struct zin {
    z_stream zs;
    const unsigned char *file;
    int shape;
    size_t header; /* the shape's byte offset in the file */
    size_t inflated;
    bool ended;
    struct error *err;
};

/* Inflates exactly n bytes into dst; `what` names the field for the
   message when the stream ends, breaks off or is corrupt first. */
static bool zin_read(struct zin *z, void *dst, size_t n, const char *what)
{
    unsigned char *out = dst;
    while (n > 0) {
        if (z->ended)
            return error_set(z->err,
                             "shape %d (byte %zu): its data ends after %zu bytes, inside its %s (counts larger than "
                             "the data?)",
                             z->shape, z->header, z->inflated, what);
        uInt chunk = n > UINT_MAX ? UINT_MAX : (uInt)n;
        z->zs.next_out = out;
        z->zs.avail_out = chunk;
        int rc = inflate(&z->zs, Z_NO_FLUSH);
        size_t got = chunk - z->zs.avail_out;
        out += got;
        n -= got;
        z->inflated += got;
        size_t at = (size_t)(z->zs.next_in - z->file);
        switch (rc) {
        case Z_OK:
            break;
        case Z_STREAM_END:
            z->ended = true;
            break;
        case Z_BUF_ERROR:
            return error_set(z->err,
                             "shape %d (byte %zu): its zlib stream breaks off at byte %zu, the end of the shapes' "
                             "data, inside its %s: truncated",
                             z->shape, z->header, at, what);
        case Z_MEM_ERROR:
            return error_set(z->err, "shape %d (byte %zu): out of memory in zlib", z->shape, z->header);
        default: /* Z_DATA_ERROR, Z_NEED_DICT, Z_STREAM_ERROR */
            return error_set(z->err, "shape %d (byte %zu): corrupt zlib stream near byte %zu, inside its %s: %s",
                             z->shape, z->header, at, what,
                             rc == Z_NEED_DICT ? "a preset dictionary"
                             : z->zs.msg       ? z->zs.msg
                                               : "inflate failed");
        }
    }
    return true;
}

/* Reads past n bytes of a field the renderer does not use. */
static bool zin_skip(struct zin *z, uint64_t n, const char *what)
{
    unsigned char buf[1 << 14];
    while (n > 0) {
        size_t k = n > sizeof buf ? sizeof buf : (size_t)n;
        if (!zin_read(z, buf, k, what)) return false;
        n -= k;
    }
    return true;
}

/* After the indices: the stream must end there, its checksum included
   (inflate checks it). No byte may come out on the way. */
static bool zin_finish(struct zin *z, int n_triangles)
{
    unsigned char extra;
    while (!z->ended) {
        z->zs.next_out = &extra;
        z->zs.avail_out = 1;
        int rc = inflate(&z->zs, Z_NO_FLUSH);
        if (z->zs.avail_out == 0)
            return error_set(z->err,
                             "shape %d (byte %zu): its data goes on after the indices of its %d triangles, at byte "
                             "%zu of its data (expected the end: counts smaller than the data?)",
                             z->shape, z->header, n_triangles, z->inflated);
        if (rc == Z_STREAM_END) return true;
        if (rc != Z_OK) return zin_read(z, &extra, 1, "end (the zlib checksum)");
    }
    return true;
}

/* The shape's name (version 4): UTF-8 up to a NUL, which is not checked
   further: the renderer does not use it. */
static bool read_name(struct zin *z)
{
    for (int i = 0; i < MESH_SERIALIZED_NAME_MAX; ++i) {
        unsigned char c;
        if (!zin_read(z, &c, 1, "name")) return false;
        if (c == '\0') return true;
    }
    return error_set(z->err, "shape %d (byte %zu): a name longer than %d bytes (expected a NUL-terminated name)",
                     z->shape, z->header, MESH_SERIALIZED_NAME_MAX - 1);
}

static bool read_positions(struct zin *z, size_t real_bytes, struct mesh_serialized *m)
{
    unsigned char buf[1 << 15];
    size_t per = 3 * real_bytes, batch = sizeof buf / per;
    for (int v = 0; v < m->n_vertices;) {
        int k = m->n_vertices - v < (int)batch ? m->n_vertices - v : (int)batch;
        if (!zin_read(z, buf, (size_t)k * per, "positions")) return false;
        for (int i = 0; i < k; ++i, ++v) {
            const unsigned char *p = buf + (size_t)i * per;
            struct vec3 q = real_bytes == 4 ? vec3_make(f32le(p), f32le(p + 4), f32le(p + 8))
                                            : vec3_make(f64le(p), f64le(p + 8), f64le(p + 16));
            if (!isfinite(q.x) || !isfinite(q.y) || !isfinite(q.z))
                return error_set(z->err, "shape %d (byte %zu): vertex %d is not finite (%g, %g, %g)", z->shape,
                                 z->header, v, q.x, q.y, q.z);
            m->positions[v] = q;
        }
    }
    return true;
}

static bool read_indices(struct zin *z, struct mesh_serialized *m)
{
    unsigned char buf[12 << 11];
    for (int t = 0; t < m->n_triangles;) {
        int k = m->n_triangles - t < (int)(sizeof buf / 12) ? m->n_triangles - t : (int)(sizeof buf / 12);
        if (!zin_read(z, buf, (size_t)k * 12, "indices")) return false;
        for (int i = 0; i < k; ++i, ++t)
            for (int c = 0; c < 3; ++c) {
                uint32_t idx = u32le(buf + 12 * i + 4 * c);
                if (idx >= (uint32_t)m->n_vertices)
                    return error_set(z->err,
                                     "shape %d (byte %zu): triangle %d has vertex index %u, out of range (expected 0 "
                                     "to %d)",
                                     z->shape, z->header, t, (unsigned)idx, m->n_vertices - 1);
                m->triangles[t][c] = (int)idx;
            }
    }
    return true;
}

/* The counts against the limits and against what the stream can hold;
   then the arrays. */
static bool check_counts(struct zin *z, uint64_t nv, uint64_t nt, uint64_t vertex_bytes, size_t stream_bytes)
{
    if (nv == 0 || nt == 0)
        return error_set(z->err, "shape %d (byte %zu): %llu vertices, %llu triangles (expected at least one triangle)",
                         z->shape, z->header, (unsigned long long)nv, (unsigned long long)nt);
    if (nv > INT_MAX / 2 || nt > MESH_FILE_TRIANGLES_MAX)
        return error_set(z->err,
                         "shape %d (byte %zu): %llu vertices, %llu triangles (expected at most %d vertices and %d "
                         "triangles)",
                         z->shape, z->header, (unsigned long long)nv, (unsigned long long)nt, INT_MAX / 2,
                         MESH_FILE_TRIANGLES_MAX);
    uint64_t need = z->inflated + nv * vertex_bytes + nt * 12;
    uint64_t can = (uint64_t)stream_bytes * INFLATE_RATIO_MAX + INFLATE_SLACK;
    if (need > can)
        return error_set(z->err,
                         "shape %d (byte %zu): %llu vertices and %llu triangles take %llu bytes, but its zlib stream "
                         "of at most %zu bytes inflates to at most %llu (counts larger than the data)",
                         z->shape, z->header, (unsigned long long)nv, (unsigned long long)nt, (unsigned long long)need,
                         stream_bytes, (unsigned long long)can);
    return true;
}

/* The stream after the header: flags, name, counts, arrays, end. */
static bool read_shape(struct zin *z, unsigned version, size_t stream_bytes, struct mesh_serialized *m)
{
    unsigned char head[16];
    if (!zin_read(z, head, 4, "flags")) return false;
    uint32_t flags = u32le(head);
    bool single = flags & FLAG_SINGLE, dbl = flags & FLAG_DOUBLE;
    if (single == dbl)
        return error_set(z->err,
                         "shape %d (byte %zu): flags 0x%04X set %s precision flag (expected exactly one of single "
                         "0x1000 and double 0x2000)",
                         z->shape, z->header, (unsigned)flags, single ? "each" : "no");
    if (version == 4 && !read_name(z)) return false;
    if (!zin_read(z, head, 16, "counts")) return false;
    uint64_t nv = u64le(head), nt = u64le(head + 8);
    size_t real_bytes = single ? 4 : 8;
    uint64_t reals =
        3 + (flags & FLAG_NORMALS ? 3 : 0) + (flags & FLAG_TEXCOORDS ? 2 : 0) + (flags & FLAG_COLORS ? 3 : 0);
    if (!check_counts(z, nv, nt, reals * real_bytes, stream_bytes)) return false;
    m->n_vertices = (int)nv;
    m->n_triangles = (int)nt;
    m->positions = malloc(sizeof *m->positions * (size_t)nv);
    m->triangles = malloc(sizeof *m->triangles * (size_t)nt);
    if (!m->positions || !m->triangles)
        return error_set(z->err, "shape %d (byte %zu): out of memory for %llu vertices and %llu triangles", z->shape,
                         z->header, (unsigned long long)nv, (unsigned long long)nt);
    return read_positions(z, real_bytes, m) &&
           (!(flags & FLAG_NORMALS) || zin_skip(z, nv * 3 * real_bytes, "normals")) &&
           (!(flags & FLAG_TEXCOORDS) || zin_skip(z, nv * 2 * real_bytes, "texture coordinates")) &&
           (!(flags & FLAG_COLORS) || zin_skip(z, nv * 3 * real_bytes, "colors")) && read_indices(z, m) &&
           zin_finish(z, m->n_triangles);
}

bool mesh_serialized_read(const void *data, size_t size, int shape, struct mesh_serialized *out, struct error *err)
{
    memset(out, 0, sizeof *out);
    const unsigned char *d = data;
    struct layout lay = { 0, 0, 0, 0 };
    if (!layout_read(d, size, &lay, err)) return false;
    if (shape < 0 || (uint32_t)shape >= lay.n_shapes)
        return error_set(err, "shape %d out of range (the file holds %u shape%s: expected 0 to %u)", shape,
                         (unsigned)lay.n_shapes, lay.n_shapes == 1 ? "" : "s", (unsigned)lay.n_shapes - 1);
    struct zin z;
    memset(&z, 0, sizeof z);
    z.file = d;
    z.shape = shape;
    z.header = (size_t)layout_offset(d, &lay, (uint32_t)shape);
    z.err = err;
    /* The stream runs at most to the dictionary; it ends where zlib says. */
    size_t stream_bytes = lay.dictionary - z.header - 4;
    z.zs.next_in = (Bytef *)(uintptr_t)(d + z.header + 4); /* zlib's API is not const; it only reads */
    z.zs.avail_in = (uInt)stream_bytes;
    if (inflateInit(&z.zs) != Z_OK) return error_set(err, "shape %d: zlib could not start", shape);
    bool ok = read_shape(&z, lay.version, stream_bytes, out);
    inflateEnd(&z.zs);
    if (!ok) mesh_serialized_free(out);
    return ok;
}

void mesh_serialized_free(struct mesh_serialized *m)
{
    free(m->positions);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

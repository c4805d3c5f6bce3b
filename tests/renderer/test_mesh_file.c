/* test_mesh_file.c: meshes from OBJ and PLY files (mesh_file.h, ply_check.h)
   and their place in configs: triangle counts and positions of the
   fixtures in tests/configs/meshes, the same mesh from ASCII and both
   binary PLYs, what each bad file gives, nothing on stdout, transforms of
   file meshes, the digest in the effective YAML and the hashes, mesh files
   in config.files, the render's exit status for bad meshes, and a cube
   from an OBJ file against the inline box. */
#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_util.h"
#include "config/config.h"
#include "config/mesh_file.h"
#include "config/ply_check.h"
#include "render_util.h"
#include "testlib.h"
#include "base/transform.h"

#define MESHES     "tests/configs/meshes"
#define BAD_MESHES "tests/configs/bad/meshes"
#define GOOD       "tests/configs/good"

static bool read_file(const char *path, char **data, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return false;
    size_t cap = 1 << 16, n = 0, got;
    char *buf = malloc(cap + 1);
    while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
        n += got;
        if (n == cap) {
            char *grown = realloc(buf, (cap *= 2) + 1);
            if (!grown) {
                free(buf);
                buf = NULL;
            }
            buf = grown;
        }
    }
    fclose(f);
    if (buf) buf[n] = '\0'; /* for the text files */
    *data = buf;
    *size = n;
    return buf != NULL;
}

static bool load_mesh(const char *path, struct mesh_data *m, struct error *err)
{
    char *data;
    size_t size;
    enum mesh_format fmt;
    if (!mesh_format_from_path(path, &fmt)) return error_set(err, "no format");
    if (!read_file(path, &data, &size)) return error_set(err, "cannot read %s", path);
    bool ok = mesh_file_parse(data, size, fmt, m, err);
    free(data);
    return ok;
}

static struct vec3 tri_normal(const struct mesh_data *m, int t)
{
    struct vec3 a = m->vertices[m->triangles[t][0]], b = m->vertices[m->triangles[t][1]],
                c = m->vertices[m->triangles[t][2]];
    return vec3_cross(vec3_sub(b, a), vec3_sub(c, a));
}

static double mesh_area(const struct mesh_data *m)
{
    double area = 0.0;
    for (int t = 0; t < m->n_triangles; ++t) area += 0.5 * vec3_length(tri_normal(m, t));
    return area;
}

/* Counts, winding and area of the good fixtures. */
static void test_good_fixtures(void)
{
    struct mesh_data m;
    struct error err = { "" };
    CHECK_MSG(load_mesh(MESHES "/cube.obj", &m, &err), "%s", err.message);
    CHECK(m.n_vertices == 8 && m.n_triangles == 12);
    CHECK_NEAR(mesh_area(&m), 6.0, 1e-12);
    /* Every triangle faces out of the cube (centre (0, 0.5, 0)). */
    for (int t = 0; t < m.n_triangles; ++t) {
        struct vec3 c = vec3_scale(vec3_add(vec3_add(m.vertices[m.triangles[t][0]], m.vertices[m.triangles[t][1]]),
                                            m.vertices[m.triangles[t][2]]),
                                   1.0 / 3.0);
        CHECK(vec3_dot(tri_normal(&m, t), vec3_sub(c, vec3_make(0, 0.5, 0))) > 0.0);
    }
    mesh_data_free(&m);

    /* v/vt/vn, negative indices, quad + pentagon + triangle, two objects,
       groups, a line (skipped) and a missing mtllib (ignored). */
    CHECK_MSG(load_mesh(MESHES "/mixed.obj", &m, &err), "%s", err.message);
    CHECK_MSG(m.n_triangles == 2 + 3 + 1, "%d triangles", m.n_triangles);
    /* The floor's 2 x 2, the pentagon's area by the shoelace formula, the side's 0.5 x 1 / 2. */
    double pent = 0.5 * fabs((0 * 0.5 - 0.4 * 0.5) + (0.4 * 0.8 - 0.5 * 0.5) + (0.5 * 1.0 - 0.2 * 0.8) +
                             (0.2 * 0.8 - (-0.1) * 1.0) + ((-0.1) * 0.5 - 0 * 0.8));
    CHECK_NEAR(mesh_area(&m), 4.0 + pent + 0.25, 1e-6);
    bool found_corner = false;
    for (int v = 0; v < m.n_vertices; ++v)
        if (m.vertices[v].x == (double)0.2f && m.vertices[v].y == 1.0 && m.vertices[v].z == 0.0) found_corner = true;
    CHECK(found_corner); /* assimp reads floats */
    mesh_data_free(&m);

    /* One mesh in three encodings: the same vertices and triangles. */
    static const char *const plys[] = { MESHES "/polys_ascii.ply", MESHES "/polys_le.ply", MESHES "/polys_be.ply" };
    struct mesh_data first = { 0, NULL, 0, NULL };
    for (int i = 0; i < 3; ++i) {
        CHECK_MSG(load_mesh(plys[i], &m, &err), "%s: %s", plys[i], err.message);
        /* A quad and a pentagon; vertex 5 is in no face and is dropped. */
        CHECK_MSG(m.n_triangles == 5 && m.n_vertices == 5, "%s: %d triangles, %d vertices", plys[i], m.n_triangles,
                  m.n_vertices);
        for (int t = 0; t < m.n_triangles; ++t) CHECK(tri_normal(&m, t).y > 0.0);
        CHECK_NEAR(mesh_area(&m), 1.0 + 1.0 + 0.25, 1e-12);
        if (i == 0) {
            first = m;
            continue;
        }
        CHECK(m.n_vertices == first.n_vertices && m.n_triangles == first.n_triangles);
        if (m.n_vertices == first.n_vertices && m.n_triangles == first.n_triangles) {
            CHECK(!memcmp(m.vertices, first.vertices, sizeof *m.vertices * (size_t)m.n_vertices));
            CHECK(!memcmp(m.triangles, first.triangles, sizeof *m.triangles * (size_t)m.n_triangles));
        }
        mesh_data_free(&m);
    }
    mesh_data_free(&first);
}

/* Each bad file, straight through mesh_file_parse: the message, and out left empty. */
static void test_bad_files(void)
{
    static const struct {
        const char *file, *expect;
    } cases[] = {
        { "index_out_of_range.obj", "assimp: OBJ: vertex index out of range" },
        { "negative_out_of_range.obj", "assimp: OBJ: vertex index out of range" },
        { "nan_vertex.obj", "vertex 1 of object 0 is not finite" },
        { "inf_vertex.ply", "line 17: \"inf\" is not a finite decimal number" },
        { "garbage.obj", "no triangles" },
        { "binary.obj", "byte 7: a NUL byte: not a text file" },
        { "empty.obj", "empty file" },
        { "ply_content.obj", "line 1: a PLY file by its content" },
        { "obj_content.ply", "line 1: not a PLY file" },
        { "huge_count.ply", "line 3: element vertex declares 1000000000000 elements (expected at most 2147483647)" },
        { "large_count.ply", "line 7: element face declares 2000000000 elements, which take at least 2000000000 "
                             "bytes, but the file has 64 bytes after the header" },
        { "truncated.ply", "byte 447: the file ends inside face 0 (of 2): truncated" },
        { "no_end_header.ply", "line 5: the file ends in the header (expected end_header)" },
        { "face_index.ply", "line 22: face 0 has vertex index 9, out of range (expected 0 to 5)" },
        { "points_only.ply", "no face element in the header" },
        { "vertices_only.obj", "no triangles" },
        { "lines_only.obj", "no triangles" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char path[256];
        snprintf(path, sizeof path, "%s/%s", BAD_MESHES, cases[i].file);
        struct mesh_data m;
        struct error err = { "" };
        bool ok = load_mesh(path, &m, &err);
        CHECK_MSG(!ok && strstr(err.message, cases[i].expect), "%s: got \"%s\"", cases[i].file, err.message);
        CHECK(m.vertices == NULL && m.triangles == NULL && m.n_vertices == 0);
        if (ok) mesh_data_free(&m);
    }
    enum mesh_format fmt;
    CHECK(!mesh_format_from_path(BAD_MESHES "/cube.stl", &fmt));
    CHECK(!mesh_format_from_path("a.obj/cube", &fmt));
    CHECK(mesh_format_from_path("dir.x/CUBE.PLY", &fmt) && fmt == MESH_FORMAT_PLY);
}

/* Identical positions are joined by mesh_file.c itself (not by assimp's
   post-processing, which crashed on an OBJ without faces): repeated v lines,
   -0 and +0 alike, and only the vertices some triangle uses are kept, in
   the order of first use. */
static void test_join_identical(void)
{
    static const char obj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\n"
                              "v 1 -0 0\nv -0 1 0\nv 1 1 0\n"
                              "f 1 2 3\nf 5 7 6\nl 1 4\n";
    struct mesh_data m;
    struct error err = { "" };
    bool ok = mesh_file_parse(obj, sizeof obj - 1, MESH_FORMAT_OBJ, &m, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(m.n_triangles == 2 && m.n_vertices == 4);
    if (m.n_triangles == 2 && m.n_vertices == 4) {
        CHECK(m.triangles[0][0] == 0 && m.triangles[0][1] == 1 && m.triangles[0][2] == 2);
        CHECK(m.triangles[1][0] == 1 && m.triangles[1][1] == 3 && m.triangles[1][2] == 2);
        CHECK(m.vertices[3].x == 1.0 && m.vertices[3].y == 1.0 && m.vertices[3].z == 0.0);
    }
    mesh_data_free(&m);
}

/* The x of a float's 4 bytes, in memory order of the given endianness. */
static double float_of(const unsigned char *b, bool big_endian)
{
    unsigned char le[4];
    for (int i = 0; i < 4; ++i) le[i] = b[big_endian ? 3 - i : i];
    uint32_t u = (uint32_t)le[0] | (uint32_t)le[1] << 8 | (uint32_t)le[2] << 16 | (uint32_t)le[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* A binary PLY whose body starts with 0x0a (the first vertex's x): assimp
   5.2.5 skipped that byte after end_header's line as if it were text,
   misread every count and aborted the process (0x0d, 0x20 and 0x09 it read
   right: kept here as neighbours); the renderer reads PLY itself. body_newline.ply (little-endian, 0x0a), then
   in memory each of those bytes, little- and big-endian (the same file
   with every value's bytes reversed). */
static void test_ply_body_whitespace(void)
{
    char *data;
    size_t size;
    CHECK(read_file(MESHES "/body_newline.ply", &data, &size));
    if (!data) return;
    const char *end = strstr(data, "end_header\n");
    CHECK(end != NULL && size == (size_t)(end - data) + 11 + 4 * 12 + 2 * 13);
    if (!end || size != (size_t)(end - data) + 11 + 4 * 12 + 2 * 13) {
        free(data);
        return;
    }
    size_t body = (size_t)(end - data) + 11;
    CHECK((unsigned char)data[body] == 0x0a);
    static const char be_header[] = "ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\n"
                                    "property float y\nproperty float z\nelement face 2\n"
                                    "property list uchar int vertex_indices\nend_header\n";
    size_t be_body = sizeof be_header - 1, be_size = be_body + size - body;
    char *be = malloc(be_size);
    CHECK(be != NULL);
    if (!be) {
        free(data);
        return;
    }
    memcpy(be, be_header, be_body);
    for (int v = 0; v < 12; ++v)
        for (int i = 0; i < 4; ++i)
            be[be_body + 4 * (size_t)v + (size_t)i] = data[body + 4 * (size_t)v + 3 - (size_t)i];
    for (int f = 0; f < 2; ++f) {
        size_t o = 48 + 13 * (size_t)f;
        be[be_body + o] = data[body + o];
        for (int k = 0; k < 3; ++k)
            for (int i = 0; i < 4; ++i)
                be[be_body + o + 1 + 4 * (size_t)k + (size_t)i] = data[body + o + 1 + 4 * (size_t)k + 3 - (size_t)i];
    }
    static const unsigned char firsts[] = { 0x0a, 0x0d, 0x20, 0x09 };
    for (int e = 0; e < 2; ++e) {
        char *buf = e ? be : data;
        size_t n = e ? be_size : size, at = e ? be_body : body;
        for (size_t k = 0; k < sizeof firsts; ++k) {
            buf[at] = (char)firsts[k];
            struct mesh_data m;
            struct error err = { "" };
            bool ok = mesh_file_parse(buf, n, MESH_FORMAT_PLY, &m, &err);
            CHECK_MSG(ok, "%s, first byte 0x%02x: %s", e ? "big-endian" : "little-endian", firsts[k], err.message);
            if (!ok) continue;
            /* The square's two triangles; vertex 0 is the first one used. */
            CHECK(m.n_triangles == 2 && m.n_vertices == 4);
            double x = float_of((const unsigned char *)buf + at, e == 1);
            CHECK(x != 0.0 && x != 1.0);
            bool found = false;
            for (int v = 0; v < m.n_vertices; ++v) found |= m.vertices[v].x == x && m.vertices[v].z == 0.0;
            CHECK_MSG(found, "%s, first byte 0x%02x: x = %g not found", e ? "big-endian" : "little-endian", firsts[k],
                      x);
            mesh_data_free(&m);
        }
    }
    free(be);
    free(data);
}

/* Zero-area triangles: mesh_file_parse keeps them (it only reads), a
   surface in a config drops them with one warning per mesh on stderr that
   counts them (good/mesh_degenerate.yaml), and the vertices only they used;
   a mesh light refuses them and a mesh of nothing else is refused
   (bad/mesh_light_degenerate.yaml, bad/mesh_file_degenerate.yaml). */
static void test_degenerate_dropped(void)
{
    struct mesh_data m;
    struct error err = { "" };
    CHECK_MSG(load_mesh(MESHES "/degenerate_tris.ply", &m, &err), "%s", err.message);
    CHECK(m.n_triangles == 6 && m.n_vertices == 5);
    mesh_data_free(&m);

    char tmp[] = "/tmp/portal-stderr-XXXXXX";
    int fd = mkstemp(tmp);
    CHECK(fd >= 0);
    if (fd < 0) return;
    fflush(stderr);
    int saved = dup(2);
    dup2(fd, 2);
    struct config c;
    bool ok = config_load(GOOD "/mesh_degenerate.yaml", NULL, 0, &c, &err);
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    char text[2048] = "";
    ssize_t got = pread(fd, text, sizeof text - 1, 0);
    text[got > 0 ? got : 0] = '\0';
    close(fd);
    unlink(tmp);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.n_shapes == 2);
    CHECK_MSG(c.shapes[0].n_triangles == 2 && c.shapes[0].n_vertices == 4, "floor: %d triangles, %d vertices",
              c.shapes[0].n_triangles, c.shapes[0].n_vertices);
    CHECK(c.shapes[1].n_triangles == 1 && c.shapes[1].n_vertices == 3);
    for (int s = 0; s < 2; ++s)
        for (int t = 0; t < c.shapes[s].n_triangles; ++t)
            for (int k = 0; k < 3; ++k)
                CHECK(c.shapes[s].triangles[t][k] >= 0 && c.shapes[s].triangles[t][k] < c.shapes[s].n_vertices);
    static const char *const want[] = {
        "mesh_degenerate.yaml:10:53: warning: mesh \"../meshes/degenerate_tris.ply\": dropped 4 degenerate "
        "(zero-area) triangles of 6, the first triangle 2 (after triangulation)\n",
        "mesh_degenerate.yaml:11:53: warning: mesh \"../bad/meshes/degenerate.obj\": dropped 1 degenerate "
        "(zero-area) triangle of 2, the first triangle 0 (after triangulation)\n",
    };
    for (int i = 0; i < 2; ++i) CHECK_MSG(strstr(text, want[i]) != NULL, "stderr: %s", text);
    int lines = 0;
    for (const char *p = text; (p = strchr(p, '\n')) != NULL; ++p) ++lines;
    CHECK_MSG(lines == 2, "stderr: %s", text);
    config_free(&c);
}

/* Truncating a binary and an ASCII PLY at every byte: an error each time
   (never a crash or a silently shorter mesh), except for the ASCII file's
   last two bytes: without its final newline, or with the last value "45"
   cut to "4", it is still a whole file. */
static void test_ply_every_truncation(void)
{
    static const char *const files[] = { MESHES "/polys_le.ply", MESHES "/polys_be.ply", MESHES "/polys_ascii.ply" };
    for (int k = 0; k < 3; ++k) {
        char *data;
        size_t size;
        CHECK(read_file(files[k], &data, &size));
        int accepted = 0;
        for (size_t n = 0; n < size; ++n) {
            struct mesh_data m;
            struct error err = { "" };
            if (mesh_file_parse(data, n, MESH_FORMAT_PLY, &m, &err)) {
                ++accepted;
                CHECK_MSG(k == 2 && n >= size - 2, "%s accepted at %zu of %zu bytes", files[k], n, size);
                mesh_data_free(&m);
            }
        }
        CHECK(accepted == (k == 2 ? 2 : 0));
        free(data);
    }
}

/* Nothing reaches stdout while meshes load, good or bad (stdout is the
   render's JSON event stream). */
static void test_no_stdout(void)
{
    char tmp[] = "/tmp/portal-stdout-XXXXXX";
    int fd = mkstemp(tmp);
    CHECK(fd >= 0);
    if (fd < 0) return;
    fflush(stdout);
    int saved = dup(1);
    dup2(fd, 1);
    static const char *const dirs[] = { MESHES, BAD_MESHES };
    int n = 0;
    for (int d = 0; d < 2; ++d) {
        DIR *dir = opendir(dirs[d]);
        for (struct dirent *e; dir && (e = readdir(dir)) != NULL;) {
            char path[512];
            snprintf(path, sizeof path, "%s/%s", dirs[d], e->d_name);
            struct mesh_data m;
            struct error err = { "" };
            enum mesh_format fmt;
            char *data;
            size_t size;
            if (!mesh_format_from_path(path, &fmt) || !read_file(path, &data, &size)) continue;
            /* Both formats for every file: assimp sees wrong-format input too. */
            for (int f = 0; f < 2; ++f)
                if (mesh_file_parse(data, size, (enum mesh_format)f, &m, &err)) mesh_data_free(&m);
            free(data);
            ++n;
        }
        if (dir) closedir(dir);
    }
    fflush(stdout);
    dup2(saved, 1);
    close(saved);
    struct stat st;
    CHECK(fstat(fd, &st) == 0 && st.st_size == 0);
    close(fd);
    unlink(tmp);
    CHECK(n >= 20);
}

/* good/mesh_files.yaml: counts, positions after each transform, the
   mirror's reversed winding, config.files, the effective YAML. */
static void test_config_meshes(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load(GOOD "/mesh_files.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.n_shapes == 4);
    struct mesh_data raw, ply;
    CHECK(load_mesh(MESHES "/mixed.obj", &raw, &err) && load_mesh(MESHES "/polys_be.ply", &ply, &err));
    /* mixed: [{scale: 2}, {rotate: {axis: [0, 1, 0], angle: -30}}, {translate: [1, 2, 3]}]. */
    const struct shape_desc *s = &c.shapes[0];
    CHECK(s->n_vertices == raw.n_vertices && s->n_triangles == raw.n_triangles && s->n_quads == 0);
    double a = -30 * M_PI / 180;
    for (int v = 0; v < raw.n_vertices && v < s->n_vertices; ++v) {
        struct vec3 p = vec3_scale(raw.vertices[v], 2.0);
        struct vec3 r = vec3_make(p.x * cos(a) + p.z * sin(a), p.y, -p.x * sin(a) + p.z * cos(a));
        struct vec3 e = vec3_add(r, vec3_make(1, 2, 3));
        CHECK_NEAR(s->vertices[v].x, e.x, 1e-14);
        CHECK_NEAR(s->vertices[v].y, e.y, 1e-14);
        CHECK_NEAR(s->vertices[v].z, e.z, 1e-14);
    }
    CHECK(!memcmp(s->triangles, raw.triangles, sizeof *raw.triangles * (size_t)raw.n_triangles));
    /* ascii: translated by -2 in x, exactly. */
    CHECK(c.shapes[1].n_triangles == 5 && c.shapes[1].vertices[0].x == ply.vertices[0].x - 2.0);
    /* le: no transform, the file's floats exactly. */
    CHECK(!memcmp(c.shapes[2].vertices, ply.vertices, sizeof *ply.vertices * (size_t)ply.n_vertices));
    /* be: z -> -z mirrors, so each triangle keeps its first corner and swaps the other two. */
    const struct shape_desc *be = &c.shapes[3];
    for (int t = 0; t < ply.n_triangles; ++t)
        CHECK(be->triangles[t][0] == ply.triangles[t][0] && be->triangles[t][1] == ply.triangles[t][2] &&
              be->triangles[t][2] == ply.triangles[t][1]);
    for (int v = 0; v < ply.n_vertices; ++v)
        CHECK(be->vertices[v].x == ply.vertices[v].x + 2.0 && be->vertices[v].z == -ply.vertices[v].z);
    /* The light, turned over and lifted: it faces down at y = 3. */
    CHECK(c.lights[0].polygon.v[0].y == 3.0 && polygon_normal(&c.lights[0].polygon).y == -1.0);
    mesh_data_free(&raw);
    mesh_data_free(&ply);

    /* config.files: the config, then each mesh once, as opened. */
    CHECK(c.n_files == 5);
    if (c.n_files == 5) {
        CHECK(!strcmp(c.files[1], GOOD "/../meshes/mixed.obj"));
        CHECK(!strcmp(c.files[4], GOOD "/../meshes/polys_be.ply"));
    }
    /* The effective YAML keeps each file by its absolute path, with the
       composed matrix and the digest. */
    char cwd[PATH_MAX - 128], abs[PATH_MAX];
    CHECK(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(abs, sizeof abs, "    file: \"%s/" MESHES "/mixed.obj\"\n    transform: [{matrix: [", cwd);
    CHECK_MSG(strstr(c.effective_yaml, abs) != NULL, "%s", c.effective_yaml);
    CHECK(strstr(c.effective_yaml, "digest: {fnv1a64: \"") != NULL);
    CHECK(strstr(c.effective_yaml, "type: mesh\n    material: \"grey\"\n    file: ") != NULL);
    config_free(&c);

    /* transforms.yaml: the mirrored inline triangle reversed, the lamp turned over. */
    ok = config_load(GOOD "/transforms.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.shapes[2].triangles[0][0] == 0 && c.shapes[2].triangles[0][1] == 2 && c.shapes[2].triangles[0][2] == 1);
    CHECK(c.shapes[2].vertices[1].x == -2.0);
    CHECK(polygon_normal(&c.lights[0].polygon).y == -1.0 && c.lights[0].polygon.v[0].y == 2.5);
    CHECK(c.portals[0].polygon.v[0].y == 2.0);
    CHECK(c.shapes[0].vertices[0].x == -3.0 && c.shapes[0].vertices[0].z == -3.0);
    CHECK(strstr(c.effective_yaml, "transform") == NULL);
    config_free(&c);
}

static bool copy_file(const char *from, const char *to)
{
    char *data;
    size_t size;
    if (!read_file(from, &data, &size)) return false;
    FILE *f = fopen(to, "wb");
    bool ok = f && fwrite(data, 1, size, f) == size;
    if (f) ok = fclose(f) == 0 && ok;
    free(data);
    return ok;
}

/* The hashes follow the mesh file's bytes; a config.yaml whose mesh has
   changed since does not load; a relative path in a string config is an
   error, an absolute one loads. */
static void test_digest_and_hash(void)
{
    char dir[] = "/tmp/portal-mesh-XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char cfg[128], mesh[128];
    snprintf(cfg, sizeof cfg, "%s/scene.yaml", dir);
    snprintf(mesh, sizeof mesh, "%s/cube.obj", dir);
    CHECK(copy_file(GOOD "/mesh_cube_obj.yaml", cfg));
    char *text;
    size_t len;
    CHECK(read_file(cfg, &text, &len));
    /* The copied config names ../meshes/cube.obj: point it next to itself. */
    char *at = strstr(text, "../meshes/cube.obj");
    CHECK(at != NULL);
    if (!at) return;
    FILE *f = fopen(cfg, "wb");
    fprintf(f, "%.*scube.obj%s", (int)(at - text), text, at + strlen("../meshes/cube.obj"));
    fclose(f);
    free(text);
    CHECK(copy_file(MESHES "/cube.obj", mesh));

    struct config a, b, back;
    struct error err = { "" };
    CHECK_MSG(config_load(cfg, NULL, 0, &a, &err), "%s", err.message);
    f = fopen(mesh, "ab");
    fputs("# one more comment: the same mesh, other bytes\n", f);
    fclose(f);
    CHECK_MSG(config_load(cfg, NULL, 0, &b, &err), "%s", err.message);
    if (!a.effective_yaml || !b.effective_yaml) return;
    CHECK(a.hash != b.hash && a.image_hash != b.image_hash);
    /* The first effective YAML no longer matches the file. */
    bool ok = config_load_string(a.effective_yaml, strlen(a.effective_yaml), "config.yaml", NULL, 0, &back, &err);
    CHECK_MSG(!ok && strstr(err.message, "has changed: fnv1a64 ") &&
                  strstr(err.message, "expected the file the "
                                      "config was made with"),
              "%s", err.message);
    /* The second one loads back to the same text. */
    ok = config_load_string(b.effective_yaml, strlen(b.effective_yaml), "config.yaml", NULL, 0, &back, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(!strcmp(back.effective_yaml, b.effective_yaml) && back.hash == b.hash);
        CHECK(back.shapes[1].n_triangles == 12);
        config_free(&back);
    }
    config_free(&a);
    config_free(&b);

    static const char relative[] =
        "camera: {position: [0, 1, 5], look_at: [0, 1, 0], up: [0, 1, 0], fov_y: 40}\n"
        "film: {width: 4, height: 4}\nmaterials: {grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}}\n"
        "shapes: [{type: mesh, material: grey, file: cube.obj}]\n"
        "lights: [{name: l, vertices: [[0, 2, 0], [0, 2, 1], [1, 2, 1]], radiance: [1, 1, 1]}]\nrender: {spp: 1}\n";
    ok = config_load_string(relative, sizeof relative - 1, "s.yaml", NULL, 0, &back, &err);
    CHECK_MSG(!ok && strstr(err.message, "s.yaml:4:45: mesh \"cube.obj\": a relative path in a config given as a "
                                         "string"),
              "%s", err.message);
    const struct config_override ov = { "shapes.0.file", mesh };
    ok = config_load_string(relative, sizeof relative - 1, "s.yaml", &ov, 1, &back, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(back.n_files == 2 && !strcmp(back.files[1], mesh));
        config_free(&back);
    }
    remove_tree(dir);
}

/* Every bad config about meshes and transforms, through the binary: exit
   2, the message on stderr, nothing on stdout, no output folder. */
static void test_cli_bad(void)
{
    find_binary();
    DIR *d = opendir("tests/configs/bad");
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d)) != NULL;) {
        if (strncmp(e->d_name, "mesh_file_", 10) && strncmp(e->d_name, "transform_", 10)) continue;
        char path[512], out[64], line[1024] = "";
        snprintf(path, sizeof path, "tests/configs/bad/%s", e->d_name);
        FILE *f = fopen(path, "r");
        if (!f || !fgets(line, sizeof line, f)) line[0] = '\0';
        if (f) fclose(f);
        line[strcspn(line, "\n")] = '\0';
        char tmp[] = "/tmp/portal-bad-XXXXXX";
        make_tmpdir(tmp);
        snprintf(out, sizeof out, "%s/out", tmp);
        char *argv[] = { NULL, path, "--out", out, NULL };
        struct run r;
        run_render(argv, 0, 0, &r);
        CHECK_MSG(r.status == 2, "%s: status %d", path, r.status);
        CHECK_MSG(strstr(r.err, line + 10) != NULL, "%s: stderr %s", path, r.err);
        CHECK_MSG(r.out[0] == '\0', "%s: stdout %s", path, r.out);
        CHECK(!exists(out));
        remove_tree(tmp);
        ++n;
    }
    if (d) closedir(d);
    CHECK(n >= 30);
}

/* The unit cube from an OBJ file and the inline box of the same corners:
   the OBJ's quads start at the corner that makes assimp's split Embree's
   split of the box's quads, so the traced triangles are the same, and
   Embree's quad and triangle intersectors (robust mode) give the same
   hits: the images are bit-identical (measured; the noise test stays as
   the weaker claim that would hold for any triangulation). */
static void test_cube_matches_box(void)
{
    struct film_image obj, box;
    CHECK(render_to_image(GOOD "/mesh_cube_obj.yaml", NULL, 0, &obj, NULL));
    CHECK(render_to_image(GOOD "/mesh_cube_box.yaml", NULL, 0, &box, NULL));
    int n = obj.width * obj.height * 3, differ = 0;
    for (int i = 0; i < n; ++i) differ += memcmp(&obj.rgb[i], &box.rgb[i], sizeof(float)) != 0;
    double z = images_max_block_z(&obj, &box, 4);
    printf("  cube.obj against the box: %d of %d values differ, largest block z %.3g\n", differ, n, z);
    CHECK(z < 4.0);
    CHECK(differ == 0);
    film_image_free(&obj);
    film_image_free(&box);
}

static const struct test_case tests[] = {
    { "good_fixtures", test_good_fixtures },
    { "bad_files", test_bad_files },
    { "join_identical", test_join_identical },
    { "ply_every_truncation", test_ply_every_truncation },
    { "ply_body_whitespace", test_ply_body_whitespace },
    { "degenerate_dropped", test_degenerate_dropped },
    { "no_stdout", test_no_stdout },
    { "config_meshes", test_config_meshes },
    { "digest_and_hash", test_digest_and_hash },
    { "cli_bad", test_cli_bad },
    { "cube_matches_box", test_cube_matches_box },
};

TEST_MAIN(tests)

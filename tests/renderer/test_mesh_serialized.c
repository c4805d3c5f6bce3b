/* test_mesh_serialized.c: Mitsuba's serialized meshes (mesh_serialized.h
   through mesh_file.h) and their place in configs: the geometry of every
   shape of the fixtures that tests/configs/meshes/make_fixtures.py writes
   (versions 3 and 4, single and double precision), what each bad file
   gives, every truncation and every flipped byte refused or harmless,
   shape_index in configs and in the effective YAML, and the cube of a
   serialized file rendered against the inline box. */
#include <limits.h>
#include <unistd.h>

#include "config/config.h"
#include "config/mesh_file.h"
#include "config/mesh_serialized.h"
#include "render_util.h"
#include "testlib.h"

#define MESHES     "tests/configs/meshes"
#define BAD_MESHES "tests/configs/bad/meshes"
#define GOOD       "tests/configs/good"

static bool read_file(const char *path, unsigned char **data, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return false;
    size_t cap = 1 << 12, n = 0, got;
    unsigned char *buf = malloc(cap);
    while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0)
        if ((n += got) == cap) {
            unsigned char *grown = realloc(buf, cap *= 2);
            if (!grown) free(buf);
            buf = grown;
        }
    fclose(f);
    *data = buf;
    *size = n;
    return buf != NULL;
}

static bool load_shape(const char *path, int shape, struct mesh_data *m, struct error *err)
{
    unsigned char *data;
    size_t size;
    if (!read_file(path, &data, &size)) return error_set(err, "cannot read %s", path);
    bool ok = mesh_file_parse_shape(data, size, MESH_FORMAT_SERIALIZED, shape, m, err);
    free(data);
    return ok;
}

static struct vec3 corner(const struct mesh_data *m, int t, int c)
{
    return m->vertices[m->triangles[t][c]];
}

static struct vec3 tri_normal(const struct mesh_data *m, int t)
{
    struct vec3 a = corner(m, t, 0);
    return vec3_cross(vec3_sub(corner(m, t, 1), a), vec3_sub(corner(m, t, 2), a));
}

static double mesh_area(const struct mesh_data *m)
{
    double area = 0.0;
    for (int t = 0; t < m->n_triangles; ++t) area += 0.5 * vec3_length(tri_normal(m, t));
    return area;
}

static bool same_mesh(const struct mesh_data *a, const struct mesh_data *b)
{
    return a->n_vertices == b->n_vertices && a->n_triangles == b->n_triangles &&
           !memcmp(a->vertices, b->vertices, sizeof *a->vertices * (size_t)a->n_vertices) &&
           !memcmp(a->triangles, b->triangles, sizeof *a->triangles * (size_t)a->n_triangles);
}

static const char *const fixtures[4] = { MESHES "/shapes_v4_single.serialized", MESHES "/shapes_v4_double.serialized",
                                         MESHES "/shapes_v3_single.serialized", MESHES "/shapes_v3_double.serialized" };

/* The generator's tetrahedron (make_fixtures.py TETRA_V, TETRA_T). */
static const double tetra_v[4][3] = { { 0.1, 0.2, 0.3 }, { 1.1, 0.2, 0.3 }, { 0.1, 1.2, 0.3 }, { 0.1, 0.2, 1.3 } };
static const int tetra_t[4][3] = { { 0, 2, 1 }, { 0, 1, 3 }, { 0, 3, 2 }, { 1, 2, 3 } };

/* 1. Every shape of every fixture: counts after the join, the square's
   area and facing, the tetrahedron's corners to the file's precision, and
   the cube equal to cube.obj's mesh (its vertices joined in the same
   order); version 3 and 4 files of one precision give the same meshes. */
static void test_good_fixtures(void)
{
    struct mesh_data first[2][3];
    for (int f = 0; f < 4; ++f) {
        bool dbl = f % 2 == 1;
        unsigned char *data;
        size_t size;
        int n = 0;
        struct error err = { "" };
        CHECK(read_file(fixtures[f], &data, &size));
        CHECK_MSG(mesh_file_shape_count(data, size, MESH_FORMAT_SERIALIZED, &n, &err) && n == 3, "%s: %d, %s",
                  fixtures[f], n, err.message);
        free(data);
        struct mesh_data m[3];
        for (int s = 0; s < 3; ++s) {
            bool ok = load_shape(fixtures[f], s, &m[s], &err);
            CHECK_MSG(ok, "%s shape %d: %s", fixtures[f], s, err.message);
            if (!ok) return;
        }
        /* The square: 6 vertices at 4 positions, two triangles facing +y. */
        CHECK(m[0].n_vertices == 4 && m[0].n_triangles == 2);
        CHECK_NEAR(mesh_area(&m[0]), 1.0, 0.0);
        for (int t = 0; t < 2; ++t) CHECK(tri_normal(&m[0], t).y > 0.0);
        /* The tetrahedron, corner by corner. */
        CHECK(m[1].n_vertices == 4 && m[1].n_triangles == 4);
        for (int t = 0; t < 4 && m[1].n_triangles == 4; ++t)
            for (int c = 0; c < 3; ++c) {
                const double *e = tetra_v[tetra_t[t][c]];
                struct vec3 p = corner(&m[1], t, c);
                for (int k = 0; k < 3; ++k) {
                    double want = dbl ? e[k] : (double)(float)e[k], got = k == 0 ? p.x : k == 1 ? p.y : p.z;
                    CHECK_MSG(got == want, "%s: tetra triangle %d corner %d axis %d: %.17g, expected %.17g",
                              fixtures[f], t, c, k, got, want);
                }
            }
        /* The cube: 24 vertices at 8 positions, as cube.obj. */
        CHECK(m[2].n_vertices == 8 && m[2].n_triangles == 12);
        CHECK_NEAR(mesh_area(&m[2]), 6.0, 1e-12);
        struct mesh_data obj;
        unsigned char *text;
        size_t len;
        CHECK(read_file(MESHES "/cube.obj", &text, &len));
        CHECK(mesh_file_parse(text, len, MESH_FORMAT_OBJ, &obj, &err));
        free(text);
        CHECK_MSG(same_mesh(&m[2], &obj), "%s: the cube differs from cube.obj", fixtures[f]);
        mesh_data_free(&obj);
        for (int s = 0; s < 3; ++s) {
            if (f < 2) first[dbl][s] = m[s];
            else {
                CHECK_MSG(same_mesh(&m[s], &first[dbl][s]), "%s shape %d differs from version 4", fixtures[f], s);
                mesh_data_free(&m[s]);
            }
        }
    }
    for (int p = 0; p < 2; ++p)
        for (int s = 0; s < 3; ++s) mesh_data_free(&first[p][s]);
}

/* 2. Each bad file: its message (naming the shape where one is read), and
   out left empty. */
static void test_bad_files(void)
{
    static const struct {
        const char *file, *expect;
    } cases[] = {
        { "serialized_empty.serialized", "empty file (expected a Mitsuba serialized mesh)" },
        { "serialized_wrong_id.serialized",
          "byte 0: format id 0x041D (expected 0x041C: not a Mitsuba serialized mesh)" },
        { "serialized_version5.serialized", "byte 2: version 5 (expected 3 or 4)" },
        { "serialized_truncated.serialized", "byte 159: shape count 1085581124, whose dictionary of 8684648992 bytes "
                                             "does not fit in the file of 163 bytes (truncated, or not the end of a "
                                             "serialized mesh)" },
        { "serialized_no_shapes.serialized", "byte 322: shape count 0 (expected at least one shape)" },
        { "serialized_huge_shape_count.serialized",
          "byte 322: shape count 1073741824, whose dictionary of 8589934592 bytes does not fit in the file of 326 "
          "bytes" },
        { "serialized_bad_offset.serialized",
          "dictionary entry 0 (byte 76): offset 1099511627776 is outside the shapes' data (expected at most 71, "
          "before the dictionary at byte 76)" },
        { "serialized_offset_not_header.serialized",
          "dictionary entry 0 (byte 76): offset 6 holds id 0x1063, version 24672 (expected a shape header: id "
          "0x041C, version 4)" },
        { "serialized_stream_cut.serialized", "shape 0 (byte 0): its zlib stream breaks off at byte 64, the end of "
                                              "the shapes' data, inside its indices: truncated" },
        { "serialized_corrupt.serialized", "shape 0 (byte 0): corrupt zlib stream near byte 47, inside its "
                                           "positions: invalid distance too far back" },
        { "serialized_lying_vertices.serialized",
          "shape 0 (byte 0): its data ends after 117 bytes, inside its positions (counts larger than the data?)" },
        { "serialized_lying_triangles.serialized",
          "shape 0 (byte 0): its data ends after 117 bytes, inside its indices (counts larger than the data?)" },
        { "serialized_short_count.serialized",
          "shape 0 (byte 0): its data goes on after the indices of its 3 triangles, at byte 105 of its data "
          "(expected the end: counts smaller than the data?)" },
        { "serialized_huge_count.serialized", "shape 0 (byte 0): 1099511627776 vertices, 4 triangles (expected at "
                                              "most 1073741823 vertices and 268435456 triangles)" },
        { "serialized_large_count.serialized",
          "shape 0 (byte 0): 100000000 vertices and 4 triangles take 1200000069 bytes, but its zlib stream of at "
          "most 70 bytes inflates to at most 73264 (counts larger than the data)" },
        { "serialized_index.serialized",
          "shape 0 (byte 0): triangle 1 has vertex index 4, out of range (expected 0 to 3)" },
        { "serialized_nan.serialized", "shape 0 (byte 0): vertex 1 is not finite (nan, 0, 0)" },
        { "serialized_no_precision.serialized",
          "shape 0 (byte 0): flags 0x0001 set no precision flag (expected exactly one of single 0x1000 and double "
          "0x2000)" },
        { "serialized_no_triangles.serialized",
          "shape 0 (byte 0): 4 vertices, 0 triangles (expected at least one triangle)" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char path[256];
        snprintf(path, sizeof path, "%s/%s", BAD_MESHES, cases[i].file);
        struct mesh_data m;
        struct error err = { "" };
        bool ok = load_shape(path, 0, &m, &err);
        CHECK_MSG(!ok && strstr(err.message, cases[i].expect), "%s: got \"%s\"", cases[i].file, err.message);
        CHECK(m.vertices == NULL && m.triangles == NULL && m.n_vertices == 0 && m.n_triangles == 0);
        if (ok) mesh_data_free(&m);
    }
    enum mesh_format fmt;
    CHECK(mesh_format_from_path("dir.obj/a.Serialized", &fmt) && fmt == MESH_FORMAT_SERIALIZED);
    CHECK(!mesh_format_from_path("a.serialize", &fmt) && !mesh_format_from_path("a.serializedx", &fmt));
}

/* 3. A shape index out of range, through the API: an error, for
   serialized and for OBJ files alike. */
static void test_shape_range(void)
{
    struct mesh_data m;
    struct error err = { "" };
    CHECK(!load_shape(fixtures[0], 3, &m, &err) &&
          strstr(err.message, "shape 3 out of range (the file holds 3 shapes: expected 0 to 2)"));
    CHECK(!load_shape(fixtures[2], -1, &m, &err) && strstr(err.message, "shape -1 out of range"));
    static const char obj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    CHECK(!mesh_file_parse_shape(obj, sizeof obj - 1, MESH_FORMAT_OBJ, 1, &m, &err) &&
          strstr(err.message, "shape 1 out of range (an OBJ file holds one mesh: expected 0)"));
    int n = 0;
    CHECK(mesh_file_shape_count(obj, sizeof obj - 1, MESH_FORMAT_OBJ, &n, &err) && n == 1);
}

/* 4. Every prefix of a fixture is refused (the dictionary is at the end),
   and every byte flipped gives an error or, where the flip is one the
   format cannot see, the same meshes: never a crash or other geometry. */
static void test_every_truncation_and_flip(void)
{
    for (int f = 0; f < 4; ++f) {
        unsigned char *data;
        size_t size;
        CHECK(read_file(fixtures[f], &data, &size));
        struct mesh_data good[3];
        struct error err = { "" };
        for (int s = 0; s < 3; ++s) CHECK(mesh_file_parse_shape(data, size, MESH_FORMAT_SERIALIZED, s, &good[s], &err));
        int accepted = 0, flips_seen = 0;
        for (size_t n = 0; n < size; ++n)
            for (int s = 0; s < 3; ++s) {
                struct mesh_data m;
                if (mesh_file_parse_shape(data, n, MESH_FORMAT_SERIALIZED, s, &m, &err)) {
                    ++accepted;
                    mesh_data_free(&m);
                }
            }
        CHECK_MSG(accepted == 0, "%s: %d prefixes accepted", fixtures[f], accepted);
        for (size_t i = 0; i < size; ++i) {
            data[i] ^= 0xFF;
            for (int s = 0; s < 3; ++s) {
                struct mesh_data m;
                if (mesh_file_parse_shape(data, size, MESH_FORMAT_SERIALIZED, s, &m, &err)) {
                    CHECK_MSG(same_mesh(&m, &good[s]), "%s: byte %zu flipped gives other geometry for shape %d",
                              fixtures[f], i, s);
                    mesh_data_free(&m);
                } else {
                    ++flips_seen;
                }
            }
            data[i] ^= 0xFF;
        }
        CHECK(flips_seen > 0);
        for (int s = 0; s < 3; ++s) mesh_data_free(&good[s]);
        free(data);
    }
}

/* 5. good/mesh_serialized.yaml: a shape of each file by shape_index, the
   transform applied, a mesh light; shape_index in the effective YAML and
   in both hashes. */
static void test_config(void)
{
    struct config c;
    struct error err = { "" };
    bool ok = config_load(GOOD "/mesh_serialized.yaml", NULL, 0, &c, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (!ok) return;
    CHECK(c.n_shapes == 3 && c.shapes[0].n_triangles == 12 && c.shapes[1].n_triangles == 4 &&
          c.shapes[2].n_triangles == 2);
    /* The tetrahedron of the double-precision file, moved by +1 in x. */
    bool found = false;
    for (int v = 0; v < c.shapes[1].n_vertices; ++v) {
        struct vec3 p = c.shapes[1].vertices[v];
        found |= p.x == 0.1 + 1.0 && p.y == 0.2 && p.z == 0.3;
    }
    CHECK(found);
    /* The light: the unit square turned over at y = 3, facing down. */
    CHECK(c.lights[0].mesh.n_triangles == 2 && c.lights[0].mesh.vertices[0].y == 3.0);
    CHECK(strstr(c.effective_yaml, "shapes_v4_single.serialized\"\n    shape_index: 2\n") != NULL);
    CHECK(strstr(c.effective_yaml, "shapes_v4_double.serialized\"\n    shape_index: 0\n") != NULL);
    CHECK(strstr(c.effective_yaml, "shapes_v3_single.serialized\"\n      shape_index: 0\n") != NULL);
    /* Another shape of the same file is another image. */
    struct config other;
    const struct config_override ov = { "shapes.0.shape_index", "1" };
    ok = config_load(GOOD "/mesh_serialized.yaml", &ov, 1, &other, &err);
    CHECK_MSG(ok, "%s", err.message);
    if (ok) {
        CHECK(other.shapes[0].n_triangles == 4 && other.image_hash != c.image_hash && other.hash != c.hash);
        config_free(&other);
    }
    config_free(&c);
}

/* 6. The cube of a serialized file in mesh_cube_obj.yaml's scene renders
   the inline box's image bit for bit: its mesh is cube.obj's, whose
   triangles are Embree's split of the box's quads (test_mesh_file.c). */
static void test_cube_matches_box(void)
{
    char cwd[PATH_MAX - 64], file[PATH_MAX];
    CHECK(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(file, sizeof file, "%s/" MESHES "/shapes_v3_double.serialized", cwd);
    const struct config_override ov[2] = { { "shapes.1.file", file }, { "shapes.1.shape_index", "2" } };
    struct film_image ser, box;
    CHECK(render_to_image(GOOD "/mesh_cube_obj.yaml", ov, 2, &ser, NULL));
    CHECK(render_to_image(GOOD "/mesh_cube_box.yaml", NULL, 0, &box, NULL));
    int n = ser.width * ser.height * 3, differ = 0;
    for (int i = 0; i < n; ++i) differ += memcmp(&ser.rgb[i], &box.rgb[i], sizeof(float)) != 0;
    CHECK_MSG(differ == 0, "%d of %d values differ", differ, n);
    film_image_free(&ser);
    film_image_free(&box);
}

static const struct test_case tests[] = {
    { "good_fixtures", test_good_fixtures },
    { "bad_files", test_bad_files },
    { "shape_range", test_shape_range },
    { "every_truncation_and_flip", test_every_truncation_and_flip },
    { "config", test_config },
    { "cube_matches_box", test_cube_matches_box },
};

TEST_MAIN(tests)

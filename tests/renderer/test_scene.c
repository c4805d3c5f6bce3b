/* test_scene.c: what scene_create hands Embree for a shape's faces. Quads
   are traced as two triangles each (scene.c, add_shape): the faces must
   still cover exactly their polygons, at the right distance, with the
   winding's normal. */
#include "polygon_util.h"
#include "scene_util.h"
#include "testlib.h"

/* A mesh of two planar, convex, non-rectangular quads sharing an edge and
   one triangle, in the tilted plane y = 0.3 x + 0.2 z, and a light far
   above. */
static const char mesh_yaml[] =
    "camera: {position: [0, 5, 5], look_at: [0, 0, 0], up: [0, 1, 0], fov_y: 40}\n"
    "film: {width: 8, height: 8}\n"
    "materials:\n"
    "  grey: {type: diffuse, albedo: [0.5, 0.5, 0.5]}\n"
    "shapes:\n"
    "  - type: mesh\n"
    "    material: grey\n"
    "    vertices: [[0, 0, 0], [0, 0.2, 1], [1.5, 0.69, 1.2], [1, 0.24, -0.3], [2.5, 1.03, 1.4], [2, 0.5, -0.5],\n"
    "               [3, 1, 0.5]]\n"
    "    quads: [[0, 1, 2, 3], [3, 2, 4, 5]]\n"
    "    triangles: [[5, 4, 6]]\n"
    "lights:\n"
    "  - {name: sky, vertices: [[-1, 9, -1], [-1, 9, 3], [4, 9, 3], [4, 9, -1]], radiance: [1, 1, 1]}\n"
    "render: {spp: 1}\n";

/* The faces' polygons, as the config lists them. */
static int mesh_faces(struct polygon faces[3])
{
    static const double v[7][3] = { { 0, 0, 0 },        { 0, 0.2, 1 },    { 1.5, 0.69, 1.2 }, { 1, 0.24, -0.3 },
                                    { 2.5, 1.03, 1.4 }, { 2, 0.5, -0.5 }, { 3, 1, 0.5 } };
    static const int idx[3][4] = { { 0, 1, 2, 3 }, { 3, 2, 4, 5 }, { 5, 4, 6, -1 } };
    for (int f = 0; f < 3; ++f) {
        faces[f].n = idx[f][3] < 0 ? 3 : 4;
        for (int k = 0; k < faces[f].n; ++k)
            faces[f].v[k] = vec3_make(v[idx[f][k]][0], v[idx[f][k]][1], v[idx[f][k]][2]);
    }
    return 3;
}

/* Rays straight down the plane's normal onto a 61 x 61 grid over the mesh's
   extent: every one whose foot lies inside a face (clear of its rim by
   1e-6) hits at the plane's distance with the face's winding normal, every
   one outside all faces misses. */
static void test_quads_cover_their_polygons(void)
{
    struct config cfg;
    struct scene sc;
    if (!test_scene_load_string(mesh_yaml, sizeof mesh_yaml - 1, "mesh.yaml", &cfg, &sc)) {
        CHECK(false);
        return;
    }
    struct polygon faces[3];
    int n_faces = mesh_faces(faces);
    struct vec3 n = polygon_normal(&faces[0]);
    for (int f = 1; f < n_faces; ++f) CHECK(vec3_dot(polygon_normal(&faces[f]), n) > 1.0 - 1e-12);
    struct plane pl = polygon_plane(&faces[0]);
    /* A frame of the plane, and the grid's corners in it. */
    struct vec3 u = vec3_normalize(vec3_sub(faces[0].v[3], faces[0].v[0])), w = vec3_cross(n, u);
    long hits = 0, misses = 0, wrong = 0;
    const int N = 61;
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            double a = -0.5 + 4.0 * i / (N - 1), b = -1.5 + 3.5 * j / (N - 1);
            struct vec3 foot = vec3_madd(vec3_madd(faces[0].v[0], u, a), w, b);
            foot = vec3_madd(foot, n, -plane_distance(&pl, foot)); /* onto the plane exactly */
            bool inside = false, near_rim = false;
            for (int f = 0; f < n_faces; ++f) {
                inside |= polygon_contains(&faces[f], foot);
                near_rim |= test_rim_distance(&faces[f], foot) < 1e-6;
            }
            if (near_rim) continue;
            struct vec3 o = vec3_madd(foot, n, 2.0);
            struct hit h;
            bool hit = scene_intersect(&sc, o, vec3_neg(n), INFINITY, &h);
            if (inside) {
                ++hits;
                bool ok = hit && fabs(h.t - 2.0) < 1e-5 && h.material == 0 && vec3_dot(h.ng, n) > 1.0 - 1e-6;
                if (!ok && wrong < 3)
                    fprintf(stderr, "  (%g, %g): hit %d t %g ng.n %g\n", a, b, hit, hit ? h.t : 0.0,
                            hit ? vec3_dot(h.ng, n) : 0.0);
                wrong += !ok;
            } else {
                ++misses;
                wrong += hit;
            }
        }
    CHECK_MSG(wrong == 0, "%ld of %ld rays wrong", wrong, hits + misses);
    CHECK(hits > 500 && misses > 500);
    scene_destroy(&sc);
    config_free(&cfg);
}

static const struct test_case tests[] = {
    { "quads_cover_their_polygons", test_quads_cover_their_polygons },
};

TEST_MAIN(tests)

#include "scene/scene.h"

#include <embree3/rtcore.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "config/config.h"
#include "base/fastmath.h"
#include "scene/light_hit.h"
#include "geometry/watertight.h"
#include "scene/portal_finder.h"

/* Embree reports device errors through a callback; the first one is kept in
   the struct error the callback points at, so it reaches the caller. */
static void on_embree_error(void *user, enum RTCError code, const char *message)
{
    struct error *err = user;
    if (err && err->message[0] == '\0')
        error_set(err, "Embree error %d: %s", (int)code, message ? message : "(no message)");
}

static bool grow_geometries(struct scene *s, struct error *err)
{
    struct geometry_info *g = realloc(s->geometries, sizeof *g * (size_t)(s->n_geometries + 1));
    if (!g) return error_set(err, "out of memory adding geometry %d", s->n_geometries);
    s->geometries = g;
    return true;
}

/* A committed Embree geometry of an indexed triangle mesh; NULL with a
   message on failure. */
static RTCGeometry new_mesh(struct scene *s, const struct vec3 *verts, int n_verts, const int *indices, int n_faces,
                            struct error *err)
{
    RTCDevice dev = s->device;
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) {
        error_set(err, "Embree could not create a geometry");
        return NULL;
    }
    float *vb =
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), (size_t)n_verts);
    unsigned *ib =
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), (size_t)n_faces);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        error_set(err, "out of memory for Embree buffers");
        return NULL;
    }
    for (int i = 0; i < n_verts; ++i) {
        vb[3 * i + 0] = (float)verts[i].x;
        vb[3 * i + 1] = (float)verts[i].y;
        vb[3 * i + 2] = (float)verts[i].z;
    }
    for (int i = 0; i < 3 * n_faces; ++i) ib[i] = (unsigned)indices[i];
    rtcCommitGeometry(g);
    return g;
}

/* Attaches an indexed triangle mesh. */
static bool add_mesh(struct scene *s, const struct vec3 *verts, int n_verts, const int *indices, int n_faces,
                     struct geometry_info info, struct error *err)
{
    RTCGeometry g = new_mesh(s, verts, n_verts, indices, n_faces, err);
    if (!g) return false;
    if (!grow_geometries(s, err)) {
        rtcReleaseGeometry(g);
        return false;
    }
    unsigned id = rtcAttachGeometry(s->rtc_scene, g);
    rtcReleaseGeometry(g);
    if (id != (unsigned)s->n_geometries) return error_set(err, "unexpected Embree geometry id %u", id);
    s->geometries[s->n_geometries++] = info; /* it owns info.prim_face from here */
    return true;
}

/* Lights are not among the faces: the strategies sample their polygons,
   which must stay as they are. */
bool scene_collect_faces(const struct config *cfg, struct watertight_face **out, int *n_out, struct error *err)
{
    size_t n = 0;
    for (int i = 0; i < cfg->n_shapes; ++i) n += (size_t)cfg->shapes[i].n_quads + (size_t)cfg->shapes[i].n_triangles;
    if (n > (size_t)(INT_MAX / 8)) return error_set(err, "too many faces (%zu)", n);
    struct watertight_face *f = malloc(sizeof *f * (n > 0 ? n : 1));
    if (!f) return error_set(err, "out of memory for %zu faces", n);
    int k = 0;
    for (int i = 0; i < cfg->n_shapes; ++i) {
        const struct shape_desc *sh = &cfg->shapes[i];
        for (int q = 0; q < sh->n_quads; ++q, ++k) {
            f[k].n = 4;
            for (int v = 0; v < 4; ++v) f[k].v[v] = sh->vertices[sh->quads[q][v]];
        }
        for (int t = 0; t < sh->n_triangles; ++t, ++k) {
            f[k].n = 3;
            for (int v = 0; v < 3; ++v) f[k].v[v] = sh->vertices[sh->triangles[t][v]];
        }
    }
    *out = f;
    *n_out = k;
    return true;
}

/* Attaches one shape, its faces being w's faces face0.. (scene_collect_faces'
   order), as one triangle geometry: the triangles and quads that gained no
   vertex keep the shape's vertices, the fans of the faces that changed get
   their vertices appended. A quad goes in as Embree would split it
   ((v0, v1, v3) and (v2, v3, v1)), so the surface and every hit are the
   same as a quad geometry's, bit for bit, but traced as triangles:
   Embree 3.13 traces the lampshade's camera and bounce rays faster so, at
   high and medium build quality alike (docs/performance.md;
   results/bench/NOTEBOOK.md, "Sixth pass"). The geometry carries the
   shape's info, so hits map back to its material. */
static bool add_shape(struct scene *s, const struct shape_desc *sh, const struct watertight *w, int face0,
                      struct geometry_info info, struct error *err)
{
    int n_tris = 0, n_fan = 0;
    for (int f = face0; f < face0 + sh->n_quads + sh->n_triangles; ++f) {
        if (watertight_changed(w, f)) n_fan += w->first[f + 1] - w->first[f];
        else n_tris += f < face0 + sh->n_quads ? 2 : 1;
    }
    int n_verts = sh->n_vertices + 3 * n_fan;
    int *tris = malloc(sizeof *tris * (size_t)(3 * (n_tris + n_fan) + 1));
    struct vec3 *verts = malloc(sizeof *verts * (size_t)(n_verts > 0 ? n_verts : 1));
    info.prim_face = malloc(sizeof *info.prim_face * (size_t)(n_tris + n_fan + 1));
    bool ok = tris && verts && info.prim_face;
    if (!ok) error_set(err, "out of memory for the faces of a shape");
    if (ok) {
        memcpy(verts, sh->vertices, sizeof *verts * (size_t)sh->n_vertices);
        int nt = 0, nv = sh->n_vertices;
        for (int q = 0; q < sh->n_quads; ++q) {
            if (watertight_changed(w, face0 + q)) continue;
            const int *v = sh->quads[q];
            const int split[6] = { v[0], v[1], v[3], v[2], v[3], v[1] };
            for (int k = 0; k < 6; ++k) tris[3 * nt + k] = split[k];
            info.prim_face[nt] = info.prim_face[nt + 1] = q;
            nt += 2;
        }
        for (int t = 0; t < sh->n_triangles; ++t) {
            if (watertight_changed(w, face0 + sh->n_quads + t)) continue;
            for (int v = 0; v < 3; ++v) tris[3 * nt + v] = sh->triangles[t][v];
            info.prim_face[nt++] = sh->n_quads + t;
        }
        for (int f = face0; f < face0 + sh->n_quads + sh->n_triangles; ++f)
            for (int k = w->first[f]; k < w->first[f + 1]; ++k, ++nt) {
                info.prim_face[nt] = f - face0;
                for (int v = 0; v < 3; ++v) {
                    verts[nv] = w->tris[k].v[v];
                    tris[3 * nt + v] = nv++;
                }
            }
        if (nt > 0) {
            ok = add_mesh(s, verts, nv, tris, nt, info, err);
            if (ok) info.prim_face = NULL; /* the scene's now */
        }
    }
    free(info.prim_face);
    free(tris);
    free(verts);
    return ok;
}

static void bounds_add(struct vec3 *lo, struct vec3 *hi, struct vec3 p)
{
    lo->x = fmin(lo->x, p.x), lo->y = fmin(lo->y, p.y), lo->z = fmin(lo->z, p.z);
    hi->x = fmax(hi->x, p.x), hi->y = fmax(hi->y, p.y), hi->z = fmax(hi->z, p.z);
}

/* The file an item came from: an included file, or the config itself. */
static const char *loc_file(const struct config *cfg, const struct source_loc *loc)
{
    return loc->file ? loc->file : cfg->path;
}

/* The polygon of member m of config light d: its own, or triangle m of its mesh. */
static struct polygon member_polygon(const struct light_desc *d, int m)
{
    if (d->mesh.n_triangles == 0) return d->polygon;
    struct polygon p;
    p.n = 3;
    for (int v = 0; v < 3; ++v) p.v[v] = d->mesh.vertices[d->mesh.triangles[m][v]];
    return p;
}

static bool build_lights(struct scene *s, const struct config *cfg, struct error *err)
{
    size_t n_lights = 0, n_portals = 0;
    for (int i = 0; i < cfg->n_lights; ++i) {
        size_t members = cfg->lights[i].mesh.n_triangles > 0 ? (size_t)cfg->lights[i].mesh.n_triangles : 1;
        n_lights += members;
        for (int j = 0; j < cfg->n_portals; ++j) n_portals += cfg->portals[j].light == i ? members : 0;
    }
    if (n_lights > INT_MAX / 2 || n_portals > INT_MAX / 2)
        return error_set(err, "too many lights (%zu) or light/portal pairs (%zu)", n_lights, n_portals);
    s->lights = calloc(n_lights, sizeof *s->lights);
    s->portals = calloc(n_portals > 0 ? n_portals : 1, sizeof *s->portals);
    s->emitters = calloc((size_t)cfg->n_lights, sizeof *s->emitters);
    s->target_blocks = malloc(sizeof *s->target_blocks);
    struct target *targets = calloc((size_t)(cfg->n_portals > 0 ? cfg->n_portals : 1), sizeof *targets);
    if (s->target_blocks && targets) s->target_blocks[s->n_target_blocks++] = targets;
    else free(targets);
    if (!s->lights || !s->portals || !s->emitters || !s->target_blocks || !targets)
        return error_set(err, "out of memory for %zu lights", n_lights);
    s->n_emitters = cfg->n_lights;
    for (int i = 0; i < cfg->n_lights; ++i) {
        const struct light_desc *d = &cfg->lights[i];
        struct emitter *e = &s->emitters[i];
        e->first_light = s->n_lights;
        e->n_lights = d->mesh.n_triangles > 0 ? d->mesh.n_triangles : 1;
        e->power = 0.0;
        for (int m = 0; m < e->n_lights; ++m) {
            struct light *l = &s->lights[s->n_lights];
            struct polygon poly = member_polygon(d, m);
            if (!light_init(l, &poly, d->radiance, d->two_sided)) {
                if (d->mesh.n_triangles > 0)
                    return error_at(err, loc_file(cfg, &d->loc), d->loc.line, d->loc.column,
                                    "light \"%s\": triangle %d is degenerate", d->name, m);
                return error_at(err, loc_file(cfg, &d->loc), d->loc.line, d->loc.column, "light \"%s\" is degenerate",
                                d->name);
            }
            l->emitter = i;
            e->power += l->power;
            /* Portals are grouped by light so that a light's portals are one range. */
            l->first_portal = s->n_portals;
            for (int j = 0; j < cfg->n_portals; ++j) {
                if (cfg->portals[j].light != i) continue;
                struct portal *pt = &s->portals[s->n_portals];
                pt->light = s->n_lights;
                const struct portal_desc *pd = &cfg->portals[j];
                struct error aerr;
                /* Portal j belongs to light i alone: its target is made at the emitter's first member. */
                if (m == 0 && !target_init(&targets[j], &pd->polygon))
                    return error_at(err, loc_file(cfg, &pd->loc), pd->loc.line, pd->loc.column,
                                    "portal \"%s\" is degenerate", pd->name);
                pt->target = &targets[j];
                pt->centroid = polygon_centroid(&pt->target->polygon);
                if (!antishadow_build(&l->target.polygon, &pt->target->polygon, &pt->antishadow, &aerr)) {
                    if (d->mesh.n_triangles > 0)
                        return error_at(err, loc_file(cfg, &pd->loc), pd->loc.line, pd->loc.column,
                                        "portal \"%s\" with triangle %d of light \"%s\": %s", pd->name, m, d->name,
                                        aerr.message);
                    return error_at(err, loc_file(cfg, &pd->loc), pd->loc.line, pd->loc.column, "portal \"%s\": %s",
                                    pd->name, aerr.message);
                }
                ++s->n_portals;
            }
            l->n_portals = s->n_portals - l->first_portal;
            ++s->n_lights;
        }
    }
    return true;
}

/* The lights as planes for scene_first_light, when they are all polygons
   and few enough (light_hit.h); false only when out of memory. */
static bool build_light_hits(struct scene *s)
{
    for (int i = 0; i < s->n_emitters; ++i)
        if (s->emitters[i].rtc_scene) return true;
    s->light_hits = malloc(sizeof *s->light_hits);
    if (!s->light_hits) return false;
    if (!light_hit_set_init(s->light_hits, s->lights, s->n_lights)) {
        free(s->light_hits);
        s->light_hits = NULL;
    }
    return true;
}

bool scene_create(const struct config *cfg, struct scene *s, struct error *err)
{
    memset(s, 0, sizeof *s);
    struct error dev_err = { { 0 } };
    s->device = rtcNewDevice(NULL);
    if (!s->device) return error_set(err, "cannot create the Embree device (error %d)", (int)rtcGetDeviceError(NULL));
    rtcSetDeviceErrorFunction(s->device, on_embree_error, &dev_err);
    s->rtc_scene = rtcNewScene(s->device);
    rtcSetSceneFlags(s->rtc_scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(s->rtc_scene, RTC_BUILD_QUALITY_HIGH);
    s->rtc_lights = rtcNewScene(s->device);
    rtcSetSceneFlags(s->rtc_lights, RTC_SCENE_FLAG_ROBUST);
    if (!s->rtc_scene || !s->rtc_lights) goto oom;

    s->n_materials = cfg->n_materials;
    s->materials = calloc((size_t)(cfg->n_materials > 0 ? cfg->n_materials : 1), sizeof *s->materials);
    if (!s->materials) goto oom;
    for (int i = 0; i < cfg->n_materials; ++i) {
        s->materials[i].kind = cfg->materials[i].kind;
        s->materials[i].albedo = cfg->materials[i].albedo;
        s->materials[i].roughness = cfg->materials[i].roughness;
    }

    struct vec3 lo = vec3_make(INFINITY, INFINITY, INFINITY), hi = vec3_neg(lo);
    /* T-junctions are stitched before anything reaches Embree: see
       watertight.c for the cracks they leave otherwise. */
    struct watertight_face *faces = NULL;
    int n_faces = 0;
    struct watertight w;
    if (!scene_collect_faces(cfg, &faces, &n_faces, err)) goto fail;
    bool stitched = watertight_stitch(faces, n_faces, &w, err);
    free(faces);
    if (!stitched) goto fail;
    for (int i = 0, face0 = 0; i < cfg->n_shapes; ++i) {
        const struct shape_desc *sh = &cfg->shapes[i];
        struct geometry_info info = { sh->material, -1, false, i, NULL };
        for (int v = 0; v < sh->n_vertices; ++v) bounds_add(&lo, &hi, sh->vertices[v]);
        if (!add_shape(s, sh, &w, face0, info, err)) {
            watertight_free(&w);
            goto fail;
        }
        face0 += sh->n_quads + sh->n_triangles;
    }
    watertight_free(&w);
    if (!build_lights(s, cfg, err)) goto fail;
    int first_light_geometry = s->n_geometries;
    for (int i = 0; i < s->n_emitters; ++i) {
        const struct emitter *e = &s->emitters[i];
        const struct shape_desc *mesh = &cfg->lights[i].mesh;
        if (mesh->n_triangles > 0) {
            /* One geometry for the whole mesh: its primitive k is light k. */
            struct geometry_info info = { -1, e->first_light, true, -1, NULL };
            for (int v = 0; v < mesh->n_vertices; ++v) bounds_add(&lo, &hi, mesh->vertices[v]);
            if (!add_mesh(s, mesh->vertices, mesh->n_vertices, &mesh->triangles[0][0], mesh->n_triangles, info, err))
                goto fail;
            /* And alone, for scene_emitter_hit. */
            RTCGeometry g =
                new_mesh(s, mesh->vertices, mesh->n_vertices, &mesh->triangles[0][0], mesh->n_triangles, err);
            if (!g) goto fail;
            RTCScene own = rtcNewScene(s->device);
            rtcSetSceneFlags(own, RTC_SCENE_FLAG_ROBUST);
            rtcAttachGeometry(own, g);
            rtcReleaseGeometry(g);
            rtcCommitScene(own);
            s->emitters[i].rtc_scene = own;
            continue;
        }
        const struct polygon *poly = &s->lights[e->first_light].target.polygon;
        struct geometry_info info = { -1, e->first_light, false, -1, NULL };
        int fan[3 * (POLYGON_MAX - 2)];
        for (int k = 0; k + 2 < poly->n; ++k) fan[3 * k] = 0, fan[3 * k + 1] = k + 1, fan[3 * k + 2] = k + 2;
        for (int v = 0; v < poly->n; ++v) bounds_add(&lo, &hi, poly->v[v]);
        if (!add_mesh(s, poly->v, poly->n, fan, poly->n - 2, info, err)) goto fail;
    }
    for (int g = first_light_geometry; g < s->n_geometries; ++g)
        rtcAttachGeometryByID(s->rtc_lights, rtcGetGeometry(s->rtc_scene, (unsigned)g), (unsigned)g);
    rtcCommitScene(s->rtc_lights);
    if (!build_light_hits(s)) goto oom;
    s->bounds_lo = lo;
    s->bounds_hi = hi;
    s->scale = vec3_length(vec3_sub(hi, lo));
    if (!(s->scale > 0.0) || !isfinite(s->scale)) s->scale = 1.0;
    rtcCommitScene(s->rtc_scene);
    if (dev_err.message[0]) {
        error_set(err, "%s", dev_err.message);
        goto fail;
    }
    rtcSetDeviceErrorFunction(s->device, NULL, NULL);
    if (!portal_finder_run(s, cfg, err)) {
        scene_destroy(s);
        return false;
    }
    return true;
oom:
    error_set(err, "out of memory building the scene");
fail:
    rtcSetDeviceErrorFunction(s->device, NULL, NULL);
    scene_destroy(s);
    return false;
}

void scene_destroy(struct scene *s)
{
    if (s->rtc_scene) rtcReleaseScene(s->rtc_scene);
    if (s->rtc_lights) rtcReleaseScene(s->rtc_lights);
    free(s->light_hits);
    if (s->device) rtcReleaseDevice(s->device);
    free(s->materials);
    free(s->lights);
    for (int i = 0; s->emitters && i < s->n_emitters; ++i)
        if (s->emitters[i].rtc_scene) rtcReleaseScene(s->emitters[i].rtc_scene);
    free(s->emitters);
    for (int i = 0; s->portals && i < s->n_portals; ++i) antishadow_free(&s->portals[i].antishadow);
    free(s->portals);
    for (int i = 0; i < s->n_target_blocks; ++i) free(s->target_blocks[i]);
    free(s->target_blocks);
    for (int i = 0; s->geometries && i < s->n_geometries; ++i) free(s->geometries[i].prim_face);
    free(s->geometries);
    for (int i = 0; s->auto_portals && i < s->n_emitters; ++i) free(s->auto_portals[i].planes);
    free(s->auto_portals);
    memset(s, 0, sizeof *s);
}

static void ray_setup(struct RTCRay *r, struct vec3 o, struct vec3 d, double tmax)
{
    r->org_x = (float)o.x, r->org_y = (float)o.y, r->org_z = (float)o.z;
    r->dir_x = (float)d.x, r->dir_y = (float)d.y, r->dir_z = (float)d.z;
    r->tnear = 0.0f;
    r->tfar = ray_stream_tfar(tmax);
    r->time = 0.0f;
    r->mask = ~0u;
    r->id = 0;
    r->flags = 0;
}

/* Where a hit lies and how it faces: the point at distance t of o + t d
   and the unit normal from Embree's unnormalised geometric normal ng.
   Straight-line, so that resolve_block vectorises it; hit_at (single
   rays) calls it too, so that a ray traced either way gives the same hit,
   bit for bit. */
struct hit_geometry {
    struct vec3 p, ng;
};
FM_INLINE struct hit_geometry hit_geometry_at(struct vec3 o, struct vec3 d, double t, struct vec3 ng)
{
    struct hit_geometry h = { vec3_madd(o, d, t), vec3_normalize(ng) };
    return h;
}

/* What primitive prim of geometry geom is: its material or its light. */
FM_INLINE void hit_what(const struct scene *s, unsigned geom, unsigned prim, struct hit *h)
{
    const struct geometry_info *g = &s->geometries[geom];
    h->material = g->material;
    h->light = geometry_light(g, prim);
}

/* The hit at distance t of o + t d on primitive prim of geometry geom, with
   Embree's unnormalised geometric normal (ngx, ngy, ngz). */
static void hit_at(const struct scene *s, struct vec3 o, struct vec3 d, float t, float ngx, float ngy, float ngz,
                   unsigned geom, unsigned prim, struct hit *h)
{
    struct hit_geometry hg = hit_geometry_at(o, d, t, vec3_make(ngx, ngy, ngz));
    h->t = t;
    h->p = hg.p;
    h->ng = hg.ng;
    hit_what(s, geom, prim, h);
}

static void hit_from_embree(const struct scene *s, struct vec3 o, struct vec3 d, const struct RTCRayHit *rh,
                            struct hit *h)
{
    hit_at(s, o, d, rh->ray.tfar, rh->hit.Ng_x, rh->hit.Ng_y, rh->hit.Ng_z, rh->hit.geomID, rh->hit.primID, h);
}

static void rayhit_setup(struct RTCRayHit *rh, struct vec3 o, struct vec3 d, double tmax)
{
    ray_setup(&rh->ray, o, d, tmax);
    rh->hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

/* Closest hit of one ray in `scene` (the whole scene or the lights'
   alone); false on a miss. */
static bool trace_closest(RTCScene scene, struct vec3 o, struct vec3 d, double tmax, struct RTCRayHit *rh)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rayhit_setup(rh, o, d, tmax);
    rtcIntersect1(scene, &ctx, rh);
    return rh->hit.geomID != RTC_INVALID_GEOMETRY_ID;
}

bool scene_intersect(const struct scene *s, struct vec3 o, struct vec3 d, double tmax, struct hit *h)
{
    struct RTCRayHit rh;
    if (!trace_closest(s->rtc_scene, o, d, tmax, &rh)) return false;
    hit_from_embree(s, o, d, &rh, h);
    return true;
}

bool scene_intersect_geometry(const struct scene *s, struct vec3 o, struct vec3 d, double tmax, struct hit *h,
                              int *geometry, int *face)
{
    struct RTCRayHit rh;
    if (!trace_closest(s->rtc_scene, o, d, tmax, &rh)) return false;
    hit_from_embree(s, o, d, &rh, h);
    *geometry = (int)rh.hit.geomID;
    const int *prim_face = s->geometries[rh.hit.geomID].prim_face;
    *face = prim_face ? prim_face[rh.hit.primID] : -1;
    return true;
}

bool scene_add_portals(struct scene *s, int emitter, const struct polygon *portals, int n, struct error *err)
{
    const struct emitter *e = &s->emitters[emitter];
    size_t total = (size_t)s->n_portals + (size_t)n * (size_t)e->n_lights;
    if (n == 0) return true;
    if (total > INT_MAX / 2) return error_set(err, "too many light/portal pairs (%zu)", total);
    struct target **blocks = realloc(s->target_blocks, sizeof *blocks * (size_t)(s->n_target_blocks + 1));
    if (!blocks) return error_set(err, "out of memory for %zu portals", total);
    s->target_blocks = blocks;
    struct target *targets = calloc((size_t)n, sizeof *targets);
    if (!targets) return error_set(err, "out of memory for %zu portals", total);
    for (int j = 0; j < n; ++j)
        if (!target_init(&targets[j], &portals[j])) {
            free(targets);
            return error_set(err, "found portal %d is degenerate", j);
        }
    struct portal *all = calloc(total, sizeof *all);
    int *first = malloc(sizeof *first * (size_t)s->n_lights);
    if (!all || !first) {
        free(targets);
        free(all);
        free(first);
        return error_set(err, "out of memory for %zu portals", total);
    }
    int k = 0;
    for (int i = 0; i < s->n_lights; ++i) {
        struct light *l = &s->lights[i];
        first[i] = k;
        for (int j = 0; j < l->n_portals; ++j) all[k++] = s->portals[l->first_portal + j];
        if (l->emitter != emitter) continue;
        for (int j = 0; j < n; ++j, ++k) {
            struct portal *pt = &all[k];
            struct error aerr;
            pt->light = i;
            pt->target = &targets[j];
            pt->centroid = polygon_centroid(&portals[j]);
            if (!antishadow_build(&l->target.polygon, &portals[j], &pt->antishadow, &aerr)) {
                /* The pairs built so far are this call's; the others still belong to s->portals. */
                for (int b = 0; b <= i; ++b)
                    for (int c = 0; s->lights[b].emitter == emitter && c < n; ++c)
                        antishadow_free(&all[first[b] + s->lights[b].n_portals + c].antishadow);
                free(targets);
                free(all);
                free(first);
                return error_set(err, "found portal %d with light %d: %s", j, i - e->first_light, aerr.message);
            }
        }
    }
    for (int i = 0; i < s->n_lights; ++i) {
        if (s->lights[i].emitter == emitter) s->lights[i].n_portals = n;
        s->lights[i].first_portal = first[i];
    }
    free(first);
    free(s->portals);
    s->portals = all;
    s->target_blocks[s->n_target_blocks++] = targets;
    s->n_portals = k;
    return true;
}

/* Hits per block of resolve_hits: the block's points and normals are
   computed in one vectorised loop, then stored with their lookups. */
#define HIT_BLOCK 16

/* hit_at for the closest-hit results b..b+m-1 (m <= HIT_BLOCK) of stream
   c, ray i from o0 (one_origin) or o[i] along d[i]: found[i] says whether
   it met anything, hits[i] what. The points and normals (a square root and a
   division per ray) go through one vectorised loop, the lookups and the
   stores to the hits through a plain one. one_origin is a constant in
   each caller's copy: a select between the two origins is not
   vectorised. */
FM_INLINE void resolve_block(const struct scene *s, bool one_origin, struct vec3 o0, const struct vec3 *o,
                             const struct vec3 *d, const struct ray_stream *c, int b, int m, struct hit *hits,
                             bool *found)
{
    double t[HIT_BLOCK], p[3][HIT_BLOCK], ng[3][HIT_BLOCK];
#pragma omp simd
    for (int k = 0; k < m; ++k) {
        int i = b + k;
        t[k] = c->tfar[i];
        struct hit_geometry hg =
            hit_geometry_at(one_origin ? o0 : o[i], d[i], t[k], vec3_make(c->ng_x[i], c->ng_y[i], c->ng_z[i]));
        p[0][k] = hg.p.x, p[1][k] = hg.p.y, p[2][k] = hg.p.z;
        ng[0][k] = hg.ng.x, ng[1][k] = hg.ng.y, ng[2][k] = hg.ng.z;
    }
    for (int k = 0; k < m; ++k) {
        int i = b + k;
        unsigned g = c->geom_id[i];
        found[i] = g != RTC_INVALID_GEOMETRY_ID;
        if (!found[i]) continue;
        struct hit *h = &hits[i];
        h->t = t[k];
        h->p = vec3_make(p[0][k], p[1][k], p[2][k]);
        h->ng = vec3_make(ng[0][k], ng[1][k], ng[2][k]);
        hit_what(s, g, c->prim_id[i], h);
    }
}

/* resolve_block for n results, ray i from o[i] (o NULL: from o0). */
FM_SIMD_CLONES static void resolve_hits(const struct scene *s, struct vec3 o0, const struct vec3 *o,
                                        const struct vec3 *d, const struct ray_stream *c, int n, struct hit *hits,
                                        bool *found)
{
    for (int b = 0; b < n; b += HIT_BLOCK) {
        int m = n - b < HIT_BLOCK ? n - b : HIT_BLOCK;
        if (o) resolve_block(s, false, o0, o, d, c, b, m, hits, found);
        else resolve_block(s, true, o0, o, d, c, b, m, hits, found);
    }
}

/* The end of the segment o + t d that must be clear for light `light`,
   met at distance t, to count (0 or less: nothing to test). */
static double light_clear_to(const struct scene *s, struct vec3 o, struct vec3 d, double t, int light)
{
    return t - scene_offset_step(s, vec3_madd(o, d, t), s->lights[light].target.normal, d);
}

/* The ray as Embree holds it, in floats: both ways of finding the first
   light read it so, and the stream form can read nothing else. */
static struct vec3 vec3_as_float(struct vec3 v)
{
    return vec3_make((float)v.x, (float)v.y, (float)v.z);
}

int scene_first_light(const struct scene *s, struct vec3 o, struct vec3 d, double tmax)
{
    struct vec3 of = vec3_as_float(o), df = vec3_as_float(d);
    int light;
    double t;
    if (s->light_hits) {
        float ox = (float)of.x, oy = (float)of.y, oz = (float)of.z, dx = (float)df.x, dy = (float)df.y,
              dz = (float)df.z, tnear = 0.0f, tfar = ray_stream_tfar(tmax);
        light_hit_many(s->light_hits, &ox, &oy, &oz, &dx, &dy, &dz, &tnear, &tfar, 1, &light, &t);
        if (light < 0) return -1;
    } else {
        struct RTCRayHit rh;
        if (!trace_closest(s->rtc_lights, o, d, tmax, &rh)) return -1;
        light = geometry_light(&s->geometries[rh.hit.geomID], rh.hit.primID);
        t = rh.ray.tfar;
    }
    double clear_to = light_clear_to(s, of, df, t, light);
    return clear_to > 0.0 && scene_occluded(s, o, d, clear_to) ? -1 : light;
}

/* Embree's view of a stream's arrays. */
static struct RTCRayNp ray_np(struct ray_stream *r)
{
    struct RTCRayNp np = { r->ox, r->oy,   r->oz,   r->tnear, r->dx, r->dy,
                           r->dz, r->time, r->tfar, r->mask,  r->id, r->flags };
    return np;
}

void scene_occluded_stream(const struct scene *s, struct ray_stream *rays, int n, bool coherent)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    struct RTCRayNp np = ray_np(rays);
    rtcOccludedNp(s->rtc_scene, &ctx, &np, (unsigned)n);
}

/* Groups of scene_occluded_grouped: rays are ordered by group modulo this. */
#define OCCLUDED_GROUPS 16

void scene_occluded_grouped(const struct scene *s, struct ray_stream *rays, int n, const int *group,
                            struct ray_stream *packed, int *order)
{
    int start[OCCLUDED_GROUPS + 1] = { 0 }, last = 0;
    bool in_order = true;
    for (int i = 0; i < n; ++i) {
        if (!ray_stream_active(rays, i)) continue;
        int g = group[i] & (OCCLUDED_GROUPS - 1);
        ++start[g + 1];
        in_order &= g >= last;
        last = g;
    }
    /* One light (or rays already in order, inactive ones among them): as
       they are. */
    if (in_order) {
        scene_occluded_stream(s, rays, n, true);
        return;
    }
    for (int g = 0; g < OCCLUDED_GROUPS; ++g) start[g + 1] += start[g];
    int m = start[OCCLUDED_GROUPS];
    for (int i = 0; i < n; ++i) {
        if (!ray_stream_active(rays, i)) continue;
        int j = start[group[i] & (OCCLUDED_GROUPS - 1)]++;
        ray_stream_copy(packed, j, rays, i);
        order[j] = i;
    }
    scene_occluded_stream(s, packed, m, true);
    for (int j = 0; j < m; ++j) rays->tfar[order[j]] = packed->tfar[j];
}

/* Closest hits of the first n rays of a stream in `scene` (the whole
   scene or the lights' alone), its hit fields reset first; coherent: rays
   that Embree may trace as packets (from one point). */
static void trace_closest_stream(RTCScene scene, struct ray_stream *rays, int n, bool coherent)
{
    for (int i = 0; i < n; ++i) rays->geom_id[i] = RTC_INVALID_GEOMETRY_ID;
    for (int i = 0; i < n; ++i) rays->inst_id[i] = RTC_INVALID_GEOMETRY_ID;
    struct RTCRayHitNp np = {
        ray_np(rays),
        { rays->ng_x, rays->ng_y, rays->ng_z, rays->u, rays->v, rays->prim_id, rays->geom_id, { rays->inst_id } }
    };
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    rtcIntersectNp(scene, &ctx, &np, (unsigned)n);
}

/* Rays whose light distances scene_first_light_stream keeps at a time. */
#define FIRST_LIGHT_BLOCK 64

void scene_first_light_stream(const struct scene *s, struct ray_stream *rays, int n, int *light)
{
    if (!s->light_hits) trace_closest_stream(s->rtc_lights, rays, n, false);
    /* The rays that met a light become the segments to test, the others
       inactive; one occlusion call for them all. */
    int to_test = 0;
    for (int i0 = 0; i0 < n; i0 += FIRST_LIGHT_BLOCK) {
        int m = n - i0 < FIRST_LIGHT_BLOCK ? n - i0 : FIRST_LIGHT_BLOCK;
        double t[FIRST_LIGHT_BLOCK];
        if (s->light_hits) {
            light_hit_many(s->light_hits, rays->ox + i0, rays->oy + i0, rays->oz + i0, rays->dx + i0, rays->dy + i0,
                           rays->dz + i0, rays->tnear + i0, rays->tfar + i0, m, light + i0, t);
        } else {
            for (int k = 0; k < m; ++k) {
                unsigned g = rays->geom_id[i0 + k];
                light[i0 + k] =
                    g == RTC_INVALID_GEOMETRY_ID ? -1 : geometry_light(&s->geometries[g], rays->prim_id[i0 + k]);
                t[k] = rays->tfar[i0 + k];
            }
        }
        for (int k = 0; k < m; ++k) {
            int i = i0 + k;
            if (light[i] < 0) {
                ray_stream_skip(rays, i);
                continue;
            }
            struct vec3 o = vec3_make(rays->ox[i], rays->oy[i], rays->oz[i]);
            struct vec3 d = vec3_make(rays->dx[i], rays->dy[i], rays->dz[i]);
            double clear_to = light_clear_to(s, o, d, t[k], light[i]);
            if (clear_to > 0.0) {
                rays->tnear[i] = ray_stream_tnear_for(true);
                rays->tfar[i] = ray_stream_tfar(clear_to);
                ++to_test;
            } else {
                ray_stream_skip(rays, i);
            }
        }
    }
    if (to_test == 0) return;
    scene_occluded_stream(s, rays, n, false);
    for (int i = 0; i < n; ++i)
        if (ray_stream_blocked(rays, i)) light[i] = -1;
}

FM_SIMD_CLONES
void scene_intersect_coherent(const struct scene *s, struct vec3 o, const struct vec3 *d, int n,
                              struct ray_stream *rays, struct hit *hits, bool *found)
{
#pragma omp simd
    for (int i = 0; i < n; ++i) ray_stream_set(rays, i, o, d[i], INFINITY);
    trace_closest_stream(s->rtc_scene, rays, n, true);
    resolve_hits(s, o, NULL, d, rays, n, hits, found);
}

void scene_intersect_stream(const struct scene *s, struct ray_stream *rays, int n, const struct vec3 *o,
                            const struct vec3 *d, struct hit *hits, bool *found)
{
    trace_closest_stream(s->rtc_scene, rays, n, false);
    resolve_hits(s, vec3_make(0.0, 0.0, 0.0), o, d, rays, n, hits, found);
}

int scene_emitter_hit(const struct scene *s, int emitter, struct vec3 o, struct vec3 d, double *dist)
{
    const struct emitter *e = &s->emitters[emitter];
    if (!e->rtc_scene) {
        /* A polygon light (or a scene built without Embree, as tests do). */
        int best = -1;
        for (int i = e->first_light; i < e->first_light + e->n_lights; ++i) {
            double t;
            if (polygon_intersect_ray(&s->lights[i].target.polygon, o, d, &t) && (best < 0 || t < *dist))
                best = i, *dist = t;
        }
        return best;
    }
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    rayhit_setup(&rh, o, d, INFINITY);
    rtcIntersect1(e->rtc_scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return -1;
    *dist = rh.ray.tfar;
    return e->first_light + (int)rh.hit.primID;
}

bool scene_occluded(const struct scene *s, struct vec3 o, struct vec3 d, double tmax)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    ray_setup(&r, o, d, tmax);
    rtcOccluded1(s->rtc_scene, &ctx, &r);
    return r.tfar < 0.0f;
}

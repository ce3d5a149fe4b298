/* The scene as one Embree 3 triangle geometry (see embree_scene.h for the contract).
 *
 * Layout: world-space vertices (float x,y,z per vertex, object after object), indices (three per
 * triangle, global vertex numbers), tri_object[t] and obj_first[o]. Embree reads the vertex and
 * index buffers in place (shared buffers, allocated with the handle's allocator and padded as
 * Embree asks), so the geometry costs no second copy. */
#include "embree_scene.h"

#include "core/sl_core.h"
#include "scene/scene_internal.h"

#include <embree3/rtcore.h>
#include <math.h>

/* rays handed to rtcIntersect1M at once */
#define TRACE_CHUNK 64u

enum { OBJ_CLOSED = 1u, OBJ_SEE_THROUGH = 2u };

/* The intersect context of sl_es_trace: Embree's, then the nearest see-through hit per ray of the
 * chunk (the filter records it and lets the ray go on). */
typedef struct trace_ctx {
    struct RTCIntersectContext base;
    uint32_t st_tri[TRACE_CHUNK];
    float st_t[TRACE_CHUNK];
} trace_ctx;

struct sl_es {
    sl_allocator alloc;
    RTCDevice device;
    RTCScene rscene;
    uint32_t object_count, triangle_count, vertex_count;
    float *vertices;            /* 3 per vertex + 4 floats of padding (Embree reads 16 bytes) */
    uint32_t *indices;          /* 3 per triangle (+1 padding) */
    uint32_t *tri_object;       /* per triangle */
    uint32_t *obj_first;        /* per object + 1 */
    uint8_t *obj_closed;        /* per object: OBJ_CLOSED (back faces skipped), OBJ_SEE_THROUGH */
    bool filter;
    sl_aabb bounds;
    double build_seconds;
    char embree_error[256];     /* first error Embree reported through the callback */
};

static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    struct sl_es *es = user;
    if (es->embree_error[0] == 0)
        snprintf(es->embree_error, sizeof es->embree_error, "Embree error %d: %s", (int)code, str ? str : "?");
}

/* Intersection filter of scenes with closed convex or see-through objects: reject a hit on the
 * back face of a closed convex object (the point oracle skips those faces too; the front side is
 * the counter-clockwise one, windings were already fixed for mirroring transforms when the buffers
 * were filled), and every hit on a see-through object, which is recorded (the nearest per ray)
 * while the ray goes on: see-through surfaces are seen but stop no sight line (docs/oracle.md). */
static void backface_filter(const struct RTCFilterFunctionNArguments *args)
{
    const struct sl_es *es = args->geometryUserPtr;
    const unsigned N = args->N;
    float *ray = (float *)args->ray;
    const unsigned *hit = (const unsigned *)args->hit;
    trace_ctx *tc = (trace_ctx *)args->context;
    for (unsigned i = 0; i < N; i++) {
        if (args->valid[i] == 0)
            continue;
        uint32_t prim = hit[5 * N + i];
        uint8_t kind = prim < es->triangle_count ? es->obj_closed[es->tri_object[prim]] : 0;
        if (kind & OBJ_SEE_THROUGH) {
            unsigned id = ((const unsigned *)ray)[10 * N + i]; /* ray id: the slot in the chunk */
            float t = ray[8 * N + i];                         /* tfar holds the candidate's distance */
            if (id < TRACE_CHUNK && t < tc->st_t[id]) {
                tc->st_t[id] = t;
                tc->st_tri[id] = prim;
            }
            args->valid[i] = 0;
            continue;
        }
        if (!(kind & OBJ_CLOSED))
            continue;
        const uint32_t *ix = &es->indices[3 * (size_t)prim];
        const float *a = &es->vertices[3 * (size_t)ix[0]], *b = &es->vertices[3 * (size_t)ix[1]],
                    *c = &es->vertices[3 * (size_t)ix[2]];
        double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
        double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double d = n[0] * ray[4 * N + i] + n[1] * ray[5 * N + i] + n[2] * ray[6 * N + i];
        if (d > 0) /* the ray runs along the normal: it meets the back face */
            args->valid[i] = 0;
    }
}

static double affine_det(const sl_affine *t)
{
    const float *m = t->m;
    return (double)m[0] * ((double)m[5] * m[10] - (double)m[6] * m[9]) -
           (double)m[1] * ((double)m[4] * m[10] - (double)m[6] * m[8]) +
           (double)m[2] * ((double)m[4] * m[9] - (double)m[5] * m[8]);
}

static size_t vertex_bytes(uint32_t n) { return (3 * (size_t)n + 4) * sizeof(float); }
static size_t index_bytes(uint32_t n) { return (3 * (size_t)n + 1) * sizeof(uint32_t); }

void sl_es_destroy(sl_es *es)
{
    if (!es)
        return;
    const sl_allocator *a = &es->alloc;
    if (es->rscene)
        rtcReleaseScene(es->rscene);
    if (es->device)
        rtcReleaseDevice(es->device);
    sl_free(a, es->vertices, vertex_bytes(es->vertex_count));
    sl_free(a, es->indices, index_bytes(es->triangle_count));
    sl_free(a, es->tri_object, ((size_t)es->triangle_count + 1) * sizeof(uint32_t));
    sl_free(a, es->obj_first, ((size_t)es->object_count + 1) * sizeof(uint32_t));
    sl_free(a, es->obj_closed, (size_t)es->object_count + 1);
    sl_free(a, es, sizeof *es);
}

sl_status sl_es_create(sl_scene scene, const sl_es_options *opt, const sl_allocator *alloc, sl_es **out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_es_create: scene and out must not be NULL");
    *out = NULL;
    sl_es_options o = {0};
    if (opt)
        o = *opt;
    if (o.quality > 2)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "embree scene: build quality %u is not 0, 1 or 2", o.quality);
    double t0 = sl_now();
    alloc = sl_alloc_or_default(alloc);
    const struct sl_scene_t *s = scene;
    const uint32_t no = sl_scene_object_count(scene);
    const sl_object_rec *objects = sl_scene_objects(s);
    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    const sl_affine *transforms = sl_scene_transforms(s);
    const float *positions = sl_scene_positions(s);
    const uint32_t *indices = sl_scene_indices(s);

    /* count first: both totals must fit 32-bit ids */
    uint64_t nt = 0, nv = 0;
    bool any_closed = false;
    for (uint32_t i = 0; i < no; i++) {
        const sl_mesh_rec *m = &meshes[objects[i].mesh];
        nt += m->triangle_count;
        nv += m->vertex_count;
        if ((((objects[i].flags & SL_OBJECT_CLOSED_CONVEX) && !o.draw_closed_backfaces) ||
             (objects[i].flags & SL_OBJECT_SEE_THROUGH)) &&
            m->triangle_count)
            any_closed = true; /* the filter is needed */
    }
    if (nt > SL_ES_MAX_TRIANGLES)
        return sl_fail(err, SL_ERROR_LIMIT, "embree scene: %llu triangles exceed the limit of %u",
                       (unsigned long long)nt, SL_ES_MAX_TRIANGLES);
    if (nv >= UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "embree scene: %llu vertices exceed 32-bit indices",
                       (unsigned long long)nv);

    struct sl_es *es = sl_calloc(alloc, 1, sizeof *es);
    if (!es)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "embree scene: out of memory");
    es->alloc = *alloc;
    es->object_count = no;
    es->triangle_count = (uint32_t)nt;
    es->vertex_count = (uint32_t)nv;
    es->filter = any_closed;
    es->bounds = sl_aabb_empty();
    es->vertices = sl_alloc_aligned(alloc, vertex_bytes(es->vertex_count), 16);
    es->indices = sl_alloc_aligned(alloc, index_bytes(es->triangle_count), 16);
    es->tri_object = sl_alloc(alloc, ((size_t)es->triangle_count + 1) * sizeof(uint32_t));
    es->obj_first = sl_alloc(alloc, ((size_t)no + 1) * sizeof(uint32_t));
    es->obj_closed = sl_calloc(alloc, (size_t)no + 1, 1);
    if (!es->vertices || !es->indices || !es->tri_object || !es->obj_first || !es->obj_closed) {
        sl_es_destroy(es);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "embree scene: out of memory for %u triangles and %u vertices",
                       (uint32_t)nt, (uint32_t)nv);
    }
    memset(es->vertices + 3 * (size_t)es->vertex_count, 0, 4 * sizeof(float));
    es->indices[3 * (size_t)es->triangle_count] = 0;

    /* flatten: world vertices, global indices, windings fixed for mirroring transforms */
    uint32_t vt = 0, tt = 0;
    for (uint32_t i = 0; i < no; i++) {
        const sl_object_rec *ob = &objects[i];
        const sl_mesh_rec *m = &meshes[ob->mesh];
        es->obj_first[i] = tt;
        es->obj_closed[i] = (uint8_t)((((ob->flags & SL_OBJECT_CLOSED_CONVEX) && !o.draw_closed_backfaces) ? OBJ_CLOSED : 0) |
                                      ((ob->flags & SL_OBJECT_SEE_THROUGH) ? OBJ_SEE_THROUGH : 0));
        const sl_affine *xf = ob->transform == SL_NONE ? NULL : &transforms[ob->transform];
        const float *p = positions + 3 * m->first_vertex;
        for (uint32_t k = 0; k < m->vertex_count; k++) {
            sl_vec3 v = {p[3 * k], p[3 * k + 1], p[3 * k + 2]};
            if (xf)
                v = sl_affine_point(xf, v);
            es->vertices[3 * (size_t)(vt + k)] = v.x;
            es->vertices[3 * (size_t)(vt + k) + 1] = v.y;
            es->vertices[3 * (size_t)(vt + k) + 2] = v.z;
            if (m->triangle_count)
                sl_aabb_grow(&es->bounds, v);
        }
        bool flip = xf && affine_det(xf) < 0;
        const uint32_t *ix = indices + m->first_index;
        for (uint32_t k = 0; k < m->triangle_count; k++) {
            uint32_t *d = &es->indices[3 * (size_t)(tt + k)];
            d[0] = vt + ix[3 * k];
            d[1] = vt + ix[3 * k + (flip ? 2 : 1)];
            d[2] = vt + ix[3 * k + (flip ? 1 : 2)];
            es->tri_object[tt + k] = i;
        }
        vt += m->vertex_count;
        tt += m->triangle_count;
    }
    es->obj_first[no] = tt;

    char config[64];
    if (o.threads)
        snprintf(config, sizeof config, "threads=%u,verbose=0", o.threads);
    else
        snprintf(config, sizeof config, "verbose=0");
    es->device = rtcNewDevice(config);
    if (!es->device) {
        int code = (int)rtcGetDeviceError(NULL);
        sl_es_destroy(es);
        return sl_fail(err, SL_ERROR_INTERNAL, "embree scene: rtcNewDevice failed (error %d)", code);
    }
    rtcSetDeviceErrorFunction(es->device, on_embree_error, es);
    es->rscene = rtcNewScene(es->device);
    if (es->rscene) {
        static const enum RTCBuildQuality q[3] = {RTC_BUILD_QUALITY_MEDIUM, RTC_BUILD_QUALITY_LOW,
                                                  RTC_BUILD_QUALITY_HIGH};
        rtcSetSceneFlags(es->rscene, RTC_SCENE_FLAG_ROBUST);
        rtcSetSceneBuildQuality(es->rscene, q[o.quality]);
        if (es->triangle_count) {
            RTCGeometry g = rtcNewGeometry(es->device, RTC_GEOMETRY_TYPE_TRIANGLE);
            if (g) {
                rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, es->vertices, 0,
                                           3 * sizeof(float), es->vertex_count);
                rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, es->indices, 0,
                                           3 * sizeof(uint32_t), es->triangle_count);
                rtcSetGeometryBuildQuality(g, q[o.quality]);
                if (es->filter) {
                    rtcSetGeometryUserData(g, es);
                    rtcSetGeometryIntersectFilterFunction(g, backface_filter);
                }
                rtcCommitGeometry(g);
                rtcAttachGeometryByID(es->rscene, g, 0);
                rtcReleaseGeometry(g);
            }
        }
        rtcCommitScene(es->rscene);
    }
    if (!es->rscene || es->embree_error[0] || rtcGetDeviceError(es->device) != RTC_ERROR_NONE) {
        sl_status st = sl_fail(err, SL_ERROR_INTERNAL, "embree scene: building %u triangles failed: %s",
                               es->triangle_count, es->embree_error[0] ? es->embree_error : "unknown Embree error");
        sl_es_destroy(es);
        return st;
    }
    es->build_seconds = sl_now() - t0;
    *out = es;
    return SL_OK;
}

void sl_es_get_stats(const sl_es *es, sl_es_stats *out)
{
    memset(out, 0, sizeof *out);
    out->object_count = es->object_count;
    out->triangle_count = es->triangle_count;
    out->vertex_count = es->vertex_count;
    out->backface_filter = es->filter;
    out->build_seconds = es->build_seconds;
    out->memory_bytes = sizeof *es + vertex_bytes(es->vertex_count) + index_bytes(es->triangle_count) +
                        ((size_t)es->triangle_count + 1) * sizeof(uint32_t) +
                        ((size_t)es->object_count + 1) * (sizeof(uint32_t) + 1);
}

uint32_t sl_es_triangle_count(const sl_es *es) { return es->triangle_count; }
uint32_t sl_es_object_count(const sl_es *es) { return es->object_count; }
uint32_t sl_es_triangle_object(const sl_es *es, uint32_t triangle) { return es->tri_object[triangle]; }
uint32_t sl_es_object_first_triangle(const sl_es *es, uint32_t object) { return es->obj_first[object]; }
sl_aabb sl_es_bounds(const sl_es *es) { return es->bounds; }

void sl_es_triangle_vertices(const sl_es *es, uint32_t triangle, double v[3][3])
{
    const uint32_t *ix = &es->indices[3 * (size_t)triangle];
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++)
            v[k][c] = es->vertices[3 * (size_t)ix[k] + c];
}

void sl_es_trace(const sl_es *es, const sl_es_ray *rays, sl_es_hit *hits, uint32_t n)
{
    trace_ctx ctx;
    rtcInitIntersectContext(&ctx.base);
    struct RTCRayHit rh[TRACE_CHUNK];
    for (uint32_t base = 0; base < n; base += TRACE_CHUNK) {
        uint32_t m = SL_MIN(TRACE_CHUNK, n - base);
        for (uint32_t i = 0; i < m; i++) {
            ctx.st_tri[i] = SL_NONE;
            ctx.st_t[i] = INFINITY;
            const sl_es_ray *r = &rays[base + i];
            struct RTCRayHit *h = &rh[i];
            h->ray.org_x = r->org[0];
            h->ray.org_y = r->org[1];
            h->ray.org_z = r->org[2];
            h->ray.tnear = r->tnear;
            h->ray.dir_x = r->dir[0];
            h->ray.dir_y = r->dir[1];
            h->ray.dir_z = r->dir[2];
            h->ray.time = 0.0f;
            h->ray.tfar = r->tfar;
            h->ray.mask = UINT32_MAX;
            h->ray.id = i;
            h->ray.flags = 0;
            h->hit.geomID = RTC_INVALID_GEOMETRY_ID;
            h->hit.primID = RTC_INVALID_GEOMETRY_ID;
            h->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect1M(es->rscene, &ctx.base, rh, m, sizeof(struct RTCRayHit));
        for (uint32_t i = 0; i < m; i++) {
            sl_es_hit *o = &hits[base + i];
            float limit = rays[base + i].tfar;
            if (rh[i].hit.geomID == RTC_INVALID_GEOMETRY_ID || rh[i].hit.primID >= es->triangle_count) {
                o->triangle = o->object = SL_NONE;
                o->t = INFINITY;
            } else {
                o->triangle = rh[i].hit.primID;
                o->object = es->tri_object[o->triangle];
                o->t = limit = rh[i].ray.tfar;
            }
            /* a see-through hit counts when it lies in front of the solid one (the filter may have
             * met it before the ray was shortened) */
            bool st = ctx.st_tri[i] != SL_NONE && ctx.st_t[i] <= limit;
            o->see_through_triangle = st ? ctx.st_tri[i] : SL_NONE;
            o->see_through_object = st ? es->tri_object[ctx.st_tri[i]] : SL_NONE;
            o->see_through_t = st ? ctx.st_t[i] : INFINITY;
        }
    }
}

sl_status sl_es_render_ids(const sl_es *es, const sl_camera *cam, uint32_t *tri_ids, sl_error *err)
{
    sl_view view;
    sl_status st = sl_view_from_camera(cam, &view, err);
    return st != SL_OK ? st : sl_es_render_view_ids(es, &view, tri_ids, err);
}

sl_status sl_es_render_view_ids(const sl_es *es, const sl_view *view, uint32_t *tri_ids, sl_error *err)
{
    if (!es || !tri_ids)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_es_render_view_ids: arguments must not be NULL");
    sl_status st = sl_view_validate(view, err);
    if (st != SL_OK)
        return st;
    if ((uint64_t)view->width * view->height > (1ull << 28))
        return sl_fail(err, SL_ERROR_LIMIT, "embree render: %ux%u pixels are too many", view->width, view->height);
    sl_es_ray rays[TRACE_CHUNK];
    sl_es_hit hits[TRACE_CHUNK];
    const uint64_t total = (uint64_t)view->width * view->height;
    for (uint64_t base = 0; base < total; base += TRACE_CHUNK) {
        uint32_t m = (uint32_t)SL_MIN((uint64_t)TRACE_CHUNK, total - base);
        for (uint32_t i = 0; i < m; i++) {
            uint64_t px = base + i;
            /* the pixel centre's sight line through the view's inverse projection (perspective:
             * dir has unit length along forward, so t is the view depth, as the near/far planes) */
            double org[3], dir[3];
            sl_view_pixel_ray(view, (double)(px % view->width) + 0.5, (double)(px / view->width) + 0.5, org, dir);
            sl_es_ray *ray = &rays[i];
            for (int k = 0; k < 3; k++) {
                ray->org[k] = (float)org[k];
                ray->dir[k] = (float)dir[k];
            }
            ray->tnear = (float)view->near_plane;
            ray->tfar = (float)view->far_plane; /* an infinite far plane stays infinite */
        }
        sl_es_trace(es, rays, hits, m);
        for (uint32_t i = 0; i < m; i++)
            tri_ids[base + i] = hits[i].triangle;
    }
    return SL_OK;
}

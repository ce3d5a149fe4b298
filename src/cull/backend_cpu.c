/* The CPU reference draw backend (include/sightline/backend.h): the oracle's reference rasterizer
 * (raster/raster_ref.h) drawing objects into an id + depth buffer and counting the fragments of
 * queries, with a result latency in frames.
 *
 * Why the reference rasterizer and not the conservative one of sl_raster: its coverage (exact
 * integer edge functions at pixel centres) and depth (the oracle's (1 - z/w)/2 per pixel) are the
 * oracle's, so a buffer drawn from a set of objects is the oracle's buffer for that set, a sample
 * count is an exact number of pixel-centre fragments (not a conservative estimate), and a query
 * culler drawing through it can be held to zero misses at the culling resolution. */
#include "sightline/backend.h"

#include "core/sl_core.h"
#include "raster/raster_ref.h"
#include "scene/scene_internal.h"

#include <math.h>

#define MAX_LATENCY 64

enum { Q_FREE = 0, Q_IDLE = 1, Q_OPEN = 2, Q_DONE = 3 };

typedef struct query_slot {
    uint8_t state;
    uint64_t samples;
    uint64_t ready_frame; /* first frame its result is ready for poll */
    double ready_ns;      /* the simulated clock from which it is ready */
    uint64_t triangles;   /* its triangles so far (the clock) */
    bool forced;          /* made ready by a wait */
} query_slot;

struct sl_draw_backend_cpu_t {
    sl_allocator alloc;
    sl_scene scene;
    uint32_t latency;
    sl_draw_backend_cpu_options clock; /* the time model (its latency_frames unused) */
    bool clocked;             /* any time field non-zero */
    double now;               /* the simulated clock, ns */
    uint32_t width, height;   /* of the buffers */
    float *depth;
    uint32_t *ids;
    double vp[16];
    bool in_frame;
    uint64_t frame;           /* index of the current (or last) frame; frames counted from 0 */
    uint64_t frames_begun;
    sl_refrast_scratch scratch;
    query_slot *slots;
    uint32_t slot_cap;
    uint32_t open;            /* slot index + 1 of the open query, 0 for none */
    sl_draw_backend_cpu_stats stats;
};

static sl_refrast_target target(const struct sl_draw_backend_cpu_t *b)
{
    sl_refrast_target t;
    memset(&t, 0, sizeof t);
    t.width = b->width;
    t.height = b->height;
    t.ids = b->ids;
    t.depth = b->depth;
    t.guard_x = 2.0 * SL_REFRAST_GUARD_PX / b->width;
    t.guard_y = 2.0 * SL_REFRAST_GUARD_PX / b->height;
    return t;
}

sl_status sl_draw_backend_check(const sl_draw_backend *b, sl_error *err)
{
    if (!b)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "draw backend: the table is NULL");
    if (b->version != SL_DRAW_BACKEND_VERSION)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "draw backend: version %u, this library knows version %u",
                       b->version, SL_DRAW_BACKEND_VERSION);
    const char *missing = !b->begin_frame       ? "begin_frame"
                          : !b->draw_objects    ? "draw_objects"
                          : !b->create_queries  ? "create_queries"
                          : !b->destroy_queries ? "destroy_queries"
                          : !b->begin_query     ? "begin_query"
                          : !b->query_boxes     ? "query_boxes"
                          : !b->query_objects   ? "query_objects"
                          : !b->end_query       ? "end_query"
                          : !b->poll_query      ? "poll_query"
                          : !b->wait_query      ? "wait_query"
                          : !b->end_frame       ? "end_frame"
                                                : NULL;
    if (missing)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "draw backend: callback %s is NULL", missing);
    return SL_OK;
}

/* ---- the callbacks ---- */

static sl_status cpu_begin_frame(void *user, const float world_to_clip[16], uint32_t width, uint32_t height,
                                 sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    if (b->in_frame)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: begin_frame inside a frame (end_frame missing)");
    if (!world_to_clip || width == 0 || height == 0 || width > 16384 || height > 16384)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: begin_frame needs a matrix and a viewport of "
                       "1..16384 pixels a side (got %ux%u)", width, height);
    for (int i = 0; i < 16; i++)
        if (!isfinite(world_to_clip[i]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: matrix entry %d is not finite", i);
    size_t n = (size_t)width * height;
    if (width != b->width || height != b->height) {
        size_t old = (size_t)b->width * b->height;
        sl_free(&b->alloc, b->depth, old * sizeof(float));
        sl_free(&b->alloc, b->ids, old * sizeof(uint32_t));
        b->depth = sl_alloc(&b->alloc, n * sizeof(float));
        b->ids = sl_alloc(&b->alloc, n * sizeof(uint32_t));
        b->width = b->height = 0;
        if (!b->depth || !b->ids) {
            sl_free(&b->alloc, b->depth, n * sizeof(float));
            sl_free(&b->alloc, b->ids, n * sizeof(uint32_t));
            b->depth = NULL;
            b->ids = NULL;
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cpu backend: out of memory for %ux%u pixels", width, height);
        }
        b->width = width;
        b->height = height;
    }
    sl_refrast_target t = target(b);
    sl_refrast_clear(&t);
    for (int i = 0; i < 16; i++)
        b->vp[i] = (double)world_to_clip[i]; /* as the oracle converts its float matrix */
    b->frame = b->frames_begun++;
    if (b->clocked)
        b->now = fmax(b->now, (double)b->frame * b->clock.frame_ns);
    b->in_frame = true;
    b->stats.frames++;
    return SL_OK;
}

static sl_status need_frame(const struct sl_draw_backend_cpu_t *b, const char *what, sl_error *err)
{
    return b->in_frame ? SL_OK : sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s outside a frame", what);
}

/* Draw (or, test_only, query) one object with the oracle's matrix and facing rule; returns the
 * fragments at least as near as the stored depth. */
static uint64_t object_fragments(struct sl_draw_backend_cpu_t *b, uint32_t id, bool test_only)
{
    const struct sl_scene_t *s = b->scene;
    const sl_object_rec *obj = &sl_scene_objects(s)[id];
    const sl_mesh_rec *mesh = &sl_scene_meshes(s)[obj->mesh];
    if (mesh->triangle_count == 0 || !sl_refrast_box_visible(b->vp, &sl_scene_object_bounds_array(b->scene)[id],
                                                             b->width, b->height))
        return 0; /* covers no pixel centre (the oracle skips it too) */
    const sl_affine identity = sl_affine_identity();
    const sl_affine *xf = obj->transform == SL_NONE ? &identity : &sl_scene_transforms(s)[obj->transform];
    double m[16];
    sl_refrast_compose(b->vp, xf, m);
    sl_refrast_cull cull = SL_REFRAST_CULL_NONE;
    if (obj->flags & SL_OBJECT_CLOSED_CONVEX) {
        const float *a = xf->m;
        double det = (double)a[0] * ((double)a[5] * a[10] - (double)a[6] * a[9]) -
                     (double)a[1] * ((double)a[4] * a[10] - (double)a[6] * a[8]) +
                     (double)a[2] * ((double)a[4] * a[9] - (double)a[5] * a[8]);
        cull = det < 0 ? SL_REFRAST_CULL_FRONT : SL_REFRAST_CULL_BACK;
    }
    sl_refrast_target t = target(b);
    /* a see-through object writes no depth (docs/oracle.md): its draw counts like a query */
    return sl_refrast_mesh_count(&t, &b->scratch, m, sl_scene_positions(s) + 3 * mesh->first_vertex,
                                 mesh->vertex_count, sl_scene_indices(s) + mesh->first_index, mesh->triangle_count, id,
                                 cull, test_only || (obj->flags & SL_OBJECT_SEE_THROUGH));
}

static sl_status check_ids(const struct sl_draw_backend_cpu_t *b, const uint32_t *ids, uint32_t count,
                           const char *what, sl_error *err)
{
    if (count && !ids)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s: ids is NULL", what);
    uint32_t n = sl_scene_object_count(b->scene);
    for (uint32_t i = 0; i < count; i++)
        if (ids[i] >= n)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s: object %u of a scene with %u", what,
                           ids[i], n);
    return SL_OK;
}

/* The clock: work of the simulated GPU. */
static void advance(struct sl_draw_backend_cpu_t *b, double ns)
{
    b->now += ns;
    b->stats.busy_ns += ns;
}

static sl_status cpu_draw_objects(void *user, const uint32_t *ids, uint32_t count, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_frame(b, "draw_objects", err);
    if (st == SL_OK)
        st = check_ids(b, ids, count, "draw_objects", err);
    if (st != SL_OK)
        return st;
    const struct sl_scene_t *s = b->scene;
    uint64_t passed = 0;
    for (uint32_t i = 0; i < count; i++) {
        passed += object_fragments(b, ids[i], false);
        b->stats.triangles_drawn += sl_scene_meshes(s)[sl_scene_objects(s)[ids[i]].mesh].triangle_count;
    }
    if (b->open)
        b->slots[b->open - 1].samples += passed;
    b->stats.draw_calls++;
    b->stats.objects_drawn += count;
    if (b->clocked) {
        uint64_t tris = 0;
        for (uint32_t i = 0; i < count; i++)
            tris += sl_scene_meshes(s)[sl_scene_objects(s)[ids[i]].mesh].triangle_count;
        advance(b, b->clock.ns_per_call + (double)tris * b->clock.ns_per_triangle +
                       (double)passed * b->clock.ns_per_fragment);
    }
    return SL_OK;
}

static query_slot *find_slot(struct sl_draw_backend_cpu_t *b, sl_draw_query q)
{
    return q >= 1 && q <= b->slot_cap && b->slots[q - 1].state != Q_FREE ? &b->slots[q - 1] : NULL;
}

static sl_status cpu_create_queries(void *user, uint32_t count, sl_draw_query *out, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    if (count && !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: create_queries: out is NULL");
    uint32_t free_slots = 0;
    for (uint32_t i = 0; i < b->slot_cap; i++)
        free_slots += b->slots[i].state == Q_FREE;
    if (free_slots < count) {
        uint64_t want = (uint64_t)b->slot_cap + (count - free_slots);
        uint64_t cap = SL_MAX(want, 2 * (uint64_t)b->slot_cap);
        if (cap > (1u << 24))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: more than %u query objects", 1u << 24);
        query_slot *s = sl_calloc(&b->alloc, (size_t)cap, sizeof *s);
        if (!s)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cpu backend: out of memory for %u query objects", (uint32_t)cap);
        if (b->slot_cap)
            memcpy(s, b->slots, b->slot_cap * sizeof *s);
        sl_free(&b->alloc, b->slots, b->slot_cap * sizeof *s);
        b->slots = s;
        b->slot_cap = (uint32_t)cap;
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < b->slot_cap && k < count; i++)
        if (b->slots[i].state == Q_FREE) {
            memset(&b->slots[i], 0, sizeof b->slots[i]);
            b->slots[i].state = Q_IDLE;
            out[k++] = i + 1;
        }
    return SL_OK;
}

static void cpu_destroy_queries(void *user, const sl_draw_query *queries, uint32_t count)
{
    struct sl_draw_backend_cpu_t *b = user;
    for (uint32_t i = 0; queries && i < count; i++) {
        query_slot *s = find_slot(b, queries[i]);
        if (!s)
            continue;
        if (b->open == queries[i])
            b->open = 0;
        s->state = Q_FREE;
    }
}

static sl_status cpu_begin_query(void *user, sl_draw_query q, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_frame(b, "begin_query", err);
    if (st != SL_OK)
        return st;
    if (b->open)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: begin_query(%u) while query %u is open", q, b->open);
    query_slot *s = find_slot(b, q);
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: begin_query: %u is not a query object", q);
    s->state = Q_OPEN;
    s->samples = 0;
    s->triangles = 0;
    s->forced = false;
    b->open = q;
    b->stats.queries++;
    return SL_OK;
}

static sl_status need_query(const struct sl_draw_backend_cpu_t *b, const char *what, sl_error *err)
{
    sl_status st = need_frame(b, what, err);
    if (st == SL_OK && !b->open)
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s without an open query", what);
    return st;
}

/* The 12 triangles of a box, both facings drawn: corner k has x from bit 0, y bit 1, z bit 2. */
static const uint32_t g_box_tris[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                        2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};

static sl_status cpu_query_boxes(void *user, const sl_aabb *boxes, uint32_t count, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_query(b, "query_boxes", err);
    if (st == SL_OK && count && !boxes)
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: query_boxes: boxes is NULL");
    if (st != SL_OK)
        return st;
    uint64_t passed = 0;
    sl_refrast_target t = target(b);
    for (uint32_t i = 0; i < count; i++) {
        const sl_aabb *x = &boxes[i];
        if (!(x->min.x <= x->max.x && x->min.y <= x->max.y && x->min.z <= x->max.z) || !isfinite(x->min.x) ||
            !isfinite(x->min.y) || !isfinite(x->min.z) || !isfinite(x->max.x) || !isfinite(x->max.y) ||
            !isfinite(x->max.z))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: query box %u is empty or not finite", i);
        b->stats.query_boxes++;
        b->stats.query_triangles += 12;
        b->slots[b->open - 1].triangles += 12;
        if (!sl_refrast_box_visible(b->vp, x, b->width, b->height))
            continue; /* covers no pixel centre */
        float pos[24];
        for (int k = 0; k < 8; k++) {
            pos[3 * k] = (k & 1) ? x->max.x : x->min.x;
            pos[3 * k + 1] = (k & 2) ? x->max.y : x->min.y;
            pos[3 * k + 2] = (k & 4) ? x->max.z : x->min.z;
        }
        passed += sl_refrast_mesh_count(&t, &b->scratch, b->vp, pos, 8, g_box_tris, 12, SL_NONE, SL_REFRAST_CULL_NONE,
                                        true);
    }
    b->slots[b->open - 1].samples += passed;
    return SL_OK;
}

static sl_status cpu_query_objects(void *user, const uint32_t *ids, uint32_t count, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_query(b, "query_objects", err);
    if (st == SL_OK)
        st = check_ids(b, ids, count, "query_objects", err);
    if (st != SL_OK)
        return st;
    const struct sl_scene_t *s = b->scene;
    uint64_t passed = 0;
    for (uint32_t i = 0; i < count; i++) {
        passed += object_fragments(b, ids[i], true);
        uint32_t tris = sl_scene_meshes(s)[sl_scene_objects(s)[ids[i]].mesh].triangle_count;
        b->stats.query_triangles += tris;
        b->slots[b->open - 1].triangles += tris;
    }
    b->stats.query_objects += count;
    b->slots[b->open - 1].samples += passed;
    return SL_OK;
}

static sl_status cpu_end_query(void *user, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_query(b, "end_query", err);
    if (st != SL_OK)
        return st;
    query_slot *s = &b->slots[b->open - 1];
    s->state = Q_DONE;
    s->ready_frame = b->frame + b->latency;
    if (b->clocked) /* (draws inside the query were charged by draw_objects) */
        advance(b, b->clock.ns_per_call + (double)s->triangles * b->clock.ns_per_triangle +
                       (double)s->samples * b->clock.ns_per_fragment);
    s->ready_ns = b->now + b->clock.query_latency_ns;
    b->stats.samples_passed += s->samples;
    b->open = 0;
    return SL_OK;
}

static sl_status done_slot(struct sl_draw_backend_cpu_t *b, sl_draw_query q, const char *what, query_slot **out,
                           sl_error *err)
{
    query_slot *s = find_slot(b, q);
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s: %u is not a query object", what, q);
    if (s->state != Q_DONE)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s: query %u %s", what, q,
                       s->state == Q_OPEN ? "is still open (end_query first)" : "was never issued");
    *out = s;
    return SL_OK;
}

static sl_status cpu_poll_query(void *user, sl_draw_query q, bool *ready, uint64_t *samples, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    query_slot *s = NULL;
    if (!ready || !samples)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: poll_query: ready and samples must not be NULL");
    sl_status st = done_slot(b, q, "poll_query", &s, err);
    if (st != SL_OK)
        return st;
    b->stats.polls++;
    *ready = s->forced || (b->frame >= s->ready_frame && b->now >= s->ready_ns);
    *samples = *ready ? s->samples : 0;
    if (!*ready)
        b->stats.polls_not_ready++;
    return SL_OK;
}

static sl_status cpu_wait_query(void *user, sl_draw_query q, uint64_t *samples, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    query_slot *s = NULL;
    if (!samples)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: wait_query: samples is NULL");
    sl_status st = done_slot(b, q, "wait_query", &s, err);
    if (st != SL_OK)
        return st;
    b->stats.waits++;
    if (!s->forced && (b->frame < s->ready_frame || b->now < s->ready_ns)) {
        b->stats.stalls++;
        s->forced = true;
        if (b->clocked && b->now < s->ready_ns) { /* the clock waits for it */
            b->stats.wait_ns += s->ready_ns - b->now;
            b->now = s->ready_ns;
        }
    }
    *samples = s->samples;
    return SL_OK;
}

static sl_status cpu_end_frame(void *user, sl_error *err)
{
    struct sl_draw_backend_cpu_t *b = user;
    sl_status st = need_frame(b, "end_frame", err);
    if (st != SL_OK)
        return st;
    if (b->open)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: end_frame with query %u open", b->open);
    b->in_frame = false;
    return SL_OK;
}

/* ---- the handle ---- */

sl_status sl_draw_backend_cpu_create(sl_scene scene, const sl_draw_backend_cpu_options *options,
                                     const sl_allocator *alloc, sl_draw_backend_cpu *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_draw_backend_cpu_create: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_draw_backend_cpu_create: scene is NULL");
    uint32_t latency = options ? options->latency_frames : 0;
    if (latency > MAX_LATENCY)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: latency_frames %u is above %u", latency,
                       MAX_LATENCY);
    sl_draw_backend_cpu_options clock;
    memset(&clock, 0, sizeof clock);
    if (options)
        clock = *options;
    const struct {
        const char *name;
        double v;
    } times[] = {{"ns_per_call", clock.ns_per_call},           {"ns_per_triangle", clock.ns_per_triangle},
                 {"ns_per_fragment", clock.ns_per_fragment},   {"query_latency_ns", clock.query_latency_ns},
                 {"frame_ns", clock.frame_ns}};
    bool clocked = false;
    for (size_t i = 0; i < SL_COUNTOF(times); i++) {
        if (!(times[i].v >= 0 && times[i].v <= 1e12))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "cpu backend: %s %g is not in 0..1e12 ns", times[i].name,
                           times[i].v);
        clocked |= times[i].v > 0;
    }
    alloc = sl_alloc_or_default(alloc);
    struct sl_draw_backend_cpu_t *b = sl_calloc(alloc, 1, sizeof *b);
    if (!b)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cpu backend: out of memory");
    b->alloc = *alloc;
    b->scene = scene;
    b->latency = latency;
    b->clock = clock;
    b->clocked = clocked;
    /* scratch for the largest mesh (and a box), so that drawing allocates nothing */
    const struct sl_scene_t *s = scene;
    uint32_t nm = sl_scene_mesh_count(scene), maxv = 8;
    for (uint32_t m = 0; m < nm; m++)
        maxv = SL_MAX(maxv, sl_scene_meshes(s)[m].vertex_count);
    if (!sl_refrast_scratch_reserve(&b->alloc, &b->scratch, maxv)) {
        sl_draw_backend_cpu_destroy(b);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cpu backend: out of memory for %u transformed vertices", maxv);
    }
    *out = b;
    return SL_OK;
}

void sl_draw_backend_cpu_destroy(sl_draw_backend_cpu b)
{
    if (!b)
        return;
    sl_allocator a = b->alloc;
    size_t n = (size_t)b->width * b->height;
    sl_free(&a, b->depth, n * sizeof(float));
    sl_free(&a, b->ids, n * sizeof(uint32_t));
    sl_free(&a, b->slots, b->slot_cap * sizeof(query_slot));
    sl_refrast_scratch_free(&a, &b->scratch);
    sl_free(&a, b, sizeof *b);
}

sl_draw_backend sl_draw_backend_cpu_table(sl_draw_backend_cpu b)
{
    sl_draw_backend t;
    memset(&t, 0, sizeof t);
    t.version = SL_DRAW_BACKEND_VERSION;
    t.user = b;
    t.begin_frame = cpu_begin_frame;
    t.draw_objects = cpu_draw_objects;
    t.create_queries = cpu_create_queries;
    t.destroy_queries = cpu_destroy_queries;
    t.begin_query = cpu_begin_query;
    t.query_boxes = cpu_query_boxes;
    t.query_objects = cpu_query_objects;
    t.end_query = cpu_end_query;
    t.poll_query = cpu_poll_query;
    t.wait_query = cpu_wait_query;
    t.end_frame = cpu_end_frame;
    return t;
}

sl_draw_backend_cpu sl_draw_backend_cpu_of(const sl_draw_backend *t)
{
    return t && t->begin_frame == cpu_begin_frame && t->poll_query == cpu_poll_query ? t->user : NULL;
}

sl_draw_backend_cpu_options sl_draw_backend_cpu_clock_default(void)
{
    sl_draw_backend_cpu_options o;
    memset(&o, 0, sizeof o);
    o.ns_per_call = 2000;
    o.ns_per_triangle = 2;
    o.ns_per_fragment = 0.05;
    o.query_latency_ns = 20000;
    o.frame_ns = 1e9 / 30;
    return o;
}

void sl_draw_backend_cpu_get_stats(sl_draw_backend_cpu b, sl_draw_backend_cpu_stats *out)
{
    if (!out)
        return;
    if (!b) {
        memset(out, 0, sizeof *out);
    } else {
        *out = b->stats;
        out->clock_ns = b->now;
    }
}

void sl_draw_backend_cpu_reset_stats(sl_draw_backend_cpu b)
{
    if (b)
        memset(&b->stats, 0, sizeof b->stats);
}

void sl_draw_backend_cpu_buffers(sl_draw_backend_cpu b, const float **depth, const uint32_t **ids, uint32_t *width,
                                 uint32_t *height)
{
    if (depth)
        *depth = b ? b->depth : NULL;
    if (ids)
        *ids = b ? b->ids : NULL;
    if (width)
        *width = b ? b->width : 0;
    if (height)
        *height = b ? b->height : 0;
}

size_t sl_draw_backend_cpu_memory(sl_draw_backend_cpu b)
{
    if (!b)
        return 0;
    return sizeof *b + (size_t)b->width * b->height * (sizeof(float) + sizeof(uint32_t)) +
           b->slot_cap * sizeof(query_slot) + b->scratch.cap * (4 * sizeof(double) + 32 + 1);
}

/* gl-stopwait (called hoq before issue 15): hierarchical occlusion queries through a draw backend
 * (backend.h), stop and wait: the baseline of the query cullers (chc, chc++: chc.c).
 *
 * The object BVH is walked front to back (sl_bvh_traverse). A node in the frustum is tested by an
 * occlusion query over its box, grown by a margin (below), against what has been drawn so far: the
 * culler waits for the answer (stop and wait: poll, and wait when it is not ready, a stall) and
 * skips the subtree when no sample passed. In a leaf each object is tested by a query over its own
 * triangles (object_queries) and drawn when visible; the ids drawn are the result. This is the
 * hierarchical stop-and-wait scheme that coherent hierarchical culling (J. Bittner, M. Wimmer,
 * H. Piringer, W. Purgathofer, "Coherent Hierarchical Culling: Hardware Occlusion Queries Made
 * Useful", Eurographics 2004, section 3) starts from; CHC and CHC++ keep queries in flight across
 * frames on the same backend calls.
 *
 * Without a backend (sl_culler_params.backend NULL) the method draws through a CPU reference
 * backend of its own (the oracle's rasterizer, exact sample counts, latency=L frames).
 *
 * Guarantee: SL_CONSERVATIVE_AT_RESOLUTION with the CPU backend (or any backend whose draws and
 * queries sample pixel centres as the oracle does). The depth buffer holds the oracle's fragments
 * of the objects drawn so far, so it is never nearer than the oracle's final buffer at any pixel.
 * An object's query draws its own triangles, whose fragments are the oracle's: one the oracle shows
 * at pixel p is at least as near as the buffer there and passes (exact, no margin needed). A node
 * is queried by a box (sl_hoq_grow_box): its box grown by `margin` pixel footprints at its
 * farthest corner (1/16 by default, against vertex snapping of 1/512 pixel), then moved toward the
 * eye along the view rays until its farthest point is as near as its nearest one was. The growth
 * keeps every pixel its objects cover inside the query's footprint; the reach is the depth bound:
 * the reference rasterizer takes depth from the exact plane at a snapped pixel centre, and for a
 * surface seen edge-on that extrapolation has no bound but the triangle's vertex range (hoq.h), so
 * no fragment of the node is nearer than its nearest corner, and the query box is at least that
 * near everywhere on its footprint (tests/test_backend.c, test_hoq_box_covers: the margin alone
 * misses 1 pixel in 439,225, a ground polygon under a degree; the query box none). A query box
 * that reaches behind the near plane (or holds the eye) cannot be queried by its faces and counts
 * as visible. Objects hidden at the culling resolution may show at another one (the drawn objects
 * are sampled at pixel centres), hence not SL_CONSERVATIVE. */
#include "hoq.h"
#include "culler_internal.h"

#include "accel/bvh_internal.h"
#include "scene/scene_internal.h"

#include <math.h>

typedef struct hoq_config {
    uint32_t leaf_size;
    sl_qc_backend_opts backend;
    bool object_queries;
    bool node_queries;
    float margin;   /* pixels */
} hoq_config;

typedef struct hoq_state {
    sl_allocator alloc;
    sl_scene scene;
    hoq_config cfg;
    sl_bvh bvh;
    bool bvh_owned;
    sl_qc_backend qb;          /* the backend (given, or its own) */
    sl_draw_query query;
    uint32_t object_count;
    uint32_t *sort_scratch;
} hoq_state;

/* One frame. */
typedef struct frame_ctx {
    hoq_state *s;
    sl_hoq_view view;       /* matrices, eye and pixel footprint of the query boxes */
    sl_frustum frustum;
    sl_cull_stats *stats;
    uint32_t *out;
    uint32_t count;
    bool drawn_any;
    sl_status st;
    sl_error *err;
} frame_ctx;

static const char g_help[] =
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n"
    "object_queries=BOOL (default true): query each object of a visible leaf by its own triangles before drawing it\n"
    "node_queries=BOOL (default true): query BVH nodes by their grown boxes (false: only the objects, every answer exact)\n"
    "margin=0.0625..4 (default 0.0625): pixels each queried node box grows by, at its farthest corner (before its "
    "reach toward the eye)\n" SL_QC_BACKEND_HELP;

static sl_status hoq_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    hoq_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_u32(o, "leaf_size", SL_BVH_DEFAULT_LEAF_SIZE, 1, SL_BVH_MAX_LEAF_SIZE, &c->leaf_size, err)) !=
            SL_OK ||
        (st = sl_opts_bool(o, "object_queries", true, &c->object_queries, err)) != SL_OK ||
        (st = sl_opts_bool(o, "node_queries", true, &c->node_queries, err)) != SL_OK ||
        (st = sl_opts_float(o, "margin", 0.0625f, 0.0625f, 4.0f, &c->margin, err)) != SL_OK ||
        (st = sl_qc_backend_configure(o, &c->backend, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void hoq_destroy(void *state)
{
    hoq_state *s = state;
    if (!s)
        return;
    if (s->query && s->qb.be.destroy_queries)
        s->qb.be.destroy_queries(s->qb.be.user, &s->query, 1);
    sl_qc_backend_close(&s->qb);
    if (s->bvh_owned)
        sl_bvh_destroy(s->bvh);
    sl_free(&s->alloc, s->sort_scratch, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(&s->alloc, s, sizeof *s);
}

static sl_status hoq_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                            const sl_allocator *alloc, void **state, sl_error *err)
{
    hoq_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gl-stopwait: out of memory");
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *(const hoq_config *)config;
    s->object_count = sl_scene_object_count(scene);
    sl_status st = sl_cull_object_bvh(scene, extras, s->cfg.leaf_size, alloc, &s->bvh, &s->bvh_owned, err);
    if (st == SL_OK)
        st = sl_qc_backend_open(&s->qb, scene, &s->cfg.backend, extras, alloc, err);
    if (st == SL_OK && (st = s->qb.be.create_queries(s->qb.be.user, 1, &s->query, err)) != SL_OK)
        s->query = 0;
    if (st == SL_OK) {
        s->sort_scratch = sl_alloc(alloc, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
        if (!s->sort_scratch)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for %u objects", s->object_count);
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "gl-stopwait");
        hoq_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status hoq_scene_changed(void *state, sl_error *err)
{
    hoq_state *s = state;
    if (!s->bvh_owned)
        return SL_OK; /* the handle's owner refitted the tree (accel.h) */
    sl_status st = sl_bvh_refit(s->bvh, s->scene, err);
    if (st == SL_OK)
        st = sl_bvh_rebuild_if_degraded(s->bvh, s->scene, 0, NULL, err);
    if (st != SL_OK)
        sl_error_prefix(err, "gl-stopwait");
    return st;
}

void sl_hoq_view_set(sl_hoq_view *v, const sl_mat4 *view_proj, const sl_mat4 *proj, uint32_t width, uint32_t height,
                     sl_vec3 eye, bool ortho, float margin)
{
    for (int i = 0; i < 16; i++)
        v->vp[i] = (double)view_proj->m[i];
    v->eye[0] = eye.x, v->eye[1] = eye.y, v->eye[2] = eye.z;
    /* a pixel's width in eye space, from the projection's scales (per unit of depth in perspective,
     * the eye distance bounding the depth): the larger of the two axes */
    v->footprint = fmax(2.0 / (fabs((double)proj->m[0]) * width), 2.0 / (fabs((double)proj->m[5]) * height));
    v->ortho = ortho;
    v->margin = margin;
    v->reach = true;
}

/* Clip z and w of world point p. */
static void clip_zw(const sl_hoq_view *v, const double p[3], double *z, double *w)
{
    *z = v->vp[2] * p[0] + v->vp[6] * p[1] + v->vp[10] * p[2] + v->vp[14];
    *w = v->vp[3] * p[0] + v->vp[7] * p[1] + v->vp[11] * p[2] + v->vp[15];
}

bool sl_hoq_grow_box(const sl_hoq_view *v, const sl_aabb *b, sl_aabb *g)
{
    double far2 = 0;
    for (int k = 0; k < 8; k++) {
        double dx = ((k & 1) ? b->max.x : b->min.x) - (double)v->eye[0];
        double dy = ((k & 2) ? b->max.y : b->min.y) - (double)v->eye[1];
        double dz = ((k & 4) ? b->max.z : b->min.z) - (double)v->eye[2];
        far2 = fmax(far2, dx * dx + dy * dy + dz * dz);
    }
    double px = v->ortho ? v->footprint : v->footprint * sqrt(far2);
    /* and the float rounding of the box's coordinates (a few units in the last place) */
    double ext = fmax(fmax(fmax(fabs(b->min.x), fabs(b->max.x)), fmax(fabs(b->min.y), fabs(b->max.y))),
                      fmax(fabs(b->min.z), fabs(b->max.z)));
    float m = (float)(v->margin * px + 4e-7 * (ext + 1.0));
    g->min = (sl_vec3){b->min.x - m, b->min.y - m, b->min.z - m};
    g->max = (sl_vec3){b->max.x + m, b->max.y + m, b->max.z + m};
    double zmin = INFINITY, zmax = -INFINITY, wmin = INFINITY, wmax = -INFINITY;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? g->max.x : g->min.x, (k & 2) ? g->max.y : g->min.y, (k & 4) ? g->max.z : g->min.z};
        double z, w;
        clip_zw(v, p, &z, &w);
        if (!(z >= -w) || !(w > 0))
            return false;
        zmin = fmin(zmin, z), zmax = fmax(zmax, z), wmin = fmin(wmin, w), wmax = fmax(wmax, w);
    }
    if (!v->reach)
        return true;
    /* The reach toward the eye (the depth bound, hoq.h): the query box is the grown box's copy
     * moved along the view rays until its farthest point is as near as the grown box's nearest.
     * In perspective the copy is the box scaled about the eye by wmin / wmax (clip x, y and w
     * scale alike, so it projects onto the grown box's own footprint, at w <= wmin); in
     * orthographic projection it is the box moved along the rays (the null direction of clip x
     * and y) by its depth extent. */
    double lo[3] = {g->min.x, g->min.y, g->min.z}, hi[3] = {g->max.x, g->max.y, g->max.z};
    double e[3] = {v->eye[0], v->eye[1], v->eye[2]}, shift[3] = {0, 0, 0}, scale = 1;
    if (v->ortho) {
        const double r0[3] = {v->vp[0], v->vp[4], v->vp[8]}, r1[3] = {v->vp[1], v->vp[5], v->vp[9]};
        double r[3] = {r0[1] * r1[2] - r0[2] * r1[1], r0[2] * r1[0] - r0[0] * r1[2], r0[0] * r1[1] - r0[1] * r1[0]};
        double gr = v->vp[2] * r[0] + v->vp[6] * r[1] + v->vp[10] * r[2];
        if (!(fabs(gr) > 0) || !isfinite(gr))
            return false;
        double t = -(zmax - zmin) / gr;
        for (int i = 0; i < 3; i++)
            shift[i] = t * r[i];
    } else {
        scale = wmin / wmax;
    }
    float nlo[3], nhi[3];
    for (int i = 0; i < 3; i++) {
        double a = e[i] + scale * (lo[i] - e[i]) + shift[i], c = e[i] + scale * (hi[i] - e[i]) + shift[i];
        /* rounded outward, with the rounding of the arithmetic above: a larger copy still holds
         * the exact one, so its front is at least as near on at least its footprint */
        double slack = 4e-7 * (fabs(a) + fabs(c) + fabs(e[i]) + fabs(shift[i]) + 1.0);
        double want_lo = fmin(a, c) - slack, want_hi = fmax(a, c) + slack;
        nlo[i] = (float)want_lo;
        nhi[i] = (float)want_hi;
        if ((double)nlo[i] > want_lo)
            nlo[i] = nextafterf(nlo[i], -INFINITY);
        if ((double)nhi[i] < want_hi)
            nhi[i] = nextafterf(nhi[i], INFINITY);
    }
    g->min = (sl_vec3){nlo[0], nlo[1], nlo[2]};
    g->max = (sl_vec3){nhi[0], nhi[1], nhi[2]};
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? g->max.x : g->min.x, (k & 2) ? g->max.y : g->min.y, (k & 4) ? g->max.z : g->min.z};
        double z, w;
        clip_zw(v, p, &z, &w);
        if (!(z >= -w) || !(w > 0))
            return false;
    }
    return true;
}

/* Is the node's box, or the object, visible: the stop-and-wait query. A node is queried by its
 * grown box; an object (object != NULL) by its own triangles, whose fragments are the oracle's. */
static bool query_visible(frame_ctx *f, const sl_aabb *box, const uint32_t *object)
{
    if (f->st != SL_OK)
        return false;
    sl_aabb g;
    if (!object && !sl_hoq_grow_box(&f->view, box, &g))
        return true;
    if (!f->drawn_any)
        return true; /* nothing drawn: anything on screen passes wherever it covers a centre */
    hoq_state *s = f->s;
    const sl_draw_backend *be = &s->qb.be;
    sl_error *err = f->err;
    f->stats->occlusion_tests++;
    f->stats->queries++;
    bool ready = false;
    uint64_t samples = 0;
    sl_status st = be->begin_query(be->user, s->query, err);
    if (st == SL_OK) {
        st = object ? be->query_objects(be->user, object, 1, err) : be->query_boxes(be->user, &g, 1, err);
        sl_error ignored; /* the query is closed even after a failure (end_frame needs it) */
        sl_status st2 = be->end_query(be->user, st == SL_OK ? err : &ignored);
        if (st == SL_OK)
            st = st2;
    }
    if (st == SL_OK)
        st = be->poll_query(be->user, s->query, &ready, &samples, err);
    if (st == SL_OK && !ready) {
        f->stats->query_stalls++;
        st = sl_qc_wait(&s->qb, s->query, &samples, err);
    }
    if (st != SL_OK) {
        f->st = st;
        return false;
    }
    return samples > 0;
}

static bool node_fn(void *user, uint32_t node, const sl_aabb *bounds)
{
    frame_ctx *f = user;
    if (f->st != SL_OK)
        return false;
    f->stats->nodes_visited++;
    if (sl_frustum_test_aabb(&f->frustum, bounds) == 0)
        return false;
    const sl_bvh_node *n = &f->s->bvh->nodes[node];
    if (!f->s->cfg.node_queries || (sl_bvh_node_is_leaf(n) && n->count == 1 && f->s->cfg.object_queries))
        return true; /* (the object's own query follows) */
    return query_visible(f, bounds, NULL);
}

static bool object_fn(void *user, uint32_t object, const sl_aabb *bounds)
{
    frame_ctx *f = user;
    if (f->st != SL_OK)
        return false;
    f->stats->objects_tested++;
    if (sl_frustum_test_aabb(&f->frustum, bounds) == 0)
        return true;
    if (f->s->cfg.object_queries && !query_visible(f, bounds, &object))
        return f->st == SL_OK;
    const sl_draw_backend *be = &f->s->qb.be;
    sl_status st = be->draw_objects(be->user, &object, 1, f->err);
    if (st != SL_OK) {
        f->st = st;
        return false;
    }
    f->drawn_any = true;
    f->out[f->count++] = object;
    return true;
}

static sl_status hoq_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    hoq_state *s = state;
    frame_ctx f;
    memset(&f, 0, sizeof f);
    f.s = s;
    f.stats = stats;
    f.out = out;
    f.err = err;
    /* the view: the only lines that read it (an off-axis projection keeps its scales in P00, P11) */
    sl_mat4 vpf = view->view_proj;
    uint32_t width = view->width, height = view->height;
    f.frustum = view->frustum;
    sl_hoq_view_set(&f.view, &vpf, &view->proj, width, height, view->eye, view->projection == SL_ORTHOGRAPHIC,
                    s->cfg.margin);

    double t0 = sl_now();
    sl_qc_frame_start(&s->qb);
    const sl_draw_backend *be = &s->qb.be;
    sl_status st = be->begin_frame(be->user, vpf.m, width, height, err);
    if (st == SL_OK) {
        sl_bvh_traverse(s->bvh, (sl_vec3){f.view.eye[0], f.view.eye[1], f.view.eye[2]}, node_fn, object_fn, &f);
        st = f.st;
        /* close the frame even after a failure, so that the next one can begin */
        sl_error ignored;
        sl_status st2 = be->end_frame(be->user, st == SL_OK ? err : &ignored);
        if (st == SL_OK)
            st = st2;
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "gl-stopwait");
        return st;
    }
    double t1 = sl_now();
    sl_cull_sort_ids(out, f.count, s->sort_scratch);
    sl_cull_phase(stats, "traverse+draw", sl_cull_ms(t0, t1));
    stats->query_wait_ms = sl_qc_wait_ms(&s->qb);
    *count = f.count;
    return SL_OK;
}

const sl_cull_method sl_cull_method_stopwait = {
    .name = "gl-stopwait",
    .summary = "hierarchical stop-and-wait occlusion queries over the object BVH, front to back, through a draw "
               "backend (its own CPU reference backend with a simulated clock when given none; the baseline of "
               "Bittner et al. 2004, section 3; called hoq before issue 15)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE_AT_RESOLUTION,
    .config_size = sizeof(hoq_config),
    .depth = SL_DEPTH_CLIP_Z,
    .configure = hoq_configure,
    .create_with = hoq_create,
    .draws = true,
    .cull = hoq_cull,
    .scene_changed = hoq_scene_changed,
    .destroy = hoq_destroy,
};

/* ---- what the query cullers share ---- */

sl_status sl_qc_backend_configure(sl_opts *o, sl_qc_backend_opts *c, sl_error *err)
{
    sl_status st;
    if ((st = sl_opts_u32(o, "latency", 0, 0, 64, &c->latency, err)) != SL_OK ||
        (st = sl_opts_bool(o, "clock", true, &c->clock, err)) != SL_OK ||
        (st = sl_opts_float(o, "query_latency_us", 20.0f, 0.0f, 100000.0f, &c->query_latency_us, err)) != SL_OK)
        return st;
    return SL_OK;
}

sl_status sl_qc_backend_open(sl_qc_backend *q, sl_scene scene, const sl_qc_backend_opts *c, const sl_cull_extras *extras,
                             const sl_allocator *alloc, sl_error *err)
{
    memset(q, 0, sizeof *q);
    if (extras && extras->backend) {
        const char *own = c->latency ? "latency" : !c->clock ? "clock" : c->query_latency_us != 20.0f ? "query_latency_us"
                                                                                                      : NULL;
        if (own)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "%s= is for the CPU backend made without a backend; the given backend has its own", own);
        q->be = *extras->backend;
        q->cpu = sl_draw_backend_cpu_of(&q->be);
        return SL_OK;
    }
    sl_draw_backend_cpu_options co;
    if (c->clock) {
        co = sl_draw_backend_cpu_clock_default();
        co.query_latency_ns = 1000.0 * (double)c->query_latency_us;
    } else {
        memset(&co, 0, sizeof co);
    }
    co.latency_frames = c->latency;
    sl_status st = sl_draw_backend_cpu_create(scene, &co, alloc, &q->own, err);
    if (st != SL_OK)
        return st;
    q->cpu = q->own;
    q->be = sl_draw_backend_cpu_table(q->own);
    return SL_OK;
}

void sl_qc_backend_close(sl_qc_backend *q)
{
    sl_draw_backend_cpu_destroy(q->own);
    q->own = q->cpu = NULL;
}

void sl_qc_frame_start(sl_qc_backend *q)
{
    q->wall_wait_ms = 0;
    q->wait_ns0 = 0;
    if (q->cpu) {
        sl_draw_backend_cpu_stats st;
        sl_draw_backend_cpu_get_stats(q->cpu, &st);
        q->wait_ns0 = st.wait_ns;
    }
}

double sl_qc_wait_ms(const sl_qc_backend *q)
{
    if (!q->cpu)
        return q->wall_wait_ms;
    sl_draw_backend_cpu_stats st;
    sl_draw_backend_cpu_get_stats(q->cpu, &st);
    return (st.wait_ns - q->wait_ns0) * 1e-6;
}

sl_status sl_qc_wait(sl_qc_backend *q, sl_draw_query query, uint64_t *samples, sl_error *err)
{
    if (q->cpu)
        return q->be.wait_query(q->be.user, query, samples, err);
    double t0 = sl_now();
    sl_status st = q->be.wait_query(q->be.user, query, samples, err);
    q->wall_wait_ms += sl_cull_ms(t0, sl_now());
    return st;
}

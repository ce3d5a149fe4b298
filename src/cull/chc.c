/* chc and chc++: coherent hierarchical culling with occlusion queries through a draw backend
 * (backend.h), after J. Bittner, M. Wimmer, H. Piringer, W. Purgathofer, "Coherent Hierarchical
 * Culling: Hardware Occlusion Queries Made Useful", Eurographics 2004, in the form of M. Wimmer and
 * J. Bittner, GPU Gems 2 chapter 6 (the seed's chapter 4, ../shared/seeds/notes/003_wimmer.md §3),
 * and O. Mattausch, J. Bittner, M. Wimmer, "CHC++: Coherent Hierarchical Culling Revisited",
 * Computer Graphics Forum 27(2), 2008 (not in the seeds: built from the elements the issue lists;
 * docs/query-culling.md says which parts follow the paper and which are choices of this file).
 *
 * CHC (chapter, Figs. 4.5-4.6): the object BVH is walked front to back with a priority queue keyed
 * by the distance to the eye. Each node keeps `visible` and `last_visited` (frame ids, no reset per
 * frame). A node visited is set invisible; a previously visible interior node is traversed without a
 * query (its visibility is pulled up from its children); a previously visible leaf is drawn at once
 * and queried (by its grown box, or with geometry_queries by its own draw inside the query) for the
 * next frame; a previously invisible node is queried and its result awaited interleaved with the
 * traversal: results are polled after every node and waited for only when the traversal queue is
 * empty. A result above `threshold` pulls visibility up to the root and traverses the node (draws a
 * leaf, pushes an interior node's children: the pull-down). Queries of previously visible leaves
 * still in flight at the end of the frame are read at the start of the next one (they only update
 * the classification, never what is drawn).
 *
 * CHC++ (chc++): previously invisible nodes go to an i-queue, issued when it holds `batch` nodes or
 * when nothing else is left, as multiqueries (one query over the boxes of several nodes, grouped by
 * how long they have stayed invisible; a multiquery that comes back visible is split into one query
 * per node); queries of previously visible leaves go to a v-queue, issued `vbatch` at a time while
 * waiting for a result and the rest at the end of the frame; a leaf found visible is not queried
 * again for a seeded random number of frames (0..assume_visible when it becomes visible, then
 * assume_visible); a queried node may be tested by the boxes of its children or objects (down to
 * tight_depth levels) when their projection is smaller by tight_ratio.
 *
 * Guarantee (threshold 0, any other option): SL_CONSERVATIVE_AT_RESOLUTION with the CPU backend, by
 * the argument of gl-stopwait (hoq.c, hoq.h): the depth buffer holds the oracle's fragments of the
 * objects drawn so far, never nearer than the oracle's final buffer; an object is left undrawn only
 * when its box is outside the frustum or a query issued in this frame, over boxes that hold it grown
 * by sl_hoq_grow_box (its node's, an ancestor's, a tighter child or object box, or a multiquery of
 * such), counted no sample; that query box is at least as near as every fragment of the object at
 * every pixel centre the object covers, so an object the oracle shows would have passed. Objects of
 * previously visible leaves, and of leaves assumed visible, are drawn whatever their queries say
 * (those answers only decide whether the leaf is queried before drawing next frame); a node whose
 * query box reaches behind the near plane, or queried before anything is drawn, counts as visible
 * unqueried. threshold > 0: SL_AGGRESSIVE; a node is dropped only when its query counted at most
 * threshold samples, and every pixel its objects show in the oracle's image is one of them, so the
 * objects of one dropped node own at most threshold pixels of the image together. */
#include "hoq.h"
#include "culler_internal.h"

#include "accel/bvh_internal.h"
#include "scene/scene_internal.h"

#include <math.h>

#define TIGHT_MAX 16     /* most boxes of one node's query */
#define MQ_MAX 16        /* most nodes of one multiquery */

typedef struct chc_config {
    uint32_t leaf_size;
    sl_qc_backend_opts backend;
    float margin;
    uint32_t threshold;      /* samples a query may count and still be occluded */
    uint32_t assume_visible; /* frames a visible leaf is not queried again */
    bool zpass;
    bool geometry_queries;
    bool pullup_fix;
    /* chc++ */
    bool plus;
    uint32_t batch;          /* i-queue size that issues it */
    uint32_t multiquery;     /* most nodes a multiquery (1: none) */
    uint32_t vbatch;         /* v-queue queries issued while waiting */
    uint32_t tight_depth;    /* levels of tighter volumes (0: the node's box) */
    float tight_ratio;
    uint32_t seed;
} chc_config;

enum { K_V = 0, K_I = 1, K_M = 2 };

typedef struct qrec {
    uint32_t name;   /* index into names */
    uint32_t node;   /* K_V, K_I: the node; K_M: first entry in mq_nodes */
    uint32_t n;      /* K_M: nodes */
    uint32_t frame;  /* the frame it was issued in */
    uint8_t kind;
} qrec;

typedef struct ring {
    qrec *r;
    uint32_t cap, head, count;
} ring;

typedef struct heap_ent {
    float key, tie;
    uint32_t node;
} heap_ent;

typedef struct chc_state {
    sl_allocator alloc;
    sl_scene scene;
    chc_config cfg;
    const char *name;
    sl_bvh bvh;
    bool bvh_owned;
    sl_qc_backend qb;
    uint32_t object_count;
    uint32_t cap;            /* node capacity (any BVH of these objects: 2 n + 2) */
    uint32_t node_count;     /* the tree's, when the parents were computed */
    uint32_t *parent;
    uint32_t *last_visited;
    uint32_t *next_query;    /* first frame a visible leaf is queried again */
    uint32_t *invisible_for; /* consecutive frames found invisible */
    uint8_t *visible;
    uint32_t *rendered;      /* per object: the frame it was drawn in */
    sl_draw_query *names;    /* the query objects, cap of them */
    uint32_t *free_names;    /* indices into names */
    uint32_t free_count;
    ring iq, vq;             /* issued: awaited in the frame / read for the next frame */
    heap_ent *heap;
    uint32_t heap_n;
    uint32_t *ipend, ipend_n; /* chc++: unissued previously invisible nodes */
    uint32_t *vpend, vpend_n; /* chc++: unissued queries of previously visible leaves */
    uint32_t *mq_nodes, mq_n; /* the nodes of this frame's multiqueries */
    uint32_t *sort_scratch;
    uint32_t frame;
} chc_state;

typedef struct frame_ctx {
    chc_state *s;
    sl_hoq_view view;
    sl_frustum frustum;
    float eye[3];
    uint32_t width, height;
    sl_cull_stats *stats;
    uint32_t *out;
    uint32_t count;
    bool drawn_any;
    sl_status st;
    sl_error *err;
} frame_ctx;

static const char g_help_chc[] =
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n"
    "threshold=0..100000 (default 0): visibility threshold in samples (pixels): a node whose query counts at most "
    "this many is occluded; 0 is exact (conservative at resolution), more is aggressive\n"
    "assume_visible=0..100 (default 0): frames a leaf found visible is drawn without a query (conservative "
    "visibility testing)\n"
    "zpass=BOOL (default false): the culling pass is a depth pass, followed by one colour pass drawing the visible "
    "set sorted (a second draw of every visible object)\n"
    "geometry_queries=BOOL (default true): query a previously visible leaf with its own objects, drawn inside the "
    "query, instead of its box\n"
    "pullup_fix=BOOL (default true): a leaf drawn without a query (assume_visible) pulls its visibility up to the "
    "root, so that its ancestors stay previously visible (false: the book's loop, the ancestors are queried)\n"
    "margin=0.0625..4 (default 0.0625): pixels each queried box grows by (gl-stopwait's query box)\n" SL_QC_BACKEND_HELP;

static const char g_help_plus[] =
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n"
    "threshold=0..100000 (default 0): visibility threshold in samples (pixels); 0 exact, more aggressive\n"
    "assume_visible=0..100 (default 5): a leaf found visible is not queried again for this many frames; when it "
    "becomes visible, for a seeded random 0..assume_visible (spreads the queries over frames)\n"
    "seed=0..4294967295 (default 1): the seed of those random intervals\n"
    "batch=1..1024 (default 50): previously invisible nodes collected before they are issued\n"
    "multiquery=1..16 (default 16): most nodes one query tests (1: one query a node)\n"
    "vbatch=1..1024 (default 16): queries of previously visible leaves issued each time a result is waited for\n"
    "tight_depth=0..3 (default 3): levels below a node whose boxes may replace its own in its query (0: off)\n"
    "tight_ratio=1..16 (default 1.4): the node's projected area must exceed the smaller boxes' by this factor\n"
    "zpass=BOOL (default false): a depth pass, then one colour pass of the visible set sorted\n"
    "geometry_queries=BOOL (default true): previously visible leaves are queried with their own objects\n"
    "pullup_fix=BOOL (default true): a leaf drawn without a query pulls its visibility up to the root\n"
    "margin=0.0625..4 (default 0.0625): pixels each queried box grows by (gl-stopwait's query box)\n" SL_QC_BACKEND_HELP;

static sl_status configure_common(sl_opts *o, chc_config *c, bool plus, sl_cull_guarantee *g, sl_error *err)
{
    sl_status st;
    c->plus = plus;
    if ((st = sl_opts_u32(o, "leaf_size", SL_BVH_DEFAULT_LEAF_SIZE, 1, SL_BVH_MAX_LEAF_SIZE, &c->leaf_size, err)) !=
            SL_OK ||
        (st = sl_opts_u32(o, "threshold", 0, 0, 100000, &c->threshold, err)) != SL_OK ||
        (st = sl_opts_u32(o, "assume_visible", plus ? 5 : 0, 0, 100, &c->assume_visible, err)) != SL_OK ||
        (st = sl_opts_bool(o, "zpass", false, &c->zpass, err)) != SL_OK ||
        (st = sl_opts_bool(o, "geometry_queries", true, &c->geometry_queries, err)) != SL_OK ||
        (st = sl_opts_bool(o, "pullup_fix", true, &c->pullup_fix, err)) != SL_OK ||
        (st = sl_opts_float(o, "margin", 0.0625f, 0.0625f, 4.0f, &c->margin, err)) != SL_OK ||
        (st = sl_qc_backend_configure(o, &c->backend, err)) != SL_OK)
        return st;
    if (plus) {
        if ((st = sl_opts_u32(o, "seed", 1, 0, UINT32_MAX, &c->seed, err)) != SL_OK ||
            (st = sl_opts_u32(o, "batch", 50, 1, 1024, &c->batch, err)) != SL_OK ||
            (st = sl_opts_u32(o, "multiquery", MQ_MAX, 1, MQ_MAX, &c->multiquery, err)) != SL_OK ||
            (st = sl_opts_u32(o, "vbatch", 16, 1, 1024, &c->vbatch, err)) != SL_OK ||
            (st = sl_opts_u32(o, "tight_depth", 3, 0, 3, &c->tight_depth, err)) != SL_OK ||
            (st = sl_opts_float(o, "tight_ratio", 1.4f, 1.0f, 16.0f, &c->tight_ratio, err)) != SL_OK)
            return st;
    } else {
        c->batch = 1;
        c->multiquery = 1;
    }
    if (c->threshold > 0)
        *g = SL_AGGRESSIVE;
    return SL_OK;
}

static sl_status chc_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure_common(o, config, false, g, err);
}

static sl_status chcpp_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure_common(o, config, true, g, err);
}

static void chc_destroy(void *state)
{
    chc_state *s = state;
    if (!s)
        return;
    if (s->names && s->qb.be.destroy_queries)
        s->qb.be.destroy_queries(s->qb.be.user, s->names, s->cap);
    sl_qc_backend_close(&s->qb);
    if (s->bvh_owned)
        sl_bvh_destroy(s->bvh);
    size_t c = s->cap, n = s->object_count ? s->object_count : 1;
    sl_free(&s->alloc, s->parent, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->last_visited, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->next_query, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->invisible_for, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->visible, c);
    sl_free(&s->alloc, s->rendered, n * sizeof(uint32_t));
    sl_free(&s->alloc, s->names, c * sizeof(sl_draw_query));
    sl_free(&s->alloc, s->free_names, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->iq.r, c * sizeof(qrec));
    sl_free(&s->alloc, s->vq.r, c * sizeof(qrec));
    sl_free(&s->alloc, s->heap, c * sizeof(heap_ent));
    sl_free(&s->alloc, s->ipend, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->vpend, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->mq_nodes, c * sizeof(uint32_t));
    sl_free(&s->alloc, s->sort_scratch, n * sizeof(uint32_t));
    sl_free(&s->alloc, s, sizeof *s);
}

/* Parents of the current tree, and a fresh classification (every node previously invisible). */
static void reset_tree(chc_state *s)
{
    const sl_bvh_node *nodes = s->bvh->nodes;
    for (uint32_t i = 0; i < s->cap; i++) {
        s->parent[i] = SL_NONE;
        s->visible[i] = 0;
        s->last_visited[i] = 0;
        s->next_query[i] = 0;
        s->invisible_for[i] = 0;
    }
    for (uint32_t i = 0; i < s->bvh->node_slots && s->bvh->node_count; i++) {
        if (i == 1 && !sl_bvh_node_is_leaf(&nodes[0]))
            continue; /* the padding slot */
        if (!sl_bvh_node_is_leaf(&nodes[i]))
            s->parent[nodes[i].first] = s->parent[nodes[i].first + 1] = i;
    }
    s->node_count = s->bvh->node_count;
}

static sl_status chc_create_common(sl_scene scene, const void *config, const sl_cull_extras *extras,
                                   const sl_allocator *alloc, void **state, const char *name, sl_error *err)
{
    chc_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *(const chc_config *)config;
    s->name = name;
    s->object_count = sl_scene_object_count(scene);
    s->cap = 2 * s->object_count + 2;
    size_t c = s->cap, n = s->object_count ? s->object_count : 1;
    sl_status st = sl_cull_object_bvh(scene, extras, s->cfg.leaf_size, alloc, &s->bvh, &s->bvh_owned, err);
    if (st == SL_OK) {
        s->parent = sl_alloc(alloc, c * sizeof(uint32_t));
        s->last_visited = sl_alloc(alloc, c * sizeof(uint32_t));
        s->next_query = sl_alloc(alloc, c * sizeof(uint32_t));
        s->invisible_for = sl_alloc(alloc, c * sizeof(uint32_t));
        s->visible = sl_alloc(alloc, c);
        s->rendered = sl_calloc(alloc, n, sizeof(uint32_t));
        s->names = sl_calloc(alloc, c, sizeof(sl_draw_query));
        s->free_names = sl_alloc(alloc, c * sizeof(uint32_t));
        s->iq.r = sl_alloc(alloc, c * sizeof(qrec));
        s->vq.r = sl_alloc(alloc, c * sizeof(qrec));
        s->heap = sl_alloc(alloc, c * sizeof(heap_ent));
        s->ipend = sl_alloc(alloc, c * sizeof(uint32_t));
        s->vpend = sl_alloc(alloc, c * sizeof(uint32_t));
        s->mq_nodes = sl_alloc(alloc, c * sizeof(uint32_t));
        s->sort_scratch = sl_alloc(alloc, n * sizeof(uint32_t));
        if (!s->parent || !s->last_visited || !s->next_query || !s->invisible_for || !s->visible || !s->rendered ||
            !s->names || !s->free_names || !s->iq.r || !s->vq.r || !s->heap || !s->ipend || !s->vpend ||
            !s->mq_nodes || !s->sort_scratch)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for %u nodes", s->cap);
        s->iq.cap = s->vq.cap = s->cap;
    }
    if (st == SL_OK)
        st = sl_qc_backend_open(&s->qb, scene, &s->cfg.backend, extras, alloc, err);
    if (st == SL_OK) {
        st = s->qb.be.create_queries(s->qb.be.user, s->cap, s->names, err);
        if (st != SL_OK)
            memset(s->names, 0, c * sizeof(sl_draw_query));
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", name);
        chc_destroy(s);
        return st;
    }
    for (uint32_t i = 0; i < s->cap; i++)
        s->free_names[i] = s->cap - 1 - i;
    s->free_count = s->cap;
    reset_tree(s);
    *state = s;
    return SL_OK;
}

static sl_status chc_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                            const sl_allocator *alloc, void **state, sl_error *err)
{
    return chc_create_common(scene, config, extras, alloc, state, "chc", err);
}

static sl_status chcpp_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                              const sl_allocator *alloc, void **state, sl_error *err)
{
    return chc_create_common(scene, config, extras, alloc, state, "chc++", err);
}

static sl_status chc_scene_changed(void *state, sl_error *err)
{
    chc_state *s = state;
    if (!s->bvh_owned)
        return SL_OK; /* the handle's owner refits (accel.h); a new tree is noticed at the next cull */
    bool rebuilt = false;
    sl_status st = sl_bvh_refit(s->bvh, s->scene, err);
    if (st == SL_OK)
        st = sl_bvh_rebuild_if_degraded(s->bvh, s->scene, 0, &rebuilt, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", s->name);
        return st;
    }
    if (rebuilt)
        s->node_count = 0; /* the next cull starts a fresh classification */
    return SL_OK;
}

/* ---- queues ---- */

static void ring_push(ring *q, qrec r)
{
    q->r[(q->head + q->count) % q->cap] = r;
    q->count++;
}

static qrec ring_pop(ring *q)
{
    qrec r = q->r[q->head];
    q->head = (q->head + 1) % q->cap;
    q->count--;
    return r;
}

static bool heap_less(const heap_ent *a, const heap_ent *b)
{
    return a->key != b->key ? a->key < b->key : a->tie != b->tie ? a->tie < b->tie : a->node < b->node;
}

static void heap_push(chc_state *s, const float eye[3], uint32_t node)
{
    const sl_aabb *b = &s->bvh->nodes[node].box;
    heap_ent e = {sl_bvh_dist2(b, eye), sl_bvh_centre_dist2(b, eye), node};
    uint32_t i = s->heap_n++;
    while (i > 0) {
        uint32_t p = (i - 1) / 2;
        if (!heap_less(&e, &s->heap[p]))
            break;
        s->heap[i] = s->heap[p];
        i = p;
    }
    s->heap[i] = e;
}

static uint32_t heap_pop(chc_state *s)
{
    uint32_t top = s->heap[0].node;
    heap_ent e = s->heap[--s->heap_n];
    uint32_t i = 0, n = s->heap_n;
    for (;;) {
        uint32_t c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && heap_less(&s->heap[c + 1], &s->heap[c]))
            c++;
        if (!heap_less(&s->heap[c], &e))
            break;
        s->heap[i] = s->heap[c];
        i = c;
    }
    if (n)
        s->heap[i] = e;
    return top;
}

/* ---- classification ---- */

/* Visibility pulled up to the root (the loop of Fig. 4.6 with the root's missing parent checked). */
static void pull_up(chc_state *s, uint32_t n)
{
    while (n != SL_NONE && !s->visible[n]) {
        s->visible[n] = 1;
        n = s->parent[n];
    }
}

static uint64_t mix64(uint64_t x)
{
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

/* A leaf found visible in frame `frame`: the first frame it is queried again. */
static void schedule(chc_state *s, uint32_t n, uint32_t frame, bool became_visible)
{
    uint32_t skip = s->cfg.assume_visible;
    if (s->cfg.plus && became_visible && skip)
        skip = (uint32_t)(mix64(((uint64_t)s->cfg.seed << 32) ^ ((uint64_t)n << 1) ^ mix64(frame)) % (skip + 1));
    s->next_query[n] = frame + 1 + skip;
    s->invisible_for[n] = 0;
}

/* ---- drawing and querying ---- */

static void fail(frame_ctx *f, sl_status st)
{
    if (f->st == SL_OK)
        f->st = st;
}

/* The objects of leaf n in the frustum and not drawn this frame; stamps them (test_only: the
 * objects in the frustum, drawn or not, unstamped). */
static uint32_t leaf_objects(frame_ctx *f, uint32_t n, uint32_t *ids, bool test_only)
{
    chc_state *s = f->s;
    const sl_bvh_node *nd = &s->bvh->nodes[n];
    uint32_t k = 0;
    for (uint32_t i = nd->first; i < nd->first + nd->count; i++) {
        uint32_t id = s->bvh->objects[i];
        if (!test_only && s->rendered[id] == s->frame)
            continue;
        f->stats->objects_tested++;
        if (sl_frustum_test_aabb(&f->frustum, &s->bvh->object_bounds[i]) == 0)
            continue;
        if (!test_only)
            s->rendered[id] = s->frame;
        ids[k++] = id;
    }
    return k;
}

static void render_leaf(frame_ctx *f, uint32_t n)
{
    uint32_t ids[SL_BVH_MAX_LEAF_SIZE];
    uint32_t k = leaf_objects(f, n, ids, false);
    if (!k || f->st != SL_OK)
        return;
    const sl_draw_backend *be = &f->s->qb.be;
    sl_status st = be->draw_objects(be->user, ids, k, f->err);
    if (st != SL_OK) {
        fail(f, st);
        return;
    }
    f->drawn_any = true;
    memcpy(f->out + f->count, ids, k * sizeof *ids);
    f->count += k;
}

static void traverse(frame_ctx *f, uint32_t n)
{
    const sl_bvh_node *nd = &f->s->bvh->nodes[n];
    if (sl_bvh_node_is_leaf(nd)) {
        render_leaf(f, n);
    } else {
        heap_push(f->s, f->eye, nd->first);
        heap_push(f->s, f->eye, nd->first + 1);
    }
}

/* Projected area in pixels of a box (its 8 corners' rectangle, clamped to the viewport); INFINITY
 * when a corner is not in front of the eye. */
static double screen_area(const frame_ctx *f, const sl_aabb *b)
{
    const double *m = f->view.vp;
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? b->max.x : b->min.x, (k & 2) ? b->max.y : b->min.y, (k & 4) ? b->max.z : b->min.z};
        double x = m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12];
        double y = m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13];
        double w = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
        if (!(w > 0))
            return INFINITY;
        x /= w, y /= w;
        x0 = fmin(x0, x), x1 = fmax(x1, x), y0 = fmin(y0, y), y1 = fmax(y1, y);
    }
    x0 = fmax(x0, -1), y0 = fmax(y0, -1), x1 = fmin(x1, 1), y1 = fmin(y1, 1);
    if (!(x1 > x0) || !(y1 > y0))
        return 0;
    return (x1 - x0) * (y1 - y0) * 0.25 * f->width * f->height;
}

/* Tighter volumes of node n (chc++): up to `room` grown boxes into out whose union holds every
 * object of n in the frustum, and their area; false when n's own box is to be used. */
static bool tight_set(frame_ctx *f, uint32_t n, uint32_t depth, sl_aabb *out, uint32_t room, uint32_t *count,
                      double *area)
{
    chc_state *s = f->s;
    const sl_bvh_node *nd = &s->bvh->nodes[n];
    if (depth == 0)
        return false;
    uint32_t k = 0;
    double sum = 0;
    if (sl_bvh_node_is_leaf(nd)) {
        for (uint32_t i = nd->first; i < nd->first + nd->count; i++) {
            const sl_aabb *b = &s->bvh->object_bounds[i];
            if (sl_frustum_test_aabb(&f->frustum, b) == 0)
                continue; /* never drawn: its box may stay out of the query */
            if (k == room || !sl_hoq_grow_box(&f->view, b, &out[k]))
                return false;
            sum += screen_area(f, &out[k]);
            k++;
        }
    } else {
        for (uint32_t c = 0; c < 2; c++) {
            uint32_t ch = nd->first + c;
            const sl_aabb *b = &s->bvh->nodes[ch].box;
            if (sl_frustum_test_aabb(&f->frustum, b) == 0)
                continue;
            uint32_t kc;
            double ac;
            if (!tight_set(f, ch, depth - 1, out + k, room - k, &kc, &ac)) {
                if (k == room || !sl_hoq_grow_box(&f->view, b, &out[k]))
                    return false;
                ac = screen_area(f, &out[k]);
                kc = 1;
            }
            k += kc;
            sum += ac;
        }
    }
    sl_aabb g;
    if (!sl_hoq_grow_box(&f->view, &nd->box, &g))
        return false;
    if (!(screen_area(f, &g) > (double)s->cfg.tight_ratio * sum))
        return false;
    *count = k;
    *area = sum;
    return true;
}

/* The query boxes of node n into out (room >= TIGHT_MAX); 0 when it cannot be queried by boxes
 * (its query box reaches behind the near plane or holds the eye). */
static uint32_t node_boxes(frame_ctx *f, uint32_t n, sl_aabb *out)
{
    chc_state *s = f->s;
    if (!sl_hoq_grow_box(&f->view, &s->bvh->nodes[n].box, &out[0]))
        return 0;
    uint32_t k;
    double area;
    if (s->cfg.plus && s->cfg.tight_depth && tight_set(f, n, s->cfg.tight_depth, out, TIGHT_MAX, &k, &area)) {
        if (k == 0) { /* nothing of it in the frustum: one box that covers no pixel is still a query */
            sl_hoq_grow_box(&f->view, &s->bvh->nodes[n].box, &out[0]);
            return 1;
        }
        return k;
    }
    sl_hoq_grow_box(&f->view, &s->bvh->nodes[n].box, &out[0]);
    return 1;
}

/* Issue one query: over boxes (leaf_mode 0), or leaf's objects drawn inside it (1) or tested by it
 * (2, already drawn); returns the record (kind and nodes filled by the caller). */
enum { Q_BOXES = 0, Q_DRAW_LEAF = 1, Q_TEST_LEAF = 2 };

static qrec issue(frame_ctx *f, const sl_aabb *boxes, uint32_t nb, uint32_t leaf, int mode)
{
    chc_state *s = f->s;
    const sl_draw_backend *be = &s->qb.be;
    qrec r;
    memset(&r, 0, sizeof r);
    r.name = s->free_names[--s->free_count];
    r.frame = s->frame;
    sl_draw_query q = s->names[r.name];
    f->stats->queries++;
    sl_status st = be->begin_query(be->user, q, f->err);
    if (st == SL_OK) {
        if (mode == Q_DRAW_LEAF) {
            render_leaf(f, leaf);
            st = f->st;
        } else if (mode == Q_TEST_LEAF) {
            uint32_t ids[SL_BVH_MAX_LEAF_SIZE];
            uint32_t k = leaf_objects(f, leaf, ids, true);
            st = be->query_objects(be->user, ids, k, f->err);
        } else {
            st = be->query_boxes(be->user, boxes, nb, f->err);
        }
        sl_error ignored;
        sl_status st2 = be->end_query(be->user, st == SL_OK ? f->err : &ignored);
        if (st == SL_OK)
            st = st2;
    }
    if (st != SL_OK)
        fail(f, st);
    return r;
}

/* The query of a previously visible leaf n (for the next frame's classification). drawn: its
 * objects are drawn already (chc++'s v-queue). */
static void issue_v(frame_ctx *f, uint32_t n, bool drawn)
{
    chc_state *s = f->s;
    f->stats->occlusion_tests++;
    qrec r;
    if (s->cfg.geometry_queries) {
        r = issue(f, NULL, 0, n, drawn ? Q_TEST_LEAF : Q_DRAW_LEAF);
    } else {
        sl_aabb g;
        sl_hoq_grow_box(&f->view, &s->bvh->nodes[n].box, &g); /* queryable: checked at the visit */
        r = issue(f, &g, 1, n, Q_BOXES);
        if (!drawn)
            render_leaf(f, n);
    }
    r.kind = K_V;
    r.node = n;
    ring_push(&s->vq, r);
}

/* One query of a previously invisible node, awaited in this frame. */
static void issue_i(frame_ctx *f, uint32_t n)
{
    sl_aabb boxes[TIGHT_MAX];
    uint32_t nb = node_boxes(f, n, boxes);
    f->stats->occlusion_tests++;
    qrec r = issue(f, boxes, nb, SL_NONE, Q_BOXES);
    r.kind = K_I;
    r.node = n;
    ring_push(&f->s->iq, r);
}

/* chc++'s estimate that a node invisible for i frames stays invisible (a choice of this file). */
static double stay_invisible(uint32_t i) { return 1.0 - ldexp(0.5, -(int)SL_MIN(i, 30u)); }

/* chc++: issue the i-queue as multiqueries: consecutive nodes grouped while the chance that all stay
 * invisible is at least one half (each alone otherwise), at most `multiquery` nodes a query. */
static void flush_i(frame_ctx *f)
{
    chc_state *s = f->s;
    sl_aabb boxes[MQ_MAX * TIGHT_MAX];
    uint32_t i = 0;
    while (i < s->ipend_n && f->st == SL_OK) {
        uint32_t j = i + 1;
        double p = stay_invisible(s->invisible_for[s->ipend[i]]);
        while (j < s->ipend_n && j - i < s->cfg.multiquery) {
            double q = p * stay_invisible(s->invisible_for[s->ipend[j]]);
            if (q < 0.5)
                break;
            p = q;
            j++;
        }
        if (j - i == 1) {
            issue_i(f, s->ipend[i]);
        } else {
            uint32_t nb = 0;
            for (uint32_t k = i; k < j; k++)
                nb += node_boxes(f, s->ipend[k], boxes + nb);
            f->stats->occlusion_tests += j - i;
            qrec r = issue(f, boxes, nb, SL_NONE, Q_BOXES);
            r.kind = K_M;
            r.node = s->mq_n;
            r.n = j - i;
            memcpy(s->mq_nodes + s->mq_n, s->ipend + i, (j - i) * sizeof(uint32_t));
            s->mq_n += j - i;
            ring_push(&s->iq, r);
        }
        i = j;
    }
    s->ipend_n = 0;
}

/* chc++: issue up to `most` queries of the v-queue. */
static void flush_v(frame_ctx *f, uint32_t most)
{
    chc_state *s = f->s;
    uint32_t k = SL_MIN(most, s->vpend_n);
    for (uint32_t i = 0; i < k && f->st == SL_OK; i++)
        issue_v(f, s->vpend[i], true);
    memmove(s->vpend, s->vpend + k, (s->vpend_n - k) * sizeof(uint32_t));
    s->vpend_n -= k;
}

/* A result. */
static void handle(frame_ctx *f, const qrec *r, uint64_t samples)
{
    chc_state *s = f->s;
    s->free_names[s->free_count++] = r->name;
    bool vis = samples > s->cfg.threshold;
    if (r->kind == K_V) {
        if (vis) {
            pull_up(s, r->node);
            schedule(s, r->node, r->frame, false);
        } else {
            s->invisible_for[r->node]++;
        }
    } else if (r->kind == K_I) {
        if (vis) {
            pull_up(s, r->node);
            if (sl_bvh_node_is_leaf(&s->bvh->nodes[r->node]))
                schedule(s, r->node, r->frame, true);
            s->invisible_for[r->node] = 0;
            traverse(f, r->node);
        } else {
            s->invisible_for[r->node]++;
        }
    } else {
        for (uint32_t k = 0; k < r->n; k++) {
            uint32_t n = s->mq_nodes[r->node + k];
            if (vis)
                issue_i(f, n); /* split: one query a node */
            else
                s->invisible_for[n]++;
        }
    }
}

/* Read the front of a queue: poll, and with `block` wait (a stall when it was not ready). */
static bool read_front(frame_ctx *f, ring *q, bool block)
{
    chc_state *s = f->s;
    const sl_draw_backend *be = &s->qb.be;
    qrec r = q->r[q->head];
    bool ready = false;
    uint64_t samples = 0;
    sl_status st = be->poll_query(be->user, s->names[r.name], &ready, &samples, f->err);
    if (st == SL_OK && !ready) {
        if (!block)
            return false;
        f->stats->query_stalls++;
        st = sl_qc_wait(&s->qb, s->names[r.name], &samples, f->err);
    }
    if (st != SL_OK) {
        fail(f, st);
        return false;
    }
    ring_pop(q);
    handle(f, &r, samples);
    return true;
}

/* A node popped from the traversal queue (Fig. 4.5, part 2). */
static void visit(frame_ctx *f, uint32_t n)
{
    chc_state *s = f->s;
    const sl_bvh_node *nd = &s->bvh->nodes[n];
    if (sl_frustum_test_aabb(&f->frustum, &nd->box) == 0)
        return; /* keeps its last_visited: previously invisible when it comes back */
    f->stats->nodes_visited++;
    bool was = s->visible[n] && s->last_visited[n] == s->frame - 1;
    bool leaf = sl_bvh_node_is_leaf(nd);
    s->visible[n] = 0;
    s->last_visited[n] = s->frame;
    if (was && !leaf) {
        traverse(f, n);
        return;
    }
    sl_aabb g;
    bool queryable = sl_hoq_grow_box(&f->view, &nd->box, &g);
    if (was) {
        if (s->next_query[n] > s->frame) { /* assumed visible: no query */
            if (s->cfg.pullup_fix)
                pull_up(s, n);
            else
                s->visible[n] = 1;
            render_leaf(f, n);
        } else if (!queryable) {
            pull_up(s, n);
            render_leaf(f, n);
        } else if (s->cfg.plus) {
            render_leaf(f, n);
            s->vpend[s->vpend_n++] = n;
        } else {
            issue_v(f, n, false);
        }
        return;
    }
    if (!queryable || !f->drawn_any) { /* visible unqueried: the near rule, or nothing to hide it yet */
        pull_up(s, n);
        if (leaf)
            schedule(s, n, s->frame, true);
        traverse(f, n);
        return;
    }
    if (s->cfg.plus) {
        s->ipend[s->ipend_n++] = n;
        if (s->ipend_n >= s->cfg.batch)
            flush_i(f);
    } else {
        issue_i(f, n);
    }
}

static sl_status chc_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    chc_state *s = state;
    frame_ctx f;
    memset(&f, 0, sizeof f);
    f.s = s;
    f.stats = stats;
    f.out = out;
    f.err = err;
    f.frustum = view->frustum;
    f.width = view->width;
    f.height = view->height;
    f.eye[0] = view->eye.x, f.eye[1] = view->eye.y, f.eye[2] = view->eye.z;
    sl_mat4 vpf = view->view_proj;
    sl_hoq_view_set(&f.view, &vpf, &view->proj, view->width, view->height, view->eye,
                    view->projection == SL_ORTHOGRAPHIC, s->cfg.margin);
    if (s->bvh->node_count != s->node_count) { /* a new tree: start over (queries of the old one read back) */
        reset_tree(s);
    }
    double t0 = sl_now();
    sl_qc_frame_start(&s->qb);
    const sl_draw_backend *be = &s->qb.be;
    s->frame++;
    s->mq_n = 0;
    s->heap_n = 0;
    s->ipend_n = s->vpend_n = 0;
    sl_status st = be->begin_frame(be->user, vpf.m, view->width, view->height, err);
    if (st == SL_OK) {
        /* last frame's queries of previously visible leaves (their answers still in flight then) */
        while (s->vq.count && f.st == SL_OK)
            read_front(&f, &s->vq, true);
        if (s->object_count && s->bvh->node_count)
            heap_push(s, f.eye, 0);
        while (f.st == SL_OK) {
            /* part 1: the results that are there */
            while (s->iq.count && f.st == SL_OK && read_front(&f, &s->iq, false))
                ;
            while (s->vq.count && f.st == SL_OK && read_front(&f, &s->vq, false))
                ;
            if (f.st != SL_OK)
                break;
            /* part 2: the traversal */
            if (s->heap_n) {
                visit(&f, heap_pop(s));
                continue;
            }
            if (s->ipend_n) { /* chc++: nothing left to traverse, issue the i-queue */
                flush_i(&f);
                continue;
            }
            if (s->iq.count) {
                if (s->vpend_n) { /* chc++: do the v-queue's queries while the result is on its way */
                    flush_v(&f, s->cfg.vbatch);
                    continue;
                }
                read_front(&f, &s->iq, true);
                continue;
            }
            break;
        }
        if (f.st == SL_OK)
            flush_v(&f, s->vpend_n);
        /* what is ready now; the rest is read at the start of the next frame */
        while (s->vq.count && f.st == SL_OK && read_front(&f, &s->vq, false))
            ;
        st = f.st;
        if (st == SL_OK)
            sl_cull_sort_ids(out, f.count, s->sort_scratch);
        if (st == SL_OK && s->cfg.zpass && f.count) /* the colour pass: the visible set, sorted, one call */
            st = be->draw_objects(be->user, out, f.count, err);
        sl_error ignored;
        sl_status st2 = be->end_frame(be->user, st == SL_OK ? err : &ignored);
        if (st == SL_OK)
            st = st2;
    }
    if (st != SL_OK) {
        /* a failed frame: drop what is in flight, classify afresh */
        while (s->vq.count)
            s->free_names[s->free_count++] = ring_pop(&s->vq).name;
        while (s->iq.count)
            s->free_names[s->free_count++] = ring_pop(&s->iq).name;
        reset_tree(s);
        sl_error_prefix(err, "%s", s->name);
        return st;
    }
    double t1 = sl_now();
    sl_cull_phase(stats, "traverse+draw", sl_cull_ms(t0, t1));
    stats->query_wait_ms = sl_qc_wait_ms(&s->qb);
    *count = f.count;
    return SL_OK;
}

const sl_cull_method sl_cull_method_chc = {
    .name = "chc",
    .summary = "coherent hierarchical culling: occlusion queries over the object BVH interleaved with drawing, "
               "classification kept from the last frame, through a draw backend (its own CPU reference backend "
               "with a simulated clock when given none; Bittner, Wimmer, Piringer, Purgathofer 2004)",
    .options_help = g_help_chc,
    .guarantee = SL_CONSERVATIVE_AT_RESOLUTION,
    .config_size = sizeof(chc_config),
    .depth = SL_DEPTH_CLIP_Z,
    .configure = chc_configure,
    .create_with = chc_create,
    .draws = true,
    .cull = chc_cull,
    .scene_changed = chc_scene_changed,
    .destroy = chc_destroy,
};

const sl_cull_method sl_cull_method_chcpp = {
    .name = "chc++",
    .summary = "CHC++: coherent hierarchical culling with multiqueries of previously invisible nodes, batched "
               "queries of visible leaves, random re-query intervals and tighter volumes (after Mattausch, "
               "Bittner, Wimmer 2008; docs/query-culling.md)",
    .options_help = g_help_plus,
    .guarantee = SL_CONSERVATIVE_AT_RESOLUTION,
    .config_size = sizeof(chc_config),
    .depth = SL_DEPTH_CLIP_Z,
    .configure = chcpp_configure,
    .create_with = chcpp_create,
    .draws = true,
    .cull = chc_cull,
    .scene_changed = chc_scene_changed,
    .destroy = chc_destroy,
};

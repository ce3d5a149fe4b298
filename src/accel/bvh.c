/* Binned-SAH bounding volume hierarchy over object boxes.
 *
 * Build: I. Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies", IEEE Symposium
 * on Interactive Ray Tracing 2007, section 3: objects are binned by centroid on the axis of largest
 * centroid extent, the SAH is evaluated at every bin boundary with one sweep from each side, and
 * the objects are partitioned in place. Leaves hold 1..max_leaf_size objects.
 *
 * Determinism: every split depends only on the set and the order of the objects of its node, and the
 * in-place partition is a fixed sequence of swaps, so the tree is a pure function of the input.
 * Parallel build: the top of the tree is built level by level, the nodes of a level split in
 * parallel, down to nodes of at most TASK_SIZE objects; each such node becomes a task that builds
 * its subtree into its own reserved slot range, tasks run in parallel, and the ranges are then
 * packed in task order. The decomposition and the slot order depend only on the input (never on
 * the thread count), so any thread count produces a bit-identical tree.
 *
 * Traversal: depth-first with an explicit stack of SL_BVH_MAX_DEPTH entries on the caller's stack;
 * the builder guarantees the depth bound (median splits near the limit), so no traversal allocates
 * or shares mutable state.
 */
#include "bvh_internal.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

/* Objects per task of the parallel build (a constant: the layout must not depend on threads). */
#define TASK_SIZE 4096u
/* Below this many objects the build never starts threads. */
#define PARALLEL_MIN 65536u
#define MAX_THREADS 16u
/* Nodes of at most this many objects get an exact sweep instead of binning. */
#define SMALL_NODE 16u

/* A build reference: an object's box and id, 32 bytes, permuted in place into leaf order. */
typedef struct bref {
    float min[3];
    uint32_t id;
    float max[3];
    uint32_t pad;
} bref;

/* The objects of a node under construction: refs[begin .. begin+count), their box and the bounds
 * of their doubled centroids (min + max, which needs no multiply and keeps the same order). */
typedef struct span {
    uint32_t begin, count;
    sl_aabb box;
    float cmin[3], cmax[3];
} span;

typedef struct tally {
    uint32_t leaves, internals, depth;
} tally;

typedef struct builder {
    bref *refs;
    sl_bvh_node *nodes;
    uint32_t max_leaf, bins;
} builder;

typedef struct task {
    uint32_t node, depth;       /* the task's root slot (in the top part) and its depth */
    uint32_t base, used;        /* reserved slot range start, slots used */
    span s;
    tally t;
} task;

/* ---- small helpers ---- */

static double half_area(const sl_aabb *b)
{
    double dx = (double)b->max.x - b->min.x, dy = (double)b->max.y - b->min.y, dz = (double)b->max.z - b->min.z;
    return dx * dy + dy * dz + dz * dx;
}

static inline void box_add_ref(sl_aabb *b, const bref *r)
{
    b->min.x = SL_MIN(b->min.x, r->min[0]);
    b->min.y = SL_MIN(b->min.y, r->min[1]);
    b->min.z = SL_MIN(b->min.z, r->min[2]);
    b->max.x = SL_MAX(b->max.x, r->max[0]);
    b->max.y = SL_MAX(b->max.y, r->max[1]);
    b->max.z = SL_MAX(b->max.z, r->max[2]);
}

static inline void box_add_box(sl_aabb *b, const sl_aabb *o)
{
    b->min.x = SL_MIN(b->min.x, o->min.x);
    b->min.y = SL_MIN(b->min.y, o->min.y);
    b->min.z = SL_MIN(b->min.z, o->min.z);
    b->max.x = SL_MAX(b->max.x, o->max.x);
    b->max.y = SL_MAX(b->max.y, o->max.y);
    b->max.z = SL_MAX(b->max.z, o->max.z);
}

static inline void cent_add(float cmin[3], float cmax[3], const bref *r)
{
    for (int k = 0; k < 3; k++) {
        float c = r->min[k] + r->max[k];
        cmin[k] = SL_MIN(cmin[k], c);
        cmax[k] = SL_MAX(cmax[k], c);
    }
}

static void span_init(span *s, uint32_t begin, uint32_t count)
{
    s->begin = begin;
    s->count = count;
    s->box = sl_aabb_empty();
    for (int k = 0; k < 3; k++) {
        s->cmin[k] = INFINITY;
        s->cmax[k] = -INFINITY;
    }
}

static void span_scan(span *s, const bref *refs)
{
    for (uint32_t i = s->begin; i < s->begin + s->count; i++) {
        box_add_ref(&s->box, &refs[i]);
        cent_add(s->cmin, s->cmax, &refs[i]);
    }
}

/* ceil(log2(ceil(n / m))): the levels that median splits need below a node of n objects. */
static uint32_t levels_needed(uint32_t n, uint32_t m)
{
    uint32_t k = (n + m - 1) / m;
    return k <= 1 ? 0 : 32u - (uint32_t)__builtin_clz(k - 1);
}

/* Validate one input box: finite, not inverted, within +-SL_BVH_MAX_COORD. */
static sl_status check_box(const sl_aabb *b, uint32_t id, const char *what, sl_error *err)
{
    const float *lo = &b->min.x, *hi = &b->max.x;
    if (!sl_finite3(lo) || !sl_finite3(hi))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s %u: bounds are not finite (min %g %g %g, max %g %g %g)", what, id, (double)lo[0],
                       (double)lo[1], (double)lo[2], (double)hi[0], (double)hi[1], (double)hi[2]);
    for (int k = 0; k < 3; k++) {
        if (lo[k] > hi[k])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s %u: bounds are inverted on axis %c (min %g > max %g)",
                           what, id, "xyz"[k], (double)lo[k], (double)hi[k]);
        if (fabsf(lo[k]) > SL_BVH_MAX_COORD || fabsf(hi[k]) > SL_BVH_MAX_COORD)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s %u: bounds exceed +-1e30 on axis %c", what, id,
                           "xyz"[k]);
    }
    return SL_OK;
}

/* ---- splitting ---- */

static inline uint32_t bin_of(const bref *r, int axis, float cmin, float scale, uint32_t bins)
{
    float f = (r->min[axis] + r->max[axis] - cmin) * scale;
    /* f is finite and >= 0 (cmin is the minimum of the same expression); clamp before converting */
    if (!(f > 0.0f))
        return 0;
    return f >= (float)(bins - 1) ? bins - 1 : (uint32_t)f;
}

static int cmp_ref_axis(const void *pa, const void *pb, void *ctx)
{
    const bref *a = pa, *b = pb;
    int axis = *(const int *)ctx;
    float ka = a->min[axis] + a->max[axis], kb = b->min[axis] + b->max[axis];
    if (ka != kb)
        return ka < kb ? -1 : 1;
    return (a->id > b->id) - (a->id < b->id);
}

/* Object-median split on the axis of largest centroid extent. Sorting by (centroid, id) is a total
 * order, so the result does not depend on the sort algorithm. */
static void median_split(const builder *b, const span *s, int axis, span *l, span *r)
{
    qsort_r(b->refs + s->begin, s->count, sizeof(bref), cmp_ref_axis, &axis);
    uint32_t nl = s->count / 2;
    span_init(l, s->begin, nl);
    span_init(r, s->begin + nl, s->count - nl);
    span_scan(l, b->refs);
    span_scan(r, b->refs);
}

/* Exact SAH for a small node: sort its objects by (centroid, id) on the axis, evaluate every split
 * position. Cheaper than binning below a few dozen objects, and at least as good. */
static bool split_small(const builder *b, const span *s, int axis, span *l, span *r)
{
    const uint32_t n = s->count, m = b->max_leaf;
    bref *a = b->refs + s->begin;
    for (uint32_t i = 1; i < n; i++) {
        bref x = a[i];
        uint32_t j = i;
        while (j > 0 && cmp_ref_axis(&a[j - 1], &x, &axis) > 0) {
            a[j] = a[j - 1];
            j--;
        }
        a[j] = x;
    }
    double rarea[SMALL_NODE];
    sl_aabb acc = sl_aabb_empty();
    for (uint32_t k = n - 1; k >= 1; k--) {
        box_add_ref(&acc, &a[k]);
        rarea[k] = half_area(&acc);
    }
    double best = INFINITY;
    uint32_t best_k = 0, best_imb = UINT32_MAX;
    acc = sl_aabb_empty();
    for (uint32_t k = 0; k + 1 < n; k++) {
        box_add_ref(&acc, &a[k]);
        uint32_t nl = k + 1, nr = n - nl;
        double cost = half_area(&acc) * nl + rarea[k + 1] * nr;
        uint32_t imb = nl > nr ? nl - nr : nr - nl;
        if (cost < best || (cost == best && imb < best_imb)) {
            best = cost;
            best_k = k;
            best_imb = imb;
        }
    }
    double area = half_area(&s->box);
    if (n <= m && area * n <= area + best)
        return false;
    span_init(l, s->begin, best_k + 1);
    span_init(r, s->begin + best_k + 1, n - best_k - 1);
    span_scan(l, b->refs);
    span_scan(r, b->refs);
    return true;
}

/* Decide the fate of span s at `depth` (root = 1): false for a leaf; true with its two non-empty
 * children in l and r (refs partitioned in place). */
static bool split_span(const builder *b, const span *s, uint32_t depth, span *l, span *r)
{
    const uint32_t n = s->count, m = b->max_leaf, bins = b->bins;
    if (n <= 1)
        return false;
    int axis = 0;
    float ext[3];
    for (int k = 0; k < 3; k++)
        ext[k] = s->cmax[k] - s->cmin[k];
    if (ext[1] > ext[axis])
        axis = 1;
    if (ext[2] > ext[axis])
        axis = 2;
    /* near the depth limit, median splits keep the depth within SL_BVH_MAX_DEPTH (each halves n) */
    if (depth + levels_needed(n, m) >= SL_BVH_MAX_DEPTH) {
        if (n <= m)
            return false;
        median_split(b, s, axis, l, r);
        return true;
    }
    float scale = (float)bins * 0.99999f / ext[axis];
    if (!(ext[axis] > 0.0f) || !isfinite(scale)) {
        /* centroids indistinguishable: SAH cannot separate them */
        if (n <= m)
            return false;
        median_split(b, s, axis, l, r);
        return true;
    }
    if (n <= SMALL_NODE)
        return split_small(b, s, axis, l, r);
    const float cmin = s->cmin[axis];

    uint32_t count[SL_BVH_MAX_BINS] = {0};
    sl_aabb box[SL_BVH_MAX_BINS];
    for (uint32_t k = 0; k < bins; k++)
        box[k] = sl_aabb_empty();
    const bref *refs = b->refs + s->begin;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = bin_of(&refs[i], axis, cmin, scale, bins);
        count[k]++;
        box_add_ref(&box[k], &refs[i]);
    }

    /* sweep from the right: area and count of bins k..bins-1 */
    double rarea[SL_BVH_MAX_BINS];
    uint32_t rcount[SL_BVH_MAX_BINS];
    sl_aabb acc = sl_aabb_empty();
    uint32_t cnt = 0;
    for (uint32_t k = bins - 1; k >= 1; k--) {
        box_add_box(&acc, &box[k]);
        cnt += count[k];
        rcount[k] = cnt;
        rarea[k] = cnt ? half_area(&acc) : 0.0;
    }
    /* sweep from the left; ties go to the more balanced split */
    double best = INFINITY;
    uint32_t best_k = UINT32_MAX, best_imb = UINT32_MAX;
    acc = sl_aabb_empty();
    cnt = 0;
    for (uint32_t k = 0; k + 1 < bins; k++) {
        box_add_box(&acc, &box[k]);
        cnt += count[k];
        if (cnt == 0 || rcount[k + 1] == 0)
            continue;
        double cost = half_area(&acc) * cnt + rarea[k + 1] * rcount[k + 1];
        uint32_t imb = cnt > rcount[k + 1] ? cnt - rcount[k + 1] : rcount[k + 1] - cnt;
        if (cost < best || (cost == best && imb < best_imb)) {
            best = cost;
            best_k = k;
            best_imb = imb;
        }
    }
    if (best_k == UINT32_MAX) {
        /* unreachable with a positive extent (the extreme bins are never empty); stay safe */
        if (n <= m)
            return false;
        median_split(b, s, axis, l, r);
        return true;
    }
    /* SAH with equal node and object test costs: leaf cost A*n against A + best */
    double area = half_area(&s->box);
    if (n <= m && area * n <= area + best)
        return false;

    /* partition in place; child centroid bounds are gathered as each ref is classified once */
    span_init(l, s->begin, 0);
    span_init(r, s->begin, 0);
    for (uint32_t k = 0; k <= best_k; k++)
        box_add_box(&l->box, &box[k]);
    for (uint32_t k = best_k + 1; k < bins; k++)
        box_add_box(&r->box, &box[k]);
    bref *a = b->refs;
    uint32_t i = s->begin, j = s->begin + n;
    for (;;) {
        while (i < j && bin_of(&a[i], axis, cmin, scale, bins) <= best_k) {
            cent_add(l->cmin, l->cmax, &a[i]);
            i++;
        }
        while (i < j && bin_of(&a[j - 1], axis, cmin, scale, bins) > best_k) {
            cent_add(r->cmin, r->cmax, &a[j - 1]);
            j--;
        }
        if (i >= j)
            break;
        bref t = a[i];
        a[i] = a[j - 1];
        a[j - 1] = t;
        cent_add(l->cmin, l->cmax, &a[i]);
        cent_add(r->cmin, r->cmax, &a[j - 1]);
        i++;
        j--;
    }
    l->count = i - s->begin;
    r->begin = i;
    r->count = n - l->count;
    return true;
}

/* ---- recursive construction ---- */

static void build_rec(const builder *b, uint32_t ni, const span *s, uint32_t depth, uint32_t *cursor, tally *t)
{
    sl_bvh_node *node = &b->nodes[ni];
    node->box = s->box;
    span l, r;
    if (!split_span(b, s, depth, &l, &r)) {
        node->first = s->begin;
        node->count = s->count;
        t->leaves++;
        t->depth = SL_MAX(t->depth, depth);
        return;
    }
    uint32_t c = *cursor;
    *cursor += 2;
    node->first = c;
    node->count = 0;
    t->internals++;
    build_rec(b, c, &l, depth + 1, cursor, t);
    build_rec(b, c + 1, &r, depth + 1, cursor, t);
}

static void run_task(const builder *b, task *tk)
{
    uint32_t cursor = tk->base;
    build_rec(b, tk->node, &tk->s, tk->depth, &cursor, &tk->t);
    tk->used = cursor - tk->base;
}

/* ---- a small parallel for: jobs 0..count-1 pulled from an atomic counter ---- */

typedef struct pfor {
    void (*fn)(void *ctx, uint32_t i);
    void *ctx;
    uint32_t count;
    atomic_uint next;
} pfor;

static void *pfor_worker(void *arg)
{
    pfor *p = arg;
    for (;;) {
        uint32_t i = atomic_fetch_add(&p->next, 1);
        if (i >= p->count)
            return NULL;
        p->fn(p->ctx, i);
    }
}

/* Run fn(ctx, i) for every i < count on up to `threads` threads (the caller is one of them). Every
 * job writes only its own outputs, so the result does not depend on which thread ran what. */
static void parallel_for(uint32_t threads, uint32_t count, void (*fn)(void *, uint32_t), void *ctx)
{
    pfor p;
    p.fn = fn;
    p.ctx = ctx;
    p.count = count;
    atomic_init(&p.next, 0);
    pthread_t tid[MAX_THREADS];
    uint32_t started = 0;
    for (uint32_t i = 1; i < SL_MIN(threads, count); i++) {
        if (pthread_create(&tid[started], NULL, pfor_worker, &p) != 0)
            break; /* fewer threads: the caller does the rest, the result is the same */
        started++;
    }
    pfor_worker(&p);
    for (uint32_t i = 0; i < started; i++)
        pthread_join(tid[i], NULL);
}

/* The top of the tree is built level by level: every node of a level is split in parallel (each
 * touches only its own range of refs), then the child pairs get their slots in level order. Nodes
 * of at most TASK_SIZE objects become tasks. The slot order is fixed by the input alone. */
typedef struct top_item {
    uint32_t node, depth;
    bool split;
    span s, l, r;
} top_item;

typedef struct job_ctx {
    const builder *b;
    top_item *items;
    task *tasks;
} job_ctx;

static void top_job(void *ctx, uint32_t i)
{
    job_ctx *c = ctx;
    top_item *it = &c->items[i];
    it->split = split_span(c->b, &it->s, it->depth, &it->l, &it->r);
}

static void task_job(void *ctx, uint32_t i)
{
    job_ctx *c = ctx;
    run_task(c->b, &c->tasks[i]);
}

static bool push_task(const sl_allocator *al, sl_array *tasks, uint32_t node, uint32_t depth, const span *s)
{
    task tk = {node, depth, 0, 0, *s, {0, 0, 0}};
    return sl_array_push(al, tasks, sizeof tk, &tk, 1) != NULL;
}

/* Build the top part from the root span; false when out of memory. */
static bool build_top(const builder *b, const sl_allocator *al, const span *root, uint32_t threads, uint32_t *cursor,
                      tally *t, sl_array *tasks)
{
    if (root->count <= TASK_SIZE)
        return push_task(al, tasks, 0, 1, root);
    sl_array level = {0}, next = {0};
    top_item first = {0, 1, false, *root, *root, *root};
    bool ok = sl_array_push(al, &level, sizeof first, &first, 1) != NULL;
    while (ok && level.count) {
        job_ctx ctx = {b, level.data, NULL};
        parallel_for(threads, (uint32_t)level.count, top_job, &ctx);
        next.count = 0;
        for (size_t i = 0; ok && i < level.count; i++) {
            const top_item *it = &SL_AT(level, top_item, i);
            if (!it->split) { /* only for tiny nodes; kept for safety: a task makes it a leaf */
                ok = push_task(al, tasks, it->node, it->depth, &it->s);
                continue;
            }
            sl_bvh_node *node = &b->nodes[it->node];
            node->box = it->s.box;
            node->first = *cursor;
            node->count = 0;
            *cursor += 2;
            t->internals++;
            const span *kids[2] = {&it->l, &it->r};
            for (uint32_t k = 0; ok && k < 2; k++) {
                if (kids[k]->count <= TASK_SIZE) {
                    ok = push_task(al, tasks, node->first + k, it->depth + 1, kids[k]);
                } else {
                    top_item child = {node->first + k, it->depth + 1, false, *kids[k], *kids[k], *kids[k]};
                    ok = sl_array_push(al, &next, sizeof child, &child, 1) != NULL;
                }
            }
        }
        sl_array tmp = level;
        level = next;
        next = tmp;
    }
    sl_array_free(al, &level, sizeof(top_item));
    sl_array_free(al, &next, sizeof(top_item));
    return ok;
}

static uint32_t resolve_threads(uint32_t requested)
{
    if (requested)
        return SL_MIN(requested, MAX_THREADS);
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (uint32_t)SL_MIN((unsigned long)n, MAX_THREADS);
}

/* ---- tree arrays (shared by build, rebuild, destroy) ---- */

typedef struct tree {
    sl_bvh_node *nodes;
    uint32_t node_slots, node_count, leaf_count, depth;
    uint32_t *objects;
    sl_aabb *object_bounds;
    uint32_t object_count;
} tree;

static void tree_free(const sl_allocator *a, tree *t)
{
    sl_free(a, t->nodes, (size_t)t->node_slots * sizeof(sl_bvh_node));
    sl_free(a, t->objects, (size_t)t->object_count * sizeof(uint32_t));
    sl_free(a, t->object_bounds, (size_t)t->object_count * sizeof(sl_aabb));
    memset(t, 0, sizeof *t);
}

static double tree_sah(const sl_bvh_node *nodes, uint32_t slots)
{
    if (slots == 0)
        return 0.0;
    double root = half_area(&nodes[0].box), sum = 0.0;
    for (uint32_t i = 0; i < slots; i++) {
        if (i == 1 && nodes[0].count == 0)
            continue; /* padding slot */
        const sl_bvh_node *n = &nodes[i];
        double w = root > 0.0 ? half_area(&n->box) / root : 1.0;
        sum += n->count ? w * n->count : w;
    }
    return sum;
}

/* Build the arrays of a tree over n validated boxes. */
static sl_status tree_build(const sl_allocator *al, const sl_aabb *boxes, uint32_t n, uint32_t max_leaf,
                            uint32_t bins, uint32_t threads, tree *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (n == 0)
        return SL_OK;
    if (n > UINT32_MAX / 2 - 1)
        return sl_fail(err, SL_ERROR_LIMIT, "bvh: %u objects exceed the limit of %u", n, UINT32_MAX / 2 - 1);
    const size_t cap = 2 * (size_t)n; /* exact worst case: root, padding slot and 2 per internal node */
    bref *refs = sl_alloc_aligned(al, (size_t)n * sizeof(bref), 64);
    sl_bvh_node *nodes = sl_alloc_aligned(al, cap * sizeof(sl_bvh_node), 64);
    sl_array tasks = {0};
    if (!refs || !nodes) {
        sl_free(al, refs, (size_t)n * sizeof(bref));
        sl_free(al, nodes, cap * sizeof(sl_bvh_node));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bvh: out of memory for %u objects", n);
    }
    span root;
    span_init(&root, 0, n);
    for (uint32_t i = 0; i < n; i++) {
        const sl_aabb *bx = &boxes[i];
        refs[i] = (bref){{bx->min.x, bx->min.y, bx->min.z}, i, {bx->max.x, bx->max.y, bx->max.z}, 0};
        box_add_ref(&root.box, &refs[i]);
        cent_add(root.cmin, root.cmax, &refs[i]);
    }
    builder b = {refs, nodes, max_leaf, bins};
    /* slot 1 is the padding slot: pairs start at even slots */
    nodes[1] = (sl_bvh_node){sl_aabb_empty(), 0, 0};
    uint32_t cursor = 2;
    tally top = {0, 0, 0};
    threads = resolve_threads(threads);
    if (n < PARALLEL_MIN)
        threads = 1;
    if (!build_top(&b, al, &root, threads, &cursor, &top, &tasks)) {
        sl_free(al, refs, (size_t)n * sizeof(bref));
        sl_free(al, nodes, cap * sizeof(sl_bvh_node));
        sl_array_free(al, &tasks, sizeof(task));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bvh: out of memory");
    }
    /* reserve each task 2*count - 2 slots (its nodes below its root), then build them all */
    task *tk = tasks.data;
    uint32_t ntasks = (uint32_t)tasks.count, base = cursor;
    for (uint32_t i = 0; i < ntasks; i++) {
        tk[i].base = base;
        base += 2 * tk[i].s.count - 2;
    }
    job_ctx ctx = {&b, NULL, tk};
    parallel_for(threads, ntasks, task_job, &ctx);

    /* pack the task ranges in task order and shift the child indices that point into them */
    uint32_t dst = cursor, leaves = top.leaves, internals = top.internals, depth = top.depth;
    for (uint32_t i = 0; i < ntasks; i++) {
        uint32_t shift = tk[i].base - dst;
        if (shift) {
            memmove(nodes + dst, nodes + tk[i].base, (size_t)tk[i].used * sizeof(sl_bvh_node));
            for (uint32_t j = dst; j < dst + tk[i].used; j++)
                if (nodes[j].count == 0)
                    nodes[j].first -= shift;
            if (nodes[tk[i].node].count == 0)
                nodes[tk[i].node].first -= shift;
        }
        dst += tk[i].used;
        leaves += tk[i].t.leaves;
        internals += tk[i].t.internals;
        depth = SL_MAX(depth, tk[i].t.depth);
    }
    sl_array_free(al, &tasks, sizeof(task));
    uint32_t slots = nodes[0].count ? 1 : dst;

    out->node_slots = slots;
    out->node_count = leaves + internals;
    out->leaf_count = leaves;
    out->depth = depth;
    out->object_count = n;
    out->nodes = sl_alloc_aligned(al, (size_t)slots * sizeof(sl_bvh_node), 64);
    out->objects = sl_alloc(al, (size_t)n * sizeof(uint32_t));
    out->object_bounds = sl_alloc(al, (size_t)n * sizeof(sl_aabb));
    if (!out->nodes || !out->objects || !out->object_bounds) {
        sl_free(al, refs, (size_t)n * sizeof(bref));
        sl_free(al, nodes, cap * sizeof(sl_bvh_node));
        tree_free(al, out);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bvh: out of memory for %u objects", n);
    }
    memcpy(out->nodes, nodes, (size_t)slots * sizeof(sl_bvh_node));
    for (uint32_t i = 0; i < n; i++) {
        out->objects[i] = refs[i].id;
        out->object_bounds[i] = boxes[refs[i].id];
    }
    sl_free(al, refs, (size_t)n * sizeof(bref));
    sl_free(al, nodes, cap * sizeof(sl_bvh_node));
    return SL_OK;
}

/* ---- public: lifetime ---- */

static sl_status resolve_options(const sl_bvh_options *o, uint32_t *max_leaf, uint32_t *bins, uint32_t *threads,
                                 sl_error *err)
{
    sl_bvh_options d = {0};
    if (!o)
        o = &d;
    *max_leaf = o->max_leaf_size ? o->max_leaf_size : SL_BVH_DEFAULT_LEAF_SIZE;
    *bins = o->bin_count ? o->bin_count : SL_BVH_DEFAULT_BINS;
    *threads = o->threads;
    if (*max_leaf > SL_BVH_MAX_LEAF_SIZE)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh: max_leaf_size %u is not in 1..%d", *max_leaf,
                       SL_BVH_MAX_LEAF_SIZE);
    if (*bins < 2 || *bins > SL_BVH_MAX_BINS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh: bin_count %u is not in 2..%d", *bins, SL_BVH_MAX_BINS);
    return SL_OK;
}

static sl_status validate_boxes(const sl_aabb *boxes, uint32_t n, sl_error *err)
{
    if (n && !boxes)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh: %u boxes but the array is NULL", n);
    for (uint32_t i = 0; i < n; i++) {
        sl_status st = check_box(&boxes[i], i, "object", err);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

static void adopt(sl_bvh bvh, tree *t)
{
    bvh->nodes = t->nodes;
    bvh->node_slots = t->node_slots;
    bvh->node_count = t->node_count;
    bvh->leaf_count = t->leaf_count;
    bvh->depth = t->depth;
    bvh->objects = t->objects;
    bvh->object_bounds = t->object_bounds;
    bvh->object_count = t->object_count;
    bvh->build_sah = bvh->sah = tree_sah(bvh->nodes, bvh->node_slots);
}

static tree tree_of(sl_bvh bvh)
{
    tree t = {bvh->nodes,   bvh->node_slots, bvh->node_count,    bvh->leaf_count,
              bvh->depth,   bvh->objects,    bvh->object_bounds, bvh->object_count};
    return t;
}

static sl_status create(const sl_allocator *al, const sl_aabb *boxes, uint32_t n, const sl_bvh_options *o,
                        sl_bvh *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh: out is NULL");
    *out = NULL;
    uint32_t max_leaf, bins, threads;
    sl_status st = resolve_options(o, &max_leaf, &bins, &threads, err);
    if (st == SL_OK)
        st = validate_boxes(boxes, n, err);
    if (st != SL_OK)
        return st;
    al = sl_alloc_or_default(al);
    sl_bvh bvh = sl_calloc(al, 1, sizeof *bvh);
    if (!bvh)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bvh: out of memory");
    bvh->alloc = *al;
    bvh->max_leaf_size = max_leaf;
    bvh->bin_count = bins;
    bvh->threads = threads;
    double t0 = sl_now();
    tree t;
    st = tree_build(&bvh->alloc, boxes, n, max_leaf, bins, threads, &t, err);
    if (st != SL_OK) {
        sl_free(al, bvh, sizeof *bvh);
        return st;
    }
    adopt(bvh, &t);
    bvh->build_seconds = sl_now() - t0;
    *out = bvh;
    return SL_OK;
}

sl_status sl_bvh_build(sl_scene scene, const sl_bvh_options *options, sl_bvh *out, sl_error *err)
{
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh: scene is NULL");
    const sl_allocator *al = options && options->alloc ? options->alloc : &scene->alloc;
    return create(al, sl_scene_object_bounds_array(scene), sl_scene_object_count(scene), options, out, err);
}

sl_status sl_bvh_build_boxes(const sl_aabb *boxes, uint32_t count, const sl_bvh_options *options, sl_bvh *out,
                             sl_error *err)
{
    return create(options ? options->alloc : NULL, boxes, count, options, out, err);
}

void sl_bvh_destroy(sl_bvh bvh)
{
    if (!bvh)
        return;
    sl_allocator al = bvh->alloc;
    tree t = tree_of(bvh);
    tree_free(&al, &t);
    sl_free(&al, bvh, sizeof *bvh);
}

/* ---- public: stats ---- */

void sl_bvh_get_stats(sl_bvh bvh, sl_bvh_stats *out)
{
    memset(out, 0, sizeof *out);
    if (!bvh)
        return;
    out->object_count = bvh->object_count;
    out->node_count = bvh->node_count;
    out->leaf_count = bvh->leaf_count;
    out->depth = bvh->depth;
    out->max_leaf_size = bvh->max_leaf_size;
    out->bin_count = bvh->bin_count;
    out->sah_cost = bvh->sah;
    out->build_sah_cost = bvh->build_sah;
    out->build_seconds = bvh->build_seconds;
    out->memory_bytes = sizeof *bvh + (size_t)bvh->node_slots * sizeof(sl_bvh_node) +
                        (size_t)bvh->object_count * (sizeof(uint32_t) + sizeof(sl_aabb));
}

uint32_t sl_bvh_object_count(sl_bvh bvh) { return bvh ? bvh->object_count : 0; }

sl_aabb sl_bvh_bounds(sl_bvh bvh) { return bvh && bvh->node_slots ? bvh->nodes[0].box : sl_aabb_empty(); }

/* ---- public: refit and rebuild ---- */

sl_status sl_bvh_refit_boxes(sl_bvh bvh, const sl_aabb *boxes, uint32_t count, sl_error *err)
{
    if (!bvh)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh refit: bvh is NULL");
    if (count != bvh->object_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "bvh refit: %u objects given but the tree holds %u (rebuild instead)", count,
                       bvh->object_count);
    if (count && !boxes)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh refit: boxes is NULL");
    /* validate everything first so that a failure leaves the tree untouched */
    for (uint32_t i = 0; i < count; i++) {
        sl_status st = check_box(&boxes[i], i, "bvh refit: object", err);
        if (st != SL_OK)
            return st;
    }
    for (uint32_t i = 0; i < count; i++)
        bvh->object_bounds[i] = boxes[bvh->objects[i]];
    /* children always sit at higher slots than their parent: one reverse sweep is bottom-up */
    sl_bvh_node *nodes = bvh->nodes;
    for (uint32_t i = bvh->node_slots; i-- > 0;) {
        if (i == 1 && nodes[0].count == 0)
            continue;
        sl_bvh_node *n = &nodes[i];
        sl_aabb b = sl_aabb_empty();
        if (n->count) {
            for (uint32_t k = n->first; k < n->first + n->count; k++)
                box_add_box(&b, &bvh->object_bounds[k]);
        } else {
            b = nodes[n->first].box;
            box_add_box(&b, &nodes[n->first + 1].box);
        }
        n->box = b;
    }
    bvh->sah = tree_sah(nodes, bvh->node_slots);
    return SL_OK;
}

sl_status sl_bvh_refit(sl_bvh bvh, sl_scene scene, sl_error *err)
{
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh refit: scene is NULL");
    return sl_bvh_refit_boxes(bvh, sl_scene_object_bounds_array(scene), sl_scene_object_count(scene), err);
}

sl_status sl_bvh_rebuild_if_degraded(sl_bvh bvh, sl_scene scene, double max_ratio, bool *rebuilt, sl_error *err)
{
    if (rebuilt)
        *rebuilt = false;
    if (!bvh || !scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "bvh rebuild: NULL argument");
    if (!(max_ratio > 0.0))
        max_ratio = 1.5;
    uint32_t n = sl_scene_object_count(scene);
    if (n == bvh->object_count && !(bvh->sah > max_ratio * bvh->build_sah))
        return SL_OK;
    const sl_aabb *boxes = sl_scene_object_bounds_array(scene);
    sl_status st = validate_boxes(boxes, n, err);
    if (st != SL_OK)
        return st;
    double t0 = sl_now();
    tree t;
    st = tree_build(&bvh->alloc, boxes, n, bvh->max_leaf_size, bvh->bin_count, bvh->threads, &t, err);
    if (st != SL_OK)
        return st;
    tree old = tree_of(bvh);
    tree_free(&bvh->alloc, &old);
    adopt(bvh, &t);
    bvh->build_seconds = sl_now() - t0;
    if (rebuilt)
        *rebuilt = true;
    return SL_OK;
}

/* ---- public: traversal and queries ---- */

uint32_t sl_bvh_traverse(sl_bvh bvh, sl_vec3 eye, sl_bvh_node_fn node_fn, sl_bvh_object_fn object_fn, void *user)
{
    if (!bvh || bvh->node_slots == 0)
        return 0;
    const float e[3] = {eye.x, eye.y, eye.z};
    const sl_bvh_node *nodes = bvh->nodes;
    uint32_t stack[SL_BVH_MAX_DEPTH], sp = 0, ni = 0, reported = 0;
    for (;;) {
        const sl_bvh_node *n = &nodes[ni];
        if (!node_fn || node_fn(user, ni, &n->box)) {
            if (n->count == 0) {
                /* descend into the nearer child, keep the farther one for later */
                bool rf = sl_bvh_right_first(nodes, n, e);
                stack[sp++] = n->first + !rf;
                ni = n->first + rf;
                continue;
            }
            for (uint32_t k = n->first; k < n->first + n->count; k++) {
                reported++;
                if (object_fn && !object_fn(user, bvh->objects[k], &bvh->object_bounds[k]))
                    return reported;
            }
        }
        if (sp == 0)
            return reported;
        ni = stack[--sp];
    }
}

uint32_t sl_bvh_query_aabb(sl_bvh bvh, const sl_aabb *box, uint32_t *out, uint32_t capacity)
{
    if (!bvh || !box || bvh->node_slots == 0 || !sl_bvh_overlap(&bvh->nodes[0].box, box))
        return 0;
    const sl_bvh_node *nodes = bvh->nodes;
    uint32_t stack[SL_BVH_MAX_DEPTH], sp = 0, ni = 0, total = 0;
    for (;;) {
        const sl_bvh_node *n = &nodes[ni];
        if (n->count) {
            for (uint32_t k = n->first; k < n->first + n->count; k++) {
                if (sl_bvh_overlap(&bvh->object_bounds[k], box)) {
                    if (total < capacity)
                        out[total] = bvh->objects[k];
                    total++;
                }
            }
        } else {
            /* children are tested before being pushed, so the stack holds only overlapping nodes */
            bool l = sl_bvh_overlap(&nodes[n->first].box, box), r = sl_bvh_overlap(&nodes[n->first + 1].box, box);
            if (l && r) {
                stack[sp++] = n->first + 1;
                ni = n->first;
                continue;
            }
            if (l || r) {
                ni = n->first + r;
                continue;
            }
        }
        if (sp == 0)
            return total;
        ni = stack[--sp];
    }
}

/* Slab test of a box against the ray; returns the entry parameter or INFINITY on a miss. Axes with
 * a zero (or denormal) direction component only check that the origin lies within the slab. */
typedef struct ray {
    float o[3], inv[3];
    bool zero[3];
    float tmax;
} ray;

static inline float ray_box(const ray *r, const sl_aabb *b)
{
    const float *lo = &b->min.x, *hi = &b->max.x;
    float t0 = 0.0f, t1 = r->tmax;
    for (int k = 0; k < 3; k++) {
        if (r->zero[k]) {
            if (r->o[k] < lo[k] || r->o[k] > hi[k])
                return INFINITY;
            continue;
        }
        float a = (lo[k] - r->o[k]) * r->inv[k], c = (hi[k] - r->o[k]) * r->inv[k];
        t0 = SL_MAX(t0, SL_MIN(a, c));
        t1 = SL_MIN(t1, SL_MAX(a, c));
    }
    return t0 <= t1 ? t0 : INFINITY;
}

uint32_t sl_bvh_query_ray(sl_bvh bvh, sl_vec3 origin, sl_vec3 dir, float tmax, uint32_t *out, uint32_t capacity)
{
    if (!bvh || bvh->node_slots == 0)
        return 0;
    ray r;
    const float o[3] = {origin.x, origin.y, origin.z}, d[3] = {dir.x, dir.y, dir.z};
    if (!sl_finite3(o) || !sl_finite3(d) || isnan(tmax) || tmax < 0.0f)
        return 0;
    for (int k = 0; k < 3; k++) {
        /* a component so small that its inverse overflows counts as parallel to the slab */
        r.o[k] = o[k];
        r.zero[k] = d[k] == 0.0f || !isfinite(1.0f / d[k]);
        r.inv[k] = r.zero[k] ? 0.0f : 1.0f / d[k];
    }
    r.tmax = tmax;
    const sl_bvh_node *nodes = bvh->nodes;
    if (ray_box(&r, &nodes[0].box) == INFINITY)
        return 0;
    uint32_t stack[SL_BVH_MAX_DEPTH], sp = 0, ni = 0, total = 0;
    for (;;) {
        const sl_bvh_node *n = &nodes[ni];
        if (n->count) {
            for (uint32_t k = n->first; k < n->first + n->count; k++) {
                if (ray_box(&r, &bvh->object_bounds[k]) != INFINITY) {
                    if (total < capacity)
                        out[total] = bvh->objects[k];
                    total++;
                }
            }
        } else {
            float tl = ray_box(&r, &nodes[n->first].box), tr = ray_box(&r, &nodes[n->first + 1].box);
            if (tl != INFINITY && tr != INFINITY) {
                bool rf = tr < tl;
                stack[sp++] = n->first + !rf;
                ni = n->first + rf;
                continue;
            }
            if (tl != INFINITY || tr != INFINITY) {
                ni = n->first + (tr != INFINITY);
                continue;
            }
        }
        if (sp == 0)
            return total;
        ni = stack[--sp];
    }
}

/* Screen bins and the built-in thread pool of the occlusion rasterizer.
 *
 * The screen is cut into a grid of bins (rectangles of whole tiles). A front end prepares
 * triangles and appends a copy of each (64 bytes) to the queue of every bin its tile bounds
 * overlap; a renderer drains a bin's queues in order, handing the kernels runs of consecutive
 * triangles (the batched SIMD setup works on groups of 8). There is one queue per (front-end slot, bin): the caller-driven
 * API uses slot 0, the pool's parallel front end uses slot w for worker w's contiguous share of
 * the triangles, and a bin renders slot 0's queue before slot 1's, so every tile sees the
 * triangles in submission order whatever the thread count: the buffer is identical.
 *
 * Concurrency (one front end per slot, one renderer per bin): queues are chunked lists of blocks
 * that never move, so a renderer can read while the front end appends. The front end writes the
 * triangle, the reference and any block link first, then publishes the new count with a release
 * store; the renderer reads the count with an acquire load and touches nothing beyond it. Storage
 * is recycled (never freed until destroy) by sl_rt_bins_reset, which needs exclusive use. */
#include "raster/raster_internal.h"

#include <pthread.h>

#define REF_BLOCK 255 /* triangles per block: 16 KiB with the link */

typedef struct ref_block {
    sl_rt_prim refs[REF_BLOCK];
    struct ref_block *next;
} ref_block;

/* One (slot, bin) queue; the front end's and the renderer's fields live on separate cache lines. */
typedef struct queue {
    _Alignas(64) ref_block *head, *tail;
    uint32_t tail_n;
    uint64_t written;
    _Atomic uint64_t published;
    _Alignas(64) ref_block *rblock;
    uint32_t rpos;
    uint64_t consumed;
} queue;

typedef struct slot {
    ref_block *ref_free;
    queue *queues; /* bin_count */
    size_t bytes;
} slot;

struct sl_rt_bins {
    const sl_allocator *alloc;
    uint32_t bins_x, bins_y, bin_tw, bin_th, slot_count;
    slot *slots;
};

sl_status sl_rt_bins_create(const sl_allocator *alloc, int32_t tiles_x, int32_t tiles_y, uint32_t bins_x,
                            uint32_t bins_y, uint32_t slot_count, sl_rt_bins **out, sl_error *err)
{
    sl_rt_bins *b = sl_calloc(alloc, 1, sizeof *b);
    if (!b)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for bins");
    b->alloc = alloc;
    b->bin_tw = ((uint32_t)tiles_x + bins_x - 1) / bins_x;
    b->bin_th = ((uint32_t)tiles_y + bins_y - 1) / bins_y;
    b->bins_x = ((uint32_t)tiles_x + b->bin_tw - 1) / b->bin_tw;
    b->bins_y = ((uint32_t)tiles_y + b->bin_th - 1) / b->bin_th;
    b->slot_count = slot_count;
    b->slots = sl_calloc(alloc, slot_count, sizeof(slot));
    if (!b->slots) {
        sl_free(alloc, b, sizeof *b);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for bins");
    }
    uint32_t n = b->bins_x * b->bins_y;
    for (uint32_t s = 0; s < slot_count; s++) {
        b->slots[s].queues = sl_alloc_aligned(alloc, sizeof(queue) * n, 64);
        if (!b->slots[s].queues) {
            sl_rt_bins_destroy(b);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for bins");
        }
        memset(b->slots[s].queues, 0, sizeof(queue) * n);
        for (uint32_t i = 0; i < n; i++)
            atomic_init(&b->slots[s].queues[i].published, 0);
    }
    *out = b;
    return SL_OK;
}

void sl_rt_bins_destroy(sl_rt_bins *b)
{
    if (!b)
        return;
    sl_rt_bins_reset(b); /* moves every reference block to the free lists */
    uint32_t n = b->bins_x * b->bins_y;
    for (uint32_t s = 0; s < b->slot_count; s++) {
        slot *sl = &b->slots[s];
        for (ref_block *r = sl->ref_free, *nx; r; r = nx) {
            nx = r->next;
            sl_free(b->alloc, r, sizeof *r);
        }
        if (sl->queues)
            sl_free(b->alloc, sl->queues, sizeof(queue) * n);
    }
    sl_free(b->alloc, b->slots, sizeof(slot) * b->slot_count);
    sl_free(b->alloc, b, sizeof *b);
}

uint32_t sl_rt_bins_count(const sl_rt_bins *b) { return b->bins_x * b->bins_y; }

size_t sl_rt_bins_memory(const sl_rt_bins *b)
{
    size_t bytes = sizeof *b + sizeof(slot) * b->slot_count;
    for (uint32_t s = 0; s < b->slot_count; s++)
        bytes += b->slots[s].bytes + sizeof(queue) * b->bins_x * b->bins_y;
    return bytes;
}

void sl_rt_bins_reset(sl_rt_bins *b)
{
    uint32_t n = b->bins_x * b->bins_y;
    for (uint32_t s = 0; s < b->slot_count; s++) {
        slot *sl = &b->slots[s];
        for (uint32_t i = 0; i < n; i++) {
            queue *q = &sl->queues[i];
            if (q->tail) {
                q->tail->next = sl->ref_free;
                sl->ref_free = q->head;
            }
            q->head = q->tail = NULL;
            q->tail_n = 0;
            q->written = 0;
            atomic_store_explicit(&q->published, 0, memory_order_relaxed);
            q->rblock = NULL;
            q->rpos = 0;
            q->consumed = 0;
        }
    }
}

static bool push(sl_rt_bins *b, slot *s, queue *q, const sl_rt_prim *t)
{
    if (!q->tail || q->tail_n == REF_BLOCK) {
        ref_block *nb = s->ref_free;
        if (nb) {
            s->ref_free = nb->next;
        } else {
            nb = sl_alloc_aligned(b->alloc, sizeof *nb, 64);
            if (!nb)
                return false;
            s->bytes += sizeof *nb;
        }
        nb->next = NULL;
        if (q->tail)
            q->tail->next = nb;
        else
            q->head = nb;
        q->tail = nb;
        q->tail_n = 0;
    }
    q->tail->refs[q->tail_n++] = *t;
    q->written++;
    atomic_store_explicit(&q->published, q->written, memory_order_release);
    return true;
}

bool sl_rt_bins_add(sl_rt_bins *b, uint32_t slot_index, const sl_rt_prim *prim, uint64_t *refs)
{
    slot *s = &b->slots[slot_index];
    const sl_rt_prim *t = prim;
    int32_t tx0 = t->col0 / SL_RT_TILE_W, tx1 = (t->col1 - 1) / SL_RT_TILE_W + 1;
    int32_t ty0 = t->row0 / SL_RT_TILE_H, ty1 = (t->row1 - 1) / SL_RT_TILE_H + 1;
    uint32_t bx0 = (uint32_t)tx0 / b->bin_tw, bx1 = (uint32_t)(tx1 - 1) / b->bin_tw;
    uint32_t by0 = (uint32_t)ty0 / b->bin_th, by1 = (uint32_t)(ty1 - 1) / b->bin_th;
    for (uint32_t by = by0; by <= by1; by++)
        for (uint32_t bx = bx0; bx <= bx1; bx++) {
            if (!push(b, s, &s->queues[by * b->bins_x + bx], t))
                return false;
            (*refs)++;
        }
    return true;
}

uint32_t sl_rt_bins_render(sl_rt_bins *b, const sl_rt_kernels *k, const sl_rt_target *tg, int mode, uint32_t bin)
{
    if (bin >= b->bins_x * b->bins_y)
        return 0;
    int32_t bx = (int32_t)(bin % b->bins_x), by = (int32_t)(bin / b->bins_x);
    int32_t btx0 = bx * (int32_t)b->bin_tw, bty0 = by * (int32_t)b->bin_th;
    int32_t btx1 = sl_rt_mini(btx0 + (int32_t)b->bin_tw, tg->tiles_x);
    int32_t bty1 = sl_rt_mini(bty0 + (int32_t)b->bin_th, tg->tiles_y);
    uint32_t n = 0;
    for (uint32_t s = 0; s < b->slot_count; s++) {
        queue *q = &b->slots[s].queues[bin];
        uint64_t pub = atomic_load_explicit(&q->published, memory_order_acquire);
        while (q->consumed < pub) {
            if (!q->rblock) {
                q->rblock = q->head;
                q->rpos = 0;
            } else if (q->rpos == REF_BLOCK) {
                q->rblock = q->rblock->next;
                q->rpos = 0;
            }
            /* the run of published triangles left in this block; the setup is redone in every bin
             * a triangle reaches: 64 bytes per queued triangle instead of a set-up one, and the
             * same bits everywhere */
            uint64_t left = pub - q->consumed;
            uint32_t run = REF_BLOCK - q->rpos;
            if (left < run)
                run = (uint32_t)left;
            k->render(tg, mode, &q->rblock->refs[q->rpos], run, btx0, btx1, bty0, bty1);
            q->rpos += run;
            q->consumed += run;
            n += run;
        }
    }
    return n;
}

/* ---- the pool: n workers beside the calling thread, one job at a time ---- */

struct sl_rt_pool {
    const sl_allocator *alloc;
    pthread_t *threads;
    uint32_t started;
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    uint64_t generation;
    uint32_t busy;
    bool quit;
    sl_rt_job_fn fn;
    void *arg;
};

typedef struct worker_arg {
    sl_rt_pool *pool;
    uint32_t index;
} worker_arg;

static void *worker_main(void *p)
{
    worker_arg wa = *(worker_arg *)p;
    sl_rt_pool *pool = wa.pool;
    uint64_t seen = 0;
    pthread_mutex_lock(&pool->mu);
    for (;;) {
        while (!pool->quit && pool->generation == seen)
            pthread_cond_wait(&pool->go, &pool->mu);
        if (pool->quit)
            break;
        seen = pool->generation;
        sl_rt_job_fn fn = pool->fn;
        void *arg = pool->arg;
        pthread_mutex_unlock(&pool->mu);
        fn(arg, wa.index);
        pthread_mutex_lock(&pool->mu);
        if (--pool->busy == 0)
            pthread_cond_signal(&pool->done);
    }
    pthread_mutex_unlock(&pool->mu);
    return NULL;
}

static void pool_stop(sl_rt_pool *p)
{
    pthread_mutex_lock(&p->mu);
    p->quit = true;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (uint32_t i = 0; i < p->started; i++)
        pthread_join(p->threads[i], NULL);
}

sl_status sl_rt_pool_create(const sl_allocator *alloc, uint32_t workers, sl_rt_pool **out, sl_error *err)
{
    sl_rt_pool *p = sl_calloc(alloc, 1, sizeof *p);
    worker_arg *args = sl_calloc(alloc, workers, sizeof *args);
    if (p)
        p->threads = sl_calloc(alloc, workers, sizeof(pthread_t));
    if (!p || !args || !p->threads) {
        if (p && p->threads)
            sl_free(alloc, p->threads, sizeof(pthread_t) * workers);
        sl_free(alloc, args, sizeof *args * workers);
        sl_free(alloc, p, sizeof *p);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for the thread pool");
    }
    p->alloc = alloc;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    /* workers copy their argument before the first job, which cannot start before create returns */
    for (uint32_t i = 0; i < workers; i++) {
        args[i].pool = p;
        args[i].index = i + 1;
        if (pthread_create(&p->threads[i], NULL, worker_main, &args[i]) != 0) {
            pool_stop(p);
            sl_free(alloc, args, sizeof *args * workers);
            sl_rt_pool_destroy_n(p, workers);
            return sl_fail(err, SL_ERROR_INTERNAL, "raster: cannot start worker thread %u of %u", i + 1, workers);
        }
        p->started++;
    }
    /* wait until every worker has read its argument: run an empty job */
    *out = p;
    sl_rt_pool_run(p, NULL, NULL);
    sl_free(alloc, args, sizeof *args * workers);
    return SL_OK;
}

void sl_rt_pool_destroy_n(sl_rt_pool *p, uint32_t workers)
{
    if (!p)
        return;
    if (!p->quit)
        pool_stop(p);
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
    sl_free(p->alloc, p->threads, sizeof(pthread_t) * workers);
    sl_free(p->alloc, p, sizeof *p);
}

static void nop_job(void *arg, uint32_t worker)
{
    (void)arg;
    (void)worker;
}

void sl_rt_pool_run(sl_rt_pool *p, sl_rt_job_fn fn, void *arg)
{
    if (!fn)
        fn = nop_job;
    pthread_mutex_lock(&p->mu);
    p->fn = fn;
    p->arg = arg;
    p->busy = p->started;
    p->generation++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    fn(arg, 0);
    pthread_mutex_lock(&p->mu);
    while (p->busy > 0)
        pthread_cond_wait(&p->done, &p->mu);
    pthread_mutex_unlock(&p->mu);
}

/* The occlusion rasterizer's context and public API: options, buffer, instruction-set dispatch,
 * direct and pooled rendering, caller-driven bins, queries and debugging reads.
 * Design notes: docs/rasterizer.md; the buffer and the kernels' contract: raster_internal.h. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#include <math.h>
#if defined(SL_RT_X86)
#include <emmintrin.h> /* SSE2: the x86-64 baseline */
#endif

/* Batches smaller than this are rendered on the calling thread even with a pool: waking workers
 * costs more than it saves, and the result is the same either way. */
#define POOL_MIN_TRIANGLES 512
/* The pool bins and renders a large batch this many triangles at a time, which bounds the queue
 * storage (64 bytes per triangle and bin) whatever the batch size. */
#define POOL_CHUNK 16384
#define MAX_THREADS SL_MAX_THREADS /* the one limit (core.h) */

const sl_rt_zero_tile_t sl_rt_zero_tile; /* all zero: a cleared tile */

struct sl_raster {
    const sl_allocator *alloc;
    sl_raster_options opt;
    sl_rt_view view;
    sl_rt_target target;
    const sl_rt_kernels *k;
    int mode; /* SL_RT_CENTER or SL_RT_INNER */
    size_t mask_bytes, depth_bytes;
    uint8_t *row_empty;        /* lazy clear: tile rows not yet written since the clear */
    uint32_t slots;            /* front-end slots = threads */
    sl_rt_counters cnt;        /* direct rendering */
    sl_rt_counters *slot_cnt;  /* binning, per slot */
    sl_rt_bins *bins;
    bool pending;              /* triangles binned and maybe not rendered */
    sl_rt_pool *pool;          /* NULL when single-threaded */
};

sl_raster_options sl_raster_default_options(uint32_t width, uint32_t height)
{
    sl_raster_options o;
    memset(&o, 0, sizeof o);
    o.width = width;
    o.height = height;
    o.threads = 1;
    o.isa = SL_RASTER_ISA_AUTO;
    o.depth = SL_RASTER_DEPTH_INV_W;
    o.coverage = SL_RASTER_COVERAGE_CENTER;
    o.near_w = 1e-5f;
    return o;
}

bool sl_raster_isa_available(sl_raster_isa isa)
{
    switch (isa) {
    case SL_RASTER_ISA_AUTO:
    case SL_RASTER_ISA_SCALAR: return true;
#if defined(SL_RT_X86)
    case SL_RASTER_ISA_SSE41: return __builtin_cpu_supports("sse4.1");
    case SL_RASTER_ISA_AVX2: return __builtin_cpu_supports("avx2");
    case SL_RASTER_ISA_AVX512:
        return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("avx512f") &&
               __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") &&
               __builtin_cpu_supports("avx512dq");
#else
    case SL_RASTER_ISA_SSE41:
    case SL_RASTER_ISA_AVX2:
    case SL_RASTER_ISA_AVX512: return false;
#endif
    }
    return false;
}

const char *sl_raster_isa_name(sl_raster_isa isa)
{
    switch (isa) {
    case SL_RASTER_ISA_AUTO: return "auto";
    case SL_RASTER_ISA_SCALAR: return "scalar";
    case SL_RASTER_ISA_SSE41: return "sse41";
    case SL_RASTER_ISA_AVX2: return "avx2";
    case SL_RASTER_ISA_AVX512: return "avx512";
    }
    return "unknown";
}

static const sl_rt_kernels *kernels_for(sl_raster_isa isa)
{
    if (isa == SL_RASTER_ISA_AUTO) {
        static const sl_raster_isa order[] = {SL_RASTER_ISA_AVX512, SL_RASTER_ISA_AVX2, SL_RASTER_ISA_SSE41};
        for (size_t i = 0; i < SL_COUNTOF(order); i++)
            if (sl_raster_isa_available(order[i]))
                return kernels_for(order[i]);
        return &sl_rt_kernels_scalar;
    }
    switch (isa) {
#if defined(SL_RT_X86)
    case SL_RASTER_ISA_SSE41: return &sl_rt_kernels_sse41;
    case SL_RASTER_ISA_AVX2: return &sl_rt_kernels_avx2;
    case SL_RASTER_ISA_AVX512: return &sl_rt_kernels_avx512;
#endif
    default: return &sl_rt_kernels_scalar;
    }
}

sl_status sl_raster_create(const sl_raster_options *options, const sl_allocator *alloc, sl_raster **out,
                           sl_error *err)
{
    if (!options || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: options and out must not be NULL");
    *out = NULL;
    sl_raster_options o = *options;
    if (o.width < 1 || o.width > SL_RT_MAX_DIM || o.height < 1 || o.height > SL_RT_MAX_DIM)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: size %ux%u outside 1..%d", o.width, o.height,
                       SL_RT_MAX_DIM);
    if (o.threads > MAX_THREADS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %u threads, at most %u (SL_MAX_THREADS)", o.threads,
                       MAX_THREADS);
    if ((unsigned)o.isa > SL_RASTER_ISA_AVX512)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: unknown isa %d", (int)o.isa);
    if (!sl_raster_isa_available(o.isa))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "raster: this CPU or build has no %s path",
                       sl_raster_isa_name(o.isa));
    if ((unsigned)o.depth > SL_RASTER_DEPTH_LINEAR_Z)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: unknown depth mode %d", (int)o.depth);
    if ((unsigned)o.coverage > SL_RASTER_COVERAGE_INNER)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: unknown coverage rule %d", (int)o.coverage);
    if (!(o.near_w > 0.0f) || !isfinite(o.near_w))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: near_w %g must be finite and > 0", (double)o.near_w);
    uint32_t tiles_x = (o.width + SL_RT_TILE_W - 1) / SL_RT_TILE_W;
    uint32_t tiles_y = (o.height + SL_RT_TILE_H - 1) / SL_RT_TILE_H;
    if (o.bins_x > tiles_x || o.bins_y > tiles_y)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %ux%u bins for %ux%u tiles", o.bins_x, o.bins_y,
                       tiles_x, tiles_y);
    /* default bins: full-width strips, so that no tile row's spans are computed in two bins */
    if (o.bins_x == 0)
        o.bins_x = 1;
    if (o.bins_y == 0)
        o.bins_y = SL_MIN(16u, tiles_y);
    if (o.threads == 0)
        o.threads = 1;

    alloc = sl_alloc_or_default(alloc);
    sl_raster *ctx = sl_calloc(alloc, 1, sizeof *ctx);
    if (!ctx)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for the context");
    ctx->alloc = alloc;
    ctx->opt = o;
    ctx->k = kernels_for(o.isa);
    ctx->opt.isa = ctx->k->isa;
    ctx->mode = o.coverage == SL_RASTER_COVERAGE_INNER ? SL_RT_INNER : SL_RT_CENTER;
    sl_rt_view_init(&ctx->view, o.width, o.height, o.near_w, o.depth);
    size_t tiles = (size_t)tiles_x * tiles_y;
    ctx->mask_bytes = tiles * SL_RT_SUBTILES * sizeof(uint32_t);
    ctx->depth_bytes = tiles * sizeof(sl_rt_tile_depth);
    ctx->target.mask = sl_alloc_aligned(alloc, ctx->mask_bytes, 64);
    ctx->target.depth = sl_alloc_aligned(alloc, ctx->depth_bytes, 64);
    ctx->row_empty = sl_calloc(alloc, tiles_y, 1);
    ctx->target.row_empty = ctx->row_empty;
    ctx->target.tiles_x = (int32_t)tiles_x;
    ctx->target.tiles_y = (int32_t)tiles_y;
    ctx->target.width = (int32_t)o.width;
    ctx->target.height = (int32_t)o.height;
    ctx->slots = o.threads;
    ctx->slot_cnt = sl_calloc(alloc, ctx->slots, sizeof(sl_rt_counters));
    sl_status st = SL_OK;
    if (!ctx->target.mask || !ctx->target.depth || !ctx->row_empty || !ctx->slot_cnt)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: out of memory for a %ux%u buffer", o.width, o.height);
    if (st == SL_OK)
        st = sl_rt_bins_create(alloc, (int32_t)tiles_x, (int32_t)tiles_y, o.bins_x, o.bins_y, ctx->slots,
                               &ctx->bins, err);
    if (st == SL_OK && o.threads > 1)
        st = sl_rt_pool_create(alloc, o.threads - 1, &ctx->pool, err);
    if (st != SL_OK) {
        sl_raster_destroy(ctx);
        return st;
    }
    sl_raster_clear(ctx);
    *out = ctx;
    return SL_OK;
}

void sl_raster_destroy(sl_raster *ctx)
{
    if (!ctx)
        return;
    const sl_allocator *a = ctx->alloc;
    if (ctx->pool)
        sl_rt_pool_destroy_n(ctx->pool, ctx->opt.threads - 1);
    sl_rt_bins_destroy(ctx->bins);
    sl_free(a, ctx->target.mask, ctx->mask_bytes);
    sl_free(a, ctx->target.depth, ctx->depth_bytes);
    sl_free(a, ctx->row_empty, (size_t)ctx->target.tiles_y);
    sl_free(a, ctx->slot_cnt, ctx->slots * sizeof(sl_rt_counters));
    sl_free(a, ctx, sizeof *ctx);
}

const sl_rt_target *sl_rt_target_of(const sl_raster *ctx) { return &ctx->target; }
const sl_rt_view *sl_rt_view_of(const sl_raster *ctx) { return &ctx->view; }

sl_raster_isa sl_raster_get_isa(const sl_raster *ctx) { return ctx ? ctx->opt.isa : SL_RASTER_ISA_AUTO; }

void sl_raster_get_size(const sl_raster *ctx, uint32_t *width, uint32_t *height, uint32_t *tiles_x,
                        uint32_t *tiles_y)
{
    if (width)
        *width = ctx->opt.width;
    if (height)
        *height = ctx->opt.height;
    if (tiles_x)
        *tiles_x = (uint32_t)ctx->target.tiles_x;
    if (tiles_y)
        *tiles_y = (uint32_t)ctx->target.tiles_y;
}

size_t sl_raster_memory(const sl_raster *ctx)
{
    if (!ctx)
        return 0;
    size_t pool = ctx->pool ? (ctx->opt.threads - 1) * sizeof(void *) * 2 + 256 : 0;
    return sizeof *ctx + ctx->mask_bytes + ctx->depth_bytes + (size_t)ctx->target.tiles_y +
           ctx->slots * sizeof(sl_rt_counters) + sl_rt_bins_memory(ctx->bins) + pool;
}

void sl_raster_reset_stats(sl_raster *ctx)
{
    memset(&ctx->cnt, 0, sizeof ctx->cnt);
    memset(ctx->slot_cnt, 0, ctx->slots * sizeof(sl_rt_counters));
}

/* The lazy clear: sl_raster_clear only marks every tile row empty; rows [ty0, ty1) get their zeros
 * (depth 0.0f and an empty mask are all-zero bits) here, before anything is merged into them. */
static void fill_rows(sl_raster *ctx, int32_t ty0, int32_t ty1)
{
    size_t tx = (size_t)ctx->target.tiles_x;
    for (int32_t ty = ty0; ty < ty1; ty++) {
        if (!ctx->row_empty[ty])
            continue;
        int32_t te = ty + 1; /* a run of empty rows in one memset */
        while (te < ty1 && ctx->row_empty[te])
            te++;
        size_t t0 = (size_t)ty * tx, nt = (size_t)(te - ty) * tx;
        memset(ctx->target.mask + t0 * SL_RT_SUBTILES, 0, nt * SL_RT_SUBTILES * sizeof(uint32_t));
        memset(ctx->target.depth + t0, 0, nt * sizeof(sl_rt_tile_depth));
        memset(ctx->row_empty + ty, 0, (size_t)(te - ty));
        ctx->target.empty_rows -= te - ty;
        ty = te - 1;
    }
}

/* Every empty row written (before binning: bins are rendered concurrently and never fill rows). */
static void fill_all(sl_raster *ctx)
{
    if (ctx->target.empty_rows)
        fill_rows(ctx, 0, ctx->target.tiles_y);
}

void sl_rt_settle(sl_raster *ctx) { fill_all(ctx); }

/* True when every subtile of the (at most 4) tiles [ta, tb] x [ua, ub] has za > d; then the
 * rectangle is hidden whatever it covers of them. Otherwise the kernel decides (same answer). */
static inline bool small_rect_hidden(const sl_rt_target *t, int32_t ta, int32_t tb, int32_t ua, int32_t ub, float d)
{
#if defined(SL_RT_X86)
    __m128 z = _mm_set1_ps(d), acc = _mm_castsi128_ps(_mm_set1_epi32(-1));
    for (int32_t u = ua; u <= ub; u++)
        for (int32_t x = ta; x <= tb; x++) {
            const float *za = t->depth[(size_t)u * (size_t)t->tiles_x + (size_t)x].za;
            acc = _mm_and_ps(acc, _mm_and_ps(_mm_cmpgt_ps(_mm_load_ps(za), z), _mm_cmpgt_ps(_mm_load_ps(za + 4), z)));
        }
    return _mm_movemask_ps(acc) == 0xF;
#else
    bool all = true;
    for (int32_t u = ua; u <= ub; u++)
        for (int32_t x = ta; x <= tb; x++)
            for (int s = 0; s < SL_RT_SUBTILES; s++)
                all &= t->depth[(size_t)u * (size_t)t->tiles_x + (size_t)x].za[s] > d;
    return all;
#endif
}

bool sl_rt_rect_occluded(const sl_rt_kernels *k, const sl_rt_target *t, int32_t x0, int32_t y0, int32_t x1,
                         int32_t y1, float d)
{
    if (!t->empty_rows) { /* the common case: every row holds data */
        int32_t ta = x0 / SL_RT_TILE_W, tb = (x1 - 1) / SL_RT_TILE_W, ua = y0 / SL_RT_TILE_H,
                ub = (y1 - 1) / SL_RT_TILE_H;
        /* a small rectangle behind whole-subtile depths: answered here, without the call */
        if ((tb - ta + 1) * (ub - ua + 1) <= 4 && small_rect_hidden(t, ta, tb, ua, ub, d))
            return true;
        return k->rect_occluded(t, x0, y0, x1, y1, d);
    }
    int32_t ta = y0 / SL_RT_TILE_H, tb = (y1 - 1) / SL_RT_TILE_H;
    const uint8_t *e = t->row_empty;
    int32_t ty = ta;
    while (ty <= tb && !e[ty])
        ty++;
    if (ty > tb)
        return k->rect_occluded(t, x0, y0, x1, y1, d);
    if (!(d < 0.0f)) /* a cleared subtile (za = 0) hides no depth >= 0 */
        return false;
    /* d < 0: the cleared rows hide it; test the bands of rows with data */
    for (ty = ta; ty <= tb;) {
        if (e[ty]) {
            ty++;
            continue;
        }
        int32_t te = ty;
        while (te + 1 <= tb && !e[te + 1])
            te++;
        int32_t ya = sl_rt_maxi(y0, ty * SL_RT_TILE_H), yb = sl_rt_mini(y1, (te + 1) * SL_RT_TILE_H);
        if (!k->rect_occluded(t, x0, ya, x1, yb, d))
            return false;
        ty = te + 1;
    }
    return true;
}

void sl_raster_clear(sl_raster *ctx)
{
    if (!ctx)
        return;
    /* lazy: rows are written when first drawn into (fill_rows) */
    memset(ctx->row_empty, 1, (size_t)ctx->target.tiles_y);
    ctx->target.empty_rows = ctx->target.tiles_y;
    sl_rt_bins_reset(ctx->bins);
    ctx->pending = false;
    sl_raster_reset_stats(ctx);
}

sl_status sl_raster_begin_frame(sl_raster *ctx, sl_raster_depth depth, sl_error *err)
{
    if (!ctx)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: context must not be NULL");
    if ((unsigned)depth > SL_RASTER_DEPTH_LINEAR_Z)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: unknown depth mode %d", (int)depth);
    ctx->opt.depth = depth;
    ctx->view.depth = depth;
    sl_raster_clear(ctx);
    return SL_OK;
}

/* ---- rendering ---- */

static sl_status check_batch(const char *what, const float *vertices, const uint32_t *indices,
                             uint32_t triangle_count, uint32_t stride, const float *m, sl_raster_backface bf,
                             sl_error *err)
{
    if (triangle_count > 0 && (!vertices || !indices))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: vertices and indices must not be NULL", what);
    if (stride < 12 || stride % 4 != 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: vertex stride %u must be >= 12 and a multiple of 4",
                       what, stride);
    if (((uintptr_t)vertices & 3u) != 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: vertices must be 4-byte aligned", what);
    if (!m)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: matrix must not be NULL", what);
    for (int i = 0; i < 16; i++)
        if (!isfinite(m[i]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: matrix element %d is not finite", what, i);
    if ((unsigned)bf > SL_RASTER_CULL_CCW)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: %s: unknown backface mode %d", what, (int)bf);
    return SL_OK;
}

/* Prepared triangles handed from the front end to the kernels at a time (16 KiB on the stack). */
#define PRIM_BUF 256

/* Front end and rendering of triangles [first, last) on the calling thread, in order. */
static void render_direct(sl_raster *ctx, const sl_rt_batch *b, uint32_t first, uint32_t last)
{
    sl_rt_prim prims[PRIM_BUF];
    for (uint32_t t = first; t < last;) {
        uint32_t n = ctx->k->front(&ctx->view, ctx->mode, b, &t, last, &ctx->cnt, prims, PRIM_BUF);
        if (ctx->target.empty_rows && n > 0) { /* the rows the prims reach get their zeros */
            int32_t r0 = prims[0].row0, r1 = prims[0].row1;
            for (uint32_t i = 1; i < n; i++) {
                r0 = sl_rt_mini(r0, prims[i].row0);
                r1 = sl_rt_maxi(r1, prims[i].row1);
            }
            fill_rows(ctx, r0 / SL_RT_TILE_H, (r1 - 1) / SL_RT_TILE_H + 1);
        }
        ctx->k->render(&ctx->target, ctx->mode, prims, n, 0, ctx->target.tiles_x, 0, ctx->target.tiles_y);
    }
}

/* Front end of slot `slot` into the bins; false when queue storage ran out. */
static bool bin_range(sl_raster *ctx, uint32_t slot, const sl_rt_batch *b, uint32_t first, uint32_t last)
{
    sl_rt_prim prims[PRIM_BUF];
    sl_rt_counters *cnt = &ctx->slot_cnt[slot];
    for (uint32_t t = first; t < last;) {
        uint32_t n = ctx->k->front(&ctx->view, ctx->mode, b, &t, last, cnt, prims, PRIM_BUF);
        for (uint32_t i = 0; i < n; i++)
            if (!sl_rt_bins_add(ctx->bins, slot, &prims[i], &cnt->bin_refs))
                return false;
    }
    return true;
}

typedef struct pool_job {
    sl_raster *ctx;
    const sl_rt_batch *batch;
    uint32_t first, last; /* the chunk of the batch being binned */
    _Atomic uint32_t next_bin;
    _Atomic bool failed;
} pool_job;

static void front_end_job(void *arg, uint32_t w)
{
    pool_job *j = arg;
    sl_raster *ctx = j->ctx;
    uint64_t n = j->last - j->first, parts = ctx->slots;
    uint32_t first = j->first + (uint32_t)(n * w / parts), last = j->first + (uint32_t)(n * (w + 1) / parts);
    if (!bin_range(ctx, w, j->batch, first, last))
        atomic_store(&j->failed, true);
}

static void render_job(void *arg, uint32_t w)
{
    (void)w;
    pool_job *j = arg;
    sl_raster *ctx = j->ctx;
    uint32_t count = sl_rt_bins_count(ctx->bins);
    for (uint32_t b; (b = atomic_fetch_add(&j->next_bin, 1)) < count;)
        sl_rt_bins_render(ctx->bins, ctx->k, &ctx->target, ctx->mode, b);
}

void sl_raster_flush(sl_raster *ctx)
{
    if (!ctx || !ctx->pending)
        return;
    if (ctx->pool) {
        pool_job j = {.ctx = ctx};
        atomic_init(&j.next_bin, 0);
        atomic_init(&j.failed, false);
        sl_rt_pool_run(ctx->pool, render_job, &j);
    } else {
        uint32_t count = sl_rt_bins_count(ctx->bins);
        for (uint32_t b = 0; b < count; b++)
            sl_rt_bins_render(ctx->bins, ctx->k, &ctx->target, ctx->mode, b);
    }
    sl_rt_bins_reset(ctx->bins);
    ctx->pending = false;
}

sl_status sl_raster_render_triangles(sl_raster *ctx, const float *vertices, uint32_t vertex_count,
                                     const uint32_t *indices, uint32_t triangle_count, uint32_t vertex_stride_bytes,
                                     const float model_to_clip[16], sl_raster_backface backface, sl_error *err)
{
    if (!ctx)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: render: context must not be NULL");
    sl_status st = check_batch("render", vertices, indices, triangle_count, vertex_stride_bytes, model_to_clip,
                               backface, err);
    if (st != SL_OK)
        return st;
    sl_rt_batch b = {vertices, vertex_count, indices, triangle_count, vertex_stride_bytes, model_to_clip, backface};
    /* triangles binned earlier come first */
    sl_raster_flush(ctx);
    if (!ctx->pool || triangle_count < POOL_MIN_TRIANGLES) {
        render_direct(ctx, &b, 0, triangle_count);
        return SL_OK;
    }
    fill_all(ctx);
    pool_job j = {.ctx = ctx, .batch = &b};
    atomic_init(&j.failed, false);
    for (uint32_t first = 0; first < triangle_count; first += POOL_CHUNK) {
        j.first = first;
        j.last = triangle_count - first > POOL_CHUNK ? first + POOL_CHUNK : triangle_count;
        atomic_init(&j.next_bin, 0);
        ctx->pending = true;
        sl_rt_pool_run(ctx->pool, front_end_job, &j);
        sl_rt_pool_run(ctx->pool, render_job, &j);
        sl_rt_bins_reset(ctx->bins);
        ctx->pending = false;
    }
    if (atomic_load(&j.failed))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY,
                       "raster: render: out of memory while binning %u triangles (some occluders were dropped)",
                       triangle_count);
    return SL_OK;
}

uint32_t sl_raster_bin_count(const sl_raster *ctx) { return ctx ? sl_rt_bins_count(ctx->bins) : 0; }

sl_status sl_raster_bin_triangles(sl_raster *ctx, const float *vertices, uint32_t vertex_count,
                                  const uint32_t *indices, uint32_t triangle_count, uint32_t vertex_stride_bytes,
                                  const float model_to_clip[16], sl_raster_backface backface, sl_error *err)
{
    if (!ctx)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: bin: context must not be NULL");
    sl_status st = check_batch("bin", vertices, indices, triangle_count, vertex_stride_bytes, model_to_clip,
                               backface, err);
    if (st != SL_OK)
        return st;
    sl_rt_batch b = {vertices, vertex_count, indices, triangle_count, vertex_stride_bytes, model_to_clip, backface};
    fill_all(ctx); /* before anything is published to render_bin */
    ctx->pending = true;
    if (!bin_range(ctx, 0, &b, 0, triangle_count))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "raster: bin: out of memory for the bin queues");
    return SL_OK;
}

uint32_t sl_raster_render_bin(sl_raster *ctx, uint32_t bin)
{
    if (!ctx)
        return 0;
    return sl_rt_bins_render(ctx->bins, ctx->k, &ctx->target, ctx->mode, bin);
}

/* ---- queries ---- */

sl_raster_result sl_raster_test_rect(const sl_raster *ctx, int32_t xmin, int32_t ymin, int32_t xmax, int32_t ymax,
                                     float nearest_depth)
{
    if (!ctx)
        return SL_RASTER_VISIBLE;
    int32_t x0 = sl_rt_maxi(xmin, 0), y0 = sl_rt_maxi(ymin, 0);
    int32_t x1 = sl_rt_mini(xmax, ctx->target.width), y1 = sl_rt_mini(ymax, ctx->target.height);
    if (x0 >= x1 || y0 >= y1)
        return SL_RASTER_OUTSIDE;
    if (isnan(nearest_depth))
        return SL_RASTER_VISIBLE;
    if (nearest_depth < 0.0f)
        return SL_RASTER_OUTSIDE;
    return sl_rt_rect_occluded(ctx->k, &ctx->target, x0, y0, x1, y1, nearest_depth) ? SL_RASTER_OCCLUDED
                                                                                     : SL_RASTER_VISIBLE;
}

bool sl_raster_project(const sl_raster *ctx, const float clip[4], float *x, float *y, float *depth)
{
    if (!ctx || !clip)
        return false;
    const sl_rt_view *v = &ctx->view;
    if (!(clip[3] >= v->near_w))
        return false;
    float inv = 1.0f / clip[3];
    float sx = (clip[0] * inv) * v->half_w + v->half_w;
    float sy = v->half_h - (clip[1] * inv) * v->half_h;
    float d = sl_rt_depth_of(v, clip);
    if (!isfinite(sx) || !isfinite(sy) || !isfinite(d))
        return false;
    if (x)
        *x = sx;
    if (y)
        *y = sy;
    if (depth)
        *depth = d;
    return true;
}

/* Pixel index range [*lo, *hi) whose closed pixels touch [a, b], clamped to [0, n]. */
static void touched(float a, float b, int32_t n, int32_t *lo, int32_t *hi)
{
    const float eps = SL_MARGIN_RECT_PX; /* rounding of the projection (core/margins.h) */
    float fa = floorf(a - eps), fb = floorf(b + eps) + 1.0f;
    fa = fa < 0.0f ? 0.0f : (fa > (float)n ? (float)n : fa);
    fb = fb < 0.0f ? 0.0f : (fb > (float)n ? (float)n : fb);
    *lo = (int32_t)fa;
    *hi = (int32_t)fb;
}

/* The box query, corner by corner: the reference of the SIMD version below (and the code where
 * there is none). The box is finite and not empty. */
sl_raster_result sl_rt_test_aabb_scalar(const sl_raster *ctx, const float box_min[3], const float box_max[3],
                                        const float world_to_clip[16])
{
    const sl_rt_view *v = &ctx->view;
    unsigned all = 63, near_cross = 0;
    float c[8][4];
    for (int i = 0; i < 8; i++) {
        float p[3] = {(i & 1) ? box_max[0] : box_min[0], (i & 2) ? box_max[1] : box_min[1],
                      (i & 4) ? box_max[2] : box_min[2]};
        sl_rt_transform(world_to_clip, p, c[i]);
        float x = c[i][0], y = c[i][1], z = c[i][2], w = c[i][3];
        if (!isfinite(x) || !isfinite(y) || !isfinite(z) || !isfinite(w))
            return SL_RASTER_VISIBLE;
        unsigned o = (x < -w ? 1u : 0u) | (x > w ? 2u : 0u) | (y < -w ? 4u : 0u) | (y > w ? 8u : 0u) |
                     (z < -w ? 16u : 0u) | (z > w ? 32u : 0u);
        all &= o;
        near_cross |= (z < -w || w < v->near_w) ? 1u : 0u;
    }
    if (all)
        return SL_RASTER_OUTSIDE;
    if (near_cross)
        return SL_RASTER_VISIBLE;
    float minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY, dn = -INFINITY;
    for (int i = 0; i < 8; i++) {
        float inv = 1.0f / c[i][3];
        float sx = (c[i][0] * inv) * v->half_w + v->half_w;
        float sy = v->half_h - (c[i][1] * inv) * v->half_h;
        float d = sl_rt_depth_of(v, c[i]);
        if (!isfinite(sx) || !isfinite(sy) || !isfinite(d))
            return SL_RASTER_VISIBLE;
        minx = sl_rt_minf(minx, sx), maxx = sl_rt_maxf(maxx, sx);
        miny = sl_rt_minf(miny, sy), maxy = sl_rt_maxf(maxy, sy);
        dn = sl_rt_maxf(dn, d);
    }
    int32_t x0, x1, y0, y1;
    touched(minx, maxx, v->width, &x0, &x1);
    touched(miny, maxy, v->height, &y0, &y1);
    return sl_raster_test_rect(ctx, x0, y0, x1, y1, dn);
}

#if defined(SL_RT_X86)
static inline __m128 sse_finite(__m128 a) /* all-ones where a is finite */
{
    return _mm_cmplt_ps(_mm_andnot_ps(_mm_set1_ps(-0.0f), a), _mm_set1_ps(INFINITY));
}
static inline float sse_hmin(__m128 a)
{
    a = _mm_min_ps(a, _mm_shuffle_ps(a, a, 0x4E));
    return _mm_cvtss_f32(_mm_min_ps(a, _mm_shuffle_ps(a, a, 0xB1)));
}
static inline float sse_hmax(__m128 a)
{
    a = _mm_max_ps(a, _mm_shuffle_ps(a, a, 0x4E));
    return _mm_cvtss_f32(_mm_max_ps(a, _mm_shuffle_ps(a, a, 0xB1)));
}

/* sl_rt_test_aabb_scalar with the 8 corners in two SSE2 registers (corners 0-3: z = min, 4-7:
 * z = max; lane i: x = min/max by bit 0, y by bit 1): the same float operations on every corner
 * in the same order, so the same clip coordinates, outcodes and projected values. The minima and
 * maxima are taken in another order, which cannot change them (finite values, never -0: sx and sy
 * are sums with a positive term, d > 0 or a difference). */
static sl_raster_result test_aabb_sse2(const sl_raster *ctx, const float bmin[3], const float bmax[3],
                                       const float *m)
{
    const sl_rt_view *v = &ctx->view;
    const __m128 X = _mm_setr_ps(bmin[0], bmax[0], bmin[0], bmax[0]);
    const __m128 Y = _mm_setr_ps(bmin[1], bmin[1], bmax[1], bmax[1]);
    const __m128 Z[2] = {_mm_set1_ps(bmin[2]), _mm_set1_ps(bmax[2])};
    __m128 c[2][4]; /* [corner group][clip row] */
    for (int r = 0; r < 4; r++) {
        __m128 xy = _mm_add_ps(_mm_mul_ps(_mm_set1_ps(m[r]), X), _mm_mul_ps(_mm_set1_ps(m[4 + r]), Y));
        for (int g = 0; g < 2; g++)
            c[g][r] = _mm_add_ps(_mm_add_ps(xy, _mm_mul_ps(_mm_set1_ps(m[8 + r]), Z[g])), _mm_set1_ps(m[12 + r]));
    }
    __m128 fin = _mm_and_ps(_mm_and_ps(sse_finite(c[0][0]), sse_finite(c[0][1])),
                            _mm_and_ps(sse_finite(c[0][2]), sse_finite(c[0][3])));
    fin = _mm_and_ps(fin, _mm_and_ps(_mm_and_ps(sse_finite(c[1][0]), sse_finite(c[1][1])),
                                     _mm_and_ps(sse_finite(c[1][2]), sse_finite(c[1][3]))));
    if (_mm_movemask_ps(fin) != 0xF)
        return SL_RASTER_VISIBLE;
    /* a plane every corner lies beyond: outside; a corner in front of the near plane: visible */
    const __m128 sign = _mm_set1_ps(-0.0f), nearw = _mm_set1_ps(v->near_w);
    int all = 0xF, near_cross = 0, out = 0;
    for (int p = 0; p < 6; p++) {
        all = 0xF;
        for (int g = 0; g < 2; g++) {
            __m128 w = c[g][3], nw = _mm_xor_ps(w, sign), a = c[g][p >> 1];
            all &= _mm_movemask_ps(p & 1 ? _mm_cmpgt_ps(a, w) : _mm_cmplt_ps(a, nw));
        }
        out |= all == 0xF;
    }
    if (out)
        return SL_RASTER_OUTSIDE;
    for (int g = 0; g < 2; g++) {
        __m128 w = c[g][3];
        near_cross |= _mm_movemask_ps(_mm_or_ps(_mm_cmplt_ps(c[g][2], _mm_xor_ps(w, sign)), _mm_cmplt_ps(w, nearw)));
    }
    if (near_cross)
        return SL_RASTER_VISIBLE;
    const __m128 hw = _mm_set1_ps(v->half_w), hh = _mm_set1_ps(v->half_h);
    __m128 sx[2], sy[2], d[2];
    for (int g = 0; g < 2; g++) {
        __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), c[g][3]);
        sx[g] = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(c[g][0], inv), hw), hw);
        sy[g] = _mm_sub_ps(hh, _mm_mul_ps(_mm_mul_ps(c[g][1], inv), hh));
        d[g] = v->depth == SL_RASTER_DEPTH_INV_W
                   ? inv
                   : _mm_sub_ps(_mm_set1_ps(0.5f), _mm_mul_ps(_mm_set1_ps(0.5f), _mm_mul_ps(c[g][2], inv)));
    }
    fin = _mm_and_ps(_mm_and_ps(_mm_and_ps(sse_finite(sx[0]), sse_finite(sx[1])),
                                _mm_and_ps(sse_finite(sy[0]), sse_finite(sy[1]))),
                     _mm_and_ps(sse_finite(d[0]), sse_finite(d[1])));
    if (_mm_movemask_ps(fin) != 0xF)
        return SL_RASTER_VISIBLE;
    int32_t x0, x1, y0, y1;
    touched(sse_hmin(_mm_min_ps(sx[0], sx[1])), sse_hmax(_mm_max_ps(sx[0], sx[1])), v->width, &x0, &x1);
    touched(sse_hmin(_mm_min_ps(sy[0], sy[1])), sse_hmax(_mm_max_ps(sy[0], sy[1])), v->height, &y0, &y1);
    return sl_raster_test_rect(ctx, x0, y0, x1, y1, sse_hmax(_mm_max_ps(d[0], d[1])));
}
#endif

sl_raster_result sl_raster_test_aabb(const sl_raster *ctx, const float box_min[3], const float box_max[3],
                                     const float world_to_clip[16])
{
    if (!ctx || !box_min || !box_max || !world_to_clip)
        return SL_RASTER_VISIBLE;
    for (int i = 0; i < 3; i++) {
        if (!isfinite(box_min[i]) || !isfinite(box_max[i]))
            return SL_RASTER_VISIBLE;
        if (box_min[i] > box_max[i])
            return SL_RASTER_OUTSIDE; /* an empty box */
    }
#if defined(SL_RT_X86)
    return test_aabb_sse2(ctx, box_min, box_max, world_to_clip);
#else
    return sl_rt_test_aabb_scalar(ctx, box_min, box_max, world_to_clip);
#endif
}

sl_raster_result sl_raster_test_triangles(const sl_raster *ctx, const float *vertices, uint32_t vertex_count,
                                          const uint32_t *indices, uint32_t triangle_count,
                                          uint32_t vertex_stride_bytes, const float model_to_clip[16],
                                          sl_raster_backface backface)
{
    if (!ctx || check_batch("query", vertices, indices, triangle_count, vertex_stride_bytes, model_to_clip,
                            backface, NULL) != SL_OK)
        return SL_RASTER_VISIBLE;
    sl_rt_batch b = {vertices, vertex_count, indices, triangle_count, vertex_stride_bytes, model_to_clip, backface};
    return sl_rt_query_batch(&ctx->view, ctx->k, &ctx->target, &b);
}

/* ---- debugging reads ---- */

static inline float pixel_depth(const sl_rt_target *t, int32_t x, int32_t y)
{
    size_t tile = (size_t)(y / SL_RT_TILE_H) * (size_t)t->tiles_x + (size_t)(x / SL_RT_TILE_W);
    int k = ((y % SL_RT_TILE_H) / SL_RT_SUB_H) * 4 + (x % SL_RT_TILE_W) / SL_RT_SUB_W;
    int bit = (y % SL_RT_SUB_H) * 8 + x % SL_RT_SUB_W;
    int32_t ty = y / SL_RT_TILE_H;
    uint32_t m = sl_rt_tile_mask(t, ty, tile)[k];
    const sl_rt_tile_depth *d = sl_rt_tile_depths(t, ty, tile);
    return (m >> bit) & 1u ? d->zm[k] : d->za[k];
}

sl_status sl_raster_read_depth(const sl_raster *ctx, float *out, size_t count, sl_error *err)
{
    if (!ctx || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: read_depth: NULL argument");
    size_t need = (size_t)ctx->opt.width * ctx->opt.height;
    if (count < need)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: read_depth: %zu floats given, %zu needed", count, need);
    for (int32_t y = 0; y < ctx->target.height; y++)
        for (int32_t x = 0; x < ctx->target.width; x++)
            out[(size_t)y * ctx->opt.width + (size_t)x] = pixel_depth(&ctx->target, x, y);
    return SL_OK;
}

sl_status sl_raster_read_subtile_depth(const sl_raster *ctx, float *out, size_t count, sl_error *err)
{
    if (!ctx || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: read_subtile_depth: NULL argument");
    size_t sw = (size_t)ctx->target.tiles_x * 4, sh = (size_t)ctx->target.tiles_y * 2;
    if (count < sw * sh)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: read_subtile_depth: %zu floats given, %zu needed",
                       count, sw * sh);
    for (size_t sy = 0; sy < sh; sy++)
        for (size_t sx = 0; sx < sw; sx++) {
            size_t tile = (sy / 2) * (size_t)ctx->target.tiles_x + sx / 4;
            size_t k = (sy % 2) * 4 + sx % 4;
            uint32_t m = sl_rt_tile_mask(&ctx->target, (int32_t)(sy / 2), tile)[k];
            const sl_rt_tile_depth *d = sl_rt_tile_depths(&ctx->target, (int32_t)(sy / 2), tile);
            /* the farthest pixel: za unless every pixel is in the mask (zm >= za) */
            out[sy * sw + sx] = m == ~0u ? d->zm[k] : d->za[k];
        }
    return SL_OK;
}

sl_status sl_raster_get_tile_info(const sl_raster *ctx, uint32_t tile_x, uint32_t tile_y, sl_raster_tile_info *out,
                                  sl_error *err)
{
    if (!ctx || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: tile_info: NULL argument");
    if (tile_x >= (uint32_t)ctx->target.tiles_x || tile_y >= (uint32_t)ctx->target.tiles_y)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "raster: tile_info: tile (%u, %u) outside %dx%d", tile_x,
                       tile_y, ctx->target.tiles_x, ctx->target.tiles_y);
    memset(out, 0, sizeof *out);
    size_t tile = (size_t)tile_y * (size_t)ctx->target.tiles_x + tile_x;
    const uint32_t *m = sl_rt_tile_mask(&ctx->target, (int32_t)tile_y, tile);
    const sl_rt_tile_depth *d = sl_rt_tile_depths(&ctx->target, (int32_t)tile_y, tile);
    for (int k = 0; k < SL_RT_SUBTILES; k++) {
        out->full_subtiles += d->za[k] > 0.0f;
        out->partial_subtiles += m[k] != 0;
    }
    out->min_depth = INFINITY;
    out->max_depth = -INFINITY;
    int32_t x0 = (int32_t)tile_x * SL_RT_TILE_W, y0 = (int32_t)tile_y * SL_RT_TILE_H;
    int32_t x1 = sl_rt_mini(x0 + SL_RT_TILE_W, ctx->target.width), y1 = sl_rt_mini(y0 + SL_RT_TILE_H, ctx->target.height);
    for (int32_t y = y0; y < y1; y++)
        for (int32_t x = x0; x < x1; x++) {
            float z = pixel_depth(&ctx->target, x, y);
            out->covered_pixels += z > 0.0f;
            out->min_depth = sl_rt_minf(out->min_depth, z);
            out->max_depth = sl_rt_maxf(out->max_depth, z);
        }
    return SL_OK;
}

static void add_counters(sl_raster_stats *s, const sl_rt_counters *c)
{
    s->triangles_submitted += c->submitted;
    s->rejected_index += c->rejected_index;
    s->rejected_nonfinite += c->rejected_nonfinite;
    s->culled_outside += c->culled_outside;
    s->culled_backface += c->culled_backface;
    s->degenerate += c->degenerate;
    s->clipped += c->clipped;
    s->triangles_rasterized += c->rasterized;
    s->bin_references += c->bin_refs;
}

void sl_raster_get_stats(const sl_raster *ctx, sl_raster_stats *out)
{
    if (!out)
        return;
    memset(out, 0, sizeof *out);
    if (!ctx)
        return;
    add_counters(out, &ctx->cnt);
    for (uint32_t s = 0; s < ctx->slots; s++)
        add_counters(out, &ctx->slot_cnt[s]);
}

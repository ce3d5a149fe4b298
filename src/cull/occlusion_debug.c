/* Debugging the occlusion methods the way engine developers debug a culler that dropped
 * something: dump the depth buffer and the method's pyramid as PNG, and record one frame's
 * occluders and queries to a file that replays deterministically on a fresh rasterizer (any
 * instruction set: the rasterizer is bit-identical across paths and thread counts).
 *
 * Recording format (docs/occlusion.md), little-endian:
 *   header  "SLOCCREC" u32 version=2, u32 width, u32 height, u32 depth (sl_raster_depth),
 *           u32 coverage (sl_raster_coverage), f32 near_w, u32 record_count
 *   record  u32 type: 1 = batch: u32 triangle_count, u32 backface, f32 matrix[16],
 *                         f32 vertices[9 * triangle_count] (3 vertices per triangle)
 *                     2 = query: i32 x0, y0, x1, y1, f32 depth, u32 result (sl_raster_result)
 *                     3 = mesh query: a batch's fields, then u32 result
 *   trailer u64 XXH3-64 (seed 0) of every byte before it (version 2; version 1 had none, so a
 *           damaged file could replay as "ok")
 * The replayer checks the checksum, then validates every field before it uses it. */
#include "cull/occlusion_debug.h"

#include "sightline/image.h"

#include <math.h>

/* ---- PNG dumps ---- */

/* log range of the non-zero finite values */
static void depth_range(const float *d, size_t n, double *lo, double *hi)
{
    *lo = INFINITY;
    *hi = -INFINITY;
    for (size_t i = 0; i < n; i++)
        if (d[i] > 0 && isfinite(d[i])) {
            double l = log((double)d[i]);
            *lo = fmin(*lo, l);
            *hi = fmax(*hi, l);
        }
}

static uint8_t depth_grey(float d, double lo, double hi)
{
    if (!(d > 0) || !isfinite(d))
        return 0;
    double t = hi > lo ? (log((double)d) - lo) / (hi - lo) : 1.0;
    return (uint8_t)(40.0 + 215.0 * fmin(fmax(t, 0.0), 1.0) + 0.5);
}

sl_status sl_occ_write_depth_png(const char *path, const float *depth, uint32_t width, uint32_t height,
                                 const sl_allocator *alloc, sl_error *err)
{
    size_t n = (size_t)width * height;
    uint8_t *px = sl_alloc(alloc, n ? n : 1);
    if (!px)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %ux%u pixels", path, width, height);
    double lo, hi;
    depth_range(depth, n, &lo, &hi);
    for (size_t i = 0; i < n; i++)
        px[i] = depth_grey(depth[i], lo, hi);
    sl_status st = sl_png_write(path, width, height, 1, px, 0, err);
    sl_free(alloc, px, n ? n : 1);
    return st;
}

sl_status sl_occ_write_levels_png(const char *path, const sl_occ_levels *lv, const sl_allocator *alloc, sl_error *err)
{
    if (!lv || lv->count == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: no pyramid levels", path);
    uint32_t W = lv->w[0], H = lv->h[0], right = 0, stack = 0;
    for (uint32_t i = 1; i < lv->count; i++) {
        right = SL_MAX(right, lv->w[i]);
        stack += lv->h[i];
    }
    W += right;
    H = SL_MAX(H, stack);
    size_t n = (size_t)W * H;
    uint8_t *px = sl_calloc(alloc, n ? n : 1, 1);
    if (!px)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %ux%u pixels", path, W, H);
    double lo = INFINITY, hi = -INFINITY;
    if (!lv->opacity)
        for (uint32_t i = 0; i < lv->count; i++) {
            double a, b;
            depth_range(lv->data[i], (size_t)lv->w[i] * lv->h[i], &a, &b);
            lo = fmin(lo, a);
            hi = fmax(hi, b);
        }
    uint32_t ox = 0, oy = 0;
    for (uint32_t i = 0; i < lv->count; i++) {
        if (i == 1) {
            ox = lv->w[0];
            oy = 0;
        }
        for (uint32_t y = 0; y < lv->h[i]; y++)
            for (uint32_t x = 0; x < lv->w[i]; x++) {
                float v = lv->data[i][(size_t)y * lv->w[i] + x];
                uint8_t g = lv->opacity ? (uint8_t)(255.0f * fminf(fmaxf(v, 0.0f), 1.0f) + 0.5f) : depth_grey(v, lo, hi);
                px[(size_t)(oy + y) * W + ox + x] = g;
            }
        if (i >= 1)
            oy += lv->h[i];
    }
    sl_status st = sl_png_write(path, W, H, 1, px, 0, err);
    sl_free(alloc, px, n ? n : 1);
    return st;
}

/* ---- recording ---- */

#define REC_MAGIC "SLOCCREC"
#define REC_VERSION 2u
#define REC_HEADER 36u
#define REC_TRAILER 8u
enum { REC_BATCH = 1, REC_QUERY = 2, REC_MESH_QUERY = 3 };

struct sl_occ_recorder {
    sl_allocator alloc;
    sl_array bytes;
    uint32_t records;
    bool failed;
};

static void put(sl_occ_recorder *r, const void *p, size_t n)
{
    if (!r->failed && !sl_array_push(&r->alloc, &r->bytes, 1, p, n))
        r->failed = true;
}
static void put_u32(sl_occ_recorder *r, uint32_t v) { put(r, &v, 4); }
static void put_f32(sl_occ_recorder *r, float v) { put(r, &v, 4); }

sl_status sl_occ_recorder_create(const sl_allocator *alloc, const sl_raster_options *ropt, sl_raster_depth depth,
                                 sl_occ_recorder **out, sl_error *err)
{
    sl_occ_recorder *r = sl_calloc(alloc, 1, sizeof *r);
    if (!r)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "record: out of memory");
    r->alloc = *alloc;
    put(r, REC_MAGIC, 8);
    put_u32(r, REC_VERSION);
    put_u32(r, ropt->width);
    put_u32(r, ropt->height);
    put_u32(r, (uint32_t)depth);
    put_u32(r, (uint32_t)ropt->coverage);
    put_f32(r, ropt->near_w);
    put_u32(r, 0); /* record count, patched at save */
    if (r->failed) {
        sl_occ_recorder_destroy(r);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "record: out of memory");
    }
    *out = r;
    return SL_OK;
}

void sl_occ_recorder_destroy(sl_occ_recorder *r)
{
    if (!r)
        return;
    sl_array_free(&r->alloc, &r->bytes, 1);
    sl_allocator a = r->alloc;
    sl_free(&a, r, sizeof *r);
}

void sl_occ_recorder_batch(sl_occ_recorder *r, const float *vertices, uint32_t stride, const uint32_t *indices,
                           uint32_t triangle_count, const float m[16], sl_raster_backface backface)
{
    put_u32(r, REC_BATCH);
    put_u32(r, triangle_count);
    put_u32(r, (uint32_t)backface);
    put(r, m, 64);
    /* the triangles expanded: the rasterizer's result depends only on each triple's values */
    for (size_t i = 0; i < 3 * (size_t)triangle_count; i++) {
        const float *v = (const float *)((const char *)vertices + (size_t)indices[i] * stride);
        put(r, v, 12);
    }
    r->records++;
}

void sl_occ_recorder_mesh_query(sl_occ_recorder *r, const float *vertices, uint32_t stride, const uint32_t *indices,
                                uint32_t triangle_count, const float m[16], sl_raster_backface backface,
                                sl_raster_result result)
{
    put_u32(r, REC_MESH_QUERY);
    put_u32(r, triangle_count);
    put_u32(r, (uint32_t)backface);
    put(r, m, 64);
    for (size_t i = 0; i < 3 * (size_t)triangle_count; i++) {
        const float *v = (const float *)((const char *)vertices + (size_t)indices[i] * stride);
        put(r, v, 12);
    }
    put_u32(r, (uint32_t)result);
    r->records++;
}

void sl_occ_recorder_query(sl_occ_recorder *r, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d,
                           sl_raster_result result)
{
    int32_t q[4] = {x0, y0, x1, y1};
    put_u32(r, REC_QUERY);
    put(r, q, 16);
    put_f32(r, d);
    put_u32(r, (uint32_t)result);
    r->records++;
}

sl_status sl_occ_recorder_save(sl_occ_recorder *r, const char *path, sl_error *err)
{
    if (r->failed)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory while recording", path);
    memcpy((char *)r->bytes.data + 32, &r->records, 4);
    uint64_t sum = sl_hash64(r->bytes.data, r->bytes.count, 0);
    sl_atomic_file f;
    sl_status st = sl_atomic_open(&r->alloc, path, &f, err);
    if (st != SL_OK)
        return st;
    sl_atomic_write(&f, r->bytes.data, r->bytes.count);
    sl_atomic_write(&f, &sum, sizeof sum);
    return sl_atomic_commit(&f, err);
}

/* ---- replay ---- */

typedef struct reader {
    const uint8_t *p;
    size_t size, off; /* size: the header and records, without the checksum */
    const char *path;
    size_t file_size;
} reader;

static bool rd(reader *r, void *out, size_t n)
{
    if (r->size - r->off < n)
        return false;
    memcpy(out, r->p + r->off, n);
    r->off += n;
    return true;
}

static sl_status truncated(const reader *r, const char *what, sl_error *err)
{
    return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: truncated %s (file is %zu bytes)", r->path, r->off, what,
                   r->file_size);
}

/* Walk the records; with ctx NULL only validate (and size the index buffer), else replay. */
static sl_status walk(reader *r, uint32_t records, sl_raster *ctx, uint32_t *idx, uint32_t *max_tris,
                      sl_occ_replay_report *rep, sl_error *err)
{
    for (uint32_t i = 0; i < records; i++) {
        size_t at = r->off;
        uint32_t type;
        if (!rd(r, &type, 4))
            return truncated(r, "record type", err);
        if (type == REC_BATCH || type == REC_MESH_QUERY) {
            bool query = type == REC_MESH_QUERY;
            uint32_t tris, backface;
            float m[16];
            if (!rd(r, &tris, 4) || !rd(r, &backface, 4) || !rd(r, m, 64))
                return truncated(r, query ? "mesh query header" : "batch header", err);
            if (backface > SL_RASTER_CULL_CCW)
                return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: record %u: back-face mode %u (0..2)", r->path,
                               at, i, backface);
            for (int k = 0; k < 16; k++)
                if (!isfinite(m[k]))
                    return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: record %u: matrix entry %d is not finite",
                                   r->path, at, i, k);
            if (tris > (r->size - r->off - (query ? 4 : 0)) / 36 || (query && r->size - r->off < 4))
                return sl_fail(err, SL_ERROR_FORMAT,
                               "%s: offset %zu: record %u: %u triangles but only %zu bytes remain", r->path, at, i,
                               tris, r->size - r->off);
            const float *v = (const float *)(r->p + r->off);
            if (query) {
                uint32_t res;
                memcpy(&res, r->p + r->off + (size_t)tris * 36, 4);
                if (res > SL_RASTER_OUTSIDE)
                    return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: record %u: query result %u (0..2)",
                                   r->path, at, i, res);
                if (ctx) {
                    sl_raster_result now = sl_raster_test_triangles(ctx, v, 3 * tris, idx, tris, 12, m,
                                                                    (sl_raster_backface)backface);
                    if (now != (sl_raster_result)res) {
                        if (rep->mismatches == 0)
                            rep->first_mismatch = rep->queries;
                        rep->mismatches++;
                    }
                    rep->occluded += res == SL_RASTER_OCCLUDED;
                    rep->queries++;
                }
                if (!ctx)
                    *max_tris = SL_MAX(*max_tris, tris);
                r->off += (size_t)tris * 36 + 4;
                continue;
            }
            if (ctx && tris) {
                /* the bytes are 4-byte aligned: the header and every record are multiples of 4 */
                sl_status st = sl_raster_render_triangles(ctx, v, 3 * tris, idx, tris, 12, m,
                                                          (sl_raster_backface)backface, err);
                if (st != SL_OK)
                    return st;
                rep->batches++;
                rep->triangles += tris;
            }
            if (!ctx)
                *max_tris = SL_MAX(*max_tris, tris);
            r->off += (size_t)tris * 36;
        } else if (type == REC_QUERY) {
            int32_t q[4];
            float d;
            uint32_t res;
            if (!rd(r, q, 16) || !rd(r, &d, 4) || !rd(r, &res, 4))
                return truncated(r, "query", err);
            if (res > SL_RASTER_OUTSIDE)
                return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: record %u: query result %u (0..2)", r->path,
                               at, i, res);
            if (ctx) {
                sl_raster_result now = sl_raster_test_rect(ctx, q[0], q[1], q[2], q[3], d);
                if (now != (sl_raster_result)res) {
                    if (rep->mismatches == 0)
                        rep->first_mismatch = rep->queries;
                    rep->mismatches++;
                }
                rep->occluded += res == SL_RASTER_OCCLUDED;
                rep->queries++;
            }
        } else {
            return sl_fail(err, SL_ERROR_FORMAT,
                           "%s: offset %zu: record %u has type %u (1 = batch, 2 = query, 3 = mesh query)",
                           r->path, at, i, type);
        }
    }
    if (r->off != r->size)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %zu: %zu bytes after the last of %u records", r->path, r->off,
                       r->size - r->off, records);
    return SL_OK;
}

sl_status sl_occ_replay(const char *path, sl_raster_isa isa, const sl_allocator *alloc, sl_occ_replay_report *out,
                        sl_error *err)
{
    alloc = sl_alloc_or_default(alloc);
    memset(out, 0, sizeof *out);
    out->first_mismatch = UINT32_MAX;
    uint8_t *data = NULL;
    size_t size = 0;
    sl_status st = sl_file_read_all(alloc, path, &data, &size, err);
    if (st != SL_OK)
        return st;
    st = sl_occ_replay_memory(data, size, path, isa, alloc, out, err);
    sl_free(alloc, data, size ? size : 1);
    return st;
}

sl_status sl_occ_replay_memory(const void *bytes, size_t file_size, const char *path, sl_raster_isa isa,
                               const sl_allocator *alloc, sl_occ_replay_report *out, sl_error *err)
{
    alloc = sl_alloc_or_default(alloc);
    memset(out, 0, sizeof *out);
    out->first_mismatch = UINT32_MAX;
    const uint8_t *data = bytes;
    if (!path)
        path = "<memory>";
    if (!data && file_size)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_occ_replay_memory: data is NULL");
    sl_status st = SL_OK;
    /* the records end where the checksum begins */
    size_t size = file_size >= REC_HEADER + REC_TRAILER ? file_size - REC_TRAILER : file_size;
    reader r = {data, size, 0, path, file_size};
    char magic[8];
    uint32_t version = 0, w = 0, h = 0, depth = 0, coverage = 0, records = 0;
    float near_w = 0;
    sl_raster *ctx = NULL;
    uint32_t *idx = NULL, max_tris = 0;
    float *buf = NULL;
    if (!rd(&r, magic, 8) || !rd(&r, &version, 4) || !rd(&r, &w, 4) || !rd(&r, &h, 4) || !rd(&r, &depth, 4) ||
        !rd(&r, &coverage, 4) || !rd(&r, &near_w, 4) || !rd(&r, &records, 4)) {
        st = truncated(&r, "header", err);
        goto done;
    }
    if (memcmp(magic, REC_MAGIC, 8) != 0) {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: offset 0: not an occlusion recording (magic is not %s)", path,
                     REC_MAGIC);
        goto done;
    }
    if (version != REC_VERSION) {
        st = sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: offset 8: version %u (this build reads %u%s)", path, version,
                     REC_VERSION,
                     version == 1             ? "; version 1 has no checksum: record the frame again"
                     : version > REC_VERSION ? "; a newer Sightline wrote it: replay it with that one, or record the "
                                               "frame again with this one"
                                             : "");
        goto done;
    }
    if (file_size < REC_HEADER + REC_TRAILER) {
        r.off = file_size;
        st = truncated(&r, "checksum", err);
        goto done;
    }
    uint64_t stored, sum = sl_hash64(data, size, 0);
    memcpy(&stored, data + size, sizeof stored);
    if (stored != sum) {
        st = sl_fail(err, SL_ERROR_FORMAT,
                     "%s: offset %zu: checksum mismatch (stored %016llx, content %016llx): the file is damaged", path,
                     size, (unsigned long long)stored, (unsigned long long)sum);
        goto done;
    }
    if (w < 1 || w > 8192 || h < 1 || h > 8192 || depth > SL_RASTER_DEPTH_LINEAR_Z ||
        coverage > SL_RASTER_COVERAGE_INNER || !(near_w > 0) || !isfinite(near_w)) {
        st = sl_fail(err, SL_ERROR_FORMAT,
                     "%s: offset 12: bad rasterizer options (size %ux%u, depth %u, coverage %u, near_w %g)", path, w,
                     h, depth, coverage, (double)near_w);
        goto done;
    }
    /* pass 1: validate everything and size the index buffer */
    if ((st = walk(&r, records, NULL, NULL, &max_tris, out, err)) != SL_OK)
        goto done;
    idx = sl_alloc(alloc, ((size_t)max_tris * 3 + 1) * sizeof(uint32_t));
    if (!idx) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %u triangles", path, max_tris);
        goto done;
    }
    for (size_t i = 0; i < (size_t)max_tris * 3; i++)
        idx[i] = (uint32_t)i;
    sl_raster_options o = sl_raster_default_options(w, h);
    o.isa = isa;
    o.depth = (sl_raster_depth)depth;
    o.coverage = (sl_raster_coverage)coverage;
    o.near_w = near_w;
    if ((st = sl_raster_create(&o, alloc, &ctx, err)) != SL_OK)
        goto done;
    out->width = w;
    out->height = h;
    /* pass 2: replay */
    r.off = REC_HEADER;
    if ((st = walk(&r, records, ctx, idx, &max_tris, out, err)) != SL_OK)
        goto done;
    buf = sl_alloc(alloc, (size_t)w * h * sizeof(float));
    if (!buf) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the depth buffer", path);
        goto done;
    }
    if ((st = sl_raster_read_depth(ctx, buf, (size_t)w * h, err)) != SL_OK)
        goto done;
    out->depth_hash = sl_hash64(buf, (size_t)w * h * sizeof(float), 0);
done:
    sl_free(alloc, buf, (size_t)w * h * sizeof(float));
    sl_free(alloc, idx, ((size_t)max_tris * 3 + 1) * sizeof(uint32_t));
    sl_raster_destroy(ctx);
    return st;
}

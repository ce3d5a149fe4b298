/* Sightline software occlusion rasterizer: a conservative, tiled, SIMD depth buffer for occlusion
 * culling on the CPU (docs/rasterizer.md has the full design).
 *
 * Occluders are indexed triangles with a model-to-clip matrix (OpenGL clip space, column-major
 * float[16] as in geom.h's sl_mat4) and a vertex stride; occludees are tested as screen rectangles,
 * projected boxes or triangle meshes. Every answer is conservative: the buffer never holds a depth
 * nearer than the occluders' true depth and never claims coverage they do not have (under the
 * documented fill rule), and a query never reports hidden what may be visible.
 *
 * Screen: width x height pixels, pixel (x, y) spans [x, x+1] x [y, y+1], row 0 at the TOP
 * (NDC y = +1), NDC x = -1 at the left edge. Sample point of a pixel: its centre (x+0.5, y+0.5).
 *
 * Depth convention (both: LARGER = NEARER, affine in screen space over a planar triangle, the
 * cleared buffer holds 0):
 *   SL_RASTER_DEPTH_INV_W     d = 1/w_clip. For perspective projections (d = 0 is infinitely far).
 *   SL_RASTER_DEPTH_LINEAR_Z  d = (1 - z_clip/w_clip)/2, i.e. 1 on the near plane, 0 on the far
 *                             plane. For orthographic projections (w constant), or any projection
 *                             whose depth may be mixed with it.
 * A point at depth d is hidden at pixel p when d < buffer(p) (strictly).
 *
 * Fill rule (SL_RASTER_COVERAGE_CENTER, default): vertices are snapped to 1/256 pixel (round to
 * nearest) and a pixel is covered when its centre lies inside the snapped triangle, a centre exactly
 * on an edge belonging to the triangle only for top and left edges (D3D/OpenGL rule): two
 * triangles sharing an edge cover each pixel along it exactly once, so meshes are watertight.
 * SL_RASTER_COVERAGE_INNER covers a pixel only when its whole square lies inside the unsnapped
 * triangle (strict, leaves cracks of up to 2 pixels along shared edges).
 *
 * Thread safety (stricter than the defaults in core.h, see docs/rasterizer.md):
 *  - sl_raster_clear, sl_raster_begin_frame, sl_raster_render_triangles, sl_raster_flush,
 *    sl_raster_reset_stats and sl_raster_destroy need exclusive use of the context.
 *  - sl_raster_bin_triangles is called from one thread at a time (the "front end"); it may run
 *    while other threads call sl_raster_render_bin.
 *  - sl_raster_render_bin may run concurrently on distinct bins (never twice on the same bin at the
 *    same time) and concurrently with sl_raster_bin_triangles.
 *  - Queries, sl_raster_read_* and sl_raster_get_* only read: any number of threads may call them
 *    together, but not while a writer above runs.
 * Results are bit-identical whatever the thread count, bin layout or instruction set. */
#ifndef SIGHTLINE_RASTER_H
#define SIGHTLINE_RASTER_H

#include "core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_raster sl_raster;

/* Instruction-set path of the kernels. AUTO picks the best the CPU supports at create time. */
typedef enum sl_raster_isa {
    SL_RASTER_ISA_AUTO = 0,
    SL_RASTER_ISA_SCALAR = 1, /* portable reference; every other path is tested bit-equal to it */
    SL_RASTER_ISA_SSE41 = 2,
    SL_RASTER_ISA_AVX2 = 3,
    SL_RASTER_ISA_AVX512 = 4  /* AVX-512 F+BW+VL+DQ */
} sl_raster_isa;

/* Back-face culling; winding as seen in NDC (x right, y up), OpenGL style: with CULL_CW the
 * counter-clockwise triangles are the front faces (glFrontFace(GL_CCW) + glCullFace(GL_BACK)). */
typedef enum sl_raster_backface {
    SL_RASTER_CULL_NONE = 0,
    SL_RASTER_CULL_CW = 1,
    SL_RASTER_CULL_CCW = 2
} sl_raster_backface;

typedef enum sl_raster_depth {
    SL_RASTER_DEPTH_INV_W = 0,   /* perspective */
    SL_RASTER_DEPTH_LINEAR_Z = 1 /* orthographic */
} sl_raster_depth;

typedef enum sl_raster_coverage {
    SL_RASTER_COVERAGE_CENTER = 0, /* pixel centre, top-left rule, watertight */
    SL_RASTER_COVERAGE_INNER = 1   /* whole pixel inside the unsnapped triangle */
} sl_raster_coverage;

typedef enum sl_raster_result {
    SL_RASTER_VISIBLE = 0,  /* may be visible (also the answer for doubtful input) */
    SL_RASTER_OCCLUDED = 1, /* hidden behind the occluders rendered so far */
    SL_RASTER_OUTSIDE = 2   /* outside the view frustum or the screen */
} sl_raster_result;

typedef struct sl_raster_options {
    uint32_t width, height;      /* pixels, 1..8192 each; padded internally to 32x8 tiles */
    uint32_t threads;            /* threads of the built-in pool used by render_triangles and flush,
                                    the caller included; 0 or 1 = single-threaded */
    sl_raster_isa isa;           /* AUTO, or force a path (create fails if the CPU lacks it) */
    sl_raster_depth depth;       /* initial depth mode (see sl_raster_begin_frame) */
    sl_raster_coverage coverage; /* occluder fill rule */
    float near_w;                /* geometry is clipped to w >= near_w (and to the near plane
                                    z >= -w); > 0, default 1e-5 */
    uint32_t bins_x, bins_y;     /* screen bins for multi-threaded rendering, 0 = automatic
                                    (full-width strips: 1 x min(16, tile rows)); each at most
                                    the tile count on that axis */
} sl_raster_options;

/* Per-frame counters (reset by clear, begin_frame and reset_stats). */
typedef struct sl_raster_stats {
    uint64_t triangles_submitted;  /* index triples handed to render/bin */
    uint64_t rejected_index;       /* an index >= vertex_count */
    uint64_t rejected_nonfinite;   /* a NaN/Inf vertex, or a vertex beyond float range after clipping */
    uint64_t culled_outside;       /* entirely outside the frustum or the screen's pixel centres */
    uint64_t culled_backface;
    uint64_t degenerate;           /* zero area after snapping */
    uint64_t clipped;              /* crossed the near plane or the guard band and were clipped */
    uint64_t triangles_rasterized; /* set-up triangles sent to the tiles (clipping can make several) */
    uint64_t bin_references;       /* triangle-bin pairs queued by binning */
} sl_raster_stats;

/* Summary of one 32x8 tile (8 subtiles of 8x4 pixels). */
typedef struct sl_raster_tile_info {
    uint32_t covered_pixels;  /* pixels of the screen whose depth is above the clear value */
    uint32_t full_subtiles;   /* subtiles whose whole-subtile depth is above the clear value */
    uint32_t partial_subtiles;/* subtiles holding a partial coverage mask */
    float min_depth;          /* farthest and nearest per-pixel depth over the tile's screen pixels */
    float max_depth;
} sl_raster_tile_info;

/* Default options for a width x height buffer: AUTO isa, one thread, INV_W depth, CENTER coverage. */
SL_API sl_raster_options sl_raster_default_options(uint32_t width, uint32_t height);

/* Create a context (a cleared buffer, the pool's threads if any); alloc may be NULL. */
SL_API sl_status sl_raster_create(const sl_raster_options *options, const sl_allocator *alloc, sl_raster **out,
                                  sl_error *err);
/* Destroy a context, joining its threads. NULL is fine. */
SL_API void sl_raster_destroy(sl_raster *ctx);

/* True when this CPU can run the path (AUTO and SCALAR always can). */
SL_API bool sl_raster_isa_available(sl_raster_isa isa);
/* Short name of a path: "auto", "scalar", "sse41", "avx2", "avx512". */
SL_API const char *sl_raster_isa_name(sl_raster_isa isa);
/* The path a context runs. */
SL_API sl_raster_isa sl_raster_get_isa(const sl_raster *ctx);
/* Width, height and tile grid (tiles are 32x8 pixels) of a context; any pointer may be NULL. */
SL_API void sl_raster_get_size(const sl_raster *ctx, uint32_t *width, uint32_t *height, uint32_t *tiles_x,
                               uint32_t *tiles_y);
/* Bytes held by the context: buffer, bins, triangle storage and the context itself. */
SL_API size_t sl_raster_memory(const sl_raster *ctx);

/* Empty the buffer (every pixel at depth 0), drop triangles binned but not rendered, reset stats. */
SL_API void sl_raster_clear(sl_raster *ctx);
/* Clear and switch the depth mode for the coming frame (a camera can change projection). */
SL_API sl_status sl_raster_begin_frame(sl_raster *ctx, sl_raster_depth depth, sl_error *err);

/* Render occluder triangles: vertex i is 3 floats (x, y, z) at byte offset i*vertex_stride_bytes
 * (stride >= 12, multiple of 4, vertices 4-byte aligned), indices has 3*triangle_count entries.
 * Triangles with an index >= vertex_count or a non-finite vertex are skipped and counted, so are
 * zero-area ones. Uses the built-in pool when the context has threads. Invalid arguments (NULL
 * pointers, bad stride, non-finite matrix, unknown backface) fail without rendering anything. */
SL_API sl_status sl_raster_render_triangles(sl_raster *ctx, const float *vertices, uint32_t vertex_count,
                                            const uint32_t *indices, uint32_t triangle_count,
                                            uint32_t vertex_stride_bytes, const float model_to_clip[16],
                                            sl_raster_backface backface, sl_error *err);

/* Number of screen bins. */
SL_API uint32_t sl_raster_bin_count(const sl_raster *ctx);
/* Front end of a caller-driven multi-threaded frame: transform, clip and snap the triangles
 * (arguments as for render_triangles) and queue them in the bins they overlap, in order. They reach
 * the buffer when their bins are rendered. Fails with SL_ERROR_OUT_OF_MEMORY when queue storage
 * cannot grow (the triangles queued until then stay queued; missing occluders are conservative). */
SL_API sl_status sl_raster_bin_triangles(sl_raster *ctx, const float *vertices, uint32_t vertex_count,
                                         const uint32_t *indices, uint32_t triangle_count,
                                         uint32_t vertex_stride_bytes, const float model_to_clip[16],
                                         sl_raster_backface backface, sl_error *err);
/* Render into bin `bin` every triangle queued for it so far and not yet rendered. Returns the number
 * of triangles rendered; an out-of-range bin renders nothing. */
SL_API uint32_t sl_raster_render_bin(sl_raster *ctx, uint32_t bin);
/* Render every queued triangle (with the pool's threads if any) and recycle the queue storage.
 * Call it (or render every bin) after the last bin_triangles of a frame, before querying. */
SL_API void sl_raster_flush(sl_raster *ctx);

/* Is anything in the half-open pixel rectangle [xmin,xmax) x [ymin,ymax) at depth nearest_depth or
 * nearer visible? OUTSIDE when the rectangle misses the screen or nearest_depth < 0 (beyond the far
 * plane / invalid); a NaN depth is VISIBLE. The fast path for callers that project themselves. */
SL_API sl_raster_result sl_raster_test_rect(const sl_raster *ctx, int32_t xmin, int32_t ymin, int32_t xmax,
                                            int32_t ymax, float nearest_depth);
/* Test a world-space box: its 8 corners projected with world_to_clip. OUTSIDE when all corners lie
 * beyond one frustum plane (far plane included); VISIBLE when it crosses the near plane (a camera
 * inside the box) or anything is non-finite; otherwise the rectangle of every pixel its projection
 * touches is tested at the depth of its nearest corner. */
SL_API sl_raster_result sl_raster_test_aabb(const sl_raster *ctx, const float box_min[3], const float box_max[3],
                                            const float world_to_clip[16]);
/* Test a triangle mesh without writing: each triangle is clipped to the near plane and rasterized
 * outward-conservatively (every pixel its area touches) at its nearest depth over each 8x4 block.
 * OUTSIDE when no triangle reaches the view; VISIBLE for invalid arguments or non-finite vertices. */
SL_API sl_raster_result sl_raster_test_triangles(const sl_raster *ctx, const float *vertices,
                                                 uint32_t vertex_count, const uint32_t *indices,
                                                 uint32_t triangle_count, uint32_t vertex_stride_bytes,
                                                 const float model_to_clip[16], sl_raster_backface backface);

/* Project a clip-space point the way occluders and queries are: pixel coordinates (row 0 at the
 * top) and depth in the context's convention. False (outputs untouched) when w < near_w or non-finite. */
SL_API bool sl_raster_project(const sl_raster *ctx, const float clip[4], float *x, float *y, float *depth);

/* Copy the buffer as width*height floats, row 0 first (top): each pixel's conservative depth (every
 * point farther than it is hidden). `count` must be at least width*height. */
SL_API sl_status sl_raster_read_depth(const sl_raster *ctx, float *out, size_t count, sl_error *err);
/* Copy the per-subtile depth (the farthest pixel of each 8x4 subtile) as (tiles_x*4) x (tiles_y*2)
 * floats, row-major, top first: the base level for a max-depth (HZB) pyramid. */
SL_API sl_status sl_raster_read_subtile_depth(const sl_raster *ctx, float *out, size_t count, sl_error *err);
/* Summary of tile (tile_x, tile_y). */
SL_API sl_status sl_raster_get_tile_info(const sl_raster *ctx, uint32_t tile_x, uint32_t tile_y,
                                         sl_raster_tile_info *out, sl_error *err);
/* Counters since the last clear/begin_frame/reset_stats. */
SL_API void sl_raster_get_stats(const sl_raster *ctx, sl_raster_stats *out);
SL_API void sl_raster_reset_stats(sl_raster *ctx);

#ifdef __cplusplus
}
#endif
#endif

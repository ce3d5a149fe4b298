/* Debugging the occlusion methods (occlusion_debug.c): depth buffers and pyramid levels written as
 * PNG, one frame's occluders and queries recorded to a file, and its replay. */
#ifndef SL_CULL_OCCLUSION_DEBUG_H
#define SL_CULL_OCCLUSION_DEBUG_H

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/raster.h"

typedef struct sl_occ_recorder sl_occ_recorder;

/* Images to debug (a pyramid, a grid): level i is w[i] x h[i] floats. */
typedef struct sl_occ_levels {
    uint32_t count;
    const float *const *data;
    const uint32_t *w, *h;
    bool opacity;             /* values are opacities in [0,1] (else depths, larger = nearer) */
} sl_occ_levels;

/* Write a depth buffer (width x height floats, larger = nearer, 0 = empty) as a grey PNG: empty
 * pixels black, the rest from dark (far) to white (near) on a logarithmic ramp. */
sl_status sl_occ_write_depth_png(const char *path, const float *depth, uint32_t width, uint32_t height,
                                 const sl_allocator *alloc, sl_error *err);
/* Write pyramid levels in one grey PNG, mipmap style: level 0 on the left, the coarser levels
 * stacked top to bottom to its right, each at its own size (depths on the ramp of
 * sl_occ_write_depth_png, opacities from black 0 to white 1). */
sl_status sl_occ_write_levels_png(const char *path, const sl_occ_levels *levels, const sl_allocator *alloc,
                                  sl_error *err);

/* A recording of one frame: the rasterizer's options, every occluder batch (triangles expanded
 * to 3 vertices each, the model-to-clip matrix, the back-face mode) and every rectangle query with
 * its answer, in order. The file format is in docs/occlusion.md. */
sl_status sl_occ_recorder_create(const sl_allocator *alloc, const sl_raster_options *ropt, sl_raster_depth depth,
                                 sl_occ_recorder **out, sl_error *err);
void sl_occ_recorder_destroy(sl_occ_recorder *rec);
/* Append a batch (vertices at byte stride, indices) or a query; failures are sticky. */
void sl_occ_recorder_batch(sl_occ_recorder *rec, const float *vertices, uint32_t vertex_stride_bytes,
                           const uint32_t *indices, uint32_t triangle_count, const float m[16],
                           sl_raster_backface backface);
void sl_occ_recorder_query(sl_occ_recorder *rec, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d,
                           sl_raster_result result);
/* A triangle-mesh query (sl_raster_test_triangles) with its answer. */
void sl_occ_recorder_mesh_query(sl_occ_recorder *rec, const float *vertices, uint32_t vertex_stride_bytes,
                                const uint32_t *indices, uint32_t triangle_count, const float m[16],
                                sl_raster_backface backface, sl_raster_result result);
/* Write the recording atomically. */
sl_status sl_occ_recorder_save(sl_occ_recorder *rec, const char *path, sl_error *err);

/* sl_occ_replay_report and sl_occ_replay: sightline/cull.h. */
/* The same on a recording held in memory (`path` names it in messages; the fuzz target). */
sl_status sl_occ_replay_memory(const void *data, size_t size, const char *path, sl_raster_isa isa,
                               const sl_allocator *alloc, sl_occ_replay_report *out, sl_error *err);

#endif

/* The rasterizer wrapper of the occlusion methods (sl_occ_raster): the conservative rasterizer at
 * the view's resolution, proxies rendered once a frame, queries counted and recorded, the debug
 * frame's recording and dumps. */
#ifndef SL_CULL_OCCLUSION_RASTER_H
#define SL_CULL_OCCLUSION_RASTER_H

#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion_debug.h"
#include "sightline/raster.h"

/* ---- the rasterizer wrapper ---- */

typedef struct sl_occ_raster {
    sl_allocator alloc;
    sl_raster *ctx;
    uint32_t width, height;
    uint32_t threads, isa;
    bool erode;               /* res=any: occluders by inner coverage (render_prism_hull or _eroded,
                                 MESH and SCENE_MESH proxies shrunk by the pixel footprint) */
    bool hull;                /* res=any, inner=hull: prisms by their convex silhouettes */
    uint32_t *batch;          /* prism indices of one batch */
    size_t batch_cap;         /* in indices */
    float *shrunk;            /* one MESH proxy's triangles shrunk on screen, 3 vertices x 3 floats each */
    uint32_t *shrunk_idx;     /* 0, 1, 2, ... */
    size_t shrunk_cap;        /* in triangles: the largest MESH proxy */
    struct sl_occ_screen_vertex *shrunk_proj; /* its vertices projected */
    size_t shrunk_proj_cap;   /* in vertices */
    uint32_t *stamp;          /* per proxy: frame + 1 when rendered this frame */
    uint32_t proxy_count;
    uint32_t frame_id;        /* increments per frame (never 0 in stamp) */
    uint64_t frame;           /* cull calls so far */
    /* counters of the frame */
    uint64_t queries, pixel_queries, occluders_rendered, triangles_rendered;
    /* debugging */
    const char *dump, *record;
    uint32_t debug_frame;
    sl_occ_recorder *rec;     /* non-NULL while frame debug_frame is being recorded */
    char dump_path[256], record_path[256];
} sl_occ_raster;

sl_status sl_occ_raster_init(sl_occ_raster *r, const sl_occ_common *c, const sl_occ_set *set,
                             const sl_allocator *alloc, sl_error *err);
void sl_occ_raster_free(sl_occ_raster *r);
/* Start a frame: (re)create the context at the camera's resolution when it changed, clear it in
 * the view's depth mode, start recording if this is the debug frame. */
sl_status sl_occ_raster_begin(sl_occ_raster *r, const sl_occ_view *v, sl_error *err);
/* Render proxies (skipping those already rendered this frame): prisms in one batch (threaded when
 * large), meshes one call each. Returns the number rendered. */
uint32_t sl_occ_raster_render(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const uint32_t *proxies,
                              uint32_t n);
/* Was the proxy rendered this frame? */
static inline bool sl_occ_raster_rendered(const sl_occ_raster *r, uint32_t proxy)
{
    return r->stamp[proxy] == r->frame_id;
}
/* test_rect through the wrapper: counted (queries, pixels) and recorded. */
sl_raster_result sl_occ_raster_test(sl_occ_raster *r, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d);
/* Test an object by its own triangles (sl_raster_test_triangles, two-sided, with its current
 * transform): counted as one query and recorded. */
sl_raster_result sl_occ_raster_test_object(sl_occ_raster *r, sl_scene scene, const sl_occ_view *v, uint32_t object);
/* End a frame: on the debug frame, write the recording and the dumps (the pyramid given as
 * `levels` float images, level i of size w_i x h_i, may be NULL). Debug output failures are
 * reported as errors of the cull call. (sl_occ_levels: occlusion_debug.h.) */
sl_status sl_occ_raster_end(sl_occ_raster *r, const sl_occ_levels *levels, sl_error *err);

#endif

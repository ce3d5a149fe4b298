/* Screen pyramids over the rasterizer's 8x4 subtiles (hzb's max-depth pyramid, hom's opacity
 * pyramid): layout, base level from the depth buffer, as debugging levels. */
#ifndef SL_CULL_OCCLUSION_PYRAMID_H
#define SL_CULL_OCCLUSION_PYRAMID_H

#include "cull/occlusion_debug.h"
#include "sightline/raster.h"

/* ---- screen pyramids (hzb's max-depth pyramid, hom's opacity pyramid) ---- */

#define SL_OCC_MAX_LEVELS 24

/* Levels over the rasterizer's 8x4 subtiles: level 0 has one entry per subtile of the tiled
 * buffer, each next level half as many per axis (rounded up), down to 1x1. */
typedef struct sl_occ_pyramid {
    float *data;
    size_t cap;               /* entries allocated */
    uint32_t levels;
    uint32_t lw[SL_OCC_MAX_LEVELS], lh[SL_OCC_MAX_LEVELS];
    size_t loff[SL_OCC_MAX_LEVELS];
    const float *level_ptr[SL_OCC_MAX_LEVELS];
    uint32_t w, h;            /* screen size it was laid out for (0: none) */
} sl_occ_pyramid;

/* Lay the pyramid out for the rasterizer of a w x h screen; allocates only when the size changed
 * (*resized then true; may be NULL). */
sl_status sl_occ_pyramid_size(sl_occ_pyramid *p, const sl_allocator *alloc, const sl_raster *ctx, uint32_t w,
                              uint32_t h, bool *resized, sl_error *err);
void sl_occ_pyramid_free(sl_occ_pyramid *p, const sl_allocator *alloc);
/* Level 0 from the buffer: the farthest depth of each subtile (sl_raster_read_subtile_depth). */
void sl_occ_pyramid_read_base(sl_occ_pyramid *p, const sl_raster *ctx);
/* The pyramid as debugging levels. */
static inline sl_occ_levels sl_occ_pyramid_levels(const sl_occ_pyramid *p, bool opacity)
{
    sl_occ_levels l = {p->levels, p->level_ptr, p->lw, p->lh, opacity};
    return l;
}

#endif

/* Screen pyramids over the rasterizer's subtiles (pyramid.h). */
#include "pyramid.h"

/* ---- screen pyramids ---- */

sl_status sl_occ_pyramid_size(sl_occ_pyramid *p, const sl_allocator *alloc, const sl_raster *ctx, uint32_t w,
                              uint32_t h, bool *resized, sl_error *err)
{
    if (resized)
        *resized = false;
    if (p->data && p->w == w && p->h == h)
        return SL_OK;
    uint32_t tx, ty;
    sl_raster_get_size(ctx, NULL, NULL, &tx, &ty);
    uint32_t lw = tx * 4, lh = ty * 2; /* 8x4 subtiles of 32x8 tiles */
    size_t total = 0;
    p->levels = 0;
    for (;;) {
        p->lw[p->levels] = lw;
        p->lh[p->levels] = lh;
        p->loff[p->levels] = total;
        total += (size_t)lw * lh;
        p->levels++;
        if ((lw == 1 && lh == 1) || p->levels == SL_OCC_MAX_LEVELS)
            break;
        lw = (lw + 1) / 2;
        lh = (lh + 1) / 2;
    }
    sl_free(alloc, p->data, p->cap * sizeof(float));
    p->data = sl_alloc(alloc, total * sizeof(float));
    p->cap = p->data ? total : 0;
    p->w = p->h = 0;
    if (!p->data)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for a %zu-entry pyramid", total);
    for (uint32_t i = 0; i < p->levels; i++)
        p->level_ptr[i] = p->data + p->loff[i];
    p->w = w;
    p->h = h;
    if (resized)
        *resized = true;
    return SL_OK;
}

void sl_occ_pyramid_free(sl_occ_pyramid *p, const sl_allocator *alloc)
{
    sl_free(alloc, p->data, p->cap * sizeof(float));
    memset(p, 0, sizeof *p);
}

void sl_occ_pyramid_read_base(sl_occ_pyramid *p, const sl_raster *ctx)
{
    (void)sl_raster_read_subtile_depth(ctx, p->data, (size_t)p->lw[0] * p->lh[0], NULL);
}

/* Scalar reference kernels of the occlusion rasterizer: the definition every SIMD path must match
 * bit for bit (tests/test_raster.c checks it). The arithmetic is spelled out in
 * raster_internal.h (sl_rt_tri, sl_rt_merge, sl_rt_subtile_hides). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#include <math.h>

/* Covered column span [xl[r], xr[r]) of the 8 pixel rows j0..j0+7 (empty when xl >= xr). */
static void row_spans(const sl_rt_tri *t, int32_t j0, int32_t xl[8], int32_t xr[8])
{
    double c0 = t->col0, c1 = t->col1;
    for (int r = 0; r < 8; r++) {
        int32_t te[3];
        for (int e = 0; e < 3; e++) {
            /* exact integers: only the division rounds, and its ceiling is exact */
            double num = (t->num0[e] + (double)j0 * t->nstep[e]) + (double)r * t->nstep[e];
            double q = ceil(num / t->den[e]);
            q = q < c0 ? c0 : (q > c1 ? c1 : q);
            te[e] = (int32_t)q;
        }
        int32_t l = sl_rt_maxi(te[0], sl_rt_mini(te[2], t->cap));
        int32_t h = sl_rt_mini(te[1], sl_rt_maxi(te[2], t->cap));
        int32_t j = j0 + r;
        if (j < t->row0 || j >= t->row1)
            h = l;
        xl[r] = l;
        xr[r] = h;
    }
}

/* Tile columns [*ta, *tb) holding the non-empty spans, within [tx0, tx1); false if none. */
static bool span_tiles(const int32_t xl[8], const int32_t xr[8], int32_t tx0, int32_t tx1, int32_t *ta, int32_t *tb)
{
    int32_t lo = INT32_MAX, hi = INT32_MIN;
    for (int r = 0; r < 8; r++)
        if (xl[r] < xr[r]) {
            lo = sl_rt_mini(lo, xl[r]);
            hi = sl_rt_maxi(hi, xr[r]);
        }
    if (lo >= hi)
        return false;
    *ta = sl_rt_maxi(tx0, lo / SL_RT_TILE_W);
    *tb = sl_rt_mini(tx1, (hi - 1) / SL_RT_TILE_W + 1);
    return *ta < *tb;
}

/* Subtile coverage masks of the tile starting at pixel column x. */
static void tile_masks(const int32_t xl[8], const int32_t xr[8], int32_t x, uint32_t sub[8])
{
    uint32_t rows[8];
    for (int r = 0; r < 8; r++)
        rows[r] = sl_rt_ones_from(sl_rt_maxi(xl[r] - x, 0)) & ~sl_rt_ones_from(sl_rt_maxi(xr[r] - x, 0));
    sl_rt_rows_to_subtiles(rows, sub);
}

static void raster_scalar(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                          int32_t ty1)
{
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, xl[8], xr[8], ta, tb;
        row_spans(t, j0, xl, xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        for (int32_t tx = ta; tx < tb; tx++) {
            int32_t x = tx * SL_RT_TILE_W;
            uint32_t sub[8];
            tile_masks(xl, xr, x, sub);
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)tx;
            uint32_t *m = tg->mask + ti * SL_RT_SUBTILES;
            sl_rt_tile_depth *d = &tg->depth[ti];
            for (int k = 0; k < SL_RT_SUBTILES; k++) {
                float z = sl_rt_maxf(zt + t->off[k], t->zclamp);
                sl_rt_merge(sub[k], z, &m[k], &d->za[k], &d->zm[k]);
            }
        }
    }
}

static bool query_scalar(const sl_rt_target *tg, const sl_rt_tri *t)
{
    int32_t ty0 = t->row0 / SL_RT_TILE_H, ty1 = (t->row1 - 1) / SL_RT_TILE_H + 1;
    int32_t tx0 = t->col0 / SL_RT_TILE_W, tx1 = (t->col1 - 1) / SL_RT_TILE_W + 1;
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, xl[8], xr[8], ta, tb;
        row_spans(t, j0, xl, xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        for (int32_t tx = ta; tx < tb; tx++) {
            int32_t x = tx * SL_RT_TILE_W;
            uint32_t sub[8];
            tile_masks(xl, xr, x, sub);
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)tx;
            const uint32_t *m = sl_rt_tile_mask(tg, ty, ti);
            const sl_rt_tile_depth *d = sl_rt_tile_depths(tg, ty, ti);
            for (int k = 0; k < SL_RT_SUBTILES; k++) {
                float z = sl_rt_minf(zt + t->off[k], t->zclamp);
                if (!sl_rt_subtile_hides(sub[k], z, m[k], d->za[k], d->zm[k]))
                    return true;
            }
        }
    }
    return false;
}

static bool rect_scalar(const sl_rt_target *tg, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float dz)
{
    for (int32_t ty = y0 / SL_RT_TILE_H; ty <= (y1 - 1) / SL_RT_TILE_H; ty++) {
        uint32_t valid[8];
        for (int r = 0; r < 8; r++) {
            int32_t j = ty * SL_RT_TILE_H + r;
            valid[r] = j >= y0 && j < y1 ? ~0u : 0u;
        }
        for (int32_t tx = x0 / SL_RT_TILE_W; tx <= (x1 - 1) / SL_RT_TILE_W; tx++) {
            int32_t x = tx * SL_RT_TILE_W;
            uint32_t cols = sl_rt_ones_from(sl_rt_maxi(x0 - x, 0)) & ~sl_rt_ones_from(sl_rt_maxi(x1 - x, 0));
            uint32_t rows[8], sub[8];
            for (int r = 0; r < 8; r++)
                rows[r] = cols & valid[r];
            sl_rt_rows_to_subtiles(rows, sub);
            size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)tx;
            const uint32_t *m = tg->mask + ti * SL_RT_SUBTILES;
            const sl_rt_tile_depth *d = &tg->depth[ti];
            for (int k = 0; k < SL_RT_SUBTILES; k++)
                if (!sl_rt_subtile_hides(sub[k], dz, m[k], d->za[k], d->zm[k]))
                    return false;
        }
    }
    return true;
}

static void render_scalar(const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0, int32_t tx1,
                          int32_t ty0, int32_t ty1)
{
    sl_rt_render_each(raster_scalar, tg, mode, p, n, tx0, tx1, ty0, ty1);
}

const sl_rt_kernels sl_rt_kernels_scalar = {SL_RASTER_ISA_SCALAR, raster_scalar, query_scalar, rect_scalar,
                                            sl_rt_front_prims, render_scalar};

/* AVX2 kernels of the occlusion rasterizer. One 256-bit register holds the 8 pixel rows of a tile
 * row (coverage spans, row masks) or the 8 subtiles of a tile (masks, depths); the row masks are
 * turned into subtile masks with one byte shuffle. Same results as raster_scalar.c, bit for bit:
 * exact integer/double coverage, the same float operations in the same order, and no FMA (the
 * target is "avx2" alone and contraction is off). Compiled for the baseline; run only when
 * __builtin_cpu_supports("avx2"). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#if defined(SL_RT_X86)
#define AVX2 __attribute__((target("avx2")))
#define SL_RT_T AVX2
#define SL_RT_NAME(n) n##_avx2
#include "raster/raster_simd8.h"

/* One tile with partial coverage. */
AVX2 static inline void partial_tile(const sl_rt_target *tg, const sl_rt_tri *t, __m256i xl, __m256i xr, size_t row,
                                     int32_t tx, float zrow, __m256 off, __m256 zclamp, __m256i ctl)
{
    int32_t x = tx * SL_RT_TILE_W;
    size_t ti = row + (size_t)tx;
    float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
    __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt), off), zclamp);
    merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, x), ctl), z, tg->mask + ti * SL_RT_SUBTILES, &tg->depth[ti]);
}

AVX2 static void raster_avx2(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                             int32_t ty1)
{
    const __m256i ctl = transpose_ctl();
    const __m256 off = _mm256_loadu_ps(t->off), zclamp = _mm256_set1_ps(t->zclamp);
    /* past four tile rows, stepping the thresholds beats dividing for every row */
    bool tall = ty1 - ty0 > 4;
    edge_dda dda[3];
    if (tall)
        for (int e = 0; e < 3; e++)
            dda_init(&dda[e], t, e, ty0 * SL_RT_TILE_H);
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, ta, tb, ia, ib;
        __m256i xl, xr;
        if (tall)
            row_spans_dda(t, dda, j0, &xl, &xr);
        else
            row_spans(t, j0, &xl, &xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb, &ia, &ib))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        size_t row = (size_t)ty * (size_t)tg->tiles_x;
        /* partial tiles on the left, fully covered ones, partial ones on the right: three loops
         * rather than a per-tile test that mispredicts at both ends of the interior */
        int32_t ea = ia < ib ? ia : tb, eb = ia < ib ? ib : tb, tx = ta;
        for (; tx < ea; tx++)
            partial_tile(tg, t, xl, xr, row, tx, zrow, off, zclamp, ctl);
        for (; tx < eb; tx++) {
            size_t ti = row + (size_t)tx;
            float zt = (t->z0 + t->zdx * (float)(tx * SL_RT_TILE_W - t->x_ref)) + zrow;
            merge_full_tile(_mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt), off), zclamp),
                            tg->mask + ti * SL_RT_SUBTILES, &tg->depth[ti]);
        }
        for (; tx < tb; tx++)
            partial_tile(tg, t, xl, xr, row, tx, zrow, off, zclamp, ctl);
    }
}

const sl_rt_kernels sl_rt_kernels_avx2 = {SL_RASTER_ISA_AVX2, raster_avx2, query_avx2, rect_avx2};

#endif

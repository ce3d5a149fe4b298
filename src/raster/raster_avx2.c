/* AVX2 kernels of the occlusion rasterizer. One 256-bit register holds the 8 pixel rows of a tile
 * row (coverage spans, row masks) or the 8 subtiles of a tile (masks, depths); the row masks are
 * turned into subtile masks with one byte shuffle. The front end and the small-triangle setup
 * work on 8 triangles at a time (raster_batch8.h); small triangles then take raster_cols (one to
 * three tiles wide: a fixed number of tiles per tile row) or raster_small, the others the general
 * kernel raster_avx2. Same results as raster_scalar.c, bit for bit: exact coverage, the same float
 * operations in the same order, and no FMA (the target is "avx2" alone and contraction is off).
 * Compiled for the baseline; run only when __builtin_cpu_supports("avx2"). */
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
#include "raster/raster_batch8.h"

/* One tile with partial coverage: zc = the tile column's z0 + zdx*(float)(x - x_ref). */
AVX2 static inline __attribute__((always_inline)) void partial_tile(uint32_t *mask, sl_rt_tile_depth *depth,
                                                                     __m256i xl, __m256i xr, size_t row, int32_t tx,
                                                                     float zc, float zrow, __m256 off, __m256 zclamp,
                                                                     __m256i ctl)
{
    size_t ti = row + (size_t)tx;
    __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zc + zrow), off), zclamp);
    merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, tx * SL_RT_TILE_W), ctl), z, mask + ti * SL_RT_SUBTILES,
               &depth[ti]);
}

/* The general kernel (any triangle sl_rt_setup produces): exact stepped thresholds, then per tile
 * row the partial tiles on the left, the fully covered ones, the partial ones on the right. The
 * next tile row's spans are computed before the current row's tiles (see raster_avx512.c), and
 * each tile column's z0 + zdx*(float)(x - x_ref) once per triangle. */
AVX2 static void raster_avx2(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                             int32_t ty1)
{
    const __m256i ctl = transpose_ctl();
    const __m256 off = _mm256_loadu_ps(t->off), zclamp = _mm256_set1_ps(t->zclamp);
    const float zdy = t->zdy;
    const int32_t y_ref = t->y_ref;
    uint32_t *const mask = tg->mask;
    sl_rt_tile_depth *const depth = tg->depth;
    const size_t tiles_x = (size_t)tg->tiles_x;
    /* zcol[tx - tx0] = z0 + zdx*(float)(32*tx - x_ref), 8 columns at a time (tx1 - tx0 <= 256) */
    float zcol[SL_RT_MAX_DIM / SL_RT_TILE_W + 8];
    {
        const __m256 z0 = _mm256_set1_ps(t->z0), zdx = _mm256_set1_ps(t->zdx);
        __m256i xv = _mm256_add_epi32(_mm256_set1_epi32(tx0 * SL_RT_TILE_W - t->x_ref),
                                      _mm256_setr_epi32(0, 32, 64, 96, 128, 160, 192, 224));
        for (int32_t c = 0; c < tx1 - tx0; c += 8) {
            _mm256_storeu_ps(zcol + c, _mm256_add_ps(z0, _mm256_mul_ps(zdx, _mm256_cvtepi32_ps(xv))));
            xv = _mm256_add_epi32(xv, _mm256_set1_epi32(8 * SL_RT_TILE_W));
        }
    }
    const float *zc = zcol - tx0;
    vdda dda;
    vdda_init(&dda, t, ty0 * SL_RT_TILE_H);
    grow g;
    grow_at(&dda, t, ty0, ty1, tx0, tx1, &g);
    for (int32_t ty = ty0; ty < ty1; ty++) {
        grow n;
        grow_at(&dda, t, ty + 1, ty1, tx0, tx1, &n);
        if (g.any) {
            float zrow = zdy * (float)(ty * SL_RT_TILE_H - y_ref);
            size_t row = (size_t)ty * tiles_x;
            int32_t ea = g.ia < g.ib ? g.ia : g.tb, eb = g.ia < g.ib ? g.ib : g.tb, tx = g.ta;
            for (; tx < ea; tx++)
                partial_tile(mask, depth, g.xl, g.xr, row, tx, zc[tx], zrow, off, zclamp, ctl);
            for (; tx < eb; tx++) {
                size_t ti = row + (size_t)tx;
                merge_full_tile(_mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zc[tx] + zrow), off), zclamp),
                                mask + ti * SL_RT_SUBTILES, &depth[ti]);
            }
            for (; tx < g.tb; tx++)
                partial_tile(mask, depth, g.xl, g.xr, row, tx, zc[tx], zrow, off, zclamp, ctl);
        }
        g = n;
    }
}

/* A small triangle (raster_batch8.h): float thresholds, then the tiles of each tile row; rows are
 * computed one ahead (see raster_avx512.c). */
AVX2 static inline __attribute__((always_inline)) void raster_small(const sl_rt_target *tg, small_tri *t)
{
    const __m256i ctl = transpose_ctl();
    const float zdy = t->zdy;
    const int32_t y_ref = t->y_ref, ox = t->ox;
    uint32_t *const mask = tg->mask;
    sl_rt_tile_depth *const depth = tg->depth;
    const size_t tiles_x = (size_t)tg->tiles_x;
    /* each tile column's z0 + zdx*(float)(x - x_ref), as in raster_avx2 */
    float zcol[SL_RT_MAX_DIM / SL_RT_TILE_W + 8];
    {
        const __m256 z0 = _mm256_set1_ps(t->z0), zdx = _mm256_set1_ps(t->zdx);
        __m256i xv = _mm256_add_epi32(_mm256_set1_epi32(t->tx0 * SL_RT_TILE_W - t->x_ref),
                                      _mm256_setr_epi32(0, 32, 64, 96, 128, 160, 192, 224));
        for (int32_t c = 0; c < t->tx1 - t->tx0; c += 8) {
            _mm256_storeu_ps(zcol + c, _mm256_add_ps(z0, _mm256_mul_ps(zdx, _mm256_cvtepi32_ps(xv))));
            xv = _mm256_add_epi32(xv, _mm256_set1_epi32(8 * SL_RT_TILE_W));
        }
    }
    const float *zc = zcol - t->tx0;
    small_row cur;
    small_row_at(t, t->ty0, &cur);
    for (int32_t ty = t->ty0; ty < t->ty1; ty++) {
        small_row nxt = cur;
        if (ty + 1 < t->ty1)
            small_row_at(t, ty + 1, &nxt);
        if (cur.any) {
            float zrow = zdy * (float)(ty * SL_RT_TILE_H - y_ref);
            size_t row = (size_t)ty * tiles_x;
            for (int32_t tx = cur.ta; tx < cur.tb; tx++) {
                size_t ti = row + (size_t)tx;
                __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zc[tx] + zrow), t->off), t->zclamp);
                merge_tile(_mm256_shuffle_epi8(row_masks(cur.xl, cur.xr, tx * SL_RT_TILE_W - ox), ctl), z,
                           mask + ti * SL_RT_SUBTILES, &depth[ti]);
            }
        }
        cur = nxt;
    }
}

/* Set up prims in groups of 8; small ones take raster_small, each loaded (with its first tile row)
 * before the previous one is rasterized, the others the reference setup and the general kernel. */
/* Set up prims in groups of 8: small ones take raster_small, the others the reference setup and
 * the general kernel. */
AVX2 static void render_avx2(const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0,
                             int32_t tx1, int32_t ty0, int32_t ty1)
{
    for (uint32_t i = 0; i < n; i += 8) {
        uint32_t k = n - i < 8 ? n - i : 8;
        small8 s;
        unsigned empty, small = setup8(p + i, k, mode, &s, &empty);
        for (uint32_t l = 0; l < k; l++) {
            if (small >> l & 1) {
                small_tri st;
                if (!small_load(&s, (int)l, tx0, tx1, ty0, ty1, &st))
                    continue;
                if (st.tx1 - st.tx0 == 1)
                    raster_cols(tg, &st, 1);
                else if (st.tx1 - st.tx0 == 2)
                    raster_cols(tg, &st, 2);
                else if (st.tx1 - st.tx0 == 3)
                    raster_cols(tg, &st, 3);
                else
                    raster_small(tg, &st);
            } else if (!(empty >> l & 1)) {
                sl_rt_render_each(raster_avx2, tg, mode, p + i + l, 1, tx0, tx1, ty0, ty1);
            }
        }
    }
}

const sl_rt_kernels sl_rt_kernels_avx2 = {SL_RASTER_ISA_AVX2, raster_avx2, query_avx2, rect_avx2, front_avx2,
                                          render_avx2};

#endif

/* AVX-512 kernels of the occlusion rasterizer (F, BW, VL, DQ). The row spans and queries are the
 * 8-lane code of raster_simd8.h; the tile loop takes two adjacent tiles per 512-bit register
 * (lanes 0-7 the left tile's subtiles, 8-15 the right one's), with mask registers instead of
 * blends. Bit-identical to raster_scalar.c (same exact coverage, same float operations in the
 * same order, contraction off); run only when the CPU reports all four extensions. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#if defined(SL_RT_X86)
#define AVX512 __attribute__((target("avx2,avx512f,avx512bw,avx512vl,avx512dq")))
#define SL_RT_T AVX512
#define SL_RT_NAME(n) n##_avx512
#include "raster/raster_simd8.h"

/* za of two tiles in one register from their depth blocks (za[8] then zm[8] each), and back. */
AVX512 static inline void load_pair(const sl_rt_tile_depth *dp, __m512 *za, __m512 *zm)
{
    __m512 a = _mm512_load_ps(dp[0].za), b = _mm512_load_ps(dp[1].za);
    *za = _mm512_shuffle_f32x4(a, b, 0x44);
    *zm = _mm512_shuffle_f32x4(a, b, 0xEE);
}

AVX512 static inline void store_pair(sl_rt_tile_depth *dp, __m512 za, __m512 zm)
{
    _mm512_store_ps(dp[0].za, _mm512_shuffle_f32x4(za, zm, 0x44));
    _mm512_store_ps(dp[1].za, _mm512_shuffle_f32x4(za, zm, 0xEE));
}

/* sl_rt_merge on the 16 subtiles of two tiles. */
AVX512 static inline void merge_pair(__m512i c, __m512 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    __m512 za, zm;
    load_pair(dp, &za, &zm);
    __m512i m = _mm512_loadu_si512(mp);
    __mmask16 act = _mm512_test_epi32_mask(c, c) & _mm512_cmp_ps_mask(z, za, _CMP_GT_OQ);
    __mmask16 nearer = _mm512_cmp_ps_mask(z, zm, _CMP_GT_OQ) &
                       _mm512_cmp_ps_mask(_mm512_sub_ps(z, zm), _mm512_sub_ps(zm, za), _CMP_GT_OQ);
    __mmask16 repl = _mm512_testn_epi32_mask(m, m) | nearer;
    __m512i nm = _mm512_mask_mov_epi32(_mm512_or_si512(m, c), repl, c);
    __m512 nz = _mm512_mask_mov_ps(_mm512_min_ps(zm, z), repl, z);
    __mmask16 full = _mm512_cmpeq_epi32_mask(nm, _mm512_set1_epi32(-1));
    za = _mm512_mask_mov_ps(za, act & full, nz);
    m = _mm512_mask_mov_epi32(m, act, _mm512_maskz_mov_epi32((__mmask16)~full, nm));
    zm = _mm512_mask_mov_ps(zm, act, nz);
    _mm512_storeu_si512(mp, m);
    store_pair(dp, za, zm);
}

/* merge_pair with every subtile fully covered. */
AVX512 static inline void merge_pair_full(__m512 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    __m512 za, zm;
    load_pair(dp, &za, &zm);
    __mmask16 act = _mm512_cmp_ps_mask(z, za, _CMP_GT_OQ);
    if (!act)
        return;
    __m512i m = _mm512_loadu_si512(mp);
    __mmask16 nearer = _mm512_cmp_ps_mask(z, zm, _CMP_GT_OQ) &
                       _mm512_cmp_ps_mask(_mm512_sub_ps(z, zm), _mm512_sub_ps(zm, za), _CMP_GT_OQ);
    __mmask16 repl = _mm512_testn_epi32_mask(m, m) | nearer;
    __m512 nz = _mm512_mask_mov_ps(_mm512_min_ps(zm, z), repl, z);
    _mm512_storeu_si512(mp, _mm512_maskz_mov_epi32((__mmask16)~act, m));
    store_pair(dp, _mm512_mask_mov_ps(za, act, nz), _mm512_mask_mov_ps(zm, act, nz));
}

AVX512 static void raster_avx512(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                                 int32_t ty1)
{
    const __m256i ctl = transpose_ctl();
    const __m512i ctl2 = _mm512_broadcast_i64x4(ctl), ones = _mm512_set1_epi32(-1), zero = _mm512_setzero_si512();
    const __m512i pair_x = _mm512_setr_epi32(0, 0, 0, 0, 0, 0, 0, 0, 32, 32, 32, 32, 32, 32, 32, 32);
    const __m256 off = _mm256_loadu_ps(t->off), zclamp = _mm256_set1_ps(t->zclamp);
    const __m512 off2 = _mm512_insertf32x8(_mm512_castps256_ps512(off), off, 1);
    const __m512 zclamp2 = _mm512_set1_ps(t->zclamp);
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
        const __m512i xl2 = _mm512_broadcast_i64x4(xl), xr2 = _mm512_broadcast_i64x4(xr);
        int32_t tx = ta;
        for (; tx + 1 < tb; tx += 2) {
            int32_t x = tx * SL_RT_TILE_W;
            size_t ti = row + (size_t)tx;
            float za_ = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            float zb_ = (t->z0 + t->zdx * (float)(x + SL_RT_TILE_W - t->x_ref)) + zrow;
            __m512 zt = _mm512_insertf32x8(_mm512_set1_ps(za_), _mm256_set1_ps(zb_), 1);
            __m512 z = _mm512_max_ps(_mm512_add_ps(zt, off2), zclamp2);
            uint32_t *mp = tg->mask + ti * SL_RT_SUBTILES;
            if (tx >= ia && tx + 1 < ib) {
                merge_pair_full(z, mp, &tg->depth[ti]);
                continue;
            }
            __m512i xo = _mm512_add_epi32(_mm512_set1_epi32(x), pair_x);
            __m512i lo = _mm512_max_epi32(_mm512_sub_epi32(xl2, xo), zero);
            __m512i hi = _mm512_max_epi32(_mm512_sub_epi32(xr2, xo), zero);
            __m512i rows = _mm512_andnot_si512(_mm512_sllv_epi32(ones, hi), _mm512_sllv_epi32(ones, lo));
            merge_pair(_mm512_shuffle_epi8(rows, ctl2), z, mp, &tg->depth[ti]);
        }
        if (tx < tb) {
            int32_t x = tx * SL_RT_TILE_W;
            size_t ti = row + (size_t)tx;
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt), off), zclamp);
            if (tx >= ia && tx < ib)
                merge_full_tile(z, tg->mask + ti * SL_RT_SUBTILES, &tg->depth[ti]);
            else
                merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, x), ctl), z, tg->mask + ti * SL_RT_SUBTILES,
                           &tg->depth[ti]);
        }
    }
}

const sl_rt_kernels sl_rt_kernels_avx512 = {SL_RASTER_ISA_AVX512, raster_avx512, query_avx512, rect_avx512};

#endif

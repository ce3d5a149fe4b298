/* AVX-512 kernels of the occlusion rasterizer (F, BW, VL, DQ). The front end, the small-triangle
 * setup (its double arithmetic on 512-bit registers), the general kernel and the queries are the
 * code of raster_simd8.h, raster_batch.h and raster_small8.h compiled for this target. The
 * small-triangle kernels take two adjacent tiles per 512-bit register (lanes 0-7 the left tile's
 * subtiles, 8-15 the right one's), with mask registers instead of blends; triangles two tiles wide
 * take two tile rows per register of spans (raster_narrow), three tiles wide a pair and a single
 * tile per tile row (raster_cols with SL_RT_PAIR_COLS). Bit-identical to raster_scalar.c (same exact coverage, same
 * float operations in the same order, contraction off); run only when the CPU reports all four
 * extensions. */
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
#define SL_RT_W 8
#define SL_RT_MASKED_FULL 1 /* raster_simd8.h's merge_full_tile with masked stores */
#include "raster/raster_simd8.h"
#define SL_RT_D8_512 1 /* raster_lanes.h's doubles on 512-bit registers */
#include "raster/raster_lanes.h"
#include "raster/raster_batch.h"

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
    __mmask16 repl = _mm512_testn_epi32_mask(_mm512_andnot_si512(c, m), _mm512_andnot_si512(c, m)) | nearer;
    __m512i nm = _mm512_mask_mov_epi32(_mm512_or_si512(m, c), repl, c);
    __m512 nz = _mm512_mask_mov_ps(_mm512_min_ps(zm, z), repl, z);
    __mmask16 full = _mm512_cmpeq_epi32_mask(nm, _mm512_set1_epi32(-1));
    za = _mm512_mask_mov_ps(za, act & full, nz);
    m = _mm512_mask_mov_epi32(m, act, _mm512_maskz_mov_epi32((__mmask16)~full, nm));
    zm = _mm512_mask_mov_ps(zm, act, nz);
    _mm512_storeu_si512(mp, m);
    store_pair(dp, za, zm);
}

/* The general kernel (any triangle sl_rt_setup produces): raster_simd8.h's general_ymm, one tile
 * per 256-bit register. Measured against two tiles per 512-bit register (with two tile rows per
 * step, or masked stores for full tiles), it is faster here: its fully covered tiles take the
 * short merge, and the pair version's interleaving shuffles cost more than they save. */
AVX512 static void raster_avx512(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                                 int32_t ty1)
{
    general_ymm(tg, t, tx0, tx1, ty0, ty1);
}

/* Depths of the pair of tiles starting at pixel column x: lanes 0-7 the left tile's subtiles, 8-15
 * the right one's, each ((z0 + zdx*(float)(x - x_ref)) + zrow) + off[k], clamped, as in scalar. */
AVX512 static inline __m512 pair_depth(float z0, float zdx, float zrow, int32_t dx, __m512 off2, __m512 zclamp2)
{
    const __m512i pair_x = _mm512_setr_epi32(0, 0, 0, 0, 0, 0, 0, 0, 32, 32, 32, 32, 32, 32, 32, 32);
    __m512 xf = _mm512_cvtepi32_ps(_mm512_add_epi32(_mm512_set1_epi32(dx), pair_x));
    __m512 zt = _mm512_add_ps(_mm512_add_ps(_mm512_set1_ps(z0), _mm512_mul_ps(_mm512_set1_ps(zdx), xf)),
                              _mm512_set1_ps(zrow));
    return _mm512_max_ps(_mm512_add_ps(zt, off2), zclamp2);
}

/* Subtile masks of the pair of tiles at local column x from the row spans (both tiles' copies). */
AVX512 static inline __m512i pair_masks(__m512i xl2, __m512i xr2, int32_t x, __m512i ctl2)
{
    const __m512i pair_x = _mm512_setr_epi32(0, 0, 0, 0, 0, 0, 0, 0, 32, 32, 32, 32, 32, 32, 32, 32);
    const __m512i ones = _mm512_set1_epi32(-1), zero = _mm512_setzero_si512();
    __m512i xo = _mm512_add_epi32(_mm512_set1_epi32(x), pair_x);
    __m512i lo = _mm512_max_epi32(_mm512_sub_epi32(xl2, xo), zero);
    __m512i hi = _mm512_max_epi32(_mm512_sub_epi32(xr2, xo), zero);
    return _mm512_shuffle_epi8(_mm512_andnot_si512(_mm512_sllv_epi32(ones, hi), _mm512_sllv_epi32(ones, lo)), ctl2);
}

#define SL_RT_PAIR_COLS 1 /* raster_cols merges the first two of three tiles as a pair */
#include "raster/raster_small8.h"

/* A small triangle (raster_batch.h): float thresholds, then the tiles of each tile row two at a
 * time. A pair may reach one tile past the triangle (no coverage there: its merge changes
 * nothing) but never past the caller's range tx_end. Rows are computed one ahead, as in the
 * general kernel. */
AVX512 static inline __attribute__((always_inline)) void raster_small(const sl_rt_target *tg, small_tri *t,
                                                                      int32_t tx_end)
{
    const __m256i ctl = transpose_ctl();
    const __m512i ctl2 = _mm512_broadcast_i64x4(ctl);
    const __m512 off2 = _mm512_insertf32x8(_mm512_castps256_ps512(t->off), t->off, 1);
    const __m512 zclamp2 = _mm512_broadcast_f32x8(t->zclamp);
    const float z0 = t->z0, zdx = t->zdx, zdy = t->zdy;
    const int32_t x_ref = t->x_ref, y_ref = t->y_ref, ox = t->ox;
    uint32_t *const mask = tg->mask;
    sl_rt_tile_depth *const depth = tg->depth;
    const size_t tiles_x = (size_t)tg->tiles_x;
    small_dda dda;
    small_dda_init(t, &dda);
    small_row cur;
    small_row_at(t, &dda, t->ty0, &cur);
    for (int32_t ty = t->ty0; ty < t->ty1; ty++) {
        small_row nxt = cur;
        if (ty + 1 < t->ty1)
            small_row_at(t, &dda, ty + 1, &nxt);
        if (cur.any) {
            float zrow = zdy * (float)(ty * SL_RT_TILE_H - y_ref);
            size_t row = (size_t)ty * tiles_x;
            const __m512i xl2 = _mm512_broadcast_i64x4(cur.xl), xr2 = _mm512_broadcast_i64x4(cur.xr);
            for (int32_t tx = cur.ta; tx < cur.tb; tx += 2) {
                int32_t x = tx * SL_RT_TILE_W;
                size_t ti = row + (size_t)tx;
                if (SL_UNLIKELY(tx + 1 >= tx_end)) {
                    float zt = (z0 + zdx * (float)(x - x_ref)) + zrow;
                    __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt), t->off), t->zclamp);
                    merge_tile(_mm256_shuffle_epi8(row_masks(cur.xl, cur.xr, x - ox), ctl), z,
                               mask + ti * SL_RT_SUBTILES, &depth[ti]);
                    break;
                }
                merge_pair(pair_masks(xl2, xr2, x - ox, ctl2), pair_depth(z0, zdx, zrow, x - x_ref, off2, zclamp2),
                           mask + ti * SL_RT_SUBTILES, &depth[ti]);
            }
        }
        cur = nxt;
    }
}

/* A triangle at most two tiles wide whose pair of tile columns lies in the caller's range: two tile
 * rows at a time, their 16 pixel rows' spans in one register per edge, then one pair of tiles per
 * tile row, without a branch inside (a row or tile past the triangle has no coverage: its merge
 * changes nothing; only a row past the caller's range is skipped). */
AVX512 static inline __attribute__((always_inline)) void raster_narrow(const sl_rt_target *tg, const small_tri *t,
                                                                       int32_t ty_end, bool one_step)
{
    const __m512 ramp16 = _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m512 nbig = _mm512_set1_ps((float)-SL_RT_BIG);
    const __m512i ctl2 = _mm512_broadcast_i64x4(transpose_ctl());
    const __m512 off2 = _mm512_insertf32x8(_mm512_castps256_ps512(t->off), t->off, 1);
    const __m512 zclamp2 = _mm512_broadcast_f32x8(t->zclamp);
    const __m512 cap = _mm512_broadcast_f32x8(t->cap), cl = _mm512_broadcast_f32x8(t->cl);
    const __m512 cr = _mm512_broadcast_f32x8(t->cr);
    const __m512 row0 = _mm512_set1_ps((float)t->row0), row1 = _mm512_set1_ps((float)t->row1);
    __m512 n[3], s16[3], dd[3];
    for (int e = 0; e < 3; e++) {
        /* rows 8-15: one more step of 8 rows; every value an integer below 2^24, exact */
        n[e] = _mm512_insertf32x8(_mm512_castps256_ps512(t->n[e]), _mm256_add_ps(t->n[e], t->s8[e]), 1);
        __m512 s8 = _mm512_broadcast_f32x8(t->s8[e]);
        s16[e] = _mm512_add_ps(s8, s8);
        dd[e] = _mm512_broadcast_f32x8(t->dd[e]);
    }
    const int32_t x = t->tx0 * SL_RT_TILE_W, dxl = x - t->ox, dxz = x - t->x_ref;
    const size_t tiles_x = (size_t)tg->tiles_x;
    for (int32_t ty = t->ty0; ty < t->ty1; ty += 2) {
        __m512 t0 = _mm512_ceil_ps(_mm512_div_ps(n[0], dd[0]));
        __m512 t1 = _mm512_ceil_ps(_mm512_div_ps(n[1], dd[1]));
        __m512 t2 = _mm512_ceil_ps(_mm512_div_ps(n[2], dd[2]));
        for (int e = 0; e < 3; e++)
            n[e] = _mm512_add_ps(n[e], s16[e]);
        __m512 xl = _mm512_max_ps(_mm512_max_ps(cl, t0), _mm512_min_ps(t2, cap));
        __m512 xr = _mm512_min_ps(_mm512_min_ps(cr, t1), _mm512_max_ps(t2, cap));
        __m512 j = _mm512_add_ps(_mm512_set1_ps((float)(ty * SL_RT_TILE_H)), ramp16);
        __mmask16 valid = _mm512_cmp_ps_mask(j, row0, _CMP_GE_OQ) & _mm512_cmp_ps_mask(j, row1, _CMP_LT_OQ);
        xr = _mm512_mask_mov_ps(nbig, valid, xr);
        __m512i xli = _mm512_cvttps_epi32(xl), xri = _mm512_cvttps_epi32(xr);
        size_t ti = (size_t)ty * tiles_x + (size_t)t->tx0;
        float zrow0 = t->zdy * (float)(ty * SL_RT_TILE_H - t->y_ref);
        merge_pair(pair_masks(_mm512_shuffle_i64x2(xli, xli, 0x44), _mm512_shuffle_i64x2(xri, xri, 0x44), dxl, ctl2),
                   pair_depth(t->z0, t->zdx, zrow0, dxz, off2, zclamp2), tg->mask + ti * SL_RT_SUBTILES,
                   &tg->depth[ti]);
        if (!one_step && SL_UNLIKELY(ty + 1 >= ty_end))
            break;
        ti += tiles_x;
        float zrow1 = t->zdy * (float)((ty + 1) * SL_RT_TILE_H - t->y_ref);
        merge_pair(pair_masks(_mm512_shuffle_i64x2(xli, xli, 0xEE), _mm512_shuffle_i64x2(xri, xri, 0xEE), dxl, ctl2),
                   pair_depth(t->z0, t->zdx, zrow1, dxz, off2, zclamp2), tg->mask + ti * SL_RT_SUBTILES,
                   &tg->depth[ti]);
        if (one_step)
            break;
    }
}

/* Set up prims in groups of 8: small ones take raster_small, the others the reference setup and
 * the general kernel. */
AVX512 static void render_avx512(const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0,
                             int32_t tx1, int32_t ty0, int32_t ty1)
{
    for (uint32_t i = 0; i < n; i += 8) {
        uint32_t k = n - i < 8 ? n - i : 8;
        small_lanes s;
        unsigned empty, small = setup_lanes(p + i, k, mode, &s, &empty);
        for (uint32_t l = 0; l < k; l++) {
            if (small >> l & 1) {
                small_tri st;
                if (!small_load(&s, (int)l, tx0, tx1, ty0, ty1, &st))
                    continue;
                if (st.tx1 - st.tx0 == 1) {
                    raster_cols(tg, &st, 1);
                } else if (st.tx1 - st.tx0 == 2) {
                    /* up to two tile rows (both inside the caller's range): no loop at all */
                    if (st.ty1 - st.ty0 <= 2 && st.ty0 + 1 < ty1)
                        raster_narrow(tg, &st, ty1, true);
                    else
                        raster_narrow(tg, &st, ty1, false);
                } else if (st.tx1 - st.tx0 == 3) {
                    raster_cols(tg, &st, 3);
                } else {
                    raster_small(tg, &st, tx1);
                }
            } else if (!(empty >> l & 1)) {
                sl_rt_render_each(raster_avx512, tg, mode, p + i + l, 1, tx0, tx1, ty0, ty1);
            }
        }
    }
}

const sl_rt_kernels sl_rt_kernels_avx512 = {SL_RASTER_ISA_AVX512, raster_avx512, query_avx512, rect_avx512,
                                            front_avx512, render_avx512};

#endif

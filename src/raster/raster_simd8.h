/* 8-lane (256-bit) building blocks of the AVX2 and AVX-512 kernels of the occlusion rasterizer:
 * exact row spans (by division for queries, stepped without a division or a branch for the general
 * occluder kernels), tile ranges, row masks, the subtile merge and the query tests. Included by raster_avx2.c and raster_avx512.c after
 * defining SL_RT_T (the target attribute of every function) and SL_RT_NAME(n) (a suffix for the
 * query kernels), so that each file compiles its own copy for its own instruction set. Nothing
 * here may differ from raster_scalar.c in its results. */
#ifndef SL_RT_T
#error "define SL_RT_T and SL_RT_NAME before including raster_simd8.h"
#endif

#include <immintrin.h>
#include <math.h>

/* Byte shuffle turning rows (lane r, byte c) into subtiles (lane c, byte r) within each half. */
SL_RT_T static inline __m256i transpose_ctl(void)
{
    return _mm256_setr_epi8(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15, 0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10,
                            14, 3, 7, 11, 15);
}

/* Thresholds of edge e for rows j0..j0+7: ceil(num/den) clamped to [col0, col1] (exact). */
SL_RT_T static inline __m256i edge_thresholds(const sl_rt_tri *t, int e, int32_t j0, __m256d c0, __m256d c1)
{
    const __m256d rlo = _mm256_setr_pd(0, 1, 2, 3), rhi = _mm256_setr_pd(4, 5, 6, 7);
    __m256d step = _mm256_set1_pd(t->nstep[e]), den = _mm256_set1_pd(t->den[e]);
    __m256d base = _mm256_set1_pd(t->num0[e] + (double)j0 * t->nstep[e]);
    __m256d qlo = _mm256_ceil_pd(_mm256_div_pd(_mm256_add_pd(base, _mm256_mul_pd(rlo, step)), den));
    __m256d qhi = _mm256_ceil_pd(_mm256_div_pd(_mm256_add_pd(base, _mm256_mul_pd(rhi, step)), den));
    qlo = _mm256_min_pd(_mm256_max_pd(qlo, c0), c1);
    qhi = _mm256_min_pd(_mm256_max_pd(qhi, c0), c1);
    return _mm256_set_m128i(_mm256_cvttpd_epi32(qhi), _mm256_cvttpd_epi32(qlo));
}

/* Exact incremental thresholds of the general kernel, without a division per tile row. With
 * N = num(j0) = t0*D - e0 (t0 = ceil(N/D), 0 <= e0 < D) and r*S = Q_r*D + E_r (0 <= E_r < D):
 *     ceil((N + r*S) / D) = t0 + Q_r + (E_r > e0 ? 1 : 0)
 * and the same step with r = 8 moves (t0, e0) to the next tile row. All integers: the same
 * results as the reference's division. The three edges' (t0, e0) sit in the 64-bit lanes 0-2 of
 * one register each and step without a branch. */
typedef struct vdda {
    __m256i t, e, q8, e8, d; /* int64 lanes: t0, e0, the 8-row step and D of slots 0-2 */
    __m256i q[3], er[3];     /* int32 lanes r = 0..7: Q_r and E_r of each slot */
} vdda;

SL_RT_T static void vdda_init(vdda *v, const sl_rt_tri *t, int32_t j0)
{
    int64_t T[4] = {0, 0, 0, 0}, E[4] = {0, 0, 0, 0}, Q8[4] = {0, 0, 0, 0}, E8[4] = {0, 0, 0, 0};
    int64_t D[4] = {1, 1, 1, 1};
    const __m256d rlo = _mm256_setr_pd(0, 1, 2, 3), rhi = _mm256_setr_pd(4, 5, 6, 7);
    SL_RT_UNROLL
    for (int s = 0; s < 3; s++) {
        double S = t->nstep[s], Dd = t->den[s], N = t->num0[s] + (double)j0 * S;
        double t0 = ceil(N / Dd);
        T[s] = (int64_t)t0;
        E[s] = (int64_t)(t0 * Dd - N); /* |t0*D| < 2^53: exact */
        double q1 = floor(S / Dd), e1 = S - q1 * Dd;
        __m256d dv = _mm256_set1_pd(Dd), q1v = _mm256_set1_pd(q1), e1v = _mm256_set1_pd(e1);
        __m256d relo = _mm256_mul_pd(rlo, e1v), rehi = _mm256_mul_pd(rhi, e1v); /* < 2^34: exact */
        __m256d klo = _mm256_floor_pd(_mm256_div_pd(relo, dv)), khi = _mm256_floor_pd(_mm256_div_pd(rehi, dv));
        __m256d qlo = _mm256_add_pd(_mm256_mul_pd(rlo, q1v), klo), qhi = _mm256_add_pd(_mm256_mul_pd(rhi, q1v), khi);
        __m256d elo = _mm256_sub_pd(relo, _mm256_mul_pd(klo, dv)), ehi = _mm256_sub_pd(rehi, _mm256_mul_pd(khi, dv));
        v->q[s] = _mm256_set_m128i(_mm256_cvttpd_epi32(qhi), _mm256_cvttpd_epi32(qlo));
        v->er[s] = _mm256_set_m128i(_mm256_cvttpd_epi32(ehi), _mm256_cvttpd_epi32(elo));
        double k8 = floor(8.0 * e1 / Dd);
        Q8[s] = (int64_t)(8.0 * q1 + k8);
        E8[s] = (int64_t)(8.0 * e1 - k8 * Dd);
        D[s] = (int64_t)Dd;
    }
    v->t = _mm256_loadu_si256((const __m256i *)T);
    v->e = _mm256_loadu_si256((const __m256i *)E);
    v->q8 = _mm256_loadu_si256((const __m256i *)Q8);
    v->e8 = _mm256_loadu_si256((const __m256i *)E8);
    v->d = _mm256_loadu_si256((const __m256i *)D);
}

/* Spans [xl, xr) of the rows of the current tile row (j0..j0+7; rows outside [row0, row1)
 * emptied), every threshold clamped to [col0, col1] as in the reference; then steps to the next
 * tile row. */
SL_RT_T static inline void vdda_spans(vdda *v, const sl_rt_tri *t, int32_t j0, __m256i *pxl, __m256i *pxr)
{
    const __m256i big = _mm256_set1_epi64x(SL_RT_BIG), nbig = _mm256_set1_epi64x(-SL_RT_BIG);
    __m256i tc = _mm256_blendv_epi8(v->t, big, _mm256_cmpgt_epi64(v->t, big));
    tc = _mm256_blendv_epi8(tc, nbig, _mm256_cmpgt_epi64(nbig, tc));
    const __m256i c0 = _mm256_set1_epi32(t->col0), c1 = _mm256_set1_epi32(t->col1);
    __m256i th[3];
    SL_RT_UNROLL
    for (int s = 0; s < 3; s++) {
        __m256i sel = _mm256_set1_epi32(2 * s);
        __m256i ts = _mm256_permutevar8x32_epi32(tc, sel), es = _mm256_permutevar8x32_epi32(v->e, sel);
        __m256i x = _mm256_sub_epi32(_mm256_add_epi32(ts, v->q[s]), _mm256_cmpgt_epi32(v->er[s], es));
        th[s] = _mm256_min_epi32(_mm256_max_epi32(x, c0), c1);
    }
    __m256i cap = _mm256_set1_epi32(t->cap);
    __m256i xl = _mm256_max_epi32(th[0], _mm256_min_epi32(th[2], cap));
    __m256i xr = _mm256_min_epi32(th[1], _mm256_max_epi32(th[2], cap));
    if (j0 < t->row0 || j0 + SL_RT_TILE_H > t->row1) {
        __m256i j = _mm256_add_epi32(_mm256_set1_epi32(j0), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        __m256i valid = _mm256_and_si256(_mm256_cmpgt_epi32(j, _mm256_set1_epi32(t->row0 - 1)),
                                         _mm256_cmpgt_epi32(_mm256_set1_epi32(t->row1), j));
        xr = _mm256_blendv_epi8(xl, xr, valid);
    }
    *pxl = xl;
    *pxr = xr;
    /* (t0, e0) += one tile row: t0 += q8, e0 -= e8, borrowing D when e0 goes negative */
    __m256i e = _mm256_sub_epi64(v->e, v->e8);
    __m256i borrow = _mm256_cmpgt_epi64(_mm256_setzero_si256(), e);
    v->e = _mm256_add_epi64(e, _mm256_and_si256(borrow, v->d));
    v->t = _mm256_sub_epi64(_mm256_add_epi64(v->t, v->q8), borrow);
}

/* Turn per-edge thresholds into the spans [xl, xr) of rows j0..j0+7 (invalid rows emptied). */
SL_RT_T static inline void combine_spans(const sl_rt_tri *t, int32_t j0, __m256i ta, __m256i tb, const __m256i *tc,
                                      __m256i *pxl, __m256i *pxr)
{
    __m256i xl = ta, xr = tb;
    if (tc) {
        __m256i cap = _mm256_set1_epi32(t->cap);
        xl = _mm256_max_epi32(ta, _mm256_min_epi32(*tc, cap));
        xr = _mm256_min_epi32(tb, _mm256_max_epi32(*tc, cap));
    }
    if (j0 < t->row0 || j0 + SL_RT_TILE_H > t->row1) {
        __m256i j = _mm256_add_epi32(_mm256_set1_epi32(j0), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        __m256i valid = _mm256_and_si256(_mm256_cmpgt_epi32(j, _mm256_set1_epi32(t->row0 - 1)),
                                         _mm256_cmpgt_epi32(_mm256_set1_epi32(t->row1), j));
        xr = _mm256_blendv_epi8(xl, xr, valid);
    }
    *pxl = xl;
    *pxr = xr;
}

static inline bool edge_active(const sl_rt_tri *t, int e, int32_t j0)
{
    return t->ja[e] <= j0 + SL_RT_TILE_H - 1 && t->jb[e] >= j0;
}

/* Column spans [xl, xr) of the 8 rows j0..j0+7, equal (as coverage) to raster_scalar.c's
 * row_spans. Edges whose rows miss this tile row are skipped (raster_internal.h, ja/jb). */
SL_RT_T static inline void row_spans(const sl_rt_tri *t, int32_t j0, __m256i *pxl, __m256i *pxr)
{
    const __m256d c0 = _mm256_set1_pd((double)t->col0), c1 = _mm256_set1_pd((double)t->col1);
    __m256i ta = edge_active(t, 0, j0) ? edge_thresholds(t, 0, j0, c0, c1) : _mm256_set1_epi32(t->col0);
    __m256i tb = edge_active(t, 1, j0) ? edge_thresholds(t, 1, j0, c0, c1) : _mm256_set1_epi32(t->col1);
    __m256i tc;
    bool use_c = edge_active(t, 2, j0);
    if (use_c)
        tc = edge_thresholds(t, 2, j0, c0, c1);
    combine_spans(t, j0, ta, tb, use_c ? &tc : NULL, pxl, pxr);
}


SL_RT_T static inline int32_t hmin(__m256i v)
{
    __m128i m = _mm_min_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1));
    return _mm_cvtsi128_si32(m);
}

SL_RT_T static inline int32_t hmax(__m256i v)
{
    __m128i m = _mm_max_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    m = _mm_max_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    m = _mm_max_epi32(m, _mm_shuffle_epi32(m, 0xB1));
    return _mm_cvtsi128_si32(m);
}

/* Minimum and maximum of 8 lanes in [0, 65535] (spans of the padded screen): packed to 16 bits,
 * one phminposuw (a maximum is 65535 minus the minimum of the complements). */
SL_RT_T static inline uint32_t hmin_u16(__m256i v)
{
    __m128i p = _mm_packus_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    return (uint32_t)_mm_cvtsi128_si32(_mm_minpos_epu16(p)) & 0xFFFFu;
}

SL_RT_T static inline uint32_t hmax_u16(__m256i v)
{
    __m128i p = _mm_packus_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    p = _mm_xor_si128(p, _mm_set1_epi32(-1));
    return 0xFFFFu - ((uint32_t)_mm_cvtsi128_si32(_mm_minpos_epu16(p)) & 0xFFFFu);
}

/* Tile columns [*ta, *tb) of the non-empty spans within [tx0, tx1), and [*ia, *ib) of the tiles
 * every row covers completely (empty when a row is empty); false if no span. */
SL_RT_T static inline bool span_tiles(__m256i xl, __m256i xr, int32_t tx0, int32_t tx1, int32_t *ta, int32_t *tb,
                                   int32_t *ia, int32_t *ib)
{
    __m256i ne = _mm256_cmpgt_epi32(xr, xl);
    int nm = _mm256_movemask_ps(_mm256_castsi256_ps(ne));
    if (nm == 0)
        return false;
    *ia = *ib = 0;
    if (tx1 - tx0 <= 2) {
        /* narrow: visiting an empty tile costs less than finding out */
        *ta = tx0, *tb = tx1;
        return true;
    }
    /* spans lie in [col0, col1], so the columns are >= 0: unsigned division is a shift */
    /* spans lie in [col0, col1] within the padded screen: 16-bit reductions (empty lanes take
     * 65535 for the minimum, 0 for the maximum) */
    uint32_t lo = hmin_u16(_mm256_blendv_epi8(_mm256_set1_epi32(0xFFFF), xl, ne));
    uint32_t hi = hmax_u16(_mm256_and_si256(xr, ne));
    *ta = sl_rt_maxi(tx0, (int32_t)(lo / SL_RT_TILE_W));
    *tb = sl_rt_mini(tx1, (int32_t)((hi - 1) / SL_RT_TILE_W + 1));
    if (nm == 0xFF) {
        uint32_t l = hmax_u16(xl), r = hmin_u16(xr);
        *ia = sl_rt_maxi(*ta, (int32_t)((l + SL_RT_TILE_W - 1) / SL_RT_TILE_W));
        *ib = sl_rt_mini(*tb, (int32_t)(r / SL_RT_TILE_W));
    }
    return *ta < *tb;
}

/* Spans and tile ranges of tile row ty of a general triangle (none past ty_end), computed where
 * this is called (see raster_avx512.c). */
typedef struct grow {
    __m256i xl, xr;
    int32_t ta, tb, ia, ib; /* the tiles the spans touch, and those every row covers */
    bool any;
} grow;

SL_RT_T static inline __attribute__((always_inline)) void grow_at(vdda *dda, const sl_rt_tri *t, int32_t ty,
                                                                int32_t ty_end, int32_t tx0, int32_t tx1, grow *g)
{
    g->any = false;
    g->ta = g->tb = g->ia = g->ib = 0;
    g->xl = g->xr = _mm256_setzero_si256();
    if (ty < ty_end) {
        vdda_spans(dda, t, ty * SL_RT_TILE_H, &g->xl, &g->xr);
        g->any = span_tiles(g->xl, g->xr, tx0, tx1, &g->ta, &g->tb, &g->ia, &g->ib);
    }
    __asm__("" : "+x"(g->xl), "+x"(g->xr), "+r"(g->ta), "+r"(g->tb), "+r"(g->ia), "+r"(g->ib), "+r"(g->any));
}

/* Row masks of the tile at column x: bits [xl - x, xr - x) of each row (vpsllvd gives 0 past 31). */
SL_RT_T static inline __m256i row_masks(__m256i xl, __m256i xr, int32_t x)
{
    const __m256i ones = _mm256_set1_epi32(-1), zero = _mm256_setzero_si256();
    __m256i xo = _mm256_set1_epi32(x);
    __m256i lo = _mm256_max_epi32(_mm256_sub_epi32(xl, xo), zero);
    __m256i hi = _mm256_max_epi32(_mm256_sub_epi32(xr, xo), zero);
    return _mm256_andnot_si256(_mm256_sllv_epi32(ones, hi), _mm256_sllv_epi32(ones, lo));
}

/* sl_rt_merge of coverage c at depth z into one tile. No early exit: which tiles a triangle
 * changes is data-dependent, and a mispredicted branch costs more than the stores it saves. */
#if defined(SL_RT_MASKED_FULL)
/* AVX-512: the conditions in mask registers and the results written by masked stores (raster_avx512.c's
 * merge_pair on 8 lanes) */
SL_RT_T static inline void merge_tile(__m256i c, __m256 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    __m256 za = _mm256_load_ps(dp->za), zm = _mm256_load_ps(dp->zm);
    __m256i m = _mm256_load_si256((const __m256i *)mp);
    __mmask8 act = _mm256_test_epi32_mask(c, c) & _mm256_cmp_ps_mask(z, za, _CMP_GT_OQ);
    __mmask8 nearer = _mm256_cmp_ps_mask(z, zm, _CMP_GT_OQ) &
                      _mm256_cmp_ps_mask(_mm256_sub_ps(z, zm), _mm256_sub_ps(zm, za), _CMP_GT_OQ);
    __m256i mc = _mm256_andnot_si256(c, m);
    __mmask8 repl = _mm256_testn_epi32_mask(mc, mc) | nearer;
    __m256i nm = _mm256_mask_mov_epi32(_mm256_or_si256(m, c), repl, c);
    __m256 nz = _mm256_mask_mov_ps(_mm256_min_ps(zm, z), repl, z);
    __mmask8 full = _mm256_cmpeq_epi32_mask(nm, _mm256_set1_epi32(-1));
    _mm256_mask_store_epi32(mp, act, _mm256_maskz_mov_epi32((__mmask8)~full, nm));
    _mm256_mask_store_ps(dp->za, act & full, nz);
    _mm256_mask_store_ps(dp->zm, act, nz);
}
#else
SL_RT_T static inline void merge_tile(__m256i c, __m256 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    const __m256i zero = _mm256_setzero_si256(), ones = _mm256_set1_epi32(-1);
    __m256 za = _mm256_load_ps(dp->za);
    __m256i act = _mm256_andnot_si256(_mm256_cmpeq_epi32(c, zero), _mm256_castps_si256(_mm256_cmp_ps(z, za, _CMP_GT_OQ)));
    __m256i m = _mm256_load_si256((const __m256i *)mp);
    __m256 zm = _mm256_load_ps(dp->zm);
    __m256 nearer = _mm256_and_ps(_mm256_cmp_ps(z, zm, _CMP_GT_OQ),
                                  _mm256_cmp_ps(_mm256_sub_ps(z, zm), _mm256_sub_ps(zm, za), _CMP_GT_OQ));
    __m256i repl = _mm256_or_si256(_mm256_cmpeq_epi32(_mm256_andnot_si256(c, m), zero), _mm256_castps_si256(nearer));
    __m256i nm = _mm256_blendv_epi8(_mm256_or_si256(m, c), c, repl);
    __m256 nz = _mm256_blendv_ps(_mm256_min_ps(zm, z), z, _mm256_castsi256_ps(repl));
    __m256i full = _mm256_cmpeq_epi32(nm, ones);
    za = _mm256_blendv_ps(za, nz, _mm256_castsi256_ps(_mm256_and_si256(full, act)));
    m = _mm256_blendv_epi8(m, _mm256_andnot_si256(full, nm), act);
    zm = _mm256_blendv_ps(zm, nz, _mm256_castsi256_ps(act));
    _mm256_store_si256((__m256i *)mp, m);
    _mm256_store_ps(dp->za, za);
    _mm256_store_ps(dp->zm, zm);
}
#endif

/* merge_tile with c = ~0 in every lane: the old mask lies inside c, so a nearer subtile simply
 * takes z over its whole area. */
#if defined(SL_RT_MASKED_FULL)
/* AVX-512: the same result with masked stores, without reading m or zm */
SL_RT_T static inline void merge_full_tile(__m256 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    __mmask8 act = _mm256_cmp_ps_mask(z, _mm256_load_ps(dp->za), _CMP_GT_OQ);
    _mm256_mask_store_epi32(mp, act, _mm256_setzero_si256());
    _mm256_mask_store_ps(dp->za, act, z);
    _mm256_mask_store_ps(dp->zm, act, z);
}
#else
SL_RT_T static inline void merge_full_tile(__m256 z, uint32_t *mp, sl_rt_tile_depth *dp)
{
    __m256 za = _mm256_load_ps(dp->za);
    __m256 act = _mm256_cmp_ps(z, za, _CMP_GT_OQ);
    __m256i m = _mm256_load_si256((const __m256i *)mp);
    _mm256_store_si256((__m256i *)mp, _mm256_andnot_si256(_mm256_castps_si256(act), m));
    _mm256_store_ps(dp->za, _mm256_blendv_ps(za, z, act));
    _mm256_store_ps(dp->zm, _mm256_blendv_ps(_mm256_load_ps(dp->zm), z, act));
}
#endif

/* One tile with partial coverage: zc = the tile column's z0 + zdx*(float)(x - x_ref). */
SL_RT_T static inline __attribute__((always_inline)) void partial_tile(uint32_t *mask, sl_rt_tile_depth *depth,
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
 * next tile row's spans are computed before the current row's tiles (see raster_avx512.c's general kernels), and
 * each tile column's z0 + zdx*(float)(x - x_ref) once per triangle. */
SL_RT_T static inline __attribute__((always_inline)) void general_ymm(const sl_rt_target *tg, const sl_rt_tri *t,
                                                                       int32_t tx0, int32_t tx1, int32_t ty0,
                                                                       int32_t ty1)
{
    const __m256i ctl = transpose_ctl();
    const __m256 off = _mm256_loadu_ps(t->off), zclamp = _mm256_set1_ps(t->zclamp);
    const float zdy = t->zdy;
    const int32_t y_ref = t->y_ref;
    uint32_t *const mask = tg->mask;
    sl_rt_tile_depth *const depth = tg->depth;
    const size_t tiles_x = (size_t)tg->tiles_x;
    /* zcol[tx - tx0] = z0 + zdx*(float)(32*tx - x_ref), 8 columns at a time. The tile range lies
     * in the padded screen (sl_rt_prepare clamps col0/col1 to [0, pad_w], pad_w <= SL_RT_MAX_DIM),
     * so tx1 - tx0 <= 256 and the stores reach zcol[255] at most. Indexed as zcol[tx - tx0]: a
     * pointer zcol - tx0 would lie outside the array, which is undefined even if never read
     * below tx0 (issue 12: UBSan, fuzz/seeds/occrec/raster_zcol_base.rec). */
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
                partial_tile(mask, depth, g.xl, g.xr, row, tx, zcol[tx - tx0], zrow, off, zclamp, ctl);
            for (; tx < eb; tx++) {
                size_t ti = row + (size_t)tx;
                merge_full_tile(_mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zcol[tx - tx0] + zrow), off), zclamp),
                                mask + ti * SL_RT_SUBTILES, &depth[ti]);
            }
            for (; tx < g.tb; tx++)
                partial_tile(mask, depth, g.xl, g.xr, row, tx, zcol[tx - tx0], zrow, off, zclamp, ctl);
        }
        g = n;
    }
}

/* Lanes where the subtile hides depth z under coverage c (sl_rt_subtile_hides). */
SL_RT_T static inline int hides_mask(__m256i c, __m256 z, const uint32_t *mp, const sl_rt_tile_depth *dp)
{
    const __m256i zero = _mm256_setzero_si256();
    __m256 za = _mm256_load_ps(dp->za), zm = _mm256_load_ps(dp->zm);
    __m256i m = _mm256_load_si256((const __m256i *)mp);
    __m256i uncovered = _mm256_cmpeq_epi32(_mm256_andnot_si256(m, c), zero);
    __m256i ok = _mm256_or_si256(_mm256_cmpeq_epi32(c, zero), _mm256_castps_si256(_mm256_cmp_ps(za, z, _CMP_GT_OQ)));
    ok = _mm256_or_si256(ok, _mm256_and_si256(_mm256_castps_si256(_mm256_cmp_ps(zm, z, _CMP_GT_OQ)), uncovered));
    return _mm256_movemask_ps(_mm256_castsi256_ps(ok));
}

SL_RT_T static bool SL_RT_NAME(query)(const sl_rt_target *tg, const sl_rt_tri *t)
{
    const __m256i ctl = transpose_ctl();
    const __m256 off = _mm256_loadu_ps(t->off), zclamp = _mm256_set1_ps(t->zclamp);
    int32_t ty0 = t->row0 / SL_RT_TILE_H, ty1 = (t->row1 - 1) / SL_RT_TILE_H + 1;
    int32_t tx0 = t->col0 / SL_RT_TILE_W, tx1 = (t->col1 - 1) / SL_RT_TILE_W + 1;
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, ta, tb, ia, ib;
        __m256i xl, xr;
        row_spans(t, j0, &xl, &xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb, &ia, &ib))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)ta;
        for (int32_t tx = ta; tx < tb; tx++, ti++) {
            int32_t x = tx * SL_RT_TILE_W;
            __m256i c = _mm256_shuffle_epi8(row_masks(xl, xr, x), ctl);
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            __m256 z = _mm256_min_ps(_mm256_add_ps(_mm256_set1_ps(zt), off), zclamp);
            if (hides_mask(c, z, sl_rt_tile_mask(tg, ty, ti), sl_rt_tile_depths(tg, ty, ti)) != 0xFF)
                return true;
        }
    }
    return false;
}

SL_RT_T static bool SL_RT_NAME(rect)(const sl_rt_target *tg, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float dz)
{
    const __m256i ctl = transpose_ctl();
    const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 z = _mm256_set1_ps(dz);
    int32_t txa = x0 / SL_RT_TILE_W, txb = (x1 - 1) / SL_RT_TILE_W;
    int32_t tya = y0 / SL_RT_TILE_H, tyb = (y1 - 1) / SL_RT_TILE_H;
    /* The common case first, without a branch per tile: every tile's whole-subtile depths hide z
     * (then so does every subtile, whatever the rectangle covers of it). Tile pairs per step, one
     * test per tile row; any other answer is left to the exact loop below. */
    {
        bool all = true;
        const size_t tx = (size_t)tg->tiles_x, nt = (size_t)(txb - txa + 1);
        for (int32_t ty = tya; ty <= tyb && all; ty++) {
            const sl_rt_tile_depth *dp = &tg->depth[(size_t)ty * tx + (size_t)txa];
            __m256 acc = _mm256_cmp_ps(_mm256_load_ps(dp[0].za), z, _CMP_GT_OQ);
            size_t i = 1;
            for (; i + 1 < nt; i += 2)
                acc = _mm256_and_ps(acc, _mm256_and_ps(_mm256_cmp_ps(_mm256_load_ps(dp[i].za), z, _CMP_GT_OQ),
                                                       _mm256_cmp_ps(_mm256_load_ps(dp[i + 1].za), z, _CMP_GT_OQ)));
            if (i < nt)
                acc = _mm256_and_ps(acc, _mm256_cmp_ps(_mm256_load_ps(dp[i].za), z, _CMP_GT_OQ));
            all = _mm256_movemask_ps(acc) == 0xFF;
        }
        if (all)
            return true;
    }
    for (int32_t ty = tya; ty <= tyb; ty++) {
        __m256i j = _mm256_add_epi32(_mm256_set1_epi32(ty * SL_RT_TILE_H), lanes);
        __m256i valid = _mm256_and_si256(_mm256_cmpgt_epi32(j, _mm256_set1_epi32(y0 - 1)),
                                         _mm256_cmpgt_epi32(_mm256_set1_epi32(y1), j));
        size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)txa;
        for (int32_t tx = txa; tx <= txb; tx++, ti++) {
            const sl_rt_tile_depth *dp = &tg->depth[ti];
            /* the common case: the whole-subtile depths alone hide z */
            if (_mm256_movemask_ps(_mm256_cmp_ps(_mm256_load_ps(dp->za), z, _CMP_GT_OQ)) == 0xFF)
                continue;
            int32_t x = tx * SL_RT_TILE_W;
            __m256i cols = _mm256_set1_epi32((int32_t)(sl_rt_ones_from(sl_rt_maxi(x0 - x, 0)) &
                                                       ~sl_rt_ones_from(sl_rt_maxi(x1 - x, 0))));
            __m256i c = _mm256_shuffle_epi8(_mm256_and_si256(cols, valid), ctl);
            if (hides_mask(c, z, tg->mask + ti * SL_RT_SUBTILES, dp) != 0xFF)
                return false;
        }
    }
    return true;
}


/* SSE4.1 kernels of the occlusion rasterizer: raster_avx2.c's algorithm on 128-bit registers, one
 * register per half tile (pixel rows 0-3 / 4-7, subtiles 0-3 / 4-7). SSE has no per-lane shift,
 * so the masks ~0 << n come from 2^n built in a float's exponent. The front end and the
 * small-triangle setup are raster_batch.h's, 4 triangles per register; small triangles then take
 * raster_cols4 (one to three tiles wide) or raster_small4, the others the reference setup and the
 * general kernel raster_sse41 (a division per tile row). Bit-identical to the scalar reference;
 * run only when __builtin_cpu_supports("sse4.1"). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#if defined(SL_RT_X86)
#include <immintrin.h>

#define SSE41 __attribute__((target("sse4.1")))
#define SL_RT_T SSE41
#define SL_RT_NAME(n) n##_sse41
#define SL_RT_W 4
#include "raster/raster_lanes.h"
#include "raster/raster_batch.h"

SSE41 static inline __m128i transpose_ctl(void)
{
    return _mm_setr_epi8(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15);
}

/* ~0 << n per lane for n >= 0, 0 when n >= 32: 2^n is the float with exponent n; converting 2^31
 * overflows to 0x80000000, which happens to be 1 << 31. */
SSE41 static inline __m128i ones_from(__m128i n)
{
    const __m128i k32 = _mm_set1_epi32(32);
    __m128i nc = _mm_min_epi32(n, k32);
    __m128i p = _mm_cvttps_epi32(_mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(nc, _mm_set1_epi32(127)), 23)));
    return _mm_andnot_si128(_mm_cmpeq_epi32(nc, k32), _mm_sub_epi32(_mm_setzero_si128(), p));
}

/* Thresholds of one edge for rows j0+4h .. j0+4h+3. */
SSE41 static inline __m128i edge4(const sl_rt_tri *t, int e, double base, int h, __m128d c0, __m128d c1)
{
    __m128d step = _mm_set1_pd(t->nstep[e]), den = _mm_set1_pd(t->den[e]), b = _mm_set1_pd(base);
    double r = 4.0 * h;
    __m128d ra = _mm_setr_pd(r, r + 1), rb = _mm_setr_pd(r + 2, r + 3);
    __m128d qa = _mm_ceil_pd(_mm_div_pd(_mm_add_pd(b, _mm_mul_pd(ra, step)), den));
    __m128d qb = _mm_ceil_pd(_mm_div_pd(_mm_add_pd(b, _mm_mul_pd(rb, step)), den));
    qa = _mm_min_pd(_mm_max_pd(qa, c0), c1);
    qb = _mm_min_pd(_mm_max_pd(qb, c0), c1);
    return _mm_unpacklo_epi64(_mm_cvttpd_epi32(qa), _mm_cvttpd_epi32(qb));
}

/* Spans [xl[h], xr[h]) of rows j0+4h..j0+4h+3, h = 0, 1; edges whose rows miss this tile row
 * are skipped as in raster_avx2.c. */
SSE41 static inline void row_spans(const sl_rt_tri *t, int32_t j0, __m128i xl[2], __m128i xr[2])
{
    const __m128d c0 = _mm_set1_pd((double)t->col0), c1 = _mm_set1_pd((double)t->col1);
    const __m128i cap = _mm_set1_epi32(t->cap);
    int32_t j1 = j0 + SL_RT_TILE_H - 1;
    bool act[3];
    double base[3];
    for (int e = 0; e < 3; e++) {
        act[e] = t->ja[e] <= j1 && t->jb[e] >= j0;
        base[e] = t->num0[e] + (double)j0 * t->nstep[e];
    }
    bool partial = j0 < t->row0 || j1 >= t->row1;
    for (int h = 0; h < 2; h++) {
        __m128i l = act[0] ? edge4(t, 0, base[0], h, c0, c1) : _mm_set1_epi32(t->col0);
        __m128i r = act[1] ? edge4(t, 1, base[1], h, c0, c1) : _mm_set1_epi32(t->col1);
        if (act[2]) {
            __m128i c = edge4(t, 2, base[2], h, c0, c1);
            l = _mm_max_epi32(l, _mm_min_epi32(c, cap));
            r = _mm_min_epi32(r, _mm_max_epi32(c, cap));
        }
        if (partial) {
            __m128i j = _mm_add_epi32(_mm_set1_epi32(j0 + 4 * h), _mm_setr_epi32(0, 1, 2, 3));
            __m128i valid = _mm_and_si128(_mm_cmpgt_epi32(j, _mm_set1_epi32(t->row0 - 1)),
                                          _mm_cmpgt_epi32(_mm_set1_epi32(t->row1), j));
            r = _mm_blendv_epi8(l, r, valid);
        }
        xl[h] = l;
        xr[h] = r;
    }
}

SSE41 static inline int32_t hmin4(__m128i m)
{
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    return _mm_cvtsi128_si32(_mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1)));
}

SSE41 static inline int32_t hmax4(__m128i m)
{
    m = _mm_max_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    return _mm_cvtsi128_si32(_mm_max_epi32(m, _mm_shuffle_epi32(m, 0xB1)));
}

/* As raster_avx2.c's span_tiles. */
SSE41 static inline bool span_tiles(const __m128i xl[2], const __m128i xr[2], int32_t tx0, int32_t tx1, int32_t *ta,
                                    int32_t *tb, int32_t *ia, int32_t *ib)
{
    __m128i n0 = _mm_cmpgt_epi32(xr[0], xl[0]), n1 = _mm_cmpgt_epi32(xr[1], xl[1]);
    int nm = _mm_movemask_ps(_mm_castsi128_ps(n0)) | _mm_movemask_ps(_mm_castsi128_ps(n1)) << 4;
    if (nm == 0)
        return false;
    *ia = *ib = 0;
    if (tx1 - tx0 <= 2) {
        *ta = tx0, *tb = tx1;
        return true;
    }
    const __m128i big = _mm_set1_epi32(INT32_MAX), small = _mm_set1_epi32(INT32_MIN);
    int32_t lo = hmin4(_mm_min_epi32(_mm_blendv_epi8(big, xl[0], n0), _mm_blendv_epi8(big, xl[1], n1)));
    int32_t hi = hmax4(_mm_max_epi32(_mm_blendv_epi8(small, xr[0], n0), _mm_blendv_epi8(small, xr[1], n1)));
    *ta = sl_rt_maxi(tx0, lo / SL_RT_TILE_W);
    *tb = sl_rt_mini(tx1, (hi - 1) / SL_RT_TILE_W + 1);
    if (nm == 0xFF) {
        int32_t l = hmax4(_mm_max_epi32(xl[0], xl[1])), r = hmin4(_mm_min_epi32(xr[0], xr[1]));
        *ia = sl_rt_maxi(*ta, (l + SL_RT_TILE_W - 1) / SL_RT_TILE_W);
        *ib = sl_rt_mini(*tb, r / SL_RT_TILE_W);
    }
    return *ta < *tb;
}

SSE41 static inline __m128i row_masks(__m128i xl, __m128i xr, __m128i xo)
{
    const __m128i zero = _mm_setzero_si128();
    __m128i lo = _mm_max_epi32(_mm_sub_epi32(xl, xo), zero);
    __m128i hi = _mm_max_epi32(_mm_sub_epi32(xr, xo), zero);
    return _mm_andnot_si128(ones_from(hi), ones_from(lo));
}

/* sl_rt_merge on 4 subtiles; with `skip`, returns early when no subtile gets nearer (worth it where
 * that is common: the general kernel's partial tiles), else branch-free like raster_simd8.h's. */
SSE41 static inline __attribute__((always_inline)) void merge4_to(__m128i c, __m128 z, uint32_t *mp, float *zap,
                                                                 float *zmp, bool skip)
{
    const __m128i zero = _mm_setzero_si128(), ones = _mm_set1_epi32(-1);
    __m128 za = _mm_load_ps(zap);
    __m128i act = _mm_andnot_si128(_mm_cmpeq_epi32(c, zero), _mm_castps_si128(_mm_cmpgt_ps(z, za)));
    if (skip && _mm_testz_si128(act, act))
        return;
    __m128i m = _mm_load_si128((const __m128i *)mp);
    __m128 zm = _mm_load_ps(zmp);
    __m128 nearer = _mm_and_ps(_mm_cmpgt_ps(z, zm), _mm_cmpgt_ps(_mm_sub_ps(z, zm), _mm_sub_ps(zm, za)));
    __m128i repl = _mm_or_si128(_mm_cmpeq_epi32(_mm_andnot_si128(c, m), zero), _mm_castps_si128(nearer));
    __m128i nm = _mm_blendv_epi8(_mm_or_si128(m, c), c, repl);
    __m128 nz = _mm_blendv_ps(_mm_min_ps(zm, z), z, _mm_castsi128_ps(repl));
    __m128i full = _mm_cmpeq_epi32(nm, ones);
    za = _mm_blendv_ps(za, nz, _mm_castsi128_ps(_mm_and_si128(full, act)));
    m = _mm_blendv_epi8(m, _mm_andnot_si128(full, nm), act);
    zm = _mm_blendv_ps(zm, nz, _mm_castsi128_ps(act));
    _mm_store_si128((__m128i *)mp, m);
    _mm_store_ps(zap, za);
    _mm_store_ps(zmp, zm);
}

SSE41 static inline void merge4(__m128i c, __m128 z, uint32_t *mp, float *zap, float *zmp)
{
    merge4_to(c, z, mp, zap, zmp, true);
}

/* merge4 with full coverage: the old mask lies inside it, so every nearer subtile takes z. */
SSE41 static inline void merge4_full(__m128 z, uint32_t *mp, float *zap, float *zmp)
{
    __m128 za = _mm_load_ps(zap);
    __m128 act = _mm_cmpgt_ps(z, za);
    if (_mm_movemask_ps(act) == 0)
        return;
    __m128i m = _mm_load_si128((const __m128i *)mp);
    _mm_store_si128((__m128i *)mp, _mm_andnot_si128(_mm_castps_si128(act), m));
    _mm_store_ps(zap, _mm_blendv_ps(za, z, act));
    _mm_store_ps(zmp, _mm_blendv_ps(_mm_load_ps(zmp), z, act));
}

SSE41 static void raster_sse41(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                               int32_t ty1)
{
    const __m128i ctl = transpose_ctl();
    const __m128 off0 = _mm_loadu_ps(t->off), off1 = _mm_loadu_ps(t->off + 4), zclamp = _mm_set1_ps(t->zclamp);
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, ta, tb, ia, ib;
        __m128i xl[2], xr[2];
        row_spans(t, j0, xl, xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb, &ia, &ib))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        size_t row = (size_t)ty * (size_t)tg->tiles_x;
        for (int32_t tx = ta; tx < tb; tx++) {
            int32_t x = tx * SL_RT_TILE_W;
            size_t ti = row + (size_t)tx;
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            __m128 zt4 = _mm_set1_ps(zt);
            __m128 z0 = _mm_max_ps(_mm_add_ps(zt4, off0), zclamp), z1 = _mm_max_ps(_mm_add_ps(zt4, off1), zclamp);
            uint32_t *mp = tg->mask + ti * SL_RT_SUBTILES;
            sl_rt_tile_depth *dp = &tg->depth[ti];
            if (tx >= ia && tx < ib) {
                merge4_full(z0, mp, dp->za, dp->zm);
                merge4_full(z1, mp + 4, dp->za + 4, dp->zm + 4);
                continue;
            }
            __m128i xo = _mm_set1_epi32(x);
            __m128i r0 = row_masks(xl[0], xr[0], xo), r1 = row_masks(xl[1], xr[1], xo);
            __m128i any = _mm_or_si128(r0, r1);
            if (_mm_testz_si128(any, any))
                continue;
            merge4(_mm_shuffle_epi8(r0, ctl), z0, mp, dp->za, dp->zm);
            merge4(_mm_shuffle_epi8(r1, ctl), z1, mp + 4, dp->za + 4, dp->zm + 4);
        }
    }
}

/* Lanes of 4 subtiles hiding z under coverage c. */
SSE41 static inline int hides4(__m128i c, __m128 z, const uint32_t *mp, const float *zap, const float *zmp)
{
    const __m128i zero = _mm_setzero_si128();
    __m128 za = _mm_load_ps(zap), zm = _mm_load_ps(zmp);
    __m128i m = _mm_load_si128((const __m128i *)mp);
    __m128i uncovered = _mm_cmpeq_epi32(_mm_andnot_si128(m, c), zero);
    __m128i ok = _mm_or_si128(_mm_cmpeq_epi32(c, zero), _mm_castps_si128(_mm_cmpgt_ps(za, z)));
    ok = _mm_or_si128(ok, _mm_and_si128(_mm_castps_si128(_mm_cmpgt_ps(zm, z)), uncovered));
    return _mm_movemask_ps(_mm_castsi128_ps(ok));
}

SSE41 static bool query_sse41(const sl_rt_target *tg, const sl_rt_tri *t)
{
    const __m128i ctl = transpose_ctl();
    const __m128 off0 = _mm_loadu_ps(t->off), off1 = _mm_loadu_ps(t->off + 4), zclamp = _mm_set1_ps(t->zclamp);
    int32_t ty0 = t->row0 / SL_RT_TILE_H, ty1 = (t->row1 - 1) / SL_RT_TILE_H + 1;
    int32_t tx0 = t->col0 / SL_RT_TILE_W, tx1 = (t->col1 - 1) / SL_RT_TILE_W + 1;
    for (int32_t ty = ty0; ty < ty1; ty++) {
        int32_t j0 = ty * SL_RT_TILE_H, ta, tb, ia, ib;
        __m128i xl[2], xr[2];
        row_spans(t, j0, xl, xr);
        if (!span_tiles(xl, xr, tx0, tx1, &ta, &tb, &ia, &ib))
            continue;
        float zrow = t->zdy * (float)(j0 - t->y_ref);
        size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)ta;
        for (int32_t tx = ta; tx < tb; tx++, ti++) {
            int32_t x = tx * SL_RT_TILE_W;
            __m128i xo = _mm_set1_epi32(x);
            __m128i c0 = _mm_shuffle_epi8(row_masks(xl[0], xr[0], xo), ctl);
            __m128i c1 = _mm_shuffle_epi8(row_masks(xl[1], xr[1], xo), ctl);
            float zt = (t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow;
            __m128 zt4 = _mm_set1_ps(zt);
            const uint32_t *mp = sl_rt_tile_mask(tg, ty, ti);
            const sl_rt_tile_depth *dp = sl_rt_tile_depths(tg, ty, ti);
            if (hides4(c0, _mm_min_ps(_mm_add_ps(zt4, off0), zclamp), mp, dp->za, dp->zm) != 0xF ||
                hides4(c1, _mm_min_ps(_mm_add_ps(zt4, off1), zclamp), mp + 4, dp->za + 4, dp->zm + 4) != 0xF)
                return true;
        }
    }
    return false;
}

SSE41 static bool rect_sse41(const sl_rt_target *tg, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float dz)
{
    const __m128i ctl = transpose_ctl(), lanes = _mm_setr_epi32(0, 1, 2, 3);
    const __m128 z = _mm_set1_ps(dz);
    int32_t txa = x0 / SL_RT_TILE_W, txb = (x1 - 1) / SL_RT_TILE_W;
    for (int32_t ty = y0 / SL_RT_TILE_H; ty <= (y1 - 1) / SL_RT_TILE_H; ty++) {
        __m128i valid[2];
        for (int h = 0; h < 2; h++) {
            __m128i j = _mm_add_epi32(_mm_set1_epi32(ty * SL_RT_TILE_H + 4 * h), lanes);
            valid[h] = _mm_and_si128(_mm_cmpgt_epi32(j, _mm_set1_epi32(y0 - 1)), _mm_cmpgt_epi32(_mm_set1_epi32(y1), j));
        }
        size_t ti = (size_t)ty * (size_t)tg->tiles_x + (size_t)txa;
        for (int32_t tx = txa; tx <= txb; tx++, ti++) {
            const sl_rt_tile_depth *dp = &tg->depth[ti];
            __m128 a = _mm_and_ps(_mm_cmpgt_ps(_mm_load_ps(dp->za), z), _mm_cmpgt_ps(_mm_load_ps(dp->za + 4), z));
            if (_mm_movemask_ps(a) == 0xF)
                continue;
            int32_t x = tx * SL_RT_TILE_W;
            __m128i cols = _mm_set1_epi32(
                (int32_t)(sl_rt_ones_from(sl_rt_maxi(x0 - x, 0)) & ~sl_rt_ones_from(sl_rt_maxi(x1 - x, 0))));
            const uint32_t *mp = tg->mask + ti * SL_RT_SUBTILES;
            if (hides4(_mm_shuffle_epi8(_mm_and_si128(cols, valid[0]), ctl), z, mp, dp->za, dp->zm) != 0xF ||
                hides4(_mm_shuffle_epi8(_mm_and_si128(cols, valid[1]), ctl), z, mp + 4, dp->za + 4, dp->zm + 4) != 0xF)
                return false;
        }
    }
    return true;
}

/* A small triangle of lane l of raster_batch.h's setup_lanes: float thresholds (exact, see
 * raster_batch.h), the rows of a tile row in two registers (rows 0-3 and 4-7). */
typedef struct small_tri4 {
    __m128 n[3][2], s8[3], dd[3]; /* n: numerators of the rows of the current tile row */
    __m128 cap, cl, cr, off[2], zclamp;
    float z0, zdx, zdy;
    int32_t ox, x_ref, y_ref, row0, row1;
    int32_t tx0, tx1, ty0, ty1; /* tile bounds, clipped to the caller's */
} small_tri4;

/* As raster_small8.h's small_load, for lane l. False when the triangle misses the tile range. */
SSE41 static inline bool small_load4(const small_lanes *s, int l, int32_t tx0, int32_t tx1, int32_t ty0, int32_t ty1,
                                     small_tri4 *o)
{
    int32_t tb[4];
    if (!small_tiles(s, l, tx0, tx1, ty0, ty1, tb))
        return false;
    o->tx0 = tb[0], o->tx1 = tb[1], o->ty0 = tb[2], o->ty1 = tb[3];
    o->ox = s->ox[l];
    o->row0 = s->row0[l], o->row1 = s->row1[l];
    o->x_ref = s->col0[l], o->y_ref = s->row0[l];
    const __m128 ramp[2] = {_mm_setr_ps(0, 1, 2, 3), _mm_setr_ps(4, 5, 6, 7)};
    __m128 jr = _mm_set1_ps((float)(o->ty0 * SL_RT_TILE_H - s->oy[l]));
    for (int e = 0; e < 3; e++) {
        /* (n0 + jr*s) + r*s at the first tile row: integers below 2^24, every operation exact */
        __m128 st = _mm_set1_ps(s->s[e][l]), nj = _mm_add_ps(_mm_set1_ps(s->n0[e][l]), _mm_mul_ps(jr, st));
        for (int h = 0; h < 2; h++)
            o->n[e][h] = _mm_add_ps(nj, _mm_mul_ps(ramp[h], st));
        o->s8[e] = _mm_mul_ps(st, _mm_set1_ps(8.0f));
        o->dd[e] = _mm_set1_ps(s->dd[e][l]);
    }
    o->cap = _mm_set1_ps(s->cap[l]);
    o->cl = _mm_set1_ps(s->cl[l]);
    o->cr = _mm_set1_ps(s->cr[l]);
    o->z0 = s->z0[l], o->zdx = s->zdx[l], o->zdy = s->zdy[l];
    o->zclamp = _mm_set1_ps(s->zclamp[l]);
    /* off[k] = zdx*((float)(8*(k&3)) + offx) + zdy*((float)(4*(k>>2)) + offy), as sl_rt_setup */
    __m128 kx = _mm_add_ps(_mm_setr_ps(0, 8, 16, 24), _mm_set1_ps(s->offx[l]));
    for (int h = 0; h < 2; h++) {
        __m128 ky = _mm_add_ps(_mm_set1_ps(4.0f * (float)h), _mm_set1_ps(s->offy[l]));
        o->off[h] = _mm_add_ps(_mm_mul_ps(_mm_set1_ps(o->zdx), kx), _mm_mul_ps(_mm_set1_ps(o->zdy), ky));
    }
    return true;
}

/* Spans [xl[h], xr[h]) relative to ox of the rows of tile row ty (emptied outside [row0, row1));
 * then steps the numerators to the next tile row. */
SSE41 static inline void small_spans4(small_tri4 *t, int32_t ty, __m128i xl[2], __m128i xr[2])
{
    bool partial = ty * SL_RT_TILE_H < t->row0 || ty * SL_RT_TILE_H + SL_RT_TILE_H > t->row1;
    for (int h = 0; h < 2; h++) {
        __m128 t0 = _mm_ceil_ps(_mm_div_ps(t->n[0][h], t->dd[0]));
        __m128 t1 = _mm_ceil_ps(_mm_div_ps(t->n[1][h], t->dd[1]));
        __m128 t2 = _mm_ceil_ps(_mm_div_ps(t->n[2][h], t->dd[2]));
        for (int e = 0; e < 3; e++)
            t->n[e][h] = _mm_add_ps(t->n[e][h], t->s8[e]);
        __m128 l = _mm_max_ps(_mm_max_ps(t->cl, t0), _mm_min_ps(t2, t->cap));
        __m128 r = _mm_min_ps(_mm_min_ps(t->cr, t1), _mm_max_ps(t2, t->cap));
        if (partial) {
            __m128 j = _mm_add_ps(_mm_set1_ps((float)(ty * SL_RT_TILE_H + 4 * h)), _mm_setr_ps(0, 1, 2, 3));
            __m128 valid = _mm_and_ps(_mm_cmpge_ps(j, _mm_set1_ps((float)t->row0)),
                                      _mm_cmplt_ps(j, _mm_set1_ps((float)t->row1)));
            r = _mm_blendv_ps(_mm_set1_ps((float)-SL_RT_BIG), r, valid);
        }
        xl[h] = _mm_cvttps_epi32(l);
        xr[h] = _mm_cvttps_epi32(r);
    }
}

/* raster_small8.h's small_dda on two 4-lane halves: the thresholds of a wide small triangle
 * stepped exactly in integers instead of six divisions per tile row (the same values). */
typedef struct small_dda4 {
    __m128i q[3][2], r[3][2], q8[3], e8[3], dd[3];
    __m128i cap, cl, cr;
} small_dda4;

SSE41 static inline void small_dda4_init(const small_tri4 *t, small_dda4 *d)
{
    for (int e = 0; e < 3; e++) {
        /* exact as in small_dda_init: |n|, |8s| < 2^23, products and remainders below 2^24 */
        for (int h = 0; h < 2; h++) {
            __m128 q = _mm_ceil_ps(_mm_div_ps(t->n[e][h], t->dd[e]));
            d->q[e][h] = _mm_cvttps_epi32(q);
            d->r[e][h] = _mm_cvttps_epi32(_mm_sub_ps(_mm_mul_ps(q, t->dd[e]), t->n[e][h]));
        }
        __m128 q8 = _mm_floor_ps(_mm_div_ps(t->s8[e], t->dd[e]));
        d->q8[e] = _mm_cvttps_epi32(q8);
        d->e8[e] = _mm_cvttps_epi32(_mm_sub_ps(t->s8[e], _mm_mul_ps(q8, t->dd[e])));
        d->dd[e] = _mm_cvttps_epi32(t->dd[e]);
    }
    d->cap = _mm_cvttps_epi32(t->cap);
    d->cl = _mm_cvttps_epi32(t->cl);
    d->cr = _mm_cvttps_epi32(t->cr);
}

/* small_spans4 with small_dda4's stepping. */
SSE41 static inline void small_spans4_dda(const small_tri4 *t, small_dda4 *d, int32_t ty, __m128i xl[2], __m128i xr[2])
{
    bool partial = ty * SL_RT_TILE_H < t->row0 || ty * SL_RT_TILE_H + SL_RT_TILE_H > t->row1;
    for (int h = 0; h < 2; h++) {
        __m128i t0 = d->q[0][h], t1 = d->q[1][h], t2 = d->q[2][h];
        for (int e = 0; e < 3; e++) {
            __m128i r = _mm_sub_epi32(d->r[e][h], d->e8[e]);
            __m128i borrow = _mm_srai_epi32(r, 31);
            d->r[e][h] = _mm_add_epi32(r, _mm_and_si128(borrow, d->dd[e]));
            d->q[e][h] = _mm_sub_epi32(_mm_add_epi32(d->q[e][h], d->q8[e]), borrow);
        }
        __m128i l = _mm_max_epi32(_mm_max_epi32(d->cl, t0), _mm_min_epi32(t2, d->cap));
        __m128i r = _mm_min_epi32(_mm_min_epi32(d->cr, t1), _mm_max_epi32(t2, d->cap));
        if (partial) {
            __m128i j = _mm_add_epi32(_mm_set1_epi32(ty * SL_RT_TILE_H + 4 * h), _mm_setr_epi32(0, 1, 2, 3));
            __m128i valid = _mm_and_si128(_mm_cmpgt_epi32(j, _mm_set1_epi32(t->row0 - 1)),
                                          _mm_cmpgt_epi32(_mm_set1_epi32(t->row1), j));
            r = _mm_blendv_epi8(_mm_set1_epi32(-SL_RT_BIG), r, valid);
        }
        xl[h] = l;
        xr[h] = r;
    }
}

/* Rasterize a small triangle: per tile row its spans, the tiles they touch, and per tile the
 * row masks and the merge of each half. */
SSE41 static void raster_small4(const sl_rt_target *tg, small_tri4 *t)
{
    const __m128i ctl = transpose_ctl();
    const size_t tiles_x = (size_t)tg->tiles_x;
    small_dda4 dda;
    small_dda4_init(t, &dda);
    for (int32_t ty = t->ty0; ty < t->ty1; ty++) {
        __m128i xl[2], xr[2];
        small_spans4_dda(t, &dda, ty, xl, xr);
        int32_t ta = t->tx0, tb = t->tx1;
        if (tb - ta > 2) {
            /* the tiles this tile row's spans touch (spans relative to ox) */
            __m128i n0 = _mm_cmpgt_epi32(xr[0], xl[0]), n1 = _mm_cmpgt_epi32(xr[1], xl[1]);
            if (_mm_testz_si128(_mm_or_si128(n0, n1), _mm_or_si128(n0, n1)))
                continue;
            const __m128i big = _mm_set1_epi32(SL_RT_BIG), nbig = _mm_set1_epi32(-SL_RT_BIG);
            int32_t lo = hmin4(_mm_min_epi32(_mm_blendv_epi8(big, xl[0], n0), _mm_blendv_epi8(big, xl[1], n1))) + t->ox;
            int32_t hi = hmax4(_mm_max_epi32(_mm_blendv_epi8(nbig, xr[0], n0), _mm_blendv_epi8(nbig, xr[1], n1))) + t->ox;
            ta = sl_rt_maxi(ta, lo >> 5);
            tb = sl_rt_mini(tb, ((hi - 1) >> 5) + 1);
        }
        float zrow = t->zdy * (float)(ty * SL_RT_TILE_H - t->y_ref);
        size_t row = (size_t)ty * tiles_x;
        for (int32_t tx = ta; tx < tb; tx++) {
            int32_t x = tx * SL_RT_TILE_W;
            __m128i xo = _mm_set1_epi32(x - t->ox);
            __m128i r0 = row_masks(xl[0], xr[0], xo), r1 = row_masks(xl[1], xr[1], xo);
            size_t ti = row + (size_t)tx;
            __m128 zt = _mm_set1_ps((t->z0 + t->zdx * (float)(x - t->x_ref)) + zrow);
            uint32_t *mp = tg->mask + ti * SL_RT_SUBTILES;
            sl_rt_tile_depth *dp = &tg->depth[ti];
            merge4(_mm_shuffle_epi8(r0, ctl), _mm_max_ps(_mm_add_ps(zt, t->off[0]), t->zclamp), mp, dp->za, dp->zm);
            merge4(_mm_shuffle_epi8(r1, ctl), _mm_max_ps(_mm_add_ps(zt, t->off[1]), t->zclamp), mp + 4, dp->za + 4,
                   dp->zm + 4);
        }
    }
}

/* A small triangle one to three tiles wide (cols, a constant; the tiles inside the caller's range):
 * each tile row merges exactly cols tiles without a branch (a tile the row does not reach has no
 * coverage: its merge changes nothing), as raster_small8.h's raster_cols. */
SSE41 static inline __attribute__((always_inline)) void raster_cols4(const sl_rt_target *tg, small_tri4 *t, int cols)
{
    const __m128i ctl = transpose_ctl();
    const int32_t x = t->tx0 * SL_RT_TILE_W;
    float zt[3];
    for (int c = 0; c < cols; c++)
        zt[c] = t->z0 + t->zdx * (float)(x + c * SL_RT_TILE_W - t->x_ref);
    const size_t tiles_x = (size_t)tg->tiles_x;
    size_t ti = (size_t)t->ty0 * tiles_x + (size_t)t->tx0;
    for (int32_t ty = t->ty0; ty < t->ty1; ty++, ti += tiles_x) {
        __m128i xl[2], xr[2];
        small_spans4(t, ty, xl, xr);
        float zrow = t->zdy * (float)(ty * SL_RT_TILE_H - t->y_ref);
        for (int c = 0; c < cols; c++) {
            __m128i xo = _mm_set1_epi32(x + c * SL_RT_TILE_W - t->ox);
            __m128 z = _mm_set1_ps(zt[c] + zrow);
            uint32_t *mp = tg->mask + (ti + (size_t)c) * SL_RT_SUBTILES;
            sl_rt_tile_depth *dp = &tg->depth[ti + (size_t)c];
            merge4_to(_mm_shuffle_epi8(row_masks(xl[0], xr[0], xo), ctl), _mm_max_ps(_mm_add_ps(z, t->off[0]), t->zclamp),
                      mp, dp->za, dp->zm, false);
            merge4_to(_mm_shuffle_epi8(row_masks(xl[1], xr[1], xo), ctl), _mm_max_ps(_mm_add_ps(z, t->off[1]), t->zclamp),
                      mp + 4, dp->za + 4, dp->zm + 4, false);
        }
    }
}

/* Set up prims in groups of 4: small ones take raster_cols4 or raster_small4 (by width), the others the reference setup and
 * the general kernel. */
SSE41 static void render_sse41(const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0,
                               int32_t tx1, int32_t ty0, int32_t ty1)
{
    for (uint32_t i = 0; i < n; i += SL_RT_W) {
        uint32_t k = n - i < SL_RT_W ? n - i : SL_RT_W;
        small_lanes s;
        unsigned empty, small = setup_lanes(p + i, k, mode, &s, &empty);
        for (uint32_t l = 0; l < k; l++) {
            if (small >> l & 1) {
                small_tri4 st;
                if (!small_load4(&s, (int)l, tx0, tx1, ty0, ty1, &st))
                    continue;
                if (st.tx1 - st.tx0 == 1)
                    raster_cols4(tg, &st, 1);
                else if (st.tx1 - st.tx0 == 2)
                    raster_cols4(tg, &st, 2);
                else if (st.tx1 - st.tx0 == 3)
                    raster_cols4(tg, &st, 3);
                else
                    raster_small4(tg, &st);
            } else if (!(empty >> l & 1)) {
                sl_rt_render_each(raster_sse41, tg, mode, p + i + l, 1, tx0, tx1, ty0, ty1);
            }
        }
    }
}

const sl_rt_kernels sl_rt_kernels_sse41 = {SL_RASTER_ISA_SSE41, raster_sse41, query_sse41, rect_sse41,
                                           front_sse41, render_sse41};

#endif

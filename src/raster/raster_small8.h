/* The small-triangle kernels of the AVX2 and AVX-512 paths: a triangle set up by raster_batch.h's
 * setup_lanes (8 lanes) is rasterized with float thresholds, one tile row (8 pixel rows) per
 * 256-bit register of spans. Included by raster_avx2.c and raster_avx512.c after raster_simd8.h
 * and raster_batch.h. */
#if !defined(SL_RT_T) || SL_RT_W != 8
#error "raster_small8.h needs the 8-lane raster_batch.h"
#endif

/* One tile row of a small triangle, ready for its tiles: spans relative to ox and the tiles
 * [ta, tb) they touch (any = false when no row of it is covered). */
typedef struct small_row {
    __m256i xl, xr;
    int32_t ta, tb;
    bool any;
} small_row;

/* Per-triangle constants of the small kernel for lane l. */
typedef struct small_tri {
    __m256 n[3], s8[3], dd[3]; /* n: numerators of the rows of the current tile row */
    __m256 cap, cl, cr, off, zclamp;
    float z0, zdx, zdy;
    int32_t ox, oy, x_ref, y_ref, row0, row1;
    int32_t tx0, tx1, ty0, ty1; /* tile bounds, clipped to the caller's */
} small_tri;

/* Exact stepping of a wide small triangle's thresholds (raster_small_ymm, raster_small): with
 * n = q*dd - r (0 <= r < dd) and 8s = q8*dd + e8 (0 <= e8 < dd), the next tile row's threshold
 * ceil((n + 8s)/dd) is q + q8, plus 1 when r - e8 < 0 (then r - e8 + dd is its remainder): integer
 * operations instead of three divisions per tile row, the same values. */
typedef struct small_dda {
    __m256i q[3], r[3], q8[3], e8[3], dd[3];
    __m256i cap, cl, cr;
} small_dda;

SL_RT_T static inline __attribute__((always_inline)) void small_dda_init(const small_tri *t, small_dda *d)
{
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        /* the first tile row by division (|n| < 2^23: exact), q*dd - n an exact integer below
         * 2^24; floor(8s/dd) of |8s| < 2^23 is exact like the ceiling, q8*dd and e8 exact too */
        __m256 q = _mm256_ceil_ps(_mm256_div_ps(t->n[e], t->dd[e]));
        __m256 q8 = _mm256_floor_ps(_mm256_div_ps(t->s8[e], t->dd[e]));
        d->q[e] = _mm256_cvttps_epi32(q);
        d->r[e] = _mm256_cvttps_epi32(_mm256_sub_ps(_mm256_mul_ps(q, t->dd[e]), t->n[e]));
        d->q8[e] = _mm256_cvttps_epi32(q8);
        d->e8[e] = _mm256_cvttps_epi32(_mm256_sub_ps(t->s8[e], _mm256_mul_ps(q8, t->dd[e])));
        d->dd[e] = _mm256_cvttps_epi32(t->dd[e]);
    }
    d->cap = _mm256_cvttps_epi32(t->cap);
    d->cl = _mm256_cvttps_epi32(t->cl);
    d->cr = _mm256_cvttps_epi32(t->cr);
}

SL_RT_T static inline __attribute__((always_inline)) void small_row_at(const small_tri *t, small_dda *d, int32_t ty,
                                                                       small_row *r);

SL_RT_T static inline __attribute__((always_inline)) bool small_load(const small_lanes *s, int l, int32_t tx0, int32_t tx1,
                                                                     int32_t ty0, int32_t ty1, small_tri *o)
{
    int32_t tb[4];
    if (!small_tiles(s, l, tx0, tx1, ty0, ty1, tb))
        return false;
    o->tx0 = tb[0], o->tx1 = tb[1], o->ty0 = tb[2], o->ty1 = tb[3];
    o->ox = s->ox[l], o->oy = s->oy[l];
    o->row0 = s->row0[l], o->row1 = s->row1[l];
    o->x_ref = s->col0[l], o->y_ref = s->row0[l];
    const __m256 ramp = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    __m256 jr = FSPLAT((float)(o->ty0 * SL_RT_TILE_H - o->oy));
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        /* (n0 + jr*s) + r*s at the first tile row: integers below 2^24, every operation exact */
        __m256 st = _mm256_broadcast_ss(&s->s[e][l]);
        o->n[e] = _mm256_add_ps(_mm256_add_ps(_mm256_broadcast_ss(&s->n0[e][l]), _mm256_mul_ps(jr, st)),
                                _mm256_mul_ps(ramp, st));
        o->s8[e] = _mm256_mul_ps(st, FSPLAT(8.0f));
        o->dd[e] = _mm256_broadcast_ss(&s->dd[e][l]);
    }
    o->cap = _mm256_broadcast_ss(&s->cap[l]);
    o->cl = _mm256_broadcast_ss(&s->cl[l]);
    o->cr = _mm256_broadcast_ss(&s->cr[l]);
    o->z0 = s->z0[l], o->zdx = s->zdx[l], o->zdy = s->zdy[l];
    o->zclamp = _mm256_broadcast_ss(&s->zclamp[l]);
    /* off[k] = zdx*((float)(8*(k&3)) + ox) + zdy*((float)(4*(k>>2)) + oy), as sl_rt_setup */
    __m256 kx = _mm256_add_ps(_mm256_setr_ps(0, 8, 16, 24, 0, 8, 16, 24), _mm256_broadcast_ss(&s->offx[l]));
    __m256 ky = _mm256_add_ps(_mm256_setr_ps(0, 0, 0, 0, 4, 4, 4, 4), _mm256_broadcast_ss(&s->offy[l]));
    o->off = _mm256_add_ps(_mm256_mul_ps(FSPLAT(o->zdx), kx), _mm256_mul_ps(FSPLAT(o->zdy), ky));
    return true;
}

/* Spans [xl, xr) (relative to ox) of the pixel rows of tile row ty, empty outside [row0, row1);
 * then steps the numerators to the next tile row (tile rows are visited in order). */
SL_RT_T static inline __attribute__((always_inline)) void small_spans(small_tri *t, int32_t ty, __m256i *pxl,
                                                                      __m256i *pxr)
{
    const __m256 ramp = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    __m256 t0 = _mm256_ceil_ps(_mm256_div_ps(t->n[0], t->dd[0]));
    __m256 t1 = _mm256_ceil_ps(_mm256_div_ps(t->n[1], t->dd[1]));
    __m256 t2 = _mm256_ceil_ps(_mm256_div_ps(t->n[2], t->dd[2]));
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++)
        t->n[e] = _mm256_add_ps(t->n[e], t->s8[e]);
    __m256 xl = _mm256_max_ps(_mm256_max_ps(t->cl, t0), _mm256_min_ps(t2, t->cap));
    __m256 xr = _mm256_min_ps(_mm256_min_ps(t->cr, t1), _mm256_max_ps(t2, t->cap));
    if (ty * SL_RT_TILE_H < t->row0 || ty * SL_RT_TILE_H + SL_RT_TILE_H > t->row1) {
        __m256 j = _mm256_add_ps(FSPLAT((float)(ty * SL_RT_TILE_H)), ramp);
        __m256 valid = _mm256_and_ps(_mm256_cmp_ps(j, FSPLAT((float)t->row0), _CMP_GE_OQ),
                                     _mm256_cmp_ps(j, FSPLAT((float)t->row1), _CMP_LT_OQ));
        xr = _mm256_blendv_ps(FSPLAT((float)-SL_RT_BIG), xr, valid);
    }
    *pxl = _mm256_cvttps_epi32(xl);
    *pxr = _mm256_cvttps_epi32(xr);
}

/* small_spans with the exact stepping of small_dda (the same spans). */
SL_RT_T static inline __attribute__((always_inline)) void small_spans_dda(const small_tri *t, small_dda *d, int32_t ty,
                                                                          __m256i *pxl, __m256i *pxr)
{
    const __m256i t0 = d->q[0], t1 = d->q[1], t2 = d->q[2];
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        __m256i r = _mm256_sub_epi32(d->r[e], d->e8[e]);
        __m256i borrow = _mm256_srai_epi32(r, 31); /* -1 where r - e8 < 0 */
        d->r[e] = _mm256_add_epi32(r, _mm256_and_si256(borrow, d->dd[e]));
        d->q[e] = _mm256_sub_epi32(_mm256_add_epi32(d->q[e], d->q8[e]), borrow);
    }
    /* min/max of exact integers: the float version's values */
    __m256i xl = _mm256_max_epi32(_mm256_max_epi32(d->cl, t0), _mm256_min_epi32(t2, d->cap));
    __m256i xr = _mm256_min_epi32(_mm256_min_epi32(d->cr, t1), _mm256_max_epi32(t2, d->cap));
    if (ty * SL_RT_TILE_H < t->row0 || ty * SL_RT_TILE_H + SL_RT_TILE_H > t->row1) {
        __m256i j = _mm256_add_epi32(_mm256_set1_epi32(ty * SL_RT_TILE_H), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        __m256i valid = _mm256_and_si256(_mm256_cmpgt_epi32(j, _mm256_set1_epi32(t->row0 - 1)),
                                         _mm256_cmpgt_epi32(_mm256_set1_epi32(t->row1), j));
        xr = _mm256_blendv_epi8(_mm256_set1_epi32(-SL_RT_BIG), xr, valid);
    }
    *pxl = xl;
    *pxr = xr;
}

SL_RT_T static inline __attribute__((always_inline)) void small_row_at(const small_tri *t, small_dda *d, int32_t ty,
                                                                       small_row *r)
{
    small_spans_dda(t, d, ty, &r->xl, &r->xr);
    r->ta = t->tx0, r->tb = t->tx1;
    r->any = true;
    if (r->tb - r->ta > 2) {
        /* wider than two tiles: the tiles this tile row's spans touch */
        __m256i ne = _mm256_cmpgt_epi32(r->xr, r->xl);
        r->any = !_mm256_testz_si256(ne, ne);
        /* (empty rows give sentinels that cannot overflow; the range is then unused) */
        int32_t lo = hmin(_mm256_blendv_epi8(_mm256_set1_epi32(SL_RT_BIG), r->xl, ne)) + t->ox;
        int32_t hi = hmax(_mm256_blendv_epi8(_mm256_set1_epi32(-SL_RT_BIG), r->xr, ne)) + t->ox;
        /* arithmetic shifts: floor division, and the range is only used when a row is covered
         * (then lo >= 0 and hi >= 1) */
        r->ta = sl_rt_maxi(r->ta, lo >> 5);
        r->tb = sl_rt_mini(r->tb, ((hi - 1) >> 5) + 1);
    }
    /* computed here, not where it is used: see raster_avx512.c */
    __asm__("" : "+x"(r->xl), "+x"(r->xr), "+r"(r->ta), "+r"(r->tb), "+r"(r->any));
}

/* A triangle one to three tiles wide (cols, a constant; the tiles inside the caller's range): each
 * tile row merges exactly cols tiles, without an inner loop (a tile the row does not reach has no
 * coverage: its merge changes nothing). */
SL_RT_T static inline __attribute__((always_inline)) void raster_cols(const sl_rt_target *tg, small_tri *t, int cols)
{
    const __m256i ctl = transpose_ctl();
    const int32_t x = t->tx0 * SL_RT_TILE_W, dxl = x - t->ox;
    float zt[3];
    SL_RT_UNROLL
    for (int c = 0; c < cols; c++)
        zt[c] = t->z0 + t->zdx * (float)(x + c * SL_RT_TILE_W - t->x_ref);
    const size_t tiles_x = (size_t)tg->tiles_x;
    size_t ti = (size_t)t->ty0 * tiles_x + (size_t)t->tx0;
    for (int32_t ty = t->ty0; ty < t->ty1; ty++, ti += tiles_x) {
        __m256i xl, xr;
        small_spans(t, ty, &xl, &xr);
        float zrow = t->zdy * (float)(ty * SL_RT_TILE_H - t->y_ref);
        int c0 = 1;
#if defined(SL_RT_PAIR_COLS)
        if (cols == 3) {
            /* AVX-512: tiles 0 and 1 in one 512-bit register (raster_avx512.c's merge_pair); measured
             * 5-10% faster on 50x50-pixel triangles than three 256-bit merges */
            const __m512 off2 = _mm512_insertf32x8(_mm512_castps256_ps512(t->off), t->off, 1);
            merge_pair(pair_masks(_mm512_broadcast_i64x4(xl), _mm512_broadcast_i64x4(xr), dxl,
                                  _mm512_broadcast_i64x4(ctl)),
                       pair_depth(t->z0, t->zdx, zrow, x - t->x_ref, off2, _mm512_broadcast_f32x8(t->zclamp)),
                       tg->mask + ti * SL_RT_SUBTILES, &tg->depth[ti]);
            c0 = 2;
        } else
#endif
        {
            __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt[0] + zrow), t->off), t->zclamp);
            merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, dxl), ctl), z, tg->mask + ti * SL_RT_SUBTILES,
                       &tg->depth[ti]);
        }
        SL_RT_UNROLL
        for (int c = c0; c < cols; c++) {
            __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt[c] + zrow), t->off), t->zclamp);
            merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, dxl + c * SL_RT_TILE_W), ctl), z,
                       tg->mask + (ti + (size_t)c) * SL_RT_SUBTILES, &tg->depth[ti + (size_t)c]);
        }
    }
}

/* A small triangle of any width: its float thresholds, then each tile row's tiles one per 256-bit
 * register, each tile column's z0 + zdx*(float)(x - x_ref) computed once; rows are computed one
 * ahead (see raster_simd8.h's general_ymm). */
SL_RT_T static inline __attribute__((always_inline)) void raster_small_ymm(const sl_rt_target *tg, small_tri *t)
{
    const __m256i ctl = transpose_ctl();
    const float zdy = t->zdy;
    const int32_t y_ref = t->y_ref, ox = t->ox;
    uint32_t *const mask = tg->mask;
    sl_rt_tile_depth *const depth = tg->depth;
    const size_t tiles_x = (size_t)tg->tiles_x;
    /* each tile column's z0 + zdx*(float)(x - x_ref), as in general_ymm (indexed zcol[tx - tx0]:
     * a pointer zcol - tx0 would lie outside the array) */
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
    const int32_t tx0 = t->tx0;
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
            for (int32_t tx = cur.ta; tx < cur.tb; tx++) {
                size_t ti = row + (size_t)tx;
                __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zcol[tx - tx0] + zrow), t->off), t->zclamp);
                merge_tile(_mm256_shuffle_epi8(row_masks(cur.xl, cur.xr, tx * SL_RT_TILE_W - ox), ctl), z,
                           mask + ti * SL_RT_SUBTILES, &depth[ti]);
            }
        }
        cur = nxt;
    }
}

/* The batched front end and the small-triangle setup of the SIMD paths, one triangle per lane:
 * 8 per 256-bit register on AVX2 and AVX-512, 4 per 128-bit register on SSE4.1. Written once with
 * the lane vectors of raster_lanes.h (included first, with SL_RT_W) and included by raster_sse41.c,
 * raster_avx2.c and raster_avx512.c, so that each file compiles its own copy for its own
 * instruction set and width (SL_RT_T, SL_RT_NAME, SL_RT_W).
 *
 * Every lane repeats the operations of the scalar reference (raster_setup.c) exactly:
 *  - front: the transform ((m0*x + m4*y) + m8*z) + m12, the outcodes, the snap
 *    ((c*(1/w))*h + h, rounded to nearest even) and sl_rt_prepare, with the same float operations
 *    in the same order and the area in exact double arithmetic. A triangle that needs clipping
 *    goes through the scalar code (sl_rt_front_prims) at its place in the order.
 *  - setup_lanes: the depth plane of sl_rt_setup in double precision, operation for operation, so
 *    z0, zdx, zdy, the offsets and the clamp are the same bits. The edges are set up differently
 *    (coverage is exact, so any exact method gives the same pixels): relative to the triangle's
 *    tile-aligned origin (ox, oy) the column threshold of pixel row oy + r is
 *        t(r) = ox + ceil((N0 + r*S) / D),  D = |dY| > 0, S = -+dX
 *    (the reference's quotient with its common factor 256 removed, by
 *    ceil(ceil(a/256)/D) = ceil(a/(256*D))). When every numerator the triangle's rows need is below
 *    2^23 in magnitude (a "small" triangle, up to about 100 pixels wide and tall) the kernels
 *    compute the thresholds in float: the integers are exact and the correctly rounded quotient
 *    has the exact ceiling (a non-integer quotient is at least 1/D from an integer, more than its
 *    rounding error |q|*2^-24 < 1/D). Other triangles take the reference setup and the general
 *    kernel. */
#ifndef SL_RT_T
#error "define SL_RT_T, SL_RT_NAME and SL_RT_W and include raster_lanes.h before raster_batch.h"
#endif

/* ceil(a / 256) of int32 lanes (arithmetic shifts, as in raster_setup.c). */
SL_RT_T static inline lvi ceil256_l(lvi a)
{
    return li_sub(li_zero(), li_srai(li_sub(li_zero(), a), 8));
}
SL_RT_T static inline lvi clamp_l(lvi x, int32_t lo, int32_t hi)
{
    return li_min(li_max(x, ISPLAT(lo)), ISPLAT(hi));
}

/* ---- the front end ---- */

SL_RT_T static uint32_t SL_RT_NAME(front)(const sl_rt_view *v, int mode, const sl_rt_batch *b, uint32_t *next,
                                          uint32_t last, sl_rt_counters *cnt, sl_rt_prim *out, uint32_t cap)
{
    const lvi lane = li_lanes(), lanebit = li_lanebits(), zero = li_zero();
    const char *vbase = (const char *)b->vertices;
    const uint32_t vc = b->vertex_count, stride = b->stride;
    const float *m = b->m;
    const lvf sign = FSPLAT(-0.0f), lim = FSPLAT(SL_RT_SNAP_LIMIT), nlim = lf_sub(lf_zero(), lim);
    const lvf hw = FSPLAT(v->half_w), hh = FSPLAT(v->half_h), nhh = FSPLAT(-v->half_h);
    const lvf gx = FSPLAT(v->guard_x), gy = FSPLAT(v->guard_y), nearw = FSPLAT(v->near_w);
    const lvf sub = FSPLAT((float)SL_RT_SUBPIX);
    const bool inv_w = v->depth == SL_RASTER_DEPTH_INV_W;
    uint32_t t = *next, n = 0;
    while (t < last && n + SL_RT_W * SL_RT_FAN_MAX <= cap) {
        uint32_t k = last - t < SL_RT_W ? last - t : SL_RT_W;
        lvi valid = li_gt(ISPLAT((int32_t)k), lane);
        /* indices: a bad one is replaced by 0 for the load (when there is a vertex 0) and the lane
         * rejected */
        const uint32_t *ix = b->indices + (size_t)t * 3;
        uint32_t vi[3][SL_RT_W];
        lvi badidx;
        if (k == SL_RT_W) {
            lvi idx[3];
            load_indices(ix, idx);
            badidx = zero;
            SL_RT_UNROLL
            for (int c = 0; c < 3; c++) {
                /* unsigned idx >= vertex_count; a bad index loads vertex 0 instead */
                lvi bad = li_eq(li_maxu(idx[c], ISPLAT((int32_t)vc)), idx[c]);
                badidx = li_or(badidx, bad);
                li_storeu(vi[c], li_andnot(bad, idx[c]));
            }
        } else {
            /* the tail of the batch: lanes past it load vertex 0 too and are ignored */
            unsigned bad = 0;
            for (uint32_t l = 0; l < SL_RT_W; l++)
                for (int c = 0; c < 3; c++) {
                    uint32_t i = l < k ? ix[3 * l + c] : 0;
                    bool ok = i < vc;
                    bad |= (unsigned)!ok << l;
                    vi[c][l] = ok ? i : 0;
                }
            badidx = li_eq(li_and(ISPLAT((int32_t)bad), lanebit), lanebit);
        }
        badidx = li_and(badidx, valid);
        lvi fetch = li_andnot(badidx, valid);
        if (vc == 0)
            fetch = zero;
        /* transform and classify the three corners */
        lvf cx[3], cy[3], cz[3], cw[3];
        lvi nonfin = zero, clip = zero;
        lvi outl = ISPLAT(-1), outb = outl, outn = outl, outr = outl, outt = outl, outf = outl;
        SL_RT_UNROLL
        for (int c = 0; c < 3; c++) {
            lvf px, py, pz;
            if (vc > 0) {
                load_corner(vbase, vi[c], stride, &px, &py, &pz);
            } else {
                px = py = pz = lf_zero();
            }
            lvf r[4];
            SL_RT_UNROLL
            for (int i = 0; i < 4; i++)
                r[i] = lf_add(lf_add(lf_add(lf_mul(FSPLAT(m[i]), px),
                                                                 lf_mul(FSPLAT(m[4 + i]), py)),
                                                   lf_mul(FSPLAT(m[8 + i]), pz)),
                                     FSPLAT(m[12 + i]));
            cx[c] = r[0], cy[c] = r[1], cz[c] = r[2], cw[c] = r[3];
            nonfin = li_or(nonfin, li_or(li_or(li_nonfinite(r[0]), li_nonfinite(r[1])),
                                                             li_or(li_nonfinite(r[2]), li_nonfinite(r[3]))));
            lvf w = r[3], nw = lf_xor(w, sign);
            outl = li_and(outl, AS_SI(lf_cmp(r[0], nw, _CMP_LT_OQ)));
            outb = li_and(outb, AS_SI(lf_cmp(r[1], nw, _CMP_LT_OQ)));
            lvf near = lf_cmp(r[2], nw, _CMP_LT_OQ);
            outn = li_and(outn, AS_SI(near));
            outr = li_and(outr, AS_SI(lf_cmp(r[0], w, _CMP_GT_OQ)));
            outt = li_and(outt, AS_SI(lf_cmp(r[1], w, _CMP_GT_OQ)));
            outf = li_and(outf, AS_SI(lf_cmp(r[2], w, _CMP_GT_OQ)));
            lvf g = lf_or(lf_cmp(lf_andnot(sign, r[0]), lf_mul(gx, w), _CMP_GT_OQ),
                                    lf_cmp(lf_andnot(sign, r[1]), lf_mul(gy, w), _CMP_GT_OQ));
            g = lf_or(g, lf_or(near, lf_cmp(w, nearw, _CMP_LT_OQ)));
            clip = li_or(clip, AS_SI(g));
        }
        nonfin = li_and(nonfin, fetch);
        lvi live = li_andnot(nonfin, fetch);
        lvi outside = li_or(li_or(li_or(outl, outb), li_or(outn, outr)),
                                          li_or(outt, outf));
        outside = li_and(outside, live);
        live = li_andnot(outside, live);
        clip = li_and(clip, live);
        live = li_andnot(clip, live);
        /* snap (sl_rt_snap) */
        lvi X[3], Y[3], snapbad = zero;
        lvf d[3];
        SL_RT_UNROLL
        for (int c = 0; c < 3; c++) {
            lvf inv = lf_div(FSPLAT(1.0f), cw[c]);
            lvf sx = lf_add(lf_mul(lf_mul(cx[c], inv), hw), hw);
            lvf sy = lf_add(lf_mul(lf_mul(cy[c], inv), nhh), hh);
            d[c] = inv_w ? inv
                         : lf_add(lf_mul(lf_mul(cz[c], inv), FSPLAT(-0.5f)), FSPLAT(0.5f));
            lvf in =
                lf_and(lf_and(lf_cmp(sx, lim, _CMP_LE_OQ), lf_cmp(sx, nlim, _CMP_GE_OQ)),
                              lf_and(lf_cmp(sy, lim, _CMP_LE_OQ), lf_cmp(sy, nlim, _CMP_GE_OQ)));
            snapbad =
                li_or(snapbad, li_or(li_xor(AS_SI(in), ISPLAT(-1)), li_nonfinite(d[c])));
            X[c] = li_round_f(lf_mul(sx, sub));
            Y[c] = li_round_f(lf_mul(sy, sub));
        }
        snapbad = li_and(snapbad, live);
        live = li_andnot(snapbad, live);
        /* prepare (sl_rt_prepare): area, winding, orientation, pixel bounds */
        dl area = dl_sub(dl_mul(dl_i32(li_sub(X[1], X[0])), dl_i32(li_sub(Y[2], Y[0]))),
                         dl_mul(dl_i32(li_sub(X[2], X[0])), dl_i32(li_sub(Y[1], Y[0]))));
        lvi neg = DL_CMP(area, dl_set(0.0), _CMP_LT_OQ), pos = DL_CMP(area, dl_set(0.0), _CMP_GT_OQ);
        lvi degen = li_and(li_andnot(li_or(neg, pos), ISPLAT(-1)), live);
        live = li_andnot(degen, live);
        lvi back = b->backface == SL_RASTER_CULL_CW ? pos : (b->backface == SL_RASTER_CULL_CCW ? neg : zero);
        back = li_and(back, live);
        live = li_andnot(back, live);
        lvi X1 = li_blendv(X[1], X[2], neg), X2 = li_blendv(X[2], X[1], neg);
        lvi Y1 = li_blendv(Y[1], Y[2], neg), Y2 = li_blendv(Y[2], Y[1], neg);
        lvf d1 = lf_blendv(d[1], d[2], AS_PS(neg)), d2 = lf_blendv(d[2], d[1], AS_PS(neg));
        dl aarea = dl_abs(area);
        lvi xmin = li_min(X[0], li_min(X[1], X[2]));
        lvi xmax = li_max(X[0], li_max(X[1], X[2]));
        lvi ymin = li_min(Y[0], li_min(Y[1], Y[2]));
        lvi ymax = li_max(Y[0], li_max(Y[1], Y[2]));
        const lvi half = ISPLAT(SL_RT_SUBPIX / 2), one = ISPLAT(1);
        lvi c0 = clamp_l(ceil256_l(li_sub(xmin, half)), 0, v->pad_w);
        lvi c1 = clamp_l(li_add(li_srai(li_sub(xmax, half), 8), one), 0, v->pad_w);
        lvi r0 = clamp_l(ceil256_l(li_sub(ymin, half)), 0, v->pad_h);
        lvi r1 = clamp_l(li_add(li_srai(li_sub(ymax, half), 8), one), 0, v->pad_h);
        lvi empty =
            li_andnot(li_and(li_gt(c1, c0), li_gt(r1, r0)), live);
        live = li_andnot(empty, live);
        /* counts: every lane but the clipped ones, which the scalar code counts in order below */
        unsigned mclip = (unsigned)lf_movemask(AS_PS(clip)), mlive = (unsigned)lf_movemask(AS_PS(live));
        cnt->submitted += k - lanes_count(mclip);
        cnt->rejected_index += lanes_count((unsigned)lf_movemask(AS_PS(badidx)));
        cnt->rejected_nonfinite += lanes_count(
            (unsigned)lf_movemask(AS_PS(li_or(nonfin, snapbad))));
        cnt->culled_outside += lanes_count(
            (unsigned)lf_movemask(AS_PS(li_or(outside, empty))));
        cnt->degenerate += lanes_count((unsigned)lf_movemask(AS_PS(degen)));
        cnt->culled_backface += lanes_count((unsigned)lf_movemask(AS_PS(back)));
        cnt->rasterized += lanes_count(mlive);
        /* the prims, one 64-byte row per lane: the 16 fields transposed */
        lvi f[16] = {X[0], X1, X2, Y[0], Y1, Y2, AS_SI(d[0]), AS_SI(d1), AS_SI(d2), c0, c1, r0, r1, zero};
        dl_to_dwords(aarea, &f[14], &f[15]); /* area: lane i's double as dwords 14 (low) and 15 (high) */
        prims_from_lanes(f);
        if (!mclip) {
            for (unsigned bits = mlive; bits; bits &= bits - 1) {
                int l = __builtin_ctz(bits);
                prim_store(f, l, &out[n]);
                n++;
            }
        } else {
            for (unsigned l = 0; l < k; l++) {
                if (mlive >> l & 1) {
                    prim_store(f, (int)l, &out[n]);
                    n++;
                } else if (mclip >> l & 1) {
                    uint32_t tt = t + l;
                    n += sl_rt_front_prims(v, mode, b, &tt, t + l + 1, cnt, out + n, cap - n);
                }
            }
        }
        t += k;
    }
    *next = t;
    return n;
}

/* ---- the small-triangle setup ---- */

/* Set-up triangles of a group of W prims (lanes), structure of arrays. The edges sit in slots as
 * in sl_rt_tri: slot 0 bounds the span from the left, slot 1 from the right, slot 2 from the left
 * when cap = +BIG and from the right when cap = -BIG (a horizontal third edge is made neutral).
 * Threshold of slot e for pixel row oy + r, relative to column ox: ceil((n0[e] + r*s[e]) / dd[e]). */
typedef struct small_lanes {
    float n0[3][SL_RT_W], s[3][SL_RT_W], dd[3][SL_RT_W];
    float cap[SL_RT_W];
    float cl[SL_RT_W], cr[SL_RT_W];             /* col0 - ox, col1 - ox */
    int32_t ox[SL_RT_W], oy[SL_RT_W], col0[SL_RT_W], col1[SL_RT_W], row0[SL_RT_W], row1[SL_RT_W];
    float z0[SL_RT_W], zdx[SL_RT_W], zdy[SL_RT_W], zclamp[SL_RT_W], offx[SL_RT_W], offy[SL_RT_W];
} small_lanes;

/* Set up prims p[0..k) (k <= W) for the small path. Returns the lanes set up (a bit per lane);
 * *empty gets the lanes with no pixel row left (nothing to draw). The others need the reference
 * setup and the general kernel. */
SL_RT_T static unsigned setup_lanes(const sl_rt_prim *p, uint32_t k, int mode, small_lanes *s, unsigned *empty)
{
    *empty = 0;
    if (mode != SL_RT_CENTER && mode != SL_RT_INNER)
        return 0;
    lvi f[16];
    prims_to_lanes(p, k, f);
    const lvi zero = li_zero(), ones = ISPLAT(-1);
    lvi X[3] = {f[0], f[1], f[2]}, Y[3] = {f[3], f[4], f[5]};
    lvf d[3] = {AS_PS(f[6]), AS_PS(f[7]), AS_PS(f[8])};
    lvi col0 = f[9], col1 = f[10], row0 = f[11], row1 = f[12];
    dl area = dl_from_dwords(f[14], f[15]);
    /* edges: slope, tie or margin constant, horizontal edges' row limits */
    lvi dX[3], dY[3];
    dl cst[3];
    lvi xmin = li_min(X[0], li_min(X[1], X[2]));
    lvi xmax = li_max(X[0], li_max(X[1], X[2]));
    lvi ymin = li_min(Y[0], li_min(Y[1], Y[2]));
    lvi ymax = li_max(Y[0], li_max(Y[1], Y[2]));
    /* bbw + bbh + 3, below 2^25 */
    dl bbwh = dl_i32(li_add(li_add(li_sub(xmax, xmin), li_sub(ymax, ymin)),
                                      ISPLAT(3)));
    lvi horiz = zero;
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        int a = e, bb = e == 2 ? 0 : e + 1;
        dX[e] = li_sub(X[bb], X[a]);
        dY[e] = li_sub(Y[bb], Y[a]);
        lvi hz = li_eq(dY[e], zero);
        horiz = li_or(horiz, hz);
        if (mode == SL_RT_CENTER) {
            /* 0 for top-left edges (dY < 0, or dY == 0 and dX > 0), else 1 */
            lvi tl =
                li_or(li_gt(zero, dY[e]), li_and(hz, li_gt(dX[e], zero)));
            cst[e] = dl_i32(li_andnot(tl, ISPLAT(1)));
        } else {
            /* 129*(|dX| + |dY|) + bbw + bbh + 3, exact in double */
            dl s1 = dl_i32(li_add(li_abs(dX[e]), li_abs(dY[e])));
            cst[e] = dl_add(dl_mul(s1, dl_set(129.0)), bbwh);
        }
    }
    if (!li_testz(horiz, horiz)) {
        /* dX*(256j + 128 - Ya) >= c bounds the rows (raster_setup.c's ceil_q/floor_q, clamped) */
        SL_RT_UNROLL
        for (int e = 0; e < 3; e++) {
            lvi hz = li_eq(dY[e], zero);
            if (li_testz(hz, hz))
                continue;
            dl dx = dl_i32(dX[e]);
            dl num = dl_sub(cst[e], dl_mul(dx, dl_i32(li_sub(ISPLAT(SL_RT_SUBPIX / 2), Y[e]))));
            dl q = dl_div(num, dl_mul(dx, dl_set((double)SL_RT_SUBPIX)));
            const dl big = dl_set((double)SL_RT_BIG), nbig = dl_set((double)-SL_RT_BIG);
            dl qc = dl_ceil(q), qf = dl_floor(q);
            qc = dl_blend(qc, big, DL_CMP(qc, big, _CMP_GT_OQ));
            qc = dl_blend(qc, nbig, DL_CMP(qc, nbig, _CMP_LT_OQ));
            qf = dl_blend(qf, big, DL_CMP(qf, big, _CMP_GT_OQ));
            qf = dl_blend(qf, nbig, DL_CMP(qf, nbig, _CMP_LT_OQ));
            lvi top = li_and(hz, li_gt(dX[e], zero));
            lvi bot = li_and(hz, li_gt(zero, dX[e]));
            row0 = li_blendv(row0, li_max(row0, dl_to_i32(qc)), top);
            row1 = li_blendv(row1, li_min(row1, li_add(dl_to_i32(qf), ISPLAT(1))), bot);
        }
    }
    lvi rows_ok = li_gt(row1, row0);
    /* thresholds relative to the tile-aligned origin */
    lvi ox = li_and(col0, ISPLAT(~(SL_RT_TILE_W - 1))),
            oy = li_and(row0, ISPLAT(~(SL_RT_TILE_H - 1)));
    /* the last row the kernel evaluates: the tile rows up to row1 */
    dl rlast =
        dl_i32(li_or(li_sub(li_sub(row1, ISPLAT(1)), oy), ISPLAT(SL_RT_TILE_H - 1)));
    const dl lim = dl_set(8388608.0); /* 2^23 */
    lvi fits = rows_ok;
    lvf en0[3], es[3], edd[3];
    lvi left[3], right[3];
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        int a = e;
        lvi hz = li_eq(dY[e], zero);
        left[e] = li_gt(zero, dY[e]);
        right[e] = li_gt(dY[e], zero);
        lvi xa = li_sub(X[a], li_slli(ox, 8)),
                ya = li_sub(Y[a], li_slli(oy, 8));
        /* sg * (dX*(128 - Ya) - dY*(128 - Xa) - c + (dY > 0)), exact in double (below 2^48) */
        dl nl = dl_sub(dl_mul(dl_i32(dX[e]), dl_i32(li_sub(ISPLAT(SL_RT_SUBPIX / 2), ya))),
                       dl_mul(dl_i32(dY[e]), dl_i32(li_sub(ISPLAT(SL_RT_SUBPIX / 2), xa))));
        nl = dl_add(dl_sub(nl, cst[e]), dl_i32(li_and(right[e], ISPLAT(1))));
        dl sg = dl_blend(dl_set(1.0), dl_set(-1.0), left[e]);
        dl n0 = dl_ceil(dl_mul(dl_mul(nl, sg), dl_set(1.0 / SL_RT_SUBPIX)));
        dl st = dl_mul(dl_i32(dX[e]), sg);
        /* every numerator of rows 0..rlast below 2^23, and 8 steps too */
        dl nend = dl_add(n0, dl_mul(rlast, st));
        lvi ok = li_and(DL_CMP(dl_max(dl_abs(n0), dl_abs(nend)), lim, _CMP_LT_OQ),
                                      DL_CMP(dl_mul(dl_abs(st), dl_set(8.0)), lim, _CMP_LT_OQ));
        fits = li_and(fits, li_or(ok, hz));
        /* a horizontal edge: threshold -BIG whatever the row (neutral in slot 2 with cap +BIG) */
        en0[e] = lf_blendv(dl_to_ps(n0), FSPLAT((float)-SL_RT_BIG), AS_PS(hz));
        es[e] = lf_andnot(AS_PS(hz), dl_to_ps(st));
        edd[e] = lf_blendv(lf_from_i(li_abs(dY[e])), FSPLAT(1.0f), AS_PS(hz));
    }
    /* slots as in sl_rt_setup: the first left edge, the first right edge, the remaining one */
    {
        lvi sa1 = li_andnot(left[0], left[1]);           /* slot 0 holds edge 1 */
        lvi sa2 = li_andnot(li_or(left[0], left[1]), ISPLAT(-1)); /* edge 2 */
        lvi sb1 = li_andnot(right[0], right[1]);
        lvi sb2 = li_andnot(li_or(right[0], right[1]), ISPLAT(-1));
        lvi two_right = li_or(li_and(right[0], right[1]),
                                            li_or(li_and(right[0], right[2]),
                                                            li_and(right[1], right[2])));
        /* the edge of slot 2 is 3 - (slot 0's) - (slot 1's) */
        lvi ia = li_sub(li_zero(), li_add(sa1, li_add(sa2, sa2)));
        lvi ib = li_sub(li_zero(), li_add(sb1, li_add(sb2, sb2)));
        lvi ic = li_sub(li_sub(ISPLAT(3), ia), ib);
        lvi idx[3] = {ia, ib, ic};
        SL_RT_UNROLL
        for (int sl = 0; sl < 3; sl++) {
            lvf is1 = AS_PS(li_eq(idx[sl], ISPLAT(1))),
                   is2 = AS_PS(li_eq(idx[sl], ISPLAT(2)));
            lf_storeu(s->n0[sl], lf_blendv(lf_blendv(en0[0], en0[1], is1), en0[2], is2));
            lf_storeu(s->s[sl], lf_blendv(lf_blendv(es[0], es[1], is1), es[2], is2));
            lf_storeu(s->dd[sl], lf_blendv(lf_blendv(edd[0], edd[1], is1), edd[2], is2));
        }
        lf_storeu(s->cap,
                         lf_blendv(FSPLAT((float)SL_RT_BIG), FSPLAT((float)-SL_RT_BIG), AS_PS(two_right)));
    }
    li_storeu(s->ox, ox);
    li_storeu(s->oy, oy);
    li_storeu(s->col0, col0);
    li_storeu(s->col1, col1);
    li_storeu(s->row0, row0);
    li_storeu(s->row1, row1);
    lf_storeu(s->cl, lf_from_i(li_sub(col0, ox)));
    lf_storeu(s->cr, lf_from_i(li_sub(col1, ox)));

    /* depth plane: sl_rt_setup's double arithmetic, operation for operation */
    const dl kk = dl_set(1.0 / SL_RT_SUBPIX);
    dl ex1 = dl_mul(dl_i32(li_sub(X[1], X[0])), kk), ey1 = dl_mul(dl_i32(li_sub(Y[1], Y[0])), kk);
    dl ex2 = dl_mul(dl_i32(li_sub(X[2], X[0])), kk), ey2 = dl_mul(dl_i32(li_sub(Y[2], Y[0])), kk);
    dl dd0 = dl_ps(d[0]);
    dl dd1 = dl_sub(dl_ps(d[1]), dd0), dd2 = dl_sub(dl_ps(d[2]), dd0);
    dl inv_det = dl_div(dl_set(65536.0), area);
    dl pa = dl_mul(dl_sub(dl_mul(dd1, ey2), dl_mul(dd2, ey1)), inv_det);
    dl pb = dl_mul(dl_sub(dl_mul(ex1, dd2), dl_mul(ex2, dd1)), inv_det);
    dl cref = dl_add(dl_add(dd0, dl_mul(pa, dl_sub(dl_i32(col0), dl_mul(dl_i32(X[0]), kk)))),
                     dl_mul(pb, dl_sub(dl_i32(row0), dl_mul(dl_i32(Y[0]), kk))));
    lvf dmin = lf_min(lf_min(d[0], d[1]), d[2]);
    dl fa = dl_abs(pa), fb = dl_abs(pb);
    dl span =
        dl_add(dl_add(dl_abs(cref), dl_mul(fa, dl_i32(li_add(li_sub(col1, col0), ISPLAT(40))))),
               dl_mul(fb, dl_i32(li_add(li_sub(row1, row0), ISPLAT(40)))));
    dl bias = dl_add(dl_mul(span, dl_set(0x1p-19)), dl_mul(dl_add(fa, fb), dl_set(1.0 / 256.0)));
    const dl huge = dl_set(1e30);
    lvi ok = li_and(DL_CMP(span, huge, _CMP_LT_OQ),
                                  li_and(DL_CMP(fa, huge, _CMP_LT_OQ), DL_CMP(fb, huge, _CMP_LT_OQ)));
    float lo_x = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_x = mode == SL_RT_CENTER ? 7.5f : 8.0f;
    float lo_y = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_y = mode == SL_RT_CENTER ? 3.5f : 4.0f;
    lvi age = DL_CMP(pa, dl_set(0.0), _CMP_GE_OQ), bge = DL_CMP(pb, dl_set(0.0), _CMP_GE_OQ);
    lvf z0 = dl_to_ps(dl_sub(cref, bias)), zdx = dl_to_ps(pa), zdy = dl_to_ps(pb);
    ok = li_andnot(li_nonfinite(z0), ok);
    /* a plane too steep to evaluate: the vertex bound alone (offsets then come out 0) */
    z0 = lf_blendv(dmin, z0, AS_PS(ok));
    zdx = lf_and(zdx, AS_PS(ok));
    zdy = lf_and(zdy, AS_PS(ok));
    lf_storeu(s->z0, z0);
    lf_storeu(s->zdx, zdx);
    lf_storeu(s->zdy, zdy);
    lf_storeu(s->zclamp, dmin);
    lf_storeu(s->offx, lf_blendv(FSPLAT(hi_x), FSPLAT(lo_x), AS_PS(age)));
    lf_storeu(s->offy, lf_blendv(FSPLAT(hi_y), FSPLAT(lo_y), AS_PS(bge)));
    unsigned kmask = (1u << k) - 1;
    *empty = (unsigned)lf_movemask(AS_PS(li_xor(rows_ok, ones))) & kmask;
    return (unsigned)lf_movemask(AS_PS(fits)) & kmask;
}

/* Tile bounds [tb[0], tb[1]) x [tb[2], tb[3]) of lane l's triangle within the caller's range
 * [tx0, tx1) x [ty0, ty1); false when they are empty. */
SL_RT_T static inline bool small_tiles(const small_lanes *s, int l, int32_t tx0, int32_t tx1, int32_t ty0, int32_t ty1,
                                       int32_t tb[4])
{
    tb[0] = sl_rt_maxi(tx0, s->col0[l] / SL_RT_TILE_W);
    tb[1] = sl_rt_mini(tx1, (s->col1[l] - 1) / SL_RT_TILE_W + 1);
    tb[2] = sl_rt_maxi(ty0, s->row0[l] / SL_RT_TILE_H);
    tb[3] = sl_rt_mini(ty1, (s->row1[l] - 1) / SL_RT_TILE_H + 1);
    return tb[0] < tb[1] && tb[2] < tb[3];
}

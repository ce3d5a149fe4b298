/* The batched front end and the small-triangle setup of the AVX2 and AVX-512 paths, 8 triangles
 * per 256-bit register (one lane each). Included by raster_avx2.c and raster_avx512.c after
 * raster_simd8.h, so each file compiles its own copy for its own instruction set (SL_RT_T,
 * SL_RT_NAME).
 *
 * Every lane repeats the operations of the scalar reference (raster_setup.c) exactly:
 *  - front: the transform ((m0*x + m4*y) + m8*z) + m12, the outcodes, the snap
 *    ((c*(1/w))*h + h, rounded to nearest even) and sl_rt_prepare, with the same float operations
 *    in the same order and the area in exact double arithmetic. A triangle that needs clipping
 *    goes through the scalar code (sl_rt_front_prims) at its place in the order.
 *  - setup8: the depth plane of sl_rt_setup in double precision, operation for operation, so
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
#error "define SL_RT_T and SL_RT_NAME before including raster_batch8.h"
#endif


/* ---- 8 doubles: one 512-bit register on AVX-512 (SL_RT_D8_512), two 256-bit ones otherwise;
 * the same IEEE operations either way ---- */

#if defined(SL_RT_D8_512)
typedef struct d8 {
    __m512d v;
} d8;

SL_RT_T static inline d8 d8_i32(__m256i v)
{
    d8 r = {_mm512_cvtepi32_pd(v)};
    return r;
}
SL_RT_T static inline d8 d8_ps(__m256 v)
{
    d8 r = {_mm512_cvtps_pd(v)};
    return r;
}
SL_RT_T static inline d8 d8_set(double x)
{
    d8 r = {_mm512_set1_pd(x)};
    return r;
}
#define D8_OP(name, op)                                                                                             \
    SL_RT_T static inline d8 name(d8 a, d8 b)                                                                       \
    {                                                                                                               \
        d8 r = {op(a.v, b.v)};                                                                                      \
        return r;                                                                                                   \
    }
D8_OP(d8_add, _mm512_add_pd)
D8_OP(d8_sub, _mm512_sub_pd)
D8_OP(d8_mul, _mm512_mul_pd)
D8_OP(d8_div, _mm512_div_pd)
D8_OP(d8_max, _mm512_max_pd)
#undef D8_OP
SL_RT_T static inline d8 d8_abs(d8 a)
{
    d8 r = {_mm512_andnot_pd(_mm512_set1_pd(-0.0), a.v)};
    return r;
}
SL_RT_T static inline d8 d8_ceil(d8 a)
{
    d8 r = {_mm512_roundscale_pd(a.v, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC)};
    return r;
}
SL_RT_T static inline d8 d8_floor(d8 a)
{
    d8 r = {_mm512_roundscale_pd(a.v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)};
    return r;
}
SL_RT_T static inline __m256 d8_to_ps(d8 a) { return _mm512_cvtpd_ps(a.v); }
SL_RT_T static inline __m256i d8_to_i32(d8 a) { return _mm512_cvttpd_epi32(a.v); }
#define D8_CMP(a, b, pred) _mm256_movm_epi32(_mm512_cmp_pd_mask((a).v, (b).v, pred))
SL_RT_T static inline d8 d8_blend(d8 a, d8 b, __m256i mask) /* mask ? b : a (32-bit lane mask) */
{
    d8 r = {_mm512_mask_blend_pd(_mm256_movepi32_mask(mask), a.v, b.v)};
    return r;
}
SL_RT_T static inline void d8_split(d8 a, __m256d *lo, __m256d *hi)
{
    *lo = _mm512_castpd512_pd256(a.v);
    *hi = _mm512_extractf64x4_pd(a.v, 1);
}
#else
typedef struct d8 {
    __m256d lo, hi;
} d8;

SL_RT_T static inline d8 d8_i32(__m256i v)
{
    d8 r = {_mm256_cvtepi32_pd(_mm256_castsi256_si128(v)), _mm256_cvtepi32_pd(_mm256_extracti128_si256(v, 1))};
    return r;
}
SL_RT_T static inline d8 d8_ps(__m256 v)
{
    d8 r = {_mm256_cvtps_pd(_mm256_castps256_ps128(v)), _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))};
    return r;
}
SL_RT_T static inline d8 d8_set(double x)
{
    d8 r = {_mm256_set1_pd(x), _mm256_set1_pd(x)};
    return r;
}
#define D8_OP(name, op)                                                                                             \
    SL_RT_T static inline d8 name(d8 a, d8 b)                                                                       \
    {                                                                                                               \
        d8 r = {op(a.lo, b.lo), op(a.hi, b.hi)};                                                                    \
        return r;                                                                                                   \
    }
D8_OP(d8_add, _mm256_add_pd)
D8_OP(d8_sub, _mm256_sub_pd)
D8_OP(d8_mul, _mm256_mul_pd)
D8_OP(d8_div, _mm256_div_pd)
D8_OP(d8_max, _mm256_max_pd)
#undef D8_OP
SL_RT_T static inline d8 d8_abs(d8 a)
{
    const __m256d sign = _mm256_set1_pd(-0.0);
    d8 r = {_mm256_andnot_pd(sign, a.lo), _mm256_andnot_pd(sign, a.hi)};
    return r;
}
SL_RT_T static inline d8 d8_ceil(d8 a)
{
    d8 r = {_mm256_ceil_pd(a.lo), _mm256_ceil_pd(a.hi)};
    return r;
}
SL_RT_T static inline d8 d8_floor(d8 a)
{
    d8 r = {_mm256_floor_pd(a.lo), _mm256_floor_pd(a.hi)};
    return r;
}
/* Round to float, lanes in order. */
SL_RT_T static inline __m256 d8_to_ps(d8 a)
{
    return _mm256_set_m128(_mm256_cvtpd_ps(a.hi), _mm256_cvtpd_ps(a.lo));
}
/* Exact integers of magnitude below 2^31 to int32, lanes in order. */
SL_RT_T static inline __m256i d8_to_i32(d8 a)
{
    return _mm256_set_m128i(_mm256_cvttpd_epi32(a.hi), _mm256_cvttpd_epi32(a.lo));
}
/* A 64-bit lane mask per half to a 32-bit lane mask, lanes in order. */
SL_RT_T static inline __m256i d8_mask(__m256d lo, __m256d hi)
{
    __m256 s = _mm256_shuffle_ps(_mm256_castpd_ps(lo), _mm256_castpd_ps(hi), _MM_SHUFFLE(2, 0, 2, 0));
    return _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(s), _MM_SHUFFLE(3, 1, 2, 0)));
}
#define D8_CMP(a, b, pred) d8_mask(_mm256_cmp_pd((a).lo, (b).lo, pred), _mm256_cmp_pd((a).hi, (b).hi, pred))
SL_RT_T static inline d8 d8_blend(d8 a, d8 b, __m256i mask) /* mask ? b : a (32-bit lane mask) */
{
    __m256i lo = _mm256_cvtepi32_epi64(_mm256_castsi256_si128(mask));
    __m256i hi = _mm256_cvtepi32_epi64(_mm256_extracti128_si256(mask, 1));
    d8 r = {_mm256_blendv_pd(a.lo, b.lo, _mm256_castsi256_pd(lo)),
            _mm256_blendv_pd(a.hi, b.hi, _mm256_castsi256_pd(hi))};
    return r;
}
SL_RT_T static inline void d8_split(d8 a, __m256d *lo, __m256d *hi)
{
    *lo = a.lo;
    *hi = a.hi;
}
#endif

/* 8x8 transpose of 32-bit elements: r[i] lane j -> r[j] lane i. */
SL_RT_T static inline void transpose8(__m256i r[8])
{
    __m256i t[8], u[8];
    SL_RT_UNROLL
    for (int i = 0; i < 8; i += 2) {
        t[i] = _mm256_unpacklo_epi32(r[i], r[i + 1]);
        t[i + 1] = _mm256_unpackhi_epi32(r[i], r[i + 1]);
    }
    SL_RT_UNROLL
    for (int i = 0; i < 8; i += 4) {
        u[i] = _mm256_unpacklo_epi64(t[i], t[i + 2]);
        u[i + 1] = _mm256_unpackhi_epi64(t[i], t[i + 2]);
        u[i + 2] = _mm256_unpacklo_epi64(t[i + 1], t[i + 3]);
        u[i + 3] = _mm256_unpackhi_epi64(t[i + 1], t[i + 3]);
    }
    SL_RT_UNROLL
    for (int i = 0; i < 4; i++) {
        r[i] = _mm256_permute2x128_si256(u[i], u[i + 4], 0x20);
        r[i + 4] = _mm256_permute2x128_si256(u[i], u[i + 4], 0x31);
    }
}

#define ISPLAT(x) _mm256_set1_epi32(x)
#define FSPLAT(x) _mm256_set1_ps(x)
#define AS_PS(x) _mm256_castsi256_ps(x)
#define AS_SI(x) _mm256_castps_si256(x)

/* Lanes where a float is not finite: x - x is NaN exactly there. */
SL_RT_T static inline __m256i nonfinite8(__m256 x)
{
    __m256 z = _mm256_sub_ps(x, x);
    return AS_SI(_mm256_cmp_ps(z, z, _CMP_UNORD_Q));
}

/* ceil(a / 256) and floor(a / 256) of int32 lanes (arithmetic shifts, as in raster_setup.c). */
SL_RT_T static inline __m256i ceil256_8(__m256i a)
{
    return _mm256_sub_epi32(_mm256_setzero_si256(), _mm256_srai_epi32(_mm256_sub_epi32(_mm256_setzero_si256(), a), 8));
}
SL_RT_T static inline __m256i clamp8(__m256i x, int32_t lo, int32_t hi)
{
    return _mm256_min_epi32(_mm256_max_epi32(x, ISPLAT(lo)), ISPLAT(hi));
}

/* ---- the front end ---- */

/* Vertex i as (x, y, z, 0), reading exactly its 12 bytes. */
SL_RT_T static inline __m128 load_vertex(const char *base, uint32_t i, uint32_t stride)
{
    const float *p = (const float *)(base + (size_t)i * stride);
    return _mm_movelh_ps(_mm_castsi128_ps(_mm_loadl_epi64((const __m128i *)p)), _mm_load_ss(p + 2));
}

/* x, y, z of corner c of the 8 triangles (vertex indices vi[lane]) as three 8-lane vectors. Gathers
 * are slower than these loads and shuffles on the CPUs at hand. */
SL_RT_T static inline void load_corner(const char *base, const uint32_t vi[8], uint32_t stride, __m256 *x, __m256 *y,
                                       __m256 *z)
{
    __m256 r[4];
    SL_RT_UNROLL
    for (int l = 0; l < 4; l++)
        r[l] = _mm256_set_m128(load_vertex(base, vi[l + 4], stride), load_vertex(base, vi[l], stride));
    __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
    __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
    *x = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
    *y = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
    *z = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
}

SL_RT_T static uint32_t SL_RT_NAME(front)(const sl_rt_view *v, int mode, const sl_rt_batch *b, uint32_t *next,
                                          uint32_t last, sl_rt_counters *cnt, sl_rt_prim *out, uint32_t cap)
{
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), zero = _mm256_setzero_si256();
    const __m256i lanebit = _mm256_sllv_epi32(ISPLAT(1), lane);
    const char *vbase = (const char *)b->vertices;
    const uint32_t vc = b->vertex_count, stride = b->stride;
    const float *m = b->m;
    const __m256 sign = FSPLAT(-0.0f), lim = FSPLAT(SL_RT_SNAP_LIMIT), nlim = _mm256_sub_ps(_mm256_setzero_ps(), lim);
    const __m256 hw = FSPLAT(v->half_w), hh = FSPLAT(v->half_h), nhh = FSPLAT(-v->half_h);
    const __m256 gx = FSPLAT(v->guard_x), gy = FSPLAT(v->guard_y), nearw = FSPLAT(v->near_w);
    const __m256 sub = FSPLAT((float)SL_RT_SUBPIX);
    const bool inv_w = v->depth == SL_RASTER_DEPTH_INV_W;
    uint32_t t = *next, n = 0;
    while (t < last && n + 8 * SL_RT_FAN_MAX <= cap) {
        uint32_t k = last - t < 8 ? last - t : 8;
        __m256i valid = _mm256_cmpgt_epi32(ISPLAT((int32_t)k), lane);
        /* indices: a bad one is replaced by 0 for the load (when there is a vertex 0) and the lane
         * rejected */
        const uint32_t *ix = b->indices + (size_t)t * 3;
        uint32_t vi[3][8];
        __m256i badidx;
        if (k == 8) {
            /* 24 indices deinterleaved: lane l of idx[c] is ix[3l + c] */
            __m256i v0 = _mm256_loadu_si256((const __m256i *)ix), v1 = _mm256_loadu_si256((const __m256i *)ix + 1);
            __m256i v2 = _mm256_loadu_si256((const __m256i *)ix + 2);
            const __m256i p0 = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5),
                          p1 = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
            const __m256i p2 = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
            __m256i idx[3];
            idx[0] = _mm256_blend_epi32(
                _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p0), _mm256_permutevar8x32_epi32(v1, p0), 0x38),
                _mm256_permutevar8x32_epi32(v2, p0), 0xC0);
            idx[1] = _mm256_blend_epi32(
                _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p1), _mm256_permutevar8x32_epi32(v1, p1), 0x18),
                _mm256_permutevar8x32_epi32(v2, p1), 0xE0);
            idx[2] = _mm256_blend_epi32(
                _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p2), _mm256_permutevar8x32_epi32(v1, p2), 0x1C),
                _mm256_permutevar8x32_epi32(v2, p2), 0xE0);
            badidx = zero;
            SL_RT_UNROLL
            for (int c = 0; c < 3; c++) {
                /* unsigned idx >= vertex_count; a bad index loads vertex 0 instead */
                __m256i bad = _mm256_cmpeq_epi32(_mm256_max_epu32(idx[c], ISPLAT((int32_t)vc)), idx[c]);
                badidx = _mm256_or_si256(badidx, bad);
                _mm256_storeu_si256((__m256i *)vi[c], _mm256_andnot_si256(bad, idx[c]));
            }
        } else {
            /* the tail of the batch: lanes past it load vertex 0 too and are ignored */
            unsigned bad = 0;
            for (uint32_t l = 0; l < 8; l++)
                for (int c = 0; c < 3; c++) {
                    uint32_t i = l < k ? ix[3 * l + c] : 0;
                    bool ok = i < vc;
                    bad |= (unsigned)!ok << l;
                    vi[c][l] = ok ? i : 0;
                }
            badidx = _mm256_cmpeq_epi32(_mm256_and_si256(ISPLAT((int32_t)bad), lanebit), lanebit);
        }
        badidx = _mm256_and_si256(badidx, valid);
        __m256i fetch = _mm256_andnot_si256(badidx, valid);
        if (vc == 0)
            fetch = zero;
        /* transform and classify the three corners */
        __m256 cx[3], cy[3], cz[3], cw[3];
        __m256i nonfin = zero, clip = zero;
        __m256i outl = ISPLAT(-1), outb = outl, outn = outl, outr = outl, outt = outl, outf = outl;
        SL_RT_UNROLL
        for (int c = 0; c < 3; c++) {
            __m256 px, py, pz;
            if (vc > 0) {
                load_corner(vbase, vi[c], stride, &px, &py, &pz);
            } else {
                px = py = pz = _mm256_setzero_ps();
            }
            __m256 r[4];
            SL_RT_UNROLL
            for (int i = 0; i < 4; i++)
                r[i] = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(FSPLAT(m[i]), px),
                                                                 _mm256_mul_ps(FSPLAT(m[4 + i]), py)),
                                                   _mm256_mul_ps(FSPLAT(m[8 + i]), pz)),
                                     FSPLAT(m[12 + i]));
            cx[c] = r[0], cy[c] = r[1], cz[c] = r[2], cw[c] = r[3];
            nonfin = _mm256_or_si256(nonfin, _mm256_or_si256(_mm256_or_si256(nonfinite8(r[0]), nonfinite8(r[1])),
                                                             _mm256_or_si256(nonfinite8(r[2]), nonfinite8(r[3]))));
            __m256 w = r[3], nw = _mm256_xor_ps(w, sign);
            outl = _mm256_and_si256(outl, AS_SI(_mm256_cmp_ps(r[0], nw, _CMP_LT_OQ)));
            outb = _mm256_and_si256(outb, AS_SI(_mm256_cmp_ps(r[1], nw, _CMP_LT_OQ)));
            __m256 near = _mm256_cmp_ps(r[2], nw, _CMP_LT_OQ);
            outn = _mm256_and_si256(outn, AS_SI(near));
            outr = _mm256_and_si256(outr, AS_SI(_mm256_cmp_ps(r[0], w, _CMP_GT_OQ)));
            outt = _mm256_and_si256(outt, AS_SI(_mm256_cmp_ps(r[1], w, _CMP_GT_OQ)));
            outf = _mm256_and_si256(outf, AS_SI(_mm256_cmp_ps(r[2], w, _CMP_GT_OQ)));
            __m256 g = _mm256_or_ps(_mm256_cmp_ps(_mm256_andnot_ps(sign, r[0]), _mm256_mul_ps(gx, w), _CMP_GT_OQ),
                                    _mm256_cmp_ps(_mm256_andnot_ps(sign, r[1]), _mm256_mul_ps(gy, w), _CMP_GT_OQ));
            g = _mm256_or_ps(g, _mm256_or_ps(near, _mm256_cmp_ps(w, nearw, _CMP_LT_OQ)));
            clip = _mm256_or_si256(clip, AS_SI(g));
        }
        nonfin = _mm256_and_si256(nonfin, fetch);
        __m256i live = _mm256_andnot_si256(nonfin, fetch);
        __m256i outside = _mm256_or_si256(_mm256_or_si256(_mm256_or_si256(outl, outb), _mm256_or_si256(outn, outr)),
                                          _mm256_or_si256(outt, outf));
        outside = _mm256_and_si256(outside, live);
        live = _mm256_andnot_si256(outside, live);
        clip = _mm256_and_si256(clip, live);
        live = _mm256_andnot_si256(clip, live);
        /* snap (sl_rt_snap) */
        __m256i X[3], Y[3], snapbad = zero;
        __m256 d[3];
        SL_RT_UNROLL
        for (int c = 0; c < 3; c++) {
            __m256 inv = _mm256_div_ps(FSPLAT(1.0f), cw[c]);
            __m256 sx = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(cx[c], inv), hw), hw);
            __m256 sy = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(cy[c], inv), nhh), hh);
            d[c] = inv_w ? inv
                         : _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(cz[c], inv), FSPLAT(-0.5f)), FSPLAT(0.5f));
            __m256 in =
                _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(sx, lim, _CMP_LE_OQ), _mm256_cmp_ps(sx, nlim, _CMP_GE_OQ)),
                              _mm256_and_ps(_mm256_cmp_ps(sy, lim, _CMP_LE_OQ), _mm256_cmp_ps(sy, nlim, _CMP_GE_OQ)));
            snapbad =
                _mm256_or_si256(snapbad, _mm256_or_si256(_mm256_xor_si256(AS_SI(in), ISPLAT(-1)), nonfinite8(d[c])));
            X[c] = _mm256_cvtps_epi32(_mm256_mul_ps(sx, sub));
            Y[c] = _mm256_cvtps_epi32(_mm256_mul_ps(sy, sub));
        }
        snapbad = _mm256_and_si256(snapbad, live);
        live = _mm256_andnot_si256(snapbad, live);
        /* prepare (sl_rt_prepare): area, winding, orientation, pixel bounds */
        d8 area = d8_sub(d8_mul(d8_i32(_mm256_sub_epi32(X[1], X[0])), d8_i32(_mm256_sub_epi32(Y[2], Y[0]))),
                         d8_mul(d8_i32(_mm256_sub_epi32(X[2], X[0])), d8_i32(_mm256_sub_epi32(Y[1], Y[0]))));
        __m256i neg = D8_CMP(area, d8_set(0.0), _CMP_LT_OQ), pos = D8_CMP(area, d8_set(0.0), _CMP_GT_OQ);
        __m256i degen = _mm256_and_si256(_mm256_andnot_si256(_mm256_or_si256(neg, pos), ISPLAT(-1)), live);
        live = _mm256_andnot_si256(degen, live);
        __m256i back = b->backface == SL_RASTER_CULL_CW ? pos : (b->backface == SL_RASTER_CULL_CCW ? neg : zero);
        back = _mm256_and_si256(back, live);
        live = _mm256_andnot_si256(back, live);
        __m256i X1 = _mm256_blendv_epi8(X[1], X[2], neg), X2 = _mm256_blendv_epi8(X[2], X[1], neg);
        __m256i Y1 = _mm256_blendv_epi8(Y[1], Y[2], neg), Y2 = _mm256_blendv_epi8(Y[2], Y[1], neg);
        __m256 d1 = _mm256_blendv_ps(d[1], d[2], AS_PS(neg)), d2 = _mm256_blendv_ps(d[2], d[1], AS_PS(neg));
        d8 aarea = d8_abs(area);
        __m256i xmin = _mm256_min_epi32(X[0], _mm256_min_epi32(X[1], X[2]));
        __m256i xmax = _mm256_max_epi32(X[0], _mm256_max_epi32(X[1], X[2]));
        __m256i ymin = _mm256_min_epi32(Y[0], _mm256_min_epi32(Y[1], Y[2]));
        __m256i ymax = _mm256_max_epi32(Y[0], _mm256_max_epi32(Y[1], Y[2]));
        const __m256i half = ISPLAT(SL_RT_SUBPIX / 2), one = ISPLAT(1);
        __m256i c0 = clamp8(ceil256_8(_mm256_sub_epi32(xmin, half)), 0, v->pad_w);
        __m256i c1 = clamp8(_mm256_add_epi32(_mm256_srai_epi32(_mm256_sub_epi32(xmax, half), 8), one), 0, v->pad_w);
        __m256i r0 = clamp8(ceil256_8(_mm256_sub_epi32(ymin, half)), 0, v->pad_h);
        __m256i r1 = clamp8(_mm256_add_epi32(_mm256_srai_epi32(_mm256_sub_epi32(ymax, half), 8), one), 0, v->pad_h);
        __m256i empty =
            _mm256_andnot_si256(_mm256_and_si256(_mm256_cmpgt_epi32(c1, c0), _mm256_cmpgt_epi32(r1, r0)), live);
        live = _mm256_andnot_si256(empty, live);
        /* counts: every lane but the clipped ones, which the scalar code counts in order below */
        unsigned mclip = (unsigned)_mm256_movemask_ps(AS_PS(clip)), mlive = (unsigned)_mm256_movemask_ps(AS_PS(live));
        cnt->submitted += k - (uint32_t)__builtin_popcount(mclip);
        cnt->rejected_index += (uint32_t)__builtin_popcount((unsigned)_mm256_movemask_ps(AS_PS(badidx)));
        cnt->rejected_nonfinite += (uint32_t)__builtin_popcount(
            (unsigned)_mm256_movemask_ps(AS_PS(_mm256_or_si256(nonfin, snapbad))));
        cnt->culled_outside += (uint32_t)__builtin_popcount(
            (unsigned)_mm256_movemask_ps(AS_PS(_mm256_or_si256(outside, empty))));
        cnt->degenerate += (uint32_t)__builtin_popcount((unsigned)_mm256_movemask_ps(AS_PS(degen)));
        cnt->culled_backface += (uint32_t)__builtin_popcount((unsigned)_mm256_movemask_ps(AS_PS(back)));
        cnt->rasterized += (uint32_t)__builtin_popcount(mlive);
        /* the prims, one 64-byte row per lane: fields 0-7 and 8-15 transposed */
        __m256i lo[8] = {X[0], X1, X2, Y[0], Y1, Y2, AS_SI(d[0]), AS_SI(d1)};
        __m256i hi[8];
        hi[0] = AS_SI(d2), hi[1] = c0, hi[2] = c1, hi[3] = r0, hi[4] = r1, hi[5] = zero;
        {
            /* area: lane i's double as dwords 14 (low) and 15 (high) */
            __m256d alo_d, ahi_d;
            d8_split(aarea, &alo_d, &ahi_d);
            __m256 a0 = _mm256_castpd_ps(alo_d), a1 = _mm256_castpd_ps(ahi_d);
            __m256 alo = _mm256_shuffle_ps(a0, a1, _MM_SHUFFLE(2, 0, 2, 0));
            __m256 ahi = _mm256_shuffle_ps(a0, a1, _MM_SHUFFLE(3, 1, 3, 1));
            hi[6] = _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(alo), _MM_SHUFFLE(3, 1, 2, 0)));
            hi[7] = _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(ahi), _MM_SHUFFLE(3, 1, 2, 0)));
        }
        transpose8(lo);
        transpose8(hi);
        if (!mclip) {
            for (unsigned bits = mlive; bits; bits &= bits - 1) {
                int l = __builtin_ctz(bits);
                _mm256_storeu_si256((__m256i *)&out[n], lo[l]);
                _mm256_storeu_si256((__m256i *)&out[n] + 1, hi[l]);
                n++;
            }
        } else {
            for (unsigned l = 0; l < k; l++) {
                if (mlive >> l & 1) {
                    _mm256_storeu_si256((__m256i *)&out[n], lo[l]);
                    _mm256_storeu_si256((__m256i *)&out[n] + 1, hi[l]);
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

/* Set-up triangles of a group of 8 prims (lanes), structure of arrays. The edges sit in slots as
 * in sl_rt_tri: slot 0 bounds the span from the left, slot 1 from the right, slot 2 from the left
 * when cap = +BIG and from the right when cap = -BIG (a horizontal third edge is made neutral).
 * Threshold of slot e for pixel row oy + r, relative to column ox: ceil((n0[e] + r*s[e]) / dd[e]). */
typedef struct small8 {
    float n0[3][8], s[3][8], dd[3][8];
    float cap[8];
    float cl[8], cr[8];                         /* col0 - ox, col1 - ox */
    int32_t ox[8], oy[8], col0[8], col1[8], row0[8], row1[8];
    float z0[8], zdx[8], zdy[8], zclamp[8], offx[8], offy[8];
} small8;

/* Set up prims p[0..k) (k <= 8) for the small path. Returns the lanes set up (a bit per lane);
 * *empty gets the lanes with no pixel row left (nothing to draw). The others need the reference
 * setup and the general kernel. */
SL_RT_T static unsigned setup8(const sl_rt_prim *p, uint32_t k, int mode, small8 *s, unsigned *empty)
{
    *empty = 0;
    if (mode != SL_RT_CENTER && mode != SL_RT_INNER)
        return 0;
    __m256i lo[8], hi[8];
    SL_RT_UNROLL
    for (uint32_t i = 0; i < 8; i++) {
        const sl_rt_prim *q = &p[i < k ? i : 0];
        lo[i] = _mm256_loadu_si256((const __m256i *)q);
        hi[i] = _mm256_loadu_si256((const __m256i *)q + 1);
    }
    transpose8(lo);
    transpose8(hi);
    const __m256i zero = _mm256_setzero_si256(), ones = ISPLAT(-1);
    __m256i X[3] = {lo[0], lo[1], lo[2]}, Y[3] = {lo[3], lo[4], lo[5]};
    __m256 d[3] = {AS_PS(lo[6]), AS_PS(lo[7]), AS_PS(hi[0])};
    __m256i col0 = hi[1], col1 = hi[2], row0 = hi[3], row1 = hi[4];
    d8 area;
    {
        __m256i ul = _mm256_unpacklo_epi32(hi[6], hi[7]), uh = _mm256_unpackhi_epi32(hi[6], hi[7]);
        __m256d alo = _mm256_castsi256_pd(_mm256_permute2x128_si256(ul, uh, 0x20));
        __m256d ahi = _mm256_castsi256_pd(_mm256_permute2x128_si256(ul, uh, 0x31));
#if defined(SL_RT_D8_512)
        area.v = _mm512_insertf64x4(_mm512_castpd256_pd512(alo), ahi, 1);
#else
        area.lo = alo, area.hi = ahi;
#endif
    }
    /* edges: slope, tie or margin constant, horizontal edges' row limits */
    __m256i dX[3], dY[3];
    d8 cst[3];
    __m256i xmin = _mm256_min_epi32(X[0], _mm256_min_epi32(X[1], X[2]));
    __m256i xmax = _mm256_max_epi32(X[0], _mm256_max_epi32(X[1], X[2]));
    __m256i ymin = _mm256_min_epi32(Y[0], _mm256_min_epi32(Y[1], Y[2]));
    __m256i ymax = _mm256_max_epi32(Y[0], _mm256_max_epi32(Y[1], Y[2]));
    /* bbw + bbh + 3, below 2^25 */
    d8 bbwh = d8_i32(_mm256_add_epi32(_mm256_add_epi32(_mm256_sub_epi32(xmax, xmin), _mm256_sub_epi32(ymax, ymin)),
                                      ISPLAT(3)));
    __m256i horiz = zero;
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        int a = e, bb = e == 2 ? 0 : e + 1;
        dX[e] = _mm256_sub_epi32(X[bb], X[a]);
        dY[e] = _mm256_sub_epi32(Y[bb], Y[a]);
        __m256i hz = _mm256_cmpeq_epi32(dY[e], zero);
        horiz = _mm256_or_si256(horiz, hz);
        if (mode == SL_RT_CENTER) {
            /* 0 for top-left edges (dY < 0, or dY == 0 and dX > 0), else 1 */
            __m256i tl =
                _mm256_or_si256(_mm256_cmpgt_epi32(zero, dY[e]), _mm256_and_si256(hz, _mm256_cmpgt_epi32(dX[e], zero)));
            cst[e] = d8_i32(_mm256_andnot_si256(tl, ISPLAT(1)));
        } else {
            /* 129*(|dX| + |dY|) + bbw + bbh + 3, exact in double */
            d8 s1 = d8_i32(_mm256_add_epi32(_mm256_abs_epi32(dX[e]), _mm256_abs_epi32(dY[e])));
            cst[e] = d8_add(d8_mul(s1, d8_set(129.0)), bbwh);
        }
    }
    if (!_mm256_testz_si256(horiz, horiz)) {
        /* dX*(256j + 128 - Ya) >= c bounds the rows (raster_setup.c's ceil_q/floor_q, clamped) */
        SL_RT_UNROLL
        for (int e = 0; e < 3; e++) {
            __m256i hz = _mm256_cmpeq_epi32(dY[e], zero);
            if (_mm256_testz_si256(hz, hz))
                continue;
            d8 dx = d8_i32(dX[e]);
            d8 num = d8_sub(cst[e], d8_mul(dx, d8_i32(_mm256_sub_epi32(ISPLAT(SL_RT_SUBPIX / 2), Y[e]))));
            d8 q = d8_div(num, d8_mul(dx, d8_set((double)SL_RT_SUBPIX)));
            const d8 big = d8_set((double)SL_RT_BIG), nbig = d8_set((double)-SL_RT_BIG);
            d8 qc = d8_ceil(q), qf = d8_floor(q);
            qc = d8_blend(qc, big, D8_CMP(qc, big, _CMP_GT_OQ));
            qc = d8_blend(qc, nbig, D8_CMP(qc, nbig, _CMP_LT_OQ));
            qf = d8_blend(qf, big, D8_CMP(qf, big, _CMP_GT_OQ));
            qf = d8_blend(qf, nbig, D8_CMP(qf, nbig, _CMP_LT_OQ));
            __m256i top = _mm256_and_si256(hz, _mm256_cmpgt_epi32(dX[e], zero));
            __m256i bot = _mm256_and_si256(hz, _mm256_cmpgt_epi32(zero, dX[e]));
            row0 = _mm256_blendv_epi8(row0, _mm256_max_epi32(row0, d8_to_i32(qc)), top);
            row1 = _mm256_blendv_epi8(row1, _mm256_min_epi32(row1, _mm256_add_epi32(d8_to_i32(qf), ISPLAT(1))), bot);
        }
    }
    __m256i rows_ok = _mm256_cmpgt_epi32(row1, row0);
    /* thresholds relative to the tile-aligned origin */
    __m256i ox = _mm256_and_si256(col0, ISPLAT(~(SL_RT_TILE_W - 1))),
            oy = _mm256_and_si256(row0, ISPLAT(~(SL_RT_TILE_H - 1)));
    /* the last row the kernel evaluates: the tile rows up to row1 */
    d8 rlast =
        d8_i32(_mm256_or_si256(_mm256_sub_epi32(_mm256_sub_epi32(row1, ISPLAT(1)), oy), ISPLAT(SL_RT_TILE_H - 1)));
    const d8 lim = d8_set(8388608.0); /* 2^23 */
    __m256i fits = rows_ok;
    __m256 en0[3], es[3], edd[3];
    __m256i left[3], right[3];
    SL_RT_UNROLL
    for (int e = 0; e < 3; e++) {
        int a = e;
        __m256i hz = _mm256_cmpeq_epi32(dY[e], zero);
        left[e] = _mm256_cmpgt_epi32(zero, dY[e]);
        right[e] = _mm256_cmpgt_epi32(dY[e], zero);
        __m256i xa = _mm256_sub_epi32(X[a], _mm256_slli_epi32(ox, 8)),
                ya = _mm256_sub_epi32(Y[a], _mm256_slli_epi32(oy, 8));
        /* sg * (dX*(128 - Ya) - dY*(128 - Xa) - c + (dY > 0)), exact in double (below 2^48) */
        d8 nl = d8_sub(d8_mul(d8_i32(dX[e]), d8_i32(_mm256_sub_epi32(ISPLAT(SL_RT_SUBPIX / 2), ya))),
                       d8_mul(d8_i32(dY[e]), d8_i32(_mm256_sub_epi32(ISPLAT(SL_RT_SUBPIX / 2), xa))));
        nl = d8_add(d8_sub(nl, cst[e]), d8_i32(_mm256_and_si256(right[e], ISPLAT(1))));
        d8 sg = d8_blend(d8_set(1.0), d8_set(-1.0), left[e]);
        d8 n0 = d8_ceil(d8_mul(d8_mul(nl, sg), d8_set(1.0 / SL_RT_SUBPIX)));
        d8 st = d8_mul(d8_i32(dX[e]), sg);
        /* every numerator of rows 0..rlast below 2^23, and 8 steps too */
        d8 nend = d8_add(n0, d8_mul(rlast, st));
        __m256i ok = _mm256_and_si256(D8_CMP(d8_max(d8_abs(n0), d8_abs(nend)), lim, _CMP_LT_OQ),
                                      D8_CMP(d8_mul(d8_abs(st), d8_set(8.0)), lim, _CMP_LT_OQ));
        fits = _mm256_and_si256(fits, _mm256_or_si256(ok, hz));
        /* a horizontal edge: threshold -BIG whatever the row (neutral in slot 2 with cap +BIG) */
        en0[e] = _mm256_blendv_ps(d8_to_ps(n0), FSPLAT((float)-SL_RT_BIG), AS_PS(hz));
        es[e] = _mm256_andnot_ps(AS_PS(hz), d8_to_ps(st));
        edd[e] = _mm256_blendv_ps(_mm256_cvtepi32_ps(_mm256_abs_epi32(dY[e])), FSPLAT(1.0f), AS_PS(hz));
    }
    /* slots as in sl_rt_setup: the first left edge, the first right edge, the remaining one */
    {
        __m256i sa1 = _mm256_andnot_si256(left[0], left[1]);           /* slot 0 holds edge 1 */
        __m256i sa2 = _mm256_andnot_si256(_mm256_or_si256(left[0], left[1]), ISPLAT(-1)); /* edge 2 */
        __m256i sb1 = _mm256_andnot_si256(right[0], right[1]);
        __m256i sb2 = _mm256_andnot_si256(_mm256_or_si256(right[0], right[1]), ISPLAT(-1));
        __m256i two_right = _mm256_or_si256(_mm256_and_si256(right[0], right[1]),
                                            _mm256_or_si256(_mm256_and_si256(right[0], right[2]),
                                                            _mm256_and_si256(right[1], right[2])));
        /* the edge of slot 2 is 3 - (slot 0's) - (slot 1's) */
        __m256i ia = _mm256_sub_epi32(_mm256_setzero_si256(), _mm256_add_epi32(sa1, _mm256_add_epi32(sa2, sa2)));
        __m256i ib = _mm256_sub_epi32(_mm256_setzero_si256(), _mm256_add_epi32(sb1, _mm256_add_epi32(sb2, sb2)));
        __m256i ic = _mm256_sub_epi32(_mm256_sub_epi32(ISPLAT(3), ia), ib);
        __m256i idx[3] = {ia, ib, ic};
        SL_RT_UNROLL
        for (int sl = 0; sl < 3; sl++) {
            __m256 is1 = AS_PS(_mm256_cmpeq_epi32(idx[sl], ISPLAT(1))),
                   is2 = AS_PS(_mm256_cmpeq_epi32(idx[sl], ISPLAT(2)));
            _mm256_storeu_ps(s->n0[sl], _mm256_blendv_ps(_mm256_blendv_ps(en0[0], en0[1], is1), en0[2], is2));
            _mm256_storeu_ps(s->s[sl], _mm256_blendv_ps(_mm256_blendv_ps(es[0], es[1], is1), es[2], is2));
            _mm256_storeu_ps(s->dd[sl], _mm256_blendv_ps(_mm256_blendv_ps(edd[0], edd[1], is1), edd[2], is2));
        }
        _mm256_storeu_ps(s->cap,
                         _mm256_blendv_ps(FSPLAT((float)SL_RT_BIG), FSPLAT((float)-SL_RT_BIG), AS_PS(two_right)));
    }
    _mm256_storeu_si256((__m256i *)s->ox, ox);
    _mm256_storeu_si256((__m256i *)s->oy, oy);
    _mm256_storeu_si256((__m256i *)s->col0, col0);
    _mm256_storeu_si256((__m256i *)s->col1, col1);
    _mm256_storeu_si256((__m256i *)s->row0, row0);
    _mm256_storeu_si256((__m256i *)s->row1, row1);
    _mm256_storeu_ps(s->cl, _mm256_cvtepi32_ps(_mm256_sub_epi32(col0, ox)));
    _mm256_storeu_ps(s->cr, _mm256_cvtepi32_ps(_mm256_sub_epi32(col1, ox)));

    /* depth plane: sl_rt_setup's double arithmetic, operation for operation */
    const d8 kk = d8_set(1.0 / SL_RT_SUBPIX);
    d8 ex1 = d8_mul(d8_i32(_mm256_sub_epi32(X[1], X[0])), kk), ey1 = d8_mul(d8_i32(_mm256_sub_epi32(Y[1], Y[0])), kk);
    d8 ex2 = d8_mul(d8_i32(_mm256_sub_epi32(X[2], X[0])), kk), ey2 = d8_mul(d8_i32(_mm256_sub_epi32(Y[2], Y[0])), kk);
    d8 dd0 = d8_ps(d[0]);
    d8 dd1 = d8_sub(d8_ps(d[1]), dd0), dd2 = d8_sub(d8_ps(d[2]), dd0);
    d8 inv_det = d8_div(d8_set(65536.0), area);
    d8 pa = d8_mul(d8_sub(d8_mul(dd1, ey2), d8_mul(dd2, ey1)), inv_det);
    d8 pb = d8_mul(d8_sub(d8_mul(ex1, dd2), d8_mul(ex2, dd1)), inv_det);
    d8 cref = d8_add(d8_add(dd0, d8_mul(pa, d8_sub(d8_i32(col0), d8_mul(d8_i32(X[0]), kk)))),
                     d8_mul(pb, d8_sub(d8_i32(row0), d8_mul(d8_i32(Y[0]), kk))));
    __m256 dmin = _mm256_min_ps(_mm256_min_ps(d[0], d[1]), d[2]);
    d8 fa = d8_abs(pa), fb = d8_abs(pb);
    d8 span =
        d8_add(d8_add(d8_abs(cref), d8_mul(fa, d8_i32(_mm256_add_epi32(_mm256_sub_epi32(col1, col0), ISPLAT(40))))),
               d8_mul(fb, d8_i32(_mm256_add_epi32(_mm256_sub_epi32(row1, row0), ISPLAT(40)))));
    d8 bias = d8_add(d8_mul(span, d8_set(0x1p-19)), d8_mul(d8_add(fa, fb), d8_set(1.0 / 256.0)));
    const d8 huge = d8_set(1e30);
    __m256i ok = _mm256_and_si256(D8_CMP(span, huge, _CMP_LT_OQ),
                                  _mm256_and_si256(D8_CMP(fa, huge, _CMP_LT_OQ), D8_CMP(fb, huge, _CMP_LT_OQ)));
    float lo_x = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_x = mode == SL_RT_CENTER ? 7.5f : 8.0f;
    float lo_y = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_y = mode == SL_RT_CENTER ? 3.5f : 4.0f;
    __m256i age = D8_CMP(pa, d8_set(0.0), _CMP_GE_OQ), bge = D8_CMP(pb, d8_set(0.0), _CMP_GE_OQ);
    __m256 z0 = d8_to_ps(d8_sub(cref, bias)), zdx = d8_to_ps(pa), zdy = d8_to_ps(pb);
    ok = _mm256_andnot_si256(nonfinite8(z0), ok);
    /* a plane too steep to evaluate: the vertex bound alone (offsets then come out 0) */
    z0 = _mm256_blendv_ps(dmin, z0, AS_PS(ok));
    zdx = _mm256_and_ps(zdx, AS_PS(ok));
    zdy = _mm256_and_ps(zdy, AS_PS(ok));
    _mm256_storeu_ps(s->z0, z0);
    _mm256_storeu_ps(s->zdx, zdx);
    _mm256_storeu_ps(s->zdy, zdy);
    _mm256_storeu_ps(s->zclamp, dmin);
    _mm256_storeu_ps(s->offx, _mm256_blendv_ps(FSPLAT(hi_x), FSPLAT(lo_x), AS_PS(age)));
    _mm256_storeu_ps(s->offy, _mm256_blendv_ps(FSPLAT(hi_y), FSPLAT(lo_y), AS_PS(bge)));
    unsigned kmask = (1u << k) - 1;
    *empty = (unsigned)_mm256_movemask_ps(AS_PS(_mm256_xor_si256(rows_ok, ones))) & kmask;
    return (unsigned)_mm256_movemask_ps(AS_PS(fits)) & kmask;
}

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

SL_RT_T static inline __attribute__((always_inline)) void small_row_at(small_tri *t, int32_t ty, small_row *r);

SL_RT_T static inline __attribute__((always_inline)) bool small_load(const small8 *s, int l, int32_t tx0, int32_t tx1,
                                                                     int32_t ty0, int32_t ty1, small_tri *o)
{
    o->ox = s->ox[l], o->oy = s->oy[l];
    o->row0 = s->row0[l], o->row1 = s->row1[l];
    o->x_ref = s->col0[l], o->y_ref = s->row0[l];
    o->tx0 = sl_rt_maxi(tx0, s->col0[l] / SL_RT_TILE_W);
    o->tx1 = sl_rt_mini(tx1, (s->col1[l] - 1) / SL_RT_TILE_W + 1);
    o->ty0 = sl_rt_maxi(ty0, o->row0 / SL_RT_TILE_H);
    o->ty1 = sl_rt_mini(ty1, (o->row1 - 1) / SL_RT_TILE_H + 1);
    if (o->tx0 >= o->tx1 || o->ty0 >= o->ty1)
        return false;
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

SL_RT_T static inline __attribute__((always_inline)) void small_row_at(small_tri *t, int32_t ty, small_row *r)
{
    small_spans(t, ty, &r->xl, &r->xr);
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
        __m256 z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt[0] + zrow), t->off), t->zclamp);
        merge_tile(_mm256_shuffle_epi8(row_masks(xl, xr, dxl), ctl), z, tg->mask + ti * SL_RT_SUBTILES, &tg->depth[ti]);
        SL_RT_UNROLL
        for (int c = 1; c < cols; c++) {
            z = _mm256_max_ps(_mm256_add_ps(_mm256_set1_ps(zt[c] + zrow), t->off), t->zclamp);
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

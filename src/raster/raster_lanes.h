/* Lane vectors of the batched front end and small-triangle setup (raster_batch.h): one triangle
 * per lane, SL_RT_W lanes per register: 8 on AVX2 and AVX-512 (256-bit registers), 4 on SSE4.1.
 * The includer defines SL_RT_T (the target attribute), SL_RT_NAME(n) and SL_RT_W (and
 * SL_RT_D8_512 on AVX-512, where the W doubles take one 512-bit register).
 *
 *   lvf, lvi     W floats, W int32 (one register)
 *   lf_*, li_*   their operations, named after the instructions they stand for: every one is one
 *                IEEE or integer instruction on every lane, the same on every width, so the code
 *                written with them does the same operations lane for lane at any width
 *   dl, dl_*     W doubles (two registers, or one 512-bit one) and their operations
 *   lf_cmp, DL_CMP  comparisons with an AVX predicate (_CMP_LT_OQ, _CMP_GT_OQ, _CMP_LE_OQ,
 *                _CMP_GE_OQ, _CMP_UNORD_Q), which SSE spells as separate instructions
 *
 * and the width-specific moves: lane constants, vertex loads and the transposes between lanes
 * (triangles) and 64-byte prims. */
#ifndef SL_RT_T
#error "define SL_RT_T, SL_RT_NAME and SL_RT_W before including raster_lanes.h"
#endif

#include <immintrin.h>

#if SL_RT_W == 8

typedef __m256 lvf;
typedef __m256i lvi;
#define lf_add _mm256_add_ps
#define lf_sub _mm256_sub_ps
#define lf_mul _mm256_mul_ps
#define lf_div _mm256_div_ps
#define lf_min _mm256_min_ps
#define lf_and _mm256_and_ps
#define lf_or _mm256_or_ps
#define lf_xor _mm256_xor_ps
#define lf_andnot _mm256_andnot_ps
#define lf_blendv _mm256_blendv_ps
#define lf_cmp _mm256_cmp_ps
#define lf_zero _mm256_setzero_ps
#define lf_storeu _mm256_storeu_ps
#define lf_movemask _mm256_movemask_ps
#define lf_from_i _mm256_cvtepi32_ps
#define li_round_f _mm256_cvtps_epi32
#define li_add _mm256_add_epi32
#define li_sub _mm256_sub_epi32
#define li_and _mm256_and_si256
#define li_or _mm256_or_si256
#define li_xor _mm256_xor_si256
#define li_andnot _mm256_andnot_si256
#define li_eq _mm256_cmpeq_epi32
#define li_gt _mm256_cmpgt_epi32
#define li_min _mm256_min_epi32
#define li_max _mm256_max_epi32
#define li_maxu _mm256_max_epu32
#define li_abs _mm256_abs_epi32
#define li_srai _mm256_srai_epi32
#define li_slli _mm256_slli_epi32
#define li_blendv _mm256_blendv_epi8
#define li_zero _mm256_setzero_si256
#define li_testz _mm256_testz_si256
#define li_loadu(p) _mm256_loadu_si256((const __m256i *)(p))
#define li_storeu(p, v) _mm256_storeu_si256((__m256i *)(p), v)
#define ISPLAT(x) _mm256_set1_epi32(x)
#define FSPLAT(x) _mm256_set1_ps(x)
#define AS_PS(x) _mm256_castsi256_ps(x)
#define AS_SI(x) _mm256_castps_si256(x)

SL_RT_T static inline lvi li_lanes(void) { return _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7); }
SL_RT_T static inline lvf lf_lanes(void) { return _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7); }
SL_RT_T static inline lvi li_lanebits(void) { return _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128); }

#elif SL_RT_W == 4

typedef __m128 lvf;
typedef __m128i lvi;
#define lf_add _mm_add_ps
#define lf_sub _mm_sub_ps
#define lf_mul _mm_mul_ps
#define lf_div _mm_div_ps
#define lf_min _mm_min_ps
#define lf_and _mm_and_ps
#define lf_or _mm_or_ps
#define lf_xor _mm_xor_ps
#define lf_andnot _mm_andnot_ps
#define lf_blendv _mm_blendv_ps
#define lf_cmp(a, b, pred) LF_CMP_##pred(a, b)
#define LF_CMP__CMP_LT_OQ _mm_cmplt_ps
#define LF_CMP__CMP_GT_OQ _mm_cmpgt_ps
#define LF_CMP__CMP_LE_OQ _mm_cmple_ps
#define LF_CMP__CMP_GE_OQ _mm_cmpge_ps
#define LF_CMP__CMP_UNORD_Q _mm_cmpunord_ps
#define lf_zero _mm_setzero_ps
#define lf_storeu _mm_storeu_ps
#define lf_movemask _mm_movemask_ps
#define lf_from_i _mm_cvtepi32_ps
#define li_round_f _mm_cvtps_epi32
#define li_add _mm_add_epi32
#define li_sub _mm_sub_epi32
#define li_and _mm_and_si128
#define li_or _mm_or_si128
#define li_xor _mm_xor_si128
#define li_andnot _mm_andnot_si128
#define li_eq _mm_cmpeq_epi32
#define li_gt _mm_cmpgt_epi32
#define li_min _mm_min_epi32
#define li_max _mm_max_epi32
#define li_maxu _mm_max_epu32
#define li_abs _mm_abs_epi32
#define li_srai _mm_srai_epi32
#define li_slli _mm_slli_epi32
#define li_blendv _mm_blendv_epi8
#define li_zero _mm_setzero_si128
#define li_testz _mm_testz_si128
#define li_loadu(p) _mm_loadu_si128((const __m128i *)(p))
#define li_storeu(p, v) _mm_storeu_si128((__m128i *)(p), v)
#define ISPLAT(x) _mm_set1_epi32(x)
#define FSPLAT(x) _mm_set1_ps(x)
#define AS_PS(x) _mm_castsi128_ps(x)
#define AS_SI(x) _mm_castps_si128(x)

SL_RT_T static inline lvi li_lanes(void) { return _mm_setr_epi32(0, 1, 2, 3); }
SL_RT_T static inline lvf lf_lanes(void) { return _mm_setr_ps(0, 1, 2, 3); }
SL_RT_T static inline lvi li_lanebits(void) { return _mm_setr_epi32(1, 2, 4, 8); }

#else
#error "SL_RT_W must be 4 or 8"
#endif

/* Number of lanes set in a movemask (the SSE4.1 target has no popcnt instruction). */
SL_RT_T static inline uint32_t lanes_count(unsigned m)
{
#if SL_RT_W == 8
    return (uint32_t)__builtin_popcount(m);
#else
    return (0x4332322132212110ull >> (4 * (m & 15))) & 15;
#endif
}

/* Lanes where a float is not finite: x - x is NaN exactly there. */
SL_RT_T static inline lvi li_nonfinite(lvf x)
{
    lvf z = lf_sub(x, x);
    return AS_SI(lf_cmp(z, z, _CMP_UNORD_Q));
}

/* ---- W doubles: one 512-bit register on AVX-512 (SL_RT_D8_512), two registers otherwise; the
 * same IEEE operations either way ---- */

#if defined(SL_RT_D8_512)
typedef __m256d dl_half; /* lanes 0-3 / 4-7 */
typedef struct dl {
    __m512d v;
} dl;

SL_RT_T static inline dl dl_i32(__m256i v)
{
    dl r = {_mm512_cvtepi32_pd(v)};
    return r;
}
SL_RT_T static inline dl dl_ps(__m256 v)
{
    dl r = {_mm512_cvtps_pd(v)};
    return r;
}
SL_RT_T static inline dl dl_set(double x)
{
    dl r = {_mm512_set1_pd(x)};
    return r;
}
#define DL_OP(name, op)                                                                                             \
    SL_RT_T static inline dl name(dl a, dl b)                                                                       \
    {                                                                                                               \
        dl r = {op(a.v, b.v)};                                                                                      \
        return r;                                                                                                   \
    }
DL_OP(dl_add, _mm512_add_pd)
DL_OP(dl_sub, _mm512_sub_pd)
DL_OP(dl_mul, _mm512_mul_pd)
DL_OP(dl_div, _mm512_div_pd)
DL_OP(dl_max, _mm512_max_pd)
#undef DL_OP
SL_RT_T static inline dl dl_abs(dl a)
{
    dl r = {_mm512_andnot_pd(_mm512_set1_pd(-0.0), a.v)};
    return r;
}
SL_RT_T static inline dl dl_ceil(dl a)
{
    dl r = {_mm512_roundscale_pd(a.v, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC)};
    return r;
}
SL_RT_T static inline dl dl_floor(dl a)
{
    dl r = {_mm512_roundscale_pd(a.v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)};
    return r;
}
SL_RT_T static inline __m256 dl_to_ps(dl a) { return _mm512_cvtpd_ps(a.v); }
SL_RT_T static inline __m256i dl_to_i32(dl a) { return _mm512_cvttpd_epi32(a.v); }
#define DL_CMP(a, b, pred) _mm256_movm_epi32(_mm512_cmp_pd_mask((a).v, (b).v, pred))
SL_RT_T static inline dl dl_blend(dl a, dl b, __m256i mask) /* mask ? b : a (32-bit lane mask) */
{
    dl r = {_mm512_mask_blend_pd(_mm256_movepi32_mask(mask), a.v, b.v)};
    return r;
}
SL_RT_T static inline void dl_halves(dl a, __m256d *lo, __m256d *hi)
{
    *lo = _mm512_castpd512_pd256(a.v);
    *hi = _mm512_extractf64x4_pd(a.v, 1);
}
SL_RT_T static inline dl dl_from_halves(__m256d lo, __m256d hi)
{
    dl r = {_mm512_insertf64x4(_mm512_castpd256_pd512(lo), hi, 1)};
    return r;
}
#else
#if SL_RT_W == 8
typedef __m256d dl_half; /* lanes 0-3 / 4-7 */
#define DLH(op) _mm256_##op
#define DL_CMP(a, b, pred) dl_mask(_mm256_cmp_pd((a).lo, (b).lo, pred), _mm256_cmp_pd((a).hi, (b).hi, pred))
#else
typedef __m128d dl_half; /* lanes 0-1 / 2-3 */
#define DLH(op) _mm_##op
/* (the predicate is pasted, not expanded: _CMP_LT_OQ names _mm_cmplt_pd) */
#define DL_CMP(a, b, pred) dl_mask(DLH_CMP_##pred((a).lo, (b).lo), DLH_CMP_##pred((a).hi, (b).hi))
#define DLH_CMP__CMP_LT_OQ _mm_cmplt_pd
#define DLH_CMP__CMP_GT_OQ _mm_cmpgt_pd
#define DLH_CMP__CMP_GE_OQ _mm_cmpge_pd
#endif
typedef struct dl {
    dl_half lo, hi;
} dl;

#if SL_RT_W == 8
SL_RT_T static inline dl dl_i32(__m256i v)
{
    dl r = {_mm256_cvtepi32_pd(_mm256_castsi256_si128(v)), _mm256_cvtepi32_pd(_mm256_extracti128_si256(v, 1))};
    return r;
}
SL_RT_T static inline dl dl_ps(__m256 v)
{
    dl r = {_mm256_cvtps_pd(_mm256_castps256_ps128(v)), _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))};
    return r;
}
/* Round to float, lanes in order. */
SL_RT_T static inline __m256 dl_to_ps(dl a) { return _mm256_set_m128(_mm256_cvtpd_ps(a.hi), _mm256_cvtpd_ps(a.lo)); }
/* Exact integers of magnitude below 2^31 to int32, lanes in order. */
SL_RT_T static inline __m256i dl_to_i32(dl a)
{
    return _mm256_set_m128i(_mm256_cvttpd_epi32(a.hi), _mm256_cvttpd_epi32(a.lo));
}
/* A 64-bit lane mask per half to a 32-bit lane mask, lanes in order. */
SL_RT_T static inline __m256i dl_mask(__m256d lo, __m256d hi)
{
    __m256 s = _mm256_shuffle_ps(_mm256_castpd_ps(lo), _mm256_castpd_ps(hi), _MM_SHUFFLE(2, 0, 2, 0));
    return _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(s), _MM_SHUFFLE(3, 1, 2, 0)));
}
/* A 32-bit lane mask to the 64-bit masks of the halves. */
SL_RT_T static inline void dl_widen(__m256i mask, __m256d *lo, __m256d *hi)
{
    *lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(mask)));
    *hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(mask, 1)));
}
#else
SL_RT_T static inline dl dl_i32(__m128i v)
{
    dl r = {_mm_cvtepi32_pd(v), _mm_cvtepi32_pd(_mm_srli_si128(v, 8))};
    return r;
}
SL_RT_T static inline dl dl_ps(__m128 v)
{
    dl r = {_mm_cvtps_pd(v), _mm_cvtps_pd(_mm_movehl_ps(v, v))};
    return r;
}
SL_RT_T static inline __m128 dl_to_ps(dl a) { return _mm_movelh_ps(_mm_cvtpd_ps(a.lo), _mm_cvtpd_ps(a.hi)); }
SL_RT_T static inline __m128i dl_to_i32(dl a)
{
    return _mm_unpacklo_epi64(_mm_cvttpd_epi32(a.lo), _mm_cvttpd_epi32(a.hi));
}
SL_RT_T static inline __m128i dl_mask(__m128d lo, __m128d hi)
{
    return _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(lo), _mm_castpd_ps(hi), _MM_SHUFFLE(2, 0, 2, 0)));
}
SL_RT_T static inline void dl_widen(__m128i mask, __m128d *lo, __m128d *hi)
{
    *lo = _mm_castsi128_pd(_mm_cvtepi32_epi64(mask));
    *hi = _mm_castsi128_pd(_mm_cvtepi32_epi64(_mm_srli_si128(mask, 8)));
}
#endif

SL_RT_T static inline dl dl_set(double x)
{
    dl r = {DLH(set1_pd)(x), DLH(set1_pd)(x)};
    return r;
}
#define DL_OP(name, op)                                                                                             \
    SL_RT_T static inline dl name(dl a, dl b)                                                                       \
    {                                                                                                               \
        dl r = {DLH(op)(a.lo, b.lo), DLH(op)(a.hi, b.hi)};                                                          \
        return r;                                                                                                   \
    }
DL_OP(dl_add, add_pd)
DL_OP(dl_sub, sub_pd)
DL_OP(dl_mul, mul_pd)
DL_OP(dl_div, div_pd)
DL_OP(dl_max, max_pd)
#undef DL_OP
SL_RT_T static inline dl dl_abs(dl a)
{
    const dl_half sign = DLH(set1_pd)(-0.0);
    dl r = {DLH(andnot_pd)(sign, a.lo), DLH(andnot_pd)(sign, a.hi)};
    return r;
}
SL_RT_T static inline dl dl_ceil(dl a)
{
    dl r = {DLH(ceil_pd)(a.lo), DLH(ceil_pd)(a.hi)};
    return r;
}
SL_RT_T static inline dl dl_floor(dl a)
{
    dl r = {DLH(floor_pd)(a.lo), DLH(floor_pd)(a.hi)};
    return r;
}
SL_RT_T static inline dl dl_blend(dl a, dl b, lvi mask) /* mask ? b : a (32-bit lane mask) */
{
    dl_half lo, hi;
    dl_widen(mask, &lo, &hi);
    dl r = {DLH(blendv_pd)(a.lo, b.lo, lo), DLH(blendv_pd)(a.hi, b.hi, hi)};
    return r;
}
SL_RT_T static inline void dl_halves(dl a, dl_half *lo, dl_half *hi)
{
    *lo = a.lo;
    *hi = a.hi;
}
SL_RT_T static inline dl dl_from_halves(dl_half lo, dl_half hi)
{
    dl r = {lo, hi};
    return r;
}
#endif

/* ---- moves between lanes (triangles) and memory ---- */

/* Vertex i as (x, y, z, 0), reading exactly its 12 bytes. */
SL_RT_T static inline __m128 load_vertex(const char *base, uint32_t i, uint32_t stride)
{
    const float *p = (const float *)(base + (size_t)i * stride);
    return _mm_movelh_ps(_mm_castsi128_ps(_mm_loadl_epi64((const __m128i *)p)), _mm_load_ss(p + 2));
}

/* x, y, z of one corner of the W triangles (vertex indices vi[lane]) as three lane vectors. Gathers
 * are slower than these loads and shuffles on the CPUs at hand. */
SL_RT_T static inline void load_corner(const char *base, const uint32_t vi[SL_RT_W], uint32_t stride, lvf *x, lvf *y,
                                       lvf *z)
{
    lvf r[4];
#if SL_RT_W == 8
    SL_RT_UNROLL
    for (int l = 0; l < 4; l++)
        r[l] = _mm256_set_m128(load_vertex(base, vi[l + 4], stride), load_vertex(base, vi[l], stride));
    lvf t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
    lvf t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
    *x = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
    *y = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
    *z = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
#else
    SL_RT_UNROLL
    for (int l = 0; l < 4; l++)
        r[l] = load_vertex(base, vi[l], stride);
    lvf t0 = _mm_unpacklo_ps(r[0], r[1]), t1 = _mm_unpackhi_ps(r[0], r[1]);
    lvf t2 = _mm_unpacklo_ps(r[2], r[3]), t3 = _mm_unpackhi_ps(r[2], r[3]);
    *x = _mm_movelh_ps(t0, t2);
    *y = _mm_movehl_ps(t2, t0);
    *z = _mm_movelh_ps(t1, t3);
#endif
}

/* The 24 (W = 8) indices of triangles ix[0..W) deinterleaved: lane l of idx[c] is ix[3l + c]. */
SL_RT_T static inline void load_indices(const uint32_t *ix, lvi idx[3])
{
#if SL_RT_W == 8
    __m256i v0 = _mm256_loadu_si256((const __m256i *)ix), v1 = _mm256_loadu_si256((const __m256i *)ix + 1);
    __m256i v2 = _mm256_loadu_si256((const __m256i *)ix + 2);
    const __m256i p0 = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5), p1 = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
    const __m256i p2 = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
    idx[0] = _mm256_blend_epi32(
        _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p0), _mm256_permutevar8x32_epi32(v1, p0), 0x38),
        _mm256_permutevar8x32_epi32(v2, p0), 0xC0);
    idx[1] = _mm256_blend_epi32(
        _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p1), _mm256_permutevar8x32_epi32(v1, p1), 0x18),
        _mm256_permutevar8x32_epi32(v2, p1), 0xE0);
    idx[2] = _mm256_blend_epi32(
        _mm256_blend_epi32(_mm256_permutevar8x32_epi32(v0, p2), _mm256_permutevar8x32_epi32(v1, p2), 0x1C),
        _mm256_permutevar8x32_epi32(v2, p2), 0xE0);
#else
    /* v0 = a0 b0 c0 a1, v1 = b1 c1 a2 b2, v2 = c2 a3 b3 c3 (corners a, b, c of triangles 0-3) */
    __m128 v0 = _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)ix));
    __m128 v1 = _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)ix + 1));
    __m128 v2 = _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)ix + 2));
    __m128 a = _mm_shuffle_ps(v0, v0, _MM_SHUFFLE(3, 3, 3, 0)), aa = _mm_shuffle_ps(v1, v2, _MM_SHUFFLE(1, 1, 2, 2));
    __m128 b = _mm_shuffle_ps(v0, v1, _MM_SHUFFLE(0, 0, 1, 1)), bb = _mm_shuffle_ps(v1, v2, _MM_SHUFFLE(2, 2, 3, 3));
    __m128 c = _mm_shuffle_ps(v0, v1, _MM_SHUFFLE(1, 1, 2, 2)), cc = _mm_shuffle_ps(v2, v2, _MM_SHUFFLE(3, 3, 0, 0));
    idx[0] = _mm_castps_si128(_mm_shuffle_ps(a, aa, _MM_SHUFFLE(2, 0, 1, 0)));
    idx[1] = _mm_castps_si128(_mm_shuffle_ps(b, bb, _MM_SHUFFLE(2, 0, 2, 0)));
    idx[2] = _mm_castps_si128(_mm_shuffle_ps(c, cc, _MM_SHUFFLE(2, 0, 2, 0)));
#endif
}

#if SL_RT_W == 8
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
#else
/* 4x4 transpose of 32-bit elements. */
SL_RT_T static inline void transpose4(__m128i r[4])
{
    __m128i t0 = _mm_unpacklo_epi32(r[0], r[1]), t1 = _mm_unpackhi_epi32(r[0], r[1]);
    __m128i t2 = _mm_unpacklo_epi32(r[2], r[3]), t3 = _mm_unpackhi_epi32(r[2], r[3]);
    r[0] = _mm_unpacklo_epi64(t0, t2);
    r[1] = _mm_unpackhi_epi64(t0, t2);
    r[2] = _mm_unpacklo_epi64(t1, t3);
    r[3] = _mm_unpackhi_epi64(t1, t3);
}
#endif

/* Prims as lanes: f[i] lane l is dword i of prim l (16 dwords, sl_rt_prim's layout). prims_from_lanes
 * transposes f in place so that prim_store(f, l, out) writes lane l's prim; prims_to_lanes loads
 * prims p[0..W) (p[0] for lanes at and past k) into f. */
SL_RT_T static inline void prims_from_lanes(lvi f[16])
{
#if SL_RT_W == 8
    transpose8(f);
    transpose8(f + 8);
#else
    for (int g = 0; g < 16; g += 4)
        transpose4(f + g);
#endif
}

SL_RT_T static inline void prim_store(const lvi f[16], int l, sl_rt_prim *out)
{
#if SL_RT_W == 8
    _mm256_storeu_si256((__m256i *)out, f[l]);
    _mm256_storeu_si256((__m256i *)out + 1, f[8 + l]);
#else
    SL_RT_UNROLL
    for (int g = 0; g < 4; g++)
        _mm_storeu_si128((__m128i *)out + g, f[4 * g + l]);
#endif
}

SL_RT_T static inline void prims_to_lanes(const sl_rt_prim *p, uint32_t k, lvi f[16])
{
#if SL_RT_W == 8
    SL_RT_UNROLL
    for (uint32_t i = 0; i < 8; i++) {
        const sl_rt_prim *q = &p[i < k ? i : 0];
        f[i] = _mm256_loadu_si256((const __m256i *)q);
        f[8 + i] = _mm256_loadu_si256((const __m256i *)q + 1);
    }
    transpose8(f);
    transpose8(f + 8);
#else
    SL_RT_UNROLL
    for (uint32_t i = 0; i < 4; i++) {
        const sl_rt_prim *q = &p[i < k ? i : 0];
        SL_RT_UNROLL
        for (int g = 0; g < 4; g++)
            f[4 * g + i] = _mm_loadu_si128((const __m128i *)q + g);
    }
    for (int g = 0; g < 16; g += 4)
        transpose4(f + g);
#endif
}

/* A double per lane as its low and high dwords (prim dwords 14 and 15), and back. */
SL_RT_T static inline void dl_to_dwords(dl a, lvi *lo, lvi *hi)
{
    dl_half h0, h1;
    dl_halves(a, &h0, &h1);
#if SL_RT_W == 8
    __m256 a0 = _mm256_castpd_ps(h0), a1 = _mm256_castpd_ps(h1);
    __m256 l = _mm256_shuffle_ps(a0, a1, _MM_SHUFFLE(2, 0, 2, 0)), h = _mm256_shuffle_ps(a0, a1, _MM_SHUFFLE(3, 1, 3, 1));
    *lo = _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(l), _MM_SHUFFLE(3, 1, 2, 0)));
    *hi = _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(h), _MM_SHUFFLE(3, 1, 2, 0)));
#else
    __m128 a0 = _mm_castpd_ps(h0), a1 = _mm_castpd_ps(h1);
    *lo = _mm_castps_si128(_mm_shuffle_ps(a0, a1, _MM_SHUFFLE(2, 0, 2, 0)));
    *hi = _mm_castps_si128(_mm_shuffle_ps(a0, a1, _MM_SHUFFLE(3, 1, 3, 1)));
#endif
}

SL_RT_T static inline dl dl_from_dwords(lvi lo, lvi hi)
{
#if SL_RT_W == 8
    __m256i ul = _mm256_unpacklo_epi32(lo, hi), uh = _mm256_unpackhi_epi32(lo, hi);
    return dl_from_halves(_mm256_castsi256_pd(_mm256_permute2x128_si256(ul, uh, 0x20)),
                          _mm256_castsi256_pd(_mm256_permute2x128_si256(ul, uh, 0x31)));
#else
    return dl_from_halves(_mm_castsi128_pd(_mm_unpacklo_epi32(lo, hi)), _mm_castsi128_pd(_mm_unpackhi_epi32(lo, hi)));
#endif
}

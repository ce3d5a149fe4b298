/* The one box-against-frustum classifier of the library (issue 13 §6): every culler's frustum
 * test, the occlusion framework's BVH walk, the urban methods, the pvs culler and the public
 * sl_frustum_test_aabb call it; sl_frustum_lanes_reject below is the same test with the planes in
 * SSE lanes (plp's completion phase), tested bit-identical to it. Include only; included by core/sl_core.h. */
#ifndef SL_CORE_FRUSTUM_CLASSIFY_H
#define SL_CORE_FRUSTUM_CLASSIFY_H

#include "margins.h"
#include "sightline/geom.h"

#include <stdbool.h>
#include <stdint.h>

/* Inlined in every caller, so that each frustum loop compiles as its own hand-written copy did
 * (constant masks fold away). */
#if defined(__GNUC__)
#define SL_FRUSTUM_INLINE static inline __attribute__((always_inline))
#else
#define SL_FRUSTUM_INLINE static inline
#endif

/* Slack of each of six planes (sl_margin_plane_slack of its d). */
SL_FRUSTUM_INLINE void sl_frustum_slacks(const sl_plane planes[6], float slack[6])
{
    for (int i = 0; i < 6; i++)
        slack[i] = sl_margin_plane_slack(planes[i].d);
}

/* Is box b beyond plane p by more than slack (its p-vertex, the corner farthest along the normal,
 * outside)? */
SL_FRUSTUM_INLINE bool sl_frustum_plane_rejects(const sl_plane *p, float slack, const sl_aabb *b)
{
    float px = p->a >= 0 ? b->max.x : b->min.x, py = p->b >= 0 ? b->max.y : b->min.y;
    float pz = p->c >= 0 ? b->max.z : b->min.z;
    return p->a * px + p->b * py + p->c * pz + p->d < -slack;
}

/* Classify box b against the planes in mask (bit i: planes[i]) with per-plane slack: -1 when it
 * lies beyond one of them (its index written to *rejected, which may be NULL), else, with
 * `straddle`, the mask of the planes it straddles (0: wholly inside those planes), without it
 * the mask unchanged. Planes are tried in index order. */
SL_FRUSTUM_INLINE int sl_frustum_classify_box(const sl_plane *planes, const float *slack, const sl_aabb *b, uint32_t mask,
                                          bool straddle, uint8_t *rejected)
{
    uint32_t out = mask;
    for (uint32_t i = 0; i < 6; i++) {
        if (!(mask & (1u << i)))
            continue;
        const sl_plane *p = &planes[i];
        float px = p->a >= 0 ? b->max.x : b->min.x, nx = p->a >= 0 ? b->min.x : b->max.x;
        float py = p->b >= 0 ? b->max.y : b->min.y, ny = p->b >= 0 ? b->min.y : b->max.y;
        float pz = p->c >= 0 ? b->max.z : b->min.z, nz = p->c >= 0 ? b->min.z : b->max.z;
        if (p->a * px + p->b * py + p->c * pz + p->d < -slack[i]) {
            if (rejected)
                *rejected = (uint8_t)i;
            return -1;
        }
        if (straddle && p->a * nx + p->b * ny + p->c * nz + p->d >= 0)
            out &= ~(1u << i);
    }
    return (int)out;
}

/* ---- the same rejection with the planes in SSE lanes ----
 * For loops that test many boxes against one frustum (plp's completion phase): four planes a
 * register, each lane doing sl_frustum_classify_box's float operations in its order, so the
 * answer is the same bit for any box (tests/test_frustum_lanes.c checks it against the scalar
 * classifier on seeded boxes, planes and masks, touching and non-finite ones included). Unused
 * lanes hold zero planes with slack -0 (0 < -0 is false: never a rejection). Without SSE2 the
 * scalar classifier is called. */
#if defined(__SSE2__) || defined(_M_X64)
#include <emmintrin.h>
#define SL_FRUSTUM_LANES_SSE 1
#else
#define SL_FRUSTUM_LANES_SSE 0
#endif

typedef struct sl_frustum_lanes {
#if SL_FRUSTUM_LANES_SSE
    __m128 a[2], b[2], c[2], d[2], nslack[2]; /* lanes 0-3 | 4-7: the planes of the mask */
#else
    sl_plane planes[6];
    float slack[6];
    uint32_t mask;
#endif
} sl_frustum_lanes;

/* Prepare the planes of mask (bit i: planes[i]) with their slack. */
static inline void sl_frustum_lanes_init(sl_frustum_lanes *l, const sl_plane planes[6], const float slack[6],
                                         uint32_t mask)
{
#if SL_FRUSTUM_LANES_SSE
    float a[8] = {0}, b[8] = {0}, c[8] = {0}, d[8] = {0}, ns[8] = {0};
    for (int i = 0; i < 6; i++) {
        if (!(mask & (1u << i)))
            continue;
        a[i] = planes[i].a, b[i] = planes[i].b, c[i] = planes[i].c, d[i] = planes[i].d, ns[i] = -slack[i];
    }
    for (int h = 0; h < 2; h++) {
        l->a[h] = _mm_loadu_ps(a + 4 * h);
        l->b[h] = _mm_loadu_ps(b + 4 * h);
        l->c[h] = _mm_loadu_ps(c + 4 * h);
        l->d[h] = _mm_loadu_ps(d + 4 * h);
        l->nslack[h] = _mm_loadu_ps(ns + 4 * h);
    }
#else
    for (int i = 0; i < 6; i++)
        l->planes[i] = planes[i], l->slack[i] = slack[i];
    l->mask = mask;
#endif
}

/* sl_frustum_classify_box(planes, slack, b, mask, false, NULL) < 0 of the planes l was made from. */
SL_FRUSTUM_INLINE bool sl_frustum_lanes_reject(const sl_frustum_lanes *l, const sl_aabb *b)
{
#if SL_FRUSTUM_LANES_SSE
    const __m128 zero = _mm_setzero_ps();
    __m128 out = zero;
    for (int h = 0; h < 2; h++) {
        /* the p-vertex: max where the normal's component is >= 0 (a select, as the scalar ?:) */
        __m128 ma = _mm_cmpge_ps(l->a[h], zero), mb = _mm_cmpge_ps(l->b[h], zero), mc = _mm_cmpge_ps(l->c[h], zero);
        __m128 px = _mm_or_ps(_mm_and_ps(ma, _mm_set1_ps(b->max.x)), _mm_andnot_ps(ma, _mm_set1_ps(b->min.x)));
        __m128 py = _mm_or_ps(_mm_and_ps(mb, _mm_set1_ps(b->max.y)), _mm_andnot_ps(mb, _mm_set1_ps(b->min.y)));
        __m128 pz = _mm_or_ps(_mm_and_ps(mc, _mm_set1_ps(b->max.z)), _mm_andnot_ps(mc, _mm_set1_ps(b->min.z)));
        __m128 dot = _mm_add_ps(
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(l->a[h], px), _mm_mul_ps(l->b[h], py)), _mm_mul_ps(l->c[h], pz)), l->d[h]);
        out = _mm_or_ps(out, _mm_cmplt_ps(dot, l->nslack[h]));
    }
    return _mm_movemask_ps(out) != 0;
#else
    return sl_frustum_classify_box(l->planes, l->slack, b, l->mask, false, NULL) < 0;
#endif
}

#endif

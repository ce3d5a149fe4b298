/* The one box-against-frustum classifier of the library (issue 13 §6): every culler's frustum
 * test, the occlusion framework's BVH walk, the urban methods, the pvs culler and the public
 * sl_frustum_test_aabb call it (plp.c's SSE twin computes the same bits lane by lane and is
 * checked against it). Include only; included by core/sl_core.h. */
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

#endif

/* Coorg-Teller occluder selection: a proxy's quality for a view, the per-node area bounds that
 * prune the walk, and the choice of the frame's occluders within a count and a triangle budget. */
#ifndef SL_CULL_OCCLUSION_SELECT_H
#define SL_CULL_OCCLUSION_SELECT_H

#include "accel/bvh_internal.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/view.h"

/* Coorg-Teller occluder quality, summed over the proxy's faces: -A (N.V) / |D|^2 with V the unit
 * direction from the eye to the face centre and D the vector to it (a solid-angle estimate); for a
 * MESH proxy, its half area over the squared distance to its box centre. */
float sl_occ_quality(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v);

/* Per BVH node slot, the largest proxy area in its subtree (0 where none), for pruning the
 * selection walk: area / dist^2(eye, node) bounds every quality below the node. */
void sl_occ_node_areas(const sl_occ_set *s, const struct sl_bvh_t *bvh, float *node_area);

typedef struct sl_occ_pick {
    uint32_t proxy;
    float quality;
} sl_occ_pick;

/* Choose this frame's occluders: the usable proxies in the frustum whose quality is at least
 * min_quality, the best max_count of them, then in decreasing quality while their triangles fit
 * in tri_budget. heap must hold max_count entries. Writes the choice to out sorted nearest first
 * (the order to render them in; out[i].quality then holds the squared distance to the proxy's
 * box) and returns its length. nodes_visited (may be NULL) counts the walk. */
uint32_t sl_occ_select(const sl_occ_set *s, const sl_occ_view *v, const struct sl_bvh_t *bvh, const float *node_area,
                       uint32_t max_count, uint32_t tri_budget, float min_quality, sl_occ_pick *heap,
                       sl_occ_pick *out, uint64_t *nodes_visited);

#endif

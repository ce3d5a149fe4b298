/* The front-to-back BVH walk every occlusion method uses: nearer child first, frustum plane masks,
 * a skip and a visit callback per box. */
#ifndef SL_CULL_OCCLUSION_WALK_H
#define SL_CULL_OCCLUSION_WALK_H

#include "accel/bvh_internal.h"
#include "cull/occlusion/view.h"

/* ---- the front-to-back BVH walk every method uses ---- */

/* What a walk asks its method. Boxes beyond a frustum plane are skipped before any question. */
typedef struct sl_occ_walk {
    /* Skip this box: a node's subtree (slot: its node slot) or an object of a leaf that holds more
     * than one (slot SL_NONE; a one-object leaf's box is the node's)? NULL: never. */
    bool (*skip)(void *ctx, uint32_t slot, const sl_aabb *box);
    /* Every object reached, in the walk's front-to-back order; NULL: append it to out. */
    void (*visit)(void *ctx, uint32_t object, const sl_aabb *box);
    void *ctx;
    uint32_t *out;            /* with visit NULL: the objects reached (count of them) */
    uint32_t count;
} sl_occ_walk;

/* Walk the BVH nearer child first (sl_bvh_right_first) with the view's frustum plane masks.
 * Returns the nodes visited; *objects_tested (may be NULL) counts the leaf objects looked at. */
uint64_t sl_occ_walk_bvh(const struct sl_bvh_t *bvh, const sl_occ_view *v, sl_occ_walk *w,
                         uint64_t *objects_tested);

#endif

/* The front-to-back BVH walk with frustum plane masks (walk.h). */
#include "walk.h"

uint64_t sl_occ_walk_bvh(const struct sl_bvh_t *bvh, const sl_occ_view *v, sl_occ_walk *w,
                         uint64_t *objects_tested)
{
    uint64_t visited = 0, tested = 0;
    const float e[3] = {v->eye.x, v->eye.y, v->eye.z};
    if (bvh->node_slots) {
        uint32_t stack[SL_BVH_MAX_DEPTH + 1], masks[SL_BVH_MAX_DEPTH + 1], sp = 0, ni = 0, mask = 0x3f;
        for (;;) {
            const sl_bvh_node *n = &bvh->nodes[ni];
            visited++;
            int r = mask ? sl_occ_frustum_classify(v, &n->box, mask) : 0;
            if (r >= 0 && !(w->skip && w->skip(w->ctx, ni, &n->box))) {
                if (n->count == 0) {
                    bool right = sl_bvh_right_first(bvh->nodes, n, e);
                    stack[sp] = n->first + (right ? 0 : 1);
                    masks[sp] = (uint32_t)r;
                    sp++;
                    ni = n->first + (right ? 1 : 0);
                    mask = (uint32_t)r;
                    continue;
                }
                for (uint32_t j = n->first; j < n->first + n->count; j++) {
                    tested++;
                    const sl_aabb *ob = &bvh->object_bounds[j];
                    if (r && sl_occ_frustum_classify(v, ob, (uint32_t)r) < 0)
                        continue;
                    if (n->count > 1 && w->skip && w->skip(w->ctx, SL_NONE, ob))
                        continue;
                    if (w->visit)
                        w->visit(w->ctx, bvh->objects[j], ob);
                    else
                        w->out[w->count++] = bvh->objects[j];
                }
            }
            if (sp == 0)
                break;
            sp--;
            ni = stack[sp];
            mask = masks[sp];
        }
    }
    if (objects_tested)
        *objects_tested += tested;
    return visited;
}

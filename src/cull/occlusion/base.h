/* The base every occlusion method builds on (sl_occ_base): the object BVH, the occluder proxies,
 * the selection's per-node areas and pick buffers, refit on scene change. */
#ifndef SL_CULL_OCCLUSION_BASE_H
#define SL_CULL_OCCLUSION_BASE_H

#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/select.h"
#include "sightline/accel.h"

/* ---- the base of every method: BVH, proxies, selection buffers ---- */

/* What every occlusion method holds besides its own buffers: the object BVH, the occluder proxies,
 * the selection's per-node areas and pick buffers (methods that select only), and the scratch of
 * sl_cull_sort_ids. */
typedef struct sl_occ_base {
    sl_allocator alloc;
    sl_scene scene;
    const char *method;       /* static name, for error messages */
    sl_bvh bvh;
    bool bvh_owned;           /* false: the shared handle's tree (sl_cull_extras.accel), not refitted here */
    sl_occ_set *occ;
    float *node_area;         /* per BVH node slot (sl_occ_node_areas); NULL unless selecting */
    uint32_t node_slots;
    sl_occ_pick *heap, *picks;/* pick_cap entries each */
    uint32_t *pick_ids;       /* the frame's chosen proxies, nearest first */
    uint32_t pick_cap;        /* 0 unless selecting */
    uint32_t object_count;
    uint32_t *sort_scratch;   /* object_count entries */
} sl_occ_base;

/* Build the BVH (c->leaf_size; the shared handle's when extras has one, sl_cull_object_bvh) and
 * the proxies (c->inset, c->all_objects, faces/mesh_faces as given); when `select`, also the node
 * areas and the buffers for c->occluders picks. extras may be NULL. On failure everything built is
 * freed and the error is prefixed with `method`. */
sl_status sl_occ_base_init(sl_occ_base *b, sl_scene scene, const char *method, const sl_occ_common *c, bool faces,
                           uint32_t mesh_faces, bool select, const sl_cull_extras *extras, const sl_allocator *alloc,
                           sl_error *err);
void sl_occ_base_free(sl_occ_base *b);
/* Objects moved: refit the BVH (rebuilt when the refit degrades it; a shared tree is left to its
 * owner, accel.h), refresh the node areas and disable the prisms of moved objects. */
sl_status sl_occ_base_scene_changed(sl_occ_base *b, sl_error *err);
/* Choose the frame's occluders (sl_occ_select with c's count, budget and min_quality) into
 * b->picks and b->pick_ids, nearest first; returns their number. */
uint32_t sl_occ_base_select(sl_occ_base *b, const sl_occ_view *v, const sl_occ_common *c, uint64_t *nodes_visited);

#endif

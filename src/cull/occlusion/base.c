/* The base every occlusion method builds on: BVH, proxies, selection buffers (base.h). */
#include "base.h"

/* ---- the base of every method ---- */

static size_t at_least_one(size_t n) { return n ? n : 1; }

void sl_occ_base_free(sl_occ_base *b)
{
    const sl_allocator *a = &b->alloc;
    if (b->bvh_owned)
        sl_bvh_destroy(b->bvh);
    sl_occ_set_destroy(b->occ);
    sl_free(a, b->node_area, at_least_one(b->node_slots) * sizeof(float));
    sl_free(a, b->heap, at_least_one(b->pick_cap) * sizeof(sl_occ_pick));
    sl_free(a, b->picks, at_least_one(b->pick_cap) * sizeof(sl_occ_pick));
    sl_free(a, b->pick_ids, at_least_one(b->pick_cap) * sizeof(uint32_t));
    sl_free(a, b->sort_scratch, at_least_one(b->object_count) * sizeof(uint32_t));
    memset(b, 0, sizeof *b);
}

/* (Re)size the per-node areas to the tree and fill them (selecting methods only). */
static sl_status base_node_areas(sl_occ_base *b, sl_error *err)
{
    if (!b->pick_cap)
        return SL_OK;
    uint32_t n = b->bvh->node_slots;
    if (n != b->node_slots || !b->node_area) {
        sl_free(&b->alloc, b->node_area, at_least_one(b->node_slots) * sizeof(float));
        b->node_area = sl_alloc(&b->alloc, at_least_one(n) * sizeof(float));
        b->node_slots = b->node_area ? n : 0;
        if (!b->node_area)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for %u node areas", n);
    }
    sl_occ_node_areas(b->occ, b->bvh, b->node_area);
    return SL_OK;
}

sl_status sl_occ_base_init(sl_occ_base *b, sl_scene scene, const char *method, const sl_occ_common *c, bool faces,
                           uint32_t mesh_faces, bool select, const sl_cull_extras *extras, const sl_allocator *alloc,
                           sl_error *err)
{
    memset(b, 0, sizeof *b);
    b->alloc = *alloc;
    b->scene = scene;
    b->method = method;
    b->object_count = sl_scene_object_count(scene);
    /* res=any draws prisms face by face (render_prism_eroded): their vertices are kept */
    sl_occ_options oo = {c->inset, c->all_objects, faces || c->res_any, mesh_faces, c->res_any && !c->inner_faces};
    sl_status st = sl_cull_object_bvh(scene, extras, c->leaf_size, alloc, &b->bvh, &b->bvh_owned, err);
    if (st == SL_OK)
        st = sl_occ_set_create(scene, &oo, alloc, &b->occ, err);
    if (st == SL_OK) {
        b->sort_scratch = sl_alloc(alloc, at_least_one(b->object_count) * sizeof(uint32_t));
        if (select) {
            /* pick_cap is set only with every pick buffer, so that free sizes them right */
            size_t pc = at_least_one(c->occluders);
            b->heap = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
            b->picks = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
            b->pick_ids = sl_alloc(alloc, pc * sizeof(uint32_t));
            b->pick_cap = (uint32_t)pc;
        }
        if (!b->sort_scratch || (select && (!b->heap || !b->picks || !b->pick_ids)))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    if (st == SL_OK)
        st = base_node_areas(b, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", method);
        sl_occ_base_free(b);
    }
    return st;
}

sl_status sl_occ_base_scene_changed(sl_occ_base *b, sl_error *err)
{
    /* a shared tree is refitted by the handle's owner before this (accel.h) */
    sl_status st = b->bvh_owned ? sl_bvh_refit(b->bvh, b->scene, err) : SL_OK;
    if (st == SL_OK && b->bvh_owned)
        st = sl_bvh_rebuild_if_degraded(b->bvh, b->scene, 0, NULL, err);
    if (st == SL_OK)
        st = base_node_areas(b, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", b->method);
        return st;
    }
    sl_occ_set_scene_changed(b->occ);
    return SL_OK;
}

uint32_t sl_occ_base_select(sl_occ_base *b, const sl_occ_view *v, const sl_occ_common *c, uint64_t *nodes_visited)
{
    if (!b->pick_cap)
        return 0;
    uint32_t n = sl_occ_select(b->occ, v, b->bvh, b->node_area, c->occluders, c->budget, c->min_quality, b->heap,
                               b->picks, nodes_visited);
    for (uint32_t i = 0; i < n; i++)
        b->pick_ids[i] = b->picks[i].proxy;
    return n;
}

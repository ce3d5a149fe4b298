/* The shared per-scene acceleration handle (accel.h, sl_scene_accel): one object BVH for many
 * cullers. */
#include "sightline/accel.h"

#include "bvh_internal.h"
#include "core/sl_core.h"

struct sl_scene_accel_t {
    sl_allocator alloc;
    sl_scene scene;
    sl_bvh bvh;
    uint32_t leaf_size;
};

sl_status sl_scene_accel_create(sl_scene scene, const sl_scene_accel_options *options, sl_scene_accel *out,
                                sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_accel_create: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_accel_create: scene is NULL");
    uint32_t leaf = options && options->leaf_size ? options->leaf_size : SL_BVH_DEFAULT_LEAF_SIZE;
    if (leaf > SL_BVH_MAX_LEAF_SIZE)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "scene accel: leaf_size %u is above %u", leaf,
                       SL_BVH_MAX_LEAF_SIZE);
    const sl_allocator *alloc = sl_alloc_or_default(options ? options->alloc : NULL);
    struct sl_scene_accel_t *a = sl_calloc(alloc, 1, sizeof *a);
    if (!a)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "scene accel: out of memory");
    a->alloc = *alloc;
    a->scene = scene;
    a->leaf_size = leaf;
    sl_bvh_options bo = {0};
    bo.max_leaf_size = leaf;
    bo.threads = options ? options->threads : 0;
    bo.alloc = alloc;
    sl_status st = sl_bvh_build(scene, &bo, &a->bvh, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "scene accel");
        sl_free(alloc, a, sizeof *a);
        return st;
    }
    *out = a;
    return SL_OK;
}

void sl_scene_accel_destroy(sl_scene_accel a)
{
    if (!a)
        return;
    sl_bvh_destroy(a->bvh);
    sl_allocator al = a->alloc;
    sl_free(&al, a, sizeof *a);
}

sl_scene sl_scene_accel_scene(sl_scene_accel a) { return a ? a->scene : NULL; }

sl_bvh sl_scene_accel_bvh(sl_scene_accel a) { return a ? a->bvh : NULL; }

uint32_t sl_scene_accel_leaf_size(sl_scene_accel a) { return a ? a->leaf_size : 0; }

sl_status sl_scene_accel_scene_changed(sl_scene_accel a, sl_error *err)
{
    if (!a)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_accel_scene_changed: accel is NULL");
    sl_status st = sl_bvh_refit(a->bvh, a->scene, err);
    if (st == SL_OK)
        st = sl_bvh_rebuild_if_degraded(a->bvh, a->scene, 0, NULL, err);
    if (st != SL_OK)
        sl_error_prefix(err, "scene accel");
    return st;
}

size_t sl_scene_accel_memory(sl_scene_accel a)
{
    if (!a)
        return 0;
    sl_bvh_stats s;
    sl_bvh_get_stats(a->bvh, &s);
    return sizeof *a + s.memory_bytes;
}

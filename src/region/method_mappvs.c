/* mappvs: the Quake III map's own cluster PVS (computed by q3map's portal flood when the map was
 * compiled) stored as a Sightline PVS, so that it can be verified against the region oracle, used
 * by the pvs culler and compared with baked methods cell for cell.
 *
 * A cell's set: the objects listed in the leaves of every cluster the map marks visible from the
 * cell's cluster, plus the objects in no leaf (models and props the engine always draws). Maps
 * without vis data see everything. Declared aggressive: the map's visibility is whatever its
 * compiler produced, and Sightline does not vouch for it (`sightline pvs verify` measures it).
 * CLUSTER cells only. */
#include "pvs_internal.h"

#include <stdlib.h>

typedef struct mappvs_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    uint32_t nobj;
} mappvs_shared;

typedef struct mappvs_worker {
    mappvs_shared *sh;
    uint8_t *mark;
} mappvs_worker;

static sl_status mappvs_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                                uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads; /* serial */
    (void)config;
    *removed = 0;
    sl_bsp_view bv;
    if (!sl_scene_bsp(scene, &bv))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "mappvs: the scene has no BSP data (not a Quake III map)");
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_CLUSTER || (uint32_t)vc[i].cluster >= bv.cluster_count)
            return sl_fail(err, SL_ERROR_UNSUPPORTED, "mappvs: view cell %u is not a cluster of this map (use --cells bsp)",
                           i);
    mappvs_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "mappvs: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->nobj = sl_scene_object_count(scene);
    *shared = s;
    return SL_OK;
}

static void mappvs_release(void *p)
{
    mappvs_shared *s = p;
    if (s)
        sl_free(&s->a, s, sizeof *s);
}

static sl_status mappvs_worker_create(void *shared, void **out, sl_error *err)
{
    mappvs_shared *s = shared;
    mappvs_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (w)
        w->mark = sl_alloc(&s->a, 2 * (size_t)s->nobj + 1);
    if (!w || !w->mark) {
        if (w)
            sl_free(&s->a, w, sizeof *w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "mappvs: out of memory");
    }
    w->sh = s;
    *out = w;
    return SL_OK;
}

static void mappvs_worker_destroy(void *p)
{
    mappvs_worker *w = p;
    if (!w)
        return;
    sl_free(&w->sh->a, w->mark, 2 * (size_t)w->sh->nobj + 1);
    sl_free(&w->sh->a, w, sizeof *w);
}

static sl_status mappvs_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    (void)err;
    mappvs_worker *w = worker;
    mappvs_shared *s = w->sh;
    sl_bsp_view bv;
    sl_scene_bsp(s->scene, &bv);
    int32_t from = sl_viewcells_data(s->cells)[cell].cluster;
    uint8_t *mark = w->mark, *in_leaf = w->mark + s->nobj;
    memset(mark, 0, 2 * (size_t)s->nobj);
    for (uint32_t l = 0; l < bv.leaf_count; l++) {
        int32_t c = bv.leaves[l].cluster;
        bool vis = c >= 0 && (uint32_t)c < bv.cluster_count &&
                   (!bv.pvs || bv.cluster_bytes == 0 ||
                    ((bv.pvs[(size_t)from * bv.cluster_bytes + ((uint32_t)c >> 3)] >> (c & 7)) & 1));
        for (uint32_t k = 0; k < bv.leaves[l].object_count; k++) {
            uint32_t id = bv.leaf_objects[bv.leaves[l].first_object + k];
            if (id >= s->nobj)
                continue;
            in_leaf[id] = 1;
            if (vis)
                mark[id] = 1;
        }
    }
    uint32_t n = 0;
    for (uint32_t id = 0; id < s->nobj; id++)
        if (mark[id] || !in_leaf[id])
            out->ids[n++] = id;
    out->count = n;
    out->work = 0;
    return SL_OK;
}

const sl_pvs_method sl_pvs_method_mappvs = {
    .name = "mappvs",
    .summary = "the Quake III map's own cluster PVS as a Sightline PVS (for verification and comparison); bsp cells",
    .options_help = "",
    .guarantee = SL_AGGRESSIVE,
    .config_size = 0,
    .configure = NULL,
    .prepare = mappvs_prepare,
    .worker_create = mappvs_worker_create,
    .cell = mappvs_cell,
    .worker_destroy = mappvs_worker_destroy,
    .release = mappvs_release,
    .notice = NULL,
};

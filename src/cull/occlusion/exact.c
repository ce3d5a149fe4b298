/* The exact layer: visible objects drawn with the oracle's own rasterizer (exact.h). */
#include "exact.h"

#include "project.h"

#include <math.h>

/* ---- the exact layer ---- */

sl_status sl_occ_exact_init(sl_occ_exact *e, const sl_allocator *alloc, sl_error *err)
{
    (void)err;
    memset(e, 0, sizeof *e);
    e->alloc = *alloc;
    return SL_OK;
}

void sl_occ_exact_free(sl_occ_exact *e)
{
    size_t n = (size_t)e->width * e->height;
    sl_free(&e->alloc, e->depth, n * sizeof(float));
    sl_free(&e->alloc, e->ids, n * sizeof(uint32_t));
    sl_free(&e->alloc, e->dirty, e->dirty_cap * sizeof *e->dirty);
    sl_refrast_scratch_free(&e->alloc, &e->scratch);
    memset(e, 0, sizeof *e);
}

sl_status sl_occ_exact_begin(sl_occ_exact *e, const sl_occ_view *v, sl_error *err)
{
    if (e->width != v->width || e->height != v->height) {
        size_t old = (size_t)e->width * e->height, n = (size_t)v->width * v->height;
        sl_free(&e->alloc, e->depth, old * sizeof(float));
        sl_free(&e->alloc, e->ids, old * sizeof(uint32_t));
        e->depth = sl_calloc(&e->alloc, n, sizeof(float));
        e->ids = sl_alloc(&e->alloc, n * sizeof(uint32_t));
        e->width = e->height = 0;
        if (!e->depth || !e->ids) {
            sl_free(&e->alloc, e->depth, n * sizeof(float));
            sl_free(&e->alloc, e->ids, n * sizeof(uint32_t));
            e->depth = NULL;
            e->ids = NULL;
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory for %ux%u pixels", v->width,
                           v->height);
        }
        for (size_t i = 0; i < n; i++)
            e->ids[i] = SL_NONE;
        e->width = v->width;
        e->height = v->height;
        e->dirty_count = 0;
    }
    /* clear what the last frame drew (depth 0 and no id: what sl_refrast_clear writes) */
    for (size_t k = 0; k < e->dirty_count; k++) {
        const sl_occ_rect *r = &e->dirty[k];
        for (int32_t y = r->y0; y < r->y1; y++) {
            size_t at = (size_t)y * e->width + (size_t)r->x0, n = (size_t)(r->x1 - r->x0);
            memset(e->depth + at, 0, n * sizeof(float));
            for (size_t i = 0; i < n; i++)
                e->ids[at + i] = SL_NONE;
        }
    }
    e->dirty_count = 0;
    e->drawn = 0;
    e->pixel_tests = 0;
    for (int i = 0; i < 16; i++)
        e->vp[i] = (double)v->vp.m[i]; /* as the oracle converts sl_camera_view_proj */
    return SL_OK;
}

double sl_occ_exact_box_depth(const sl_occ_exact *e, const sl_aabb *b)
{
    double best = 0.0;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? grow_coord(b->max.x, 1) : grow_coord(b->min.x, -1),
                       (k & 2) ? grow_coord(b->max.y, 1) : grow_coord(b->min.y, -1),
                       (k & 4) ? grow_coord(b->max.z, 1) : grow_coord(b->min.z, -1)};
        double c[4];
        for (int row = 0; row < 4; row++)
            c[row] = e->vp[row] * p[0] + e->vp[4 + row] * p[1] + e->vp[8 + row] * p[2] + e->vp[12 + row];
        if (!(c[3] > 0.0))
            return INFINITY;
        double od = oracle_depth(c);
        best = od > best ? od : best;
    }
    return best;
}

sl_status sl_occ_exact_draw(sl_occ_exact *e, sl_scene scene, uint32_t object, const sl_occ_rect *r, sl_error *err)
{
    const struct sl_scene_t *sc = scene;
    object_mesh om = get_object_mesh(sc, object);
    if (!sl_refrast_scratch_reserve(&e->alloc, &e->scratch, om.mr->vertex_count))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory for %u vertices", om.mr->vertex_count);
    if (e->dirty_count == e->dirty_cap) {
        size_t cap = e->dirty_cap ? 2 * e->dirty_cap : 256;
        sl_occ_rect *d = sl_alloc(&e->alloc, cap * sizeof *d);
        if (!d)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory");
        if (e->dirty_count)
            memcpy(d, e->dirty, e->dirty_count * sizeof *d);
        sl_free(&e->alloc, e->dirty, e->dirty_cap * sizeof *d);
        e->dirty = d;
        e->dirty_cap = cap;
    }
    /* what the oracle draws for the object: its matrix, mesh and facing rule (a closed convex
     * mesh without its back faces; drawing fewer fragments than the oracle is always safe) */
    double m[16];
    sl_refrast_compose(e->vp, &om.xf, m);
    sl_refrast_cull cull = SL_REFRAST_CULL_NONE;
    if (sl_scene_objects(sc)[object].flags & SL_OBJECT_CLOSED_CONVEX) {
        const float *a = om.xf.m;
        double det = (double)a[0] * ((double)a[5] * a[10] - (double)a[6] * a[9]) -
                     (double)a[1] * ((double)a[4] * a[10] - (double)a[6] * a[8]) +
                     (double)a[2] * ((double)a[4] * a[9] - (double)a[5] * a[8]);
        cull = det < 0 ? SL_REFRAST_CULL_FRONT : SL_REFRAST_CULL_BACK;
    }
    sl_refrast_target t = {e->width, e->height, e->ids, e->depth, NULL, 2.0 * SL_REFRAST_GUARD_PX / e->width,
                           2.0 * SL_REFRAST_GUARD_PX / e->height};
    sl_refrast_mesh(&t, &e->scratch, m, om.pos, om.mr->vertex_count, om.idx, om.mr->triangle_count, object, cull);
    e->dirty[e->dirty_count++] = *r;
    e->drawn++;
    return SL_OK;
}

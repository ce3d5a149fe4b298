/* The rasterizer wrapper: one conservative rasterizer per method, sized to the view, rendering
 * proxies (each once a frame), counting and recording queries, and writing the debug frame's
 * recording and dumps (raster.h). How the proxies are drawn by inner coverage under res=any is in
 * inner_coverage.c. */
#include "raster.h"

#include "inner_coverage.h"
#include "project.h"

/* ---- the rasterizer wrapper ---- */

sl_status sl_occ_raster_init(sl_occ_raster *r, const sl_occ_common *c, const sl_occ_set *set,
                             const sl_allocator *alloc, sl_error *err)
{
    memset(r, 0, sizeof *r);
    r->alloc = *alloc;
    r->threads = c->threads;
    r->isa = c->isa;
    r->erode = c->res_any;
    r->hull = c->res_any && !c->inner_faces;
    if (!sl_raster_isa_available((sl_raster_isa)c->isa))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "isa=%s: this CPU cannot run it",
                       sl_raster_isa_name((sl_raster_isa)c->isa));
    r->batch_cap = (size_t)(set ? set->prism_tri_count : 0) * 3 + 3;
    r->batch = sl_alloc(alloc, r->batch_cap * sizeof(uint32_t));
    r->proxy_count = set ? set->proxy_count : 0;
    r->stamp = sl_calloc(alloc, r->proxy_count ? r->proxy_count : 1, sizeof(uint32_t));
    size_t mt = 1, mv = 1;
    for (uint32_t p = 0; p < r->proxy_count; p++) {
        const sl_occ_proxy *pr = &set->proxies[p];
        if (pr->kind == SL_OCC_MESH || (r->erode && pr->kind == SL_OCC_SCENE_MESH)) {
            mt = SL_MAX(mt, (size_t)pr->triangles);
            mv = SL_MAX(mv, (size_t)sl_scene_meshes(set->scene)[pr->mesh].vertex_count);
        } else if (r->erode && pr->kind == SL_OCC_PRISM) {
            /* its faces fanned: at most its triangles; their vertices projected */
            mt = SL_MAX(mt, (size_t)pr->count);
            for (uint32_t f = 0; f < pr->face_count; f++)
                mv = SL_MAX(mv, (size_t)set->faces[pr->face_first + f].count);
        }
    }
    if (r->hull)
        mt = SL_MAX(mt, (size_t)256); /* sl_occ_render_prism_hull's pieces: up to 64 + 128 vertices each */
    r->shrunk = sl_alloc(alloc, mt * 9 * sizeof(float));
    r->shrunk_idx = sl_alloc(alloc, mt * 3 * sizeof(uint32_t));
    r->shrunk_proj = sl_alloc(alloc, mv * sizeof(sl_occ_screen_vertex));
    r->shrunk_cap = mt;
    r->shrunk_proj_cap = mv;
    if (!r->batch || !r->stamp || !r->shrunk || !r->shrunk_idx || !r->shrunk_proj)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for the occluder batch");
    for (size_t i = 0; i < mt * 3; i++)
        r->shrunk_idx[i] = (uint32_t)i;
    if (c->dump) {
        snprintf(r->dump_path, sizeof r->dump_path, "%s", c->dump);
        r->dump = r->dump_path;
    }
    if (c->record) {
        snprintf(r->record_path, sizeof r->record_path, "%s", c->record);
        r->record = r->record_path;
    }
    r->debug_frame = c->debug_frame;
    return SL_OK;
}

void sl_occ_raster_free(sl_occ_raster *r)
{
    sl_raster_destroy(r->ctx);
    sl_occ_recorder_destroy(r->rec);
    sl_free(&r->alloc, r->batch, r->batch_cap * sizeof(uint32_t));
    sl_free(&r->alloc, r->shrunk, r->shrunk_cap * 9 * sizeof(float));
    sl_free(&r->alloc, r->shrunk_idx, r->shrunk_cap * 3 * sizeof(uint32_t));
    sl_free(&r->alloc, r->shrunk_proj, r->shrunk_proj_cap * sizeof(sl_occ_screen_vertex));
    sl_free(&r->alloc, r->stamp, (size_t)(r->proxy_count ? r->proxy_count : 1) * sizeof(uint32_t));
    memset(r, 0, sizeof *r);
}

sl_status sl_occ_raster_begin(sl_occ_raster *r, const sl_occ_view *v, sl_error *err)
{
    sl_status st;
    if (!r->ctx || r->width != v->width || r->height != v->height) {
        sl_raster_destroy(r->ctx);
        r->ctx = NULL;
        sl_raster_options o = sl_raster_default_options(v->width, v->height);
        o.threads = r->threads;
        o.isa = (sl_raster_isa)r->isa;
        o.depth = v->depth;
        if ((st = sl_raster_create(&o, &r->alloc, &r->ctx, err)) != SL_OK)
            return st;
        r->width = v->width;
        r->height = v->height;
    }
    if ((st = sl_raster_begin_frame(r->ctx, v->depth, err)) != SL_OK)
        return st;
    if (++r->frame_id == 0) {
        memset(r->stamp, 0, (size_t)r->proxy_count * sizeof(uint32_t));
        r->frame_id = 1;
    }
    r->queries = r->pixel_queries = r->occluders_rendered = r->triangles_rendered = 0;
    sl_occ_recorder_destroy(r->rec);
    r->rec = NULL;
    if (r->record && r->frame == r->debug_frame) {
        sl_raster_options o = sl_raster_default_options(v->width, v->height);
        if ((st = sl_occ_recorder_create(&r->alloc, &o, v->depth, &r->rec, err)) != SL_OK)
            return st;
    }
    return SL_OK;
}

/* Render a scene mesh with a transform, two-sided (open meshes are seen from both sides by the
 * oracle). */
static void render_mesh(sl_occ_raster *r, const struct sl_scene_t *sc, const sl_occ_view *v, uint32_t mesh,
                        sl_affine xf)
{
    const sl_mesh_rec *mr = &sl_scene_meshes(sc)[mesh];
    float m[16];
    mul_affine(&v->vp, &xf, m);
    const float *pos = sl_scene_positions(sc) + 3 * mr->first_vertex;
    const uint32_t *idx = sl_scene_indices(sc) + mr->first_index;
    (void)sl_raster_render_triangles(r->ctx, pos, mr->vertex_count, idx, mr->triangle_count, 12, m,
                                     SL_RASTER_CULL_NONE, NULL);
    if (r->rec)
        sl_occ_recorder_batch(r->rec, pos, 12, idx, mr->triangle_count, m, SL_RASTER_CULL_NONE);
}

uint32_t sl_occ_raster_render(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const uint32_t *proxies,
                              uint32_t n)
{
    size_t k = 0;
    uint32_t rendered = 0;
    const struct sl_scene_t *sc = s->scene;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t p = proxies[i];
        if (r->stamp[p] == r->frame_id)
            continue;
        r->stamp[p] = r->frame_id;
        const sl_occ_proxy *pr = &s->proxies[p];
        rendered++;
        r->triangles_rendered += pr->triangles;
        if (pr->kind == SL_OCC_PRISM && r->erode) {
            if (r->hull)
                sl_occ_render_prism_hull(r, s, v, pr);
            else
                sl_occ_render_prism_eroded(r, s, v, pr);
            continue;
        }
        if (pr->kind == SL_OCC_PRISM) {
            size_t m = 3 * (size_t)pr->count;
            memcpy(r->batch + k, s->prism_idx + 3 * (size_t)pr->first, m * sizeof(uint32_t));
            k += m;
            continue;
        }
        if (pr->kind == SL_OCC_MESH && r->hull)
            sl_occ_render_mesh_hull(r, s, v, pr->mesh, object_transform(sc, pr->object));
        else if (pr->kind == SL_OCC_MESH)
            sl_occ_render_mesh_shrunk(r, sc, v, pr->mesh, object_transform(sc, pr->object), NULL, 0);
        else if (r->hull)
            sl_occ_render_mesh_hull(r, s, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform);
        else if (r->erode)
            sl_occ_render_mesh_shrunk(r, sc, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform, NULL, 0);
        else
            render_mesh(r, sc, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform);
    }
    if (k) {
        /* prisms are closed and the eye is outside them (sl_occ_usable): back faces are hidden */
        (void)sl_raster_render_triangles(r->ctx, s->prism_pos, s->prism_vertex_count, r->batch, (uint32_t)(k / 3), 12,
                                         v->vp.m, SL_RASTER_CULL_CW, NULL);
        if (r->rec)
            sl_occ_recorder_batch(r->rec, s->prism_pos, 12, r->batch, (uint32_t)(k / 3), v->vp.m, SL_RASTER_CULL_CW);
    }
    r->occluders_rendered += rendered;
    return rendered;
}

sl_raster_result sl_occ_raster_test(sl_occ_raster *r, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d)
{
    r->queries++;
    if (x1 > x0 && y1 > y0)
        r->pixel_queries += (uint64_t)(x1 - x0) * (uint64_t)(y1 - y0);
    sl_raster_result res = sl_raster_test_rect(r->ctx, x0, y0, x1, y1, d);
    if (r->rec)
        sl_occ_recorder_query(r->rec, x0, y0, x1, y1, d, res);
    return res;
}

sl_raster_result sl_occ_raster_test_object(sl_occ_raster *r, sl_scene scene, const sl_occ_view *v, uint32_t object)
{
    object_mesh om = get_object_mesh(scene, object);
    float m[16];
    mul_affine(&v->vp, &om.xf, m);
    r->queries++;
    sl_raster_result res = sl_raster_test_triangles(r->ctx, om.pos, om.mr->vertex_count, om.idx,
                                                    om.mr->triangle_count, 12, m, SL_RASTER_CULL_NONE);
    if (r->rec)
        sl_occ_recorder_mesh_query(r->rec, om.pos, 12, om.idx, om.mr->triangle_count, m, SL_RASTER_CULL_NONE, res);
    return res;
}

sl_status sl_occ_raster_end(sl_occ_raster *r, const sl_occ_levels *levels, sl_error *err)
{
    bool debug = r->frame == r->debug_frame;
    r->frame++;
    if (!debug)
        return SL_OK;
    sl_status st = SL_OK;
    if (r->rec) {
        st = sl_occ_recorder_save(r->rec, r->record, err);
        sl_occ_recorder_destroy(r->rec);
        r->rec = NULL;
        if (st != SL_OK)
            return st;
    }
    if (r->dump) {
        char path[300];
        size_t n = (size_t)r->width * r->height;
        float *depth = sl_alloc(&r->alloc, n * sizeof(float));
        if (!depth)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "dump: out of memory for %zu depths", n);
        st = sl_raster_read_depth(r->ctx, depth, n, err);
        snprintf(path, sizeof path, "%s-depth.png", r->dump);
        if (st == SL_OK)
            st = sl_occ_write_depth_png(path, depth, r->width, r->height, &r->alloc, err);
        sl_free(&r->alloc, depth, n * sizeof(float));
        if (st == SL_OK && levels && levels->count) {
            snprintf(path, sizeof path, "%s-pyramid.png", r->dump);
            st = sl_occ_write_levels_png(path, levels, &r->alloc, err);
        }
    }
    return st;
}

/* hzb: hierarchical z-buffer occlusion culling on the CPU, after Greene, Kass & Miller,
 * "Hierarchical Z-Buffer Visibility" (SIGGRAPH 1993), sections 3-4, as summarised in the SIGGRAPH
 * 2000 course "Visibility, problems, techniques and applications" (section 6.1).
 *
 * Per frame:
 *  1. select: the best occluder proxies in the frustum by Coorg-Teller quality under a triangle
 *     budget (occluders.c), rendered in one batch into the conservative rasterizer (threaded);
 *  2. pyramid: a max-depth (farthest) pyramid over the buffer, its base level the farthest depth of
 *     each 8x4 subtile (sl_raster_read_subtile_depth), each coarser level the farthest of 2x2;
 *  3. traverse: the object BVH front to back; each node and object box passes the frustum test,
 *     then the hierarchical box test: its screen rectangle against the coarsest pyramid level
 *     where it spans at most 2x2 entries (one compare each), and, when that cannot prove it
 *     hidden, the rasterizer's exact rectangle query at its nearest depth. A visible object is
 *     reported and, when it has a proxy of sufficient quality, rendered at once as an occluder
 *     (front-to-back order makes the objects found first the best occluders); the pyramid is
 *     rebuilt after every `refresh` such occluders. A stale pyramid is still conservative: every
 *     state of the buffer during a frame bounds the depth of occluders that stay valid all frame.
 *     Objects of at most `mesh_test` triangles whose box looks visible are tested by their own
 *     triangles. Visible proxies of quality below min_quality (small, mostly far) go to a second
 *     buffer (`far_layer`): merged into the main one, their far depths would dilute the partial
 *     layers the rasterizer keeps along near silhouettes; a box hidden in either buffer is hidden
 *     (each holds valid occluders only).
 * Conservative: proxies lie inside their objects (occluders.h), the rasterizer never writes a
 * depth nearer than its occluders, and boxes are tested at the depth of their nearest corner. */
#include "occluders.h"

#include <math.h>

#define MAX_LEVELS 24

typedef struct hzb_config {
    sl_occ_common c;
    bool pyramid;
    bool render_visible;
    uint32_t refresh;
    uint32_t mesh_test;
    bool far_layer;
    float far_quality;
} hzb_config;

typedef struct hzb_state {
    sl_allocator alloc;
    sl_scene scene;
    hzb_config cfg;
    sl_bvh bvh;
    float *node_area;
    uint32_t node_slots;
    sl_occ_set *occ;
    sl_occ_raster r;
    sl_occ_raster far;           /* far layer: visible proxies of low quality (far_layer) */
    sl_occ_pick *heap, *picks;
    uint32_t *pick_ids;
    uint32_t pick_cap;
    uint32_t object_count;
    uint32_t *sort_scratch;
    /* the pyramid: level i is lw[i] x lh[i] floats at pyr + loff[i] */
    float *pyr;
    size_t pyr_cap;
    uint32_t levels, lw[MAX_LEVELS], lh[MAX_LEVELS];
    size_t loff[MAX_LEVELS];
    uint32_t pyr_w, pyr_h;       /* screen size the pyramid was sized for */
    bool pyr_valid;
    const float *level_ptr[MAX_LEVELS];
} hzb_state;

static const char g_help[] =
    SL_OCC_HELP_RASTER
    "occluders=0..4096 (default 48): most occluders chosen per frame by Coorg-Teller quality\n"
    "budget=0..10000000 (default 20000): triangle budget of the chosen occluders\n"
    "min_quality=NUMBER (default 0.0005): least quality (solid angle, sr) of an occluder\n"
    "inset=0.01..10 (default 0.1): metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n"
    "pyramid=BOOL (default true): test boxes against the max-depth pyramid before the exact query\n"
    "render_visible=BOOL (default true): render the proxies of objects found visible as occluders\n"
    "refresh=0..100000 (default 16): rebuild the pyramid after this many occluders found during the "
    "traversal (0: only after the selected occluders)\n"
    "mesh_test=0..100000 (default 64): test an object whose box looks visible by its own triangles when it "
    "has at most this many (0: boxes only)\n"
    "far_layer=BOOL (default true): render visible proxies below min_quality into a second buffer; a box "
    "hidden in either buffer is hidden\n"
    "far_quality=NUMBER (default 0.00001): least quality (sr) of a far-layer occluder\n" SL_OCC_HELP_DEBUG;

static sl_status hzb_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    hzb_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_occ_configure_common(o, SL_OCC_OPT_RASTER | SL_OCC_OPT_SELECT | SL_OCC_OPT_DEBUG, 48, 20000, &c->c,
                                      err)) != SL_OK ||
        (st = sl_opts_bool(o, "pyramid", true, &c->pyramid, err)) != SL_OK ||
        (st = sl_opts_bool(o, "render_visible", true, &c->render_visible, err)) != SL_OK ||
        (st = sl_opts_u32(o, "refresh", 16, 0, 100000, &c->refresh, err)) != SL_OK ||
        (st = sl_opts_u32(o, "mesh_test", 64, 0, 100000, &c->mesh_test, err)) != SL_OK ||
        (st = sl_opts_bool(o, "far_layer", true, &c->far_layer, err)) != SL_OK ||
        (st = sl_opts_float(o, "far_quality", 0.00001f, 0.0f, 100.0f, &c->far_quality, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void hzb_destroy(void *state)
{
    hzb_state *s = state;
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    sl_bvh_destroy(s->bvh);
    sl_free(a, s->node_area, (size_t)(s->node_slots ? s->node_slots : 1) * sizeof(float));
    sl_occ_raster_free(&s->r);
    sl_occ_raster_free(&s->far);
    sl_occ_set_destroy(s->occ);
    sl_free(a, s->heap, (size_t)(s->pick_cap ? s->pick_cap : 1) * sizeof(sl_occ_pick));
    sl_free(a, s->picks, (size_t)(s->pick_cap ? s->pick_cap : 1) * sizeof(sl_occ_pick));
    sl_free(a, s->pick_ids, (size_t)(s->pick_cap ? s->pick_cap : 1) * sizeof(uint32_t));
    sl_free(a, s->sort_scratch, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->pyr, s->pyr_cap * sizeof(float));
    sl_free(a, s, sizeof *s);
}

/* (Re)size the per-node areas to the tree and fill them. */
static sl_status refresh_node_areas(hzb_state *s, sl_error *err)
{
    uint32_t n = s->bvh->node_slots;
    if (n != s->node_slots) {
        sl_free(&s->alloc, s->node_area, (size_t)(s->node_slots ? s->node_slots : 1) * sizeof(float));
        s->node_area = sl_alloc(&s->alloc, (size_t)(n ? n : 1) * sizeof(float));
        s->node_slots = s->node_area ? n : 0;
        if (!s->node_area)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hzb: out of memory for %u node areas", n);
    }
    sl_occ_node_areas(s->occ, s->bvh, s->node_area);
    return SL_OK;
}

static sl_status hzb_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state, sl_error *err)
{
    hzb_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hzb: out of memory");
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *(const hzb_config *)config;
    if (s->cfg.c.dump)
        s->cfg.c.dump = s->cfg.c.dump_buf;
    if (s->cfg.c.record)
        s->cfg.c.record = s->cfg.c.record_buf;
    s->object_count = sl_scene_object_count(scene);
    sl_bvh_options bo = {0};
    bo.max_leaf_size = s->cfg.c.leaf_size;
    bo.alloc = alloc;
    sl_occ_options oo = {s->cfg.c.inset, s->cfg.c.all_objects, false, 0};
    sl_status st = sl_bvh_build(scene, &bo, &s->bvh, err);
    if (st == SL_OK)
        st = sl_occ_set_create(scene, &oo, alloc, &s->occ, err);
    if (st == SL_OK)
        st = refresh_node_areas(s, err);
    if (st == SL_OK)
        st = sl_occ_raster_init(&s->r, &s->cfg.c, s->occ, alloc, err);
    if (st == SL_OK && s->cfg.far_layer) {
        sl_occ_common fc = s->cfg.c;
        fc.dump = fc.record = NULL; /* the debugging outputs show the main layer */
        st = sl_occ_raster_init(&s->far, &fc, s->occ, alloc, err);
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "hzb");
        hzb_destroy(s);
        return st;
    }
    s->pick_cap = s->cfg.c.occluders;
    size_t pc = s->pick_cap ? s->pick_cap : 1;
    s->heap = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
    s->picks = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
    s->pick_ids = sl_alloc(alloc, pc * sizeof(uint32_t));
    s->sort_scratch = sl_alloc(alloc, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    if (!s->heap || !s->picks || !s->pick_ids || !s->sort_scratch) {
        hzb_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hzb: out of memory");
    }
    *state = s;
    return SL_OK;
}

static sl_status hzb_scene_changed(void *state, sl_error *err)
{
    hzb_state *s = state;
    sl_status st = sl_bvh_refit(s->bvh, s->scene, err);
    if (st == SL_OK)
        st = sl_bvh_rebuild_if_degraded(s->bvh, s->scene, 0, NULL, err);
    if (st == SL_OK)
        st = refresh_node_areas(s, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "hzb");
        return st;
    }
    sl_occ_set_scene_changed(s->occ);
    return SL_OK;
}

/* Size the pyramid for a w x h screen (allocates only when the resolution changes). */
static sl_status size_pyramid(hzb_state *s, uint32_t w, uint32_t h, sl_error *err)
{
    if (s->pyr && s->pyr_w == w && s->pyr_h == h)
        return SL_OK;
    uint32_t tx, ty;
    sl_raster_get_size(s->r.ctx, NULL, NULL, &tx, &ty);
    uint32_t lw = tx * 4, lh = ty * 2;
    size_t total = 0;
    s->levels = 0;
    for (;;) {
        s->lw[s->levels] = lw;
        s->lh[s->levels] = lh;
        s->loff[s->levels] = total;
        total += (size_t)lw * lh;
        s->levels++;
        if ((lw == 1 && lh == 1) || s->levels == MAX_LEVELS)
            break;
        lw = (lw + 1) / 2;
        lh = (lh + 1) / 2;
    }
    sl_free(&s->alloc, s->pyr, s->pyr_cap * sizeof(float));
    s->pyr = sl_alloc(&s->alloc, total * sizeof(float));
    s->pyr_cap = s->pyr ? total : 0;
    if (!s->pyr)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hzb: out of memory for a %zu-entry pyramid", total);
    for (uint32_t i = 0; i < s->levels; i++)
        s->level_ptr[i] = s->pyr + s->loff[i];
    s->pyr_w = w;
    s->pyr_h = h;
    return SL_OK;
}

/* Rebuild the pyramid from the buffer: each entry the farthest (smallest) depth below it. */
static void build_pyramid(hzb_state *s)
{
    (void)sl_raster_read_subtile_depth(s->r.ctx, s->pyr, (size_t)s->lw[0] * s->lh[0], NULL);
    for (uint32_t l = 1; l < s->levels; l++) {
        const float *src = s->pyr + s->loff[l - 1];
        float *dst = s->pyr + s->loff[l];
        uint32_t sw = s->lw[l - 1], sh = s->lh[l - 1], w = s->lw[l], h = s->lh[l];
        for (uint32_t y = 0; y < h; y++) {
            const float *r0 = src + (size_t)(2 * y) * sw, *r1 = 2 * y + 1 < sh ? r0 + sw : r0;
            for (uint32_t x = 0; x < w; x++) {
                uint32_t x1 = 2 * x + 1 < sw ? 2 * x + 1 : 2 * x;
                float m = sl_occ_minf(sl_occ_minf(r0[2 * x], r0[x1]), sl_occ_minf(r1[2 * x], r1[x1]));
                dst[(size_t)y * w + x] = m;
            }
        }
    }
    s->pyr_valid = true;
}

/* Hierarchical test: true when the coarsest level where the rectangle spans at most 2x2 entries
 * proves every pixel of it hidden at depth d. */
static bool pyramid_hides(const hzb_state *s, const sl_occ_rect *r)
{
    uint32_t sx0 = (uint32_t)r->x0 >> 3, sx1 = (uint32_t)(r->x1 - 1) >> 3;
    uint32_t sy0 = (uint32_t)r->y0 >> 2, sy1 = (uint32_t)(r->y1 - 1) >> 2;
    uint32_t l = 0;
    while (l + 1 < s->levels && ((sx1 >> l) - (sx0 >> l) > 1 || (sy1 >> l) - (sy0 >> l) > 1))
        l++;
    const float *p = s->pyr + s->loff[l];
    uint32_t w = s->lw[l];
    for (uint32_t y = sy0 >> l; y <= sy1 >> l; y++)
        for (uint32_t x = sx0 >> l; x <= sx1 >> l; x++)
            if (!(r->dnear < p[(size_t)y * w + x]))
                return false;
    return true;
}

typedef struct frame_ctx {
    hzb_state *s;
    const sl_occ_view *v;
    sl_cull_stats *st;
    uint32_t since_refresh;
} frame_ctx;

/* True when box b is hidden (or off screen). */
static bool occluded(frame_ctx *f, const sl_aabb *b)
{
    sl_occ_rect r;
    int k = sl_occ_project_box(f->v, b, &r);
    if (k == SL_OCC_OUT)
        return true;
    if (k == SL_OCC_NEAR)
        return false;
    f->st->occlusion_tests++;
    hzb_state *s = f->s;
    if (s->cfg.pyramid && s->pyr_valid && pyramid_hides(s, &r))
        return true;
    if (sl_occ_raster_test(&s->r, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE)
        return true;
    /* hidden by the far layer's occluders alone is hidden too: both hold valid occluders only */
    return s->cfg.far_layer && s->far.occluders_rendered &&
           sl_occ_raster_test(&s->far, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE;
}

static void maybe_render(frame_ctx *f, uint32_t object)
{
    hzb_state *s = f->s;
    uint32_t p = s->occ->object_proxy[object];
    if (p == SL_NONE || sl_occ_raster_rendered(&s->r, p) || !sl_occ_usable(s->occ, p, f->v))
        return;
    float q = sl_occ_quality(s->occ, p, f->v);
    if (q < s->cfg.c.min_quality) {
        /* small (mostly far) occluders: merged into the main layer their far depths would dilute
         * the partial layers along near silhouettes; they go to the far layer */
        if (s->cfg.far_layer && q >= s->cfg.far_quality && !sl_occ_raster_rendered(&s->far, p))
            sl_occ_raster_render(&s->far, s->occ, f->v, &p, 1);
        return;
    }
    sl_occ_raster_render(&s->r, s->occ, f->v, &p, 1);
    if (s->cfg.pyramid && s->cfg.refresh && ++f->since_refresh >= s->cfg.refresh) {
        build_pyramid(s);
        f->since_refresh = 0;
    }
}

static sl_status hzb_cull(void *state, const sl_camera *cam, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    hzb_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, cam);
    sl_status st = sl_occ_raster_begin(&s->r, &v, err);
    if (st == SL_OK && s->cfg.far_layer)
        st = sl_occ_raster_begin(&s->far, &v, err);
    if (st == SL_OK && s->cfg.pyramid)
        st = size_pyramid(s, v.width, v.height, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "hzb");
        return st;
    }
    s->pyr_valid = false;
    /* 1. the chosen occluders */
    uint32_t np = sl_occ_select(s->occ, &v, s->bvh, s->node_area, s->cfg.c.occluders, s->cfg.c.budget,
                                s->cfg.c.min_quality, s->heap, s->picks, &stats->nodes_visited);
    for (uint32_t i = 0; i < np; i++)
        s->pick_ids[i] = s->picks[i].proxy;
    double t1 = sl_now();
    sl_occ_raster_render(&s->r, s->occ, &v, s->pick_ids, np);
    if (s->cfg.pyramid)
        build_pyramid(s);
    double t2 = sl_now();
    /* 2. front-to-back traversal */
    frame_ctx f = {s, &v, stats, 0};
    const struct sl_bvh_t *b = s->bvh;
    const float e[3] = {v.eye.x, v.eye.y, v.eye.z};
    uint32_t k = 0;
    uint64_t visited = 0, tested = 0;
    const sl_object_rec *objects = sl_scene_objects(s->scene);
    const sl_mesh_rec *meshes = sl_scene_meshes(s->scene);
    if (b->node_slots) {
        uint32_t stack[SL_BVH_MAX_DEPTH + 1], masks[SL_BVH_MAX_DEPTH + 1], sp = 0, ni = 0, mask = 0x3f;
        for (;;) {
            const sl_bvh_node *n = &b->nodes[ni];
            visited++;
            int r = mask ? sl_occ_frustum_classify(&v, &n->box, mask) : 0;
            if (r >= 0 && !occluded(&f, &n->box)) {
                if (n->count == 0) {
                    bool right = sl_bvh_right_first(b->nodes, n, e);
                    stack[sp] = n->first + (right ? 0 : 1);
                    masks[sp] = (uint32_t)r;
                    sp++;
                    ni = n->first + (right ? 1 : 0);
                    mask = (uint32_t)r;
                    continue;
                }
                for (uint32_t j = n->first; j < n->first + n->count; j++) {
                    tested++;
                    const sl_aabb *ob = &b->object_bounds[j];
                    if (r && sl_occ_frustum_classify(&v, ob, (uint32_t)r) < 0)
                        continue;
                    if (n->count > 1 && occluded(&f, ob))
                        continue;
                    uint32_t id = b->objects[j];
                    /* a small mesh whose box looks visible: its own triangles may still be hidden */
                    if (s->cfg.mesh_test && meshes[objects[id].mesh].triangle_count <= s->cfg.mesh_test &&
                        !sl_occ_point_in_box(v.eye, ob, 0.0f)) {
                        stats->occlusion_tests++;
                        if (sl_occ_raster_test_object(&s->r, s->scene, &v, id) != SL_RASTER_VISIBLE ||
                            (s->cfg.far_layer && s->far.occluders_rendered &&
                             sl_occ_raster_test_object(&s->far, s->scene, &v, id) != SL_RASTER_VISIBLE))
                            continue;
                    }
                    out[k++] = id;
                    if (s->cfg.render_visible)
                        maybe_render(&f, id);
                }
            }
            if (sp == 0)
                break;
            sp--;
            ni = stack[sp];
            mask = masks[sp];
        }
    }
    double t3 = sl_now();
    sl_cull_sort_ids(out, k, s->sort_scratch);
    double t4 = sl_now();
    stats->nodes_visited += visited;
    stats->objects_tested = tested;
    stats->queries = s->r.queries + s->far.queries;
    stats->pixel_queries = s->r.pixel_queries + s->far.pixel_queries;
    sl_cull_phase(stats, "select", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "render", sl_cull_ms(t1, t2));
    sl_cull_phase(stats, "traverse", sl_cull_ms(t2, t3));
    sl_cull_phase(stats, "sort", sl_cull_ms(t3, t4));
    *count = k;
    if (s->cfg.far_layer)
        (void)sl_occ_raster_end(&s->far, NULL, NULL); /* counts the frame; it has no debug outputs */
    sl_occ_levels lv = {s->cfg.pyramid ? s->levels : 0, s->level_ptr, s->lw, s->lh, false};
    if ((st = sl_occ_raster_end(&s->r, s->cfg.pyramid && s->pyr_valid ? &lv : NULL, err)) != SL_OK)
        sl_error_prefix(err, "hzb");
    return st;
}

const sl_cull_method sl_cull_method_hzb = {
    .name = "hzb",
    .summary = "hierarchical z-buffer: quality-selected occluder proxies plus the visible objects' proxies "
               "rendered front to back into the conservative rasterizer, boxes tested through a max-depth "
               "pyramid (Greene, Kass & Miller 1993)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(hzb_config),
    .configure = hzb_configure,
    .create = hzb_create,
    .cull = hzb_cull,
    .scene_changed = hzb_scene_changed,
    .destroy = hzb_destroy,
};

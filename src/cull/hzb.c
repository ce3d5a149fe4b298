/* hzb: hierarchical z-buffer occlusion culling on the CPU, after Greene, Kass & Miller,
 * "Hierarchical Z-Buffer Visibility" (SIGGRAPH 1993), sections 3-4, as summarised in the SIGGRAPH
 * 2000 course "Visibility, problems, techniques and applications" (section 6.1).
 *
 * Per frame:
 *  1. select: the best occluder proxies in the frustum by Coorg-Teller quality under a triangle
 *     budget (occlusion/select.c), rendered in one batch into the conservative rasterizer (threaded);
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
 *     A box whose rectangle looks visible is then tested at the pixel centres its silhouette
 *     covers (sl_occ_box_rows_hidden, `box_rows`): the rectangle touches border rows and columns
 *     whose centres the box does not reach, and a box between pixel centres hides nothing.
 *     An object whose box looks visible is then tested by its own triangles (sl_occ_object_hidden):
 *     sampled at the pixel centres the oracle samples (at most `sample_tris` triangles, box
 *     rectangle of at most `sample_px` pixels), then rasterized outward-conservatively (at most
 *     `mesh_test` triangles); hidden by either is hidden. The sampling drops objects hidden behind occluders that do not cover their
 *     whole box and objects that cover no pixel centre at all (far lamps, trees, cars). Visible
 *     proxies of quality below min_quality (small, mostly far) go to a second buffer
 *     (`far_layer`): merged into the main one, their far depths would dilute the partial layers
 *     the rasterizer keeps along near silhouettes; a box (or a sampled pixel) hidden in either
 *     buffer is hidden (each holds valid occluders only).
 *     Visible objects whose box rectangle holds at most `exact_px` pixels (far, small ones) are
 *     also drawn into an exact layer (sl_occ_exact) with the oracle's own rasterizer: their
 *     fragments are the oracle's, so a pixel-centre test that finds one nearer than anything the
 *     tested object may show there proves the pixel lost, at the same resolution. At the end of
 *     a street far props and buildings a pixel or two in size hide each other, and no conservative
 *     proxy of them survives the rasterizer's inset.
 * Conservative: proxies lie inside their objects (occlusion/proxies.h), the rasterizer never writes a
 * depth nearer than its occluders, and boxes are tested at the depth of their nearest corner.
 * Resolution (docs/culler-contract.md, "Guarantees and resolution"): by default (res=any) the
 * occluders are drawn by inner coverage and the three pixel-centre tests (box_rows' silhouette
 * rows, the sampled triangles, the exact layer) are off, so no object visible at any resolution
 * or sample position is dropped; res=culling turns them on (the defaults 8, 64, 48) and draws
 * occluders at pixel centres: tighter, conservative at the culling resolution only. */
#include "cull/occlusion/base.h"
#include "cull/occlusion/exact.h"
#include "cull/occlusion/object_tests.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/pyramid.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/select.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion/walk.h"
#include "cull/occlusion_debug.h"

#include <math.h>

typedef struct hzb_config {
    sl_occ_common c;
    bool pyramid;
    bool render_visible;
    uint32_t refresh;
    sl_occ_mesh_tests mt;
    bool far_layer;
    float far_quality;
    uint32_t box_rows;
    uint32_t exact_px;
} hzb_config;

typedef struct hzb_state {
    sl_occ_base b;               /* BVH, proxies, selection buffers */
    hzb_config cfg;
    sl_occ_raster r;
    sl_occ_raster far;           /* far layer: visible proxies of low quality (far_layer) */
    sl_occ_pyramid pyr;          /* the max-depth pyramid */
    sl_occ_exact ex;             /* small visible objects drawn as the oracle draws them (exact_px) */
    bool pyr_valid;
} hzb_state;

static const char g_help[] =
    SL_OCC_HELP_RES SL_OCC_HELP_RASTER
    "occluders=0..4096 (default 48): most occluders chosen per frame by Coorg-Teller quality\n"
    "budget=0..10000000 (default 20000): triangle budget of the chosen occluders\n"
    "min_quality=NUMBER (default 0.0005): least quality (solid angle, sr) of an occluder\n"
    "inset=0.01..10 (default 0.01 with res=any and inner=hull, raised where float rounding needs more; else 0.1): "
    "metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n"
    "pyramid=BOOL (default true): test boxes against the max-depth pyramid before the exact query\n"
    "render_visible=BOOL (default true): render the proxies of objects found visible as occluders\n"
    "refresh=0..100000 (default 16): rebuild the pyramid after this many occluders found during the "
    "traversal (0: only after the selected occluders)\n"
    SL_OCC_HELP_MESH_TESTS
    "far_layer=BOOL (default true): render visible proxies below min_quality into a second buffer; a box "
    "hidden in either buffer is hidden\n"
    "far_quality=NUMBER (default 0): least quality (sr) of a far-layer occluder\n"
    "box_rows=0..100000 (default 0; 8 with res=culling, which it needs): a box whose rectangle looks visible is tested again at the pixel centres "
    "it covers: those of its corners' bounding box, and, when the rectangle is at most this many rows tall, "
    "those inside its silhouette (0: neither)\n"
    "exact_px=0..16777216 (default 0; 48 with res=culling, which it needs): a visible object whose box rectangle holds at most this many pixels "
    "is drawn with the oracle's rasterizer into an exact layer that pixel-centre tests consult (0: never)\n"
    SL_OCC_HELP_DEBUG;

static sl_status hzb_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    hzb_config *c = config;
    sl_status st;
    if ((st = sl_occ_configure_common(o,
                                      SL_OCC_OPT_RASTER | SL_OCC_OPT_SELECT | SL_OCC_OPT_DEBUG | SL_OCC_OPT_RES |
                                          SL_OCC_OPT_THIN_INSET,
                                      48, 20000, &c->c, err)) != SL_OK ||
        (st = sl_opts_bool(o, "pyramid", true, &c->pyramid, err)) != SL_OK ||
        (st = sl_opts_bool(o, "render_visible", true, &c->render_visible, err)) != SL_OK ||
        (st = sl_opts_u32(o, "refresh", 16, 0, 100000, &c->refresh, err)) != SL_OK ||
        (st = sl_occ_configure_mesh_tests(o, &c->c, &c->mt, err)) != SL_OK ||
        (st = sl_opts_bool(o, "far_layer", true, &c->far_layer, err)) != SL_OK ||
        (st = sl_opts_float(o, "far_quality", 0.0f, 0.0f, 100.0f, &c->far_quality, err)) != SL_OK ||
        (st = sl_opts_u32(o, "box_rows", c->c.res_culling ? 8 : 0, 0, 100000, &c->box_rows, err)) != SL_OK ||
        (st = sl_opts_u32(o, "exact_px", c->c.res_culling ? 48 : 0, 0, 1u << 24, &c->exact_px, err)) != SL_OK ||
        (st = sl_occ_require_res_culling(o, &c->c, "box_rows", c->box_rows, err)) != SL_OK ||
        (st = sl_occ_require_res_culling(o, &c->c, "exact_px", c->exact_px, err)) != SL_OK)
        return st;
    *g = sl_occ_res_guarantee(&c->c);
    return SL_OK;
}

static void hzb_destroy(void *state)
{
    hzb_state *s = state;
    if (!s)
        return;
    sl_allocator a = s->b.alloc;
    sl_occ_raster_free(&s->r);
    sl_occ_raster_free(&s->far);
    sl_occ_pyramid_free(&s->pyr, &a);
    sl_occ_exact_free(&s->ex);
    sl_occ_base_free(&s->b);
    sl_free(&a, s, sizeof *s);
}

static sl_status hzb_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                            const sl_allocator *alloc, void **state, sl_error *err)
{
    hzb_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hzb: out of memory");
    s->cfg = *(const hzb_config *)config;
    if (s->cfg.c.dump)
        s->cfg.c.dump = s->cfg.c.dump_buf;
    if (s->cfg.c.record)
        s->cfg.c.record = s->cfg.c.record_buf;
    sl_status st = sl_occ_base_init(&s->b, scene, "hzb", &s->cfg.c, false, 0, true, extras, alloc, err);
    if (st != SL_OK) {
        sl_free(alloc, s, sizeof *s);
        return st;
    }
    st = sl_occ_exact_init(&s->ex, alloc, err);
    if (st == SL_OK)
        st = sl_occ_raster_init(&s->r, &s->cfg.c, s->b.occ, alloc, err);
    if (st == SL_OK && s->cfg.far_layer) {
        sl_occ_common fc = s->cfg.c;
        fc.dump = fc.record = NULL; /* the debugging outputs show the main layer */
        st = sl_occ_raster_init(&s->far, &fc, s->b.occ, alloc, err);
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "hzb");
        hzb_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status hzb_scene_changed(void *state, sl_error *err)
{
    hzb_state *s = state;
    return sl_occ_base_scene_changed(&s->b, err);
}

/* Rebuild the pyramid from the buffer: each entry the farthest (smallest) depth below it. */
static void build_pyramid(hzb_state *s)
{
    sl_occ_pyramid *p = &s->pyr;
    sl_occ_pyramid_read_base(p, s->r.ctx);
    for (uint32_t l = 1; l < p->levels; l++) {
        const float *src = p->data + p->loff[l - 1];
        float *dst = p->data + p->loff[l];
        uint32_t sw = p->lw[l - 1], sh = p->lh[l - 1], w = p->lw[l], h = p->lh[l];
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
    const sl_occ_pyramid *py = &s->pyr;
    uint32_t l = 0;
    while (l + 1 < py->levels && ((sx1 >> l) - (sx0 >> l) > 1 || (sy1 >> l) - (sy0 >> l) > 1))
        l++;
    const float *p = py->data + py->loff[l];
    uint32_t w = py->lw[l];
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
    uint32_t *out, k;           /* objects found visible */
    sl_status status;           /* the first failure of the exact layer */
    sl_error *err;
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
    if (s->cfg.far_layer && s->far.occluders_rendered &&
        sl_occ_raster_test(&s->far, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE)
        return true;
    /* the rectangle looks visible: the pixel centres of the box's silhouette */
    sl_occ_raster *layers[2] = {&s->r, &s->far};
    return s->cfg.box_rows &&
           sl_occ_box_rows_hidden(layers, s->cfg.far_layer ? 2 : 1, s->cfg.exact_px ? &s->ex : NULL, f->v, b, &r,
                                  s->cfg.box_rows);
}

static void maybe_render(frame_ctx *f, uint32_t object)
{
    hzb_state *s = f->s;
    const sl_occ_set *o = s->b.occ;
    uint32_t p = o->object_proxy[object];
    if (p == SL_NONE || sl_occ_raster_rendered(&s->r, p) || !sl_occ_usable(o, p, f->v))
        return;
    float q = sl_occ_quality(o, p, f->v);
    if (q < s->cfg.c.min_quality) {
        /* small (mostly far) occluders: merged into the main layer their far depths would dilute
         * the partial layers along near silhouettes; they go to the far layer */
        if (s->cfg.far_layer && q >= s->cfg.far_quality && !sl_occ_raster_rendered(&s->far, p))
            sl_occ_raster_render(&s->far, o, f->v, &p, 1);
        return;
    }
    sl_occ_raster_render(&s->r, o, f->v, &p, 1);
    if (s->cfg.pyramid && s->cfg.refresh && ++f->since_refresh >= s->cfg.refresh) {
        build_pyramid(s);
        f->since_refresh = 0;
    }
}

/* The walk's questions (sl_occ_walk). */
static bool skip(void *ctx, uint32_t slot, const sl_aabb *box)
{
    (void)slot;
    return occluded(ctx, box);
}

/* An object whose box looks visible: reported unless its own triangles are hidden, and rendered as
 * an occluder. */
static void visit(void *ctx, uint32_t id, const sl_aabb *box)
{
    frame_ctx *f = ctx;
    hzb_state *s = f->s;
    sl_occ_raster *layers[2] = {&s->r, &s->far};
    sl_occ_exact *ex = s->cfg.exact_px ? &s->ex : NULL;
    if (sl_occ_object_hidden(layers, s->cfg.far_layer ? 2 : 1, ex, s->b.scene, f->v, id, box, &s->cfg.mt,
                             &f->st->occlusion_tests))
        return;
    f->out[f->k++] = id;
    sl_occ_rect r;
    if (ex && f->status == SL_OK && sl_occ_project_box(f->v, box, &r) == SL_OCC_RECT &&
        (uint64_t)(r.x1 - r.x0) * (uint64_t)(r.y1 - r.y0) <= s->cfg.exact_px)
        f->status = sl_occ_exact_draw(ex, s->b.scene, id, &r, f->err);
    if (f->s->cfg.render_visible)
        maybe_render(f, id);
}

static sl_status hzb_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    hzb_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, view);
    sl_status st = sl_occ_raster_begin(&s->r, &v, err);
    if (st == SL_OK && s->cfg.far_layer)
        st = sl_occ_raster_begin(&s->far, &v, err);
    if (st == SL_OK && s->cfg.pyramid)
        st = sl_occ_pyramid_size(&s->pyr, &s->b.alloc, s->r.ctx, v.width, v.height, NULL, err);
    if (st == SL_OK && s->cfg.exact_px)
        st = sl_occ_exact_begin(&s->ex, &v, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "hzb");
        return st;
    }
    s->pyr_valid = false;
    /* 1. the chosen occluders */
    uint32_t np = sl_occ_base_select(&s->b, &v, &s->cfg.c, &stats->nodes_visited);
    double t1 = sl_now();
    sl_occ_raster_render(&s->r, s->b.occ, &v, s->b.pick_ids, np);
    if (s->cfg.pyramid)
        build_pyramid(s);
    double t2 = sl_now();
    /* 2. front-to-back traversal */
    frame_ctx f = {s, &v, stats, 0, out, 0, SL_OK, err};
    sl_occ_walk w = {skip, visit, &f, NULL, 0};
    uint64_t tested = 0;
    uint64_t visited = sl_occ_walk_bvh(s->b.bvh, &v, &w, &tested);
    uint32_t k = f.k;
    if (f.status != SL_OK) {
        sl_error_prefix(err, "hzb");
        return f.status;
    }
    double t3 = sl_now();
    sl_cull_sort_ids(out, k, s->b.sort_scratch);
    double t4 = sl_now();
    stats->nodes_visited += visited;
    stats->objects_tested = tested;
    stats->queries = s->r.queries + s->far.queries;
    stats->pixel_queries = s->r.pixel_queries + s->far.pixel_queries + s->ex.pixel_tests;
    sl_cull_phase(stats, "select", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "render", sl_cull_ms(t1, t2));
    sl_cull_phase(stats, "traverse", sl_cull_ms(t2, t3));
    sl_cull_phase(stats, "sort", sl_cull_ms(t3, t4));
    *count = k;
    if (s->cfg.far_layer)
        (void)sl_occ_raster_end(&s->far, NULL, NULL); /* counts the frame; it has no debug outputs */
    sl_occ_levels lv = sl_occ_pyramid_levels(&s->pyr, false);
    if ((st = sl_occ_raster_end(&s->r, s->cfg.pyramid && s->pyr_valid ? &lv : NULL, err)) != SL_OK)
        sl_error_prefix(err, "hzb");
    return st;
}

const sl_cull_method sl_cull_method_hzb = {
    .name = "hzb",
    .suits = "any scene with occluders: building footprints, occluder meshes (Quake III maps, the city) or all_objects=true",
    .summary = "hierarchical z-buffer: quality-selected occluder proxies plus the visible objects' proxies "
               "rendered front to back into the conservative rasterizer, boxes tested through a max-depth "
               "pyramid (Greene, Kass & Miller 1993)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .res_culling = true,
    .depth = SL_DEPTH_CLIP_Z,
    .config_size = sizeof(hzb_config),
    .configure = hzb_configure,
    .create_with = hzb_create,
    .cull = hzb_cull,
    .scene_changed = hzb_scene_changed,
    .destroy = hzb_destroy,
    .applicable = sl_occ_applicable,
};

/* lazygrid, lazygrid-z, busygrid: the lazy occlusion grid of Hey, Tobler & Purgathofer,
 * "Real-Time Occlusion Culling With A Lazy Occlusion Grid" (TR 2001): sections 3.1 (occlusion-
 * buffer variant, Fig. 2), 3.2 (z-buffer variant, Fig. 3), 4 (front-to-back traversals, Figs. 4-6)
 * and 7 (the busy update it is compared with).
 *
 * The screen is a flat grid of cells (`cell` pixels square, default 32). A BVH node or object box
 * is tested through the cells its screen rectangle overlaps, internal cells (wholly inside the
 * rectangle) before border cells, cell summaries before pixel-level queries, and stops at the
 * first free cell. Pixel queries read the conservative rasterizer (raster.h); the "drawn" objects
 * are the occluder proxies of the objects found visible (occlusion/proxies.h), rendered into it.
 *
 *  lazygrid    occlusion-buffer variant: cells are COMPLETELY_FREE, PARTIALLY_FREE or OUTDATED with
 *              an overriding `full` flag; a pixel query asks "is every pixel of this rectangle
 *              covered?" (sl_raster_test_rect at depth 0). Coverage alone is enough because of the
 *              traversal: a test-list of untested boxes by nearest eye depth and a draw-list of
 *              visible objects by farthest eye depth; the smaller head goes first (a tie tests
 *              first), so everything drawn lies entirely in front of every box tested later.
 *              Drawing marks the cells of the object's rectangle OUTDATED (full cells stay full).
 *  busygrid    the same test with the busy update: after each draw every cell of the rectangle is
 *              queried at once (full or partially free). Same decisions, more pixel queries.
 *  lazygrid-z  z-buffer variant: each cell keeps a lower bound of its farthest depth (0: free) and
 *              an outdated flag; a box is hidden in a cell when its nearest depth is farther than
 *              that bound. The lazy update recomputes the bound of an outdated internal cell by
 *              bisecting test_rect over the depth's float bits (every bound it finds is proven by a
 *              query, so it never exceeds the truth). One priority list by nearest depth suffices.
 * An object whose box passes is also tested by its own triangles (sl_occ_object_hidden: options
 * mesh_test, sample_tris, sample_px, as in hzb) before it is reported and drawn; the rasterizer
 * holds true depths in every variant, so that depth test is valid at any point of the traversal.
 * Per frame, `queries` counts the cell-level pixel queries (what the paper's Fig. 8 reports) and
 * `pixel_queries` the pixels they read. Conservative at any resolution (res=any, the default:
 * occluders by inner coverage, no pixel-centre test); res=culling draws them at pixel centres and
 * allows sample_tris (default 64 there): conservative at the culling resolution only. */
#include "cull/occlusion/base.h"
#include "cull/occlusion/object_tests.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/select.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion_debug.h"

#include <math.h>

typedef enum lg_variant { LG_LAZY = 0, LG_Z = 1, LG_BUSY = 2 } lg_variant;

typedef struct lg_config {
    sl_occ_common c;
    uint32_t variant;
    uint32_t cell;
    sl_occ_mesh_tests mt;       /* an object whose box passes may still be hidden by its triangles */
} lg_config;

enum { CELL_FREE = 0, CELL_PARTIAL = 1, CELL_OUTDATED = 2 };

typedef struct lg_item {
    float key;
    uint32_t item;              /* node slot, or SL_LG_OBJECT | object slot */
} lg_item;

#define SL_LG_OBJECT 0x80000000u

typedef struct lg_heap {
    lg_item *a;
    uint32_t n, cap;
} lg_heap;

typedef struct lg_state {
    sl_occ_base b;                /* BVH, proxies (no selection) */
    lg_config cfg;
    sl_occ_raster r;
    lg_heap test, draw;
    /* the grid */
    uint32_t gw, gh, grid_cap, sw, sh;
    uint8_t *state, *full, *outdated;
    float *bmin;
    uint32_t *int_list, *bord_list;
    uint64_t cell_queries;
    float *dump_grid;             /* the grid as an image, on the debug frame only */
} lg_state;

static const char g_help[] =
    "cell=8..512 (default 32): edge of a grid cell in pixels\n" SL_OCC_HELP_RES SL_OCC_HELP_RASTER
    "min_quality=NUMBER (default 0.0005): least Coorg-Teller quality (sr) of a visible object drawn as an occluder\n"
    "inset=0.01..10 (default 0.01 with res=any and inner=hull, raised where float rounding needs more; else 0.1): "
    "metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n" SL_OCC_HELP_MESH_TESTS SL_OCC_HELP_DEBUG;

static sl_status configure(sl_opts *o, lg_config *c, lg_variant v, sl_cull_guarantee *g, sl_error *err)
{
    sl_status st;
    c->variant = v;
    if ((st = sl_opts_u32(o, "cell", 32, 8, 512, &c->cell, err)) != SL_OK ||
        (st = sl_occ_configure_common(o, SL_OCC_OPT_RASTER | SL_OCC_OPT_DEBUG | SL_OCC_OPT_RES | SL_OCC_OPT_THIN_INSET,
                                      0, 0, &c->c, err)) != SL_OK ||
        (st = sl_opts_float(o, "min_quality", 0.0005f, 0.0f, 100.0f, &c->c.min_quality, err)) != SL_OK ||
        (st = sl_occ_configure_mesh_tests(o, &c->c, &c->mt, err)) != SL_OK)
        return st;
    *g = sl_occ_res_guarantee(&c->c);
    return SL_OK;
}

static sl_status lazy_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure(o, config, LG_LAZY, g, err);
}
static sl_status z_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure(o, config, LG_Z, g, err);
}
static sl_status busy_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure(o, config, LG_BUSY, g, err);
}

static void free_grid(lg_state *s)
{
    const sl_allocator *a = &s->b.alloc;
    size_t n = s->grid_cap;
    sl_free(a, s->state, n);
    sl_free(a, s->full, n);
    sl_free(a, s->outdated, n);
    sl_free(a, s->bmin, n * sizeof(float));
    sl_free(a, s->int_list, n * sizeof(uint32_t));
    sl_free(a, s->bord_list, n * sizeof(uint32_t));
    s->state = s->full = s->outdated = NULL;
    s->bmin = NULL;
    s->int_list = s->bord_list = NULL;
    s->grid_cap = 0;
}

static void lg_destroy(void *state)
{
    lg_state *s = state;
    if (!s)
        return;
    sl_allocator a = s->b.alloc;
    sl_occ_raster_free(&s->r);
    sl_free(&a, s->test.a, (size_t)(s->test.cap ? s->test.cap : 1) * sizeof(lg_item));
    sl_free(&a, s->draw.a, (size_t)(s->draw.cap ? s->draw.cap : 1) * sizeof(lg_item));
    free_grid(s);
    sl_occ_base_free(&s->b);
    sl_free(&a, s, sizeof *s);
}

/* Heaps hold every node slot and object once at most. */
static sl_status size_heaps(lg_state *s, sl_error *err)
{
    uint32_t need = s->b.bvh->node_slots + s->b.object_count + 1;
    if (s->test.cap >= need)
        return SL_OK;
    sl_free(&s->b.alloc, s->test.a, (size_t)(s->test.cap ? s->test.cap : 1) * sizeof(lg_item));
    s->test.a = sl_alloc(&s->b.alloc, (size_t)need * sizeof(lg_item));
    s->test.cap = s->test.a ? need : 0;
    if (!s->test.a)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for the test list");
    return SL_OK;
}

static const char *const g_names[] = {"lazygrid", "lazygrid-z", "busygrid"};

static sl_status lg_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                           const sl_allocator *alloc, void **state, sl_error *err)
{
    lg_state *s = sl_calloc(alloc, 1, sizeof *s);
    const lg_config *cfg = config;
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", g_names[cfg->variant]);
    s->cfg = *cfg;
    sl_status st = sl_occ_base_init(&s->b, scene, g_names[cfg->variant], &s->cfg.c, false, 0, false, extras, alloc, err);
    if (st != SL_OK) {
        sl_free(alloc, s, sizeof *s);
        return st;
    }
    st = sl_occ_raster_init(&s->r, &s->cfg.c, s->b.occ, alloc, err);
    if (st == SL_OK)
        st = size_heaps(s, err);
    if (st == SL_OK) {
        size_t n = s->b.object_count ? s->b.object_count : 1;
        s->draw.a = sl_alloc(alloc, n * sizeof(lg_item));
        s->draw.cap = s->draw.a ? (uint32_t)n : 0;
        if (!s->draw.a)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", g_names[cfg->variant]);
        lg_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status lg_scene_changed(void *state, sl_error *err)
{
    lg_state *s = state;
    sl_status st = sl_occ_base_scene_changed(&s->b, err);
    if (st == SL_OK && (st = size_heaps(s, err)) != SL_OK)
        sl_error_prefix(err, "%s", g_names[s->cfg.variant]);
    return st;
}

/* ---- heaps (min by key; ties by item for determinism) ---- */

static inline bool less(lg_item a, lg_item b) { return a.key < b.key || (a.key == b.key && a.item < b.item); }

static void heap_push(lg_heap *h, float key, uint32_t item)
{
    lg_item x = {key, item};
    uint32_t i = h->n++;
    while (i > 0 && less(x, h->a[(i - 1) / 2])) {
        h->a[i] = h->a[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h->a[i] = x;
}

static lg_item heap_pop(lg_heap *h)
{
    lg_item top = h->a[0], x = h->a[--h->n];
    uint32_t i = 0, n = h->n;
    for (;;) {
        uint32_t l = 2 * i + 1, r = l + 1, m = i;
        lg_item mv = x;
        if (l < n && less(h->a[l], mv))
            m = l, mv = h->a[l];
        if (r < n && less(h->a[r], mv))
            m = r;
        if (m == i)
            break;
        h->a[i] = h->a[m];
        i = m;
    }
    if (n)
        h->a[i] = x;
    return top;
}

/* ---- the grid ---- */

static sl_status size_grid(lg_state *s, uint32_t w, uint32_t h, sl_error *err)
{
    uint32_t gw = (w + s->cfg.cell - 1) / s->cfg.cell, gh = (h + s->cfg.cell - 1) / s->cfg.cell;
    size_t n = (size_t)gw * gh;
    if (n > s->grid_cap) {
        free_grid(s);
        const sl_allocator *a = &s->b.alloc;
        s->state = sl_alloc(a, n);
        s->full = sl_alloc(a, n);
        s->outdated = sl_alloc(a, n);
        s->bmin = sl_alloc(a, n * sizeof(float));
        s->int_list = sl_alloc(a, n * sizeof(uint32_t));
        s->bord_list = sl_alloc(a, n * sizeof(uint32_t));
        s->grid_cap = n;
        if (!s->state || !s->full || !s->outdated || !s->bmin || !s->int_list || !s->bord_list) {
            free_grid(s);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for a %ux%u grid", gw, gh);
        }
    }
    s->gw = gw;
    s->gh = gh;
    s->sw = w;
    s->sh = h;
    memset(s->state, CELL_FREE, n);
    memset(s->full, 0, n);
    memset(s->outdated, 0, n);
    for (size_t i = 0; i < n; i++)
        s->bmin[i] = 0.0f;
    return SL_OK;
}

/* Pixel rectangle of cell (cx, cy), clipped to the screen. */
static inline void cell_rect(const lg_state *s, uint32_t cx, uint32_t cy, int32_t *x0, int32_t *y0, int32_t *x1,
                             int32_t *y1)
{
    uint32_t c = s->cfg.cell;
    *x0 = (int32_t)(cx * c);
    *y0 = (int32_t)(cy * c);
    *x1 = (int32_t)SL_MIN((cx + 1) * c, s->sw);
    *y1 = (int32_t)SL_MIN((cy + 1) * c, s->sh);
}

/* A pixel query through the rasterizer (counted as one cell-level query). */
static inline sl_raster_result query(lg_state *s, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d)
{
    s->cell_queries++;
    return sl_occ_raster_test(&s->r, x0, y0, x1, y1, d);
}

/* Lazy update of the z variant: the largest depth the query proves every pixel of the cell
 * farther... i.e. nearer than (B(p) > bound for all p), found by bisection over the float bits. */
static float cell_bound(lg_state *s, uint32_t cx, uint32_t cy)
{
    int32_t x0, y0, x1, y1;
    cell_rect(s, cx, cy, &x0, &y0, &x1, &y1);
    if (query(s, x0, y0, x1, y1, 0.0f) != SL_RASTER_OCCLUDED)
        return 0.0f; /* some pixel is still empty */
    uint32_t lo = 0, hi = 0x7f800000u; /* bits of 0 (proven) and +inf (never proven) */
    for (int step = 0; step < 20 && hi - lo > 1; step++) {
        uint32_t mid = lo + (hi - lo) / 2;
        float m;
        memcpy(&m, &mid, 4);
        if (query(s, x0, y0, x1, y1, m) == SL_RASTER_OCCLUDED)
            lo = mid;
        else
            hi = mid;
    }
    float b;
    memcpy(&b, &lo, 4);
    return b;
}

/* Is every pixel of the cell covered (the busy update and the occlusion-buffer lazy update)? */
static bool cell_full(lg_state *s, uint32_t cx, uint32_t cy)
{
    int32_t x0, y0, x1, y1;
    cell_rect(s, cx, cy, &x0, &y0, &x1, &y1);
    return query(s, x0, y0, x1, y1, 0.0f) == SL_RASTER_OCCLUDED;
}

/* Fig. 2 (occlusion-buffer variant): true when the rectangle is covered in every cell. */
static bool occluded_obuf(lg_state *s, const sl_occ_rect *r)
{
    uint32_t c = s->cfg.cell, ni = 0, nb = 0;
    uint32_t cx0 = (uint32_t)r->x0 / c, cx1 = (uint32_t)(r->x1 - 1) / c;
    uint32_t cy0 = (uint32_t)r->y0 / c, cy1 = (uint32_t)(r->y1 - 1) / c;
    /* internal cells without pixel queries */
    for (uint32_t cy = cy0; cy <= cy1; cy++)
        for (uint32_t cx = cx0; cx <= cx1; cx++) {
            int32_t x0, y0, x1, y1;
            cell_rect(s, cx, cy, &x0, &y0, &x1, &y1);
            uint32_t i = cy * s->gw + cx;
            bool internal = x0 >= r->x0 && x1 <= r->x1 && y0 >= r->y0 && y1 <= r->y1;
            if (s->full[i])
                continue;
            if (internal) {
                if (s->state[i] != CELL_OUTDATED)
                    return false;
                s->int_list[ni++] = i;
            } else {
                s->bord_list[nb++] = i;
            }
        }
    /* border cells without pixel queries */
    for (uint32_t k = 0; k < nb; k++)
        if (s->state[s->bord_list[k]] == CELL_FREE)
            return false;
    /* internal cells with pixel queries: the lazy update */
    for (uint32_t k = 0; k < ni; k++) {
        uint32_t i = s->int_list[k];
        if (cell_full(s, i % s->gw, i / s->gw)) {
            s->full[i] = 1;
        } else {
            s->state[i] = CELL_PARTIAL;
            return false;
        }
    }
    /* border cells with pixel queries over their part of the rectangle (never sets full) */
    for (uint32_t k = 0; k < nb; k++) {
        uint32_t i = s->bord_list[k];
        int32_t x0, y0, x1, y1;
        cell_rect(s, i % s->gw, i / s->gw, &x0, &y0, &x1, &y1);
        x0 = SL_MAX(x0, r->x0), y0 = SL_MAX(y0, r->y0), x1 = SL_MIN(x1, r->x1), y1 = SL_MIN(y1, r->y1);
        if (query(s, x0, y0, x1, y1, 0.0f) != SL_RASTER_OCCLUDED) {
            s->state[i] = CELL_PARTIAL;
            return false;
        }
    }
    return true;
}

/* Fig. 3 (z-buffer variant): true when the box's nearest depth is farther than the buffer in
 * every cell. A box is visible in a cell when dnear >= the cell's bound (the bound is a lower
 * bound of every pixel's depth, and a query hides only strictly nearer buffer depths). */
static bool occluded_z(lg_state *s, const sl_occ_rect *r)
{
    uint32_t c = s->cfg.cell, ni = 0, nb = 0;
    uint32_t cx0 = (uint32_t)r->x0 / c, cx1 = (uint32_t)(r->x1 - 1) / c;
    uint32_t cy0 = (uint32_t)r->y0 / c, cy1 = (uint32_t)(r->y1 - 1) / c;
    float d = r->dnear;
    for (uint32_t cy = cy0; cy <= cy1; cy++)
        for (uint32_t cx = cx0; cx <= cx1; cx++) {
            int32_t x0, y0, x1, y1;
            cell_rect(s, cx, cy, &x0, &y0, &x1, &y1);
            uint32_t i = cy * s->gw + cx;
            bool internal = x0 >= r->x0 && x1 <= r->x1 && y0 >= r->y0 && y1 <= r->y1;
            if (internal) {
                if (!(d < s->bmin[i])) {
                    if (!s->outdated[i])
                        return false;
                    s->int_list[ni++] = i;
                }
            } else {
                s->bord_list[nb++] = i;
            }
        }
    for (uint32_t k = 0; k < nb; k++) {
        uint32_t i = s->bord_list[k];
        if (s->bmin[i] == 0.0f && !s->outdated[i])
            return false;
    }
    for (uint32_t k = 0; k < ni; k++) {
        uint32_t i = s->int_list[k];
        s->outdated[i] = 0;
        s->bmin[i] = cell_bound(s, i % s->gw, i / s->gw);
        if (!(d < s->bmin[i]))
            return false;
    }
    for (uint32_t k = 0; k < nb; k++) {
        uint32_t i = s->bord_list[k];
        if (d < s->bmin[i])
            continue; /* the (possibly stale) bound already hides it: still a proven bound */
        int32_t x0, y0, x1, y1;
        cell_rect(s, i % s->gw, i / s->gw, &x0, &y0, &x1, &y1);
        x0 = SL_MAX(x0, r->x0), y0 = SL_MAX(y0, r->y0), x1 = SL_MIN(x1, r->x1), y1 = SL_MIN(y1, r->y1);
        if (query(s, x0, y0, x1, y1, d) != SL_RASTER_OCCLUDED)
            return false;
    }
    return true;
}

/* After drawing into rectangle r: flag its cells (lazy) or recompute them (busy). */
static void mark_drawn(lg_state *s, const sl_occ_rect *r)
{
    uint32_t c = s->cfg.cell;
    uint32_t cx0 = (uint32_t)r->x0 / c, cx1 = (uint32_t)(r->x1 - 1) / c;
    uint32_t cy0 = (uint32_t)r->y0 / c, cy1 = (uint32_t)(r->y1 - 1) / c;
    for (uint32_t cy = cy0; cy <= cy1; cy++)
        for (uint32_t cx = cx0; cx <= cx1; cx++) {
            uint32_t i = cy * s->gw + cx;
            if (s->cfg.variant == LG_Z) {
                s->outdated[i] = 1;
            } else if (!s->full[i]) {
                if (s->cfg.variant == LG_BUSY) {
                    if (cell_full(s, cx, cy))
                        s->full[i] = 1;
                    else
                        s->state[i] = CELL_PARTIAL;
                } else {
                    s->state[i] = CELL_OUTDATED;
                }
            }
        }
}

/* Draw object `id`'s proxy (if it has a usable one of sufficient quality). */
static void draw(lg_state *s, const sl_occ_view *v, uint32_t id)
{
    uint32_t p = s->b.occ->object_proxy[id];
    if (p == SL_NONE || !sl_occ_usable(s->b.occ, p, v) || sl_occ_quality(s->b.occ, p, v) < s->cfg.c.min_quality)
        return;
    if (!sl_occ_raster_render(&s->r, s->b.occ, v, &p, 1))
        return;
    sl_aabb b = sl_occ_proxy_box(s->b.occ, &s->b.occ->proxies[p]);
    sl_occ_rect r;
    int k = sl_occ_project_box(v, &b, &r);
    if (k == SL_OCC_OUT)
        return;
    mark_drawn(s, &r); /* SL_OCC_NEAR: the whole screen */
}

static bool drawable(const lg_state *s, const sl_occ_view *v, uint32_t id)
{
    uint32_t p = s->b.occ->object_proxy[id];
    return p != SL_NONE && sl_occ_usable(s->b.occ, p, v) && sl_occ_quality(s->b.occ, p, v) >= s->cfg.c.min_quality;
}

static sl_status lg_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                         sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    lg_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, view);
    sl_status st = sl_occ_raster_begin(&s->r, &v, err);
    if (st == SL_OK)
        st = size_grid(s, v.width, v.height, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", g_names[s->cfg.variant]);
        return st;
    }
    s->cell_queries = 0;
    const struct sl_bvh_t *b = s->b.bvh;
    uint32_t k = 0;
    uint64_t visited = 0, tested = 0, otests = 0;
    s->test.n = s->draw.n = 0;
    bool obuf = s->cfg.variant != LG_Z;
    if (b->node_slots) {
        float zmin, zmax;
        sl_occ_box_zrange(&v, &b->nodes[0].box, &zmin, &zmax);
        heap_push(&s->test, zmin, 0);
    }
    while (s->test.n) { /* objects still waiting to be drawn when no test remains are not drawn */
        /* the occlusion-buffer variant draws an object only when it lies wholly in front of
         * every box still to be tested; a tie tests first */
        if (s->draw.n && (!s->test.n || s->draw.a[0].key < s->test.a[0].key)) {
            lg_item it = heap_pop(&s->draw);
            draw(s, &v, b->objects[it.item]);
            continue;
        }
        lg_item it = heap_pop(&s->test);
        bool is_object = (it.item & SL_LG_OBJECT) != 0;
        uint32_t slot = it.item & ~SL_LG_OBJECT;
        const sl_aabb *box = is_object ? &b->object_bounds[slot] : &b->nodes[slot].box;
        if (is_object)
            tested++;
        else
            visited++;
        if (sl_occ_frustum_classify(&v, box, 0x3f) < 0)
            continue;
        sl_occ_rect r;
        int pk = sl_occ_project_box(&v, box, &r);
        if (pk == SL_OCC_OUT)
            continue;
        if (pk == SL_OCC_RECT) {
            otests++;
            if (obuf ? occluded_obuf(s, &r) : occluded_z(s, &r))
                continue;
        }
        if (is_object) {
            uint32_t id = b->objects[slot];
            /* the rasterizer holds true depths whatever the variant: a depth test of the object's
             * own triangles is valid at any point of the traversal */
            sl_occ_raster *layer = &s->r;
            if (pk == SL_OCC_RECT && sl_occ_object_hidden(&layer, 1, NULL, s->b.scene, &v, id, box, &s->cfg.mt, &otests))
                continue;
            out[k++] = id;
            if (obuf) {
                if (drawable(s, &v, id)) {
                    float zmin, zmax;
                    sl_occ_box_zrange(&v, box, &zmin, &zmax);
                    heap_push(&s->draw, zmax, slot);
                }
            } else {
                draw(s, &v, id);
            }
            continue;
        }
        const sl_bvh_node *n = &b->nodes[slot];
        if (n->count == 0) {
            for (uint32_t c = 0; c < 2; c++) {
                float zmin, zmax;
                sl_occ_box_zrange(&v, &b->nodes[n->first + c].box, &zmin, &zmax);
                heap_push(&s->test, zmin, n->first + c);
            }
        } else {
            for (uint32_t j = n->first; j < n->first + n->count; j++) {
                float zmin, zmax;
                sl_occ_box_zrange(&v, &b->object_bounds[j], &zmin, &zmax);
                heap_push(&s->test, zmin, SL_LG_OBJECT | j);
            }
        }
    }
    double t1 = sl_now();
    sl_cull_sort_ids(out, k, s->b.sort_scratch);
    double t2 = sl_now();
    stats->nodes_visited = visited;
    stats->objects_tested = tested;
    stats->occlusion_tests = otests;
    stats->queries = s->cell_queries;
    stats->pixel_queries = s->r.pixel_queries;
    sl_cull_phase(stats, "traverse", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "sort", sl_cull_ms(t1, t2));
    *count = k;
    /* the debug frame's dump shows the grid: cell bounds (z variant) or states (full 1, partially
     * free 0.5, outdated 0.25, free 0) */
    sl_occ_levels lv = {0, NULL, NULL, NULL, false};
    const float *grid_ptr[1];
    uint32_t gw[1] = {s->gw}, gh[1] = {s->gh};
    size_t cells = (size_t)s->gw * s->gh;
    if (s->r.dump && s->r.frame == s->r.debug_frame) {
        s->dump_grid = sl_alloc(&s->b.alloc, (cells ? cells : 1) * sizeof(float));
        if (s->dump_grid) {
            for (size_t i = 0; i < cells; i++)
                s->dump_grid[i] = s->cfg.variant == LG_Z ? s->bmin[i]
                                  : s->full[i]           ? 1.0f
                                  : s->state[i] == CELL_PARTIAL ? 0.5f
                                  : s->state[i] == CELL_OUTDATED ? 0.25f
                                                                  : 0.0f;
            grid_ptr[0] = s->dump_grid;
            lv = (sl_occ_levels){1, grid_ptr, gw, gh, s->cfg.variant != LG_Z};
        }
    }
    st = sl_occ_raster_end(&s->r, lv.count ? &lv : NULL, err);
    sl_free(&s->b.alloc, s->dump_grid, (cells ? cells : 1) * sizeof(float));
    s->dump_grid = NULL;
    if (st != SL_OK)
        sl_error_prefix(err, "%s", g_names[s->cfg.variant]);
    return st;
}

#define LG_METHOD(NAME, STR, CONF, SUMMARY)                                                                            \
    const sl_cull_method sl_cull_method_##NAME = {                                                                     \
        .name = STR,                                                                                                   \
        .suits = "any scene with occluders: building footprints, occluder meshes (Quake III maps, the city) or all_objects=true",                                                                                                 \
        .summary = SUMMARY,                                                                                            \
        .options_help = g_help,                                                                                        \
        .guarantee = SL_CONSERVATIVE,                                                                                  \
        .res_culling = true,                                                                                           \
        .depth = SL_DEPTH_INV_W,                                                                                       \
        .config_size = sizeof(lg_config),                                                                              \
        .configure = CONF,                                                                                             \
        .create_with = lg_create,                                                                                           \
        .cull = lg_cull,                                                                                               \
        .scene_changed = lg_scene_changed,                                                                             \
        .destroy = lg_destroy,                                                                                         \
        .applicable = sl_occ_applicable,                                                                               \
    };

LG_METHOD(lazygrid, "lazygrid", lazy_configure,
          "lazy occlusion grid, occlusion-buffer variant: screen cells updated only when a test needs them, test "
          "and draw lists by nearest and farthest depth (Hey, Tobler & Purgathofer 2001)")
LG_METHOD(lazygrid_z, "lazygrid-z", z_configure,
          "lazy occlusion grid, z-buffer variant: per-cell farthest depth updated lazily, one front-to-back list "
          "(Hey, Tobler & Purgathofer 2001)")
LG_METHOD(busygrid, "busygrid", busy_configure,
          "occlusion grid with the busy update (every cell under a drawn object queried at once): the baseline of "
          "Hey, Tobler & Purgathofer 2001")

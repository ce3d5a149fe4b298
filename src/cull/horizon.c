/* horizon: object-space occlusion horizon in polar coordinates around the eye, built front to back
 * over the scene grid.
 *
 * T. Downs, T. Moeller, C. Sequin, "Occlusion Horizons for Driving through Urban Scenery", I3D
 * 2001 (the front-to-back sweep over a max-height quadtree, the horizon in a binary tree with min
 * and max per node); G. Koldaş, PhD thesis, METU 2008, §3.1.2 (the horizon in object space, as
 * elevation over azimuth around the eye, which makes it independent of pitch and roll and lets it
 * cover 360 degrees).
 *
 * The sweep pops pyramid nodes (2x2 groups of grid cells, level by level) in order of their
 * nearest plan distance d. Before a node is tested, every occluder piece whose farthest point is
 * at most d away has been inserted into the horizon, and nothing farther: so whatever the node
 * holds lies behind every inserted occluder in its direction. A node whose highest point (at its
 * nearest distance) is below the horizon over its whole azimuth range, and whose lowest point is
 * above the bottom of the occluders that made that horizon, is hidden with everything in it (its
 * occluders too, whose shadows therefore add nothing). A visible grid cell has its objects tested
 * (the whole box when none of it is nearer than the cell, else the part of the box in the cell;
 * an object is reported when any part of it is visible) and its occluder pieces queued for
 * insertion at their farthest distance. Occluder pieces are the façade top edges of the
 * footprints clipped to the cells (urban_internal.h says which are used).
 *
 * dhorizon (dhorizon.c) runs this same sweep with one more way to skip a node: see there. */
#include "urban_internal.h"

#include <float.h>

static const char g_help[] =
    "cell=NUMBER (default 16): scene-grid cell size in metres (0.5..1000)\n"
    "bins=1024..1048576 (default 8192): azimuth bins of the horizon (rounded up to a power of two)\n";

typedef struct horizon_config {
    float cell;
    uint32_t bins;
} horizon_config;

static sl_status horizon_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    horizon_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_float(o, "cell", 16.0f, 0.5f, 1000.0f, &c->cell, err)) != SL_OK ||
        (st = sl_opts_u32(o, "bins", 8192, 1024, 1u << 20, &c->bins, err)) != SL_OK)
        return st;
    return SL_OK;
}

/* ---- the sweep ---- */

void sl_urban_sweep_destroy(sl_urban_sweep *s)
{
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    size_t no = s->us.object_count ? s->us.object_count : 1;
    sl_free(a, s->obj_stamp, no * sizeof(uint32_t));
    sl_free(a, s->sort_scratch, no * sizeof(uint32_t));
    sl_free(a, s->fp_excluded, (s->us.fp_count ? s->us.fp_count : 1) * sizeof(uint32_t));
    sl_free(a, s->modes.frame, (s->us.edge_count ? s->us.edge_count : 1) * sizeof(uint32_t));
    sl_free(a, s->modes.mode, s->us.edge_count ? s->us.edge_count : 1);
    sl_free(a, s->front[0], (s->us.node_count ? s->us.node_count : 1) * sizeof(uint32_t));
    sl_free(a, s->front[1], (s->us.node_count ? s->us.node_count : 1) * sizeof(uint32_t));
    sl_free(a, s->span_x0, (s->us.ny ? s->us.ny : 1) * sizeof(int32_t));
    sl_free(a, s->span_x1, (s->us.ny ? s->us.ny : 1) * sizeof(int32_t));
    sl_urban_heap_free(&s->nodes, a);
    sl_urban_heap_free(&s->pieces, a);
    sl_horizon_free(&s->hz[0]);
    sl_horizon_free(&s->hz[1]);
    sl_urban_scene_free(&s->us);
    sl_free(a, s, sizeof *s);
}

sl_status sl_urban_sweep_create(sl_scene scene, float cell, uint32_t bins, bool record, const sl_allocator *alloc,
                                sl_urban_sweep **out, sl_error *err)
{
    sl_urban_sweep *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "horizon: out of memory");
    s->alloc = *alloc;
    const sl_allocator *a = &s->alloc;
    sl_status st = sl_urban_scene_build(scene, cell, a, &s->us, err);
    if (st != SL_OK) {
        sl_free(a, s, sizeof *s);
        return st;
    }
    size_t no = s->us.object_count ? s->us.object_count : 1;
    s->obj_stamp = sl_calloc(a, no, sizeof(uint32_t));
    s->sort_scratch = sl_alloc(a, no * sizeof(uint32_t));
    s->fp_excluded = sl_calloc(a, s->us.fp_count ? s->us.fp_count : 1, sizeof(uint32_t));
    s->modes.frame = sl_calloc(a, s->us.edge_count ? s->us.edge_count : 1, sizeof(uint32_t));
    s->modes.mode = sl_calloc(a, s->us.edge_count ? s->us.edge_count : 1, 1);
    if (record) {
        s->front[0] = sl_alloc(a, (s->us.node_count ? s->us.node_count : 1) * sizeof(uint32_t));
        s->front[1] = sl_alloc(a, (s->us.node_count ? s->us.node_count : 1) * sizeof(uint32_t));
    }
    s->span_x0 = sl_alloc(a, (s->us.ny ? s->us.ny : 1) * sizeof(int32_t));
    s->span_x1 = sl_alloc(a, (s->us.ny ? s->us.ny : 1) * sizeof(int32_t));
    if (!s->obj_stamp || !s->sort_scratch || !s->fp_excluded || !s->span_x0 || !s->span_x1 || !s->modes.frame ||
        !s->modes.mode ||
        (record && (!s->front[0] || !s->front[1])))
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "horizon: out of memory for %zu objects", no);
    if (st == SL_OK && s->us.node_count >= (1u << 30))
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "horizon: the grid has too many cells (%u pyramid nodes)",
                     s->us.node_count);
    if (st == SL_OK)
        st = sl_urban_heap_init(&s->nodes, s->us.node_count, a, err);
    if (st == SL_OK)
        st = sl_urban_heap_init(&s->pieces, s->us.piece_count, a, err);
    if (st == SL_OK)
        st = sl_horizon_init(&s->hz[0], bins, record, a, err);
    if (st == SL_OK)
        st = sl_horizon_init(&s->hz[1], bins, record, a, err);
    if (st != SL_OK) {
        sl_urban_sweep_destroy(s);
        return st;
    }
    *out = s;
    return SL_OK;
}

/* Level of node id. */
static inline uint32_t node_level(const sl_urban_scene *u, uint32_t id)
{
    uint32_t l = 0; /* the bases increase with the level: count those at most id (no branch) */
    for (uint32_t k = 1; k < u->levels; k++)
        l += id >= u->level_base[k];
    return l;
}

/* Plan rectangle of a node, grown by the rounding margin. */
static inline void node_rect(const sl_urban_scene *u, uint32_t l, uint32_t i, uint32_t j, double r[4])
{
    uint32_t ci0 = i << l, cj0 = j << l;
    uint32_t ci1 = SL_MIN((i + 1) << l, u->nx), cj1 = SL_MIN((j + 1) << l, u->ny);
    r[0] = u->min_x + ci0 * u->cell - u->margin;
    r[1] = u->min_y + cj0 * u->cell - u->margin;
    r[2] = u->min_x + ci1 * u->cell + u->margin;
    r[3] = u->min_y + cj1 * u->cell + u->margin;
}

/* Heap keys: floats at most (at least) the distance. */
static inline float key_down(double d)
{
    float f = (float)d;
    if ((double)f > d)
        f -= fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

static inline float key_up(double d)
{
    float f = (float)d;
    if ((double)f < d)
        f += fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

/* Record where the sweep left a node (dhorizon's frontier). */
static inline void front_add(sl_urban_sweep *s, uint32_t id, uint32_t kind)
{
    if (s->incremental)
        s->front[s->cur][s->front_count[s->cur]++] = SL_FRONT_ENTRY(id, kind);
}

/* Append a node keyed by its nearest plan distance to the heap's entries (sl_urban_heap_build
 * makes them a heap). */
static void append_node(sl_urban_sweep *s, const sl_urban_view *v, uint32_t id, uint32_t kind)
{
    const sl_urban_scene *u = &s->us;
    uint32_t l = node_level(u, id);
    uint32_t lnx = u->level_nx[l], i = (id - u->level_base[l]) % lnx, j = (id - u->level_base[l]) / lnx;
    double r[4], dmin, dmax;
    node_rect(u, l, i, j, r);
    sl_urban_rect_dist(v->eye, r[0], r[1], r[2], r[3], &dmin, &dmax);
    if (s->nodes.n == s->nodes.cap)
        return; /* cannot happen: the frontier's nodes are disjoint */
    s->nodes.key[s->nodes.n] = key_down(dmin);
    s->nodes.val[s->nodes.n++] = SL_FRONT_ENTRY(id, kind);
}

/* Test (the part in the cell of) object o; report it when visible. */
static void test_object(sl_urban_sweep *s, const sl_urban_view *v, const sl_horizon *h, uint32_t o, const double cr[4],
                        float sweep_key, uint32_t *out, uint32_t *n)
{
    const sl_aabb *b = &s->us.boxes[o];
    s->objects_tested++;
    if (!sl_urban_box_in_frustum(v, b)) {
        s->obj_stamp[o] = s->frame; /* nowhere visible this frame */
        return;
    }
    double r[4] = {b->min.x, b->min.y, b->max.x, b->max.y}, dmin, dmax;
    sl_urban_rect_dist(v->eye, r[0], r[1], r[2], r[3], &dmin, &dmax);
    /* every inserted occluder is at most sweep_key away: the whole box is behind them only when
     * none of it is nearer; else judge the part of the box inside this cell */
    bool whole = dmin >= (double)sweep_key;
    if (!whole) {
        r[0] = sl_urban_max(r[0], cr[0]);
        r[1] = sl_urban_max(r[1], cr[1]);
        r[2] = sl_urban_min(r[2], cr[2]);
        r[3] = sl_urban_min(r[3], cr[3]);
        if (r[0] > r[2] || r[1] > r[3])
            return; /* listed through rounding only: nothing of it in this cell */
        sl_urban_rect_dist(v->eye, r[0], r[1], r[2], r[3], &dmin, &dmax);
    }
    double a0, span;
    if (!sl_urban_rect_az(v->eye, r[0], r[1], r[2], r[3], &a0, &span))
        span = SL_URBAN_CIRCLE;
    double top = sl_urban_slope_hi(b->max.z, v->eye[2], dmin, dmax);
    double bottom = sl_urban_slope_lo(b->min.z, v->eye[2], dmin, dmax);
    s->occlusion_tests++;
    if (!sl_horizon_occluded(h, a0, span, top, bottom)) {
        s->obj_stamp[o] = s->frame;
        out[(*n)++] = o;
    } else if (whole)
        s->obj_stamp[o] = s->frame;
}

sl_status sl_urban_sweep_cull(sl_urban_sweep *s, const sl_view *view, uint32_t *out, uint32_t *count,
                              sl_cull_stats *stats, sl_error *err)
{
    (void)err;
    double t0 = sl_now();
    sl_urban_scene *u = &s->us;
    if (++s->frame == 0) { /* the stamps wrapped: start afresh */
        memset(s->obj_stamp, 0, (size_t)(u->object_count ? u->object_count : 1) * sizeof(uint32_t));
        memset(s->fp_excluded, 0, (size_t)(u->fp_count ? u->fp_count : 1) * sizeof(uint32_t));
        memset(s->modes.frame, 0, (size_t)(u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
        s->have_prev = false;
        s->frame = 1;
    }
    s->nodes_visited = s->occlusion_tests = s->objects_tested = s->skipped = 0;
    sl_urban_view v;
    sl_urban_view_make(u, view, &v);
    uint32_t n = 0;
    if (!v.perspective) {
        /* no eye point to build a horizon around: frustum culling over the grid */
        n = sl_urban_frustum_only(u, &v, s->obj_stamp, s->frame, s->span_x0, s->span_x1, out, &stats->nodes_visited,
                                  &stats->objects_tested);
        sl_urban_add_outside(u, &v, s->obj_stamp, s->frame, out, &n);
        s->have_prev = false;
        double t1 = sl_now();
        sl_cull_sort_ids(out, n, s->sort_scratch);
        sl_cull_phase(stats, "frustum", sl_cull_ms(t0, t1));
        sl_cull_phase(stats, "sort", sl_cull_ms(t1, sl_now()));
        *count = n;
        return SL_OK;
    }
    sl_urban_exclude(u, &v, s->fp_excluded, s->frame);
    bool delta = s->incremental && sl_dhorizon_prepare(s, &v);
    sl_horizon *h = &s->hz[s->cur];
    sl_horizon_reset(h);
    s->nodes.n = s->pieces.n = 0;
    s->front_count[s->cur] = 0;
    if (delta) {
        /* start from where the last sweep stopped (ΔH: the cells in front of the last horizon, and
         * the hidden and unexamined parts, which are re-examined at their distance) */
        const uint32_t *f = s->front[s->cur ^ 1];
        for (uint32_t k = 0; k < s->front_count[s->cur ^ 1]; k++)
            append_node(s, &v, SL_FRONT_ID(f[k]), SL_FRONT_KIND(f[k]));
        sl_urban_heap_build(&s->nodes);
    } else if (u->node_count)
        sl_urban_heap_push(&s->nodes, 0.0f, SL_FRONT_ENTRY(u->level_base[u->levels - 1], SL_FRONT_OUT));
    const double ez = v.eye[2];
    while (s->nodes.n) {
        float key = s->nodes.key[0];
        /* occluders entirely nearer than the next node go in first */
        while (s->pieces.n && s->pieces.key[0] <= key) {
            h->key = s->pieces.key[0];
            const sl_urban_piece *p = &u->pieces[sl_urban_heap_pop(&s->pieces)];
            const sl_urban_fp *f = &u->fps[u->edges[p->edge].fp];
            sl_horizon_seg sg = {p->x0, p->y0, f->roof, p->x1, p->y1, f->roof, f->base};
            sl_horizon_insert(h, v.eye, &sg);
        }
        uint32_t entry = sl_urban_heap_pop(&s->nodes), id = SL_FRONT_ID(entry), kind = SL_FRONT_KIND(entry);
        if ((double)key > v.far) {
            /* this node and every later one lie beyond the far plane */
            front_add(s, id, SL_FRONT_OUT);
            while (s->nodes.n)
                front_add(s, SL_FRONT_ID(sl_urban_heap_pop(&s->nodes)), SL_FRONT_OUT);
            break;
        }
        s->nodes_visited++;
        float top = u->pyr_top[id];
        if (top == -INFINITY)
            continue; /* empty: nothing to see or to hide here (nor on any later frame, while the
                         objects stay: not kept in the frontier) */
        uint32_t l = node_level(u, id), lnx = u->level_nx[l];
        uint32_t i = (id - u->level_base[l]) % lnx, j = (id - u->level_base[l]) / lnx;
        double r[4], dmin, dmax, a0, span;
        node_rect(u, l, i, j, r);
        bool bounded = sl_urban_rect_az(v.eye, r[0], r[1], r[2], r[3], &a0, &span);
        if (!bounded)
            span = SL_URBAN_CIRCLE;
        if (!sl_urban_az_meets(&v, a0, span)) {
            front_add(s, id, SL_FRONT_OUT);
            continue;
        }
        sl_urban_rect_dist(v.eye, r[0], r[1], r[2], r[3], &dmin, &dmax);
        double hi = sl_urban_slope_hi(top, ez, dmin, dmax), lo = sl_urban_slope_lo(u->pyr_floor[id], ez, dmin, dmax);
        s->occlusion_tests++;
        if (sl_horizon_occluded(h, a0, span, hi, lo)) {
            front_add(s, id, SL_FRONT_HIDDEN);
            continue;
        }
        if (delta && bounded && kind == SL_FRONT_HIDDEN && sl_dhorizon_skip(s, &v, id, dmin, dmax, a0, span, lo)) {
            s->skipped++;
            front_add(s, id, SL_FRONT_HIDDEN);
            continue;
        }
        if (l > 0) {
            uint32_t cnx = u->level_nx[l - 1], cny = u->level_ny[l - 1];
            for (uint32_t dj = 0; dj < 2; dj++)
                for (uint32_t di = 0; di < 2; di++) {
                    uint32_t ci = 2 * i + di, cj = 2 * j + dj;
                    if (ci >= cnx || cj >= cny)
                        continue;
                    double cr[4], cdmin, cdmax;
                    node_rect(u, l - 1, ci, cj, cr);
                    sl_urban_rect_dist(v.eye, cr[0], cr[1], cr[2], cr[3], &cdmin, &cdmax);
                    /* a child of a node hidden last frame was hidden last frame */
                    sl_urban_heap_push(&s->nodes, key_down(cdmin),
                                       SL_FRONT_ENTRY(u->level_base[l - 1] + cj * cnx + ci,
                                                      kind == SL_FRONT_HIDDEN ? SL_FRONT_HIDDEN : SL_FRONT_OUT));
                }
            continue;
        }
        /* a visible cell: its objects, then its occluders */
        front_add(s, id, SL_FRONT_VISIBLE);
        const uint32_t c = id;
        const struct sl_grid_t *g = u->grid;
        const uint32_t *ids = g->ids + g->start[c];
        for (uint32_t k = 0; k < g->count[c]; k++)
            if (s->obj_stamp[ids[k]] != s->frame)
                test_object(s, &v, h, ids[k], r, key, out, &n);
        for (uint32_t p = u->cell_piece_start[c]; p < u->cell_piece_start[c + 1]; p++) {
            const sl_urban_piece *pc = &u->pieces[p];
            if (!sl_urban_edge_mode_cached(u, pc->edge, &v, s->fp_excluded, s->frame, &s->modes))
                continue;
            double dx0 = pc->x0 - v.eye[0], dy0 = pc->y0 - v.eye[1], dx1 = pc->x1 - v.eye[0], dy1 = pc->y1 - v.eye[1];
            double far = sqrt(sl_urban_max(dx0 * dx0 + dy0 * dy0, dx1 * dx1 + dy1 * dy1));
            /* a façade already below the horizon (every occluder in it is nearer than this cell,
             * hence than the façade) hides nothing new: an occluded occluder */
            double near = sl_urban_seg_dist(&v, pc->x0, pc->y0, pc->x1, pc->y1);
            double pa0 = sl_urban_paz(dx0, dy0), pa1 = sl_urban_paz(dx1, dy1);
            double lo_p = pa0, span_p = sl_urban_paz_wrap(pa1 - pa0);
            if (span_p > 2.0) { /* the other way round (the piece spans less than half a turn) */
                lo_p = pa1;
                span_p = SL_URBAN_CIRCLE - span_p;
            }
            const sl_urban_fp *f = &u->fps[u->edges[pc->edge].fp];
            s->occlusion_tests++;
            if (near > 0 && sl_horizon_occluded(h, lo_p - 1e-9, span_p + 2e-9, sl_urban_slope_hi(f->roof, ez, near, far),
                                                 sl_urban_slope_lo(f->base, ez, near, far)))
                continue;
            sl_urban_heap_push(&s->pieces, key_up(far), p);
        }
    }
    sl_urban_add_outside(u, &v, s->obj_stamp, s->frame, out, &n);
    s->pixels_written = h->bins_written;
    if (s->incremental) {
        s->prev_view = v;
        s->have_prev = true;
        s->cur ^= 1;
    }
    double t1 = sl_now();
    sl_cull_sort_ids(out, n, s->sort_scratch);
    stats->nodes_visited = s->nodes_visited;
    stats->objects_tested = s->objects_tested;
    stats->occlusion_tests = s->occlusion_tests;
    stats->pixels_rasterized = s->pixels_written;
    stats->queries = s->skipped;
    sl_cull_phase(stats, s->incremental ? (delta ? "sweep-delta" : "sweep-full") : "sweep", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "sort", sl_cull_ms(t1, sl_now()));
    *count = n;
    return SL_OK;
}

/* ---- the method ---- */

static sl_status horizon_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state,
                                sl_error *err)
{
    const horizon_config *c = config;
    sl_urban_sweep *s;
    sl_status st = sl_urban_sweep_create(scene, c->cell, c->bins, false, alloc, &s, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "horizon");
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status horizon_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                              sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    return sl_urban_sweep_cull(state, view, out, count, stats, err);
}

static sl_status horizon_scene_changed(void *state, sl_error *err)
{
    sl_urban_sweep *s = state;
    s->have_prev = false;
    sl_status st = sl_urban_scene_refresh(&s->us, err);
    if (st != SL_OK)
        sl_error_prefix(err, "%s", s->incremental ? "dhorizon" : "horizon");
    return st;
}

static void horizon_destroy(void *state) { sl_urban_sweep_destroy(state); }

const sl_cull_method sl_cull_method_horizon = {
    .name = "horizon",
    .suits = "cities with building footprints (2.5D), eyes near the ground",
    .summary = "2.5D occlusion horizon (elevation over azimuth) swept front to back over the scene grid "
               "(Downs et al. I3D 2001; Koldas 2008 ch. 3)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(horizon_config),
    .configure = horizon_configure,
    .create = horizon_create,
    .cull = horizon_cull,
    .scene_changed = horizon_scene_changed,
    .destroy = horizon_destroy,
    .applicable = sl_urban_applicable,
};

/* For dhorizon.c: the same entry points. */
sl_status sl_urban_horizon_scene_changed(void *state, sl_error *err) { return horizon_scene_changed(state, err); }
void sl_urban_horizon_destroy(void *state) { horizon_destroy(state); }

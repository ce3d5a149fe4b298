/* sample: from-region visibility by occluder shrinking and point sampling.
 *
 * P. Wonka, "Occlusion Culling for Real-Time Rendering of Urban Environments", PhD thesis, TU Wien
 * 2001: chapter 5 (the algorithm: sections 5.2-5.6) and chapter 7 (shrinking: Theorem 3, Lemma 6).
 *
 * 1. Every building footprint is eroded by eps in XY (the cylinder of section 7.4: viewers move on
 *    the ground; heights are kept because occlusion is computed from the highest eye point).
 * 2. Samples on the boundary of the cell's TOP face (its three or four top edges, at the cell's
 *    maximum eye height) no more than 2 eps apart, so every top-boundary point is within eps of a
 *    sample. In 2.5D anything visible from inside the cell or from lower down is visible from a
 *    point of that boundary (section 5.3), and by Theorem 3 / Lemma 6 what the shrunk occluders hide
 *    from a sample the real ones hide from every point within eps of it, at the same height.
 *    (Sampling the boundary at a lower fixed height would not be conservative.)
 * 3. For each sample, the shadows of the shrunk occluders' facades are rasterized into a cull map
 *    with max merging (the urban layer's conservative rasterizer, src/raster/cullmap_raster.h: a
 *    cell is written only when wholly inside a shadow, with the lowest shadow height over it — the
 *    per-edge sampling correction of section 4.3.4); the cell's map is the minimum over the samples
 *    (section 5.5): z(c) = min over samples of max over occluders.
 * 4. Hierarchical growing maps (section 5.6): the map starts as a square around the cell and
 *    doubles until every object is decided. An object inside the map is visible when its box pokes
 *    above the map in a cell it overlaps; one wholly outside is hidden when the horizon test
 *    succeeds: every sight line from the cell to it leaves the map through a border cell inside
 *    the convex hull of the two boxes, below the map there (the view-channel bound of section
 *    5.6); an object the map cannot decide waits for the next, larger map.
 * 5. Occluders are rasterized front to back from each sample and an occluder whose top edge lies
 *    wholly inside the shadows already drawn is skipped (rejection of occluded occluders;
 *    skipping an occluder can only make the result larger, so it never costs conservativeness).
 * 6. View channels: a map after the first is needed only for the objects still undecided, and its
 *    decisions read only cells meeting the convex hull of the view cell's box and such an object's
 *    box. Those maps are drawn only there (channel_spans), with only the occluders meeting those
 *    cells: a sight line from the cell to a point of a hull stays inside the convex hull, so an
 *    occluder outside every hull shades no cell that is read; leaving any occluder out can only
 *    lower map values, i.e. enlarge the result.
 * 7. Prefilter: the adjustable method's set (method_adjustable.c) is computed first and only its
 *    members are decided; the others are hidden. Both sets contain every visible object, hence so
 *    does their intersection, which is what the cell gets.
 *
 * Rasterization bound: the thesis proves centre-sampled rasterization conservative when eps >=
 * k sqrt(2)/2 for map cells of side k (Corollary 5). The rasterizer used here covers a map cell
 * only when the whole cell is in the shadow and writes the lowest shadow height over it, so its
 * output is conservative at any eps; the bound is still checked and a smaller eps is reported
 * (stats, metadata, the CLI) so that a reader knows the thesis' proof is not the argument used.
 *
 * Scope: PRISM and BOX cells of 2.5D scenes (footprints). Objects are judged by their boxes.
 * Deterministic: the result of a cell depends on the scene, the cells and the options only. */
#include "pvs_internal.h"

#include "raster/cullmap_raster.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

#define BUCKET 32.0 /* metres per bucket of the occluder and object lookup grids */

typedef struct sample_config {
    float eps;          /* shrink distance, metres */
    float cell;         /* cull-map cell, metres */
    float map0;         /* side of the first map, metres */
    bool occluder_cull; /* skip occluders hidden by the shadows drawn so far */
    bool merge;         /* shrink touching footprints as one height field */
    bool channels;      /* maps after the first: only the view channels of undecided objects */
    bool prefilter;     /* start from the adjustable method's set (intersection) */
} sample_config;

typedef struct spoly {
    uint32_t first, count; /* vertices in pxy (all rings) */
    uint32_t ring_first, ring_count; /* ring sizes in rings: the outer ring, then holes */
    double base, roof;
    double x0, y0, x1, y1;
} spoly;

typedef struct sample_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    sample_config cfg;
    uint32_t npoly;
    spoly *polys;
    double *pxy;
    size_t pxy_count;
    uint32_t *rings;
    size_t ring_total;
    /* buckets over the global grid: CSR lists of polygons and objects per bucket */
    double bx0, by0;
    uint32_t bnx, bny;
    uint32_t *poly_start, *poly_ids, *obj_start, *obj_ids;
    size_t poly_ids_count, obj_ids_count;
    /* the global cull-map grid (every map is a window of it) */
    double min_x, min_y;
    uint32_t gnx, gny;
    const sl_aabb *obj_bounds;
    uint32_t nobj;
    sl_base_levels bases; /* the scene's distinct footprint bases (sl_cell_floor) */
    /* prefilter: the adjustable method, prepared alongside (NULL when off) */
    const sl_pvs_method *pre;
    void *pre_config, *pre_shared;
} sample_shared;

typedef struct sample_worker {
    sample_shared *sh;
    size_t map_cap;
    float *acc, *zs, *floor, *top;
    uint16_t *unsat;            /* per 16 x 16 block (saturation bookkeeping of the rasterizer) */
    size_t unsat_cap;
    size_t row_cap;
    int32_t *x0, *x1;
    uint8_t *state;             /* per object: 0 undecided, 1 visible, 2 hidden */
    uint32_t *poly_stamp, *obj_stamp;
    uint32_t stamp;
    sl_array cand;              /* uint32 polygon ids */
    sl_array keys;              /* cand_key */
    sl_array objs;              /* uint32 object ids in the window */
    size_t chain_cap;
    sl_shadow_edge *chain;
    uint8_t *front;
    size_t front_cap;
    sl_array samples;           /* double[3] */
    sl_array aggs;              /* sl_aabb: undecided objects merged per bucket (channel_spans) */
    uint32_t *agg_stamp, *agg_of; /* per bucket: stamp of its aggregate, its index in aggs */
    void *pre_worker;           /* the prefilter's worker, and its set */
    uint32_t *pre_ids;
} sample_worker;

static const char g_help[] =
    "eps=FLOAT (default 1.5): occluder shrinking in metres; samples on the cell's top edges at most 2 eps apart\n"
    "cell=FLOAT (default 2): cull-map cell size in metres (the thesis bound asks eps >= cell*sqrt(2)/2)\n"
    "map=FLOAT (default 256): side of the first (smallest) cull map in metres; maps double until all objects are decided\n"
    "occluder_cull=BOOL (default true): skip occluders hidden behind the shadows already drawn\n"
    "merge=BOOL (default true): shrink touching footprints together as one 2.5D occluder (no gaps between them)\n"
    "channels=BOOL (default true): maps after the first draw only the occluders and cells in the view channels of "
    "the objects still undecided\n"
    "prefilter=BOOL (default true): decide only the objects in the adjustable method's set (default options) and "
    "keep the intersection of the two conservative sets\n";

static sl_status sample_configure(sl_opts *o, void *config, sl_error *err)
{
    sample_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "eps", 1.5f, 0.01f, 1000.0f, &c->eps, err)) != SL_OK ||
        (st = sl_opts_float(o, "cell", 2.0f, 0.05f, 1000.0f, &c->cell, err)) != SL_OK ||
        (st = sl_opts_float(o, "map", 256.0f, 8.0f, 1e6f, &c->map0, err)) != SL_OK ||
        (st = sl_opts_bool(o, "occluder_cull", true, &c->occluder_cull, err)) != SL_OK ||
        (st = sl_opts_bool(o, "merge", true, &c->merge, err)) != SL_OK ||
        (st = sl_opts_bool(o, "channels", true, &c->channels, err)) != SL_OK ||
        (st = sl_opts_bool(o, "prefilter", true, &c->prefilter, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void sample_release(void *p)
{
    sample_shared *s = p;
    if (!s)
        return;
    const sl_allocator *a = &s->a;
    size_t nb = (size_t)s->bnx * s->bny + 1;
    if (s->pre_shared)
        s->pre->release(s->pre_shared);
    if (s->pre_config)
        sl_free(a, s->pre_config, s->pre->config_size ? s->pre->config_size : 1);
    sl_base_levels_free(&s->bases, a);
    sl_free(a, s->polys, ((size_t)s->npoly + 1) * sizeof(spoly));
    sl_free(a, s->pxy, (s->pxy_count + 1) * sizeof(double));
    sl_free(a, s->rings, (s->ring_total + 1) * sizeof(uint32_t));
    sl_free(a, s->poly_start, nb * sizeof(uint32_t));
    sl_free(a, s->obj_start, nb * sizeof(uint32_t));
    sl_free(a, s->poly_ids, (s->poly_ids_count + 1) * sizeof(uint32_t));
    sl_free(a, s->obj_ids, (s->obj_ids_count + 1) * sizeof(uint32_t));
    sl_free(a, s, sizeof *s);
}

/* Bucket range of an XY box (clamped). */
static void bucket_range(const sample_shared *s, double x0, double y0, double x1, double y1, uint32_t r[4])
{
    double fx0 = floor((x0 - s->bx0) / BUCKET), fx1 = floor((x1 - s->bx0) / BUCKET);
    double fy0 = floor((y0 - s->by0) / BUCKET), fy1 = floor((y1 - s->by0) / BUCKET);
    r[0] = (uint32_t)fmin(fmax(fx0, 0), s->bnx - 1);
    r[1] = (uint32_t)fmin(fmax(fy0, 0), s->bny - 1);
    r[2] = (uint32_t)fmin(fmax(fx1, 0), s->bnx - 1);
    r[3] = (uint32_t)fmin(fmax(fy1, 0), s->bny - 1);
}

/* CSR bucket lists of n boxes. */
static bool build_buckets(sample_shared *s, uint32_t n, const double (*box)[4], uint32_t **start, uint32_t **ids,
                          size_t *ids_count)
{
    size_t nb = (size_t)s->bnx * s->bny;
    uint32_t *st = sl_calloc(&s->a, nb + 1, sizeof(uint32_t));
    if (!st)
        return false;
    size_t total = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t r[4];
        bucket_range(s, box[i][0], box[i][1], box[i][2], box[i][3], r);
        for (uint32_t y = r[1]; y <= r[3]; y++)
            for (uint32_t x = r[0]; x <= r[2]; x++)
                st[(size_t)y * s->bnx + x + 1]++;
        total += (size_t)(r[2] - r[0] + 1) * (r[3] - r[1] + 1);
    }
    if (total >= UINT32_MAX) {
        sl_free(&s->a, st, (nb + 1) * sizeof(uint32_t));
        return false;
    }
    for (size_t b = 0; b < nb; b++)
        st[b + 1] += st[b];
    uint32_t *list = sl_alloc(&s->a, (total + 1) * sizeof(uint32_t));
    uint32_t *fill = sl_alloc(&s->a, (nb + 1) * sizeof(uint32_t));
    if (!list || !fill) {
        sl_free(&s->a, st, (nb + 1) * sizeof(uint32_t));
        sl_free(&s->a, list, (total + 1) * sizeof(uint32_t));
        sl_free(&s->a, fill, (nb + 1) * sizeof(uint32_t));
        return false;
    }
    memcpy(fill, st, (nb + 1) * sizeof(uint32_t));
    for (uint32_t i = 0; i < n; i++) {
        uint32_t r[4];
        bucket_range(s, box[i][0], box[i][1], box[i][2], box[i][3], r);
        for (uint32_t y = r[1]; y <= r[3]; y++)
            for (uint32_t x = r[0]; x <= r[2]; x++)
                list[fill[(size_t)y * s->bnx + x]++] = i;
    }
    sl_free(&s->a, fill, (nb + 1) * sizeof(uint32_t));
    *start = st;
    *ids = list;
    *ids_count = total;
    return true;
}

static sl_status sample_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                                uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    const sample_config *cfg = config;
    sample_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *cfg;
    s->nobj = sl_scene_object_count(scene);
    s->obj_bounds = sl_scene_object_bounds_array(scene);
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_PRISM && vc[i].shape != SL_CELL_BOX) {
            sample_release(s);
            return sl_fail(err, SL_ERROR_UNSUPPORTED,
                           "sample: view cell %u is a BSP cluster; the method needs prism or box cells of a 2.5D "
                           "scene (street or grid cells)",
                           i);
        }
    /* 1. shrink the footprints */
    sl_shrunk sh;
    sl_status st = sl_shrink_footprints(scene, cfg->eps, SL_SHRINK_CYLINDER, cfg->merge, alloc, &sh, err);
    if (st != SL_OK) {
        sample_release(s);
        return st;
    }
    sl_shrink_stats ss;
    sl_shrunk_get_stats(sh, &ss);
    *removed = ss.vanished;
    s->npoly = sl_shrunk_count(sh);
    size_t nv = 0, nr = 0;
    for (uint32_t i = 0; i < s->npoly; i++) {
        nv += sl_shrunk_get(sh, i).vertex_count;
        nr += sl_shrunk_get(sh, i).ring_count;
    }
    s->polys = sl_alloc(alloc, ((size_t)s->npoly + 1) * sizeof(spoly));
    s->pxy_count = 2 * nv;
    s->pxy = sl_alloc(alloc, (s->pxy_count + 1) * sizeof(double));
    s->ring_total = nr;
    s->rings = sl_alloc(alloc, (nr + 1) * sizeof(uint32_t));
    if (!s->polys || !s->pxy || !s->rings) {
        sl_shrunk_destroy(sh);
        sample_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory for %u occluders", s->npoly);
    }
    /* 2. the global grid covers the objects and the cells */
    sl_aabb world = sl_scene_bounds(scene);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        sl_aabb_merge(&world, &vc[i].bounds);
    size_t at = 0, ra = 0;
    for (uint32_t i = 0; i < s->npoly; i++) {
        sl_shrunk_polygon p = sl_shrunk_get(sh, i);
        spoly *q = &s->polys[i];
        q->first = (uint32_t)(at / 2);
        q->count = p.vertex_count;
        q->ring_first = (uint32_t)ra;
        q->ring_count = p.ring_count;
        for (uint32_t r = 0; r < p.ring_count; r++)
            s->rings[ra++] = p.rings[r];
        q->base = p.base_z;
        q->roof = p.roof_z;
        q->x0 = q->y0 = INFINITY;
        q->x1 = q->y1 = -INFINITY;
        for (uint32_t k = 0; k < p.vertex_count; k++) {
            double x = p.xy[2 * k], y = p.xy[2 * k + 1];
            s->pxy[at++] = x;
            s->pxy[at++] = y;
            q->x0 = fmin(q->x0, x), q->x1 = fmax(q->x1, x);
            q->y0 = fmin(q->y0, y), q->y1 = fmax(q->y1, y);
        }
        sl_aabb_grow(&world, (sl_vec3){(float)q->x0, (float)q->y0, (float)q->base});
        sl_aabb_grow(&world, (sl_vec3){(float)q->x1, (float)q->y1, (float)q->roof});
    }
    sl_shrunk_destroy(sh);
    /* the scene's footprint bases: each occluder's base is one of them (a merged group takes its
     * highest member's), so every occluder drawn for a cell lies at or below its tb */
    if (!sl_base_levels_of_scene(&s->bases, scene, alloc)) {
        sample_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory for %u occluders", s->npoly);
    }
    if (sl_aabb_is_empty(&world)) {
        sample_release(s);
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "sample: the scene is empty");
    }
    double k = cfg->cell;
    s->min_x = floor((world.min.x - k) / k) * k;
    s->min_y = floor((world.min.y - k) / k) * k;
    double gnx = ceil((world.max.x + k - s->min_x) / k), gny = ceil((world.max.y + k - s->min_y) / k);
    if (gnx * gny > 1.5e8) {
        sample_release(s);
        return sl_fail(err, SL_ERROR_LIMIT, "sample: a %.0f x %.0f cull map of %g m cells is too large (raise cell)",
                       gnx, gny, (double)k);
    }
    s->gnx = (uint32_t)gnx;
    s->gny = (uint32_t)gny;
    s->bx0 = s->min_x;
    s->by0 = s->min_y;
    s->bnx = (uint32_t)fmax(1, ceil(gnx * k / BUCKET));
    s->bny = (uint32_t)fmax(1, ceil(gny * k / BUCKET));
    /* 3. bucket lists of occluders and objects */
    size_t nbox = SL_MAX((size_t)s->npoly, (size_t)s->nobj) + 1;
    double(*box)[4] = sl_alloc(alloc, nbox * sizeof *box);
    if (!box) {
        sample_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
    }
    for (uint32_t i = 0; i < s->npoly; i++) {
        box[i][0] = s->polys[i].x0, box[i][1] = s->polys[i].y0;
        box[i][2] = s->polys[i].x1, box[i][3] = s->polys[i].y1;
    }
    bool ok = build_buckets(s, s->npoly, (const double(*)[4])box, &s->poly_start, &s->poly_ids, &s->poly_ids_count);
    for (uint32_t i = 0; ok && i < s->nobj; i++) {
        const sl_aabb *b = &s->obj_bounds[i];
        box[i][0] = b->min.x, box[i][1] = b->min.y, box[i][2] = b->max.x, box[i][3] = b->max.y;
    }
    ok = ok && build_buckets(s, s->nobj, (const double(*)[4])box, &s->obj_start, &s->obj_ids, &s->obj_ids_count);
    sl_free(alloc, box, nbox * sizeof *box);
    if (!ok) {
        sample_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory for the lookup grids");
    }
    /* the prefilter: adjustable shrinking with its default options */
    if (cfg->prefilter) {
        uint64_t pre_removed = 0;
        if ((st = sl_pvs_registry_find("adjustable", &s->pre, err)) != SL_OK ||
            (st = sl_pvs_method_configure(s->pre, "", alloc, &s->pre_config, NULL, err)) != SL_OK ||
            (st = s->pre->prepare(scene, cells, s->pre_config, alloc, threads, &s->pre_shared, &pre_removed, err)) !=
                SL_OK) {
            sample_release(s);
            return st;
        }
    }
    *shared = s;
    return SL_OK;
}

static void sample_worker_destroy(void *p)
{
    sample_worker *w = p;
    if (!w)
        return;
    const sl_allocator *a = &w->sh->a;
    sl_free(a, w->acc, w->map_cap * sizeof(float));
    sl_free(a, w->zs, w->map_cap * sizeof(float));
    sl_free(a, w->floor, w->map_cap * sizeof(float));
    sl_free(a, w->top, w->map_cap * sizeof(float));
    sl_free(a, w->unsat, w->unsat_cap * sizeof(uint16_t));
    sl_free(a, w->x0, w->row_cap * sizeof(int32_t));
    sl_free(a, w->x1, w->row_cap * sizeof(int32_t));
    sl_free(a, w->state, (size_t)w->sh->nobj + 1);
    sl_free(a, w->poly_stamp, ((size_t)w->sh->npoly + 1) * sizeof(uint32_t));
    sl_free(a, w->obj_stamp, ((size_t)w->sh->nobj + 1) * sizeof(uint32_t));
    sl_array_free(a, &w->cand, sizeof(uint32_t));
    sl_array_free(a, &w->keys, 2 * sizeof(double));
    sl_array_free(a, &w->objs, sizeof(uint32_t));
    sl_free(a, w->chain, w->chain_cap * sizeof(sl_shadow_edge));
    sl_free(a, w->front, w->front_cap);
    sl_array_free(a, &w->samples, 3 * sizeof(double));
    sl_array_free(a, &w->aggs, sizeof(sl_aabb));
    sl_free(a, w->agg_stamp, ((size_t)w->sh->bnx * w->sh->bny + 1) * sizeof(uint32_t));
    sl_free(a, w->agg_of, ((size_t)w->sh->bnx * w->sh->bny + 1) * sizeof(uint32_t));
    if (w->pre_worker)
        w->sh->pre->worker_destroy(w->pre_worker);
    sl_free(a, w->pre_ids, ((size_t)w->sh->nobj + 1) * sizeof(uint32_t));
    sl_free(a, w, sizeof *w);
}

static sl_status sample_worker_create(void *shared, void **out, sl_error *err)
{
    sample_shared *s = shared;
    sample_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
    w->sh = s;
    w->state = sl_calloc(&s->a, (size_t)s->nobj + 1, 1);
    w->poly_stamp = sl_calloc(&s->a, (size_t)s->npoly + 1, sizeof(uint32_t));
    w->obj_stamp = sl_calloc(&s->a, (size_t)s->nobj + 1, sizeof(uint32_t));
    w->agg_stamp = sl_calloc(&s->a, (size_t)s->bnx * s->bny + 1, sizeof(uint32_t));
    w->agg_of = sl_calloc(&s->a, (size_t)s->bnx * s->bny + 1, sizeof(uint32_t));
    if (!w->state || !w->poly_stamp || !w->obj_stamp || !w->agg_stamp || !w->agg_of) {
        sample_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
    }
    if (s->pre) {
        w->pre_ids = sl_alloc(&s->a, ((size_t)s->nobj + 1) * sizeof(uint32_t));
        sl_status st = w->pre_ids ? s->pre->worker_create(s->pre_shared, &w->pre_worker, err)
                                  : sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
        if (st != SL_OK) {
            sample_worker_destroy(w);
            return st;
        }
    }
    *out = w;
    return SL_OK;
}

#define BLOCK_SHIFT 4u /* saturation blocks of 16 x 16 map cells */

/* Room for a map of nx * ny cells. */
static bool reserve_map(sample_worker *w, uint32_t nx, uint32_t ny)
{
    const sl_allocator *a = &w->sh->a;
    size_t n = (size_t)nx * ny, rows = ny;
    size_t blocks = (size_t)((nx >> BLOCK_SHIFT) + 1) * ((ny >> BLOCK_SHIFT) + 1);
    if (n > w->map_cap) {
        float **arr[4] = {&w->acc, &w->zs, &w->floor, &w->top};
        bool ok = true;
        for (int i = 0; i < 4; i++) {
            sl_free(a, *arr[i], w->map_cap * sizeof(float));
            *arr[i] = sl_alloc(a, n * sizeof(float));
            ok &= *arr[i] != NULL;
        }
        w->map_cap = n;
        if (!ok) {
            for (int i = 0; i < 4; i++) {
                sl_free(a, *arr[i], n * sizeof(float));
                *arr[i] = NULL;
            }
            w->map_cap = 0;
            return false;
        }
    }
    if (blocks > w->unsat_cap) {
        sl_free(a, w->unsat, w->unsat_cap * sizeof(uint16_t));
        w->unsat = sl_alloc(a, blocks * sizeof(uint16_t));
        w->unsat_cap = w->unsat ? blocks : 0;
        if (!w->unsat)
            return false;
    }
    if (rows > w->row_cap) {
        sl_free(a, w->x0, w->row_cap * sizeof(int32_t));
        sl_free(a, w->x1, w->row_cap * sizeof(int32_t));
        w->x0 = sl_alloc(a, rows * sizeof(int32_t));
        w->x1 = sl_alloc(a, rows * sizeof(int32_t));
        w->row_cap = rows;
        if (!w->x0 || !w->x1) {
            sl_free(a, w->x0, rows * sizeof(int32_t));
            sl_free(a, w->x1, rows * sizeof(int32_t));
            w->x0 = w->x1 = NULL;
            w->row_cap = 0;
            return false;
        }
    }
    return true;
}

/* A map window of the global grid. */
typedef struct window {
    uint32_t i0, j0, nx, ny;    /* global cell of the window's corner, size */
    double mx, my;              /* world corner */
    double x0, y0, x1, y1;      /* world rectangle */
    bool all;                   /* covers the whole global grid */
} window;

static int cmp_key(const void *a, const void *b)
{
    const double *x = a, *y = b;
    if (x[0] != y[0])
        return x[0] < y[0] ? -1 : 1;
    return (x[1] > y[1]) - (x[1] < y[1]);
}

/* Is the top edge (a, b) at height z inside the shadows of map zs: every map cell the segment
 * passes through (walked column by column, or row by row along the steeper axis) within the clip
 * (cells outside it hold stale values) and at least z? Only an optimisation: a wrong "yes" would
 * only drop an occluder, which can only enlarge the result. */
static bool edge_hidden(const sample_worker *w, const window *win, const float *zs, const sl_cullmap_clip *clip,
                        double ax, double ay, double bx, double by, double z)
{
    const double k = w->sh->cfg.cell;
    double u0 = (ax - win->mx) / k, v0 = (ay - win->my) / k, u1 = (bx - win->mx) / k, v1 = (by - win->my) / k;
    const bool steep = fabs(v1 - v0) > fabs(u1 - u0);
    if (steep) { /* walk rows: swap the roles of u and v */
        double t = u0;
        u0 = v0, v0 = t;
        t = u1;
        u1 = v1, v1 = t;
    }
    if (u0 > u1) {
        double t = u0;
        u0 = u1, u1 = t;
        t = v0;
        v0 = v1, v1 = t;
    }
    const double nu = steep ? win->ny : win->nx, nv = steep ? win->nx : win->ny;
    if (!(u0 >= 0 && u1 < nu && fmin(v0, v1) >= 0 && fmax(v0, v1) < nv))
        return false;
    const double slope = u1 > u0 ? (v1 - v0) / (u1 - u0) : 0;
    for (int64_t c = (int64_t)u0, c1 = (int64_t)u1; c <= c1; c++) {
        double ua = fmax(u0, (double)c), ub = fmin(u1, (double)c + 1);
        double va = v0 + (ua - u0) * slope, vb = v0 + (ub - u0) * slope;
        int64_t r0 = (int64_t)fmin(va, vb), r1 = (int64_t)fmax(va, vb);
        for (int64_t r = r0; r <= r1; r++) {
            int64_t i = steep ? r : c, j = steep ? c : r;
            if (j < clip->j0 || j > clip->j1)
                return false;
            size_t row = (size_t)j - clip->j0;
            if (i < clip->x0[row] || i > clip->x1[row])
                return false;
            if (!((double)zs[(size_t)j * win->nx + (size_t)i] >= z))
                return false;
        }
    }
    return true;
}

/* Rasterize the front-facing facades of one ring (solid on its left) seen from eye. */
static sl_status draw_ring(sample_worker *w, const window *win, const double eye[3], sl_cullmap_grid *g,
                           const sl_cullmap_clip *clip, const double *v, uint32_t n, double roof, double base,
                           uint64_t *written, sl_error *err)
{
    const sample_shared *s = w->sh;
    if (n > w->front_cap || n + 1 > w->chain_cap) {
        size_t cap = (size_t)n + 16;
        sl_free(&s->a, w->front, w->front_cap);
        sl_free(&s->a, w->chain, w->chain_cap * sizeof(sl_shadow_edge));
        w->front = sl_alloc(&s->a, cap);
        w->chain = sl_alloc(&s->a, cap * sizeof(sl_shadow_edge));
        w->front_cap = w->chain_cap = w->front && w->chain ? cap : 0;
        if (!w->front || !w->chain) {
            sl_free(&s->a, w->front, cap);
            sl_free(&s->a, w->chain, cap * sizeof(sl_shadow_edge));
            w->front = NULL;
            w->chain = NULL;
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
        }
    }
    /* front-facing: the eye to the right of edge a->b (outside the solid) */
    uint32_t nfront = 0;
    for (uint32_t e = 0; e < n; e++) {
        const double *a = v + 2 * e, *b = v + 2 * ((e + 1) % n);
        double cr = (b[0] - a[0]) * (eye[1] - a[1]) - (b[1] - a[1]) * (eye[0] - a[0]);
        w->front[e] = cr < 0;
        nfront += w->front[e];
    }
    if (nfront == 0 || nfront == n)
        return SL_OK; /* edge-on, or the eye inside the ring: nothing to draw */
    /* runs of consecutive front edges, starting after a back edge: the rasterizer's seam windows */
    uint32_t start = 0;
    while (!(w->front[start] && !w->front[(start + n - 1) % n]))
        start++;
    for (uint32_t k = 0; k < n;) {
        if (!w->front[(start + k) % n]) {
            k++;
            continue;
        }
        uint32_t len = 0;
        while (k + len < n && w->front[(start + k + len) % n])
            len++;
        for (uint32_t q = 0; q < len; q++) {
            uint32_t ee = (start + k + q) % n;
            const double *a = v + 2 * ee, *b = v + 2 * ((ee + 1) % n);
            w->chain[q] = (sl_shadow_edge){a[0], a[1], roof, b[0], b[1], roof, base};
        }
        for (uint32_t q = 0; q < len; q++) {
            const sl_shadow_edge *ed = &w->chain[q];
            if (s->cfg.occluder_cull && edge_hidden(w, win, g->z, clip, ed->ax, ed->ay, ed->bx, ed->by, ed->az))
                continue;
            *written += sl_cullmap_raster_wedge(g, eye, w->chain, len, q, clip);
        }
        k += len;
    }
    return SL_OK;
}

/* Rasterize every candidate occluder's front-facing facades seen from eye into map g (its rings:
 * the outer one counter-clockwise, holes clockwise). */
static sl_status draw_sample(sample_worker *w, const window *win, const double eye[3], sl_cullmap_grid *g,
                             const sl_cullmap_clip *clip, uint64_t *written, sl_error *err)
{
    const sample_shared *s = w->sh;
    const uint32_t *cand = w->cand.data;
    for (size_t c = 0; c < w->cand.count; c++) {
        const spoly *p = &s->polys[cand[c]];
        const double *v = s->pxy + 2 * (size_t)p->first;
        for (uint32_t r = 0; r < p->ring_count; r++) {
            uint32_t n = s->rings[p->ring_first + r];
            sl_status st = draw_ring(w, win, eye, g, clip, v, n, p->roof, p->base, written, err);
            if (st != SL_OK)
                return st;
            v += 2 * (size_t)n;
        }
    }
    return SL_OK;
}

/* Cell test of an object wholly inside the window: hidden when its top is at most the map value in
 * every map cell its box overlaps (its bottom is at least the cell's floor by construction). */
static bool hidden_inside(const sample_worker *w, const window *win, const sl_aabb *b)
{
    double k = w->sh->cfg.cell;
    int64_t i0 = (int64_t)floor((b->min.x - win->mx) / k), i1 = (int64_t)floor((b->max.x - win->mx) / k);
    int64_t j0 = (int64_t)floor((b->min.y - win->my) / k), j1 = (int64_t)floor((b->max.y - win->my) / k);
    i0 = SL_MAX(i0, 0), j0 = SL_MAX(j0, 0);
    i1 = SL_MIN(i1, (int64_t)win->nx - 1), j1 = SL_MIN(j1, (int64_t)win->ny - 1);
    for (int64_t j = j0; j <= j1; j++) {
        const float *row = w->acc + (size_t)j * win->nx;
        for (int64_t i = i0; i <= i1; i++)
            if (!(b->max.z <= row[i]))
                return false;
    }
    return true;
}

/* Convex hull (counter-clockwise) of n <= 8 points; returns its size. */
static int hull8(double (*p)[2], int n, double (*h)[2])
{
    /* sort by x then y (insertion sort: tiny n) */
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && (p[j][0] < p[j - 1][0] || (p[j][0] == p[j - 1][0] && p[j][1] < p[j - 1][1])); j--) {
            double tx = p[j][0], ty = p[j][1];
            p[j][0] = p[j - 1][0], p[j][1] = p[j - 1][1];
            p[j - 1][0] = tx, p[j - 1][1] = ty;
        }
    int m = 0;
    for (int pass = 0; pass < 2; pass++) {
        int base = m;
        for (int i = 0; i < n; i++) {
            const double *q = p[pass == 0 ? i : n - 1 - i];
            while (m >= base + 2 && sl_orient2d(h[m - 2][0], h[m - 2][1], h[m - 1][0], h[m - 1][1], q[0], q[1]) <= 0)
                m--;
            h[m][0] = q[0], h[m][1] = q[1];
            m++;
        }
        m--; /* the last point starts the other chain */
    }
    return m;
}

/* A fresh stamp for the per-worker "seen" marks (all marks cleared when it wraps). */
static void next_stamp(sample_worker *w)
{
    const sample_shared *s = w->sh;
    if (++w->stamp == 0) {
        memset(w->poly_stamp, 0, ((size_t)s->npoly + 1) * sizeof(uint32_t));
        memset(w->obj_stamp, 0, ((size_t)s->nobj + 1) * sizeof(uint32_t));
        memset(w->agg_stamp, 0, ((size_t)s->bnx * s->bny + 1) * sizeof(uint32_t));
        w->stamp = 1;
    }
}

/* Extent of the convex polygon h along coordinate 1 - c within the slab lo <= p[c] <= hi (c = 1: the
 * x-extent of a horizontal strip; c = 0: the y-extent of a vertical one); false when the slab misses
 * the polygon. Every edge is clipped to the slab and its clipped ends taken. */
static bool hull_slab(const double (*h)[2], int n, int c, double lo, double hi, double *a, double *b)
{
    const int o = 1 - c;
    double mn = INFINITY, mx = -INFINITY;
    for (int i = 0; i < n; i++) {
        const double *p = h[i], *q = h[(i + 1) % n];
        double d = q[c] - p[c], t0 = 0, t1 = 1;
        if (d == 0) {
            if (p[c] < lo || p[c] > hi)
                continue;
        } else {
            double ta = (lo - p[c]) / d, tb = (hi - p[c]) / d;
            t0 = fmax(0.0, fmin(ta, tb));
            t1 = fmin(1.0, fmax(ta, tb));
            if (!(t0 <= t1))
                continue;
        }
        double u0 = p[o] + t0 * (q[o] - p[o]), u1 = p[o] + t1 * (q[o] - p[o]);
        mn = fmin(mn, fmin(u0, u1));
        mx = fmax(mx, fmax(u0, u1));
    }
    *a = mn;
    *b = mx;
    return mn <= mx;
}

/* Hull of the view cell's box and an object's box (the view channel of the horizon test). */
static int channel_hull(const sl_aabb *v, const sl_aabb *b, double (*h)[2])
{
    double pts[8][2] = {{v->min.x, v->min.y}, {v->max.x, v->min.y}, {v->max.x, v->max.y}, {v->min.x, v->max.y},
                        {b->min.x, b->min.y}, {b->max.x, b->min.y}, {b->max.x, b->max.y}, {b->min.x, b->max.y}};
    return hull8(pts, 8, h);
}

/* Horizon test of an object wholly outside the window (section 5.6): every sight line from the
 * view cell V to the object leaves the map through a border cell meeting the hull of the two
 * boxes, at a height within [lo, hi]; hidden when every such cell hides that range. The border
 * cells meeting the hull are found per border line from the hull's extent in that row (column):
 * a cell meets a convex polygon exactly when its side overlaps the polygon's extent in its strip;
 * the strip and the extent are widened by a rounding margin, so a few more cells may be tested
 * (a stricter test), never fewer. */
static bool hidden_by_horizon(const sample_worker *w, const window *win, const sl_aabb *v, const sl_aabb *b)
{
    double k = w->sh->cfg.cell;
    double h[16][2];
    int nh = channel_hull(v, b, h);
    if (nh < 3)
        return false;
    /* nearest horizontal distance between the boxes */
    double gx = fmax(0.0, fmax((double)b->min.x - v->max.x, (double)v->min.x - b->max.x));
    double gy = fmax(0.0, fmax((double)b->min.y - v->max.y, (double)v->min.y - b->max.y));
    double dmin = hypot(gx, gy);
    if (!(dmin > 0))
        return false;
    double lo = fmin(v->min.z, b->min.z), vtop = v->max.z, otop = b->max.z;
    const double tol = 1e-9 * (1.0 + fabs(win->mx) + fabs(win->my) + win->nx * k + win->ny * k);
    bool any = false;
    for (int side = 0; side < 4; side++) {
        /* side 0: bottom row, 1: top row, 2: left column, 3: right column (corners twice: harmless) */
        const bool row = side < 2;
        const int64_t fixed = side == 0 || side == 2 ? 0 : (int64_t)(row ? win->ny : win->nx) - 1;
        const double base = row ? win->my : win->mx, along0 = row ? win->mx : win->my;
        const int64_t len = row ? win->nx : win->ny;
        double ea, eb;
        if (!hull_slab((const double(*)[2])h, nh, row ? 1 : 0, base + (double)fixed * k - tol,
                       base + (double)(fixed + 1) * k + tol, &ea, &eb))
            continue;
        /* cells whose [t k, (t+1) k] overlaps [ea, eb] */
        int64_t a0 = (int64_t)fmax(0.0, ceil((ea - tol - along0) / k) - 1);
        int64_t a1 = (int64_t)fmin((double)len - 1, floor((eb + tol - along0) / k));
        for (int64_t t = a0; t <= a1; t++) {
            int64_t i = row ? t : fixed, j = row ? fixed : t;
            double x0 = win->mx + (double)i * k, y0 = win->my + (double)j * k;
            size_t c = (size_t)j * win->nx + (size_t)i;
            any = true;
            if (!(w->floor[c] <= lo))
                return false;
            double hi = vtop;
            if (otop > vtop) {
                /* farthest point of the cell from the view cell's box, over the nearest gap */
                double fx = fmax(fabs(x0 - v->min.x), fabs(x0 + k - v->min.x));
                fx = fmax(fx, fmax(fabs(x0 - v->max.x), fabs(x0 + k - v->max.x)));
                double fy = fmax(fabs(y0 - v->min.y), fabs(y0 + k - v->min.y));
                fy = fmax(fy, fmax(fabs(y0 - v->max.y), fabs(y0 + k - v->max.y)));
                double frac = fmin(1.0, hypot(fx, fy) / dmin);
                hi = vtop + (otop - vtop) * frac;
            }
            if (!(hi <= (double)w->acc[c]))
                return false;
        }
    }
    return any; /* no border cell found: the hull misses the map (cannot happen), undecided */
}

/* The map cells that this level's decisions read: every cell meeting the view channel of an
 * undecided object (its box's cells and the border cells of the horizon test lie in the
 * channel), one cell wider on every side against rounding, as a span per row. Occluders that miss
 * every channel cannot shade a point of one (a sight line from the cell to a point of a channel
 * stays in that convex channel), and cells outside the spans are neither written nor read. */
static bool channel_spans(sample_worker *w, const window *win, const sl_aabb *v, sl_cullmap_clip *clip)
{
    const sample_shared *s = w->sh;
    const double k = s->cfg.cell;
    for (uint32_t j = 0; j < win->ny; j++)
        w->x0[j] = (int32_t)win->nx, w->x1[j] = -1;
    /* the undecided objects' boxes merged per bucket of their lower corner: the channel of a
     * merged box holds the channels of its members (fewer, larger channels: a superset) */
    next_stamp(w);
    w->aggs.count = 0;
    for (uint32_t o = 0; o < s->nobj; o++) {
        if (w->state[o])
            continue;
        const sl_aabb *b = &s->obj_bounds[o];
        uint32_t r[4];
        bucket_range(s, b->min.x, b->min.y, b->min.x, b->min.y, r);
        size_t bi = (size_t)r[1] * s->bnx + r[0];
        if (w->agg_stamp[bi] != w->stamp) {
            w->agg_stamp[bi] = w->stamp;
            w->agg_of[bi] = (uint32_t)w->aggs.count;
            if (!sl_array_push(&s->a, &w->aggs, sizeof *b, b, 1))
                return false;
        } else {
            sl_aabb_merge(&SL_AT(w->aggs, sl_aabb, w->agg_of[bi]), b);
        }
    }
    for (size_t q = 0; q < w->aggs.count; q++) {
        double h[16][2];
        int nh = channel_hull(v, &SL_AT(w->aggs, sl_aabb, q), h);
        if (nh < 3) { /* a degenerate hull (flat boxes): keep the whole window, to be safe */
            for (uint32_t j = 0; j < win->ny; j++)
                w->x0[j] = 0, w->x1[j] = (int32_t)win->nx - 1;
            continue;
        }
        /* per edge, its extent in each row it crosses (rows widened by one on both sides) */
        for (int e = 0; e < nh; e++) {
            const double *p = h[e], *pq = h[(e + 1) % nh];
            double ey0 = fmin(p[1], pq[1]), ey1 = fmax(p[1], pq[1]);
            int64_t j0 = (int64_t)fmax(0.0, floor((ey0 - win->my) / k) - 1);
            int64_t j1 = (int64_t)fmin(win->ny - 1.0, floor((ey1 - win->my) / k) + 1);
            double dy = pq[1] - p[1];
            for (int64_t j = j0; j <= j1; j++) {
                double y0 = win->my + (double)(j - 1) * k, y1 = win->my + (double)(j + 2) * k, t0 = 0, t1 = 1;
                if (dy != 0) {
                    double ta = (y0 - p[1]) / dy, tb = (y1 - p[1]) / dy;
                    t0 = fmax(0.0, fmin(ta, tb));
                    t1 = fmin(1.0, fmax(ta, tb));
                    if (!(t0 <= t1))
                        continue;
                }
                double u0 = p[0] + t0 * (pq[0] - p[0]), u1 = p[0] + t1 * (pq[0] - p[0]);
                int32_t a = (int32_t)fmax(0.0, floor((fmin(u0, u1) - win->mx) / k) - 1);
                int32_t b = (int32_t)fmin(win->nx - 1.0, floor((fmax(u0, u1) - win->mx) / k) + 1);
                if (a < w->x0[j])
                    w->x0[j] = a;
                if (b > w->x1[j])
                    w->x1[j] = b;
            }
        }
    }
    uint32_t j0 = win->ny, j1 = 0, i0 = win->nx, i1 = 0;
    for (uint32_t j = 0; j < win->ny; j++)
        if (w->x0[j] <= w->x1[j]) {
            j0 = SL_MIN(j0, j), j1 = j;
            i0 = SL_MIN(i0, (uint32_t)w->x0[j]), i1 = SL_MAX(i1, (uint32_t)w->x1[j]);
        }
    if (j0 > j1) { /* nothing undecided: an empty clip */
        j0 = j1 = 0;
        i0 = 1, i1 = 0;
        w->x0[0] = 1, w->x1[0] = 0;
    }
    clip->j0 = j0, clip->j1 = j1, clip->i0 = i0, clip->i1 = i1;
    clip->x0 = w->x0 + j0, clip->x1 = w->x1 + j0;
    return true;
}

/* Does the occluder's box meet the clip's spans? */
static bool box_in_clip(const window *win, double k, const sl_cullmap_clip *clip, const spoly *p)
{
    int64_t j0 = (int64_t)floor((p->y0 - win->my) / k), j1 = (int64_t)floor((p->y1 - win->my) / k);
    int64_t i0 = (int64_t)floor((p->x0 - win->mx) / k), i1 = (int64_t)floor((p->x1 - win->mx) / k);
    j0 = SL_MAX(j0, (int64_t)clip->j0), j1 = SL_MIN(j1, (int64_t)clip->j1);
    for (int64_t j = j0; j <= j1; j++) {
        int64_t a = clip->x0[j - clip->j0], b = clip->x1[j - clip->j0];
        if (a <= b && a <= i1 && b >= i0)
            return true;
    }
    return false;
}

static sl_status sample_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    sample_worker *w = worker;
    sample_shared *s = w->sh;
    const sl_viewcell *vc = &sl_viewcells_data(s->cells)[cell];
    const double k = s->cfg.cell, eps = s->cfg.eps;
    /* the top face and its boundary samples, at the cell's highest eye position */
    double top[4][2];
    int nt;
    if (vc->shape == SL_CELL_PRISM) {
        for (int i = 0; i < 3; i++)
            top[i][0] = vc->tri[i].x, top[i][1] = vc->tri[i].y;
        nt = 3;
    } else {
        const sl_aabb *b = &vc->bounds;
        double q[4][2] = {{b->min.x, b->min.y}, {b->max.x, b->min.y}, {b->max.x, b->max.y}, {b->min.x, b->max.y}};
        memcpy(top, q, sizeof q);
        nt = 4;
    }
    const double zt = vc->z_max;
    w->samples.count = 0;
    for (int e = 0; e < nt; e++) {
        const double *a = top[e], *b = top[(e + 1) % nt];
        double len = hypot(b[0] - a[0], b[1] - a[1]);
        uint32_t n = (uint32_t)fmax(1.0, ceil(len / (2.0 * eps)));
        for (uint32_t j = 0; j < n; j++) {
            double t = (double)j / n;
            double p[3] = {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), zt};
            if (!sl_array_push(&s->a, &w->samples, sizeof p, p, 1))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
        }
    }
    const double(*samples)[3] = w->samples.data;
    const uint32_t ns = (uint32_t)w->samples.count;

    memset(w->state, 0, s->nobj);
    uint32_t undecided = s->nobj;
    if (w->pre_worker) {
        /* the adjustable set is conservative, so is its intersection with this method's set: the
         * objects outside it start hidden and only its members are decided here */
        sl_pvs_cell_result pr = {w->pre_ids, 0, 0};
        sl_status st = s->pre->cell(w->pre_worker, cell, &pr, err);
        if (st != SL_OK)
            return st;
        memset(w->state, 2, s->nobj);
        for (uint32_t q = 0; q < pr.count; q++)
            w->state[pr.ids[q]] = 0;
        undecided = pr.count;
    }
    /* Footprints above the ground (docs/pvs.md): the samples at the cell's top see most only
     * with occluders standing on the ground, as every one of base <= the lowest eye does for the
     * sight lines between points at or above its base. So occluders above the lowest eye are not
     * drawn, and an object reaching below the highest base drawn (tb) is kept (the prefilter,
     * when on, tests it through its stand-in: the cell's set is the intersection). */
    double tb;
    const double zfloor = sl_cell_floor(&s->bases, vc, &tb);
    if (tb > -INFINITY)
        for (uint32_t o = 0; o < s->nobj; o++)
            if (w->state[o] == 0 && s->obj_bounds[o].min.z < tb) {
                w->state[o] = 1;
                undecided--;
            }
    const double cx = 0.5 * ((double)vc->bounds.min.x + vc->bounds.max.x);
    const double cy = 0.5 * ((double)vc->bounds.min.y + vc->bounds.max.y);
    uint64_t written = 0;
    for (uint32_t level = 0; undecided > 0; level++) {
        /* the window: a square of side map0 * 2^level around the cell, snapped to the global grid */
        double half = 0.5 * s->cfg.map0 * ldexp(1.0, (int)SL_MIN(level, 60u));
        double fx0 = floor((fmin(cx - half, vc->bounds.min.x - k) - s->min_x) / k);
        double fy0 = floor((fmin(cy - half, vc->bounds.min.y - k) - s->min_y) / k);
        double fx1 = ceil((fmax(cx + half, vc->bounds.max.x + k) - s->min_x) / k) - 1;
        double fy1 = ceil((fmax(cy + half, vc->bounds.max.y + k) - s->min_y) / k) - 1;
        window win;
        win.i0 = (uint32_t)fmax(0, fx0);
        win.j0 = (uint32_t)fmax(0, fy0);
        uint32_t i1 = (uint32_t)fmin(s->gnx - 1.0, fx1), j1 = (uint32_t)fmin(s->gny - 1.0, fy1);
        win.nx = i1 - win.i0 + 1;
        win.ny = j1 - win.j0 + 1;
        win.all = win.i0 == 0 && win.j0 == 0 && i1 == s->gnx - 1 && j1 == s->gny - 1;
        win.mx = s->min_x + win.i0 * k;
        win.my = s->min_y + win.j0 * k;
        win.x0 = win.mx, win.y0 = win.my;
        win.x1 = win.mx + win.nx * k, win.y1 = win.my + win.ny * k;
        if (!reserve_map(w, win.nx, win.ny))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory for a %u x %u cull map", win.nx, win.ny);
        for (uint32_t j = 0; j < win.ny; j++)
            w->x0[j] = 0, w->x1[j] = (int32_t)win.nx - 1;
        sl_cullmap_clip clip = {0, win.ny - 1, 0, win.nx - 1, w->x0, w->x1};
        /* level 0 decides every object; later levels only need the view channels of the objects
         * still undecided (channel_spans) */
        /* (with the prefilter the first map needs only the channels of the survivors too) */
        const bool channels = s->cfg.channels && (level > 0 || w->pre_worker);
        if (channels && !channel_spans(w, &win, &vc->bounds, &clip))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
        const double cx0 = win.mx + clip.i0 * k, cy0 = win.my + clip.j0 * k;
        const double cx1 = win.mx + (clip.i1 + 1.0) * k, cy1 = win.my + (clip.j1 + 1.0) * k;

        /* candidates: occluders and objects of the buckets under the window */
        next_stamp(w);
        w->cand.count = 0;
        w->keys.count = 0;
        w->objs.count = 0;
        uint32_t r[4];
        bucket_range(s, cx0, cy0, cx1, cy1, r);
        for (uint32_t by = r[1]; by <= r[3]; by++)
            for (uint32_t bx = r[0]; bx <= r[2]; bx++) {
                size_t bi = (size_t)by * s->bnx + bx;
                for (uint32_t q = s->poly_start[bi]; q < s->poly_start[bi + 1]; q++) {
                    uint32_t id = s->poly_ids[q];
                    if (w->poly_stamp[id] == w->stamp)
                        continue;
                    w->poly_stamp[id] = w->stamp;
                    const spoly *p = &s->polys[id];
                    if (p->x1 < cx0 || p->x0 > cx1 || p->y1 < cy0 || p->y0 > cy1 || !(p->base <= zfloor))
                        continue;
                    /* an occluder missing every view channel shades none of the cells read */
                    if (channels && !box_in_clip(&win, k, &clip, p))
                        continue;
                    double dx = fmax(0.0, fmax(p->x0 - cx, cx - p->x1)), dy = fmax(0.0, fmax(p->y0 - cy, cy - p->y1));
                    double key[2] = {hypot(dx, dy), (double)id};
                    if (!sl_array_push(&s->a, &w->keys, sizeof key, key, 1))
                        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
                }
                for (uint32_t q = s->obj_start[bi]; q < s->obj_start[bi + 1]; q++) {
                    uint32_t id = s->obj_ids[q];
                    if (w->obj_stamp[id] == w->stamp)
                        continue;
                    w->obj_stamp[id] = w->stamp;
                    if (!sl_array_push(&s->a, &w->objs, sizeof id, &id, 1))
                        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
                }
            }
        /* front to back from the cell (ties by id: deterministic) */
        if (w->keys.count > 1)
            qsort(w->keys.data, w->keys.count, 2 * sizeof(double), cmp_key);
        if (!sl_array_reserve(&s->a, &w->cand, sizeof(uint32_t), w->keys.count))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sample: out of memory");
        for (size_t q = 0; q < w->keys.count; q++)
            SL_AT(w->cand, uint32_t, w->cand.count++) = (uint32_t)((double *)w->keys.data)[2 * q + 1];

        /* floor and top: the lowest and highest point of any object overlapping each map cell. A
         * map value at or above a cell's top hides all of it, so the rasterizer stops raising it
         * (saturation) — except on the border ring, whose values the horizon test reads above the
         * objects' tops (top +inf there). Empty cells: nothing to hide (top -inf). */
        /* (only the clip's cells: nothing reads the others) */
        for (uint32_t j = clip.j0; j <= clip.j1; j++) {
            const size_t row = (size_t)j * win.nx;
            for (int32_t i = clip.x0[j - clip.j0]; i <= clip.x1[j - clip.j0]; i++) {
                w->floor[row + (size_t)i] = INFINITY;
                w->top[row + (size_t)i] = -INFINITY;
            }
        }
        const uint32_t *objs = w->objs.data;
        for (size_t q = 0; q < w->objs.count; q++) {
            const sl_aabb *b = &s->obj_bounds[objs[q]];
            int64_t i0 = (int64_t)floor((b->min.x - win.mx) / k), ii1 = (int64_t)floor((b->max.x - win.mx) / k);
            int64_t jj0 = (int64_t)floor((b->min.y - win.my) / k), jj1 = (int64_t)floor((b->max.y - win.my) / k);
            jj0 = SL_MAX(jj0, (int64_t)clip.j0), jj1 = SL_MIN(jj1, (int64_t)clip.j1);
            const float bz0 = b->min.z, bz1 = b->max.z;
            for (int64_t j = jj0; j <= jj1; j++) {
                int64_t a = SL_MAX(i0, (int64_t)clip.x0[j - clip.j0]), e = SL_MIN(ii1, (int64_t)clip.x1[j - clip.j0]);
                float *fl = w->floor + (size_t)j * win.nx, *tp = w->top + (size_t)j * win.nx;
                for (int64_t i = a; i <= e; i++) {
                    fl[i] = bz0 < fl[i] ? bz0 : fl[i];
                    tp[i] = bz1 > tp[i] ? bz1 : tp[i];
                }
            }
        }
        if (!win.all) {
            for (uint32_t i = 0; i < win.nx; i++)
                w->top[i] = w->top[(size_t)(win.ny - 1) * win.nx + i] = INFINITY;
            for (uint32_t j = 0; j < win.ny; j++)
                w->top[(size_t)j * win.nx] = w->top[(size_t)j * win.nx + win.nx - 1] = INFINITY;
        }

        /* z(c) = min over samples of max over occluders */
        sl_cullmap_grid g;
        memset(&g, 0, sizeof g);
        g.nx = win.nx;
        g.ny = win.ny;
        g.min_x = win.mx;
        g.min_y = win.my;
        g.cell = k;
        g.margin = SL_MARGIN_GRID_REL * (1.0 + fabs(win.mx) + fabs(win.my));
        g.z = w->zs;
        g.floor = w->floor;
        g.top = w->top;
        g.unsat = w->unsat;
        g.block_shift = BLOCK_SHIFT;
        g.bnx = (win.nx >> BLOCK_SHIFT) + 1;
        for (uint32_t si = 0; si < ns; si++) {
            g.z = si == 0 ? w->acc : w->zs;
            /* sl_cullmap_clear counts the unsaturated cells per block on top of what is there */
            memset(w->unsat, 0, (size_t)g.bnx * ((win.ny >> BLOCK_SHIFT) + 1) * sizeof(uint16_t));
            sl_cullmap_clear(&g, &clip);
            sl_status st = draw_sample(w, &win, samples[si], &g, &clip, &written, err);
            if (st != SL_OK)
                return st;
            if (si > 0) {
                sl_cullmap_grid acc = g;
                acc.z = w->acc;
                sl_cullmap_merge_min(&acc, &g, &clip);
            }
        }

        /* decide the undecided objects this map can decide */
        for (uint32_t o = 0; o < s->nobj; o++) {
            if (w->state[o])
                continue;
            const sl_aabb *b = &s->obj_bounds[o];
            bool inside = b->min.x >= win.x0 && b->max.x <= win.x1 && b->min.y >= win.y0 && b->max.y <= win.y1;
            bool outside = b->max.x < win.x0 || b->min.x > win.x1 || b->max.y < win.y0 || b->min.y > win.y1;
            if (inside || win.all) {
                w->state[o] = hidden_inside(w, &win, b) ? 2 : 1;
                undecided--;
            } else if (!outside && !hidden_inside(w, &win, b)) {
                /* its part inside the map pokes out of the shadows: visible, whatever lies outside */
                w->state[o] = 1;
                undecided--;
            } else if (hidden_by_horizon(w, &win, &vc->bounds, b)) {
                /* the part inside (if any) is hidden, and every sight line to the part outside
                 * leaves the map below the shadows */
                w->state[o] = 2;
                undecided--;
            }
        }
    }
    uint32_t n = 0;
    for (uint32_t o = 0; o < s->nobj; o++)
        if (w->state[o] == 1)
            out->ids[n++] = o;
    out->count = n;
    out->work = written;
    return SL_OK;
}

static void sample_notice(const void *config, char *buf, size_t size)
{
    const sample_config *c = config;
    double bound = c->cell * M_SQRT2 / 2;
    if (c->eps < bound)
        snprintf(buf, size,
                 "eps %g is below cell*sqrt(2)/2 = %g, the thesis' bound for centre-sampled cull maps; the result stays "
                 "conservative only because this rasterizer covers whole cells (docs/pvs.md)",
                 (double)c->eps, bound);
    else
        buf[0] = 0;
}

const sl_pvs_method sl_pvs_method_sample = {
    .name = "sample",
    .summary = "occluder shrinking + point sampling on the cell's top edges, cull maps merged by minimum "
               "(Wonka 2001, ch. 5 and 7); conservative for 2.5D scenes",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(sample_config),
    .configure = sample_configure,
    .prepare = sample_prepare,
    .worker_create = sample_worker_create,
    .cell = sample_cell,
    .worker_destroy = sample_worker_destroy,
    .release = sample_release,
    .notice = sample_notice,
};

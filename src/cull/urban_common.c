/* Shared machinery of the urban 2.5D cullers: occluders from footprints, the view analysis, the
 * max-height pyramid, the polar horizon and heaps. See urban_internal.h for the guarantees. */
#include "urban_internal.h"

#include <float.h>
#include <stdlib.h>

/* ===== small helpers ============================================================================ */

/* A float at most (at least) v: one rounding step is below 2^-24 relative, stepping by 2^-23
 * relative (plus the smallest normal) lands on the right side without a libm call. */
static inline float float_down(double v)
{
    float f = (float)v;
    if ((double)f > v)
        f -= fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

static inline float float_up(double v)
{
    float f = (float)v;
    if ((double)f < v)
        f += fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

static inline double wrap_angle(double a)
{
    a = fmod(a, SL_URBAN_TWO_PI);
    if (a < 0)
        a += SL_URBAN_TWO_PI;
    if (a >= SL_URBAN_TWO_PI)
        a = 0;
    return a;
}

/* ===== building the occluders and the per-cell data ============================================= */

typedef struct vkey {
    uint64_t key;   /* bit patterns of x and y */
    uint32_t edge;
} vkey;

static uint64_t vertex_key(float x, float y)
{
    /* -0 and +0 are the same point */
    if (x == 0.0f)
        x = 0.0f;
    if (y == 0.0f)
        y = 0.0f;
    uint32_t bx, by;
    memcpy(&bx, &x, 4);
    memcpy(&by, &y, 4);
    return ((uint64_t)bx << 32) | by;
}

static int cmp_vkey(const void *a, const void *b)
{
    const vkey *p = a, *q = b;
    if (p->key != q->key)
        return p->key < q->key ? -1 : 1;
    return p->edge < q->edge ? -1 : (p->edge > q->edge);
}

/* First index in sorted keys with key >= k. */
static size_t lower_bound(const vkey *v, size_t n, uint64_t k)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t m = (lo + hi) / 2;
        if (v[m].key < k)
            lo = m + 1;
        else
            hi = m;
    }
    return lo;
}

typedef struct walk_ctx {
    sl_array cells;   /* uint32 */
    sl_array pieces;  /* sl_urban_piece */
    sl_array piece_cell; /* uint32 */
    const sl_allocator *a;
    float ax, ay, bx, by;
    uint32_t edge;
    uint32_t nx;
    bool oom;
} walk_ctx;

static bool walk_cell(void *user, uint32_t cx, uint32_t cy, float t0, float t1)
{
    walk_ctx *w = user;
    uint32_t c = cy * w->nx + cx;
    if (!sl_array_push(w->a, &w->cells, sizeof c, &c, 1)) {
        w->oom = true;
        return false;
    }
    if (t1 > t0) {
        sl_urban_piece p = {w->ax + t0 * (w->bx - w->ax), w->ay + t0 * (w->by - w->ay), w->ax + t1 * (w->bx - w->ax),
                            w->ay + t1 * (w->by - w->ay), w->edge};
        if (!sl_array_push(w->a, &w->pieces, sizeof p, &p, 1) || !sl_array_push(w->a, &w->piece_cell, sizeof c, &c, 1)) {
            w->oom = true;
            return false;
        }
    }
    return true;
}

/* Is the footprint's prism inside its object's box (so any sight line entering the prism has
 * crossed the rendered building)? */
static bool footprint_valid(const sl_urban_fp *f, const sl_aabb *prism, const sl_aabb *obj)
{
    if (!(f->roof > f->base))
        return false;
    if (!obj)
        return true;
    const float *lo = &prism->min.x, *hi = &prism->max.x, *olo = &obj->min.x, *ohi = &obj->max.x;
    for (int k = 0; k < 3; k++) {
        float tol = 1e-2f + 1e-5f * sl_urban_maxf(fabsf(lo[k]), fabsf(hi[k]));
        if (olo[k] > lo[k] + tol || ohi[k] < hi[k] - tol)
            return false;
    }
    return true;
}

/* Per-cell heights and the pyramid, from the grid and the pieces. */
static void compute_heights(sl_urban_scene *u)
{
    const struct sl_grid_t *g = u->grid;
    const sl_aabb *boxes = u->boxes;
    for (uint32_t c = 0; c < u->ncells; c++) {
        float lo = INFINITY;
        const uint32_t *ids = g->ids + g->start[c];
        for (uint32_t k = 0; k < g->count[c]; k++)
            lo = sl_urban_minf(lo, boxes[ids[k]].min.z);
        u->cell_floor[c] = lo;
        float top = g->max_z[c], nf = lo;
        for (uint32_t p = u->cell_piece_start[c]; p < u->cell_piece_start[c + 1]; p++) {
            const sl_urban_fp *f = &u->fps[u->edges[u->pieces[p].edge].fp];
            top = sl_urban_maxf(top, f->roof);
            nf = sl_urban_minf(nf, f->base);
        }
        u->cell_top[c] = top;
        u->node_floor[c] = nf;
    }
    /* the world box: object boxes, the grid rectangle, the footprints' bases and roofs */
    double w[2][3] = {{u->min_x, u->min_y, INFINITY}, {u->min_x + u->nx * u->cell, u->min_y + u->ny * u->cell, -INFINITY}};
    for (uint32_t i = 0; i < u->object_count; i++) {
        const float *lo = &boxes[i].min.x, *hi = &boxes[i].max.x;
        if (!(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]))
            continue; /* empty */
        for (int a = 0; a < 3; a++) {
            w[0][a] = fmin(w[0][a], lo[a]);
            w[1][a] = fmax(w[1][a], hi[a]);
        }
    }
    for (uint32_t f = 0; f < u->fp_count; f++) {
        w[0][2] = fmin(w[0][2], fmin(u->fps[f].base, u->fps[f].roof));
        w[1][2] = fmax(w[1][2], fmax(u->fps[f].base, u->fps[f].roof));
    }
    if (!(w[0][2] <= w[1][2]))
        w[0][2] = w[1][2] = 0;
    memcpy(u->world, w, sizeof w);
    memcpy(u->pyr_top, u->cell_top, (size_t)u->ncells * sizeof(float));
    memcpy(u->pyr_floor, u->node_floor, (size_t)u->ncells * sizeof(float));
    for (uint32_t l = 1; l < u->levels; l++) {
        uint32_t pnx = u->level_nx[l - 1], pny = u->level_ny[l - 1];
        for (uint32_t j = 0; j < u->level_ny[l]; j++)
            for (uint32_t i = 0; i < u->level_nx[l]; i++) {
                float top = -INFINITY, fl = INFINITY;
                for (uint32_t dj = 0; dj < 2; dj++)
                    for (uint32_t di = 0; di < 2; di++) {
                        uint32_t ci = 2 * i + di, cj = 2 * j + dj;
                        if (ci >= pnx || cj >= pny)
                            continue;
                        uint32_t id = u->level_base[l - 1] + cj * pnx + ci;
                        top = sl_urban_maxf(top, u->pyr_top[id]);
                        fl = sl_urban_minf(fl, u->pyr_floor[id]);
                    }
                uint32_t id = u->level_base[l] + j * u->level_nx[l] + i;
                u->pyr_top[id] = top;
                u->pyr_floor[id] = fl;
            }
    }
}

/* The objects not wholly inside the grid's area: the cells do not cover all of them. */
static void find_outside(sl_urban_scene *u)
{
    const struct sl_grid_t *g = u->grid;
    u->outside_count = 0;
    for (uint32_t i = 0; i < u->object_count; i++) {
        const sl_aabb *b = &u->boxes[i];
        if (b->min.x < g->min_x || b->min.y < g->min_y || b->max.x > g->max_x || b->max.y > g->max_y)
            u->outside[u->outside_count++] = i;
    }
}

void sl_urban_add_outside(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame,
                          uint32_t *out, uint32_t *n)
{
    for (uint32_t k = 0; k < u->outside_count; k++) {
        uint32_t o = u->outside[k];
        if (stamp[o] == frame)
            continue;
        stamp[o] = frame;
        if (sl_urban_box_in_frustum(v, &u->boxes[o]))
            out[(*n)++] = o;
    }
}

/* Footprint validity against the current object boxes. The footprint of a DYNAMIC object is never
 * used: footprints stay where they were placed while their object moves, and a motion that keeps
 * the object's box (a half turn about its centre) would leave a stale prism inside the box
 * (tests/test_urban_oracle.c, test_moving_occluder; docs/motion.md). */
static void validate_footprints(sl_urban_scene *u)
{
    const sl_object_rec *objs = sl_scene_objects(u->scene);
    for (uint32_t f = 0; f < u->fp_count; f++) {
        sl_urban_fp *fp = &u->fps[f];
        sl_footprint_view v = sl_scene_footprint(u->scene, f);
        sl_aabb prism = sl_aabb_empty();
        for (uint32_t k = 0; k < v.vertex_count; k++)
            sl_aabb_grow(&prism, (sl_vec3){v.xy[2 * k], v.xy[2 * k + 1], v.base_z});
        prism.max.z = v.roof_z;
        const sl_aabb *ob = fp->object < u->object_count ? &u->boxes[fp->object] : NULL;
        fp->valid = footprint_valid(fp, &prism, ob) && !(ob && (objs[fp->object].flags & SL_OBJECT_DYNAMIC));
        fp->box = prism;
        if (ob)
            sl_aabb_merge(&fp->box, ob);
    }
}

static sl_status build_csr(const sl_allocator *a, uint32_t ncells, const uint32_t *cell_of, const uint32_t *val,
                           size_t n, uint32_t **start, uint32_t **list, sl_error *err)
{
    *start = sl_calloc(a, (size_t)ncells + 1, sizeof(uint32_t));
    *list = sl_alloc(a, (n ? n : 1) * sizeof(uint32_t));
    if (!*start || !*list)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for cell lists");
    for (size_t i = 0; i < n; i++)
        (*start)[cell_of[i] + 1]++;
    for (uint32_t c = 0; c < ncells; c++)
        (*start)[c + 1] += (*start)[c];
    uint32_t *fill = sl_alloc(a, (size_t)ncells * sizeof(uint32_t) + 4);
    if (!fill)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for cell lists");
    memcpy(fill, *start, (size_t)ncells * sizeof(uint32_t));
    for (size_t i = 0; i < n; i++)
        (*list)[fill[cell_of[i]]++] = val ? val[i] : (uint32_t)i;
    sl_free(a, fill, (size_t)ncells * sizeof(uint32_t) + 4);
    return SL_OK;
}

void sl_urban_scene_free(sl_urban_scene *u)
{
    if (!u)
        return;
    const sl_allocator *a = &u->alloc;
    sl_grid_destroy(u->grid);
    size_t nc = u->ncells;
    sl_free(a, u->cell_floor, nc * sizeof(float));
    sl_free(a, u->cell_top, nc * sizeof(float));
    sl_free(a, u->node_floor, nc * sizeof(float));
    sl_free(a, u->fps, (u->fp_count ? u->fp_count : 1) * sizeof(sl_urban_fp));
    sl_free(a, u->edges, (u->edge_count ? u->edge_count : 1) * sizeof(sl_urban_edge));
    sl_free(a, u->edge_cells, (u->edge_cell_total ? u->edge_cell_total : 1) * sizeof(uint32_t));
    sl_free(a, u->cell_edge_start, (nc + 1) * sizeof(uint32_t));
    sl_free(a, u->cell_edges, (u->edge_cell_total ? u->edge_cell_total : 1) * sizeof(uint32_t));
    if (u->cell_fp_start)
        sl_free(a, u->cell_fps, (u->cell_fp_start[nc] ? u->cell_fp_start[nc] : 1) * sizeof(uint32_t));
    sl_free(a, u->cell_fp_start, (nc + 1) * sizeof(uint32_t));
    sl_free(a, u->cell_piece_start, (nc + 1) * sizeof(uint32_t));
    sl_free(a, u->pieces, (u->piece_count ? u->piece_count : 1) * sizeof(sl_urban_piece));
    sl_free(a, u->pyr_top, (size_t)u->node_count * sizeof(float));
    sl_free(a, u->pyr_floor, (size_t)u->node_count * sizeof(float));
    sl_free(a, u->boxes, (u->object_count ? u->object_count : 1) * sizeof(sl_aabb));
    sl_free(a, u->footprint_of, (u->object_count ? u->object_count : 1) * sizeof(uint32_t));
    sl_free(a, u->outside, (u->object_count ? u->object_count : 1) * sizeof(uint32_t));
    memset(u, 0, sizeof *u);
}

sl_status sl_urban_scene_build(sl_scene scene, float cell, const sl_allocator *alloc, sl_urban_scene *u, sl_error *err)
{
    memset(u, 0, sizeof *u);
    u->alloc = *sl_alloc_or_default(alloc);
    const sl_allocator *a = &u->alloc;
    u->scene = scene;
    sl_status st;
    sl_grid_options go = {0};
    go.cell_size = cell;
    go.alloc = a;
    if ((st = sl_grid_build(scene, &go, &u->grid, err)) != SL_OK)
        return st;
    const struct sl_grid_t *g = u->grid;
    u->nx = g->nx;
    u->ny = g->ny;
    u->ncells = g->ncells;
    u->min_x = g->min_x;
    u->min_y = g->min_y;
    u->cell = g->cell;
    /* the grid maps float points to cells with float arithmetic: allow its rounding everywhere */
    u->margin = 8.0 * FLT_EPSILON *
                    (sl_urban_max(sl_urban_max(fabs((double)g->min_x), fabs((double)g->max_x)),
                          sl_urban_max(fabs((double)g->min_y), fabs((double)g->max_y))) +
                     g->cell) +
                SL_MARGIN_GRID_REL;
    const size_t nc = u->ncells;
    u->object_count = sl_scene_object_count(scene);
    const size_t no = u->object_count ? u->object_count : 1;
    u->cell_floor = sl_alloc(a, nc * sizeof(float));
    u->cell_top = sl_alloc(a, nc * sizeof(float));
    u->node_floor = sl_alloc(a, nc * sizeof(float));
    u->boxes = sl_alloc(a, no * sizeof(sl_aabb));
    u->footprint_of = sl_alloc(a, no * sizeof(uint32_t));
    u->outside = sl_alloc(a, no * sizeof(uint32_t));
    if (!u->cell_floor || !u->cell_top || !u->node_floor || !u->boxes || !u->footprint_of || !u->outside) {
        sl_urban_scene_free(u);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for %zu cells", nc);
    }
    if (u->object_count)
        memcpy(u->boxes, sl_scene_object_bounds_array(scene), u->object_count * sizeof(sl_aabb));
    for (uint32_t i = 0; i < u->object_count; i++)
        u->footprint_of[i] = SL_NONE;

    /* footprints and their façade edges (the top edge of each façade quad) */
    u->fp_count = sl_scene_footprint_count(scene);
    uint32_t ne = 0;
    for (uint32_t f = 0; f < u->fp_count; f++)
        ne += sl_scene_footprint(scene, f).vertex_count;
    u->edge_count = ne;
    u->fps = sl_calloc(a, u->fp_count ? u->fp_count : 1, sizeof(sl_urban_fp));
    u->edges = sl_calloc(a, ne ? ne : 1, sizeof(sl_urban_edge));
    vkey *starts = sl_alloc(a, (ne ? ne : 1) * sizeof(vkey)), *ends = sl_alloc(a, (ne ? ne : 1) * sizeof(vkey));
    if (!u->fps || !u->edges || !starts || !ends) {
        sl_free(a, starts, (ne ? ne : 1) * sizeof(vkey));
        sl_free(a, ends, (ne ? ne : 1) * sizeof(vkey));
        sl_urban_scene_free(u);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for %u occluder edges", ne);
    }
    uint32_t e = 0;
    for (uint32_t f = 0; f < u->fp_count; f++) {
        sl_footprint_view v = sl_scene_footprint(scene, f);
        sl_urban_fp *fp = &u->fps[f];
        fp->object = v.object;
        fp->first_edge = e;
        fp->edge_count = v.vertex_count;
        fp->roof = v.roof_z;
        fp->base = v.base_z;
        if (v.object < u->object_count && u->footprint_of[v.object] == SL_NONE)
            u->footprint_of[v.object] = f;
        for (uint32_t k = 0; k < v.vertex_count; k++, e++) {
            sl_vec3 quad[4];
            sl_footprint_facade(&v, k, quad); /* base a, base b, roof b, roof a */
            sl_urban_edge *ed = &u->edges[e];
            ed->ax = quad[3].x;
            ed->ay = quad[3].y;
            ed->bx = quad[2].x;
            ed->by = quad[2].y;
            ed->fp = f;
            ed->next = fp->first_edge + (k + 1) % v.vertex_count;
            ed->prev = fp->first_edge + (k + v.vertex_count - 1) % v.vertex_count;
            ed->alt_next[0] = ed->alt_next[1] = ed->alt_prev[0] = ed->alt_prev[1] = SL_NONE;
            starts[e] = (vkey){vertex_key(ed->ax, ed->ay), e};
            ends[e] = (vkey){vertex_key(ed->bx, ed->by), e};
        }
    }
    validate_footprints(u);
    /* junctions: edges of other footprints that continue exactly at a shared vertex */
    qsort(starts, ne, sizeof(vkey), cmp_vkey);
    qsort(ends, ne, sizeof(vkey), cmp_vkey);
    for (e = 0; e < ne; e++) {
        sl_urban_edge *ed = &u->edges[e];
        uint64_t kb = vertex_key(ed->bx, ed->by), ka = vertex_key(ed->ax, ed->ay);
        uint32_t m = 0;
        for (size_t i = lower_bound(starts, ne, kb); i < ne && starts[i].key == kb && m < 2; i++)
            if (u->edges[starts[i].edge].fp != ed->fp)
                ed->alt_next[m++] = starts[i].edge;
        m = 0;
        for (size_t i = lower_bound(ends, ne, ka); i < ne && ends[i].key == ka && m < 2; i++)
            if (u->edges[ends[i].edge].fp != ed->fp)
                ed->alt_prev[m++] = ends[i].edge;
    }
    sl_free(a, starts, (ne ? ne : 1) * sizeof(vkey));
    sl_free(a, ends, (ne ? ne : 1) * sizeof(vkey));

    /* the cells each edge passes through, and its pieces per cell */
    walk_ctx w;
    memset(&w, 0, sizeof w);
    w.a = a;
    w.nx = u->nx;
    for (e = 0; e < ne && !w.oom; e++) {
        sl_urban_edge *ed = &u->edges[e];
        ed->cell_first = (uint32_t)w.cells.count;
        w.ax = ed->ax, w.ay = ed->ay, w.bx = ed->bx, w.by = ed->by, w.edge = e;
        sl_grid_walk_segment(u->grid, (sl_vec2){ed->ax, ed->ay}, (sl_vec2){ed->bx, ed->by}, walk_cell, &w);
        ed->cell_count = (uint32_t)w.cells.count - ed->cell_first;
    }
    st = SL_OK;
    if (w.oom || w.cells.count > UINT32_MAX)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for the occluders' cells");
    /* exact-size copies: the cells per edge, and per cell the edges */
    if (st == SL_OK) {
        size_t n = w.cells.count;
        u->edge_cell_total = n;
        u->edge_cells = sl_alloc(a, (n ? n : 1) * sizeof(uint32_t));
        uint32_t *edge_of = sl_alloc(a, (n ? n : 1) * sizeof(uint32_t));
        if (!u->edge_cells || !edge_of)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory");
        else {
            if (n)
                memcpy(u->edge_cells, w.cells.data, n * sizeof(uint32_t));
            for (e = 0; e < ne; e++)
                for (uint32_t k = 0; k < u->edges[e].cell_count; k++)
                    edge_of[u->edges[e].cell_first + k] = e;
            st = build_csr(a, u->ncells, u->edge_cells, edge_of, n, &u->cell_edge_start, &u->cell_edges, err);
        }
        sl_free(a, edge_of, (n ? n : 1) * sizeof(uint32_t));
    }
    /* pieces grouped by cell */
    if (st == SL_OK) {
        size_t n = w.pieces.count;
        uint32_t *order = NULL;
        if (n > UINT32_MAX)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: too many occluder pieces");
        else
            st = build_csr(a, u->ncells, w.piece_cell.data, NULL, n, &u->cell_piece_start, &order, err);
        if (st == SL_OK) {
            u->pieces = sl_alloc(a, (n ? n : 1) * sizeof(sl_urban_piece));
            if (!u->pieces)
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for pieces");
            else {
                for (size_t i = 0; i < n; i++)
                    u->pieces[i] = SL_AT(w.pieces, sl_urban_piece, order[i]);
                u->piece_count = (uint32_t)n;
            }
        }
        sl_free(a, order, (n ? n : 1) * sizeof(uint32_t));
    }
    sl_array_free(a, &w.pieces, sizeof(sl_urban_piece));
    sl_array_free(a, &w.piece_cell, sizeof(uint32_t));
    sl_array_free(a, &w.cells, sizeof(uint32_t));
    /* cell -> footprints whose box overlaps it (for the eye-inside test) */
    if (st == SL_OK) {
        sl_array cl = {0}, fl = {0};
        for (uint32_t f = 0; f < u->fp_count && st == SL_OK; f++) {
            const sl_aabb *b = &u->fps[f].box;
            uint32_t i0 = sl_grid_coord(b->min.x, g->min_x, g->inv_cell, g->nx);
            uint32_t i1 = sl_grid_coord(b->max.x, g->min_x, g->inv_cell, g->nx);
            uint32_t j0 = sl_grid_coord(b->min.y, g->min_y, g->inv_cell, g->ny);
            uint32_t j1 = sl_grid_coord(b->max.y, g->min_y, g->inv_cell, g->ny);
            for (uint32_t j = j0; j <= j1 && st == SL_OK; j++)
                for (uint32_t i = i0; i <= i1; i++) {
                    uint32_t c = j * g->nx + i;
                    if (!sl_array_push(a, &cl, 4, &c, 1) || !sl_array_push(a, &fl, 4, &f, 1)) {
                        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory");
                        break;
                    }
                }
        }
        if (st == SL_OK)
            st = build_csr(a, u->ncells, cl.data, fl.data, cl.count, &u->cell_fp_start, &u->cell_fps, err);
        sl_array_free(a, &cl, 4);
        sl_array_free(a, &fl, 4);
    }
    /* the pyramid */
    if (st == SL_OK) {
        uint32_t lnx = u->nx, lny = u->ny, total = 0, l = 0;
        for (;;) {
            u->level_nx[l] = lnx;
            u->level_ny[l] = lny;
            u->level_base[l] = total;
            total += lnx * lny;
            l++;
            if ((lnx == 1 && lny == 1) || l == 32)
                break;
            lnx = (lnx + 1) / 2;
            lny = (lny + 1) / 2;
        }
        u->levels = l;
        u->node_count = total;
        u->pyr_top = sl_alloc(a, (size_t)total * sizeof(float));
        u->pyr_floor = sl_alloc(a, (size_t)total * sizeof(float));
        if (!u->pyr_top || !u->pyr_floor)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for the pyramid");
    }
    if (st != SL_OK) {
        sl_urban_scene_free(u);
        return st;
    }
    compute_heights(u);
    find_outside(u);
    u->memory = nc * 3 * sizeof(float) + (size_t)u->fp_count * sizeof(sl_urban_fp) +
                (size_t)ne * sizeof(sl_urban_edge) + u->edge_cell_total * 2 * sizeof(uint32_t) +
                (size_t)u->piece_count * sizeof(sl_urban_piece) + (nc + 1) * 3 * sizeof(uint32_t) +
                (size_t)u->node_count * 2 * sizeof(float);
    return SL_OK;
}

sl_status sl_urban_scene_refresh(sl_urban_scene *u, sl_error *err)
{
    const sl_aabb *now = sl_scene_object_bounds_array(u->scene);
    sl_array moved = {0};
    for (uint32_t i = 0; i < u->object_count; i++)
        if (memcmp(&now[i], &u->boxes[i], sizeof(sl_aabb)) != 0 && !sl_array_push(&u->alloc, &moved, 4, &i, 1)) {
            sl_array_free(&u->alloc, &moved, 4);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory");
        }
    sl_status st = SL_OK;
    if (moved.count) {
        st = sl_grid_update_objects(u->grid, u->scene, moved.data, (uint32_t)moved.count, err);
        if (st == SL_OK) {
            for (size_t k = 0; k < moved.count; k++) {
                uint32_t i = SL_AT(moved, uint32_t, k);
                u->boxes[i] = now[i];
            }
            validate_footprints(u);
            compute_heights(u);
            find_outside(u);
        }
    }
    sl_array_free(&u->alloc, &moved, 4);
    return st;
}

/* ===== the view ================================================================================= */

void sl_urban_view_make(const sl_urban_scene *u, const sl_view *view, sl_urban_view *v)
{
    /* the far plane just beyond the world box's farthest corner: a point of the frustum within
     * that distance of the eye has a depth within it too, so nothing the methods see is lost */
    sl_view bounded;
    const sl_view *cam = view;
    double reach2 = 0, e3[3] = {view->eye.x, view->eye.y, view->eye.z};
    for (int a = 0; a < 3; a++) {
        double d = fmax(fabs(u->world[0][a] - e3[a]), fabs(u->world[1][a] - e3[a]));
        reach2 += d * d;
    }
    double reach = sqrt(reach2) * (1 + 1e-3) + 1.0;
    reach = fmax(reach, 2.0 * view->near_plane);
    if (isfinite(reach) && reach < view->far_plane && sl_view_with_far(view, reach, &bounded, NULL) == SL_OK)
        cam = &bounded;
    memset(v, 0, sizeof *v);
    v->perspective = cam->projection == SL_PERSPECTIVE;
    v->eye[0] = cam->eye.x;
    v->eye[1] = cam->eye.y;
    v->eye[2] = cam->eye.z;
    sl_vec3 f = cam->forward;
    v->forward[0] = f.x, v->forward[1] = f.y, v->forward[2] = f.z;
    sl_frustum fr = cam->frustum;
    for (int i = 0; i < 6; i++) {
        v->planes[i] = fr.planes[i];
        v->slack[i] = sl_margin_plane_slack(fr.planes[i].d);
    }
    /* azimuth range of the viewing cone: the hull of its four edges, unless it reaches the vertical */
    bool up_in = true, down_in = true;
    for (int i = 0; i < 4; i++) {
        up_in &= fr.planes[i].c >= -1e-5f;
        down_in &= fr.planes[i].c <= 1e-5f;
    }
    double dirs[4][3], far = 0, cmin = 1;
    bool degenerate = false;
    for (int k = 0; k < 4; k++) {
        for (int q = 0; q < 3; q++)
            dirs[k][q] = (double)(&fr.corners[4 + k].x)[q] - v->eye[q];
        double len = sqrt(dirs[k][0] * dirs[k][0] + dirs[k][1] * dirs[k][1] + dirs[k][2] * dirs[k][2]);
        far = sl_urban_max(far, len);
        if (len > 0)
            cmin = sl_urban_min(cmin, (dirs[k][0] * f.x + dirs[k][1] * f.y + dirs[k][2] * f.z) / len);
        if (hypot(dirs[k][0], dirs[k][1]) < 1e-9 * (1 + len))
            degenerate = true;
    }
    v->far = far * (1 + 1e-6) + 1e-3;
    v->near_guard = cam->near_plane / sl_urban_max(cmin, 1e-3) * SL_MARGIN_NEAR_FACTOR + 1e-3; /* core/margins.h */
    v->full_az = !v->perspective || up_in || down_in || degenerate;
    if (!v->full_az) {
        double rx = 0, ry = 0;
        for (int k = 0; k < 4; k++) {
            double h = hypot(dirs[k][0], dirs[k][1]);
            rx += dirs[k][0] / h;
            ry += dirs[k][1] / h;
        }
        double amin = INFINITY, amax = -INFINITY;
        for (int k = 0; k < 4; k++) {
            double rel = atan2(rx * dirs[k][1] - ry * dirs[k][0], rx * dirs[k][0] + ry * dirs[k][1]);
            amin = sl_urban_min(amin, rel);
            amax = sl_urban_max(amax, rel);
        }
        const double m = 1e-5; /* the float corners against the exact frustum */
        double span = amax - amin + 2 * m;
        if (!(span < M_PI - 1e-3) || !(rx != 0 || ry != 0))
            v->full_az = true;
        else {
            v->az0 = wrap_angle(atan2(ry, rx) + amin - m);
            v->az_span = span;
            double u0x = cos(v->az0), u0y = sin(v->az0), a1 = v->az0 + span, u1x = cos(a1), u1y = sin(a1);
            v->paz0 = sl_urban_paz(u0x, u0y);
            v->paz_span = sl_urban_paz_wrap(sl_urban_paz(u1x, u1y) - v->paz0);
            v->cone[0][0] = -u0y, v->cone[0][1] = u0x;
            v->cone[0][2] = -(v->cone[0][0] * v->eye[0] + v->cone[0][1] * v->eye[1]);
            v->cone[1][0] = u1y, v->cone[1][1] = -u1x;
            v->cone[1][2] = -(v->cone[1][0] * v->eye[0] + v->cone[1][1] * v->eye[1]);
        }
    }
    /* the ground plan: convex hull of the eight corners */
    double pts[16], hull[16];
    for (int k = 0; k < 8; k++) {
        pts[2 * k] = fr.corners[k].x;
        pts[2 * k + 1] = fr.corners[k].y;
    }
    int h = (int)sl_convex_hull8(pts, 8, hull);
    v->npoly = h;
    memcpy(v->poly, hull, (size_t)h * 2 * sizeof hull[0]);
}

bool sl_urban_box_in_frustum(const sl_urban_view *v, const sl_aabb *b)
{
    return sl_frustum_classify_box(v->planes, v->slack, b, 0x3fu, false, NULL) >= 0;
}

bool sl_urban_frustum_spans(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *j0, uint32_t *j1, int32_t *x0,
                            int32_t *x1)
{
    const double m = u->margin + 1e-3 + SL_MARGIN_GRID_REL * (fabs(v->eye[0]) + fabs(v->eye[1]));
    double ylo = INFINITY, yhi = -INFINITY;
    for (int k = 0; k < v->npoly; k++) {
        ylo = sl_urban_min(ylo, v->poly[k][1]);
        yhi = sl_urban_max(yhi, v->poly[k][1]);
    }
    double fj0 = floor((ylo - m - u->min_y) / u->cell), fj1 = floor((yhi + m - u->min_y) / u->cell);
    fj0 = sl_urban_max(fj0, 0.0);
    fj1 = sl_urban_min(fj1, (double)u->ny - 1);
    if (!(fj0 <= fj1))
        return false;
    *j0 = (uint32_t)fj0;
    *j1 = (uint32_t)fj1;
    bool any = false;
    for (uint32_t j = *j0; j <= *j1; j++) {
        double b0 = u->min_y + j * u->cell - m, b1 = u->min_y + (j + 1.0) * u->cell + m;
        double xlo = INFINITY, xhi = -INFINITY;
        for (int k = 0; k < v->npoly; k++) {
            const double *p = v->poly[k], *q = v->poly[(k + 1) % v->npoly];
            /* the part of edge p-q inside the band */
            double t0 = 0, t1 = 1, dy = q[1] - p[1];
            if (dy == 0) {
                if (p[1] < b0 || p[1] > b1)
                    continue;
            } else {
                double ta = (b0 - p[1]) / dy, tb = (b1 - p[1]) / dy;
                if (ta > tb) {
                    double t = ta;
                    ta = tb;
                    tb = t;
                }
                t0 = sl_urban_max(t0, ta);
                t1 = sl_urban_min(t1, tb);
                if (t0 > t1)
                    continue;
            }
            double xa = p[0] + t0 * (q[0] - p[0]), xb = p[0] + t1 * (q[0] - p[0]);
            xlo = sl_urban_min(xlo, sl_urban_min(xa, xb));
            xhi = sl_urban_max(xhi, sl_urban_max(xa, xb));
        }
        int32_t *a = &x0[j - *j0], *b = &x1[j - *j0];
        *a = 1;
        *b = 0;
        if (!(xlo <= xhi))
            continue;
        double fi0 = sl_urban_max(floor((xlo - m - u->min_x) / u->cell), 0.0);
        double fi1 = sl_urban_min(floor((xhi + m - u->min_x) / u->cell), (double)u->nx - 1);
        if (fi0 <= fi1) {
            *a = (int32_t)fi0;
            *b = (int32_t)fi1;
            any = true;
        }
    }
    return any;
}

void sl_urban_exclude(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame)
{
    const double g = v->near_guard + u->margin;
    const double ex = v->eye[0], ey = v->eye[1], ez = v->eye[2];
    double fi = floor((ex - u->min_x) / u->cell), fj = floor((ey - u->min_y) / u->cell);
    double r = ceil(g / u->cell) + 1;
    double i0 = sl_urban_max(fi - r, 0), i1 = sl_urban_min(fi + r, (double)u->nx - 1);
    double j0 = sl_urban_max(fj - r, 0), j1 = sl_urban_min(fj + r, (double)u->ny - 1);
    if (!(i0 <= i1) || !(j0 <= j1))
        return;
    for (uint32_t j = (uint32_t)j0; j <= (uint32_t)j1; j++)
        for (uint32_t i = (uint32_t)i0; i <= (uint32_t)i1; i++) {
            uint32_t c = j * u->nx + i;
            for (uint32_t k = u->cell_fp_start[c]; k < u->cell_fp_start[c + 1]; k++) {
                uint32_t f = u->cell_fps[k];
                const sl_aabb *b = &u->fps[f].box;
                if (ex >= b->min.x - g && ex <= b->max.x + g && ey >= b->min.y - g && ey <= b->max.y + g &&
                    ez >= b->min.z - g && ez <= b->max.z + g)
                    stamp[f] = frame;
            }
        }
}

double sl_urban_seg_dist(const sl_urban_view *v, double x0, double y0, double x1, double y1)
{
    double dx = x1 - x0, dy = y1 - y0, px = v->eye[0] - x0, py = v->eye[1] - y0;
    double l2 = dx * dx + dy * dy, t = l2 > 0 ? (px * dx + py * dy) / l2 : 0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    double qx = px - t * dx, qy = py - t * dy;
    return sqrt(qx * qx + qy * qy);
}

int sl_urban_edge_mode(const sl_urban_scene *u, uint32_t e, const sl_urban_view *v, const uint32_t *excluded,
                       uint32_t frame)
{
    const sl_urban_edge *ed = &u->edges[e];
    const sl_urban_fp *f = &u->fps[ed->fp];
    if (!f->valid || excluded[ed->fp] == frame)
        return 0;
    double ax = ed->ax - v->eye[0], ay = ed->ay - v->eye[1], bx = ed->bx - v->eye[0], by = ed->by - v->eye[1];
    double cr = ax * by - ay * bx, tol = 1e-9 * sqrt((ax * ax + ay * ay) * (bx * bx + by * by)) + 1e-12;
    int mode = (double)f->roof > v->eye[2] ? (cr < -tol ? 1 : 0) : (cr > tol ? -1 : 0);
    if (mode && sl_urban_seg_dist(v, ed->ax, ed->ay, ed->bx, ed->by) < v->near_guard)
        return 0;
    return mode;
}

sl_shadow_edge sl_urban_shadow_edge(const sl_urban_scene *u, uint32_t e, int mode)
{
    const sl_urban_edge *ed = &u->edges[e];
    const sl_urban_fp *f = &u->fps[ed->fp];
    sl_shadow_edge s;
    if (mode >= 0) {
        s.ax = ed->ax, s.ay = ed->ay, s.bx = ed->bx, s.by = ed->by;
    } else {
        s.ax = ed->bx, s.ay = ed->by, s.bx = ed->ax, s.by = ed->ay;
    }
    s.az = s.bz = f->roof;
    s.base = f->base;
    return s;
}

uint32_t sl_urban_chain_step(const sl_urban_scene *u, uint32_t e, int mode, int dir, const sl_urban_view *v,
                             const uint32_t *excluded, uint32_t frame, const sl_urban_mode_cache *cache)
{
    const sl_urban_edge *ed = &u->edges[e];
    /* oriented forward along the chain: in mode +1 the CCW successors, in mode -1 the predecessors */
    bool succ = (mode > 0) == (dir > 0);
    uint32_t cand[3] = {succ ? ed->next : ed->prev, succ ? ed->alt_next[0] : ed->alt_prev[0],
                        succ ? ed->alt_next[1] : ed->alt_prev[1]};
    uint32_t ok[3], nok = 0;
    for (int k = 0; k < 3; k++)
        if (cand[k] != SL_NONE && cand[k] != e &&
            sl_urban_edge_mode_cached(u, cand[k], v, excluded, frame, cache) == mode)
            ok[nok++] = cand[k];
    if (nok < 2)
        return nok ? ok[0] : SL_NONE; /* no choice to make */
    double dex = (ed->bx - ed->ax) * mode, dey = (ed->by - ed->ay) * mode;
    uint32_t best = SL_NONE;
    double best_turn = INFINITY;
    for (uint32_t k = 0; k < nok; k++) {
        uint32_t c = ok[k];
        const sl_urban_edge *cd = &u->edges[c];
        double dcx = (cd->bx - cd->ax) * mode, dcy = (cd->by - cd->ay) * mode;
        /* the turn from the earlier to the later edge of the pair; the rightmost one traces the
         * outline of the union of the footprints */
        double turn = dir > 0 ? atan2(dex * dcy - dey * dcx, dex * dcx + dey * dcy)
                              : atan2(dcx * dey - dcy * dex, dcx * dex + dcy * dey);
        if (turn < best_turn) {
            best_turn = turn;
            best = c;
        }
    }
    return best;
}

/* ===== polar helpers ============================================================================ */

bool sl_urban_rect_az(const double eye[3], double x0, double y0, double x1, double y1, double *a0, double *span)
{
    double ex = eye[0], ey = eye[1];
    if (ex >= x0 && ex <= x1 && ey >= y0 && ey <= y1) {
        *a0 = 0;
        *span = SL_URBAN_CIRCLE;
        return false;
    }
    /* the two corners the tangents from the eye touch, by the eye's region around the rectangle */
    double px, py, qx, qy; /* p: the most clockwise corner, q: the most counter-clockwise */
    if (ex < x0) {
        if (ey < y0)
            px = x1, py = y0, qx = x0, qy = y1;
        else if (ey > y1)
            px = x0, py = y0, qx = x1, qy = y1;
        else
            px = x0, py = y0, qx = x0, qy = y1;
    } else if (ex > x1) {
        if (ey < y0)
            px = x1, py = y1, qx = x0, qy = y0;
        else if (ey > y1)
            px = x0, py = y1, qx = x1, qy = y0;
        else
            px = x1, py = y1, qx = x1, qy = y0;
    } else if (ey < y0)
        px = x1, py = y0, qx = x0, qy = y0;
    else
        px = x0, py = y1, qx = x1, qy = y1;
    double ap = sl_urban_paz(px - ex, py - ey), aq = sl_urban_paz(qx - ex, qy - ey);
    double s = aq - ap;
    if (s < 0)
        s += SL_URBAN_CIRCLE;
    const double m = 1e-9;
    *a0 = sl_urban_paz_wrap(ap - m);
    *span = s + 2 * m;
    return true;
}

void sl_urban_rect_dist(const double eye[3], double x0, double y0, double x1, double y1, double *dmin, double *dmax)
{
    double ex = eye[0], ey = eye[1];
    double dx = ex < x0 ? x0 - ex : (ex > x1 ? ex - x1 : 0), dy = ey < y0 ? y0 - ey : (ey > y1 ? ey - y1 : 0);
    *dmin = sqrt(dx * dx + dy * dy);
    double fx = sl_urban_max(fabs(ex - x0), fabs(ex - x1)), fy = sl_urban_max(fabs(ey - y0), fabs(ey - y1));
    *dmax = sqrt(fx * fx + fy * fy);
}

bool sl_urban_az_meets(const sl_urban_view *v, double a0, double span)
{
    if (v->full_az || span >= SL_URBAN_CIRCLE)
        return true;
    double d = sl_urban_paz_wrap(a0 - v->paz0);
    return d <= v->paz_span || d + span >= SL_URBAN_CIRCLE;
}

/* ===== the horizon ============================================================================== */

#define H_NONE (-INFINITY) /* below every slope */

sl_status sl_horizon_init(sl_horizon *h, uint32_t bins, bool record, const sl_allocator *alloc, sl_error *err)
{
    memset(h, 0, sizeof *h);
    h->alloc = *sl_alloc_or_default(alloc);
    uint32_t n = 16;
    while (n < bins && n < (1u << 24))
        n *= 2;
    h->n = n;
    h->binw = SL_URBAN_CIRCLE / n;
    const sl_allocator *a = &h->alloc;
    h->hmin = sl_alloc(a, 2 * (size_t)n * sizeof(float));
    h->hmax = sl_alloc(a, 2 * (size_t)n * sizeof(float));
    h->hbot = sl_alloc(a, 2 * (size_t)n * sizeof(float));
    h->lx = sl_alloc(a, (size_t)n * sizeof(double));
    h->rx = sl_alloc(a, (size_t)n * sizeof(double));
    h->lv = sl_alloc(a, (size_t)n * sizeof(float));
    h->lb = sl_alloc(a, (size_t)n * sizeof(float));
    h->rv = sl_alloc(a, (size_t)n * sizeof(float));
    h->rb = sl_alloc(a, (size_t)n * sizeof(float));
    h->record = record;
    if (record) {
        h->hist_n = sl_alloc(a, (size_t)n);
        h->hist_d = sl_alloc(a, (size_t)n * SL_HORIZON_STEPS * sizeof(float));
        h->hist_v = sl_alloc(a, (size_t)n * SL_HORIZON_STEPS * sizeof(float));
    }
    if (!h->hmin || !h->hmax || !h->hbot || !h->lx || !h->rx || !h->lv || !h->lb || !h->rv || !h->rb ||
        (record && (!h->hist_n || !h->hist_d || !h->hist_v))) {
        sl_horizon_free(h);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "horizon: out of memory for %u bins", n);
    }
    sl_horizon_reset(h);
    return SL_OK;
}

void sl_horizon_free(sl_horizon *h)
{
    if (!h)
        return;
    const sl_allocator *a = &h->alloc;
    size_t n = h->n;
    sl_free(a, h->hmin, 2 * n * sizeof(float));
    sl_free(a, h->hmax, 2 * n * sizeof(float));
    sl_free(a, h->hbot, 2 * n * sizeof(float));
    sl_free(a, h->lx, n * sizeof(double));
    sl_free(a, h->rx, n * sizeof(double));
    sl_free(a, h->lv, n * sizeof(float));
    sl_free(a, h->lb, n * sizeof(float));
    sl_free(a, h->rv, n * sizeof(float));
    sl_free(a, h->rb, n * sizeof(float));
    sl_free(a, h->hist_n, n);
    sl_free(a, h->hist_d, n * SL_HORIZON_STEPS * sizeof(float));
    sl_free(a, h->hist_v, n * SL_HORIZON_STEPS * sizeof(float));
    memset(h, 0, sizeof *h);
}

void sl_horizon_reset(sl_horizon *h)
{
    const size_t n = h->n;
    for (size_t i = 0; i < 2 * n; i++) {
        h->hmin[i] = h->hmax[i] = H_NONE;
        h->hbot[i] = -INFINITY;
    }
    for (size_t k = 0; k < n; k++) {
        h->lx[k] = -INFINITY;
        h->rx[k] = INFINITY;
    }
    if (h->record)
        memset(h->hist_n, 0, n);
    h->bins_written = 0;
    h->key = 0;
}

/* Recompute the tree above leaves [k0, k1]. */
static void tree_update(sl_horizon *h, uint32_t k0, uint32_t k1)
{
    uint32_t l = (k0 + h->n) >> 1, r = (k1 + h->n) >> 1;
    while (l >= 1) {
        for (uint32_t i = l; i <= r; i++) {
            h->hmin[i] = sl_urban_minf(h->hmin[2 * i], h->hmin[2 * i + 1]);
            h->hmax[i] = sl_urban_maxf(h->hmax[2 * i], h->hmax[2 * i + 1]);
            h->hbot[i] = sl_urban_maxf(h->hbot[2 * i], h->hbot[2 * i + 1]);
        }
        if (l == 1)
            break;
        l >>= 1;
        r >>= 1;
    }
}

/* Raise leaf k to top (with its occluder's bottom) if higher. */
static inline bool leaf_raise(sl_horizon *h, uint32_t k, float top, float bottom)
{
    uint32_t i = k + h->n;
    if (top > h->hmin[i]) {
        h->hmin[i] = h->hmax[i] = top;
        h->hbot[i] = bottom;
        h->bins_written++;
        if (h->record) {
            /* a step (key, top); when full, the last step takes the new value (an upper bound of
             * the horizon between its distance and this one) */
            uint32_t m = h->hist_n[k];
            float *d = h->hist_d + (size_t)k * SL_HORIZON_STEPS, *v = h->hist_v + (size_t)k * SL_HORIZON_STEPS;
            if (m && (d[m - 1] >= h->key || m == SL_HORIZON_STEPS))
                v[m - 1] = top;
            else {
                d[m] = h->key;
                v[m] = top;
                h->hist_n[k] = (uint8_t)(m + 1);
            }
        }
        return true;
    }
    return false;
}

/* The segment as seen from the eye, for bounds over sub-ranges of azimuth. */
typedef struct seg_ctx {
    double ex, ey, ez;
    double ax, ay, dx, dy;  /* a relative to the eye, b - a */
    double az, dz;          /* top height at a, its change to b */
    double base;
    double tfoot, dfoot;    /* parameter and distance of the nearest point */
} seg_ctx;

/* Parameter of the segment point in pseudo-azimuth p (clamped to [lo, hi]). */
static inline double seg_param(const seg_ctx *c, double p, double lo, double hi)
{
    double rx, ry;
    sl_urban_paz_dir(p, &rx, &ry);
    double den = rx * c->dy - ry * c->dx;
    double t = den != 0 ? -(rx * c->ay - ry * c->ax) / den : lo;
    if (!(t >= lo))
        t = lo;
    if (t > hi)
        t = hi;
    return t;
}

/* Lower bound of the occluder's top elevation and upper bound of its bottom elevation over the
 * part of the segment between parameters t0 and t1. */
static void seg_bounds(const seg_ctx *c, double t0, double t1, float *top, float *bottom)
{
    if (t0 > t1) {
        double t = t0;
        t0 = t1;
        t1 = t;
    }
    double x0 = c->ax + t0 * c->dx, y0 = c->ay + t0 * c->dy, x1 = c->ax + t1 * c->dx, y1 = c->ay + t1 * c->dy;
    double d0 = sqrt(x0 * x0 + y0 * y0), d1 = sqrt(x1 * x1 + y1 * y1);
    double dmax = sl_urban_max(d0, d1), dmin = c->tfoot > t0 && c->tfoot < t1 ? c->dfoot : sl_urban_min(d0, d1);
    double zmin = sl_urban_min(c->az + t0 * c->dz, c->az + t1 * c->dz);
    double top_s = sl_urban_slope_lo(zmin, c->ez, dmin, dmax);
    *top = float_down(top_s - 1e-7 * (1 + fabs(top_s)));
    if (c->base == -INFINITY)
        *bottom = -INFINITY;
    else {
        double b = sl_urban_slope_hi(c->base, c->ez, dmin, dmax);
        *bottom = float_up(b + 1e-7 * (1 + fabs(b)));
    }
}

/* A part of the occluder covers [x0, x1] inside bin k (touching at most one of its ends). */
static void partial(sl_horizon *h, uint32_t k, double x0, double x1, float v, float b)
{
    const double lo = k * h->binw, hi = (k + 1) * h->binw;
    if (x0 <= lo) { /* a left part */
        if (x1 > h->lx[k]) {
            if (h->lx[k] >= lo && x0 <= h->lx[k]) { /* overlaps the old one: extend */
                h->lv[k] = sl_urban_minf(h->lv[k], v);
                h->lb[k] = sl_urban_maxf(h->lb[k], b);
            } else {
                h->lv[k] = v;
                h->lb[k] = b;
            }
            h->lx[k] = x1;
        }
    } else if (x1 >= hi) { /* a right part */
        if (x0 < h->rx[k]) {
            if (h->rx[k] <= hi && x1 >= h->rx[k]) {
                h->rv[k] = sl_urban_minf(h->rv[k], v);
                h->rb[k] = sl_urban_maxf(h->rb[k], b);
            } else {
                h->rv[k] = v;
                h->rb[k] = b;
            }
            h->rx[k] = x0;
        }
    } else { /* strictly inside: it can only extend a left or a right part it touches */
        if (h->lx[k] >= lo && x0 <= h->lx[k] && x1 > h->lx[k]) {
            h->lx[k] = x1;
            h->lv[k] = sl_urban_minf(h->lv[k], v);
            h->lb[k] = sl_urban_maxf(h->lb[k], b);
        }
        if (h->rx[k] <= hi && x1 >= h->rx[k] && x0 < h->rx[k]) {
            h->rx[k] = x0;
            h->rv[k] = sl_urban_minf(h->rv[k], v);
            h->rb[k] = sl_urban_maxf(h->rb[k], b);
        }
    }
    if (h->lx[k] >= lo && h->rx[k] <= hi && h->lx[k] >= h->rx[k]) {
        if (leaf_raise(h, k, sl_urban_minf(h->lv[k], h->rv[k]), sl_urban_maxf(h->lb[k], h->rb[k])))
            tree_update(h, k, k);
    }
}

/* Insert the part of the segment seen between azimuths lo < hi (within [0, 2*pi]); ta, tb: the
 * segment parameters at lo and hi. */
static void insert_range(sl_horizon *h, const seg_ctx *c, double lo, double hi, double ta, double tb)
{
    const double w = h->binw;
    uint32_t k0 = (uint32_t)(lo / w), k1 = (uint32_t)(hi / w);
    if (k0 >= h->n)
        k0 = h->n - 1;
    if (k1 > h->n)
        k1 = h->n;
    double tlo = sl_urban_min(ta, tb), thi = sl_urban_max(ta, tb);
    float v, b;
    if (k0 == k1 || (k1 == k0 + 1 && hi == k1 * w && lo > k0 * w)) {
        /* within one bin */
        if (k0 < h->n) {
            seg_bounds(c, ta, tb, &v, &b);
            partial(h, k0, lo, hi, v, b);
        }
        return;
    }
    uint32_t kf = k0, kl = k1; /* full bins [kf, kl) */
    if (lo > k0 * w) {
        double t = seg_param(c, (k0 + 1) * w, tlo, thi);
        seg_bounds(c, ta, t, &v, &b);
        partial(h, k0, lo, (k0 + 1) * w, v, b);
        kf = k0 + 1;
    }
    if (k1 < h->n && hi > k1 * w) {
        double t = seg_param(c, k1 * w, tlo, thi);
        seg_bounds(c, t, tb, &v, &b);
        partial(h, k1, k1 * w, hi, v, b);
    }
    if (kf >= kl)
        return;
    /* whole bins, in chunks sharing one bound */
    const uint32_t chunk = 8;
    bool changed = false;
    double tprev = seg_param(c, kf * w, tlo, thi);
    for (uint32_t k = kf; k < kl; k += chunk) {
        uint32_t ke = k + chunk < kl ? k + chunk : kl;
        double tnext = seg_param(c, ke * w, tlo, thi);
        seg_bounds(c, tprev, tnext, &v, &b);
        for (uint32_t q = k; q < ke; q++)
            changed |= leaf_raise(h, q, v, b);
        tprev = tnext;
    }
    if (changed)
        tree_update(h, kf, kl - 1);
}

void sl_horizon_insert(sl_horizon *h, const double eye[3], const sl_horizon_seg *s)
{
    seg_ctx c;
    c.ex = eye[0], c.ey = eye[1], c.ez = eye[2];
    c.ax = s->ax - eye[0], c.ay = s->ay - eye[1];
    c.dx = s->bx - s->ax, c.dy = s->by - s->ay;
    c.az = s->az, c.dz = s->bz - s->az;
    c.base = s->base;
    double bxr = s->bx - eye[0], byr = s->by - eye[1];
    double cr = c.ax * byr - c.ay * bxr;
    double la = sqrt(c.ax * c.ax + c.ay * c.ay), lb = sqrt(bxr * bxr + byr * byr);
    if (!(fabs(cr) > 1e-12 * la * lb) || !(la > 0) || !(lb > 0))
        return; /* seen edge-on (or through the eye): covers no azimuth */
    double l2 = c.dx * c.dx + c.dy * c.dy;
    c.tfoot = l2 > 0 ? -(c.ax * c.dx + c.ay * c.dy) / l2 : 0;
    c.tfoot = c.tfoot < 0 ? 0 : (c.tfoot > 1 ? 1 : c.tfoot);
    double fx = c.ax + c.tfoot * c.dx, fy = c.ay + c.tfoot * c.dy;
    c.dfoot = sqrt(fx * fx + fy * fy);
    double aa = sl_urban_paz(c.ax, c.ay), ab = sl_urban_paz(bxr, byr);
    /* the range runs counter-clockwise from its start; t at the start and at the end */
    double start, end, ts, te;
    if (cr > 0)
        start = aa, end = ab, ts = 0, te = 1;
    else
        start = ab, end = aa, ts = 1, te = 0;
    if (end >= start) {
        insert_range(h, &c, start, end, ts, te);
    } else {
        /* crosses azimuth 0: split at the wrap, which is a bin boundary */
        double tw = seg_param(&c, 0.0, 0, 1);
        insert_range(h, &c, start, SL_URBAN_CIRCLE, ts, tw);
        insert_range(h, &c, 0.0, end, tw, te);
    }
}

/* Decompose the azimuth range into at most two bin ranges. */
static int az_bins(const sl_horizon *h, double a0, double span, uint32_t r[2][2])
{
    if (span >= SL_URBAN_CIRCLE || !(span >= 0)) {
        r[0][0] = 0;
        r[0][1] = h->n - 1;
        return 1;
    }
    a0 = sl_urban_paz_wrap(a0);
    double a1 = a0 + span;
    uint32_t k0 = (uint32_t)(a0 / h->binw);
    if (k0 >= h->n)
        k0 = h->n - 1;
    if (a1 < SL_URBAN_CIRCLE) {
        uint32_t k1 = (uint32_t)(a1 / h->binw);
        if (k1 >= h->n)
            k1 = h->n - 1;
        r[0][0] = k0;
        r[0][1] = k1;
        return 1;
    }
    uint32_t k1 = (uint32_t)((a1 - SL_URBAN_CIRCLE) / h->binw);
    if (k1 >= k0) {
        r[0][0] = 0;
        r[0][1] = h->n - 1;
        return 1;
    }
    r[0][0] = k0;
    r[0][1] = h->n - 1;
    r[1][0] = 0;
    r[1][1] = k1;
    return 2;
}

bool sl_horizon_occluded(const sl_horizon *h, double a0, double span, double top, double bottom)
{
    const float t = float_up(top + sl_margin_height_slack(top)), b = float_down(bottom - sl_margin_height_slack(bottom));
    uint32_t r[2][2];
    int nr = az_bins(h, a0, span, r);
    for (int q = 0; q < nr; q++) {
        uint32_t l = r[q][0] + h->n, rr = r[q][1] + h->n + 1;
        while (l < rr) {
            if (l & 1) {
                if (h->hmin[l] <= t || h->hbot[l] > b)
                    return false;
                l++;
            }
            if (rr & 1) {
                rr--;
                if (h->hmin[rr] <= t || h->hbot[rr] > b)
                    return false;
            }
            l >>= 1;
            rr >>= 1;
        }
    }
    return true;
}

double sl_horizon_max_before(const sl_horizon *h, double a0, double span, double d, uint32_t max_bins)
{
    if (!h->record)
        return INFINITY;
    uint32_t r[2][2];
    int nr = az_bins(h, a0, span, r);
    uint32_t total = 0;
    for (int q = 0; q < nr; q++)
        total += r[q][1] - r[q][0] + 1;
    if (total > max_bins)
        return INFINITY;
    float mx = -INFINITY;
    for (int q = 0; q < nr; q++)
        for (uint32_t k = r[q][0]; k <= r[q][1]; k++) {
            const float *hd = h->hist_d + (size_t)k * SL_HORIZON_STEPS, *hv = h->hist_v + (size_t)k * SL_HORIZON_STEPS;
            for (uint32_t m = h->hist_n[k]; m > 0; m--)
                if ((double)hd[m - 1] <= d) {
                    mx = sl_urban_maxf(mx, hv[m - 1]);
                    break;
                }
        }
    return mx;
}

void sl_horizon_range(const sl_horizon *h, double a0, double span, double *min_h, double *max_b)
{
    float mn = INFINITY, mb = -INFINITY;
    uint32_t r[2][2];
    int nr = az_bins(h, a0, span, r);
    for (int q = 0; q < nr; q++) {
        uint32_t l = r[q][0] + h->n, rr = r[q][1] + h->n + 1;
        while (l < rr) {
            if (l & 1) {
                mn = sl_urban_minf(mn, h->hmin[l]);
                mb = sl_urban_maxf(mb, h->hbot[l]);
                l++;
            }
            if (rr & 1) {
                rr--;
                mn = sl_urban_minf(mn, h->hmin[rr]);
                mb = sl_urban_maxf(mb, h->hbot[rr]);
            }
            l >>= 1;
            rr >>= 1;
        }
    }
    *min_h = mn;
    *max_b = mb;
}

double sl_horizon_max(const sl_horizon *h, double a0, double span)
{
    float mx = -INFINITY;
    uint32_t r[2][2];
    int nr = az_bins(h, a0, span, r);
    for (int q = 0; q < nr; q++) {
        uint32_t l = r[q][0] + h->n, rr = r[q][1] + h->n + 1;
        while (l < rr) {
            if (l & 1)
                mx = sl_urban_maxf(mx, h->hmax[l++]);
            if (rr & 1)
                mx = sl_urban_maxf(mx, h->hmax[--rr]);
            l >>= 1;
            rr >>= 1;
        }
    }
    return mx;
}

/* ===== heaps ==================================================================================== */

sl_status sl_urban_heap_init(sl_urban_heap *h, uint32_t cap, const sl_allocator *a, sl_error *err)
{
    h->n = 0;
    h->cap = cap ? cap : 1;
    h->key = sl_alloc(a, (size_t)h->cap * sizeof(float));
    h->val = sl_alloc(a, (size_t)h->cap * sizeof(uint32_t));
    if (!h->key || !h->val) {
        sl_urban_heap_free(h, a);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "urban: out of memory for a heap of %u", cap);
    }
    return SL_OK;
}

void sl_urban_heap_free(sl_urban_heap *h, const sl_allocator *a)
{
    sl_free(a, h->key, (size_t)h->cap * sizeof(float));
    sl_free(a, h->val, (size_t)h->cap * sizeof(uint32_t));
    h->key = NULL;
    h->val = NULL;
    h->n = h->cap = 0;
}

void sl_urban_heap_push(sl_urban_heap *h, float key, uint32_t val)
{
    if (h->n == h->cap)
        return; /* cannot happen: every entry is pushed at most once per frame */
    uint32_t i = h->n++;
    while (i > 0) {
        uint32_t p = (i - 1) / 2;
        if (h->key[p] <= key)
            break;
        h->key[i] = h->key[p];
        h->val[i] = h->val[p];
        i = p;
    }
    h->key[i] = key;
    h->val[i] = val;
}

/* Move (key, val) down from slot i to its place. */
static void heap_sift_down(sl_urban_heap *h, uint32_t i, float key, uint32_t val)
{
    for (;;) {
        uint32_t c = 2 * i + 1;
        if (c >= h->n)
            break;
        if (c + 1 < h->n && h->key[c + 1] < h->key[c])
            c++;
        if (h->key[c] >= key)
            break;
        h->key[i] = h->key[c];
        h->val[i] = h->val[c];
        i = c;
    }
    h->key[i] = key;
    h->val[i] = val;
}

void sl_urban_heap_build(sl_urban_heap *h)
{
    for (uint32_t i = h->n / 2; i > 0; i--)
        heap_sift_down(h, i - 1, h->key[i - 1], h->val[i - 1]);
}

uint32_t sl_urban_heap_pop(sl_urban_heap *h)
{
    uint32_t top = h->val[0];
    float key = h->key[--h->n];
    uint32_t val = h->val[h->n];
    if (h->n)
        heap_sift_down(h, 0, key, val);
    return top;
}

/* ===== frustum-only fallback ===================================================================== */

uint32_t sl_urban_frustum_only(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame,
                               int32_t *x0, int32_t *x1, uint32_t *out, uint64_t *cells, uint64_t *tested)
{
    uint32_t j0, j1, n = 0;
    if (!sl_urban_frustum_spans(u, v, &j0, &j1, x0, x1))
        return 0;
    const struct sl_grid_t *g = u->grid;
    for (uint32_t j = j0; j <= j1; j++)
        for (int32_t i = x0[j - j0]; i <= x1[j - j0]; i++) {
            uint32_t c = j * u->nx + (uint32_t)i;
            (*cells)++;
            const uint32_t *ids = g->ids + g->start[c];
            for (uint32_t k = 0; k < g->count[c]; k++) {
                uint32_t o = ids[k];
                if (stamp[o] == frame)
                    continue;
                stamp[o] = frame;
                (*tested)++;
                if (sl_urban_box_in_frustum(v, &u->boxes[o]))
                    out[n++] = o;
            }
        }
    return n;
}

bool sl_urban_applicable(sl_scene scene, const void *config, char *why, size_t why_size)
{
    (void)config;
    if (sl_scene_footprint_count(scene))
        return true;
    snprintf(why, why_size,
             "the scene has no building footprints (the 2.5D occluders a generated city has; imported models "
             "have none): hzb or lazygrid cull with occluder meshes instead");
    return false;
}

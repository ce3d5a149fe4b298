/* The 2D scene grid: per square cell the objects whose box overlaps it, their maximum height and a
 * lower bound of the terrain; a conservative 2D DDA segment walk; in-place updates of moved objects.
 *
 * Segment walk: a conservative 2D DDA in double precision. Like J. Amanatides and A. Woo, "A Fast
 * Voxel Traversal Algorithm for Ray Tracing" (Eurographics 1987) it visits the cells in order along
 * the segment, but column by column along the major axis (each column spans at most three rows),
 * and it treats the segment as a band of half-width delta (a few float ulps of the grid's
 * coordinates): a point of the segment rounded to float, mapped by sl_grid_cell_at, always lands in
 * a visited cell, even where the segment grazes a cell corner or runs along a cell line.
 */
#include "grid_internal.h"
#include "scene/scene_internal.h"

#include <float.h>
#include <math.h>

/* ---- helpers ---- */

static size_t grid_bytes(const struct sl_grid_t *g)
{
    return sizeof *g + ((size_t)g->ncells + 1) * sizeof(uint32_t) +
           (size_t)g->ncells * (sizeof(uint32_t) + 2 * sizeof(float) + sizeof(int32_t)) +
           (size_t)(g->start ? g->start[g->ncells] : 0) * sizeof(uint32_t) +
           (size_t)g->object_count * (sizeof(sl_grid_rect) + sizeof(float) + 1);
}

static void grid_free(struct sl_grid_t *g)
{
    const sl_allocator *a = &g->alloc;
    size_t nc = g->ncells, no = g->object_count;
    if (g->start)
        sl_free(a, g->ids, (size_t)g->start[nc] * sizeof(uint32_t));
    sl_free(a, g->start, (nc + 1) * sizeof(uint32_t));
    sl_free(a, g->count, nc * sizeof(uint32_t));
    sl_free(a, g->max_z, nc * sizeof(float));
    sl_free(a, g->ground, nc * sizeof(float));
    sl_free(a, g->pending, nc * sizeof(int32_t));
    sl_free(a, g->rect, no * sizeof(sl_grid_rect));
    sl_free(a, g->top, no * sizeof(float));
    sl_free(a, g->mark, no);
}

static sl_status check_box(const sl_aabb *b, uint32_t id, sl_error *err)
{
    const float *lo = &b->min.x, *hi = &b->max.x;
    if (!sl_finite3(lo) || !sl_finite3(hi))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: object %u: bounds are not finite", id);
    for (int k = 0; k < 3; k++)
        if (lo[k] > hi[k])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: object %u: bounds are inverted on axis %c (%g > %g)",
                           id, "xyz"[k], (double)lo[k], (double)hi[k]);
    return SL_OK;
}

/* The cells a box overlaps (closed box against half-open cells whose far edges belong to the last
 * cells), computed with the same mapping as sl_grid_cell_at. */
static sl_grid_rect rect_of(const struct sl_grid_t *g, const sl_aabb *b)
{
    sl_grid_rect r = {SL_NONE, SL_NONE, SL_NONE, SL_NONE};
    /* in or out is decided in world units against the grid's edges (max_x >= every coordinate the
       extent holds, while (x - min_x) * inv_cell may round past nx at the far edge) */
    if (b->max.x < g->min_x || b->max.y < g->min_y || b->min.x > g->max_x || b->min.y > g->max_y)
        return r;
    r.i0 = sl_grid_coord(b->min.x, g->min_x, g->inv_cell, g->nx);
    r.i1 = sl_grid_coord(b->max.x, g->min_x, g->inv_cell, g->nx);
    r.j0 = sl_grid_coord(b->min.y, g->min_y, g->inv_cell, g->ny);
    r.j1 = sl_grid_coord(b->max.y, g->min_y, g->inv_cell, g->ny);
    return r;
}

static uint64_t rect_cells(const sl_grid_rect *r)
{
    return r->i0 == SL_NONE ? 0 : (uint64_t)(r->i1 - r->i0 + 1) * (r->j1 - r->j0 + 1);
}

/* Recompute a cell's maximum height from the tops of its objects. */
static void cell_refresh_max(struct sl_grid_t *g, uint32_t c)
{
    float m = -INFINITY;
    const uint32_t *ids = g->ids + g->start[c];
    for (uint32_t k = 0; k < g->count[c]; k++)
        m = SL_MAX(m, g->top[ids[k]]);
    g->max_z[c] = m;
}

/* Lower bound of the terrain over cell (i, j): the minimum of the samples of every terrain quad the
 * (clamped) cell overlaps. Bilinear interpolation never goes below its quad's corner samples. */
static float terrain_min(const struct sl_scene_t *s, float x0, float y0, float x1, float y1)
{
    const float *h = (const float *)s->terrain_heights.data;
    const uint32_t tnx = s->terrain_nx, tny = s->terrain_ny;
    double inv = 1.0 / s->terrain_cell;
    double fx0 = ((double)x0 - s->terrain_origin_x) * inv, fx1 = ((double)x1 - s->terrain_origin_x) * inv;
    double fy0 = ((double)y0 - s->terrain_origin_y) * inv, fy1 = ((double)y1 - s->terrain_origin_y) * inv;
    double qmx = tnx - 2, qmy = tny - 2;
    uint32_t qa = (uint32_t)SL_CLAMP(floor(fx0), 0.0, qmx), qb = (uint32_t)SL_CLAMP(floor(fx1), 0.0, qmx);
    uint32_t ra = (uint32_t)SL_CLAMP(floor(fy0), 0.0, qmy), rb = (uint32_t)SL_CLAMP(floor(fy1), 0.0, qmy);
    float m = INFINITY;
    for (uint32_t j = ra; j <= rb + 1; j++)
        for (uint32_t i = qa; i <= qb + 1; i++)
            m = SL_MIN(m, h[(size_t)j * tnx + i]);
    return m;
}

/* ---- build ---- */

static sl_status grid_create(const sl_allocator *al, const sl_aabb *boxes, uint32_t n, const sl_grid_options *o,
                             const struct sl_scene_t *scene, sl_grid *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: out is NULL");
    *out = NULL;
    sl_grid_options defaults = {0};
    if (!o)
        o = &defaults;
    if (n && !boxes)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: %u boxes but the array is NULL", n);
    if (!(o->cell_size >= 0.0f) || !isfinite(o->cell_size))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: cell_size %g must be a finite value >= 0",
                       (double)o->cell_size);
    for (uint32_t i = 0; i < n; i++) {
        sl_status st = check_box(&boxes[i], i, err);
        if (st != SL_OK)
            return st;
    }
    /* the area covered */
    double x0, y0, x1, y1;
    if (o->extent) {
        const sl_aabb *e = o->extent;
        if (!isfinite(e->min.x) || !isfinite(e->min.y) || !isfinite(e->max.x) || !isfinite(e->max.y) ||
            e->min.x > e->max.x || e->min.y > e->max.y)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "grid: extent (%g %g)-(%g %g) is not a finite box with min <= max", (double)e->min.x,
                           (double)e->min.y, (double)e->max.x, (double)e->max.y);
        x0 = e->min.x, y0 = e->min.y, x1 = e->max.x, y1 = e->max.y;
    } else if (n == 0) {
        x0 = y0 = 0.0;
        x1 = y1 = o->cell_size > 0.0f ? o->cell_size : 1.0;
    } else {
        x0 = y0 = INFINITY;
        x1 = y1 = -INFINITY;
        for (uint32_t i = 0; i < n; i++) {
            x0 = SL_MIN(x0, boxes[i].min.x), y0 = SL_MIN(y0, boxes[i].min.y);
            x1 = SL_MAX(x1, boxes[i].max.x), y1 = SL_MAX(y1, boxes[i].max.y);
        }
    }
    double w = x1 - x0, h = y1 - y0, cell = o->cell_size;
    if (cell == 0.0) {
        /* about four objects per cell if they were points spread evenly */
        double per = n ? (double)n : 1.0;
        if (w > 0.0 && h > 0.0)
            cell = 2.0 * sqrt(w * h / per);
        else if (w > 0.0 || h > 0.0)
            cell = 4.0 * SL_MAX(w, h) / per;
        else
            cell = 1.0;
        /* never more than SL_GRID_MAX_CELLS: grow the cell until the grid fits */
        while (ceil(w / cell) * ceil(h / cell) > SL_GRID_MAX_CELLS)
            cell *= 1.25;
        cell = (float)cell;
    }
    double dnx = SL_MAX(1.0, ceil(w / cell)), dny = SL_MAX(1.0, ceil(h / cell));
    if (!isfinite((float)cell) || !isfinite((float)(x0 + dnx * cell)) || !isfinite((float)(y0 + dny * cell)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "grid: extent %g x %g m with %g m cells is too large for float coordinates", w, h, cell);
    if (dnx * dny > SL_GRID_MAX_CELLS)
        return sl_fail(err, SL_ERROR_LIMIT, "grid: cell size %g m over %g x %g m gives %.0f cells (limit %u)",
                       cell, w, h, dnx * dny, SL_GRID_MAX_CELLS);

    al = sl_alloc_or_default(al);
    struct sl_grid_t *g = sl_calloc(al, 1, sizeof *g);
    if (!g)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid: out of memory");
    g->alloc = *al;
    al = &g->alloc;
    g->nx = (uint32_t)dnx;
    g->ny = (uint32_t)dny;
    g->ncells = g->nx * g->ny;
    g->cell = (float)cell;
    g->inv_cell = (float)(1.0 / cell);
    g->min_x = (float)x0;
    g->min_y = (float)y0;
    g->max_x = (float)(x0 + g->nx * cell);
    g->max_y = (float)(y0 + g->ny * cell);
    g->object_count = n;
    size_t nc = g->ncells;
    g->start = sl_calloc(al, nc + 1, sizeof(uint32_t));
    g->count = sl_calloc(al, nc, sizeof(uint32_t));
    g->max_z = sl_alloc(al, nc * sizeof(float));
    g->ground = sl_alloc(al, nc * sizeof(float));
    g->pending = sl_calloc(al, nc, sizeof(int32_t));
    g->rect = sl_alloc(al, (size_t)n * sizeof(sl_grid_rect));
    g->top = sl_alloc(al, (size_t)n * sizeof(float));
    g->mark = sl_calloc(al, n, 1);
    if (!g->start || !g->count || !g->max_z || !g->ground || !g->pending ||
        (n && (!g->rect || !g->top || !g->mark))) {
        grid_free(g);
        sl_free(al, g, sizeof *g);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid: out of memory for %zu cells", nc);
    }

    /* count, then prefix sums, then fill in object order: lists come out ascending */
    uint64_t entries = 0;
    for (uint32_t i = 0; i < n; i++) {
        g->rect[i] = rect_of(g, &boxes[i]);
        g->top[i] = boxes[i].max.z;
        entries += rect_cells(&g->rect[i]);
    }
    if (entries > UINT32_MAX) {
        grid_free(g);
        sl_free(al, g, sizeof *g);
        return sl_fail(err, SL_ERROR_LIMIT, "grid: %llu object-cell entries exceed the limit of %u (use larger cells)",
                       (unsigned long long)entries, UINT32_MAX);
    }
    for (uint32_t i = 0; i < n; i++) {
        const sl_grid_rect *r = &g->rect[i];
        if (r->i0 == SL_NONE)
            continue;
        for (uint32_t j = r->j0; j <= r->j1; j++)
            for (uint32_t k = r->i0; k <= r->i1; k++)
                g->count[(size_t)j * g->nx + k]++;
    }
    for (size_t c = 0; c < nc; c++)
        g->start[c + 1] = g->start[c] + g->count[c];
    g->ids = sl_alloc(al, (size_t)g->start[nc] * sizeof(uint32_t));
    if (!g->ids) {
        grid_free(g);
        sl_free(al, g, sizeof *g);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid: out of memory for %llu entries",
                       (unsigned long long)entries);
    }
    g->entries = entries;
    memset(g->count, 0, nc * sizeof(uint32_t));
    for (size_t c = 0; c < nc; c++)
        g->max_z[c] = -INFINITY;
    for (uint32_t i = 0; i < n; i++) {
        const sl_grid_rect *r = &g->rect[i];
        if (r->i0 == SL_NONE)
            continue;
        for (uint32_t j = r->j0; j <= r->j1; j++)
            for (uint32_t k = r->i0; k <= r->i1; k++) {
                size_t c = (size_t)j * g->nx + k;
                g->ids[g->start[c] + g->count[c]++] = i;
                g->max_z[c] = SL_MAX(g->max_z[c], g->top[i]);
            }
    }
    for (uint32_t j = 0; j < g->ny; j++)
        for (uint32_t i = 0; i < g->nx; i++) {
            float cx0 = g->min_x + (float)i * g->cell, cy0 = g->min_y + (float)j * g->cell;
            g->ground[(size_t)j * g->nx + i] =
                scene && scene->has_terrain ? terrain_min(scene, cx0, cy0, cx0 + g->cell, cy0 + g->cell) : 0.0f;
        }
    *out = g;
    return SL_OK;
}

sl_status sl_grid_build(sl_scene scene, const sl_grid_options *options, sl_grid *out, sl_error *err)
{
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid: scene is NULL");
    const sl_allocator *al = options && options->alloc ? options->alloc : &scene->alloc;
    return grid_create(al, sl_scene_object_bounds_array(scene), sl_scene_object_count(scene), options, scene, out,
                       err);
}

sl_status sl_grid_build_boxes(const sl_aabb *boxes, uint32_t count, const sl_grid_options *options, sl_grid *out,
                              sl_error *err)
{
    return grid_create(options ? options->alloc : NULL, boxes, count, options, NULL, out, err);
}

void sl_grid_destroy(sl_grid g)
{
    if (!g)
        return;
    sl_allocator al = g->alloc;
    grid_free(g);
    sl_free(&al, g, sizeof *g);
}

/* ---- queries ---- */

void sl_grid_get_info(sl_grid g, sl_grid_info *out)
{
    memset(out, 0, sizeof *out);
    if (!g)
        return;
    out->nx = g->nx;
    out->ny = g->ny;
    out->cell_size = g->cell;
    out->min_x = g->min_x;
    out->min_y = g->min_y;
    out->max_x = g->max_x;
    out->max_y = g->max_y;
    out->object_count = g->object_count;
    out->entry_count = g->entries;
    out->memory_bytes = grid_bytes(g);
}

bool sl_grid_cell_at(sl_grid g, float x, float y, uint32_t *cx, uint32_t *cy)
{
    uint32_t i = 0, j = 0;
    bool inside = false;
    if (g && isfinite(x) && isfinite(y)) {
        inside = x >= g->min_x && y >= g->min_y && x <= g->max_x && y <= g->max_y;
        i = sl_grid_coord(x, g->min_x, g->inv_cell, g->nx);
        j = sl_grid_coord(y, g->min_y, g->inv_cell, g->ny);
    }
    if (cx)
        *cx = i;
    if (cy)
        *cy = j;
    return inside;
}

uint32_t sl_grid_cell_objects(sl_grid g, uint32_t cx, uint32_t cy, const uint32_t **ids)
{
    if (!g || cx >= g->nx || cy >= g->ny) {
        if (ids)
            *ids = NULL;
        return 0;
    }
    size_t c = (size_t)cy * g->nx + cx;
    if (ids)
        *ids = g->ids + g->start[c];
    return g->count[c];
}

float sl_grid_cell_max_height(sl_grid g, uint32_t cx, uint32_t cy)
{
    return g && cx < g->nx && cy < g->ny ? g->max_z[(size_t)cy * g->nx + cx] : -INFINITY;
}

float sl_grid_cell_ground_min(sl_grid g, uint32_t cx, uint32_t cy)
{
    return g && cx < g->nx && cy < g->ny ? g->ground[(size_t)cy * g->nx + cx] : 0.0f;
}

/* ---- segment walk ---- */

/* Liang-Barsky: narrow [*t0, *t1] to where p*t <= q. */
static bool clip(double p, double q, double *t0, double *t1)
{
    if (p == 0.0)
        return q >= 0.0;
    double t = q / p;
    if (p < 0.0) {
        if (t > *t1)
            return false;
        if (t > *t0)
            *t0 = t;
    } else {
        if (t < *t0)
            return false;
        if (t < *t1)
            *t1 = t;
    }
    return true;
}

/* Parameter interval of a + t*d inside the slab [lo, hi] (d may be 0), intersected with [*t0, *t1]. */
static bool slab(double a, double d, double lo, double hi, double *t0, double *t1)
{
    return clip(-d, a - lo, t0, t1) && clip(d, hi - a, t0, t1) && *t0 <= *t1;
}

static uint32_t cell_index(double v, double origin, double cell, uint32_t n)
{
    double f = floor((v - origin) / cell);
    return f <= 0.0 ? 0 : f >= (double)(n - 1) ? n - 1 : (uint32_t)f;
}

uint32_t sl_grid_walk_segment(sl_grid g, sl_vec2 a, sl_vec2 b, sl_grid_cell_fn fn, void *user)
{
    if (!g || !fn || !isfinite(a.x) || !isfinite(a.y) || !isfinite(b.x) || !isfinite(b.y))
        return 0;
    const double cell = g->cell;
    /* delta covers a point of the segment rounded to float plus the float mapping of sl_grid_cell_at */
    const double delta = 8.0 * FLT_EPSILON *
                         (SL_MAX(SL_MAX(fabs((double)g->min_x), fabs((double)g->max_x)),
                                 SL_MAX(fabs((double)g->min_y), fabs((double)g->max_y))) +
                          cell);
    /* u: the major axis (the walk goes column by column along it), v: the minor one */
    const bool xmajor = fabs((double)b.x - a.x) >= fabs((double)b.y - a.y);
    const double au = xmajor ? a.x : a.y, av = xmajor ? a.y : a.x;
    const double du = (xmajor ? (double)b.x : (double)b.y) - au, dv = (xmajor ? (double)b.y : (double)b.x) - av;
    const double u0 = xmajor ? g->min_x : g->min_y, v0 = xmajor ? g->min_y : g->min_x;
    const double u1 = xmajor ? g->max_x : g->max_y, v1 = xmajor ? g->max_y : g->max_x;
    const uint32_t nu = xmajor ? g->nx : g->ny, nv = xmajor ? g->ny : g->nx;
    /* the part of the segment within delta of the grid */
    double t0 = 0.0, t1 = 1.0;
    if (!slab(au, du, u0 - delta, u1 + delta, &t0, &t1) || !slab(av, dv, v0 - delta, v1 + delta, &t0, &t1))
        return 0;
    const int su = du >= 0.0 ? 1 : -1, sv = dv >= 0.0 ? 1 : -1;
    uint32_t c_first = cell_index(au + t0 * du - su * delta, u0, cell, nu);
    uint32_t c_last = cell_index(au + t1 * du + su * delta, u0, cell, nu);
    uint32_t visited = 0;
    double t_prev = t0;
    for (uint32_t c = c_first;; c = (uint32_t)((int64_t)c + su)) {
        /* the segment within this column grown by delta, and the rows it spans (grown by delta) */
        double ta = t0, tb = t1;
        double cu0 = u0 + (double)c * cell;
        if (slab(au, du, cu0 - delta, cu0 + cell + delta, &ta, &tb)) {
            double va = av + ta * dv, vb = av + tb * dv;
            uint32_t r_lo = cell_index(SL_MIN(va, vb) - delta, v0, cell, nv);
            uint32_t r_hi = cell_index(SL_MAX(va, vb) + delta, v0, cell, nv);
            uint32_t r = sv > 0 ? r_lo : r_hi, r_end = sv > 0 ? r_hi : r_lo;
            for (;; r = (uint32_t)((int64_t)r + sv)) {
                double tr0 = ta, tr1 = tb;
                double cv0 = v0 + (double)r * cell;
                if (!slab(av, dv, cv0 - delta, cv0 + cell + delta, &tr0, &tr1))
                    tr0 = tr1 = t_prev; /* within rounding of the band's edge */
                /* report nondecreasing parameters along the walk */
                tr0 = SL_MAX(tr0, t_prev);
                tr1 = SL_MAX(tr1, tr0);
                t_prev = tr0;
                visited++;
                uint32_t cx = xmajor ? c : r, cy = xmajor ? r : c;
                if (!fn(user, cx, cy, (float)tr0, (float)tr1))
                    return visited;
                if (r == r_end)
                    break;
            }
        }
        if (c == c_last)
            break;
    }
    return visited;
}

/* ---- updates ---- */

/* Re-lay the cell arrays out so that cell c has room for count[c] + pending[c] entries. Atomic: on
 * failure nothing changed. */
static sl_status relayout(struct sl_grid_t *g, sl_error *err)
{
    const sl_allocator *al = &g->alloc;
    size_t nc = g->ncells;
    uint64_t total = 0;
    for (size_t c = 0; c < nc; c++) {
        uint64_t cap = g->start[c + 1] - g->start[c];
        uint64_t need = (uint64_t)((int64_t)g->count[c] + g->pending[c]);
        uint64_t want = need > cap ? 2 * need + 4 : SL_MAX(cap, (uint64_t)g->count[c] + 1);
        total += want;
    }
    if (total > UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "grid update: %llu slots exceed the limit of %u",
                       (unsigned long long)total, UINT32_MAX);
    uint32_t *start = sl_alloc(al, (nc + 1) * sizeof(uint32_t));
    uint32_t *ids = sl_alloc(al, (size_t)total * sizeof(uint32_t));
    if (!start || !ids) {
        sl_free(al, start, (nc + 1) * sizeof(uint32_t));
        sl_free(al, ids, (size_t)total * sizeof(uint32_t));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid update: out of memory");
    }
    start[0] = 0;
    for (size_t c = 0; c < nc; c++) {
        uint64_t cap = g->start[c + 1] - g->start[c];
        uint64_t need = (uint64_t)((int64_t)g->count[c] + g->pending[c]);
        uint64_t want = need > cap ? 2 * need + 4 : SL_MAX(cap, (uint64_t)g->count[c] + 1);
        start[c + 1] = start[c] + (uint32_t)want;
        memcpy(ids + start[c], g->ids + g->start[c], (size_t)g->count[c] * sizeof(uint32_t));
    }
    sl_free(al, g->ids, (size_t)g->start[nc] * sizeof(uint32_t));
    sl_free(al, g->start, (nc + 1) * sizeof(uint32_t));
    g->start = start;
    g->ids = ids;
    return SL_OK;
}

/* Position of the first id >= object in a cell's sorted list. */
static uint32_t cell_lower_bound(const struct sl_grid_t *g, size_t c, uint32_t object)
{
    const uint32_t *ids = g->ids + g->start[c];
    uint32_t lo = 0, hi = g->count[c];
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (ids[mid] < object)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

#define FOR_RECT(g, r, c)                                                                                              \
    for (uint32_t rj_ = (r)->j0; (r)->i0 != SL_NONE && rj_ <= (r)->j1; rj_++)                                          \
        for (uint32_t ri_ = (r)->i0, c = rj_ * (g)->nx + ri_; ri_ <= (r)->i1; ri_++, c++)

sl_status sl_grid_update_boxes(sl_grid g, const uint32_t *objects, const sl_aabb *boxes, uint32_t count,
                               sl_error *err)
{
    if (!g)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: grid is NULL");
    if (count && (!objects || !boxes))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: NULL arrays");
    /* validate the whole batch first: the grid stays unchanged on failure */
    sl_status st = SL_OK;
    uint32_t marked = 0;
    for (; marked < count; marked++) {
        uint32_t o = objects[marked];
        if (o >= g->object_count) {
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: object %u out of range (grid has %u objects)",
                         o, g->object_count);
            break;
        }
        if (g->mark[o]) {
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: object %u appears twice in the batch", o);
            break;
        }
        st = check_box(&boxes[marked], o, err);
        if (st != SL_OK)
            break;
        g->mark[o] = 1;
    }
    /* net insertions per cell, to size a relayout */
    bool overflow = false;
    if (st == SL_OK) {
        for (uint32_t k = 0; k < count; k++) {
            sl_grid_rect nr = rect_of(g, &boxes[k]);
            FOR_RECT(g, &g->rect[objects[k]], c) g->pending[c]--;
            FOR_RECT(g, &nr, c) g->pending[c]++;
        }
        for (uint32_t k = 0; k < count; k++) {
            sl_grid_rect nr = rect_of(g, &boxes[k]);
            FOR_RECT(g, &nr, c) overflow |= (int64_t)g->count[c] + g->pending[c] > (int64_t)(g->start[c + 1] - g->start[c]);
        }
        if (overflow)
            st = relayout(g, err);
    }
    /* clear the scratch state (marks, pending) whatever happened */
    for (uint32_t k = 0; k < count && k < marked; k++) {
        sl_grid_rect nr = rect_of(g, &boxes[k]);
        g->mark[objects[k]] = 0;
        if (marked == count) {
            FOR_RECT(g, &g->rect[objects[k]], c) g->pending[c] = 0;
            FOR_RECT(g, &nr, c) g->pending[c] = 0;
        }
    }
    if (st != SL_OK)
        return st;

    /* remove every moved object from the cells it was in */
    for (uint32_t k = 0; k < count; k++) {
        uint32_t o = objects[k];
        FOR_RECT(g, &g->rect[o], c)
        {
            uint32_t pos = cell_lower_bound(g, c, o);
            uint32_t *ids = g->ids + g->start[c];
            if (pos < g->count[c] && ids[pos] == o) {
                memmove(ids + pos, ids + pos + 1, (size_t)(g->count[c] - pos - 1) * sizeof(uint32_t));
                g->count[c]--;
                g->entries--;
                cell_refresh_max(g, c);
            }
        }
    }
    /* insert them where they are now */
    for (uint32_t k = 0; k < count; k++) {
        uint32_t o = objects[k];
        g->rect[o] = rect_of(g, &boxes[k]);
        g->top[o] = boxes[k].max.z;
        FOR_RECT(g, &g->rect[o], c)
        {
            uint32_t pos = cell_lower_bound(g, c, o);
            uint32_t *ids = g->ids + g->start[c];
            memmove(ids + pos + 1, ids + pos, (size_t)(g->count[c] - pos) * sizeof(uint32_t));
            ids[pos] = o;
            g->count[c]++;
            g->entries++;
            g->max_z[c] = SL_MAX(g->max_z[c], g->top[o]);
        }
    }
    return SL_OK;
}

sl_status sl_grid_update_objects(sl_grid g, sl_scene scene, const uint32_t *objects, uint32_t count, sl_error *err)
{
    if (!g || !scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: NULL argument");
    if (count && !objects)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: objects is NULL");
    const sl_aabb *all = sl_scene_object_bounds_array(scene);
    uint32_t n = sl_scene_object_count(scene);
    /* a batch is applied atomically, so its boxes are gathered first: on the stack for small batches
       (no allocation per frame for a few cars), in one temporary array otherwise */
    enum { CHUNK = 64 };
    sl_aabb boxes[CHUNK];
    for (uint32_t k = 0; k < count; k++)
        if (objects[k] >= n || objects[k] >= g->object_count)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "grid update: object %u out of range (grid has %u objects)",
                           objects[k], g->object_count);
    if (count <= CHUNK) {
        for (uint32_t k = 0; k < count; k++)
            boxes[k] = all[objects[k]];
        return sl_grid_update_boxes(g, objects, boxes, count, err);
    }
    sl_aabb *copy = sl_alloc(&g->alloc, (size_t)count * sizeof(sl_aabb));
    if (!copy)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid update: out of memory");
    for (uint32_t k = 0; k < count; k++)
        copy[k] = all[objects[k]];
    sl_status st = sl_grid_update_boxes(g, objects, copy, count, err);
    sl_free(&g->alloc, copy, (size_t)count * sizeof(sl_aabb));
    return st;
}

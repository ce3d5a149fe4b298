/* View-cell generators (region layer, bake time): the free space of the streets triangulated with
 * GEOS (Wonka 2001, section 5.3), a regular grid, the clusters of a Quake III map and an adaptive
 * subdivision of a navigable box; see src/pvs/viewcells.c for the container and the run-time
 * lookup. */
#include "pvs/viewcells_internal.h"

#include "core/dvec3.h"
#include "geos_util.h"
#include "scene/scene_internal.h"
#include "sightline/accel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DEFAULT_STREET_EDGE 12.0f
#define DEFAULT_GRID_EDGE 8.0f
#define DEFAULT_ADAPTIVE_EDGE 16.0f
#define DEFAULT_ADAPTIVE_MIN 2.0f
#define DEFAULT_EYE_MIN 1.0f
#define DEFAULT_EYE_MAX 2.0f
#define DEFAULT_MAX_CELLS 4000000u

/* ============================================================================================
 * Ground heights
 * ============================================================================================ */

void sl_ground_range(sl_scene scene, double x0, double y0, double x1, double y1, float *lo, float *hi)
{
    sl_terrain_view t;
    if (!sl_scene_terrain(scene, &t)) {
        *lo = *hi = 0;
        return;
    }
    /* sample indices of the squares meeting the box, clamped like sl_scene_ground_height */
    double fx0 = (x0 - t.origin_x) / t.cell, fx1 = (x1 - t.origin_x) / t.cell;
    double fy0 = (y0 - t.origin_y) / t.cell, fy1 = (y1 - t.origin_y) / t.cell;
    int64_t i0 = (int64_t)floor(fmax(0.0, fmin(fx0, (double)t.nx - 1)));
    int64_t i1 = (int64_t)ceil(fmax(0.0, fmin(fx1, (double)t.nx - 1)));
    int64_t j0 = (int64_t)floor(fmax(0.0, fmin(fy0, (double)t.ny - 1)));
    int64_t j1 = (int64_t)ceil(fmax(0.0, fmin(fy1, (double)t.ny - 1)));
    float l = INFINITY, h = -INFINITY;
    for (int64_t j = j0; j <= j1; j++)
        for (int64_t i = i0; i <= i1; i++) {
            float z = t.heights[(size_t)j * t.nx + (size_t)i];
            l = fminf(l, z);
            h = fmaxf(h, z);
        }
    *lo = l;
    *hi = h;
}

static void fill_prism(sl_scene scene, const double tri[6], float eye_min, float eye_max, sl_viewcell *c)
{
    memset(c, 0, sizeof *c);
    c->shape = SL_CELL_PRISM;
    c->cluster = -1;
    for (int k = 0; k < 3; k++) {
        c->tri[k].x = (float)tri[2 * k];
        c->tri[k].y = (float)tri[2 * k + 1];
    }
    sl_aabb b = sl_viewcell_prism_bounds(c);
    float lo, hi;
    sl_ground_range(scene, b.min.x, b.min.y, b.max.x, b.max.y, &lo, &hi);
    c->z_min = lo + eye_min;
    c->z_max = hi + eye_max;
    c->bounds = sl_viewcell_prism_bounds(c);
}

static void fill_box(sl_viewcell *c, sl_aabb b)
{
    memset(c, 0, sizeof *c);
    c->shape = SL_CELL_BOX;
    c->cluster = -1;
    c->z_min = b.min.z;
    c->z_max = b.max.z;
    c->bounds = b;
}

/* ============================================================================================
 * Options
 * ============================================================================================ */

typedef struct resolved {
    float max_edge, min_edge, eye_min, eye_max;
    uint32_t max_cells;
    const sl_allocator *alloc;
    const sl_progress *progress;
} resolved;

static sl_status resolve(const sl_viewcell_options *opt, float def_edge, resolved *r, const char *who, sl_error *err)
{
    sl_viewcell_options o;
    if (opt)
        o = *opt;
    else
        memset(&o, 0, sizeof o);
    if (isnan(o.max_edge) || isnan(o.min_edge) || o.max_edge < 0 || o.min_edge < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: max_edge %g and min_edge %g must be positive (0: default)",
                       who, (double)o.max_edge, (double)o.min_edge);
    r->max_edge = o.max_edge > 0 ? o.max_edge : def_edge;
    r->min_edge = o.min_edge > 0 ? o.min_edge : fminf(DEFAULT_ADAPTIVE_MIN, r->max_edge);
    r->eye_min = o.eye_min != 0 ? o.eye_min : DEFAULT_EYE_MIN;
    r->eye_max = o.eye_max != 0 ? o.eye_max : DEFAULT_EYE_MAX;
    r->max_cells = o.max_cells ? o.max_cells : DEFAULT_MAX_CELLS;
    r->alloc = sl_alloc_or_default(o.alloc);
    r->progress = opt ? &opt->progress : NULL;
    if (!isfinite(r->max_edge) || !(r->max_edge >= 0.01f) || !(r->max_edge <= 1e5f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: max_edge %g is outside [0.01, 100000] m", who,
                       (double)r->max_edge);
    if (!isfinite(r->min_edge) || !(r->min_edge >= 0.001f) || r->min_edge > r->max_edge)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: min_edge %g must lie in [0.001, max_edge %g]", who,
                       (double)r->min_edge, (double)r->max_edge);
    if (!isfinite(r->eye_min) || !isfinite(r->eye_max) || !(r->eye_min <= r->eye_max) || fabsf(r->eye_max) > 1e4f)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: eye heights %g..%g are not an interval of finite heights",
                       who, (double)r->eye_min, (double)r->eye_max);
    return SL_OK;
}

/* ============================================================================================
 * Street cells (constrained triangulation of the free space)
 * ============================================================================================ */

typedef struct tri_sink {
    const sl_allocator *a;
    sl_scene scene;
    const resolved *r;
    sl_array cells; /* sl_viewcell */
    double *xy;
    size_t xy_cap;
    sl_geos *g;
    bool oom, limit;
} tri_sink;

/* Split a triangle at the midpoint of its longest edge until no edge exceeds max_edge, emitting
 * the pieces as cells (counter-clockwise). */
static void emit_refined(tri_sink *s, const double t0[6])
{
    double stack[64][6];
    int sp = 0;
    memcpy(stack[sp++], t0, sizeof stack[0]);
    double lim2 = (double)s->r->max_edge * s->r->max_edge;
    while (sp > 0 && !s->oom && !s->limit) {
        double t[6];
        memcpy(t, stack[--sp], sizeof t);
        int longest = 0;
        double l2max = -1;
        for (int e = 0; e < 3; e++) {
            int f = (e + 1) % 3;
            double dx = t[2 * f] - t[2 * e], dy = t[2 * f + 1] - t[2 * e + 1];
            double l2 = dx * dx + dy * dy;
            if (l2 > l2max) {
                l2max = l2;
                longest = e;
            }
        }
        if (l2max > lim2 && sp + 2 <= 64) {
            /* midpoint m of edge (e, f); children (e, m, g) and (m, f, g) keep the orientation */
            int e = longest, f = (e + 1) % 3, gi = (e + 2) % 3;
            double mx = 0.5 * (t[2 * e] + t[2 * f]), my = 0.5 * (t[2 * e + 1] + t[2 * f + 1]);
            double a[6] = {t[2 * e], t[2 * e + 1], mx, my, t[2 * gi], t[2 * gi + 1]};
            double b[6] = {mx, my, t[2 * f], t[2 * f + 1], t[2 * gi], t[2 * gi + 1]};
            memcpy(stack[sp++], b, sizeof b);
            memcpy(stack[sp++], a, sizeof a);
            continue;
        }
        sl_viewcell c;
        fill_prism(s->scene, t, s->r->eye_min, s->r->eye_max, &c);
        /* float rounding can flatten a sliver: such a cell holds no point worth keeping */
        if (!(sl_orient2d(c.tri[0].x, c.tri[0].y, c.tri[1].x, c.tri[1].y, c.tri[2].x, c.tri[2].y) > 0))
            continue;
        if (s->cells.count >= s->r->max_cells) {
            s->limit = true;
            return;
        }
        if (!sl_array_push(s->a, &s->cells, sizeof c, &c, 1))
            s->oom = true;
    }
}

/* One triangle of GEOS's output. */
static bool take_triangle(void *user, const GEOSGeometry *poly)
{
    tri_sink *s = user;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(s->g->h, poly);
    int n = ring ? sl_geos_ring_coords(s->g, ring, s->a, &s->xy, &s->xy_cap) : -1;
    if (n != 3) {
        s->oom = n < 0;
        return n >= 0; /* not a triangle: skip it */
    }
    double t[6];
    memcpy(t, s->xy, sizeof t);
    double o = sl_orient2d(t[0], t[1], t[2], t[3], t[4], t[5]);
    if (o == 0)
        return true;
    if (o < 0) {
        double x = t[2], y = t[3];
        t[2] = t[4], t[3] = t[5], t[4] = x, t[5] = y;
    }
    emit_refined(s, t);
    return !s->oom && !s->limit;
}

typedef struct poly_ctx {
    tri_sink *sink;
    uint32_t done, total;
    sl_status st;
    sl_error *err;
} poly_ctx;

/* Triangulate one polygon of the free space: densified to the maximum edge first. GEOS's ear
 * clipping can fail on near-degenerate input ("unable to find a convex corner"); the polygon is then
 * triangulated undensified (the longest-edge splits refine it all the same), and last snapped to a
 * millimetre grid. */
static bool triangulate_polygon(void *user, const GEOSGeometry *poly)
{
    poly_ctx *p = user;
    sl_geos *g = p->sink->g;
    GEOSGeometry *tris = NULL;
    GEOSGeometry *dense = GEOSDensify_r(g->h, poly, p->sink->r->max_edge);
    if (dense) {
        tris = GEOSConstrainedDelaunayTriangulation_r(g->h, dense);
        GEOSGeom_destroy_r(g->h, dense);
    }
    if (!tris)
        tris = GEOSConstrainedDelaunayTriangulation_r(g->h, poly);
    if (!tris) {
        GEOSGeometry *snapped = GEOSGeom_setPrecision_r(g->h, poly, 1e-3, 0);
        if (snapped) {
            tris = GEOSConstrainedDelaunayTriangulation_r(g->h, snapped);
            GEOSGeom_destroy_r(g->h, snapped);
        }
    }
    if (!tris) {
        p->st = sl_fail(p->err, SL_ERROR_INTERNAL, "view cells: GEOS could not triangulate free-space polygon %u: %s",
                        p->done, g->message);
        return false;
    }
    bool ok = sl_geos_each_polygon(g, tris, take_triangle, p->sink);
    GEOSGeom_destroy_r(g->h, tris);
    p->done++;
    if (!ok)
        return false;
    if (!sl_progress_report(p->sink->r->progress, "view cells", p->done, p->total)) {
        p->st = sl_fail(p->err, SL_ERROR_CANCELLED, "view cells: cancelled");
        return false;
    }
    return true;
}

/* Union of the street polygons (valid parts only) minus the footprints. */
static GEOSGeometry *free_space(sl_geos *g, const sl_allocator *a, sl_scene scene, sl_error *err, sl_status *st)
{
    uint32_t ns = sl_scene_street_polygon_count(scene), nf = sl_scene_footprint_count(scene);
    size_t parts_size = ((size_t)SL_MAX(ns, nf) + 1) * sizeof(GEOSGeometry *);
    GEOSGeometry **parts = sl_alloc(a, parts_size);
    if (!parts) {
        *st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "view cells: out of memory");
        return NULL;
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < ns; i++) {
        sl_polygon_view pv = sl_scene_street_polygon(scene, i);
        GEOSGeometry *p = sl_geos_polygon(g, pv.xy, pv.vertex_count);
        if (p && !GEOSisValid_r(g->h, p)) {
            GEOSGeometry *fixed = GEOSMakeValid_r(g->h, p);
            GEOSGeom_destroy_r(g->h, p);
            p = fixed;
        }
        if (p)
            parts[k++] = p;
    }
    GEOSGeometry *coll = GEOSGeom_createCollection_r(g->h, GEOS_GEOMETRYCOLLECTION, parts, k);
    GEOSGeometry *space = coll ? GEOSUnaryUnion_r(g->h, coll) : NULL;
    if (coll)
        GEOSGeom_destroy_r(g->h, coll);
    else
        for (uint32_t i = 0; i < k; i++)
            GEOSGeom_destroy_r(g->h, parts[i]);
    if (!space) {
        sl_free(a, parts, parts_size);
        *st = sl_fail(err, SL_ERROR_INTERNAL, "view cells: GEOS could not unite the street polygons: %s", g->message);
        return NULL;
    }
    k = 0;
    for (uint32_t i = 0; i < nf; i++) {
        sl_footprint_view fv = sl_scene_footprint(scene, i);
        GEOSGeometry *p = sl_geos_polygon(g, fv.xy, fv.vertex_count);
        if (p)
            parts[k++] = p;
    }
    if (k > 0) {
        GEOSGeometry *fcoll = GEOSGeom_createCollection_r(g->h, GEOS_GEOMETRYCOLLECTION, parts, k);
        GEOSGeometry *fu = fcoll ? GEOSUnaryUnion_r(g->h, fcoll) : NULL;
        if (fcoll)
            GEOSGeom_destroy_r(g->h, fcoll);
        else
            for (uint32_t i = 0; i < k; i++)
                GEOSGeom_destroy_r(g->h, parts[i]);
        GEOSGeometry *diff = fu ? GEOSDifference_r(g->h, space, fu) : NULL;
        if (fu)
            GEOSGeom_destroy_r(g->h, fu);
        GEOSGeom_destroy_r(g->h, space);
        space = diff;
        if (!space) {
            sl_free(a, parts, parts_size);
            *st = sl_fail(err, SL_ERROR_INTERNAL, "view cells: GEOS could not subtract the footprints: %s", g->message);
            return NULL;
        }
    }
    sl_free(a, parts, parts_size);
    return space;
}

sl_status sl_viewcells_from_streets(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_from_streets: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_STREET_EDGE, &r, "street view cells", err);
    if (st != SL_OK)
        return st;
    if (sl_scene_street_polygon_count(scene) == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "street view cells: the scene has no street polygons (use grid, adaptive or bsp cells)");
    sl_geos g;
    if (!sl_geos_init(&g))
        return sl_fail(err, SL_ERROR_INTERNAL, "street view cells: GEOS could not start");
    tri_sink sink;
    memset(&sink, 0, sizeof sink);
    sink.a = r.alloc;
    sink.scene = scene;
    sink.r = &r;
    sink.g = &g;
    GEOSGeometry *space = free_space(&g, r.alloc, scene, err, &st);
    if (space) {
        poly_ctx pc = {&sink, 0, (uint32_t)SL_MAX(GEOSGetNumGeometries_r(g.h, space), 1), SL_OK, err};
        sl_geos_each_polygon(&g, space, triangulate_polygon, &pc);
        st = pc.st;
        if (st == SL_OK && sink.oom)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street view cells: out of memory after %zu cells", sink.cells.count);
        if (st == SL_OK && sink.limit)
            st = sl_fail(err, SL_ERROR_LIMIT, "street view cells: more than %u cells (raise max_cells or max_edge)",
                         r.max_cells);
        GEOSGeom_destroy_r(g.h, space);
    }
    sl_geos_finish(&g);
    sl_free(r.alloc, sink.xy, sink.xy_cap * sizeof(double));
    if (st == SL_OK && sink.cells.count == 0)
        st = sl_fail(err, SL_ERROR_UNSUPPORTED, "street view cells: the free space has no area");
    if (st != SL_OK) {
        sl_array_free(r.alloc, &sink.cells, sizeof(sl_viewcell));
        return st;
    }
    /* shrink the array to its count so that the container frees exactly what it holds */
    sl_viewcell *cells = sl_realloc(r.alloc, sink.cells.data, sink.cells.cap * sizeof(sl_viewcell),
                                    sink.cells.count * sizeof(sl_viewcell));
    if (!cells) {
        sl_array_free(r.alloc, &sink.cells, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street view cells: out of memory");
    }
    return sl_viewcells_adopt(r.alloc, cells, (uint32_t)sink.cells.count, out, err);
}

/* ============================================================================================
 * Grid cells
 * ============================================================================================ */

static sl_status finish_array(const sl_allocator *a, sl_array *arr, sl_viewcells *out, const char *who, sl_error *err)
{
    if (arr->count == 0) {
        sl_array_free(a, arr, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: no cells", who);
    }
    sl_viewcell *cells = sl_realloc(a, arr->data, arr->cap * sizeof(sl_viewcell), arr->count * sizeof(sl_viewcell));
    if (!cells) {
        sl_array_free(a, arr, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", who);
    }
    return sl_viewcells_adopt(a, cells, (uint32_t)arr->count, out, err);
}

sl_status sl_viewcells_grid(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_grid: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_GRID_EDGE, &r, "grid view cells", err);
    if (st != SL_OK)
        return st;
    uint32_t ns = sl_scene_street_polygon_count(scene);
    sl_aabb ext = sl_aabb_empty();
    for (uint32_t i = 0; i < ns; i++) {
        sl_polygon_view pv = sl_scene_street_polygon(scene, i);
        for (uint32_t k = 0; k < pv.vertex_count; k++)
            sl_aabb_grow(&ext, (sl_vec3){pv.xy[2 * k], pv.xy[2 * k + 1], 0});
    }
    if (ns == 0)
        ext = sl_scene_bounds(scene);
    if (sl_aabb_is_empty(&ext))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "grid view cells: the scene is empty");
    double s = r.max_edge;
    double nxd = ceil(((double)ext.max.x - ext.min.x) / s), nyd = ceil(((double)ext.max.y - ext.min.y) / s);
    nxd = fmax(nxd, 1);
    nyd = fmax(nyd, 1);
    if (nxd * nyd > (double)r.max_cells * 4.0 || nxd * nyd > 1e9)
        return sl_fail(err, SL_ERROR_LIMIT, "grid view cells: %.0f x %.0f cells of %g m is too many (max_cells %u)",
                       nxd, nyd, s, r.max_cells);
    uint32_t nx = (uint32_t)nxd, ny = (uint32_t)nyd;
    sl_geos g;
    GEOSGeometry *space = NULL;
    const GEOSPreparedGeometry *prep = NULL;
    if (ns > 0) {
        if (!sl_geos_init(&g))
            return sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS could not start");
        space = free_space(&g, r.alloc, scene, err, &st);
        prep = space ? GEOSPrepare_r(g.h, space) : NULL;
        if (space && !prep)
            st = sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS could not prepare the free space: %s",
                         g.message);
    }
    sl_array arr = {0};
    for (uint32_t j = 0; j < ny && st == SL_OK; j++) {
        for (uint32_t i = 0; i < nx && st == SL_OK; i++) {
            double x0 = ext.min.x + i * s, y0 = ext.min.y + j * s, x1 = x0 + s, y1 = y0 + s;
            if (prep) {
                GEOSGeometry *rect = GEOSGeom_createRectangle_r(g.h, x0, y0, x1, y1);
                char hit = rect ? GEOSPreparedIntersects_r(g.h, prep, rect) : 2;
                if (rect)
                    GEOSGeom_destroy_r(g.h, rect);
                if (hit == 2) {
                    st = sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS failed on cell (%u, %u): %s", i, j,
                                 g.message);
                    break;
                }
                if (!hit)
                    continue;
            }
            float lo, hi;
            sl_ground_range(scene, x0, y0, x1, y1, &lo, &hi);
            sl_aabb b = {{(float)x0, (float)y0, lo + r.eye_min}, {(float)x1, (float)y1, hi + r.eye_max}};
            sl_viewcell c;
            fill_box(&c, b);
            if (arr.count >= r.max_cells)
                st = sl_fail(err, SL_ERROR_LIMIT, "grid view cells: more than %u cells", r.max_cells);
            else if (!sl_array_push(r.alloc, &arr, sizeof c, &c, 1))
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid view cells: out of memory");
        }
        if (st == SL_OK && !sl_progress_report(r.progress, "view cells", j + 1, ny))
            st = sl_fail(err, SL_ERROR_CANCELLED, "grid view cells: cancelled");
    }
    if (ns > 0) {
        if (prep)
            GEOSPreparedGeom_destroy_r(g.h, prep);
        if (space)
            GEOSGeom_destroy_r(g.h, space);
        sl_geos_finish(&g);
    }
    if (st != SL_OK) {
        sl_array_free(r.alloc, &arr, sizeof(sl_viewcell));
        return st;
    }
    return finish_array(r.alloc, &arr, out, "grid view cells", err);
}

/* ============================================================================================
 * Quake III clusters
 * ============================================================================================ */

sl_status sl_viewcells_from_bsp(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_from_bsp: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_GRID_EDGE, &r, "bsp view cells", err);
    if (st != SL_OK)
        return st;
    sl_bsp_view bsp;
    if (!sl_scene_bsp(scene, &bsp))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "bsp view cells: the scene has no BSP data (not a Quake III map)");
    if (bsp.cluster_count == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "bsp view cells: the map has no clusters");
    if (bsp.cluster_count > SL_VC_MAX_CLUSTER)
        return sl_fail(err, SL_ERROR_LIMIT, "bsp view cells: %u clusters (at most %d)", bsp.cluster_count,
                       SL_VC_MAX_CLUSTER);
    sl_aabb *boxes = sl_alloc(r.alloc, bsp.cluster_count * sizeof(sl_aabb));
    if (!boxes)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bsp view cells: out of memory");
    for (uint32_t c = 0; c < bsp.cluster_count; c++)
        boxes[c] = sl_aabb_empty();
    for (uint32_t l = 0; l < bsp.leaf_count; l++) {
        int32_t c = bsp.leaves[l].cluster;
        if (c >= 0 && (uint32_t)c < bsp.cluster_count && !sl_aabb_is_empty(&bsp.leaves[l].bounds))
            sl_aabb_merge(&boxes[c], &bsp.leaves[l].bounds);
    }
    sl_array arr = {0};
    for (uint32_t c = 0; c < bsp.cluster_count && st == SL_OK; c++) {
        if (sl_aabb_is_empty(&boxes[c]))
            continue;
        sl_viewcell cell;
        fill_box(&cell, boxes[c]);
        cell.shape = SL_CELL_CLUSTER;
        cell.cluster = (int32_t)c;
        if (!sl_array_push(r.alloc, &arr, sizeof cell, &cell, 1))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bsp view cells: out of memory");
    }
    sl_free(r.alloc, boxes, bsp.cluster_count * sizeof(sl_aabb));
    if (st != SL_OK) {
        sl_array_free(r.alloc, &arr, sizeof(sl_viewcell));
        return st;
    }
    return finish_array(r.alloc, &arr, out, "bsp view cells", err);
}

/* ============================================================================================
 * Adaptive subdivision of a navigable volume
 * ============================================================================================ */

typedef struct adapt {
    const resolved *r;
    sl_scene scene;
    sl_bvh bvh;
    uint32_t object;            /* the volume's own object (not an obstacle), or SL_NONE */
    /* world-space triangles of the volume mesh, 9 floats each (NULL: box volume) */
    float *tris;
    uint32_t tri_count;
    sl_array cells;
    sl_status st;
    sl_error *err;
} adapt;

/* Ray parity along a fixed skewed direction: inside a closed mesh when odd. */
static bool inside_mesh(const adapt *ad, sl_vec3 p)
{
    const double d[3] = {0.8727, 0.3141, 0.3737}; /* skewed so that it grazes no axis-aligned edge */
    const double o[3] = {p.x, p.y, p.z};
    uint32_t hits = 0;
    for (uint32_t k = 0; k < ad->tri_count; k++) {
        double v[9];
        for (int i = 0; i < 9; i++)
            v[i] = ad->tris[9 * k + (uint32_t)i];
        hits += sl_ray_triangle(o, d, v, v + 3, v + 6, 1e-18, NULL); /* src/core/dvec3.c */
    }
    return hits & 1;
}

static bool meets_obstacle(const adapt *ad, const sl_aabb *b)
{
    if (!ad->bvh)
        return false;
    uint32_t ids[2];
    uint32_t n = sl_bvh_query_aabb(ad->bvh, b, ids, 2);
    if (n == 0)
        return false;
    if (n >= 2 || ids[0] != ad->object)
        return true;
    return false;
}

static void subdivide(adapt *ad, sl_aabb b, uint32_t depth)
{
    if (ad->st != SL_OK)
        return;
    float ext[3] = {b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z};
    int axis = ext[1] > ext[0] ? 1 : 0;
    if (ext[2] > ext[axis])
        axis = 2;
    float big = ext[axis];
    bool split = depth < 48 && (big > ad->r->max_edge || (big > ad->r->min_edge && meets_obstacle(ad, &b)));
    if (split) {
        sl_aabb lo = b, hi = b;
        float mid = 0.5f * ((&b.min.x)[axis] + (&b.max.x)[axis]);
        (&lo.max.x)[axis] = mid;
        (&hi.min.x)[axis] = mid;
        subdivide(ad, lo, depth + 1);
        subdivide(ad, hi, depth + 1);
        return;
    }
    if (ad->tris) {
        sl_vec3 c = {0.5f * (b.min.x + b.max.x), 0.5f * (b.min.y + b.max.y), 0.5f * (b.min.z + b.max.z)};
        if (!inside_mesh(ad, c))
            return;
    }
    if (ad->cells.count >= ad->r->max_cells) {
        ad->st = sl_fail(ad->err, SL_ERROR_LIMIT, "adaptive view cells: more than %u cells", ad->r->max_cells);
        return;
    }
    sl_viewcell c;
    fill_box(&c, b);
    if (!sl_array_push(ad->r->alloc, &ad->cells, sizeof c, &c, 1))
        ad->st = sl_fail(ad->err, SL_ERROR_OUT_OF_MEMORY, "adaptive view cells: out of memory");
}

sl_status sl_viewcells_adaptive(sl_scene scene, const sl_aabb *volume, uint32_t object, const sl_viewcell_options *opt,
                                sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_adaptive: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_ADAPTIVE_EDGE, &r, "adaptive view cells", err);
    if (st != SL_OK)
        return st;
    adapt ad;
    memset(&ad, 0, sizeof ad);
    ad.r = &r;
    ad.scene = scene;
    ad.err = err;
    ad.object = SL_NONE;
    sl_aabb box;
    const struct sl_scene_t *s = scene;
    if (volume) {
        box = *volume;
        if (!sl_finite3(&box.min.x) || !sl_finite3(&box.max.x) || !(box.min.x < box.max.x) ||
            !(box.min.y < box.max.y) || !(box.min.z <= box.max.z))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "adaptive view cells: the volume box is empty or not finite");
    } else {
        if (object >= sl_scene_object_count(scene))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "adaptive view cells: object %u does not exist (%u objects)",
                           object, sl_scene_object_count(scene));
        ad.object = object;
        sl_object_view ov = sl_scene_object(scene, object);
        sl_mesh_view mv = sl_scene_mesh(scene, ov.mesh);
        box = ov.bounds;
        ad.tri_count = mv.triangle_count;
        ad.tris = sl_alloc(r.alloc, ((size_t)mv.triangle_count + 1) * 9 * sizeof(float));
        if (!ad.tris)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adaptive view cells: out of memory");
        for (uint32_t t = 0; t < mv.triangle_count; t++)
            for (int k = 0; k < 3; k++) {
                const float *v = mv.positions + 3 * (size_t)mv.indices[3 * t + k];
                sl_vec3 w = sl_affine_point(&ov.transform, (sl_vec3){v[0], v[1], v[2]});
                memcpy(ad.tris + 9 * (size_t)t + 3 * k, &w, sizeof w);
            }
        (void)s;
    }
    sl_bvh_options bo = {0};
    bo.alloc = r.alloc;
    bo.threads = 1;
    if (sl_scene_object_count(scene) > 0 && (st = sl_bvh_build(scene, &bo, &ad.bvh, err)) != SL_OK) {
        sl_free(r.alloc, ad.tris, ((size_t)ad.tri_count + 1) * 9 * sizeof(float));
        return st;
    }
    ad.st = SL_OK;
    subdivide(&ad, box, 0);
    sl_bvh_destroy(ad.bvh);
    sl_free(r.alloc, ad.tris, ((size_t)ad.tri_count + 1) * 9 * sizeof(float));
    if (ad.st != SL_OK) {
        sl_array_free(r.alloc, &ad.cells, sizeof(sl_viewcell));
        return ad.st;
    }
    return finish_array(r.alloc, &ad.cells, out, "adaptive view cells", err);
}

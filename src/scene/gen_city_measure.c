/* sl_city_measure: the figures that say whether two generated cities are comparable (extent,
 * objects, building height, street area) and how far one sees along their streets (straight
 * sight lines from every street edge's midpoint, blocked by building footprints). Public scene
 * API only, plus the scene's allocator. */
#include "gen_city_internal.h"

#include <stdlib.h>

#define MEASURE_CELL 16.0 /* bucket size of the footprint-edge grid */

typedef struct seg2 {
    double ax, ay, bx, by;
} seg2;

typedef struct edge_grid {
    double x0, y0;
    int nx, ny;
    uint32_t *start; /* nx*ny + 1 */
    uint32_t *item;  /* segment indices */
    seg2 *seg;
    uint32_t nseg, nitem;
} edge_grid;

static int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

static void seg_cells(const edge_grid *g, const seg2 *s, int *i0, int *j0, int *i1, int *j1)
{
    *i0 = clampi((int)floor((fmin(s->ax, s->bx) - g->x0) / MEASURE_CELL), 0, g->nx - 1);
    *i1 = clampi((int)floor((fmax(s->ax, s->bx) - g->x0) / MEASURE_CELL), 0, g->nx - 1);
    *j0 = clampi((int)floor((fmin(s->ay, s->by) - g->y0) / MEASURE_CELL), 0, g->ny - 1);
    *j1 = clampi((int)floor((fmax(s->ay, s->by) - g->y0) / MEASURE_CELL), 0, g->ny - 1);
}

/* Ray o + t d (d unit) against segment s: the hit parameter t >= 0, or INFINITY. */
static double ray_seg(double ox, double oy, double dx, double dy, const seg2 *s)
{
    double ex = s->bx - s->ax, ey = s->by - s->ay;
    double den = dx * ey - dy * ex;
    if (fabs(den) < 1e-12)
        return INFINITY;
    double wx = s->ax - ox, wy = s->ay - oy;
    double t = (wx * ey - wy * ex) / den, u = (wx * dy - wy * dx) / den;
    return t >= 0 && u >= 0 && u <= 1 ? t : INFINITY;
}

/* Distance along the ray to the first footprint edge, at most tmax (grid traversal). */
static double cast(const edge_grid *g, double ox, double oy, double dx, double dy, double tmax, uint32_t *stamp,
                   uint32_t ray)
{
    int i = (int)floor((ox - g->x0) / MEASURE_CELL), j = (int)floor((oy - g->y0) / MEASURE_CELL);
    if (i < 0 || j < 0 || i >= g->nx || j >= g->ny)
        return 0;
    int si = dx > 0 ? 1 : -1, sj = dy > 0 ? 1 : -1;
    double tdx = fabs(dx) > 1e-12 ? MEASURE_CELL / fabs(dx) : INFINITY;
    double tdy = fabs(dy) > 1e-12 ? MEASURE_CELL / fabs(dy) : INFINITY;
    double bx = g->x0 + (i + (dx > 0)) * MEASURE_CELL, by = g->y0 + (j + (dy > 0)) * MEASURE_CELL;
    double tx = fabs(dx) > 1e-12 ? (bx - ox) / dx : INFINITY, ty = fabs(dy) > 1e-12 ? (by - oy) / dy : INFINITY;
    double best = INFINITY;
    for (;;) {
        size_t cell = (size_t)j * g->nx + i;
        for (uint32_t k = g->start[cell]; k < g->start[cell + 1]; k++) {
            uint32_t sidx = g->item[k];
            if (stamp[sidx] == ray)
                continue;
            stamp[sidx] = ray;
            best = fmin(best, ray_seg(ox, oy, dx, dy, &g->seg[sidx]));
        }
        double leave = fmin(tx, ty);
        if (best <= leave || leave >= tmax)
            break;
        if (tx < ty)
            i += si, tx += tdx;
        else
            j += sj, ty += tdy;
        if (i < 0 || j < 0 || i >= g->nx || j >= g->ny)
            break;
    }
    return fmin(best, tmax);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

sl_status sl_city_measure(sl_scene scene, sl_city_stats *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_city_measure: NULL argument");
    memset(out, 0, sizeof *out);
    uint32_t nfp = sl_scene_footprint_count(scene), npoly = sl_scene_street_polygon_count(scene);
    if (nfp == 0 || npoly == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_city_measure: the scene has %u footprints and %u street polygons (not a city)", nfp, npoly);
    const sl_allocator *a = &scene->alloc;

    /* extent */
    double ex0, ey0, ex1, ey1;
    const char *ext = sl_scene_meta(scene, "extent");
    if (!ext || sscanf(ext, "%lf %lf %lf %lf", &ex0, &ey0, &ex1, &ey1) != 4 || !(ex1 > ex0) || !(ey1 > ey0)) {
        sl_scene_stats st;
        sl_scene_get_stats(scene, &st);
        ex0 = st.bounds.min.x, ey0 = st.bounds.min.y, ex1 = st.bounds.max.x, ey1 = st.bounds.max.y;
    }
    out->extent_x = ex1 - ex0, out->extent_y = ey1 - ey0;

    /* objects and buildings */
    out->object_count = sl_scene_object_count(scene);
    double hsum = 0;
    for (uint32_t o = 0; o < out->object_count; o++) {
        sl_object_view v = sl_scene_object(scene, o);
        if (v.kind != SL_KIND_BUILDING)
            continue;
        out->building_count++;
        hsum += (double)v.bounds.max.z - v.bounds.min.z;
    }
    out->mean_building_height = out->building_count ? hsum / out->building_count : 0;

    /* street area */
    for (uint32_t p = 0; p < npoly; p++) {
        sl_polygon_view v = sl_scene_street_polygon(scene, p);
        double area = 0;
        for (uint32_t k = 0; k < v.vertex_count; k++) {
            uint32_t l = (k + 1) % v.vertex_count;
            area += (double)v.xy[2 * k] * v.xy[2 * l + 1] - (double)v.xy[2 * l] * v.xy[2 * k + 1];
        }
        out->street_area += 0.5 * fabs(area);
    }
    double extent_area = out->extent_x * out->extent_y;
    out->street_fraction = extent_area > 0 ? out->street_area / extent_area : 0;

    /* the footprint-edge grid */
    edge_grid g;
    memset(&g, 0, sizeof g);
    g.x0 = ex0 - MEASURE_CELL, g.y0 = ey0 - MEASURE_CELL;
    g.nx = (int)ceil(out->extent_x / MEASURE_CELL) + 2, g.ny = (int)ceil(out->extent_y / MEASURE_CELL) + 2;
    for (uint32_t f = 0; f < nfp; f++)
        g.nseg += sl_scene_footprint(scene, f).vertex_count;
    size_t ncell = (size_t)g.nx * g.ny;
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(scene, &nodes, &nn, &edges, &ne);
    g.seg = sl_alloc(a, (size_t)g.nseg * sizeof(seg2));
    g.start = sl_calloc(a, ncell + 1, sizeof(uint32_t));
    uint32_t *stamp = sl_alloc(a, (size_t)g.nseg * sizeof(uint32_t));
    double *len = sl_alloc(a, (size_t)2 * ne * sizeof(double) + 1);
    sl_status st = SL_OK;
    if (!g.seg || !g.start || !stamp || !len) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_city_measure: out of memory for %u footprint edges", g.nseg);
        goto done;
    }
    uint32_t n = 0;
    for (uint32_t f = 0; f < nfp; f++) {
        sl_footprint_view v = sl_scene_footprint(scene, f);
        for (uint32_t k = 0; k < v.vertex_count; k++) {
            uint32_t l = (k + 1) % v.vertex_count;
            seg2 s = {v.xy[2 * k], v.xy[2 * k + 1], v.xy[2 * l], v.xy[2 * l + 1]};
            g.seg[n++] = s;
        }
    }
    for (int pass = 0; pass < 2; pass++) {
        for (uint32_t k = 0; k < g.nseg; k++) {
            int i0, j0, i1, j1;
            seg_cells(&g, &g.seg[k], &i0, &j0, &i1, &j1);
            for (int j = j0; j <= j1; j++)
                for (int i = i0; i <= i1; i++) {
                    size_t cell = (size_t)j * g.nx + i;
                    if (pass == 0)
                        g.start[cell + 1]++;
                    else
                        g.item[g.start[cell]++] = k;
                }
        }
        if (pass == 0) {
            for (size_t c = 0; c < ncell; c++)
                g.start[c + 1] += g.start[c];
            g.nitem = g.start[ncell];
            g.item = sl_alloc(a, (size_t)g.nitem * sizeof(uint32_t) + 1);
            if (!g.item) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_city_measure: out of memory for the edge grid");
                goto done;
            }
        } else {
            /* start[c] now holds the end of cell c: shift back */
            for (size_t c = ncell; c > 0; c--)
                g.start[c] = g.start[c - 1];
            g.start[0] = 0;
        }
    }

    /* sight lines */
    for (uint32_t k = 0; k < g.nseg; k++)
        stamp[k] = UINT32_MAX;
    double diag = hypot(out->extent_x, out->extent_y);
    uint32_t nr = 0;
    double sum = 0;
    for (uint32_t e = 0; e < ne; e++) {
        if (edges[e].a >= nn || edges[e].b >= nn)
            continue;
        sl_street_node A = nodes[edges[e].a], B = nodes[edges[e].b];
        double dx = (double)B.x - A.x, dy = (double)B.y - A.y, l = hypot(dx, dy);
        out->street_length += l;
        if (!(l > 1e-6) || (edges[e].flags & SL_STREET_SQUARE))
            continue;
        dx /= l, dy /= l;
        double mx = 0.5 * ((double)A.x + B.x), my = 0.5 * ((double)A.y + B.y);
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            /* a ray that leaves the city without meeting a building ends at the extent */
            double rx = sgn * dx, ry = sgn * dy, tmax = diag;
            if (fabs(rx) > 1e-12)
                tmax = fmin(tmax, ((rx > 0 ? ex1 : ex0) - mx) / rx);
            if (fabs(ry) > 1e-12)
                tmax = fmin(tmax, ((ry > 0 ? ey1 : ey0) - my) / ry);
            double t = cast(&g, mx, my, rx, ry, fmax(tmax, 0.0), stamp, nr);
            len[nr++] = t;
            sum += t;
        }
    }
    out->sight_rays = nr;
    if (nr) {
        out->sight_mean = sum / nr;
        qsort(len, nr, sizeof(double), cmp_double);
        out->sight_p90 = len[(size_t)floor(0.9 * (nr - 1))];
    }
done:
    sl_free(a, g.seg, (size_t)g.nseg * sizeof(seg2));
    sl_free(a, g.start, (ncell + 1) * sizeof(uint32_t));
    sl_free(a, g.item, (size_t)g.nitem * sizeof(uint32_t) + 1);
    sl_free(a, stamp, (size_t)g.nseg * sizeof(uint32_t));
    sl_free(a, len, (size_t)2 * ne * sizeof(double) + 1);
    return st;
}

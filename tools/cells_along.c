/* The view cells near a camera path: `pvs build --along PATH --radius R` and `pvs update` with
 * the same options (tools/pvs_cli.h, cli_viewcells_along). Apart from cmd_pvs.c so that
 * tests/test_cells_along.c can hold it to a brute-force reference. */
#include "pvs_cli.h"

#include "tool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

double cli_box_gap(const sl_aabb *a, const sl_aabb *b)
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double lo = fmax((&a->min.x)[k], (&b->min.x)[k]), hi = fmin((&a->max.x)[k], (&b->max.x)[k]);
        if (lo > hi)
            d2 += (lo - hi) * (lo - hi);
    }
    return sqrt(d2);
}

/* The path's cameras bucketed on a plan grid of at most ALONG_GRID x ALONG_GRID squares, so that a
 * cell looks only at the cameras in the squares its bounds (widened by the radius) cover: a long
 * path and a whole city's cells no longer cost cells x cameras distance tests. */
#define ALONG_GRID 512u

typedef struct along_grid {
    double x0, y0, size; /* the grid's corner and square edge */
    uint32_t *start;     /* ALONG_GRID^2 + 1 offsets into order */
    uint32_t *order;     /* camera indices, square by square */
} along_grid;

static uint32_t along_square(double v, double v0, double size)
{
    double q = floor((v - v0) / size);
    return q <= 0 ? 0 : q >= ALONG_GRID - 1 ? ALONG_GRID - 1 : (uint32_t)q;
}

static bool along_grid_make(const sl_pose *poses, uint32_t np, along_grid *g)
{
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (uint32_t i = 0; i < np; i++) {
        x0 = fmin(x0, poses[i].position.x), x1 = fmax(x1, poses[i].position.x);
        y0 = fmin(y0, poses[i].position.y), y1 = fmax(y1, poses[i].position.y);
    }
    g->x0 = x0, g->y0 = y0, g->size = fmax(fmax(x1 - x0, y1 - y0) / ALONG_GRID, 1e-3);
    g->start = calloc((size_t)ALONG_GRID * ALONG_GRID + 1, sizeof *g->start);
    g->order = malloc(((size_t)np + 1) * sizeof *g->order);
    if (!g->start || !g->order)
        return false;
    for (uint32_t i = 0; i < np; i++)
        g->start[along_square(poses[i].position.y, y0, g->size) * ALONG_GRID +
                 along_square(poses[i].position.x, x0, g->size) + 1]++;
    for (size_t k = 0; k < (size_t)ALONG_GRID * ALONG_GRID; k++)
        g->start[k + 1] += g->start[k];
    uint32_t *fill = malloc(((size_t)ALONG_GRID * ALONG_GRID + 1) * sizeof *fill);
    if (!fill)
        return false;
    memcpy(fill, g->start, ((size_t)ALONG_GRID * ALONG_GRID + 1) * sizeof *fill);
    for (uint32_t i = 0; i < np; i++)
        g->order[fill[along_square(poses[i].position.y, y0, g->size) * ALONG_GRID +
                      along_square(poses[i].position.x, x0, g->size)]++] = i;
    free(fill);
    return true;
}

sl_status cli_viewcells_along(sl_viewcells cells, sl_path path, float radius, sl_viewcells *out, uint32_t *far_cameras,
                              sl_error *err)
{
    *out = NULL;
    if (far_cameras)
        *far_cameras = 0;
    uint32_t nc = sl_viewcells_count(cells), np = sl_path_count(path);
    if (np == 0)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "the path has no cameras: no view cell is near it");
    const sl_viewcell *vc = sl_viewcells_data(cells);
    const sl_pose *poses = sl_path_poses(path);
    sl_viewcell *keep = malloc(((size_t)nc + 1) * sizeof *keep);
    uint8_t *near = calloc((size_t)np + 1, 1);
    along_grid g = {0, 0, 0, NULL, NULL};
    if (!keep || !near || !along_grid_make(poses, np, &g)) {
        free(keep), free(near), free(g.start), free(g.order);
        return tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "cells along the path: out of memory");
    }
    /* a cell is kept when a camera comes within radius of its bounds; every such camera is near */
    uint32_t n = 0;
    for (uint32_t c = 0; c < nc && np; c++) {
        const sl_aabb *b = &vc[c].bounds;
        /* in doubles: a camera within radius lies in [min - r, max + r] on each axis, and the
         * (monotone) square index of that range holds its square */
        uint32_t sx0 = along_square((double)b->min.x - radius, g.x0, g.size);
        uint32_t sx1 = along_square((double)b->max.x + radius, g.x0, g.size);
        uint32_t sy0 = along_square((double)b->min.y - radius, g.y0, g.size);
        uint32_t sy1 = along_square((double)b->max.y + radius, g.y0, g.size);
        /* one square more on each side: proof against a rounding of the division at any scale */
        sx0 -= sx0 > 0, sy0 -= sy0 > 0;
        sx1 += sx1 < ALONG_GRID - 1, sy1 += sy1 < ALONG_GRID - 1;
        bool kept = false;
        for (uint32_t sy = sy0; sy <= sy1 && !(kept && !far_cameras); sy++)
            for (uint32_t k = g.start[sy * ALONG_GRID + sx0]; k < g.start[sy * ALONG_GRID + sx1 + 1]; k++) {
                uint32_t i = g.order[k];
                sl_aabb eye = {poses[i].position, poses[i].position};
                if (cli_box_gap(b, &eye) <= radius) {
                    kept = true, near[i] = 1;
                    if (!far_cameras) /* only the cells are asked for: the first camera decides */
                        break;
                }
            }
        if (kept)
            keep[n++] = vc[c];
    }
    for (uint32_t i = 0; far_cameras && n && i < np; i++)
        *far_cameras += !near[i];
    sl_status st = n ? sl_viewcells_create(keep, n, NULL, out, err)
                     : tool_fail(err, SL_ERROR_INVALID_ARGUMENT,
                               "no view cell lies within %g m of the path's %u cameras (a path of another scene?)",
                               (double)radius, np);
    free(keep), free(near), free(g.start), free(g.order);
    return st;
}

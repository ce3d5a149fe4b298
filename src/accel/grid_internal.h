/* Internal layout of sl_grid, for methods that read cells in tight loops (horizon, cull maps).
 *
 * Cells are numbered c = cy * nx + cx. Cell lists use a CSR layout with slack: the slots of cell c
 * are ids[start[c] .. start[c+1]), of which the first count[c] are used, in ascending object id.
 * A fresh build has no slack (start[c+1] - start[c] == count[c]); updates that overflow a cell
 * re-lay the arrays out with room to spare (the overflowing cells get twice what they need, every
 * other cell at least one free slot), so relayouts become rare once traffic has settled.
 * Per object the grid remembers the cell rectangle it is listed in (rect) and its top (box max z),
 * which lets an update remove it and recompute the maximum heights of the cells it left.
 */
#ifndef SL_ACCEL_GRID_INTERNAL_H
#define SL_ACCEL_GRID_INTERNAL_H

#include "sightline/accel.h"
#include "core/sl_core.h"

/* Most cells a grid may have (64 Mi): beyond that the cell size is unreasonable for the scene. */
#define SL_GRID_MAX_CELLS (1u << 26)

typedef struct sl_grid_rect {
    uint32_t i0, j0, i1, j1;    /* inclusive cell range; i0 == SL_NONE: listed nowhere */
} sl_grid_rect;

struct sl_grid_t {
    sl_allocator alloc;
    uint32_t nx, ny, ncells;
    float cell, inv_cell;
    float min_x, min_y, max_x, max_y;
    uint32_t *start;            /* ncells + 1 */
    uint32_t *count;            /* ncells */
    uint32_t *ids;              /* start[ncells] slots */
    float *max_z;               /* ncells; -INFINITY for an empty cell */
    float *ground;              /* ncells; lower bound of the terrain */
    uint32_t object_count;
    sl_grid_rect *rect;         /* object_count */
    float *top;                 /* object_count */
    uint8_t *mark;              /* object_count, zero between updates (duplicate detection) */
    int32_t *pending;           /* ncells, zero between updates (net insertions per cell) */
    uint64_t entries;           /* sum of count[] */
};

/* Cell coordinate of v along one axis, clamped to 0..n-1 (NaN gives 0). The single mapping used by
 * every grid function, so that all of them agree on which cell a point belongs to. */
static inline uint32_t sl_grid_coord(float v, float origin, float inv, uint32_t n)
{
    float f = (v - origin) * inv;
    if (!(f > 0.0f))
        return 0;
    if (f >= (float)n)
        return n - 1;
    uint32_t i = (uint32_t)f;
    return i < n ? i : n - 1;
}

#endif

/* The cull map of Wonka's thesis (ch. 4, "occluder shadows"): a top-down height map over a regular
 * grid, one value per cell, filled by rasterizing the shadow polygon of each occluder edge seen from
 * an eye with max merging. The map is conservative: every point of cell c whose height lies in
 * [floor[c], z[c]] is hidden from the eye (it is also valid for any object listed in the cell,
 * since floor[c] is at most the lowest point of every such object).
 *
 * This is an internal API shared by the online cull-map culler (src/cull/cullmap.c) and the
 * from-region PVS (which merges several point cull maps with a minimum): it knows nothing of
 * scenes, cameras or cullers, only of an eye, occluder edges and a grid of cells.
 *
 * Shadow of one edge. A façade is a vertical quad from the top edge a->b down to base_z. Its
 * shadow from eye O is the wedge behind the edge between the rays O->a and O->b; at a point (x,y)
 * of the wedge every height between the plane through O and the base edge and the plane through O
 * and the top edge is hidden (the segment from O crosses the façade). Edges are given oriented so
 * that O is in front (the edge turns clockwise seen from O).
 *
 * Conservative rasterization (thesis §4.3.4): a cell is written only when it lies entirely inside
 * the shadow, tested at its centre against the edge line and the side rays moved inward by
 * l(|nx|+|ny|) (l: half the cell plus a rounding margin; n: the line's unit normal), and the value
 * written is the minimum of the top plane over the cell, P(centre) - l(|Px|+|Py|); a cell is
 * skipped where the bottom plane rises above the cell's floor. Seams: a side ray shared with the
 * neighbouring edge of the same silhouette chain (the next edge starts where this one ends, both
 * facing the eye) is not moved inward, so the shadows of a building's (or a row of buildings')
 * façades leave no crack: a cell straddling such rays takes the minimum over every wedge it
 * touches, each checked for "behind its edge", and is dropped when it reaches past the chain's end.
 * Overlapping shadows of separate occluders: with partial coverage on (sl_cullmap_grid.part), a cell
 * straddling a silhouette ray but wholly behind the edge keeps the covered part of its azimuth
 * range, and is written when the parts of several shadows meet (Wonka's fig. 5.2 b).
 */
#ifndef SL_REGION_CULLMAP_RASTER_H
#define SL_REGION_CULLMAP_RASTER_H

#include "sightline/core.h"

#include <stdbool.h>
#include <stdint.h>

/* Most edges on each side of the rasterized one that a cell may straddle (longer runs of tiny
 * wedges near the eye are simply not covered). */
#define SL_CULLMAP_MAX_SEAM 4

/* Partial coverage of one cell, in pseudo-azimuth offsets from the cell's first azimuth: [0, l_end]
 * covered with value l_val, [r_start, span] with r_val. */
typedef struct sl_cullmap_part {
    uint32_t stamp;
    float l_end, l_val, r_start, r_val;
} sl_cullmap_part;

typedef struct sl_cullmap_grid {
    uint32_t nx, ny;           /* cells along x and y */
    double min_x, min_y;       /* corner of cell (0,0) */
    double cell;               /* cell edge in metres */
    double margin;             /* added to the half cell in every coverage test: absorbs the float
                                  rounding of the mapping from points to cells */
    float *z;                  /* nx*ny cull values; -INFINITY: nothing known hidden */
    const float *floor;        /* nx*ny lowest point of anything in the cell (INFINITY when empty);
                                  NULL: the caller guarantees that nothing lies below the bottom
                                  plane of any shadow (the bottom test is skipped) */
    /* optional saturation (NULL top: off): a value at or above top[c], the highest point of
     * anything in the cell, hides all of it, so higher values are worthless; unsat[b] counts the
     * cells of block b (2^block_shift cells square, block_shift <= 6, bnx blocks per row) still below their top
     * within the clip, which sl_cullmap_clear sets up; the rasterizer skips saturated blocks */
    const float *top;
    uint16_t *unsat;
    uint32_t block_shift, bnx;
    /* optional (NULL: off), with top: a value per block known to hold over the whole block (a
     * coarser map's) and the block's highest point; a block whose value reaches its top is
     * skipped like a saturated one */
    const float *block_z, *block_top;
    /* optional (NULL: off), with top: the unsaturated cells as bits, so that the rasterizer visits
     * only those (a cell is unsaturated while its value is below its top). row_bits: per row,
     * words 64-bit words, bit i set when cell i of the row is unsaturated; band_bits: the same per
     * band of 2^block_shift rows (bit i: some cell of column i in the band is unsaturated);
     * band_count: per band and column (nx per band), how many. Valid on the clip's cells (zero
     * elsewhere); sl_cullmap_clear sets them up there (the caller zeroes them first). */
    uint64_t *row_bits, *band_bits;
    uint8_t *band_count;
    uint32_t words;
    /* optional partial coverage (NULL part: off): a cell straddling the silhouette ray of a shadow
     * records the part of its azimuth range that the shadow covers (an entry per cell, valid when
     * its stamp equals the map's); when the shadows of different occluders together cover the cell,
     * it takes the smaller value. The caller bumps stamp once per map. */
    struct sl_cullmap_part *part;
    uint32_t stamp;
    /* values at or below this hide nothing anywhere (the lowest floor of the map): shadows are
     * clipped where they drop below it (descending shadows seen from above end there);
     * -INFINITY: no clipping */
    float useful_min;
} sl_cullmap_grid;

/* Rows j0..j1 (inclusive) and per row an inclusive cell range x0[j-j0]..x1[j-j0] (x0 > x1: empty)
 * that the rasterizer may write: the part of the map the caller cares about (the view frustum). */
typedef struct sl_cullmap_clip {
    uint32_t j0, j1;
    uint32_t i0, i1;           /* bounding columns of all the rows' ranges */
    const int32_t *x0, *x1;
} sl_cullmap_clip;

/* One occluder edge, oriented with the eye in front (clockwise seen from the eye): top edge from
 * (ax, ay, az) to (bx, by, bz), façade down to base. */
typedef struct sl_shadow_edge {
    double ax, ay, az, bx, by, bz;
    double base;
} sl_shadow_edge;

/* Rasterize the shadow of window[self] into the map (max merging), clipped to clip. window[0..count)
 * is a run of consecutive edges of one silhouette chain (window[i] ends exactly where window[i+1]
 * starts, all facing the eye); the others are seam partners only, at most SL_CULLMAP_MAX_SEAM on
 * each side of self. An edge that does not face the eye (or is degenerate) yields nothing. Returns
 * the number of cells written. */
uint64_t sl_cullmap_raster_wedge(sl_cullmap_grid *map, const double eye[3], const sl_shadow_edge *window, uint32_t count,
                                 uint32_t self, const sl_cullmap_clip *clip);

/* Set z to -INFINITY on the clip's cells (and count the unsaturated cells per block when the map
 * has top, and set their bits when it has row_bits; the blocks, bands and rows touching the clip
 * must have been zeroed by the caller). */
void sl_cullmap_clear(sl_cullmap_grid *map, const sl_cullmap_clip *clip);

/* dst = min(dst, src) cell by cell on the clip's cells (the from-region merge over sample points:
 * hidden from the region means hidden from every sample). */
void sl_cullmap_merge_min(sl_cullmap_grid *dst, const sl_cullmap_grid *src, const sl_cullmap_clip *clip);

/* floor and ceil without a libm call (the rasterizer's cell ranges). Exact for every double: a
 * value of magnitude 2^52 or more is already an integer, and infinities and NaN are returned as they
 * are, so only values strictly inside (-2^52, 2^52) are converted to int64_t (a conversion of an
 * infinite or out-of-range value is undefined behaviour). */
static inline double sl_cullmap_ffloor(double x)
{
    if (!(x > -0x1p52 && x < 0x1p52))
        return x;
    double t = (double)(int64_t)x;
    return t > x ? t - 1 : t;
}
static inline double sl_cullmap_fceil(double x)
{
    if (!(x > -0x1p52 && x < 0x1p52))
        return x;
    double t = (double)(int64_t)x;
    return t < x ? t + 1 : t;
}

#endif

/* Internal layout of the pvs layer's handles (view cells), shared by the cell generators, the
 * .slpvs reader and writer, the bake and the region oracle. */
#ifndef SL_VIEWCELLS_INTERNAL_H
#define SL_VIEWCELLS_INTERNAL_H

#include "sightline/region.h"
#include "core/sl_core.h"

#include <math.h>

/* A node of the lookup tree over the cell boxes. Leaves (count > 0) list cells
 * order[first .. first+count); an inner node's children are node+1 and `first`. */
typedef struct sl_vc_node {
    sl_aabb box;
    uint32_t first;
    uint32_t count;
} sl_vc_node;

#define SL_VC_LEAF_SIZE 4u
#define SL_VC_MAX_DEPTH 64u
/* Largest cluster number a CLUSTER cell may carry (bounds the cluster-to-cell table). */
#define SL_VC_MAX_CLUSTER (1 << 24)

struct sl_viewcells_t {
    sl_allocator alloc;
    uint32_t count;
    sl_viewcell *cells;
    uint32_t node_count;
    sl_vc_node *nodes;
    uint32_t *order;            /* count entries */
    uint32_t cluster_span;      /* entries of cluster_map: largest cluster + 1 (0: no clusters) */
    uint32_t *cluster_map;      /* cluster -> cell, or SL_NONE */
    uint64_t key;
};

/* The box of a prism cell: its triangle's XY extent and [z_min, z_max]. */
static inline sl_aabb sl_viewcell_prism_bounds(const sl_viewcell *c)
{
    sl_aabb b;
    b.min.x = fminf(c->tri[0].x, fminf(c->tri[1].x, c->tri[2].x));
    b.min.y = fminf(c->tri[0].y, fminf(c->tri[1].y, c->tri[2].y));
    b.max.x = fmaxf(c->tri[0].x, fmaxf(c->tri[1].x, c->tri[2].x));
    b.max.y = fmaxf(c->tri[0].y, fmaxf(c->tri[1].y, c->tri[2].y));
    b.min.z = c->z_min;
    b.max.z = c->z_max;
    return b;
}

/* Validate one record; the message names the cell. */
sl_status sl_viewcell_validate(const sl_viewcell *c, uint32_t index, sl_error *err);

/* Make a container of count cells, taking ownership of cells (allocated with a, count entries; freed
 * on failure too): validates them and builds the lookup tree. For the generators (region layer). */
sl_status sl_viewcells_adopt(const sl_allocator *a, sl_viewcell *cells, uint32_t count, sl_viewcells *out,
                             sl_error *err);

/* Lower and upper bound of the ground height over the XY box [x0,x1] x [y0,y1]: the extreme
 * terrain samples of every terrain square meeting the box (a bilinear patch stays between its
 * corners), or 0 and 0 without terrain. */
void sl_ground_range(sl_scene scene, double x0, double y0, double x1, double y1, float *lo, float *hi);

/* Twice the signed area of triangle (a, b, c): > 0 when counter-clockwise. */
static inline double sl_orient2d(double ax, double ay, double bx, double by, double cx, double cy)
{
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
}

#endif

/* Motion regions for the PVS bake: the box hierarchy over the regions of the scene's motion
 * records and, per view cell, the nodes the static occluders may fail to hide (motion_regions.c;
 * the file's rules: pvs.h, sl_pvs_regions). */
#ifndef SL_MOTION_REGIONS_H
#define SL_MOTION_REGIONS_H

#include "sightline/pvs.h"

typedef struct sl_motion_regions {
    sl_pvs_region *nodes;       /* count nodes, node 0 the root; NULL when the scene has no records */
    uint32_t count;
    uint8_t *rows;              /* cell c's marks at rows + c * ((count + 7) / 8) */
    size_t rows_size;
} sl_motion_regions;

/* Build the hierarchy and mark it for every cell on `threads` OpenMP threads (0: the runtime's
 * default). probe_options: adjustable's options for the probe (NULL: its defaults). A scene
 * without motion records gives count 0 and no allocation. Free with sl_motion_regions_free. */
sl_status sl_motion_regions_bake(sl_scene scene, sl_viewcells cells, const char *probe_options, uint32_t threads,
                                 const sl_allocator *a, sl_motion_regions *out, sl_error *err);
/* The same, taking the row of each cell c with keep[c] set from `old` (a file of the same cells)
 * when old holds exactly the hierarchy built now; otherwise every cell is marked. *copied receives
 * the cells whose rows were taken (pvs_update.c: the cells whose every sight line into the edit
 * is blocked see the regions as before). */
sl_status sl_motion_regions_update(sl_scene scene, sl_viewcells cells, const char *probe_options, uint32_t threads,
                                   sl_pvs old, const uint8_t *keep, const sl_allocator *a, sl_motion_regions *out,
                                   uint32_t *copied, sl_error *err);
void sl_motion_regions_free(const sl_allocator *a, sl_motion_regions *r);

#endif

#ifndef SL_CULL_OCCLUSION_EXACT_H
#define SL_CULL_OCCLUSION_EXACT_H

#include "cull/occlusion/view.h"
#include "raster/raster_ref.h"
#include "scene/scene_internal.h"

#include <math.h>

/* ---- the exact layer: visible objects drawn with the oracle's own rasterizer ----
 * Far, small objects (a pixel or two at the end of a street) hide each other, but as occluders
 * they are too thin for the conservative rasterizer (MESH proxies drop triangles thinner than
 * SL_OCC_MIN_INSET_PX). Drawn with the point oracle's reference rasterizer (truth/raster_ref.h),
 * with the same world-to-clip matrix, object transform and facing rule, an object's fragments
 * (covered pixel centres and their depths) are bit-identical to the ones the oracle draws for it
 * at the same resolution. Where such a fragment is nearer than every point a tested object may
 * show at that pixel centre, with a margin far above float rounding, the oracle gives the pixel
 * to something else. Only visible objects' true triangles are drawn (no proxies), so the layer
 * holds nothing that is not there. Pixels never drawn hold depth 0 (hides nothing). */
typedef struct sl_occ_exact {
    sl_allocator alloc;
    uint32_t width, height;   /* allocated size */
    float *depth;             /* oracle's reversed depth, 0 where nothing was drawn */
    uint32_t *ids;
    sl_refrast_scratch scratch;
    sl_occ_rect *dirty;       /* rectangles drawn this frame: cleared at the next begin */
    size_t dirty_count, dirty_cap;
    uint32_t drawn;           /* objects drawn this frame */
    double vp[16];            /* the oracle's world-to-clip matrix */
    uint64_t pixel_tests;
} sl_occ_exact;

sl_status sl_occ_exact_init(sl_occ_exact *e, const sl_allocator *alloc, sl_error *err);
void sl_occ_exact_free(sl_occ_exact *e);
/* Start a frame: size the buffers for the view, clear what the last frame drew. */
sl_status sl_occ_exact_begin(sl_occ_exact *e, const sl_occ_view *v, sl_error *err);
/* Draw an object (its own triangles, the oracle's facing rule) whose box covers rectangle r. */
sl_status sl_occ_exact_draw(sl_occ_exact *e, sl_scene scene, uint32_t object, const sl_occ_rect *r, sl_error *err);
/* Does the layer prove pixel (x, y) hidden for surfaces whose oracle depth there is at most rd
 * (reversed depth (1 - z/w) / 2, larger = nearer, as computed from the oracle's matrix)? The
 * oracle's own order is compared: converting to 1/w is not exact, because z and w come from a
 * float matrix whose rows are not exactly proportional. The margin (2^-20 relative) covers the
 * float storage of both depths and the ties the oracle breaks by object id. */
static inline bool sl_occ_exact_hides(sl_occ_exact *e, int32_t x, int32_t y, double rd)
{
    if (!e || !e->drawn)
        return false;
    e->pixel_tests++;
    double stored = (double)e->depth[(size_t)y * e->width + (size_t)x];
    return stored > 0.0 && stored > rd + fabs(rd) * SL_MARGIN_REL;
}
/* The largest oracle depth of a point in the box, grown by 2^-20 of its coordinates (a corner's:
 * the reversed depth is monotone along segments in front of the eye); +infinity when a corner is
 * not in front of the eye. */
double sl_occ_exact_box_depth(const sl_occ_exact *e, const sl_aabb *b);
#endif

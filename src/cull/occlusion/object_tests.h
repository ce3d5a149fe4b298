/* The hidden-object tests shared by the occlusion methods: an object tested by its own triangles
 * (sampled at pixel centres, or rasterized outward-conservatively), a box tested by the pixel rows
 * of its silhouette, over several rasterizer layers and the exact layer. */
#ifndef SL_CULL_OCCLUSION_OBJECT_TESTS_H
#define SL_CULL_OCCLUSION_OBJECT_TESTS_H

#include "cull/occlusion/exact.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/view.h"

/* Most pixels of an object's box rectangle for sl_occ_test_object_sampled. */
#define SL_OCC_SAMPLED_MAX_PX 1024
/* Test an object by its own triangles sampled at pixel centres, the way the oracle decides
 * visibility: every pixel centre within SL_OCC_MIN_INSET_PX of one of its triangles (two-sided,
 * current transform) is tested at that triangle's nearest depth, and a centre hidden in any of
 * the layers (rasterizers that hold valid occluders only) or in the exact layer (may be NULL) is
 * hidden. OCCLUDED when every such
 * centre is hidden, including when there is none (the object covers no pixel centre at the
 * camera's resolution: the oracle, and a renderer without multisampling, draw nothing of it);
 * VISIBLE otherwise, and whenever rect (the object's box, SL_OCC_RECT) holds more than
 * SL_OCC_SAMPLED_MAX_PX pixels or a vertex is not in front of the eye. Counted as one query of
 * layers[0] plus the pixel queries. */
struct sl_occ_exact;
sl_raster_result sl_occ_test_object_sampled(sl_occ_raster *const *layers, uint32_t layer_count,
                                            struct sl_occ_exact *exact, sl_scene scene, const sl_occ_view *v,
                                            uint32_t object, const sl_occ_rect *rect);
/* A box whose rectangle r (sl_occ_project_box) looks visible, tested at the pixel centres its
 * silhouette covers, at depth r->dnear: true when each such centre is hidden in some layer. The
 * box is grown by 2^-20 of its coordinates (object boxes are computed in float, the oracle places
 * vertices in double), its corners projected in double, and centres within 1/64 pixel of the
 * silhouette count as covered (the oracle snaps vertices by at most 1/512 pixel). First one query
 * for the rectangle of the centres inside the corners' bounding box (the border rows and columns
 * the box only grazes are left out; no centre at all: hidden); then, when r is at most max_rows
 * rows tall, the centres inside the convex hull of the corners, row by row (the rows within one
 * 4-row band of subtiles as one rectangle, hidden in one layer; failing that, pixel by pixel in
 * the layers and the exact layer, which may be NULL, when the band holds at most 64 centres).
 * Everything in the box covers only centres its silhouette covers, at depths no nearer than its
 * nearest corner, so it is hidden from the oracle at the same resolution too. False when a corner
 * is not in front of the eye. */
bool sl_occ_box_rows_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact,
                            const sl_occ_view *v, const sl_aabb *box, const sl_occ_rect *r, uint32_t max_rows);
/* Is an object whose box looks visible hidden by its own triangles? Hidden when either test, as
 * configured by t, hides it: the pixel-centre test (sl_occ_test_object_sampled) over all the
 * layers, tried first (cheaper, and it answers most of the small objects it applies to), then the
 * outward-conservative mesh query in each layer. Queries leave the buffers unchanged, so the
 * order changes the cost, never the answer. False when the eye is in its box. *tests (may be
 * NULL) counts the objects tested. */
bool sl_occ_object_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact, sl_scene scene,
                          const sl_occ_view *v, uint32_t object, const sl_aabb *box, const sl_occ_mesh_tests *t,
                          uint64_t *tests);
#endif

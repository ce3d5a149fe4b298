/* The margins behind every guarantee (issue 13 §6), in one place: each rounding allowance, nudge
 * and slack a conservative answer relies on, with its name and the reason for its size. A margin
 * only ever makes an answer more conservative (a box kept, a depth taken nearer or farther on the
 * safe side, an occluder shrunk); widening one costs tightness, never correctness. Narrowing one
 * needs the argument of its line redone. docs/culler-contract.md, "Margins", lists the users.
 * Include only (constants and inline functions); included by core/sl_core.h. */
#ifndef SL_CORE_MARGINS_H
#define SL_CORE_MARGINS_H

#include <math.h>

/* Relative nudge of a depth, box coordinate or depth-plane value computed in float (2^-20): a few
 * chained float operations (a transform, a division by w) round by a few 2^-24; sixteen times
 * that is far above it and far below any depth difference that matters. Users: box depths nudged
 * nearer (sl_occ_project_box, hom and cplp's box projections), occluder depths nudged farther
 * (MESH proxies, hom's occluder far depth), the exact layer's comparison, box corners grown before
 * pixel-centre tests (occluders.c), and the oracle's depth of a box. The same 2^-20 of the eye's
 * |x|+|y|+|z|+1 m is the least near plane of a float depth (sl_camera_min_near). */
#define SL_MARGIN_REL 0x1p-20
#define SL_MARGIN_REL_F 0x1p-20f

/* Frustum plane slack, relative to 1 + |d| (1e-6): a box is beyond a frustum plane only when its
 * nearest-to-inside corner is farther out than the float rounding of a dot product of a unit
 * normal with coordinates of magnitude |d| (about 2^-23 |d| per term, three terms and the sum).
 * Every culler's frustum test (sl_frustum_classify_box) and the BSP walk of view-cell lookup. */
#define SL_MARGIN_PLANE_REL 1e-6
#define SL_MARGIN_PLANE_REL_F 1e-6f
static inline float sl_margin_plane_slack(float d) { return SL_MARGIN_PLANE_REL_F * (1.0f + fabsf(d)); }

/* No slack: the public sl_frustum_test_aabb, documented as the exact p/n-vertex test on the float
 * planes (a box touching a plane within rounding may go either way). Cullers do not use it: the
 * pvs culler used to, and classifies with the plane slack now. */
#define SL_MARGIN_PLANE_EXACT 0.0f

/* Growth of a projected box's screen rectangle (1/64 pixel): its corners are projected in float,
 * which moves them by far less; the rasterizer's box query uses the same growth. */
#define SL_MARGIN_RECT_PX (1.0f / 64.0f)

/* Pixel distance within which a pixel centre counts as covered by a silhouette or a triangle in
 * the pixel-centre tests (1/64 pixel): the oracle snaps vertices to 1/256 pixel (moving an edge
 * by at most 1/512 pixel), and the tests project in double. */
#define SL_MARGIN_CENTRE_PX (1.0 / 64.0)

/* How far inside its object's silhouette an occluder must stay on screen (1/32 pixel): 8 times the
 * combined snapping error of the rasterizer and the oracle (1/512 pixel each, plus the float
 * transform), so that the two cannot disagree about a covered sample. Prism proxies are used only
 * when their inset is at least this on screen (except with res=any's silhouette rule, which erodes
 * every silhouette by it on screen), MESH proxies are shrunk by it, frusta's shadow planes are
 * moved by its angle. With inner coverage (res=any) it also covers an oracle sample
 * snapped at another resolution: its snapping error is 1/512 of its own pixel, at most 1/32 of a
 * culling pixel for any oracle up to 16 times coarser. */
#define SL_MARGIN_INSET_PX (1.0f / 32.0f)

/* Half a pixel's diagonal, rounded up (sqrt(2) / 2 < 0.70711): how far a pixel square reaches
 * from its centre along any unit direction ((|nx| + |ny|) / 2 at most). res=any shrinks occluder
 * triangles outside convex parts by it (inner coverage through the pixel-centre rule); convex
 * silhouettes are eroded by the exact (|nx| + |ny|) / 2 of each edge. */
#define SL_MARGIN_HALF_DIAG_PX 0.70711

/* Shadow-frustum plane slack of frusta (1e-6 of the magnitudes in the dot product): as the view
 * frustum's, relative to each term since shadow planes are not normalised to |d|. */
#define SL_MARGIN_SHADOW_REL 1e-6f

/* Slack of a height, a slope or an elevation tangent compared against a horizon (1e-6 relative to
 * 1 + |value|): the horizon stores float values (2^-24 relative) computed through a division and
 * atan/tan in double; sixteen times the float rounding. A node is skipped or called hidden only
 * when it clears the horizon by this. Users: sl_horizon_occluded (urban_common.c: the top raised,
 * the bottom lowered by it) and dhorizon's skip test (sl_dhorizon_skip: last frame's bound and
 * this frame's horizon). */
#define SL_MARGIN_HEIGHT_REL 1e-6
static inline double sl_margin_height_slack(double h) { return SL_MARGIN_HEIGHT_REL * (1.0 + fabs(h)); }

/* Cell-mapping slack of a 2D grid, relative to 1 m + the magnitude of the coordinates (1e-6): a
 * float point is mapped to its cell through a float subtraction of the origin and a division
 * (a few 2^-24 of the magnitude), so a box is widened by this before its cells are listed. Users:
 * the urban grid (urban_common.c: the absolute floor of u->margin, the eye-relative part of the
 * frustum's cell spans) and the sample method's cull-map window (method_sample.c). */
#define SL_MARGIN_GRID_REL 1e-6
static inline double sl_margin_grid_slack(double mag) { return SL_MARGIN_GRID_REL * (1.0 + mag); }

/* Growth of a box of transformed points (1e-6 relative to 1 + the sum of its coordinates'
 * magnitudes): the affine transform rounds each coordinate by a few 2^-24 of the magnitudes in
 * its dot products. Users: plp's per-triangle boxes (the cells a triangle is filed in). */
#define SL_MARGIN_XFORM_REL_F 1e-6f

/* The near region grown for float rounding (near_reach, near_depth of sl_occ_view_init; urban's
 * near_guard of sl_urban_view_make): exact in double, then grown by a factor 1.001 (the float
 * near-rectangle corners and the float matrix the renderer clips with) plus 1e-6 of the eye's
 * |x|+|y|+|z| plus 1e-6 m. Those two functions still spell the numbers out (issue 13: the view
 * rewrite moves them); new code uses these. */
#define SL_MARGIN_NEAR_FACTOR 1.001
#define SL_MARGIN_NEAR_EYE_REL 1e-6
static inline double sl_margin_near_grow(double r, double eye_mag)
{
    return r * SL_MARGIN_NEAR_FACTOR + SL_MARGIN_NEAR_EYE_REL * eye_mag + SL_MARGIN_NEAR_EYE_REL;
}

#endif

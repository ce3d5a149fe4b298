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

#endif

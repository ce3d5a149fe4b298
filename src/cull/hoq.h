/* The query box of the hoq method (hoq.c), apart so that tests/test_backend.c can check it: every
 * pixel centre an object covers at the culling resolution, the grown box covers at least as near. */
#ifndef SL_CULL_HOQ_H
#define SL_CULL_HOQ_H

#include "core/sl_core.h"
#include "sightline/geom.h"

/* What the query box needs of a view. */
typedef struct sl_hoq_view {
    double vp[16];      /* world to clip, the float matrix in double (as the backend converts it) */
    float eye[3];
    double footprint;   /* a pixel's width in world units: per unit of distance (perspective), or
                           absolute (ortho) */
    bool ortho;
    float margin;       /* pixels */
    bool reach;         /* the reach toward the eye (below); true from sl_hoq_view_set, false in a
                           test measuring the margin alone */
} sl_hoq_view;

/* From a view: the float world-to-clip and projection matrices (column-major, OpenGL), the viewport
 * and the eye. The pixel's width is the larger of the two axes' 2 / (scale * pixels). */
void sl_hoq_view_set(sl_hoq_view *v, const sl_mat4 *view_proj, const sl_mat4 *proj, uint32_t width, uint32_t height,
                     sl_vec3 eye, bool ortho, float margin);

/* The query box of a node with box b, into *g: b grown by margin pixel footprints at its farthest
 * corner (and by the float rounding of its coordinates), then given its reach toward the eye:
 * moved along the view rays (scaled about the eye in perspective) until its farthest point is as
 * near as its nearest one was; it keeps the grown box's footprint on screen. False when the query box reaches behind the near plane or holds the eye (it
 * must count as visible unqueried).
 *
 * Why the reach (the depth bound). The reference rasterizer covers pixel centres by the snapped
 * vertices (1/256 pixel) but takes depth from the plane through the exact ones, clamped to the
 * triangle's vertex range (raster_ref.h). A centre p the snapped triangle T covers lies within
 * 1/512 pixel (each axis) of T's exact projection, at the point q* with the same barycentric
 * weights, and p's depth is d(q*) + grad(d).(p - q*), clamped: the error grad(d).(p - q*) has no
 * bound but the clamp, since a triangle seen edge-on has an unbounded screen-space depth gradient
 * (test_hoq_box_covers measures one: a ground polygon under a degree, the fragment 0.1 % nearer
 * than the grown box at a pixel on the horizon). So the one bound is the clamp: no fragment of a
 * triangle inside b is nearer than b's nearest corner, and it lies within 1/512 pixel of b's
 * projection. The query box lies, on every view ray through the grown box's footprint, at least
 * as near as that corner, and that footprint covers b's projection
 * with the margin to spare (against both snappings), so its rasterized front is at least as near
 * as any fragment of b's triangles at every pixel they cover. */
bool sl_hoq_grow_box(const sl_hoq_view *v, const sl_aabb *b, sl_aabb *g);

#endif

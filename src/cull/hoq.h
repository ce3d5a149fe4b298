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
} sl_hoq_view;

/* From a view: the float world-to-clip and projection matrices (column-major, OpenGL), the viewport
 * and the eye. The pixel's width is the larger of the two axes' 2 / (scale * pixels). */
void sl_hoq_view_set(sl_hoq_view *v, const sl_mat4 *view_proj, const sl_mat4 *proj, uint32_t width, uint32_t height,
                     sl_vec3 eye, bool ortho, float margin);

/* Box b grown by margin pixel footprints at its farthest corner (and by the float rounding of its
 * coordinates) into *g; false when the grown box reaches behind the near plane or holds the eye
 * (it must count as visible unqueried). */
bool sl_hoq_grow_box(const sl_hoq_view *v, const sl_aabb *b, sl_aabb *g);

#endif

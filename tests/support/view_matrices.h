/* Engine-style view and projection matrices of a camera, for the tests of sl_view_from_matrices
 * (issue 13 §1): the camera's OpenGL matrices re-expressed in another depth convention, with the
 * eye space left-handed, the image flipped, the frustum shifted off-axis or cut into a tile, the
 * far plane at infinity. */
#ifndef SL_TEST_VIEW_MATRICES_H
#define SL_TEST_VIEW_MATRICES_H
#include "sightline/view.h"

enum {
    SL_TVM_LH_Z = 1,   /* eye z negated (a left-handed eye space looking down +Z, as Direct3D) */
    SL_TVM_LH_X = 2,   /* eye x negated (left-handed, still looking down -Z) */
    SL_TVM_FLIP_X = 4, /* clip x negated (a horizontally mirrored image) */
    SL_TVM_FLIP_Y = 8, /* clip y negated (Vulkan's y-down image) */
    SL_TVM_INF = 16    /* perspective: the far plane at infinity */
};

/* The screen-space map of an off-axis view: NDC x' = kx x + ox, y' = ky y + oy of the camera's
 * image (kx = ky = 1, ox = oy = 0: the camera's; a stereo eye shifts ox; tile (i, j) of an n x n
 * screen has kx = n, ox = n - 1 - 2 i). */
typedef struct sl_tvm_shape {
    double kx, ox, ky, oy;
} sl_tvm_shape;

/* V (world -> eye) and P (eye -> clip) of cam, column-major floats, in depth convention `depth`
 * with flags SL_TVM_*; shape may be NULL (the camera's own image). Computed in double, rounded
 * once. */
void sl_tvm_matrices(const sl_camera *cam, sl_clip_depth depth, unsigned flags, const sl_tvm_shape *shape, float V[16],
                     float P[16]);
#endif

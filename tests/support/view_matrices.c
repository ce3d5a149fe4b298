#include "support/view_matrices.h"

#define E(m, i, j) (m)[4 * (j) + (i)]

void sl_tvm_matrices(const sl_camera *cam, sl_clip_depth depth, unsigned flags, const sl_tvm_shape *shape, float V[16],
                     float P[16])
{
    sl_mat4 v = sl_camera_view(cam), p = sl_camera_proj(cam);
    double Vd[16], Pd[16];
    for (int i = 0; i < 16; i++) {
        Vd[i] = v.m[i];
        Pd[i] = p.m[i];
    }
    if ((flags & SL_TVM_INF) && cam->projection == SL_PERSPECTIVE) {
        E(Pd, 2, 2) = -1.0;
        E(Pd, 2, 3) = -2.0 * (double)cam->near_plane;
    }
    for (int j = 0; shape && j < 4; j++) {
        E(Pd, 0, j) = shape->kx * E(Pd, 0, j) + shape->ox * E(Pd, 3, j);
        E(Pd, 1, j) = shape->ky * E(Pd, 1, j) + shape->oy * E(Pd, 3, j);
    }
    for (int j = 0; j < 4; j++) {
        double z = E(Pd, 2, j), w = E(Pd, 3, j);
        if (depth == SL_CLIP_DEPTH_ZERO_ONE)
            E(Pd, 2, j) = 0.5 * (z + w);
        else if (depth == SL_CLIP_DEPTH_REVERSED)
            E(Pd, 2, j) = 0.5 * (w - z);
        if (flags & SL_TVM_FLIP_X)
            E(Pd, 0, j) = -E(Pd, 0, j);
        if (flags & SL_TVM_FLIP_Y)
            E(Pd, 1, j) = -E(Pd, 1, j);
    }
    for (int j = 0; j < 4; j++) {
        if (flags & SL_TVM_LH_Z) {
            E(Vd, 2, j) = -E(Vd, 2, j);
            E(Pd, j, 2) = -E(Pd, j, 2);
        }
        if (flags & SL_TVM_LH_X) {
            E(Vd, 0, j) = -E(Vd, 0, j);
            E(Pd, j, 0) = -E(Pd, j, 0);
        }
    }
    for (int i = 0; i < 16; i++) {
        V[i] = (float)Vd[i];
        P[i] = (float)Pd[i];
    }
}

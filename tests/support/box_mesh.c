#include "support/box_mesh.h"

/* counter-clockwise seen from outside (tests/test_box_mesh.c checks it): -x, +x, -y, +y, -z, +z */
const uint32_t sl_test_box_indices[36] = {0, 6, 2, 0, 4, 6, 1, 7, 5, 1, 3, 7, 0, 5, 4, 0, 1, 5,
                                          2, 7, 3, 2, 6, 7, 0, 3, 1, 0, 2, 3, 4, 7, 6, 4, 5, 7};

void sl_test_box_vertices(sl_vec3 lo, sl_vec3 hi, float p[24])
{
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
}

uint32_t sl_test_add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags)
{
    sl_error err;
    float p[24];
    sl_test_box_vertices(lo, hi, p);
    sl_mesh_desc md = {p, NULL, 8, sl_test_box_indices, 12, NULL};
    uint32_t mesh, obj;
    if (sl_scene_add_mesh(s, &md, &mesh, &err) != SL_OK)
        return SL_NONE;
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, flags, 0};
    if (sl_scene_add_object(s, &od, &obj, &err) != SL_OK)
        return SL_NONE;
    return obj;
}

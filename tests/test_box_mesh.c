/* tests/support/box_mesh: the box the hand-built test scenes use is wound outward, as its header
 * says, because tests flag it SL_OBJECT_CLOSED_CONVEX (the oracle then skips its back faces and
 * vfc drops it when every face looks away). Checked twice: every triangle's normal (counter-
 * clockwise, right-handed) points away from the box's centre, and vfc with back-face rejection
 * drops the closed box for an eye inside it while keeping it for an eye outside looking at it. An
 * inward-wound box fails both. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "support/box_mesh.h"

static void test_normals_outward(void **state)
{
    (void)state;
    float p[24];
    sl_vec3 lo = {1, 2, 3}, hi = {4, 7, 5};
    sl_test_box_vertices(lo, hi, p);
    double c[3] = {(lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, (lo.z + hi.z) / 2.0};
    for (int t = 0; t < 12; t++) {
        const float *a = &p[3 * sl_test_box_indices[3 * t]], *b = &p[3 * sl_test_box_indices[3 * t + 1]],
                    *d = &p[3 * sl_test_box_indices[3 * t + 2]];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double out = 0, len2 = 0;
        for (int k = 0; k < 3; k++) {
            out += n[k] * (a[k] - c[k]);
            len2 += n[k] * n[k];
        }
        if (!(len2 > 0 && out > 0))
            fail_msg("box triangle %d is wound inward (or degenerate)", t);
    }
}

static void test_vfc_backface(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t box = sl_test_add_box(s, (sl_vec3){-5, -5, -5}, (sl_vec3){5, 5, 5}, 0, SL_OBJECT_CLOSED_CONVEX);
    assert_int_not_equal(box, SL_NONE);
    sl_culler c;
    assert_int_equal(sl_culler_create("vfc", s, "backface=true", NULL, &c, &err), SL_OK);
    uint32_t ids[1], k;
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 0};
    assert_int_equal(sl_culler_cull(c, &cam, ids, 1, &k, &err), SL_OK);
    assert_int_equal(k, 0); /* inside a closed box every face looks away */
    /* outside, looking at it (yaw 0 looks along +x) */
    cam.position = (sl_vec3){-20, 0, 0};
    cam.yaw = 0;
    cam.pitch = 0;
    assert_int_equal(sl_culler_cull(c, &cam, ids, 1, &k, &err), SL_OK);
    assert_int_equal(k, 1);
    sl_culler_destroy(c);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_normals_outward),
        cmocka_unit_test(test_vfc_backface),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The shared frustum classifier's SSE lanes (core/frustum_classify.h, sl_frustum_lanes_reject, used
 * by plp's completion phase) give the scalar classifier's answer bit for bit: seeded camera
 * frusta and arbitrary planes, every plane mask, random slack and none, boxes from random ones to
 * boxes on small integer grids against planes with small integer coefficients (so that a box's
 * p-vertex lies exactly on a plane or exactly at its slack: `<` against `<=` tells), signed zeros,
 * infinite and NaN coordinates. Both answers occur often. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/sl_core.h"
#include "sightline/camera.h"

static float pick(sl_rng *r, const float *vals, uint32_t n) { return vals[sl_rng_u32(r) % n]; }

static float coord(sl_rng *r, int kind)
{
    static const float odd[] = {0.0f, -0.0f, 1.0f, -1.0f, 2.0f, -3.0f, INFINITY, -INFINITY, NAN, 1e30f, -1e30f};
    switch (kind) {
    case 0: return 200.0f * (sl_rng_float(r) - 0.5f);
    case 1: return (float)((int)(sl_rng_u32(r) % 9) - 4);
    default: return pick(r, odd, SL_COUNTOF(odd));
    }
}

static void test_lanes_equal_scalar(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 20261202, 13);
    const uint32_t rounds = getenv("SL_SANITIZED") ? 300 : 3000;
    uint64_t rejected = 0, kept = 0, touching = 0;
    for (uint32_t round = 0; round < rounds; round++) {
        sl_plane planes[6];
        const int pk = (int)(round % 3); /* camera frustum, integer planes, random planes */
        if (pk == 0) {
            sl_camera cam = sl_camera_default();
            cam.position = (sl_vec3){coord(&r, 0), coord(&r, 0), coord(&r, 0)};
            cam.yaw = 6.3f * sl_rng_float(&r);
            cam.pitch = 3.0f * (sl_rng_float(&r) - 0.5f);
            cam.roll = sl_rng_float(&r);
            if (round % 7 == 0)
                cam.projection = SL_ORTHOGRAPHIC, cam.ortho_height = 50;
            sl_frustum f = sl_camera_frustum(&cam);
            memcpy(planes, f.planes, sizeof planes);
        } else {
            for (int i = 0; i < 6; i++)
                planes[i] = (sl_plane){coord(&r, pk == 1 ? 1 : 0), coord(&r, pk == 1 ? 1 : 0),
                                       coord(&r, pk == 1 ? 1 : 0), coord(&r, pk == 1 ? 1 : 0)};
            if (round % 11 == 0)
                planes[sl_rng_u32(&r) % 6].a = -0.0f;
        }
        float slack[6];
        if (round % 2)
            sl_frustum_slacks(planes, slack);
        else
            for (int i = 0; i < 6; i++)
                slack[i] = pk == 1 ? (float)(sl_rng_u32(&r) % 2) : 0.0f; /* exactly at the slack too */
        const uint32_t mask = sl_rng_u32(&r) & 0x3fu;
        sl_frustum_lanes l;
        sl_frustum_lanes_init(&l, planes, slack, mask);
        for (int k = 0; k < 40; k++) {
            const int ck = k < 30 ? (pk == 1 ? 1 : 0) : (k < 36 ? 1 : 2);
            sl_aabb b;
            float x0 = coord(&r, ck), x1 = coord(&r, ck), y0 = coord(&r, ck), y1 = coord(&r, ck);
            float z0 = coord(&r, ck), z1 = coord(&r, ck);
            b.min = (sl_vec3){fminf(x0, x1), fminf(y0, y1), fminf(z0, z1)};
            b.max = (sl_vec3){fmaxf(x0, x1), fmaxf(y0, y1), fmaxf(z0, z1)};
            if (k == 39)
                b.min.x = NAN; /* fminf would have dropped it */
            const bool scalar = sl_frustum_classify_box(planes, slack, &b, mask, false, NULL) < 0;
            const bool lanes = sl_frustum_lanes_reject(&l, &b);
            if (scalar != lanes)
                fail_msg("round %u box %d mask %02x: scalar %d, lanes %d", round, k, mask, scalar, lanes);
            rejected += scalar;
            kept += !scalar;
            /* a p-vertex exactly at -slack of some plane of the mask (kept by both) */
            for (int i = 0; ck == 1 && i < 6; i++) {
                const sl_plane *p = &planes[i];
                float px = p->a >= 0 ? b.max.x : b.min.x, py = p->b >= 0 ? b.max.y : b.min.y;
                float pz = p->c >= 0 ? b.max.z : b.min.z;
                touching += (mask >> i & 1u) && p->a * px + p->b * py + p->c * pz + p->d == -slack[i];
            }
        }
    }
    print_message("frustum lanes: %llu boxes rejected, %llu kept, %llu p-vertices exactly at the slack; lanes "
                  "equal to the scalar classifier on all\n",
                  (unsigned long long)rejected, (unsigned long long)kept, (unsigned long long)touching);
    assert_true(rejected > 1000 / (getenv("SL_SANITIZED") ? 10 : 1));
    assert_true(kept > 1000 / (getenv("SL_SANITIZED") ? 10 : 1));
    assert_true(touching > 100 / (getenv("SL_SANITIZED") ? 10 : 1));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lanes_equal_scalar),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

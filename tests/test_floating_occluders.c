/* Footprints that do not stand on the ground (a bridge, a walkway, an overhang: base_z above the
 * floor of the scene) hide nothing beneath them. Every conservative method that occludes with
 * footprints, online and precomputed, must keep an object seen under one, and must still hide it
 * behind the same slab when the slab reaches the ground (so the test cannot pass by a method
 * that never occludes).
 *
 * The scene: a slab 160 m wide across y in [10, 14], either floating (z in [6, 30]) or grounded
 * (z in [0, 30]); a 4 x 2 x 3 m box behind it at y in [30, 32]; the eye (or the view cell) at
 * x, y in [-2, 2], z in [1, 2]. Under the floating slab the box is in plain view: every sight line
 * from the cell to it runs below z = 3 where it crosses the slab.
 *
 * And an object below the ground, a 4 x 5 x 2 m pit at y in [15, 20], z in [-3, -1], just behind
 * the grounded slab (in the scene without a street): seen from the cell under the slab's base
 * (the line from (0, 0, 2) to (0, 15, -3) passes y = 10 at z = -1.3), so kept by every method. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <math.h>
#include <string.h>
#include "sightline/bake.h"
#include "sightline/cull.h"
#include "sightline/region.h"
#include "support/box_cell.h"
#include "support/box_mesh.h"

typedef struct slab_scene {
    sl_scene scene;
    uint32_t slab, behind, pit;
} slab_scene;

static slab_scene make_scene(float base, bool with_ground)
{
    slab_scene r;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &r.scene, &err), SL_OK);
    if (with_ground) /* a street under everything: an object lower than the slab's base */
        assert_int_not_equal(sl_test_add_box(r.scene, (sl_vec3){-100, -20, -0.2f}, (sl_vec3){100, 60, 0},
                                             SL_KIND_GROUND, SL_OBJECT_CLOSED_CONVEX),
                             SL_NONE);
    r.slab = sl_test_add_box(r.scene, (sl_vec3){-80, 10, base}, (sl_vec3){80, 14, 30}, SL_KIND_BUILDING,
                             SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    assert_int_not_equal(r.slab, SL_NONE);
    float xy[8] = {-80, 10, 80, 10, 80, 14, -80, 14};
    sl_footprint_desc fd = {xy, 4, base, 30, r.slab};
    assert_int_equal(sl_scene_add_footprint(r.scene, &fd, NULL, &err), SL_OK);
    r.behind = sl_test_add_box(r.scene, (sl_vec3){-2, 30, 0}, (sl_vec3){2, 32, 3}, SL_KIND_BUILDING,
                               SL_OBJECT_CLOSED_CONVEX);
    assert_int_not_equal(r.behind, SL_NONE);
    r.pit = SL_NONE;
    if (!with_ground) {
        r.pit = sl_test_add_box(r.scene, (sl_vec3){-2, 15, -3}, (sl_vec3){2, 20, -1}, SL_KIND_OTHER,
                                SL_OBJECT_CLOSED_CONVEX);
        assert_int_not_equal(r.pit, SL_NONE);
    }
    return r;
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* Methods that cannot bake a single box cell of this scene (a BSP, a portal graph, a map's own
 * PVS) are skipped; every other conservative method must keep the box under the floating slab. */
static bool bakes_box_cells(const char *m)
{
    return strcmp(m, "mappvs") != 0 && strcmp(m, "portal") != 0;
}

static void test_pvs_methods(void **state)
{
    (void)state;
    for (int ground = 0; ground < 2; ground++) {
        slab_scene fl = make_scene(6, ground), gr = make_scene(0, ground);
        sl_viewcells vc = sl_test_box_cell(-2, -2, 2, 2);
        uint32_t hidden_grounded = 0, misses = 0;
        for (uint32_t i = 0; i < sl_pvs_method_count(); i++) {
            sl_pvs_method_desc d;
            sl_error err;
            assert_int_equal(sl_pvs_method_info(i, &d, &err), SL_OK);
            if (d.guarantee == SL_AGGRESSIVE || !bakes_box_cells(d.name))
                continue;
            uint32_t ids[8], n;
            sl_status st = sl_pvs_bake_cell(fl.scene, vc, 0, d.name, NULL, ids, 8, &n, &err);
            if (st != SL_OK)
                fail_msg("%s: %s", d.name, err.message);
            if (!has(ids, n, fl.behind)) {
                print_error("%s%s: the box seen under a floating slab was culled\n", d.name,
                            ground ? " (with a street below)" : "");
                misses++;
            }
            assert_int_equal(sl_pvs_bake_cell(gr.scene, vc, 0, d.name, NULL, ids, 8, &n, &err), SL_OK);
            hidden_grounded += !has(ids, n, gr.behind);
            if (gr.pit != SL_NONE && !has(ids, n, gr.pit)) {
                print_error("%s: the pit seen under the slab's base was culled\n", d.name);
                misses++;
            }
        }
        assert_int_equal(misses, 0);
        /* the footprint methods do hide it behind the grounded slab */
        assert_true(hidden_grounded >= 3);
        sl_viewcells_destroy(vc);
        sl_scene_destroy(fl.scene);
        sl_scene_destroy(gr.scene);
    }
}

/* Cases found by review, with a cell of eyes from 0.5 to 3 m (x, y in [-2, 2]) and the slab of
 * roof 30 at y in [10, 14]: seen only from eyes below the cell's top, so a method that samples
 * the top alone culled them. A: base 1.5, a box at z in [0.5, 1] behind it, seen under it from
 * (0, 2, 0.5). B: base 6 (a bridge), a box at z in [16, 16.5], seen under it from (0, 2, 0.5)
 * (at y = 14 the line runs at z 5.4). C: base 0, a pit at z in [-1, -0.9]. */
static void test_low_eyes(void **state)
{
    (void)state;
    static const struct {
        float base, y0, y1, z0, z1;
    } cases[] = {{1.5f, 40, 40.5f, 0.5f, 1}, {6, 40, 40.5f, 16, 16.5f}, {0, 20, 20.5f, -1, -0.9f}};
    sl_viewcells vc = sl_test_box_cell_z(-2, -2, 2, 2, 0.5f, 3);
    sl_error err;
    uint32_t misses = 0;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sl_scene s;
        assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
        uint32_t slab = sl_test_add_box(s, (sl_vec3){-80, 10, cases[k].base}, (sl_vec3){80, 14, 30}, SL_KIND_BUILDING,
                                        SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
        float xy[8] = {-80, 10, 80, 10, 80, 14, -80, 14};
        sl_footprint_desc fd = {xy, 4, cases[k].base, 30, slab};
        assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
        uint32_t obj = sl_test_add_box(s, (sl_vec3){-0.25f, cases[k].y0, cases[k].z0},
                                       (sl_vec3){0.25f, cases[k].y1, cases[k].z1}, SL_KIND_OTHER, SL_OBJECT_CLOSED_CONVEX);
        for (uint32_t i = 0; i < sl_pvs_method_count(); i++) {
            sl_pvs_method_desc d;
            assert_int_equal(sl_pvs_method_info(i, &d, &err), SL_OK);
            if (d.guarantee == SL_AGGRESSIVE || !bakes_box_cells(d.name))
                continue;
            uint32_t ids[8], n;
            if (sl_pvs_bake_cell(s, vc, 0, d.name, NULL, ids, 8, &n, &err) != SL_OK)
                fail_msg("%s: %s", d.name, err.message);
            if (!has(ids, n, obj)) {
                print_error("case %c, %s: the box seen from low eyes was culled\n", (char)('A' + k), d.name);
                misses++;
            }
        }
        sl_scene_destroy(s);
    }
    sl_viewcells_destroy(vc);
    assert_int_equal(misses, 0);
}

static void test_cullers(void **state)
{
    (void)state;
    for (int ground = 0; ground < 2; ground++) {
        slab_scene fl = make_scene(6, ground), gr = make_scene(0, ground);
        uint32_t hidden_grounded = 0;
        for (uint32_t i = 0; i < sl_cull_method_count(); i++) {
            sl_cull_method_desc d;
            sl_error err;
            assert_int_equal(sl_cull_method_info(i, &d, &err), SL_OK);
            if (d.guarantee == SL_AGGRESSIVE || strcmp(d.name, "pvs") == 0 || strcmp(d.name, "instant") == 0)
                continue;
            for (int g = 0; g < 2; g++) {
                slab_scene *sc = g ? &gr : &fl;
                sl_culler c;
                sl_status st = sl_culler_create(d.name, sc->scene, NULL, NULL, &c, &err);
                if (st != SL_OK)
                    fail_msg("%s: %s", d.name, err.message);
                /* eyes against the slab's underside, low and high in the cell, looking at the box */
                static const float eyes[][3] = {{0, 0, 1}, {0, 0, 2}, {1.5f, -1.5f, 1.5f}, {0, 9.5f, 1}};
                bool kept_all = true;
                for (size_t e = 0; e < sizeof eyes / sizeof eyes[0]; e++) {
                    sl_camera cam;
                    memset(&cam, 0, sizeof cam);
                    cam.position = (sl_vec3){eyes[e][0], eyes[e][1], eyes[e][2]};
                    cam.yaw = (float)(M_PI / 2);
                    cam.projection = SL_PERSPECTIVE;
                    cam.fov_y = 1.0f;
                    cam.near_plane = 0.1f;
                    cam.far_plane = 500;
                    cam.width = 320;
                    cam.height = 240;
                    uint32_t ids[8], n;
                    assert_int_equal(sl_culler_cull(c, &cam, ids, 8, &n, &err), SL_OK);
                    bool kept = has(ids, n, sc->behind);
                    if (g && sc->pit != SL_NONE && e < 3 && !has(ids, n, sc->pit))
                        fail_msg("%s: the pit seen under the slab's base was culled from (%g, %g, %g)", d.name,
                                 eyes[e][0], eyes[e][1], eyes[e][2]);
                    if (!g && !kept)
                        fail_msg("%s%s: the box seen under a floating slab was culled from (%g, %g, %g)", d.name,
                                 ground ? " (with a street below)" : "", eyes[e][0], eyes[e][1], eyes[e][2]);
                    kept_all &= kept;
                }
                hidden_grounded += g && !kept_all;
                sl_culler_destroy(c);
            }
        }
        assert_true(hidden_grounded >= 3);
        sl_scene_destroy(fl.scene);
        sl_scene_destroy(gr.scene);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pvs_methods),
        cmocka_unit_test(test_low_eyes),
        cmocka_unit_test(test_cullers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

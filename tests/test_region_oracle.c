/* The region oracle on a hand-built scene whose answer is known: a wall hides a box from the whole
 * cell, a second box peeks past the wall's end from one corner of the cell only, a third stands
 * in the open. Sample points lie in the cell, are deterministic, and the convergence figure is
 * reported; BSP clusters sample inside their leaves; bad arguments are refused; a point next to a
 * wall does not look through it (per-sample near plane) and a point on it is skipped; sight lines
 * through a BSP's solid leaves do not count. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/region.h"
#include "support/counting_alloc.h"

static uint32_t add_mesh_object(sl_scene s, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt)
{
    sl_error err;
    sl_mesh_desc md = {pos, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* An axis-aligned box (both sides of every face are drawn: no flags). */
static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    return add_mesh_object(s, p, 8, idx, 12);
}

/* A wall in the plane x = x0. */
static uint32_t add_wall(sl_scene s, float x0, float y0, float y1, float z0, float z1)
{
    float p[12] = {x0, y0, z0, x0, y1, z0, x0, y1, z1, x0, y0, z1};
    uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    return add_mesh_object(s, p, 4, idx, 2);
}

static sl_viewcell prism(float ax, float ay, float bx, float by, float cx, float cy, float z0, float z1)
{
    sl_viewcell c;
    memset(&c, 0, sizeof c);
    c.shape = SL_CELL_PRISM;
    c.cluster = -1;
    c.tri[0] = (sl_vec2){ax, ay};
    c.tri[1] = (sl_vec2){bx, by};
    c.tri[2] = (sl_vec2){cx, cy};
    c.z_min = z0;
    c.z_max = z1;
    c.bounds = (sl_aabb){{fminf(ax, fminf(bx, cx)), fminf(ay, fminf(by, cy)), z0},
                         {fmaxf(ax, fmaxf(bx, cx)), fmaxf(ay, fmaxf(by, cy)), z1}};
    return c;
}

static bool has(const sl_region_visibility *v, uint32_t id)
{
    for (uint32_t i = 0; i < v->visible_count; i++)
        if (v->visible[i] == id)
            return true;
    return false;
}

static void test_wall_scene(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t wall = add_wall(s, 10, -5, 5, 0, 10);
    uint32_t hidden = add_box(s, (sl_vec3){20, -1, 0}, (sl_vec3){22, 1, 2});
    uint32_t corner = add_box(s, (sl_vec3){20, 8, 0}, (sl_vec3){22, 10, 2});
    uint32_t open = add_box(s, (sl_vec3){-12, -1, 0}, (sl_vec3){-10, 1, 2});
    sl_viewcell cell[2] = {prism(0, -1, 2, -1, 1, 1, 1, 2), prism(0, -21, 2, -21, 1, -19, 1, 2)};
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(cell, 2, &a, &vc, &err), SL_OK);

    sl_region_oracle_options o = {0};
    o.face_size = 128;
    o.edge_spacing = 0.5f;
    o.face_samples = 16;
    o.interior_samples = 16;
    o.seed = 7;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &o, &a, &ro, &err), SL_OK);

    /* the sample points: inside the cell, in a deterministic order */
    const sl_vec3 *pts;
    uint32_t n;
    assert_int_equal(sl_region_oracle_points(ro, vc, 0, &pts, &n, &err), SL_OK);
    /* 6 vertices, edges of 2.0/2.24/2.24/1 m at 0.5 m: 3+4+4 top, same bottom, 3 vertical; 32 random */
    assert_int_equal(n, 6 + 2 * 11 + 3 + 32);
    sl_vec3 *copy = malloc(n * sizeof *copy);
    memcpy(copy, pts, n * sizeof *copy);
    for (uint32_t i = 0; i < n; i++)
        assert_true(sl_viewcell_contains(vc, NULL, 0, pts[i]));
    assert_int_equal(sl_region_oracle_points(ro, vc, 0, &pts, &n, &err), SL_OK);
    assert_memory_equal(copy, pts, n * sizeof *copy);
    free(copy);

    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, 0, &v, &err), SL_OK);
    assert_int_equal(v.sample_count, n);
    assert_true(has(&v, wall));
    assert_true(has(&v, open));
    assert_true(has(&v, corner)); /* past the wall's end from the cell's corner near (1, 1) */
    assert_false(has(&v, hidden));
    for (uint32_t i = 1; i < v.visible_count; i++)
        assert_true(v.visible[i] > v.visible[i - 1]);
    for (uint32_t i = 0; i < v.visible_count; i++) {
        assert_true(v.max_pixels[i] > 0);
        assert_true(v.first_sample[i] < v.sample_count);
    }
    assert_true(v.added_last_tenth <= v.visible_count);
    assert_true(v.ms > 0);

    /* the second cell is beside the wall: from it the hidden box shows */
    assert_int_equal(sl_region_oracle_cell(ro, vc, 1, &v, &err), SL_OK);
    assert_true(has(&v, hidden));

    /* any point set: a point far behind the wall sees the hidden box */
    sl_vec3 p[2] = {{30, 0, 1}, {1, 0, 1.5f}};
    assert_int_equal(sl_region_oracle_points_visible(ro, p, 2, &v, &err), SL_OK);
    assert_true(has(&v, hidden));
    assert_int_equal(v.sample_count, 2);
    sl_vec3 bad[1] = {{NAN, 0, 0}};
    assert_int_equal(sl_region_oracle_points_visible(ro, bad, 1, &v, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_region_oracle_cell(ro, vc, 5, &v, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cell 5"));

    sl_region_oracle_destroy(ro);
    sl_viewcells_destroy(vc);
    assert_int_equal(cnt.live, 0);
    sl_scene_destroy(s);
}

/* The cap on samples widens the edge spacing instead of dropping edges. */
static void test_cap_and_options(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){5, 5, 0}, (sl_vec3){6, 6, 1});
    sl_viewcell cell = prism(0, 0, 100, 0, 0, 100, 1, 2);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(&cell, 1, NULL, &vc, &err), SL_OK);
    sl_region_oracle_options o = {0};
    o.edge_spacing = 0.01f;
    o.max_samples = 200;
    o.face_samples = 10;
    o.interior_samples = 10;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_OK);
    const sl_vec3 *pts;
    uint32_t n;
    assert_int_equal(sl_region_oracle_points(ro, vc, 0, &pts, &n, &err), SL_OK);
    assert_true(n <= 200 && n > 150);
    sl_region_oracle_destroy(ro);
    o.max_samples = 100000;
    assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_ERROR_INVALID_ARGUMENT);
    o.max_samples = 0;
    o.edge_spacing = -1;
    assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_ERROR_INVALID_ARGUMENT);
    o.edge_spacing = 0;
    o.near_plane = 5;
    o.far_plane = 1;
    assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* A BSP with two clusters split at x = 0: a cluster's samples are in its half only. */
static void test_cluster_samples(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t left = add_box(s, (sl_vec3){-3, -1, -1}, (sl_vec3){-2, 1, 1});
    sl_plane planes[1] = {{1, 0, 0, 0}};
    sl_bsp_node nodes[1] = {{0, {-1, -2}, {{-4, -4, -4}, {4, 4, 4}}}};
    sl_bsp_leaf leaves[2] = {{0, 0, {{0, -4, -4}, {4, 4, 4}}, 0, 0}, {1, 0, {{-4, -4, -4}, {0, 4, 4}}, 0, 1}};
    uint32_t lo[1] = {left};
    uint8_t pvs[2] = {0x3, 0x3};
    sl_bsp_desc bd = {planes, 1, nodes, 1, leaves, 2, lo, 1, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, NULL, NULL, &ro, &err), SL_OK);
    for (uint32_t c = 0; c < 2; c++) {
        const sl_vec3 *pts;
        uint32_t n;
        assert_int_equal(sl_region_oracle_points(ro, vc, c, &pts, &n, &err), SL_OK);
        assert_true(n > 9);
        for (uint32_t i = 0; i < n; i++)
            assert_true(sl_viewcells_locate(vc, s, pts[i]) == c);
    }
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, 0, &v, &err), SL_OK);
    assert_true(has(&v, left)); /* nothing occludes it from the right half */
    sl_region_oracle_destroy(ro);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* A sample point next to a wall must not look through it: the cube faces' near plane (5 cm by
 * default) would clip a wall nearer than that away, and the room behind the wall would show
 * (Quake III walls are single brushes between rooms; this made the maps' own PVS look wrong).
 * The oracle shrinks the near plane below half the eye's distance to the nearest triangle. */
static void test_near_wall(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* a closed room x in [0, 10], and a box in the next room behind the wall x = 10 */
    uint32_t room = add_box(s, (sl_vec3){0, -5, 0}, (sl_vec3){10, 5, 4});
    uint32_t behind = add_box(s, (sl_vec3){12, -1, 1}, (sl_vec3){14, 1, 3});
    /* a wall of an instanced mesh (a transform) between the room and a second box */
    float p[12] = {0, -5, 0, 0, 5, 0, 0, 5, 4, 0, -5, 4};
    uint32_t idx[6] = {0, 1, 2, 0, 2, 3}, mesh, wall2;
    sl_mesh_desc md = {p, NULL, 4, idx, 2, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_affine xf = sl_affine_identity();
    xf.m[3] = -20; /* translated to x = -20 (row-major 3x4: translation in m[3], m[7], m[11]) */
    sl_object_desc od = {mesh, &xf, 0xffffffffu, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &wall2, &err), SL_OK);
    uint32_t beyond = add_box(s, (sl_vec3){-24, -1, 1}, (sl_vec3){-22, 1, 3});
    assert_true(sl_scene_object_bounds(s, wall2).max.x < -19.9f);
    sl_region_oracle_options o = {0};
    o.face_size = 64;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_OK);
    sl_region_visibility v;
    /* 1 mm, 1 cm and 4 cm from the room's wall; 2 mm from the translated wall */
    sl_vec3 near_pts[4] = {{9.999f, 0, 2}, {9.99f, 0.5f, 2}, {9.96f, -0.5f, 2.5f}, {-19.998f, 0, 2}};
    for (uint32_t i = 0; i < 4; i++) {
        assert_int_equal(sl_region_oracle_points_visible(ro, &near_pts[i], 1, &v, &err), SL_OK);
        assert_false(has(&v, i < 3 ? behind : beyond));
        assert_true(has(&v, i < 3 ? room : wall2));
    }
    /* a point on the wall's plane cannot be rendered without looking through it: it is skipped */
    sl_vec3 on_wall[2] = {{10, 0, 2}, {9.5f, 0, 2}};
    assert_int_equal(sl_region_oracle_points_visible(ro, on_wall, 2, &v, &err), SL_OK);
    assert_int_equal(v.sample_count, 1);
    assert_false(has(&v, behind));
    assert_true(has(&v, room));
    assert_int_equal(v.first_sample[0], 0);
    /* the control: from outside, past the wall, both show */
    sl_vec3 outside[2] = {{11, 0, 2}, {-21, 0, 2}};
    assert_int_equal(sl_region_oracle_points_visible(ro, outside, 2, &v, &err), SL_OK);
    assert_true(has(&v, behind) && has(&v, beyond));
    sl_region_oracle_destroy(ro);
    sl_scene_destroy(s);
}

/* Quake III's opaque volumes are its brushes, and their faces are not all drawn (caulk): a sight
 * line through a leaf without a cluster must not count, or the oracle would see through the
 * undrawn sides. Leaves along x: [0, 8] open (cluster 0), [-2, 0) solid with nothing drawn,
 * below -2 open (cluster 1) holding a box. The control makes the middle leaf open. */
static void test_open_space(void **state)
{
    (void)state;
    for (int open_middle = 0; open_middle < 2; open_middle++) {
        sl_scene s;
        sl_error err;
        assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
        uint32_t box = add_box(s, (sl_vec3){-6, -1, -1}, (sl_vec3){-4, 1, 1});
        sl_plane planes[2] = {{1, 0, 0, 0}, {1, 0, 0, 2}};
        sl_bsp_node nodes[2] = {{0, {-1, 1}, {{-8, -8, -8}, {8, 8, 8}}}, {1, {-2, -3}, {{-8, -8, -8}, {0, 8, 8}}}};
        sl_bsp_leaf leaves[3] = {{0, 0, {{0, -8, -8}, {8, 8, 8}}, 0, 0},
                                 {open_middle ? 2 : -1, 0, {{-2, -8, -8}, {0, 8, 8}}, 0, 0},
                                 {1, 0, {{-8, -8, -8}, {-2, 8, 8}}, 0, 1}};
        uint32_t lo[1] = {box};
        uint8_t pvs[3] = {0x7, 0x7, 0x7};
        sl_bsp_desc bd = {planes, 2, nodes, 2, leaves, 3, lo, 1, 3, 1, pvs};
        assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
        sl_region_oracle_options o = {0};
        o.face_size = 32;
        o.far_plane = 100; /* the default (twice the scene's diagonal) would not reach across */
        sl_region_oracle ro;
        assert_int_equal(sl_region_oracle_create(s, &o, NULL, &ro, &err), SL_OK);
        sl_vec3 p[2] = {{4, 0, 0}, {-7, 0, 0}}; /* open space on either side */
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_points_visible(ro, &p[0], 1, &v, &err), SL_OK);
        assert_int_equal(has(&v, box), open_middle == 1);
        assert_int_equal(sl_region_oracle_points_visible(ro, &p[1], 1, &v, &err), SL_OK);
        assert_true(has(&v, box)); /* in its own open leaf: seen */
        sl_region_oracle_destroy(ro);
        sl_scene_destroy(s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wall_scene),
        cmocka_unit_test(test_cap_and_options),
        cmocka_unit_test(test_cluster_samples),
        cmocka_unit_test(test_near_wall),
        cmocka_unit_test(test_open_space),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

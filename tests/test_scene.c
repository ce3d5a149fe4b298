/* The scene model: meshes, instancing, objects, footprints, occluders, terrain, streets, BSP,
 * metadata, dynamic objects, validation of bad input, allocator accounting. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>

#include "scene/scene_internal.h"
#include "sightline/scene.h"
#include "support/counting_alloc.h"

/* A unit cube centred at the origin: 8 vertices, 12 triangles, outward CCW. */
static const float cube_pos[] = {-.5f, -.5f, -.5f, .5f, -.5f, -.5f, .5f, .5f, -.5f, -.5f, .5f, -.5f,
                                 -.5f, -.5f, .5f,  .5f, -.5f, .5f,  .5f, .5f, .5f,  -.5f, .5f, .5f};
static const uint32_t cube_idx[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                    1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};

static uint32_t add_cube(sl_scene s)
{
    sl_mesh_desc m = {cube_pos, NULL, 8, cube_idx, 12, NULL};
    uint32_t id;
    sl_error err;
    assert_int_equal(sl_scene_add_mesh(s, &m, &id, &err), SL_OK);
    return id;
}

static void test_meshes_objects_instancing(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(&a, &s, &err), SL_OK);
    uint32_t mesh = add_cube(s);
    sl_mesh_view mv = sl_scene_mesh(s, mesh);
    assert_int_equal(mv.vertex_count, 8);
    assert_int_equal(mv.triangle_count, 12);
    assert_true(mv.bounds.min.x == -.5f && mv.bounds.max.z == .5f);
    /* computed normals point away from the centre */
    for (uint32_t v = 0; v < 8; v++) {
        const float *p = mv.positions + 3 * v, *n = mv.normals + 3 * v;
        assert_true(p[0] * n[0] + p[1] * n[1] + p[2] * n[2] > 0.5f);
        assert_true(fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 1e-5f);
    }
    /* three instances: identity, translated, scaled+translated */
    sl_affine t1 = {{1, 0, 0, 10, 0, 1, 0, 0, 0, 0, 1, 0}};
    sl_affine t2 = {{2, 0, 0, 0, 0, 2, 0, 5, 0, 0, 2, 1}};
    sl_object_desc od = {mesh, NULL, 0xff0000ff, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER, 0};
    uint32_t o0, o1, o2;
    assert_int_equal(sl_scene_add_object(s, &od, &o0, &err), SL_OK);
    od.transform = &t1;
    od.kind = SL_KIND_CAR;
    od.flags = SL_OBJECT_DYNAMIC;
    assert_int_equal(sl_scene_add_object(s, &od, &o1, &err), SL_OK);
    od.transform = &t2;
    od.kind = SL_KIND_TREE;
    od.flags = 0;
    assert_int_equal(sl_scene_add_object(s, &od, &o2, &err), SL_OK);
    assert_int_equal(o0, 0);
    assert_int_equal(o2, 2);
    sl_object_view v0 = sl_scene_object(s, o0), v1 = sl_scene_object(s, o1), v2 = sl_scene_object(s, o2);
    assert_true(v0.identity);
    assert_false(v1.identity);
    assert_int_equal(v1.kind, SL_KIND_CAR);
    assert_int_equal(v0.color, 0xff0000ff);
    assert_true(v1.bounds.min.x == 9.5f && v1.bounds.max.x == 10.5f);
    assert_true(v2.bounds.min.y == 4.0f && v2.bounds.max.y == 6.0f && v2.bounds.max.z == 2.0f);
    sl_aabb all = sl_scene_bounds(s);
    assert_true(all.min.x == -1.0f && all.max.x == 10.5f);
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    assert_int_equal(st.mesh_count, 1);
    assert_int_equal(st.object_count, 3);
    assert_int_equal(st.triangle_count, 12);
    assert_int_equal(st.instanced_triangle_count, 36);
    assert_int_equal(st.objects_per_kind[SL_KIND_CAR], 1);
    assert_int_equal(st.triangles_per_kind[SL_KIND_TREE], 12);
    assert_true(st.memory_bytes > 0);
    /* moving a dynamic object updates its bounds; a static one gets a transform slot on demand */
    sl_affine t3 = {{1, 0, 0, -20, 0, 1, 0, 0, 0, 0, 1, 0}};
    assert_int_equal(sl_scene_set_object_transform(s, o1, &t3, &err), SL_OK);
    assert_true(sl_scene_object_bounds(s, o1).min.x == -20.5f);
    assert_int_equal(sl_scene_set_object_transform(s, o0, &t3, &err), SL_OK);
    assert_false(sl_scene_object(s, o0).identity);
    assert_true(sl_scene_object_bounds_array(s)[o0].max.x == -19.5f);
    assert_string_equal(sl_object_kind_name(SL_KIND_BUILDING), "building");
    assert_string_equal(sl_object_kind_name(999), "unknown");
    sl_scene_destroy(s);
    assert_int_equal(c.live, 0);
}

static void test_bad_meshes_and_objects(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t bad_idx[] = {0, 1, 8};
    sl_mesh_desc m = {cube_pos, NULL, 8, bad_idx, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &m, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "index 8"));
    float nan_pos[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    uint32_t idx[3] = {0, 1, 2};
    sl_mesh_desc m2 = {nan_pos, NULL, 3, idx, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &m2, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "vertex 2"));
    sl_object_desc od = {5, NULL, 0, 0, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    uint32_t mesh = add_cube(s);
    sl_affine inf = sl_affine_identity();
    inf.m[3] = INFINITY;
    od.mesh = mesh;
    od.transform = &inf;
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_scene_object_count(s), 0);
    assert_int_equal(sl_scene_add_mesh(NULL, &m, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(s);
}

static void test_footprints(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* clockwise L-shape, with a repeated closing vertex: stored CCW without the repeat */
    const float l_cw[] = {0, 0, 0, 20, 10, 20, 10, 10, 20, 10, 20, 0, 0, 0};
    sl_footprint_desc fd = {l_cw, 7, 0, 15, SL_NONE};
    uint32_t fi;
    assert_int_equal(sl_scene_add_footprint(s, &fd, &fi, &err), SL_OK);
    sl_footprint_view fv = sl_scene_footprint(s, fi);
    assert_int_equal(fv.vertex_count, 6);
    double area = 0;
    for (uint32_t i = 0; i < fv.vertex_count; i++) {
        uint32_t j = (i + 1) % fv.vertex_count;
        area += fv.xy[2 * i] * fv.xy[2 * j + 1] - fv.xy[2 * j] * fv.xy[2 * i + 1];
    }
    assert_true(area > 0); /* CCW */
    assert_true(fabs(area / 2 - 300) < 1e-6);
    /* façade of edge 0 is a vertical quad whose normal (right-hand rule) points outward */
    sl_vec3 q[4];
    sl_footprint_facade(&fv, 0, q);
    assert_true(q[0].z == 0 && q[2].z == 15 && q[3].z == 15);
    float e1[3] = {q[1].x - q[0].x, q[1].y - q[0].y, 0}, e2[3] = {q[3].x - q[0].x, q[3].y - q[0].y, q[3].z - q[0].z};
    float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    float mid[2] = {(q[0].x + q[1].x) / 2 + n[0] * 1e-3f, (q[0].y + q[1].y) / 2 + n[1] * 1e-3f};
    /* just outside the edge midpoint, along the normal, lies outside the L (all of it is in [0,20]^2) */
    bool inside_l = mid[0] > 0 && mid[0] < 20 && mid[1] > 0 && mid[1] < 20 && !(mid[0] > 10 && mid[1] > 10);
    assert_false(inside_l);
    /* bad footprints */
    const float bowtie[] = {0, 0, 10, 10, 10, 0, 0, 5};
    sl_footprint_desc bad = {bowtie, 4, 0, 10, SL_NONE};
    assert_int_equal(sl_scene_add_footprint(s, &bad, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "not simple"));
    const float line[] = {0, 0, 1, 1, 2, 2};
    bad.xy = line;
    bad.vertex_count = 3;
    assert_int_equal(sl_scene_add_footprint(s, &bad, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "zero area"));
    fd.roof_z = -1;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    fd.roof_z = 10;
    fd.object = 3;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_scene_footprint_count(s), 1);
    sl_scene_destroy(s);
}

static void test_terrain_streets_meta_occluders(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(&a, &s, &err), SL_OK);
    assert_float_equal(sl_scene_ground_height(s, 5, 5), 0, 0);
    float h[9] = {0, 1, 2, 0, 1, 2, 0, 1, 2};
    sl_terrain_desc td = {3, 3, 100, 200, 10, h};
    assert_int_equal(sl_scene_set_terrain(s, &td, &err), SL_OK);
    assert_float_equal(sl_scene_ground_height(s, 105, 205), 0.5f, 1e-6);
    assert_float_equal(sl_scene_ground_height(s, 120, 220), 2.0f, 1e-6);
    assert_float_equal(sl_scene_ground_height(s, 1000, -1000), 2.0f, 1e-6); /* clamped */
    sl_terrain_view tv;
    assert_true(sl_scene_terrain(s, &tv));
    assert_int_equal(tv.nx, 3);
    h[4] = NAN;
    assert_int_equal(sl_scene_set_terrain(s, &td, &err), SL_ERROR_INVALID_ARGUMENT);
    td.nx = 1;
    assert_int_equal(sl_scene_set_terrain(s, &td, &err), SL_ERROR_INVALID_ARGUMENT);
    const float street[] = {0, 0, 100, 0, 100, 10, 0, 10};
    assert_int_equal(sl_scene_add_street_polygon(s, street, 4, &err), SL_OK);
    assert_int_equal(sl_scene_street_polygon_count(s), 1);
    assert_int_equal(sl_scene_street_polygon(s, 0).vertex_count, 4);
    sl_street_node nodes[3] = {{0, 5}, {50, 5}, {100, 5}};
    sl_street_edge edges[2] = {{0, 1, 10, 0}, {1, 2, 10, SL_STREET_AVENUE}};
    assert_int_equal(sl_scene_set_street_graph(s, nodes, 3, edges, 2, &err), SL_OK);
    edges[1].b = 7;
    assert_int_equal(sl_scene_set_street_graph(s, nodes, 3, edges, 2, &err), SL_ERROR_INVALID_ARGUMENT);
    const sl_street_node *gn;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &gn, &nn, NULL, &ne);
    assert_int_equal(nn, 3);
    assert_int_equal(ne, 2);
    assert_int_equal(sl_scene_set_meta(s, "seed", "1", &err), SL_OK);
    assert_int_equal(sl_scene_set_meta(s, "seed", "2", &err), SL_OK);
    assert_int_equal(sl_scene_set_meta(s, "preset", "tiny", &err), SL_OK);
    assert_string_equal(sl_scene_meta(s, "seed"), "2");
    assert_null(sl_scene_meta(s, "nope"));
    assert_int_equal(sl_scene_meta_count(s), 2);
    assert_int_equal(sl_scene_set_meta(s, "", "x", &err), SL_ERROR_INVALID_ARGUMENT);
    uint32_t mesh = add_cube(s);
    assert_int_equal(sl_scene_add_occluder(s, mesh, NULL, SL_NONE, &err), SL_OK);
    assert_int_equal(sl_scene_add_occluder(s, 9, NULL, SL_NONE, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_scene_occluder_count(s), 1);
    assert_true(sl_scene_occluder(s, 0).mesh == mesh);
    assert_int_equal(sl_scene_validate(s, &err), SL_OK);
    sl_scene_destroy(s);
    assert_int_equal(c.live, 0);
}

static void test_bsp(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t mesh = add_cube(s);
    sl_object_desc od = {mesh, NULL, 0, SL_KIND_BSP_FACES, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    /* one node splitting at x = 0: front (x >= 0) is leaf 0, back is leaf 1 */
    sl_plane planes[1] = {{1, 0, 0, 0}};
    sl_bsp_node nodes[1] = {{0, {-1, -2}, {{-1, -1, -1}, {1, 1, 1}}}};
    sl_bsp_leaf leaves[2] = {{0, 0, {{0, -1, -1}, {1, 1, 1}}, 0, 1}, {1, 0, {{-1, -1, -1}, {0, 1, 1}}, 1, 0}};
    uint32_t leaf_objects[1] = {0};
    uint8_t pvs[2] = {0x1, 0x3};
    sl_bsp_desc bd = {planes, 1, nodes, 1, leaves, 2, leaf_objects, 1, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){0.5f, 0, 0}), 0);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){-0.5f, 0, 0}), 1);
    sl_bsp_view bv;
    assert_true(sl_scene_bsp(s, &bv));
    assert_int_equal(bv.cluster_count, 2);
    assert_int_equal(bv.pvs[1], 0x3);
    /* a child pointing backwards (a cycle) is refused */
    sl_bsp_node cyc[2] = {{0, {1, -1}, {{0, 0, 0}, {0, 0, 0}}}, {0, {0, -2}, {{0, 0, 0}, {0, 0, 0}}}};
    sl_bsp_desc bad = bd;
    bad.nodes = cyc;
    bad.node_count = 2;
    assert_int_equal(sl_scene_set_bsp(s, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "node 1"));
    bad = bd;
    sl_bsp_leaf badleaf[2] = {leaves[0], leaves[1]};
    badleaf[1].cluster = 5;
    bad.leaves = badleaf;
    assert_int_equal(sl_scene_set_bsp(s, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cluster 5"));
    bad = bd;
    bad.cluster_bytes = 0;
    assert_int_equal(sl_scene_set_bsp(s, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    /* the valid data stayed */
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){-0.5f, 0, 0}), 1);
    sl_scene_destroy(s);
}

static void test_validate_catches_corruption(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t mesh = add_cube(s);
    sl_object_desc od = {mesh, NULL, 0, 0, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    assert_int_equal(sl_scene_validate(s, &err), SL_OK);
    /* poke internals as a corrupted file would */
    uint32_t *idx = s->indices.data;
    uint32_t saved = idx[5];
    idx[5] = 99;
    assert_int_equal(sl_scene_validate(s, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "mesh 0"));
    idx[5] = saved;
    float *p = s->positions.data;
    p[4] = NAN;
    assert_int_equal(sl_scene_validate(s, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "vertex 1"));
    p[4] = 0;
    sl_object_rec *o = s->objects.data;
    o[0].mesh = 4;
    assert_int_equal(sl_scene_validate(s, &err), SL_ERROR_FORMAT);
    o[0].mesh = 0;
    sl_mesh_rec *m = s->meshes.data;
    m[0].triangle_count = 1000;
    assert_int_equal(sl_scene_validate(s, &err), SL_ERROR_FORMAT);
    m[0].triangle_count = 12;
    assert_int_equal(sl_scene_validate(s, &err), SL_OK);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_meshes_objects_instancing), cmocka_unit_test(test_bad_meshes_and_objects),
        cmocka_unit_test(test_footprints),                cmocka_unit_test(test_terrain_streets_meta_occluders),
        cmocka_unit_test(test_bsp),                       cmocka_unit_test(test_validate_catches_corruption),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* View cells: street triangulation covers exactly the free space (areas known by hand), respects
 * the maximum edge, excludes footprints, is deterministic; grid, adaptive and BSP-cluster cells;
 * the lookup finds the cell holding a point (and none outside); bad records are refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/gen.h"
#include "sightline/region.h"
#include "support/box_mesh.h"
#include "support/counting_alloc.h"

static void add_rect(sl_scene s, float x0, float y0, float x1, float y1)
{
    sl_error err;
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    assert_int_equal(sl_scene_add_street_polygon(s, xy, 4, &err), SL_OK);
}

static void add_footprint(sl_scene s, float x0, float y0, float x1, float y1, float h)
{
    sl_error err;
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0, h, SL_NONE};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
}

static double tri_area(const sl_viewcell *c)
{
    const sl_vec2 *t = c->tri;
    return 0.5 * ((double)(t[1].x - t[0].x) * (t[2].y - t[0].y) - (double)(t[1].y - t[0].y) * (t[2].x - t[0].x));
}

/* A cross of two 100 x 10 streets: free area 1900 m^2. */
static void test_street_cross(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_rect(s, -50, -5, 50, 5);
    add_rect(s, -5, -50, 5, 50);
    sl_viewcell_options vo = {0};
    vo.max_edge = 6;
    vo.alloc = &a;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_OK);
    uint32_t n = sl_viewcells_count(vc);
    const sl_viewcell *c = sl_viewcells_data(vc);
    assert_true(n > 100);
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        assert_int_equal(c[i].shape, SL_CELL_PRISM);
        assert_true(tri_area(&c[i]) > 0);
        for (int e = 0; e < 3; e++) {
            const sl_vec2 *p = &c[i].tri[e], *q = &c[i].tri[(e + 1) % 3];
            assert_true(hypotf(q->x - p->x, q->y - p->y) <= 6.0f + 1e-4f);
        }
        /* defaults: eyes 1 to 2 m above flat ground */
        assert_float_equal(c[i].z_min, 1.0f, 0);
        assert_float_equal(c[i].z_max, 2.0f, 0);
        area += tri_area(&c[i]);
    }
    assert_float_equal(area, 1900.0, 1e-2);
    sl_viewcells_stats st;
    sl_viewcells_get_stats(vc, &st);
    assert_int_equal(st.prisms, n);
    assert_float_equal(st.area, 1900.0, 1e-2);
    assert_true(st.max_edge <= 6.0 + 1e-4);

    /* lookup: every centroid in its own cell; random free points in a cell that contains them;
     * points in the blocks, above the eye range or not finite in none */
    for (uint32_t i = 0; i < n; i++) {
        sl_vec3 q = {(c[i].tri[0].x + c[i].tri[1].x + c[i].tri[2].x) / 3,
                     (c[i].tri[0].y + c[i].tri[1].y + c[i].tri[2].y) / 3, 1.5f};
        assert_int_equal(sl_viewcells_locate(vc, NULL, q), i);
        assert_true(sl_viewcell_contains(vc, NULL, i, q));
    }
    sl_rng r;
    sl_rng_seed(&r, 3, 0);
    for (int k = 0; k < 2000; k++) {
        sl_vec3 q = {sl_rng_range(&r, -50, 50), sl_rng_range(&r, -5, 5), sl_rng_range(&r, 1, 2)};
        if (k & 1) {
            float t = q.x;
            q.x = q.y;
            q.y = t;
        }
        uint32_t cell = sl_viewcells_locate(vc, NULL, q);
        assert_true(cell != SL_NONE);
        assert_true(sl_viewcell_contains(vc, NULL, cell, q));
    }
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){20, 20, 1.5f}), SL_NONE);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){0, 0, 2.5f}), SL_NONE);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){0, 0, 0.5f}), SL_NONE);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){NAN, 0, 1.5f}), SL_NONE);

    /* deterministic: same cells, same key */
    sl_viewcells vc2;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc2, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc2), n);
    assert_memory_equal(sl_viewcells_data(vc2), c, (size_t)n * sizeof *c);
    assert_true(sl_viewcells_key(vc2) == sl_viewcells_key(vc));
    sl_viewcells_destroy(vc2);
    sl_viewcells_destroy(vc);
    assert_int_equal(cnt.live, 0);

    /* eye heights are options */
    vo.eye_min = 0.5f;
    vo.eye_max = 3.0f;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_OK);
    assert_float_equal(sl_viewcells_data(vc)[0].z_min, 0.5f, 0);
    assert_float_equal(sl_viewcells_data(vc)[0].z_max, 3.0f, 0);
    sl_viewcells_destroy(vc);
    /* bad options */
    vo.eye_min = 3, vo.eye_max = 1;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "eye heights"));
    vo.eye_min = 1, vo.eye_max = 2, vo.max_edge = NAN;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_ERROR_INVALID_ARGUMENT);
    vo.max_edge = 1;
    vo.max_cells = 10;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_ERROR_LIMIT);
    assert_null(vc);
    assert_int_equal(cnt.live, 0);
    sl_scene_destroy(s);
}

/* A square with a building in the middle: the footprint is cut out of the free space. */
static void test_footprint_hole(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_rect(s, 0, 0, 40, 40);
    add_footprint(s, 15, 15, 25, 25, 20);
    sl_viewcell_options vo = {0};
    vo.max_edge = 5;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &vc, &err), SL_OK);
    double area = 0;
    for (uint32_t i = 0; i < sl_viewcells_count(vc); i++)
        area += tri_area(&sl_viewcells_data(vc)[i]);
    assert_float_equal(area, 1600.0 - 100.0, 1e-2);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){20, 20, 1.5f}), SL_NONE);
    assert_true(sl_viewcells_locate(vc, NULL, (sl_vec3){5, 20, 1.5f}) != SL_NONE);
    sl_viewcells_destroy(vc);

    /* grid fallback: 8 m squares over 40 x 40 are 25 cells; the middle one lies inside the
     * building and is dropped */
    vo.max_edge = 8;
    assert_int_equal(sl_viewcells_grid(s, &vo, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 24);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){20, 20, 1.5f}), SL_NONE);
    assert_int_equal(sl_viewcells_data(vc)[0].shape, SL_CELL_BOX);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){1, 1, 1.5f}), 0);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){39, 39, 1.5f}), 23);
    sl_viewcells_destroy(vc);
    /* a scene without streets has no street cells */
    sl_scene empty;
    assert_int_equal(sl_scene_create(NULL, &empty, &err), SL_OK);
    assert_int_equal(sl_viewcells_from_streets(empty, NULL, &vc, &err), SL_ERROR_UNSUPPORTED);
    assert_int_equal(sl_viewcells_from_bsp(empty, NULL, &vc, &err), SL_ERROR_UNSUPPORTED);
    sl_scene_destroy(empty);
    sl_scene_destroy(s);
}

/* Adaptive subdivision: a 32 m cube volume with 8 m cells is 64 boxes; an object refines its
 * surroundings down to the minimum size. */
static void test_adaptive(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_aabb vol = {{0, 0, 0}, {32, 32, 32}};
    sl_viewcell_options vo = {0};
    vo.max_edge = 8;
    vo.min_edge = 2;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_adaptive(s, &vol, SL_NONE, &vo, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 64);
    sl_viewcells_stats st;
    sl_viewcells_get_stats(vc, &st);
    assert_float_equal(st.area, 64 * 64.0, 1e-3); /* XY area counts every box: 64 boxes of 8 x 8 */
    for (int k = 0; k < 100; k++) {
        sl_vec3 p = {(float)(k % 10) * 3.1f + 0.5f, (float)(k / 10) * 3.1f + 0.5f, 17.0f};
        uint32_t c = sl_viewcells_locate(vc, NULL, p);
        assert_true(c != SL_NONE);
        assert_true(sl_viewcell_contains(vc, NULL, c, p));
    }
    sl_viewcells_destroy(vc);
    /* a small box object at (4,4,4): cells around it split to 2 m */
    float pos[24];
    for (int i = 0; i < 8; i++) {
        pos[3 * i] = (i & 1) ? 5.0f : 4.0f;
        pos[3 * i + 1] = (i & 2) ? 5.0f : 4.0f;
        pos[3 * i + 2] = (i & 4) ? 5.0f : 4.0f;
    }
    uint32_t idx[3] = {0, 1, 2};
    sl_mesh_desc md = {pos, NULL, 8, idx, 1, NULL};
    uint32_t mesh;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    assert_int_equal(sl_viewcells_adaptive(s, &vol, SL_NONE, &vo, &vc, &err), SL_OK);
    assert_true(sl_viewcells_count(vc) > 64);
    uint32_t c = sl_viewcells_locate(vc, NULL, (sl_vec3){4.5f, 4.5f, 4.5f});
    assert_true(c != SL_NONE);
    const sl_aabb *b = &sl_viewcells_data(vc)[c].bounds;
    assert_true(b->max.x - b->min.x <= 2.0f + 1e-5f);
    sl_viewcells_destroy(vc);
    /* the inside of a closed mesh object: an 8 m cube split into 4 m boxes, all inside */
    sl_scene m;
    assert_int_equal(sl_scene_create(NULL, &m, &err), SL_OK);
    float cube[24];
    sl_test_box_vertices((sl_vec3){100, 0, 0}, (sl_vec3){108, 8, 8}, cube);
    sl_mesh_desc cm = {cube, NULL, 8, sl_test_box_indices, 12, NULL};
    uint32_t cmesh, cobj;
    assert_int_equal(sl_scene_add_mesh(m, &cm, &cmesh, &err), SL_OK);
    sl_object_desc cod = {cmesh, NULL, 0, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(m, &cod, &cobj, &err), SL_OK);
    vo.max_edge = 4;
    vo.min_edge = 1;
    assert_int_equal(sl_viewcells_adaptive(m, NULL, cobj, &vo, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 8);
    assert_true(sl_viewcells_locate(vc, NULL, (sl_vec3){104, 4, 4}) != SL_NONE);
    sl_viewcells_destroy(vc);
    assert_int_equal(sl_viewcells_adaptive(m, NULL, 5, &vo, &vc, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(m);
    /* an empty volume box is refused */
    sl_aabb flat = {{0, 0, 0}, {0, 1, 1}};
    assert_int_equal(sl_viewcells_adaptive(s, &flat, SL_NONE, &vo, &vc, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(s);
}

/* Clusters of a hand-made BSP: one plane at x = 0, front leaf cluster 0, back leaf cluster 1. */
static void test_bsp_clusters(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_plane planes[1] = {{1, 0, 0, 0}};
    sl_bsp_node nodes[1] = {{0, {-1, -2}, {{-4, -4, -4}, {4, 4, 4}}}};
    sl_bsp_leaf leaves[2] = {{0, 0, {{0, -4, -4}, {4, 4, 4}}, 0, 0}, {1, 0, {{-4, -4, -4}, {0, 4, 4}}, 0, 0}};
    uint8_t pvs[2] = {0x3, 0x3};
    sl_bsp_desc bd = {planes, 1, nodes, 1, leaves, 2, NULL, 0, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 2);
    const sl_viewcell *c = sl_viewcells_data(vc);
    assert_int_equal(c[0].shape, SL_CELL_CLUSTER);
    assert_int_equal(c[0].cluster, 0);
    assert_int_equal(c[1].cluster, 1);
    assert_int_equal(sl_viewcells_locate(vc, s, (sl_vec3){1, 0, 0}), 0);
    assert_int_equal(sl_viewcells_locate(vc, s, (sl_vec3){-1, 0, 0}), 1);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){-1, 0, 0}), SL_NONE); /* clusters need the BSP */
    assert_true(sl_viewcell_contains(vc, s, 1, (sl_vec3){-1, 2, 2}));
    assert_false(sl_viewcell_contains(vc, s, 0, (sl_vec3){-1, 2, 2}));
    /* the records round-trip through sl_viewcells_create */
    sl_viewcells copy;
    assert_int_equal(sl_viewcells_create(c, 2, NULL, &copy, &err), SL_OK);
    assert_true(sl_viewcells_key(copy) == sl_viewcells_key(vc));
    sl_viewcells_destroy(copy);
    /* a duplicated cluster is refused */
    sl_viewcell twice[2] = {c[0], c[0]};
    assert_int_equal(sl_viewcells_create(twice, 2, NULL, &copy, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "cluster 0"));
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* sl_viewcells_overlap (the pvs culler's near-plane region): the cells a box meets, ascending, and
 * whether they cover it — through the BSP for clusters (a solid leaf uncovers), by volume for
 * boxes and prisms (a box reaching past the cells, sideways or below the eye range, uncovers). */
static void test_overlap(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* x < 0: cluster 1; 0 <= x < 2: cluster 0; x >= 2: solid */
    sl_plane planes[2] = {{1, 0, 0, 0}, {1, 0, 0, -2}};
    sl_bsp_node nodes[2] = {{0, {1, -2}, {{-4, -4, -4}, {4, 4, 4}}}, {1, {-3, -1}, {{0, -4, -4}, {4, 4, 4}}}};
    sl_bsp_leaf leaves[3] = {{0, 0, {{0, -4, -4}, {2, 4, 4}}, 0, 0},
                             {1, 0, {{-4, -4, -4}, {0, 4, 4}}, 0, 0},
                             {-1, 0, {{2, -4, -4}, {4, 4, 4}}, 0, 0}};
    uint8_t pvs[2] = {0x3, 0x3};
    sl_bsp_desc bd = {planes, 2, nodes, 2, leaves, 3, NULL, 0, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    uint32_t out[4];
    bool cov;
    sl_aabb b1 = {{0.5f, -1, -1}, {1, 1, 1}}, b2 = {{-0.5f, -1, -1}, {0.5f, 1, 1}}, b3 = {{1.9f, -1, -1}, {2.1f, 1, 1}};
    assert_int_equal(sl_viewcells_overlap(vc, s, &b1, out, 4, &cov), 1);
    assert_int_equal(out[0], 0);
    assert_true(cov);
    assert_int_equal(sl_viewcells_overlap(vc, s, &b2, out, 4, &cov), 2);
    assert_int_equal(out[0], 0);
    assert_int_equal(out[1], 1);
    assert_true(cov);
    assert_int_equal(sl_viewcells_overlap(vc, s, &b2, out, 1, &cov), 1); /* does not fit */
    assert_false(cov);
    assert_int_equal(sl_viewcells_overlap(vc, s, &b3, out, 4, &cov), 1); /* reaches the solid leaf */
    assert_int_equal(out[0], 0);
    assert_false(cov);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);

    /* two boxes side by side */
    sl_viewcell c[2];
    memset(c, 0, sizeof c);
    for (int i = 0; i < 2; i++) {
        c[i].shape = SL_CELL_BOX;
        c[i].cluster = -1;
        c[i].z_min = 0;
        c[i].z_max = 1;
        c[i].bounds = (sl_aabb){{(float)i, 0, 0}, {(float)i + 1, 1, 1}};
    }
    assert_int_equal(sl_viewcells_create(c, 2, NULL, &vc, &err), SL_OK);
    sl_aabb q1 = {{0.9f, 0.2f, 0.2f}, {1.1f, 0.8f, 0.8f}}, q2 = {{1.9f, 0.2f, 0.2f}, {2.1f, 0.8f, 0.8f}};
    assert_int_equal(sl_viewcells_overlap(vc, NULL, &q1, out, 4, &cov), 2);
    assert_true(cov);
    assert_int_equal(sl_viewcells_overlap(vc, NULL, &q2, out, 4, &cov), 1);
    assert_int_equal(out[0], 1);
    assert_false(cov);
    sl_viewcells_destroy(vc);

    /* a square of two prisms, eyes 1 to 2 m up */
    memset(c, 0, sizeof c);
    const sl_vec2 tri[2][3] = {{{0, 0}, {4, 0}, {4, 4}}, {{0, 0}, {4, 4}, {0, 4}}};
    for (int i = 0; i < 2; i++) {
        c[i].shape = SL_CELL_PRISM;
        c[i].cluster = -1;
        memcpy(c[i].tri, tri[i], sizeof tri[i]);
        c[i].z_min = 1;
        c[i].z_max = 2;
        c[i].bounds = (sl_aabb){{0, 0, 1}, {4, 4, 2}};
    }
    assert_int_equal(sl_viewcells_create(c, 2, NULL, &vc, &err), SL_OK);
    sl_aabb p1 = {{1.5f, 1.5f, 1.2f}, {2.5f, 2.5f, 1.8f}}, p2 = {{1.5f, 1.5f, 0.8f}, {2.5f, 2.5f, 1.2f}},
            p3 = {{3.5f, 1.5f, 1.2f}, {4.5f, 2.5f, 1.8f}};
    assert_int_equal(sl_viewcells_overlap(vc, NULL, &p1, out, 4, &cov), 2);
    assert_true(cov);
    assert_int_equal(sl_viewcells_overlap(vc, NULL, &p2, out, 4, &cov), 2); /* below the eye range */
    assert_false(cov);
    assert_int_equal(sl_viewcells_overlap(vc, NULL, &p3, out, 4, &cov), 2); /* off the square */
    assert_false(cov);
    sl_viewcells_destroy(vc);
}

/* sl_viewcells_create refuses each kind of bad record, naming the cell. */
static void test_validation(void **state)
{
    (void)state;
    sl_error err;
    sl_viewcell good;
    memset(&good, 0, sizeof good);
    good.shape = SL_CELL_PRISM;
    good.cluster = -1;
    good.tri[0] = (sl_vec2){0, 0};
    good.tri[1] = (sl_vec2){4, 0};
    good.tri[2] = (sl_vec2){0, 4};
    good.z_min = 1;
    good.z_max = 2;
    good.bounds = (sl_aabb){{0, 0, 1}, {4, 4, 2}};
    sl_viewcells vc;
    sl_viewcell cells[2] = {good, good};
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_OK);
    sl_viewcells_destroy(vc);
    sl_viewcell b = good;
    b.tri[1] = (sl_vec2){0, 4}, b.tri[2] = (sl_vec2){4, 0}, b.bounds = good.bounds;
    cells[1] = b;
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "view cell 1"));
    assert_non_null(strstr(err.message, "clockwise"));
    b = good;
    b.z_min = NAN;
    cells[1] = b;
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "not finite"));
    b = good;
    b.bounds.max.x = 5;
    cells[1] = b;
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "bounds"));
    b = good;
    b.shape = 7;
    cells[1] = b;
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "unknown shape"));
    b = good;
    b.z_min = 3;
    cells[1] = b;
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    b = good;
    b.shape = SL_CELL_BOX;
    cells[1] = b; /* a box must have a zero triangle */
    assert_int_equal(sl_viewcells_create(cells, 2, NULL, &vc, &err), SL_ERROR_FORMAT);
    assert_null(vc);
    /* an empty set is fine and finds nothing */
    assert_int_equal(sl_viewcells_create(NULL, 0, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_locate(vc, NULL, (sl_vec3){0, 0, 0}), SL_NONE);
    sl_viewcells_destroy(vc);
}

/* The tiny city: street cells cover the street polygons' area minus nothing (no overlap with
 * buildings), and lookups of random street points succeed. */
static void test_tiny_city(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&o, NULL, &s, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_streets(s, NULL, &vc, &err), SL_OK);
    sl_viewcells_stats st;
    sl_viewcells_get_stats(vc, &st);
    assert_true(st.count > 100);
    assert_true(st.max_edge <= 12.0 + 1e-3);
    /* no cell centroid lies inside a footprint */
    const sl_viewcell *c = sl_viewcells_data(vc);
    for (uint32_t i = 0; i < st.count; i++) {
        float cx = (c[i].tri[0].x + c[i].tri[1].x + c[i].tri[2].x) / 3;
        float cy = (c[i].tri[0].y + c[i].tri[1].y + c[i].tri[2].y) / 3;
        for (uint32_t f = 0; f < sl_scene_footprint_count(s); f++) {
            sl_footprint_view fv = sl_scene_footprint(s, f);
            bool in = false;
            for (uint32_t k = 0, j = fv.vertex_count - 1; k < fv.vertex_count; j = k++) {
                float xk = fv.xy[2 * k], yk = fv.xy[2 * k + 1], xj = fv.xy[2 * j], yj = fv.xy[2 * j + 1];
                if ((yk > cy) != (yj > cy) && cx < (xj - xk) * (cy - yk) / (yj - yk) + xk)
                    in = !in;
            }
            assert_false(in);
        }
    }
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_street_cross),  cmocka_unit_test(test_footprint_hole),
        cmocka_unit_test(test_adaptive),      cmocka_unit_test(test_bsp_clusters),
        cmocka_unit_test(test_validation),    cmocka_unit_test(test_tiny_city),
        cmocka_unit_test(test_overlap),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

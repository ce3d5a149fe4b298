/* Occluder shrinking: every point of an eroded footprint is at least eps inside the original
 * (squares, an L with a reflex corner), thin parts vanish and are reported, a dumbbell splits,
 * touching footprints merge into height layers, the ball mode lowers the roof; height-field
 * erosion stays below the exact one; voxel erosion of a closed cube stays eps inside it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/region.h"
#include "support/box_mesh.h"
#include "support/counting_alloc.h"

static void add_fp(sl_scene s, const float *xy, uint32_t n, float roof)
{
    sl_error err;
    sl_footprint_desc fd = {xy, n, 0, roof, SL_NONE};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
}

/* Distance from p to the polygon's boundary, and whether p is inside (even-odd). */
static double boundary_distance(const float *xy, uint32_t n, double px, double py, bool *inside)
{
    double best = INFINITY;
    bool in = false;
    for (uint32_t i = 0, j = n - 1; i < n; j = i++) {
        double ax = xy[2 * j], ay = xy[2 * j + 1], bx = xy[2 * i], by = xy[2 * i + 1];
        double dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
        double t = l2 > 0 ? fmax(0, fmin(1, ((px - ax) * dx + (py - ay) * dy) / l2)) : 0;
        best = fmin(best, hypot(ax + t * dx - px, ay + t * dy - py));
        if ((ay > py) != (by > py) && px < (bx - ax) * (py - ay) / (by - ay) + ax)
            in = !in;
    }
    *inside = in;
    return best;
}

/* The vertices and random points of piece k are inside the source polygon, at least eps from its
 * boundary. */
static void check_piece(sl_shrunk sh, uint32_t k, const float *src, uint32_t n, float eps)
{
    sl_rng r;
    sl_rng_seed(&r, 3, k);
    {
        sl_shrunk_polygon p = sl_shrunk_get(sh, k);
        /* counter-clockwise */
        double area2 = 0;
        for (uint32_t i = 0, j = p.vertex_count - 1; i < p.vertex_count; j = i++)
            area2 += (double)p.xy[2 * j] * p.xy[2 * i + 1] - (double)p.xy[2 * i] * p.xy[2 * j + 1];
        assert_true(area2 > 0);
        float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (uint32_t i = 0; i < p.vertex_count; i++) {
            bool in;
            double d = boundary_distance(src, n, p.xy[2 * i], p.xy[2 * i + 1], &in);
            assert_true(in);
            assert_true(d >= eps - 1e-4);
            x0 = fminf(x0, p.xy[2 * i]), x1 = fmaxf(x1, p.xy[2 * i]);
            y0 = fminf(y0, p.xy[2 * i + 1]), y1 = fmaxf(y1, p.xy[2 * i + 1]);
        }
        for (int q = 0; q < 2000; q++) {
            double px = sl_rng_range(&r, x0, x1), py = sl_rng_range(&r, y0, y1);
            bool in_piece;
            boundary_distance(p.xy, p.vertex_count, px, py, &in_piece);
            if (!in_piece)
                continue;
            bool in;
            double d = boundary_distance(src, n, px, py, &in);
            assert_true(in);
            assert_true(d >= eps - 1e-4);
        }
    }
}

static double piece_area(sl_shrunk_polygon p)
{
    double a = 0;
    for (uint32_t i = 0, j = p.vertex_count - 1; i < p.vertex_count; j = i++)
        a += (double)p.xy[2 * j] * p.xy[2 * i + 1] - (double)p.xy[2 * i] * p.xy[2 * j + 1];
    return 0.5 * a;
}

static void test_footprints(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    const float sq[8] = {0, 0, 10, 0, 10, 10, 0, 10};
    const float ell[12] = {20, 0, 30, 0, 30, 4, 24, 4, 24, 12, 20, 12}; /* reflex corner at (24, 4) */
    const float thin[8] = {40, 0, 50, 0, 50, 0.8f, 40, 0.8f};
    const float bell[16] = {60, 0, 66, 0, 66, 4, 68, 4, 68, 0, 74, 0, 74, 6, 60, 6}; /* two halves, a 2 m neck */
    add_fp(s, sq, 4, 10);
    add_fp(s, ell, 6, 10);
    add_fp(s, thin, 4, 10);
    add_fp(s, bell, 8, 10);
    sl_shrunk sh;
    assert_int_equal(sl_shrink_footprints(s, 1.0f, SL_SHRINK_CYLINDER, false, &a, &sh, &err), SL_OK);
    sl_shrink_stats st;
    sl_shrunk_get_stats(sh, &st);
    assert_int_equal(st.footprints, 4);
    assert_int_equal(st.vanished, 1);
    const uint32_t *gone;
    assert_int_equal(sl_shrunk_vanished(sh, &gone), 1);
    assert_int_equal(gone[0], 2); /* 0.8 m < 2 eps */
    assert_int_equal(st.kept, 3);
    /* every piece is eps inside its source */
    for (uint32_t k = 0; k < sl_shrunk_count(sh); k++) {
        sl_shrunk_polygon p = sl_shrunk_get(sh, k);
        assert_float_equal(p.roof_z, 10, 0);
        assert_float_equal(p.base_z, 0, 0);
        const float *src = p.footprint == 0 ? sq : p.footprint == 1 ? ell : bell;
        uint32_t n = p.footprint == 0 ? 4 : p.footprint == 1 ? 6 : 8;
        assert_true(p.footprint != 2);
        check_piece(sh, k, src, n, 1.0f);
    }
    /* the square's piece is the 8 x 8 square (corners exact: convex corners need no arcs) */
    sl_shrunk_polygon p0 = sl_shrunk_get(sh, 0);
    assert_int_equal(p0.footprint, 0);
    /* the radius is enlarged by 1/cos(pi/32) for the arcs: 0.5% more is taken */
    assert_float_equal(piece_area(p0), 64.0, 0.5);
    sl_shrunk_destroy(sh);
    assert_int_equal(cnt.live, 0);

    /* a wider eps splits the bell at its neck (2 m < 2 x 1.4 m) into two pieces */
    sl_scene b;
    assert_int_equal(sl_scene_create(NULL, &b, &err), SL_OK);
    add_fp(b, bell, 8, 10);
    assert_int_equal(sl_shrink_footprints(b, 1.4f, SL_SHRINK_CYLINDER, false, &a, &sh, &err), SL_OK);
    sl_shrunk_get_stats(sh, &st);
    assert_int_equal(st.split, 1);
    assert_int_equal(sl_shrunk_count(sh), 2);
    check_piece(sh, 0, bell, 8, 1.4f);
    check_piece(sh, 1, bell, 8, 1.4f);
    sl_shrunk_destroy(sh);
    /* ball mode: the roof comes down by eps, the base up */
    assert_int_equal(sl_shrink_footprints(b, 1.0f, SL_SHRINK_BALL, false, &a, &sh, &err), SL_OK);
    assert_float_equal(sl_shrunk_get(sh, 0).roof_z, 9, 0);
    assert_float_equal(sl_shrunk_get(sh, 0).base_z, 1, 0);
    sl_shrunk_destroy(sh);
    /* eps 0 keeps the footprint as it is (up to the float margin) */
    assert_int_equal(sl_shrink_footprints(b, 0, SL_SHRINK_CYLINDER, false, &a, &sh, &err), SL_OK);
    assert_int_equal(sl_shrunk_count(sh), 1);
    sl_shrunk_destroy(sh);
    assert_int_equal(sl_shrink_footprints(b, -1, SL_SHRINK_CYLINDER, false, &a, &sh, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_shrink_footprints(b, NAN, SL_SHRINK_CYLINDER, false, &a, &sh, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(b);
    assert_int_equal(cnt.live, 0);
    sl_scene_destroy(s);
}

/* Two footprints sharing a wall, 20 m and 10 m tall: merged, the union shrinks at 10 m and the
 * tall one alone at 20 m; apart, a gap opens at the shared wall. */
static void test_merge(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    const float a[8] = {0, 0, 10, 0, 10, 10, 0, 10}, b[8] = {10, 0, 20, 0, 20, 10, 10, 10};
    add_fp(s, a, 4, 20);
    add_fp(s, b, 4, 10);
    sl_shrunk sh;
    assert_int_equal(sl_shrink_footprints(s, 1.0f, SL_SHRINK_CYLINDER, true, NULL, &sh, &err), SL_OK);
    assert_int_equal(sl_shrunk_count(sh), 2);
    double area20 = 0, area10 = 0;
    for (uint32_t k = 0; k < 2; k++) {
        sl_shrunk_polygon p = sl_shrunk_get(sh, k);
        if (p.roof_z == 20)
            area20 = piece_area(p);
        else if (p.roof_z == 10)
            area10 = piece_area(p);
        assert_int_equal(p.object, SL_NONE);
    }
    assert_float_equal(area20, 8.0 * 8.0, 0.5);
    assert_float_equal(area10, 18.0 * 8.0, 1.0); /* the 20 x 10 union, eroded */
    sl_shrunk_destroy(sh);
    assert_int_equal(sl_shrink_footprints(s, 1.0f, SL_SHRINK_CYLINDER, false, NULL, &sh, &err), SL_OK);
    assert_int_equal(sl_shrunk_count(sh), 2);
    for (uint32_t k = 0; k < 2; k++)
        assert_float_equal(piece_area(sl_shrunk_get(sh, k)), 64.0, 0.5);
    sl_shrunk_destroy(sh);
    sl_scene_destroy(s);
}

static double bilinear(const float *h, uint32_t nx, uint32_t ny, float cell, double x, double y)
{
    double fx = fmin(fmax(x / cell, 0), nx - 1.000001), fy = fmin(fmax(y / cell, 0), ny - 1.000001);
    uint32_t i = (uint32_t)fx, j = (uint32_t)fy;
    double u = fx - i, v = fy - j;
    return (1 - u) * (1 - v) * h[j * nx + i] + u * (1 - v) * h[j * nx + i + 1] + (1 - u) * v * h[(j + 1) * nx + i] +
           u * v * h[(j + 1) * nx + i + 1];
}

static void test_heightfield(void **state)
{
    (void)state;
    sl_error err;
    enum { NX = 24, NY = 20 };
    float h[NX * NY], out[NX * NY];
    sl_rng r;
    sl_rng_seed(&r, 9, 0);
    for (int i = 0; i < NX * NY; i++)
        h[i] = sl_rng_range(&r, 0, 30);
    const float cell = 2, eps = 3;
    assert_int_equal(sl_shrink_heightfield(h, NX, NY, cell, eps, SL_SHRINK_CYLINDER, out, &err), SL_OK);
    /* at random points the eroded field is not above the minimum over the eps-disk (dense sample) */
    for (int k = 0; k < 300; k++) {
        double x = sl_rng_range(&r, 0, (NX - 1) * cell), y = sl_rng_range(&r, 0, (NY - 1) * cell);
        double m = INFINITY;
        for (int a = 0; a < 64; a++)
            for (int d = 1; d <= 8; d++) {
                double ang = a * 2 * M_PI / 64, rr = eps * d / 8;
                m = fmin(m, bilinear(h, NX, NY, cell, x + rr * cos(ang), y + rr * sin(ang)));
            }
        m = fmin(m, bilinear(h, NX, NY, cell, x, y));
        assert_true(bilinear(out, NX, NY, cell, x, y) <= m + 1e-4);
    }
    float ball[NX * NY];
    assert_int_equal(sl_shrink_heightfield(h, NX, NY, cell, eps, SL_SHRINK_BALL, ball, &err), SL_OK);
    for (int i = 0; i < NX * NY; i++)
        assert_float_equal(ball[i], out[i] - eps, 1e-5);
    assert_int_equal(sl_shrink_heightfield(h, 1, NY, cell, eps, SL_SHRINK_CYLINDER, out, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_shrink_heightfield(h, NX, NY, cell, eps, SL_SHRINK_CYLINDER, h, &err), SL_ERROR_INVALID_ARGUMENT);
}

static void test_voxels(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    /* a closed cube [0, 4]^3, 12 triangles */
    float p[24];
    sl_test_box_vertices((sl_vec3){0, 0, 0}, (sl_vec3){4, 4, 4}, p);
    const uint32_t *idx = sl_test_box_indices;
    sl_aabb *boxes;
    uint32_t n;
    assert_int_equal(sl_shrink_mesh_voxels(p, 8, idx, 12, 0.25f, 0.5f, &a, &boxes, &n, &err), SL_OK);
    assert_true(n > 0);
    double vol = 0;
    for (uint32_t i = 0; i < n; i++) {
        const sl_aabb *b = &boxes[i];
        assert_true(b->min.x >= 0.5f - 1e-5f && b->min.y >= 0.5f - 1e-5f && b->min.z >= 0.5f - 1e-5f);
        assert_true(b->max.x <= 3.5f + 1e-5f && b->max.y <= 3.5f + 1e-5f && b->max.z <= 3.5f + 1e-5f);
        vol += ((double)b->max.x - b->min.x) * ((double)b->max.y - b->min.y) * ((double)b->max.z - b->min.z);
    }
    /* the exact erosion is the 3 m cube; voxels on the faces are not solid (triangles touch them),
     * so the result is 2.5 m on a side here */
    assert_true(vol >= 2.4 * 2.4 * 2.4 && vol <= 27.0);
    sl_shrink_boxes_free(&a, boxes, n);
    /* eps of half the cube: nothing is left */
    assert_int_equal(sl_shrink_mesh_voxels(p, 8, idx, 12, 0.25f, 2.0f, &a, &boxes, &n, &err), SL_OK);
    assert_int_equal(n, 0);
    sl_shrink_boxes_free(&a, boxes, n);
    uint32_t bad[3] = {0, 1, 9};
    assert_int_equal(sl_shrink_mesh_voxels(p, 8, bad, 1, 0.25f, 0.5f, &a, &boxes, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_shrink_mesh_voxels(p, 8, idx, 12, 0, 0.5f, &a, &boxes, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_shrink_mesh_voxels(p, 8, idx, 12, 1e-4f, 0.5f, &a, &boxes, &n, &err), SL_ERROR_LIMIT);
    assert_int_equal(cnt.live, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_footprints),
        cmocka_unit_test(test_merge),
        cmocka_unit_test(test_heightfield),
        cmocka_unit_test(test_voxels),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

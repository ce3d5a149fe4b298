/* The shared vector kit and ray-triangle test (src/core/dvec3.h), which the occluder shrinker's and
 * the view cells' point-in-mesh parity tests, the GVS tests, the camera, the city generator (3- and
 * 2-vectors) and the near-wall views (float 3-vectors) use: hits inside, on an edge and at a vertex
 * count, from either face; misses beside, behind the origin and parallel to the plane do not; the
 * parity of a closed box tells inside from outside; the kit's functions give the textbook values. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>

#include "core/dvec3.h"

static const double A[3] = {0, 0, 0}, B[3] = {1, 0, 0}, C[3] = {0, 1, 0};

static bool hit(double ox, double oy, double oz, double dx, double dy, double dz, double *t)
{
    const double o[3] = {ox, oy, oz}, d[3] = {dx, dy, dz};
    return sl_ray_triangle(o, d, A, B, C, 1e-18, t);
}

static void test_ray_triangle(void **state)
{
    (void)state;
    double t = -1;
    assert_true(hit(0.25, 0.25, 2, 0, 0, -1, &t)); /* inside, from the front */
    assert_true(fabs(t - 2) < 1e-15);
    assert_true(hit(0.25, 0.25, -3, 0, 0, 2, &t)); /* from the back face */
    assert_true(fabs(t - 1.5) < 1e-15);
    assert_true(hit(0.5, 0.5, 1, 0, 0, -1, NULL)); /* on the hypotenuse: u + v == 1 */
    assert_true(hit(0.5, 0, 1, 0, 0, -1, NULL));   /* on the edge v == 0 */
    assert_true(hit(0, 0, 1, 0, 0, -1, NULL));     /* at a vertex */
    assert_true(hit(1, 0, 1, 0, 0, -1, NULL));
    assert_false(hit(0.6, 0.6, 1, 0, 0, -1, NULL)); /* beside the hypotenuse */
    assert_false(hit(-0.01, 0.5, 1, 0, 0, -1, NULL));
    assert_false(hit(0.5, -0.01, 1, 0, 0, -1, NULL));
    assert_false(hit(0.25, 0.25, 2, 0, 0, 1, NULL));   /* the triangle is behind the origin */
    assert_false(hit(0.25, 0.25, 0, 0, 0, -1, NULL));  /* t == 0 is no hit */
    assert_false(hit(-1, 0.25, 0, 1, 0, 0, NULL));     /* in the plane: parallel */
    assert_false(hit(-1, 0.25, 1e-9, 1, 0, 1e-30, NULL)); /* nearly parallel: below det_eps */
    t = 7;
    assert_false(hit(2, 2, 1, 0, 0, -1, &t));
    assert_true(t == 7); /* untouched on a miss */
    /* a degenerate triangle never hits */
    const double o[3] = {0, 0, 1}, d[3] = {0, 0, -1};
    assert_false(sl_ray_triangle(o, d, A, A, B, 1e-18, NULL));
}

/* Ray parity from points in and around the unit cube made of 12 triangles. */
static void test_parity(void **state)
{
    (void)state;
    static const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    double v[8][3];
    for (int i = 0; i < 8; i++)
        v[i][0] = i & 1, v[i][1] = (i >> 1) & 1, v[i][2] = (i >> 2) & 1;
    const double d[3] = {0.8727, 0.3141, 0.3737};
    for (int k = 0; k < 27; k++) {
        double p[3] = {-0.5 + 0.5 * (k % 3) + 0.01, -0.5 + 0.5 * ((k / 3) % 3) + 0.02, -0.5 + 0.5 * (k / 9) + 0.03};
        unsigned hits = 0;
        for (int q = 0; q < 6; q++) {
            const int *f = quads[q];
            hits += sl_ray_triangle(p, d, v[f[0]], v[f[1]], v[f[2]], 1e-18, NULL);
            hits += sl_ray_triangle(p, d, v[f[0]], v[f[2]], v[f[3]], 1e-18, NULL);
        }
        bool inside = p[0] > 0 && p[0] < 1 && p[1] > 0 && p[1] < 1 && p[2] > 0 && p[2] < 1;
        assert_int_equal(hits & 1, inside);
    }
}

static void test_kit(void **state)
{
    (void)state;
    sl_dvec3 a = sl_d3(1, 2, 3), b = sl_d3(-4, 5, 0.5);
    sl_dvec3 c = sl_d3_cross(a, b);
    assert_true(c.x == 2 * 0.5 - 3 * 5 && c.y == 3 * -4 - 1 * 0.5 && c.z == 1 * 5 - 2 * -4);
    assert_true(sl_d3_dot(c, a) == 0 && sl_d3_dot(c, b) == 0);
    assert_true(sl_d3_dot(a, b) == -4 + 10 + 1.5);
    sl_dvec3 s = sl_d3_sub(sl_d3_add(a, b), b);
    assert_true(s.x == a.x && s.y == a.y && s.z == a.z);
    assert_true(sl_d3_len(sl_d3(3, 4, 12)) == 13);
    sl_dvec3 u = sl_d3_unit(sl_d3(0, 0, -5));
    assert_true(u.x == 0 && u.y == 0 && u.z == -1);
    sl_dvec3 z = sl_d3_unit(sl_d3(0, 0, 0));
    assert_true(z.x == 0 && z.y == 0 && z.z == 0); /* never NaN */
    sl_vec3 f = sl_d3_to_vec3(sl_d3_scale(sl_d3_of((sl_vec3){1, 2, 4}), 0.5));
    assert_true(f.x == 0.5f && f.y == 1 && f.z == 2);
    const double arr[3] = {7, 8, 9};
    assert_true(sl_d3_of_array(arr).y == 8);
    /* 2-vectors (the city generator's plan geometry) */
    sl_dvec2 p = sl_d2(3, -4), q = sl_d2(1, 2);
    assert_true(sl_d2_len(p) == 5 && sl_d2_dot(p, q) == 3 - 8 && sl_d2_cross(p, q) == 3 * 2 - -4 * 1);
    assert_true(sl_d2_cross(sl_d2(1, 0), sl_d2(0, 1)) > 0); /* counter-clockwise */
    sl_dvec2 d = sl_d2_sub(sl_d2_add(p, q), q), m = sl_d2_lerp(p, q, 0.25), l = sl_d2_left(sl_d2(1, 0));
    assert_true(d.x == p.x && d.y == p.y && m.x == 2.5 && m.y == -2.5 && l.x == 0 && l.y == 1);
    sl_dvec2 n = sl_d2_unit(sl_d2_scale(p, 2)), n0 = sl_d2_unit(sl_d2(0, 0));
    assert_true(fabs(n.x - 0.6) < 1e-15 && fabs(n.y + 0.8) < 1e-15 && n0.x == 0 && n0.y == 0);
    sl_dvec3 h = sl_d3_of_d2(q, 7);
    assert_true(h.x == 1 && h.y == 2 && h.z == 7);
    /* float 3-vectors: in float, the length in double */
    sl_vec3 fa = {1, 2, 3}, fb = {-4, 5, 0.5f}, fc = sl_v3_cross(fa, fb), fd = sl_v3_sub(fa, fb);
    assert_true(fc.x == 2 * 0.5f - 3 * 5 && fc.y == 3 * -4 - 1 * 0.5f && fc.z == 1 * 5 - 2 * -4);
    assert_true(fd.x == 5 && fd.y == -3 && fd.z == 2.5f);
    assert_true(sl_v3_len((sl_vec3){3, 4, 12}) == 13);
    assert_true(sl_v3_len((sl_vec3){3e30f, 4e30f, 0}) > 4.9e30); /* no float overflow */
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_ray_triangle), cmocka_unit_test(test_parity),
                                       cmocka_unit_test(test_kit)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}

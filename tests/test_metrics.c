/* Metrics on inputs whose answers are known by hand: missed objects and pixels, over-estimation,
 * triangle counts, and the series summaries (median, nearest-rank 95th percentile, max). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"

/* Object i gets a mesh of i+1 triangles (a fan), so triangle counts are easy to add up. */
static sl_scene fan_scene(uint32_t objects)
{
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    for (uint32_t i = 0; i < objects; i++) {
        uint32_t nt = i + 1, nv = nt + 2;
        float *p = malloc(nv * 3 * sizeof *p);
        uint32_t *idx = malloc(nt * 3 * sizeof *idx);
        for (uint32_t v = 0; v < nv; v++) {
            double a = v * 0.3;
            p[3 * v] = v ? (float)cos(a) : 0, p[3 * v + 1] = v ? (float)sin(a) : 0, p[3 * v + 2] = (float)i;
        }
        for (uint32_t t = 0; t < nt; t++)
            idx[3 * t] = 0, idx[3 * t + 1] = t + 1, idx[3 * t + 2] = t + 2;
        sl_mesh_desc md = {p, NULL, nv, idx, nt, NULL};
        uint32_t mesh;
        sl_error err;
        assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
        sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_OTHER, 0, 0};
        assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
        free(p);
        free(idx);
    }
    return s;
}

static sl_oracle_frame frame_of(const uint32_t *visible, const uint32_t *pixels, uint32_t n)
{
    sl_oracle_frame f;
    memset(&f, 0, sizeof f);
    f.view_count = 1;
    f.visible = visible;
    f.pixels = pixels;
    f.visible_count = n;
    return f;
}

static void test_compare_known(void **state)
{
    (void)state;
    sl_scene s = fan_scene(8);
    const uint32_t vis[] = {1, 3, 5, 7}, pix[] = {10, 20, 30, 40};
    sl_oracle_frame f = frame_of(vis, pix, 4);
    const uint32_t res[] = {0, 1, 5, 6};
    sl_cull_metrics m;
    uint32_t mid[4], mpx[4];
    sl_error err;
    assert_int_equal(sl_metrics_compare(s, &f, res, 4, &m, mid, mpx, 4, &err), SL_OK);
    assert_int_equal(m.visible_count, 4);
    assert_int_equal(m.result_count, 4);
    assert_int_equal(m.missed_count, 2);
    assert_int_equal(mid[0], 3);
    assert_int_equal(mpx[0], 20);
    assert_int_equal(mid[1], 7);
    assert_int_equal(mpx[1], 40);
    assert_int_equal(m.missed_pixels, 60);
    assert_int_equal(m.extra_count, 2); /* 0 and 6 */
    assert_true(m.overestimation == 1.0);
    assert_int_equal(m.triangles_rendered, 1 + 2 + 6 + 7);
    assert_int_equal(m.triangles_visible, 2 + 4 + 6 + 8);
    /* room for one missed object: the count still says two */
    mid[1] = 999;
    assert_int_equal(sl_metrics_compare(s, &f, res, 4, &m, mid, mpx, 1, &err), SL_OK);
    assert_int_equal(m.missed_count, 2);
    assert_int_equal(mid[0], 3);
    assert_int_equal(mid[1], 999);
    assert_int_equal(m.missed_pixels, 60);
    /* a superset misses nothing; over-estimation is |R| / |V| */
    const uint32_t all[] = {0, 1, 2, 3, 4, 5, 6, 7};
    assert_int_equal(sl_metrics_compare(s, &f, all, 8, &m, NULL, NULL, 0, &err), SL_OK);
    assert_int_equal(m.missed_count, 0);
    assert_int_equal(m.missed_pixels, 0);
    assert_int_equal(m.extra_count, 4);
    assert_true(m.overestimation == 2.0);
    assert_int_equal(m.triangles_rendered, 36);
    /* an empty result misses everything */
    assert_int_equal(sl_metrics_compare(s, &f, NULL, 0, &m, NULL, NULL, 0, &err), SL_OK);
    assert_int_equal(m.missed_count, 4);
    assert_int_equal(m.missed_pixels, 100);
    assert_true(m.overestimation == 0.0);
    assert_int_equal(m.triangles_rendered, 0);
    /* nothing visible: over-estimation is |R| / 1 */
    sl_oracle_frame none = frame_of(NULL, NULL, 0);
    assert_int_equal(sl_metrics_compare(s, &none, res, 3, &m, NULL, NULL, 0, &err), SL_OK);
    assert_true(m.overestimation == 3.0);
    assert_int_equal(m.extra_count, 3);
    sl_scene_destroy(s);
}

static void test_compare_errors(void **state)
{
    (void)state;
    sl_scene s = fan_scene(4);
    const uint32_t vis[] = {1, 2}, pix[] = {5, 6};
    sl_oracle_frame f = frame_of(vis, pix, 2);
    sl_cull_metrics m;
    sl_error err;
    const uint32_t unsorted[] = {2, 1}, dup[] = {1, 1}, range[] = {1, 4};
    assert_int_equal(sl_metrics_compare(s, &f, unsorted, 2, &m, NULL, NULL, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "ascending"));
    assert_int_equal(sl_metrics_compare(s, &f, dup, 2, &m, NULL, NULL, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_metrics_compare(s, &f, range, 2, &m, NULL, NULL, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "result[1] = 4"));
    assert_int_equal(sl_metrics_compare(s, &f, NULL, 2, &m, NULL, NULL, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_metrics_compare(s, &f, vis, 2, &m, NULL, NULL, 3, &err), SL_ERROR_INVALID_ARGUMENT);
    const uint32_t bad_vis[] = {3, 9};
    sl_oracle_frame g = frame_of(bad_vis, pix, 2);
    assert_int_equal(sl_metrics_compare(s, &g, vis, 2, &m, NULL, NULL, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another scene"));
    sl_scene_destroy(s);
}

/* With a real oracle frame: the oracle's own set is judged perfect. */
static void test_compare_oracle_frame(void **state)
{
    (void)state;
    sl_scene s = fan_scene(6);
    sl_oracle o;
    sl_error err;
    sl_oracle_options opt = sl_oracle_default_options();
    opt.width = 64;
    opt.height = 64;
    assert_int_equal(sl_oracle_create(s, &opt, NULL, &o, &err), SL_OK);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0.2f, 0.3f, 8};
    cam.pitch = -(float)M_PI_2;
    sl_oracle_frame f;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    assert_true(f.visible_count >= 1);
    sl_cull_metrics m;
    assert_int_equal(sl_metrics_compare(s, &f, f.visible, f.visible_count, &m, NULL, NULL, 0, &err), SL_OK);
    assert_int_equal(m.missed_count, 0);
    assert_int_equal(m.extra_count, 0);
    assert_true(m.overestimation == 1.0);
    assert_int_equal(m.triangles_rendered, m.triangles_visible);
    /* dropping the topmost fan (the nearest, drawn over the others) misses exactly its pixels */
    uint32_t last = f.visible[f.visible_count - 1];
    assert_int_equal(last, 5);
    assert_int_equal(sl_metrics_compare(s, &f, f.visible, f.visible_count - 1, &m, NULL, NULL, 0, &err), SL_OK);
    assert_int_equal(m.missed_count, 1);
    assert_int_equal(m.missed_pixels, f.pixels[f.visible_count - 1]);
    assert_int_equal(m.missed_pixels, f.covered_pixels); /* it hides all the others */
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

static void test_series(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_series_summary s;
    sl_error err;
    const double odd[] = {5, 1, 4, 2, 3};
    assert_int_equal(sl_series_summarize(odd, 5, &a, &s, &err), SL_OK);
    assert_int_equal(s.count, 5);
    assert_true(s.min == 1 && s.max == 5 && s.mean == 3 && s.median == 3);
    assert_true(s.p95 == 5); /* ceil(4.75) = 5th smallest */
    assert_true(odd[0] == 5 && odd[4] == 3); /* input untouched */
    const double even[] = {4, 1, 3, 2};
    assert_int_equal(sl_series_summarize(even, 4, &a, &s, &err), SL_OK);
    assert_true(s.median == 2.5);
    assert_true(s.p95 == 4);
    double hundred[100], twenty[20];
    for (int i = 0; i < 100; i++)
        hundred[i] = 100 - i; /* 100 .. 1 */
    for (int i = 0; i < 20; i++)
        twenty[i] = i + 1;
    assert_int_equal(sl_series_summarize(hundred, 100, &a, &s, &err), SL_OK);
    assert_true(s.p95 == 95 && s.median == 50.5 && s.max == 100 && s.min == 1);
    assert_int_equal(sl_series_summarize(twenty, 20, &a, &s, &err), SL_OK);
    assert_true(s.p95 == 19);
    const double one[] = {7.5};
    assert_int_equal(sl_series_summarize(one, 1, &a, &s, &err), SL_OK);
    assert_true(s.median == 7.5 && s.p95 == 7.5 && s.max == 7.5);
    assert_int_equal(sl_series_summarize(NULL, 0, &a, &s, &err), SL_OK);
    assert_int_equal(s.count, 0);
    assert_true(s.median == 0 && s.max == 0);
    const double bad[] = {1, NAN};
    assert_int_equal(sl_series_summarize(bad, 2, &a, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "value 1"));
    assert_int_equal(sl_series_summarize(NULL, 3, &a, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(c.live, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compare_known),
        cmocka_unit_test(test_compare_errors),
        cmocka_unit_test(test_compare_oracle_frame),
        cmocka_unit_test(test_series),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

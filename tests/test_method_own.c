/* Every culling method on its own: the shared hidden-object test that runs after the occlusion
 * methods' own tests (sl_occ_object_hidden: mesh_test and sample_tris, src/cull/occlusion/object_tests.c) is
 * turned off (option shared=false), so a method whose own test is broken can no longer hide behind
 * it. On street and flyover views of the tiny city each method must
 *  - keep every object the point oracle sees, when it is conservative, and
 *  - still cull on its own: the objects it keeps, summed over the views, may be at most a floor
 *    fraction of what a reference keeps (the frustum set of vfc for the occlusion methods, every
 *    object for vfc itself). The floors were measured when the test was written (the figures are
 *    printed on every run) and carry a margin; a method whose own test answers "visible" always
 *    keeps the whole frustum set (ratio 1) and fails.
 * scripts/mutants.sh breaks each method's core test on purpose and checks that this test (or
 * another one) fails. The pvs culler needs a baked file: tests/test_pvs_build.c checks it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

typedef struct own_method {
    const char *name, *options;
    double floor;  /* most kept / reference kept (sum over the views) */
} own_method;

/* The floors: the ratio measured (the larger of the release run and the shorter SL_SANITIZED one)
 * plus a quarter of the way to 1, rounded up; hzb and the grids get 0.80, room for a
 * resolution-independent default (issue 13 section 6) that keeps a few more. Measured: vfc 0.31
 * of all objects; of the frustum set hzb 0.63 (0.68 with shared=false, 0.70 without pyramid,
 * box_rows and the exact layer), lazygrid and busygrid 0.70, lazygrid-z 0.68, hom 0.79 (and at
 * threshold 0.7), frusta 0.72, plp (budget 5000) 0.70, cplp 0.88, cullmap 0.72, horizon and
 * dhorizon 0.68. */
static const own_method g_methods[] = {
    {"vfc", NULL, 0.48},
    {"hzb", "shared=false", 0.80},
    {"hzb", "shared=false,pyramid=false,box_rows=0,exact_px=0", 0.80},
    {"lazygrid", "shared=false", 0.80},
    {"lazygrid-z", "shared=false", 0.80},
    {"busygrid", "shared=false", 0.80},
    {"hzb", NULL, 0.75},
    {"hom", NULL, 0.85},
    {"hom", "threshold=0.7", 0.85},
    {"frusta", NULL, 0.79},
    {"plp", "budget=5000", 0.78},
    {"cplp", NULL, 0.92},
    {"cullmap", NULL, 0.79},
    {"horizon", NULL, 0.77},
    {"dhorizon", NULL, 0.77},
};

typedef struct own_run {
    sl_culler c;
    sl_cull_guarantee g;
    uint64_t kept, missed;
} own_run;

static sl_path views_of(sl_scene s, sl_view_kind kind, uint32_t count, uint64_t seed)
{
    sl_path_options po = sl_path_options_default(kind == SL_VIEWS_STREET ? SL_PATH_WALK : SL_PATH_FLYOVER);
    po.intrinsics.width = 320;
    po.intrinsics.height = 240;
    sl_path p;
    sl_error err;
    if (sl_path_random_views(s, kind, count, seed, &po, NULL, &p, &err) != SL_OK)
        fail_msg("%s", err.message);
    return p;
}

/* Cull every view with every method and the vfc reference; count what each keeps and misses. */
static void run(sl_scene s, sl_path views, own_run *runs, uint64_t *ref_kept, uint64_t *all)
{
    uint32_t n = sl_scene_object_count(s);
    sl_error err;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_culler ref;
    assert_int_equal(sl_culler_create("vfc", s, "backface=false", NULL, &ref, &err), SL_OK);
    uint32_t *out = malloc(n * sizeof *out);
    assert_non_null(out);
    for (uint32_t f = 0; f < sl_path_count(views); f++) {
        sl_camera cam = sl_path_camera(views, f);
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        uint32_t k;
        assert_int_equal(sl_culler_cull(ref, &cam, out, n, &k, &err), SL_OK);
        *ref_kept += k;
        *all += n;
        for (size_t i = 0; i < SL_COUNTOF(g_methods); i++) {
            if (sl_culler_cull(runs[i].c, &cam, out, n, &k, &err) != SL_OK)
                fail_msg("%s %s frame %u: %s", g_methods[i].name, g_methods[i].options ? g_methods[i].options : "",
                         f, err.message);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, NULL, NULL, 0, &err), SL_OK);
            runs[i].kept += k;
            runs[i].missed += mt.missed_count;
        }
    }
    free(out);
    sl_culler_destroy(ref);
    sl_oracle_destroy(o);
}

static void test_own(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    own_run runs[SL_COUNTOF(g_methods)];
    memset(runs, 0, sizeof runs);
    for (size_t i = 0; i < SL_COUNTOF(g_methods); i++) {
        if (sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &runs[i].c, &err) != SL_OK)
            fail_msg("%s: %s", g_methods[i].name, err.message);
        runs[i].g = sl_culler_guarantee(runs[i].c);
    }
    uint64_t ref_kept = 0, all = 0;
    sl_path street = views_of(s, SL_VIEWS_STREET, sanitized() ? 12 : 200, 41);
    sl_path fly = views_of(s, SL_VIEWS_FLYOVER, sanitized() ? 4 : 60, 42);
    run(s, street, runs, &ref_kept, &all);
    run(s, fly, runs, &ref_kept, &all);
    assert_true(ref_kept > 0);
    int failed = 0;
    for (size_t i = 0; i < SL_COUNTOF(g_methods); i++) {
        const own_method *m = &g_methods[i];
        bool is_vfc = strcmp(m->name, "vfc") == 0;
        double ratio = (double)runs[i].kept / (double)(is_vfc ? all : ref_kept);
        print_message("%-10s %-52s %-12s kept %.4f of %s (floor %.2f), missed %llu\n", m->name,
                      m->options ? m->options : "", sl_cull_guarantee_name(runs[i].g), ratio,
                      is_vfc ? "all objects" : "the frustum set", m->floor, (unsigned long long)runs[i].missed);
        if (runs[i].g == SL_CONSERVATIVE && runs[i].missed) {
            print_error("%s (%s): conservative, missed %llu visible objects\n", m->name, m->options ? m->options : "",
                        (unsigned long long)runs[i].missed);
            failed++;
        }
        if (ratio > m->floor) {
            print_error("%s (%s): keeps %.4f, above its floor %.2f: its own test culls less than it did\n", m->name,
                        m->options ? m->options : "", ratio, m->floor);
            failed++;
        }
        sl_culler_destroy(runs[i].c);
    }
    sl_path_destroy(street);
    sl_path_destroy(fly);
    sl_scene_destroy(s);
    assert_int_equal(failed, 0);
}

/* dhorizon's own idea is to restart each frame's sweep from the last frame's frontier instead of
 * the root (docs/urban.md; its delta-H skip almost never fires there, so it is not required here):
 * along a slow drive most frames must be delta frames (phase "sweep-delta", whose node visits differ
 * from a full sweep's: measured 1.13 of horizon's on this drive, the frontier is finer than the
 * nodes a fresh sweep opens) and keep every object horizon keeps. With every frame a full sweep its
 * output is horizon's and every other test passes. */
static void test_dhorizon_reuses(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_culler d, h;
    assert_int_equal(sl_culler_create("dhorizon", s, NULL, NULL, &d, &err), SL_OK);
    assert_int_equal(sl_culler_create("horizon", s, NULL, NULL, &h, &err), SL_OK);
    sl_path_options po = sl_path_options_default(SL_PATH_DRIVE);
    po.frames = sanitized() ? 40 : 150;
    po.speed = 14; /* about 0.5 m a frame at 30 fps */
    po.seed = 3;
    sl_path p;
    assert_int_equal(sl_path_generate(s, &po, NULL, &p, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), ka, kb;
    uint32_t delta_frames = 0, extra = 0;
    uint64_t nodes_d = 0, nodes_h = 0;
    for (uint32_t f = 0; f < po.frames; f++) {
        sl_camera cam = sl_path_camera(p, f);
        cam.width = 320, cam.height = 240;
        assert_int_equal(sl_culler_cull(d, &cam, a, n, &ka, &err), SL_OK);
        assert_int_equal(sl_culler_cull(h, &cam, b, n, &kb, &err), SL_OK);
        sl_cull_stats st;
        sl_culler_stats(d, &st);
        for (uint32_t q = 0; q < st.phase_count; q++)
            delta_frames += strcmp(st.phase_names[q], "sweep-delta") == 0;
        nodes_d += st.nodes_visited;
        sl_culler_stats(h, &st);
        nodes_h += st.nodes_visited;
        /* every object horizon keeps, dhorizon keeps */
        uint32_t i = 0;
        for (uint32_t j = 0; j < kb; j++) {
            while (i < ka && a[i] < b[j])
                i++;
            if (i >= ka || a[i] != b[j])
                fail_msg("frame %u: horizon keeps object %u, dhorizon drops it", f, b[j]);
        }
        extra += ka - kb;
    }
    double ratio = (double)nodes_d / (double)(nodes_h ? nodes_h : 1);
    print_message("dhorizon: %u of %u frames restarted from the frontier; nodes visited %.3f of horizon's; kept %u "
                  "more objects than horizon\n",
                  delta_frames, po.frames, ratio, extra);
    assert_true(delta_frames * 2 > po.frames);
    assert_true(nodes_d != nodes_h);
    free(a);
    free(b);
    sl_path_destroy(p);
    sl_culler_destroy(d);
    sl_culler_destroy(h);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_own),
        cmocka_unit_test(test_dhorizon_reuses),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

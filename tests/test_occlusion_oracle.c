/* The online occlusion methods against the point oracle: every conservative method (hzb, hom at
 * threshold 1, lazygrid, lazygrid-z, busygrid, frusta, cplp) must keep every object the oracle
 * sees, from random street-level and flyover viewpoints of the generated cities, with the cars
 * moving between frames, and on Quake III maps; the aggressive ones (plp, hom below 1) report
 * their missed pixels. The camera's resolution is the oracle's, as the contract requires.
 *
 * Sizes: CTest runs the tiny city and a reduced small city (fewer views under SL_SANITIZED);
 * SL_LONG_TESTS=1 runs the full counts: 1,000 street and 200 flyover views of the small
 * city at 1024x768 and every map of openarena-081-maps. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/truth.h"
#include "support/pk3_names.h"

#define OA_PK3 SL_TEST_OA_PK3

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }
static bool long_tests(void)
{
    const char *e = getenv("SL_LONG_TESTS");
    return e && strcmp(e, "1") == 0;
}

typedef struct method_run {
    const char *name, *options;
    sl_culler c;
    sl_cull_guarantee g;
    uint64_t frames, missed_objects, missed_pixels, kept, visible, queries;
    double ms;
} method_run;

static const struct {
    const char *name, *options;
} g_methods[] = {
    {"hzb", NULL},
    {"hzb", "pyramid=false,render_visible=false,occluders=200"},
    {"hom", NULL},
    {"hom", "threshold=0.7"},
    {"lazygrid", NULL},
    {"lazygrid-z", NULL},
    {"busygrid", NULL},
    {"frusta", NULL},
    {"plp", NULL},
    {"cplp", NULL},
};

static uint32_t make_runs(sl_scene s, method_run *runs)
{
    uint32_t n = 0;
    for (size_t i = 0; i < SL_COUNTOF(g_methods); i++) {
        sl_error err;
        method_run *m = &runs[n];
        memset(m, 0, sizeof *m);
        m->name = g_methods[i].name;
        m->options = g_methods[i].options;
        if (sl_cull_method_find(m->name, NULL, &err) != SL_OK)
            fail_msg("method %s is not registered", m->name);
        if (sl_culler_create(m->name, s, m->options, NULL, &m->c, &err) != SL_OK)
            fail_msg("%s: %s", m->name, err.message);
        m->g = sl_culler_guarantee(m->c);
        n++;
    }
    return n;
}

static void report(const char *label, method_run *runs, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        method_run *m = &runs[i];
        print_message("%-16s %-10s %-45s %s: %llu frames, kept %.1f / visible %.1f, missed %llu objects "
                      "(%llu pixels), %.3f ms mean\n",
                      label, m->name, m->options ? m->options : "", sl_cull_guarantee_name(m->g),
                      (unsigned long long)m->frames, m->frames ? (double)m->kept / (double)m->frames : 0,
                      m->frames ? (double)m->visible / (double)m->frames : 0, (unsigned long long)m->missed_objects,
                      (unsigned long long)m->missed_pixels, m->frames ? m->ms / (double)m->frames : 0);
        sl_culler_destroy(m->c);
    }
}

/* Move every dynamic object by (dx, dy) from its transform at `base` (one per object). */
static void move_dynamic(sl_scene s, const sl_affine *base, float dx, float dy)
{
    uint32_t n = sl_scene_object_count(s);
    for (uint32_t i = 0; i < n; i++) {
        sl_object_view ov = sl_scene_object(s, i);
        if (!(ov.flags & SL_OBJECT_DYNAMIC))
            continue;
        sl_affine t = base[i];
        t.m[3] += dx;
        t.m[7] += dy;
        sl_error err;
        assert_int_equal(sl_scene_set_object_transform(s, i, &t, &err), SL_OK);
    }
}

/* Run every method on every view of `views`; a conservative method may miss nothing. With
 * `moving`, dynamic objects move before each frame and every culler is told. */
static void run_views(sl_scene s, sl_path views, method_run *runs, uint32_t nm, const char *label, bool moving)
{
    uint32_t n = sl_scene_object_count(s);
    sl_error err;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out), missed[8], mpx[8];
    sl_affine *base = NULL;
    if (moving) {
        base = malloc(n * sizeof *base);
        for (uint32_t i = 0; i < n; i++)
            base[i] = sl_scene_object(s, i).transform;
    }
    for (uint32_t f = 0; f < sl_path_count(views); f++) {
        sl_camera cam = sl_path_camera(views, f);
        if (moving) {
            /* cars drive 2 m a frame, alternating east and north-west */
            float t = (float)f;
            move_dynamic(s, base, 2.0f * t * ((f % 2) ? 1.0f : -0.5f), 1.3f * t * ((f % 3) ? -1.0f : 1.0f));
            for (uint32_t i = 0; i < nm; i++)
                assert_int_equal(sl_culler_scene_changed(runs[i].c, &err), SL_OK);
        }
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        for (uint32_t i = 0; i < nm; i++) {
            method_run *m = &runs[i];
            uint32_t k;
            if (sl_culler_cull(m->c, &cam, out, n, &k, &err) != SL_OK)
                fail_msg("%s %s frame %u: %s", label, m->name, f, err.message);
            sl_cull_stats st;
            sl_culler_stats(m->c, &st);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 8, &err), SL_OK);
            m->frames++;
            m->kept += k;
            m->visible += fr.visible_count;
            m->missed_objects += mt.missed_count;
            m->missed_pixels += mt.missed_pixels;
            m->queries += st.queries;
            m->ms += st.total_ms;
            if (mt.missed_count && m->g == SL_CONSERVATIVE)
                fail_msg("%s: %s (%s) frame %u missed %u objects (first %u with %u pixels); camera at "
                         "(%.3f, %.3f, %.3f) yaw %.4f pitch %.4f %s %ux%u",
                         label, m->name, m->options ? m->options : "", f, mt.missed_count, missed[0], mpx[0],
                         (double)cam.position.x, (double)cam.position.y, (double)cam.position.z, (double)cam.yaw,
                         (double)cam.pitch, cam.projection == SL_ORTHOGRAPHIC ? "ortho" : "persp", cam.width,
                         cam.height);
        }
    }
    if (moving) {
        move_dynamic(s, base, 0, 0);
        for (uint32_t i = 0; i < nm; i++)
            assert_int_equal(sl_culler_scene_changed(runs[i].c, &err), SL_OK);
        free(base);
    }
    free(out);
    sl_oracle_destroy(o);
}

static sl_path views_of(sl_scene s, sl_view_kind kind, uint32_t count, uint64_t seed, uint32_t w, uint32_t h)
{
    sl_path_options po = sl_path_options_default(kind == SL_VIEWS_STREET ? SL_PATH_WALK : SL_PATH_FLYOVER);
    po.intrinsics.width = w;
    po.intrinsics.height = h;
    sl_path p;
    sl_error err;
    if (sl_path_random_views(s, kind, count, seed, &po, NULL, &p, &err) != SL_OK)
        fail_msg("%s", err.message);
    return p;
}

static sl_scene city(sl_city_preset preset)
{
    sl_city_options co = sl_city_defaults(preset);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    return s;
}

/* The tiny city: street and flyover views, one orthographic pass, with and without moving cars. */
static void test_tiny_city(void **state)
{
    (void)state;
    sl_scene s = city(SL_CITY_TINY);
    method_run runs[SL_COUNTOF(g_methods)];
    uint32_t nm = make_runs(s, runs);
    uint32_t ns = sanitized() ? 10 : 200, nf = sanitized() ? 4 : 60;
    sl_path street = views_of(s, SL_VIEWS_STREET, ns, 11, 320, 240);
    sl_path fly = views_of(s, SL_VIEWS_FLYOVER, nf, 12, 320, 240);
    run_views(s, street, runs, nm, "tiny street", false);
    run_views(s, fly, runs, nm, "tiny flyover", false);
    /* the same flyover views through an orthographic camera */
    sl_camera in = sl_path_intrinsics(fly);
    in.projection = SL_ORTHOGRAPHIC;
    in.ortho_height = 160;
    sl_error err;
    assert_int_equal(sl_path_set_intrinsics(fly, &in, &err), SL_OK);
    run_views(s, fly, runs, nm, "tiny ortho", false);
    run_views(s, street, runs, nm, "tiny moving", true);
    report("tiny", runs, nm);
    sl_path_destroy(street);
    sl_path_destroy(fly);
    sl_scene_destroy(s);
}

/* The small city, reduced in CTest; SL_LONG_TESTS=1 runs 1,000 street and 200 flyover views at
 * 1024x768. */
static void test_small_city(void **state)
{
    (void)state;
    sl_scene s = city(SL_CITY_SMALL);
    method_run runs[SL_COUNTOF(g_methods)];
    uint32_t nm = make_runs(s, runs);
    bool full = long_tests();
    uint32_t ns = full ? 1000 : (sanitized() ? 4 : 100), nf = full ? 200 : (sanitized() ? 2 : 30);
    uint32_t w = full ? 1024 : 480, h = full ? 768 : 360;
    sl_path street = views_of(s, SL_VIEWS_STREET, ns, 21, w, h);
    sl_path fly = views_of(s, SL_VIEWS_FLYOVER, nf, 22, w, h);
    run_views(s, street, runs, nm, "small street", !full);
    run_views(s, fly, runs, nm, "small flyover", false);
    report(full ? "small (full)" : "small", runs, nm);
    sl_path_destroy(street);
    sl_path_destroy(fly);
    sl_scene_destroy(s);
}

/* Quake III maps: views from the spawn points. CTest: four maps (one under the sanitizers);
 * SL_LONG_TESTS=1: every map, 40 views each at 640x480. */
static void test_q3_maps(void **state)
{
    (void)state;
    if (access(OA_PK3, R_OK) != 0) {
        print_message("skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
        skip();
    }
    sl_test_name_list *list = calloc(1, sizeof *list);
    sl_error err;
    assert_int_equal(sl_pk3_list_maps(OA_PK3, sl_test_collect_name, list, &err), SL_OK);
    assert_true(list->count >= 2);
    bool full = long_tests();
    int maps = full ? list->count : (sanitized() ? 1 : 4);
    uint32_t views = full ? 40 : (sanitized() ? 3 : 20);
    for (int i = 0; i < maps; i++) {
        sl_scene s;
        if (sl_import_q3bsp(OA_PK3, list->names[i], NULL, NULL, &s, &err) != SL_OK)
            fail_msg("%s", err.message);
        sl_path p;
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.intrinsics.width = full ? 640 : 320;
        po.intrinsics.height = full ? 480 : 240;
        if (sl_path_random_views(s, SL_VIEWS_STREET, views, 31 + (uint64_t)i, &po, NULL, &p, &err) != SL_OK) {
            print_message("%s: no views (%s)\n", list->names[i], err.message);
            sl_scene_destroy(s);
            continue;
        }
        method_run runs[SL_COUNTOF(g_methods)];
        uint32_t nm = make_runs(s, runs);
        run_views(s, p, runs, nm, list->names[i], false);
        report(list->names[i], runs, nm);
        sl_path_destroy(p);
        sl_scene_destroy(s);
    }
    free(list);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tiny_city),
        cmocka_unit_test(test_small_city),
        cmocka_unit_test(test_q3_maps),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The urban cullers (cullmap, horizon, dhorizon) against the point oracle: zero missed objects.
 *  - the occluder-fusion cases of Wonka's thesis (figure 5.2) as hand-built scenes: (a) connected
 *    occluders (a party wall), (b) overlapping umbrae, (c) two occluders with a gap between them
 *    and an object hidden from every point of a short segment in front of them; each fused case
 *    must be culled where no single occluder hides the object;
 *  - a building visible only through a gap one grid cell wide is kept;
 *  - random street-level viewpoints of the tiny and small cities, a quarter of them pitched and
 *    rolled (6 degrees of freedom), and a walk for dhorizon.
 * With SL_LONG_TESTS=1 it also runs 1,000 views of the small city and 1,000 of vienna (minutes);
 * bench/urban.c runs the same checks with timings. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

static const char *const g_methods[3] = {"cullmap", "horizon", "dhorizon"};

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    sl_error err;
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, kind == SL_KIND_BUILDING ? SL_OBJECT_OCCLUDER : 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

static uint32_t add_building(sl_scene s, float x0, float y0, float x1, float y1, float h)
{
    uint32_t obj = add_box(s, (sl_vec3){x0, y0, 0}, (sl_vec3){x1, y1, h}, SL_KIND_BUILDING);
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0.0f, h, obj};
    sl_error err;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    return obj;
}

static sl_scene new_scene(void)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){-20, -60, -0.1f}, (sl_vec3){140, 60, 0}, SL_KIND_GROUND);
    return s;
}

/* Run the three methods with 8 m cells (the scale these scenes are drawn at; the defaults are
 * coarser and are covered by the generated cities below) from cam: no misses against the oracle.
 * Returns a bit per method that kept object `probe`, and whether the oracle sees it. */
static unsigned judge(sl_scene s, const sl_camera *cam, uint32_t probe, bool *seen)
{
    sl_error err;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(o, cam, &fr, &err), SL_OK);
    *seen = false;
    for (uint32_t k = 0; k < fr.visible_count; k++)
        *seen |= fr.visible[k] == probe;
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * sizeof *ids), cnt;
    unsigned kept = 0;
    for (int m = 0; m < 3; m++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(g_methods[m], s, "cell=8", NULL, &c, &err), SL_OK);
        for (int rep = 0; rep < 2; rep++) { /* dhorizon: a fresh frame, then one reusing it */
            assert_int_equal(sl_culler_cull(c, cam, ids, n, &cnt, &err), SL_OK);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, ids, cnt, &mt, NULL, NULL, 0, &err), SL_OK);
            assert_int_equal(mt.missed_count, 0);
        }
        for (uint32_t k = 0; k < cnt; k++)
            if (ids[k] == probe)
                kept |= 1u << m;
        sl_culler_destroy(c);
    }
    free(ids);
    sl_oracle_destroy(o);
    return kept;
}

static sl_camera street_cam(float x, float y, float yaw)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){x, y, 1.7f};
    c.yaw = yaw;
    c.width = 640, c.height = 480;
    return c;
}

/* (a) connected occluders: two buildings sharing a party wall hide what neither hides alone. */
static void test_fusion_connected(void **state)
{
    (void)state;
    for (int variant = 0; variant < 3; variant++) {
        sl_scene s = new_scene();
        if (variant != 2)
            add_building(s, 20, -20, 30, 0, 15);
        if (variant != 1)
            add_building(s, 20, 0, 30, 20, 15);
        uint32_t probe = add_box(s, (sl_vec3){50, -3, 0}, (sl_vec3){54, 3, 4}, SL_KIND_CAR);
        sl_camera cam = street_cam(0, 0.5f, 0);
        bool seen;
        unsigned kept = judge(s, &cam, probe, &seen);
        if (variant == 0) {
            assert_false(seen);
            assert_int_equal(kept, 0); /* fused across the party wall by every method */
        } else {
            assert_true(seen); /* one building alone leaves it visible: kept (judge checked) */
            assert_int_equal(kept, 7);
        }
        sl_scene_destroy(s);
    }
}

/* (b) overlapping umbrae: two buildings at different depths whose shadows overlap. */
static void test_fusion_overlapping(void **state)
{
    (void)state;
    for (int variant = 0; variant < 3; variant++) {
        sl_scene s = new_scene();
        if (variant != 2)
            add_building(s, 20, -20, 30, 1, 15);
        if (variant != 1)
            add_building(s, 40, -1, 50, 20, 25);
        uint32_t probe = add_box(s, (sl_vec3){70, -6, 0}, (sl_vec3){74, 6, 4}, SL_KIND_CAR);
        sl_camera cam = street_cam(0, 0, 0);
        bool seen;
        unsigned kept = judge(s, &cam, probe, &seen);
        if (variant == 0) {
            assert_false(seen);
            assert_int_equal(kept, 0);
        } else {
            assert_true(seen);
            assert_int_equal(kept, 7);
        }
        sl_scene_destroy(s);
    }
}

/* (c) two occluders with a gap: behind them, off the line of the gap, an object hidden from every
 * point of a segment in front (for a point viewer the joint umbra is the union of the umbrae: each
 * point culls it through whichever occluder covers it); in the gap's line, one that is kept. */
static void test_fusion_gap_segment(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    add_building(s, 20, -40, 30, -1, 20);
    add_building(s, 20, 1, 30, 40, 20);
    uint32_t hidden = add_box(s, (sl_vec3){100, 18, 0}, (sl_vec3){104, 22, 4}, SL_KIND_CAR);
    for (int k = 0; k <= 6; k++) {
        float y = -3.0f + k;
        sl_camera cam = street_cam(0, y, 0);
        bool seen;
        unsigned kept = judge(s, &cam, hidden, &seen);
        assert_false(seen);
        assert_int_equal(kept, 0);
    }
    sl_scene_destroy(s);
}

/* A building seen only through a gap one grid cell (8 m) wide is kept. */
static void test_gap_one_cell(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    add_building(s, 20, -40, 30, -4, 22);
    add_building(s, 20, 4, 30, 40, 22);
    uint32_t probe = add_building(s, 60, -3, 70, 3, 10);
    sl_camera cam = street_cam(0, 0, 0);
    bool seen;
    unsigned kept = judge(s, &cam, probe, &seen);
    assert_true(seen);
    assert_int_equal(kept, 7);
    /* seen from the side, the same building is hidden by the walls, and culled */
    cam = street_cam(0, 25, -0.3f);
    kept = judge(s, &cam, probe, &seen);
    assert_false(seen);
    sl_scene_destroy(s);
}

/* ---- generated cities ---- */

typedef struct city_run {
    uint64_t views, misses, kept, visible;
} city_run;

/* count random street views of a city (every fourth pitched and rolled) and, when walk_frames,
 * a walk replayed by dhorizon: every method must keep every visible object. */
/* A moving occluder with a footprint: an L-shaped DYNAMIC building (a bar across the view and a
 * stub along it, 10 m tall) turned half a turn about its box centre, which leaves its box as it
 * was but swaps the bar to the far side. Its footprint is where it was placed: a method that
 * occluded with it would hide the box behind the old bar, now in plain view. Every conservative
 * method, created before the turn (then told by scene_changed) or after it: zero misses. */
static void test_moving_occluder(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s = new_scene();
    float p[48];
    const sl_vec3 lo[2] = {{0, 0, 0}, {2, 0, 0}}, hi[2] = {{2, 10, 10}, {10, 2, 10}};
    uint32_t idx[72];
    static const uint32_t box_idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                         2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    for (int b = 0; b < 2; b++) {
        for (int i = 0; i < 8; i++) {
            p[24 * b + 3 * i] = (i & 1) ? hi[b].x : lo[b].x;
            p[24 * b + 3 * i + 1] = (i & 2) ? hi[b].y : lo[b].y;
            p[24 * b + 3 * i + 2] = (i & 4) ? hi[b].z : lo[b].z;
        }
        for (int k = 0; k < 36; k++)
            idx[36 * b + k] = box_idx[k] + 8u * (uint32_t)b;
    }
    sl_mesh_desc md = {p, NULL, 16, idx, 24, NULL};
    uint32_t mesh, l;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER | SL_OBJECT_DYNAMIC, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &l, &err), SL_OK);
    float xy[12] = {0, 0, 10, 0, 10, 2, 2, 2, 2, 10, 0, 10};
    sl_footprint_desc fd = {xy, 6, 0.0f, 10, l};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    uint32_t probe = add_box(s, (sl_vec3){4, 4, 0}, (sl_vec3){5, 6, 1}, SL_KIND_CAR);
    sl_camera cam = street_cam(-20, 5, 0);
    static const char *const methods[][2] = {{"cullmap", "cell=8"}, {"horizon", "cell=8"}, {"dhorizon", "cell=8"},
                                             {"cullmap", NULL},     {"hzb", NULL},         {"hom", NULL},
                                             {"frusta", NULL},      {"lazygrid", NULL},    {"cplp", NULL}};
    enum { NMETH = sizeof methods / sizeof methods[0] };
    sl_culler before[NMETH];
    for (size_t m = 0; m < NMETH; m++)
        assert_int_equal(sl_culler_create(methods[m][0], s, methods[m][1], NULL, &before[m], &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), ids[8], cnt;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    for (int turned = 0; turned < 2; turned++) {
        if (turned) {
            sl_affine t = sl_affine_identity();
            t.m[0] = -1, t.m[5] = -1, t.m[3] = 10, t.m[7] = 10;
            sl_aabb b0 = sl_scene_object_bounds(s, l);
            assert_int_equal(sl_scene_set_object_transform(s, l, &t, &err), SL_OK);
            sl_aabb b1 = sl_scene_object_bounds(s, l);
            assert_memory_equal(&b0, &b1, sizeof b0); /* the box is as it was */
        }
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        bool seen = false;
        for (uint32_t k = 0; k < fr.visible_count; k++)
            seen |= fr.visible[k] == probe;
        assert_true(seen == (turned == 1)); /* hidden by the bar, then in plain view */
        for (size_t m = 0; m < NMETH; m++)
            for (int fresh = 0; fresh < 2; fresh++) {
                sl_culler c = before[m];
                if (fresh)
                    assert_int_equal(sl_culler_create(methods[m][0], s, methods[m][1], NULL, &c, &err), SL_OK);
                else if (turned)
                    assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
                assert_int_equal(sl_culler_cull(c, &cam, ids, n, &cnt, &err), SL_OK);
                sl_cull_metrics mt;
                assert_int_equal(sl_metrics_compare(s, &fr, ids, cnt, &mt, NULL, NULL, 0, &err), SL_OK);
                if (mt.missed_count)
                    fail_msg("%s %s (%s, %s the turn): %u missed", methods[m][0], methods[m][1] ? methods[m][1] : "",
                             fresh ? "created" : "told", turned ? "after" : "before", mt.missed_count);
                if (fresh)
                    sl_culler_destroy(c);
            }
    }
    for (size_t m = 0; m < NMETH; m++)
        sl_culler_destroy(before[m]);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

static void run_city(sl_city_preset preset, uint32_t count, uint32_t walk_frames, city_run out[3])
{
    sl_city_options co = sl_city_defaults(preset);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_culler c[3];
    for (int m = 0; m < 3; m++)
        assert_int_equal(sl_culler_create(g_methods[m], s, NULL, NULL, &c[m], &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * sizeof *ids), cnt;
    sl_path views;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, count ? count : 1, 7, NULL, NULL, &views, &err), SL_OK);
    sl_path walk = NULL;
    if (walk_frames) {
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.frames = walk_frames;
        po.speed = 5; /* brisk: about 0.17 m per frame */
        assert_int_equal(sl_path_generate(s, &po, NULL, &walk, &err), SL_OK);
    }
    sl_rng r;
    sl_rng_seed(&r, 99, 1);
    memset(out, 0, 3 * sizeof *out);
    for (uint32_t v = 0; v < count + walk_frames; v++) {
        sl_camera cam = v < count ? sl_path_camera(views, v) : sl_path_camera(walk, v - count);
        if (v < count && v % 4 == 3) {
            cam.pitch = sl_rng_range(&r, -1.2f, 1.2f);
            cam.roll = sl_rng_range(&r, -3.1f, 3.1f);
        }
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        for (int m = 0; m < 3; m++) {
            if (v >= count && m != 2)
                continue; /* the walk is for dhorizon */
            assert_int_equal(sl_culler_cull(c[m], &cam, ids, n, &cnt, &err), SL_OK);
            sl_cull_metrics mt;
            uint32_t missed[4], px[4];
            assert_int_equal(sl_metrics_compare(s, &fr, ids, cnt, &mt, missed, px, 4, &err), SL_OK);
            if (mt.missed_count)
                fprintf(stderr, "%s missed object %u (%u px) at view %u, eye (%g %g %g) yaw %g pitch %g roll %g\n",
                        g_methods[m], missed[0], px[0], v, (double)cam.position.x, (double)cam.position.y,
                        (double)cam.position.z, (double)cam.yaw, (double)cam.pitch, (double)cam.roll);
            out[m].views++;
            out[m].misses += mt.missed_count;
            out[m].kept += cnt;
            out[m].visible += fr.visible_count;
        }
    }
    sl_path_destroy(views);
    sl_path_destroy(walk);
    free(ids);
    sl_oracle_destroy(o);
    for (int m = 0; m < 3; m++)
        sl_culler_destroy(c[m]);
    sl_scene_destroy(s);
}

static void report(const char *what, const city_run r[3])
{
    for (int m = 0; m < 3; m++) {
        printf("%s %s: %llu views, %llu missed, %.2f kept per visible object\n", what, g_methods[m],
               (unsigned long long)r[m].views, (unsigned long long)r[m].misses,
               (double)r[m].kept / (double)(r[m].visible ? r[m].visible : 1));
        assert_int_equal(r[m].misses, 0);
    }
}

static void test_cities(void **state)
{
    (void)state;
    bool san = getenv("SL_SANITIZED") != NULL;
    city_run r[3];
    run_city(SL_CITY_TINY, san ? 12 : 60, san ? 20 : 120, r);
    report("tiny", r);
    /* the methods cull: on average well under vfc's dozens of objects per visible one */
    for (int m = 0; m < 3; m++)
        assert_true(r[m].kept < 4 * r[m].visible);
    if (!san) {
        run_city(SL_CITY_SMALL, 16, 0, r);
        report("small", r);
    }
}

static void test_long(void **state)
{
    (void)state;
    const char *e = getenv("SL_LONG_TESTS");
    if (!e || strcmp(e, "1") != 0) {
        skip();
        return;
    }
    city_run r[3];
    run_city(SL_CITY_SMALL, 1000, 600, r);
    report("small (long)", r);
    run_city(SL_CITY_VIENNA, 1000, 300, r);
    report("vienna (long)", r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fusion_connected),
        cmocka_unit_test(test_fusion_overlapping),
        cmocka_unit_test(test_fusion_gap_segment),
        cmocka_unit_test(test_gap_one_cell),
        cmocka_unit_test(test_moving_occluder),
        cmocka_unit_test(test_cities),
        cmocka_unit_test(test_long),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The occlusion horizon: the polar structure against brute force (soundness of every "occluded"
 * answer, no cracks between contiguous occluders, the 0-degree wrap), the pseudo-azimuth, and the
 * horizon cullers on special cases: fast movement for dhorizon (with and without its guard),
 * occluders nearer than the near plane, the eye inside a building, the eye above the roofs. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "cull/urban_internal.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"

/* ---- the structure ---- */

static void test_pseudo_azimuth(void **state)
{
    (void)state;
    double prev = -1;
    for (int k = 0; k < 3600; k++) {
        double a = k * (2 * M_PI / 3600);
        double p = sl_urban_paz(cos(a), sin(a));
        assert_true(p >= 0 && p < 4);
        if (k > 0)
            assert_true(p > prev); /* strictly increasing with the azimuth */
        prev = p;
        double dx, dy;
        sl_urban_paz_dir(p, &dx, &dy);
        assert_true(fabs(atan2(dy, dx) - atan2(sin(a), cos(a))) < 1e-9 ||
                    fabs(fabs(atan2(dy, dx) - atan2(sin(a), cos(a))) - 2 * M_PI) < 1e-9);
    }
}

typedef struct seg {
    double ax, ay, az, bx, by, bz, base;
} seg;

/* The exact top and bottom slopes of segment s in direction (dx, dy) from the eye, if it covers it. */
static bool seg_at(const double eye[3], const seg *s, double dx, double dy, double *top, double *bot)
{
    double ax = s->ax - eye[0], ay = s->ay - eye[1], ex = s->bx - s->ax, ey = s->by - s->ay;
    double den = dx * ey - dy * ex;
    if (fabs(den) < 1e-15)
        return false;
    double t = -(dx * ay - dy * ax) / den;
    if (t < 0 || t > 1)
        return false;
    double px = ax + t * ex, py = ay + t * ey;
    if (px * dx + py * dy <= 0)
        return false; /* behind the eye */
    double d = sqrt(px * px + py * py), z = s->az + t * (s->bz - s->az);
    *top = (z - eye[2]) / d;
    *bot = s->base == -INFINITY ? -INFINITY : (s->base - eye[2]) / d;
    return true;
}

static void test_horizon_sound(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 21, 4);
    sl_horizon h;
    sl_error err;
    assert_int_equal(sl_horizon_init(&h, 1024, false, NULL, &err), SL_OK);
    seg segs[64];
    int claims = 0;
    for (int trial = 0; trial < 60; trial++) {
        sl_horizon_reset(&h);
        double eye[3] = {sl_rng_range(&r, -5, 5), sl_rng_range(&r, -5, 5), sl_rng_range(&r, 0, 20)};
        int n = 1 + (int)sl_rng_below(&r, 60);
        for (int k = 0; k < n; k++) {
            seg *s = &segs[k];
            if (k > 0 && sl_rng_below(&r, 2)) { /* continue the previous one: contiguous chains */
                s->ax = segs[k - 1].bx, s->ay = segs[k - 1].by, s->az = segs[k - 1].bz;
            } else {
                double ang = sl_rng_range(&r, 0, 6.283f), d = sl_rng_range(&r, 3, 60);
                s->ax = eye[0] + d * cos(ang), s->ay = eye[1] + d * sin(ang), s->az = sl_rng_range(&r, 0, 30);
            }
            double ang = sl_rng_range(&r, 0, 6.283f), len = sl_rng_range(&r, 0.5f, 25);
            s->bx = s->ax + len * cos(ang), s->by = s->ay + len * sin(ang);
            s->bz = sl_rng_below(&r, 3) ? s->az : sl_rng_range(&r, 0, 30);
            s->base = sl_rng_below(&r, 4) ? -INFINITY : sl_rng_range(&r, -3, 5);
            sl_horizon_seg hs = {s->ax, s->ay, s->az, s->bx, s->by, s->bz, s->base};
            sl_horizon_insert(&h, eye, &hs);
        }
        /* every range the horizon calls occluded must be covered, direction by direction */
        for (int q = 0; q < 300; q++) {
            double a0 = sl_rng_range(&r, 0, 4), span = sl_rng_range(&r, 0, 0.3f);
            double top = sl_rng_range(&r, -1.5f, 1.5f), bottom = top - sl_rng_range(&r, 0, 3);
            if (!sl_horizon_occluded(&h, a0, span, top, bottom))
                continue;
            claims++;
            for (int s = 0; s <= 50; s++) {
                double dx, dy;
                sl_urban_paz_dir(sl_urban_paz_wrap(a0 + span * s / 50.0), &dx, &dy);
                bool covered = false;
                for (int k = 0; k < n && !covered; k++) {
                    double t, b;
                    covered = seg_at(eye, &segs[k], dx, dy, &t, &b) && t > top && b <= bottom;
                }
                if (!covered) {
                    fprintf(stderr, "trial %d: direction %g of [%g, +%g] is not hidden below %g\n", trial,
                            a0 + span * s / 50.0, a0, span, top);
                    fail();
                }
            }
        }
    }
    assert_true(claims > 200); /* the test did exercise occluded answers */
    sl_horizon_free(&h);
}

static void test_horizon_no_cracks_and_wrap(void **state)
{
    (void)state;
    sl_horizon h;
    sl_error err;
    assert_int_equal(sl_horizon_init(&h, 4096, false, NULL, &err), SL_OK);
    /* a closed ring of 37 walls around the eye, 10 m high, inserted in a scrambled order: every
     * direction is hidden below the lowest top, including across azimuth 0 and at every joint */
    double eye[3] = {0.3, -0.2, 1.7};
    enum { N = 37 };
    double px[N], py[N];
    for (int k = 0; k < N; k++) {
        double a = 2 * M_PI * k / N + 0.01;
        px[k] = 40 * cos(a), py[k] = 40 * sin(a);
    }
    for (int k = 0; k < N; k++) {
        int i = (k * 11) % N, j = (i + 1) % N;
        sl_horizon_seg s = {px[i], py[i], 10, px[j], py[j], 10, 0};
        sl_horizon_insert(&h, eye, &s);
    }
    double low = (10 - 1.7) / 40.5; /* below the lowest point of the ring */
    for (int b = 0; b < 4096; b++)
        assert_true(sl_horizon_occluded(&h, b * (4.0 / 4096), 4.0 / 4096 * 0.999, low, 0.0));
    assert_true(sl_horizon_occluded(&h, 3.9, 0.2, low, 0.0)); /* across the wrap */
    assert_true(sl_horizon_occluded(&h, 0, 4.0, low, 0.0));   /* the whole circle */
    /* above the ring's top, or below its base, nothing is hidden */
    assert_false(sl_horizon_occluded(&h, 1.0, 0.1, (10 - 1.7) / 39.0, 0.0));
    assert_false(sl_horizon_occluded(&h, 1.0, 0.1, low, -0.5));
    /* one segment across azimuth 0 alone */
    sl_horizon_reset(&h);
    sl_horizon_seg w = {30, -5, 20, 30, 5, 20, 0};
    sl_horizon_insert(&h, eye, &w);
    assert_true(sl_horizon_occluded(&h, 3.98, 0.04, 0.3, 0.0));
    assert_false(sl_horizon_occluded(&h, 3.5, 0.04, 0.3, 0.0));
    sl_horizon_free(&h);
}

/* ---- the cullers on special cases ---- */

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags)
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
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

static uint32_t add_building(sl_scene s, float x0, float y0, float x1, float y1, float h, uint32_t flags)
{
    uint32_t obj = add_box(s, (sl_vec3){x0, y0, 0}, (sl_vec3){x1, y1, h}, SL_KIND_BUILDING, flags | SL_OBJECT_OCCLUDER);
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0.0f, h, obj};
    sl_error err;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    return obj;
}

/* Every method keeps every object the oracle sees from cam; returns the oracle's count. */
static uint32_t check_all(sl_scene s, const sl_camera *cam, sl_culler *c, int nc)
{
    sl_oracle o;
    sl_error err;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(o, cam, &fr, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * sizeof *ids), cnt;
    for (int k = 0; k < nc; k++) {
        assert_int_equal(sl_culler_cull(c[k], cam, ids, n, &cnt, &err), SL_OK);
        sl_cull_metrics m;
        assert_int_equal(sl_metrics_compare(s, &fr, ids, cnt, &m, NULL, NULL, 0, &err), SL_OK);
        if (m.missed_count)
            fprintf(stderr, "%s missed %u objects\n", sl_culler_method(c[k]), m.missed_count);
        assert_int_equal(m.missed_count, 0);
    }
    uint32_t vis = fr.visible_count;
    free(ids);
    sl_oracle_destroy(o);
    return vis;
}

static const char *const g_methods[] = {"cullmap", "horizon", "dhorizon"};

static void make_cullers(sl_scene s, sl_culler c[3])
{
    sl_error err;
    for (int k = 0; k < 3; k++)
        assert_int_equal(sl_culler_create(g_methods[k], s, "cell=2", NULL, &c[k], &err), SL_OK);
}

static void test_near_and_inside(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){-60, -60, -0.1f}, (sl_vec3){60, 60, 0}, SL_KIND_GROUND, 0);
    add_building(s, 10, -20, 10.04f, 20, 12, 0);                  /* a thin wall 10 m ahead */
    add_building(s, -30, -30, -20, -20, 15, SL_OBJECT_CLOSED_CONVEX); /* a convex building */
    uint32_t behind = add_box(s, (sl_vec3){30, -2, 0}, (sl_vec3){32, 2, 3}, SL_KIND_CAR, 0);
    add_box(s, (sl_vec3){-45, -45, 0}, (sl_vec3){-43, -43, 3}, SL_KIND_CAR, 0);
    sl_culler c[3];
    make_cullers(s, c);
    sl_camera cam = sl_camera_default();
    cam.width = 320, cam.height = 240;
    /* the eye 5 cm in front of the wall, the near plane at 10 cm: the wall is clipped away and the
     * car behind it shows through; no method may use the wall */
    cam.position = (sl_vec3){9.97f, 0, 1.7f};
    cam.yaw = 0;
    uint32_t seen = check_all(s, &cam, c, 3);
    assert_true(seen >= 2);
    /* from further back the wall hides the car, and every method drops it */
    cam.position = (sl_vec3){0, 0, 1.7f};
    check_all(s, &cam, c, 3);
    uint32_t ids[8], n;
    for (int k = 0; k < 3; k++) {
        assert_int_equal(sl_culler_cull(c[k], &cam, ids, 8, &n, &err), SL_OK);
        for (uint32_t i = 0; i < n; i++)
            assert_int_not_equal(ids[i], behind);
    }
    /* inside the convex building (its back faces are not drawn: the oracle sees out through it) */
    cam.position = (sl_vec3){-25, -25, 2};
    cam.yaw = 3.93f;
    assert_true(check_all(s, &cam, c, 3) >= 2);
    /* inside the wall (a box that is not closed-convex is drawn both sides) */
    cam.position = (sl_vec3){10.02f, 0, 2};
    cam.yaw = 0;
    check_all(s, &cam, c, 3);
    /* above the roofs, looking down over the wall, pitched and rolled */
    cam.position = (sl_vec3){-5, 3, 40};
    cam.pitch = -0.8f;
    cam.roll = 0.4f;
    check_all(s, &cam, c, 3);
    cam.pitch = 1.2f; /* up at the sky, then straight down */
    check_all(s, &cam, c, 3);
    cam.pitch = -1.5707f;
    check_all(s, &cam, c, 3);
    for (int k = 0; k < 3; k++)
        sl_culler_destroy(c[k]);
    sl_scene_destroy(s);
}

/* dhorizon along a slow and a fast drive, every frame against the oracle, with its guard and
 * without: no misses; the frames that restart from the last frontier are those the guard allows,
 * and the delta-H rule skips nodes on those frames only. */
static void test_dhorizon_fast(void **state)
{
    (void)state;
    bool san = getenv("SL_SANITIZED") != NULL;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    const char *opts[3] = {"", "max_move=10000,max_turn=180,refresh=0", "max_move=10000,max_turn=180,refresh=0,bins=1024"};
    sl_culler c[3];
    for (int k = 0; k < 3; k++)
        assert_int_equal(sl_culler_create("dhorizon", s, opts[k], NULL, &c[k], &err), SL_OK);
    sl_oracle o;
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 400, oo.height = 300;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * sizeof *ids), cnt;
    const float speeds[2] = {14, 150}; /* about 0.5 and 5 m per frame at 30 fps */
    uint64_t skipped[3] = {0}, frames_checked = 0;
    const uint32_t frames = san ? 40 : 150;
    uint32_t delta_frames[2][3] = {{0}};
    for (int sp = 0; sp < 2; sp++) {
        sl_path_options po = sl_path_options_default(SL_PATH_DRIVE);
        po.frames = frames;
        po.speed = speeds[sp];
        po.seed = 3 + (uint64_t)sp;
        sl_path p;
        sl_status pst = sl_path_generate(s, &po, NULL, &p, &err);
        if (pst != SL_OK)
            fprintf(stderr, "%s\n", err.message);
        assert_int_equal(pst, SL_OK);
        for (uint32_t f = 0; f < po.frames; f++) {
            sl_camera cam = sl_path_camera(p, f);
            cam.width = 400, cam.height = 300;
            sl_oracle_frame fr;
            assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
            for (int k = 0; k < 3; k++) {
                assert_int_equal(sl_culler_cull(c[k], &cam, ids, n, &cnt, &err), SL_OK);
                sl_cull_metrics m;
                assert_int_equal(sl_metrics_compare(s, &fr, ids, cnt, &m, NULL, NULL, 0, &err), SL_OK);
                if (m.missed_count)
                    fprintf(stderr, "dhorizon (%s) missed %u objects at frame %u, speed %g\n", opts[k], m.missed_count,
                            f, (double)speeds[sp]);
                assert_int_equal(m.missed_count, 0);
                sl_cull_stats st;
                sl_culler_stats(c[k], &st);
                bool delta = false;
                for (uint32_t q = 0; q < st.phase_count; q++)
                    delta |= strcmp(st.phase_names[q], "sweep-delta") == 0;
                /* the delta-H rule skips nodes on delta frames only */
                if (!delta)
                    assert_int_equal(st.queries, 0);
                skipped[k] += st.queries;
                delta_frames[sp][k] += delta;
            }
            frames_checked++;
        }
        sl_path_destroy(p);
    }
    fprintf(stderr, "dhorizon fast drives: delta frames %u %u %u (slow), %u %u %u (fast) of %u each; nodes skipped %llu %llu %llu\n",
            delta_frames[0][0], delta_frames[0][1], delta_frames[0][2], delta_frames[1][0], delta_frames[1][1],
            delta_frames[1][2], frames, (unsigned long long)skipped[0], (unsigned long long)skipped[1],
            (unsigned long long)skipped[2]);
    assert_true(frames_checked > 0);
    /* without the guard every frame but the very first restarts from the frontier (the second
     * drive's first frame too: max_move = 10 km spans the city); with it the 0.5 m frames mostly
     * do and the 5 m frames (beyond max_move = 4 m) never */
    for (int k = 1; k < 3; k++) {
        assert_int_equal(delta_frames[0][k], frames - 1);
        assert_int_equal(delta_frames[1][k], frames);
    }
    assert_true(delta_frames[0][0] > frames / 2);
    assert_int_equal(delta_frames[1][0], 0);
    free(ids);
    sl_oracle_destroy(o);
    for (int k = 0; k < 3; k++)
        sl_culler_destroy(c[k]);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pseudo_azimuth),
        cmocka_unit_test(test_horizon_sound),
        cmocka_unit_test(test_horizon_no_cracks_and_wrap),
        cmocka_unit_test(test_near_and_inside),
        cmocka_unit_test(test_dhorizon_fast),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* `sightline view` without a window (tools/view_control.c, linked into this test): the --methods
 * grammar, the walk/fly controller on the tiny city and on a scene without ground, the HUD's
 * text, --size. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "view.h"
#include "sightline/gen.h"

#define DEG ((float)(M_PI / 180.0))

static bool fake_render_method(const char *name) { return !strcmp(name, "gl-only"); }

static void test_methods(void **state)
{
    (void)state;
    view_methods ms;
    sl_error err;
    assert_int_equal(view_methods_parse(NULL, NULL, &ms, &err), SL_OK);
    assert_int_equal(ms.count, 2);
    assert_string_equal(ms.m[0].name, "none");
    assert_string_equal(ms.m[1].name, "vfc");
    assert_string_equal(ms.m[1].options, "");

    assert_int_equal(view_methods_parse("vfc:coherence=off:leaf_size=2,cullmap,gl-only", fake_render_method, &ms, &err),
                     SL_OK);
    assert_int_equal(ms.count, 3);
    assert_string_equal(ms.m[0].name, "vfc");
    assert_string_equal(ms.m[0].options, "coherence=off,leaf_size=2");
    assert_string_equal(ms.m[1].name, "cullmap");
    assert_string_equal(ms.m[2].name, "gl-only");
    assert_int_equal(view_methods_add_options(&ms, "cullmap:cell=8,radius=100", &err), SL_OK);
    assert_string_equal(ms.m[1].options, "cell=8,radius=100");
    assert_int_equal(view_methods_add_options(&ms, "vfc:plane_masks=false", &err), SL_OK);
    assert_string_equal(ms.m[0].options, "coherence=off,leaf_size=2,plane_masks=false");
    assert_int_not_equal(view_methods_add_options(&ms, "hzb:x=1", &err), SL_OK);
    assert_non_null(strstr(err.message, "not among the methods"));
    assert_int_not_equal(view_methods_add_options(&ms, "vfc", &err), SL_OK);

    assert_int_not_equal(view_methods_parse("gl-only", NULL, &ms, &err), SL_OK); /* not a render method here */
    assert_int_not_equal(view_methods_parse("nosuch", NULL, &ms, &err), SL_OK);
    assert_non_null(strstr(err.message, "nosuch"));
    assert_int_not_equal(view_methods_parse("vfc,vfc", NULL, &ms, &err), SL_OK);
    assert_non_null(strstr(err.message, "twice"));
    assert_int_not_equal(view_methods_parse("vfc,,none", NULL, &ms, &err), SL_OK);
    assert_int_not_equal(view_methods_parse("vfc:", NULL, &ms, &err), SL_OK);
    assert_int_not_equal(view_methods_parse("none:x=1", NULL, &ms, &err), SL_OK);

    /* --pvs: appended, or the listed pvs gets file= */
    assert_int_equal(view_methods_parse("vfc", NULL, &ms, &err), SL_OK);
    assert_int_equal(view_methods_add_pvs(&ms, "a.slpvs", &err), SL_OK);
    assert_int_equal(ms.count, 2);
    assert_string_equal(ms.m[1].name, "pvs");
    assert_string_equal(ms.m[1].options, "file=a.slpvs");
    assert_int_equal(view_methods_parse("pvs:frustum=true,none", NULL, &ms, &err), SL_OK);
    assert_int_equal(view_methods_add_pvs(&ms, "b.slpvs", &err), SL_OK);
    assert_int_equal(ms.count, 2);
    assert_string_equal(ms.m[0].options, "frustum=true,file=b.slpvs");
    assert_int_equal(view_methods_parse("pvs:file=x", NULL, &ms, &err), SL_OK);
    assert_int_not_equal(view_methods_add_pvs(&ms, "b.slpvs", &err), SL_OK);
    assert_int_not_equal(view_methods_add_pvs(&ms, "with,comma", &err), SL_OK);
}

static sl_scene tiny_city(void)
{
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    if (sl_gen_city(&o, NULL, &s, &err) != SL_OK)
        fail_msg("sl_gen_city: %s", err.message);
    return s;
}

static sl_camera at(float x, float y, float z, float yaw_deg, float pitch_deg)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){x, y, z};
    c.yaw = yaw_deg * DEG, c.pitch = pitch_deg * DEG;
    return c;
}

static void test_walk(void **state)
{
    (void)state;
    sl_scene s = tiny_city();
    assert_true(view_scene_walkable(s));
    float g0 = sl_scene_ground_height(s, 10, 20);
    sl_camera start = at(10, 20, g0 + 1.7f, 90, 0);
    view_control c;
    view_control_init(&c, s, &start);
    assert_true(c.walk);
    assert_true(fabsf(c.eye_height - 1.7f) < 1e-4f);
    /* W for one second, looking up 30 degrees: walking moves on the ground plane at the speed */
    c.pitch = 30 * DEG;
    view_input in = {0};
    in.forward = true;
    float speed = c.speed;
    view_control_step(&c, s, &in, 0.2);
    view_control_step(&c, s, &in, 0.2);
    assert_true(fabsf(c.position.x - 10) < 1e-3f);
    assert_true(fabsf(c.position.y - (20 + 0.4f * speed)) < 1e-3f);
    assert_true(fabsf(c.position.z - (sl_scene_ground_height(s, c.position.x, c.position.y) + 1.7f)) < 1e-4f);
    /* D strafes right of yaw 90 (+Y): +X; Shift is 4x */
    in.forward = false, in.right = true, in.fast = true;
    float x0 = c.position.x;
    view_control_step(&c, s, &in, 0.1);
    assert_true(fabsf(c.position.x - (x0 + 0.4f * speed)) < 1e-3f);
    /* E raises the eye while walking, never below 0.3 m */
    in = (view_input){0};
    in.down = true;
    for (int i = 0; i < 50; i++)
        view_control_step(&c, s, &in, 0.2);
    assert_true(fabsf(c.eye_height - 0.3f) < 1e-5f);
    /* a stalled frame moves at most 0.25 s */
    in = (view_input){0};
    in.back = true;
    float y0 = c.position.y;
    view_control_step(&c, s, &in, 10.0);
    assert_true(fabsf(c.position.y - (y0 - 0.25f * speed)) < 1e-3f);
    /* fly: along the view direction */
    assert_false(view_control_toggle_walk(&c, s));
    assert_false(c.walk);
    c.pitch = 30 * DEG, c.yaw = 0;
    sl_vec3 p0 = c.position;
    in = (view_input){0};
    in.forward = true;
    view_control_step(&c, s, &in, 0.25);
    assert_true(fabsf(c.position.x - (p0.x + 0.25f * speed * cosf(30 * DEG))) < 1e-3f);
    assert_true(fabsf(c.position.z - (p0.z + 0.25f * speed * sinf(30 * DEG))) < 1e-3f);
    /* back to walking: on the ground again */
    assert_true(view_control_toggle_walk(&c, s));
    assert_true(fabsf(c.position.z - (sl_scene_ground_height(s, c.position.x, c.position.y) + 1.7f)) < 1e-4f);
    /* a camera high above flies */
    sl_camera high = at(0, 0, 200, 0, -40);
    view_control_init(&c, s, &high);
    assert_false(c.walk);
    sl_scene_destroy(s);
}

/* On a slope (terrain z = x / 10) walking climbs with the ground; flying does not. */
static void test_terrain(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    float h[4] = {0, 10, 0, 10}; /* x = 0 and x = 100 at y = 0 and y = 100 */
    sl_terrain_desc t = {2, 2, 0, 0, 100, h};
    assert_int_equal(sl_scene_set_terrain(s, &t, &err), SL_OK);
    assert_true(view_scene_walkable(s));
    sl_camera start = at(10, 50, 1 + 2, 0, 0); /* 2 m above the ground at x = 10 */
    view_control c;
    view_control_init(&c, s, &start);
    assert_true(c.walk);
    assert_true(fabsf(c.eye_height - 2) < 1e-4f);
    view_input in = {0};
    in.forward = true;
    for (int i = 0; i < 10; i++)
        view_control_step(&c, s, &in, 0.25);
    float x = c.position.x;
    assert_true(x > 15);
    assert_true(fabsf(c.position.z - (x / 10 + 2)) < 1e-3f);
    assert_false(view_control_toggle_walk(&c, s));
    float z = c.position.z;
    view_control_step(&c, s, &in, 0.25);
    assert_true(c.position.z == z); /* level flight */
    sl_scene_destroy(s);
}

static void test_look(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK); /* no ground: fly only */
    assert_false(view_scene_walkable(s));
    sl_camera start = at(0, 0, 1, 170, 0);
    view_control c;
    view_control_init(&c, s, &start);
    assert_false(c.walk);
    assert_false(view_control_toggle_walk(&c, s));
    view_input in = {0};
    in.turn_left = true; /* 90 degrees a second: 170 + 45 wraps to -145 */
    view_control_step(&c, s, &in, 0.25);
    view_control_step(&c, s, &in, 0.25);
    assert_true(fabsf(c.yaw - (-145 * DEG)) < 1e-4f);
    in = (view_input){0};
    in.look_dy = -10000; /* mouse up: pitch clamped at 89 */
    view_control_step(&c, s, &in, 0.01);
    assert_true(fabsf(c.pitch - 89 * DEG) < 1e-5f);
    in.look_dy = 0, in.look_dx = 100; /* mouse right turns right (yaw down) at 0.15 degrees a pixel */
    float yaw = c.yaw;
    view_control_step(&c, s, &in, 0.01);
    assert_true(fabsf(c.yaw - (yaw - 15 * DEG)) < 1e-4f);
    for (int i = 0; i < 40; i++)
        view_control_scale_speed(&c, 2);
    assert_true(c.speed == 5000.0f);
    for (int i = 0; i < 40; i++)
        view_control_scale_speed(&c, 0.5f);
    assert_true(c.speed == 0.05f);
    sl_camera in_cam = sl_camera_default();
    in_cam.fov_y = 1.0f, in_cam.width = 320, in_cam.height = 200;
    sl_camera cam = view_control_camera(&c, &in_cam);
    assert_true(cam.fov_y == 1.0f && cam.width == 320 && cam.yaw == c.yaw && cam.pitch == c.pitch && cam.roll == 0);
    assert_true(cam.position.x == c.position.x && cam.position.z == c.position.z);
    sl_scene_destroy(s);
}

static void test_hud(void **state)
{
    (void)state;
    view_hud h;
    memset(&h, 0, sizeof h);
    h.method = "hzb", h.guarantee = "conservative", h.method_index = 1, h.method_count = 3;
    h.frame_ms = 12.345, h.cull_ms = 0.5, h.draw_ms = 3, h.gpu_ms = -1;
    h.objects_drawn = 120, h.objects_total = 900, h.triangles_drawn = 123456, h.draw_calls = 2;
    h.cull.objects_tested = 900, h.cull.pixels_rasterized = 5000000;
    h.position = (sl_vec3){1.25f, -3, 1.7f}, h.yaw = 90 * DEG, h.speed = 2.8f, h.walk = true;
    char buf[2048];
    uint32_t lines = view_hud_text(&h, buf, sizeof buf);
    assert_int_equal(lines, 6);
    assert_non_null(strstr(buf, "method 2/3: hzb (conservative)\n"));
    assert_non_null(strstr(buf, "frame 12.35 ms  cull 0.50 ms  draw 3.00 ms\n")); /* no gpu: not shown */
    assert_non_null(strstr(buf, "objects 120/900  triangles 123.5k  draw calls 2  queries 0 (stalls 0)\n"));
    assert_non_null(strstr(buf, "culler: tested 900  pixels 5.00M\n"));
    assert_non_null(strstr(buf, "pos 1.2 -3.0 1.7  yaw 90  pitch 0  walk 2.8 m/s\n"));
    assert_null(strstr(buf, "FROZEN"));
    assert_null(strstr(buf, "REC"));
    h.frozen = true, h.recording = true, h.recorded = 42, h.gpu_ms = 1.5, h.message = "saved view-0001.png";
    h.cull.phase_count = 1, h.cull.phase_names[0] = "raster", h.cull.phase_ms[0] = 0.25;
    lines = view_hud_text(&h, buf, sizeof buf);
    assert_int_equal(lines, 9);
    assert_non_null(strstr(buf, "FROZEN"));
    assert_non_null(strstr(buf, "gpu 1.50 ms"));
    assert_non_null(strstr(buf, "phases: raster 0.25 ms\n"));
    assert_non_null(strstr(buf, "REC 42 poses\n"));
    assert_non_null(strstr(buf, "saved view-0001.png\n"));
    /* a small buffer is cut, always terminated */
    char small[16];
    memset(small, 'x', sizeof small);
    view_hud_text(&h, small, sizeof small);
    assert_int_equal(strlen(small), 15);
}

static void test_size(void **state)
{
    (void)state;
    uint32_t w = 0, h = 0;
    assert_true(view_parse_size("320x240", &w, &h));
    assert_int_equal(w, 320);
    assert_int_equal(h, 240);
    assert_true(view_parse_size("1920X1080", &w, &h));
    assert_false(view_parse_size("320", &w, &h));
    assert_false(view_parse_size("320x", &w, &h));
    assert_false(view_parse_size("x240", &w, &h));
    assert_false(view_parse_size("-320x240", &w, &h));
    assert_false(view_parse_size("320x-240", &w, &h));
    assert_false(view_parse_size("8x8", &w, &h));
    assert_false(view_parse_size("320x240x", &w, &h));
    assert_false(view_parse_size("99999x240", &w, &h));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_methods),
        cmocka_unit_test(test_walk),
        cmocka_unit_test(test_terrain),
        cmocka_unit_test(test_look),
        cmocka_unit_test(test_hud),
        cmocka_unit_test(test_size),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The command line's number-list readers, moved into the library (src/core/text_parse.c) so that
 * they are tested and fuzzed (fuzz/fuzz_options.c): --point, --volume, --eye and --camera. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "core/text_parse.h"

#include <stdint.h>

static void test_floats(void **state)
{
    (void)state;
    float v[6] = {0};
    assert_true(sl_parse_floats("1.5,-2,3e2", v, 3));
    assert_true(v[0] == 1.5f && v[1] == -2.0f && v[2] == 300.0f);
    assert_true(sl_parse_floats("-1,-2,-3,4,5.5,6e1", v, 6));
    assert_true(v[5] == 60.0f);
    assert_true(sl_parse_floats("1e-50,0,0", v, 3)); /* underflow reads as zero */
    assert_true(v[0] == 0.0f);
    float keep[3] = {7, 8, 9};
    const char *bad[] = {"",        "1,2",      "1,2,3,4", "1,,3",     "1,2,3,",  ",1,2,3", "1,2,x",
                         "nan,0,0", "inf,0,0",  "0,-inf,0", "3e39,0,0", " 1,2,3", "1,2, 3", "1,2,3 ",
                         "1;2;3",   "1,2,3\n", "0x,1,2",  "\v1,2,3", "1,\r2,3"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        if (sl_parse_floats(bad[i], keep, 3))
            fail_msg("'%s' was accepted", bad[i]);
        assert_true(keep[0] == 7 && keep[1] == 8 && keep[2] == 9);
    }
    assert_false(sl_parse_floats(NULL, v, 3));
    assert_false(sl_parse_floats("1", v, 0));
    assert_false(sl_parse_floats("1", v, 17));
}

static void test_camera(void **state)
{
    (void)state;
    sl_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.fov_y = 1.0f;
    assert_true(sl_parse_camera_spec("0,0,1.7,90,-45,0", &cam));
    assert_true(cam.position.z == 1.7f);
    assert_true(fabsf(cam.yaw - (float)(M_PI / 2)) < 1e-6f && fabsf(cam.pitch + (float)(M_PI / 4)) < 1e-6f);
    assert_true(cam.fov_y == 1.0f); /* untouched without a seventh number */
    assert_true(sl_parse_camera_spec("1,2,3,0,0,0,60", &cam));
    assert_true(fabsf(cam.fov_y - (float)(M_PI / 3)) < 1e-6f);
    sl_camera before = cam;
    /* a double that is finite but not as a float (the old --camera reader let it become inf) */
    const char *bad[] = {"1e300,0,0,0,0,0", "0,0,0,0,0,0,1e40", "0,0,0,0,0", "0,0,0,0,0,0,0,0", "0,0,0,nan,0,0",
                         "0,0,0,0,0,0,",   "",                 "a,b,c,d,e,f"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        if (sl_parse_camera_spec(bad[i], &cam))
            fail_msg("'%s' was accepted", bad[i]);
        assert_memory_equal(&cam, &before, sizeof cam);
    }
}

/* The one --frames reader of `bench` and `render` (the two copies it replaced differed on a first
 * frame of UINT32_MAX: bench took "4294967295" as frame 2^32-1 alone, whose end wraps to 0; render
 * refused it). */
static void test_range(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        uint32_t first, end;
    } good[] = {
        {"0:10", 0, 10},           {"3:4", 3, 4},           {"5", 5, 6},
        {"7:", 7, UINT32_MAX},     {":9", 0, 9},            {":", 0, UINT32_MAX},
        {"0", 0, 1},               {"007:010", 7, 10},      {"4294967294", 4294967294u, UINT32_MAX},
        {"0:4294967295", 0, UINT32_MAX}, {"4294967294:4294967295", 4294967294u, UINT32_MAX},
    };
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        uint32_t f = 123, e = 456;
        if (!sl_parse_range(good[i].text, &f, &e))
            fail_msg("'%s' was refused", good[i].text);
        if (f != good[i].first || e != good[i].end)
            fail_msg("'%s' read as %u:%u, not %u:%u", good[i].text, f, e, good[i].first, good[i].end);
    }
    static const char *const bad[] = {
        "",       "a",          "1:a",         "5:5",         "6:5",          "-1",          "1:-2",
        "+1",     " 1",         "1 ",          "1: 2",        "1:2:3",        "1::",         "0x10",
        "4294967295", "4294967295:", "4294967296", "0:4294967296", "99999999999999999999", "1.5", ":0",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        uint32_t f = 123, e = 456;
        if (sl_parse_range(bad[i], &f, &e))
            fail_msg("'%s' was accepted as %u:%u", bad[i], f, e);
        assert_int_equal(f, 123);
        assert_int_equal(e, 456);
    }
    uint32_t f, e;
    assert_false(sl_parse_range(NULL, &f, &e));
}


static void test_suggest(void **state)
{
    (void)state;
    assert_int_equal(sl_text_distance("method", "methods"), 1);
    assert_int_equal(sl_text_distance("hbz", "hzb"), 1); /* a swap of neighbours */
    assert_int_equal(sl_text_distance("HZB", "hzb"), 0);
    assert_int_equal(sl_text_distance("", "abc"), 3);
    assert_int_equal(sl_text_distance("kitten", "sitting"), 3);
    assert_int_equal(sl_text_distance(NULL, "ab"), 2);
    const char *opts[] = {"methods", "method-options", "walk", "views", NULL, "frames", "fps"};
    char out[128];
    assert_int_equal(sl_text_suggest("method", opts, 7, out, sizeof out), 2);
    assert_string_equal(out, "methods or method-options"); /* nearer first, the prefix after */
    assert_int_equal(sl_text_suggest("wlak", opts, 7, out, sizeof out), 1);
    assert_string_equal(out, "walk");
    assert_int_equal(sl_text_suggest("zzzzzz", opts, 7, out, sizeof out), 0);
    assert_string_equal(out, "");
    assert_int_equal(sl_text_suggest("walk", opts, 7, out, sizeof out), 0); /* itself: nothing to suggest */
    const char *maps[] = {"oasago1", "oasago2", "oa_dm1", "oa_dm2", "oa_dm3", "oa_dm4"};
    assert_int_equal(sl_text_suggest("oasag", maps, 6, out, sizeof out), 2);
    assert_string_equal(out, "oasago1 or oasago2");
    assert_int_equal(sl_text_suggest("oa_dm", maps, 6, out, sizeof out), 3); /* at most three */
    assert_string_equal(out, "oa_dm1, oa_dm2 or oa_dm3");
    char small[8];
    sl_text_suggest("method", opts, 7, small, sizeof small); /* truncated, still terminated */
    assert_true(strlen(small) < sizeof small);
    char long_word[200];
    memset(long_word, 'a', sizeof long_word - 1);
    long_word[sizeof long_word - 1] = 0;
    assert_int_equal(sl_text_distance(long_word, "a"), 198);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_floats), cmocka_unit_test(test_camera),
                                       cmocka_unit_test(test_range), cmocka_unit_test(test_suggest)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}

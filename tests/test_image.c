/* PNG writing/reading round trip, atomic output, colour helpers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/image.h"

static void test_png_round_trip(void **state)
{
    (void)state;
    char dir[] = "/tmp/sl_img_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/a.png", dir);
    uint8_t rgb[5 * 3 * 3];
    for (size_t i = 0; i < sizeof rgb; i++)
        rgb[i] = (uint8_t)(i * 7);
    sl_error err;
    assert_int_equal(sl_png_write(path, 5, 3, 3, rgb, 0, &err), SL_OK);
    uint8_t *px;
    uint32_t w, h;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &h, &err), SL_OK);
    assert_int_equal(w, 5);
    assert_int_equal(h, 3);
    for (uint32_t i = 0; i < 15; i++) {
        assert_int_equal(px[4 * i], rgb[3 * i]);
        assert_int_equal(px[4 * i + 2], rgb[3 * i + 2]);
        assert_int_equal(px[4 * i + 3], 255);
    }
    sl_free(NULL, px, (size_t)w * h * 4);
    /* grey with a stride wider than the row */
    uint8_t grey[4 * 8] = {0};
    grey[8] = 200;
    assert_int_equal(sl_png_write(path, 4, 4, 1, grey, 8, &err), SL_OK);
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &h, &err), SL_OK);
    assert_int_equal(px[4 * 4], 200);
    sl_free(NULL, px, (size_t)w * h * 4);
    /* bad arguments and unreadable input */
    assert_int_equal(sl_png_write(path, 0, 4, 1, grey, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_png_write(path, 4, 4, 2, grey, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    char junk[256];
    snprintf(junk, sizeof junk, "%s/junk.png", dir);
    FILE *f = fopen(junk, "wb");
    fputs("not a png at all", f);
    fclose(f);
    assert_int_equal(sl_png_read_rgba(junk, NULL, &px, &w, &h, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "junk.png"));
    unlink(junk);
    unlink(path);
    rmdir(dir);
}

static void test_colors(void **state)
{
    (void)state;
    /* neighbouring ids get clearly different colours */
    for (uint32_t i = 0; i < 1000; i++) {
        uint32_t a = sl_id_color(i), b = sl_id_color(i + 1);
        int dr = (int)(a >> 16) - (int)(b >> 16), dg = (int)((a >> 8) & 255) - (int)((b >> 8) & 255),
            db = (int)(a & 255) - (int)(b & 255);
        assert_true(dr * dr + dg * dg + db * db > 40 * 40);
    }
    assert_int_equal(sl_ramp_color(-1), sl_ramp_color(0));
    assert_int_equal(sl_ramp_color(2), sl_ramp_color(1));
    assert_int_not_equal(sl_ramp_color(0), sl_ramp_color(1));
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_png_round_trip), cmocka_unit_test(test_colors)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The cull-map rasterizer's floor/ceil helpers (sl_cullmap_ffloor, sl_cullmap_fceil): equal to libm's
 * floor/ceil on every double, including infinities, NaN and values beyond the int64 range, which the
 * rasterizer meets as the bounds of unbounded shadow rows (converting those to int64_t was undefined
 * behaviour, caught by clang's -fsanitize=float-cast-overflow). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "raster/cullmap_raster.h"

/* the same value (a zero of either sign matches a zero); NaN gives NaN */
static void check_one(double x)
{
    double f = sl_cullmap_ffloor(x), c = sl_cullmap_fceil(x);
    if (isnan(x)) {
        assert_true(isnan(f));
        assert_true(isnan(c));
        return;
    }
    if (f != floor(x) || c != ceil(x))
        fail_msg("x = %.17g: ffloor %.17g (floor %.17g), fceil %.17g (ceil %.17g)", x, f, floor(x), c, ceil(x));
}

static void test_special_values(void **state)
{
    (void)state;
    const double v[] = {INFINITY, -INFINITY, NAN, -NAN, 0x1p52, -0x1p52, 0x1p52 + 1, -0x1p52 - 1, 0x1p53,
                        0x1p63, -0x1p63, 0x1p64, -0x1p64, 1e300, -1e300, DBL_MAX, -DBL_MAX, 0x1p52 - 0.5,
                        -0x1p52 + 0.5, 0x1p52 - 1, -0x1p52 + 1, 0.0, 1.0, -1.0, 0.5, -0.5, 1.5, -1.5,
                        DBL_MIN, -DBL_MIN, 0x1p-1074, -0x1p-1074, 2147483647.5, -2147483648.5};
    for (size_t k = 0; k < sizeof v / sizeof v[0]; k++)
        check_one(v[k]);
}

/* values spread over many magnitudes (a fixed xorshift sequence of bit patterns) */
static void test_spread(void **state)
{
    (void)state;
    uint64_t r = 0x9e3779b97f4a7c15ull;
    for (int k = 0; k < 200000; k++) {
        r ^= r << 13, r ^= r >> 7, r ^= r << 17;
        /* exponent limited to [-64, 70] around 1 so that most values are near the 2^52 edge or below */
        uint64_t bits = (r & 0x800fffffffffffffull) | ((uint64_t)(1023 - 64 + (r >> 52) % 135) << 52);
        double x;
        memcpy(&x, &bits, sizeof x);
        check_one(x);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_special_values),
        cmocka_unit_test(test_spread),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The cells near a camera path (tools/cells_along.c, `pvs build --along` and `pvs update --along`):
 * the grid of cameras must keep exactly the cells a brute-force test of every cell against every
 * camera keeps, in the same order, and count the same cameras that no cell comes near.
 * - random box cells and paths of several sizes, radii 0 to 5 m;
 * - cameras exactly on the radius (a cell's face plus r on one axis), which an index off by one
 *   square would lose;
 * - a path with all cameras at one point (a grid of zero extent), and cameras far above the cells;
 * - no cell near any camera, and a path without cameras: SL_ERROR_INVALID_ARGUMENT and no output;
 * - without the camera count (far_cameras NULL, which stops at a cell's first camera): the same cells. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sightline/path.h"
#include "sightline/region.h"

#include "../tools/cells_along.c"
#include "../tools/tool.c"

static uint64_t g_rng = 0x9e3779b97f4a7c15ull;

static double uniform(double lo, double hi)
{
    g_rng ^= g_rng << 13, g_rng ^= g_rng >> 7, g_rng ^= g_rng << 17;
    return lo + (hi - lo) * (double)(g_rng >> 11) / 9007199254740992.0;
}

static sl_viewcells random_cells(uint32_t n, double extent)
{
    sl_viewcell *c = calloc(n, sizeof *c);
    assert_non_null(c);
    for (uint32_t i = 0; i < n; i++) {
        float x = (float)uniform(-extent, extent), y = (float)uniform(-extent, extent);
        float w = (float)uniform(0.5, 25), d = (float)uniform(0.5, 25);
        c[i].shape = SL_CELL_BOX;
        c[i].cluster = -1;
        c[i].z_min = 1.0f, c[i].z_max = 2.0f;
        c[i].bounds = (sl_aabb){{x, y, 1.0f}, {x + w, y + d, 2.0f}};
    }
    sl_viewcells out = NULL;
    sl_error err;
    if (sl_viewcells_create(c, n, NULL, &out, &err) != SL_OK)
        fail_msg("%s", err.message);
    free(c);
    return out;
}

static sl_path make_path(const sl_vec3 *at, uint32_t n)
{
    sl_path p = NULL;
    sl_error err;
    assert_int_equal(sl_path_create(NULL, NULL, &p, &err), SL_OK);
    for (uint32_t i = 0; i < n; i++) {
        sl_pose pose = {0};
        pose.position = at[i];
        pose.time = (float)i / 30.0f;
        assert_int_equal(sl_path_append(p, &pose, &err), SL_OK);
    }
    return p;
}

/* The reference: every cell against every camera. */
static uint32_t brute(sl_viewcells cells, const sl_vec3 *at, uint32_t np, float radius, uint32_t *kept,
                      uint32_t *far)
{
    const sl_viewcell *vc = sl_viewcells_data(cells);
    uint32_t n = 0;
    uint8_t *near = calloc(np + 1, 1);
    assert_non_null(near);
    for (uint32_t c = 0; c < sl_viewcells_count(cells); c++) {
        bool keep = false;
        for (uint32_t i = 0; i < np; i++) {
            sl_aabb eye = {at[i], at[i]};
            if (cli_box_gap(&vc[c].bounds, &eye) <= radius)
                keep = true, near[i] = 1;
        }
        if (keep)
            kept[n++] = c;
    }
    *far = 0;
    for (uint32_t i = 0; i < np; i++)
        *far += !near[i];
    free(near);
    return n;
}

static void check(sl_viewcells cells, const sl_vec3 *at, uint32_t np, float radius)
{
    uint32_t nc = sl_viewcells_count(cells), far_ref = 0, far = 12345;
    uint32_t *kept = malloc((nc + 1) * sizeof *kept);
    assert_non_null(kept);
    uint32_t n = brute(cells, at, np, radius, kept, &far_ref);
    sl_path path = make_path(at, np);
    sl_viewcells out = NULL;
    sl_error err;
    sl_status st = cli_viewcells_along(cells, path, radius, &out, &far, &err);
    if (n == 0) {
        assert_int_equal(st, SL_ERROR_INVALID_ARGUMENT);
        assert_null(out);
    } else {
        assert_int_equal(st, SL_OK);
        assert_int_equal(sl_viewcells_count(out), n);
        for (uint32_t k = 0; k < n; k++)
            assert_memory_equal(&sl_viewcells_data(out)[k].bounds, &sl_viewcells_data(cells)[kept[k]].bounds,
                                sizeof(sl_aabb));
        assert_int_equal(far, far_ref);
    }
    sl_viewcells_destroy(out);
    /* without the count (the demo's and the bench's call) the same cells */
    out = NULL;
    st = cli_viewcells_along(cells, path, radius, &out, NULL, &err);
    assert_int_equal(st, n ? SL_OK : SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(out ? sl_viewcells_count(out) : 0, n);
    for (uint32_t k = 0; k < n; k++)
        assert_memory_equal(&sl_viewcells_data(out)[k].bounds, &sl_viewcells_data(cells)[kept[k]].bounds,
                            sizeof(sl_aabb));
    sl_viewcells_destroy(out);
    sl_path_destroy(path);
    free(kept);
}

static void test_random(void **state)
{
    (void)state;
    static const uint32_t cell_counts[] = {1, 7, 300, 2000};
    static const uint32_t cameras[] = {1, 2, 50, 3000};
    static const float radii[] = {0.0f, 0.5f, 2.0f, 5.0f};
    for (int a = 0; a < 4; a++)
        for (int b = 0; b < 4; b++) {
            double extent = 30.0 + 400.0 * a;
            sl_viewcells cells = random_cells(cell_counts[a], extent);
            sl_vec3 *at = malloc(cameras[b] * sizeof *at);
            assert_non_null(at);
            /* a walk: steps of up to 2 m, some cameras lifted far above the cells */
            sl_vec3 p = {(float)uniform(-extent, extent), (float)uniform(-extent, extent), 1.7f};
            for (uint32_t i = 0; i < cameras[b]; i++) {
                p.x += (float)uniform(-2, 2), p.y += (float)uniform(-2, 2);
                at[i] = p;
                if (uniform(0, 1) < 0.1)
                    at[i].z = 60.0f;
            }
            for (int r = 0; r < 4; r++)
                check(cells, at, cameras[b], radii[r]);
            free(at);
            sl_viewcells_destroy(cells);
        }
}

/* Cameras exactly r beyond a cell's face on x and on y (both sides), and one just beyond. */
static void test_on_the_radius(void **state)
{
    (void)state;
    sl_viewcells cells = random_cells(200, 500);
    const sl_viewcell *vc = sl_viewcells_data(cells);
    const float r = 2.0f;
    sl_vec3 at[5 * 200];
    uint32_t n = 0;
    for (uint32_t c = 0; c < 200; c++) {
        const sl_aabb *b = &vc[c].bounds;
        float cy = 0.5f * (b->min.y + b->max.y), cx = 0.5f * (b->min.x + b->max.x);
        at[n++] = (sl_vec3){b->max.x + r, cy, 1.5f};
        at[n++] = (sl_vec3){b->min.x - r, cy, 1.5f};
        at[n++] = (sl_vec3){cx, b->max.y + r, 1.5f};
        at[n++] = (sl_vec3){cx, b->min.y - r, 1.5f};
        at[n++] = (sl_vec3){nextafterf(b->max.x + r, INFINITY), cy, 1.5f};
    }
    check(cells, at, n, r);
    sl_viewcells_destroy(cells);
}

static void test_degenerate_paths(void **state)
{
    (void)state;
    sl_viewcells cells = random_cells(100, 50);
    const sl_aabb *b = &sl_viewcells_data(cells)[0].bounds;
    sl_vec3 same[40];
    for (int i = 0; i < 40; i++) /* one point: a grid of zero extent */
        same[i] = (sl_vec3){b->min.x, b->min.y, 1.5f};
    check(cells, same, 40, 2.0f);
    sl_vec3 high[10];
    for (int i = 0; i < 10; i++) /* far above every cell: none kept */
        high[i] = (sl_vec3){b->min.x + (float)i, b->min.y, 500.0f};
    check(cells, high, 10, 2.0f);
    sl_vec3 mixed[3] = {{b->min.x, b->min.y, 1.5f}, {b->min.x, b->min.y, 500.0f}, {1e6f, -1e6f, 1.5f}};
    check(cells, mixed, 3, 2.0f);
    /* a path without cameras: refused, with what is wrong */
    sl_path empty = make_path(NULL, 0);
    sl_viewcells out = NULL;
    sl_error err;
    uint32_t far = 7;
    assert_int_equal(cli_viewcells_along(cells, empty, 2.0f, &out, &far, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(out);
    assert_non_null(strstr(err.message, "no cameras"));
    sl_path_destroy(empty);
    sl_viewcells_destroy(cells);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random),
        cmocka_unit_test(test_on_the_radius),
        cmocka_unit_test(test_degenerate_paths),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* Radar echo generation: every triangle with a point in line of sight of the transmitter (exact
 * check over the triangulated terrain) must be reported, over 360 degrees and in sectors, for
 * several grid sizes and transmitters; the terrain generator; bad input; the echo image. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/image.h"
#include "sightline/radar.h"
#include "support/counting_alloc.h"

static sl_terrain_desc small_terrain(uint32_t nx, uint32_t ny, uint64_t seed, float relief)
{
    sl_radar_terrain_options o = sl_radar_terrain_defaults();
    o.nx = nx, o.ny = ny, o.cell = 10, o.relief = relief, o.seed = seed;
    sl_terrain_desc t;
    sl_error err;
    assert_int_equal(sl_radar_terrain_generate(&o, NULL, &t, &err), SL_OK);
    return t;
}

/* Points of triangle t, a little inside it. */
static void sample_points(const sl_terrain_desc *td, uint64_t t, sl_vec3 p[7])
{
    uint64_t q = t >> 1;
    uint32_t i = (uint32_t)(q % (td->nx - 1)), j = (uint32_t)(q / (td->nx - 1));
    uint32_t ci[3], cj[3];
    if (!(t & 1))
        ci[0] = i, cj[0] = j, ci[1] = i + 1, cj[1] = j, ci[2] = i + 1, cj[2] = j + 1;
    else
        ci[0] = i, cj[0] = j, ci[1] = i + 1, cj[1] = j + 1, ci[2] = i, cj[2] = j + 1;
    double v[3][3];
    for (int k = 0; k < 3; k++) {
        v[k][0] = td->origin_x + ci[k] * (double)td->cell;
        v[k][1] = td->origin_y + cj[k] * (double)td->cell;
        v[k][2] = td->heights[(size_t)cj[k] * td->nx + ci[k]];
    }
    static const double bary[7][3] = {{0.98, 0.01, 0.01}, {0.01, 0.98, 0.01}, {0.01, 0.01, 0.98}, {1 / 3., 1 / 3., 1 / 3.},
                                      {0.49, 0.49, 0.02},  {0.02, 0.49, 0.49}, {0.49, 0.02, 0.49}};
    for (int s = 0; s < 7; s++) {
        double x = 0, y = 0, z = 0;
        for (int k = 0; k < 3; k++) {
            x += bary[s][k] * v[k][0];
            y += bary[s][k] * v[k][1];
            z += bary[s][k] * v[k][2];
        }
        p[s] = (sl_vec3){(float)x, (float)y, (float)z};
    }
}

/* Check one sweep against the exact line of sight; returns the triangles seen by some sample. */
static uint64_t check_sweep(sl_radar r, const sl_terrain_desc *td, const sl_radar_sweep *sw, uint64_t *reported)
{
    sl_error err;
    sl_radar_stats st;
    assert_int_equal(sl_radar_run(r, sw, &st, &err), SL_OK);
    uint64_t n = sl_radar_triangle_count(r), seen = 0, rep = 0;
    double a0 = sw->azimuth, w = sw->width;
    for (uint64_t t = 0; t < n; t++) {
        rep += sl_radar_visible(r, t);
        sl_vec3 p[7];
        sample_points(td, t, p);
        bool any = false;
        for (int s = 0; s < 7 && !any; s++) {
            double dx = p[s].x - sw->transmitter.x, dy = p[s].y - sw->transmitter.y;
            if (hypot(dx, dy) > sw->range)
                continue;
            if (w < 6.283) {
                double az = fmod(atan2(dy, dx) - a0, 2 * M_PI);
                if (az < 0)
                    az += 2 * M_PI;
                if (az > w)
                    continue;
            }
            any = sl_radar_line_of_sight(r, sw->transmitter, p[s], 1e-6);
        }
        if (any) {
            seen++;
            if (!sl_radar_visible(r, t)) {
                fprintf(stderr, "triangle %llu is in line of sight but was not reported\n", (unsigned long long)t);
                fail();
            }
        }
    }
    assert_int_equal(rep, st.triangles_visible);
    if (reported)
        *reported = rep;
    return seen;
}

static void test_conservative_sweeps(void **state)
{
    (void)state;
    bool san = getenv("SL_SANITIZED") != NULL;
    sl_rng rng;
    sl_rng_seed(&rng, 5, 1);
    const uint32_t grids[] = {4, 16, 40};
    uint64_t total_seen = 0, total_rep = 0;
    for (int trial = 0; trial < (san ? 3 : 6); trial++) {
        sl_terrain_desc td = small_terrain(61 + trial, 53, 100 + (uint64_t)trial, 120 + 40 * trial);
        sl_radar_options o = sl_radar_default_options();
        o.grid = grids[trial % 3];
        o.bins = trial % 2 ? 4096 : 16384;
        sl_radar r;
        sl_error err;
        assert_int_equal(sl_radar_create(&td, &o, &r, &err), SL_OK);
        float x = sl_rng_range(&rng, 50, 550), y = sl_rng_range(&rng, 50, 470);
        sl_radar_sweep sw = {{x, y, sl_radar_height(r, x, y) + sl_rng_range(&rng, 2, 40)}, 0, 6.2832f, INFINITY};
        uint64_t rep;
        uint64_t seen = check_sweep(r, &td, &sw, &rep);
        assert_true(seen > 0);
        total_seen += seen, total_rep += rep;
        /* sectors, including one across azimuth 0, and a limited range */
        sw.azimuth = sl_rng_range(&rng, -3, 3);
        sw.width = 1.0472f; /* 60 degrees */
        check_sweep(r, &td, &sw, NULL);
        sw.azimuth = -0.3f;
        sw.width = 0.6f;
        sw.range = 250;
        check_sweep(r, &td, &sw, NULL);
        sl_radar_destroy(r);
        sl_radar_terrain_free(&td, NULL);
    }
    /* and not everything: the sweep culls (reported within a small factor of the truth) */
    assert_true(total_rep < 3 * total_seen);
}

static void test_flat_and_wall(void **state)
{
    (void)state;
    /* a flat plain with a ridge across it: everything in front visible, the far side behind the
     * ridge hidden near its foot */
    enum { N = 41 };
    float h[N * N];
    for (int j = 0; j < N; j++)
        for (int i = 0; i < N; i++)
            h[j * N + i] = (i == 20) ? 50.0f : 0.0f;
    sl_terrain_desc td = {N, N, 0, 0, 10, h};
    sl_test_counter ctr = {0};
    sl_allocator a = sl_test_counting_allocator(&ctr);
    sl_radar_options o = sl_radar_default_options();
    o.grid = 8;
    o.alloc = &a;
    sl_radar r;
    sl_error err;
    assert_int_equal(sl_radar_create(&td, &o, &r, &err), SL_OK);
    sl_radar_sweep sw = {{50, 200, 5}, 0, 6.2832f, INFINITY};
    assert_int_equal(sl_radar_run(r, &sw, NULL, &err), SL_OK);
    /* the quad at (10, 20) in front of the ridge is visible; at (22, 20), right behind it, hidden */
    uint64_t front = 2ull * (20 * (N - 1) + 10), behind = 2ull * (20 * (N - 1) + 22);
    assert_true(sl_radar_visible(r, front) || sl_radar_visible(r, front + 1));
    assert_false(sl_radar_visible(r, behind));
    assert_false(sl_radar_visible(r, behind + 1));
    assert_true(sl_radar_line_of_sight(r, sw.transmitter, (sl_vec3){105, 200, 0}, 1e-6));
    assert_false(sl_radar_line_of_sight(r, sw.transmitter, (sl_vec3){225, 200, 0}, 1e-6));
    check_sweep(r, &td, &sw, NULL);
    /* the echo image */
    char path[512];
    snprintf(path, sizeof path, "%s/test_radar_%ld.png", SL_BINARY_DIR, (long)getpid());
    assert_int_equal(sl_radar_echo_png(r, &sw, path, 200, 200, &err), SL_OK);
    uint8_t *px;
    uint32_t w, hh;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &hh, &err), SL_OK);
    assert_int_equal(w, 200);
    /* a visible pixel (green) in front of the ridge, a dark one behind it */
    const uint8_t *p = px + 4 * ((size_t)100 * w + 40), *q = px + 4 * ((size_t)100 * w + 120);
    assert_true(p[1] > 60 && p[1] > p[0]);
    assert_true(q[1] < 60);
    sl_free(NULL, px, (size_t)w * hh * 4);
    unlink(path);
    sl_radar_destroy(r);
    assert_int_equal(ctr.live, 0);
}

static void test_bad_input(void **state)
{
    (void)state;
    sl_error err;
    sl_radar r;
    float h[9] = {0, 0, 0, 0, NAN, 0, 0, 0, 0};
    sl_terrain_desc td = {3, 3, 0, 0, 1, h};
    assert_int_equal(sl_radar_create(&td, NULL, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "height"));
    h[4] = 0;
    td.cell = 0;
    assert_int_equal(sl_radar_create(&td, NULL, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    td.cell = 1;
    td.nx = 1;
    assert_int_equal(sl_radar_create(&td, NULL, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    td.nx = 3;
    sl_radar_options o = sl_radar_default_options();
    o.grid = 1;
    assert_int_equal(sl_radar_create(&td, &o, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    o.grid = 10;
    o.bins = 5;
    assert_int_equal(sl_radar_create(&td, &o, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_radar_create(&td, NULL, &r, &err), SL_OK);
    sl_radar_sweep sw = {{1, 1, -1}, 0, 6.2832f, INFINITY}; /* below the ground */
    assert_int_equal(sl_radar_run(r, &sw, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sw.transmitter.z = 2;
    sw.width = 0;
    assert_int_equal(sl_radar_run(r, &sw, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sw.width = 1;
    sw.range = NAN;
    assert_int_equal(sl_radar_run(r, &sw, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sw.range = INFINITY;
    assert_int_equal(sl_radar_run(r, &sw, NULL, &err), SL_OK);
    assert_int_equal(sl_radar_echo_png(r, &sw, "/nonexistent-dir/echo.png", 10, 10, &err) != SL_OK, true);
    assert_int_equal(sl_radar_echo_png(r, &sw, "x.png", 0, 10, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_radar_destroy(r);
    sl_radar_terrain_options to = sl_radar_terrain_defaults();
    /* the default generated terrain is the thesis' size: at least 4M triangles */
    assert_true(2ull * (to.nx - 1) * (to.ny - 1) >= 4000000ull);
    to.nx = 1;
    sl_terrain_desc g;
    assert_int_equal(sl_radar_terrain_generate(&to, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
}

/* Run a shell command; its exit status. */
static int run(const char *fmt, ...)
{
    char cmd[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_cli(void **state)
{
    (void)state;
    const char *sl = getenv("SL_SIGHTLINE");
    if (!sl || access(sl, X_OK) != 0) {
        skip();
        return;
    }
    char dir[] = "/tmp/sl_test_radar_XXXXXX";
    assert_non_null(mkdtemp(dir));
    assert_int_equal(run("%s radar --help > /dev/null", sl), 0);
    assert_int_equal(run("%s radar --bogus 2> /dev/null", sl), 2);
    assert_int_equal(run("%s radar -q 2> /dev/null", sl), 2);
    assert_int_equal(run("%s radar --width 0 2> /dev/null", sl), 2);
    assert_int_equal(run("%s radar --samples 5y5 2> /dev/null", sl), 2);
    assert_int_equal(run("%s radar %s/missing.slscene 2> /dev/null", sl, dir), 1);
    assert_int_equal(run("%s radar --samples 101x91 --cell 20 --tx 999999,1 2> /dev/null", sl), 2);
    assert_int_equal(run("%s radar --samples 101x91 --cell 20 --grid 1 2> /dev/null", sl), 1);
    /* a sweep with its image and an exact check, as JSON */
    assert_int_equal(run("%s radar --samples 101x91 --cell 20 --relief 300 --mast 20 --verify 300 --size 200x180 "
                         "-o %s/echo.png --json > %s/out.json",
                         sl, dir, dir),
                     0);
    char path[600];
    snprintf(path, sizeof path, "%s/echo.png", dir);
    uint8_t *px;
    uint32_t w, h;
    sl_error err;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &h, &err), SL_OK);
    assert_int_equal(w, 200);
    assert_int_equal(h, 180);
    sl_free(NULL, px, (size_t)w * h * 4);
    snprintf(path, sizeof path, "%s/out.json", dir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char buf[4096] = {0};
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    assert_true(n > 0);
    assert_non_null(strstr(buf, "\"triangles_visible\""));
    assert_non_null(strstr(buf, "\"missed\":0"));
    /* the timing table for the thesis' grid sizes */
    assert_int_equal(run("%s radar --samples 61x61 --cell 20 --table --runs 1 > %s/table.txt", sl, dir), 0);
    assert_int_equal(run("grep -q '400 x 400' %s/table.txt", dir), 0);
    run("rm -rf %s", dir);
}

static void test_generator(void **state)
{
    (void)state;
    sl_terrain_desc a = small_terrain(80, 70, 9, 300), b = small_terrain(80, 70, 9, 300), c = small_terrain(80, 70, 10, 300);
    assert_memory_equal(a.heights, b.heights, 80 * 70 * sizeof(float));
    float lo = INFINITY, hi = -INFINITY;
    bool differs = false;
    for (int k = 0; k < 80 * 70; k++) {
        lo = fminf(lo, a.heights[k]);
        hi = fmaxf(hi, a.heights[k]);
        differs |= a.heights[k] != c.heights[k];
    }
    assert_true(differs);
    assert_true(fabsf(lo) < 1e-3f && fabsf(hi - 300) < 1e-2f);
    sl_radar_terrain_free(&a, NULL);
    sl_radar_terrain_free(&b, NULL);
    sl_radar_terrain_free(&c, NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_conservative_sweeps),
        cmocka_unit_test(test_flat_and_wall),
        cmocka_unit_test(test_bad_input),
        cmocka_unit_test(test_generator),
        cmocka_unit_test(test_cli),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

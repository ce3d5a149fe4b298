/* `sightline view` end to end (the binary in $SL_SIGHTLINE): usage errors and bad files before any
 * window; without a display it says so and exits 1, and so it does when the driver gives less than
 * OpenGL 4.5 (Mesa capped by MESA_GL_VERSION_OVERRIDE); under Xvfb (xvfb-run -a) a few frames of the
 * tiny city along a short path, with a screenshot that is not blank (many colours, the HUD's white
 * text in the top rows, which a run with --no-hud lacks, the rest of the frame identical), freezing
 * (the frozen frustum's colour appears) and the top-down map; a recorded path round-trips (the
 * poses followed, bit for bit; re-recording it gives the same bytes).
 * Skips (77) when the command was built without the viewer or xvfb-run is not installed, saying
 * which. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sightline/image.h"
#include "sightline/path.h"

static const char *sl_bin;
static char dir[256];
static const char xvfb[] = ""; /* the test runs inside xvfb-run (main): DISPLAY is Xvfb's */
static char child_env[1024];  /* "env ..." before the command under a sanitizer (main) */

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return strdup("");
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    return strdup(buf);
}

/* Run "PREFIX SIGHTLINE view ARGS" through the shell, stdout and stderr in dir/out, dir/err; the
 * exit status. */
static int run_view(const char *prefix, const char *args)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "cd '%s' && timeout 120 %s %s '%s' view %s >out 2>err", dir, prefix, child_env, sl_bin,
             args);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

static void expect_view(int want, const char *prefix, const char *args, const char *in_err)
{
    int rc = run_view(prefix, args);
    char p[300];
    snprintf(p, sizeof p, "%s/err", dir);
    char *err = slurp(p);
    if (rc != want || (in_err && !strstr(err, in_err)))
        fail_msg("view %s: exit %d (expected %d), stderr: %s (expected '%s' in it)", args, rc, want, err,
                 in_err ? in_err : "");
    free(err);
}

static const char path_text[] =
    "# sightline-path 1\n"
    "camera fov=60 near=0.1 far=5000 width=320 height=240 projection=perspective ortho_height=100\n"
    "0 -60 -20 1.7 20 0 0\n"
    "0.0333333351 -59.9 -19.95 1.7 20.5 0 0\n"
    "0.0666666701 -59.8 -19.9 1.7 21 1 0\n"
    "0.100000001 -80 -50 30 40 -20 0\n";

static void write_file(const char *name, const char *text)
{
    char p[300];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

typedef struct image {
    uint8_t *px;
    uint32_t w, h;
} image;

static image load(const char *name)
{
    char p[300];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    image im = {0};
    sl_error err;
    if (sl_png_read_rgba(p, NULL, &im.px, &im.w, &im.h, &err) != SL_OK)
        fail_msg("%s: %s", name, err.message);
    return im;
}

static void image_free(image *im)
{
    sl_default_allocator()->free(sl_default_allocator()->user, im->px, (size_t)im->w * im->h * 4);
}

static uint32_t rgb(const image *im, uint32_t x, uint32_t y)
{
    const uint8_t *p = im->px + ((size_t)y * im->w + x) * 4;
    return (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
}

static uint32_t distinct_colours(const image *im)
{
    /* a small open-addressing set of RGB values */
    static uint32_t set[1 << 16];
    memset(set, 0xff, sizeof set);
    uint32_t n = 0;
    for (uint32_t y = 0; y < im->h; y++)
        for (uint32_t x = 0; x < im->w; x++) {
            uint32_t c = rgb(im, x, y), h = (c * 2654435761u) >> 16;
            while (set[h] != 0xffffffffu && set[h] != c)
                h = (h + 1) & 0xffff;
            if (set[h] == 0xffffffffu && n < 30000)
                set[h] = c, n++;
        }
    return n;
}

static uint32_t count_colour(const image *im, uint32_t y0, uint32_t y1, uint32_t colour)
{
    uint32_t n = 0;
    for (uint32_t y = y0; y < y1 && y < im->h; y++)
        for (uint32_t x = 0; x < im->w; x++)
            n += rgb(im, x, y) == colour;
    return n;
}

static void test_usage_and_files(void **state)
{
    (void)state;
    expect_view(0, "", "--help", NULL);
    char p[300];
    snprintf(p, sizeof p, "%s/out", dir);
    char *out = slurp(p);
    assert_non_null(strstr(out, "usage: sightline view"));
    assert_non_null(strstr(out, "Space"));      /* the keys */
    assert_non_null(strstr(out, "--screenshot"));
    free(out);
    expect_view(2, "", "", "missing SCENE");
    expect_view(2, "", "city:tiny --size 10", "--size");
    expect_view(2, "", "city:tiny --methods nosuch", "nosuch");
    expect_view(2, "", "city:tiny --methods vfc:bogus=1", "bogus");
    expect_view(2, "", "city:tiny --method-options hzb:x=1", "not among the methods");
    expect_view(2, "", "city:tiny --camera 0,0,2,0,0,0 --path x.txt", "not both");
    expect_view(2, "", "city:tiny --camera 0,0,2,0,95,0", "pitch");
    expect_view(2, "", "city:tiny --ghosts some", "--ghosts");
    expect_view(2, "", "city:tiny --frames 0", "--frames");
    expect_view(2, "", "city:tiny --bogus", "unknown option --bogus");
    expect_view(1, "", "city:tiny --path missing.txt", "missing.txt");
    write_file("bad.txt", "# sightline-path 1\n0 0 0 2 0 0\n");
    expect_view(1, "", "city:tiny --path bad.txt", "bad.txt:2");
    expect_view(1, "", "nosuch.slscene", "nosuch.slscene");
}

static void test_no_display(void **state)
{
    (void)state;
    expect_view(1, "env -u DISPLAY -u WAYLAND_DISPLAY", "city:tiny --frames 2", "no display");
    /* a driver giving less than 4.5 (Mesa capped at 4.1) */
    expect_view(1, "env MESA_GL_VERSION_OVERRIDE=4.1", "city:tiny --frames 2", "no OpenGL 4.5 core context");
}

static void test_smoke(void **state)
{
    (void)state;
    write_file("walk.txt", path_text);
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --methods vfc,cullmap --screenshot hud.png", NULL);
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --methods vfc,cullmap --screenshot plain.png --no-hud", NULL);
    image a = load("hud.png"), b = load("plain.png");
    assert_int_equal(a.w, 320);
    assert_int_equal(a.h, 240);
    assert_int_equal(b.w, 320);
    /* not blank: sky, ground, buildings, trees, shading */
    uint32_t colours = distinct_colours(&b);
    if (colours < 16)
        fail_msg("the frame has %u distinct colours", colours);
    /* the HUD: white text in the top rows, absent without it; below it the frames are the same */
    uint32_t white_hud = count_colour(&a, 0, 100, 0xffffff), white_plain = count_colour(&b, 0, 100, 0xffffff);
    if (white_hud < white_plain + 200)
        fail_msg("HUD: %u white pixels in the top rows, %u without the HUD", white_hud, white_plain);
    size_t differ_below = 0;
    for (uint32_t y = 120; y < a.h; y++)
        for (uint32_t x = 0; x < a.w; x++)
            differ_below += rgb(&a, x, y) != rgb(&b, x, y);
    assert_int_equal(differ_below, 0);
    image_free(&a);
    image_free(&b);
    /* --frames stops early: 2 frames of the 4-pose path */
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 2 --no-hud --screenshot two.png", NULL);
    char p[300];
    snprintf(p, sizeof p, "%s/out", dir);
    char *out = slurp(p);
    assert_non_null(strstr(out, "2 frames"));
    free(out);
}

static void test_freeze_and_map(void **state)
{
    (void)state;
    write_file("walk.txt", path_text);
    /* frozen at frame 1: the last frame flies up and back, the frozen frustum (0xffe020) in view */
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --methods cullmap --freeze-at 1 --no-hud --screenshot frozen.png",
                "culling frozen");
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --methods cullmap --no-hud --screenshot live.png", NULL);
    image f = load("frozen.png"), l = load("live.png");
    uint32_t frustum_f = count_colour(&f, 0, f.h, 0xffe020), frustum_l = count_colour(&l, 0, l.h, 0xffe020);
    if (frustum_f < 50 || frustum_l)
        fail_msg("frozen frustum: %u pixels of its colour frozen, %u live", frustum_f, frustum_l);
    image_free(&f);
    image_free(&l);
    /* the top-down map: frustum lines and the eye's cross (0x20ff20) */
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --top-down --no-hud --screenshot map.png", NULL);
    image m = load("map.png");
    uint32_t eye = count_colour(&m, 0, m.h, 0x20ff20), fr = count_colour(&m, 0, m.h, 0xffe020);
    if (eye < 4 || fr < 20)
        fail_msg("map: %u eye pixels, %u frustum pixels", eye, fr);
    if (distinct_colours(&m) < 16)
        fail_msg("map: %u colours", distinct_colours(&m));
    image_free(&m);
    /* indoors (a Quake III map, cut above the eye): the eye and the frustum are still drawn */
    static const char pk3[] = "/usr/share/games/openarena/baseoa/pak1-maps.pk3";
    if (access(pk3, R_OK) == 0) {
        char args[512];
        snprintf(args, sizeof args, "'%s' --map oa_dm1 --frames 2 --size 320x200 --top-down --no-hud --screenshot q3.png",
                 pk3);
        expect_view(0, xvfb, args, NULL);
        image q = load("q3.png");
        uint32_t qe = count_colour(&q, 0, q.h, 0x20ff20), qf = count_colour(&q, 0, q.h, 0xffe020);
        if (qe < 4 || qf < 20)
            fail_msg("map of oa_dm1: %u eye pixels, %u frustum pixels", qe, qf);
        image_free(&q);
    } else
        printf("(%s not installed: the indoor map is not tested)\n", pk3);
}

/* Keys (scripted with --keys, through the same handler as the window's): Tab and Shift+Tab cycle
 * the methods, M the map, P a screenshot, R starts and stops a recording. */
static void test_keys(void **state)
{
    (void)state;
    write_file("walk.txt", path_text);
    expect_view(0, xvfb,
                "city:tiny --path walk.txt --frames 4 --methods vfc,cullmap,hzb --no-hud "
                "--keys 0:tab,0:m,1:p,1:r,2:r,3:shift+tab,3:shift+tab",
                "method cullmap");
    char p[300];
    snprintf(p, sizeof p, "%s/err", dir);
    char *err = slurp(p);
    assert_non_null(strstr(err, "saved view-0001.png"));
    assert_non_null(strstr(err, "recorded 1 poses into view-path-0001.txt"));
    assert_non_null(strstr(err, "method hzb")); /* cullmap, back twice: hzb */
    free(err);
    snprintf(p, sizeof p, "%s/out", dir);
    char *out = slurp(p);
    assert_non_null(strstr(out, "4 frames"));
    assert_non_null(strstr(out, "(hzb)"));
    free(out);
    image m = load("view-0001.png");
    if (count_colour(&m, 0, m.h, 0x20ff20) < 4) /* the map's eye */
        fail_msg("the screenshot after M shows no map");
    image_free(&m);
    snprintf(p, sizeof p, "%s/view-path-0001.txt", dir);
    sl_path rec;
    sl_error e;
    assert_int_equal(sl_path_load(p, NULL, &rec, &e), SL_OK);
    assert_int_equal(sl_path_count(rec), 1);
    sl_path_destroy(rec);
    expect_view(2, "", "city:tiny --keys 1:nokey", "--keys");
    expect_view(2, "", "city:tiny --keys x:tab", "--keys");
}

static void test_record_round_trip(void **state)
{
    (void)state;
    write_file("walk.txt", path_text);
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 4 --no-hud --record rec1.txt", "recorded 4 poses");
    expect_view(0, xvfb, "city:tiny --path rec1.txt --frames 4 --no-hud --record rec2.txt", "recorded 4 poses");
    char p0[300], p1[300], p2[300];
    snprintf(p0, sizeof p0, "%s/walk.txt", dir);
    snprintf(p1, sizeof p1, "%s/rec1.txt", dir);
    snprintf(p2, sizeof p2, "%s/rec2.txt", dir);
    sl_path a, b;
    sl_error err;
    assert_int_equal(sl_path_load(p0, NULL, &a, &err), SL_OK);
    assert_int_equal(sl_path_load(p1, NULL, &b, &err), SL_OK);
    assert_int_equal(sl_path_count(a), 4);
    assert_int_equal(sl_path_count(b), 4);
    assert_memory_equal(sl_path_poses(a), sl_path_poses(b), 4 * sizeof(sl_pose));
    sl_pose path_poses[4];
    memcpy(path_poses, sl_path_poses(a), sizeof path_poses);
    sl_camera ia = sl_path_intrinsics(a), ib = sl_path_intrinsics(b);
    assert_true(ia.fov_y == ib.fov_y && ia.width == ib.width && ia.height == ib.height &&
                ia.near_plane == ib.near_plane && ia.far_plane == ib.far_plane);
    sl_path_destroy(a);
    sl_path_destroy(b);
    char *t1 = slurp(p1), *t2 = slurp(p2);
    assert_string_equal(t1, t2);
    free(t1);
    free(t2);
    /* past the path's end the input takes over and the recording goes on, its times in order */
    expect_view(0, xvfb, "city:tiny --path walk.txt --frames 6 --no-hud --record rec3.txt", "recorded 6 poses");
    char p3[300];
    snprintf(p3, sizeof p3, "%s/rec3.txt", dir);
    assert_int_equal(sl_path_load(p3, NULL, &b, &err), SL_OK);
    assert_int_equal(sl_path_count(b), 6);
    assert_memory_equal(sl_path_poses(b), path_poses, 4 * sizeof(sl_pose));
    assert_true(sl_path_poses(b)[4].time >= sl_path_poses(b)[3].time);
    sl_path_destroy(b);
}

int main(int argc, char **argv)
{
    (void)argc, (void)argv;
    /* one X server for the whole test: run again inside xvfb-run */
    if (!getenv("SL_TEST_VIEWER_IN_XVFB") && system("command -v xvfb-run >/dev/null 2>&1") == 0) {
        setenv("SL_TEST_VIEWER_IN_XVFB", "1", 1);
        char self[4096];
        ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
        if (n > 0) {
            self[n] = '\0';
            fflush(stdout);
            execlp("xvfb-run", "xvfb-run", "-a", "-s", "-screen 0 640x480x24", self, (char *)NULL);
            perror("xvfb-run");
            return 1;
        }
    }
    sl_bin = getenv("SL_SIGHTLINE");
    if (!sl_bin) {
        printf("SL_SIGHTLINE is not set (CTest sets it to the built sightline)\n");
        return 1;
    }
    snprintf(dir, sizeof dir, "%s", "/tmp/sl-test-viewer-XXXXXX");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    /* Under ASan: the viewer's libraries (X11, Mesa, GLFW) keep memory to the end, not Sightline's
     * leaks, and GLX unloads Mesa's driver at glfwTerminate, after which LeakSanitizer cannot name
     * the module of such a leak. So the children get the suppressions below and the driver
     * preloaded (it then stays mapped; ASan's check that its runtime comes first is relaxed for
     * that). Sightline's own allocations are still checked. */
    if (getenv("SL_SANITIZED")) {
        static const char *const keep[] = {"/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so",
                                           "/usr/lib/x86_64-linux-gnu/libGLX_mesa.so.0"};
        char preload[512] = "";
        for (size_t i = 0; i < sizeof keep / sizeof keep[0]; i++)
            if (access(keep[i], R_OK) == 0)
                snprintf(preload + strlen(preload), sizeof preload - strlen(preload), "%s%s", *preload ? " " : "",
                         keep[i]);
        const char *asan = getenv("ASAN_OPTIONS");
        snprintf(child_env, sizeof child_env, "env ASAN_OPTIONS='%s%sverify_asan_link_order=0' LD_PRELOAD='%s'",
                 asan ? asan : "", asan && *asan ? ":" : "", preload);
    }
    char supp[300];
    snprintf(supp, sizeof supp, "%s/lsan.supp", dir);
    FILE *f = fopen(supp, "w");
    if (f) {
        fputs("leak:libX11.so\nleak:libxcb\nleak:libGLX\nleak:libGL\nleak:libEGL\nleak:libglfw.so\n"
              "leak:swrast_dri.so\nleak:libgallium\nleak:libLLVM\nleak:libdrm\nleak:libglapi\n", f);
        fclose(f);
        char opt[400];
        snprintf(opt, sizeof opt, "suppressions=%s", supp);
        setenv("LSAN_OPTIONS", opt, 1);
    }
    int rc;
    bool built = true;
    {
        run_view("env -u DISPLAY -u WAYLAND_DISPLAY", "city:tiny --frames 1");
        char p[300];
        snprintf(p, sizeof p, "%s/err", dir);
        char *err = slurp(p);
        built = !strstr(err, "built without the viewer");
        free(err);
    }
    bool have_xvfb = getenv("SL_TEST_VIEWER_IN_XVFB") != NULL;
    if (!built) {
        printf("skipped: this sightline was built without the viewer (no OpenGL renderer or no libglfw3-dev)\n");
        rc = 77;
    } else if (!have_xvfb) {
        printf("skipped: xvfb-run is not installed (apt-get install xvfb xauth; scripts/packages.txt)\n");
        rc = 77;
    } else {
        const struct CMUnitTest tests[] = {
            cmocka_unit_test(test_usage_and_files),
            cmocka_unit_test(test_no_display),
            cmocka_unit_test(test_smoke),
            cmocka_unit_test(test_freeze_and_map),
            cmocka_unit_test(test_keys),
            cmocka_unit_test(test_record_round_trip),
        };
        rc = cmocka_run_group_tests(tests, NULL, NULL);
    }
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return rc;
}

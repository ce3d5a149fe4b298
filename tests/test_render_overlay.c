/* The renderer's overlays (render.h, "overlays"; src/render/overlay.c) on a headless EGL context:
 * text lands where it is asked for, in its colour, one line below the other, non-ASCII as '?';
 * lines are drawn in world space on top of everything; ghosts tint an object where nothing drawn
 * is in front of it and nothing where something is; none of them touches the id or depth buffers;
 * bad arguments fail. Exits 77 (skipped) only when no GL context can be made. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sightline/render.h"
#include "support/box_mesh.h"

#define W 96
#define H 64
#define NPIX ((size_t)W * H)

typedef struct fixture {
    sl_scene scene;
    sl_renderer r;
    sl_view view;
    uint8_t before[NPIX * 4], after[NPIX * 4];
    uint32_t ids_before[NPIX], ids_after[NPIX];
    float depth_before[NPIX], depth_after[NPIX];
} fixture;

/* A box A [-1,1]^3 (id 0) seen from (-6, 0, 0) along +x; B (id 1) behind and beside it, in view;
 * C (id 2) straight behind A, hidden by it. */
static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &f->scene, &err), SL_OK);
    assert_int_equal(sl_test_add_box(f->scene, (sl_vec3){-1, -1, -1}, (sl_vec3){1, 1, 1}, SL_KIND_BUILDING,
                                     SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER), 0);
    assert_int_equal(sl_test_add_box(f->scene, (sl_vec3){3, -5, -0.5f}, (sl_vec3){4, -3, 0.5f}, SL_KIND_BUILDING,
                                     SL_OBJECT_CLOSED_CONVEX), 1);
    assert_int_equal(sl_test_add_box(f->scene, (sl_vec3){3, -0.5f, -0.5f}, (sl_vec3){4, 0.5f, 0.5f}, SL_KIND_BUILDING,
                                     SL_OBJECT_CLOSED_CONVEX), 2);
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = W, o.height = H;
    if (sl_renderer_create(f->scene, &o, NULL, &f->r, &err) != SL_OK)
        fail_msg("sl_renderer_create: %s", err.message);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){-6, 0, 0};
    cam.yaw = 0, cam.pitch = 0, cam.roll = 0;
    cam.fov_y = 1.2f, cam.near_plane = 0.1f, cam.far_plane = 100.0f;
    cam.width = W, cam.height = H;
    assert_int_equal(sl_view_from_camera(&cam, &f->view, &err), SL_OK);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    sl_renderer_destroy(f->r);
    sl_scene_destroy(f->scene);
    free(f);
    return 0;
}

/* Draw ids (count may be 0: sky only) and read colour, ids and depth into the "before" images. */
static void frame(fixture *f, const uint32_t *ids, uint32_t count)
{
    sl_error err;
    if (sl_renderer_draw(f->r, &f->view, ids, count, SL_RENDER_SHADED, NULL, &err) != SL_OK)
        fail_msg("sl_renderer_draw: %s", err.message);
    assert_int_equal(sl_renderer_read_rgba(f->r, f->before, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(f->r, f->ids_before, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(f->r, f->depth_before, &err), SL_OK);
}

/* Read the "after" images; ids and depth must be as before. */
static void read_after(fixture *f)
{
    sl_error err;
    assert_int_equal(sl_renderer_read_rgba(f->r, f->after, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(f->r, f->ids_after, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(f->r, f->depth_after, &err), SL_OK);
    assert_memory_equal(f->ids_before, f->ids_after, sizeof f->ids_before);
    assert_memory_equal(f->depth_before, f->depth_after, sizeof f->depth_before);
}

static bool changed(const fixture *f, size_t i) { return memcmp(f->before + i * 4, f->after + i * 4, 4) != 0; }

static bool is_rgb(const uint8_t *p, uint32_t rgba)
{
    return p[0] == (rgba >> 24) && p[1] == ((rgba >> 16) & 255) && p[2] == ((rgba >> 8) & 255);
}

typedef struct box2 {
    int x0, y0, x1, y1; /* inclusive; x0 > x1 when empty */
    size_t count;
} box2;

/* Bounds and count of the changed pixels. */
static box2 changes(const fixture *f)
{
    box2 b = {W, H, -1, -1, 0};
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            if (changed(f, (size_t)y * W + (size_t)x)) {
                b.count++;
                b.x0 = x < b.x0 ? x : b.x0, b.y0 = y < b.y0 ? y : b.y0;
                b.x1 = x > b.x1 ? x : b.x1, b.y1 = y > b.y1 ? y : b.y1;
            }
    return b;
}

static void text(fixture *f, float x, float y, float scale, const char *t, uint32_t rgba)
{
    sl_error err;
    if (sl_renderer_draw_text(f->r, x, y, scale, t, rgba, &err) != SL_OK)
        fail_msg("sl_renderer_draw_text: %s", err.message);
}

static void test_text(void **state)
{
    fixture *f = *state;
    uint32_t a = 0;
    frame(f, &a, 1);
    text(f, 10, 5, 2, "HI", 0xff00ffffu);
    read_after(f);
    box2 b = changes(f);
    /* the glyphs' stems start at the point asked for; two capitals at scale 2 stay within 12 x 7
     * font units a glyph; every changed pixel is the text's colour (opaque: no blending left) */
    assert_true(b.count >= 30);
    assert_int_equal(b.x0, 10);
    assert_int_equal(b.y0, 5);
    assert_true(b.x1 < 10 + 2 * 12 && b.y1 < 5 + 2 * 8);
    for (size_t i = 0; i < NPIX; i++)
        if (changed(f, i))
            assert_true(is_rgb(f->after + i * 4, 0xff00ffffu));

    /* a second line 12 font units lower; scale 1 */
    frame(f, &a, 1);
    text(f, 0, 0, 1, "A\nB", 0xffffffffu);
    read_after(f);
    b = changes(f);
    assert_true(b.y0 < 12 && b.y1 >= 12 && b.y1 < 24);
    bool top = false, bottom = false;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            if (changed(f, (size_t)y * W + (size_t)x)) {
                top = top || y < 12;
                bottom = bottom || y >= 12;
            }
    assert_true(top && bottom);

    /* bytes outside printable ASCII are drawn as '?' */
    frame(f, &a, 1);
    text(f, 3, 3, 1, "??", 0xffff00ffu);
    read_after(f);
    static uint8_t question[NPIX * 4];
    memcpy(question, f->after, sizeof question);
    frame(f, &a, 1);
    text(f, 3, 3, 1, "\x01\xff", 0xffff00ffu);
    read_after(f);
    assert_memory_equal(question, f->after, sizeof question);
    assert_true(changes(f).count > 5);

    /* translucent text blends */
    frame(f, NULL, 0);
    text(f, 10, 10, 3, "#", 0x0000ff80u);
    read_after(f);
    b = changes(f);
    assert_true(b.count > 20);
    for (size_t i = 0; i < NPIX; i++)
        if (changed(f, i)) {
            const uint8_t *p = f->after + i * 4, *q = f->before + i * 4;
            assert_true(p[2] > q[2] || q[2] >= 250);
            assert_false(p[0] == 0 && p[1] == 0 && p[2] == 255); /* not the plain colour */
        }

    /* empty text draws nothing; errors */
    frame(f, &a, 1);
    text(f, 5, 5, 1, "", 0xffffffffu);
    read_after(f);
    assert_int_equal(changes(f).count, 0);
    sl_error err;
    assert_int_equal(sl_renderer_draw_text(f->r, 0, 0, 1, NULL, 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_renderer_draw_text(f->r, 0, 0, 0, "x", 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "scale"));
    assert_int_equal(sl_renderer_draw_text(f->r, NAN, 0, 1, "x", 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_renderer_draw_text(NULL, 0, 0, 1, "x", 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
}

static void test_lines(void **state)
{
    fixture *f = *state;
    uint32_t a = 0;
    frame(f, &a, 1);
    /* across the view in front of A at eye height: the middle row(s) */
    float seg[6] = {-3, -10, 0, -3, 10, 0};
    sl_error err;
    assert_int_equal(sl_renderer_draw_lines(f->r, &f->view, seg, 1, 0x00ff00ffu, &err), SL_OK);
    read_after(f);
    box2 b = changes(f);
    assert_true(b.y0 >= H / 2 - 1 && b.y1 <= H / 2);
    assert_true(b.x0 <= 1 && b.x1 >= W - 2);
    assert_true(b.count >= W - 2 && b.count <= 2 * W);
    for (size_t i = 0; i < NPIX; i++)
        if (changed(f, i))
            assert_true(is_rgb(f->after + i * 4, 0x00ff00ffu));

    /* a vertical segment behind A is drawn on top of it (no depth test): through the middle column */
    frame(f, &a, 1);
    float behind[6] = {3, 0, -0.5f, 3, 0, 0.5f};
    assert_int_equal(sl_renderer_draw_lines(f->r, &f->view, behind, 1, 0xff0000ffu, &err), SL_OK);
    read_after(f);
    b = changes(f);
    assert_true(b.count >= 3);
    assert_true(b.x0 >= W / 2 - 1 && b.x1 <= W / 2);
    for (size_t i = 0; i < NPIX; i++)
        if (changed(f, i))
            assert_int_equal(f->ids_after[i], 0); /* over A's pixels */

    /* nothing to draw; errors */
    frame(f, &a, 1);
    assert_int_equal(sl_renderer_draw_lines(f->r, &f->view, NULL, 0, 0xffffffffu, &err), SL_OK);
    read_after(f);
    assert_int_equal(changes(f).count, 0);
    assert_int_equal(sl_renderer_draw_lines(f->r, &f->view, NULL, 1, 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
    float bad[6] = {0, 0, 0, INFINITY, 0, 0};
    assert_int_equal(sl_renderer_draw_lines(f->r, &f->view, bad, 1, 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "non-finite"));
    sl_view unmade;
    memset(&unmade, 0, sizeof unmade);
    assert_int_equal(sl_renderer_draw_lines(f->r, &unmade, seg, 1, 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
}

/* The pixels of object id in a frame that draws every object. */
static void id_image(fixture *f, uint32_t *out)
{
    uint32_t all[3] = {0, 1, 2};
    frame(f, all, 3);
    memcpy(out, f->ids_before, NPIX * sizeof *out);
}

static bool near_id(const uint32_t *img, int x, int y, uint32_t id)
{
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int u = x + dx, v = y + dy;
            if (u >= 0 && v >= 0 && u < W && v < H && img[(size_t)v * W + (size_t)u] == id)
                return true;
        }
    return false;
}

static void test_ghosts(void **state)
{
    fixture *f = *state;
    static uint32_t full[NPIX];
    id_image(f, full);
    size_t b_pixels = 0;
    for (size_t i = 0; i < NPIX; i++)
        b_pixels += full[i] == 1;
    assert_true(b_pixels > 20);

    /* B culled, ghosted: its pixels tinted blue, nothing away from it changes */
    uint32_t a = 0, b = 1, c = 2;
    frame(f, &a, 1);
    sl_error err;
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, &b, 1, 0x0000ff60u, &err), SL_OK);
    read_after(f);
    size_t tinted = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + (size_t)x;
            if (changed(f, i))
                assert_true(near_id(full, x, y, 1));
            if (full[i] == 1 && changed(f, i)) {
                tinted++;
                assert_true(f->after[i * 4 + 2] > f->before[i * 4 + 2] || f->before[i * 4 + 2] >= 250);
            }
        }
    assert_true(tinted * 100 >= b_pixels * 95); /* all but edge pixels where two vertex programs round apart */

    /* C is behind A: a ghost of it is hidden by the frame's depth (fill and edges) */
    frame(f, &a, 1);
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, &c, 1, 0x0000ff60u, &err), SL_OK);
    read_after(f);
    assert_int_equal(changes(f).count, 0);
    /* ... and shows when A is not drawn */
    frame(f, NULL, 0);
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, &c, 1, 0x0000ff60u, &err), SL_OK);
    read_after(f);
    assert_true(changes(f).count > 10);

    /* a drawn object ghosted over itself: equal depth passes (pulled toward the eye) */
    frame(f, &a, 1);
    size_t a_pixels = 0, a_changed = 0;
    for (size_t i = 0; i < NPIX; i++)
        a_pixels += f->ids_before[i] == 0;
    uint32_t twice[2] = {0, 0}; /* duplicates are drawn once */
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, twice, 2, 0xffff0080u, &err), SL_OK);
    read_after(f);
    for (size_t i = 0; i < NPIX; i++)
        a_changed += f->ids_before[i] == 0 && changed(f, i);
    assert_true(a_pixels > 100);
    assert_true(a_changed * 100 >= a_pixels * 95);
    static uint8_t once[NPIX * 4];
    memcpy(once, f->after, sizeof once);
    frame(f, &a, 1);
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, &a, 1, 0xffff0080u, &err), SL_OK);
    read_after(f);
    assert_memory_equal(once, f->after, sizeof once);

    /* nothing; errors */
    frame(f, &a, 1);
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, NULL, 0, 0xffffffffu, &err), SL_OK);
    read_after(f);
    assert_int_equal(changes(f).count, 0);
    uint32_t out_of_scene = 3;
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, &out_of_scene, 1, 0xffffffffu, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "object 3"));
    assert_int_equal(sl_renderer_draw_ghosts(f->r, &f->view, NULL, 1, 0xffffffffu, &err), SL_ERROR_INVALID_ARGUMENT);
}

/* Overlays survive into the PNG and are redrawn after a resize (their programs stay valid). */
static void test_resize(void **state)
{
    fixture *f = *state;
    sl_error err;
    uint32_t a = 0;
    frame(f, &a, 1);
    text(f, 1, 1, 1, "ok", 0xffffffffu);
    assert_int_equal(sl_renderer_resize(f->r, W / 2, H / 2, &err), SL_OK);
    assert_int_equal(sl_renderer_draw(f->r, &f->view, &a, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    static uint8_t small_before[NPIX], small_after[NPIX];
    assert_int_equal(sl_renderer_read_rgba(f->r, small_before, &err), SL_OK);
    text(f, 1, 1, 1, "ok", 0xffffffffu);
    assert_int_equal(sl_renderer_read_rgba(f->r, small_after, &err), SL_OK);
    assert_memory_not_equal(small_before, small_after, (size_t)(W / 2) * (H / 2) * 4);
    assert_int_equal(sl_renderer_resize(f->r, W, H, &err), SL_OK);
}

int main(void)
{
    sl_error err;
    if (sl_renderer_probe(SL_GL_CONTEXT_AUTO, &err) != SL_OK) {
        printf("skipped: no headless GL context: %s\n", err.message);
        return 77;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_text, setup, teardown),
        cmocka_unit_test_setup_teardown(test_lines, setup, teardown),
        cmocka_unit_test_setup_teardown(test_ghosts, setup, teardown),
        cmocka_unit_test_setup_teardown(test_resize, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

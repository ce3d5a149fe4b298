/* The OpenGL renderer (include/sightline/render.h) on a headless EGL context (llvmpipe here): a
 * known scene's pixels (colour, sky, the light's direction), the id buffer against the oracle's on
 * the tiny city and a Quake III map (identical but for depth ties and silhouette pixels, both
 * counted and bounded), KHR_debug errors reported with context, read-back, resize and PNG output,
 * frames decided by a culler. Exits 77 (skipped) only when no GL context can be made. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/image.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/render.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"
#include "support/city_views.h"
#include "support/pk3_names.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static sl_renderer make_renderer(sl_scene s, uint32_t w, uint32_t h, const float sun[3])
{
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = w;
    o.height = h;
    if (sun)
        memcpy(o.sun_direction, sun, sizeof o.sun_direction);
    sl_renderer r = NULL;
    sl_error err;
    if (sl_renderer_create(s, &o, NULL, &r, &err) != SL_OK)
        fail_msg("sl_renderer_create: %s", err.message);
    return r;
}

/* One box [-1, 1]^3 of colour 0xC04020FF (closed convex) seen from (-6, 0, 0) looking along +x. */
static sl_scene box_scene(uint32_t color)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    float p[24];
    sl_test_box_vertices((sl_vec3){-1, -1, -1}, (sl_vec3){1, 1, 1}, p);
    sl_mesh_desc md = {p, NULL, 8, sl_test_box_indices, 12, NULL};
    uint32_t mesh;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, color, SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    return s;
}

static sl_view box_view(uint32_t w, uint32_t h)
{
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){-6, 0, 0};
    cam.yaw = 0;
    cam.pitch = 0;
    cam.roll = 0;
    cam.fov_y = 1.0f;
    cam.near_plane = 0.1f;
    cam.far_plane = 100.0f;
    cam.width = w;
    cam.height = h;
    sl_view v;
    sl_error err;
    assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
    return v;
}

static void render_box(const float sun[3], uint8_t *rgba, uint32_t *ids, float *depth)
{
    sl_scene s = box_scene(0xC04020FFu);
    sl_renderer r = make_renderer(s, 64, 48, sun);
    sl_view v = box_view(64, 48);
    sl_error err;
    uint32_t id = 0;
    sl_render_frame_stats st;
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, &st, &err), SL_OK);
    assert_int_equal(st.objects_drawn, 1);
    assert_int_equal(st.triangles_drawn, 12);
    assert_true(st.draw_calls >= 1);
    assert_true(st.frame_ms >= 0.0);
    assert_int_equal(sl_renderer_read_rgba(r, rgba, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(r, depth, &err), SL_OK);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* A box of known colour at the centre, sky elsewhere; the face toward the sun is lit. */
static void test_box_pixels(void **state)
{
    (void)state;
    uint8_t lit[64 * 48 * 4], dark[64 * 48 * 4];
    uint32_t ids[64 * 48];
    float depth[64 * 48];
    const float toward[3] = {-1, 0, 0}, away[3] = {1, 0, 0.2f};
    render_box(toward, lit, ids, depth);
    const uint8_t *c = lit + 4 * (24 * 64 + 32);
    print_message("lit face: %d %d %d\n", c[0], c[1], c[2]);
    /* the -x face, normal (-1, 0, 0): base * (0.62 + 0.22 + 0.16 * 0.5) = base * 0.92 */
    assert_true(abs(c[0] - (int)lrint(0xC0 * 0.92)) <= 2);
    assert_true(abs(c[1] - (int)lrint(0x40 * 0.92)) <= 2);
    assert_true(abs(c[2] - (int)lrint(0x20 * 0.92)) <= 2);
    assert_int_equal(ids[24 * 64 + 32], 0);
    /* depth: the oracle's (1 - z_ndc) / 2 of the face 5 m away */
    double n = 0.1, f = 100.0, z = 5.0;
    double zndc = (f + n) / (f - n) - 2.0 * f * n / ((f - n) * z);
    assert_true(fabs(depth[24 * 64 + 32] - (1.0 - zndc) / 2.0) < 1e-6);
    /* the corners: sky (blue above the horizon, brighter at the horizon), no id, depth 0 */
    const uint8_t *top = lit, *mid = lit + 4 * (23 * 64 + 0);
    assert_true(top[2] > top[0] + 40);
    assert_true(mid[0] > top[0]);
    assert_int_equal(ids[0], SL_NONE);
    assert_true(depth[0] == 0.0f);
    assert_int_equal(ids[47 * 64 + 63], SL_NONE);
    /* the box's silhouette: a face 2 m wide 5 m away with fov_y 1 rad spans 2 / (2 * 5 * tan 0.5) of
     * the height: about 17.5 of 48 rows */
    uint32_t rows = 0;
    for (uint32_t y = 0; y < 48; y++)
        rows += ids[y * 64 + 32] == 0;
    assert_true(rows >= 16 && rows <= 19);
    /* colours of the caller's, then the scene's again */
    {
        sl_scene s = box_scene(0xC04020FFu);
        sl_renderer r = make_renderer(s, 64, 48, toward);
        sl_view v = box_view(64, 48);
        sl_error err;
        uint32_t id = 0, green = 0x00FF00FFu;
        assert_int_equal(sl_renderer_set_colors(r, &green, &err), SL_OK);
        assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
        assert_int_equal(sl_renderer_read_rgba(r, dark, &err), SL_OK);
        c = dark + 4 * (24 * 64 + 32);
        assert_true(c[0] < 3 && abs(c[1] - (int)lrint(255 * 0.92)) <= 2 && c[2] < 3);
        assert_int_equal(sl_renderer_set_colors(r, NULL, &err), SL_OK);
        assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
        assert_int_equal(sl_renderer_read_rgba(r, dark, &err), SL_OK);
        assert_memory_equal(dark + 4 * (24 * 64 + 32), lit + 4 * (24 * 64 + 32), 3);
        sl_renderer_destroy(r);
        sl_scene_destroy(s);
    }
    /* the sun away from the face: ambient only, base * (0.22 + 0.08) */
    render_box(away, dark, ids, depth);
    c = dark + 4 * (24 * 64 + 32);
    assert_true(abs(c[0] - (int)lrint(0xC0 * 0.30)) <= 2);
    assert_true(lit[4 * (24 * 64 + 32)] > c[0] + 100);
}

/* ---- the id buffer against the oracle's ---- */

typedef struct compare_counts {
    uint64_t pixels, same, ties, edges, bad;
} compare_counts;

static bool neighbour_has(const uint32_t *img, uint32_t w, uint32_t h, uint32_t x, uint32_t y, uint32_t id)
{
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int xx = (int)x + dx, yy = (int)y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < (int)w && yy < (int)h && img[yy * (int)w + xx] == id)
                return true;
        }
    return false;
}

/* Every pixel: the same id, or a depth tie (both drawn, depths within a small relative tolerance),
 * or a silhouette pixel (the other image has the id next to it: a pixel centre within rounding of
 * an edge); anything else is counted bad. */
static void compare_ids(const uint32_t *gl_ids, const float *gl_depth, const sl_oracle_view *ov, compare_counts *c)
{
    uint32_t w = ov->width, h = ov->height;
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            c->pixels++;
            uint32_t a = gl_ids[i], b = ov->ids[i];
            if (a == b) {
                c->same++;
                continue;
            }
            double da = gl_depth[i], db = ov->depth[i];
            if (a != SL_NONE && b != SL_NONE && fabs(da - db) <= 1e-4 * fmax(da, db) + 1e-7)
                c->ties++;
            else if (neighbour_has(ov->ids, w, h, x, y, a) || neighbour_has(gl_ids, w, h, x, y, b))
                c->edges++;
            else {
                if (c->bad < 5)
                    print_message("pixel (%u, %u): GL id %u depth %.9g, oracle id %u depth %.9g\n", x, y, a, da, b, db);
                c->bad++;
            }
        }
}

static void compare_on(sl_scene s, sl_path p, uint32_t w, uint32_t h, bool see_through_solid, const char *name)
{
    sl_error err;
    sl_oracle_options oo = sl_oracle_default_options();
    oo.see_through_solid = see_through_solid;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    sl_renderer r = make_renderer(s, w, h, NULL);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *all = malloc((size_t)n * 4), *ids = malloc((size_t)w * h * 4);
    float *depth = malloc((size_t)w * h * 4);
    for (uint32_t i = 0; i < n; i++)
        all[i] = i;
    compare_counts c = {0};
    for (uint32_t k = 0; k < sl_path_count(p); k++) {
        sl_camera cam = sl_path_camera(p, k);
        sl_view v;
        assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render_view(o, &v, &f, &err), SL_OK);
        sl_oracle_view ov;
        assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
        assert_int_equal(ov.width, w);
        assert_int_equal(sl_renderer_draw(r, &v, all, n, SL_RENDER_IDS, NULL, &err), SL_OK);
        assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
        assert_int_equal(sl_renderer_read_depth(r, depth, &err), SL_OK);
        compare_ids(ids, depth, &ov, &c);
    }
    print_message("%s: %u views %ux%u: %llu pixels, %llu identical, %llu depth ties, %llu silhouette, %llu other\n", name,
                  sl_path_count(p), w, h, (unsigned long long)c.pixels, (unsigned long long)c.same,
                  (unsigned long long)c.ties, (unsigned long long)c.edges, (unsigned long long)c.bad);
    assert_int_equal(c.bad, 0);
    assert_true(c.ties + c.edges <= c.pixels / 200); /* at most 0.5 % */
    free(all);
    free(ids);
    free(depth);
    sl_renderer_destroy(r);
    sl_oracle_destroy(o);
}

static void test_ids_match_oracle_city(void **state)
{
    (void)state;
    sl_scene s;
    sl_path p;
    sl_error err;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, sanitized() ? 3 : 8, 5, 160, 120, &s, &p, &err), SL_OK);
    compare_on(s, p, 160, 120, false, "tiny city");
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

static void test_ids_match_oracle_map(void **state)
{
    (void)state;
    sl_test_map map;
    if (!sl_test_open_map(0, 160, 120, sanitized() ? 2 : 6, 31, &map))
        skip();
    /* every drawn pixel counts (the open-space rule is the oracle's judgement, not drawing) */
    compare_on(map.scene, map.views, 160, 120, true, map.name);
    sl_test_map_free(&map);
}

/* ---- KHR_debug and GL errors ---- */

static void test_gl_errors_reported(void **state)
{
    (void)state;
    sl_scene s = box_scene(0xFFFFFFFFu);
    sl_renderer r = make_renderer(s, 32, 24, NULL);
    sl_view v = box_view(32, 24);
    sl_error err;
    uint32_t id = 0;
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    /* a GL error made outside the renderer, on its (current) context: the next call names it */
    glBindBuffer(GL_ARRAY_BUFFER, 987654u); /* not a buffer name: GL_INVALID_OPERATION in core */
    assert_int_not_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    print_message("reported: %s\n", err.message);
    assert_non_null(strstr(err.message, "before sl_renderer_draw"));
    assert_non_null(strstr(err.message, "GL_INVALID_OPERATION"));
    assert_true(strlen(err.message) > strlen("before sl_renderer_draw (a GL call outside the renderer): GL_INVALID_OPERATION: "));
    /* once reported, the renderer works again */
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    /* a GL error inside a call: a size GL refuses, named with the call and the limit; the old
     * framebuffer stays */
    assert_int_not_equal(sl_renderer_resize(r, 1u << 20, 8, &err), SL_OK);
    print_message("reported: %s\n", err.message);
    assert_non_null(strstr(err.message, "sl_renderer_resize: glTextureStorage2D"));
    assert_non_null(strstr(err.message, "GL_INVALID_VALUE"));
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    uint32_t ids[32 * 24];
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(ids[12 * 32 + 16], 0);
    /* bad arguments */
    id = 1;
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "id 1"));
    sl_view bad;
    memset(&bad, 0, sizeof bad);
    assert_int_equal(sl_renderer_draw(r, &bad, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- read-back, resize, PNG ---- */

static void test_resize_and_png(void **state)
{
    (void)state;
    sl_scene s = box_scene(0x20C040FFu);
    sl_renderer r = make_renderer(s, 32, 24, NULL);
    sl_error err;
    assert_int_equal(sl_renderer_resize(r, 80, 40, &err), SL_OK);
    sl_view v = box_view(80, 40);
    uint32_t id = 0;
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    uint8_t rgba[80 * 40 * 4];
    uint32_t ids[80 * 40];
    assert_int_equal(sl_renderer_read_rgba(r, rgba, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(ids[20 * 80 + 40], 0);
    assert_int_equal(ids[0], SL_NONE);
    /* row 0 is the top: the box is symmetric, the sky is not (bluer above) */
    assert_true(rgba[2] > rgba[4 * (39 * 80)] || rgba[0] < rgba[4 * (39 * 80)]);
    char path[256];
    snprintf(path, sizeof path, "%s/test_render_%d.png", SL_BINARY_DIR, (int)getpid());
    assert_int_equal(sl_renderer_write_png(r, path, &err), SL_OK);
    uint8_t *png = NULL;
    uint32_t pw = 0, ph = 0;
    assert_int_equal(sl_png_read_rgba(path, NULL, &png, &pw, &ph, &err), SL_OK);
    assert_int_equal(pw, 80);
    assert_int_equal(ph, 40);
    for (size_t i = 0; i < sizeof rgba; i++)
        assert_int_equal(png[i], (i % 4) == 3 ? 255 : rgba[i]);
    sl_default_allocator()->free(NULL, png, (size_t)pw * ph * 4);
    unlink(path);
    /* the IDS kind writes ids and depth; the DEPTH kind only depth */
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_DEPTH, NULL, &err), SL_OK);
    float depth[80 * 40];
    assert_int_equal(sl_renderer_read_depth(r, depth, &err), SL_OK);
    assert_true(depth[20 * 80 + 40] > 0.0f && depth[0] == 0.0f);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(ids[20 * 80 + 40], SL_NONE);
    sl_renderer_info info;
    sl_renderer_get_info(r, &info);
    assert_true(info.reversed_z);
    assert_true(info.vertex_bytes > 0 && info.index_bytes == 36 * 4);
    print_message("GL: %s / %s / %s\n", info.vendor, info.renderer, info.version);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- the facing rule: closed convex objects lose their back faces, a mirroring transform swaps
 * the front winding ---- */

static void test_facing_rule(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    float p[24];
    uint32_t mesh_big, mesh_small;
    sl_test_box_vertices((sl_vec3){-10, -10, -10}, (sl_vec3){10, 10, 10}, p);
    sl_mesh_desc md = {p, NULL, 8, sl_test_box_indices, 12, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh_big, &err), SL_OK);
    sl_test_box_vertices((sl_vec3){-6, -1, -1}, (sl_vec3){-4, 1, 1}, p);
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh_small, &err), SL_OK);
    /* 0: a closed box around the eye (seen from inside: nothing of it is drawn) */
    sl_object_desc od = {mesh_big, NULL, 0x808080FFu, SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    /* 1: the small box mirrored in x (x -> -x): it sits in [4, 6] and its outward faces wind the
     * other way */
    sl_affine mirror = {{-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    sl_object_desc om = {mesh_small, &mirror, 0xC04020FFu, SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX, 0};
    assert_int_equal(sl_scene_add_object(s, &om, NULL, &err), SL_OK);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 0};
    cam.yaw = cam.pitch = cam.roll = 0;
    cam.fov_y = 1.0f;
    cam.near_plane = 0.1f;
    cam.far_plane = 100.0f;
    cam.width = 64;
    cam.height = 48;
    sl_view v;
    assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
    sl_renderer r = make_renderer(s, 64, 48, NULL);
    uint32_t all[2] = {0, 1}, ids[64 * 48];
    float depth[64 * 48];
    assert_int_equal(sl_renderer_draw(r, &v, all, 2, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(r, depth, &err), SL_OK);
    assert_int_equal(ids[0], SL_NONE);            /* the enclosing box's back faces are not drawn */
    assert_int_equal(ids[24 * 64 + 32], 1);
    /* the mirrored box's near face (x = 4) is its front: drawn, the far one (x = 6) is not */
    double n = 0.1, f = 100.0, z = 4.0;
    double zndc = (f + n) / (f - n) - 2.0 * f * n / ((f - n) * z);
    assert_true(fabs(depth[24 * 64 + 32] - (1.0 - zndc) / 2.0) < 1e-6);
    /* and the oracle agrees on every pixel */
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render_view(o, &v, &fr, &err), SL_OK);
    sl_oracle_view ov;
    assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
    compare_counts c = {0};
    compare_ids(ids, depth, &ov, &c);
    assert_int_equal(c.same, 64 * 48);
    sl_oracle_destroy(o);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- two renderers are independent: destroying one leaves the other working ---- */

static void test_two_renderers(void **state)
{
    (void)state;
    sl_scene s = box_scene(0x3060C0FFu);
    sl_renderer a = make_renderer(s, 32, 24, NULL), b = make_renderer(s, 32, 24, NULL);
    sl_view v = box_view(32, 24);
    sl_error err;
    uint32_t id = 0, ids[32 * 24];
    assert_int_equal(sl_renderer_draw(a, &v, &id, 1, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_draw(b, &v, &id, 1, SL_RENDER_IDS, NULL, &err), SL_OK);
    sl_renderer_destroy(a);
    if (sl_renderer_draw(b, &v, &id, 1, SL_RENDER_SHADED, NULL, &err) != SL_OK)
        fail_msg("the second renderer after the first was destroyed: %s", err.message);
    assert_int_equal(sl_renderer_read_ids(b, ids, &err), SL_OK);
    assert_int_equal(ids[12 * 32 + 16], 0);
    sl_renderer_destroy(b);
    sl_scene_destroy(s);
}

/* ---- the depth pre-pass draws the same image ---- */

static void test_depth_prepass(void **state)
{
    (void)state;
    sl_scene s;
    sl_path p;
    sl_error err;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, 2, 13, 128, 96, &s, &p, &err), SL_OK);
    sl_renderer plain = make_renderer(s, 128, 96, NULL);
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = 128;
    o.height = 96;
    o.depth_prepass = true;
    sl_renderer pre;
    assert_int_equal(sl_renderer_create(s, &o, NULL, &pre, &err), SL_OK);
    uint8_t *a = malloc(128 * 96 * 4), *b = malloc(128 * 96 * 4);
    uint32_t *ia = malloc(128 * 96 * 4), *ib = malloc(128 * 96 * 4);
    for (uint32_t k = 0; k < sl_path_count(p); k++) {
        sl_camera cam = sl_path_camera(p, k);
        sl_view v;
        assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
        sl_render_frame_stats sa, sb;
        assert_int_equal(sl_renderer_frame(plain, NULL, &v, SL_RENDER_SHADED, NULL, NULL, &sa, &err), SL_OK);
        assert_int_equal(sl_renderer_frame(pre, NULL, &v, SL_RENDER_SHADED, NULL, NULL, &sb, &err), SL_OK);
        assert_int_equal(sa.objects_drawn, sb.objects_drawn);
        assert_true(sb.draw_calls > sa.draw_calls); /* the depth pass's calls too */
        assert_int_equal(sl_renderer_read_rgba(plain, a, &err), SL_OK);
        assert_int_equal(sl_renderer_read_rgba(pre, b, &err), SL_OK);
        assert_int_equal(sl_renderer_read_ids(plain, ia, &err), SL_OK);
        assert_int_equal(sl_renderer_read_ids(pre, ib, &err), SL_OK);
        assert_memory_equal(a, b, 128 * 96 * 4);
        assert_memory_equal(ia, ib, 128 * 96 * 4);
    }
    free(a);
    free(b);
    free(ia);
    free(ib);
    sl_renderer_destroy(plain);
    sl_renderer_destroy(pre);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* ---- present into the caller's framebuffer; a renderer on the caller's current context ---- */

static void test_present_and_current_context(void **state)
{
    (void)state;
    sl_scene s = box_scene(0xC04020FFu);
    sl_renderer a = make_renderer(s, 32, 24, NULL);
    sl_view v = box_view(32, 24);
    sl_error err;
    uint32_t id = 0;
    uint8_t small[32 * 24 * 4];
    assert_int_equal(sl_renderer_draw(a, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_rgba(a, small, &err), SL_OK);
    /* a's context is current on this thread: a framebuffer of the caller's, twice the size */
    GLuint tex = 0, fbo = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &tex);
    glTextureStorage2D(tex, 1, GL_RGBA8, 64, 48);
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, tex, 0);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo);
    assert_int_equal(sl_renderer_present(a, 64, 48, &err), SL_OK);
    uint8_t *big = malloc(64 * 48 * 4);
    glGetTextureImage(tex, 0, GL_RGBA, GL_UNSIGNED_BYTE, 64 * 48 * 4, big);
    /* GL rows bottom first: the centre is the box's colour, the top row the sky's */
    const uint8_t *c = big + 4 * (24 * 64 + 32), *want = small + 4 * (12 * 32 + 16);
    for (int k = 0; k < 3; k++)
        assert_true(abs(c[k] - want[k]) <= 2);
    const uint8_t *top = big + 4 * (47 * 64 + 1), *sky = small + 4 * 0;
    for (int k = 0; k < 3; k++)
        assert_true(abs(top[k] - sky[k]) <= 4);
    /* a renderer on the current context (the viewer's way): it draws, and leaves the context */
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = 32;
    o.height = 24;
    o.context = SL_GL_CONTEXT_CURRENT;
    sl_renderer b;
    assert_int_equal(sl_renderer_create(s, &o, NULL, &b, &err), SL_OK);
    sl_renderer_info info;
    sl_renderer_get_info(b, &info);
    assert_int_equal(info.context, SL_GL_CONTEXT_CURRENT);
    uint32_t ids[32 * 24];
    assert_int_equal(sl_renderer_draw(b, &v, &id, 1, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(b, ids, &err), SL_OK);
    assert_int_equal(ids[12 * 32 + 16], 0);
    sl_renderer_destroy(b);
    /* a still works, and its KHR_debug callback is back: a driver message comes with its text */
    glDeleteFramebuffers(1, &fbo);
    glDeleteTextures(1, &tex);
    glBindBuffer(GL_ARRAY_BUFFER, 987654u);
    assert_int_not_equal(sl_renderer_draw(a, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    assert_non_null(strstr(err.message, "glBindBuffer"));
    assert_int_equal(sl_renderer_draw(a, &v, &id, 1, SL_RENDER_SHADED, NULL, &err), SL_OK);
    free(big);
    sl_renderer_destroy(a);
    sl_scene_destroy(s);
}

/* ---- moved objects: sl_renderer_scene_changed uploads their transforms ---- */

static void test_scene_changed(void **state)
{
    (void)state;
    sl_scene s = box_scene(0xC04020FFu);
    sl_renderer r = make_renderer(s, 32, 24, NULL);
    sl_view v = box_view(32, 24);
    sl_error err;
    uint32_t id = 0, ids[32 * 24];
    sl_affine moved = {{1, 0, 0, 0, 0, 1, 0, 2.5f, 0, 0, 1, 0}}; /* 2.5 m to the left (+y) */
    assert_int_equal(sl_scene_set_object_transform(s, 0, &moved, &err), SL_OK);
    /* not told yet: the old place */
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(ids[12 * 32 + 16], 0);
    assert_int_equal(sl_renderer_scene_changed(r, &err), SL_OK);
    assert_int_equal(sl_renderer_draw(r, &v, &id, 1, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(ids[12 * 32 + 16], SL_NONE); /* the centre is free now */
    assert_int_equal(ids[12 * 32 + 2], 0);        /* the box is at the left */
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- context kinds: AUTO resolves to a device with a hardware driver or to surfaceless ---- */

static void test_context_kinds(void **state)
{
    (void)state;
    sl_scene s = box_scene(0xFFFFFFFFu);
    sl_error err;
    bool device = sl_renderer_probe(SL_GL_CONTEXT_DEVICE, &err) == SL_OK;
    if (!device) {
        print_message("no EGL device with a hardware driver: %s\n", err.message);
        assert_non_null(strstr(err.message, "device platform"));
    }
    bool surfaceless = sl_renderer_probe(SL_GL_CONTEXT_SURFACELESS, &err) == SL_OK;
    sl_gl_context_kind kinds[3] = {SL_GL_CONTEXT_AUTO, SL_GL_CONTEXT_DEVICE, SL_GL_CONTEXT_SURFACELESS};
    for (int k = 0; k < 3; k++) {
        if ((kinds[k] == SL_GL_CONTEXT_DEVICE && !device) || (kinds[k] == SL_GL_CONTEXT_SURFACELESS && !surfaceless))
            continue;
        sl_renderer_options o;
        sl_renderer_options_default(&o);
        o.width = 16;
        o.height = 12;
        o.context = kinds[k];
        sl_renderer r;
        assert_int_equal(sl_renderer_create(s, &o, NULL, &r, &err), SL_OK);
        sl_renderer_info info;
        sl_renderer_get_info(r, &info);
        sl_gl_context_kind want = kinds[k] != SL_GL_CONTEXT_AUTO ? kinds[k]
                                  : device ? SL_GL_CONTEXT_DEVICE : SL_GL_CONTEXT_SURFACELESS;
        assert_int_equal(info.context, want);
        print_message("context %d: %s (%s)\n", (int)kinds[k], info.renderer, info.version);
        sl_renderer_destroy(r);
    }
    sl_scene_destroy(s);
}

/* ---- frames decided by a culler ---- */

static void test_frame_with_culler(void **state)
{
    (void)state;
    sl_scene s;
    sl_path p;
    sl_error err;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, 3, 9, 128, 96, &s, &p, &err), SL_OK);
    sl_renderer r = make_renderer(s, 128, 96, NULL);
    sl_culler c;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *set = malloc((size_t)n * 4), *want = malloc((size_t)n * 4);
    uint32_t *ids_a = malloc(128 * 96 * 4), *ids_b = malloc(128 * 96 * 4);
    for (uint32_t k = 0; k < sl_path_count(p); k++) {
        sl_camera cam = sl_path_camera(p, k);
        sl_view v;
        assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
        uint32_t count = 0, wcount = 0;
        sl_render_frame_stats st;
        assert_int_equal(sl_renderer_frame(r, c, &v, SL_RENDER_IDS, set, &count, &st, &err), SL_OK);
        assert_int_equal(sl_culler_cull_view(c, &v, want, n, &wcount, &err), SL_OK);
        assert_int_equal(count, wcount);
        assert_memory_equal(set, want, (size_t)count * 4);
        assert_int_equal(st.objects_drawn, count);
        assert_true(st.frame_ms >= st.cull_ms);
        assert_int_equal(st.cull.objects_visible, count);
        assert_int_equal(sl_renderer_read_ids(r, ids_a, &err), SL_OK);
        /* vfc drops nothing that shows: the image of drawing everything */
        assert_int_equal(sl_renderer_frame(r, NULL, &v, SL_RENDER_IDS, NULL, NULL, &st, &err), SL_OK);
        assert_int_equal(st.objects_drawn, n);
        assert_int_equal(sl_renderer_read_ids(r, ids_b, &err), SL_OK);
        assert_memory_equal(ids_a, ids_b, 128 * 96 * 4);
    }
    free(set);
    free(want);
    free(ids_a);
    free(ids_b);
    sl_culler_destroy(c);
    sl_renderer_destroy(r);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

int main(void)
{
    sl_error err;
    if (sl_renderer_probe(SL_GL_CONTEXT_AUTO, &err) != SL_OK) {
        printf("skipped: no headless GL context: %s\n", err.message);
        return 77;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box_pixels),
        cmocka_unit_test(test_ids_match_oracle_city),
        cmocka_unit_test(test_ids_match_oracle_map),
        cmocka_unit_test(test_gl_errors_reported),
        cmocka_unit_test(test_resize_and_png),
        cmocka_unit_test(test_facing_rule),
        cmocka_unit_test(test_two_renderers),
        cmocka_unit_test(test_scene_changed),
        cmocka_unit_test(test_context_kinds),
        cmocka_unit_test(test_depth_prepass),
        cmocka_unit_test(test_present_and_current_context),
        cmocka_unit_test(test_frame_with_culler),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

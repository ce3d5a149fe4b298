/* The renderer's materials (include/sightline/render.h, docs/render.md): base colours, base-colour
 * textures decoded with stb_image and mapped by the meshes' UVs, alpha-tested (mask) and blended
 * materials drawn see-through (no depth, no id: the GL id image still equals the oracle's, which
 * holds solid objects only). Exits 77 (skipped) only when no GL context can be made. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sightline/image.h"
#include "sightline/render.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"

#define W 64
#define H 48

static char dir[256];

/* A quad in the plane x = 5 over y in [y0, y0 + 2], z in [-1, 1], u along y, v along z. */
static uint32_t add_quad(sl_scene s, float y0)
{
    float p[12] = {5, y0, -1, 5, y0 + 2, -1, 5, y0 + 2, 1, 5, y0, 1};
    float uv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
    uint32_t idx[6] = {0, 1, 2, 0, 2, 3}, mesh;
    sl_mesh_desc md = {p, NULL, 4, idx, 2, uv};
    sl_error err;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    return mesh;
}

/* 0: a green solid wall at x in [9, 11]; 1: a quad with a masked texture (u < 0.5 red, the rest
 * transparent) at y in [0.3, 2.3] (left of the centre); 2: a quad of a blended half-transparent
 * white material at y in [-2.3, -0.3] (right of it). */
static sl_scene material_scene(void)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint8_t tex[4 * 4 * 4];
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 4; x++) {
            uint8_t *t = tex + 4 * (y * 4 + x);
            t[0] = 255, t[1] = 0, t[2] = 0, t[3] = x < 2 ? 255 : 0;
        }
    char file[320];
    snprintf(file, sizeof file, "%s/mask.png", dir);
    assert_int_equal(sl_png_write(file, 4, 4, 4, tex, 0, &err), SL_OK);
    assert_int_equal(sl_scene_set_base_dir(s, dir, &err), SL_OK);
    float p[24];
    sl_test_box_vertices((sl_vec3){9, -6, -6}, (sl_vec3){11, 6, 6}, p);
    sl_mesh_desc md = {p, NULL, 8, sl_test_box_indices, 12, NULL};
    uint32_t wall, masked, blended;
    assert_int_equal(sl_scene_add_mesh(s, &md, &wall, &err), SL_OK);
    masked = add_quad(s, 0.3f);
    blended = add_quad(s, -2.3f);
    sl_material mm = {{1, 1, 1, 1}, "mask.png", SL_ALPHA_MASK, 0.5f, 0};
    sl_material mb = {{1, 1, 1, 0.5f}, NULL, SL_ALPHA_BLEND, 0.5f, 0};
    uint32_t mat_mask, mat_blend;
    assert_int_equal(sl_scene_add_material(s, &mm, &mat_mask, &err), SL_OK);
    assert_int_equal(sl_scene_add_material(s, &mb, &mat_blend, &err), SL_OK);
    sl_object_desc o0 = {wall, NULL, 0x20C040FFu, SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER, 0};
    sl_object_desc o1 = {masked, NULL, 0xFFFFFFFFu, SL_KIND_OTHER, 0, mat_mask};
    sl_object_desc o2 = {blended, NULL, 0xFFFFFFFFu, SL_KIND_OTHER, 0, mat_blend};
    assert_int_equal(sl_scene_add_object(s, &o0, NULL, &err), SL_OK);
    assert_int_equal(sl_scene_add_object(s, &o1, NULL, &err), SL_OK);
    assert_int_equal(sl_scene_add_object(s, &o2, NULL, &err), SL_OK);
    assert_true(sl_scene_object(s, 1).flags & SL_OBJECT_SEE_THROUGH);
    assert_true(sl_scene_object(s, 2).flags & SL_OBJECT_SEE_THROUGH);
    return s;
}

static sl_view the_view(void)
{
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 0};
    cam.yaw = cam.pitch = cam.roll = 0;
    cam.fov_y = 1.0f;
    cam.near_plane = 0.1f;
    cam.far_plane = 100.0f;
    cam.width = W;
    cam.height = H;
    sl_view v;
    sl_error err;
    assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
    return v;
}

static sl_renderer renderer(sl_scene s, bool textures)
{
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = W;
    o.height = H;
    o.textures = textures;
    o.sun_direction[0] = -1; /* towards the camera: every face seen lit by base * 0.92 */
    sl_renderer r;
    sl_error err;
    if (sl_renderer_create(s, &o, NULL, &r, &err) != SL_OK)
        fail_msg("%s", err.message);
    return r;
}

static const uint8_t *px(const uint8_t *rgba, int x, int y) { return rgba + 4 * (y * W + x); }
static bool near(int a, double b) { return fabs(a - b) <= 4.0; }

static void test_materials(void **state)
{
    (void)state;
    sl_scene s = material_scene();
    sl_renderer r = renderer(s, true);
    sl_view v = the_view();
    sl_error err;
    uint32_t all[3] = {0, 1, 2}, ids[W * H];
    uint8_t rgba[W * H * 4];
    float depth[W * H];
    sl_render_frame_stats st;
    assert_int_equal(sl_renderer_draw(r, &v, all, 3, SL_RENDER_SHADED, &st, &err), SL_OK);
    assert_int_equal(st.objects_drawn, 3);
    assert_int_equal(sl_renderer_read_rgba(r, rgba, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(r, depth, &err), SL_OK);
    sl_renderer_info info;
    sl_renderer_get_info(r, &info);
    assert_true(info.texture_bytes > 0);
    const double k = 0.92;
    /* the wall where nothing is in front of it */
    const uint8_t *c = px(rgba, 32, 40);
    assert_true(near(c[0], 0x20 * k) && near(c[1], 0xC0 * k) && near(c[2], 0x40 * k));
    /* the masked quad's opaque half: the texture's red */
    c = px(rgba, 25, 24);
    print_message("masked, opaque half: %d %d %d\n", c[0], c[1], c[2]);
    assert_true(near(c[0], 255 * k) && c[1] < 10 && c[2] < 10);
    /* its transparent half is alpha-tested away: the wall shows */
    c = px(rgba, 15, 24);
    print_message("masked, transparent half: %d %d %d\n", c[0], c[1], c[2]);
    assert_true(near(c[0], 0x20 * k) && near(c[1], 0xC0 * k) && near(c[2], 0x40 * k));
    /* the blended quad: half white over the wall */
    c = px(rgba, 44, 24);
    print_message("blended: %d %d %d\n", c[0], c[1], c[2]);
    assert_true(near(c[0], 0.5 * 255 * k + 0.5 * 0x20 * k) && near(c[1], 0.5 * 255 * k + 0.5 * 0xC0 * k));
    /* see-through objects write no id and no depth: the wall's, everywhere they are */
    assert_int_equal(ids[24 * W + 25], 0);
    assert_int_equal(ids[24 * W + 44], 0);
    assert_true(fabsf(depth[24 * W + 25] - depth[40 * W + 32]) < 1e-3f);
    /* the oracle's id image is the same */
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render_view(o, &v, &fr, &err), SL_OK);
    sl_oracle_view ov;
    assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
    assert_int_equal(sl_renderer_draw(r, &v, all, 3, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(r, ids, &err), SL_OK);
    assert_memory_equal(ids, ov.ids, sizeof ids);
    sl_oracle_destroy(o);
    sl_renderer_destroy(r);
    /* textures off: the material's colour (white) where the texture was red, and no alpha test */
    r = renderer(s, false);
    assert_int_equal(sl_renderer_draw(r, &v, all, 3, SL_RENDER_SHADED, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_rgba(r, rgba, &err), SL_OK);
    c = px(rgba, 15, 24);
    assert_true(near(c[0], 255 * k) && near(c[1], 255 * k) && near(c[2], 255 * k));
    sl_renderer_get_info(r, &info);
    assert_true(info.texture_bytes == 0);
    assert_string_equal(info.texture_warning, "");
    sl_renderer_destroy(r);
    /* a texture that does not decode: a warning naming it, and the material's colour */
    char file[320];
    snprintf(file, sizeof file, "%s/mask.png", dir);
    FILE *f = fopen(file, "wb");
    assert_non_null(f);
    fputs("not a PNG", f);
    fclose(f);
    r = renderer(s, true);
    sl_renderer_get_info(r, &info);
    print_message("warning: %s\n", info.texture_warning);
    assert_non_null(strstr(info.texture_warning, "mask.png"));
    assert_int_equal(sl_renderer_draw(r, &v, all, 3, SL_RENDER_SHADED, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_rgba(r, rgba, &err), SL_OK);
    c = px(rgba, 15, 24);
    assert_true(near(c[0], 255 * k) && near(c[1], 255 * k) && near(c[2], 255 * k));
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

int main(void)
{
    sl_error err;
    if (sl_renderer_probe(SL_GL_CONTEXT_AUTO, &err) != SL_OK) {
        printf("skipped: no headless GL context: %s\n", err.message);
        return 77;
    }
    snprintf(dir, sizeof dir, "%s/test_render_material_%d", SL_BINARY_DIR, (int)getpid());
    mkdir(dir, 0755);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_materials),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char file[320];
    snprintf(file, sizeof file, "%s/mask.png", dir);
    unlink(file);
    rmdir(dir);
    return rc;
}

/* Materials, UVs and texture paths through the assimp importer (docs/import-export.md,
 * "Materials"), in a child process (the default) and in process:
 *  - tests/data/material/materials.gltf (hand-written; its buffer is assimp's own
 *    BoxTextured0.bin, copied next to it at run time): a MASK material with cutoff 0.3, a texture
 *    inside the folder and doubleSided; a BLEND one whose texture leaves the folder (dropped and
 *    counted); an opaque one with an embedded image (dropped: not supported); a plain colour;
 *  - tests/data/material/transparent.obj: "d 0.5" (blend) and a map_Kd written with a backslash;
 *  - assimp's test models (assimp-testmodels): BoxTextured (its texture resolves to the real file)
 *    and ClearCoatTest (a BLEND material: a see-through object).
 * Colours, alpha modes, cutoffs, texture paths, UVs and the see-through flag come through, and
 * survive a .slscene round trip. Skipped when assimp's test models are not installed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sightline/import.h"
#include "sightline/slscene.h"

#define MODELS "/usr/share/assimp/models/glTF2/"
#define DATA SL_SOURCE_DIR "/tests/data/material/"

static sl_error g_err;
#define E (&g_err)
#define OK(x)                                                                                                          \
    do {                                                                                                               \
        sl_status st_ = (x);                                                                                           \
        if (st_ != SL_OK)                                                                                              \
            fail_msg("%s: %s", #x, g_err.message);                                                                     \
    } while (0)

static char g_dir[64];

static void copy(const char *from, const char *to)
{
    FILE *a = fopen(from, "rb"), *b = fopen(to, "wb");
    if (!a || !b)
        fail_msg("copy %s -> %s", from, to);
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, a)) > 0)
        assert_int_equal(fwrite(buf, 1, n, b), n);
    fclose(a);
    fclose(b);
}

static int setup(void **state)
{
    (void)state;
    struct stat sb;
    if (stat(MODELS "BoxTextured-glTF/BoxTextured0.bin", &sb) != 0)
        return 0; /* the tests skip */
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_matimp_XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    char p[256], q[256];
    snprintf(p, sizeof p, "%s/model", g_dir);
    mkdir(p, 0755);
    snprintf(p, sizeof p, "%s/model/tex", g_dir);
    mkdir(p, 0755);
    static const char *const files[] = {"materials.gltf", "transparent.obj", "transparent.mtl"};
    for (size_t i = 0; i < sizeof files / sizeof *files; i++) {
        snprintf(p, sizeof p, DATA "%s", files[i]);
        snprintf(q, sizeof q, "%s/model/%s", g_dir, files[i]);
        copy(p, q);
    }
    snprintf(q, sizeof q, "%s/model/BoxTextured0.bin", g_dir);
    copy(MODELS "BoxTextured-glTF/BoxTextured0.bin", q);
    snprintf(q, sizeof q, "%s/model/tex/logo.png", g_dir);
    copy(MODELS "BoxTextured-glTF/CesiumLogoFlat.png", q);
    snprintf(q, sizeof q, "%s/outside.png", g_dir); /* exists, but outside the model's folder */
    copy(MODELS "BoxTextured-glTF/CesiumLogoFlat.png", q);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    if (g_dir[0]) {
        char cmd[128];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
        if (system(cmd) != 0)
            return -1;
    }
    return 0;
}

static void need_models(void)
{
    if (!g_dir[0])
        skip(); /* assimp-testmodels not installed */
}

/* The object whose node was named `name` (objects are nodes in depth-first order: by position). */
static void check_materials_gltf(sl_scene s, bool from_file)
{
    assert_int_equal(sl_scene_object_count(s), 4);
    assert_int_equal(sl_scene_material_count(s), 4);
    sl_material m[4];
    for (uint32_t i = 0; i < 4; i++) {
        sl_object_view ov = sl_scene_object(s, i);
        assert_true(sl_scene_material(s, ov.material, &m[i]));
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        assert_non_null(mv.uvs); /* TEXCOORD_0 */
        float umax = 0;
        for (uint32_t v = 0; v < mv.vertex_count; v++)
            umax = fmaxf(umax, mv.uvs[2 * v]);
        assert_true(umax == 6.0f); /* the accessor's max */
        bool see = (ov.flags & SL_OBJECT_SEE_THROUGH) != 0;
        assert_int_equal(see, i < 2);
        assert_int_equal(ov.flags & SL_OBJECT_OCCLUDER, 0);
    }
    /* leaves: MASK 0.3, double-sided, its texture inside the folder */
    assert_int_equal(m[0].alpha_mode, SL_ALPHA_MASK);
    assert_true(fabsf(m[0].alpha_cutoff - 0.3f) < 1e-6f);
    assert_int_equal(m[0].flags, SL_MATERIAL_DOUBLE_SIDED);
    assert_true(m[0].base_color[0] == 0.5f && m[0].base_color[1] == 1.0f);
    assert_non_null(m[0].base_color_texture);
    assert_string_equal(m[0].base_color_texture, "tex/logo.png");
    /* glass: BLEND, alpha 0.4, its texture "../outside.png" dropped */
    assert_int_equal(m[1].alpha_mode, SL_ALPHA_BLEND);
    assert_true(fabsf(m[1].base_color[3] - 0.4f) < 1e-6f);
    assert_null(m[1].base_color_texture);
    /* painted: opaque, embedded image dropped */
    assert_int_equal(m[2].alpha_mode, SL_ALPHA_OPAQUE);
    assert_null(m[2].base_color_texture);
    /* plain: red */
    assert_true(m[3].base_color[0] == 1.0f && m[3].base_color[1] == 0.0f);
    assert_string_equal(sl_scene_meta(s, "assimp.textures_dropped"), "1");
    assert_string_equal(sl_scene_meta(s, "assimp.textures_embedded"), "1");
    assert_non_null(strstr(sl_scene_meta(s, "assimp.textures_dropped.first"), "'..'"));
    /* the texture resolves inside the model's folder */
    char buf[PATH_MAX], want[PATH_MAX], p[256];
    snprintf(p, sizeof p, "%s/model/tex/logo.png", g_dir);
    assert_non_null(realpath(p, want));
    OK(sl_scene_texture_path(s, sl_scene_object(s, 0).material, buf, sizeof buf, E));
    assert_string_equal(buf, want);
    (void)from_file;
}

static void test_gltf(void **state)
{
    (void)state;
    need_models();
    char path[256], out[256];
    snprintf(path, sizeof path, "%s/model/materials.gltf", g_dir);
    for (int in_process = 0; in_process < 2; in_process++) {
        sl_import_options o = sl_import_defaults();
        o.in_process = in_process;
        sl_scene s;
        OK(sl_import_assimp(path, &o, NULL, &s, E));
        char dir[256];
        snprintf(dir, sizeof dir, "%s/model", g_dir);
        assert_string_equal(sl_scene_base_dir(s), dir);
        check_materials_gltf(s, false);
        /* .slscene next to the model: everything comes back, textures still resolve */
        snprintf(out, sizeof out, "%s/model/materials.slscene", g_dir);
        OK(sl_scene_save(s, out, E));
        sl_scene_destroy(s);
        OK(sl_scene_load(out, NULL, NULL, &s, E));
        check_materials_gltf(s, true);
        sl_scene_destroy(s);
        /* and split into pieces, UVs follow their vertices */
        o.split_triangles = 4;
        OK(sl_import_assimp(path, &o, NULL, &s, E));
        assert_true(sl_scene_object_count(s) > 4);
        for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
            sl_mesh_view mv = sl_scene_mesh(s, sl_scene_object(s, i).mesh);
            assert_non_null(mv.uvs);
            for (uint32_t v = 0; v < mv.vertex_count; v++)
                assert_true(mv.uvs[2 * v] >= 0.0f && mv.uvs[2 * v] <= 6.0f && mv.uvs[2 * v + 1] >= 0.0f &&
                            mv.uvs[2 * v + 1] <= 1.0f);
        }
        sl_scene_destroy(s);
    }
}

static void test_obj(void **state)
{
    (void)state;
    need_models();
    char path[256];
    snprintf(path, sizeof path, "%s/model/transparent.obj", g_dir);
    sl_scene s;
    OK(sl_import_assimp(path, NULL, NULL, &s, E));
    assert_int_equal(sl_scene_object_count(s), 1);
    sl_object_view ov = sl_scene_object(s, 0);
    sl_material m;
    assert_true(sl_scene_material(s, ov.material, &m));
    assert_int_equal(m.alpha_mode, SL_ALPHA_BLEND); /* d 0.5 */
    assert_true(fabsf(m.base_color[3] - 0.5f) < 1e-6f && fabsf(m.base_color[0] - 0.6f) < 1e-6f);
    assert_string_equal(m.base_color_texture, "tex/window.png"); /* backslash turned into '/' */
    assert_true(ov.flags & SL_OBJECT_SEE_THROUGH);
    assert_non_null(sl_scene_mesh(s, ov.mesh).uvs);
    char buf[PATH_MAX];
    assert_int_equal(sl_scene_texture_path(s, ov.material, buf, sizeof buf, E), SL_ERROR_NOT_FOUND); /* no such file */
    sl_scene_destroy(s);
}

static void test_assimp_models(void **state)
{
    (void)state;
    need_models();
    sl_scene s;
    OK(sl_import_assimp(MODELS "BoxTextured-glTF/BoxTextured.gltf", NULL, NULL, &s, E));
    assert_int_equal(sl_scene_material_count(s), 1);
    sl_object_view ov = sl_scene_object(s, 0);
    sl_material m;
    assert_true(sl_scene_material(s, ov.material, &m));
    assert_string_equal(m.base_color_texture, "CesiumLogoFlat.png");
    assert_int_equal(m.alpha_mode, SL_ALPHA_OPAQUE);
    assert_int_equal(ov.flags & SL_OBJECT_SEE_THROUGH, 0);
    char buf[PATH_MAX];
    OK(sl_scene_texture_path(s, ov.material, buf, sizeof buf, E));
    assert_string_equal(buf, MODELS "BoxTextured-glTF/CesiumLogoFlat.png");
    assert_int_equal(sl_scene_mesh(s, ov.mesh).vertex_count, 24);
    assert_non_null(sl_scene_mesh(s, ov.mesh).uvs);
    sl_scene_destroy(s);

    OK(sl_import_assimp(MODELS "ClearCoat-glTF/ClearCoatTest.gltf", NULL, NULL, &s, E));
    uint32_t blend = 0, see = 0, textured = 0;
    for (uint32_t i = 1; i <= sl_scene_material_count(s); i++) {
        assert_true(sl_scene_material(s, i, &m));
        blend += m.alpha_mode == SL_ALPHA_BLEND;
        if (m.base_color_texture) {
            textured++;
            OK(sl_scene_texture_path(s, i, buf, sizeof buf, E));
        }
    }
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        ov = sl_scene_object(s, i);
        if (ov.flags & SL_OBJECT_SEE_THROUGH) {
            see++;
            assert_true(sl_scene_material(s, ov.material, &m));
            assert_int_equal(m.alpha_mode, SL_ALPHA_BLEND);
        }
    }
    print_message("ClearCoatTest: %u materials (%u blend, %u with a base-colour texture), %u objects (%u see-through)\n",
                  sl_scene_material_count(s), blend, textured, sl_scene_object_count(s), see);
    assert_true(blend >= 1);
    assert_true(see >= 1);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_gltf),
        cmocka_unit_test(test_obj),
        cmocka_unit_test(test_assimp_models),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

/* Materials, UVs and texture paths in the scene model and in .slscene files (scene.h, issue 15 §1):
 *  - sl_scene_add_material validates (colour and cutoff in [0, 1], alpha mode, flags, texture path
 *    rules) and numbers materials from 1; objects refer to them (0 / SL_NONE: none); a mask or
 *    blend material makes its object see-through;
 *  - per-vertex UVs (meshes with and without in one scene);
 *  - sl_scene_texture_path resolves inside the base folder and refuses a symbolic link leading out;
 *  - .slscene 1.1 round trip (same bytes twice, everything read back), a 1.0 file
 *    (tests/data/scene_v1_0.slscene, written by the 1.0 writer) still loads, and hostile edits of the
 *    new sections (with fixed checksums) are refused naming the element and the reason. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/slscene.h"

#define SL_TEST_DATA_DIR SL_SOURCE_DIR "/tests/data"

static sl_error g_err;
#define E (&g_err)
#define OK(x)                                                                                                          \
    do {                                                                                                               \
        sl_status st_ = (x);                                                                                           \
        if (st_ != SL_OK)                                                                                              \
            fail_msg("%s: %s", #x, g_err.message);                                                                     \
    } while (0)

static const float k_quad_p[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
static const float k_quad_uv[] = {0, 0, 1, 0, 1, 1, 0, 1};
static const uint32_t k_quad_i[] = {0, 1, 2, 0, 2, 3};

static uint32_t add_quad(sl_scene s, const float *uvs)
{
    sl_mesh_desc md = {k_quad_p, NULL, 4, k_quad_i, 2, uvs};
    uint32_t m;
    OK(sl_scene_add_mesh(s, &md, &m, E));
    return m;
}

static uint32_t add_obj(sl_scene s, uint32_t mesh, uint32_t flags, uint32_t material)
{
    sl_object_desc od = {mesh, NULL, 0x336699ffu, SL_KIND_IMPORTED, flags, material};
    uint32_t id;
    OK(sl_scene_add_object(s, &od, &id, E));
    return id;
}

/* A scene with three materials, meshes with and without UVs, objects with and without materials. */
static sl_scene build(void)
{
    sl_scene s;
    OK(sl_scene_create(NULL, &s, E));
    uint32_t m0 = add_quad(s, NULL), m1 = add_quad(s, k_quad_uv), m2 = add_quad(s, NULL);
    sl_material opaque = {{1, 0.5f, 0.25f, 1}, "textures/brick.png", SL_ALPHA_OPAQUE, 0.5f, 0};
    sl_material mask = {{1, 1, 1, 1}, "leaves 01.png", SL_ALPHA_MASK, 0.3f, SL_MATERIAL_DOUBLE_SIDED};
    sl_material blend = {{0.2f, 0.4f, 0.9f, 0.4f}, NULL, SL_ALPHA_BLEND, 0.5f, 0};
    uint32_t a, b, c;
    OK(sl_scene_add_material(s, &opaque, &a, E));
    OK(sl_scene_add_material(s, &mask, &b, E));
    OK(sl_scene_add_material(s, &blend, &c, E));
    assert_int_equal(a, 1);
    assert_int_equal(c, 3);
    add_obj(s, m0, SL_OBJECT_OCCLUDER, 0);           /* 0: no material */
    add_obj(s, m1, SL_OBJECT_OCCLUDER, a);           /* 1: opaque: stays an occluder */
    add_obj(s, m1, SL_OBJECT_OCCLUDER, b);           /* 2: mask: see-through, not an occluder */
    add_obj(s, m2, SL_OBJECT_CLOSED_CONVEX, c);      /* 3: blend */
    add_obj(s, m2, 0, SL_NONE);                      /* 4: SL_NONE = none */
    OK(sl_scene_set_meta(s, "source", "test", E));
    return s;
}

static void check_built(sl_scene s)
{
    assert_int_equal(sl_scene_material_count(s), 3);
    sl_material m;
    assert_false(sl_scene_material(s, 0, &m));
    assert_false(sl_scene_material(s, 4, &m));
    assert_true(sl_scene_material(s, 1, &m));
    assert_string_equal(m.base_color_texture, "textures/brick.png");
    assert_true(m.base_color[1] == 0.5f && m.base_color[2] == 0.25f);
    assert_int_equal(m.alpha_mode, SL_ALPHA_OPAQUE);
    assert_true(sl_scene_material(s, 2, &m));
    assert_string_equal(m.base_color_texture, "leaves 01.png");
    assert_int_equal(m.alpha_mode, SL_ALPHA_MASK);
    assert_true(m.alpha_cutoff == 0.3f);
    assert_int_equal(m.flags, SL_MATERIAL_DOUBLE_SIDED);
    assert_true(sl_scene_material(s, 3, &m));
    assert_null(m.base_color_texture);
    assert_true(m.base_color[3] == 0.4f);
    static const uint32_t want_mat[5] = {0, 1, 2, 3, 0};
    static const uint32_t want_flags[5] = {SL_OBJECT_OCCLUDER, SL_OBJECT_OCCLUDER, SL_OBJECT_SEE_THROUGH,
                                           SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_SEE_THROUGH, 0};
    for (uint32_t i = 0; i < 5; i++) {
        sl_object_view ov = sl_scene_object(s, i);
        assert_int_equal(ov.material, want_mat[i]);
        assert_int_equal(sl_scene_object_material(s, i), want_mat[i]);
        assert_int_equal(ov.flags, want_flags[i]);
    }
    assert_null(sl_scene_mesh(s, 0).uvs);
    const float *uv = sl_scene_mesh(s, 1).uvs;
    assert_non_null(uv);
    assert_memory_equal(uv, k_quad_uv, sizeof k_quad_uv);
    assert_null(sl_scene_mesh(s, 2).uvs);
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    assert_int_equal(st.material_count, 3);
    assert_int_equal(st.see_through_count, 2);
    assert_int_equal(st.uv_mesh_count, 1);
}

static void test_model(void **state)
{
    (void)state;
    sl_scene s = build();
    check_built(s);
    /* validation */
    static const struct {
        sl_material m;
        const char *why;
    } bad[] = {
        {{{1.5f, 0, 0, 1}, NULL, 0, 0.5f, 0}, "base colour"},
        {{{NAN, 0, 0, 1}, NULL, 0, 0.5f, 0}, "base colour"},
        {{{1, 1, 1, 1}, NULL, 3, 0.5f, 0}, "alpha mode"},
        {{{1, 1, 1, 1}, NULL, SL_ALPHA_MASK, -0.1f, 0}, "cutoff"},
        {{{1, 1, 1, 1}, NULL, 0, 0.5f, 2}, "flag"},
        {{{1, 1, 1, 1}, "../up.png", 0, 0.5f, 0}, "'..'"},
        {{{1, 1, 1, 1}, "a/../../b.png", 0, 0.5f, 0}, "'..'"},
        {{{1, 1, 1, 1}, "/etc/passwd", 0, 0.5f, 0}, "absolute"},
        {{{1, 1, 1, 1}, "a//b.png", 0, 0.5f, 0}, "empty component"},
        {{{1, 1, 1, 1}, "./b.png", 0, 0.5f, 0}, "'.'"},
        {{{1, 1, 1, 1}, "a\\b.png", 0, 0.5f, 0}, "backslash"},
        {{{1, 1, 1, 1}, "a\nb.png", 0, 0.5f, 0}, "control"},
        {{{1, 1, 1, 1}, "dir/", 0, 0.5f, 0}, "empty component"},
    };
    for (size_t i = 0; i < SL_COUNTOF(bad); i++) {
        if (sl_scene_add_material(s, &bad[i].m, NULL, E) != SL_ERROR_INVALID_ARGUMENT)
            fail_msg("bad material %zu accepted", i);
        if (!strstr(g_err.message, bad[i].why))
            fail_msg("bad material %zu: \"%s\" does not say %s", i, g_err.message, bad[i].why);
    }
    char longp[SL_TEXTURE_PATH_MAX + 2];
    memset(longp, 'a', sizeof longp - 1);
    longp[sizeof longp - 1] = 0;
    sl_material lm = {{1, 1, 1, 1}, longp, 0, 0.5f, 0};
    assert_int_equal(sl_scene_add_material(s, &lm, NULL, E), SL_ERROR_INVALID_ARGUMENT);
    longp[SL_TEXTURE_PATH_MAX] = 0;
    assert_true(sl_texture_path_check(longp, NULL));
    const char *why;
    assert_false(sl_texture_path_check("x/..", &why));
    assert_non_null(why);
    assert_int_equal(sl_scene_material_count(s), 3); /* nothing half-added */
    /* an object naming a material that does not exist */
    sl_object_desc od = {0, NULL, 0, 0, 0, 9};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, E), SL_ERROR_INVALID_ARGUMENT);
    float nan_uv[8] = {0, 0, 1, 0, NAN, 1, 0, 1};
    sl_mesh_desc md = {k_quad_p, NULL, 4, k_quad_i, 2, nan_uv};
    assert_int_equal(sl_scene_add_mesh(s, &md, NULL, E), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(g_err.message, "uv"));
    /* the see-through rule: no footprint or occluder for see-through object 2 */
    float xy[6] = {0, 0, 1, 0, 0, 1};
    sl_footprint_desc fd = {xy, 3, 0, 1, 2};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, E), SL_ERROR_INVALID_ARGUMENT);
    fd.object = 1;
    OK(sl_scene_add_footprint(s, &fd, NULL, E));
    assert_int_equal(sl_scene_add_occluder(s, 0, NULL, 3, E), SL_ERROR_INVALID_ARGUMENT);
    OK(sl_scene_add_occluder(s, 0, NULL, 0, E));
    sl_scene_destroy(s);
}

static void test_texture_path(void **state)
{
    (void)state;
    char t[] = "/tmp/sl_material_XXXXXX";
    assert_non_null(mkdtemp(t));
    char model[PATH_MAX], outside[PATH_MAX], p[PATH_MAX + 64];
    snprintf(model, sizeof model, "%s/model", t);
    snprintf(outside, sizeof outside, "%s/secret.png", t);
    assert_int_equal(mkdir(model, 0755), 0);
    snprintf(p, sizeof p, "%s/textures", model);
    assert_int_equal(mkdir(p, 0755), 0);
    snprintf(p, sizeof p, "%s/textures/brick.png", model);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    fclose(f);
    f = fopen(outside, "wb");
    assert_non_null(f);
    fclose(f);
    snprintf(p, sizeof p, "%s/leaves 01.png", model);
    assert_int_equal(symlink("../secret.png", p), 0); /* a link leading out of the model's folder */

    sl_scene s = build();
    char buf[PATH_MAX];
    assert_null(sl_scene_base_dir(s));
    assert_int_equal(sl_scene_texture_path(s, 1, buf, sizeof buf, E), SL_ERROR_NOT_FOUND); /* no base folder */
    OK(sl_scene_set_base_dir(s, model, E));
    assert_string_equal(sl_scene_base_dir(s), model);
    OK(sl_scene_texture_path(s, 1, buf, sizeof buf, E));
    char real[PATH_MAX];
    snprintf(p, sizeof p, "%s/textures/brick.png", model);
    assert_non_null(realpath(p, real));
    assert_string_equal(buf, real);
    assert_int_equal(sl_scene_texture_path(s, 1, buf, 4, E), SL_ERROR_LIMIT);
    assert_int_equal(sl_scene_texture_path(s, 2, buf, sizeof buf, E), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(g_err.message, "outside the base folder"));
    assert_int_equal(sl_scene_texture_path(s, 3, buf, sizeof buf, E), SL_ERROR_NOT_FOUND); /* no texture */
    assert_int_equal(sl_scene_texture_path(s, 0, buf, sizeof buf, E), SL_ERROR_NOT_FOUND);
    /* a .slscene's textures are relative to its own folder */
    snprintf(p, sizeof p, "%s/scene.slscene", model);
    OK(sl_scene_save(s, p, E));
    sl_scene_destroy(s);
    for (int map = 0; map < 2; map++) {
        sl_load_options lo;
        memset(&lo, 0, sizeof lo);
        lo.map = map;
        OK(sl_scene_load(p, &lo, NULL, &s, E));
        assert_string_equal(sl_scene_base_dir(s), model);
        check_built(s);
        OK(sl_scene_texture_path(s, 1, buf, sizeof buf, E));
        assert_string_equal(buf, real);
        sl_scene_destroy(s);
    }
    char cmd[PATH_MAX + 16];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", t);
    assert_int_equal(system(cmd), 0);
}

/* ---- files ---- */

enum { H_MINOR = 12, H_COUNT = 24, H_TABLE = 32, H_TABLE_HASH = 48, H_HASH = 56, ENTRY = 48, E_OFFSET = 16, E_SIZE = 24,
       E_HASH = 32 };
static uint32_t get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void put32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static void put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

static uint8_t *section(uint8_t *f, const char *tag, uint64_t *size)
{
    uint32_t n = get32(f + H_COUNT);
    uint64_t t = get64(f + H_TABLE);
    for (uint32_t i = 0; i < n; i++) {
        uint8_t *e = f + t + (size_t)i * ENTRY;
        if (memcmp(e, tag, 4) == 0) {
            if (size)
                *size = get64(e + E_SIZE);
            return f + get64(e + E_OFFSET);
        }
    }
    fail_msg("no section %s", tag);
    return NULL;
}

static void fix_checksums(uint8_t *f)
{
    uint32_t n = get32(f + H_COUNT);
    uint64_t t = get64(f + H_TABLE);
    for (uint32_t i = 0; i < n; i++) {
        uint8_t *e = f + t + (size_t)i * ENTRY;
        put64(e + E_HASH, sl_hash64(f + get64(e + E_OFFSET), get64(e + E_SIZE), 0));
    }
    put64(f + H_TABLE_HASH, sl_hash64(f + t, (size_t)n * ENTRY, 0));
    put64(f + H_HASH, sl_hash64(f, H_HASH, 0));
}

static uint8_t *read_all(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("cannot open %s", path);
    fseek(f, 0, SEEK_END);
    *n = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc(*n);
    assert_int_equal(fread(b, 1, *n, f), *n);
    fclose(f);
    return b;
}

static void expect_bad(const uint8_t *orig, size_t n, void (*edit)(uint8_t *), const char *want)
{
    uint8_t *f = malloc(n);
    memcpy(f, orig, n);
    edit(f);
    fix_checksums(f);
    sl_scene s = NULL;
    sl_status st = sl_scene_load_memory(f, n, "hostile.slscene", NULL, &s, E);
    if (st != SL_ERROR_FORMAT || !strstr(g_err.message, want) || !strstr(g_err.message, "hostile.slscene"))
        fail_msg("expected a format error saying \"%s\", got %d: %s", want, st, st ? g_err.message : "loaded");
    assert_null(s);
    free(f);
}

/* material records: base_color f32[4] at 0, alpha_mode at 16, cutoff at 20, flags 24, texture
 * offset 28, length 32, reserved 36 (docs/slscene-format.md) */
static void e_mode(uint8_t *f) { put32(section(f, "MATL", NULL) + 40 + 16, 7); }
static void e_cutoff(uint8_t *f) { float x = 2; memcpy(section(f, "MATL", NULL) + 40 + 20, &x, 4); }
static void e_reserved(uint8_t *f) { put32(section(f, "MATL", NULL) + 36, 1); }
static void e_tex_len(uint8_t *f) { put32(section(f, "MATL", NULL) + 40 + 32, 500); }
static void e_tex_off(uint8_t *f) { put32(section(f, "MATL", NULL) + 40 + 28, 3); }
static void e_tex_none(uint8_t *f) { put32(section(f, "MATL", NULL) + 80 + 28, 3); }
static void e_tex_dots(uint8_t *f) { memcpy(section(f, "MTEX", NULL), "../", 3); } /* "../tures/brick.png" */
static void e_tex_nul(uint8_t *f) { section(f, "MTEX", NULL)[18] = 'x'; } /* the NUL after "textures/brick.png" */
static void e_tex_ctrl(uint8_t *f) { section(f, "MTEX", NULL)[2] = 1; }
static void e_obj_mat(uint8_t *f) { put32(section(f, "OMAT", NULL) + 4, 4); }
static void e_obj_clear(uint8_t *f)
{
    /* object 2 (mask material) loses its see-through flag: flags at 12 of the 24-byte record */
    uint8_t *o = section(f, "OBJS", NULL) + 2 * 24 + 12;
    put32(o, get32(o) & ~(uint32_t)SL_OBJECT_SEE_THROUGH);
}
static void e_obj_both(uint8_t *f)
{
    uint8_t *o = section(f, "OBJS", NULL) + 2 * 24 + 12;
    put32(o, get32(o) | SL_OBJECT_OCCLUDER);
}
static void e_uv_nan(uint8_t *f) { float x = NAN; memcpy(section(f, "VUV0", NULL) + 4 * 9, &x, 4); }
static void e_uv_flag(uint8_t *f) { section(f, "MUVS", NULL)[0] = 2; }

static void test_files(void **state)
{
    (void)state;
    char t[] = "/tmp/sl_material_f_XXXXXX";
    assert_non_null(mkdtemp(t));
    char p1[PATH_MAX], p2[PATH_MAX];
    snprintf(p1, sizeof p1, "%s/a.slscene", t);
    snprintf(p2, sizeof p2, "%s/b.slscene", t);
    sl_scene s = build(), s2 = build();
    OK(sl_scene_save(s, p1, E));
    OK(sl_scene_save(s2, p2, E));
    size_t n1, n2;
    uint8_t *f1 = read_all(p1, &n1), *f2 = read_all(p2, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(f1, f2, n1); /* same scene in, same bytes out */
    assert_int_equal(get32(f1 + H_MINOR), 1);
    sl_scene l;
    OK(sl_scene_load_memory(f1, n1, "a", NULL, &l, E));
    check_built(l);
    assert_null(sl_scene_base_dir(l)); /* from memory: no folder */
    sl_scene_destroy(l);
    /* hostile edits of the 1.1 sections */
    expect_bad(f1, n1, e_mode, "material 2: unknown alpha mode");
    expect_bad(f1, n1, e_cutoff, "material 2: alpha cutoff");
    expect_bad(f1, n1, e_reserved, "material 1: reserved");
    expect_bad(f1, n1, e_tex_len, "material 2: texture path of 500 bytes at byte 19 runs past");
    expect_bad(f1, n1, e_tex_off, "material 2: texture offset 3, expected 19 (paths in material order)");
    expect_bad(f1, n1, e_tex_none, "material 3: no texture but a texture offset of 3");
    expect_bad(f1, n1, e_tex_dots, "material 1: texture path at byte 0 contains a '..' component");
    expect_bad(f1, n1, e_tex_nul, "not followed by a NUL");
    expect_bad(f1, n1, e_tex_ctrl, "control character");
    expect_bad(f1, n1, e_obj_mat, "object 1: material 4 out of range");
    expect_bad(f1, n1, e_obj_clear, "object 2: material 2 is alpha-tested or blended but the object is not see-through");
    expect_bad(f1, n1, e_obj_both, "object 2: flagged both see-through and occluder");
    expect_bad(f1, n1, e_uv_nan, "uv.v is not finite");
    expect_bad(f1, n1, e_uv_flag, "mesh 0: uv flag 2");
    /* a 1.0 file that carries a 1.1 section: unknown in a file of that version */
    {
        uint8_t *f = malloc(n1);
        memcpy(f, f1, n1);
        put32(f + H_MINOR, 0);
        fix_checksums(f);
        sl_scene x = NULL;
        assert_int_equal(sl_scene_load_memory(f, n1, "old.slscene", NULL, &x, E), SL_ERROR_FORMAT);
        assert_non_null(strstr(g_err.message, "unknown section 'MATL' in a version 1.0 file"));
        free(f);
    }
    free(f1);
    free(f2);
    sl_scene_destroy(s);
    sl_scene_destroy(s2);
    unlink(p1);
    unlink(p2);
    rmdir(t);
}

/* A file of the 1.0 writer (before materials and UVs) still loads: no materials, no UVs. */
static void test_version_1_0(void **state)
{
    (void)state;
    const char *path = SL_TEST_DATA_DIR "/scene_v1_0.slscene";
    size_t n;
    uint8_t *f = read_all(path, &n);
    assert_int_equal(get32(f + H_MINOR), 0);
    free(f);
    sl_scene s;
    OK(sl_scene_load(path, NULL, NULL, &s, E));
    assert_int_equal(sl_scene_object_count(s), 2);
    assert_int_equal(sl_scene_material_count(s), 0);
    assert_int_equal(sl_scene_object(s, 0).material, 0);
    assert_int_equal(sl_scene_object(s, 0).flags, SL_OBJECT_OCCLUDER);
    assert_null(sl_scene_mesh(s, 0).uvs);
    assert_int_equal(sl_scene_footprint_count(s), 1);
    assert_string_equal(sl_scene_meta(s, "generator"), "sightline 1.0 fixture");
    /* and it can gain materials and be saved as 1.1 */
    sl_material m = {{1, 1, 1, 1}, NULL, SL_ALPHA_BLEND, 0.5f, 0};
    uint32_t id;
    OK(sl_scene_add_material(s, &m, &id, E));
    add_obj(s, 0, SL_OBJECT_OCCLUDER, id);
    assert_int_equal(sl_scene_object(s, 2).flags, SL_OBJECT_SEE_THROUGH);
    assert_int_equal(sl_scene_object_material(s, 0), 0);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_model),
        cmocka_unit_test(test_texture_path),
        cmocka_unit_test(test_files),
        cmocka_unit_test(test_version_1_0),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

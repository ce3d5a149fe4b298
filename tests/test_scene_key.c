/* The scene key that ties a PVS and a bake journal to its scene (issue 12, §3b): it covers what
 * the methods read, not only boxes and counts. Triangles moved inside the same boxes change it
 * (and a journal of one scene is not resumed on the other, a file of one is refused for the
 * other); a changed BSP changes it; equal scenes built twice (in memory, generated, saved and
 * loaded) give the same key; a moving car does not change it; a file of format 1.0 (the old key)
 * and a journal of version 1 are refused with a message that says to bake again. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/gen.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/slscene.h"

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

/* Two leaves split at x = 0, each its own cluster, each holding one object: a quad of two
 * triangles whose inner vertices sit at `inner` (inside the same box whatever it is). */
typedef struct scene_opts {
    float inner;        /* x of the two middle vertices of object 0's strip, in (0, 4) */
    float plane_d;      /* the split plane's offset */
    uint8_t pvs1;       /* cluster 1's row of the cluster PVS */
} scene_opts;

static sl_scene make_scene(const scene_opts *o)
{
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* object 0: a strip of 4 triangles in x in [0.5, 4], z in [0, 2] at y = 1; the middle
     * column moves with o->inner, the box stays */
    float pos[18] = {0.5f, 1, 0, o->inner, 1, 0, 4, 1, 0, 0.5f, 1, 2, o->inner, 1, 2, 4, 1, 2};
    uint32_t idx[12] = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4};
    sl_mesh_desc md = {pos, NULL, 6, idx, 4, NULL};
    uint32_t m0, m1;
    assert_int_equal(sl_scene_add_mesh(s, &md, &m0, &err), SL_OK);
    float pos1[9] = {-3, -1, 0, -1, -1, 0, -2, -1, 2};
    uint32_t idx1[3] = {0, 1, 2};
    sl_mesh_desc md1 = {pos1, NULL, 3, idx1, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &md1, &m1, &err), SL_OK);
    sl_object_desc od0 = {m0, NULL, 0, SL_KIND_BSP_FACES, 0, 0};
    sl_object_desc od1 = {m1, NULL, 0, SL_KIND_BSP_FACES, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od0, NULL, &err), SL_OK);
    assert_int_equal(sl_scene_add_object(s, &od1, NULL, &err), SL_OK);
    sl_plane planes[1] = {{1, 0, 0, o->plane_d}};
    sl_bsp_node nodes[1] = {{0, {-1, -2}, {{-8, -8, -8}, {8, 8, 8}}}};
    sl_bsp_leaf leaves[2] = {{0, 0, {{0, -8, -8}, {8, 8, 8}}, 0, 1}, {1, 0, {{-8, -8, -8}, {0, 8, 8}}, 1, 1}};
    uint32_t leaf_objects[2] = {0, 1};
    uint8_t pvs[2] = {0x3, o->pvs1};
    sl_bsp_desc bd = {planes, 1, nodes, 1, leaves, 2, leaf_objects, 2, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    return s;
}

static const scene_opts k_base = {2.0f, 0.0f, 0x3};

static bool same_boxes(sl_scene a, sl_scene b)
{
    uint32_t n = sl_scene_object_count(a);
    if (n != sl_scene_object_count(b))
        return false;
    return memcmp(sl_scene_object_bounds_array(a), sl_scene_object_bounds_array(b), n * sizeof(sl_aabb)) == 0;
}

/* Triangles moved inside the same boxes: another key; equal scenes: the same key. */
static void test_moved_triangles(void **state)
{
    (void)state;
    sl_scene a = make_scene(&k_base), a2 = make_scene(&k_base);
    scene_opts moved = k_base;
    moved.inner = 3.0f;
    sl_scene b = make_scene(&moved);
    assert_true(same_boxes(a, b));
    assert_true(sl_pvs_scene_key(a) == sl_pvs_scene_key(a2));
    assert_true(sl_pvs_scene_key(a) != sl_pvs_scene_key(b));
    sl_scene_destroy(a);
    sl_scene_destroy(a2);
    sl_scene_destroy(b);
}

/* A changed BSP (a plane, a cluster PVS row) changes the key. */
static void test_bsp_changes_key(void **state)
{
    (void)state;
    sl_scene a = make_scene(&k_base);
    scene_opts o1 = k_base, o2 = k_base;
    o1.plane_d = 0.25f;
    o2.pvs1 = 0x2;
    sl_scene b1 = make_scene(&o1), b2 = make_scene(&o2);
    assert_true(same_boxes(a, b1) && same_boxes(a, b2));
    uint64_t k = sl_pvs_scene_key(a);
    assert_true(sl_pvs_scene_key(b1) != k);
    assert_true(sl_pvs_scene_key(b2) != k);
    assert_true(sl_pvs_scene_key(b1) != sl_pvs_scene_key(b2));
    sl_scene_destroy(a);
    sl_scene_destroy(b1);
    sl_scene_destroy(b2);
}

/* A moving car leaves the key alone; a footprint changes it. */
static void test_dynamic_ignored(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s = make_scene(&k_base);
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t idx[3] = {0, 1, 2}, mesh, car;
    sl_mesh_desc md = {pos, NULL, 3, idx, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0, SL_KIND_CAR, SL_OBJECT_DYNAMIC, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &car, &err), SL_OK);
    uint64_t k0 = sl_pvs_scene_key(s);
    sl_affine t = sl_affine_identity();
    t.m[3] = 5;
    assert_int_equal(sl_scene_set_object_transform(s, car, &t, &err), SL_OK);
    assert_true(sl_pvs_scene_key(s) == k0);
    t.m[7] = -2;
    assert_int_equal(sl_scene_set_object_transform(s, car, &t, &err), SL_OK);
    assert_true(sl_pvs_scene_key(s) == k0);
    float xy[8] = {0, 0, 1, 0, 1, 1, 0, 1};
    sl_footprint_desc fd = {xy, 4, 0, 10, SL_NONE};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    assert_true(sl_pvs_scene_key(s) != k0);
    sl_scene_destroy(s);
}

/* The same city generated twice, and saved and loaded (read and mapped): one key. */
static void test_same_scene_same_key(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene c1, c2;
    assert_int_equal(sl_gen_city(&co, NULL, &c1, &err), SL_OK);
    assert_int_equal(sl_gen_city(&co, NULL, &c2, &err), SL_OK);
    uint64_t k = sl_pvs_scene_key(c1);
    assert_true(sl_pvs_scene_key(c2) == k);
    char path[300];
    path_of(path, sizeof path, "city.slscene");
    assert_int_equal(sl_scene_save(c1, path, &err), SL_OK);
    for (int m = 0; m < 2; m++) {
        sl_load_options lo;
        memset(&lo, 0, sizeof lo);
        lo.no_mmap = m != 0;
        sl_scene l;
        assert_int_equal(sl_scene_load(path, &lo, NULL, &l, &err), SL_OK);
        assert_true(sl_pvs_scene_key(l) == k);
        sl_scene_destroy(l);
    }
    /* another seed: another key */
    co.seed = 2;
    sl_scene c3;
    assert_int_equal(sl_gen_city(&co, NULL, &c3, &err), SL_OK);
    assert_true(sl_pvs_scene_key(c3) != k);
    sl_scene_destroy(c1);
    sl_scene_destroy(c2);
    sl_scene_destroy(c3);
    unlink(path);
}

static sl_viewcells cluster_cells(sl_scene s)
{
    sl_error err;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 2);
    return vc;
}

static sl_status bake(sl_scene s, const char *out, bool resume, uint32_t stop_after, sl_error *err)
{
    sl_viewcells vc = cluster_cells(s);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "mappvs";
    bo.threads = 1;
    bo.resume = resume;
    bo.stop_after = stop_after;
    sl_status st = sl_pvs_build(s, vc, out, &bo, NULL, err);
    sl_viewcells_destroy(vc);
    return st;
}

/* A file baked for one scene is refused for the scene with moved triangles and for the scene
 * with another BSP, with the bake-again message; accepted for an equal scene. */
static void test_file_refused(void **state)
{
    (void)state;
    sl_error err;
    char out[300];
    path_of(out, sizeof out, "a.slpvs");
    sl_scene a = make_scene(&k_base), a2 = make_scene(&k_base);
    assert_int_equal(bake(a, out, false, 0, &err), SL_OK);
    sl_pvs p;
    assert_int_equal(sl_pvs_load(out, NULL, &p, &err), SL_OK);
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    assert_int_equal(in.scene_key_version, SL_PVS_SCENE_KEY_VERSION);
    assert_int_equal(in.version_minor, 1);
    assert_int_equal(sl_pvs_check_scene(p, a, &err), SL_OK);
    assert_int_equal(sl_pvs_check_scene(p, a2, &err), SL_OK);
    scene_opts moved = k_base, bsp = k_base;
    moved.inner = 3.0f;
    bsp.pvs1 = 0x2;
    sl_scene others[2] = {make_scene(&moved), make_scene(&bsp)};
    for (int i = 0; i < 2; i++) {
        assert_int_equal(sl_pvs_check_scene(p, others[i], &err), SL_ERROR_INVALID_ARGUMENT);
        assert_non_null(strstr(err.message, "was not baked for this scene"));
        assert_non_null(strstr(err.message, "bake it again"));
        assert_non_null(strstr(err.message, "sightline pvs build SCENE --method mappvs -o "));
        /* the pvs culler refuses it the same way */
        char opts[400];
        snprintf(opts, sizeof opts, "file=%s,aggressive=true", out);
        sl_culler c;
        assert_int_equal(sl_culler_create("pvs", others[i], opts, NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
        assert_non_null(strstr(err.message, "bake it again"));
        sl_scene_destroy(others[i]);
    }
    sl_pvs_destroy(p);
    sl_scene_destroy(a);
    sl_scene_destroy(a2);
    unlink(out);
}

/* A journal left by a bake of one scene is not resumed on the scene with moved triangles. */
static void test_journal_refused(void **state)
{
    (void)state;
    sl_error err;
    char out[300], ckpt[320];
    path_of(out, sizeof out, "j.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", out);
    sl_scene a = make_scene(&k_base);
    assert_int_equal(bake(a, out, false, 1, &err), SL_ERROR_CANCELLED);
    assert_int_equal(access(ckpt, F_OK), 0);
    scene_opts moved = k_base;
    moved.inner = 3.0f;
    sl_scene b = make_scene(&moved);
    assert_int_not_equal(bake(b, out, true, 0, &err), SL_OK);
    assert_non_null(strstr(err.message, "another bake"));
    assert_int_equal(access(out, F_OK), -1);
    /* the same scene resumes it */
    assert_int_equal(bake(a, out, true, 0, &err), SL_OK);
    assert_int_equal(access(out, F_OK), 0);
    sl_scene_destroy(a);
    sl_scene_destroy(b);
    unlink(out);
    unlink(ckpt);
}

/* ---- files of the old formats ---- */

static uint8_t *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)n);
    assert_int_equal(fread(b, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return b;
}

static void spit(const char *path, const uint8_t *b, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, n, f), n);
    fclose(f);
}

/* Make a format 1.0 file of a 1.1 one, as the old writer made it: minor 0, no key format field
 * in PVSH (zero there), checksums recomputed (docs/pvs.md, "The .slpvs format"). */
static void downgrade(uint8_t *b)
{
    uint32_t minor = 0, nsec;
    memcpy(b + 12, &minor, 4);
    memcpy(&nsec, b + 24, 4);
    uint64_t table;
    memcpy(&table, b + 32, 8);
    for (uint32_t i = 0; i < nsec; i++) {
        uint8_t *e = b + table + (uint64_t)i * 48;
        if (memcmp(e, "PVSH", 4) != 0)
            continue;
        uint64_t off, size;
        memcpy(&off, e + 16, 8);
        memcpy(&size, e + 24, 8);
        memset(b + off + 48, 0, 4);
        uint64_t h = sl_hash64(b + off, (size_t)size, 0);
        memcpy(e + 32, &h, 8);
    }
    uint64_t th = sl_hash64(b + table, (size_t)nsec * 48, 0);
    memcpy(b + 48, &th, 8);
    uint64_t hh = sl_hash64(b, 56, 0);
    memcpy(b + 56, &hh, 8);
}

static void test_old_file_message(void **state)
{
    (void)state;
    sl_error err;
    char out[300], old[300];
    path_of(out, sizeof out, "new.slpvs");
    path_of(old, sizeof old, "old.slpvs");
    sl_scene a = make_scene(&k_base);
    assert_int_equal(bake(a, out, false, 0, &err), SL_OK);
    size_t n;
    uint8_t *b = slurp(out, &n);
    downgrade(b);
    spit(old, b, n);
    free(b);
    sl_pvs p;
    /* it still opens (pvs info, verify without a scene) ... */
    assert_int_equal(sl_pvs_load(old, NULL, &p, &err), SL_OK);
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    assert_int_equal(in.version_minor, 0);
    assert_int_equal(in.scene_key_version, 1);
    assert_int_equal(sl_pvs_verify(p, &err), SL_OK);
    /* ... but is refused for any scene, even with a matching key, with the bake-again message */
    assert_int_equal(sl_pvs_check_scene(p, a, &err), SL_ERROR_INVALID_ARGUMENT);
    char want[400];
    snprintf(want, sizeof want, "%s was baked with an older scene key (format 1;", old);
    if (!strstr(err.message, want) || !strstr(err.message, "bake it again: sightline pvs build SCENE --method mappvs -o "))
        fail_msg("unexpected message: %s", err.message);
    sl_pvs_destroy(p);
    sl_scene_destroy(a);
    unlink(out);
    unlink(old);
}

/* A journal of version 1 (the old key) is refused with the bake-again message. */
static void test_old_journal_message(void **state)
{
    (void)state;
    sl_error err;
    char out[300], ckpt[320];
    path_of(out, sizeof out, "oj.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", out);
    sl_scene a = make_scene(&k_base);
    assert_int_equal(bake(a, out, false, 1, &err), SL_ERROR_CANCELLED);
    size_t n;
    uint8_t *b = slurp(ckpt, &n);
    uint32_t v = 1;
    memcpy(b + 8, &v, 4);
    spit(ckpt, b, n); /* the version is read before the header checksum */
    free(b);
    assert_int_not_equal(bake(a, out, true, 0, &err), SL_OK);
    if (!strstr(err.message, "older scene key (format 1); bake it again"))
        fail_msg("unexpected message: %s", err.message);
    sl_scene_destroy(a);
    unlink(ckpt);
    unlink(out);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "%s/sl_scene_key_XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    return rmdir(g_dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_moved_triangles),   cmocka_unit_test(test_bsp_changes_key),
        cmocka_unit_test(test_dynamic_ignored),   cmocka_unit_test(test_same_scene_same_key),
        cmocka_unit_test(test_file_refused),      cmocka_unit_test(test_journal_refused),
        cmocka_unit_test(test_old_file_message),  cmocka_unit_test(test_old_journal_message),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

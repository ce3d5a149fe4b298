/* The `volumetric` PVS method (Schaufler et al.'s conservative volumetric visibility):
 *  - fusion: a near wall A and a farther wall B, each of which leaves a small box T visible from
 *    a box cell, hide T together, because B grows into the space A hides (the extension into
 *    hidden voxels); without the extension (extend=false), with A or B alone, T is kept; the
 *    region oracle misses nothing in every case;
 *  - an open mesh (wall B without its bottom face) is not solid: T stays in the set;
 *  - tiny and small city cells (a subset baked with sl_pvs_build) against the region oracle: no
 *    misses, and objects are culled;
 *  - determinism: the same cells baked on one and two threads give byte-identical files;
 *  - options out of range are refused with the option's name. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sightline/bake.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/scene.h"
#include "support/box_mesh.h"

static char g_dir[64];

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* Every object the region oracle sees from the cell is in ids; returns how many it sees. */
static uint32_t check_oracle(sl_region_oracle ro, sl_viewcells vc, uint32_t cell, const uint32_t *ids, uint32_t n)
{
    sl_error err;
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, cell, &v, &err), SL_OK);
    for (uint32_t i = 0; i < v.visible_count; i++)
        if (!has(ids, n, v.visible[i]))
            fail_msg("cell %u: object %u is visible (%u pixels) but not in the volumetric set", cell, v.visible[i],
                     v.max_pixels[i]);
    return v.visible_count;
}

/* ---- fusion ----
 * Top view (x lateral, y depth), heights z in [-5, 30] for the walls: cell x [-4, 4], y [-1, 0],
 * eyes z [1, 2]; A x [-20, 1], y [4, 6]; B x [-2, 20], y [8, 10]; T x [-0.5, 0.5], y [30, 31],
 * z [0, 1]. From (4, 0) a line passes right of A to T; from (-4, 0) a line passes left of B to T.
 * A hides, at B's depth, every point with x <= 4 - 0.5 y (-1 at y = 10), so B grows left
 * into that space and then covers every line from the cell to T. Neither umbra alone holds T. */
enum { W_A = 1, W_B = 2, W_B_OPEN = 4 };

static sl_scene fusion_scene(unsigned walls, uint32_t *target)
{
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    *target = sl_test_add_box(s, (sl_vec3){-0.5f, 30, 0}, (sl_vec3){0.5f, 31, 1}, SL_KIND_OTHER, SL_OBJECT_CLOSED_CONVEX);
    assert_int_not_equal(*target, SL_NONE);
    if (walls & W_A)
        assert_int_not_equal(sl_test_add_box(s, (sl_vec3){-20, 4, -5}, (sl_vec3){1, 6, 30}, SL_KIND_OTHER,
                                             SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER),
                             SL_NONE);
    if (walls & W_B)
        assert_int_not_equal(sl_test_add_box(s, (sl_vec3){-2, 8, -5}, (sl_vec3){20, 10, 30}, SL_KIND_OTHER,
                                             SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER),
                             SL_NONE);
    if (walls & W_B_OPEN) {
        /* the same box without its bottom face (the two triangles with every corner at z = lo) */
        float p[24];
        sl_test_box_vertices((sl_vec3){-2, 8, -5}, (sl_vec3){20, 10, 30}, p);
        uint32_t idx[36], n = 0;
        for (int t = 0; t < 12; t++) {
            const uint32_t *tri = &sl_test_box_indices[3 * t];
            if ((tri[0] & 4) == 0 && (tri[1] & 4) == 0 && (tri[2] & 4) == 0)
                continue;
            memcpy(&idx[3 * n++], tri, 3 * sizeof *tri);
        }
        assert_int_equal(n, 10);
        sl_mesh_desc md = {.positions = p, .vertex_count = 8, .indices = idx, .triangle_count = n};
        uint32_t mesh;
        assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
        sl_object_desc od = {.mesh = mesh, .kind = SL_KIND_OTHER, .flags = SL_OBJECT_OCCLUDER, .color = 0xffffffffu};
        assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    }
    return s;
}

static sl_viewcells fusion_cell(void)
{
    sl_viewcell c;
    memset(&c, 0, sizeof c);
    c.shape = SL_CELL_BOX;
    c.cluster = -1;
    c.bounds = (sl_aabb){{-4, -1, 1}, {4, 0, 2}};
    c.z_min = 1;
    c.z_max = 2;
    sl_viewcells vc;
    sl_error err;
    assert_int_equal(sl_viewcells_create(&c, 1, NULL, &vc, &err), SL_OK);
    return vc;
}

/* Whether T is in the set of the one cell; the oracle is checked too. */
static bool target_kept(unsigned walls, const char *options)
{
    uint32_t t;
    sl_scene s = fusion_scene(walls, &t);
    sl_viewcells vc = fusion_cell();
    sl_error err;
    uint32_t ids[8], count;
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "volumetric", options, ids, 8, &count, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = 128;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    check_oracle(ro, vc, 0, ids, count);
    sl_region_oracle_destroy(ro);
    bool kept = has(ids, count, t);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
    return kept;
}

static void test_fusion(void **state)
{
    (void)state;
    assert_false(target_kept(W_A | W_B, "voxel=0.25"));
    assert_true(target_kept(W_A | W_B, "voxel=0.25,extend=false"));
    assert_true(target_kept(W_A, "voxel=0.25"));
    assert_true(target_kept(W_B, "voxel=0.25"));
}

static void test_open_mesh(void **state)
{
    (void)state;
    /* B open: not solid, so A alone acts and T is kept; with meshes=false nothing is solid */
    assert_true(target_kept(W_A | W_B_OPEN, "voxel=0.25"));
    assert_true(target_kept(W_A | W_B, "voxel=0.25,meshes=false"));
}

/* ---- cities ---- */

static void city(sl_city_preset preset, sl_scene *s, sl_viewcells *all)
{
    sl_error err;
    sl_city_options o = sl_city_defaults(preset);
    assert_int_equal(sl_gen_city(&o, NULL, s, &err), SL_OK);
    assert_int_equal(sl_viewcells_from_streets(*s, NULL, all, &err), SL_OK);
}

/* `count` cells of `all` spread over its ids, as cells of their own. */
static sl_viewcells pick(sl_viewcells all, uint32_t count)
{
    uint32_t n = sl_viewcells_count(all);
    sl_viewcell *c = malloc(count * sizeof *c);
    assert_non_null(c);
    for (uint32_t i = 0; i < count; i++)
        c[i] = sl_viewcells_data(all)[(uint32_t)(((uint64_t)i * 7919u + 13u) % n)];
    sl_viewcells vc;
    sl_error err;
    assert_int_equal(sl_viewcells_create(c, count, NULL, &vc, &err), SL_OK);
    free(c);
    return vc;
}

static void bake(sl_scene s, sl_viewcells vc, const char *file, uint32_t threads, const char *options)
{
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "volumetric";
    bo.method_options = options;
    bo.threads = threads;
    sl_error err;
    sl_status st = sl_pvs_build(s, vc, file, &bo, NULL, &err);
    if (st != SL_OK)
        fail_msg("bake: %s", err.message);
}

static void city_check(sl_city_preset preset, uint32_t cells, uint32_t face)
{
    sl_scene s;
    sl_viewcells all;
    city(preset, &s, &all);
    sl_viewcells vc = pick(all, cells);
    char file[128];
    snprintf(file, sizeof file, "%s/city.slpvs", g_dir);
    bake(s, vc, file, 2, NULL);
    sl_error err;
    sl_pvs p;
    assert_int_equal(sl_pvs_load(file, NULL, &p, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = face;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), count;
    uint32_t *ids = malloc(n * sizeof *ids);
    assert_non_null(ids);
    uint64_t sum = 0, seen = 0;
    for (uint32_t c = 0; c < cells; c++) {
        assert_int_equal(sl_pvs_cell_set(p, c, ids, n, &count, &err), SL_OK);
        seen += check_oracle(ro, vc, c, ids, count);
        sum += count;
    }
    printf("%s: %u cells, volumetric %.1f, oracle %.1f of %u objects per cell\n", sl_city_preset_name(preset), cells,
           (double)sum / cells, (double)seen / cells, n);
    assert_true(sum < (uint64_t)n * cells * 9 / 10); /* it culls */
    free(ids);
    sl_region_oracle_destroy(ro);
    sl_pvs_destroy(p);
    unlink(file);
    sl_viewcells_destroy(vc);
    sl_viewcells_destroy(all);
    sl_scene_destroy(s);
}

static void test_tiny_city(void **state)
{
    (void)state;
    city_check(SL_CITY_TINY, getenv("SL_SANITIZED") ? 4 : 16, 128);
}

static void test_small_city(void **state)
{
    (void)state;
    city_check(SL_CITY_SMALL, getenv("SL_SANITIZED") ? 1 : 3, 128);
}

static bool same_bytes(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    bool same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        same = ca == cb;
        if (ca == EOF || cb == EOF)
            break;
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

static void test_determinism(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells all;
    city(SL_CITY_TINY, &s, &all);
    sl_viewcells vc = pick(all, 8);
    char f1[128], f2[128];
    snprintf(f1, sizeof f1, "%s/one.slpvs", g_dir);
    snprintf(f2, sizeof f2, "%s/two.slpvs", g_dir);
    bake(s, vc, f1, 1, "voxel=1.5");
    bake(s, vc, f2, 2, "voxel=1.5");
    assert_true(same_bytes(f1, f2));
    unlink(f1);
    unlink(f2);
    sl_viewcells_destroy(vc);
    sl_viewcells_destroy(all);
    sl_scene_destroy(s);
}

static void test_refusals(void **state)
{
    (void)state;
    uint32_t t;
    sl_scene s = fusion_scene(W_A, &t);
    sl_viewcells vc = fusion_cell();
    sl_error err;
    uint32_t ids[8], count;
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "volumetric", "voxel=-1", ids, 8, &count, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "voxel"));
    /* a grid over the budget is refused with what to change */
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "volumetric", "voxel=0.01,max_voxels=1", ids, 8, &count, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "max_voxels"));
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_test_volumetric_XXXXXX");
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
        cmocka_unit_test(test_fusion),       cmocka_unit_test(test_open_mesh), cmocka_unit_test(test_tiny_city),
        cmocka_unit_test(test_small_city),   cmocka_unit_test(test_determinism), cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

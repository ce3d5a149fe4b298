/* The extproj PVS method (extended projections, Durand et al. 2000), every set held to the region
 * oracle: a wall hides what lies behind it; fusion — two occluders at different depths whose
 * extended projections together cover an occludee that neither covers alone; an occluder
 * narrower than the cell, whose union of projections (not their intersection) would cover an
 * object the oracle sees, hides nothing; the tiny city has zero misses; the bake is byte-identical
 * with 1 and 2 threads and from one run to the next; a scene without footprints is refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sightline/bake.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/truth.h"
#include "support/box_cell.h"
#include "support/box_mesh.h"

static char g_dir[256];

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static uint32_t add_box(sl_scene s, float x0, float y0, float z0, float x1, float y1, float z1, uint32_t kind)
{
    uint32_t obj = sl_test_add_box(s, (sl_vec3){x0, y0, z0}, (sl_vec3){x1, y1, z1}, kind, SL_OBJECT_CLOSED_CONVEX);
    assert_int_not_equal(obj, SL_NONE);
    return obj;
}

/* A building: a box object and its footprint. */
static uint32_t add_building(sl_scene s, float x0, float y0, float x1, float y1, float h)
{
    sl_error err;
    uint32_t obj = add_box(s, x0, y0, 0, x1, y1, h, SL_KIND_BUILDING);
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0, h, obj};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    return obj;
}

static bool in_set(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* Bake the one cell with extproj, check the set against a dense region oracle and return whether
 * `target` is in it; *seen: whether the oracle sees the target. */
static bool bake_opts(sl_scene s, sl_viewcells vc, uint32_t target, const char *opts, bool *seen)
{
    sl_error err;
    uint32_t n = sl_scene_object_count(s), count;
    uint32_t *ids = malloc(n * sizeof *ids);
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "extproj", opts, ids, n, &count, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = sanitized() ? 128 : 256;
    oo.edge_spacing = sanitized() ? 0.5f : 0.2f;
    oo.face_samples = sanitized() ? 12 : 32;
    oo.interior_samples = sanitized() ? 12 : 32;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, 0, &v, &err), SL_OK);
    *seen = false;
    for (uint32_t i = 0; i < v.visible_count; i++) {
        if (!in_set(ids, count, v.visible[i]))
            fail_msg("object %u is visible (%u pixels) but not in the extproj set", v.visible[i], v.max_pixels[i]);
        *seen |= v.visible[i] == target;
    }
    bool r = in_set(ids, count, target);
    sl_region_oracle_destroy(ro);
    free(ids);
    return r;
}

static bool bake(sl_scene s, sl_viewcells vc, uint32_t target, bool *seen)
{
    return bake_opts(s, vc, target, NULL, seen);
}

static sl_scene new_scene(void)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    return s;
}

/* A long wall hides a box behind it; a gap in the wall lets it be seen, and it is kept. */
static void test_wall(void **state)
{
    (void)state;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    bool seen;
    sl_scene s = new_scene();
    add_building(s, -40, 10, 40, 12, 20);
    uint32_t t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_false(bake(s, vc, t, &seen));
    /* a box between the cell and the wall (a sign 3 m up) projects inside the wall's extended
     * projection but lies in front of it (the depth test): kept, and seen */
    uint32_t front = add_box(s, -1, 5, 3, 1, 6, 4, SL_KIND_OTHER);
    assert_true(bake(s, vc, front, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    /* the same in the other three directions (the planes of -y, +x, -x) */
    s = new_scene();
    add_building(s, -40, -12, 40, -10, 20);
    add_building(s, 10, -40, 12, 40, 20);
    add_building(s, -12, -40, -10, 40, 20);
    uint32_t a = add_box(s, -3, -31, 0, 3, -30, 3, SL_KIND_OTHER);
    uint32_t b = add_box(s, 30, -3, 0, 31, 3, 3, SL_KIND_OTHER);
    uint32_t c = add_box(s, -31, -3, 0, -30, 3, 3, SL_KIND_OTHER);
    assert_false(bake(s, vc, a, &seen));
    assert_false(bake(s, vc, b, &seen));
    assert_false(bake(s, vc, c, &seen));
    sl_scene_destroy(s);
    /* a 2 m gap in the wall */
    s = new_scene();
    add_building(s, -40, 10, -1, 12, 20);
    add_building(s, 1, 10, 40, 12, 20);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    /* a box taller than the wall's shadow at its distance shows above it */
    s = new_scene();
    add_building(s, -40, 10, 40, 12, 6);
    t = add_box(s, -3, 30, 0, 3, 31, 30, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

/* Fusion: A (x < 1, y = 10..12) and B (x > -1.5, y = 15..17). No sight line from the cell passes
 * between them; the target (x -5..4, y = 30) is hidden by neither alone — part of it lies beside
 * each — but by both: on a plane behind B, A's extended projection covers x < 1 and B's x > -1.5,
 * and the target projects inside their union. */
static void test_fusion(void **state)
{
    (void)state;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    bool seen;
    sl_scene s = new_scene();
    add_building(s, -40, 10, 1, 12, 20);
    add_building(s, -1.5f, 15, 40, 17, 20);
    uint32_t t = add_box(s, -5, 30, 0, 4, 31, 3, SL_KIND_OTHER);
    assert_false(bake(s, vc, t, &seen));
    assert_false(seen);
    sl_scene_destroy(s);
    /* A alone, B alone: the target is kept (and seen) */
    s = new_scene();
    add_building(s, -40, 10, 1, 12, 20);
    t = add_box(s, -5, 30, 0, 4, 31, 3, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    s = new_scene();
    add_building(s, -1.5f, 15, 40, 17, 20);
    t = add_box(s, -5, 30, 0, 4, 31, 3, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    /* touching buildings of different heights (a row sharing a wall at x = 0): each alone leaves
     * a wedge behind the joint that no single extended projection covers, so a low target there
     * is kept; with merge=true the level piece (both at the lower roof, one block) hides it */
    s = new_scene();
    add_building(s, -12, 10, 0, 12, 20);
    add_building(s, 0, 10, 12, 12, 18);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_false(seen);
    assert_false(bake_opts(s, vc, t, "merge=true", &seen));
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

/* The occluder's extended projection must be the intersection of its projections from the cell,
 * not their union: a pillar 0.8 m wide (narrower than the 2 m cell) 10 m away hides a 1 m box
 * 20 m away from the cell's centre, but not from its sides. The union of the pillar's
 * projections covers the box's (union) projection; the method keeps the box and the oracle sees
 * it. (Replacing the intersection by the union in extended_projection fails this test.) */
static void test_union_is_wrong_for_occluders(void **state)
{
    (void)state;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    bool seen;
    sl_scene s = new_scene();
    add_building(s, -0.4f, 10, 0.4f, 11, 20);
    uint32_t t = add_box(s, -0.5f, 20, 0, 0.5f, 20.5f, 3, SL_KIND_OTHER);
    assert_true(bake(s, vc, t, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

static uint8_t *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)n + 1);
    assert_int_equal(fread(b, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return b;
}

/* Every step-th cell of the tiny city (street cells of max edge 20 m). */
static void tiny(sl_scene *s, sl_viewcells *vc, uint32_t step)
{
    sl_error err;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&o, NULL, s, &err), SL_OK);
    sl_viewcell_options vo = {0};
    vo.max_edge = 20;
    sl_viewcells all;
    assert_int_equal(sl_viewcells_from_streets(*s, &vo, &all, &err), SL_OK);
    uint32_t nc = sl_viewcells_count(all), n = 0;
    sl_viewcell *keep = malloc(((size_t)nc + 1) * sizeof *keep);
    for (uint32_t c = 0; c < nc; c += step)
        keep[n++] = sl_viewcells_data(all)[c];
    assert_int_equal(sl_viewcells_create(keep, n, NULL, vc, &err), SL_OK);
    free(keep);
    sl_viewcells_destroy(all);
}

/* Zero misses on cells of the tiny city, sets well below everything; the file is the same bytes
 * with 1 and 2 threads and from a second run. */
static void test_tiny_city(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, sanitized() ? 40 : 12);
    sl_error err;
    char f1[300], f2[300], f3[300];
    path_of(f1, sizeof f1, "t1.slpvs");
    path_of(f2, sizeof f2, "t2.slpvs");
    path_of(f3, sizeof f3, "t3.slpvs");
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "extproj";
    bo.threads = 1;
    assert_int_equal(sl_pvs_build(s, vc, f1, &bo, NULL, &err), SL_OK);
    bo.threads = 2;
    assert_int_equal(sl_pvs_build(s, vc, f2, &bo, NULL, &err), SL_OK);
    assert_int_equal(sl_pvs_build(s, vc, f3, &bo, NULL, &err), SL_OK);
    size_t n1, n2, n3;
    uint8_t *b1 = read_all(f1, &n1), *b2 = read_all(f2, &n2), *b3 = read_all(f3, &n3);
    assert_int_equal(n1, n2);
    assert_int_equal(n1, n3);
    assert_memory_equal(b1, b2, n1);
    assert_memory_equal(b1, b3, n1);
    free(b1), free(b2), free(b3);

    sl_pvs p;
    assert_int_equal(sl_pvs_load(f1, NULL, &p, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = sanitized() ? 64 : 128;
    oo.edge_spacing = 2;
    oo.face_samples = 8;
    oo.interior_samples = 8;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), count, nc = sl_viewcells_count(vc);
    uint32_t *ids = malloc(n * sizeof *ids);
    uint64_t total = 0, visible = 0;
    for (uint32_t c = 0; c < nc; c++) {
        assert_int_equal(sl_pvs_cell_set(p, c, ids, n, &count, &err), SL_OK);
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_cell(ro, vc, c, &v, &err), SL_OK);
        for (uint32_t i = 0; i < v.visible_count; i++)
            if (!in_set(ids, count, v.visible[i]))
                fail_msg("cell %u: object %u is visible (%u pixels) but not in the extproj set", c, v.visible[i],
                         v.max_pixels[i]);
        total += count;
        visible += v.visible_count;
    }
    /* the method culls: on average less than 80% of the objects are kept */
    assert_true(total < (uint64_t)n * nc * 8 / 10);
    assert_true(visible <= total);
    free(ids);
    sl_region_oracle_destroy(ro);
    sl_pvs_destroy(p);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* A scene without footprints has no occluders for the method: refused with a reason. */
static void test_refusal(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    uint32_t ids[4], count;
    sl_error err;
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "extproj", NULL, ids, 4, &count, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "footprints"));
    /* and an option out of range */
    add_building(s, -40, 10, 40, 12, 20);
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "extproj", "res=8", ids, 4, &count, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/test_extproj.XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wall),
        cmocka_unit_test(test_fusion),
        cmocka_unit_test(test_union_is_wrong_for_occluders),
        cmocka_unit_test(test_tiny_city),
        cmocka_unit_test(test_refusal),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

/* The `virtual` PVS method (virtual occluders, src/region/method_virtual.c): two buildings whose
 * umbrae do not meet hide together what neither hides alone (one virtual occluder behind both), and
 * the region oracle agrees; a real gap and a tower above the row are kept; a scene without
 * footprints is refused with a clear message; tiny-city cells have zero misses against the region
 * oracle, and fewer virtual occluders (keep=N, the paper's decimation) or no union (fuse=false)
 * only keep more; the bake is byte-identical with 1 and 2 threads and runs as the pvs culler
 * without a miss against the point oracle. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/bake.h"
#include "sightline/cull.h"
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

/* Is every id of a (ascending, n) in b (ascending, m)? */
static bool subset_of(const uint32_t *a, uint32_t n, const uint32_t *b, uint32_t m)
{
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        while (k < m && b[k] < a[i])
            k++;
        if (k >= m || b[k] != a[i])
            return false;
    }
    return true;
}

/* Bake cell 0 with `virtual` and hold it to a dense region oracle: every object the oracle sees is
 * in the set, and a culled target is one it does not see. Returns whether target is in the set;
 * *seen whether the oracle saw it. */
static bool bake_check(sl_scene s, sl_viewcells vc, uint32_t target, const char *opts, bool *seen)
{
    sl_error err;
    uint32_t n = sl_scene_object_count(s), count;
    uint32_t *ids = malloc(n * sizeof *ids);
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "virtual", opts, ids, n, &count, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = sanitized() ? 128 : 256;
    oo.edge_spacing = sanitized() ? 0.5f : 0.25f;
    oo.face_samples = sanitized() ? 12 : 32;
    oo.interior_samples = sanitized() ? 12 : 32;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, 0, &v, &err), SL_OK);
    bool oracle_sees = false;
    for (uint32_t i = 0; i < v.visible_count; i++) {
        if (!in_set(ids, count, v.visible[i]))
            fail_msg("object %u is visible (%u pixels) but not in the virtual set", v.visible[i], v.max_pixels[i]);
        oracle_sees |= v.visible[i] == target;
    }
    bool r = in_set(ids, count, target);
    assert_true(r || !oracle_sees);
    if (seen)
        *seen = oracle_sees;
    sl_region_oracle_destroy(ro);
    free(ids);
    return r;
}

/* Fusion. The cell: x, y in [-1, 1], eyes 1 to 2 m. A (x <= 0.5, y 10..12) and B (x >= -0.5,
 * y 14..16), 20 m tall: a sight line passing A's end and then B's start would have to move 1 m
 * sideways within 2 m of depth, and such a line misses either the cell or the target at y = 30
 * (x in [-3, 3]). Neither building hides the whole target from the whole cell; their umbrae are
 * disjoint near the joint, yet together they hide it: the virtual occluder on B's middle line
 * runs on past B's end, hidden there by A. */
static void test_fusion(void **state)
{
    (void)state;
    sl_error err;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    sl_scene s;
    bool seen;
    /* each alone: kept (and seen) */
    for (int which = 0; which < 2; which++) {
        assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
        if (which == 0)
            add_building(s, -40, 10, 0.5f, 12, 20);
        else
            add_building(s, -0.5f, 14, 40, 16, 20);
        uint32_t t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
        assert_true(bake_check(s, vc, t, NULL, &seen));
        assert_true(seen);
        sl_scene_destroy(s);
    }
    /* together: culled, and the oracle agrees */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, 0.5f, 12, 20);
    add_building(s, -0.5f, 14, 40, 16, 20);
    uint32_t t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    /* a tower behind the row, taller than the row's shadow at its distance: seen over it, kept */
    uint32_t tower = add_box(s, -2, 60, 0, 2, 62, 80, SL_KIND_OTHER);
    assert_false(bake_check(s, vc, t, NULL, &seen));
    assert_false(bake_check(s, vc, t, "fuse=false", &seen));
    assert_true(bake_check(s, vc, tower, NULL, &seen));
    assert_true(seen);
    /* one slice, decimated to one virtual occluder: still culled */
    assert_false(bake_check(s, vc, t, "slices=1,keep=1", &seen));
    sl_scene_destroy(s);
    /* control: a real 2 m gap in one row lets the target be seen; it is kept */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, -1, 12, 20);
    add_building(s, 1, 10, 40, 12, 20);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake_check(s, vc, t, NULL, &seen));
    assert_true(seen);
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

/* Where the method does not apply: no footprints (an imported model, an OpenArena map) */
static void test_refusal(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, -40, 10, 0, 40, 12, 20, SL_KIND_OTHER);
    add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    uint32_t ids[2], count;
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, "virtual", NULL, ids, 2, &count, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "no building footprints"));
    assert_non_null(strstr(err.message, "portal"));
    /* bad options */
    assert_int_equal(sl_pvs_method_check_options("virtual", "slices=0", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_method_check_options("virtual", "sleces=2", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_method_check_options("virtual", "slices=3,keep=8,fuse=false", &err), SL_OK);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static void tiny(sl_scene *s, sl_viewcells *vc, float edge)
{
    sl_error err;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&o, NULL, s, &err), SL_OK);
    sl_viewcell_options vo = {0};
    vo.max_edge = edge;
    assert_int_equal(sl_viewcells_from_streets(*s, &vo, vc, &err), SL_OK);
}

/* Keep every step-th cell (replaces *vc). */
static void keep_every(sl_viewcells *vc, uint32_t step)
{
    uint32_t nc = sl_viewcells_count(*vc), n = 0;
    sl_viewcell *keep = malloc(((size_t)nc + 1) * sizeof *keep);
    for (uint32_t c = 0; c < nc; c += step)
        keep[n++] = sl_viewcells_data(*vc)[c];
    sl_viewcells sub;
    sl_error err;
    assert_int_equal(sl_viewcells_create(keep, n, NULL, &sub, &err), SL_OK);
    free(keep);
    sl_viewcells_destroy(*vc);
    *vc = sub;
}

/* Tiny-city street cells against the region oracle: zero misses; keep=2 and fuse=false hold the
 * default set; the sets cull. */
static void test_tiny_city_oracle(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 12);
    sl_error err;
    sl_region_oracle_options oo = {0};
    oo.face_size = sanitized() ? 64 : 128;
    oo.edge_spacing = sanitized() ? 4 : 1;
    oo.face_samples = sanitized() ? 6 : 16;
    oo.interior_samples = sanitized() ? 6 : 16;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), nc = sl_viewcells_count(vc);
    uint32_t *ids = malloc(n * sizeof *ids), *loose = malloc(n * sizeof *loose), *nofuse = malloc(n * sizeof *nofuse);
    uint32_t cells = sanitized() ? 3 : 24, tested = 0, count, nl, nf;
    uint64_t total = 0, seen = 0;
    for (uint32_t c = 7; c < nc && tested < cells; c += nc / cells, tested++) {
        assert_int_equal(sl_pvs_bake_cell(s, vc, c, "virtual", NULL, ids, n, &count, &err), SL_OK);
        assert_int_equal(sl_pvs_bake_cell(s, vc, c, "virtual", "keep=2", loose, n, &nl, &err), SL_OK);
        assert_int_equal(sl_pvs_bake_cell(s, vc, c, "virtual", "fuse=false", nofuse, n, &nf, &err), SL_OK);
        if (!subset_of(ids, count, loose, nl))
            fail_msg("cell %u: the set with 2 virtual occluders lacks an object of the full set", c);
        if (!subset_of(ids, count, nofuse, nf))
            fail_msg("cell %u: the set without the union lacks an object of the set with it", c);
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_cell(ro, vc, c, &v, &err), SL_OK);
        for (uint32_t i = 0; i < v.visible_count; i++)
            if (!in_set(ids, count, v.visible[i]))
                fail_msg("cell %u: object %u is visible (%u pixels) but not in the virtual set", c, v.visible[i],
                         v.max_pixels[i]);
        total += count;
        seen += v.visible_count;
    }
    print_message("virtual: %u tiny-city cells, %.1f objects per cell (oracle %.1f) of %u\n", tested,
                  (double)total / tested, (double)seen / tested, n);
    assert_true(tested > 0);
    assert_true(total < (uint64_t)n * tested * 3 / 4); /* it culls (the oracle alone sees about half) */
    free(ids);
    free(loose);
    free(nofuse);
    sl_region_oracle_destroy(ro);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

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

/* Determinism (1 and 2 threads, byte-identical files) and the pvs culler on the bake: no miss
 * against the point oracle from eyes in the baked cells. */
static void test_bake_culler(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 40);
    keep_every(&vc, sanitized() ? 24 : 6);
    sl_error err;
    char one[300], two[300], opt[400];
    snprintf(one, sizeof one, "%s/one.slpvs", g_dir);
    snprintf(two, sizeof two, "%s/two.slpvs", g_dir);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "virtual";
    bo.threads = 1;
    sl_pvs_build_stats st;
    assert_int_equal(sl_pvs_build(s, vc, one, &bo, &st, &err), SL_OK);
    assert_string_equal(st.method, "virtual");
    bo.threads = 2;
    assert_int_equal(sl_pvs_build(s, vc, two, &bo, NULL, &err), SL_OK);
    size_t na, nb;
    uint8_t *a = read_all(one, &na), *b = read_all(two, &nb);
    assert_int_equal(na, nb);
    assert_memory_equal(a, b, na);
    free(a);
    free(b);
    sl_pvs p;
    assert_int_equal(sl_pvs_load(one, NULL, &p, &err), SL_OK);
    assert_int_equal(sl_pvs_verify(p, &err), SL_OK);
    sl_pvs_destroy(p);
    snprintf(opt, sizeof opt, "file=%s", one);
    sl_culler c;
    assert_int_equal(sl_culler_create("pvs", s, opt, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE);
    sl_oracle o;
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 256;
    oo.height = 192;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), count, drawn = 0;
    uint32_t *ids = malloc(n * sizeof *ids);
    sl_rng r;
    sl_rng_seed(&r, 11, 0);
    const sl_viewcell *cells = sl_viewcells_data(vc);
    int cams = sanitized() ? 4 : 16;
    for (int k = 0; k < cams; k++) {
        const sl_viewcell *cl = &cells[sl_rng_below(&r, sl_viewcells_count(vc))];
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){(cl->tri[0].x + cl->tri[1].x + cl->tri[2].x) / 3,
                                 (cl->tri[0].y + cl->tri[1].y + cl->tri[2].y) / 3, 1.7f};
        cam.yaw = sl_rng_range(&r, -3.14f, 3.14f);
        cam.width = 256;
        cam.height = 192;
        assert_int_equal(sl_culler_cull(c, &cam, ids, n, &count, &err), SL_OK);
        drawn += count;
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        sl_cull_metrics m;
        assert_int_equal(sl_metrics_compare(s, &f, ids, count, &m, NULL, NULL, 0, &err), SL_OK);
        assert_int_equal(m.missed_count, 0);
    }
    print_message("virtual as the pvs culler: %.1f objects drawn per view of %u\n", (double)drawn / cams, n);
    free(ids);
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/test_virtual.XXXXXX");
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
        cmocka_unit_test(test_fusion),
        cmocka_unit_test(test_refusal),
        cmocka_unit_test(test_tiny_city_oracle),
        cmocka_unit_test(test_bake_culler),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

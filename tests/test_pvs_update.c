/* Updating a bake after an edit (sl_pvs_update): random edits of the buildings of one block of the
 * tiny and small cities (removed, moved, given a tower; sl_city_edit, seeded) are updated from the
 * old bake and compared byte for byte with a full bake of the edited scene, with `adjustable` and
 * `sample`; an edit that changes the view cells (a building moved over a street) is refused and
 * says so; a file of another scene and a file of another method are refused; the update is
 * deterministic; and the rule broken on purpose (weaken: no rule (a), no probe) makes a file that
 * differs from the full bake, so that the comparison is seen to catch a wrong rule.
 *
 * The full bakes are of a subset of the cells (every k-th street cell): the update works on any
 * cells, and the subset keeps the test within a minute on two shared cores. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/bake.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "support/box_mesh.h"

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

static bool same_files(const char *a, const char *b)
{
    uint8_t *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    sl_error err;
    assert_int_equal(sl_file_read_all(sl_default_allocator(), a, &x, &nx, &err), SL_OK);
    assert_int_equal(sl_file_read_all(sl_default_allocator(), b, &y, &ny, &err), SL_OK);
    bool same = nx == ny && memcmp(x, y, nx) == 0;
    sl_free(sl_default_allocator(), x, nx);
    sl_free(sl_default_allocator(), y, ny);
    return same;
}

static sl_scene city(sl_city_preset p, uint64_t seed)
{
    sl_city_options o = sl_city_defaults(p);
    o.seed = seed;
    sl_scene s = NULL;
    sl_error err;
    assert_int_equal(sl_gen_city(&o, NULL, &s, &err), SL_OK);
    return s;
}

/* Every k-th street cell of the scene, from `first` (what the test bakes: any cells would do). */
static sl_viewcells some_cells(sl_scene s, uint32_t k, uint32_t first)
{
    sl_viewcell_options vo;
    memset(&vo, 0, sizeof vo);
    sl_viewcells all = NULL, some = NULL;
    sl_error err;
    assert_int_equal(sl_viewcells_from_streets(s, &vo, &all, &err), SL_OK);
    uint32_t n = sl_viewcells_count(all), m = 0;
    sl_viewcell *keep = malloc(((size_t)n + 1) * sizeof *keep);
    assert_non_null(keep);
    for (uint32_t c = first; c < n; c += k)
        keep[m++] = sl_viewcells_data(all)[c];
    assert_int_equal(sl_viewcells_create(keep, m, NULL, &some, &err), SL_OK);
    free(keep);
    sl_viewcells_destroy(all);
    return some;
}

static void bake(sl_scene s, sl_viewcells cells, const char *method, const char *path)
{
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = method;
    bo.threads = 2;
    sl_error err;
    sl_status st = sl_pvs_build(s, cells, path, &bo, NULL, &err);
    if (st != SL_OK)
        fail_msg("bake %s: %s", path, err.message);
}

/* A 100 m square around building `pick` (by footprint) of the scene. */
static void block_region(sl_scene s, uint32_t pick, float r[4])
{
    sl_footprint_view v = sl_scene_footprint(s, pick % sl_scene_footprint_count(s));
    float cx = 0, cy = 0;
    for (uint32_t i = 0; i < v.vertex_count; i++)
        cx += v.xy[2 * i], cy += v.xy[2 * i + 1];
    cx /= v.vertex_count, cy /= v.vertex_count;
    r[0] = cx - 50, r[1] = cy - 50, r[2] = cx + 50, r[3] = cy + 50;
}

typedef struct outcome {
    uint32_t compared, refused, affected, cells;
} outcome;

/* Edit the old scene with `seed`, update the old bake and bake the edited scene in full; with the
 * cells unchanged the two files must be the same bytes, else the update must refuse. Returns
 * whether the files were compared (and equal, unless weaken: then *equal tells). */
static bool one_edit(sl_scene olds, sl_viewcells cells, const char *method, const char *old_path, uint64_t seed,
                     uint32_t weaken, bool *equal, outcome *out)
{
    sl_error err;
    sl_city_edit_options eo = sl_city_edit_defaults();
    eo.seed = seed;
    if (seed % 2) { /* every other edit: taller, seen from farther */
        eo.grow = 1.5f;
        eo.tower = 2.0f;
    }
    block_region(olds, (uint32_t)(seed * 2654435761u), eo.region);
    sl_scene news = NULL;
    sl_city_edit_stats es;
    assert_int_equal(sl_city_edit(olds, &eo, NULL, &news, &es, &err), SL_OK);
    /* the edited scene's cells, made as the full bake makes them: the same subset of the street
     * cells when the streets' free space did not change */
    sl_viewcell_options vo;
    memset(&vo, 0, sizeof vo);
    sl_viewcells all_old = NULL, all_new = NULL;
    assert_int_equal(sl_viewcells_from_streets(olds, &vo, &all_old, &err), SL_OK);
    assert_int_equal(sl_viewcells_from_streets(news, &vo, &all_new, &err), SL_OK);
    bool cells_same = sl_viewcells_key(all_old) == sl_viewcells_key(all_new);
    sl_viewcells newcells = cells;
    if (!cells_same) /* some cells of the new street cells: they differ from the file's */
        newcells = all_new;
    sl_pvs old = NULL;
    assert_int_equal(sl_pvs_load(old_path, NULL, &old, &err), SL_OK);
    char upd[300], full[300];
    path_of(upd, sizeof upd, "updated.slpvs");
    path_of(full, sizeof full, "full.slpvs");
    sl_pvs_update_options uo;
    memset(&uo, 0, sizeof uo);
    uo.threads = 2;
    uo.weaken = weaken;
    sl_pvs_update_stats us;
    sl_status st = sl_pvs_update(old, olds, news, newcells, upd, &uo, &us, &err);
    bool compared = false;
    if (!cells_same) {
        assert_int_equal(st, SL_ERROR_INVALID_ARGUMENT);
        assert_non_null(strstr(err.message, "view cells differ"));
        assert_non_null(strstr(err.message, "pvs build"));
        assert_int_not_equal(access(upd, F_OK), 0); /* nothing written */
        out->refused++;
    } else {
        if (st != SL_OK)
            fail_msg("seed %llu: %s", (unsigned long long)seed, err.message);
        bake(news, cells, method, full);
        *equal = same_files(upd, full);
        if (!weaken && !*equal)
            fail_msg("%s, seed %llu (%u removed, %u moved, %u added): the update (%u of %u cells re-baked) differs "
                     "from the full bake",
                     method, (unsigned long long)seed, es.removed, es.moved, es.added, us.cells_affected, us.cells);
        /* the cars have motion records: the kept cells' region marks are copied, not marked again */
        assert_true(us.regions > 0);
        assert_int_equal(us.region_rows_copied, us.cells - us.cells_affected);
        print_message("  %s seed %llu: %u removed, %u moved, %u towers; zone %u footprints; %u of %u cells re-baked "
                      "(%u by the old sets, %u by the probe), %u region rows copied%s\n",
                      method, (unsigned long long)seed, es.removed, es.moved, es.added, us.zone_footprints,
                      us.cells_affected, us.cells, us.cells_by_set, us.cells_by_probe, us.region_rows_copied,
                      weaken ? (*equal ? ": same bytes" : ": differs") : ": same bytes");
        out->compared++;
        out->affected += us.cells_affected;
        out->cells += us.cells;
        compared = true;
        unlink(upd);
        unlink(full);
    }
    sl_pvs_destroy(old);
    sl_viewcells_destroy(all_old);
    sl_viewcells_destroy(all_new);
    sl_scene_destroy(news);
    return compared;
}

static void run_edits(sl_city_preset preset, uint32_t k, const char *method, uint64_t first_seed, uint32_t want)
{
    sl_scene olds = city(preset, 1);
    sl_viewcells cells = some_cells(olds, k, 0);
    char old_path[300];
    path_of(old_path, sizeof old_path, "old.slpvs");
    bake(olds, cells, method, old_path);
    outcome o = {0};
    for (uint64_t seed = first_seed; o.compared < want && seed < first_seed + 4 * want; seed++) {
        bool equal = false;
        one_edit(olds, cells, method, old_path, seed, 0, &equal, &o);
    }
    print_message("%s on %s (%u cells): %u edits byte-identical to the full bake, %u refused (cells changed); "
                  "%.1f%% of the cells re-baked\n",
                  method, sl_city_preset_name(preset), sl_viewcells_count(cells), o.compared, o.refused,
                  o.cells ? 100.0 * o.affected / o.cells : 0.0);
    assert_int_equal(o.compared, want);
    assert_true(o.affected < o.cells); /* something was copied */
    unlink(old_path);
    sl_viewcells_destroy(cells);
    sl_scene_destroy(olds);
}

/* Rule (c): an edit far from every cell that brings a new footprint base at or below the cells'
 * lowest eye (a raised plaza, base 0.7, 500 m away) changes which objects the methods test
 * through stand-ins (docs/pvs.md, "Footprints above the ground"): the box behind the wall is
 * hidden before and seen after (its stand-in reaches in front of the wall). The update must
 * re-bake those cells and write the full bake's bytes. */
static sl_scene plaza_scene(bool raised)
{
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t wall = sl_test_add_box(s, (sl_vec3){-80, 10, 0}, (sl_vec3){80, 14, 20}, SL_KIND_BUILDING,
                                    SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    float xy[8] = {-80, 10, 80, 10, 80, 14, -80, 14};
    sl_footprint_desc fd = {xy, 4, 0, 20, wall};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    assert_int_not_equal(sl_test_add_box(s, (sl_vec3){-2, 30, 0}, (sl_vec3){2, 32, 3}, SL_KIND_BUILDING,
                                         SL_OBJECT_CLOSED_CONVEX),
                         SL_NONE);
    if (raised) {
        uint32_t plaza = sl_test_add_box(s, (sl_vec3){500, 0, 0.7f}, (sl_vec3){520, 20, 1.2f}, SL_KIND_GROUND,
                                         SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
        float pxy[8] = {500, 0, 520, 0, 520, 20, 500, 20};
        sl_footprint_desc pd = {pxy, 4, 0.7f, 1.2f, plaza};
        assert_int_equal(sl_scene_add_footprint(s, &pd, NULL, &err), SL_OK);
    }
    return s;
}

static void test_new_base(void **state)
{
    (void)state;
    sl_error err;
    sl_scene olds = plaza_scene(false), news = plaza_scene(true);
    sl_viewcell c[2];
    for (int i = 0; i < 2; i++) {
        memset(&c[i], 0, sizeof c[i]);
        c[i].shape = SL_CELL_BOX;
        c[i].cluster = -1;
        c[i].z_min = 1, c[i].z_max = 2;
        c[i].bounds = (sl_aabb){{-2 + 6.0f * i, -2, 1}, {2 + 6.0f * i, 2, 2}};
    }
    sl_viewcells cells;
    assert_int_equal(sl_viewcells_create(c, 2, NULL, &cells, &err), SL_OK);
    for (int m = 0; m < 2; m++) {
        const char *method = m ? "sample" : "adjustable";
        char old_path[300], upd[300], full[300];
        path_of(old_path, sizeof old_path, "plaza_old.slpvs");
        path_of(upd, sizeof upd, "plaza_upd.slpvs");
        path_of(full, sizeof full, "plaza_full.slpvs");
        bake(olds, cells, method, old_path);
        bake(news, cells, method, full);
        assert_false(same_files(old_path, full)); /* the box behind the wall: hidden, then seen */
        sl_pvs old = NULL;
        assert_int_equal(sl_pvs_load(old_path, NULL, &old, &err), SL_OK);
        sl_pvs_update_options uo;
        memset(&uo, 0, sizeof uo);
        uo.threads = 1;
        sl_pvs_update_stats us;
        if (sl_pvs_update(old, olds, news, cells, upd, &uo, &us, &err) != SL_OK)
            fail_msg("%s: %s", method, err.message);
        assert_int_equal(us.cells_by_base, 2);
        if (!same_files(upd, full))
            fail_msg("%s: the update differs from the full bake", method);
        sl_pvs_destroy(old);
        unlink(old_path);
        unlink(upd);
        unlink(full);
    }
    sl_viewcells_destroy(cells);
    sl_scene_destroy(olds);
    sl_scene_destroy(news);
}

static void test_tiny_adjustable(void **state)
{
    (void)state;
    run_edits(SL_CITY_TINY, 6, "adjustable", 1, 6);
}

static void test_small_adjustable(void **state)
{
    (void)state;
    run_edits(SL_CITY_SMALL, 60, "adjustable", 101, 2);
}

static void test_tiny_sample(void **state)
{
    (void)state;
    run_edits(SL_CITY_TINY, 40, "sample", 201, 3);
}

/* The rule broken on purpose: without the probe (rule b) or without the old sets (rule a) some
 * edit's update must differ from the full bake — the comparison catches a wrong rule. */
static void test_weakened(void **state)
{
    (void)state;
    sl_scene olds = city(SL_CITY_TINY, 1);
    sl_viewcells cells = some_cells(olds, 6, 0);
    char old_path[300];
    path_of(old_path, sizeof old_path, "old.slpvs");
    bake(olds, cells, "adjustable", old_path);
    for (uint32_t weaken = 2; weaken >= 1; weaken--) {
        outcome o = {0};
        uint32_t differ = 0;
        for (uint64_t seed = 1; seed < (weaken == 2 ? 12u : 5u) && !differ; seed++) {
            bool equal = true;
            if (one_edit(olds, cells, "adjustable", old_path, seed, weaken, &equal, &o) && !equal)
                differ++;
        }
        print_message("weaken=%u: %s\n", weaken,
                      differ ? "an update differs from the full bake (caught)"
                             : "not caught (the probe flags the cells whose old sets hold a changed object too)");
        if (weaken == 2)
            assert_int_equal(differ, 1);
    }
    unlink(old_path);
    sl_viewcells_destroy(cells);
    sl_scene_destroy(olds);
}

/* Bad inputs: a file of another scene, of another method; an edit of the streets; no output. */
static void test_refusals(void **state)
{
    (void)state;
    sl_error err;
    sl_scene a = city(SL_CITY_TINY, 1), b = city(SL_CITY_TINY, 2);
    sl_viewcells cells = some_cells(a, 30, 3);
    char pa[300], out[300], pm[300];
    path_of(pa, sizeof pa, "a.slpvs");
    path_of(out, sizeof out, "out.slpvs");
    path_of(pm, sizeof pm, "m.slpvs");
    bake(a, cells, "adjustable", pa);
    sl_pvs pvs = NULL;
    assert_int_equal(sl_pvs_load(pa, NULL, &pvs, &err), SL_OK);
    sl_pvs_update_options uo;
    memset(&uo, 0, sizeof uo);
    uo.threads = 1;
    /* another scene as the old one */
    assert_int_equal(sl_pvs_update(pvs, b, a, cells, out, &uo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "not the one the file was baked for"));
    assert_int_not_equal(access(out, F_OK), 0);
    /* an unchanged scene: nothing re-baked, the same bytes */
    sl_pvs_update_stats us;
    assert_int_equal(sl_pvs_update(pvs, a, a, cells, out, &uo, &us, &err), SL_OK);
    assert_int_equal(us.cells_affected, 0);
    assert_true(same_files(pa, out));
    unlink(out);
    /* the streets edited: refused however the cells came out */
    sl_viewcells cb = some_cells(b, 30, 3);
    sl_status st = sl_pvs_update(pvs, a, b, cb, out, &uo, NULL, &err);
    assert_true(st == SL_ERROR_INVALID_ARGUMENT || st == SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "pvs build"));
    assert_int_not_equal(access(out, F_OK), 0);
    sl_viewcells_destroy(cb);
    /* buildings moved far, over the streets: the edited scene's street cells differ: refused */
    sl_city_edit_options eo = sl_city_edit_defaults();
    eo.remove = eo.add = 0;
    eo.move = 1;
    eo.shift = 30;
    eo.seed = 3;
    eo.region[0] = eo.region[1] = -1000, eo.region[2] = eo.region[3] = 1000;
    sl_scene e = NULL;
    assert_int_equal(sl_city_edit(a, &eo, NULL, &e, NULL, &err), SL_OK);
    sl_viewcells ce = some_cells(e, 30, 3);
    assert_int_not_equal(sl_viewcells_key(ce), sl_viewcells_key(cells));
    assert_int_equal(sl_pvs_update(pvs, a, e, ce, out, &uo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "view cells differ"));
    assert_int_not_equal(access(out, F_OK), 0);
    sl_viewcells_destroy(ce);
    sl_scene_destroy(e);
    sl_pvs_destroy(pvs);
    /* a file of another method (the same scene and cells, written as a gvs bake would be) */
    uint32_t nc = sl_viewcells_count(cells);
    uint64_t *off = calloc((size_t)nc + 1, sizeof *off);
    uint32_t id0 = 0;
    assert_non_null(off);
    assert_int_equal(sl_pvs_write(pm, cells, sl_scene_object_count(a), sl_pvs_scene_key(a), off, &id0,
                                  "method=gvs\noptions=\nguarantee=aggressive\n", &err),
                     SL_OK);
    free(off);
    assert_int_equal(sl_pvs_load(pm, NULL, &pvs, &err), SL_OK);
    assert_int_equal(sl_pvs_update(pvs, a, a, cells, out, &uo, NULL, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "method gvs"));
    assert_int_not_equal(access(out, F_OK), 0);
    sl_pvs_destroy(pvs);
    unlink(pa);
    unlink(pm);
    sl_viewcells_destroy(cells);
    sl_scene_destroy(a);
    sl_scene_destroy(b);
}

/* The edit itself: seeded, and it does what it says. */
static void test_city_edit(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s = city(SL_CITY_TINY, 1);
    sl_city_edit_options eo = sl_city_edit_defaults();
    eo.seed = 7;
    block_region(s, 5, eo.region);
    sl_scene e1 = NULL, e2 = NULL;
    sl_city_edit_stats a, b;
    assert_int_equal(sl_city_edit(s, &eo, NULL, &e1, &a, &err), SL_OK);
    assert_int_equal(sl_city_edit(s, &eo, NULL, &e2, &b, &err), SL_OK);
    assert_true(a.removed + a.moved + a.added > 0);
    assert_int_equal(sl_pvs_scene_key(e1), sl_pvs_scene_key(e2));
    assert_int_not_equal(sl_pvs_scene_key(e1), sl_pvs_scene_key(s));
    assert_int_equal(sl_scene_object_count(e1), sl_scene_object_count(s) - a.removed + a.added);
    assert_int_equal(sl_scene_footprint_count(e1), sl_scene_footprint_count(s) - a.removed + a.added);
    sl_scene_destroy(e2);
    e2 = NULL;
    eo.remove = 0.8f;
    eo.add = 0.3f;
    assert_int_equal(sl_city_edit(s, &eo, NULL, &e2, &b, &err) == SL_ERROR_INVALID_ARGUMENT, 1);
    assert_null(e2);
    sl_scene_destroy(e1);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/test_pvs_update.XXXXXX");
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
        cmocka_unit_test(test_city_edit),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_new_base),
        cmocka_unit_test(test_tiny_adjustable),
        cmocka_unit_test(test_weakened),
        cmocka_unit_test(test_tiny_sample),
        cmocka_unit_test(test_small_adjustable),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

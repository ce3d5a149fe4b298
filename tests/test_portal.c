/* The `portal` PVS method (conservative portal flow through a Quake III BSP):
 *  - a synthetic map of rooms joined by doorways, its BSP built here by axis-aligned splits: a
 *    room seen only around a corner is culled, rooms in line through the doors are kept, and
 *    the region oracle misses nothing in any cell;
 *  - non-cluster cells and scenes without BSP are refused with a message naming the cause;
 *  - the sets are the same baked through the file and cell by cell;
 *  - when openarena's pak1-maps.pk3 is installed: a small map baked with `portal` misses nothing
 *    the region oracle sees on a few clusters (sizes reported next to the map's own PVS), and its
 *    file is byte-identical when the walks run on one thread. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <omp.h>
#include <unistd.h>

#include "sightline/import.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/scene.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"

#include "support/pk3_names.h"

#define OA_PK3 SL_TEST_OA_PK3

static char g_dir[64];

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi)
{
    uint32_t obj = sl_test_add_box(s, lo, hi, SL_KIND_BSP_FACES, SL_OBJECT_CLOSED_CONVEX);
    assert_int_not_equal(obj, SL_NONE);
    return obj;
}

/* ---- a BSP from open boxes: axis-aligned splits on the boxes' faces until every region lies in
 * one box (open, that box's cluster) or in none (solid) ---- */

typedef struct room { float lo[3], hi[3]; int32_t cluster; } room;

typedef struct bsp_build {
    const room *rooms;
    uint32_t nrooms;
    sl_plane planes[256];
    sl_bsp_node nodes[256];
    sl_bsp_leaf leaves[256];
    uint32_t np, nn, nl;
} bsp_build;

static bool overlaps(const room *r, const float lo[3], const float hi[3])
{
    for (int a = 0; a < 3; a++)
        if (r->hi[a] <= lo[a] || r->lo[a] >= hi[a])
            return false;
    return true;
}

/* Returns the child code of the subtree for region [lo, hi]. */
static int32_t build(bsp_build *b, const float lo[3], const float hi[3])
{
    for (uint32_t i = 0; i < b->nrooms; i++) {
        const room *r = &b->rooms[i];
        if (!overlaps(r, lo, hi))
            continue;
        for (int a = 0; a < 3; a++)
            for (int side = 0; side < 2; side++) {
                float c = side ? r->hi[a] : r->lo[a];
                if (c <= lo[a] || c >= hi[a])
                    continue;
                assert_true(b->nn < 256 && b->np < 256);
                uint32_t node = b->nn++;
                sl_plane pl = {a == 0, a == 1, a == 2, -c};
                b->planes[b->np] = pl;
                b->nodes[node].plane = b->np++;
                b->nodes[node].bounds = (sl_aabb){{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
                float mid_lo[3] = {lo[0], lo[1], lo[2]}, mid_hi[3] = {hi[0], hi[1], hi[2]};
                mid_lo[a] = c;
                mid_hi[a] = c;
                b->nodes[node].children[0] = build(b, mid_lo, hi); /* front: x_a >= c */
                b->nodes[node].children[1] = build(b, lo, mid_hi);
                return (int32_t)node;
            }
    }
    int32_t cluster = -1;
    for (uint32_t i = 0; i < b->nrooms; i++)
        if (overlaps(&b->rooms[i], lo, hi))
            cluster = b->rooms[i].cluster;
    assert_true(b->nl < 256);
    uint32_t leaf = b->nl++;
    b->leaves[leaf] = (sl_bsp_leaf){cluster, 0, {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}, 0, 0};
    return -(int32_t)leaf - 1;
}

/* Rooms along y = 5 (z 0..3): D [-11,-1] | door | A [0,10] | door | B [11,21], and C north of B's
 * west end, x [0,12] y [11,21], joined to B by a door x [11,12] y [10,11]. A line from A through
 * the A-B door (y in [4,6] over x in [10,11]) climbs at most 2 m per metre, so it is below y = 8
 * at x = 12: C is around a corner from A, while D, A and B see each other through their doors. */
enum { C_D, C_DA, C_A, C_AB, C_B, C_BC, C_C, N_CLUSTERS };
static const room g_rooms[] = {
    {{-11, 0, 0}, {-1, 10, 3}, C_D}, {{-1, 4, 0}, {0, 6, 3}, C_DA},   {{0, 0, 0}, {10, 10, 3}, C_A},
    {{10, 4, 0}, {11, 6, 3}, C_AB},  {{11, 0, 0}, {21, 10, 3}, C_B},  {{11, 10, 0}, {12, 11, 3}, C_BC},
    {{0, 11, 0}, {12, 21, 3}, C_C},
};

typedef struct synth { sl_scene s; uint32_t box[N_CLUSTERS]; } synth;

static void synth_scene(synth *out)
{
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &out->s, &err), SL_OK);
    static bsp_build b; /* large; the test is single-threaded */
    memset(&b, 0, sizeof b);
    b.rooms = g_rooms;
    b.nrooms = sizeof g_rooms / sizeof g_rooms[0];
    const float lo[3] = {-14, -3, -2}, hi[3] = {24, 24, 5};
    int32_t root = build(&b, lo, hi);
    assert_int_equal(root, 0);
    /* a box on the floor of every room and doorway, listed by every leaf it overlaps */
    uint32_t leaf_objects[512], nlo = 0;
    for (uint32_t r = 0; r < N_CLUSTERS; r++) {
        const room *rm = &g_rooms[r];
        sl_vec3 c = {0.5f * (rm->lo[0] + rm->hi[0]), 0.5f * (rm->lo[1] + rm->hi[1]), 0};
        if (rm->cluster == C_C)
            c = (sl_vec3){10, 15, 0}; /* in view of B through the B-C door */
        float h = rm->hi[0] - rm->lo[0] < 2 ? 0.2f : 0.5f;
        out->box[rm->cluster] = add_box(out->s, (sl_vec3){c.x - h, c.y - h, 0.2f}, (sl_vec3){c.x + h, c.y + h, 1});
    }
    for (uint32_t l = 0; l < b.nl; l++) {
        b.leaves[l].first_object = nlo;
        for (uint32_t k = 0; k < N_CLUSTERS; k++) {
            sl_aabb ob = sl_scene_object_bounds(out->s, out->box[k]), lb = b.leaves[l].bounds;
            if (ob.min.x < lb.max.x && ob.max.x > lb.min.x && ob.min.y < lb.max.y && ob.max.y > lb.min.y &&
                ob.min.z < lb.max.z && ob.max.z > lb.min.z)
                leaf_objects[nlo++] = out->box[k];
        }
        b.leaves[l].object_count = nlo - b.leaves[l].first_object;
    }
    sl_bsp_desc bd = {b.planes, b.np, b.nodes, b.nn, b.leaves, b.nl, leaf_objects, nlo, N_CLUSTERS, 0, NULL};
    assert_int_equal(sl_scene_set_bsp(out->s, &bd, &err), SL_OK);
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* The cell of a cluster (cells from the BSP are one per cluster, in no promised order). */
static uint32_t cell_of(sl_viewcells vc, int32_t cluster)
{
    for (uint32_t i = 0; i < sl_viewcells_count(vc); i++)
        if (sl_viewcells_data(vc)[i].cluster == cluster)
            return i;
    fail_msg("no cell for cluster %d", cluster);
    return 0;
}

/* Every object the region oracle sees from the cell is in ids. */
static void check_oracle(sl_region_oracle ro, sl_viewcells vc, uint32_t cell, const uint32_t *ids, uint32_t n,
                         uint32_t *oracle_count)
{
    sl_error err;
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, cell, &v, &err), SL_OK);
    for (uint32_t i = 0; i < v.visible_count; i++)
        if (!has(ids, n, v.visible[i]))
            fail_msg("cell %u: object %u is visible (%u pixels) but not in the portal set", cell, v.visible[i],
                     v.max_pixels[i]);
    *oracle_count = v.visible_count;
}

static void test_rooms(void **state)
{
    (void)state;
    synth sy;
    synth_scene(&sy);
    sl_error err;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(sy.s, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), N_CLUSTERS);
    char file[128];
    snprintf(file, sizeof file, "%s/rooms.slpvs", g_dir);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "portal";
    bo.threads = 2;
    sl_pvs_build_stats st;
    assert_int_equal(sl_pvs_build(sy.s, vc, file, &bo, &st, &err), SL_OK);
    sl_pvs p;
    assert_int_equal(sl_pvs_load(file, NULL, &p, &err), SL_OK);
    sl_region_oracle_options oo = {0};
    oo.face_size = 96;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(sy.s, &oo, NULL, &ro, &err), SL_OK);
    uint32_t n = sl_scene_object_count(sy.s), ids[16], one[16], count, count1, seen;
    for (int32_t c = 0; c < N_CLUSTERS; c++) {
        uint32_t cell = cell_of(vc, c);
        assert_int_equal(sl_pvs_cell_set(p, cell, ids, n, &count, &err), SL_OK);
        /* the file and a single-cell bake agree */
        assert_int_equal(sl_pvs_bake_cell(sy.s, vc, cell, "portal", NULL, one, n, &count1, &err), SL_OK);
        assert_int_equal(count, count1);
        assert_memory_equal(ids, one, count * sizeof *ids);
        assert_true(has(ids, count, sy.box[c]));
        check_oracle(ro, vc, cell, ids, count, &seen);
        assert_true(seen >= 1);
        if (c == C_A || c == C_D || c == C_DA) {
            /* D, A and B in line through the doors; C around the corner */
            assert_true(has(ids, count, sy.box[C_D]) && has(ids, count, sy.box[C_A]) && has(ids, count, sy.box[C_B]));
            assert_false(has(ids, count, sy.box[C_C]));
        }
        if (c == C_C)
            assert_false(has(ids, count, sy.box[C_D]));
        if (c == C_B)
            assert_int_equal(count, n);
    }
    sl_region_oracle_destroy(ro);
    sl_pvs_destroy(p);
    unlink(file);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(sy.s);
}

static void test_refusals(void **state)
{
    (void)state;
    synth sy;
    synth_scene(&sy);
    sl_error err;
    uint32_t ids[16], count;
    /* a prism cell is not a cluster */
    sl_viewcell cell;
    memset(&cell, 0, sizeof cell);
    cell.shape = SL_CELL_BOX;
    cell.cluster = -1;
    cell.bounds = (sl_aabb){{1, 1, 1}, {2, 2, 2}};
    cell.z_min = 1;
    cell.z_max = 2;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(&cell, 1, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_pvs_bake_cell(sy.s, vc, 0, "portal", NULL, ids, 16, &count, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "not a cluster"));
    /* a scene without BSP data */
    sl_scene plain;
    assert_int_equal(sl_scene_create(NULL, &plain, &err), SL_OK);
    add_box(plain, (sl_vec3){0, 0, 0}, (sl_vec3){1, 1, 1});
    assert_int_equal(sl_pvs_bake_cell(plain, vc, 0, "portal", NULL, ids, 16, &count, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "no BSP"));
    sl_scene_destroy(plain);
    sl_viewcells_destroy(vc);
    /* an option out of range */
    assert_int_equal(sl_viewcells_from_bsp(sy.s, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_pvs_bake_cell(sy.s, vc, 0, "portal", "eps=5", ids, 16, &count, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "eps"));
    sl_viewcells_destroy(vc);
    sl_scene_destroy(sy.s);
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

/* Small OpenArena maps: zero misses on a few clusters; sizes next to the map's own PVS. */
static void test_openarena(void **state)
{
    (void)state;
    if (access(OA_PK3, R_OK) != 0) {
        printf("%s not installed: skipped\n", OA_PK3);
        skip();
    }
    bool san = getenv("SL_SANITIZED") != NULL;
    static const char *const maps[] = {"oa_bases3cl"};
    for (uint32_t m = 0; m < sizeof maps / sizeof maps[0]; m++) {
        sl_error err;
        sl_scene s;
        sl_import_options io = sl_import_defaults();
        assert_int_equal(sl_import_q3bsp(OA_PK3, maps[m], &io, NULL, &s, &err), SL_OK);
        sl_viewcells vc;
        assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
        char file[128];
        snprintf(file, sizeof file, "%s/%s.slpvs", g_dir, maps[m]);
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = "portal";
        bo.method_options = san ? "budget=2" : NULL;
        assert_int_equal(sl_pvs_build(s, vc, file, &bo, NULL, &err), SL_OK);
        /* the walks run in parallel chunks: one thread gives the same bytes */
        char one[160];
        snprintf(one, sizeof one, "%s.one", file);
        int threads = omp_get_max_threads();
        omp_set_num_threads(1);
        bo.threads = 1;
        assert_int_equal(sl_pvs_build(s, vc, one, &bo, NULL, &err), SL_OK);
        omp_set_num_threads(threads);
        assert_true(same_bytes(file, one));
        unlink(one);
        sl_pvs p;
        assert_int_equal(sl_pvs_load(file, NULL, &p, &err), SL_OK);
        sl_region_oracle_options oo = {0};
        oo.face_size = san ? 48 : 96;
        oo.face_samples = san ? 4 : 8;
        oo.interior_samples = san ? 4 : 8;
        sl_region_oracle ro;
        assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
        sl_bsp_view bv;
        assert_true(sl_scene_bsp(s, &bv));
        uint32_t n = sl_scene_object_count(s), nc = sl_viewcells_count(vc), count, seen, mcount;
        uint32_t *ids = malloc(n * sizeof *ids), *mids = malloc(n * sizeof *mids);
        assert_non_null(ids);
        assert_non_null(mids);
        uint64_t sum_portal = 0, sum_oracle = 0, sum_map = 0, checked = 0;
        uint32_t step = nc / (san ? 2 : 5) + 1;
        for (uint32_t c = 0; c < nc; c += step) {
            assert_int_equal(sl_pvs_cell_set(p, c, ids, n, &count, &err), SL_OK);
            check_oracle(ro, vc, c, ids, count, &seen);
            assert_int_equal(sl_pvs_bake_cell(s, vc, c, "mappvs", NULL, mids, n, &mcount, &err), SL_OK);
            sum_portal += count;
            sum_oracle += seen;
            sum_map += mcount;
            checked++;
        }
        /* not everything: the flow culls, and so does the map's own PVS (mappvs) */
        assert_true(sum_portal < (uint64_t)n * checked);
        assert_true(sum_map < (uint64_t)n * checked * 9 / 10);
        printf("%s: %u clusters, %llu checked: oracle %.1f, portal %.1f, map PVS %.1f objects per cell\n", maps[m],
               nc, (unsigned long long)checked, (double)sum_oracle / (double)checked,
               (double)sum_portal / (double)checked, (double)sum_map / (double)checked);
        free(ids);
        free(mids);
        sl_region_oracle_destroy(ro);
        sl_pvs_destroy(p);
        unlink(file);
        sl_viewcells_destroy(vc);
        sl_scene_destroy(s);
    }
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_test_portal_XXXXXX");
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
        cmocka_unit_test(test_rooms),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_openarena),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

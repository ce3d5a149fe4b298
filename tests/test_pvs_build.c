/* Baking PVSs: the three occluder-fusion cases of Wonka's thesis (figure 5.2: connected occluders,
 * overlapping umbrae, disjoint umbrae with overlapping penumbrae) are culled by the sample method
 * and the oracle agrees nothing visible is lost; an object seen through a gap is kept; the bake
 * is byte-identical with 1 and 2 threads; a stopped bake resumes to the same bytes, also from a
 * torn journal; a journal of another bake is refused; the pvs culler keeps every object the point
 * oracle sees; the tiny city has zero misses against the region oracle; the speed shortcuts of the
 * adjustable and sample methods (hierarchical disks, view channels) keep the sets conservative;
 * adjustable's split and fused horizons hide what the thesis's bounds cannot, and nothing the
 * oracle sees. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/truth.h"
#include "support/box_cell.h"
#include "support/box_mesh.h"
#include "support/counting_alloc.h"

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

/* A closed box object (CLOSED_CONVEX: the oracle skips its back faces, as a renderer would). */
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

/* Bake cell 0 with a method and check it against the region oracle: returns whether `target` is
 * in the set. */
static bool bake_with(sl_scene s, sl_viewcells vc, uint32_t target, const char *method, const char *opts)
{
    sl_error err;
    uint32_t n = sl_scene_object_count(s), count;
    uint32_t *ids = malloc(n * sizeof *ids);
    assert_int_equal(sl_pvs_bake_cell(s, vc, 0, method, opts, ids, n, &count, &err), SL_OK);
    bool san = getenv("SL_SANITIZED") != NULL; /* the sanitizer build is several times slower */
    sl_region_oracle_options oo = {0};
    oo.face_size = san ? 128 : 192;
    oo.edge_spacing = san ? 0.5f : 0.25f;
    oo.face_samples = san ? 12 : 32;
    oo.interior_samples = san ? 12 : 32;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    sl_region_visibility v;
    assert_int_equal(sl_region_oracle_cell(ro, vc, 0, &v, &err), SL_OK);
    for (uint32_t i = 0; i < v.visible_count; i++)
        if (!in_set(ids, count, v.visible[i]))
            fail_msg("object %u is visible (%u pixels) but not in the PVS", v.visible[i], v.max_pixels[i]);
    bool oracle_sees = false;
    for (uint32_t i = 0; i < v.visible_count; i++)
        oracle_sees |= v.visible[i] == target;
    bool r = in_set(ids, count, target);
    /* a target the method culls must be one the oracle cannot see */
    assert_true(r || !oracle_sees);
    sl_region_oracle_destroy(ro);
    free(ids);
    return r;
}

static bool bake_and_check(sl_scene s, sl_viewcells vc, uint32_t target, const char *opts)
{
    return bake_with(s, vc, target, "sample", opts);
}

/* The view cell: x, y in [-1, 1], eyes 1 to 2 m up. Occluders 20 m tall, at y = 10 and 15. */
static void test_fusion(void **state)
{
    (void)state;
    /* prefilter off: the cases test the cull maps' fusion, not the adjustable method's */
    const char *opts = "eps=0.5,cell=0.5,map=64,prefilter=false";
    sl_error err;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);

    /* (a) connected occluders: two buildings sharing a wall at x = 0; the target behind the joint is
     * hidden by neither alone, by their union yes (merge=true shrinks them as one block) */
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -12, 10, 0, 12, 20);
    add_building(s, 0, 10, 12, 12, 18);
    uint32_t t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_false(bake_and_check(s, vc, t, opts));
    /* shrunk one by one, a 2 eps gap opens at the joint and the target shows through it */
    assert_true(bake_and_check(s, vc, t, "eps=0.5,cell=0.5,map=64,merge=false,prefilter=false"));
    sl_scene_destroy(s);

    /* (b) overlapping umbrae: A (x < 2, y = 10) and B (x > -2, y = 15); each hides part of the wide
     * target from the whole cell and their umbrae overlap */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, 2, 12, 20);
    add_building(s, -2, 15, 40, 17, 20);
    t = add_box(s, -6, 30, 0, 10, 31, 3, SL_KIND_OTHER);
    assert_false(bake_and_check(s, vc, t, opts));
    sl_scene_destroy(s);

    /* (c) disjoint umbrae, overlapping penumbrae: A (x < 1, y = 10) and B (x > -1.5, y = 15); from
     * every point of the cell the two shadows meet over the target, but no part of the target
     * near x = 1..4 is in A's umbra and none near x = -5..-2 in B's */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, 1, 12, 20);
    add_building(s, -1.5f, 15, 40, 17, 20);
    t = add_box(s, -5, 30, 0, 4, 31, 3, SL_KIND_OTHER);
    assert_false(bake_and_check(s, vc, t, opts));
    sl_scene_destroy(s);

    /* control: a real 2 m gap between the occluders lets the target be seen, and it is kept */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, -1, 12, 20);
    add_building(s, 1, 10, 40, 12, 20);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake_and_check(s, vc, t, opts));
    /* and a thin wall (0.6 m < 2 eps) vanishes under shrinking: nothing behind it is culled */
    sl_scene_destroy(s);
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, 40, 10.6f, 20);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake_and_check(s, vc, t, opts));
    sl_shrunk sh;
    assert_int_equal(sl_shrink_footprints(s, 0.5f, SL_SHRINK_CYLINDER, true, NULL, &sh, &err), SL_OK);
    const uint32_t *gone;
    assert_int_equal(sl_shrunk_vanished(sh, &gone), 1);
    assert_int_equal(gone[0], 0);
    sl_shrunk_destroy(sh);
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

static uint8_t *read_file(const char *path, size_t *size)
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

static void assert_same_file(const char *a, const char *b)
{
    size_t na, nb;
    uint8_t *x = read_file(a, &na), *y = read_file(b, &nb);
    assert_int_equal(na, nb);
    assert_memory_equal(x, y, na);
    free(x);
    free(y);
}

/* The tiny city with coarse street cells. */
static void tiny(sl_scene *s, sl_viewcells *vc, float edge)
{
    sl_error err;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&o, NULL, s, &err), SL_OK);
    sl_viewcell_options vo = {0};
    vo.max_edge = edge;
    assert_int_equal(sl_viewcells_from_streets(*s, &vo, vc, &err), SL_OK);
}

/* Under the sanitizers (SL_SANITIZED, several times slower) the bakes take every step-th cell of
 * the city only: the same code paths on fewer cells. Replaces *vc. */
static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static void keep_every(sl_viewcells *vc, uint32_t step)
{
    if (step <= 1)
        return;
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

static void test_threads_resume(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 60);
    keep_every(&vc, sanitized() ? 6 : 1); /* 97 cells, 17 under the sanitizers */
    sl_error err;
    char one[300], two[300], part[300], ckpt[320];
    path_of(one, sizeof one, "one.slpvs");
    path_of(two, sizeof two, "two.slpvs");
    path_of(part, sizeof part, "part.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", part);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method_options = "map=128";
    bo.alloc = &a;
    bo.threads = 1;
    sl_pvs_build_stats st;
    assert_int_equal(sl_pvs_build(s, vc, one, &bo, &st, &err), SL_OK);
    assert_int_equal(st.cells, sl_viewcells_count(vc));
    assert_int_equal(st.cells_baked, st.cells);
    assert_string_equal(st.method, "sample");
    assert_int_equal(st.notice[0], 0); /* eps 1.5 >= 2 * sqrt(2) / 2 */
    assert_int_equal(access(one, F_OK), 0);
    /* the counting allocator is not thread-safe: the default one for two threads */
    bo.threads = 2;
    bo.alloc = NULL;
    assert_int_equal(sl_pvs_build(s, vc, two, &bo, &st, &err), SL_OK);
    assert_same_file(one, two);
    bo.alloc = &a;
    bo.threads = 1;

    /* stop after 5 cells: the journal stays, the output does not exist */
    bo.stop_after = 5;
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_CANCELLED);
    assert_non_null(strstr(err.message, "resume"));
    assert_int_equal(access(part, F_OK), -1);
    assert_int_equal(access(ckpt, F_OK), 0);
    /* a fresh bake does not silently throw the journal away */
    bo.stop_after = 0;
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "--resume"));
    /* another bake's journal is refused */
    bo.resume = true;
    bo.method_options = "map=128,eps=2";
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another bake"));
    /* tear the last record, then resume: same bytes as the uninterrupted bake */
    bo.method_options = "map=128";
    size_t jn;
    uint8_t *j = read_file(ckpt, &jn);
    assert_int_equal(truncate(ckpt, (off_t)jn - 3), 0);
    free(j);
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_OK);
    assert_true(st.cells_resumed >= 4 && st.cells_resumed <= 6);
    assert_int_equal(st.cells_resumed + st.cells_baked, st.cells);
    assert_same_file(one, part);
    assert_int_equal(access(ckpt, F_OK), -1);
    assert_int_equal(cnt.live, 0);

    /* unknown method and option */
    bo.resume = false;
    bo.method = "nope";
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_NOT_FOUND);
    bo.method = "sample";
    bo.method_options = "espilon=2";
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "espilon"));
    assert_int_equal(sl_pvs_method_check_options("sample", "eps=0.1,cell=2", &err), SL_OK);
    /* a small eps is allowed but noticed */
    bo.method_options = "eps=0.5,cell=2,map=128";
    bo.stop_after = 1;
    assert_int_equal(sl_pvs_build(s, vc, part, &bo, &st, &err), SL_ERROR_CANCELLED);
    assert_non_null(strstr(st.notice, "below"));
    unlink(ckpt);
    assert_int_equal(cnt.live, 0);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* The pvs culler's output for one camera is the eye's cell set within the frustum: every static
 * object of the located cell's set inside the frustum is there (sl_frustum_test_aabb), every
 * static one it reports is in the set of a cell near the eye (the near-plane region may add the
 * sets of cells it meets, docs/pvs.md), every dynamic object inside the frustum is there, and at
 * most a few (boxes within a rounding slack of a plane) lie outside the frustum. An eye outside
 * every cell gets the whole frustum set. Returns the size of (near cells' sets within the frustum)
 * so that the caller can see the PVS cut something. */
static uint32_t check_cell_set(sl_scene s, sl_pvs p, const sl_camera *cam, const uint32_t *ids, uint32_t count,
                               uint32_t *in_frustum_all)
{
    uint32_t n = sl_scene_object_count(s);
    sl_viewcells vc = sl_pvs_cells(p);
    uint32_t nc = sl_viewcells_count(vc);
    uint8_t *out = calloc(n, 1), *lower = calloc(n, 1), *upper = calloc(n, 1);
    uint32_t *set = malloc(n * sizeof *set), *cells = malloc(nc * sizeof *cells);
    assert_true(out && lower && upper && set && cells);
    for (uint32_t i = 0; i < count; i++)
        out[ids[i]] = 1;
    sl_frustum fr = sl_camera_frustum(cam);
    sl_error err;
    uint32_t cell = sl_viewcells_locate(vc, s, cam->position), k;
    if (cell != SL_NONE) {
        assert_int_equal(sl_pvs_cell_set(p, cell, set, n, &k, &err), SL_OK);
        for (uint32_t i = 0; i < k; i++)
            lower[set[i]] = 1;
        const float r = 2.0f; /* the near-plane region of these cameras lies within 2 m of the eye */
        sl_aabb eb = {{cam->position.x - r, cam->position.y - r, cam->position.z - r},
                      {cam->position.x + r, cam->position.y + r, cam->position.z + r}};
        bool covered;
        uint32_t m = sl_viewcells_overlap(vc, s, &eb, cells, nc, &covered);
        for (uint32_t c = 0; c < m; c++) {
            assert_int_equal(sl_pvs_cell_set(p, cells[c], set, n, &k, &err), SL_OK);
            for (uint32_t i = 0; i < k; i++)
                upper[set[i]] = 1;
        }
    }
    uint32_t outside = 0, cut = 0, all_in = 0;
    for (uint32_t id = 0; id < n; id++) {
        sl_aabb b = sl_scene_object_bounds(s, id);
        bool in = sl_frustum_test_aabb(&fr, &b) != 0;
        bool dyn = (sl_scene_object(s, id).flags & SL_OBJECT_DYNAMIC) != 0;
        all_in += in;
        if (out[id] && !in)
            outside++;
        if (cell == SL_NONE || dyn) {
            /* a dynamic object may be dropped by the motion regions (dynamic=auto with a file that
             * has them): then a node holding its box is unmarked even for the eye's own cell (the
             * culler ORs the rows of the cells near the eye, a superset of it) */
            bool by_regions = dyn && cell != SL_NONE && !sl_pvs_region_box_visible(p, sl_pvs_region_row(p, cell), &b);
            if (in && !out[id] && !by_regions)
                fail_msg("pvs culler: object %u (%s) is inside the frustum but not reported", id,
                         dyn ? "dynamic" : "eye in no cell");
            continue;
        }
        cut += in && upper[id];
        if (in && lower[id] && !out[id])
            fail_msg("pvs culler: object %u of cell %u's set is inside the frustum but not reported", id, cell);
        if (out[id] && !upper[id])
            fail_msg("pvs culler: object %u is reported but in the set of no cell near the eye (cell %u)", id, cell);
    }
    if (outside > 2 + count / 50)
        fail_msg("pvs culler: %u of the %u objects reported lie outside the frustum", outside, count);
    *in_frustum_all += all_in;
    free(out);
    free(lower);
    free(upper);
    free(set);
    free(cells);
    return cell == SL_NONE ? 0 : cut;
}

/* The pvs culler on the tiny city: cameras at random street points keep every object the point
 * oracle sees, and report exactly the cell's set within the frustum (check_cell_set), which culls
 * a good part of the frustum set; an eye outside every cell falls back to frustum culling; bad
 * options are refused. */
static void test_culler(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 60);
    keep_every(&vc, sanitized() ? 6 : 1); /* the cameras are placed in the cells baked */
    sl_error err;
    char file[300], opt[400];
    path_of(file, sizeof file, "culler.slpvs");
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method_options = "map=128";
    assert_int_equal(sl_pvs_build(s, vc, file, &bo, NULL, &err), SL_OK);
    snprintf(opt, sizeof opt, "file=%s", file);
    sl_culler c;
    assert_int_equal(sl_culler_create("pvs", s, opt, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE);
    assert_non_null(strstr(sl_culler_options(c), "dynamic=auto"));
    sl_oracle o;
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 256;
    oo.height = 192;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), count;
    uint32_t *ids = malloc(n * sizeof *ids);
    sl_rng r;
    sl_rng_seed(&r, 5, 0);
    const sl_viewcell *cells = sl_viewcells_data(vc);
    uint32_t in_cell = 0, cut = 0, frustum_all = 0;
    sl_pvs pvs;
    assert_int_equal(sl_pvs_load(file, NULL, &pvs, &err), SL_OK);
    int cams = sanitized() ? 8 : 24;
    for (int k = 0; k < cams; k++) {
        const sl_viewcell *cl = &cells[sl_rng_below(&r, sl_viewcells_count(vc))];
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){(cl->tri[0].x + cl->tri[1].x + cl->tri[2].x) / 3,
                                 (cl->tri[0].y + cl->tri[1].y + cl->tri[2].y) / 3, 1.7f};
        cam.yaw = sl_rng_range(&r, -3.14f, 3.14f);
        cam.width = 256;
        cam.height = 192;
        if (k == cams - 1)
            cam.position.z = 50; /* above every cell */
        in_cell += sl_viewcells_locate(vc, NULL, cam.position) != SL_NONE;
        assert_int_equal(sl_culler_cull(c, &cam, ids, n, &count, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        sl_cull_metrics m;
        assert_int_equal(sl_metrics_compare(s, &f, ids, count, &m, NULL, NULL, 0, &err), SL_OK);
        assert_int_equal(m.missed_count, 0);
        cut += check_cell_set(s, pvs, &cam, ids, count, &frustum_all);
    }
    assert_int_equal(in_cell, (uint32_t)cams - 1);
    /* the sets cut: well below every object in the frustum (the test above has teeth) */
    print_message("pvs culler: near cells' sets within the frustum %u of %u objects in the frustum\n", cut,
                  frustum_all);
    assert_true(cut < frustum_all * 3 / 4);
    sl_pvs_destroy(pvs);
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    free(ids);

    assert_int_equal(sl_culler_create("pvs", s, "", NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "file=PATH is required"));
    assert_int_equal(sl_culler_create("pvs", s, "file=/no/such.slpvs", NULL, &c, &err), SL_ERROR_NOT_FOUND);
    snprintf(opt, sizeof opt, "file=%s,dynamic=maybe", file);
    assert_int_equal(sl_culler_create("pvs", s, opt, NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    snprintf(opt, sizeof opt, "file=%s,dynamic=pvs", file);
    assert_int_equal(sl_culler_create("pvs", s, opt, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_AGGRESSIVE);
    sl_culler_destroy(c);
    /* another scene is refused */
    sl_scene other;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    co.seed = 2;
    assert_int_equal(sl_gen_city(&co, NULL, &other, &err), SL_OK);
    snprintf(opt, sizeof opt, "file=%s", file);
    assert_int_equal(sl_culler_create("pvs", other, opt, NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another scene"));
    sl_scene_destroy(other);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* A coarse region oracle for the tiny city (the tests stay short). */
static sl_region_oracle coarse_oracle(sl_scene s)
{
    sl_error err;
    sl_region_oracle_options oo = {0};
    oo.face_size = 96;
    oo.edge_spacing = 4;
    oo.face_samples = 6;
    oo.interior_samples = 6;
    sl_region_oracle ro;
    assert_int_equal(sl_region_oracle_create(s, &oo, NULL, &ro, &err), SL_OK);
    return ro;
}

/* Zero misses against the region oracle on every cell of the tiny city (coarse cells). */
static void test_tiny_city_oracle(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 40);
    /* under the sanitizers only the cells checked are baked (every 12th) */
    keep_every(&vc, sanitized() ? 12 : 1);
    sl_error err;
    char file[300];
    path_of(file, sizeof file, "tiny.slpvs");
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    assert_int_equal(sl_pvs_build(s, vc, file, &bo, NULL, &err), SL_OK);
    sl_pvs p;
    assert_int_equal(sl_pvs_load(file, NULL, &p, &err), SL_OK);
    sl_region_oracle ro = coarse_oracle(s);
    uint32_t n = sl_scene_object_count(s), count, nc = sl_viewcells_count(vc);
    uint32_t *ids = malloc(n * sizeof *ids);
    uint32_t step = sanitized() ? 1 : 3; /* a third of the cells (all baked under the sanitizers) */
    uint64_t total = 0, visible = 0;
    for (uint32_t c = 0; c < nc; c += step) {
        assert_int_equal(sl_pvs_cell_set(p, c, ids, n, &count, &err), SL_OK);
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_cell(ro, vc, c, &v, &err), SL_OK);
        for (uint32_t i = 0; i < v.visible_count; i++)
            if (!in_set(ids, count, v.visible[i]))
                fail_msg("cell %u: object %u is visible (%u pixels) but not in the PVS", c, v.visible[i],
                         v.max_pixels[i]);
        total += count;
        visible += v.visible_count;
    }
    /* the set is not trivially everything */
    assert_true(total < (uint64_t)n * ((nc + step - 1) / step));
    assert_true(visible <= total);
    free(ids);
    sl_region_oracle_destroy(ro);
    sl_pvs_destroy(p);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
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

/* The speed shortcuts keep the guarantee. adjustable's hierarchical disks: the result is the
 * intersection of every level's union, so it lies inside the coarsest level's set computed alone
 * (eps 1 * 2^top, levels=0); sample's view channels only leave occluders and map cells out, so
 * with occluder culling off (whose skips depend on the maps) the set contains the full maps' set;
 * with the prefilter, sample's set lies inside the adjustable set. Every set holds every object
 * the region oracle sees. */
static void test_shortcuts(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    tiny(&s, &vc, 20);
    sl_error err;
    sl_region_oracle ro = coarse_oracle(s);
    uint32_t n = sl_scene_object_count(s), nc = sl_viewcells_count(vc);
    enum { NM = 6 };
    const char *names[NM] = {"adjustable", "adjustable", "sample", "sample", "sample", "adjustable"};
    char coarse_opts[64];
    const char *opts[NM] = {"eps=1,levels=2", coarse_opts, "occluder_cull=false,prefilter=false,channels=true",
                            "occluder_cull=false,prefilter=false,channels=false", "", ""};
    uint32_t *ids[NM], count[NM];
    for (int m = 0; m < NM; m++)
        ids[m] = malloc(((size_t)n + 1) * sizeof(uint32_t));
    uint32_t cells = getenv("SL_SANITIZED") ? 2 : 6, tested = 0;
    uint64_t fine = 0, coarse = 0;
    for (uint32_t c = 0; c < nc && tested < cells; c += nc / cells + 1, tested++) {
        /* the coarsest level the method uses: the first whose grid square (eps 2^l sqrt 2) covers
         * the cell's box, at most levels (2) */
        const sl_aabb *bb = &sl_viewcells_data(vc)[c].bounds;
        double extent = fmax((double)bb->max.x - bb->min.x, (double)bb->max.y - bb->min.y);
        int top = 0;
        while (top < 2 && ldexp(1.0, top) * M_SQRT2 < extent)
            top++;
        snprintf(coarse_opts, sizeof coarse_opts, "eps=%g,levels=0", ldexp(1.0, top));
        for (int m = 0; m < NM; m++)
            assert_int_equal(sl_pvs_bake_cell(s, vc, c, names[m], opts[m], ids[m], n, &count[m], &err), SL_OK);
        if (!subset_of(ids[0], count[0], ids[1], count[1]))
            fail_msg("cell %u: the hierarchical adjustable set is not inside the coarse level's", c);
        if (!subset_of(ids[3], count[3], ids[2], count[2]))
            fail_msg("cell %u: sample with view channels lost objects of the full maps", c);
        if (!subset_of(ids[4], count[4], ids[5], count[5]))
            fail_msg("cell %u: sample with the prefilter keeps an object outside the adjustable set", c);
        fine += count[0], coarse += count[1];
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_cell(ro, vc, c, &v, &err), SL_OK);
        for (int m = 0; m < NM; m += 2)
            if (!subset_of(v.visible, v.visible_count, ids[m], count[m]))
                fail_msg("cell %u: %s (%s) misses an object the oracle sees", c, names[m], opts[m]);
    }
    assert_true(tested > 0);
    /* the finer disks do cull more than the coarse level alone */
    assert_true(fine < coarse);
    for (int m = 0; m < NM; m++)
        free(ids[m]);
    sl_region_oracle_destroy(ro);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* adjustable's horizon beyond the thesis's bounds, each against the region oracle:
 * fuse: two buildings sharing a wall hide what lies behind the joint as one occluder; shrunk one by
 * one, a gap of asin(eps/d) opens at the joint on each side and the target shows through it.
 * An L-shaped footprint's convex pieces hide what the whole footprint hides.
 * split: a long block beside the cell, seen along its facade, hides a courtyard object near the
 * cell; with one bound per piece (from the far end of the block, 150 m away) it hides nothing
 * nearer than that far end. Both still keep what shows through a real gap. */
static void test_adjustable_horizon(void **state)
{
    (void)state;
    sl_error err;
    sl_viewcells vc = sl_test_box_cell(-1, -1, 1, 1);
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, 0, 12, 20);
    add_building(s, 0, 10, 40, 12, 18);
    uint32_t t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_false(bake_with(s, vc, t, "adjustable", "eps=0.5,fuse=true"));
    assert_true(bake_with(s, vc, t, "adjustable", "eps=0.5"));
    sl_scene_destroy(s);
    /* an L-shaped footprint: its convex pieces cover all of it (merging two triangles once dropped
     * a vertex, and the pieces lost area), so the strip in front of the target hides it */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    {
        uint32_t obj = add_box(s, -40, 10, 0, 40, 20, 20, SL_KIND_BUILDING);
        float xy[12] = {-40, 10, 40, 10, 40, 12, 2, 12, 2, 20, -40, 20};
        sl_footprint_desc fd = {xy, 6, 0, 20, obj};
        assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    }
    t = add_box(s, 4, 30, 0, 8, 31, 3, SL_KIND_OTHER);
    assert_false(bake_with(s, vc, t, "adjustable", "eps=0.5"));
    assert_false(bake_with(s, vc, t, "adjustable", "eps=0.5,fuse=true"));
    sl_scene_destroy(s);
    /* a real 2 m gap at the joint: the target is seen, and kept */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, -40, 10, -1, 12, 20);
    add_building(s, 1, 10, 40, 12, 18);
    t = add_box(s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    assert_true(bake_with(s, vc, t, "adjustable", "eps=0.5,fuse=true"));
    sl_scene_destroy(s);

    /* split: the block x in [3, 13], y in [-5, 150], 20 m; the target behind it, 10 m tall */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, 3, -5, 13, 150, 20);
    t = add_box(s, 20, 10, 0, 22, 12, 10, SL_KIND_OTHER);
    assert_false(bake_with(s, vc, t, "adjustable", "eps=0.5"));
    assert_true(bake_with(s, vc, t, "adjustable", "eps=0.5,split=0"));
    /* taller than the block's shadow at its distance: kept */
    uint32_t tall = add_box(s, 20, 40, 0, 22, 42, 200, SL_KIND_OTHER);
    assert_true(bake_with(s, vc, tall, "adjustable", "eps=0.5"));
    sl_scene_destroy(s);
    sl_viewcells_destroy(vc);
}

/* ---- checkpoint, lock and thread limit: a small scene keeps these bakes to milliseconds ---- */

/* Five buildings in a row along y = 10 (height h) and two boxes behind them; n box cells along
 * the x axis in front. */
static void row_scene(float h, uint32_t n, sl_scene *s, sl_viewcells *vc)
{
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, s, &err), SL_OK);
    for (int i = 0; i < 5; i++)
        add_building(*s, -25 + 10.0f * (float)i, 10, -17 + 10.0f * (float)i, 12, h);
    add_box(*s, -3, 30, 0, 3, 31, 3, SL_KIND_OTHER);
    add_box(*s, 10, 30, 0, 14, 31, 3, SL_KIND_OTHER);
    sl_viewcell *c = calloc(n, sizeof *c);
    for (uint32_t i = 0; i < n; i++) {
        float x0 = -12 + 2.0f * (float)i;
        c[i].shape = SL_CELL_BOX;
        c[i].cluster = -1;
        c[i].z_min = 1;
        c[i].z_max = 2;
        c[i].bounds = (sl_aabb){{x0, -1, 1}, {x0 + 2, 1, 2}};
    }
    assert_int_equal(sl_viewcells_create(c, n, NULL, vc, &err), SL_OK);
    free(c);
}

static bool exists(const char *path) { return access(path, F_OK) == 0; }

/* What a bake started from inside another bake of the same output (from its progress callback:
 * the first bake holds the lock then) answered. */
typedef struct nested {
    sl_scene s;
    sl_viewcells vc;
    const char *out;
    int calls;
    sl_status plain, resumed;
    char plain_msg[512], resumed_msg[512];
} nested;

static bool nested_bake(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)stage, (void)total;
    nested *n = user;
    if (done == 0 || n->calls++ > 0)
        return true;
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method_options = "map=64";
    bo.threads = 1;
    sl_error err;
    n->plain = sl_pvs_build(n->s, n->vc, n->out, &bo, NULL, &err);
    snprintf(n->plain_msg, sizeof n->plain_msg, "%s", err.message);
    bo.resume = true;
    n->resumed = sl_pvs_build(n->s, n->vc, n->out, &bo, NULL, &err);
    snprintf(n->resumed_msg, sizeof n->resumed_msg, "%s", err.message);
    return true;
}

/* The checkpoint is written only once a cell is done: a bake that fails in prepare (mappvs on a
 * scene without BSP) leaves none and does not block the next one; a journal of the same bake
 * with no whole cell is not worth resuming and is replaced; one with cells blocks a plain bake
 * with how many cells it holds and the command to delete it; a journal of another bake says what
 * differs (scene, cells, method or options), one of an older version or a damaged one says so, each
 * with the command to delete it. The bake lock: a second bake of the same output while the first
 * runs is told "another bake of OUT is running (pid N)", with --resume too, and the first one
 * finishes unharmed; the lock file goes with the bake. A thread count above the limit is refused. */
static void test_checkpoint_lock(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells vc;
    row_scene(20, 8, &s, &vc);
    sl_error err;
    char ref[300], out[300], ckpt[320], lock[330], rm[360];
    path_of(ref, sizeof ref, "row_ref.slpvs");
    path_of(out, sizeof out, "row.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", out);
    snprintf(lock, sizeof lock, "%s.lock", ckpt);
    snprintf(rm, sizeof rm, "rm -- '%s'", ckpt);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method_options = "map=64";
    bo.threads = 1;
    sl_pvs_build_stats st;
    assert_int_equal(sl_pvs_build(s, vc, ref, &bo, &st, &err), SL_OK);
    assert_int_equal(st.cells, 8);

    /* a prepare-time failure leaves no checkpoint and no lock; the next bake runs */
    bo.method = "mappvs";
    bo.method_options = NULL;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_UNSUPPORTED);
    assert_false(exists(ckpt));
    assert_false(exists(lock));
    bo.method = NULL;
    bo.method_options = "map=64";
    if (sl_pvs_build(s, vc, out, &bo, NULL, &err) != SL_OK)
        fail_msg("the bake after a failed one: %s", err.message);
    assert_same_file(ref, out);
    assert_false(exists(ckpt));
    assert_false(exists(lock));
    unlink(out);

    /* a journal holding no whole cell (killed while writing the first) is replaced */
    bo.stop_after = 1;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_CANCELLED);
    size_t jn;
    uint8_t *j = read_file(ckpt, &jn);
    free(j);
    assert_true(jn > 64 + 24);
    assert_int_equal(truncate(ckpt, (off_t)jn - 2), 0);
    bo.stop_after = 0;
    if (sl_pvs_build(s, vc, out, &bo, &st, &err) != SL_OK)
        fail_msg("a journal without a whole cell blocked the bake: %s", err.message);
    assert_int_equal(st.cells_resumed, 0);
    assert_same_file(ref, out);
    unlink(out);

    /* a journal with cells blocks a plain bake and says how to go on */
    bo.stop_after = 3;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_CANCELLED);
    bo.stop_after = 0;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "holds 3 of 8 cells"));
    assert_non_null(strstr(err.message, "--resume"));
    assert_non_null(strstr(err.message, rm));

    /* another bake's journal: what differs, and the command to delete it */
    bo.resume = true;
    bo.method_options = "map=64,eps=2";
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another method or options"));
    assert_non_null(strstr(err.message, "map=64"));
    assert_non_null(strstr(err.message, "eps=2"));
    assert_null(strstr(err.message, "other view cells"));
    assert_null(strstr(err.message, "another scene"));
    assert_non_null(strstr(err.message, rm));
    bo.method_options = "map=64";
    sl_scene s2;
    sl_viewcells vc2;
    row_scene(20, 9, &s2, &vc2);
    assert_int_equal(sl_pvs_build(s2, vc2, out, &bo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "other view cells (8 in the checkpoint, 9 now)"));
    assert_null(strstr(err.message, "another method"));
    sl_viewcells_destroy(vc2);
    sl_scene_destroy(s2);
    row_scene(15, 8, &s2, &vc2); /* lower buildings: same counts, another scene */
    assert_int_equal(sl_pvs_build(s2, vc2, out, &bo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another scene"));
    assert_null(strstr(err.message, "other view cells"));
    assert_non_null(strstr(err.message, rm));
    sl_viewcells_destroy(vc2);
    sl_scene_destroy(s2);
    /* the same inputs resume it */
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, &st, &err), SL_OK);
    assert_int_equal(st.cells_resumed, 3);
    assert_same_file(ref, out);
    assert_false(exists(ckpt));
    unlink(out);

    /* a journal of an older version, and a damaged one */
    FILE *f = fopen(ckpt, "wb");
    assert_non_null(f);
    uint8_t v1[64] = "SLPVSCKP\x01";
    assert_int_equal(fwrite(v1, 1, sizeof v1, f), sizeof v1);
    fclose(f);
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "journal version 1"));
    assert_non_null(strstr(err.message, rm));
    f = fopen(ckpt, "wb");
    assert_int_equal(fwrite("not a journal", 1, 13, f), 13);
    fclose(f);
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "not a PVS checkpoint journal"));
    unlink(ckpt);

    /* the lock: a bake of the same output from inside the running one (another file description,
     * as another process would have) is refused with the holder's pid, plain and with --resume */
    nested n = {s, vc, out, 0, SL_OK, SL_OK, "", ""};
    bo.resume = false;
    bo.progress.fn = nested_bake;
    bo.progress.user = &n;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, &st, &err), SL_OK);
    bo.progress.fn = NULL;
    assert_int_equal(n.calls, 8);
    char running[400];
    snprintf(running, sizeof running, "another bake of %s is running (pid %ld)", out, (long)getpid());
    assert_int_not_equal(n.plain, SL_OK);
    if (!strstr(n.plain_msg, running))
        fail_msg("plain: '%s' lacks '%s'", n.plain_msg, running);
    assert_int_not_equal(n.resumed, SL_OK);
    if (!strstr(n.resumed_msg, running))
        fail_msg("resumed: '%s' lacks '%s'", n.resumed_msg, running);
    assert_same_file(ref, out);
    assert_false(exists(ckpt));
    assert_false(exists(lock));
    unlink(out);

    /* the one thread limit */
    bo.threads = 100000;
    assert_int_equal(sl_pvs_build(s, vc, out, &bo, NULL, &err), SL_ERROR_LIMIT);
    assert_non_null(strstr(err.message, "at most"));
    assert_false(exists(ckpt));
    assert_int_equal(sl_threads_check(SL_MAX_THREADS, false, "x", &err), SL_OK);
    assert_int_equal(sl_threads_check(0, true, "x", &err), SL_OK);
    assert_int_equal(sl_threads_check(0, false, "x", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_threads_check(SL_MAX_THREADS + 1, false, "x", &err), SL_ERROR_LIMIT);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    /* a short directory of its own, not under the build tree: the checkpoint messages name their
     * paths two or three times and are cut at the 512 bytes of sl_error, so under a long build
     * path the command they end with would be cut off and the checks of it fail */
    snprintf(g_dir, sizeof g_dir, "/tmp/test_pvs_build.XXXXXX");
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
        cmocka_unit_test(test_threads_resume),
        cmocka_unit_test(test_checkpoint_lock),
        cmocka_unit_test(test_culler),
        cmocka_unit_test(test_tiny_city_oracle),
        cmocka_unit_test(test_shortcuts),
        cmocka_unit_test(test_adjustable_horizon),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

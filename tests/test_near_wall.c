/* Near-wall views against the point oracle (issue 12 §1): every conservative method must keep every
 * object the oracle sees when the eye is 0.001-0.2 m in front of a surface, where the near plane
 * (0.1 m, 0.139 m at the frustum's corners) cuts the surface and the oracle sees through the hole.
 * Views: bench/near_wall_views.h (a random point of a random triangle, stepped out along its
 * normal, looking towards the surface). Scenes: 10 OpenArena maps (openarena-081-maps) and the
 * small city. Every conservative method of the registry, frusta and hzb with all_objects=true
 * besides their defaults; the pvs culler (it reads a baked file) in test_near_wall_pvs, on 3 maps
 * with a portal bake and on street-cell views of the small city with a sample bake.
 * Hand-built scenes: a building 5 mm or 5 cm in front of the eye, closed convex (the oracle skips its back
 * faces, so through the clipped hole it sees what lies behind the building) or two-sided, with a
 * footprint (prism and 2.5D occluders) or without (its own mesh as occluder), and an object
 * behind it: no method may cull what the oracle sees there.
 * Bounded camera input: a near plane the float matrix cannot resolve (1e-30 m) is refused by the
 * methods that project with it and by the oracle, naming the limit; at the limit nothing is missed.
 * A huge far plane (1e6 to 3e38 m) on street views of the tiny and small city: every method that
 * accepts it stays conservative (cullmap did not at 1e20).
 * CTest: 60 views per map and 160 of the city at 320x240 (760 in all); under SL_SANITIZED 3 maps of
 * 8 views and the city's 10; the pvs culler: 80 views on each of 3 maps and 40 of the city (10 and
 * 10 on one map and the city under SL_SANITIZED). bench/near_wall.c sweeps every map.
 * SL_TEST_FILTER=PATTERN runs the matching tests only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/truth.h"

#include "../bench/near_wall_views.h"
#include "support/city_views.h"
#include "support/pk3_names.h"

#define OA_PK3 SL_TEST_OA_PK3

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static const struct {
    const char *name, *options;
} g_methods[] = {
    {"vfc", NULL},
    {"cullmap", NULL},
    {"horizon", NULL},
    {"dhorizon", NULL},
    {"hzb", NULL},
    {"hzb", "all_objects=true"},
    {"lazygrid", NULL},
    {"lazygrid-z", NULL},
    {"busygrid", NULL},
    {"hom", NULL},
    {"frusta", NULL},
    {"frusta", "all_objects=true"},
    {"cplp", NULL},
};
#define NM SL_COUNTOF(g_methods)

typedef struct tally {
    uint64_t frames, missed_frames, missed_objects;
} tally;

/* Cull `views` near-wall views of s with every method; returns the frames any method missed in. */
static uint64_t run_scene(sl_scene s, const char *label, uint32_t views, uint64_t seed, tally *t)
{
    sl_error err;
    sl_culler c[NM];
    bool ok[NM];
    for (size_t i = 0; i < NM; i++) {
        ok[i] = sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &c[i], &err) == SL_OK;
        if (!ok[i])
            print_message("%s: %s not run: %s\n", label, g_methods[i].name, err.message);
        else
            assert_int_equal(sl_culler_guarantee(c[i]), SL_CONSERVATIVE);
    }
    nw_table tb;
    assert_true(nw_table_build(s, &tb));
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out), missed[4], mpx[4];
    sl_camera in = sl_camera_default();
    in.width = 320;
    in.height = 240;
    nw_rng r = {seed};
    uint64_t bad = 0;
    for (uint32_t f = 0; f < views; f++) {
        sl_camera cam;
        double d = nw_view(s, &tb, &r, &in, 0.001, 0.2, &cam);
        assert_true(d >= 0);
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        bool any = false;
        for (size_t i = 0; i < NM; i++) {
            if (!ok[i])
                continue;
            uint32_t k;
            if (sl_culler_cull(c[i], &cam, out, n, &k, &err) != SL_OK)
                fail_msg("%s %s frame %u: %s", label, g_methods[i].name, f, err.message);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
            t[i].frames++;
            if (mt.missed_count) {
                any = true;
                t[i].missed_frames++;
                t[i].missed_objects += mt.missed_count;
                print_message("%s: %s%s%s view %u missed %u objects (first %u, %u pixels); eye %.3f m from the "
                              "surface at (%.4f, %.4f, %.4f) yaw %.5f pitch %.5f roll %.5f\n",
                              label, g_methods[i].name, g_methods[i].options ? " " : "",
                              g_methods[i].options ? g_methods[i].options : "", f, mt.missed_count, missed[0], mpx[0],
                              d, (double)cam.position.x, (double)cam.position.y, (double)cam.position.z,
                              (double)cam.yaw, (double)cam.pitch, (double)cam.roll);
            }
        }
        bad += any;
    }
    free(out);
    sl_oracle_destroy(o);
    nw_table_free(&tb);
    for (size_t i = 0; i < NM; i++)
        if (ok[i])
            sl_culler_destroy(c[i]);
    return bad;
}

static void report(const tally *t)
{
    for (size_t i = 0; i < NM; i++)
        print_message("near-wall %-10s %-18s %llu views, %llu with misses, %llu objects missed\n", g_methods[i].name,
                      g_methods[i].options ? g_methods[i].options : "", (unsigned long long)t[i].frames,
                      (unsigned long long)t[i].missed_frames, (unsigned long long)t[i].missed_objects);
}

/* 10 OpenArena maps spread over the pk3's list, then the small city. */
static void test_near_wall_views(void **state)
{
    (void)state;
    tally t[NM];
    memset(t, 0, sizeof t);
    uint64_t bad = 0, views = 0;
    if (access(OA_PK3, R_OK) != 0) {
        print_message("maps skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
    } else {
        sl_test_name_list *list = calloc(1, sizeof *list);
        sl_error err;
        assert_int_equal(sl_pk3_list_maps(OA_PK3, sl_test_collect_name, list, &err), SL_OK);
        assert_true(list->count >= 10);
        int maps = sanitized() ? 3 : 10;
        uint32_t per_map = sanitized() ? 8 : 60;
        for (int m = 0; m < maps; m++) {
            int i = m * list->count / maps;
            sl_scene s;
            if (sl_import_q3bsp(OA_PK3, list->names[i], NULL, NULL, &s, &err) != SL_OK)
                fail_msg("%s", err.message);
            bad += run_scene(s, list->names[i], per_map, 1000 + (uint64_t)i, t);
            views += per_map;
            sl_scene_destroy(s);
        }
        free(list);
    }
    sl_city_options co = sl_city_defaults(SL_CITY_SMALL);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    uint32_t nc = sanitized() ? 10 : 160;
    bad += run_scene(s, "small city", nc, 77, t);
    views += nc;
    sl_scene_destroy(s);
    report(t);
    print_message("near-wall: %llu views, %llu with a conservative miss\n", (unsigned long long)views,
                  (unsigned long long)bad);
    assert_int_equal(bad, 0);
}


/* The pvs culler near walls: its cell's set was computed from inside the cell, but an eye a few cm
 * from a wall sees through the near plane's cut what lies beyond it. Views as above; a PVS baked
 * with `method` (whole: every cell, by sl_pvs_build; else only the cells within 0.25 m of an eye,
 * every other cell getting every object, which is conservative and costs nothing), written to a temporary file and culled through. Returns the
 * views with an eye in a cell; adds the misses to *missed. */
static uint32_t run_pvs(sl_scene s, sl_viewcells vc, const char *label, const char *method, const char *mopts,
                        bool whole, uint32_t views, uint64_t seed, uint64_t *missed_objects)
{
    sl_error err;
    nw_table tb;
    assert_true(nw_table_build(s, &tb));
    uint32_t n = sl_scene_object_count(s), nc = sl_viewcells_count(vc);
    sl_camera in = sl_camera_default();
    in.width = 320;
    in.height = 240;
    sl_camera *cams = malloc(views * sizeof *cams);
    double *dist = malloc(views * sizeof *dist);
    bool *need = calloc(nc, 1);
    uint32_t *near = malloc(nc * sizeof *near);
    nw_rng r = {seed};
    uint32_t in_cells = 0;
    for (uint32_t f = 0; f < views; f++) {
        /* views with the eye in no cell are plain frustum culling: drawn again (up to 400 times;
         * in the city most surfaces lie outside the street cells' eye range) */
        for (int tries = 0; tries < 400; tries++) {
            dist[f] = nw_view(s, &tb, &r, &in, 0.001, 0.2, &cams[f]);
            assert_true(dist[f] >= 0);
            if (sl_viewcells_locate(vc, s, cams[f].position) != SL_NONE)
                break;
        }
        sl_vec3 e = cams[f].position;
        if (sl_viewcells_locate(vc, s, e) == SL_NONE)
            continue;
        in_cells++;
        sl_aabb b = {{e.x - 0.25f, e.y - 0.25f, e.z - 0.25f}, {e.x + 0.25f, e.y + 0.25f, e.z + 0.25f}};
        uint32_t k = sl_viewcells_overlap(vc, s, &b, near, nc, NULL);
        for (uint32_t i = 0; i < k; i++)
            need[near[i]] = true;
    }
    char file[64], opts[96];
    snprintf(file, sizeof file, "/tmp/sl_near_wall_pvs_%ld.slpvs", (long)getpid());
    uint32_t baked = 0;
    if (whole) {
        /* the method's preparation computes every cell at once: bake the file */
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = method;
        bo.method_options = mopts;
        bo.threads = 2;
        if (sl_pvs_build(s, vc, file, &bo, NULL, &err) != SL_OK)
            fail_msg("%s: %s bake: %s", label, method, err.message);
        baked = nc;
    } else {
        uint64_t *off = malloc(((size_t)nc + 1) * sizeof *off), at = 0;
        uint32_t *ids = malloc(((size_t)nc * n + 1) * sizeof *ids);
        for (uint32_t c = 0; c < nc; c++) {
            off[c] = at;
            uint32_t k = n;
            if (need[c]) {
                if (sl_pvs_bake_cell(s, vc, c, method, mopts, ids + at, n, &k, &err) != SL_OK)
                    fail_msg("%s: %s bake of cell %u: %s", label, method, c, err.message);
                baked++;
            } else {
                for (uint32_t i = 0; i < n; i++)
                    ids[at + i] = i;
            }
            at += k;
        }
        off[nc] = at;
        char meta[96];
        snprintf(meta, sizeof meta, "method=%s\nguarantee=conservative", method);
        assert_int_equal(sl_pvs_write(file, vc, n, sl_pvs_scene_key(s), off, ids, meta, &err), SL_OK);
        free(ids);
        free(off);
    }
    snprintf(opts, sizeof opts, "file=%s", file);
    sl_culler c;
    if (sl_culler_create("pvs", s, opts, NULL, &c, &err) != SL_OK)
        fail_msg("%s: pvs: %s", label, err.message);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out), missed[4], mpx[4];
    uint32_t bad = 0, every = 0;
    for (uint32_t f = 0; f < views; f++) {
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cams[f], &fr, &err), SL_OK);
        uint32_t k;
        if (sl_culler_cull(c, &cams[f], out, n, &k, &err) != SL_OK)
            fail_msg("%s pvs view %u: %s", label, f, err.message);
        sl_cull_stats cs;
        sl_culler_stats(c, &cs);
        every += cs.objects_tested >= n; /* every object was a candidate: no cell, or the near box left them */
        sl_cull_metrics mt;
        assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
        if (mt.missed_count) {
            bad++;
            *missed_objects += mt.missed_count;
            print_message("%s: pvs (%s) view %u missed %u objects (first %u, %u pixels); eye %.3f m from the surface "
                          "at (%.4f, %.4f, %.4f) yaw %.5f pitch %.5f\n",
                          label, method, f, mt.missed_count, missed[0], mpx[0], dist[f], (double)cams[f].position.x,
                          (double)cams[f].position.y, (double)cams[f].position.z, (double)cams[f].yaw,
                          (double)cams[f].pitch);
        }
    }
    print_message("%s: pvs (%s, %u of %u cells baked): %u views, %u with an eye in a cell, %u with every object a "
                  "candidate, %u with misses\n",
                  label, method, baked, nc, views, in_cells, every, bad);
    sl_culler_destroy(c);
    sl_oracle_destroy(o);
    unlink(file);
    free(out);
    free(near);
    free(need);
    free(dist);
    free(cams);
    nw_table_free(&tb);
    return in_cells;
}

/* The pvs culler on near-wall views: 3 OpenArena maps (aggressor, where the previous measurement
 * found the misses, and two more) with a portal bake of their clusters, and the small city with a
 * sample bake of its street cells. */
static void test_near_wall_pvs(void **state)
{
    (void)state;
    uint64_t missed = 0;
    uint32_t in_cells = 0;
    sl_error err;
    static const char *const maps[] = {"aggressor", "oa_dm1", "dm4ish"};
    uint32_t per_map = sanitized() ? 10 : 80;
    if (access(OA_PK3, R_OK) != 0) {
        print_message("maps skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
    } else {
        for (size_t m = 0; m < (sanitized() ? 1u : SL_COUNTOF(maps)); m++) {
            sl_scene s;
            if (sl_import_q3bsp(OA_PK3, maps[m], NULL, NULL, &s, &err) != SL_OK)
                fail_msg("%s", err.message);
            sl_viewcells vc;
            assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
            in_cells += run_pvs(s, vc, maps[m], "portal", "budget=2", true, per_map, 500 + m, &missed);
            sl_viewcells_destroy(vc);
            sl_scene_destroy(s);
        }
    }
    sl_city_options co = sl_city_defaults(SL_CITY_SMALL);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_streets(s, NULL, &vc, &err), SL_OK);
    in_cells += run_pvs(s, vc, "small city", "sample", NULL, false, sanitized() ? 10 : 40, 78, &missed);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
    print_message("near-wall pvs: %u views with an eye in a cell, %llu objects missed\n", in_cells,
                  (unsigned long long)missed);
    assert_true(in_cells > 0);
    assert_int_equal(missed, 0);
}

/* A box as 12 triangles wound counter-clockwise seen from outside (outward normals by the
 * right-hand rule, the oracle's front faces), one object of that kind and flags. */
static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    sl_error err;
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* One building 10 x 5 x 6 m (x from 0 to 5), a target box behind it, the ground; the eye at
 * x = -gap, 1.7 m up, looking along +x at `yaw`. */
static uint32_t judge_building(bool closed, bool footprint, float gap, float yaw)
{
    uint32_t bad = 0;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){-40, -40, -0.1f}, (sl_vec3){40, 40, 0}, SL_KIND_GROUND, 0);
    uint32_t flags = SL_OBJECT_OCCLUDER | (closed ? SL_OBJECT_CLOSED_CONVEX : 0u);
    uint32_t b = add_box(s, (sl_vec3){0, -5, 0}, (sl_vec3){5, 5, 6}, SL_KIND_BUILDING, flags);
    if (footprint) {
        float xy[8] = {0, -5, 5, -5, 5, 5, 0, 5};
        sl_footprint_desc fd = {xy, 4, 0.0f, 6.0f, b};
        assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    }
    uint32_t target = add_box(s, (sl_vec3){8, -1, 0}, (sl_vec3){9, 1, 3}, SL_KIND_OTHER, 0);
    sl_camera cam = sl_camera_default();
    cam.width = 160;
    cam.height = 120;
    cam.position = (sl_vec3){-gap, 0, 1.7f};
    cam.yaw = yaw;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    bool seen = false;
    for (uint32_t k = 0; k < fr.visible_count; k++)
        seen |= fr.visible[k] == target;
    /* a closed convex building seen through its clipped front face hides nothing */
    if (closed && yaw == 0.0f && !seen) {
        for (uint32_t k = 0; k < fr.visible_count; k++)
            print_message("visible %u: %u px\n", fr.visible[k], fr.pixels[k]);
        fail_msg("the oracle does not see the target through the clipped wall (gap %g)", (double)gap);
    }
    uint32_t n = sl_scene_object_count(s), out[8], missed[4], mpx[4];
    for (size_t i = 0; i < NM; i++) {
        sl_culler c;
        if (sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &c, &err) != SL_OK) {
            print_message("%s not run: %s\n", g_methods[i].name, err.message);
            continue;
        }
        uint32_t k;
        assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
        sl_cull_metrics mt;
        assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
        if (mt.missed_count && ++bad)
            print_message("%s%s%s: %s building%s, eye %.3f m from its wall, yaw %.2f: missed %u objects (first %u, %u "
                     "pixels; target %u)\n",
                     g_methods[i].name, g_methods[i].options ? " " : "", g_methods[i].options ? g_methods[i].options : "",
                     closed ? "closed convex" : "two-sided", footprint ? " with a footprint" : "", (double)gap,
                     (double)yaw, mt.missed_count, missed[0], mpx[0], target);
        sl_culler_destroy(c);
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
    return bad;
}

static void test_building_near_wall(void **state)
{
    (void)state;
    static const float gaps[] = {0.05f, 0.005f}, yaws[] = {0.0f, 0.6f, -1.1f};
    uint32_t bad = 0;
    for (int closed = 0; closed < 2; closed++)
        for (int fp = 0; fp < 2; fp++)
            for (size_t g = 0; g < SL_COUNTOF(gaps); g++)
                for (size_t y = 0; y < SL_COUNTOF(yaws); y++)
                    bad += judge_building(closed, fp, gaps[g], yaws[y]);
    assert_int_equal(bad, 0);
}

/* The pvs culler before the building of judge_building (closed convex, with its footprint): one
 * box cell in front of its wall (x in [-3, 0], eyes 1-2 m up), baked by the sample method — from
 * the cell the target behind the building is hidden, so the set leaves it out — and an eye 5 mm
 * from the wall looking at it, which sees the target through the clipped wall: the near-plane
 * region reaches into the building, outside every cell, and the culler must keep the target. */
static void test_building_pvs(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){-40, -40, -0.1f}, (sl_vec3){40, 40, 0}, SL_KIND_GROUND, 0);
    uint32_t b = add_box(s, (sl_vec3){0, -5, 0}, (sl_vec3){5, 5, 6}, SL_KIND_BUILDING,
                         SL_OBJECT_OCCLUDER | SL_OBJECT_CLOSED_CONVEX);
    float xy[8] = {0, -5, 5, -5, 5, 5, 0, 5};
    sl_footprint_desc fd = {xy, 4, 0.0f, 6.0f, b};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    uint32_t target = add_box(s, (sl_vec3){8, -1, 0}, (sl_vec3){9, 1, 3}, SL_KIND_OTHER, 0);
    sl_viewcell cell;
    memset(&cell, 0, sizeof cell);
    cell.shape = SL_CELL_BOX;
    cell.cluster = -1;
    cell.z_min = 1;
    cell.z_max = 2;
    cell.bounds = (sl_aabb){{-3, -2, 1}, {0, 2, 2}};
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(&cell, 1, NULL, &vc, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), ids[8], k;
    if (sl_pvs_bake_cell(s, vc, 0, "sample", NULL, ids, n, &k, &err) != SL_OK)
        fail_msg("sample bake: %s", err.message);
    for (uint32_t i = 0; i < k; i++)
        assert_int_not_equal(ids[i], target); /* hidden from the whole cell */
    uint64_t off[2] = {0, k};
    char file[64], opts[96];
    snprintf(file, sizeof file, "/tmp/sl_near_wall_building_%ld.slpvs", (long)getpid());
    assert_int_equal(sl_pvs_write(file, vc, n, sl_pvs_scene_key(s), off, ids, "method=sample\nguarantee=conservative",
                                  &err),
                     SL_OK);
    snprintf(opts, sizeof opts, "file=%s", file);
    sl_culler c;
    assert_int_equal(sl_culler_create("pvs", s, opts, NULL, &c, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t bad = 0;
    static const float gaps[] = {0.005f, 0.05f}, yaws[] = {0.0f, 0.6f};
    for (size_t g = 0; g < SL_COUNTOF(gaps); g++)
        for (size_t y = 0; y < SL_COUNTOF(yaws); y++) {
            sl_camera cam = sl_camera_default();
            cam.width = 160;
            cam.height = 120;
            cam.position = (sl_vec3){-gaps[g], 0, 1.7f};
            cam.yaw = yaws[y];
            sl_oracle_frame fr;
            assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
            bool seen = false;
            for (uint32_t i = 0; i < fr.visible_count; i++)
                seen |= fr.visible[i] == target;
            if (yaws[y] == 0.0f)
                assert_true(seen); /* through the clipped wall */
            uint32_t out[8], missed[4], mpx[4];
            assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
            if (mt.missed_count) {
                bad++;
                print_message("pvs: eye %.3f m from the wall, yaw %.2f: missed %u objects (first %u, %u pixels)\n",
                              (double)gaps[g], (double)yaws[y], mt.missed_count, missed[0], mpx[0]);
            }
        }
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    unlink(file);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
    assert_int_equal(bad, 0);
}

/* The union itself: two box cells side by side (x in [-4, 0] and [0, 4]) with hand-written sets
 * {a} and {b}; both objects ahead of the eye. An eye deep in the first cell gets a alone; one 5 cm
 * from the boundary, looking across it, gets a and b (its near-plane region meets both cells);
 * back deep in the first cell, a alone again (the union is not kept beyond its cells). */
static void test_pvs_union(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t a = add_box(s, (sl_vec3){10, -1, 0}, (sl_vec3){11, 1, 3}, SL_KIND_OTHER, 0);
    uint32_t b = add_box(s, (sl_vec3){12, 3, 0}, (sl_vec3){13, 5, 3}, SL_KIND_OTHER, 0);
    sl_viewcell cell[2];
    memset(cell, 0, sizeof cell);
    for (int i = 0; i < 2; i++) {
        cell[i].shape = SL_CELL_BOX;
        cell[i].cluster = -1;
        cell[i].z_min = 1;
        cell[i].z_max = 2;
        cell[i].bounds = (sl_aabb){{-4.0f + 4.0f * (float)i, -4, 1}, {4.0f * (float)i, 4, 2}};
    }
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(cell, 2, NULL, &vc, &err), SL_OK);
    uint64_t off[3] = {0, 1, 2};
    uint32_t ids[2] = {a, b};
    char file[64], opts[96];
    snprintf(file, sizeof file, "/tmp/sl_near_wall_union_%ld.slpvs", (long)getpid());
    assert_int_equal(sl_pvs_write(file, vc, 2, sl_pvs_scene_key(s), off, ids, "method=sample\nguarantee=conservative",
                                  &err),
                     SL_OK);
    snprintf(opts, sizeof opts, "file=%s", file);
    sl_culler c;
    assert_int_equal(sl_culler_create("pvs", s, opts, NULL, &c, &err), SL_OK);
    static const float xs[] = {-2.0f, -0.05f, -2.0f};
    static const uint32_t want[] = {1, 2, 1};
    for (size_t i = 0; i < SL_COUNTOF(xs); i++) {
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){xs[i], 0, 1.5f};
        cam.yaw = 0.2f;
        uint32_t out[2], k;
        assert_int_equal(sl_culler_cull(c, &cam, out, 2, &k, &err), SL_OK);
        assert_int_equal(k, want[i]);
        assert_int_equal(out[0], a);
        if (k == 2)
            assert_int_equal(out[1], b);
    }
    sl_culler_destroy(c);
    unlink(file);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* A near plane of 1e-30 m is refused, naming the limit, by every method that projects with the
 * float matrix and by the oracle; a sane one is accepted; a far/near ratio beyond 2^24 is refused
 * by the clip-space depth of hzb and the oracle, not by the 1/w of lazygrid; at the accepted limit
 * no conservative method misses an object on street views of the tiny city. */
static void test_near_plane_limit(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    uint32_t views = sanitized() ? 4 : 30;
    sl_path p;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, views, 9, 160, 120, &s, &p, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out), missed[4], mpx[4];
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_culler c[NM];
    for (size_t i = 0; i < NM; i++)
        assert_int_equal(sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &c[i], &err), SL_OK);
    sl_camera cam = sl_path_camera(p, 0);
    uint32_t k;
    sl_oracle_frame fr;
    /* 1e-30: refused with the limit named */
    sl_camera bad = cam;
    bad.near_plane = 1e-30f;
    assert_int_equal(sl_camera_validate(&bad, &err), SL_OK);
    assert_int_equal(sl_oracle_render(o, &bad, &fr, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "the oracle"));
    assert_non_null(strstr(err.message, "needs near >="));
    for (size_t i = 0; i < NM; i++) {
        sl_status st = sl_culler_cull(c[i], &bad, out, n, &k, &err);
        bool projects = strcmp(g_methods[i].name, "vfc") && strcmp(g_methods[i].name, "cullmap") &&
                        strcmp(g_methods[i].name, "horizon") && strcmp(g_methods[i].name, "dhorizon");
        if (!projects) {
            assert_int_equal(st, SL_OK); /* frustum planes in double: any near plane */
            continue;
        }
        if (st != SL_ERROR_INVALID_ARGUMENT)
            fail_msg("%s accepted a near plane of 1e-30 m", g_methods[i].name);
        print_message("%s\n", err.message);
        assert_non_null(strstr(err.message, "near plane 1e-30 m"));
        assert_non_null(strstr(err.message, g_methods[i].name));
        assert_non_null(strstr(err.message, "needs near >="));
    }
    /* far/near beyond 2^24: the clip-space depth loses the far plane, 1/w does not */
    sl_camera wide = cam;
    wide.far_plane = wide.near_plane * 1e8f;
    assert_int_equal(sl_oracle_render(o, &wide, &fr, &err), SL_ERROR_INVALID_ARGUMENT);
    print_message("%s\n", err.message);
    assert_non_null(strstr(err.message, "far/near <= 16777216"));
    assert_int_equal(sl_camera_check_depth(&wide, SL_DEPTH_CLIP_Z, "hzb", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_camera_check_depth(&wide, SL_DEPTH_INV_W, "lazygrid", &err), SL_OK);
    /* the default and the limit itself are accepted, and nothing is missed there */
    assert_int_equal(sl_camera_check_depth(&cam, SL_DEPTH_CLIP_Z, "hzb", &err), SL_OK);
    uint64_t misses = 0;
    for (uint32_t f = 0; f < sl_path_count(p); f++) {
        /* at both limits at once: near at the eye's least, far at 2^24 of it */
        sl_camera v = sl_path_camera(p, f);
        double lo = sl_camera_min_near(&v, SL_DEPTH_INV_W);
        v.near_plane = (float)lo;
        if ((double)v.near_plane < lo)
            v.near_plane = nextafterf(v.near_plane, INFINITY);
        v.far_plane = v.near_plane * 16777216.0f;
        assert_int_equal(sl_camera_check_depth(&v, SL_DEPTH_CLIP_Z, "test", &err), SL_OK);
        v.near_plane = nextafterf(v.near_plane, 0);
        assert_int_equal(sl_camera_check_depth(&v, SL_DEPTH_INV_W, "test", &err), SL_ERROR_INVALID_ARGUMENT);
        v.near_plane = nextafterf(v.near_plane, INFINITY);
        assert_int_equal(sl_oracle_render(o, &v, &fr, &err), SL_OK);
        for (size_t i = 0; i < NM; i++) {
            if (sl_culler_cull(c[i], &v, out, n, &k, &err) != SL_OK)
                fail_msg("%s refused near %g at the limit: %s", g_methods[i].name, (double)v.near_plane, err.message);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
            if (mt.missed_count)
                print_message("%s at near %g m (view %u): missed %u objects\n", g_methods[i].name,
                              (double)v.near_plane, f, mt.missed_count);
            misses += mt.missed_count;
        }
    }
    assert_int_equal(misses, 0);
    for (size_t i = 0; i < NM; i++)
        sl_culler_destroy(c[i]);
    sl_oracle_destroy(o);
    free(out);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* A huge far plane (issue 12 §1): the 2.5D methods declare no depth format, so a camera with far
 * 1e6, 1e10, 1e20 or 3e38 m is accepted; they must stay conservative there (cullmap missed 10
 * objects at 1e20 before its view bounded the far plane, docs/urban.md "Any far plane"). Judged by the oracle at the
 * same far plane where it accepts it (far/near <= 2^24), else at 1e6 m, beyond the city, which sees
 * the same. Methods that refuse the camera must name the limit. Tiny and small city, street views. */
static void test_huge_far(void **state)
{
    (void)state;
    static const float fars[] = {1e6f, 1e10f, 1e20f, 3e38f};
    uint64_t misses = 0;
    for (int city = 0; city < 2; city++) {
        sl_scene s;
        sl_error err;
        uint32_t views = sanitized() ? 3 : 12;
        sl_path p;
        assert_int_equal(sl_test_city_views(city ? SL_CITY_SMALL : SL_CITY_TINY, views, 31 + (uint64_t)city, 160, 120, &s, &p, &err), SL_OK);
        uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out), missed[4], mpx[4];
        sl_oracle o;
        assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
        sl_culler c[NM];
        for (size_t i = 0; i < NM; i++)
            assert_int_equal(sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &c[i], &err), SL_OK);
        for (uint32_t f = 0; f < sl_path_count(p); f++)
            for (size_t q = 0; q < SL_COUNTOF(fars); q++) {
                sl_camera v = sl_path_camera(p, f);
                v.far_plane = fars[q];
                sl_camera ref = v;
                if ((double)ref.far_plane / ref.near_plane > SL_CAMERA_MAX_FAR_NEAR)
                    ref.far_plane = 1e6f;
                sl_oracle_frame fr;
                assert_int_equal(sl_oracle_render(o, &ref, &fr, &err), SL_OK);
                for (size_t i = 0; i < NM; i++) {
                    uint32_t k;
                    sl_status st = sl_culler_cull(c[i], &v, out, n, &k, &err);
                    if (st != SL_OK) {
                        if (st != SL_ERROR_INVALID_ARGUMENT || !strstr(err.message, g_methods[i].name) ||
                            !strstr(err.message, "far"))
                            fail_msg("%s, far %g: %s", g_methods[i].name, (double)v.far_plane, err.message);
                        continue;
                    }
                    sl_cull_metrics mt;
                    assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
                    if (mt.missed_count)
                        print_message("%s city: %s%s%s, far %g (view %u): missed %u objects (first %u, %u pixels)\n",
                                      city ? "small" : "tiny", g_methods[i].name, g_methods[i].options ? " " : "",
                                      g_methods[i].options ? g_methods[i].options : "", (double)v.far_plane, f,
                                      mt.missed_count, missed[0], mpx[0]);
                    misses += mt.missed_count;
                }
            }
        for (size_t i = 0; i < NM; i++)
            sl_culler_destroy(c[i]);
        sl_oracle_destroy(o);
        free(out);
        sl_path_destroy(p);
        sl_scene_destroy(s);
    }
    assert_int_equal(misses, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_near_plane_limit),
        cmocka_unit_test(test_huge_far),
        cmocka_unit_test(test_building_near_wall),
        cmocka_unit_test(test_building_pvs),
        cmocka_unit_test(test_pvs_union),
        cmocka_unit_test(test_near_wall_views),
        cmocka_unit_test(test_near_wall_pvs),
    };
    /* SL_TEST_FILTER=pattern runs the matching tests only (while working on one) */
    if (getenv("SL_TEST_FILTER"))
        cmocka_set_test_filter(getenv("SL_TEST_FILTER"));
    return cmocka_run_group_tests(tests, NULL, NULL);
}

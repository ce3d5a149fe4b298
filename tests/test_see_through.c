/* See-through objects (SL_OBJECT_SEE_THROUGH: alpha-tested or transparent materials) never hide
 * anything (docs/oracle.md, "See-through objects"; scene.h).
 *
 * A wall stands between a view cell and three targets that only a sight line through the wall
 * reaches. The wall is, in turn:
 *  - solid (occluder flag, closed convex, its footprint): the oracle sees no target, and the
 *    occlusion methods cull them (so the test is not vacuous);
 *  - flagged see-through and occluder, in the generator's style (a building, closed convex): the
 *    scene clears the occluder flag and refuses its footprint and a 3D occluder mesh for it;
 *  - a building with an alpha-masked material (see-through set by the scene).
 * With a see-through wall the oracle sees the targets through it (and the wall), and every
 * conservative method of the registry (each with all_objects=true too where it takes that option)
 * and every conservative PVS baker reports every object the oracle sees. Also: the oracle's rule on
 * its own (a see-through object is seen in front of a solid one and not behind it, and hides
 * nothing), the CPU draw backend (a see-through draw writes no depth), and the Embree rays (they
 * pass through, reporting the see-through hit). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/sl_core.h"
#include "embree/embree_scene.h"
#include "sightline/backend.h"
#include "sightline/bake.h"
#include "sightline/cull.h"
#include "sightline/region.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"

enum { WALL_SOLID, WALL_FLAGGED, WALL_MATERIAL, WALL_KINDS };
static const char *const k_wall_name[WALL_KINDS] = {"solid wall", "see-through flagged occluder", "alpha-masked wall"};

#define NTARGETS 3

typedef struct world {
    sl_scene s;
    uint32_t wall, targets[NTARGETS];
} world;

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags, uint32_t material)
{
    float p[24];
    sl_test_box_vertices(lo, hi, p);
    sl_mesh_desc md = {p, NULL, 8, sl_test_box_indices, 12, NULL};
    uint32_t mesh, id;
    sl_error err;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, flags, material};
    if (sl_scene_add_object(s, &od, &id, &err) != SL_OK)
        fail_msg("add object: %s", err.message);
    return id;
}

static world build(int kind)
{
    world w;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &w.s, &err), SL_OK);
    add_box(w.s, (sl_vec3){-40, -40, -0.1f}, (sl_vec3){60, 40, 0}, SL_KIND_GROUND, 0, 0);
    uint32_t material = 0;
    if (kind == WALL_MATERIAL) {
        sl_material m = {{0.8f, 0.8f, 0.8f, 1.0f}, "leaves.png", SL_ALPHA_MASK, 0.5f, SL_MATERIAL_DOUBLE_SIDED};
        assert_int_equal(sl_scene_add_material(w.s, &m, &material, &err), SL_OK);
    }
    uint32_t flags = SL_OBJECT_OCCLUDER | SL_OBJECT_CLOSED_CONVEX | (kind == WALL_FLAGGED ? SL_OBJECT_SEE_THROUGH : 0);
    w.wall = add_box(w.s, (sl_vec3){5, -12, 0}, (sl_vec3){6, 12, 9}, SL_KIND_BUILDING, flags, material);
    sl_object_view ov = sl_scene_object(w.s, w.wall);
    float xy[8] = {5, -12, 6, -12, 6, 12, 5, 12};
    sl_footprint_desc fd = {xy, 4, 0.0f, 9.0f, w.wall};
    if (kind == WALL_SOLID) {
        assert_int_equal(ov.flags & (SL_OBJECT_SEE_THROUGH | SL_OBJECT_OCCLUDER), SL_OBJECT_OCCLUDER);
        assert_int_equal(sl_scene_add_footprint(w.s, &fd, NULL, &err), SL_OK);
    } else {
        /* the scene keeps see-through objects out of every occluder list */
        assert_int_equal(ov.flags & (SL_OBJECT_SEE_THROUGH | SL_OBJECT_OCCLUDER), SL_OBJECT_SEE_THROUGH);
        assert_int_equal(ov.material, material);
        assert_int_equal(sl_scene_add_footprint(w.s, &fd, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
        assert_non_null(strstr(err.message, "see-through"));
        assert_int_equal(sl_scene_add_occluder(w.s, ov.mesh, NULL, w.wall, &err), SL_ERROR_INVALID_ARGUMENT);
        assert_int_equal(sl_scene_footprint_count(w.s), 0);
        assert_int_equal(sl_scene_occluder_count(w.s), 0);
    }
    w.targets[0] = add_box(w.s, (sl_vec3){9, -1, 0}, (sl_vec3){10, 1, 3}, SL_KIND_CAR, 0, 0);
    w.targets[1] = add_box(w.s, (sl_vec3){13, 3, 0}, (sl_vec3){14, 5, 2}, SL_KIND_OTHER, 0, 0);
    w.targets[2] = add_box(w.s, (sl_vec3){16, -6, 0}, (sl_vec3){18, -4, 5}, SL_KIND_BUILDING,
                           SL_OBJECT_OCCLUDER | SL_OBJECT_CLOSED_CONVEX, 0);
    return w;
}

/* The view cell in front of the wall, and views from it. */
static const sl_aabb k_cell = {{-3, -2, 1}, {0, 2, 2}};
#define NVIEWS 6

static sl_camera view_at(uint32_t i)
{
    static const float yaws[NVIEWS] = {0.0f, 0.25f, -0.25f, 0.1f, -0.1f, 0.0f};
    static const float ys[NVIEWS] = {0.0f, -1.5f, 1.5f, 0.5f, -0.5f, 1.9f};
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){-1.5f + 0.2f * (float)i, ys[i], 1.2f + 0.1f * (float)i};
    c.yaw = yaws[i];
    c.pitch = -0.05f;
    c.width = 160;
    c.height = 120;
    return c;
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* Options of a method to run: its defaults, and all_objects=true where it takes it. */
static uint32_t method_runs(const sl_cull_method_desc *d, const char *opts[2])
{
    opts[0] = NULL;
    if (d->options_help && strstr(d->options_help, "all_objects=")) {
        opts[1] = "all_objects=true";
        return 2;
    }
    return 1;
}

/* Cull every view with every registered method; returns the missed objects over all conservative
 * runs (the oracle's frames judge), and in *culled_targets the (run, view, target) triples culled. */
static uint64_t run_methods(const world *w, const sl_oracle_frame *frames, const char *label, uint64_t *culled_targets)
{
    sl_error err;
    uint32_t n = sl_scene_object_count(w->s);
    uint32_t *out = malloc(n * sizeof *out), missed[8], mpx[8];
    uint64_t missed_total = 0;
    *culled_targets = 0;
    uint32_t runs = 0;
    for (uint32_t m = 0; m < sl_cull_method_count(); m++) {
        sl_cull_method_desc d;
        assert_int_equal(sl_cull_method_info(m, &d, &err), SL_OK);
        if (strcmp(d.name, "pvs") == 0)
            continue; /* reads a baked file: the bakers are checked below */
        const char *opts[2];
        uint32_t nr = method_runs(&d, opts);
        for (uint32_t r = 0; r < nr; r++) {
            sl_culler c;
            if (sl_culler_create(d.name, w->s, opts[r], NULL, &c, &err) != SL_OK)
                fail_msg("%s: %s %s: %s", label, d.name, opts[r] ? opts[r] : "", err.message);
            bool conservative = sl_cull_guarantee_keeps_visible(sl_culler_guarantee(c), false);
            runs++;
            for (uint32_t v = 0; v < NVIEWS; v++) {
                sl_camera cam = view_at(v);
                uint32_t k;
                if (sl_culler_cull(c, &cam, out, n, &k, &err) != SL_OK)
                    fail_msg("%s: %s view %u: %s", label, d.name, v, err.message);
                for (int t = 0; t < NTARGETS; t++)
                    *culled_targets += !has(out, k, w->targets[t]);
                sl_cull_metrics mt;
                assert_int_equal(sl_metrics_compare(w->s, &frames[v], out, k, &mt, missed, mpx, 8, &err), SL_OK);
                if (mt.missed_count) {
                    print_message("%s: %s%s%s (%s) view %u missed %u objects (first %u, %u pixels)\n", label, d.name,
                                  opts[r] ? " " : "", opts[r] ? opts[r] : "",
                                  conservative ? "conservative" : "not conservative", v, mt.missed_count, missed[0],
                                  mpx[0]);
                    if (conservative)
                        missed_total += mt.missed_count;
                }
            }
            sl_culler_destroy(c);
        }
    }
    print_message("%s: %u method runs, %llu (run, view, target) culled\n", label, runs,
                  (unsigned long long)*culled_targets);
    free(out);
    return missed_total;
}

/* Bake the cell with every PVS method; returns the targets a conservative baker left out that
 * the oracle sees from one of the views (all views lie in the cell). */
static uint32_t run_bakers(const world *w, const sl_oracle_frame *frames, const char *label, uint32_t *hidden)
{
    sl_error err;
    sl_viewcell cell;
    memset(&cell, 0, sizeof cell);
    cell.shape = SL_CELL_BOX;
    cell.cluster = -1;
    cell.z_min = k_cell.min.z;
    cell.z_max = k_cell.max.z;
    cell.bounds = k_cell;
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(&cell, 1, NULL, &vc, &err), SL_OK);
    uint32_t n = sl_scene_object_count(w->s), *ids = malloc(n * sizeof *ids), bad = 0, baked = 0;
    *hidden = 0;
    for (uint32_t m = 0; m < sl_pvs_method_count(); m++) {
        sl_pvs_method_desc d;
        assert_int_equal(sl_pvs_method_info(m, &d, &err), SL_OK);
        uint32_t k;
        if (sl_pvs_bake_cell(w->s, vc, 0, d.name, NULL, ids, n, &k, &err) != SL_OK) {
            print_message("%s: baker %s not run here: %s\n", label, d.name, err.message);
            continue;
        }
        baked++;
        bool conservative = sl_cull_guarantee_keeps_visible(d.guarantee, false);
        for (int t = 0; t < NTARGETS; t++) {
            bool seen = false;
            for (uint32_t v = 0; v < NVIEWS; v++)
                seen |= has(frames[v].visible, frames[v].visible_count, w->targets[t]);
            bool in = has(ids, k, w->targets[t]);
            *hidden += !in;
            if (seen && !in) {
                print_message("%s: baker %s (%s) leaves out target %u, which the oracle sees\n", label, d.name,
                              conservative ? "conservative" : "not conservative", w->targets[t]);
                bad += conservative;
            }
        }
    }
    print_message("%s: %u bakers run, %u (baker, target) left out\n", label, baked, *hidden);
    assert_true(baked >= 2);
    free(ids);
    sl_viewcells_destroy(vc);
    return bad;
}

static void test_methods_and_bakers(void **state)
{
    (void)state;
    for (int kind = 0; kind < WALL_KINDS; kind++) {
        world w = build(kind);
        sl_error err;
        sl_oracle o;
        assert_int_equal(sl_oracle_create(w.s, NULL, NULL, &o, &err), SL_OK);
        sl_oracle_frame frames[NVIEWS];
        /* frames point into the oracle's buffers: copy the sets out */
        uint32_t *sets[NVIEWS];
        uint32_t wall_seen = 0, seen = 0;
        for (uint32_t v = 0; v < NVIEWS; v++) {
            sl_oracle_frame one[NVIEWS];
            sl_camera c = view_at(v);
            assert_int_equal(sl_oracle_render(o, &c, &one[0], &err), SL_OK);
            frames[v] = one[0];
            sets[v] = malloc((frames[v].visible_count + 1) * 2 * sizeof(uint32_t));
            memcpy(sets[v], frames[v].visible, frames[v].visible_count * sizeof(uint32_t));
            memcpy(sets[v] + frames[v].visible_count, frames[v].pixels, frames[v].visible_count * sizeof(uint32_t));
            frames[v].visible = sets[v];
            frames[v].pixels = sets[v] + frames[v].visible_count;
            for (int t = 0; t < NTARGETS; t++)
                seen += has(frames[v].visible, frames[v].visible_count, w.targets[t]);
            wall_seen += has(frames[v].visible, frames[v].visible_count, w.wall);
        }
        assert_int_equal(wall_seen, NVIEWS); /* the wall fills the middle of every view */
        print_message("%s: the oracle sees %u (view, target) pairs\n", k_wall_name[kind], seen);
        uint64_t culled;
        uint64_t missed = run_methods(&w, frames, k_wall_name[kind], &culled);
        uint32_t hidden;
        uint32_t bad = run_bakers(&w, frames, k_wall_name[kind], &hidden);
        if (kind == WALL_SOLID) {
            /* not vacuous: the solid wall hides every target, and the methods use it */
            assert_int_equal(seen, 0);
            assert_true(culled > 0);
            assert_true(hidden > 0);
        } else {
            assert_true(seen >= NVIEWS); /* seen through the wall */
            assert_int_equal(missed, 0);
            assert_int_equal(bad, 0);
        }
        for (uint32_t v = 0; v < NVIEWS; v++)
            free(sets[v]);
        sl_oracle_destroy(o);
        sl_scene_destroy(w.s);
    }
}

/* The oracle's rule alone: a see-through quad in front of a solid one is seen and hides nothing;
 * behind it, it is not seen; two see-through layers are both seen; the id image holds only solids. */
static void test_oracle_rule(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t front = add_box(s, (sl_vec3){4, -1, 0}, (sl_vec3){4.1f, 1, 2}, SL_KIND_OTHER, SL_OBJECT_SEE_THROUGH, 0);
    uint32_t front2 = add_box(s, (sl_vec3){5, -0.5f, 0.5f}, (sl_vec3){5.1f, 0.5f, 1.5f}, SL_KIND_OTHER,
                              SL_OBJECT_SEE_THROUGH, 0);
    uint32_t solid = add_box(s, (sl_vec3){8, -3, -1}, (sl_vec3){9, 3, 4}, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER, 0);
    uint32_t behind = add_box(s, (sl_vec3){12, -1, 0}, (sl_vec3){12.1f, 1, 2}, SL_KIND_OTHER, SL_OBJECT_SEE_THROUGH, 0);
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){0, 0, 1};
    c.width = 64;
    c.height = 48;
    for (uint32_t threads = 1; threads <= 2; threads++) {
        sl_oracle_options oo = sl_oracle_default_options();
        oo.threads = threads;
        sl_oracle o;
        assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render(o, &c, &f, &err), SL_OK);
        assert_true(has(f.visible, f.visible_count, front));
        assert_true(has(f.visible, f.visible_count, front2));
        assert_true(has(f.visible, f.visible_count, solid));
        assert_false(has(f.visible, f.visible_count, behind));
        sl_oracle_view ov;
        assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
        uint64_t solid_px = 0;
        for (uint32_t i = 0; i < ov.width * ov.height; i++) {
            assert_true(ov.ids[i] == SL_NONE || ov.ids[i] == solid); /* see-through leave no id */
            solid_px += ov.ids[i] == solid;
        }
        for (uint32_t i = 0; i < f.visible_count; i++)
            if (f.visible[i] == solid)
                assert_int_equal(f.pixels[i], solid_px); /* the quads in front hide none of it */
            else if (f.visible[i] == front2)
                assert_true(f.pixels[i] > 0 && f.pixels[i] < solid_px);
        sl_oracle_destroy(o);
    }
    sl_scene_destroy(s);
}

/* The CPU draw backend: a see-through object drawn before a solid one writes no depth, so the
 * solid one's draw still passes every fragment it would pass alone. */
static void test_cpu_backend(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t glass = add_box(s, (sl_vec3){4, -2, -1}, (sl_vec3){4.1f, 2, 3}, SL_KIND_OTHER, SL_OBJECT_SEE_THROUGH, 0);
    uint32_t solid = add_box(s, (sl_vec3){8, -1, 0}, (sl_vec3){9, 1, 2}, SL_KIND_BUILDING, 0, 0);
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){0, 0, 1};
    c.width = 64;
    c.height = 48;
    sl_view view;
    assert_int_equal(sl_view_from_camera(&c, &view, &err), SL_OK);
    sl_draw_backend_cpu cpu;
    assert_int_equal(sl_draw_backend_cpu_create(s, NULL, NULL, &cpu, &err), SL_OK);
    sl_draw_backend b = sl_draw_backend_cpu_table(cpu);
    uint64_t alone = 0, after = 0;
    sl_draw_query q;
    assert_int_equal(b.create_queries(b.user, 1, &q, &err), SL_OK);
    for (int pass = 0; pass < 2; pass++) {
        assert_int_equal(b.begin_frame(b.user, view.view_proj.m, c.width, c.height, &err), SL_OK);
        if (pass == 1)
            assert_int_equal(b.draw_objects(b.user, &glass, 1, &err), SL_OK);
        assert_int_equal(b.begin_query(b.user, q, &err), SL_OK);
        assert_int_equal(b.draw_objects(b.user, &solid, 1, &err), SL_OK);
        assert_int_equal(b.end_query(b.user, &err), SL_OK);
        uint64_t samples = 0;
        assert_int_equal(b.wait_query(b.user, q, &samples, &err), SL_OK);
        assert_int_equal(b.end_frame(b.user, &err), SL_OK);
        if (pass)
            after = samples;
        else
            alone = samples;
    }
    b.destroy_queries(b.user, &q, 1);
    assert_true(alone > 0);
    assert_int_equal(after, alone);
    const float *depth;
    const uint32_t *ids;
    uint32_t w, h;
    sl_draw_backend_cpu_buffers(cpu, &depth, &ids, &w, &h);
    for (uint32_t i = 0; i < w * h; i++)
        assert_int_not_equal(ids[i], glass);
    sl_draw_backend_cpu_destroy(cpu);
    sl_scene_destroy(s);
}

/* Embree rays pass through see-through triangles and report the nearest one apart. */
static void test_embree_rays(void **state)
{
    (void)state;
    world w = build(WALL_MATERIAL);
    sl_error err;
    sl_es *es;
    assert_int_equal(sl_es_create(w.s, NULL, NULL, &es, &err), SL_OK);
    sl_es_ray rays[2] = {{{0, 0, 1.5f}, 0.0f, {1, 0, 0}, 100.0f}, {{0, 0, 1.5f}, 0.0f, {1, 0, 0}, 4.0f}};
    sl_es_hit hits[2];
    sl_es_trace(es, rays, hits, 2);
    assert_int_equal(hits[0].object, w.targets[0]); /* through the wall onto the car */
    assert_int_equal(hits[0].see_through_object, w.wall);
    assert_true(fabsf(hits[0].see_through_t - 5.0f) < 1e-3f);
    assert_int_equal(hits[1].object, SL_NONE); /* stops before the wall */
    assert_int_equal(hits[1].see_through_object, SL_NONE);
    sl_es_destroy(es);
    sl_scene_destroy(w.s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_oracle_rule),
        cmocka_unit_test(test_cpu_backend),
        cmocka_unit_test(test_embree_rays),
        cmocka_unit_test(test_methods_and_bakers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

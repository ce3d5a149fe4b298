/* Occlusion queries on the GL renderer (sl_renderer_backend) and the render layer's gpu-hiz, on a
 * headless EGL context (llvmpipe here):
 *  - the GL backend's sample counts equal the CPU reference backend's for the same calls: exactly
 *    on a scene without coplanar faces, and on the tiny city (boxes and objects, after drawing part
 *    of it) but for the queries where GL's and the reference rasterizer's fragments differ (depth
 *    ties and pixel centres on an edge: counted and bounded);
 *  - poll and wait: a query never issued, misuse (one open at a time, outside a frame, an open
 *    query at end_frame) refused; a wait returns what a ready poll returns; the renderer's frame
 *    stats carry the culler's queries and the backend's stalls;
 *  - gl-stopwait on the GL backend (sl_renderer_create_culler) keeps every object of the GL image
 *    drawn without culling, and every object the oracle sees at the culling resolution unless GL's
 *    own image does not show it (a depth tie or a silhouette pixel the two rasterizers decide
 *    apart); every frame's id and depth images are the unculled ones but at depth ties (shaded
 *    frames: the colours too); on the tiny city (street and flyover views) and a Quake III map;
 *  - gl-stopwait, chc and chc++ (and vfc, whose frames are the unculled ones) over a walk;
 *  - gpu-hiz over a short walk of the tiny city (with and without indirect count, and shaded),
 *    past an occluder's edge by fractions of a pixel, and behind a see-through wall: the same
 *    checks (its declared guarantee: conservative at the culling resolution), and it culls
 *    (fewer objects than vfc).
 * Exits 77 (skipped) only when no GL context can be made. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cull/hoq.h"
#include "sightline/backend.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/render.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"
#include "support/city_views.h"
#include "support/pk3_names.h"

#define W 160
#define H 120

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static sl_renderer make_renderer(sl_scene s, uint32_t w, uint32_t h)
{
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = w;
    o.height = h;
    sl_renderer r = NULL;
    sl_error err;
    if (sl_renderer_create(s, &o, NULL, &r, &err) != SL_OK)
        fail_msg("sl_renderer_create: %s", err.message);
    return r;
}

static sl_path views_of(sl_scene s, sl_view_kind kind, uint32_t count, uint64_t seed)
{
    sl_path_options po = sl_path_options_default(kind == SL_VIEWS_STREET ? SL_PATH_WALK : SL_PATH_FLYOVER);
    po.intrinsics.width = W;
    po.intrinsics.height = H;
    sl_path p;
    sl_error err;
    if (sl_path_random_views(s, kind, count, seed, &po, NULL, &p, &err) != SL_OK)
        fail_msg("%s", err.message);
    return p;
}

/* ---- sample counts: GL against the CPU reference backend ---- */

typedef struct count_tally {
    uint64_t queries, equal, samples, abs_diff, nonzero, zero;
} count_tally;

static void compare_query(const sl_draw_backend *gl, const sl_draw_backend *cpu, sl_draw_query qg, sl_draw_query qc,
                          const sl_aabb *box, const uint32_t *id, count_tally *t)
{
    sl_error err;
    uint64_t got[2];
    const sl_draw_backend *be[2] = {gl, cpu};
    sl_draw_query q[2] = {qg, qc};
    for (int k = 0; k < 2; k++) {
        assert_int_equal(be[k]->begin_query(be[k]->user, q[k], &err), SL_OK);
        if (box)
            assert_int_equal(be[k]->query_boxes(be[k]->user, box, 1, &err), SL_OK);
        else
            assert_int_equal(be[k]->query_objects(be[k]->user, id, 1, &err), SL_OK);
        assert_int_equal(be[k]->end_query(be[k]->user, &err), SL_OK);
        assert_int_equal(be[k]->wait_query(be[k]->user, q[k], &got[k], &err), SL_OK);
    }
    t->queries++;
    t->equal += got[0] == got[1];
    t->samples += got[1];
    t->abs_diff += got[0] > got[1] ? got[0] - got[1] : got[1] - got[0];
    if (got[1])
        t->nonzero++;
    else
        t->zero++;
    /* an answer of 0 against a positive one (or the reverse) is a wrong visibility decision:
     * allowed only for a handful of samples (a centre on an edge, a tie) */
    if ((got[0] == 0) != (got[1] == 0) && (got[0] > 2 || got[1] > 2))
        fail_msg("%s %u: GL counts %llu samples, the CPU backend %llu", box ? "box of object" : "object",
                 id ? *id : 0, (unsigned long long)got[0], (unsigned long long)got[1]);
}

static void test_counts_match_cpu(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_error err;
    sl_renderer r = make_renderer(s, W, H);
    sl_draw_backend gl = sl_renderer_backend(r);
    sl_draw_backend_cpu cpu;
    assert_int_equal(sl_draw_backend_cpu_create(s, NULL, NULL, &cpu, &err), SL_OK);
    sl_draw_backend cb = sl_draw_backend_cpu_table(cpu);
    assert_int_equal(sl_draw_backend_check(&gl, &err), SL_OK);
    sl_draw_query qg, qc;
    assert_int_equal(gl.create_queries(gl.user, 1, &qg, &err), SL_OK);
    assert_int_equal(cb.create_queries(cb.user, 1, &qc, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    sl_path p = views_of(s, SL_VIEWS_STREET, sanitized() ? 2 : 6, 17);
    const sl_aabb *bounds = sl_scene_object_bounds_array(s);
    count_tally boxes = {0}, grown = {0}, objects = {0};
    for (uint32_t f = 0; f < sl_path_count(p); f++) {
        sl_camera cam = sl_path_camera(p, f);
        sl_mat4 vp = sl_camera_view_proj(&cam);
        assert_int_equal(gl.begin_frame(gl.user, vp.m, W, H, &err), SL_OK);
        assert_int_equal(cb.begin_frame(cb.user, vp.m, W, H, &err), SL_OK);
        /* every third object drawn (a partial buffer), then every object queried both ways */
        for (uint32_t id = f % 3; id < n; id += 3) {
            assert_int_equal(gl.draw_objects(gl.user, &id, 1, &err), SL_OK);
            assert_int_equal(cb.draw_objects(cb.user, &id, 1, &err), SL_OK);
        }
        sl_hoq_view hv;
        sl_view v;
        assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
        sl_hoq_view_set(&hv, &v.view_proj, &v.proj, W, H, v.eye, false, 0.0625f);
        for (uint32_t id = 0; id < n; id++) {
            compare_query(&gl, &cb, qg, qc, &bounds[id], &id, &boxes);
            sl_aabb g;
            if (sl_hoq_grow_box(&hv, &bounds[id], &g))
                compare_query(&gl, &cb, qg, qc, &g, &id, &grown);
            compare_query(&gl, &cb, qg, qc, NULL, &id, &objects);
        }
        assert_int_equal(gl.end_frame(gl.user, &err), SL_OK);
        assert_int_equal(cb.end_frame(cb.user, &err), SL_OK);
    }
    print_message("boxes: %llu queries, %llu equal, %llu samples (CPU), %llu differ by samples; objects: %llu "
                  "queries, %llu equal, %llu samples, %llu differ\n",
                  (unsigned long long)boxes.queries, (unsigned long long)boxes.equal,
                  (unsigned long long)boxes.samples, (unsigned long long)boxes.abs_diff,
                  (unsigned long long)objects.queries, (unsigned long long)objects.equal,
                  (unsigned long long)objects.samples, (unsigned long long)objects.abs_diff);
    print_message("grown boxes: %llu queries, %llu equal, %llu samples, %llu differ\n", (unsigned long long)grown.queries,
                  (unsigned long long)grown.equal, (unsigned long long)grown.samples, (unsigned long long)grown.abs_diff);
    assert_true(boxes.nonzero > 0 && boxes.zero > 0 && objects.nonzero > 0 && objects.zero > 0);
    /* Exact but where depths tie. A raw box's faces lie in the planes of the walls drawn (a box
     * building's box is the building; streets and ground are coplanar): the reference rasterizer
     * evaluates both from the same exact plane and finds them equal ("at least as near": passes),
     * GL interpolates each triangulation in float and breaks the tie either way. Measured on
     * llvmpipe: raw boxes 1941 of 2010 queries equal, 6.3 % of samples apart; hoq's query boxes
     * (grown by 1/16 pixel and moved toward the eye: off every plane) 997 of 1002 equal, 10 samples
     * of 251,430; objects by their own triangles 1988 of 2010, 0.3 % (coplanar ground and street
     * polygons, and pixel centres on an edge: 8 subpixel bits in GL, the reference's 1/512). */
    assert_true(grown.queries > 0 && grown.equal * 1000 >= grown.queries * 990);
    assert_true(grown.abs_diff * 10000 <= grown.samples);
    assert_true(objects.equal * 1000 >= objects.queries * 985);
    assert_true(objects.abs_diff * 200 <= objects.samples);
    assert_true(boxes.equal * 100 >= boxes.queries * 94);
    assert_true(boxes.abs_diff * 100 <= boxes.samples * 8);
    gl.destroy_queries(gl.user, &qg, 1);
    cb.destroy_queries(cb.user, &qc, 1);
    sl_path_destroy(p);
    sl_draw_backend_cpu_destroy(cpu);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* A known scene without depth ties: five boxes at staggered depths seen obliquely; boxes 0, 2, 4
 * drawn, then every box queried (the undrawn ones by their boxes, all by their triangles) and boxes
 * between them: GL's counts are the reference's exactly. */
static void test_counts_exact_known_scene(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    for (int i = 0; i < 5; i++) {
        float x = 0.37f * (float)i, y = 2.1f * (float)i + 0.13f, z = 0.11f * (float)i;
        sl_test_add_box(s, (sl_vec3){x - 0.8f, y, z - 0.9f}, (sl_vec3){x + 0.7f, y + 1.1f, z + 0.95f},
                        SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    }
    sl_renderer r = make_renderer(s, W, H);
    sl_draw_backend gl = sl_renderer_backend(r);
    sl_draw_backend_cpu cpu;
    assert_int_equal(sl_draw_backend_cpu_create(s, NULL, NULL, &cpu, &err), SL_OK);
    sl_draw_backend cb = sl_draw_backend_cpu_table(cpu);
    sl_draw_query qg, qc;
    assert_int_equal(gl.create_queries(gl.user, 1, &qg, &err), SL_OK);
    assert_int_equal(cb.create_queries(cb.user, 1, &qc, &err), SL_OK);
    count_tally t = {0};
    for (int view = 0; view < 3; view++) {
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){0.3f + 0.21f * (float)view, -6.3f, 0.45f - 0.1f * (float)view};
        cam.yaw = 1.5708f + 0.07f * (float)view;
        cam.pitch = -0.03f;
        cam.fov_y = 0.9f;
        cam.near_plane = 0.1f;
        cam.far_plane = 100.0f;
        cam.width = W;
        cam.height = H;
        sl_mat4 vp = sl_camera_view_proj(&cam);
        assert_int_equal(gl.begin_frame(gl.user, vp.m, W, H, &err), SL_OK);
        assert_int_equal(cb.begin_frame(cb.user, vp.m, W, H, &err), SL_OK);
        const uint32_t drawn[3] = {0, 2, 4};
        assert_int_equal(gl.draw_objects(gl.user, drawn, 3, &err), SL_OK);
        assert_int_equal(cb.draw_objects(cb.user, drawn, 3, &err), SL_OK);
        for (uint32_t id = 0; id < 5; id++) {
            sl_aabb b = sl_scene_object_bounds(s, id);
            if (id % 2)
                compare_query(&gl, &cb, qg, qc, &b, &id, &t);
            compare_query(&gl, &cb, qg, qc, NULL, &id, &t);
            sl_aabb mid = {{b.min.x + 0.05f, b.min.y + 1.3f, b.min.z + 0.07f}, {b.max.x - 0.1f, b.max.y + 1.7f, b.max.z}};
            compare_query(&gl, &cb, qg, qc, &mid, &id, &t);
        }
        assert_int_equal(gl.end_frame(gl.user, &err), SL_OK);
        assert_int_equal(cb.end_frame(cb.user, &err), SL_OK);
    }
    print_message("known scene: %llu queries, %llu equal, %llu samples, %llu with samples, %llu without\n",
                  (unsigned long long)t.queries, (unsigned long long)t.equal, (unsigned long long)t.samples,
                  (unsigned long long)t.nonzero, (unsigned long long)t.zero);
    assert_true(t.nonzero > 0 && t.zero > 0);
    assert_int_equal(t.equal, t.queries);
    gl.destroy_queries(gl.user, &qg, 1);
    cb.destroy_queries(cb.user, &qc, 1);
    sl_draw_backend_cpu_destroy(cpu);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- poll and wait ---- */

static void test_poll_wait(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_error err;
    sl_renderer r = make_renderer(s, W, H);
    sl_draw_backend gl = sl_renderer_backend(r);
    sl_draw_query q[2];
    assert_int_equal(gl.create_queries(gl.user, 2, q, &err), SL_OK);
    assert_true(q[0] != q[1] && q[0] && q[1]);
    bool ready = false;
    uint64_t samples = 0, waited = 0;
    assert_int_equal(gl.poll_query(gl.user, q[0], &ready, &samples, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "never issued"));
    assert_int_equal(gl.wait_query(gl.user, q[0], &samples, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gl.begin_query(gl.user, q[0], &err), SL_ERROR_INVALID_ARGUMENT); /* outside a frame */
    sl_path p = views_of(s, SL_VIEWS_STREET, 1, 5);
    sl_camera cam = sl_path_camera(p, 0);
    sl_mat4 vp = sl_camera_view_proj(&cam);
    assert_int_equal(gl.begin_frame(gl.user, vp.m, W + 1, H, &err), SL_ERROR_INVALID_ARGUMENT); /* size */
    assert_int_equal(gl.begin_frame(gl.user, vp.m, W, H, &err), SL_OK);
    sl_aabb all = sl_scene_bounds(s);
    assert_int_equal(gl.begin_query(gl.user, q[0], &err), SL_OK);
    assert_int_equal(gl.begin_query(gl.user, q[1], &err), SL_ERROR_INVALID_ARGUMENT); /* one open at a time */
    assert_int_equal(gl.poll_query(gl.user, q[0], &ready, &samples, &err), SL_ERROR_INVALID_ARGUMENT); /* open */
    assert_int_equal(gl.query_boxes(gl.user, &all, 1, &err), SL_OK);
    assert_int_equal(gl.end_query(gl.user, &err), SL_OK);
    assert_int_equal(gl.end_query(gl.user, &err), SL_ERROR_INVALID_ARGUMENT); /* none open */
    /* a poll (ready or not: it never blocks), a wait, then a poll is ready with the same count */
    assert_int_equal(gl.poll_query(gl.user, q[0], &ready, &samples, &err), SL_OK);
    uint64_t polled = ready ? samples : UINT64_MAX;
    assert_int_equal(gl.wait_query(gl.user, q[0], &waited, &err), SL_OK);
    if (polled != UINT64_MAX)
        assert_int_equal(waited, polled);
    ready = false;
    assert_int_equal(gl.poll_query(gl.user, q[0], &ready, &samples, &err), SL_OK);
    assert_true(ready);
    assert_int_equal(waited, samples);
    /* the scene's box from inside it: every pixel, both facings of the faces around the eye */
    assert_true(samples >= (uint64_t)W * H);
    /* nothing drawn: a box behind the eye covers nothing */
    sl_aabb behind = {{cam.position.x - 1e4f, cam.position.y - 1e4f, -1e4f},
                      {cam.position.x - 9e3f, cam.position.y - 9e3f, -9e3f}};
    assert_int_equal(gl.begin_query(gl.user, q[1], &err), SL_OK);
    assert_int_equal(gl.query_boxes(gl.user, &behind, 1, &err), SL_OK);
    assert_int_equal(gl.end_query(gl.user, &err), SL_OK);
    assert_int_equal(gl.wait_query(gl.user, q[1], &waited, &err), SL_OK);
    assert_int_equal(waited, 0);
    /* an open query at end_frame is refused (and closed) */
    assert_int_equal(gl.begin_query(gl.user, q[1], &err), SL_OK);
    assert_int_equal(gl.end_frame(gl.user, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gl.end_frame(gl.user, &err), SL_ERROR_INVALID_ARGUMENT); /* outside a frame */
    gl.destroy_queries(gl.user, q, 2);

    /* the renderer's frame stats: the culler's queries, the backend's stalls, its own draws */
    sl_culler c;
    assert_int_equal(sl_renderer_create_culler(r, "gl-stopwait", NULL, &c, &err), SL_OK);
    sl_view v;
    assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * 4), k = 0;
    sl_render_frame_stats st;
    assert_int_equal(sl_renderer_frame(r, c, &v, SL_RENDER_SHADED, ids, &k, &st, &err), SL_OK);
    print_message("gl-stopwait frame: %u objects, %llu queries, %llu stalls (culler %llu), wait %.3f ms, frame %.3f ms\n", k,
                  (unsigned long long)st.queries, (unsigned long long)st.query_stalls,
                  (unsigned long long)st.cull.query_stalls, st.wait_ms, st.frame_ms);
    assert_true(st.queries > 0);
    assert_int_equal(st.queries, st.cull.queries);
    assert_true(st.query_stalls <= st.cull.query_stalls);
    assert_true(st.wait_ms >= 0);
    assert_int_equal(st.objects_drawn, k); /* drawn once, by the culler */
    assert_int_equal(st.cull.objects_visible, k);
    sl_culler_destroy(c);
    /* a method that draws nothing gets no backend, gpu-hiz is listed */
    assert_int_equal(sl_renderer_create_culler(r, "vfc", NULL, &c, &err), SL_OK);
    sl_culler_destroy(c);
    assert_int_equal(sl_renderer_create_culler(r, "no-such", NULL, &c, &err), SL_ERROR_NOT_FOUND);
    assert_int_equal(sl_render_method_count(), 1);
    assert_string_equal(sl_render_method(0)->name, "gpu-hiz");
    assert_null(sl_render_method(1));
    assert_int_equal(sl_render_method(0)->guarantee, SL_CONSERVATIVE_AT_RESOLUTION);
    assert_int_equal(sl_renderer_create_culler(r, "gpu-hiz", "margin=9", &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_culler_create("gpu-hiz", s, NULL, NULL, &c, &err), SL_ERROR_NOT_FOUND); /* GL only */
    free(ids);
    sl_path_destroy(p);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
}

/* ---- cullers on GL against GL's own image and the oracle ---- */

typedef struct gl_judge {
    sl_scene s;
    sl_renderer r;
    sl_oracle o;
    uint32_t n, npx;
    uint32_t draws_per_object; /* 1; 2 for chc's zpass (a depth pass, then the colour pass) */
    uint32_t *all, *ids, *missed, *missed_px, *full_ids, *frame_ids;
    float *full_depth, *frame_depth;
    uint8_t *shown;
    /* totals */
    uint64_t depth_differ, rgba_differ;
    uint8_t *frame_rgba, *full_rgba;
    uint64_t frames, kept, gl_missed, oracle_missed, oracle_missed_gl_shows, pixels_differ, pixels_differ_no_tie;
} gl_judge;

static void judge_init(gl_judge *j, sl_scene s, uint32_t w, uint32_t h)
{
    memset(j, 0, sizeof *j);
    j->s = s;
    j->r = make_renderer(s, w, h);
    sl_error err;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &j->o, &err), SL_OK);
    j->n = sl_scene_object_count(s);
    j->npx = w * h;
    j->draws_per_object = 1;
    j->all = malloc(j->n * 4);
    j->ids = malloc(j->n * 4);
    j->missed = malloc(j->n * 4);
    j->missed_px = malloc(j->n * 4);
    for (uint32_t i = 0; i < j->n; i++)
        j->all[i] = i;
    j->full_ids = malloc(j->npx * 4);
    j->frame_ids = malloc(j->npx * 4);
    j->full_depth = malloc(j->npx * 4);
    j->frame_depth = malloc(j->npx * 4);
    j->shown = malloc(j->n);
    j->frame_rgba = malloc((size_t)j->npx * 4);
    j->full_rgba = malloc((size_t)j->npx * 4);
}

static void judge_free(gl_judge *j)
{
    sl_oracle_destroy(j->o);
    sl_renderer_destroy(j->r);
    free(j->all);
    free(j->ids);
    free(j->missed);
    free(j->missed_px);
    free(j->full_ids);
    free(j->frame_ids);
    free(j->full_depth);
    free(j->frame_depth);
    free(j->shown);
    free(j->frame_rgba);
    free(j->full_rgba);
}

/* One frame of culler c: no object GL's unculled image shows may be missing, and the frame's id
 * image must be the unculled one except where the depths tie; oracle misses are counted, and each
 * must be an object GL's own image does not show. */
static void judge_frame(gl_judge *j, sl_culler c, const sl_camera *cam, sl_render_kind kind, const char *label,
                        uint32_t f)
{
    sl_error err;
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(j->o, cam, &fr, &err), SL_OK);
    if (fr.out_of_domain)
        return;
    sl_view v;
    assert_int_equal(sl_view_from_camera(cam, &v, &err), SL_OK);
    uint32_t k = 0;
    sl_render_frame_stats st;
    if (sl_renderer_frame(j->r, c, &v, kind, j->ids, &k, &st, &err) != SL_OK)
        fail_msg("%s frame %u: %s", label, f, err.message);
    /* the culler's draws only, each object once (see-through objects are drawn in the shaded pass only) */
    uint64_t drawable = 0;
    for (uint32_t i = 0; i < k; i++)
        drawable += kind == SL_RENDER_SHADED || !(sl_scene_object(j->s, j->ids[i]).flags & SL_OBJECT_SEE_THROUGH);
    assert_int_equal(st.objects_drawn, drawable * j->draws_per_object);
    if (kind == SL_RENDER_DEPTH) {
        assert_int_equal(sl_renderer_read_depth(j->r, j->frame_depth, &err), SL_OK);
    } else {
        assert_int_equal(sl_renderer_read_ids(j->r, j->frame_ids, &err), SL_OK);
        assert_int_equal(sl_renderer_read_depth(j->r, j->frame_depth, &err), SL_OK);
    }
    if (kind == SL_RENDER_SHADED) {
        /* the colours too: the unculled shaded frame (see-through objects blended in both) */
        assert_int_equal(sl_renderer_read_rgba(j->r, j->frame_rgba, &err), SL_OK);
        assert_int_equal(sl_renderer_draw(j->r, &v, j->all, j->n, SL_RENDER_SHADED, NULL, &err), SL_OK);
        assert_int_equal(sl_renderer_read_rgba(j->r, j->full_rgba, &err), SL_OK);
        for (uint32_t p = 0; p < j->npx; p++)
            j->rgba_differ += memcmp(j->frame_rgba + 4 * p, j->full_rgba + 4 * p, 4) != 0;
    }
    assert_int_equal(sl_renderer_draw(j->r, &v, j->all, j->n, SL_RENDER_IDS, NULL, &err), SL_OK);
    assert_int_equal(sl_renderer_read_ids(j->r, j->full_ids, &err), SL_OK);
    assert_int_equal(sl_renderer_read_depth(j->r, j->full_depth, &err), SL_OK);
    memset(j->shown, 0, j->n);
    for (uint32_t p = 0; p < j->npx; p++)
        if (j->full_ids[p] != SL_NONE)
            j->shown[j->full_ids[p]] = 1;
    /* the culler's ids hold every object GL's image shows */
    uint32_t at = 0;
    for (uint32_t i = 0; i < j->n; i++) {
        bool kept = at < k && j->ids[at] == i;
        if (kept)
            at++;
        if (j->shown[i] && !kept) {
            j->gl_missed++;
            print_message("%s frame %u: object %u shows in GL's image but was culled\n", label, f, i);
        }
    }
    /* the frame's image is the unculled one but for depth ties, and its depth is the unculled
     * depth everywhere (see-through objects write none) */
    for (uint32_t p = 0; p < j->npx; p++) {
        if (j->frame_depth[p] != j->full_depth[p])
            j->depth_differ++;
        bool differ = kind == SL_RENDER_DEPTH ? j->frame_depth[p] != j->full_depth[p]
                                              : j->frame_ids[p] != j->full_ids[p];
        if (!differ)
            continue;
        j->pixels_differ++;
        if (j->frame_depth[p] != j->full_depth[p])
            j->pixels_differ_no_tie++;
    }
    /* against the oracle at the culling resolution: each miss must be an object GL's image hides */
    sl_cull_metrics mt;
    assert_int_equal(sl_metrics_compare(j->s, &fr, j->ids, k, &mt, j->missed, j->missed_px, j->n, &err), SL_OK);
    j->oracle_missed += mt.missed_count;
    for (uint32_t m = 0; m < mt.missed_count && m < j->n; m++)
        if (j->shown[j->missed[m]])
            j->oracle_missed_gl_shows++;
    j->kept += k;
    j->frames++;
}

static void judge_report(const gl_judge *j, const char *label)
{
    print_message("%s: %llu frames, %llu kept, %llu missed against GL's image, %llu against the oracle (%llu of "
                  "them shown by GL), %llu pixels differ from the unculled image (%llu without a depth tie)\n",
                  label, (unsigned long long)j->frames, (unsigned long long)j->kept,
                  (unsigned long long)j->gl_missed, (unsigned long long)j->oracle_missed,
                  (unsigned long long)j->oracle_missed_gl_shows, (unsigned long long)j->pixels_differ,
                  (unsigned long long)j->pixels_differ_no_tie);
}

static void assert_judged(const gl_judge *j, const char *label)
{
    judge_report(j, label);
    assert_true(j->frames > 0);
    /* shaded frames: the same colours (a pixel whose ids differ by a tie may differ in colour) */
    if (j->rgba_differ > j->pixels_differ)
        fail_msg("%s: %llu pixels of the shaded frames differ from the unculled ones", label,
                 (unsigned long long)j->rgba_differ);
    if (j->depth_differ)
        fail_msg("%s: %llu pixels of the frames' depth differ from the unculled depth", label,
                 (unsigned long long)j->depth_differ);
    if (j->gl_missed || j->oracle_missed_gl_shows || j->pixels_differ_no_tie)
        fail_msg("%s: culled objects that show (GL %llu, oracle %llu), %llu pixels differ without a tie", label,
                 (unsigned long long)j->gl_missed, (unsigned long long)j->oracle_missed_gl_shows,
                 (unsigned long long)j->pixels_differ_no_tie);
}

static uint64_t vfc_kept(sl_scene s, sl_path p)
{
    sl_culler c;
    sl_error err;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *ids = malloc(n * 4), k;
    uint64_t kept = 0;
    for (uint32_t f = 0; f < sl_path_count(p); f++) {
        sl_camera cam = sl_path_camera(p, f);
        assert_int_equal(sl_culler_cull(c, &cam, ids, n, &k, &err), SL_OK);
        kept += k;
    }
    free(ids);
    sl_culler_destroy(c);
    return kept;
}

static void test_hoq_gl_city(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    gl_judge j;
    judge_init(&j, s, W, H);
    sl_error err;
    sl_culler c;
    assert_int_equal(sl_renderer_create_culler(j.r, "gl-stopwait", NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE_AT_RESOLUTION);
    sl_path street = views_of(s, SL_VIEWS_STREET, sanitized() ? 4 : 24, 61);
    sl_path fly = views_of(s, SL_VIEWS_FLYOVER, sanitized() ? 2 : 8, 62);
    for (uint32_t f = 0; f < sl_path_count(street); f++) {
        sl_camera cam = sl_path_camera(street, f);
        judge_frame(&j, c, &cam, f % 4 == 0 ? SL_RENDER_SHADED : SL_RENDER_IDS, "gl-stopwait street", f);
    }
    uint64_t street_kept = j.kept;
    for (uint32_t f = 0; f < sl_path_count(fly); f++) {
        sl_camera cam = sl_path_camera(fly, f);
        judge_frame(&j, c, &cam, f % 2 ? SL_RENDER_DEPTH : SL_RENDER_IDS, "gl-stopwait flyover", f);
    }
    assert_judged(&j, "gl-stopwait on GL, tiny city");
    uint64_t vk = vfc_kept(s, street);
    print_message("street views: gl-stopwait on GL keeps %llu, vfc %llu\n", (unsigned long long)street_kept,
                  (unsigned long long)vk);
    assert_true(street_kept * 10 < vk * 8); /* it culls by its queries */
    sl_culler_destroy(c);
    sl_path_destroy(street);
    sl_path_destroy(fly);
    judge_free(&j);
    sl_scene_destroy(s);
}

static void test_hoq_gl_map(void **state)
{
    (void)state;
    sl_test_map map;
    if (!sl_test_open_map(0, W, H, sanitized() ? 2 : 6, 31, &map))
        skip();
    sl_scene s = map.scene;
    sl_path p = map.views;
    const char *name = map.name;
    sl_error err;
    gl_judge j;
    judge_init(&j, s, W, H);
    sl_culler c;
    assert_int_equal(sl_renderer_create_culler(j.r, "gl-stopwait", NULL, &c, &err), SL_OK);
    for (uint32_t f = 0; f < sl_path_count(p); f++) {
        sl_camera cam = sl_path_camera(p, f);
        judge_frame(&j, c, &cam, SL_RENDER_IDS, name, f);
    }
    assert_judged(&j, name);
    sl_culler_destroy(c);
    judge_free(&j);
    sl_test_map_free(&map);
}

/* ---- the edge of an occluder, by fractions of a pixel ---- */

/* A wall x in [-20, 0] at 6.3 in front of the eye and two small boxes x in [-0.2, 0] and [-0.6, 0]
 * (1.5 and 4.5 pixels: tested at the pyramid's levels 0 to 2) 10 behind it:
 * with the eye at x_e > 0 the box peeks past the wall's edge by about 12 x_e pixels, with x_e < 0
 * it is hidden. The eye sweeps x_e by 1/20 pixel steps through the edge, the camera rolled by
 * multiples of 45 degrees so that the peeking edge is each side of the box's screen rectangle in
 * turn, and diagonal across the pyramid's texels: gpu-hiz must keep the box in every frame GL's
 * image shows it. */
static void test_gpu_hiz_edges(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_test_add_box(s, (sl_vec3){-20, 0, -20}, (sl_vec3){0, 0.3f, 20}, SL_KIND_BUILDING,
                    SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    sl_test_add_box(s, (sl_vec3){-0.2f, 10, -0.1f}, (sl_vec3){0, 10.2f, 0.1f}, SL_KIND_BUILDING,
                    SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    sl_test_add_box(s, (sl_vec3){-0.6f, 10, 0.5f}, (sl_vec3){0, 10.2f, 1.1f}, SL_KIND_BUILDING,
                    SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    gl_judge j;
    judge_init(&j, s, W, H);
    sl_culler c;
    assert_int_equal(sl_renderer_create_culler(j.r, "gpu-hiz", NULL, &c, &err), SL_OK);
    uint32_t shown = 0, hidden = 0, n = sanitized() ? 10 : 40;
    for (int roll = 0; roll < 8; roll++)
        for (uint32_t f = 0; f < n; f++) {
            sl_camera cam = sl_camera_default();
            float xe = -0.02f + 0.16f / (float)n * (float)f; /* 1/20 pixel steps (n = 40) */
            cam.position = (sl_vec3){xe, -6.3f, 0.0f};
            cam.yaw = 1.57079633f;
            cam.pitch = 0.0f;
            cam.roll = 0.785398163f * (float)roll;
            cam.fov_y = 0.9f;
            cam.near_plane = 0.1f;
            cam.far_plane = 100.0f;
            cam.width = W;
            cam.height = H;
            judge_frame(&j, c, &cam, SL_RENDER_IDS, "gpu-hiz edges", f);
            for (int b = 1; b <= 2; b++)
                if (j.shown[b])
                    shown++;
                else
                    hidden++;
        }
    print_message("edges: a box shows %u times, is hidden %u times\n", shown, hidden);
    assert_true(shown > 0 && hidden > 0);
    assert_judged(&j, "gpu-hiz edges");
    sl_culler_destroy(c);
    judge_free(&j);
    sl_scene_destroy(s);
}

/* See-through objects never hide (the oracle's rule): a see-through wall in front of a box, the eye
 * walking along it; gpu-hiz keeps them out of pass 1 and so out of its pyramid: the box is drawn in
 * every frame GL's image shows it. Then a wall moves into the view (scene_changed). */
static void test_gpu_hiz_see_through(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t wall = sl_test_add_box(s, (sl_vec3){-20, 0, -20}, (sl_vec3){20, 0.3f, 20}, SL_KIND_BUILDING,
                                    SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_SEE_THROUGH);
    uint32_t box = sl_test_add_box(s, (sl_vec3){-1, 10, -1}, (sl_vec3){1, 12, 1}, SL_KIND_BUILDING,
                                   SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER);
    uint32_t mover = sl_test_add_box(s, (sl_vec3){50, 3, -3}, (sl_vec3){52, 3.5f, 3}, SL_KIND_BUILDING,
                                     SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER | SL_OBJECT_DYNAMIC);
    assert_true(wall != SL_NONE && box != SL_NONE && mover != SL_NONE);
    gl_judge j;
    judge_init(&j, s, W, H);
    sl_culler c;
    assert_int_equal(sl_renderer_create_culler(j.r, "gpu-hiz", NULL, &c, &err), SL_OK);
    uint32_t shown = 0;
    for (uint32_t f = 0; f < 8; f++) {
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){-1.0f + 0.25f * (float)f, -6.3f, 0.2f};
        cam.yaw = 1.57079633f;
        cam.pitch = 0.0f;
        cam.fov_y = 0.9f;
        cam.near_plane = 0.1f;
        cam.far_plane = 100.0f;
        cam.width = W;
        cam.height = H;
        judge_frame(&j, c, &cam, f % 2 ? SL_RENDER_SHADED : SL_RENDER_IDS, "gpu-hiz see-through", f);
        shown += j.shown[box];
    }
    assert_int_equal(shown, 8);
    /* a solid wall beside the view moves in front of the box: scene_changed gives gpu-hiz its new box
     * (a stale one, outside the frustum, would cull it) */
    sl_affine in_front = {{1, 0, 0, -51.0f, 0, 1, 0, 0, 0, 0, 1, 0}};
    assert_int_equal(sl_scene_set_object_transform(s, mover, &in_front, &err), SL_OK);
    assert_int_equal(sl_renderer_scene_changed(j.r, &err), SL_OK);
    assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
    uint32_t mover_shown = 0;
    for (uint32_t f = 0; f < 4; f++) {
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){-0.2f + 0.1f * (float)f, -6.3f, 0.2f};
        cam.yaw = 1.57079633f;
        cam.pitch = 0.0f;
        cam.fov_y = 0.9f;
        cam.near_plane = 0.1f;
        cam.far_plane = 100.0f;
        cam.width = W;
        cam.height = H;
        judge_frame(&j, c, &cam, SL_RENDER_IDS, "gpu-hiz moved", f);
        mover_shown += j.shown[mover];
    }
    assert_int_equal(mover_shown, 4);
    assert_judged(&j, "gpu-hiz see-through");
    sl_culler_destroy(c);
    judge_free(&j);
    sl_scene_destroy(s);
}

/* ---- gpu-hiz over a walk ---- */

static sl_path walk_of(sl_scene s, uint32_t frames)
{
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = W;
    po.intrinsics.height = H;
    po.frames = frames;
    po.seed = 3;
    sl_path p;
    sl_error err;
    if (sl_path_generate(s, &po, NULL, &p, &err) != SL_OK)
        fail_msg("%s", err.message);
    return p;
}

/* gl-stopwait, chc (threshold 0: its images are vfc's, which are the unculled ones, but for depth
 * ties) and chc++ on GL over a walk: coherence is what CHC uses. */
static void test_query_cullers_gl_walk(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_path p = walk_of(s, sanitized() ? 6 : 40);
    /* vfc first: its frames on this renderer are the unculled images too (what chc's are compared with) */
    static const char *const methods[6] = {"vfc", "gl-stopwait", "chc", "chc", "chc++", "chc++"};
    static const char *const opts[6] = {NULL, NULL, NULL, "assume_visible=3,zpass=true", NULL, "geometry_queries=false"};
    uint64_t vk = vfc_kept(s, p), queries[6];
    for (int m = 0; m < 6; m++) {
        gl_judge j;
        judge_init(&j, s, W, H);
        if (opts[m] && strstr(opts[m], "zpass=true"))
            j.draws_per_object = 2;
        sl_error err;
        sl_culler c;
        if (sl_renderer_create_culler(j.r, methods[m], opts[m], &c, &err) != SL_OK)
            fail_msg("%s %s: %s", methods[m], opts[m] ? opts[m] : "", err.message);
        assert_int_equal(sl_culler_guarantee(c), m == 0 ? SL_CONSERVATIVE : SL_CONSERVATIVE_AT_RESOLUTION);
        char label[80];
        snprintf(label, sizeof label, "%s %s", methods[m], opts[m] ? opts[m] : "(defaults)");
        queries[m] = 0;
        for (uint32_t f = 0; f < sl_path_count(p); f++) {
            sl_camera cam = sl_path_camera(p, f);
            judge_frame(&j, c, &cam, f % 8 == 0 ? SL_RENDER_SHADED : SL_RENDER_IDS, label, f);
            sl_cull_stats cs;
            sl_culler_stats(c, &cs);
            queries[m] += cs.queries;
        }
        assert_judged(&j, label);
        print_message("%s: %llu queries over the walk, kept %llu (vfc %llu)\n", label, (unsigned long long)queries[m],
                      (unsigned long long)j.kept, (unsigned long long)vk);
        if (m == 0) {
            assert_int_equal(j.kept, vk);
        } else {
            assert_true(queries[m] > 0);
            assert_true(j.kept < vk); /* it culls */
        }
        sl_culler_destroy(c);
        judge_free(&j);
    }
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

static void test_gpu_hiz_walk(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_path p = walk_of(s, sanitized() ? 6 : 40);
    static const char *const opts[3] = {"indirect_count=false", NULL, "margin=0.5"};
    static const sl_render_kind kinds[3] = {SL_RENDER_IDS, SL_RENDER_IDS, SL_RENDER_SHADED};
    uint64_t kept[3];
    uint64_t vk = vfc_kept(s, p);
    for (int m = 0; m < 3; m++) {
        gl_judge j;
        judge_init(&j, s, W, H);
        sl_error err;
        sl_culler c;
        if (sl_renderer_create_culler(j.r, "gpu-hiz", opts[m], &c, &err) != SL_OK)
            fail_msg("gpu-hiz %s: %s", opts[m] ? opts[m] : "", err.message);
        assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE_AT_RESOLUTION);
        char label[64];
        snprintf(label, sizeof label, "gpu-hiz %s", opts[m] ? opts[m] : "(defaults)");
        for (uint32_t f = 0; f < sl_path_count(p); f++) {
            sl_camera cam = sl_path_camera(p, f);
            judge_frame(&j, c, &cam, kinds[m], label, f);
        }
        assert_judged(&j, label);
        kept[m] = j.kept;
        if (m == 0) {
            /* outside sl_renderer_frame (sl_culler_cull): it clears and draws the frame itself */
            for (uint32_t f = 0; f < 3; f++) {
                sl_camera cam = sl_path_camera(p, f * (sl_path_count(p) / 3));
                uint32_t k;
                assert_int_equal(sl_culler_cull(c, &cam, j.ids, j.n, &k, &err), SL_OK);
                assert_int_equal(sl_renderer_read_ids(j.r, j.frame_ids, &err), SL_OK);
                sl_view v;
                assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
                assert_int_equal(sl_renderer_draw(j.r, &v, j.all, j.n, SL_RENDER_IDS, NULL, &err), SL_OK);
                assert_int_equal(sl_renderer_read_ids(j.r, j.full_ids, &err), SL_OK);
                assert_memory_equal(j.frame_ids, j.full_ids, (size_t)j.npx * 4);
                assert_true(k > 0);
            }
        }
        sl_culler_destroy(c);
        judge_free(&j);
    }
    print_message("walk: gpu-hiz keeps %llu (indirect count), %llu (zeroed instances), %llu (margin 0.5); vfc %llu\n",
                  (unsigned long long)kept[0], (unsigned long long)kept[1], (unsigned long long)kept[2],
                  (unsigned long long)vk);
    assert_int_equal(kept[0], kept[1]); /* the two draw paths decide alike */
    assert_true(kept[0] <= kept[2]);
    assert_true(kept[0] * 10 < vk * 8); /* it culls */
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

int main(void)
{
    sl_error err;
    if (sl_renderer_probe(SL_GL_CONTEXT_AUTO, &err) != SL_OK) {
        printf("skipped: no headless GL context: %s\n", err.message);
        return 77;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_counts_exact_known_scene),
        cmocka_unit_test(test_counts_match_cpu),
        cmocka_unit_test(test_poll_wait),
        cmocka_unit_test(test_hoq_gl_city),
        cmocka_unit_test(test_hoq_gl_map),
        cmocka_unit_test(test_query_cullers_gl_walk),
        cmocka_unit_test(test_gpu_hiz_walk),
        cmocka_unit_test(test_gpu_hiz_edges),
        cmocka_unit_test(test_gpu_hiz_see_through),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

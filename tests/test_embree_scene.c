/* The Embree scene wrapper (src/embree/embree_scene.h): global triangle numbering and transforms,
 * first hits, misses, mirrored windings, back faces of closed convex objects skipped like the point
 * oracle does, watertight shared edges, id renders that agree with the point oracle, results that
 * do not depend on Embree's thread count, empty scenes, bad arguments, and every byte returned. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "embree/embree_scene.h"
#include "sightline/gen.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"
#include "support/view_matrices.h"

static uint32_t add_mesh_object(sl_scene s, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt,
                                const sl_affine *xf, uint32_t flags)
{
    sl_error err;
    sl_mesh_desc md = {pos, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, xf, 0xffffffffu, SL_KIND_OTHER, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* A closed box, faces counter-clockwise seen from outside. */
static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t flags)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    return add_mesh_object(s, p, 8, idx, 12, NULL, flags);
}

static sl_es_ray ray(float ox, float oy, float oz, float dx, float dy, float dz)
{
    sl_es_ray r = {{ox, oy, oz}, 0.0f, {dx, dy, dz}, INFINITY};
    return r;
}

static void test_hits_and_numbering(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(&a, &s, &err), SL_OK);
    /* object 0: a square in the plane x = 5; object 1: the same square moved to x = 8, y = 3 */
    float sq[12] = {0, -1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1};
    uint32_t sqi[6] = {0, 1, 2, 0, 2, 3};
    sl_affine t0 = sl_affine_identity(), t1 = sl_affine_identity();
    t0.m[3] = 5;
    t1.m[3] = 8, t1.m[7] = 3;
    add_mesh_object(s, sq, 4, sqi, 2, &t0, 0);
    add_mesh_object(s, sq, 4, sqi, 2, &t1, 0);
    uint32_t box = add_box(s, (sl_vec3){20, -1, -1}, (sl_vec3){22, 1, 1}, 0);
    assert_int_equal(box, 2);

    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, &a, &es, &err), SL_OK);
    assert_int_equal(sl_es_triangle_count(es), 16);
    assert_int_equal(sl_es_object_count(es), 3);
    assert_int_equal(sl_es_object_first_triangle(es, 0), 0);
    assert_int_equal(sl_es_object_first_triangle(es, 1), 2);
    assert_int_equal(sl_es_object_first_triangle(es, 2), 4);
    assert_int_equal(sl_es_object_first_triangle(es, 3), 16);
    for (uint32_t t = 0; t < 16; t++)
        assert_int_equal(sl_es_triangle_object(es, t), t < 2 ? 0 : t < 4 ? 1 : 2);
    double v[3][3];
    sl_es_triangle_vertices(es, 3, v); /* object 1's second triangle: (0,-1,-1) (0,1,1) (0,-1,1) moved */
    assert_true(v[0][0] == 8 && v[0][1] == 2 && v[0][2] == -1);
    assert_true(v[1][0] == 8 && v[1][1] == 4 && v[1][2] == 1);
    sl_aabb b = sl_es_bounds(es);
    assert_true(b.min.x == 5 && b.max.x == 22 && b.min.y == -1 && b.max.y == 4);

    sl_es_ray rays[5] = {ray(0, 0.5f, 0.25f, 1, 0, 0),   /* square 0, first triangle (z < y) */
                         ray(0, 3.5f, -0.5f, 1, 0, 0),   /* square 1 */
                         ray(0, 0, 10, 1, 0, 0),         /* above everything: a miss */
                         ray(6, 0, 0, 2, 0, 0),          /* past square 0: the box at t = 7 (dir length 2) */
                         ray(0, 0, 0, -1, 0, 0)};        /* away from everything */
    rays[3].tfar = 100;
    sl_es_hit h[5];
    sl_es_trace(es, rays, h, 5);
    assert_int_equal(h[0].object, 0);
    assert_int_equal(h[0].triangle, 0);
    assert_true(fabsf(h[0].t - 5) < 1e-5f);
    assert_int_equal(h[1].object, 1);
    assert_true(h[1].triangle == 2 || h[1].triangle == 3);
    assert_int_equal(h[2].triangle, SL_NONE);
    assert_int_equal(h[2].object, SL_NONE);
    assert_true(isinf(h[2].t));
    assert_int_equal(h[3].object, 2);
    assert_true(fabsf(h[3].t - 7) < 1e-5f);
    assert_int_equal(h[4].triangle, SL_NONE);
    /* tnear and tfar bound the search */
    sl_es_ray near = ray(0, 0.5f, 0.25f, 1, 0, 0);
    near.tfar = 4.0f;
    sl_es_trace(es, &near, h, 1);
    assert_int_equal(h[0].triangle, SL_NONE);
    near.tfar = INFINITY;
    near.tnear = 6.0f;
    sl_es_trace(es, &near, h, 1);
    assert_int_equal(h[0].object, 2);

    /* many rays: the batching gives the same answers as one by one */
    enum { N = 1000 };
    sl_es_ray *many = malloc(N * sizeof *many);
    sl_es_hit *hb = malloc(N * sizeof *hb);
    sl_rng r;
    sl_rng_seed(&r, 3, 0);
    for (int i = 0; i < N; i++)
        many[i] = ray(0, sl_rng_range(&r, -2, 5), sl_rng_range(&r, -2, 2), 1, sl_rng_range(&r, -0.1f, 0.1f), 0);
    sl_es_trace(es, many, hb, N);
    uint32_t hits = 0;
    for (int i = 0; i < N; i++) {
        sl_es_hit one;
        sl_es_trace(es, &many[i], &one, 1);
        assert_int_equal(one.triangle, hb[i].triangle);
        hits += hb[i].triangle != SL_NONE;
    }
    assert_true(hits > 100 && hits < N);
    free(many);
    free(hb);

    sl_es_stats stats;
    sl_es_get_stats(es, &stats);
    assert_int_equal(stats.triangle_count, 16);
    assert_int_equal(stats.vertex_count, 16);
    assert_false(stats.backface_filter);
    assert_true(stats.memory_bytes > 16 * 12);
    sl_es_destroy(es);
    sl_scene_destroy(s);
    assert_int_equal(cnt.live, 0);
}

/* A mirroring transform keeps the front side: the stored winding is flipped. */
static void test_mirrored_winding(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}; /* normal +z */
    uint32_t idx[3] = {0, 1, 2};
    sl_affine m = sl_affine_identity();
    m.m[0] = -1; /* mirror x */
    add_mesh_object(s, tri, 3, idx, 1, NULL, 0);
    add_mesh_object(s, tri, 3, idx, 1, &m, 0);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    for (uint32_t t = 0; t < 2; t++) {
        double v[3][3];
        sl_es_triangle_vertices(es, t, v);
        double e1[3] = {v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]};
        double e2[3] = {v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]};
        double nz = e1[0] * e2[1] - e1[1] * e2[0];
        assert_true(nz > 0);
    }
    sl_es_destroy(es);
    sl_scene_destroy(s);
}

/* Closed convex objects: a ray from inside sees through their back faces, as the oracle does,
 * unless draw_closed_backfaces is set; other objects are hit from both sides. */
static void test_closed_backfaces(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t closed = add_box(s, (sl_vec3){-1, -1, -1}, (sl_vec3){1, 1, 1}, SL_OBJECT_CLOSED_CONVEX);
    uint32_t open = add_box(s, (sl_vec3){4, -1, -1}, (sl_vec3){6, 1, 1}, 0);
    uint32_t far = add_box(s, (sl_vec3){10, -5, -5}, (sl_vec3){11, 5, 5}, 0);
    sl_es *es, *es2;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_es_options o = {0};
    o.draw_closed_backfaces = true;
    assert_int_equal(sl_es_create(s, &o, NULL, &es2, &err), SL_OK);
    sl_es_stats st;
    sl_es_get_stats(es, &st);
    assert_true(st.backface_filter);
    sl_es_get_stats(es2, &st);
    assert_false(st.backface_filter);

    sl_es_ray r[3] = {ray(0, 0, 0, 1, 0, 0),   /* from inside the closed box */
                      ray(-5, 0, 0, 1, 0, 0),  /* from outside: its front face */
                      ray(5, 0, 0, 1, 0, 0)};  /* from inside the open box: its inner face */
    sl_es_hit h[3];
    sl_es_trace(es, r, h, 3);
    assert_int_equal(h[0].object, open);
    assert_int_equal(h[1].object, closed);
    assert_true(fabsf(h[1].t - 4) < 1e-5f);
    assert_int_equal(h[2].object, open);
    assert_true(fabsf(h[2].t - 1) < 1e-5f);
    r[2] = ray(7, 0, 0, 1, 0, 0);
    sl_es_trace(es, &r[2], &h[2], 1);
    assert_int_equal(h[2].object, far);
    sl_es_trace(es2, r, h, 1);
    assert_int_equal(h[0].object, closed);
    sl_es_destroy(es);
    sl_es_destroy(es2);
    sl_scene_destroy(s);
}

/* Rays aimed exactly at the diagonal a face's two triangles share, from in front of the face,
 * never slip through (RTC_SCENE_FLAG_ROBUST). */
static void test_watertight(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t box = add_box(s, (sl_vec3){-1.3f, -0.7f, -1.1f}, (sl_vec3){1.7f, 0.9f, 1.3f}, 0);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_rng r;
    sl_rng_seed(&r, 11, 0);
    enum { N = 20000 };
    sl_es_ray *rays = malloc(N * sizeof *rays);
    sl_es_hit *h = malloc(N * sizeof *h);
    double vv[3][3];
    for (int i = 0; i < N; i++) {
        /* face k is triangles 2k (a, b, c) and 2k+1 (a, c, d): they share the diagonal a-c */
        uint32_t t = 2 * sl_rng_below(&r, 6);
        sl_es_triangle_vertices(es, t, vv);
        double f = sl_rng_double(&r), p[3], e1[3], e2[3];
        for (int c = 0; c < 3; c++) {
            p[c] = vv[0][c] + f * (vv[2][c] - vv[0][c]);
            e1[c] = vv[1][c] - vv[0][c];
            e2[c] = vv[2][c] - vv[0][c];
        }
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double dir[3];
        do {
            for (int c = 0; c < 3; c++)
                dir[c] = sl_rng_double(&r) * 2 - 1;
        } while (dir[0] * n[0] + dir[1] * n[1] + dir[2] * n[2] < 0.05 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
        float o[3];
        for (int c = 0; c < 3; c++)
            o[c] = (float)(p[c] + 20 * dir[c]);
        rays[i] = ray(o[0], o[1], o[2], (float)(p[0] - o[0]), (float)(p[1] - o[1]), (float)(p[2] - o[2]));
    }
    sl_es_trace(es, rays, h, N);
    uint32_t missed = 0;
    for (int i = 0; i < N; i++)
        missed += h[i].object != box;
    assert_int_equal(missed, 0);
    free(rays);
    free(h);
    sl_es_destroy(es);
    sl_scene_destroy(s);
}

/* An id render agrees with the point oracle's object ids on (nearly) every pixel: same camera
 * conventions. Pixels may differ only where triangle edges pass close to a pixel centre. */
static void test_render_matches_oracle(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_camera cam = sl_camera_default();
    cam.width = 160;
    cam.height = 120;
    cam.position = (sl_vec3){0, 0, 30};
    cam.pitch = -0.4f;
    cam.yaw = 0.7f;
    uint32_t *ids = malloc((size_t)cam.width * cam.height * sizeof *ids);
    for (int proj = 0; proj < 2; proj++) {
        cam.projection = proj ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE;
        assert_int_equal(sl_es_render_ids(es, &cam, ids, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        sl_oracle_view v;
        assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
        uint32_t n = cam.width * cam.height, same = 0, drawn = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t obj = ids[i] == SL_NONE ? SL_NONE : sl_es_triangle_object(es, ids[i]);
            same += obj == v.ids[i];
            drawn += obj != SL_NONE;
        }
        assert_true(drawn > n / 4);
        assert_true(same >= n - n / 50);
    }
    cam.width = 0;
    assert_int_equal(sl_es_render_ids(es, &cam, ids, &err), SL_ERROR_INVALID_ARGUMENT);
    free(ids);
    sl_oracle_destroy(o);
    sl_es_destroy(es);
    sl_scene_destroy(s);
}

/* An engine's off-axis views (issue 13 §1: a shifted stereo eye in GL depth, a reversed-z
 * infinite-far Direct3D view with a Vulkan image, an orthographic tile): the rays through the
 * view's inverse projection see what the oracle draws of the same view. */
static void test_render_view_matches_oracle(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_camera cam = sl_camera_default();
    cam.width = 160;
    cam.height = 120;
    cam.position = (sl_vec3){0, 0, 30};
    cam.pitch = -0.4f;
    cam.yaw = 0.7f;
    uint32_t *ids = malloc((size_t)cam.width * cam.height * sizeof *ids);
    const struct {
        sl_projection proj;
        sl_clip_depth depth;
        unsigned flags;
        sl_tvm_shape shape;
    } views[] = {
        {SL_PERSPECTIVE, SL_CLIP_DEPTH_GL, 0, {1, 0.3, 1, 0}},
        {SL_PERSPECTIVE, SL_CLIP_DEPTH_REVERSED, SL_TVM_INF | SL_TVM_LH_Z | SL_TVM_FLIP_Y, {1, -0.4, 1, 0.2}},
        {SL_ORTHOGRAPHIC, SL_CLIP_DEPTH_ZERO_ONE, SL_TVM_FLIP_X, {2, 1, 2, -1}},
    };
    for (size_t q = 0; q < sizeof views / sizeof views[0]; q++) {
        cam.projection = views[q].proj;
        float V[16], P[16];
        sl_tvm_matrices(&cam, views[q].depth, views[q].flags, &views[q].shape, V, P);
        sl_view view;
        assert_int_equal(sl_view_from_matrices(V, P, views[q].depth, cam.width, cam.height, &view, &err), SL_OK);
        assert_int_equal(sl_es_render_view_ids(es, &view, ids, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render_view(o, &view, &f, &err), SL_OK);
        sl_oracle_view v;
        assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
        uint32_t n = cam.width * cam.height, same = 0, drawn = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t obj = ids[i] == SL_NONE ? SL_NONE : sl_es_triangle_object(es, ids[i]);
            same += obj == v.ids[i];
            drawn += obj != SL_NONE;
        }
        print_message("view %zu: %u of %u pixels agree, %u drawn\n", q, same, n, drawn);
        assert_true(drawn > n / 4);
        assert_true(same >= n - n / 50);
    }
    free(ids);
    sl_oracle_destroy(o);
    sl_es_destroy(es);
    sl_scene_destroy(s);
}

/* Hits do not depend on how many threads Embree built its tree with. */
static void test_thread_independent(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_es *e1, *e2;
    sl_es_options o1 = {0}, o2 = {0};
    o1.threads = 1;
    o2.threads = 2;
    o2.quality = 2;
    assert_int_equal(sl_es_create(s, &o1, NULL, &e1, &err), SL_OK);
    assert_int_equal(sl_es_create(s, &o2, NULL, &e2, &err), SL_OK);
    enum { N = 20000 };
    sl_es_ray *rays = malloc(N * sizeof *rays);
    sl_es_hit *h1 = malloc(N * sizeof *h1), *h2 = malloc(N * sizeof *h2);
    sl_rng r;
    sl_rng_seed(&r, 5, 0);
    for (int i = 0; i < N; i++)
        rays[i] = ray(sl_rng_range(&r, -100, 100), sl_rng_range(&r, -100, 100), sl_rng_range(&r, 1, 3),
                      sl_rng_range(&r, -1, 1), sl_rng_range(&r, -1, 1), sl_rng_range(&r, -0.3f, 0.5f));
    sl_es_trace(e1, rays, h1, N);
    sl_es_trace(e2, rays, h2, N);
    uint32_t same = 0;
    for (int i = 0; i < N; i++)
        same += h1[i].triangle == h2[i].triangle;
    assert_int_equal(same, N);
    free(rays);
    free(h1);
    free(h2);
    sl_es_destroy(e1);
    sl_es_destroy(e2);
    sl_scene_destroy(s);
}

static void test_empty_and_errors(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(&a, &s, &err), SL_OK);
    sl_es *es = NULL;
    assert_int_equal(sl_es_create(NULL, NULL, &a, &es, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_es_create(s, NULL, &a, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_es_options o = {0};
    o.quality = 3;
    assert_int_equal(sl_es_create(s, &o, &a, &es, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "quality"));
    assert_null(es);
    /* an empty scene: every ray misses */
    assert_int_equal(sl_es_create(s, NULL, &a, &es, &err), SL_OK);
    assert_int_equal(sl_es_triangle_count(es), 0);
    sl_es_ray r = ray(0, 0, 0, 1, 0, 0);
    sl_es_hit h;
    sl_es_trace(es, &r, &h, 1);
    assert_int_equal(h.triangle, SL_NONE);
    sl_aabb b = sl_es_bounds(es);
    assert_true(sl_aabb_is_empty(&b));
    sl_es_destroy(es);
    sl_es_destroy(NULL);
    sl_scene_destroy(s);
    assert_int_equal(cnt.live, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hits_and_numbering),     cmocka_unit_test(test_mirrored_winding),
        cmocka_unit_test(test_closed_backfaces),       cmocka_unit_test(test_watertight),
        cmocka_unit_test(test_render_matches_oracle),
        cmocka_unit_test(test_render_view_matches_oracle),  cmocka_unit_test(test_thread_independent),
        cmocka_unit_test(test_empty_and_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

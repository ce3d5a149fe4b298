/* The shared per-scene acceleration handle (accel.h, sl_scene_accel) and sl_culler_create_with:
 *  - cullers of several methods on 4 threads at once, each thread with its own cullers sharing one
 *    handle, return the ids private cullers (own BVH) return, view by view (scripts/test.sh --tsan
 *    runs this test under ThreadSanitizer);
 *  - memory: a culler with the handle holds at least the BVH's bytes fewer than a private one
 *    (counted through the allocator hooks), so N cullers with the handle hold one tree;
 *  - objects moving: the owner refits the handle, each culler's scene_changed leaves the tree alone,
 *    and the results stay those of private cullers that refit their own trees;
 *  - a leaf_size other than the handle's, or a handle of another scene, is refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "core/sl_core.h"
#include "sightline/accel.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "support/city_views.h"
#include "support/counting_alloc.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

#define THREADS 4

/* vfc, the occlusion framework's BVH walkers, hoq, and two methods without an object BVH (they
 * ignore the handle) */
static const char *const g_methods[] = {"vfc", "hzb", "hom", "lazygrid", "frusta", "gl-stopwait", "cullmap", "horizon"};
#define NM (sizeof g_methods / sizeof g_methods[0])

typedef struct shared_job {
    sl_scene scene;
    sl_scene_accel accel;
    sl_path views;
    uint32_t n;
    uint32_t *ref;        /* [method][view][n] ids, SL_NONE-padded */
    uint32_t *ref_count;  /* [method][view] */
    uint32_t thread;
    uint32_t mismatches;
    char message[640];
    pthread_barrier_t *start; /* all threads cull at once (their cullers made) */
} shared_job;

static void *run_thread(void *p)
{
    shared_job *j = p;
    sl_error err;
    sl_culler c[NM];
    sl_culler_params params = {NULL, j->accel};
    size_t made = 0;
    for (; made < NM; made++)
        if (sl_culler_create_with(g_methods[made], j->scene, NULL, &params, NULL, &c[made], &err) != SL_OK) {
            snprintf(j->message, sizeof j->message, "%s: %s", g_methods[made], err.message);
            j->mismatches++;
            break;
        }
    pthread_barrier_wait(j->start);
    if (made < NM) {
        for (size_t k = 0; k < made; k++)
            sl_culler_destroy(c[k]);
        return NULL;
    }
    uint32_t *out = malloc(j->n * sizeof *out);
    uint32_t nv = sl_path_count(j->views);
    /* every thread culls every view, starting at a different one */
    for (uint32_t i = 0; i < nv; i++) {
        uint32_t v = (i + j->thread * 7) % nv;
        sl_camera cam = sl_path_camera(j->views, v);
        for (size_t m = 0; m < NM; m++) {
            uint32_t k;
            if (sl_culler_cull(c[m], &cam, out, j->n, &k, &err) != SL_OK) {
                snprintf(j->message, sizeof j->message, "%s view %u: %s", g_methods[m], v, err.message);
                j->mismatches++;
                continue;
            }
            size_t at = (m * nv + v);
            if (k != j->ref_count[at] || memcmp(out, j->ref + at * j->n, k * sizeof *out) != 0) {
                snprintf(j->message, sizeof j->message, "%s view %u: %u ids with the shared handle, %u without",
                         g_methods[m], v, k, j->ref_count[at]);
                j->mismatches++;
            }
        }
    }
    free(out);
    for (size_t m = 0; m < NM; m++)
        sl_culler_destroy(c[m]);
    return NULL;
}

static void test_threads_same_ids(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_error err;
    sl_scene_accel accel;
    assert_int_equal(sl_scene_accel_create(s, NULL, &accel, &err), SL_OK);
    assert_true(sl_scene_accel_scene(accel) == s);
    assert_int_equal(sl_scene_accel_leaf_size(accel), 4);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = 160;
    po.intrinsics.height = 120;
    sl_path views;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, sanitized() ? 6 : 24, 17, &po, NULL, &views, &err),
                     SL_OK);
    uint32_t n = sl_scene_object_count(s), nv = sl_path_count(views);
    uint32_t *ref = malloc(NM * nv * (size_t)n * sizeof *ref), *ref_count = calloc(NM * nv, sizeof *ref_count);
    /* the private cullers' ids */
    for (size_t m = 0; m < NM; m++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(g_methods[m], s, NULL, NULL, &c, &err), SL_OK);
        for (uint32_t v = 0; v < nv; v++) {
            sl_camera cam = sl_path_camera(views, v);
            assert_int_equal(sl_culler_cull(c, &cam, ref + (m * nv + v) * n, n, &ref_count[m * nv + v], &err), SL_OK);
        }
        sl_culler_destroy(c);
    }
    shared_job jobs[THREADS];
    pthread_t th[THREADS];
    pthread_barrier_t start;
    assert_int_equal(pthread_barrier_init(&start, NULL, THREADS), 0);
    for (uint32_t t = 0; t < THREADS; t++) {
        jobs[t] = (shared_job){s, accel, views, n, ref, ref_count, t, 0, "", &start};
        assert_int_equal(pthread_create(&th[t], NULL, run_thread, &jobs[t]), 0);
    }
    uint32_t bad = 0;
    for (uint32_t t = 0; t < THREADS; t++) {
        pthread_join(th[t], NULL);
        if (jobs[t].mismatches)
            print_error("thread %u: %u mismatches, last: %s\n", t, jobs[t].mismatches, jobs[t].message);
        bad += jobs[t].mismatches;
    }
    pthread_barrier_destroy(&start);
    assert_int_equal(bad, 0);
    free(ref);
    free(ref_count);
    sl_path_destroy(views);
    sl_scene_accel_destroy(accel);
    sl_scene_destroy(s);
}

static void test_memory_one_tree(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_error err;
    sl_test_counter ac = {0, 0, 0};
    sl_allocator aa = sl_test_counting_allocator(&ac);
    sl_scene_accel_options ao = {0, 1, &aa};
    sl_scene_accel accel;
    assert_int_equal(sl_scene_accel_create(s, &ao, &accel, &err), SL_OK);
    sl_bvh_stats bs;
    sl_bvh_get_stats(sl_scene_accel_bvh(accel), &bs);
    assert_true(ac.live >= bs.memory_bytes / 2);
    sl_culler_params params = {NULL, accel};
    const char *methods[] = {"vfc", "hzb", "gl-stopwait"};
    const uint32_t N = 8;
    for (size_t m = 0; m < SL_COUNTOF(methods); m++) {
        sl_test_counter priv = {0, 0, 0}, shared = {0, 0, 0};
        sl_allocator ap = sl_test_counting_allocator(&priv), as = sl_test_counting_allocator(&shared);
        sl_culler p, c[8];
        assert_int_equal(sl_culler_create_with(methods[m], s, NULL, NULL, &ap, &p, &err), SL_OK);
        for (uint32_t i = 0; i < N; i++)
            assert_int_equal(sl_culler_create_with(methods[m], s, NULL, &params, &as, &c[i], &err), SL_OK);
        size_t one_private = priv.live, n_shared = shared.live;
        print_message("%s: a private culler holds %zu bytes, %u with the shared handle %zu (%zu each), the handle "
                      "%zu (its tree %zu)\n",
                      methods[m], one_private, N, n_shared, n_shared / N, ac.live, bs.memory_bytes);
        /* each culler with the handle holds at least the tree's bytes fewer than a private one:
         * N of them and the handle hold one tree */
        assert_true(n_shared + (size_t)N * bs.memory_bytes <= (size_t)N * one_private);
        sl_culler_destroy(p);
        for (uint32_t i = 0; i < N; i++)
            sl_culler_destroy(c[i]);
        assert_int_equal(priv.live, 0);
        assert_int_equal(shared.live, 0);
    }
    sl_scene_accel_destroy(accel);
    assert_int_equal(ac.live, 0);
    sl_scene_destroy(s);
}

static void test_moving_objects(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city();
    sl_error err;
    sl_scene_accel accel;
    assert_int_equal(sl_scene_accel_create(s, NULL, &accel, &err), SL_OK);
    sl_culler_params params = {NULL, accel};
    sl_culler priv[NM], shared[NM];
    for (size_t m = 0; m < NM; m++) {
        assert_int_equal(sl_culler_create(g_methods[m], s, NULL, NULL, &priv[m], &err), SL_OK);
        assert_int_equal(sl_culler_create_with(g_methods[m], s, NULL, &params, NULL, &shared[m], &err), SL_OK);
    }
    /* the dynamic objects (cars) */
    uint32_t n = sl_scene_object_count(s), moved = 0;
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = 160;
    po.intrinsics.height = 120;
    sl_path views;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 6, 23, &po, NULL, &views, &err), SL_OK);
    uint32_t *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    for (int step = 0; step < 3; step++) {
        for (uint32_t i = 0; i < n; i++) {
            sl_object_view info = sl_scene_object(s, i);
            if (!(info.flags & SL_OBJECT_DYNAMIC))
                continue;
            sl_affine t = info.transform;
            t.m[3] += 6.0f; /* 6 m along x */
            assert_int_equal(sl_scene_set_object_transform(s, i, &t, &err), SL_OK);
            moved++;
        }
        /* the owner refits the handle while nothing culls, then every culler is told */
        assert_int_equal(sl_scene_accel_scene_changed(accel, &err), SL_OK);
        for (size_t m = 0; m < NM; m++) {
            assert_int_equal(sl_culler_scene_changed(priv[m], &err), SL_OK);
            assert_int_equal(sl_culler_scene_changed(shared[m], &err), SL_OK);
        }
        for (uint32_t v = 0; v < sl_path_count(views); v++) {
            sl_camera cam = sl_path_camera(views, v);
            for (size_t m = 0; m < NM; m++) {
                uint32_t ka, kb;
                assert_int_equal(sl_culler_cull(priv[m], &cam, a, n, &ka, &err), SL_OK);
                assert_int_equal(sl_culler_cull(shared[m], &cam, b, n, &kb, &err), SL_OK);
                if (ka != kb || memcmp(a, b, ka * sizeof *a) != 0)
                    fail_msg("%s, step %d, view %u: %u ids private, %u shared", g_methods[m], step, v, ka, kb);
            }
        }
    }
    assert_true(moved > 0);
    free(a);
    free(b);
    for (size_t m = 0; m < NM; m++) {
        sl_culler_destroy(priv[m]);
        sl_culler_destroy(shared[m]);
    }
    sl_path_destroy(views);
    sl_scene_accel_destroy(accel);
    sl_scene_destroy(s);
}

static void test_refused(void **state)
{
    (void)state;
    sl_scene s = sl_test_tiny_city(), other = sl_test_tiny_city();
    sl_error err;
    sl_scene_accel accel;
    sl_scene_accel_options ao = {8, 1, NULL};
    assert_int_equal(sl_scene_accel_create(s, &ao, &accel, &err), SL_OK);
    sl_culler_params params = {NULL, accel};
    sl_culler c = NULL;
    assert_int_equal(sl_culler_create_with("vfc", s, NULL, &params, NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "leaf_size"));
    assert_int_equal(sl_culler_create_with("hzb", s, "leaf_size=4", &params, NULL, &c, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "hzb"));
    assert_int_equal(sl_culler_create_with("vfc", s, "leaf_size=8", &params, NULL, &c, &err), SL_OK);
    sl_culler_destroy(c);
    /* methods without an object BVH ignore the handle */
    assert_int_equal(sl_culler_create_with("cullmap", s, NULL, &params, NULL, &c, &err), SL_OK);
    sl_culler_destroy(c);
    c = NULL;
    assert_int_equal(sl_culler_create_with("vfc", other, "leaf_size=8", &params, NULL, &c, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "another scene"));
    assert_null(c);
    ao.leaf_size = 17;
    sl_scene_accel bad;
    assert_int_equal(sl_scene_accel_create(s, &ao, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_accel_destroy(accel);
    sl_scene_destroy(s);
    sl_scene_destroy(other);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_threads_same_ids),
        cmocka_unit_test(test_memory_one_tree),
        cmocka_unit_test(test_moving_objects),
        cmocka_unit_test(test_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

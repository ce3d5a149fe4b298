/* The reentrant cell-set query: sl_pvs_cursor. Several threads (pthreads), each with its own cursor
 * over one sl_pvs, read the sets of every cell in their own shuffled order (so that each thread
 * switches blocks all the time) and must get exactly what was written and what the single-thread
 * sl_pvs_cell_set answers; a cursor's errors are those of sl_pvs_cell_set. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/pvs.h"
#include "support/city_views.h"

#define NCELL 200 /* seven blocks of 32, the last partial */
#define NOBJ 3000
#define NTHREAD 4

static char g_dir[256];
static uint64_t g_off[NCELL + 1];
static uint32_t *g_ids;
static sl_pvs g_pvs;

/* NCELL unit cells in a row (tests/support/city_views.h) */
static sl_viewcells make_cells(void)
{
    sl_viewcells vc = sl_test_row_cells(NCELL, NULL);
    assert_non_null(vc);
    return vc;
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_pvs_cursor_XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    g_ids = malloc((size_t)NCELL * NOBJ * sizeof *g_ids);
    sl_rng r;
    sl_rng_seed(&r, 29, 0);
    uint64_t at = 0;
    for (int c = 0; c < NCELL; c++) {
        g_off[c] = at;
        uint32_t pct = c == 0 ? 0 : c == 1 ? 100 : sl_rng_below(&r, 60);
        for (uint32_t o = 0; o < NOBJ; o++)
            if (sl_rng_below(&r, 100) < pct)
                g_ids[at++] = o;
    }
    g_off[NCELL] = at;
    char path[300];
    snprintf(path, sizeof path, "%s/cells.slpvs", g_dir);
    sl_viewcells vc = make_cells();
    sl_error err;
    sl_status st = sl_pvs_write(path, vc, NOBJ, 7, g_off, g_ids, NULL, &err);
    sl_viewcells_destroy(vc);
    if (st != SL_OK || sl_pvs_load(path, NULL, &g_pvs, &err) != SL_OK)
        return -1;
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    sl_pvs_destroy(g_pvs);
    free(g_ids);
    char path[300];
    snprintf(path, sizeof path, "%s/cells.slpvs", g_dir);
    unlink(path);
    rmdir(g_dir);
    return 0;
}

/* The single-thread answer agrees with what was written. */
static void test_single_thread(void **state)
{
    (void)state;
    uint32_t *ids = malloc(NOBJ * sizeof *ids);
    sl_error err;
    for (uint32_t c = 0; c < NCELL; c++) {
        uint32_t n = 0;
        assert_int_equal(sl_pvs_cell_set(g_pvs, c, ids, NOBJ, &n, &err), SL_OK);
        assert_int_equal(n, g_off[c + 1] - g_off[c]);
        assert_memory_equal(ids, g_ids + g_off[c], (size_t)n * sizeof *ids);
    }
    free(ids);
}

typedef struct worker {
    uint64_t seed;
    uint32_t passes;
    uint32_t mismatches, failures, queries;
} worker;

static void *run_worker(void *arg)
{
    worker *w = arg;
    sl_pvs_cursor cur;
    sl_error err;
    if (sl_pvs_cursor_create(g_pvs, &cur, &err) != SL_OK) {
        w->failures++;
        return NULL;
    }
    uint32_t *ids = malloc(NOBJ * sizeof *ids);
    uint32_t order[NCELL];
    sl_rng r;
    sl_rng_seed(&r, w->seed, 1);
    for (uint32_t pass = 0; pass < w->passes; pass++) {
        for (uint32_t i = 0; i < NCELL; i++)
            order[i] = i;
        for (uint32_t i = NCELL - 1; i > 0; i--) {
            uint32_t j = sl_rng_below(&r, i + 1), t = order[i];
            order[i] = order[j];
            order[j] = t;
        }
        for (uint32_t i = 0; i < NCELL; i++) {
            uint32_t c = order[i], n = 0;
            if (sl_pvs_cursor_cell_set(cur, c, ids, NOBJ, &n, &err) != SL_OK) {
                w->failures++;
                continue;
            }
            w->queries++;
            if (n != g_off[c + 1] - g_off[c] || memcmp(ids, g_ids + g_off[c], (size_t)n * sizeof *ids) != 0)
                w->mismatches++;
        }
    }
    free(ids);
    sl_pvs_cursor_destroy(cur);
    return NULL;
}

/* NTHREAD threads with a cursor each, and the main thread on sl_pvs_cell_set at the same time. */
static void test_threads(void **state)
{
    (void)state;
    uint32_t passes = getenv("SL_SANITIZED") ? 3 : 20;
    pthread_t th[NTHREAD];
    worker w[NTHREAD];
    for (int t = 0; t < NTHREAD; t++) {
        w[t] = (worker){.seed = 100 + (uint64_t)t, .passes = passes};
        assert_int_equal(pthread_create(&th[t], NULL, run_worker, &w[t]), 0);
    }
    uint32_t *ids = malloc(NOBJ * sizeof *ids);
    sl_error err;
    uint32_t main_mismatch = 0;
    for (uint32_t pass = 0; pass < passes; pass++)
        for (uint32_t c = 0; c < NCELL; c++) {
            uint32_t n = 0;
            assert_int_equal(sl_pvs_cell_set(g_pvs, (c * 37u + pass) % NCELL, ids, NOBJ, &n, &err), SL_OK);
            uint32_t cc = (c * 37u + pass) % NCELL;
            if (n != g_off[cc + 1] - g_off[cc] || memcmp(ids, g_ids + g_off[cc], (size_t)n * sizeof *ids) != 0)
                main_mismatch++;
        }
    free(ids);
    for (int t = 0; t < NTHREAD; t++) {
        assert_int_equal(pthread_join(th[t], NULL), 0);
        assert_int_equal(w[t].failures, 0);
        assert_int_equal(w[t].queries, passes * NCELL);
        assert_int_equal(w[t].mismatches, 0);
    }
    assert_int_equal(main_mismatch, 0);
}

/* Two cursors in one thread keep their own blocks; errors are those of sl_pvs_cell_set. */
static void test_cursor_errors(void **state)
{
    (void)state;
    sl_pvs_cursor a, b;
    sl_error err;
    assert_int_equal(sl_pvs_cursor_create(NULL, &a, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_cursor_create(g_pvs, &a, &err), SL_OK);
    assert_int_equal(sl_pvs_cursor_create(g_pvs, &b, &err), SL_OK);
    uint32_t *ids = malloc(NOBJ * sizeof *ids);
    for (uint32_t k = 0; k < NCELL; k++) {
        uint32_t c = k % 2 ? k : NCELL - 1 - k, n = 0;
        sl_pvs_cursor cur = k % 2 ? a : b;
        assert_int_equal(sl_pvs_cursor_cell_set(cur, c, ids, NOBJ, &n, &err), SL_OK);
        assert_int_equal(n, g_off[c + 1] - g_off[c]);
        assert_memory_equal(ids, g_ids + g_off[c], (size_t)n * sizeof *ids);
    }
    uint32_t n = 99;
    assert_int_equal(sl_pvs_cursor_cell_set(a, NCELL, ids, NOBJ, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(n, 0);
    assert_non_null(strstr(err.message, "does not exist"));
    assert_int_equal(sl_pvs_cursor_cell_set(a, 1, ids, 10, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "capacity"));
    assert_int_equal(sl_pvs_cursor_cell_set(NULL, 1, ids, NOBJ, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    free(ids);
    sl_pvs_cursor_destroy(a);
    sl_pvs_cursor_destroy(b);
    sl_pvs_cursor_destroy(NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_single_thread),
        cmocka_unit_test(test_threads),
        cmocka_unit_test(test_cursor_errors),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

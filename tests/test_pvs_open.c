/* Opening a .slpvs that other processes change (issue 12, §3b): by default the file is read into
 * memory, so a handle survives the file being truncated or rewritten in place afterwards (a
 * mapped file would kill the process with SIGBUS on the next access to a lost page) and keeps
 * the sets it read; mapping stays available on request; a short file, or one that shrinks while
 * it is read, is refused as "truncated: expected N bytes, file has M" with the file and offset. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include "support/file_clobber.h"
#include "core/sl_core.h"
#include "sightline/pvs.h"
#include "support/counting_alloc.h"
#include "support/city_views.h"

#define NCELL 100
#define NOBJ 6000

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

/* NCELL unit cells in a row (tests/support/city_views.h) */
static sl_viewcells make_cells(void)
{
    sl_viewcells vc = sl_test_row_cells(NCELL, NULL);
    assert_non_null(vc);
    return vc;
}

/* Pseudo-random ascending sets (seeded), big enough that the file spans many pages. */
static uint32_t *make_sets(uint64_t *off)
{
    uint32_t *ids = malloc((size_t)NCELL * NOBJ * sizeof *ids);
    sl_rng r;
    sl_rng_seed(&r, 12, 3);
    uint64_t at = 0;
    for (int c = 0; c < NCELL; c++) {
        off[c] = at;
        for (uint32_t o = 0; o < NOBJ; o++)
            if (sl_rng_below(&r, 100) < 40)
                ids[at++] = o;
    }
    off[NCELL] = at;
    return ids;
}

static void write_pvs(const char *path, uint64_t *off, uint32_t **ids)
{
    sl_viewcells vc = make_cells();
    *ids = make_sets(off);
    sl_error err;
    assert_int_equal(sl_pvs_write(path, vc, NOBJ, 0x77, off, *ids, "method=test\n", &err), SL_OK);
    sl_viewcells_destroy(vc);
}

/* Every set decodes as written and verify passes: 0, else the first cell that did not (+1).
 * No cmocka assertion: it also runs in a forked child. */
static int sets_differ(sl_pvs p, const uint64_t *off, const uint32_t *ids)
{
    sl_error err;
    uint32_t *got = malloc(NOBJ * sizeof *got);
    int bad = 0;
    for (uint32_t k = 0; k < NCELL && !bad; k++) {
        uint32_t c = NCELL - 1 - k, n = 0; /* last first: a lost page of a mapping faults at once */
        if (sl_pvs_cell_set(p, c, got, NOBJ, &n, &err) != SL_OK || n != off[c + 1] - off[c] ||
            memcmp(got, ids + off[c], (size_t)n * sizeof *got) != 0)
            bad = (int)c + 1;
    }
    free(got);
    if (!bad && sl_pvs_verify(p, &err) != SL_OK)
        bad = NCELL + 1;
    return bad;
}

/* The default open survives the file being truncated and rewritten under it. The access runs in
 * a child, so that a SIGBUS (what a mapped file does) fails this test instead of killing the
 * runner. */
static void test_read_survives_rewrite(void **state)
{
    (void)state;
    char path[300], cut[300];
    path_of(path, sizeof path, "shared.slpvs");
    path_of(cut, sizeof cut, "cut.slpvs");
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    write_pvs(path, off, &ids);
    free(ids);
    write_pvs(cut, off, &ids);
    long size = sl_test_file_size(path);
    assert_true(size > 0);
    assert_true(size > 8 * 4096);
    fflush(NULL);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        /* cmocka's handlers would catch the fault in the child and carry on with the next tests */
        signal(SIGBUS, SIG_DFL);
        signal(SIGSEGV, SIG_DFL);
        sl_test_counter cnt = {0};
        sl_allocator a = sl_test_counting_allocator(&cnt);
        sl_error err;
        sl_pvs p, q;
        if (sl_pvs_load(path, &a, &p, &err) != SL_OK || sl_pvs_load(cut, &a, &q, &err) != SL_OK)
            _exit(3);
        /* one file truncated to nothing (a mapping faults), one rewritten with other bytes (a
         * mapping reads them) */
        if (truncate(cut, 0) != 0 || !sl_test_clobber_in_place(path, size))
            _exit(7);
        /* blocks are decoded (and their checksums checked) only now */
        if (sets_differ(q, off, ids) || sets_differ(p, off, ids))
            _exit(6);
        sl_pvs_info in;
        sl_pvs_get_info(p, &in);
        if (in.file_size != (uint64_t)size || in.cell_count != NCELL)
            _exit(4);
        sl_pvs_destroy(p);
        sl_pvs_destroy(q);
        _exit(cnt.live == 0 ? 0 : 5);
    }
    int status = 0;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status))
        fail_msg("the reader died of signal %d after the file was rewritten in place", WTERMSIG(status));
    assert_true(WIFEXITED(status));
    if (WEXITSTATUS(status) != 0)
        fail_msg("the reader exited with %d (6: the sets it read changed with the file)", WEXITSTATUS(status));
    free(ids);
}

/* Mapping is still there on request (and reads the same sets); unknown flags are refused. */
static void test_map_on_request(void **state)
{
    (void)state;
    char path[300];
    path_of(path, sizeof path, "mapped.slpvs");
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    write_pvs(path, off, &ids);
    sl_error err;
    sl_pvs p;
    assert_int_equal(sl_pvs_open(path, SL_PVS_OPEN_MAP, NULL, &p, &err), SL_OK);
    assert_int_equal(sets_differ(p, off, ids), 0);
    sl_pvs_destroy(p);
    assert_int_equal(sl_pvs_open(path, 0, NULL, &p, &err), SL_OK);
    assert_int_equal(sets_differ(p, off, ids), 0);
    sl_pvs_destroy(p);
    assert_int_equal(sl_pvs_open(path, 1u << 7, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(p);
    free(ids);
}

/* A file cut short says so, with the file, the offset and both sizes, in both modes. */
static void test_truncated_message(void **state)
{
    (void)state;
    char path[300];
    path_of(path, sizeof path, "short.slpvs");
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    write_pvs(path, off, &ids);
    long size = sl_test_file_size(path);
    assert_true(size > 0);
    assert_int_equal(truncate(path, size / 2), 0);
    for (int m = 0; m < 2; m++) {
        sl_error err;
        sl_pvs p;
        assert_int_equal(sl_pvs_open(path, m ? SL_PVS_OPEN_MAP : 0, NULL, &p, &err), SL_ERROR_FORMAT);
        char want[400];
        snprintf(want, sizeof want, "%s: offset 40: truncated: expected %ld bytes, file has %ld", path, size, size / 2);
        if (!strstr(err.message, want))
            fail_msg("expected \"%s\", got \"%s\"", want, err.message);
    }
    assert_int_equal(truncate(path, 10), 0);
    sl_error err;
    sl_pvs p;
    assert_int_equal(sl_pvs_load(path, NULL, &p, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "offset 0: truncated"));
    assert_int_equal(truncate(path, 0), 0);
    assert_int_equal(sl_pvs_load(path, NULL, &p, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "offset 0: truncated"));
    free(ids);
}

/* An allocator that truncates the file when the reader allocates its buffer: the file shrinks
 * between fstat and read, as when another process rewrites it while we read it. */
typedef struct shrink_user {
    const char *path;
    size_t trigger;
    long keep;
    int fired;
} shrink_user;

static void *shrink_alloc(void *user, size_t size, size_t align)
{
    shrink_user *u = user;
    if (size == u->trigger && !u->fired) {
        u->fired = 1;
        assert_int_equal(truncate(u->path, u->keep), 0);
    }
    return sl_default_allocator()->alloc(NULL, size, align);
}
static void *shrink_realloc(void *user, void *p, size_t o, size_t n, size_t align)
{
    (void)user;
    return sl_default_allocator()->realloc(NULL, p, o, n, align);
}
static void shrink_free(void *user, void *p, size_t size)
{
    (void)user;
    sl_default_allocator()->free(NULL, p, size);
}

static void test_shrinks_while_read(void **state)
{
    (void)state;
    char path[300];
    path_of(path, sizeof path, "shrinking.slpvs");
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    write_pvs(path, off, &ids);
    long size = sl_test_file_size(path);
    assert_true(size > 0);
    shrink_user u = {path, (size_t)size, 8192, 0};
    sl_allocator a = {shrink_alloc, shrink_realloc, shrink_free, &u};
    sl_error err;
    sl_pvs p;
    assert_int_equal(sl_pvs_load(path, &a, &p, &err), SL_ERROR_FORMAT);
    assert_int_equal(u.fired, 1);
    char want[400];
    snprintf(want, sizeof want, "%s: offset 8192: truncated while reading: expected %ld bytes, file has 8192", path,
             size);
    if (!strstr(err.message, want))
        fail_msg("expected \"%s\", got \"%s\"", want, err.message);
    free(ids);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "%s/sl_pvs_open_XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    const char *names[] = {"shared.slpvs", "cut.slpvs", "mapped.slpvs", "short.slpvs", "shrinking.slpvs"};
    char p[300];
    for (size_t i = 0; i < SL_COUNTOF(names); i++) {
        path_of(p, sizeof p, names[i]);
        unlink(p);
    }
    rmdir(g_dir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_read_survives_rewrite),
        cmocka_unit_test(test_map_on_request),
        cmocka_unit_test(test_truncated_message),
        cmocka_unit_test(test_shrinks_while_read),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

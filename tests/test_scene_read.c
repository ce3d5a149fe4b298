/* A loaded .slscene and the file under it (issue 12, §3b): by default sl_scene_load reads the
 * file into memory, so a scene survives its file being truncated or rewritten in place by another
 * process (a mapped scene dies of SIGBUS on the next access to a lost page, or reads the other
 * file's bytes); mapping stays available with sl_load_options.map, and the scene's arrays are
 * then borrowed from the mapping. */
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
#include "scene/scene_internal.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/slscene.h"
#include "support/counting_alloc.h"

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

/* Save the tiny city twice; return its scene key (which reads every array of the scene). */
static uint64_t save_city(const char *a, const char *b)
{
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    assert_int_equal(sl_scene_save(s, a, &err), SL_OK);
    assert_int_equal(sl_scene_save(s, b, &err), SL_OK);
    uint64_t k = sl_pvs_scene_key(s);
    sl_scene_destroy(s);
    return k;
}

/* Load (default options), then one file truncated to nothing and the other rewritten in place;
 * every array of both scenes is read afterwards (the scene key) in a child. */
static void test_read_survives_rewrite(void **state)
{
    (void)state;
    char a[300], b[300];
    path_of(a, sizeof a, "cut.slscene");
    path_of(b, sizeof b, "rewritten.slscene");
    uint64_t key = save_city(a, b);
    long size = sl_test_file_size(b);
    assert_true(size > 0);
    assert_true(size > 64 * 4096);
    fflush(NULL);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        /* cmocka's handlers would catch the fault in the child and carry on with the next tests */
        signal(SIGBUS, SIG_DFL);
        signal(SIGSEGV, SIG_DFL);
        sl_test_counter cnt = {0};
        sl_allocator al = sl_test_counting_allocator(&cnt);
        sl_error err;
        sl_scene sa, sb;
        if (sl_scene_load(a, NULL, &al, &sa, &err) != SL_OK || sl_scene_load(b, NULL, &al, &sb, &err) != SL_OK)
            _exit(3);
        if (truncate(a, 0) != 0 || !sl_test_clobber_in_place(b, size))
            _exit(7);
        if (sl_pvs_scene_key(sa) != key || sl_pvs_scene_key(sb) != key)
            _exit(6);
        sl_scene_destroy(sa);
        sl_scene_destroy(sb);
        _exit(cnt.live == 0 ? 0 : 5);
    }
    int status = 0;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status))
        fail_msg("the scene's reader died of signal %d after its file was cut or rewritten in place",
                 WTERMSIG(status));
    assert_true(WIFEXITED(status));
    if (WEXITSTATUS(status) != 0)
        fail_msg("the reader exited with %d (6: the scene changed with its file)", WEXITSTATUS(status));
    unlink(a);
    unlink(b);
}

/* Mapping on request: the bulk arrays are borrowed from the mapping; read by default: owned. */
static void test_map_on_request(void **state)
{
    (void)state;
    char a[300], b[300];
    path_of(a, sizeof a, "m1.slscene");
    path_of(b, sizeof b, "m2.slscene");
    uint64_t key = save_city(a, b);
    sl_error err;
    sl_load_options lo;
    memset(&lo, 0, sizeof lo);
    sl_scene s;
    assert_int_equal(sl_scene_load(a, &lo, NULL, &s, &err), SL_OK);
    assert_null(s->mapping.data);
    assert_true(s->positions.cap > 0);
    assert_true(sl_pvs_scene_key(s) == key);
    sl_scene_destroy(s);
    assert_int_equal(sl_scene_open(a, NULL, NULL, &s, &err), SL_OK);
    assert_null(s->mapping.data);
    sl_scene_destroy(s);
    lo.map = true;
    assert_int_equal(sl_scene_load(a, &lo, NULL, &s, &err), SL_OK);
    assert_non_null(s->mapping.data);
    assert_true(s->positions.cap == 0);
    assert_true(sl_pvs_scene_key(s) == key);
    sl_scene_destroy(s);
    lo.no_mmap = true; /* the old switch still forces a read */
    assert_int_equal(sl_scene_load(a, &lo, NULL, &s, &err), SL_OK);
    assert_null(s->mapping.data);
    sl_scene_destroy(s);
    unlink(a);
    unlink(b);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "%s/sl_scene_read_XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
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
        cmocka_unit_test(test_read_survives_rewrite),
        cmocka_unit_test(test_map_on_request),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

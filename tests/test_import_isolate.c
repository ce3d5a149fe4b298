/* assimp in a child process (src/import/import_isolate.c): the isolated import gives the scene
 * the in-process import gives, byte for byte once saved; a child that crashes, exits, hangs or
 * is cancelled fails the import with its reason, leaves no child behind and leaks nothing in
 * this process; errors found inside the child come back unchanged; progress comes through.
 * The misbehaving children are made with the allocator hooks: the import allocates through the
 * caller's allocator in the child's copy of this process, so an allocator that crashes when it
 * runs in another process than the test's crashes exactly the child. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"
#include "support/counting_alloc.h"

#define DATA SL_SOURCE_DIR "/tests/data/"

const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libassimp.so\n"; }

/* ---- helpers ---- */

static uint8_t *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    assert_int_equal(fseek(f, 0, SEEK_END), 0);
    long n = ftell(f);
    assert_true(n >= 0);
    rewind(f);
    uint8_t *p = malloc((size_t)n + 1);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return p;
}

/* The bytes of the scene saved as .slscene. */
static uint8_t *saved(sl_scene s, const char *name, size_t *size)
{
    char path[512];
    snprintf(path, sizeof path, "%s/test_import_isolate.%ld.%s.slscene", SL_BINARY_DIR, (long)getpid(), name);
    sl_error err;
    assert_int_equal(sl_scene_save(s, path, &err), SL_OK);
    uint8_t *p = read_file(path, size);
    unlink(path);
    return p;
}

/* No child of the test is left, finished or not. */
static void no_children(void)
{
    int status;
    pid_t p = waitpid(-1, &status, WNOHANG);
    if (p != -1 || errno != ECHILD)
        fail_msg("a child process is left behind (waitpid: %d)", (int)p);
}

/* An allocator that misbehaves in any process but the test's. */
typedef enum { ACT_SEGV, ACT_EXIT, ACT_HANG } child_act;
typedef struct bad_alloc {
    pid_t test_pid;
    child_act act;
    sl_test_counter count;
    sl_allocator inner;
} bad_alloc;

static void misbehave(bad_alloc *b)
{
    if (getpid() == b->test_pid)
        return;
    if (b->act == ACT_SEGV)
        raise(SIGSEGV);
    else if (b->act == ACT_EXIT)
        _exit(7);
    else
        for (;;)
            pause();
}

static void *bad_alloc_fn(void *user, size_t size, size_t align)
{
    bad_alloc *b = user;
    misbehave(b);
    return b->inner.alloc(b->inner.user, size, align);
}

static void *bad_realloc_fn(void *user, void *ptr, size_t old_size, size_t new_size, size_t align)
{
    bad_alloc *b = user;
    misbehave(b);
    return b->inner.realloc(b->inner.user, ptr, old_size, new_size, align);
}

static void bad_free_fn(void *user, void *ptr, size_t size)
{
    bad_alloc *b = user;
    b->inner.free(b->inner.user, ptr, size);
}

static sl_allocator make_bad(bad_alloc *b, child_act act)
{
    memset(b, 0, sizeof *b);
    b->test_pid = getpid();
    b->act = act;
    b->inner = sl_test_counting_allocator(&b->count);
    sl_allocator a = {bad_alloc_fn, bad_realloc_fn, bad_free_fn, b};
    return a;
}

static double seconds_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* ---- tests ---- */

/* The child's scene is the in-process scene: same bytes once saved, for OBJ groups, glTF
 * instancing, PLY and the splitter; the parent's allocations are all returned. */
static void test_same_scene(void **state)
{
    (void)state;
    static const char *files[] = {DATA "groups.obj", DATA "instanced.gltf", DATA "quads.ply"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++)
        for (uint32_t split = 0; split <= 1; split++) {
            sl_import_options o = sl_import_defaults();
            o.split_triangles = split;
            sl_test_counter c1 = {0}, c2 = {0};
            sl_allocator a1 = sl_test_counting_allocator(&c1), a2 = sl_test_counting_allocator(&c2);
            sl_scene here = NULL, there = NULL;
            sl_error err;
            o.in_process = true;
            assert_int_equal(sl_import_assimp(files[i], &o, &a1, &here, &err), SL_OK);
            o.in_process = false;
            if (sl_import_assimp(files[i], &o, &a2, &there, &err) != SL_OK)
                fail_msg("%s: %s", files[i], err.message);
            size_t n1, n2;
            uint8_t *b1 = saved(here, "here", &n1), *b2 = saved(there, "there", &n2);
            if (n1 != n2 || memcmp(b1, b2, n1) != 0)
                fail_msg("%s (split %u): the isolated import differs from the in-process one (%zu vs %zu bytes)", files[i],
                         split, n2, n1);
            free(b1);
            free(b2);
            sl_scene_destroy(here);
            sl_scene_destroy(there);
            assert_int_equal(c1.live, 0);
            assert_int_equal(c2.live, 0);
            assert_true(c2.calls > 0); /* the scene read back was built with the caller's allocator */
        }
    no_children();
}

/* A child killed by a signal: a format error naming the signal; nothing imported, nothing left. */
static void test_child_crash(void **state)
{
    (void)state;
    bad_alloc b;
    sl_allocator a = make_bad(&b, ACT_SEGV);
    sl_scene s = (sl_scene)(uintptr_t)1;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", NULL, &a, &s, &err), SL_ERROR_FORMAT);
    assert_null(s);
    assert_non_null(strstr(err.message, "groups.obj"));
    assert_non_null(strstr(err.message, "assimp crashed"));
    assert_non_null(strstr(err.message, "signal 11"));
    assert_non_null(strstr(err.message, "nothing was imported"));
    assert_int_equal(b.count.live, 0);
    no_children();
}

/* A child that exits without a result: its status in the message. */
static void test_child_exit(void **state)
{
    (void)state;
    bad_alloc b;
    sl_allocator a = make_bad(&b, ACT_EXIT);
    sl_scene s = NULL;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", NULL, &a, &s, &err), SL_ERROR_FORMAT);
    assert_null(s);
    assert_non_null(strstr(err.message, "status 7"));
    no_children();
}

/* A child that hangs is stopped at the time limit; without the limit the call would not return. */
static void test_timeout(void **state)
{
    (void)state;
    bad_alloc b;
    sl_allocator a = make_bad(&b, ACT_HANG);
    sl_import_options o = sl_import_defaults();
    o.timeout_ms = 300;
    sl_scene s = NULL;
    sl_error err;
    double t0 = seconds_now();
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &o, &a, &s, &err), SL_ERROR_LIMIT);
    double spent = seconds_now() - t0;
    assert_null(s);
    assert_non_null(strstr(err.message, "300 ms"));
    if (spent < 0.25 || spent > 20)
        fail_msg("stopped after %.2f s for a limit of 0.3 s", spent);
    no_children();
}

/* Progress reaches the caller from the child, and returning false stops the child. */
typedef struct progress_log {
    int calls, reading;
    int cancel_after; /* <0: never */
} progress_log;

static bool log_progress(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)done;
    (void)total;
    progress_log *l = user;
    l->calls++;
    if (strcmp(stage, "import: reading") == 0)
        l->reading++;
    return l->cancel_after < 0 || l->calls <= l->cancel_after;
}

static void test_progress_and_cancel(void **state)
{
    (void)state;
    sl_import_options o = sl_import_defaults();
    progress_log l = {0, 0, -1};
    o.progress.fn = log_progress;
    o.progress.user = &l;
    sl_scene s = NULL;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &o, NULL, &s, &err), SL_OK);
    sl_scene_destroy(s);
    assert_true(l.reading >= 2); /* the child's "reading" 0/1 and 1/1 */

    /* cancelled at the first report, with a child that would otherwise never end */
    bad_alloc b;
    sl_allocator a = make_bad(&b, ACT_HANG);
    progress_log c = {0, 0, 0};
    o.progress.user = &c;
    s = NULL;
    double t0 = seconds_now();
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &o, &a, &s, &err), SL_ERROR_CANCELLED);
    assert_true(seconds_now() - t0 < 20);
    assert_null(s);
    assert_int_equal(c.calls, 1);
    no_children();
}

/* A failure found inside the child (assimp's own refusal, our checks after assimp) comes back
 * with the status and message the in-process import gives. */
static void test_child_error_forwarded(void **state)
{
    (void)state;
    static const char *files[] = {DATA "nan.obj", DATA "ply_empty_face.ply"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        sl_import_options o = sl_import_defaults();
        sl_scene s1 = NULL, s2 = NULL;
        sl_error e1, e2;
        o.in_process = true;
        sl_status st1 = sl_import_assimp(files[i], &o, NULL, &s1, &e1);
        o.in_process = false;
        sl_status st2 = sl_import_assimp(files[i], &o, NULL, &s2, &e2);
        assert_int_not_equal(st1, SL_OK);
        assert_int_equal(st2, st1);
        assert_string_equal(e2.message, e1.message);
        assert_null(s2);
    }
    no_children();
}

/* A program that ignores SIGCHLD cannot wait for its children: the result records decide. */
static void test_sigchld_ignored(void **state)
{
    (void)state;
    struct sigaction old, ign;
    memset(&ign, 0, sizeof ign);
    ign.sa_handler = SIG_IGN;
    sigaction(SIGCHLD, &ign, &old);
    sl_scene s = NULL;
    sl_error err;
    sl_status st = sl_import_assimp(DATA "groups.obj", NULL, NULL, &s, &err);
    sigaction(SIGCHLD, &old, NULL);
    if (st != SL_OK)
        fail_msg("%s", err.message);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_same_scene),          cmocka_unit_test(test_child_crash),
        cmocka_unit_test(test_child_exit),          cmocka_unit_test(test_timeout),
        cmocka_unit_test(test_progress_and_cancel), cmocka_unit_test(test_child_error_forwarded),
        cmocka_unit_test(test_sigchld_ignored),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

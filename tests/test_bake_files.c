/* The files a bake keeps beside its output: the journal (OUT.ckpt) and its lock (OUT.ckpt.lock).
 * - The bake of `bench` and `demo` (tools/pvs_along.c, compiled in here) discards a journal left
 *   by an earlier run only under the bake lock: while another bake of the same file runs, it is
 *   told "another bake of FILE is running (pid N)" and that bake's journal stays.
 * - Neither file is ever anything but a regular file: a lock that is a symbolic link (to a file
 *   that must not be truncated), a FIFO or a folder, and a journal that became a FIFO after the
 *   bake began (it would have blocked open(2) for ever) are refused with what they are, and left
 *   where they are. A journal named through a symbolic link is the file the link ends at.
 * - The journal fuzzer's seeds are journals of the current version.
 * Every bake here is of one or two cells of the tiny city; SIGALRM bounds a blocked open(2). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "region/pvs_internal.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"

/* the bake along a path of the demo and the bench, as the command runs it */
#include "../tools/pvs_along.c"
#include "../tools/tool.c"

#define BOUND_SECONDS 60

/* The command's choice of the cells near the path (tools/cmd_pvs.c) is not under test here: the
 * first cell keeps every bake to one cell. */
sl_status cli_viewcells_along(sl_viewcells cells, sl_path path, float radius, sl_viewcells *out, uint32_t *far_cameras,
                              sl_error *err)
{
    (void)path, (void)radius;
    if (far_cameras)
        *far_cameras = 0;
    return sl_viewcells_create(sl_viewcells_data(cells), 1, NULL, out, err);
}

static char g_dir[64];

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_bake_files_XXXXXX");
    alarm(BOUND_SECONDS);
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    alarm(0);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf -- '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

static void in_dir(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

static void assert_text(const char *path, const char *text)
{
    char buf[256] = "";
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    assert_string_equal(buf, text);
}

static bool is_kind(const char *path, unsigned kind)
{
    struct stat st;
    return lstat(path, &st) == 0 && (st.st_mode & S_IFMT) == kind;
}

/* The tiny city and its first n street cells. */
static void tiny_city(sl_scene *s, sl_viewcells *one, uint32_t n)
{
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, s, &err), SL_OK);
    sl_viewcells all;
    assert_int_equal(sl_viewcells_from_streets(*s, NULL, &all, &err), SL_OK);
    assert_true(sl_viewcells_count(all) >= n);
    assert_int_equal(sl_viewcells_create(sl_viewcells_data(all), n, NULL, one, &err), SL_OK);
    sl_viewcells_destroy(all);
}

/* Hold the lock of `file`'s bake as a running bake does (another open file description: flock
 * keeps it from a second one in this process too), with its pid and output. */
static int hold_lock(const char *file)
{
    char lock[320];
    snprintf(lock, sizeof lock, "%.290s.ckpt.lock", file);
    int fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    assert_true(fd >= 0);
    assert_int_equal(flock(fd, LOCK_EX | LOCK_NB), 0);
    assert_true(dprintf(fd, "%ld\n%s\n", (long)getpid(), file) > 0);
    return fd;
}

static void release_lock(const char *file, int fd)
{
    char lock[320];
    snprintf(lock, sizeof lock, "%.290s.ckpt.lock", file);
    unlink(lock);
    close(fd);
}

static void test_along_respects_lock(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells one;
    tiny_city(&s, &one, 1);
    sl_error err;
    char walk[300], file[300], ckpt[320];
    in_dir(walk, sizeof walk, "walk.txt");
    in_dir(file, sizeof file, "walk.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", file);
    write_text(walk, "# sightline-path 1\n0 0 0 1.7 0 0 0\n");
    sl_path path;
    assert_int_equal(sl_path_load(walk, NULL, &path, &err), SL_OK);
    sl_progress none = {0};
    cli_pvs_along pa;

    /* another bake of the file runs: refused with its pid, and its journal stays */
    write_text(ckpt, "the running bake's journal");
    int lock = hold_lock(file);
    sl_status st = cli_pvs_bake_along(s, path, 0, UINT32_MAX, file, &none, &pa, &err);
    assert_int_not_equal(st, SL_OK);
    char running[400];
    snprintf(running, sizeof running, "another bake of %s is running (pid %ld)", file, (long)getpid());
    if (!strstr(err.message, running))
        fail_msg("'%s' lacks '%s'", err.message, running);
    if (access(ckpt, F_OK) != 0)
        fail_msg("the journal of the running bake was removed");
    assert_text(ckpt, "the running bake's journal");
    release_lock(file, lock);

    /* no bake runs: a journal left by an earlier run is discarded, and the bake runs */
    if (cli_pvs_bake_along(s, path, 0, UINT32_MAX, file, &none, &pa, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_string_equal(pa.why, "");
    assert_int_equal(pa.cells, 1);
    assert_int_equal(access(ckpt, F_OK), -1);
    sl_pvs pvs;
    assert_int_equal(sl_pvs_open(file, 0, NULL, &pvs, &err), SL_OK);
    sl_pvs_destroy(pvs);

    /* fresh and resume exclude each other */
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = CLI_PVS_ALONG_METHOD;
    bo.fresh = bo.resume = true;
    assert_int_equal(sl_pvs_build(s, one, file, &bo, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_viewcells_destroy(one);
    sl_path_destroy(path);
    sl_scene_destroy(s);
}

/* The progress callback runs once the bake has begun (lock taken, journal looked at) and before
 * the first cell is stored: it puts a FIFO where the journal will be created. */
static bool fifo_journal(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)stage, (void)total;
    const char *ckpt = user;
    if (done == 0 && access(ckpt, F_OK) != 0)
        assert_int_equal(mkfifo(ckpt, 0644), 0);
    return true;
}

static void expect_refused(sl_scene s, sl_viewcells one, const char *out, const sl_pvs_build_options *bo,
                           const char *what)
{
    sl_error err;
    sl_status st = sl_pvs_build(s, one, out, bo, NULL, &err);
    assert_int_not_equal(st, SL_OK);
    if (!strstr(err.message, what))
        fail_msg("'%s' lacks '%s'", err.message, what);
}

static void test_journal_and_lock_regular(void **state)
{
    (void)state;
    sl_scene s;
    sl_viewcells one;
    tiny_city(&s, &one, 2);
    char out[300], ckpt[320], lock[330], victim[300];
    in_dir(out, sizeof out, "a.slpvs");
    snprintf(ckpt, sizeof ckpt, "%s.ckpt", out);
    snprintf(lock, sizeof lock, "%s.lock", ckpt);
    in_dir(victim, sizeof victim, "victim.txt");
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = CLI_PVS_ALONG_METHOD;
    bo.threads = 1;

    /* a lock that is a symbolic link: not followed (the file it names is not truncated) */
    write_text(victim, "keep me");
    assert_int_equal(symlink(victim, lock), 0);
    expect_refused(s, one, out, &bo, "the bake lock: it is a symbolic link, not a regular file");
    assert_text(victim, "keep me");
    assert_true(is_kind(lock, S_IFLNK));
    unlink(lock);
    /* a FIFO, a folder */
    assert_int_equal(mkfifo(lock, 0644), 0);
    expect_refused(s, one, out, &bo, "the bake lock: it is a FIFO, not a regular file");
    assert_true(is_kind(lock, S_IFIFO));
    unlink(lock);
    assert_int_equal(mkdir(lock, 0755), 0);
    expect_refused(s, one, out, &bo, "the bake lock: it is a directory, not a regular file");
    rmdir(lock);
    assert_int_equal(access(out, F_OK), -1);

    /* a journal that became a FIFO after the bake began: refused, not waited for, and left */
    bo.progress.fn = fifo_journal;
    bo.progress.user = ckpt;
    expect_refused(s, one, out, &bo, "the checkpoint: it is a FIFO, not a regular file");
    assert_true(is_kind(ckpt, S_IFIFO));
    assert_int_equal(access(lock, F_OK), -1);
    /* a FIFO already there is refused as an input (it would block a read) */
    bo.progress.fn = NULL;
    expect_refused(s, one, out, &bo, "not a regular file (a FIFO)");
    unlink(ckpt);

    /* a journal named through a symbolic link: the file it ends at, its lock beside that file */
    char link[300], real[300], real_lock[320];
    in_dir(link, sizeof link, "link.ckpt");
    in_dir(real, sizeof real, "real.ckpt");
    snprintf(real_lock, sizeof real_lock, "%s.lock", real);
    assert_int_equal(symlink("real.ckpt", link), 0); /* dangling, relative to its folder */
    bo.checkpoint = link;
    bo.stop_after = 1;
    sl_error err;
    assert_int_equal(sl_pvs_build(s, one, out, &bo, NULL, &err), SL_ERROR_CANCELLED);
    assert_true(is_kind(link, S_IFLNK));
    assert_true(is_kind(real, S_IFREG));
    bo.stop_after = 0;
    bo.resume = true;
    sl_pvs_build_stats st;
    if (sl_pvs_build(s, one, out, &bo, &st, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_int_equal(st.cells_resumed, 1);
    assert_int_equal(st.cells, 2);
    assert_true(is_kind(link, S_IFLNK));
    assert_int_equal(access(real, F_OK), -1);
    assert_int_equal(access(real_lock, F_OK), -1);
    sl_viewcells_destroy(one);
    sl_scene_destroy(s);
}

/* The journal fuzzer's seeds (fuzz/seeds/journal, made as its README says) are journals of the
 * current version that the reader takes whole, with the cells the README lists. */
static void test_journal_seeds(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        uint32_t cells;
        bool torn;
    } seeds[] = {{"two_cells.ckpt", 2, false},
                 {"all_cells.ckpt", 4, false},
                 {"adjustable_one_cell.ckpt", 1, false},
                 {"torn_record.ckpt", 1, true},
                 {"header_only.ckpt", 0, false}};
    for (size_t i = 0; i < sizeof seeds / sizeof seeds[0]; i++) {
        char path[512];
        snprintf(path, sizeof path, "%s/fuzz/seeds/journal/%s", SL_SOURCE_DIR, seeds[i].name);
        uint8_t *data;
        size_t size;
        sl_error err;
        assert_int_equal(sl_file_read_all(NULL, path, &data, &size, &err), SL_OK);
        assert_true(size >= 64 && size < 20000);
        uint32_t cells, objects;
        uint64_t key;
        memcpy(&cells, data + 12, 4);
        memcpy(&objects, data + 16, 4);
        memcpy(&key, data + 24, 8);
        size_t valid;
        uint32_t resumed;
        if (sl_bake_journal_check(data, size, cells, objects, key, NULL, &valid, &resumed, &err) != SL_OK)
            fail_msg("%s: %s", seeds[i].name, err.message);
        if (resumed != seeds[i].cells || (valid == size) == seeds[i].torn)
            fail_msg("%s: %u cells, %zu of %zu bytes valid", seeds[i].name, resumed, valid, size);
        sl_free(NULL, data, size);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_along_respects_lock, setup, teardown),
        cmocka_unit_test_setup_teardown(test_journal_and_lock_regular, setup, teardown),
        cmocka_unit_test(test_journal_seeds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

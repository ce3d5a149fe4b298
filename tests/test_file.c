/* The file helpers of src/core/file.c against what is not a plain file (issue 12, §3): a FIFO read
 * as an input is refused at once instead of blocking open(2); an output that is a FIFO, a device or
 * a symbolic link is written through or behind the link, never replaced by a regular file; a
 * directory is refused; stale temporaries of killed writers are removed by the next write, and
 * nothing else is. Every wait is bounded: an alarm ends a test that blocks. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/path.h"
#include "sightline/pvs.h"
#include "sightline/slscene.h"

/* A blocked open(2) ends the test process (SIGALRM's default action) instead of hanging CTest. */
#define BOUND_SECONDS 10

static char g_dir[64];

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_file_XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    DIR *d = opendir(g_dir);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            char p[512];
            snprintf(p, sizeof p, "%s/%s", g_dir, e->d_name);
            if (unlink(p) != 0)
                rmdir(p);
        }
        closedir(d);
    }
    rmdir(g_dir);
    return 0;
}

static void in_dir(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/%s", g_dir, name);
}

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

static void assert_content(const char *path, const char *text)
{
    uint8_t *data;
    size_t size;
    sl_error err;
    assert_int_equal(sl_file_read_all(NULL, path, &data, &size, &err), SL_OK);
    assert_int_equal(size, strlen(text));
    assert_memory_equal(data, text, size);
    sl_free(NULL, data, size);
}

static sl_status write_text(const char *path, const char *text, sl_error *err)
{
    sl_atomic_file f;
    sl_status st = sl_atomic_open(NULL, path, &f, err);
    if (st != SL_OK)
        return st;
    sl_atomic_write(&f, text, strlen(text));
    return sl_atomic_commit(&f, err);
}

static void assert_no_temporaries(void)
{
    DIR *d = opendir(g_dir);
    assert_non_null(d);
    struct dirent *e;
    while ((e = readdir(d)))
        if (strstr(e->d_name, ".tmp."))
            fail_msg("temporary %s left", e->d_name);
    closedir(d);
}

/* Every reader entry point refuses a FIFO (no writer ever comes) without blocking. */
static void test_fifo_inputs_refused(void **state)
{
    (void)state;
    char fifo[256];
    in_dir(fifo, sizeof fifo, "in.fifo");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    alarm(BOUND_SECONDS);
    sl_error err;
    uint8_t *data;
    size_t size;
    assert_int_equal(sl_file_read_all(NULL, fifo, &data, &size, &err), SL_ERROR_IO);
    assert_non_null(strstr(err.message, "not a regular file (a FIFO)"));
    sl_mapping m;
    assert_int_equal(sl_file_map(fifo, &m, &err), SL_ERROR_IO);
    assert_non_null(strstr(err.message, "not a regular file"));
    int fd;
    assert_int_equal(sl_file_open_read(fifo, &fd, NULL, &err), SL_ERROR_IO);
    assert_int_equal(fd, -1);
    /* the public readers: a scene (mapped and read), a path file, a PVS */
    char scene_fifo[256];
    in_dir(scene_fifo, sizeof scene_fifo, "in.slscene");
    assert_int_equal(mkfifo(scene_fifo, 0600), 0);
    sl_scene scene = NULL;
    assert_int_not_equal(sl_scene_load(scene_fifo, NULL, NULL, &scene, &err), SL_OK);
    assert_non_null(strstr(err.message, "not a regular file"));
    sl_load_options lo;
    memset(&lo, 0, sizeof lo);
    lo.no_mmap = true;
    assert_int_not_equal(sl_scene_load(scene_fifo, &lo, NULL, &scene, &err), SL_OK);
    assert_non_null(strstr(err.message, "not a regular file"));
    sl_path path = NULL;
    assert_int_not_equal(sl_path_load(fifo, NULL, &path, &err), SL_OK);
    assert_non_null(strstr(err.message, "not a regular file"));
    sl_pvs pvs = NULL;
    assert_int_not_equal(sl_pvs_load(fifo, NULL, &pvs, &err), SL_OK);
    assert_non_null(strstr(err.message, "not a regular file"));
    alarm(0);
    /* a regular file still reads, and its descriptor is blocking again */
    char reg[256];
    in_dir(reg, sizeof reg, "in.txt");
    write_file(reg, "abc");
    uint64_t fsize;
    assert_int_equal(sl_file_open_read(reg, &fd, &fsize, &err), SL_OK);
    assert_int_equal(fsize, 3);
    assert_int_equal(fcntl(fd, F_GETFL) & O_NONBLOCK, 0);
    close(fd);
    assert_content(reg, "abc");
}

/* An output that is a FIFO is written through: the reader gets the bytes, the FIFO stays. */
static void test_fifo_output_written_through(void **state)
{
    (void)state;
    char fifo[256];
    in_dir(fifo, sizeof fifo, "out.fifo");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    alarm(BOUND_SECONDS);
    /* a reader first, so that the writer's open does not wait */
    int rd = open(fifo, O_RDONLY | O_NONBLOCK);
    assert_true(rd >= 0);
    sl_error err;
    sl_atomic_file f;
    assert_int_equal(sl_atomic_open(NULL, fifo, &f, &err), SL_OK);
    assert_true(f.direct);
    sl_atomic_write(&f, "through", 7);
    assert_int_equal(sl_atomic_commit(&f, &err), SL_OK);
    char buf[16] = {0};
    assert_int_equal(read(rd, buf, sizeof buf), 7);
    assert_memory_equal(buf, "through", 7);
    close(rd);
    alarm(0);
    struct stat st;
    assert_int_equal(lstat(fifo, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    /* nothing else appeared beside it */
    DIR *d = opendir(g_dir);
    struct dirent *e;
    while ((e = readdir(d)))
        assert_null(strstr(e->d_name, ".tmp."));
    closedir(d);

    /* only now that a FIFO survives: the same path for /dev/null, which must stay a device */
    assert_int_equal(write_text("/dev/null", "nothing", &err), SL_OK);
    assert_int_equal(lstat("/dev/null", &st), 0);
    assert_true(S_ISCHR(st.st_mode));
    assert_int_equal(sl_atomic_open(NULL, "/dev/null", &f, &err), SL_OK);
    assert_true(f.direct);
    sl_atomic_write(&f, "x", 1);
    sl_atomic_abort(&f); /* abort never unlinks what was written through */
    assert_int_equal(lstat("/dev/null", &st), 0);
    assert_true(S_ISCHR(st.st_mode));
}

/* A symbolic link stays a link: its target is replaced, or created for a dangling link. */
static void test_symlink_outputs(void **state)
{
    (void)state;
    char target[256], link[256], link2[256], dang[256], missing[256], dir[256];
    in_dir(target, sizeof target, "target.txt");
    in_dir(link, sizeof link, "link.txt");
    in_dir(link2, sizeof link2, "link2.txt");
    in_dir(dang, sizeof dang, "dangling.txt");
    in_dir(missing, sizeof missing, "missing.txt");
    write_file(target, "old");
    assert_int_equal(symlink("target.txt", link), 0); /* relative, like most links */
    assert_int_equal(symlink(link, link2), 0);         /* a chain, absolute */
    sl_error err;
    assert_int_equal(write_text(link2, "new", &err), SL_OK);
    struct stat st;
    assert_int_equal(lstat(link, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_int_equal(lstat(link2, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_content(target, "new");
    assert_int_equal(write_text(link, "newer", &err), SL_OK);
    assert_int_equal(lstat(link, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_content(target, "newer");
    /* dangling: the write creates the target */
    assert_int_equal(symlink("missing.txt", dang), 0);
    assert_int_equal(write_text(dang, "created", &err), SL_OK);
    assert_int_equal(lstat(dang, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_content(missing, "created");
    /* a directory is refused, named, and left alone */
    in_dir(dir, sizeof dir, "adir");
    assert_int_equal(mkdir(dir, 0755), 0);
    assert_int_equal(write_text(dir, "x", &err), SL_ERROR_IO);
    assert_non_null(strstr(err.message, "a directory"));
    assert_int_equal(lstat(dir, &st), 0);
    assert_true(S_ISDIR(st.st_mode));
    /* a link loop is an error, not a hang */
    char l1[256], l2[256];
    in_dir(l1, sizeof l1, "loop1");
    in_dir(l2, sizeof l2, "loop2");
    assert_int_equal(symlink("loop2", l1), 0);
    assert_int_equal(symlink("loop1", l2), 0);
    assert_int_equal(write_text(l1, "x", &err), SL_ERROR_IO);
    assert_int_equal(lstat(l1, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    DIR *d = opendir(g_dir);
    struct dirent *e;
    while ((e = readdir(d)))
        assert_null(strstr(e->d_name, ".tmp."));
    closedir(d);
}

/* A pid that no longer exists: a child that has exited and been reaped. */
static long dead_pid(void)
{
    pid_t p = fork();
    assert_true(p >= 0);
    if (p == 0)
        _exit(0);
    int status;
    assert_int_equal(waitpid(p, &status, 0), p);
    assert_int_equal(kill(p, 0), -1);
    return (long)p;
}

static bool exists(const char *path)
{
    struct stat st;
    return lstat(path, &st) == 0;
}

/* The next write of an output removes the temporaries of that output left by dead processes, and
 * nothing else: not those of live processes, of other outputs, of other names, nor non-files. */
static void test_stale_temporaries(void **state)
{
    (void)state;
    long dead = dead_pid();
    char out[256], stale[300], live[300], other[300], badhex[300], short_hex[300], dir_like[300], link_like[300];
    char zero_pid[300];
    in_dir(out, sizeof out, "out.bin");
    snprintf(stale, sizeof stale, "%s.tmp.%ld.0123456789abcdef", out, dead);
    snprintf(live, sizeof live, "%s.tmp.1.0123456789abcdef", out); /* init exists */
    snprintf(other, sizeof other, "%s/other.bin.tmp.%ld.0123456789abcdef", g_dir, dead);
    snprintf(badhex, sizeof badhex, "%s.tmp.%ld.0123456789abcdeF", out, dead);
    snprintf(short_hex, sizeof short_hex, "%s.tmp.%ld.0123456789abcde", out, dead);
    snprintf(zero_pid, sizeof zero_pid, "%s.tmp.0%ld.0123456789abcdef", out, dead);
    snprintf(dir_like, sizeof dir_like, "%s.tmp.%ld.fedcba9876543210", out, dead);
    snprintf(link_like, sizeof link_like, "%s.tmp.%ld.00000000000000aa", out, dead);
    write_file(stale, "partial");
    write_file(live, "partial");
    write_file(other, "partial");
    write_file(badhex, "partial");
    write_file(short_hex, "partial");
    write_file(zero_pid, "partial");
    assert_int_equal(mkdir(dir_like, 0755), 0);
    assert_int_equal(symlink("out.bin", link_like), 0);
    sl_error err;
    assert_int_equal(write_text(out, "done", &err), SL_OK);
    assert_content(out, "done");
    assert_false(exists(stale));
    assert_true(exists(live));
    assert_true(exists(other));
    assert_true(exists(badhex));
    assert_true(exists(short_hex));
    assert_true(exists(zero_pid));
    assert_true(exists(dir_like));
    assert_true(exists(link_like));
    /* the name parser itself */
    long pid = 0;
    assert_true(sl_atomic_temp_name_pid("a.bin", "a.bin.tmp.123.0123456789abcdef", &pid));
    assert_int_equal(pid, 123);
    assert_false(sl_atomic_temp_name_pid("a.bin", "a.bin.tmp.123.0123456789abcdef0", &pid));
    assert_false(sl_atomic_temp_name_pid("a.bin", "a.bin.tmp..0123456789abcdef", &pid));
    assert_false(sl_atomic_temp_name_pid("a.bin", "a.bin.tmp.-1.0123456789abcdef", &pid));
    assert_false(sl_atomic_temp_name_pid("a.bin", "a.bin.tmp.99999999999.0123456789abcdef", &pid));
    assert_false(sl_atomic_temp_name_pid("a.bin", "xa.bin.tmp.12.0123456789abcdef", &pid));
    assert_false(sl_atomic_temp_name_pid("a.bin", "a.binx.tmp.12.0123456789abcdef", &pid));
    rmdir(dir_like);
}

/* Descriptor paths (/dev/stdout, /dev/fd/N) write through the descriptor, whatever it is open on. */
static void test_descriptor_paths(void **state)
{
    (void)state;
    char file[256];
    in_dir(file, sizeof file, "fd.txt");
    int fd = open(file, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND, 0644);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, "head,", 5), 5);
    char name[64];
    snprintf(name, sizeof name, "/dev/fd/%d", fd);
    sl_error err;
    assert_int_equal(write_text(name, "body", &err), SL_OK);
    assert_int_equal(write(fd, ",tail", 5), 5);
    close(fd);
    assert_content(file, "head,body,tail");
    struct stat st;
    assert_int_equal(lstat("/dev/null", &st), 0);
    assert_true(S_ISCHR(st.st_mode));
}

/* A file size limit for this process with SIGXFSZ ignored, so that a write past it fails with
 * EFBIG; restore puts the old limit and handler back. */
typedef struct fsize_limit {
    struct rlimit old;
    void (*handler)(int);
} fsize_limit;

static void fsize_limit_set(fsize_limit *l, rlim_t bytes)
{
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &l->old), 0);
    l->handler = signal(SIGXFSZ, SIG_IGN);
    struct rlimit small = l->old;
    small.rlim_cur = bytes;
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &small), 0);
}

static void fsize_limit_restore(fsize_limit *l)
{
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &l->old), 0);
    signal(SIGXFSZ, l->handler);
}

/* A write that fails (here: past the file size limit, SIGXFSZ ignored, so write(2) fails with
 * EFBIG) is reported by commit with that write's reason, not with whatever errno holds by commit
 * time; the temporary is removed and the old file stays. */
static void test_write_error_reported(void **state)
{
    (void)state;
    char file[256];
    in_dir(file, sizeof file, "big.bin");
    write_file(file, "old");
    fsize_limit lim;
    fsize_limit_set(&lim, 4096);
    sl_atomic_file f;
    sl_error err;
    sl_status opened = sl_atomic_open(NULL, file, &f, &err);
    static uint8_t block[65536];
    bool failed = false;
    if (opened == SL_OK) {
        for (int i = 0; i < 4; i++)
            sl_atomic_write(&f, block, sizeof block);
        failed = f.failed;
        errno = 0; /* as after any later call that succeeded, or one that failed for another reason */
    }
    sl_status st = opened == SL_OK ? sl_atomic_commit(&f, &err) : opened;
    fsize_limit_restore(&lim);
    assert_int_equal(opened, SL_OK);
    assert_true(failed);
    assert_int_equal(st, SL_ERROR_IO);
    if (!strstr(err.message, strerror(EFBIG)))
        fail_msg("'%s' does not give the failing write's reason '%s'", err.message, strerror(EFBIG));
    assert_content(file, "old");
    assert_no_temporaries();
}

/* The public face of the writer (sightline/core.h: sl_output, what the command writes its reports
 * with): commit puts the file in place, abort keeps the old one, a write error seen only by stdio
 * (ferror) fails the commit and keeps the old file, and the temporaries' names are recognised. */
static void test_public_output(void **state)
{
    (void)state;
    char file[256];
    in_dir(file, sizeof file, "report.md");
    write_file(file, "old");
    sl_error err;
    sl_output o;
    /* an empty path is named as such (it was "': write failed: No such file or directory") */
    assert_int_equal(sl_output_open("", NULL, &o, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "empty output path"));
    assert_int_equal(sl_output_open(file, NULL, &o, &err), SL_OK);
    assert_int_equal(fprintf(sl_output_stream(o), "# %s\n", "new"), 6);
    assert_content(file, "old"); /* nothing in place before the commit */
    assert_int_equal(sl_output_commit(o, &err), SL_OK);
    assert_content(file, "# new\n");
    assert_no_temporaries();

    assert_int_equal(sl_output_open(file, NULL, &o, &err), SL_OK);
    fputs("dropped", sl_output_stream(o));
    sl_output_abort(o);
    sl_output_abort(NULL);
    assert_content(file, "# new\n");
    assert_no_temporaries();

    fsize_limit lim;
    fsize_limit_set(&lim, 4096);
    sl_status opened = sl_output_open(file, NULL, &o, &err), st = opened;
    if (opened == SL_OK) {
        static char block[65536];
        memset(block, 'x', sizeof block);
        for (int i = 0; i < 4; i++)
            fwrite(block, 1, sizeof block, sl_output_stream(o));
        st = sl_output_commit(o, &err);
    }
    fsize_limit_restore(&lim);
    assert_int_equal(opened, SL_OK);
    assert_int_equal(st, SL_ERROR_IO);
    assert_non_null(strstr(err.message, "report.md: write failed"));
    assert_content(file, "# new\n");
    assert_no_temporaries();

    long pid = 0;
    assert_true(sl_output_temp_name_pid("report.md", "report.md.tmp.4242.0123456789abcdef", &pid));
    assert_int_equal(pid, 4242);
    assert_false(sl_output_temp_name_pid("report.md", "report.md.tmp.04242.0123456789abcdef", &pid));
    assert_false(sl_output_temp_name_pid("report.md", "report.md.tmp.4242.0123456789abcdeF", &pid));
    assert_false(sl_output_temp_name_pid("report.md", "other.md.tmp.4242.0123456789abcdef", &pid));
    assert_int_equal(sl_output_open(NULL, NULL, &o, &err), SL_ERROR_INVALID_ARGUMENT);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_fifo_inputs_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fifo_output_written_through, setup, teardown),
        cmocka_unit_test_setup_teardown(test_symlink_outputs, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stale_temporaries, setup, teardown),
        cmocka_unit_test_setup_teardown(test_descriptor_paths, setup, teardown),
        cmocka_unit_test_setup_teardown(test_write_error_reported, setup, teardown),
        cmocka_unit_test_setup_teardown(test_public_output, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

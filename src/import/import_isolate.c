/* sl_import_assimp: assimp in a child process.
 *
 * assimp 5.2 reads past its buffers, crashes and loops on some malformed files (fuzzing found
 * such PLY and STL files in minutes; under valgrind about one input in six of a small PLY corpus).
 * It is not built with sanitizers, so in this process such a read may corrupt the heap silently
 * and fail much later. The import therefore runs in a fork()ed child:
 *
 *   parent                                   child
 *   sl_import_assimp_check(): options, file kind and size, PLY header (our code, here)
 *   memfd (anonymous memory file), pipe
 *   fork() ------------------------------->  stdin/stdout/stderr to /dev/null, no core file,
 *                                            killed with the parent (PR_SET_PDEATHSIG)
 *                                            sl_import_assimp_checked(...)
 *   poll(pipe): progress records  <-------   progress callback: one record per report
 *     -> the caller's progress; false:
 *        SIGKILL the child (cancelled)
 *   timeout_ms passed: SIGKILL (limit)
 *                                            success: the scene as .slscene into the memfd
 *   result record  <-----------------------  status and message; _exit(0)
 *   waitpid(): a signal or a status without a result record is the importer's crash
 *   .slscene from the memfd through the validating reader (sl_scene_load_memory)
 *
 * Records are fixed-size and smaller than PIPE_BUF, so each write() is atomic. The child never
 * returns into the caller's code: it leaves with _exit(), running no atexit handler and flushing
 * no stdio buffer it inherited. */
#include "import_isolate.h"
#include "source_meta.h"
#include "scene/scene_internal.h"
#include "sightline/slscene.h"

#include <assimp/version.h>

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

enum { REC_PROGRESS = 1, REC_RESULT = 2 };

typedef struct child_rec {
    uint32_t type;
    int32_t status;
    uint64_t done, total;
    char text[sizeof(((sl_error *)0)->message)]; /* the stage, or the error message */
} child_rec;

_Static_assert(sizeof(child_rec) <= PIPE_BUF, "a record is written atomically");

/* ---- child -------------------------------------------------------------------------------- */

static void put_record(int fd, const child_rec *r)
{
    const char *p = (const char *)r;
    size_t left = sizeof *r;
    while (left) {
        ssize_t w = write(fd, p, left);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            _exit(3); /* the parent is gone */
        p += w;
        left -= (size_t)w;
    }
}

static bool child_progress(void *user, const char *stage, uint64_t done, uint64_t total)
{
    child_rec r;
    memset(&r, 0, sizeof r);
    r.type = REC_PROGRESS;
    r.done = done;
    r.total = total;
    snprintf(r.text, sizeof r.text, "%s", stage ? stage : "");
    put_record(*(const int *)user, &r);
    return true; /* cancelling is the parent's: it kills this process */
}

static void quiet_fd(int fd, int flags)
{
    int n = open("/dev/null", flags | O_CLOEXEC);
    if (n >= 0) {
        dup2(n, fd);
        if (n != fd)
            close(n);
    }
}

static _Noreturn void child_main(const char *path, const sl_import_options *opt, const sl_allocator *alloc, int rec_fd,
                                 int mem_fd, pid_t parent)
{
    /* die with the parent; it may have gone between fork() and here */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent)
        _exit(4);
    /* a crash ends this process: the caller's handlers (a crash reporter, a test framework's
     * longjmp back into its runner) would carry on in the caller's code */
    static const int fatal[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT, SIGTRAP, SIGSYS, SIGPIPE, SIGTERM, SIGINT};
    sigset_t all;
    sigemptyset(&all);
    for (size_t i = 0; i < sizeof fatal / sizeof fatal[0]; i++) {
        signal(fatal[i], SIG_DFL);
        sigaddset(&all, fatal[i]);
    }
    sigprocmask(SIG_UNBLOCK, &all, NULL);
    struct rlimit no_core = {0, 0};
    setrlimit(RLIMIT_CORE, &no_core);
    /* an importer never talks to the terminal: what it would say comes back as the result */
    quiet_fd(STDIN_FILENO, O_RDONLY);
    quiet_fd(STDOUT_FILENO, O_WRONLY);
    quiet_fd(STDERR_FILENO, O_WRONLY);

    sl_import_options o = *opt;
    o.progress.fn = child_progress;
    o.progress.user = &rec_fd;
    o.in_process = true;
    sl_scene scene = NULL;
    sl_error err;
    memset(&err, 0, sizeof err);
    sl_status st = sl_import_assimp_checked(path, &o, alloc, &scene, &err); /* checked by the parent */
    if (st == SL_OK) {
        st = sl_scene_save_fd(scene, mem_fd, path, &err);
        sl_scene_destroy(scene);
    }
    child_rec r;
    memset(&r, 0, sizeof r);
    r.type = REC_RESULT;
    r.status = (int32_t)st;
    snprintf(r.text, sizeof r.text, "%s", st == SL_OK ? "" : err.message);
    put_record(rec_fd, &r);
    _exit(0);
}

/* ---- parent ------------------------------------------------------------------------------- */

static uint64_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

static void assimp_version(char *buf, size_t size)
{
    snprintf(buf, size, "%u.%u.%u", aiGetVersionMajor(), aiGetVersionMinor(), aiGetVersionPatch());
}

/* Wait for the child to end (it has been killed, or closed its end of the pipe). */
static int reap(pid_t pid, int *wstatus)
{
    for (;;) {
        if (waitpid(pid, wstatus, 0) == pid)
            return 0;
        if (errno != EINTR)
            return -1; /* ECHILD: SIGCHLD ignored by the program; the records must tell */
    }
}

static sl_status read_back(const char *path, int mem_fd, const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    struct stat sb;
    if (fstat(mem_fd, &sb) != 0)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot read the import's result back: %s", path, strerror(errno));
    if (sb.st_size <= 0)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: the import process reported success but wrote no scene", path);
    if ((uint64_t)sb.st_size > SIZE_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: the imported scene is too large for this process", path);
    size_t size = (size_t)sb.st_size;
    void *p = mmap(NULL, size, PROT_READ, MAP_PRIVATE, mem_fd, 0);
    if (p == MAP_FAILED)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: cannot map the imported scene (%zu bytes): %s", path, size,
                       strerror(errno));
    sl_error inner;
    sl_status st = sl_scene_load_memory(p, size, path, alloc, out, &inner);
    munmap(p, size);
    if (st != SL_OK)
        return sl_fail(err, st, "%s: the import process returned a scene that does not read back: %s", path, inner.message);
    return SL_OK;
}

static int anonymous_file(void)
{
    int fd = memfd_create("sightline-import", MFD_CLOEXEC);
    if (fd >= 0)
        return fd;
    /* a kernel without memfd: an unlinked temporary file */
    FILE *f = tmpfile();
    if (!f)
        return -1;
    fd = dup(fileno(f));
    fclose(f);
    if (fd >= 0)
        fcntl(fd, F_SETFD, FD_CLOEXEC);
    return fd;
}

static sl_status import_isolated(const char *path, const sl_import_options *opt, const sl_allocator *alloc, sl_scene *out,
                                 sl_error *err)
{
    int mem_fd = anonymous_file();
    if (mem_fd < 0)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create the import's memory file: %s", path, strerror(errno));
    int pfd[2];
    if (pipe2(pfd, O_CLOEXEC) != 0) {
        int e = errno;
        close(mem_fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create the import's pipe: %s", path, strerror(e));
    }
    /* nothing the caller buffered may be written twice by the child's copy (it leaves with
     * _exit, but be safe with what it inherits) */
    fflush(stdout);
    fflush(stderr);
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        int e = errno;
        close(pfd[0]);
        close(pfd[1]);
        close(mem_fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot start the import process: %s (set in_process to import here)", path,
                       strerror(e));
    }
    if (pid == 0) {
        close(pfd[0]);
        child_main(path, opt, alloc, pfd[1], mem_fd, parent);
    }
    close(pfd[1]);

    sl_progress prog = opt->progress;
    uint64_t start = now_ms();
    child_rec rec, result;
    size_t have = 0;
    bool got_result = false, cancelled = false, timed_out = false, eof = false;
    memset(&result, 0, sizeof result);
    while (!eof) {
        int wait_ms = 250;
        if (opt->timeout_ms) {
            uint64_t spent = now_ms() - start;
            if (spent >= opt->timeout_ms) {
                timed_out = true;
                break;
            }
            if (opt->timeout_ms - spent < (uint64_t)wait_ms)
                wait_ms = (int)(opt->timeout_ms - spent);
        }
        struct pollfd pf = {pfd[0], POLLIN, 0};
        int n = poll(&pf, 1, wait_ms);
        if (n < 0 && errno != EINTR)
            break;
        if (n <= 0)
            continue;
        ssize_t r = read(pfd[0], (char *)&rec + have, sizeof rec - have);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0) {
            eof = true;
            break;
        }
        have += (size_t)r;
        if (have < sizeof rec)
            continue;
        have = 0;
        rec.text[sizeof rec.text - 1] = '\0';
        if (rec.type == REC_PROGRESS) {
            if (!sl_progress_report(&prog, rec.text, rec.done, rec.total)) {
                cancelled = true;
                break;
            }
        } else if (rec.type == REC_RESULT) {
            result = rec;
            got_result = true;
        }
    }
    if (!eof)
        kill(pid, SIGKILL);
    close(pfd[0]);
    int wstatus = 0;
    bool reaped = reap(pid, &wstatus) == 0;

    sl_status st;
    char version[32];
    if (cancelled) {
        st = sl_fail(err, SL_ERROR_CANCELLED, "%s: import cancelled", path);
    } else if (timed_out) {
        st = sl_fail(err, SL_ERROR_LIMIT, "%s: the import took longer than the limit of %u ms and was stopped", path,
                     opt->timeout_ms);
    } else if (got_result && (!reaped || (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0))) {
        if (result.status == SL_OK)
            st = read_back(path, mem_fd, alloc, out, err);
        else
            st = sl_fail(err, (sl_status)result.status, "%s", result.text);
    } else if (reaped && WIFSIGNALED(wstatus)) {
        assimp_version(version, sizeof version);
        int sig = WTERMSIG(wstatus);
        st = sl_fail(err, SL_ERROR_FORMAT,
                     "%s: assimp crashed reading the file (signal %d, %s): the file is malformed or meets a bug in "
                     "assimp %s; nothing was imported",
                     path, sig, strsignal(sig), version);
    } else if (reaped && WIFEXITED(wstatus)) {
        assimp_version(version, sizeof version);
        st = sl_fail(err, SL_ERROR_FORMAT,
                     "%s: the import process (assimp %s) ended with status %d without a result: the file is "
                     "malformed or meets a bug in assimp; nothing was imported",
                     path, version, WEXITSTATUS(wstatus));
    } else {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: the import process ended without a result", path);
    }
    close(mem_fd);
    return st;
}

sl_status sl_import_assimp(const char *path, const sl_import_options *opt, const sl_allocator *alloc, sl_scene *out,
                           sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_assimp: NULL argument");
    *out = NULL;
    sl_import_options defaults;
    memset(&defaults, 0, sizeof defaults);
    if (!opt)
        opt = &defaults;
    sl_status st;
    if (opt->in_process) {
        st = sl_import_assimp_in_process(path, opt, alloc, out, err);
    } else {
        st = sl_import_assimp_check(path, opt, alloc, err);
        if (st == SL_OK)
            st = import_isolated(path, opt, alloc, out, err);
    }
    /* texture paths are relative to the model's folder (not carried by the child's .slscene) */
    if (st == SL_OK && (st = sl_scene_set_base_dir_of(*out, path, err)) != SL_OK) {
        sl_scene_destroy(*out);
        *out = NULL;
    }
    return st;
}

/* File helpers: whole-file reads, read-only mappings, and the writer every output goes through.
 *
 * Inputs are opened without blocking (a FIFO would otherwise block open(2) for ever) and refused
 * unless they are regular files. Outputs: a regular file (or a name that does not exist yet) is
 * written to a temporary file beside it, synced and renamed over it, so an interrupted run never
 * leaves a partial file; a symbolic link is followed (the temporary goes beside the link's target,
 * which is replaced, and the link stays); a device or a FIFO is written through (opened and
 * written directly: never replaced); a directory or a socket is refused. Stale temporaries of the
 * same output left by killed processes are removed by the next write. */
#include "sl_core.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

sl_status sl_file_open_read(const char *path, int *fd_out, uint64_t *size_out, sl_error *err)
{
    *fd_out = -1;
    if (size_out)
        *size_out = 0;
    /* O_NONBLOCK: opening a FIFO for reading would wait for a writer; cleared again below */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
    if (fd < 0)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open: %s", path,
                       strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file (%s)", path, sl_file_kind_name(st.st_mode));
    }
    int flags = fcntl(fd, F_GETFL);
    if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
        int e = errno;
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    *fd_out = fd;
    if (size_out)
        *size_out = (uint64_t)st.st_size;
    return SL_OK;
}

const char *sl_file_kind_name(unsigned mode)
{
    if (S_ISREG(mode))
        return "a regular file";
    if (S_ISDIR(mode))
        return "a directory";
    if (S_ISCHR(mode))
        return "a character device";
    if (S_ISBLK(mode))
        return "a block device";
    if (S_ISFIFO(mode))
        return "a FIFO";
    if (S_ISSOCK(mode))
        return "a socket";
    if (S_ISLNK(mode))
        return "a symbolic link";
    return "not a file";
}

sl_status sl_file_read_all(const sl_allocator *a, const char *path, uint8_t **out, size_t *size, sl_error *err)
{
    *out = NULL;
    *size = 0;
    int fd;
    uint64_t n64;
    sl_status s = sl_file_open_read(path, &fd, &n64, err);
    if (s != SL_OK)
        return s;
    FILE *fp = fdopen(fd, "rb");
    if (!fp) {
        int e = errno;
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    if (n64 > SIZE_MAX - 1) {
        fclose(fp);
        return sl_fail(err, SL_ERROR_LIMIT, "%s: %llu bytes do not fit in memory", path, (unsigned long long)n64);
    }
    size_t n = (size_t)n64;
    uint8_t *buf = sl_alloc(a, n ? n : 1);
    if (!buf) {
        fclose(fp);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: cannot allocate %zu bytes", path, n);
    }
    if (n && fread(buf, 1, n, fp) != n) {
        int e = ferror(fp) ? errno : 0;
        fclose(fp);
        sl_free(a, buf, n ? n : 1);
        return sl_fail(err, SL_ERROR_IO, "%s: read failed: %s", path, e ? strerror(e) : "the file shrank while read");
    }
    fclose(fp);
    *out = buf;
    *size = n;
    return SL_OK;
}

sl_status sl_file_map(const char *path, sl_mapping *out, sl_error *err)
{
    out->data = NULL;
    out->size = 0;
    int fd;
    uint64_t size;
    sl_status s = sl_file_open_read(path, &fd, &size, err);
    if (s != SL_OK)
        return s;
    if (size == 0) {
        close(fd);
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset 0: file is empty", path);
    }
    if (size > SIZE_MAX) {
        close(fd);
        return sl_fail(err, SL_ERROR_LIMIT, "%s: %llu bytes cannot be mapped", path, (unsigned long long)size);
    }
    void *p = mmap(NULL, (size_t)size, PROT_READ, MAP_PRIVATE, fd, 0);
    int e = errno;
    close(fd);
    if (p == MAP_FAILED)
        return sl_fail(err, SL_ERROR_IO, "%s: mmap failed: %s", path, strerror(e));
    out->data = p;
    out->size = (size_t)size;
    return SL_OK;
}

void sl_file_unmap(sl_mapping *m)
{
    if (m->data)
        munmap(m->data, m->size);
    m->data = NULL;
    m->size = 0;
}

/* ---- the output writer ---- */

/* A string from a format, allocated with a at its exact length (freed with sl_strfree). */
static char *str_format(const sl_allocator *a, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static char *str_format(const sl_allocator *a, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0)
        return NULL;
    char *s = sl_alloc(a, (size_t)n + 1);
    if (!s)
        return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

/* The file a chain of symbolic links ends at when that file does not exist (a dangling link: the
 * write creates it). path itself must be a link. NULL with errno set on failure (ELOOP: more than
 * 40 links). */
static char *dangling_target(const sl_allocator *a, const char *path)
{
    char *cur = sl_strdup(a, path);
    for (int hop = 0; cur && hop < 40; hop++) {
        struct stat st;
        if (lstat(cur, &st) != 0)
            return errno == ENOENT ? cur : (sl_strfree(a, cur), NULL);
        if (!S_ISLNK(st.st_mode)) {
            /* it appeared meanwhile: the caller's stat() saw nothing; write to it as a file */
            return cur;
        }
        char link[PATH_MAX];
        ssize_t n = readlink(cur, link, sizeof link - 1);
        if (n < 0) {
            sl_strfree(a, cur);
            return NULL;
        }
        link[n] = 0;
        char *next;
        const char *slash = strrchr(cur, '/');
        if (link[0] == '/' || !slash)
            next = sl_strdup(a, link);
        else
            next = str_format(a, "%.*s/%s", (int)(slash - cur), cur, link);
        sl_strfree(a, cur);
        cur = next;
    }
    if (cur) {
        sl_strfree(a, cur);
        errno = ELOOP;
    }
    return NULL;
}

char *sl_file_resolve_links(const sl_allocator *a, const char *path, sl_error *err)
{
    struct stat lst, st;
    char *out = NULL;
    if (lstat(path, &lst) != 0 || !S_ISLNK(lst.st_mode)) {
        out = sl_strdup(a, path);
    } else if (stat(path, &st) == 0) {
        char *real = realpath(path, NULL);
        if (!real)
            return (void)sl_fail(err, SL_ERROR_IO, "%s: cannot resolve its symbolic links: %s", path, strerror(errno)),
                   NULL;
        out = sl_strdup(a, real);
        free(real);
    } else if (errno == ENOENT) {
        out = dangling_target(a, path);
        if (!out)
            return (void)sl_fail(err, SL_ERROR_IO, "%s: cannot resolve its symbolic links: %s", path,
                                 strerror(errno ? errno : ENOMEM)),
                   NULL;
    } else {
        return (void)sl_fail(err, SL_ERROR_IO, "%s: cannot resolve its symbolic links: %s", path, strerror(errno)),
               NULL;
    }
    if (!out)
        sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    return out;
}

sl_status sl_file_open_regular(const char *path, int flags, const char *what, int *fd_out, sl_error *err)
{
    *fd_out = -1;
    /* O_NONBLOCK: a FIFO fails (no reader) or opens at once, and is refused below, never waited for */
    int fd = open(path, flags | O_NOFOLLOW | O_NONBLOCK | O_NOCTTY | O_CLOEXEC, 0644);
    struct stat st;
    if (fd < 0) {
        int e = errno;
        if (lstat(path, &st) == 0 && !S_ISREG(st.st_mode))
            return sl_fail(err, SL_ERROR_IO, "%s: cannot use it as %s: it is %s, not a regular file (remove it, or "
                                             "give another path)",
                           path, what, sl_file_kind_name(st.st_mode));
        return sl_fail(err, e == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open %s: %s", path, what,
                       strerror(e));
    }
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open %s: %s", path, what, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot use it as %s: it is %s, not a regular file (remove it, or give "
                                         "another path)",
                       path, what, sl_file_kind_name(st.st_mode));
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl & ~O_NONBLOCK) != 0) {
        int e = errno;
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open %s: %s", path, what, strerror(e));
    }
    *fd_out = fd;
    return SL_OK;
}

bool sl_atomic_temp_name_pid(const char *base, const char *name, long *pid_out)
{
    size_t bl = strlen(base);
    if (strncmp(name, base, bl) != 0 || strncmp(name + bl, ".tmp.", 5) != 0)
        return false;
    const char *p = name + bl + 5;
    long pid = 0;
    int digits = 0;
    while (*p >= '0' && *p <= '9') {
        if (digits == 0 && *p == '0')
            return false;
        pid = pid * 10 + (*p - '0');
        if (pid > INT_MAX)
            return false;
        p++, digits++;
    }
    if (digits == 0 || *p != '.')
        return false;
    p++;
    for (int i = 0; i < 16; i++, p++)
        if (!((*p >= '0' && *p <= '9') || (*p >= 'a' && *p <= 'f')))
            return false;
    if (*p)
        return false;
    *pid_out = pid;
    return true;
}

/* Remove the temporaries "<target>.tmp.<pid>.<16 hex digits>" that processes now gone left beside
 * target (a run killed while writing it). Only regular files of exactly that name, and never one
 * whose process still exists (or may exist: kill() answers anything but ESRCH). Best effort:
 * failures are ignored. */
static void remove_stale_temporaries(const sl_allocator *a, const char *target)
{
    const char *slash = strrchr(target, '/');
    char *dir = slash ? str_format(a, "%.*s", (int)(slash - target + (slash == target)), target) : sl_strdup(a, ".");
    const char *base = slash ? slash + 1 : target;
    if (!dir)
        return;
    DIR *d = opendir(dir);
    if (d) {
        long self = (long)getpid();
        struct dirent *e;
        while ((e = readdir(d))) {
            long pid;
            if (!sl_atomic_temp_name_pid(base, e->d_name, &pid) || pid == self)
                continue;
            if (kill((pid_t)pid, 0) == 0 || errno != ESRCH)
                continue;
            struct stat st;
            if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(st.st_mode))
                unlinkat(dirfd(d), e->d_name, 0);
        }
        closedir(d);
    }
    sl_strfree(a, dir);
}

static void atomic_release(sl_atomic_file *f)
{
    sl_strfree(f->alloc, f->path);
    sl_strfree(f->alloc, f->target);
    sl_strfree(f->alloc, f->tmp_path);
    f->path = f->target = f->tmp_path = NULL;
    f->fp = NULL;
}

/* Open a device or FIFO for writing through. */
static sl_status open_through(sl_atomic_file *out, const struct stat *st, sl_error *err)
{
    const char *path = out->path;
    if (S_ISDIR(st->st_mode) || S_ISSOCK(st->st_mode)) {
        sl_status s = sl_fail(err, SL_ERROR_IO, "%s: cannot write: it is %s (give a file name)", path,
                              sl_file_kind_name(st->st_mode));
        atomic_release(out);
        return s;
    }
    /* a FIFO waits here for its reader, as a shell redirection does */
    int fd = open(path, O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0 || !(out->fp = fdopen(fd, "wb"))) {
        int e = errno;
        if (fd >= 0)
            close(fd);
        sl_status s = sl_fail(err, SL_ERROR_IO, "%s: cannot open %s for writing: %s", path,
                              sl_file_kind_name(st->st_mode), strerror(e));
        atomic_release(out);
        return s;
    }
    out->direct = true;
    return SL_OK;
}

/* The descriptor a path names: /dev/stdout, /dev/stderr, /dev/fd/N, /proc/self/fd/N; -1 if none.
 * Writing to it goes through a duplicate of that descriptor (its offset and O_APPEND shared, as a
 * shell's redirection expects), whatever it is open on. */
static int descriptor_path(const char *path)
{
    if (!strcmp(path, "/dev/stdout"))
        return 1;
    if (!strcmp(path, "/dev/stderr"))
        return 2;
    const char *p = !strncmp(path, "/dev/fd/", 8) ? path + 8 : !strncmp(path, "/proc/self/fd/", 14) ? path + 14 : NULL;
    if (!p || !*p)
        return -1;
    long n = 0;
    for (; *p; p++) {
        if (*p < '0' || *p > '9' || n > 1000000)
            return -1;
        n = n * 10 + (*p - '0');
    }
    return (int)n;
}

sl_status sl_atomic_open(const sl_allocator *a, const char *path, sl_atomic_file *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    out->alloc = sl_alloc_or_default(a);
    a = out->alloc;
    out->path = sl_strdup(a, path);
    if (!out->path)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    int std_fd = descriptor_path(path);
    if (std_fd >= 0) {
        int fd = fcntl(std_fd, F_DUPFD_CLOEXEC, 0);
        if (fd < 0 || !(out->fp = fdopen(fd, "wb"))) {
            int e = errno;
            if (fd >= 0)
                close(fd);
            atomic_release(out);
            return sl_fail(err, SL_ERROR_IO, "%s: cannot write to descriptor %d: %s", path, std_fd, strerror(e));
        }
        out->direct = true;
        return SL_OK;
    }
    struct stat st;
    if (stat(path, &st) == 0) {
        if (!S_ISREG(st.st_mode))
            return open_through(out, &st, err);
        /* a regular file, maybe behind links: replace the file the links end at */
        char *real = realpath(path, NULL);
        if (!real) {
            int e = errno;
            atomic_release(out);
            return sl_fail(err, SL_ERROR_IO, "%s: cannot create: %s", path, strerror(e));
        }
        out->target = sl_strdup(a, real);
        free(real);
    } else if (errno == ENOENT) {
        struct stat lst;
        if (lstat(path, &lst) == 0 && S_ISLNK(lst.st_mode)) {
            out->target = dangling_target(a, path);
            if (!out->target) {
                int e = errno;
                atomic_release(out);
                return sl_fail(err, SL_ERROR_IO, "%s: cannot create: %s", path, strerror(e ? e : ENOMEM));
            }
        } else {
            out->target = sl_strdup(a, path);
        }
    } else {
        int e = errno;
        atomic_release(out);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create: %s", path, strerror(e));
    }
    if (!out->target) {
        atomic_release(out);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    remove_stale_temporaries(a, out->target);
    static const char hex[] = "0123456789abcdef";
    /* a per-call suffix from the address of `out` and the clock keeps concurrent writers apart */
    uint64_t tag = (uint64_t)(uintptr_t)out ^ (uint64_t)(sl_now() * 1e9);
    char suffix[17];
    for (int i = 0; i < 16; i++)
        suffix[i] = hex[(tag >> (i * 4)) & 15];
    suffix[16] = 0;
    out->tmp_path = str_format(a, "%s.tmp.%ld.%s", out->target, (long)getpid(), suffix);
    if (!out->tmp_path) {
        atomic_release(out);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    int fd = open(out->tmp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0 || !(out->fp = fdopen(fd, "wb"))) {
        int e = errno;
        if (fd >= 0) {
            close(fd);
            unlink(out->tmp_path);
        }
        atomic_release(out);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create: %s", path, strerror(e));
    }
    return SL_OK;
}

sl_status sl_atomic_open_fd(const sl_allocator *a, int fd, const char *name, sl_atomic_file *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    out->alloc = sl_alloc_or_default(a);
    out->direct = true;
    out->path = sl_strdup(out->alloc, name);
    if (!out->path)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    int d = dup(fd);
    out->fp = d >= 0 ? fdopen(d, "wb") : NULL;
    if (!out->fp) {
        int e = errno;
        if (d >= 0)
            close(d);
        atomic_release(out);
        return sl_fail(err, SL_ERROR_IO, "%s: cannot write: %s", name, strerror(e));
    }
    return SL_OK;
}

void sl_atomic_write(sl_atomic_file *f, const void *data, size_t size)
{
    if (f->failed || !f->fp || size == 0)
        return;
    errno = 0;
    if (fwrite(data, 1, size, f->fp) != size) {
        /* the reason now, not whatever errno holds by commit time */
        f->error = errno ? errno : EIO;
        f->failed = true;
    }
}

sl_status sl_atomic_commit(sl_atomic_file *f, sl_error *err)
{
    if (!f->fp)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "atomic file not open");
    int e = 0;
    if (f->failed)
        e = f->error ? f->error : EIO;
    else if ((errno = 0, fflush(f->fp) != 0))
        e = errno ? errno : EIO;
    /* a device or a pipe may not sync: that is no failure of the write */
    if (!e && fsync(fileno(f->fp)) != 0 && !(f->direct && (errno == EINVAL || errno == EROFS || errno == ENOTSUP)))
        e = errno;
    if (fclose(f->fp) != 0 && !e)
        e = errno;
    f->fp = NULL;
    if (!e && !f->direct && rename(f->tmp_path, f->target) != 0)
        e = errno;
    if (e) {
        if (!f->direct)
            unlink(f->tmp_path);
        sl_status s = sl_fail(err, SL_ERROR_IO, "%s: write failed: %s", f->path, strerror(e));
        atomic_release(f);
        return s;
    }
    atomic_release(f);
    return SL_OK;
}

void sl_atomic_abort(sl_atomic_file *f)
{
    if (f->fp) {
        fclose(f->fp);
        if (!f->direct)
            unlink(f->tmp_path);
    }
    atomic_release(f);
}

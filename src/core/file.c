/* File helpers: whole-file reads, read-only mappings, and the atomic writer every output goes
 * through (temporary file + fsync + rename), so an interrupted run never leaves a partial file. */
#include "sl_core.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

sl_status sl_file_read_all(const sl_allocator *a, const char *path, uint8_t **out, size_t *size, sl_error *err)
{
    *out = NULL;
    *size = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(fp);
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file", path);
    }
    size_t n = (size_t)st.st_size;
    uint8_t *buf = sl_alloc(a, n ? n : 1);
    if (!buf) {
        fclose(fp);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: cannot allocate %zu bytes", path, n);
    }
    if (n && fread(buf, 1, n, fp) != n) {
        int e = errno;
        fclose(fp);
        sl_free(a, buf, n ? n : 1);
        return sl_fail(err, SL_ERROR_IO, "%s: read failed: %s", path, strerror(e));
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
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file", path);
    }
    if (st.st_size == 0) {
        close(fd);
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset 0: file is empty", path);
    }
    void *p = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    int e = errno;
    close(fd);
    if (p == MAP_FAILED)
        return sl_fail(err, SL_ERROR_IO, "%s: mmap failed: %s", path, strerror(e));
    out->data = p;
    out->size = (size_t)st.st_size;
    return SL_OK;
}

void sl_file_unmap(sl_mapping *m)
{
    if (m->data)
        munmap(m->data, m->size);
    m->data = NULL;
    m->size = 0;
}

sl_status sl_atomic_open(const sl_allocator *a, const char *path, sl_atomic_file *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    out->alloc = sl_alloc_or_default(a);
    size_t n = strlen(path) + 64;
    out->path = sl_strdup(a, path);
    out->tmp_path = sl_alloc(a, n);
    if (!out->path || !out->tmp_path) {
        sl_strfree(a, out->path);
        sl_free(a, out->tmp_path, n);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    static const char hex[] = "0123456789abcdef";
    /* a per-call suffix from the address of `out` and the clock keeps concurrent writers apart */
    uint64_t tag = (uint64_t)(uintptr_t)out ^ (uint64_t)(sl_now() * 1e9);
    char suffix[17];
    for (int i = 0; i < 16; i++)
        suffix[i] = hex[(tag >> (i * 4)) & 15];
    suffix[16] = 0;
    snprintf(out->tmp_path, n, "%s.tmp.%ld.%s", path, (long)getpid(), suffix);
    int fd = open(out->tmp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0 || !(out->fp = fdopen(fd, "wb"))) {
        int e = errno;
        if (fd >= 0) {
            close(fd);
            unlink(out->tmp_path);
        }
        sl_strfree(a, out->path);
        sl_free(a, out->tmp_path, n);
        out->path = out->tmp_path = NULL;
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create: %s", path, strerror(e));
    }
    return SL_OK;
}

void sl_atomic_write(sl_atomic_file *f, const void *data, size_t size)
{
    if (f->failed || !f->fp || size == 0)
        return;
    if (fwrite(data, 1, size, f->fp) != size)
        f->failed = true;
}

static void atomic_release(sl_atomic_file *f)
{
    size_t n = f->path ? strlen(f->path) + 64 : 0;
    sl_strfree(f->alloc, f->path);
    sl_free(f->alloc, f->tmp_path, n);
    f->path = f->tmp_path = NULL;
    f->fp = NULL;
}

sl_status sl_atomic_commit(sl_atomic_file *f, sl_error *err)
{
    if (!f->fp)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "atomic file not open");
    int e = 0;
    if (f->failed || fflush(f->fp) != 0 || fsync(fileno(f->fp)) != 0)
        e = errno ? errno : EIO;
    if (fclose(f->fp) != 0 && !e)
        e = errno;
    f->fp = NULL;
    if (!e && rename(f->tmp_path, f->path) != 0)
        e = errno;
    if (e) {
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
        unlink(f->tmp_path);
    }
    atomic_release(f);
}

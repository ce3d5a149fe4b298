/* The confined, read-only file system assimp imports through (see assimp_io.h). */
#include "assimp_io.h"
#include "core/escape.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdarg.h>
#include <stdlib.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct in_file {
    struct aiFile file;         /* file.UserData points back here */
    int fd;
    uint64_t size, pos;
} in_file;

static in_file *in_of(struct aiFile *f) { return (in_file *)(void *)f->UserData; }

static size_t in_read(struct aiFile *f, char *buf, size_t size, size_t count)
{
    in_file *in = in_of(f);
    if (!size || !count || in->pos >= in->size)
        return 0;
    uint64_t want = (uint64_t)size * count;
    if (count > SIZE_MAX / size)
        want = UINT64_MAX;
    uint64_t left = in->size - in->pos;
    if (want > left)
        want = left - left % size; /* whole elements only, as fread reports them */
    size_t done = 0;
    while (done < want) {
        size_t chunk = (size_t)SL_MIN(want - done, (uint64_t)1 << 30);
        ssize_t r = pread(in->fd, buf + done, chunk, (off_t)(in->pos + done));
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        done += (size_t)r;
    }
    in->pos += done;
    return done / size;
}

static size_t in_write(struct aiFile *f, const char *buf, size_t size, size_t count)
{
    (void)f, (void)buf, (void)size, (void)count;
    return 0;
}

static size_t in_tell(struct aiFile *f) { return (size_t)in_of(f)->pos; }
static size_t in_size(struct aiFile *f) { return (size_t)in_of(f)->size; }
static void in_flush(struct aiFile *f) { (void)f; }

static enum aiReturn in_seek(struct aiFile *f, size_t offset, enum aiOrigin origin)
{
    in_file *in = in_of(f);
    uint64_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? in->pos : in->size;
    if (origin != aiOrigin_SET && origin != aiOrigin_CUR && origin != aiOrigin_END)
        return aiReturn_FAILURE;
    /* assimp passes negative offsets as huge size_t values (wrap-around arithmetic) */
    uint64_t target = base + (uint64_t)offset;
    if (target > in->size)
        return aiReturn_FAILURE;
    in->pos = target;
    return aiReturn_SUCCESS;
}

/* Record the first refusal (later ones are usually consequences of it). Every text in it has
 * been escaped by the caller. */
static void refuse(sl_aio *x, sl_status status, const char *fmt, ...) SL_PRINTF(3, 4);
static void refuse(sl_aio *x, sl_status status, const char *fmt, ...)
{
    if (x->refused)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(x->refused_message, sizeof x->refused_message, fmt, ap);
    va_end(ap);
    x->refused = true;
    x->refused_status = status;
}

/* Does the canonical path lie inside a folder (with its trailing '/') or equal an allowed file? */
static bool allowed(const sl_aio *x, const char *canon)
{
    if (!strcmp(canon, x->model) || !strncmp(canon, x->folder, strlen(x->folder)))
        return true;
    for (uint32_t i = 0; i < x->root_count; i++) {
        const sl_aio_root *r = &x->roots[i];
        if (r->folder ? !strncmp(canon, r->path, strlen(r->path)) : !strcmp(canon, r->path))
            return true;
    }
    return false;
}

/* Canonical form of a path that may not exist: realpath of the whole, else of its folder plus the
 * last component. False when neither resolves (the file cannot be opened anyway). */
static bool canonical(const char *path, char out[PATH_MAX])
{
    if (realpath(path, out))
        return true;
    if (errno != ENOENT)
        return false;
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    if (!base[0] || !strcmp(base, ".") || !strcmp(base, ".."))
        return false;
    char dir[PATH_MAX];
    if (!slash) {
        strcpy(dir, ".");
    } else if (slash == path) {
        strcpy(dir, "/");
    } else {
        size_t dlen = (size_t)(slash - path);
        if (dlen >= sizeof dir)
            return false;
        memcpy(dir, path, dlen);
        dir[dlen] = 0;
    }
    char cdir[PATH_MAX];
    if (!realpath(dir, cdir))
        return false;
    size_t cl = strlen(cdir), bl = strlen(base);
    if (cl + 1 + bl + 1 > PATH_MAX)
        return false;
    memcpy(out, cdir, cl);
    if (cdir[cl - 1] != '/')
        out[cl++] = '/';
    memcpy(out + cl, base, bl + 1);
    return true;
}

/* Does the file hold a NUL byte (or fail to read)? */
static bool has_nul(int fd, uint64_t size)
{
    char buf[65536];
    for (uint64_t at = 0; at < size;) {
        ssize_t r = pread(fd, buf, (size_t)SL_MIN(size - at, (uint64_t)sizeof buf), (off_t)at);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return true;
        if (memchr(buf, 0, (size_t)r))
            return true;
        at += (uint64_t)r;
    }
    return false;
}

static struct aiFile *aio_open(struct aiFileIO *io, const char *name, const char *mode)
{
    sl_aio *x = (sl_aio *)(void *)io->UserData;
    if (!name || !mode || !name[0])
        return NULL;
    /* the reference as the model wrote it: without the model's folder assimp put before it */
    char shown[200];
    size_t gl = strlen(x->given_dir);
    sl_escape_text(gl && !strncmp(name, x->given_dir, gl) && name[gl] ? name + gl : name, 150, shown, sizeof shown);
    if (strchr(mode, 'w') || strchr(mode, 'a') || strchr(mode, '+')) {
        refuse(x, SL_ERROR_FORMAT, "assimp tried to open '%s' for writing; an import only reads", shown);
        return NULL;
    }
    /* a relative reference assimp did not put the model's folder before (LightWave scenes name
     * their objects bare: "LoadObjectLayer 1 simple_cube.lwo") means the model's folder, not the
     * current one: without this, a scene loads only when run from its own folder */
    char joined[PATH_MAX];
    if (name[0] != '/' && !(gl && strncmp(name, x->given_dir, gl) == 0)) {
        if ((size_t)snprintf(joined, sizeof joined, "%s%s", x->folder, name) >= sizeof joined)
            return NULL;
        name = joined;
    }
    char canon[PATH_MAX];
    if (!canonical(name, canon))
        return NULL; /* does not exist: assimp reports it or carries on */
    if (!allowed(x, canon)) {
        char c[200], f[200];
        sl_escape_text(canon, 150, c, sizeof c);
        sl_escape_text(x->folder, 150, f, sizeof f);
        refuse(x, SL_ERROR_FORMAT,
               "reference '%s' resolves to %s, outside the model's folder %s: refused (references stay inside the "
               "model's folder unless allowed: --allow-external PATH)",
               shown, c, f);
        return NULL;
    }
    if (++x->opens > SL_ASSIMP_MAX_OPENS) {
        refuse(x, SL_ERROR_LIMIT, "'%s': more than %u file opens in one import", shown, SL_ASSIMP_MAX_OPENS);
        return NULL;
    }
    /* the canonical path has no symlink left; O_NOFOLLOW catches one swapped in since, O_NONBLOCK
     * keeps a FIFO from blocking open(2) before the regular-file check */
    int fd = open(canon, O_RDONLY | O_NONBLOCK | O_NOFOLLOW | O_NOCTTY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    /* a folder on the way swapped for a symlink between realpath and open: check what was
     * opened (where /proc tells) */
    char proc[64], opened[PATH_MAX];
    snprintf(proc, sizeof proc, "/proc/self/fd/%d", fd);
    ssize_t ol = readlink(proc, opened, sizeof opened - 1);
    if (ol > 0) {
        opened[ol] = 0;
        if (!allowed(x, opened)) {
            close(fd);
            refuse(x, SL_ERROR_FORMAT, "reference '%s' changed while it was opened: refused", shown);
            return NULL;
        }
    }
    struct stat sb;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        close(fd);
        refuse(x, SL_ERROR_FORMAT, "reference '%s' is not a regular file: refused", shown);
        return NULL;
    }
    if ((uint64_t)sb.st_size > x->max_file_bytes) {
        close(fd);
        refuse(x, SL_ERROR_LIMIT, "'%s': %llu bytes, more than the limit of %llu", shown, (unsigned long long)sb.st_size,
               (unsigned long long)x->max_file_bytes);
        return NULL;
    }
    if (x->text_references && strcmp(canon, x->model) != 0 && has_nul(fd, (uint64_t)sb.st_size)) {
        close(fd);
        /* assimp 5.2's MTL reader crashes on some (fuzz/fuzz_assimp.c) */
        refuse(x, SL_ERROR_FORMAT, "reference '%s' holds NUL bytes: not a text file (refused)", shown);
        return NULL;
    }
    in_file *in = sl_calloc(x->a, 1, sizeof *in);
    if (!in) {
        close(fd);
        refuse(x, SL_ERROR_OUT_OF_MEMORY, "'%s': out of memory", shown);
        return NULL;
    }
    in->fd = fd;
    in->size = (uint64_t)sb.st_size;
    in->file.ReadProc = in_read;
    in->file.WriteProc = in_write;
    in->file.TellProc = in_tell;
    in->file.FileSizeProc = in_size;
    in->file.SeekProc = in_seek;
    in->file.FlushProc = in_flush;
    in->file.UserData = (aiUserData)(void *)in;
    x->open_files++;
    return &in->file;
}

static void aio_close(struct aiFileIO *io, struct aiFile *f)
{
    sl_aio *x = (sl_aio *)(void *)io->UserData;
    if (!f)
        return;
    in_file *in = in_of(f);
    close(in->fd);
    sl_free(x->a, in, sizeof *in);
    x->open_files--;
}

void sl_aio_free(sl_aio *x)
{
    for (uint32_t i = 0; i < x->root_count; i++)
        sl_free(x->a, x->roots[i].path, x->roots[i].size);
    sl_free(x->a, x->roots, (size_t)x->root_cap * sizeof *x->roots);
    x->roots = NULL;
    x->root_count = x->root_cap = 0;
}

sl_status sl_aio_init(sl_aio *x, const char *model, const char *const *allowed_paths, uint32_t allowed_count,
                      uint64_t max_file_bytes, const sl_allocator *a, sl_error *err)
{
    memset(x, 0, sizeof *x);
    x->a = sl_alloc_or_default(a);
    x->max_file_bytes = max_file_bytes ? max_file_bytes : SL_ASSIMP_MAX_FILE_BYTES;
    x->io.OpenProc = aio_open;
    x->io.CloseProc = aio_close;
    x->io.UserData = (aiUserData)(void *)x;
    char canon[PATH_MAX];
    if (!realpath(model, canon) || strlen(canon) + 2 > sizeof x->model)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot resolve the path: %s", model,
                       strerror(errno ? errno : ENAMETOOLONG));
    strcpy(x->model, canon);
    /* the folder of the path as given (assimp resolves references against it), canonical */
    const char *slash = strrchr(model, '/');
    char dir[PATH_MAX];
    size_t given = slash ? (size_t)(slash - model) + 1 : 0;
    if (given < sizeof x->given_dir) {
        memcpy(x->given_dir, model, given);
        x->given_dir[given] = 0;
    }
    if (!slash)
        strcpy(dir, ".");
    else if (slash == model)
        strcpy(dir, "/");
    else if ((size_t)(slash - model) < sizeof dir)
        memcpy(dir, model, (size_t)(slash - model)), dir[slash - model] = 0;
    else
        return sl_fail(err, SL_ERROR_LIMIT, "%s: path too long", model);
    if (!realpath(dir, canon) || strlen(canon) + 2 > sizeof x->folder)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot resolve the model's folder: %s", model, strerror(errno ? errno : ENAMETOOLONG));
    snprintf(x->folder, sizeof x->folder, "%s%s", canon, canon[strlen(canon) - 1] == '/' ? "" : "/");
    const char *base = slash ? slash + 1 : model, *dot = strrchr(base, '.');
    x->text_references = dot && !strcasecmp(dot, ".obj");
    if (!allowed_count)
        return SL_OK;
    if (!allowed_paths)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: allow_external_count is %u but the list is NULL", model, allowed_count);
    x->roots = sl_calloc(x->a, allowed_count, sizeof *x->roots);
    if (!x->roots)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", model);
    x->root_cap = allowed_count;
    for (uint32_t i = 0; i < allowed_count; i++) {
        const char *p = allowed_paths[i];
        struct stat sb;
        char shown[200];
        if (!p || !p[0]) {
            sl_aio_free(x);
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "allowed external path %u is empty", i);
        }
        sl_escape_text(p, 150, shown, sizeof shown);
        if (!realpath(p, canon) || stat(canon, &sb) != 0) {
            int e = errno;
            sl_aio_free(x);
            return sl_fail(err, e == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "allowed external path %s: %s", shown, strerror(e));
        }
        bool folder = S_ISDIR(sb.st_mode);
        size_t len = strlen(canon);
        bool slash_end = len && canon[len - 1] == '/';
        size_t size = len + (folder && !slash_end ? 1 : 0) + 1;
        char *copy = sl_alloc(x->a, size);
        if (!copy) {
            sl_aio_free(x);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", model);
        }
        snprintf(copy, size, "%s%s", canon, folder && !slash_end ? "/" : "");
        x->roots[x->root_count++] = (sl_aio_root){copy, size, folder};
    }
    return SL_OK;
}

/* Baking a PVS on all cores: cells dealt dynamically to OpenMP threads, results merged in cell
 * order, and a checkpoint journal that lets an interrupted bake resume.
 *
 * Determinism: a method computes each cell's set from (scene, cells, options, cell) alone (the
 * contract in pvs_internal.h), and the file is written in cell order with no timing or thread
 * count in it, so the output is the same bytes whatever the thread count, the process count
 * (pvs_mpi.c) or the order cells finished in.
 *
 * The journal ("<output>.ckpt" unless named), version 2: a 64-byte header (magic, version, cells,
 * objects, the length of a description, the bake key that ties it to the scene, cells, method and
 * effective options, and that key's three parts, so that a mismatch can be told: scene, cells,
 * method+options; a checksum over the header and the description), the description
 * ("method=NAME options=EFFECTIVE"), then one record per finished cell, appended as soon as the
 * cell is done:
 *   u32 tag 'CELL' (0x4c4c4543), u32 cell, u32 count, u32 bytes, u64 XXH3-64 of the 16 bytes
 *   before it and the payload, payload (the set as varint gaps, as in the .slpvs blocks).
 * The journal is created with the first finished cell, never before: a bake that fails before any
 * cell is done (in prepare, say) leaves none. One that fails later keeps its cells (the message
 * says so); one that exists is never overwritten without --resume unless it holds no whole cell.
 * A killed process leaves at most one partial record at the end; resume reads records while they
 * are whole and valid, cuts the file after the last good one and bakes only the missing cells.
 * The bake lock ("<journal>.lock", flock, held from begin to end and dropped by the kernel when
 * the process dies) keeps a second bake off a journal in use: it is told which process runs.
 * Records are written with write(2) (in the kernel once it returns, so a killed process loses
 * nothing finished) and the file is synced every few seconds (power loss costs seconds). */
#include "motion_regions.h"
#include "pvs_internal.h"
#include "core/bytes.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define J_MAGIC "SLPVSCKP"
#define J_VERSION 2u
#define J_HEADER 64u
#define J_MAX_DESC 4096u
#define J_RECORD 24u
#define J_TAG 0x4c4c4543u /* "CELL" */
#define J_SYNC_SECONDS 5.0


/* ---- journal ---- */

/* "method=NAME options=EFFECTIVE": what the header's method key hashes, kept in the journal so
 * that a mismatch can be told in words. */
static int journal_desc(const sl_bake *b, char *out, size_t n)
{
    return snprintf(out, n, "method=%s options=%s", b->method->name, b->effective);
}

static void journal_header(const sl_bake *b, uint8_t h[J_HEADER], const char *desc, uint32_t desc_len)
{
    memset(h, 0, J_HEADER);
    memcpy(h, J_MAGIC, 8);
    wr32(h + 8, J_VERSION);
    wr32(h + 12, b->cell_count);
    wr32(h + 16, b->object_count);
    wr32(h + 20, desc_len);
    wr64(h + 24, b->key);
    wr64(h + 32, b->scene_key);
    wr64(h + 40, b->cells_key);
    wr64(h + 48, b->method_key);
    wr64(h + 56, sl_hash64(desc, desc_len, sl_hash64(h, 56, 0)));
}

/* `rm -- 'PATH'` for messages, quoted for a POSIX shell. */
static void rm_command(const char *path, char *out, size_t n)
{
    size_t k = 0;
    const char *head = "rm -- '";
    for (const char *c = head; *c && k + 1 < n; c++)
        out[k++] = *c;
    for (const char *c = path; *c && k + 5 < n; c++) {
        if (*c == '\'') { /* ' -> '\'' */
            memcpy(out + k, "'\\''", 4);
            k += 4;
        } else {
            out[k++] = *c;
        }
    }
    if (k + 1 < n)
        out[k++] = '\'';
    out[k < n ? k : n - 1] = 0;
}

/* A journal's description, made safe to print (it is file content). */
static void printable(const uint8_t *p, size_t len, char *out, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < len && k + 4 < n; i++)
        out[k++] = p[i] >= 0x20 && p[i] < 0x7f ? (char)p[i] : '?';
    if (len > 0 && k + 4 >= n && n > 4) {
        memcpy(out + k, "...", 3);
        k += 3;
    }
    out[k] = 0;
}

typedef enum { J_SAME, J_OTHER, J_BAD } journal_verdict;

/* Does the journal belong to this bake? J_SAME with *records = where its records start; J_OTHER
 * or J_BAD with the reason in why (what differs, or what is wrong with the file). */
static journal_verdict journal_examine(const sl_bake *b, const uint8_t *data, size_t size, size_t *records, char *why,
                                       size_t n)
{
    why[0] = 0;
    if (size < J_HEADER || memcmp(data, J_MAGIC, 8) != 0) {
        snprintf(why, n, "offset 0: not a PVS checkpoint journal");
        return J_BAD;
    }
    if (rd32(data + 8) == 1) {
        /* version 1 held a scene key of format 1, which missed moved triangles and BSP changes */
        snprintf(why, n, "journal version 1: the checkpoint was baked with an older scene key (format 1); bake it again");
        return J_BAD;
    }
    if (rd32(data + 8) != J_VERSION) {
        snprintf(why, n, "journal version %u (this build reads and writes %u%s)", rd32(data + 8), J_VERSION,
                 rd32(data + 8) > J_VERSION ? "; the journal was written by a newer Sightline, which can resume it" : "");
        return J_BAD;
    }
    uint32_t desc_len = rd32(data + 20);
    if (desc_len > J_MAX_DESC || desc_len > size - J_HEADER) {
        snprintf(why, n, "offset 20: a header description of %u bytes in a file of %zu", desc_len, size);
        return J_BAD;
    }
    if (rd64(data + 56) != sl_hash64(data + J_HEADER, desc_len, sl_hash64(data, 56, 0))) {
        snprintf(why, n, "offset 56: journal header checksum mismatch");
        return J_BAD;
    }
    if (!b->method) {
        /* the reader alone (sl_bake_journal_check): any description, the counts and key must match */
        if (rd64(data + 24) != b->key || rd32(data + 12) != b->cell_count || rd32(data + 16) != b->object_count) {
            snprintf(why, n, "another bake key, cell or object count");
            return J_OTHER;
        }
        *records = J_HEADER + desc_len;
        return J_SAME;
    }
    char desc[SL_OPTS_MAX_CHARS + 128];
    int dl = journal_desc(b, desc, sizeof desc);
    if (rd64(data + 24) == b->key && rd32(data + 12) == b->cell_count && rd32(data + 16) == b->object_count &&
        desc_len == (uint32_t)dl && memcmp(data + J_HEADER, desc, desc_len) == 0) {
        *records = J_HEADER + desc_len;
        return J_SAME;
    }
    /* say what differs */
    size_t k = 0;
#define WHY(...)                                                                                                       \
    do {                                                                                                               \
        if (k < n) {                                                                                                   \
            int w_ = snprintf(why + k, n - k, "%s", k ? "; " : "");                                                    \
            k += w_ > 0 ? (size_t)w_ : 0;                                                                              \
        }                                                                                                              \
        if (k < n) {                                                                                                   \
            int w_ = snprintf(why + k, n - k, __VA_ARGS__);                                                            \
            k += w_ > 0 ? (size_t)w_ : 0;                                                                              \
        }                                                                                                              \
    } while (0)
    if (rd64(data + 32) != b->scene_key || rd32(data + 16) != b->object_count)
        WHY("another scene (%u objects in the checkpoint, %u now%s)", rd32(data + 16), b->object_count,
            rd32(data + 16) == b->object_count ? ", other contents" : "");
    if (rd32(data + 12) != b->cell_count || rd64(data + 40) != b->cells_key)
        WHY("other view cells (%u in the checkpoint, %u now%s)", rd32(data + 12), b->cell_count,
            rd32(data + 12) == b->cell_count ? ", other shapes" : "");
    if (rd64(data + 48) != b->method_key || desc_len != (uint32_t)dl || memcmp(data + J_HEADER, desc, desc_len)) {
        char theirs[160], ours[160];
        printable(data + J_HEADER, desc_len, theirs, sizeof theirs);
        printable((const uint8_t *)desc, (size_t)dl, ours, sizeof ours);
        WHY("another method or options (checkpoint: %s; now: %s)", theirs, ours);
    }
    if (k == 0)
        WHY("another bake key");
#undef WHY
    return J_OTHER;
}

static bool write_all(int fd, const void *data, size_t size)
{
    const uint8_t *p = data;
    while (size > 0) {
        ssize_t n = write(fd, p, size);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return false;
        p += n;
        size -= (size_t)n;
    }
    return true;
}

/* Read the journal's records from `at` into the results; returns the length of its valid prefix. */
static sl_status journal_replay(sl_bake *b, const uint8_t *data, size_t size, size_t at, size_t *valid,
                                sl_error *err)
{
    sl_status st = SL_OK;
    while (size - at >= J_RECORD) {
        const uint8_t *r = data + at;
        uint32_t cell = rd32(r + 4), count = rd32(r + 8), bytes = rd32(r + 12);
        if (rd32(r) != J_TAG || cell >= b->cell_count || count > b->object_count || bytes > size - at - J_RECORD)
            break;
        uint64_t h = sl_hash64(r, 16, 0);
        h = sl_hash64(r + J_RECORD, bytes, h);
        if (h != rd64(r + 16))
            break;
        if (!sl_pvs_decode(r + J_RECORD, r + J_RECORD + bytes, count, b->object_count, b->scratch))
            break;
        if (!b->done[cell]) {
            st = sl_bake_store_encoded(b, cell, r + J_RECORD, bytes, count, 0, false, err);
            if (st != SL_OK)
                break;
            b->resumed++;
        }
        at += J_RECORD + bytes;
    }
    *valid = at;
    return st;
}

/* Forget what a journal without a single whole cell had stored (nothing: kept for symmetry). */
static void forget_resumed(sl_bake *b)
{
    for (uint32_t c = 0; c < b->cell_count; c++)
        if (b->done[c]) {
            sl_free(b->a, b->enc[c], b->enc_size[c] ? b->enc_size[c] : 1);
            b->enc[c] = NULL;
            b->enc_size[c] = b->counts[c] = 0;
            b->done[c] = 0;
        }
    b->done_count = b->resumed = 0;
}

/* The holder's pid and output from a lock file another process has locked (it writes them just
 * after taking the lock: wait a little for them). */
static long lock_holder(int fd, char *output, size_t n)
{
    output[0] = 0;
    char text[4096 + 32];
    for (int tries = 0; tries < 50; tries++) {
        ssize_t got = pread(fd, text, sizeof text - 1, 0);
        if (got > 0) {
            text[got] = 0;
            char *end;
            long pid = strtol(text, &end, 10);
            if (end != text && *end == '\n' && strchr(end + 1, '\n')) {
                printable((const uint8_t *)end + 1, (size_t)(strchr(end + 1, '\n') - (end + 1)), output, n);
                return pid;
            }
        }
        struct timespec ts = {0, 10 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return -1;
}

/* The bake lock: an exclusive flock on "<journal>.lock", held for the bake's life and released by
 * the kernel when the process dies however it dies; the file holds "PID\nOUTPUT\n" for the
 * message of the bake that finds it taken. The holder removes the file before closing it, so one
 * that locked a file already removed (its inode is no longer the path's) tries again. */
static sl_status bake_lock(sl_bake *b, sl_error *err)
{
    size_t n = strlen(b->journal) + 6;
    b->lock_path = sl_alloc(b->a, n);
    if (!b->lock_path)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    snprintf(b->lock_path, n, "%s.lock", b->journal);
    for (int tries = 0; tries < 16; tries++) {
        /* a regular file, never through a link nor a FIFO (see sl_file_open_regular) */
        int fd;
        sl_status st = sl_file_open_regular(b->lock_path, O_RDWR | O_CREAT, "the bake lock", &fd, err);
        if (st != SL_OK)
            return st;
        if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            int e = errno;
            if (e == EWOULDBLOCK) {
                char theirs[256];
                long pid = lock_holder(fd, theirs, sizeof theirs);
                close(fd);
                char who[32] = "pid unknown";
                if (pid > 0)
                    snprintf(who, sizeof who, "pid %ld", pid);
                if (theirs[0] && strcmp(theirs, b->output) != 0)
                    return sl_fail(err, SL_ERROR_IO,
                                   "%s: another bake of %s is running (%s) and uses the same checkpoint %s: wait for "
                                   "it to end, or choose another --checkpoint",
                                   b->output, theirs, who, b->journal);
                return sl_fail(err, SL_ERROR_IO,
                               "%s: another bake of %s is running (%s): wait for it to end (its checkpoint %s is in "
                               "use; do not resume it while it runs)",
                               b->output, b->output, who, b->journal);
            }
            close(fd);
            if (e == ENOLCK || e == EOPNOTSUPP || e == ENOSYS)
                return SL_OK; /* a file system without locks: bake unlocked, as before */
            return sl_fail(err, SL_ERROR_IO, "%s: cannot lock: %s", b->lock_path, strerror(e));
        }
        struct stat held, named;
        if (fstat(fd, &held) == 0 && stat(b->lock_path, &named) == 0 && held.st_dev == named.st_dev &&
            held.st_ino == named.st_ino) {
            char text[4096 + 32];
            int len = snprintf(text, sizeof text, "%ld\n%s\n", (long)getpid(), b->output);
            if (len < 0 || (size_t)len >= sizeof text)
                len = snprintf(text, sizeof text, "%ld\n\n", (long)getpid());
            if (ftruncate(fd, 0) != 0 || pwrite(fd, text, (size_t)len, 0) != (ssize_t)len) {
                int e = errno;
                close(fd);
                return sl_fail(err, SL_ERROR_IO, "%s: cannot write the bake lock: %s", b->lock_path, strerror(e));
            }
            b->lock_fd = fd;
            return SL_OK;
        }
        close(fd); /* locked a file its holder had just removed: take the path's new one */
    }
    return sl_fail(err, SL_ERROR_IO, "%s: cannot take the bake lock (it keeps being replaced)", b->lock_path);
}

static void bake_unlock(sl_bake *b)
{
    if (b->lock_fd >= 0) {
        unlink(b->lock_path); /* while still holding it: see bake_lock */
        close(b->lock_fd);
        b->lock_fd = -1;
    }
}

/* Take the lock and read an existing journal. Nothing is written here: the journal is created with
 * the first finished cell (journal_append), so a bake that fails or is stopped before any cell is
 * done leaves none. */
static sl_status journal_open(sl_bake *b, const char *output, const sl_pvs_build_options *opt, sl_error *err)
{
    const char *named = opt && opt->checkpoint ? opt->checkpoint : NULL;
    size_t n = named ? strlen(named) + 1 : strlen(output) + 6, no = strlen(output) + 1;
    b->journal = sl_alloc(b->a, n);
    b->output = sl_alloc(b->a, no);
    if (!b->journal || !b->output)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    if (named)
        memcpy(b->journal, named, n);
    else
        snprintf(b->journal, n, "%s.ckpt", output);
    memcpy(b->output, output, no);
    /* a journal named through symbolic links is the file they end at (as for outputs), and its
     * lock lies beside that file: bakes that name it through different links share one lock */
    char *real = sl_file_resolve_links(b->a, b->journal, err);
    if (!real)
        return SL_ERROR_IO;
    sl_free(b->a, b->journal, n);
    b->journal = real;
    bool resume = opt && opt->resume;
    if (resume && opt->fresh)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pvs bake: resume and fresh exclude each other");
    sl_status st = bake_lock(b, err);
    if (st != SL_OK)
        return st;
    struct stat sb;
    if (opt && opt->fresh && lstat(b->journal, &sb) == 0 && S_ISREG(sb.st_mode)) {
        /* under the lock: a journal of an earlier bake, never that of one that runs */
        if (unlink(b->journal) != 0 && errno != ENOENT)
            return sl_fail(err, SL_ERROR_IO, "%s: cannot remove the checkpoint of an earlier bake: %s", b->journal,
                           strerror(errno));
    }
    if (stat(b->journal, &sb) != 0)
        return SL_OK; /* a fresh bake (with --resume too: nothing to resume yet) */
    char rm[4200];
    rm_command(b->journal, rm, sizeof rm);
    uint8_t *data = NULL;
    size_t size = 0;
    st = sl_file_read_all(b->a, b->journal, &data, &size, err);
    if (st != SL_OK)
        return st;
    char why[400];
    size_t at = 0, valid = 0;
    journal_verdict v = journal_examine(b, data, size, &at, why, sizeof why);
    if (v == J_SAME)
        st = journal_replay(b, data, size, at, &valid, err);
    sl_free(b->a, data, size);
    if (v == J_BAD)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: %s: not a checkpoint this bake can use; delete it to bake afresh: %s",
                       b->journal, why, rm);
    if (v == J_OTHER)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the checkpoint belongs to another bake: %s; bake with the inputs it was made with, or "
                       "delete it to bake afresh: %s",
                       b->journal, why, rm);
    if (st != SL_OK)
        return st;
    if (b->resumed == 0) {
        /* the same bake, but not one whole cell (killed while writing the first): nothing to keep */
        forget_resumed(b);
        if (unlink(b->journal) != 0 && errno != ENOENT)
            return sl_fail(err, SL_ERROR_IO, "%s: cannot remove an empty checkpoint: %s", b->journal, strerror(errno));
        return SL_OK;
    }
    if (!resume)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: a checkpoint of an interrupted bake of the same scene, cells and options holds %u of %u "
                       "cells: continue it (--resume), or delete it to bake afresh: %s",
                       b->journal, b->resumed, b->cell_count, rm);
    if ((st = sl_file_open_regular(b->journal, O_WRONLY, "the checkpoint", &b->fd, err)) != SL_OK)
        return st;
    if (ftruncate(b->fd, (off_t)valid) != 0 || lseek(b->fd, (off_t)valid, SEEK_SET) < 0)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot reopen the checkpoint: %s", b->journal, strerror(errno));
    b->last_sync = sl_now();
    return SL_OK;
}

/* Create the journal: the header, then the records (with the first finished cell). */
static sl_status journal_create(sl_bake *b, sl_error *err)
{
    /* a regular file only: a FIFO or a device put there since the bake began is refused, not
     * waited for or written into, and a symbolic link is not followed */
    sl_status st = sl_file_open_regular(b->journal, O_WRONLY | O_CREAT | O_TRUNC, "the checkpoint", &b->fd, err);
    if (st != SL_OK)
        return st;
    char desc[SL_OPTS_MAX_CHARS + 128];
    int dl = journal_desc(b, desc, sizeof desc);
    uint8_t h[J_HEADER];
    journal_header(b, h, desc, (uint32_t)dl);
    if (!write_all(b->fd, h, sizeof h) || !write_all(b->fd, desc, (size_t)dl))
        return sl_fail(err, SL_ERROR_IO, "%s: cannot write the checkpoint: %s", b->journal, strerror(errno));
    b->last_sync = sl_now();
    return SL_OK;
}

/* ---- the bake ---- */

sl_status sl_bake_begin(sl_bake *b, sl_scene scene, sl_viewcells cells, const char *output,
                        const sl_pvs_build_options *opt, bool writer, sl_error *err)
{
    memset(b, 0, sizeof *b);
    b->fd = -1;
    b->lock_fd = -1;
    if (!scene || !cells || (writer && !output))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pvs bake: scene, cells and output must not be NULL");
    b->a = sl_alloc_or_default(opt ? opt->alloc : NULL);
    b->scene = scene;
    b->cells = cells;
    b->writer = writer;
    b->cell_count = sl_viewcells_count(cells);
    b->object_count = sl_scene_object_count(scene);
    if (b->cell_count == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pvs bake: there are no view cells");
    if (b->object_count == UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "pvs bake: too many objects");
    /* the one thread limit: libgomp crashed when asked for 100000 threads */
    sl_status st = sl_threads_check(opt ? opt->threads : 0, true, "pvs bake", err);
    if (st != SL_OK)
        return st;
    st = sl_pvs_registry_find(opt ? opt->method : NULL, &b->method, err);
    if (st != SL_OK)
        return st;
    st = sl_pvs_method_configure(b->method, opt ? opt->method_options : NULL, b->a, &b->config, b->effective, err);
    if (st != SL_OK)
        return st;
    /* the key of this bake: a journal from any other one is refused */
    uint64_t k[3] = {sl_pvs_scene_key(scene), sl_viewcells_key(cells), (uint64_t)b->object_count};
    b->key = sl_hash64(k, sizeof k, 0);
    b->key = sl_hash64(b->method->name, strlen(b->method->name), b->key);
    b->key = sl_hash64(b->effective, strlen(b->effective), b->key);
    b->scene_key = k[0];
    b->cells_key = k[1];
    b->method_key = sl_hash64(b->effective, strlen(b->effective), sl_hash64(b->method->name, strlen(b->method->name), 0));
    if (writer) {
        size_t nc = b->cell_count;
        b->enc = sl_calloc(b->a, nc, sizeof *b->enc);
        b->enc_size = sl_calloc(b->a, nc, sizeof *b->enc_size);
        b->counts = sl_calloc(b->a, nc, sizeof *b->counts);
        b->done = sl_calloc(b->a, nc, 1);
        b->scratch = sl_alloc(b->a, ((size_t)b->object_count + 1) * sizeof(uint32_t));
        if (!b->enc || !b->enc_size || !b->counts || !b->done || !b->scratch)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for %u cells", b->cell_count);
        if ((st = journal_open(b, output, opt, err)) != SL_OK)
            return st;
    }
    st = b->method->prepare(scene, cells, b->config, b->a, opt ? opt->threads : 0, &b->shared, &b->removed, err);
    return st;
}

static sl_status journal_append(sl_bake *b, uint32_t cell, const uint8_t *bytes, uint32_t size, uint32_t count,
                                sl_error *err);

sl_status sl_bake_store_encoded(sl_bake *b, uint32_t cell, const uint8_t *bytes, uint32_t size, uint32_t count,
                                double seconds, bool journal, sl_error *err)
{
    if (cell >= b->cell_count || b->done[cell])
        return sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: cell %u stored twice or out of range", cell);
    if (count > b->object_count || !sl_pvs_decode(bytes, bytes + size, count, b->object_count, b->scratch))
        return sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: the set of cell %u is malformed (%u ids in %u bytes)", cell,
                       count, size);
    uint8_t *copy = sl_alloc(b->a, size ? size : 1);
    if (!copy)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for cell %u", cell);
    if (size)
        memcpy(copy, bytes, size);
    b->enc[cell] = copy;
    b->enc_size[cell] = size;
    b->counts[cell] = count;
    b->done[cell] = 1;
    b->done_count++;
    b->cell_seconds += seconds;
    b->max_cell_seconds = fmax(b->max_cell_seconds, seconds);
    return journal ? journal_append(b, cell, bytes, size, count, err) : SL_OK;
}

/* Append a finished cell to the journal. */
static sl_status journal_append(sl_bake *b, uint32_t cell, const uint8_t *bytes, uint32_t size, uint32_t count,
                                sl_error *err)
{
    if (b->fd < 0) {
        sl_status st = journal_create(b, err);
        if (st != SL_OK)
            return st;
    }
    uint8_t r[J_RECORD];
    wr32(r, J_TAG);
    wr32(r + 4, cell);
    wr32(r + 8, count);
    wr32(r + 12, size);
    uint64_t h = sl_hash64(r, 16, 0);
    h = sl_hash64(bytes, size, h);
    wr64(r + 16, h);
    if (!write_all(b->fd, r, sizeof r) || !write_all(b->fd, bytes, size))
        return sl_fail(err, SL_ERROR_IO, "%s: cannot append cell %u: %s", b->journal, cell, strerror(errno));
    double now = sl_now();
    if (now - b->last_sync > J_SYNC_SECONDS) {
        (void)fdatasync(b->fd); /* durability against power loss; a kill loses nothing either way */
        b->last_sync = now;
    }
    return SL_OK;
}

sl_status sl_bake_store(sl_bake *b, uint32_t cell, const uint32_t *ids, uint32_t count, double seconds, sl_error *err)
{
    for (uint32_t k = 0; k < count; k++)
        if (ids[k] >= b->object_count || (k > 0 && ids[k] <= ids[k - 1]))
            return sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: method %s returned a bad set for cell %u (entry %u)",
                           b->method->name, cell, k);
    uint8_t stack[1024] = {0};
    size_t cap = (size_t)count * 5;
    uint8_t *buf = cap <= sizeof stack ? stack : sl_alloc(b->a, cap);
    if (!buf)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for cell %u", cell);
    uint32_t size = (uint32_t)sl_pvs_encode(ids, count, buf);
    sl_status st = sl_bake_store_encoded(b, cell, buf, size, count, seconds, true, err);
    if (buf != stack)
        sl_free(b->a, buf, cap);
    return st;
}

sl_status sl_bake_finish(sl_bake *b, const char *output, const sl_pvs_build_options *opt, sl_error *err)
{
    if (b->done_count != b->cell_count)
        return sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: %u of %u cells done", b->done_count, b->cell_count);
    uint64_t total = 0;
    for (uint32_t c = 0; c < b->cell_count; c++)
        total += b->counts[c];
    uint64_t *offsets = sl_alloc(b->a, ((size_t)b->cell_count + 1) * sizeof *offsets);
    uint32_t *ids = sl_alloc(b->a, ((size_t)total + 1) * sizeof *ids);
    sl_status st = SL_OK;
    if (!offsets || !ids)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for %llu ids", (unsigned long long)total);
    uint64_t at = 0;
    for (uint32_t c = 0; c < b->cell_count && st == SL_OK; c++) {
        offsets[c] = at;
        if (!sl_pvs_decode(b->enc[c], b->enc[c] + b->enc_size[c], b->counts[c], b->object_count, ids + at))
            st = sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: cell %u's stored set does not decode", c);
        at += b->counts[c];
    }
    /* the motion regions: marked here, after every cell, on the writing process (docs/motion.md) */
    sl_motion_regions mr = {0};
    if (st == SL_OK && !(opt && opt->no_regions)) {
        double t0 = sl_now();
        st = sl_motion_regions_update(b->scene, b->cells, !strcmp(b->method->name, "adjustable") ? b->effective : NULL,
                                      opt ? opt->threads : 0, b->region_old, b->region_keep, b->a, &mr,
                                      &b->region_copied, err);
        b->region_seconds = sl_now() - t0;
        b->regions = mr.count;
    }
    if (st == SL_OK) {
        offsets[b->cell_count] = at;
        /* metadata: only what determines the sets (no timings, no thread counts), so that the
         * bytes do not depend on how the bake ran */
        char meta[SL_OPTS_MAX_CHARS + 512], rline[64] = "";
        if (mr.count)
            snprintf(rline, sizeof rline, "regions=%u\n", mr.count);
        snprintf(meta, sizeof meta,
                 "generator=sightline %s\nmethod=%s\noptions=%s\nguarantee=%s\ncells=%u\nobjects=%u\n"
                 "occluders_removed=%llu\n%s",
                 sl_version_string(), b->method->name, b->effective, sl_cull_guarantee_name(b->method->guarantee),
                 b->cell_count, b->object_count, (unsigned long long)b->removed, rline);
        sl_pvs_regions pr = {mr.nodes, mr.count, mr.rows};
        st = sl_pvs_write_regions(output, b->cells, b->object_count, sl_pvs_scene_key(b->scene), offsets, ids, meta,
                                  &pr, err);
    }
    sl_motion_regions_free(b->a, &mr);
    sl_free(b->a, offsets, ((size_t)b->cell_count + 1) * sizeof *offsets);
    sl_free(b->a, ids, ((size_t)total + 1) * sizeof *ids);
    if (st == SL_OK && b->fd >= 0) {
        close(b->fd);
        b->fd = -1;
        if (!(opt && opt->keep_checkpoint))
            unlink(b->journal);
    }
    return st;
}

void sl_bake_note_kept(const sl_bake *b, sl_error *err)
{
    if (!err || b->fd < 0 || b->done_count == 0)
        return;
    size_t k = strnlen(err->message, sizeof err->message);
    snprintf(err->message + k, sizeof err->message - k, " (%u of %u cells are kept in %s: --resume continues)",
             b->done_count, b->cell_count, b->journal);
}

void sl_bake_stats(const sl_bake *b, sl_pvs_build_stats *out)
{
    out->cells = b->cell_count;
    out->cells_baked = b->baked;
    out->cells_resumed = b->resumed;
    out->cell_seconds = b->cell_seconds;
    out->max_cell_seconds = b->max_cell_seconds;
    out->occluders_removed = b->removed;
    out->regions = b->regions;
    out->region_seconds = b->region_seconds;
    if (b->method) {
        snprintf(out->method, sizeof out->method, "%s", b->method->name);
        size_t n = strlen(b->effective);
        if (n >= sizeof out->options)
            n = sizeof out->options - 1;
        memcpy(out->options, b->effective, n);
        out->options[n] = 0;
        out->notice[0] = 0;
        if (b->method->notice && b->config)
            b->method->notice(b->config, out->notice, sizeof out->notice);
    }
    uint64_t total = 0;
    double culled = 0;
    if (b->counts)
        for (uint32_t c = 0; c < b->cell_count; c++) {
            total += b->counts[c];
            culled += b->object_count ? 1.0 - (double)b->counts[c] / b->object_count : 0;
        }
    out->visible_total = total;
    out->mean_culled = b->cell_count ? culled / b->cell_count : 0;
}

void sl_bake_end(sl_bake *b)
{
    if (!b->a)
        return;
    if (b->shared)
        b->method->release(b->shared);
    if (b->config)
        sl_free(b->a, b->config, b->method->config_size ? b->method->config_size : 1);
    if (b->enc)
        for (uint32_t c = 0; c < b->cell_count; c++)
            if (b->enc[c])
                sl_free(b->a, b->enc[c], b->enc_size[c] ? b->enc_size[c] : 1);
    size_t nc = b->cell_count;
    sl_free(b->a, b->enc, nc * sizeof *b->enc);
    sl_free(b->a, b->enc_size, nc * sizeof *b->enc_size);
    sl_free(b->a, b->counts, nc * sizeof *b->counts);
    sl_free(b->a, b->done, nc);
    if (b->scratch)
        sl_free(b->a, b->scratch, ((size_t)b->object_count + 1) * sizeof(uint32_t));
    if (b->fd >= 0) {
        (void)fdatasync(b->fd);
        close(b->fd);
    }
    bake_unlock(b);
    if (b->lock_path)
        sl_free(b->a, b->lock_path, strlen(b->lock_path) + 1);
    if (b->output)
        sl_free(b->a, b->output, strlen(b->output) + 1);
    if (b->journal)
        sl_free(b->a, b->journal, strlen(b->journal) + 1);
    memset(b, 0, sizeof *b);
    b->fd = -1;
    b->lock_fd = -1;
}

/* ---- the OpenMP driver ---- */

typedef struct shared_run {
    sl_bake *b;
    const sl_pvs_build_options *opt;
    const uint32_t *todo;
    uint32_t todo_count;
    volatile int stop;          /* 1: error, 2: cancelled, 3: stop_after reached */
    sl_status st;
    sl_error first_err;
} shared_run;

sl_status sl_pvs_build(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                       sl_pvs_build_stats *stats, sl_error *err)
{
    double t0 = sl_now();
    if (stats)
        memset(stats, 0, sizeof *stats);
    sl_bake b;
    sl_status st = sl_bake_begin(&b, scene, cells, output, opt, true, err);
    if (st != SL_OK) {
        sl_bake_end(&b);
        return st;
    }
    uint32_t *todo = sl_alloc(b.a, (size_t)b.cell_count * sizeof(uint32_t));
    if (!todo) {
        sl_bake_end(&b);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    }
    uint32_t nt = 0;
    for (uint32_t c = 0; c < b.cell_count; c++)
        if (!b.done[c])
            todo[nt++] = c;
    int threads = opt && opt->threads ? (int)opt->threads : omp_get_max_threads();
    threads = SL_MAX(1, SL_MIN(threads, (int)sl_thread_limit()));
    shared_run run;
    memset(&run, 0, sizeof run);
    run.b = &b;
    run.opt = opt;
    run.todo = todo;
    run.todo_count = nt;
    uint32_t stop_after = opt ? opt->stop_after : 0;
    const sl_progress *progress = opt ? &opt->progress : NULL;
    sl_progress_report(progress, "baking cells", b.done_count, b.cell_count);

#pragma omp parallel num_threads(threads)
    {
        void *worker = NULL;
        sl_error terr;
        uint32_t *ids = sl_alloc(b.a, ((size_t)b.object_count + 1) * sizeof(uint32_t));
        sl_status ts = ids ? b.method->worker_create(b.shared, &worker, &terr)
                           : sl_fail(&terr, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
        if (ts != SL_OK) {
#pragma omp critical(sl_pvs_bake)
            if (!run.stop) {
                run.stop = 1;
                run.st = ts;
                run.first_err = terr;
            }
        }
#pragma omp for schedule(dynamic, 1)
        for (uint32_t i = 0; i < nt; i++) {
            if (run.stop || ts != SL_OK)
                continue;
            uint32_t cell = todo[i];
            sl_pvs_cell_result res = {ids, 0, 0};
            double c0 = sl_now();
            sl_status cs = b.method->cell(worker, cell, &res, &terr);
            double secs = sl_now() - c0;
#pragma omp critical(sl_pvs_bake)
            {
                if (cs == SL_OK && !run.stop)
                    cs = sl_bake_store(&b, cell, ids, res.count, secs, &terr);
                if (cs != SL_OK && !run.stop) {
                    run.stop = 1;
                    run.st = cs;
                    run.first_err = terr;
                    sl_error_prefix(&run.first_err, "cell %u", cell);
                }
                if (!run.stop) {
                    b.baked++;
                    if (!sl_progress_report(progress, "baking cells", b.done_count, b.cell_count))
                        run.stop = 2;
                    else if (stop_after && b.baked >= stop_after && b.done_count < b.cell_count)
                        run.stop = 3;
                }
            }
        }
        if (worker)
            b.method->worker_destroy(worker);
        sl_free(b.a, ids, ((size_t)b.object_count + 1) * sizeof(uint32_t));
    }
    sl_free(b.a, todo, (size_t)b.cell_count * sizeof(uint32_t));

    if (run.stop == 1) {
        if (err)
            *err = run.first_err;
        st = run.st;
        sl_bake_note_kept(&b, err);
    } else if (run.stop == 2) {
        st = sl_fail(err, SL_ERROR_CANCELLED, "pvs bake: cancelled after %u of %u cells; resume from %s", b.done_count,
                     b.cell_count, b.journal);
    } else if (run.stop == 3) {
        st = sl_fail(err, SL_ERROR_CANCELLED,
                     "pvs bake: stopped after %u newly baked cells as asked (%u of %u done); resume from %s", b.baked,
                     b.done_count, b.cell_count, b.journal);
    } else {
        st = sl_bake_finish(&b, output, opt, err);
    }
    if (stats) {
        sl_bake_stats(&b, stats);
        stats->processes = 1;
        stats->threads = (uint32_t)threads;
        stats->seconds = sl_now() - t0;
        struct stat sb;
        if (st == SL_OK && stat(output, &sb) == 0)
            stats->file_bytes = (uint64_t)sb.st_size;
    }
    sl_bake_end(&b);
    return st;
}

sl_status sl_pvs_bake_cell(sl_scene scene, sl_viewcells cells, uint32_t cell, const char *method,
                           const char *method_options, uint32_t *ids, uint32_t capacity, uint32_t *count, sl_error *err)
{
    if (count)
        *count = 0;
    if (!scene || !cells || !ids || !count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_bake_cell: arguments must not be NULL");
    if (cell >= sl_viewcells_count(cells))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_bake_cell: cell %u does not exist (%u cells)", cell,
                       sl_viewcells_count(cells));
    if (capacity < sl_scene_object_count(scene))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_bake_cell: capacity %u is below the object count %u",
                       capacity, sl_scene_object_count(scene));
    sl_pvs_build_options o;
    memset(&o, 0, sizeof o);
    o.method = method;
    o.method_options = method_options;
    sl_bake b;
    sl_status st = sl_bake_begin(&b, scene, cells, NULL, &o, false, err);
    void *worker = NULL;
    if (st == SL_OK)
        st = b.method->worker_create(b.shared, &worker, err);
    if (st == SL_OK) {
        sl_pvs_cell_result res = {ids, 0, 0};
        st = b.method->cell(worker, cell, &res, err);
        if (st == SL_OK)
            *count = res.count;
    }
    if (worker)
        b.method->worker_destroy(worker);
    sl_bake_end(&b);
    return st;
}

/* ---- the journal reader alone (fuzz/fuzz_journal.c) ---- */

sl_status sl_bake_journal_check(const uint8_t *data, size_t size, uint32_t cell_count, uint32_t object_count,
                                uint64_t key, const sl_allocator *alloc, size_t *valid, uint32_t *resumed,
                                sl_error *err)
{
    sl_bake b;
    memset(&b, 0, sizeof b);
    b.fd = -1;
    b.lock_fd = -1;
    b.a = sl_alloc_or_default(alloc);
    b.cell_count = cell_count;
    b.object_count = object_count;
    b.key = key;
    b.writer = true;
    *valid = 0;
    *resumed = 0;
    sl_status st = SL_OK;
    size_t nc = cell_count ? cell_count : 1;
    b.enc = sl_calloc(b.a, nc, sizeof *b.enc);
    b.enc_size = sl_calloc(b.a, nc, sizeof *b.enc_size);
    b.counts = sl_calloc(b.a, nc, sizeof *b.counts);
    b.done = sl_calloc(b.a, nc, 1);
    b.scratch = sl_alloc(b.a, ((size_t)object_count + 1) * sizeof(uint32_t));
    b.journal = sl_alloc(b.a, sizeof "journal");
    if (!b.enc || !b.enc_size || !b.counts || !b.done || !b.scratch || !b.journal || !data) {
        st = sl_fail(err, data ? SL_ERROR_OUT_OF_MEMORY : SL_ERROR_INVALID_ARGUMENT, "journal: out of memory or no data");
    } else {
        memcpy(b.journal, "journal", sizeof "journal");
        char why[400];
        size_t at = 0;
        journal_verdict v = journal_examine(&b, data, size, &at, why, sizeof why);
        if (v == J_SAME)
            st = journal_replay(&b, data, size, at, valid, err);
        else
            st = sl_fail(err, v == J_BAD ? SL_ERROR_FORMAT : SL_ERROR_INVALID_ARGUMENT, "journal: %s", why);
        *resumed = b.resumed;
    }
    b.cell_count = (uint32_t)nc;
    sl_bake_end(&b);
    return st;
}

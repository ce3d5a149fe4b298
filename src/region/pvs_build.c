/* Baking a PVS on all cores: cells dealt dynamically to OpenMP threads, results merged in cell
 * order, and a checkpoint journal that lets an interrupted bake resume.
 *
 * Determinism: a method computes each cell's set from (scene, cells, options, cell) alone (the
 * contract in pvs_internal.h), and the file is written in cell order with no timing or thread
 * count in it, so the output is the same bytes whatever the thread count, the process count
 * (pvs_mpi.c) or the order cells finished in.
 *
 * The journal ("<output>.ckpt" unless named): a 64-byte header (magic, version, the bake key that
 * ties it to the scene, cells, method and effective options, counts, checksum), then one record per
 * finished cell, appended as soon as the cell is done:
 *   u32 tag 'CELL' (0x4c4c4543), u32 cell, u32 count, u32 bytes, u64 XXH3-64 of the 16 bytes
 *   before it and the payload, payload (the set as varint gaps, as in the .slpvs blocks).
 * A killed process leaves at most one partial record at the end; resume reads records while they
 * are whole and valid, cuts the file after the last good one and bakes only the missing cells.
 * Records are written with write(2) (in the kernel once it returns, so a killed process loses
 * nothing finished) and the file is synced every few seconds (power loss costs seconds). */
#include "pvs_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <omp.h>
#include <sys/stat.h>
#include <unistd.h>

#define J_MAGIC "SLPVSCKP"
#define J_VERSION 1u
#define J_HEADER 64u
#define J_RECORD 24u
#define J_TAG 0x4c4c4543u /* "CELL" */
#define J_SYNC_SECONDS 5.0

static inline void wr32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static inline void wr64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }
static inline uint32_t rd32(const uint8_t *p)
{
    uint32_t v;
    memcpy(&v, p, 4);
    return v;
}
static inline uint64_t rd64(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, 8);
    return v;
}

/* ---- journal ---- */

static void journal_header(const sl_bake *b, uint8_t h[J_HEADER])
{
    memset(h, 0, J_HEADER);
    memcpy(h, J_MAGIC, 8);
    wr32(h + 8, J_VERSION);
    wr32(h + 12, b->cell_count);
    wr32(h + 16, b->object_count);
    wr64(h + 24, b->key);
    wr64(h + 56, sl_hash64(h, 56, 0));
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

/* Read the journal's records into the results; returns the length of its valid prefix. */
static sl_status journal_replay(sl_bake *b, const uint8_t *data, size_t size, size_t *valid, sl_error *err)
{
    uint8_t want[J_HEADER];
    journal_header(b, want);
    if (size < J_HEADER || memcmp(data, J_MAGIC, 8) != 0)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset 0: not a PVS checkpoint journal", b->journal);
    if (rd64(data + 56) != sl_hash64(data, 56, 0))
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset 56: journal header checksum mismatch", b->journal);
    if (rd32(data + 8) != J_VERSION)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: journal version %u (this build writes %u)", b->journal,
                       rd32(data + 8), J_VERSION);
    if (memcmp(data, want, J_HEADER) != 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the checkpoint belongs to another bake (different scene, cells, method or options): "
                       "delete it or bake with the same inputs",
                       b->journal);
    size_t at = J_HEADER;
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

static sl_status journal_open(sl_bake *b, const char *output, const sl_pvs_build_options *opt, sl_error *err)
{
    const char *named = opt && opt->checkpoint ? opt->checkpoint : NULL;
    size_t n = named ? strlen(named) + 1 : strlen(output) + 6;
    b->journal = sl_alloc(b->a, n);
    if (!b->journal)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    if (named)
        memcpy(b->journal, named, n);
    else
        snprintf(b->journal, n, "%s.ckpt", output);
    bool resume = opt && opt->resume;
    struct stat sb;
    bool exists = stat(b->journal, &sb) == 0;
    if (exists && !resume)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: a checkpoint of an interrupted bake exists: resume it (--resume) or delete it", b->journal);
    if (exists) {
        uint8_t *data = NULL;
        size_t size = 0;
        sl_status st = sl_file_read_all(b->a, b->journal, &data, &size, err);
        if (st != SL_OK)
            return st;
        size_t valid = 0;
        st = journal_replay(b, data, size, &valid, err);
        sl_free(b->a, data, size);
        if (st != SL_OK)
            return st;
        b->fd = open(b->journal, O_WRONLY | O_CLOEXEC);
        if (b->fd < 0 || ftruncate(b->fd, (off_t)valid) != 0 || lseek(b->fd, (off_t)valid, SEEK_SET) < 0)
            return sl_fail(err, SL_ERROR_IO, "%s: cannot reopen the checkpoint: %s", b->journal, strerror(errno));
        return SL_OK;
    }
    b->fd = open(b->journal, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (b->fd < 0)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot create the checkpoint: %s", b->journal, strerror(errno));
    uint8_t h[J_HEADER];
    journal_header(b, h);
    if (!write_all(b->fd, h, sizeof h) || fdatasync(b->fd) != 0)
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
    sl_status st = sl_pvs_registry_find(opt ? opt->method : NULL, &b->method, err);
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
    if (st == SL_OK) {
        offsets[b->cell_count] = at;
        /* metadata: only what determines the sets (no timings, no thread counts), so that the
         * bytes do not depend on how the bake ran */
        char meta[SL_OPTS_MAX_CHARS + 512];
        snprintf(meta, sizeof meta,
                 "generator=sightline %s\nmethod=%s\noptions=%s\nguarantee=%s\ncells=%u\nobjects=%u\n"
                 "occluders_removed=%llu\n",
                 sl_version_string(), b->method->name, b->effective, sl_cull_guarantee_name(b->method->guarantee),
                 b->cell_count, b->object_count, (unsigned long long)b->removed);
        st = sl_pvs_write(output, b->cells, b->object_count, sl_pvs_scene_key(b->scene), offsets, ids, meta, err);
    }
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

void sl_bake_stats(const sl_bake *b, sl_pvs_build_stats *out)
{
    out->cells = b->cell_count;
    out->cells_baked = b->baked;
    out->cells_resumed = b->resumed;
    out->cell_seconds = b->cell_seconds;
    out->max_cell_seconds = b->max_cell_seconds;
    out->occluders_removed = b->removed;
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
    if (b->journal)
        sl_free(b->a, b->journal, strlen(b->journal) + 1);
    memset(b, 0, sizeof *b);
    b->fd = -1;
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
    if (threads < 1)
        threads = 1;
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
        st = journal_replay(&b, data, size, valid, err);
        *resumed = b.resumed;
    }
    b.cell_count = (uint32_t)nc;
    sl_bake_end(&b);
    return st;
}

/* Baking a PVS across the processes of an MPI job (MPICH): `mpiexec -n N sightline pvs build ...`.
 *
 * Every process loads the same scene, makes the same cells and prepares the method; the keys of
 * the scene, the cells and the options are compared first so that a process started with other
 * inputs stops the job with a clear message instead of poisoning it. Process 0 is the master: it
 * keeps the checkpoint journal (resuming from it when asked), hands out cells dynamically in chunks
 * of as many cells as a worker has threads, stores every set a worker sends back (in the journal at
 * once), and writes the file in cell order at the end — so the bytes are those of a one-process
 * bake whatever N is. Workers bake their chunk with OpenMP, one cell per thread.
 *
 * Messages (MPI_BYTE, tag 1 worker->master, tag 2 master->worker):
 *   worker: u32 want (cells it can take next; 0: it stops), u32 status, char[256] message,
 *           u32 count, then per finished cell: u32 cell, u32 ids, u32 bytes, f64 seconds, bytes
 *   master: u32 n, then n cell numbers (n = 0: no more work)
 * A process that dies takes the job down (mpiexec); the journal keeps every cell the master had
 * received, and `--resume` continues from there with any number of processes. With N = 1 the
 * thread driver (pvs_build.c) runs instead: same file. The master polls for messages with short
 * sleeps instead of a blocking probe (MPICH busy-waits in one), so it costs the workers no core;
 * it does not bake cells itself: N processes are N - 1 workers. */
#include "pvs_internal.h"

#include <math.h>
#include <sys/stat.h>
#include <time.h>

#ifndef SL_HAVE_MPI

sl_status sl_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                           sl_pvs_build_stats *stats, int *rank, sl_error *err)
{
    (void)scene, (void)cells, (void)output, (void)opt;
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (rank)
        *rank = 0;
    return sl_fail(err, SL_ERROR_UNSUPPORTED, "pvs bake: this Sightline was built without MPI (install libmpich-dev "
                                              "and reconfigure)");
}

#else

#include <mpi.h>
#include <omp.h>

#define TAG_RESULT 1
#define TAG_WORK 2
#define MSG_HEAD (4 + 4 + 256 + 4)
#define REC_HEAD (4 + 4 + 4 + 8)

static inline void wr32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static inline uint32_t rd32(const uint8_t *p)
{
    uint32_t v;
    memcpy(&v, p, 4);
    return v;
}

/* All processes agree on a status: the worst one wins, with its message from the lowest rank that
 * has it. */
static sl_status agree(sl_status st, sl_error *err, int rank)
{
    int mine = (int)st, worst = 0;
    MPI_Allreduce(&mine, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (worst == SL_OK)
        return SL_OK;
    int who = mine == worst ? rank : INT32_MAX, first = 0;
    MPI_Allreduce(&who, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    char msg[512];
    memset(msg, 0, sizeof msg);
    if (rank == first && err)
        snprintf(msg, sizeof msg, "%s", err->message);
    MPI_Bcast(msg, sizeof msg, MPI_CHAR, first, MPI_COMM_WORLD);
    if (err && rank != first)
        sl_fail(err, (sl_status)worst, "process %d: %s", first, msg);
    return (sl_status)worst;
}

/* ---- master ---- */

static sl_status master(sl_bake *b, const sl_pvs_build_options *opt, int nproc, sl_error *err)
{
    uint32_t *todo = sl_alloc(b->a, ((size_t)b->cell_count + 1) * sizeof(uint32_t));
    if (!todo)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    uint32_t nt = 0, next = 0;
    for (uint32_t c = 0; c < b->cell_count; c++)
        if (!b->done[c])
            todo[nt++] = c;
    uint32_t stop_after = opt ? opt->stop_after : 0;
    const sl_progress *progress = opt ? &opt->progress : NULL;
    sl_status st = SL_OK;
    int stopping = 0; /* 1: error, 2: cancelled, 3: stop_after */
    int active = nproc - 1;
    uint8_t *buf = NULL;
    size_t cap = 0;
    uint8_t *reply = sl_alloc(b->a, 4 + 4 * 4096);
    if (!reply) {
        sl_free(b->a, todo, ((size_t)b->cell_count + 1) * sizeof(uint32_t));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    }
    while (active > 0) {
        /* poll with short sleeps: a blocking probe busy-waits in MPICH and would take a core from
         * the workers for nothing */
        MPI_Status ms;
        for (int flag = 0;;) {
            MPI_Iprobe(MPI_ANY_SOURCE, TAG_RESULT, MPI_COMM_WORLD, &flag, &ms);
            if (flag)
                break;
            struct timespec ts = {0, 200000};
            nanosleep(&ts, NULL);
        }
        int size = 0;
        MPI_Get_count(&ms, MPI_BYTE, &size);
        if ((size_t)size > cap) {
            uint8_t *nb = sl_realloc(b->a, buf, cap, (size_t)size);
            if (!nb) {
                /* cannot even read the message: give up on the whole job */
                MPI_Abort(MPI_COMM_WORLD, 2);
            }
            buf = nb;
            cap = (size_t)size;
        }
        MPI_Recv(buf, size, MPI_BYTE, ms.MPI_SOURCE, TAG_RESULT, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        int src = ms.MPI_SOURCE;
        uint32_t want = 0;
        if (size < MSG_HEAD) {
            if (!stopping) {
                st = sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: process %d sent a short message", src);
                stopping = 1;
            }
        } else {
            want = SL_MIN(rd32(buf), 4096u);
            uint32_t wst = rd32(buf + 4), count = rd32(buf + 264);
            if (wst != SL_OK && !stopping) {
                char msg[257];
                memcpy(msg, buf + 8, 256);
                msg[256] = 0;
                st = sl_fail(err, (sl_status)wst, "process %d: %s", src, msg);
                stopping = 1;
            }
            size_t at = MSG_HEAD;
            for (uint32_t k = 0; k < count; k++) {
                if ((size_t)size - at < REC_HEAD) {
                    if (!stopping) {
                        st = sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: process %d sent a truncated result", src);
                        stopping = 1;
                    }
                    break;
                }
                uint32_t cell = rd32(buf + at), ids = rd32(buf + at + 4), bytes = rd32(buf + at + 8);
                double secs;
                memcpy(&secs, buf + at + 12, 8);
                at += REC_HEAD;
                if (bytes > (size_t)size - at) {
                    if (!stopping) {
                        st = sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: process %d sent a truncated set", src);
                        stopping = 1;
                    }
                    break;
                }
                if (!stopping || stopping == 3) {
                    /* a cell finished after stop_after is still kept: nothing is lost */
                    sl_error e2;
                    sl_status s2 = cell < b->cell_count && !b->done[cell]
                                       ? sl_bake_store_encoded(b, cell, buf + at, bytes, ids, secs, true, &e2)
                                       : sl_fail(&e2, SL_ERROR_INTERNAL, "pvs bake: process %d returned cell %u twice",
                                                 src, cell);
                    if (s2 != SL_OK) {
                        if (!stopping || stopping == 3) {
                            st = s2;
                            if (err)
                                *err = e2;
                        }
                        stopping = 1;
                    } else {
                        b->baked++;
                        if (!stopping && !sl_progress_report(progress, "baking cells", b->done_count, b->cell_count))
                            stopping = 2;
                        else if (!stopping && stop_after && b->baked >= stop_after && b->done_count < b->cell_count)
                            stopping = 3;
                    }
                }
                at += bytes;
            }
        }
        uint32_t n = 0;
        if (!stopping && want > 0) {
            while (n < want && next < nt)
                wr32(reply + 4 + 4 * n++, todo[next++]);
        }
        wr32(reply, n);
        MPI_Send(reply, (int)(4 + 4 * n), MPI_BYTE, src, TAG_WORK, MPI_COMM_WORLD);
        if (n == 0)
            active--;
    }
    sl_free(b->a, buf, cap);
    sl_free(b->a, reply, 4 + 4 * 4096);
    sl_free(b->a, todo, ((size_t)b->cell_count + 1) * sizeof(uint32_t));
    if (stopping == 2)
        st = sl_fail(err, SL_ERROR_CANCELLED, "pvs bake: cancelled after %u of %u cells; resume from %s", b->done_count,
                     b->cell_count, b->journal);
    else if (stopping == 3)
        st = sl_fail(err, SL_ERROR_CANCELLED,
                     "pvs bake: stopped after %u newly baked cells as asked (%u of %u done); resume from %s", b->baked,
                     b->done_count, b->cell_count, b->journal);
    return st;
}

/* ---- worker ---- */

static sl_status worker(sl_bake *b, int threads, sl_error *err)
{
    const sl_allocator *a = b->a;
    void **workers = sl_calloc(a, (size_t)threads, sizeof(void *));
    uint32_t **ids = sl_calloc(a, (size_t)threads, sizeof(uint32_t *));
    uint32_t *cells = sl_alloc(a, 4096 * sizeof(uint32_t));
    sl_array out = {0}; /* the message under construction */
    sl_status st = SL_OK;
    if (!workers || !ids || !cells)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    for (int t = 0; t < threads && st == SL_OK; t++) {
        ids[t] = sl_alloc(a, ((size_t)b->object_count + 1) * sizeof(uint32_t));
        if (!ids[t])
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
        else
            st = b->method->worker_create(b->shared, &workers[t], err);
    }
    /* per chunk: the encoded sets, cell by cell */
    typedef struct done_cell {
        uint32_t cell, ids;
        double seconds;
        uint8_t *bytes;
        uint32_t size;
        sl_status st;
        sl_error err;
    } done_cell;
    done_cell *res = sl_calloc(a, (size_t)threads, sizeof(done_cell));
    if (!res && st == SL_OK)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    uint32_t nres = 0;
    for (;;) {
        /* report the last chunk (or the error) and ask for more */
        out.count = 0;
        uint8_t head[MSG_HEAD];
        memset(head, 0, sizeof head);
        wr32(head, st == SL_OK ? (uint32_t)threads : 0);
        wr32(head + 4, (uint32_t)st);
        if (st != SL_OK && err)
            memcpy(head + 8, err->message, SL_MIN(sizeof err->message, (size_t)255));
        wr32(head + 264, st == SL_OK ? nres : 0);
        bool ok = sl_array_push(a, &out, 1, head, sizeof head) != NULL;
        for (uint32_t k = 0; k < nres && st == SL_OK && ok; k++) {
            uint8_t rh[REC_HEAD];
            wr32(rh, res[k].cell);
            wr32(rh + 4, res[k].ids);
            wr32(rh + 8, res[k].size);
            memcpy(rh + 12, &res[k].seconds, 8);
            ok = sl_array_push(a, &out, 1, rh, sizeof rh) && (res[k].size == 0 || sl_array_push(a, &out, 1, res[k].bytes, res[k].size));
        }
        for (uint32_t k = 0; k < nres; k++) {
            sl_free(a, res[k].bytes, (size_t)res[k].ids * 5 + 1);
            res[k].bytes = NULL;
        }
        nres = 0;
        if (!ok) {
            /* tell the master with a bare header */
            uint8_t bare[MSG_HEAD];
            memset(bare, 0, sizeof bare);
            wr32(bare + 4, SL_ERROR_OUT_OF_MEMORY);
            snprintf((char *)bare + 8, 256, "out of memory for a result message");
            MPI_Send(bare, MSG_HEAD, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD);
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
        } else {
            MPI_Send(out.data, (int)out.count, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD);
        }
        uint8_t work[4 + 4 * 4096];
        MPI_Status ms;
        MPI_Recv(work, sizeof work, MPI_BYTE, 0, TAG_WORK, MPI_COMM_WORLD, &ms);
        int got = 0;
        MPI_Get_count(&ms, MPI_BYTE, &got);
        uint32_t n = got >= 4 ? rd32(work) : 0;
        if (n == 0 || (size_t)got < 4 + 4 * (size_t)n || n > (uint32_t)threads)
            break;
        for (uint32_t k = 0; k < n; k++)
            cells[k] = rd32(work + 4 + 4 * k);
#pragma omp parallel for num_threads(threads) schedule(static, 1)
        for (uint32_t k = 0; k < n; k++) {
            int t = omp_get_thread_num();
            done_cell *d = &res[k];
            d->cell = cells[k];
            d->bytes = NULL;
            d->st = SL_OK;
            if (cells[k] >= b->cell_count) {
                d->st = sl_fail(&d->err, SL_ERROR_INTERNAL, "pvs bake: the master sent cell %u of %u", cells[k],
                                b->cell_count);
                continue;
            }
            sl_pvs_cell_result r = {ids[t], 0, 0};
            double c0 = sl_now();
            d->st = b->method->cell(workers[t], cells[k], &r, &d->err);
            d->seconds = sl_now() - c0;
            if (d->st != SL_OK) {
                sl_error_prefix(&d->err, "cell %u", cells[k]);
                continue;
            }
            d->ids = r.count;
            d->bytes = sl_alloc(a, (size_t)r.count * 5 + 1);
            if (!d->bytes)
                d->st = sl_fail(&d->err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for cell %u", cells[k]);
            else
                d->size = (uint32_t)sl_pvs_encode(ids[t], r.count, d->bytes);
        }
        nres = n;
        for (uint32_t k = 0; k < n; k++)
            if (res[k].st != SL_OK && st == SL_OK) {
                st = res[k].st;
                if (err)
                    *err = res[k].err;
            }
    }
    for (uint32_t k = 0; res && k < (uint32_t)threads; k++)
        sl_free(a, res[k].bytes, (size_t)res[k].ids * 5 + 1);
    sl_free(a, res, (size_t)threads * sizeof(done_cell));
    for (int t = 0; t < threads; t++) {
        if (workers && workers[t])
            b->method->worker_destroy(workers[t]);
        if (ids)
            sl_free(a, ids[t], ((size_t)b->object_count + 1) * sizeof(uint32_t));
    }
    sl_free(a, workers, (size_t)threads * sizeof(void *));
    sl_free(a, ids, (size_t)threads * sizeof(uint32_t *));
    sl_free(a, cells, 4096 * sizeof(uint32_t));
    sl_array_free(a, &out, 1);
    return st;
}

sl_status sl_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                           sl_pvs_build_stats *stats, int *rank_out, sl_error *err)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (rank_out)
        *rank_out = 0;
    int inited = 0, finalized = 0;
    MPI_Initialized(&inited);
    MPI_Finalized(&finalized);
    if (finalized)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "pvs bake: MPI was already finalized in this process");
    bool own = !inited;
    if (own) {
        int provided;
        if (MPI_Init_thread(NULL, NULL, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
            return sl_fail(err, SL_ERROR_INTERNAL, "pvs bake: MPI_Init failed");
    }
    int rank = 0, nproc = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &nproc);
    if (rank_out)
        *rank_out = rank;
    sl_status st;
    if (nproc == 1) {
        st = sl_pvs_build(scene, cells, output, opt, stats, err);
        if (own)
            MPI_Finalize();
        return st;
    }
    double t0 = MPI_Wtime();
    int threads = opt && opt->threads ? (int)opt->threads : omp_get_max_threads();
    threads = SL_MAX(1, SL_MIN(threads, 4096));
    sl_bake b;
    st = sl_bake_begin(&b, scene, cells, output, opt, rank == 0, err);
    st = agree(st, err, rank);
    if (st == SL_OK) {
        /* every process must bake the same thing: compare the bake keys */
        uint64_t key = b.key, root = b.key;
        MPI_Bcast(&root, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
        if (key != root)
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                         "pvs bake: process %d has another scene, cells, method or options than process 0", rank);
        st = agree(st, err, rank);
    }
    if (st == SL_OK)
        st = rank == 0 ? master(&b, opt, nproc, err) : worker(&b, threads, err);
    /* the master's verdict (and the file) is the job's; every process takes part */
    if (rank == 0 && st == SL_OK)
        st = sl_bake_finish(&b, output, opt, err);
    int verdict = (int)st;
    MPI_Bcast(&verdict, 1, MPI_INT, 0, MPI_COMM_WORLD);
    char msg[512];
    memset(msg, 0, sizeof msg);
    if (rank == 0 && verdict != SL_OK && err)
        snprintf(msg, sizeof msg, "%s", err->message);
    MPI_Bcast(msg, sizeof msg, MPI_CHAR, 0, MPI_COMM_WORLD);
    if (rank != 0 && verdict != SL_OK && st == SL_OK)
        st = sl_fail(err, (sl_status)verdict, "process 0: %s", msg);
    if (stats) {
        sl_bake_stats(&b, stats);
        stats->processes = (uint32_t)nproc;
        stats->threads = (uint32_t)threads;
        stats->seconds = MPI_Wtime() - t0;
        struct stat sb;
        if (rank == 0 && st == SL_OK && stat(output, &sb) == 0)
            stats->file_bytes = (uint64_t)sb.st_size;
    }
    sl_bake_end(&b);
    if (own)
        MPI_Finalize();
    return st;
}

#endif

/* Baking a PVS across the processes of an MPI job (MPICH): `mpiexec -n N sightline pvs build ...`.
 * Part of the command, not of libsightline (tools/pvs_cli.h says why); it drives the library's
 * bake through the public bake session (include/sightline/bake.h: sl_bake_session_*), the same
 * bake the thread driver uses.
 *
 * Every process loads the same scene, makes the same cells and prepares the method; the keys of
 * the scene, the cells and the options are compared first so that a process started with other
 * inputs stops the job with a clear message instead of poisoning it. Process 0 keeps the
 * checkpoint journal (resuming from it when asked), stores every finished set (in the journal at
 * once) and writes the file in cell order at the end — so the bytes are those of a one-process
 * bake whatever N is.
 *
 * Process 0 bakes too. Its main thread serves the others (the only thread that calls MPI:
 * MPI_THREAD_FUNNELED) while `threads` more OpenMP threads bake cells from the same queue, one at
 * a time; the other processes bake chunks of as many cells as they have threads. The server polls
 * for messages with short sleeps instead of a blocking probe (MPICH busy-waits in one), so it
 * costs the bakers almost no core. With one process the thread driver (sl_pvs_build) runs.
 *
 * Messages (MPI_BYTE, tag 1 worker->master, tag 2 master->worker):
 *   worker: u32 want (cells it can take next; 0: it stops), u32 status, char[256] message (the
 *           error, or "pid N on HOST" when the status is OK), u32 count, then per finished cell:
 *           u32 cell, u32 ids, u32 bytes, f64 seconds, bytes
 *   master: u32 n, then n cell numbers (n = 0: no more work); the answer to a request may wait
 *           while cells are out elsewhere (leases, below), so workers poll for it with sleeps
 * A process that dies takes the job down (mpiexec); the journal keeps every cell process 0 had
 * stored, and `--resume` continues from there with any number of processes. A process that stops
 * without dying (SIGSTOP, a hang) loses its lease: see "Leases" below. */
#include "pvs_cli.h"

#include "tool.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#ifndef SL_HAVE_MPI

sl_status cli_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                            double lease, sl_pvs_build_stats *stats, int *rank, sl_error *err)
{
    (void)scene, (void)cells, (void)output, (void)opt, (void)lease;
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (rank)
        *rank = 0;
    return tool_fail(err, SL_ERROR_UNSUPPORTED, "pvs bake: this sightline command was built without MPI (install "
                                              "libmpich-dev and reconfigure)");
}

#else

#include <mpi.h>
#include <omp.h>

#define TAG_RESULT 1
#define TAG_WORK 2
#define MSG_HEAD (4 + 4 + 256 + 4)
#define REC_HEAD (4 + 4 + 4 + 8)
#define MAX_CHUNK 4096u

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
        tool_fail(err, (sl_status)worst, "process %d: %s", first, msg);
    return (sl_status)worst;
}

/* ---- process 0: the queue, the server and the local bakers ----
 * Everything in master_run is shared by the server thread and the baking threads and touched only
 * inside the critical section sl_pvs_mpi.
 *
 * Leases: a chunk handed to a process is leased to it. A process that asks for work when the
 * queue is empty but cells are still out is not told to stop: its request waits, and once a
 * cell has been out longer than the lease (a process stopped with SIGSTOP, swapped out, hung)
 * the cell is handed to it as well; the first result to arrive is kept and later ones for that
 * cell are dropped (a method's result depends on the cell alone, so the bytes are the same).
 * Process 0's own threads take such cells too. Once every cell is done the file is written at
 * once; a process still holding a chunk (frozen) is then waited for, with a note in the log,
 * since the job ends only when each process does. */

enum { RUN = 0, STOP_ERROR = 1, STOP_CANCELLED = 2, STOP_AFTER = 3 };

typedef struct master_run {
    sl_bake_session b;
    const sl_progress *progress;
    uint32_t stop_after;
    uint32_t *todo, todo_count, next;
    int stopping;               /* RUN or STOP_* */
    sl_status st;
    sl_error err;               /* the first failure */
    /* leases */
    double lease;               /* seconds; 0: never hand a cell out twice */
    int nproc;
    int *holder;                /* per cell: the process that has it (-1: none; 0: process 0's threads) */
    double *given;              /* per cell: when it was handed out */
    uint8_t *reissued;          /* per cell: handed out more than once (a second result is dropped) */
    uint32_t *flight, flight_count; /* cells out at other processes, maybe done since */
    uint32_t *waiting;          /* per process: cells it asked for and still waits for (0: none) */
    uint8_t *busy;              /* per process: holds a chunk it has not reported yet */
    double *heard;              /* per process: when it last sent something */
    char (*who)[64];            /* per process: "pid N on HOST", from its messages */
    uint32_t duplicates;        /* results dropped because another process was first */
} master_run;

/* Record the first failure and stop handing out cells (under the lock). */
static void run_fail(master_run *r, sl_status st, const sl_error *e)
{
    if (r->stopping == RUN || r->stopping == STOP_AFTER) {
        r->stopping = STOP_ERROR;
        r->st = st;
        r->err = *e;
    }
}

/* Whether a finished cell is still stored: always, unless the bake failed or was cancelled (a cell
 * that finishes after stop_after was reached is kept: nothing done is lost). Under the lock. */
static bool run_keeps(const master_run *r) { return r->stopping == RUN || r->stopping == STOP_AFTER; }

/* Nothing more to hand out or wait for: every cell is done, or the bake stops. Under the lock. */
static bool run_over(const master_run *r)
{
    return r->stopping != RUN || sl_bake_session_done_count(r->b) == sl_bake_session_cell_count(r->b);
}

/* A cell was stored: count it, report progress, check stop_after (under the lock). */
static void run_counted(master_run *r)
{
    sl_bake_session b = r->b;
    if (r->stopping != RUN)
        return;
    uint32_t done = sl_bake_session_done_count(b), cells = sl_bake_session_cell_count(b);
    if (!tool_progress(r->progress, "baking cells", done, cells))
        r->stopping = STOP_CANCELLED;
    else if (r->stop_after && sl_bake_session_baked(b) >= r->stop_after && done < cells)
        r->stopping = STOP_AFTER;
}

/* Up to `want` cells for process `rank` (0: process 0's own threads) into out: first cells whose
 * lease ran out at another process, then cells from the queue (under the lock). */
static uint32_t run_take(master_run *r, uint32_t want, uint32_t *out, int rank, double now)
{
    uint32_t n = 0;
    if (r->stopping != RUN)
        return 0;
    if (r->lease > 0) {
        int from = -1;
        uint32_t moved = 0;
        uint32_t keep = 0;
        for (uint32_t i = 0; i < r->flight_count; i++) {
            uint32_t c = r->flight[i];
            if (sl_bake_session_cell_done(r->b, c) || r->holder[c] <= 0)
                continue; /* done, or taken over by process 0's threads: out of flight */
            if (n < want && r->holder[c] != rank && now - r->given[c] >= r->lease && (from < 0 || from == r->holder[c])) {
                from = r->holder[c];
                moved++;
                out[n++] = c;
                r->reissued[c] = 1;
                r->holder[c] = rank;
                r->given[c] = now;
                if (rank == 0)
                    continue; /* process 0's threads do not lose leases */
            }
            r->flight[keep++] = c;
        }
        r->flight_count = keep;
        if (moved)
            fprintf(stderr,
                    "sightline pvs build: process %d (%s) has sent nothing for %.0f s (--lease %g): %u of its cell(s) "
                    "go to process %d as well; the first result to arrive is kept\n",
                    from, r->who[from][0] ? r->who[from] : "pid unknown", now - r->heard[from], r->lease, moved, rank);
    }
    while (n < want && r->next < r->todo_count) {
        uint32_t c = r->todo[r->next++];
        out[n++] = c;
        r->holder[c] = rank;
        r->given[c] = now;
        if (rank > 0)
            r->flight[r->flight_count++] = c;
    }
    return n;
}

/* One result message of a worker: store its cells; the number of cells it wants next. */
static uint32_t serve_message(master_run *r, const uint8_t *buf, size_t size, int src)
{
    sl_error e;
    if (size < MSG_HEAD) {
        tool_fail(&e, SL_ERROR_INTERNAL, "pvs bake: process %d sent a short message", src);
        run_fail(r, e.status, &e);
        return 0;
    }
    uint32_t want = TOOL_MIN(rd32(buf), MAX_CHUNK);
    uint32_t wst = rd32(buf + 4), count = rd32(buf + 264);
    if (wst != SL_OK) {
        char msg[257];
        memcpy(msg, buf + 8, 256);
        msg[256] = 0;
        tool_fail(&e, (sl_status)wst, "process %d: %s", src, msg);
        run_fail(r, (sl_status)wst, &e);
    } else {
        /* an OK message carries "pid N on HOST" where an error would carry its text */
        size_t k = 0;
        for (; k < sizeof r->who[src] - 1 && buf[8 + k] >= 0x20 && buf[8 + k] < 0x7f; k++)
            r->who[src][k] = (char)buf[8 + k];
        r->who[src][k] = 0;
    }
    size_t at = MSG_HEAD;
    for (uint32_t k = 0; k < count; k++) {
        if (size - at < REC_HEAD) {
            tool_fail(&e, SL_ERROR_INTERNAL, "pvs bake: process %d sent a truncated result", src);
            run_fail(r, e.status, &e);
            break;
        }
        uint32_t cell = rd32(buf + at), ids = rd32(buf + at + 4), bytes = rd32(buf + at + 8);
        double secs;
        memcpy(&secs, buf + at + 12, 8);
        at += REC_HEAD;
        if (bytes > size - at) {
            tool_fail(&e, SL_ERROR_INTERNAL, "pvs bake: process %d sent a truncated set", src);
            run_fail(r, e.status, &e);
            break;
        }
        sl_bake_session b = r->b;
        if (cell < sl_bake_session_cell_count(b) && sl_bake_session_cell_done(b, cell) && r->reissued[cell]) {
            r->duplicates++; /* handed out twice: the first result won */
        } else if (run_keeps(r)) {
            sl_status s2 = cell < sl_bake_session_cell_count(b) && !sl_bake_session_cell_done(b, cell)
                               ? sl_bake_session_store_encoded(b, cell, buf + at, bytes, ids, secs, &e)
                               : tool_fail(&e, SL_ERROR_INTERNAL, "pvs bake: process %d returned cell %u twice", src, cell);
            if (s2 != SL_OK)
                run_fail(r, s2, &e);
            else
                run_counted(r);
        }
        at += bytes;
    }
    return want;
}

static void send_work(int dst, const uint32_t *cells, uint32_t n)
{
    uint8_t reply[4 + 4 * MAX_CHUNK];
    wr32(reply, n);
    for (uint32_t k = 0; k < n; k++)
        wr32(reply + 4 + 4 * k, cells[k]);
    MPI_Send(reply, (int)(4 + 4 * n), MPI_BYTE, dst, TAG_WORK, MPI_COMM_WORLD);
}

/* The server (process 0's main thread). Phase 1 (drain false): answer every worker; a request
 * that finds nothing to take waits (r->waiting) until a lease runs out or the bake is over, and
 * the phase ends when it is over and no request waits. Phase 2 (drain true, after the file is
 * written): every process still holding a chunk is waited for and told to stop; a silent one is
 * noted in the log every lease (or 10 s). *active counts the processes not yet told to stop. */
static void serve(master_run *r, int *active, bool drain)
{
    uint8_t *buf = NULL;
    size_t cap = 0;
    uint32_t take[MAX_CHUNK];
    double noted = tool_now();
    while (*active > 0) {
        MPI_Status ms;
        int flag = 0;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_RESULT, MPI_COMM_WORLD, &flag, &ms);
        if (flag) {
            int size = 0;
            MPI_Get_count(&ms, MPI_BYTE, &size);
            if ((size_t)size > cap) {
                uint8_t *nb = tool_realloc(sl_bake_session_allocator(r->b), buf, cap, (size_t)size);
                if (!nb) /* cannot even read the message: give up on the whole job */
                    MPI_Abort(MPI_COMM_WORLD, 2);
                buf = nb;
                cap = (size_t)size;
            }
            int src = ms.MPI_SOURCE;
            MPI_Recv(buf, size, MPI_BYTE, src, TAG_RESULT, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
            uint32_t n = 0;
            bool stop = false;
#pragma omp critical(sl_pvs_mpi)
            {
                double now = tool_now();
                r->heard[src] = now;
                r->busy[src] = 0;
                if (drain) {
                    /* the file is written (or the bake failed): results no longer matter, but those
                     * of a bake stopped by --stop-after go to the journal (nothing done is lost) */
                    if (r->stopping == STOP_AFTER)
                        (void)serve_message(r, buf, (size_t)size, src);
                    stop = true;
                } else {
                    uint32_t want = serve_message(r, buf, (size_t)size, src);
                    n = want ? run_take(r, want, take, src, now) : 0;
                    if (n == 0 && want && !run_over(r))
                        r->waiting[src] = want; /* answered when a lease runs out or the bake is over */
                    else
                        stop = n == 0;
                    if (n)
                        r->busy[src] = 1;
                }
            }
            if (n || stop)
                send_work(src, take, n);
            if (stop)
                (*active)--;
            continue;
        }
        /* nothing came: answer waiting requests whose turn has come, end the phase when over */
        bool phase_over = false;
        for (int p = 1; p < r->nproc; p++) {
            uint32_t n = 0;
            bool stop = false;
#pragma omp critical(sl_pvs_mpi)
            if (r->waiting[p]) {
                n = run_take(r, r->waiting[p], take, p, tool_now());
                stop = n == 0 && run_over(r);
                if (n || stop)
                    r->waiting[p] = 0;
                if (n)
                    r->busy[p] = 1;
            }
            if (n || stop)
                send_work(p, take, n);
            if (stop)
                (*active)--;
        }
        if (!drain) {
#pragma omp critical(sl_pvs_mpi)
            {
                phase_over = run_over(r);
                for (int p = 1; p < r->nproc && phase_over; p++)
                    phase_over = r->waiting[p] == 0;
            }
            if (phase_over)
                break;
        } else {
            double now = tool_now(), every = r->lease > 0 ? r->lease : 10;
            if (now - noted >= every) {
                noted = now;
                for (int p = 1; p < r->nproc; p++)
                    if (r->busy[p])
                        fprintf(stderr,
                                "sightline pvs build: %s is complete; waiting for process %d (%s), silent for %.0f "
                                "s, to end (kill -CONT it if stopped, or end the job)\n",
                                sl_bake_session_output(r->b), p, r->who[p][0] ? r->who[p] : "pid unknown",
                                now - r->heard[p]);
            }
        }
        /* poll with short sleeps: a blocking probe busy-waits in MPICH and would take a core from
         * the bakers for nothing */
        struct timespec ts = {0, 200000};
        nanosleep(&ts, NULL);
    }
    tool_free(sl_bake_session_allocator(r->b), buf, cap);
}

/* A baking thread of process 0: cells from the shared queue (or whose lease ran out), one at a
 * time, until the bake is over. */
static void bake_local(master_run *r)
{
    sl_bake_session b = r->b;
    sl_bake_worker w = NULL;
    sl_error e;
    const sl_allocator *a = sl_bake_session_allocator(b);
    size_t ids_size = ((size_t)sl_bake_session_object_count(b) + 1) * sizeof(uint32_t);
    uint32_t *ids = tool_alloc(a, ids_size);
    sl_status s = ids ? sl_bake_worker_create(b, &w, &e)
                      : tool_fail(&e, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    if (s != SL_OK) {
#pragma omp critical(sl_pvs_mpi)
        run_fail(r, s, &e);
    }
    while (s == SL_OK) {
        uint32_t cell, n;
        bool over;
#pragma omp critical(sl_pvs_mpi)
        {
            n = run_take(r, 1, &cell, 0, tool_now());
            over = run_over(r);
        }
        if (n == 0) {
            if (over || r->lease <= 0)
                break;
            struct timespec ts = {0, 5 * 1000 * 1000}; /* cells are out elsewhere: wait for a lease to run out */
            nanosleep(&ts, NULL);
            continue;
        }
        uint32_t count = 0;
        double c0 = tool_now();
        sl_status cs = sl_bake_worker_cell(w, cell, ids, &count, &e);
        double secs = tool_now() - c0;
#pragma omp critical(sl_pvs_mpi)
        {
            if (cs == SL_OK && sl_bake_session_cell_done(b, cell) && r->reissued[cell]) {
                r->duplicates++;
            } else if (cs == SL_OK && run_keeps(r)) {
                cs = sl_bake_session_store(b, cell, ids, count, secs, &e);
                if (cs == SL_OK)
                    run_counted(r);
            }
            if (cs != SL_OK) {
                tool_error_prefix(&e, "cell %u", cell);
                run_fail(r, cs, &e);
            }
        }
    }
    sl_bake_worker_destroy(w);
    tool_free(a, ids, ids_size);
}

/* Process 0: serve and bake until every cell is done, write the file, then wait for the processes
 * still out (see serve). */
static sl_status master(sl_bake_session b, const char *output, const sl_pvs_build_options *opt, double lease, int nproc,
                        int threads, sl_error *err)
{
    master_run r;
    memset(&r, 0, sizeof r);
    r.b = b;
    r.progress = opt ? &opt->progress : NULL;
    r.stop_after = opt ? opt->stop_after : 0;
    r.lease = lease;
    r.nproc = nproc;
    size_t nc = (size_t)sl_bake_session_cell_count(b) + 1, np = (size_t)nproc;
    r.todo = tool_alloc(sl_bake_session_allocator(b), nc * sizeof(uint32_t));
    r.flight = tool_alloc(sl_bake_session_allocator(b), nc * sizeof(uint32_t));
    r.holder = tool_alloc(sl_bake_session_allocator(b), nc * sizeof(int));
    r.given = tool_calloc(sl_bake_session_allocator(b), nc, sizeof(double));
    r.reissued = tool_calloc(sl_bake_session_allocator(b), nc, 1);
    r.waiting = tool_calloc(sl_bake_session_allocator(b), np, sizeof(uint32_t));
    r.busy = tool_calloc(sl_bake_session_allocator(b), np, 1);
    r.heard = tool_calloc(sl_bake_session_allocator(b), np, sizeof(double));
    r.who = tool_calloc(sl_bake_session_allocator(b), np, sizeof *r.who);
    sl_status st = SL_OK;
    if (!r.todo || !r.flight || !r.holder || !r.given || !r.reissued || !r.waiting || !r.busy || !r.heard || !r.who) {
        /* the workers are waiting for an answer: tell them to stop before failing */
        for (int p = 1; p < nproc; p++) {
            uint8_t buf[MSG_HEAD + 64];
            MPI_Status ms;
            MPI_Probe(p, TAG_RESULT, MPI_COMM_WORLD, &ms);
            int size = 0;
            MPI_Get_count(&ms, MPI_BYTE, &size);
            if ((size_t)size > sizeof buf)
                MPI_Abort(MPI_COMM_WORLD, 2);
            MPI_Recv(buf, size, MPI_BYTE, p, TAG_RESULT, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
            send_work(p, NULL, 0);
        }
        st = tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    } else {
        for (uint32_t c = 0; c < sl_bake_session_cell_count(b); c++) {
            r.holder[c] = -1;
            if (!sl_bake_session_cell_done(b, c))
                r.todo[r.todo_count++] = c;
        }
        double now = tool_now();
        for (int p = 0; p < nproc; p++)
            r.heard[p] = now;
        int active = nproc - 1;
        /* thread 0 of the team is the calling (main) thread: it alone calls MPI */
#pragma omp parallel num_threads(threads + 1)
        {
            if (omp_get_thread_num() == 0)
                serve(&r, &active, false);
            else
                bake_local(&r);
        }
        if (r.stopping == STOP_ERROR) {
            if (err)
                *err = r.err;
            sl_bake_session_note_kept(b, err);
            st = r.st;
        } else if (r.stopping == STOP_CANCELLED) {
            st = tool_fail(err, SL_ERROR_CANCELLED, "pvs bake: cancelled after %u of %u cells; resume from %s",
                         sl_bake_session_done_count(b), sl_bake_session_cell_count(b), sl_bake_session_journal(b));
        } else if (r.stopping == STOP_AFTER) {
            st = tool_fail(err, SL_ERROR_CANCELLED,
                         "pvs bake: stopped after %u newly baked cells as asked (%u of %u done); resume from %s",
                         sl_bake_session_baked(b), sl_bake_session_done_count(b), sl_bake_session_cell_count(b),
                         sl_bake_session_journal(b));
        } else {
            st = sl_bake_session_finish(b, output, opt, err);
        }
        if (r.duplicates)
            fprintf(stderr,
                    "sightline pvs build: %u cell result(s) arrived after another process had returned the same "
                    "cell, and were dropped\n",
                    r.duplicates);
        if (active > 0) {
            if (st == SL_OK)
                fprintf(stderr, "sightline pvs build: %s is complete; %d process(es) still hold a chunk\n", output,
                        active);
            serve(&r, &active, true);
        }
    }
    tool_free(sl_bake_session_allocator(b), r.todo, nc * sizeof(uint32_t));
    tool_free(sl_bake_session_allocator(b), r.flight, nc * sizeof(uint32_t));
    tool_free(sl_bake_session_allocator(b), r.holder, nc * sizeof(int));
    tool_free(sl_bake_session_allocator(b), r.given, nc * sizeof(double));
    tool_free(sl_bake_session_allocator(b), r.reissued, nc);
    tool_free(sl_bake_session_allocator(b), r.waiting, np * sizeof(uint32_t));
    tool_free(sl_bake_session_allocator(b), r.busy, np);
    tool_free(sl_bake_session_allocator(b), r.heard, np * sizeof(double));
    tool_free(sl_bake_session_allocator(b), r.who, np * sizeof *r.who);
    return st;
}

/* ---- the other processes ---- */

/* A finished cell of a worker's chunk, encoded. */
typedef struct done_cell {
    uint32_t cell, ids;
    double seconds;
    uint8_t *bytes;
    uint32_t size;
    sl_status st;
    sl_error err;
} done_cell;

/* The message reporting a chunk (or the error) and asking for `want` more cells. */
static bool worker_message(const sl_allocator *a, tool_bytes *out, uint32_t want, sl_status st, const sl_error *err,
                           const done_cell *res, uint32_t nres)
{
    out->count = 0;
    uint8_t head[MSG_HEAD];
    memset(head, 0, sizeof head);
    wr32(head, st == SL_OK ? want : 0);
    wr32(head + 4, (uint32_t)st);
    if (st != SL_OK && err)
        memcpy(head + 8, err->message, TOOL_MIN(sizeof err->message, (size_t)255));
    if (st == SL_OK) {
        char host[40] = "";
        gethostname(host, sizeof host - 1);
        host[sizeof host - 1] = 0;
        snprintf((char *)head + 8, 64, "pid %ld on %s", (long)getpid(), host);
    }
    wr32(head + 264, st == SL_OK ? nres : 0);
    bool ok = tool_bytes_push(a, out, head, sizeof head);
    for (uint32_t k = 0; k < nres && st == SL_OK && ok; k++) {
        uint8_t rh[REC_HEAD];
        wr32(rh, res[k].cell);
        wr32(rh + 4, res[k].ids);
        wr32(rh + 8, res[k].size);
        memcpy(rh + 12, &res[k].seconds, 8);
        ok = tool_bytes_push(a, out, rh, sizeof rh) &&
             (res[k].size == 0 || tool_bytes_push(a, out, res[k].bytes, res[k].size));
    }
    return ok;
}

static sl_status worker(sl_bake_session b, int threads, sl_error *err)
{
    const sl_allocator *a = sl_bake_session_allocator(b);
    sl_bake_worker *workers = tool_calloc(a, (size_t)threads, sizeof *workers);
    uint32_t **ids = tool_calloc(a, (size_t)threads, sizeof(uint32_t *));
    uint32_t *cells = tool_alloc(a, MAX_CHUNK * sizeof(uint32_t));
    done_cell *res = tool_calloc(a, (size_t)threads, sizeof(done_cell));
    tool_bytes out = {0}; /* the message under construction */
    sl_status st = SL_OK;
    if (!workers || !ids || !cells || !res)
        st = tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    for (int t = 0; t < threads && st == SL_OK; t++) {
        ids[t] = tool_alloc(a, ((size_t)sl_bake_session_object_count(b) + 1) * sizeof(uint32_t));
        if (!ids[t])
            st = tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
        else
            st = sl_bake_worker_create(b, &workers[t], err);
    }
    uint32_t nres = 0;
    for (;;) {
        /* report the last chunk (or the error) and ask for more */
        bool ok = worker_message(a, &out, (uint32_t)threads, st, err, res, nres);
        for (uint32_t k = 0; k < nres; k++) {
            tool_free(a, res[k].bytes, (size_t)res[k].ids * 5 + 1);
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
            st = tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
        } else {
            MPI_Send(out.data, (int)out.count, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD);
        }
        uint8_t work[4 + 4 * MAX_CHUNK];
        MPI_Status ms;
        /* poll with short sleeps: the answer may wait for a lease to run out, and a blocking
         * receive busy-waits in MPICH, taking a core from the processes still baking */
        MPI_Request rq;
        MPI_Irecv(work, sizeof work, MPI_BYTE, 0, TAG_WORK, MPI_COMM_WORLD, &rq);
        for (int flag = 0;;) {
            MPI_Test(&rq, &flag, &ms);
            if (flag)
                break;
            struct timespec ts = {0, 1000000};
            nanosleep(&ts, NULL);
        }
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
            if (cells[k] >= sl_bake_session_cell_count(b)) {
                d->st = tool_fail(&d->err, SL_ERROR_INTERNAL, "pvs bake: the master sent cell %u of %u", cells[k],
                                sl_bake_session_cell_count(b));
                continue;
            }
            uint32_t count = 0;
            double c0 = tool_now();
            d->st = sl_bake_worker_cell(workers[t], cells[k], ids[t], &count, &d->err);
            d->seconds = tool_now() - c0;
            if (d->st != SL_OK) {
                tool_error_prefix(&d->err, "cell %u", cells[k]);
                continue;
            }
            d->ids = count;
            d->bytes = tool_alloc(a, (size_t)count * 5 + 1);
            if (!d->bytes)
                d->st = tool_fail(&d->err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory for cell %u", cells[k]);
            else
                d->size = (uint32_t)sl_bake_encode_set(ids[t], count, d->bytes);
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
        tool_free(a, res[k].bytes, (size_t)res[k].ids * 5 + 1);
    tool_free(a, res, (size_t)threads * sizeof(done_cell));
    for (int t = 0; t < threads; t++) {
        if (workers)
            sl_bake_worker_destroy(workers[t]);
        if (ids)
            tool_free(a, ids[t], ((size_t)sl_bake_session_object_count(b) + 1) * sizeof(uint32_t));
    }
    tool_free(a, workers, (size_t)threads * sizeof *workers);
    tool_free(a, ids, (size_t)threads * sizeof(uint32_t *));
    tool_free(a, cells, MAX_CHUNK * sizeof(uint32_t));
    tool_bytes_free(a, &out);
    return st;
}

sl_status cli_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                            double lease, sl_pvs_build_stats *stats, int *rank_out, sl_error *err)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (rank_out)
        *rank_out = 0;
    int inited = 0, finalized = 0;
    MPI_Initialized(&inited);
    MPI_Finalized(&finalized);
    if (finalized)
        return tool_fail(err, SL_ERROR_UNSUPPORTED, "pvs bake: MPI was already finalized in this process");
    bool own = !inited;
    int provided = MPI_THREAD_SINGLE;
    if (own) {
        if (MPI_Init_thread(NULL, NULL, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
            return tool_fail(err, SL_ERROR_INTERNAL, "pvs bake: MPI_Init failed");
    } else {
        MPI_Query_thread(&provided);
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
    threads = TOOL_MAX(1, TOOL_MIN(threads, (int)sl_thread_limit())); /* opt->threads was checked against it */
    /* without FUNNELED the MPI library may not tolerate other threads beside the one calling it:
     * process 0 then only serves */
    int local = provided >= MPI_THREAD_FUNNELED ? threads : 0;
    sl_bake_session b = NULL;
    st = sl_bake_session_begin(scene, cells, output, opt, rank == 0, &b, err);
    st = agree(st, err, rank);
    if (st == SL_OK) {
        /* every process must bake the same thing: compare the bake keys */
        uint64_t key = sl_bake_session_key(b), root = sl_bake_session_key(b);
        MPI_Bcast(&root, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
        if (key != root)
            st = tool_fail(err, SL_ERROR_INVALID_ARGUMENT,
                         "pvs bake: process %d has another scene, cells, method or options than process 0", rank);
        st = agree(st, err, rank);
    }
    if (st == SL_OK)
        st = rank == 0 ? master(b, output, opt, lease, nproc, local, err) : worker(b, threads, err);
    /* the master's verdict (and the file, written by master) is the job's; every process takes part */
    int verdict = (int)st;
    MPI_Bcast(&verdict, 1, MPI_INT, 0, MPI_COMM_WORLD);
    char msg[512];
    memset(msg, 0, sizeof msg);
    if (rank == 0 && verdict != SL_OK && err)
        snprintf(msg, sizeof msg, "%s", err->message);
    MPI_Bcast(msg, sizeof msg, MPI_CHAR, 0, MPI_COMM_WORLD);
    if (rank != 0 && verdict != SL_OK && st == SL_OK)
        st = tool_fail(err, (sl_status)verdict, "process 0: %s", msg);
    if (stats) {
        sl_bake_session_stats(b, stats);
        stats->processes = (uint32_t)nproc;
        stats->threads = (uint32_t)threads;
        stats->seconds = MPI_Wtime() - t0;
        struct stat sb;
        if (rank == 0 && st == SL_OK && stat(output, &sb) == 0)
            stats->file_bytes = (uint64_t)sb.st_size;
    }
    sl_bake_session_end(b);
    if (own)
        MPI_Finalize();
    return st;
}

#endif
